//! The buffer layouts the GPU kernels use (paper Table II), defined once here and mirrored
//! field for field in WGSL (`bvh_cloth_gpu`'s `cloth.wgsl`, whose tests compare the two).
//! [`crate::BvhNode`] and [`crate::Sphere`] are uploaded unchanged.

use bytemuck::{Pod, Zeroable};
use glam::{Affine3A, Mat4, Vec3};

use crate::collider::Collider;
use crate::collision::ColliderFrame;
use crate::forces::ForceModel;
use crate::grid::ClothGrid;
use crate::params::ClothParams;
use crate::sim::ClothSim;

/// One particle: position and velocity in world space. 32 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuParticle {
    /// `xyz`: position; `w`: 1 for a free particle, 0 for a pinned one.
    pub position: [f32; 4],
    /// `xyz`: velocity; `w`: unused.
    pub velocity: [f32; 4],
}

/// The simulation constants of one cloth for one frame (a uniform). 80 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuClothParams {
    /// Particle rows.
    pub rows: u32,
    /// Particle columns.
    pub cols: u32,
    /// Number of [`GpuCollider`]s to test.
    pub collider_count: u32,
    /// Padding.
    pub _pad0: u32,
    /// Substep length in seconds.
    pub h: f32,
    /// Damping rate in 1/s.
    pub damping: f32,
    /// Padding.
    pub _pad1: [f32; 2],
    /// `scale * spring_k / m` for structural, shear and bending springs; `w` unused.
    pub k_over_m: [f32; 4],
    /// Rest lengths of the three kinds; `w` unused.
    pub rest: [f32; 4],
    /// Gravity plus the external force per unit mass; `w` unused.
    pub uniform_accel: [f32; 4],
}

impl GpuClothParams {
    /// The constants of a cloth with `params` on `grid`, for substeps of `h` seconds against
    /// `collider_count` colliders.
    pub fn new(params: &ClothParams, grid: &ClothGrid, h: f32, collider_count: u32) -> Self {
        let model = ForceModel::new(params, grid);
        let [s, sh, b] = model.k_over_m;
        let [rs, rsh, rb] = model.rest;
        Self {
            rows: grid.rows as u32,
            cols: grid.cols as u32,
            collider_count,
            h,
            damping: model.damping,
            k_over_m: [s, sh, b, 0.0],
            rest: [rs, rsh, rb, 0.0],
            uniform_accel: model.uniform_accel.extend(0.0).to_array(),
            ..Zeroable::zeroed()
        }
    }
}

/// One collider's frame and where its tree lies in the shared node and sphere arrays.
/// 176 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuCollider {
    /// World to collider-local transform, column-major.
    pub local_from_world: [[f32; 4]; 4],
    /// Collider-local to world transform, column-major.
    pub world_from_local: [[f32; 4]; 4],
    /// The collider's rotation as a quaternion `xyzw` (turns local normals into world ones).
    pub rotation: [f32; 4],
    /// The margin in local units.
    pub margin_local: f32,
    /// The Coulomb friction coefficient.
    pub friction: f32,
    /// Index of the collider's root in the node array.
    pub node_offset: u32,
    /// Index of its first sphere in the sphere array.
    pub sphere_offset: u32,
    /// Number of inner nodes (0 for a single-sphere collider).
    pub node_count: u32,
    /// Number of spheres.
    pub sphere_count: u32,
    /// How far beyond a node's box a contact can be (see [`ColliderFrame::contact_reach`]).
    pub contact_reach: f32,
    /// Padding.
    pub _pad: u32,
}

impl GpuCollider {
    /// The frame of `collider`, whose tree starts at the given offsets; `None` when the collider
    /// cannot be used (see [`ColliderFrame::new`]).
    pub fn new(collider: &Collider, node_offset: u32, sphere_offset: u32) -> Option<Self> {
        let frame = ColliderFrame::new(collider)?;
        let world_from_local = collider.pose.to_affine();
        let mat = |a: Affine3A| Mat4::from(a).to_cols_array_2d();
        Some(Self {
            local_from_world: mat(world_from_local.inverse()),
            world_from_local: mat(world_from_local),
            rotation: collider.pose.rotation.normalize().to_array(),
            margin_local: frame.margin_local,
            friction: frame.friction,
            node_offset,
            sphere_offset,
            node_count: collider.lbvh.nodes.len() as u32,
            sphere_count: collider.lbvh.spheres.len() as u32,
            contact_reach: frame.contact_reach,
            _pad: 0,
        })
    }
}

/// Where `normal_shader` writes a cloth's positions and normals: an interleaved vertex buffer
/// of `f32` words (a mesh's vertex slab), in the frame of the cloth's entity. 144 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuMeshWriteback {
    /// World to mesh-local transform for positions, column-major.
    pub local_from_world: [[f32; 4]; 4],
    /// World to mesh-local transform for normals (the transpose of the local-to-world linear
    /// part), column-major; its translation is unused.
    pub normal_from_world: [[f32; 4]; 4],
    /// Index, in words, of the first vertex's first word.
    pub first_word: u32,
    /// Words per vertex.
    pub stride_words: u32,
    /// Word offset of the position inside a vertex.
    pub position_word: u32,
    /// Word offset of the normal inside a vertex.
    pub normal_word: u32,
}

impl GpuMeshWriteback {
    /// Positions and normals written for a mesh placed in the world by `mesh_to_world`, into a
    /// vertex buffer whose vertices start at word `first_word` and are `stride_words` long.
    pub fn new(
        mesh_to_world: Affine3A,
        first_word: u32,
        stride_words: u32,
        position_word: u32,
        normal_word: u32,
    ) -> Self {
        let normal = Affine3A::from_mat3(mesh_to_world.matrix3.transpose().into());
        Self {
            local_from_world: Mat4::from(mesh_to_world.inverse()).to_cols_array_2d(),
            normal_from_world: Mat4::from(normal).to_cols_array_2d(),
            first_word,
            stride_words,
            position_word,
            normal_word,
        }
    }
}

/// The particles of `sim` in GPU layout.
pub fn gpu_particles(sim: &ClothSim) -> Vec<GpuParticle> {
    (0..sim.len())
        .map(|i| GpuParticle {
            position: sim.position(i).extend(if sim.is_pinned(i) { 0.0 } else { 1.0 }).to_array(),
            velocity: sim.velocity(i).extend(0.0).to_array(),
        })
        .collect()
}

/// Writes GPU particles back into `sim` (positions and velocities).
pub fn load_gpu_particles(sim: &mut ClothSim, particles: &[GpuParticle]) {
    for (i, p) in particles.iter().enumerate().take(sim.len()) {
        sim.set_position(i, Vec3::from_slice(&p.position[..3]));
        sim.set_velocity(i, Vec3::from_slice(&p.velocity[..3]));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_are_multiples_of_sixteen() {
        assert_eq!(size_of::<GpuParticle>(), 32);
        assert_eq!(size_of::<GpuClothParams>(), 80);
        assert_eq!(size_of::<GpuCollider>(), 176);
        assert_eq!(size_of::<GpuMeshWriteback>(), 144);
    }
}
