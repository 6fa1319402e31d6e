//! Colliders that animate with a skinned mesh: the voxel spheres are carried by the mesh's
//! linear blend skinning every frame, and the LBVH is refitted bottom-up with its topology kept.
//!
//! # What stays covered
//!
//! A voxel sphere is fitted to points of the surface: the vertices in its voxel and the corners
//! of the parts of triangles that cross into it (see [`crate::colliders::voxel_spheres`]). Every such
//! point is stored here as a triangle and barycentric coordinates on it (a vertex is its own
//! triangle). A renderer skins the vertices and interpolates linearly across each triangle, so
//! a point with fixed barycentric coordinates lands at the same blend of the skinned corners,
//! and the skinned part of a triangle is the convex hull of its skinned corners. Each frame the
//! points are skinned and every sphere is fitted again to its own points, exactly as at build
//! time (the smaller of the box-centre and centroid spheres, grown by the surface clearance).
//! So whatever the pose, each sphere encloses its part of the skinned surface, the spheres
//! together cover every skinned triangle, and the shell keeps the thickness the static build
//! gives it. No radius bound is guessed: the bound is the fit itself.
//!
//! # The tree
//!
//! The leaves keep their Morton order from the bind pose and the inner nodes their children;
//! only the boxes are refitted, children before parents. A refitted tree answers every query
//! exactly; only its culling grows looser where the animation carries leaves far from the
//! neighbours they were sorted beside.
//!
//! # Cost
//!
//! One frame skins the vertices the points use (four joints each, as Bevy and glTF do), then
//! for each sphere places its points (a vertex is one read, a corner a blend of three) and fits
//! the sphere to them while they are in cache. A corner that two triangles share (where a grid plane cuts
//! their common edge) is stored once. The report measures a frame against skinning the
//! vertices alone.

use bytemuck::{Pod, Zeroable};
use glam::{Affine3A, UVec3, Vec3, Vec3A};
use rayon::prelude::*;

use crate::bvh::lbvh::{Lbvh, Sphere};
use crate::colliders::error::ColliderError;
use crate::colliders::voxel_grid::VoxelGrid;
use crate::colliders::voxel_spheres::{SURFACE_CLEARANCE, VoxelSpheres, Voxels, voxel_spheres_in};
use crate::mesh::MeshRef;

/// A mesh's skin, borrowed from the caller: per vertex up to four joints and their weights (the
/// layout of Bevy's `Mesh::ATTRIBUTE_JOINT_INDEX` and `ATTRIBUTE_JOINT_WEIGHT`, and glTF's),
/// and how many joint matrices the skin has.
#[derive(Clone, Copy, Debug)]
pub struct SkinRef<'a> {
    /// Four joint indices per vertex.
    pub joints: &'a [[u16; 4]],
    /// Four weights per vertex, in the order of `joints`. A vertex is placed at the weighted sum
    /// of its joints' transforms, unnormalised, as Bevy's vertex shader places it.
    pub weights: &'a [[f32; 4]],
    /// Number of joint matrices: every index with a non-zero weight must be below it.
    pub joint_count: usize,
}

/// A point a sphere encloses: a blend of three skinned vertices (for a vertex, three times
/// itself). Layout: 20 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct SkinPoint {
    /// The triangle's vertices, as indices into [`SkinnedSpheres`]'s own vertex list.
    pub vertices: [u32; 3],
    /// Barycentric weights of the second and third vertex; the first has the rest.
    pub weights: [f32; 2],
}

/// The vertices a skinned collider moves, with their bind positions and skin.
#[derive(Clone, Debug, Default)]
pub struct SkinnedVertices {
    /// Bind-pose positions (the mesh's own coordinates).
    pub positions: Vec<Vec3A>,
    /// Four joint indices per vertex.
    pub joints: Vec<[u16; 4]>,
    /// Four weights per vertex.
    pub weights: Vec<[f32; 4]>,
}

impl SkinnedVertices {
    /// Skins every vertex by `joint_matrices` into `out` (resized to fit), as a linear blend
    /// skinning vertex shader does. Joint indices must be in range (as the build checked).
    pub fn skin_into(&self, joint_matrices: &[Affine3A], out: &mut Vec<Vec3A>) {
        out.resize(self.positions.len(), Vec3A::ZERO);
        let skin = |((p, joints), weights): ((&Vec3A, &[u16; 4]), &[f32; 4]), out: &mut Vec3A| {
            *out = skin_point(*p, joints, weights, joint_matrices);
        };
        if self.positions.len() >= PARALLEL_MIN {
            self.positions
                .par_iter()
                .zip(&self.joints)
                .zip(&self.weights)
                .zip(out.par_iter_mut())
                .with_min_len(PARALLEL_MIN / 4)
                .for_each(|(item, out)| skin(item, out));
        } else {
            let items = self.positions.iter().zip(&self.joints).zip(&self.weights);
            items.zip(out.iter_mut()).for_each(|(item, out)| skin(item, out));
        }
    }
}

impl SkinnedVertices {
    /// Vertex `i` skinned by `joint_matrices`, as [`Self::skin_into`] places it.
    pub fn skin_vertex(&self, i: usize, joint_matrices: &[Affine3A]) -> Vec3A {
        skin_point(self.positions[i], &self.joints[i], &self.weights[i], joint_matrices)
    }
}

/// `p` placed by linear blend skinning: each joint's matrix weighted, unnormalised.
#[inline]
fn skin_point(p: Vec3A, joints: &[u16; 4], weights: &[f32; 4], joint_matrices: &[Affine3A]) -> Vec3A {
    let mut sum = Vec3A::ZERO;
    for (&joint, &weight) in joints.iter().zip(weights) {
        if weight != 0.0 {
            sum += weight * joint_matrices[joint as usize].transform_point3a(p);
        }
    }
    sum
}

/// Above this many vertices or leaves a refit runs on the rayon pool.
const PARALLEL_MIN: usize = 8192;

/// What a skinned collider keeps to refit its spheres: the vertices, the points of each leaf
/// (in the tree's leaf order) and the clearance.
#[derive(Clone, Debug)]
pub struct SkinnedSpheres {
    /// The vertices the points use (the mesh's used vertices, renumbered densely).
    pub vertices: SkinnedVertices,
    /// Every leaf's points, leaf after leaf.
    pub points: Vec<SkinPoint>,
    /// Leaf `k`'s points are `points[leaf_starts[k]..leaf_starts[k + 1]]`.
    pub leaf_starts: Vec<u32>,
    /// How far a sphere reaches past its points, in the mesh's units (scaled by the joints'
    /// largest scale each frame).
    pub clearance: f32,
    /// Joint matrices a refit needs.
    pub joint_count: usize,
    /// The voxels along each axis of the bind-pose mesh's box.
    pub counts: UVec3,
}

/// Scratch memory a refit reuses from frame to frame: the skinned vertices, and one leaf's
/// points placed among them.
#[derive(Clone, Debug, Default)]
pub struct SkinScratch {
    skinned: Vec<Vec3A>,
    placed: Vec<Vec3A>,
}

impl SkinnedSpheres {
    /// Voxelises `mesh` in its bind pose into `voxels`, as [`voxel_spheres_in`] does, and keeps
    /// every sphere's points with `skin` so that the spheres can follow the joints. Returns the
    /// tree in the bind pose (identical to the static collider's) and what refits it.
    pub fn build(mesh: MeshRef<'_>, skin: SkinRef<'_>, voxels: Voxels) -> Result<(Lbvh, Self), ColliderError> {
        let spheres = voxel_spheres_in(mesh, voxels)?;
        check_skin(mesh, skin)?;
        let grid = VoxelGrid::new(spheres.mesh_min, spheres.mesh_max, spheres.counts);
        let keyed = keyed_points(mesh, &grid);
        let (lbvh, order) = Lbvh::build_with_order(&spheres.spheres);
        let LeafPoints { points, leaf_starts, used } = by_leaf(&keyed, &spheres, &order, mesh.positions.len())?;
        let vertices = SkinnedVertices {
            positions: used.iter().map(|&v| Vec3A::from(mesh.positions[v as usize])).collect(),
            joints: used.iter().map(|&v| skin.joints[v as usize]).collect(),
            weights: used.iter().map(|&v| skin.weights[v as usize]).collect(),
        };
        let clearance = SURFACE_CLEARANCE * grid.cell_diagonal();
        Ok((
            lbvh,
            Self { vertices, points, leaf_starts, clearance, joint_count: skin.joint_count, counts: spheres.counts },
        ))
    }

    /// Number of leaves (spheres) this refits.
    pub fn leaf_count(&self) -> usize {
        self.leaf_starts.len().saturating_sub(1)
    }

    /// Checks a pose for `lbvh` (the tree [`Self::build`] returned, or a refit of it) as
    /// [`Self::refit`] does, and returns the clearance the spheres get at that pose: the build's,
    /// grown by the largest scale any joint applies. A refit on the GPU checks the pose with
    /// this first.
    pub fn check_pose(&self, joint_matrices: &[Affine3A], lbvh: &Lbvh) -> Result<f32, ColliderError> {
        if joint_matrices.len() < self.joint_count {
            return Err(ColliderError::MissingJoints { joints: joint_matrices.len(), needed: self.joint_count });
        }
        let matrices = &joint_matrices[..self.joint_count];
        if let Some(joint) = matrices.iter().position(|m| !m.is_finite()) {
            return Err(ColliderError::NonFiniteJoint { joint });
        }
        if lbvh.spheres.len() != self.leaf_count() {
            return Err(ColliderError::SkinTreeMismatch { leaves: lbvh.spheres.len(), expected: self.leaf_count() });
        }
        let scale = matrices.iter().map(largest_scale).fold(0.0f32, f32::max);
        Ok(self.clearance * scale.max(f32::MIN_POSITIVE))
    }

    /// Moves `lbvh`'s spheres to the pose `joint_matrices` gives (each joint's world transform
    /// times its inverse bind pose, as Bevy's renderer forms them), into world coordinates, and
    /// refits its boxes. `lbvh` must be the tree [`Self::build`] returned (or a refit of it).
    ///
    /// Fewer matrices than the skin's joints, or a matrix that is not finite, is refused and
    /// leaves `lbvh` as it was.
    pub fn refit(
        &self,
        joint_matrices: &[Affine3A],
        lbvh: &mut Lbvh,
        scratch: &mut SkinScratch,
    ) -> Result<(), ColliderError> {
        let clearance = self.check_pose(joint_matrices, lbvh)?;
        let matrices = &joint_matrices[..self.joint_count];
        self.vertices.skin_into(matrices, &mut scratch.skinned);
        // Each leaf's points are placed into a small buffer and the sphere fitted from it while
        // it is still in cache (the fit reads them twice).
        let skinned = &scratch.skinned;
        let fit = |k: usize, placed: &mut Vec<Vec3A>| {
            let points = &self.points[self.leaf_starts[k] as usize..self.leaf_starts[k + 1] as usize];
            placed.clear();
            placed.extend(points.iter().map(|point| place(point, skinned)));
            fit_sphere(placed, clearance)
        };
        if self.points.len() >= PARALLEL_MIN {
            lbvh.spheres
                .par_iter_mut()
                .enumerate()
                .with_min_len(16)
                .for_each_init(Vec::new, |placed, (k, sphere)| *sphere = fit(k, placed));
        } else {
            let placed = &mut scratch.placed;
            lbvh.spheres.iter_mut().enumerate().for_each(|(k, sphere)| *sphere = fit(k, placed));
        }
        lbvh.refit();
        Ok(())
    }
}

/// The largest factor by which `transform` stretches any of its axes.
pub fn largest_scale(transform: &Affine3A) -> f32 {
    let axes = transform.matrix3;
    axes.x_axis.length().max(axes.y_axis.length()).max(axes.z_axis.length())
}

/// The point's position among the skinned vertices.
#[inline]
fn place(point: &SkinPoint, skinned: &[Vec3A]) -> Vec3A {
    let a = skinned[point.vertices[0] as usize];
    let [u, v] = point.weights;
    if u == 0.0 && v == 0.0 {
        // A vertex (or a triangle's corner): one read.
        return a;
    }
    let [b, c] = [1, 2].map(|k| skinned[point.vertices[k] as usize]);
    a + u * (b - a) + v * (c - a)
}

/// The smaller of the box-centre and centroid spheres around `points`, grown by `clearance`
/// (the rule [`crate::colliders::voxel_spheres`] fits by).
fn fit_sphere(points: &[Vec3A], clearance: f32) -> Sphere {
    let (mut lo, mut hi, mut sum) = (Vec3A::INFINITY, Vec3A::NEG_INFINITY, Vec3A::ZERO);
    for &p in points {
        lo = lo.min(p);
        hi = hi.max(p);
        sum += p;
    }
    let box_centre = 0.5 * (lo + hi);
    let centroid = sum / points.len().max(1) as f32;
    let (mut far_box, mut far_centroid) = (0.0f32, 0.0f32);
    for &p in points {
        far_box = far_box.max(p.distance_squared(box_centre));
        far_centroid = far_centroid.max(p.distance_squared(centroid));
    }
    let (centre, far) = if far_centroid < far_box { (centroid, far_centroid) } else { (box_centre, far_box) };
    Sphere::new(Vec3::from(centre), far.sqrt() + clearance)
}

/// Refuses a skin that does not match the mesh or that would place a vertex nowhere.
fn check_skin(mesh: MeshRef<'_>, skin: SkinRef<'_>) -> Result<(), ColliderError> {
    let vertices = mesh.positions.len();
    if skin.joints.len() != vertices || skin.weights.len() != vertices {
        return Err(ColliderError::SkinLength { vertices, joints: skin.joints.len(), weights: skin.weights.len() });
    }
    for (vertex, (joints, weights)) in skin.joints.iter().zip(skin.weights).enumerate() {
        if !weights.iter().all(|w| w.is_finite() && *w >= 0.0) || weights.iter().sum::<f32>() <= 0.0 {
            return Err(ColliderError::BadSkinWeights { vertex, weights: *weights });
        }
        if let Some((&joint, _)) =
            joints.iter().zip(weights).find(|&(&joint, &weight)| weight > 0.0 && joint as usize >= skin.joint_count)
        {
            return Err(ColliderError::JointOutOfRange { vertex, joint, joints: skin.joint_count });
        }
    }
    Ok(())
}

/// Every point the voxel spheres are fitted to, with its voxel: the used vertices, and the
/// corners of the parts of triangles that cross voxels (as [`crate::colliders::voxel_spheres`] visits
/// them), each on its triangle. Vertex indices are the mesh's.
fn keyed_points(mesh: MeshRef<'_>, grid: &VoxelGrid) -> Vec<(u32, SkinPoint)> {
    let positions = mesh.positions;
    let triangles: Vec<[u32; 3]> = match mesh.indices {
        Some(indices) => indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect(),
        None => (0..positions.len() as u32 / 3).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect(),
    };
    let key_of = |v: u32| grid.voxel_of(Vec3::from(positions[v as usize]));
    let mut used = vec![false; positions.len()];
    triangles.iter().flatten().for_each(|&v| used[v as usize] = true);
    let mut keyed: Vec<(u32, SkinPoint)> = (0..positions.len() as u32)
        .filter(|&v| used[v as usize])
        .map(|v| (key_of(v), SkinPoint { vertices: [v; 3], weights: [0.0; 2] }))
        .collect();
    if grid.is_single_voxel() {
        return keyed;
    }
    // The corners, with their positions, so that a corner two triangles share (where a grid
    // plane cuts their common edge) is kept once.
    let mut corners_found: Vec<(u32, [i64; 3], SkinPoint)> = Vec::new();
    // Quantised relative to the box's corner, so that the steps fit an integer anywhere: the
    // box spans at most 128 cells of 1e6 steps each per axis.
    let (origin, quantum) = (grid.min(), grid.cell_diagonal() * 1e-6);
    for &vertices in &triangles {
        let corners = vertices.map(|v| Vec3::from(positions[v as usize]));
        let keys = vertices.map(key_of);
        grid.for_each_piece(corners, |key, piece| {
            for &p in piece.corners() {
                // A corner that is one of the triangle's vertices, in that vertex's own voxel, is
                // among the voxel's points already.
                if (0..3).any(|k| corners[k] == p && keys[k] == key) {
                    continue;
                }
                let step = corner_step(p, origin, quantum);
                corners_found.push((key, step, SkinPoint { vertices, weights: barycentric(p, corners) }));
            }
        });
    }
    corners_found.sort_unstable_by_key(|&(key, step, _)| (key, step));
    corners_found.dedup_by_key(|&mut (key, step, _)| (key, step));
    keyed.extend(corners_found.into_iter().map(|(key, _, point)| (key, point)));
    keyed
}

/// `p`'s position in steps of `quantum` from `origin`, the key corners are merged by.
fn corner_step(p: Vec3, origin: Vec3, quantum: f32) -> [i64; 3] {
    ((p - origin) / quantum).round().to_array().map(|c| c as i64)
}

/// The barycentric weights of the second and third corner for a point `p` of the triangle; on a
/// degenerate triangle, `p`'s place along its longest edge.
fn barycentric(p: Vec3, [a, b, c]: [Vec3; 3]) -> [f32; 2] {
    let (e1, e2, d) = (b - a, c - a, p - a);
    let (d11, d12, d22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let denominator = d11 * d22 - d12 * d12;
    if denominator > 1e-10 * d11 * d22 {
        let (d1, d2) = (d.dot(e1), d.dot(e2));
        let u = ((d22 * d1 - d12 * d2) / denominator).clamp(0.0, 1.0);
        let v = ((d11 * d2 - d12 * d1) / denominator).clamp(0.0, 1.0 - u);
        return [u, v];
    }
    // Collinear corners: the point lies on the longest edge.
    let along = |from: Vec3, to: Vec3| {
        let edge = to - from;
        let length2 = edge.length_squared();
        if length2 > 0.0 { ((p - from).dot(edge) / length2).clamp(0.0, 1.0) } else { 0.0 }
    };
    let bc = (c - b).length_squared();
    if d11 >= d22 && d11 >= bc {
        [along(a, b), 0.0]
    } else if d22 >= bc {
        [0.0, along(a, c)]
    } else {
        let t = along(b, c);
        [1.0 - t, t]
    }
}

/// Groups the points by leaf (in `order`, the tree's leaf order of the spheres) and renumbers
/// their vertices densely. Returns the points, each leaf's start, and the mesh vertex of each
/// new index.
fn by_leaf(
    keyed: &[(u32, SkinPoint)],
    spheres: &VoxelSpheres,
    order: &[u32],
    vertex_count: usize,
) -> Result<LeafPoints, ColliderError> {
    let mut leaf_of_sphere = vec![0u32; order.len()];
    for (leaf, &sphere) in order.iter().enumerate() {
        leaf_of_sphere[sphere as usize] = leaf as u32;
    }
    // Every point's voxel holds a sphere: the spheres were fitted to these very points.
    let leaf_of = |key: u32| spheres.voxels.binary_search(&key).ok().map(|s| leaf_of_sphere[s]);
    let mismatch = ColliderError::SkinTreeMismatch { leaves: order.len(), expected: spheres.spheres.len() };
    let mut leaves = Vec::with_capacity(keyed.len());
    for &(key, _) in keyed {
        leaves.push(leaf_of(key).ok_or(mismatch.clone())?);
    }
    let mut leaf_starts = vec![0u32; order.len() + 1];
    leaves.iter().for_each(|&leaf| leaf_starts[leaf as usize + 1] += 1);
    for k in 1..leaf_starts.len() {
        leaf_starts[k] += leaf_starts[k - 1];
    }
    let mut next = leaf_starts.clone();
    let mut renumber = vec![u32::MAX; vertex_count];
    let mut used = Vec::new();
    let mut points = vec![SkinPoint::default(); keyed.len()];
    for (&(_, point), &leaf) in keyed.iter().zip(&leaves) {
        let vertices = point.vertices.map(|v| {
            let slot = &mut renumber[v as usize];
            if *slot == u32::MAX {
                *slot = used.len() as u32;
                used.push(v);
            }
            *slot
        });
        points[next[leaf as usize] as usize] = SkinPoint { vertices, ..point };
        next[leaf as usize] += 1;
    }
    Ok(LeafPoints { points, leaf_starts, used })
}

/// The points grouped by leaf, and the mesh vertex of each of their (renumbered) vertices.
struct LeafPoints {
    points: Vec<SkinPoint>,
    leaf_starts: Vec<u32>,
    used: Vec<u32>,
}

#[cfg(test)]
mod tests {
    use glam::{Quat, Vec3};

    use super::*;
    use crate::colliders::collider::Collider;

    /// A closed tube along y from 0 to `height`, `rings x slices`, its lower half on joint 0,
    /// its upper half on joint 1, blended across the middle.
    /// Positions, indices, joints and weights.
    type Tube = (Vec<[f32; 3]>, Vec<u32>, Vec<[u16; 4]>, Vec<[f32; 4]>);

    fn tube(rings: u32, slices: u32, height: f32) -> Tube {
        let mut positions = Vec::new();
        let mut joints = Vec::new();
        let mut weights = Vec::new();
        for i in 0..=rings {
            let y = height * i as f32 / rings as f32;
            let upper = ((y / height - 0.4) / 0.2).clamp(0.0, 1.0);
            for j in 0..slices {
                let angle = std::f32::consts::TAU * j as f32 / slices as f32;
                positions.push([0.2 * angle.cos(), y, 0.2 * angle.sin()]);
                joints.push([0, 1, 0, 0]);
                weights.push([1.0 - upper, upper, 0.0, 0.0]);
            }
        }
        let mut indices = Vec::new();
        for i in 0..rings {
            for j in 0..slices {
                let a = i * slices + j;
                let b = i * slices + (j + 1) % slices;
                let (c, d) = (a + slices, b + slices);
                indices.extend_from_slice(&[a, c, b, b, c, d]);
            }
        }
        (positions, indices, joints, weights)
    }

    fn build(n: u32) -> (Tube, Lbvh, SkinnedSpheres) {
        let (positions, indices, joints, weights) = tube(24, 16, 1.0);
        let mesh = MeshRef { positions: &positions, indices: Some(&indices) };
        let skin = SkinRef { joints: &joints, weights: &weights, joint_count: 2 };
        let (lbvh, skinned) = SkinnedSpheres::build(mesh, skin, Voxels::PerAxis(n)).unwrap();
        ((positions, indices, joints, weights), lbvh, skinned)
    }

    #[test]
    fn the_bind_pose_tree_is_the_static_colliders() {
        let ((positions, indices, ..), lbvh, skinned) = build(6);
        let fixed = Collider::from_mesh(MeshRef { positions: &positions, indices: Some(&indices) }, 6).unwrap();
        assert_eq!(lbvh.spheres, fixed.lbvh().unwrap().spheres);
        // Refitted at the identity pose, every sphere is the static one, but for the centroid
        // candidate: the refit counts a corner two triangles share once, the static fit twice.
        let mut refitted = lbvh.clone();
        skinned.refit(&[Affine3A::IDENTITY; 2], &mut refitted, &mut SkinScratch::default()).unwrap();
        let diagonal = (Vec3::new(0.4, 1.0, 0.4) / 6.0).length();
        for (a, b) in refitted.spheres.iter().zip(&lbvh.spheres) {
            let (moved, grew) = (a.centre().distance(b.centre()), (a.radius - b.radius).abs());
            assert!(moved < 0.05 * diagonal && grew < 0.05 * diagonal, "{a:?} vs {b:?}");
        }
        assert_eq!(refitted.nodes.len(), lbvh.nodes.len());
    }

    #[test]
    fn a_rigid_pose_moves_every_sphere_rigidly() {
        let (_, lbvh, skinned) = build(5);
        let pose = Affine3A::from_rotation_translation(Quat::from_rotation_z(0.7), Vec3::new(1.0, -2.0, 0.5));
        let (mut rest, mut moved) = (lbvh.clone(), lbvh.clone());
        skinned.refit(&[Affine3A::IDENTITY; 2], &mut rest, &mut SkinScratch::default()).unwrap();
        skinned.refit(&[pose; 2], &mut moved, &mut SkinScratch::default()).unwrap();
        for (a, b) in moved.spheres.iter().zip(&rest.spheres) {
            assert!(a.centre().distance(pose.transform_point3(b.centre())) < 1e-5);
            assert!((a.radius - b.radius).abs() < 1e-5);
        }
        let (lo, hi) = moved.bounds().unwrap();
        for s in &moved.spheres {
            assert!(s.centre().cmpge(lo + s.radius - 1e-5).all() && s.centre().cmple(hi - s.radius + 1e-5).all());
        }
    }

    /// Bent 90 degrees at the middle, every point of every skinned triangle (the surface a
    /// renderer draws) is inside the refitted collider, found through the refitted tree.
    #[test]
    fn a_bent_tube_stays_covered() {
        let ((positions, indices, joints, weights), lbvh, skinned) = build(8);
        let bend = Affine3A::from_translation(Vec3::new(0.0, 0.5, 0.0))
            * Affine3A::from_rotation_z(std::f32::consts::FRAC_PI_2)
            * Affine3A::from_translation(Vec3::new(0.0, -0.5, 0.0));
        let matrices = [Affine3A::from_translation(Vec3::new(0.3, 0.0, 0.0)), bend];
        let mut moved = lbvh.clone();
        skinned.refit(&matrices, &mut moved, &mut SkinScratch::default()).unwrap();
        let vertices =
            SkinnedVertices { positions: positions.iter().map(|&p| Vec3A::from(p)).collect(), joints, weights };
        let mut skinned_positions = Vec::new();
        vertices.skin_into(&matrices, &mut skinned_positions);
        let collider = Collider::from_tree(moved, glam::UVec3::splat(8));
        let (mut samples, mut moved_far) = (0, 0);
        for t in indices.chunks_exact(3) {
            let [a, b, c] = [0, 1, 2].map(|k| Vec3::from(skinned_positions[t[k] as usize]));
            for (u, v) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (0.33, 0.33), (0.5, 0.5), (0.1, 0.8), (0.7, 0.1)] {
                let p = a + u * (b - a) + v * (c - a);
                assert!(collider.contains(p), "{p} of the skinned surface is outside the collider");
                samples += 1;
                let rest = Vec3::from(positions[t[0] as usize]);
                moved_far += usize::from(p.distance(rest) > 0.3);
            }
        }
        assert!(moved_far > samples / 3, "the pose must move much of the surface: {moved_far} of {samples}");
    }

    #[test]
    fn bad_skins_and_poses_are_refused() {
        let (positions, indices, joints, weights) = tube(4, 6, 1.0);
        let mesh = MeshRef { positions: &positions, indices: Some(&indices) };
        let short = SkinRef { joints: &joints[1..], weights: &weights, joint_count: 2 };
        assert!(matches!(
            SkinnedSpheres::build(mesh, short, Voxels::PerAxis(3)),
            Err(ColliderError::SkinLength { .. })
        ));
        let one_joint = SkinRef { joints: &joints, weights: &weights, joint_count: 1 };
        assert!(matches!(
            SkinnedSpheres::build(mesh, one_joint, Voxels::PerAxis(3)),
            Err(ColliderError::JointOutOfRange { joint: 1, joints: 1, .. })
        ));
        let mut nan = weights.clone();
        nan[3][0] = f32::NAN;
        let bad = SkinRef { joints: &joints, weights: &nan, joint_count: 2 };
        assert!(matches!(
            SkinnedSpheres::build(mesh, bad, Voxels::PerAxis(3)),
            Err(ColliderError::BadSkinWeights { vertex: 3, .. })
        ));
        let mut zero = weights.clone();
        zero[5] = [0.0; 4];
        let bad = SkinRef { joints: &joints, weights: &zero, joint_count: 2 };
        assert!(matches!(
            SkinnedSpheres::build(mesh, bad, Voxels::PerAxis(3)),
            Err(ColliderError::BadSkinWeights { vertex: 5, .. })
        ));

        let skin = SkinRef { joints: &joints, weights: &weights, joint_count: 2 };
        let (lbvh, skinned) = SkinnedSpheres::build(mesh, skin, Voxels::PerAxis(3)).unwrap();
        let mut tree = lbvh.clone();
        let mut scratch = SkinScratch::default();
        assert!(matches!(
            skinned.refit(&[Affine3A::IDENTITY], &mut tree, &mut scratch),
            Err(ColliderError::MissingJoints { joints: 1, needed: 2 })
        ));
        let nan = Affine3A::from_translation(Vec3::NAN);
        assert!(matches!(
            skinned.refit(&[Affine3A::IDENTITY, nan], &mut tree, &mut scratch),
            Err(ColliderError::NonFiniteJoint { joint: 1 })
        ));
        assert_eq!(tree.spheres, lbvh.spheres, "a refused pose leaves the tree as it was");
        for message in [
            ColliderError::MissingJoints { joints: 1, needed: 2 }.to_string(),
            ColliderError::NonFiniteJoint { joint: 1 }.to_string(),
        ] {
            assert!(message.contains("joint"), "{message}");
        }
    }

    /// Corners are merged by their step relative to the mesh's box, so that points a hair apart
    /// stay apart on a mesh 10 km from the origin, and equal points merge.
    #[test]
    fn corner_steps_stay_distinct_far_from_the_origin() {
        let origin = Vec3::new(1.0e4, -1.0e4, 5.0e3);
        let p = origin + Vec3::new(0.25, 0.5, 0.125);
        let quantum = 1.0e-7;
        assert_eq!(corner_step(p, origin, quantum), corner_step(p, origin, quantum));
        assert_ne!(corner_step(p, origin, quantum), corner_step(p + Vec3::new(0.0, 2.0e-3, 0.0), origin, quantum));
    }

    #[test]
    fn barycentric_weights_place_the_point() {
        let tri = [Vec3::ZERO, Vec3::X, Vec3::Y];
        assert_eq!(barycentric(Vec3::new(0.25, 0.5, 0.0), tri), [0.25, 0.5]);
        // Degenerate: all on the x axis; the point lies on the longest edge, a to c.
        let flat = [Vec3::ZERO, Vec3::X, Vec3::new(2.0, 0.0, 0.0)];
        let [u, v] = barycentric(Vec3::new(1.5, 0.0, 0.0), flat);
        let p = flat[0] + u * (flat[1] - flat[0]) + v * (flat[2] - flat[0]);
        assert!(p.distance(Vec3::new(1.5, 0.0, 0.0)) < 1e-6, "{p}");
        assert_eq!(barycentric(Vec3::ONE, [Vec3::ONE; 3]), [0.0, 0.0]);
    }
}
