//! A cape on an animated, skinned character. The body is one skinned mesh built in code (a
//! torso, arms and legs on six joints, blended where they meet), walked by the same cycle as
//! the `cape` example; an `AutoCollider` on it makes a skinned collider, whose spheres follow
//! the joints every frame, so the cape is pushed by the back, the swinging arms and the legs
//! as they are drawn. The cape hangs by its painted top edge from the shoulders joint, and the
//! floor is a ground primitive. A glTF character works the same way: put `AutoCollider` on the
//! scene root and every mesh under it, skinned or not, becomes a collider.
//!
//! `cargo run --release -p bevy_bvh_cloth --features egui --example character`
//!
//! Drag to orbit, scroll to zoom, R resets, Space pauses, B shows the collider's spheres.

mod common;
#[path = "common/walk.rs"]
mod walk;

use std::f32::consts::TAU;

use bevy::asset::RenderAssetUsages;
use bevy::camera::visibility::NoFrustumCulling;
use bevy::mesh::skinning::{SkinnedMesh, SkinnedMeshInverseBindposes};
use bevy::mesh::{Indices, PrimitiveTopology, VertexAttributeValues};
use bevy::prelude::*;
use bevy_bvh_cloth::prelude::*;
use walk::{ARM_DROP, HIP_HEIGHT, HIP_WIDTH, Hips, SHOULDER_WIDTH, SHOULDERS_ABOVE_HIPS, Walker, arm_swing, leg_swing};

/// The joints, in the order of the skin's joint indices.
const HIPS: u16 = 0;
const SHOULDERS: u16 = 1;
const LEFT_LEG: u16 = 2;
const RIGHT_LEG: u16 = 3;
const LEFT_ARM: u16 = 4;
const RIGHT_ARM: u16 = 5;
/// Sides around each limb, and rings per metre along it.
const SIDES: u32 = 20;
const RINGS_PER_METRE: f32 = 60.0;

fn main() {
    common::example_app("bevy_bvh_cloth: character").add_systems(Startup, setup).add_systems(Update, walk::walk).run();
}

fn setup(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    mut bindposes: ResMut<Assets<SkinnedMeshInverseBindposes>>,
) {
    common::spawn_camera(&mut commands, Vec3::new(0.0, 0.9, 0.0), 4.5);
    let skin = materials.add(StandardMaterial { base_color: Color::srgb(0.78, 0.66, 0.55), ..default() });

    // The skeleton. Each joint's place relative to the root when the figure stands (the bind
    // pose), in the order of `HIPS`..`RIGHT_ARM`.
    let shoulders_at = Vec3::new(0.0, HIP_HEIGHT + SHOULDERS_ABOVE_HIPS, 0.0);
    let bind = [
        Vec3::new(0.0, HIP_HEIGHT, 0.0),
        shoulders_at,
        Vec3::new(-HIP_WIDTH, HIP_HEIGHT, 0.0),
        Vec3::new(HIP_WIDTH, HIP_HEIGHT, 0.0),
        shoulders_at + Vec3::new(-SHOULDER_WIDTH, -ARM_DROP, 0.0),
        shoulders_at + Vec3::new(SHOULDER_WIDTH, -ARM_DROP, 0.0),
    ];
    let walker = commands.spawn((Walker, walk::walker_pose(0.0), Visibility::default())).id();
    let hips =
        commands.spawn((Hips, Transform::from_translation(bind[0]), Visibility::default(), ChildOf(walker))).id();
    let shoulders = commands
        .spawn((
            Transform::from_xyz(0.0, SHOULDERS_ABOVE_HIPS, 0.0),
            Visibility::default(),
            ChildOf(hips),
            children![(
                Mesh3d(meshes.add(Sphere::new(0.12))),
                MeshMaterial3d(skin.clone()),
                Transform::from_xyz(0.0, 0.2, 0.0)
            )],
        ))
        .id();
    let leg = |commands: &mut Commands, left: bool, at: Vec3| {
        commands.spawn((leg_swing(left), Transform::from_translation(at), ChildOf(walker))).id()
    };
    let (left_leg, right_leg) = (leg(&mut commands, true, bind[2]), leg(&mut commands, false, bind[3]));
    let arm = |commands: &mut Commands, left: bool, at: Vec3| {
        commands.spawn((arm_swing(left), Transform::from_translation(at - shoulders_at), ChildOf(shoulders))).id()
    };
    let (left_arm, right_arm) = (arm(&mut commands, true, bind[4]), arm(&mut commands, false, bind[5]));

    // The body, skinned to those joints, and its collider: spheres of 4 cm voxels that follow
    // the joints.
    let inverse_bindposes = bindposes.add(bind.map(|at| Mat4::from_translation(-at)).to_vec());
    commands.spawn((
        Mesh3d(meshes.add(body_mesh())),
        MeshMaterial3d(skin),
        SkinnedMesh { inverse_bindposes, joints: vec![hips, shoulders, left_leg, right_leg, left_arm, right_arm] },
        AutoCollider::from_voxel_size(0.04).with_margin(0.01),
        // The body's bounds move with its joints, not with its entity.
        NoFrustumCulling,
        ChildOf(walker),
    ));

    let material = common::cloth_material(&mut materials, Color::srgb(0.2, 0.25, 0.6));
    commands.spawn(walk::cape(shoulders, &mut meshes, material));
}

/// A weight rising smoothly from 0 at `from` to 1 at `to`.
fn blend(x: f32, from: f32, to: f32) -> f32 {
    let t = ((x - from) / (to - from)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// The body in its bind pose, in the root's frame: a torso on the hips and shoulders, and a
/// leg and an arm on each side, each a closed, rounded tube. Where a limb meets the torso its
/// vertices are shared between the two joints.
fn body_mesh() -> Mesh {
    let mut body = Body::default();
    let chest = HIP_HEIGHT + SHOULDERS_ABOVE_HIPS;
    body.limb(Vec2::new(0.0, 0.0), HIP_HEIGHT - 0.12, chest + 0.05, Vec2::new(0.17, 0.12), |y| {
        let w = blend(y, HIP_HEIGHT + 0.05, chest - 0.15);
        ([HIPS, SHOULDERS, 0, 0], [1.0 - w, w, 0.0, 0.0])
    });
    for (x, leg) in [(-HIP_WIDTH, LEFT_LEG), (HIP_WIDTH, RIGHT_LEG)] {
        body.limb(Vec2::new(x, 0.0), 0.02, HIP_HEIGHT + 0.05, Vec2::splat(0.075), |y| {
            let w = 0.5 * blend(y, HIP_HEIGHT - 0.12, HIP_HEIGHT + 0.05);
            ([leg, HIPS, 0, 0], [1.0 - w, w, 0.0, 0.0])
        });
    }
    let arm_top = chest - ARM_DROP;
    for (x, arm) in [(-SHOULDER_WIDTH, LEFT_ARM), (SHOULDER_WIDTH, RIGHT_ARM)] {
        body.limb(Vec2::new(x, 0.0), arm_top - 0.64, arm_top + 0.05, Vec2::splat(0.055), |y| {
            let w = 0.5 * blend(y, arm_top - 0.06, arm_top + 0.05);
            ([arm, SHOULDERS, 0, 0], [1.0 - w, w, 0.0, 0.0])
        });
    }
    body.into_mesh()
}

/// A skinned triangle mesh under construction.
#[derive(Default)]
struct Body {
    positions: Vec<[f32; 3]>,
    joints: Vec<[u16; 4]>,
    weights: Vec<[f32; 4]>,
    indices: Vec<u32>,
}

impl Body {
    /// A closed vertical tube over `centre` (x, z) from `bottom` up to `top`, of elliptic
    /// section `radii` (x, z), its ends rounded over the larger radius and closed by a fan.
    /// `skin` gives the joints and weights of a vertex at height `y`.
    fn limb(&mut self, centre: Vec2, bottom: f32, top: f32, radii: Vec2, skin: impl Fn(f32) -> ([u16; 4], [f32; 4])) {
        let rings = ((top - bottom) * RINGS_PER_METRE).ceil() as u32;
        let round = radii.max_element();
        let first = self.positions.len() as u32;
        let vertex = |body: &mut Self, p: Vec3| {
            let (joints, weights) = skin(p.y);
            body.positions.push(p.to_array());
            body.joints.push(joints);
            body.weights.push(weights);
        };
        for i in 0..=rings {
            let y = bottom + (top - bottom) * i as f32 / rings as f32;
            // A quarter circle over the last `round` metres at each end, never quite closed.
            let end = ((y - bottom).min(top - y) / round).min(1.0);
            let scale = (1.0 - (1.0 - end) * (1.0 - end)).sqrt().max(0.3);
            for j in 0..SIDES {
                let angle = TAU * j as f32 / SIDES as f32;
                let p =
                    Vec3::new(centre.x + scale * radii.x * angle.cos(), y, centre.y + scale * radii.y * angle.sin());
                vertex(self, p);
            }
        }
        for i in 0..rings {
            for j in 0..SIDES {
                let a = first + i * SIDES + j;
                let b = first + i * SIDES + (j + 1) % SIDES;
                let (c, d) = (a + SIDES, b + SIDES);
                self.indices.extend_from_slice(&[a, c, b, b, c, d]);
            }
        }
        for (ring, y, flip) in [(0, bottom, false), (rings, top, true)] {
            let pole = self.positions.len() as u32;
            vertex(self, Vec3::new(centre.x, y, centre.y));
            for j in 0..SIDES {
                let a = first + ring * SIDES + j;
                let b = first + ring * SIDES + (j + 1) % SIDES;
                let triangle = if flip { [pole, b, a] } else { [pole, a, b] };
                self.indices.extend_from_slice(&triangle);
            }
        }
    }

    fn into_mesh(self) -> Mesh {
        Mesh::new(PrimitiveTopology::TriangleList, RenderAssetUsages::default())
            .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, self.positions)
            .with_inserted_attribute(Mesh::ATTRIBUTE_JOINT_INDEX, VertexAttributeValues::Uint16x4(self.joints))
            .with_inserted_attribute(Mesh::ATTRIBUTE_JOINT_WEIGHT, self.weights)
            .with_inserted_indices(Indices::U32(self.indices))
            .with_computed_smooth_normals()
    }
}
