//! A skinned arm built in code, shared by the headless and the render tests: a closed tube on
//! a shoulder and an elbow joint, the triangles it is drawn with at the joints' pose, and an
//! inside test against them.

use bevy::asset::RenderAssetUsages;
use bevy::math::Affine3A;
use bevy::mesh::skinning::{SkinnedMesh, SkinnedMeshInverseBindposes};
use bevy::mesh::{Indices, PrimitiveTopology};
use bevy::prelude::*;
use bevy_bvh_cloth::bvh_cloth_core::backend::SkinnedVertices;
use bevy_bvh_cloth::prelude::*;

/// The arm's length and radius, and the elbow's distance from the shoulder, in metres.
pub const LENGTH: f32 = 1.2;
pub const RADIUS: f32 = 0.12;
pub const ELBOW: f32 = 0.6;

/// Positions, indices, joints and weights.
pub type SkinnedArm = (Vec<[f32; 3]>, Vec<u32>, Vec<[u16; 4]>, Vec<[f32; 4]>);

/// A closed arm along +x from the origin: a 16-sided tube of `LENGTH` with capped ends. The part
/// before the elbow is on joint 0, the part after it on joint 1, blended over 20 cm.
pub fn arm() -> SkinnedArm {
    let (rings, slices) = (30u32, 16u32);
    let mut positions = Vec::new();
    let mut weights = Vec::new();
    let weight = |x: f32| ((x - (ELBOW - 0.1)) / 0.2).clamp(0.0, 1.0);
    for i in 0..=rings {
        let x = LENGTH * i as f32 / rings as f32;
        for j in 0..slices {
            let angle = std::f32::consts::TAU * j as f32 / slices as f32;
            positions.push([x, RADIUS * angle.cos(), RADIUS * angle.sin()]);
            weights.push([1.0 - weight(x), weight(x), 0.0, 0.0]);
        }
    }
    let mut indices = Vec::new();
    for i in 0..rings {
        for j in 0..slices {
            let a = i * slices + j;
            let b = i * slices + (j + 1) % slices;
            let (c, d) = (a + slices, b + slices);
            indices.extend_from_slice(&[a, b, c, b, d, c]);
        }
    }
    // The caps: a centre vertex at each end.
    for (ring, x) in [(0, 0.0), (rings, LENGTH)] {
        let centre = positions.len() as u32;
        positions.push([x, 0.0, 0.0]);
        weights.push([1.0 - weight(x), weight(x), 0.0, 0.0]);
        for j in 0..slices {
            let (a, b) = (ring * slices + j, ring * slices + (j + 1) % slices);
            indices.extend_from_slice(&[centre, a, b]);
        }
    }
    let joints = vec![[0, 1, 0, 0]; positions.len()];
    (positions, indices, joints, weights)
}

pub fn arm_mesh() -> Mesh {
    let (positions, indices, joints, weights) = arm();
    Mesh::new(PrimitiveTopology::TriangleList, RenderAssetUsages::default())
        .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, positions)
        .with_inserted_attribute(Mesh::ATTRIBUTE_JOINT_INDEX, bevy::mesh::VertexAttributeValues::Uint16x4(joints))
        .with_inserted_attribute(Mesh::ATTRIBUTE_JOINT_WEIGHT, weights)
        .with_inserted_indices(Indices::U32(indices))
}

/// A shoulder joint at `at` and an elbow joint under it, a skinned arm mesh on them with an
/// `AutoCollider`; returns (arm, shoulder, elbow).
pub fn spawn_arm(app: &mut App, mesh: Mesh, at: Vec3) -> (Entity, Entity, Entity) {
    let mesh = app.world_mut().resource_mut::<Assets<Mesh>>().add(mesh);
    let inverse = app
        .world_mut()
        .resource_mut::<Assets<SkinnedMeshInverseBindposes>>()
        .add(vec![Mat4::IDENTITY, Mat4::from_translation(Vec3::new(-ELBOW, 0.0, 0.0))]);
    let shoulder = app.world_mut().spawn(Transform::from_translation(at)).id();
    let elbow = app.world_mut().spawn((Transform::from_xyz(ELBOW, 0.0, 0.0), ChildOf(shoulder))).id();
    let arm = app
        .world_mut()
        .spawn((
            Mesh3d(mesh),
            SkinnedMesh { inverse_bindposes: inverse, joints: vec![shoulder, elbow] },
            AutoCollider::from_voxel_size(0.06).with_margin(0.01),
        ))
        .id();
    (arm, shoulder, elbow)
}

/// The arm's triangles as the renderer draws them this frame.
pub fn skinned_triangles(app: &App, shoulder: Entity, elbow: Entity) -> Vec<[Vec3; 3]> {
    let (positions, indices, joints, weights) = arm();
    let vertices = SkinnedVertices { positions: positions.iter().map(|&p| Vec3A::from(p)).collect(), joints, weights };
    let global = |e: Entity| app.world().get::<GlobalTransform>(e).unwrap().affine();
    let matrices = [global(shoulder), global(elbow) * Affine3A::from_translation(Vec3::new(-ELBOW, 0.0, 0.0))];
    let mut skinned = Vec::new();
    vertices.skin_into(&matrices, &mut skinned);
    indices.chunks_exact(3).map(|t| [0, 1, 2].map(|k| Vec3::from(skinned[t[k] as usize]))).collect()
}

/// A closed triangle mesh for inside tests: the parity of the crossings of a ray from the point.
/// Each triangle keeps its bounds seen along the ray (in the plane the ray's direction projects
/// to a point), so that a query runs the exact crossing test only on the few triangles whose
/// bounds hold the point's projection.
pub struct Solid {
    triangles: Vec<[Vec3; 3]>,
    /// Per triangle: the least and the greatest of its corners' projections, `[u0, w0, u1, w1]`.
    bounds: Vec<[f32; 4]>,
}

/// The ray's direction: off every axis, so that no face of the arm lies along it.
const RAY: Vec3 = Vec3::new(0.1234, 1.0, 0.0457);

/// Where the ray through `p` meets the plane `y = 0`: constant along the ray.
fn project(p: Vec3) -> [f32; 2] {
    [p.x - p.y * RAY.x / RAY.y, p.z - p.y * RAY.z / RAY.y]
}

impl Solid {
    pub fn new(triangles: Vec<[Vec3; 3]>) -> Self {
        let bounds = triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(project);
                [a[0].min(b[0]).min(c[0]), a[1].min(b[1]).min(c[1]), a[0].max(b[0]).max(c[0]), a[1].max(b[1]).max(c[1])]
            })
            .collect();
        Self { triangles, bounds }
    }

    /// Whether `p` is inside (Möller–Trumbore on the triangles whose projected bounds hold `p`'s).
    pub fn contains(&self, p: Vec3) -> bool {
        let dir = RAY.normalize();
        let [u, w] = project(p);
        let crossings = self
            .triangles
            .iter()
            .zip(&self.bounds)
            .filter(|(_, b)| u >= b[0] && w >= b[1] && u <= b[2] && w <= b[3])
            .filter(|([a, b, c], _)| {
                let (e1, e2) = (*b - *a, *c - *a);
                let h = dir.cross(e2);
                let det = e1.dot(h);
                if det.abs() < 1e-12 {
                    return false;
                }
                let s = p - *a;
                let u = s.dot(h) / det;
                let q = s.cross(e1);
                let v = dir.dot(q) / det;
                u >= 0.0 && v >= 0.0 && u + v <= 1.0 && e2.dot(q) / det > 0.0
            })
            .count();
        crossings % 2 == 1
    }

    /// The triangles, as given.
    pub fn triangles(&self) -> &[[Vec3; 3]] {
        &self.triangles
    }
}
