//! The buffer layouts the GPU kernels use (paper Table II), defined once here and mirrored
//! field for field in WGSL (`bvh_cloth_gpu`'s `cloth.wgsl`, whose tests compare the two).
//! [`crate::BvhNode`] and [`crate::Sphere`] are uploaded unchanged.

use bytemuck::{Pod, Zeroable};
use glam::{Affine3A, Mat4, Vec3};

use crate::collider::Collider;
use crate::collision::ColliderFrame;
use crate::forces::ForceModel;
use crate::params::ClothParams;
use crate::sim::ClothSim;
use crate::topology::ClothTopology;

/// One particle: position and velocity in world space. 32 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuParticle {
    /// `xyz`: position; `w`: 1 for a free particle, 0 for a pinned one.
    pub position: [f32; 4],
    /// `xyz`: velocity; `w`: unused.
    pub velocity: [f32; 4],
}

/// The simulation constants of one cloth for one frame (a uniform). 64 bytes.
///
/// The cloth's shape is in two storage buffers of `u32` words, laid out by
/// [`gpu_topology_words`] and [`gpu_surface_words`].
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuClothParams {
    /// Number of particles.
    pub particle_count: u32,
    /// Number of render vertices `normal_shader` writes.
    pub vertex_count: u32,
    /// Number of [`GpuCollider`]s to test.
    pub collider_count: u32,
    /// Threads along `x` of every dispatch (workgroups along `x` times 64): a thread's index is
    /// `y * dispatch_width + x`.
    pub dispatch_width: u32,
    /// Substep length in seconds.
    pub h: f32,
    /// Damping rate in 1/s.
    pub damping: f32,
    /// Number of pinned particles `apply_anchors` moves each tick.
    pub anchor_count: u32,
    /// Padding.
    pub _pad: u32,
    /// `scale * spring_k / mass` for structural, shear and bending springs; `w` unused.
    pub k_over_mass: [f32; 4],
    /// Gravity plus the external force per unit mass; `w` unused.
    pub uniform_accel: [f32; 4],
}

impl GpuClothParams {
    /// The constants of a cloth with `params` on `topology` and `anchor_count` pins, for
    /// substeps of `h` seconds against `collider_count` colliders, dispatched `dispatch_width`
    /// threads wide.
    pub fn new(
        params: &ClothParams,
        topology: &ClothTopology,
        anchor_count: u32,
        h: f32,
        collider_count: u32,
        dispatch_width: u32,
    ) -> Self {
        let model = ForceModel::new(params);
        let [s, sh, b] = model.k_over_mass;
        Self {
            particle_count: topology.len() as u32,
            vertex_count: topology.vertex_particle().len() as u32,
            collider_count,
            dispatch_width,
            h,
            damping: model.damping,
            anchor_count,
            k_over_mass: [s, sh, b, 0.0],
            uniform_accel: model.uniform_accel.extend(0.0).to_array(),
            ..Zeroable::zeroed()
        }
    }
}

/// What `node_update` reads of a cloth's shape, as `u32` words: the `N + 1` spring offsets of
/// [`ClothTopology::spring_offsets`], then the `N` inverse mass shares (`f32` bits), then every
/// [`crate::topology::SpringEnd`] as four words.
pub fn gpu_topology_words(topology: &ClothTopology) -> Vec<u32> {
    let mut words = Vec::with_capacity(2 * topology.len() + 1 + 4 * topology.spring_ends().len());
    words.extend_from_slice(topology.spring_offsets());
    words.extend(topology.inv_mass_share().iter().map(|s| s.to_bits()));
    words.extend_from_slice(bytemuck::cast_slice(topology.spring_ends()));
    words
}

/// What `normal_shader` reads of a cloth's surface, as `u32` words: the particle of each of
/// the `V` render vertices, then the `N + 1` triangle offsets of
/// [`ClothTopology::triangle_offsets`], then the triangle list, then the triangles' corners
/// (three words each).
pub fn gpu_surface_words(topology: &ClothTopology) -> Vec<u32> {
    let mut words =
        Vec::with_capacity(topology.vertex_particle().len() + topology.len() + 1 + 4 * topology.triangles().len());
    words.extend_from_slice(topology.vertex_particle());
    words.extend_from_slice(topology.triangle_offsets());
    words.extend_from_slice(topology.triangle_list());
    words.extend(topology.triangles().iter().flatten());
    words
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
/// of `f32` words (a mesh's vertex slab), in the frame of the cloth's entity. 144 bytes. Vertex
/// `v` shows particle `vertex_particle[v]` (see [`gpu_surface_words`]).
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

/// The particles of `sim` in GPU layout: `position.w` is 1 for a free particle and 0 for a
/// held one.
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
        assert_eq!(size_of::<GpuClothParams>(), 64);
        assert_eq!(size_of::<GpuCollider>(), 176);
        assert_eq!(size_of::<GpuMeshWriteback>(), 144);
    }
}
