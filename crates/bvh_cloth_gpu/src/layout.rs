//! The buffer layouts the GPU kernels use (paper Table II), defined once here and mirrored
//! field for field in WGSL (`bvh_cloth_gpu`'s `types.wgsl`, whose tests compare the two).
//! [`bvh_cloth_core::BvhNode`] and [`bvh_cloth_core::Sphere`] are uploaded unchanged.

use std::borrow::Cow;

use bytemuck::{Pod, Zeroable};
use glam::{Affine3A, Mat4, Vec3};

use bvh_cloth_core::ClothSim;
use bvh_cloth_core::ClothTopology;
use bvh_cloth_core::Lbvh;
use bvh_cloth_core::backend::AirModel;
use bvh_cloth_core::backend::ColliderFrame;
use bvh_cloth_core::backend::ForceModel;
use bvh_cloth_core::backend::SkinnedVertices;
use bvh_cloth_core::backend::TetherSet;
use bvh_cloth_core::{ClothParams, Integrator};
use bvh_cloth_core::{Collider, ColliderShape};

/// One particle: position and velocity in world space. 32 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuParticle {
    /// `xyz`: position; `w`: 1 for a free particle, 0 for a pinned one.
    pub position: [f32; 4],
    /// `xyz`: velocity; `w`: 1 where a collider touched the particle in the last substep's
    /// collision response, else 0 (the kernels write it; self-contact reads it).
    pub velocity: [f32; 4],
}

/// Marks a particle slot of the batched buffers that belongs to no cloth.
pub const NO_CLOTH: u32 = u32::MAX;

/// [`GpuBatchCloth::integrator`] of fourth-order Runge–Kutta.
pub const INTEGRATOR_RK4: u32 = 0;
/// [`GpuBatchCloth::integrator`] of semi-implicit Euler.
pub const INTEGRATOR_EULER: u32 = 1;
/// [`GpuBatchCloth::integrator`] of block descent. It and [`INTEGRATOR_MULTIGRID`] run the
/// block-descent kernels; the integrators below it the explicit ones.
pub const INTEGRATOR_BLOCK_DESCENT: u32 = 2;
/// [`GpuBatchCloth::integrator`] of the multigrid integrator: block descent's kernels with one
/// sweep, BDF2 and the multigrid correction (`multigrid.wgsl`).
pub const INTEGRATOR_MULTIGRID: u32 = 3;

/// One cloth of a batch: where its data lies in the shared buffers, and its constants for the
/// coming ticks. An array of these is one storage buffer. 128 bytes; the host writes the
/// first [`Self::HOST_BYTES`], up to the count of quarantined particles, which the kernels add
/// to and the host reads and clears; the drift and the multigrid integrator's step and history
/// flag follow, which the kernels write (the host sets the flag when it replaces a state).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuBatchCloth {
    /// `scale * spring_k / mass` for structural, shear and bending springs; `w` unused.
    pub k_over_mass: [f32; 4],
    /// Gravity plus the external force per unit mass; `w` unused.
    pub uniform_accel: [f32; 4],
    /// Index of the cloth's first particle in the particle buffers.
    pub particle_start: u32,
    /// Number of particles.
    pub particle_count: u32,
    /// Index of the cloth's first spring end in the spring-end buffer.
    pub ends_start: u32,
    /// Substeps per tick: the cloth sits out the batch's substeps past this count.
    pub substeps: u32,
    /// Substep length in seconds.
    pub h: f32,
    /// Damping rate in 1/s.
    pub damping: f32,
    /// [`INTEGRATOR_RK4`], [`INTEGRATOR_EULER`] or [`INTEGRATOR_BLOCK_DESCENT`].
    pub integrator: u32,
    /// Block-descent sweeps per substep (0 for the explicit integrators).
    pub iterations: u32,
    /// [`bvh_cloth_core::SelfContact::thickness`], or 0 for a cloth without self-contact.
    pub contact_thickness: f32,
    /// [`bvh_cloth_core::SelfContact::friction`].
    pub contact_friction: f32,
    /// 1 when no particle with mass is pinned (block descent then keeps the cloth's momentum:
    /// `bvh_cloth_core::solver::block_descent`), else 0.
    pub free_body: u32,
    /// Where the cloth's tethers start in the spring-end buffer, after its springs: one entry
    /// per particle (see [`gpu_tether_ends`]); meaningless while `tether_scale` is 0.
    pub tether_start: u32,
    /// `1 + slack` of the cloth's [`bvh_cloth_core::Tethers`], or 0 when it has none (no pin, block
    /// descent not its integrator, or [`ClothParams::tethers`] `None`).
    pub tether_scale: f32,
    /// The layers the cloth is a member of ([`ClothParams::layers`]).
    pub memberships: u32,
    /// The layers whose colliders and cloths it collides with ([`ClothParams::layers`]).
    pub filters: u32,
    /// Particles quarantined since the host last cleared this word.
    pub faults: u32,
    /// Block descent's drift of the centre of mass in this substep (`xyz`, metres), which the
    /// kernels compute and read; the host never writes it.
    pub drift: [f32; 4],
    /// The multigrid integrator's substep length in seconds (`h`, `2h/3` for a BDF2 substep,
    /// `(1 - θ/3) h` for a blended one), which `mg_begin` writes in every substep; the host
    /// never writes it.
    pub step: f32,
    /// Nonzero when BDF2 may not build on the cloth's last substep: a collider or the
    /// quarantine moved a particle in it (`vbd_finish` sets it), or the host replaced its state
    /// or its substep length; `mg_begin` clears it.
    pub broken: u32,
    /// 1 when the multigrid integrator's substep blends BDF2 with implicit Euler
    /// (`bvh_cloth_core::backend::BLEND_LAG`), which `mg_begin` writes; the host never writes
    /// it.
    pub blend: u32,
    /// Unused.
    pub pad: u32,
}

impl GpuBatchCloth {
    /// Bytes of a [`GpuBatchCloth`] the host writes: everything up to the fault count.
    pub const HOST_BYTES: u64 = 92;

    /// Where [`Self::broken`] lies in the struct, in bytes.
    pub const BROKEN_OFFSET: u64 = core::mem::offset_of!(GpuBatchCloth, broken) as u64;

    /// The constants of a cloth with `params` on `topology`, whose particles and spring ends
    /// start at the given indices, for `substeps` substeps of `h` seconds per tick (as a held
    /// cloth: set [`Self::free_body`] for one that nothing holds).
    pub fn new(
        params: &ClothParams,
        topology: &ClothTopology,
        particle_start: u32,
        ends_start: u32,
        substeps: u32,
        h: f32,
    ) -> Self {
        let model = ForceModel::new(params);
        let [s, sh, b] = model.k_over_mass;
        Self {
            k_over_mass: [s, sh, b, 0.0],
            uniform_accel: model.uniform_accel.extend(0.0).to_array(),
            particle_start,
            particle_count: topology.len() as u32,
            ends_start,
            substeps,
            h,
            damping: model.damping,
            integrator: match params.integrator {
                Integrator::Rk4 => INTEGRATOR_RK4,
                Integrator::SemiImplicitEuler => INTEGRATOR_EULER,
                Integrator::BlockDescent { .. } => INTEGRATOR_BLOCK_DESCENT,
                Integrator::Multigrid => INTEGRATOR_MULTIGRID,
            },
            iterations: match params.integrator {
                Integrator::BlockDescent { iterations } => iterations,
                Integrator::Multigrid => 1,
                _ => 0,
            },
            contact_thickness: params.self_contact.map_or(0.0, |c| c.thickness),
            contact_friction: params.self_contact.map_or(0.0, |c| c.friction),
            free_body: 0,
            tether_start: 0,
            tether_scale: 0.0,
            memberships: params.layers.memberships,
            filters: params.layers.filters,
            faults: 0,
            drift: [0.0; 4],
            step: h,
            broken: 1,
            blend: 0,
            pad: 0,
        }
    }
}

/// One cloth's aerodynamics as the air kernels read it (an array of these is one storage
/// buffer, indexed like the [`GpuBatchCloth`] array). 48 bytes. A cloth with zero `drag` and
/// `lift` is left out of the air kernels.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuAirCloth {
    /// Where the cloth's surface (see [`gpu_surface_words`]) starts in the surface buffer.
    pub surface_start: u32,
    /// The cloth's render vertices: the surface's first `vertex_count` words.
    pub vertex_count: u32,
    /// [`AirModel::seed`].
    pub seed: u32,
    /// Wind sources in the source buffer.
    pub source_count: u32,
    /// [`AirModel::turbulence`].
    pub turbulence: f32,
    /// [`AirModel::inv_scale`].
    pub inv_scale: f32,
    /// [`AirModel::drag`].
    pub drag: f32,
    /// [`AirModel::lift`].
    pub lift: f32,
    /// Where the cloth's triangles' forces start in the air kernels' state buffer (which holds
    /// the wind at every particle slot first, then the triangles' forces).
    pub triangle_start: u32,
    /// The cloth's triangles.
    pub triangle_count: u32,
    /// Padding.
    pub _pad: [u32; 2],
}

impl GpuAirCloth {
    /// The constants of a cloth with the air `model` on `topology`, whose surface starts at
    /// `surface_start` and whose triangles' forces start at `triangle_start`, among
    /// `source_count` wind sources.
    pub fn new(
        model: &AirModel,
        topology: &ClothTopology,
        surface_start: u32,
        triangle_start: u32,
        source_count: u32,
    ) -> Self {
        Self {
            triangle_start,
            triangle_count: topology.triangles().len() as u32,
            _pad: [0; 2],
            surface_start,
            vertex_count: topology.vertex_particle().len() as u32,
            seed: model.seed,
            source_count,
            turbulence: model.turbulence,
            inv_scale: model.inv_scale,
            drag: model.drag,
            lift: model.lift,
        }
    }

    /// One tick's word of the cloth in the air kernels' tick buffer: the ambient wind (gusts
    /// included) and the turbulence's lattice time.
    pub fn tick_word(model: &AirModel) -> [f32; 4] {
        model.ambient.extend(model.lattice_time).to_array()
    }
}

/// What every dispatch of a batch reads (a uniform). 16 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuBatchFrame {
    /// Particle slots the integrator dispatches cover (the used part of the particle buffers).
    pub particle_slots: u32,
    /// Anchor targets per tick.
    pub anchor_count: u32,
    /// Number of [`GpuCollider`]s to test.
    pub collider_count: u32,
    /// Threads along `x` of the integrator and anchor dispatches: a thread's index is
    /// `y * dispatch_width + x`.
    pub dispatch_width: u32,
}

/// Which substep of a tick, and which of RK4's first three stages, a dispatch runs (a uniform
/// bound at a dynamic offset, one per substep and stage). 16 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuBatchStep {
    /// The substep, from 0.
    pub substep: u32,
    /// The stage, 0 to 2 (`node_update_final` ignores it).
    pub stage: u32,
    /// Padding.
    pub _pad: [u32; 2],
}

/// One block-descent sweep over one colour of every block-descent cloth of a batch (a uniform
/// bound at a dynamic offset, one per iteration and colour). 16 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuColourPass {
    /// Where the colour's particles start in the batch's colour list.
    pub start: u32,
    /// How many particles it has: one thread each.
    pub count: u32,
    /// The iteration, from 0: a cloth with fewer iterations sits this pass out.
    pub iteration: u32,
    /// Threads along `x` of the dispatch.
    pub dispatch_width: u32,
}

/// What the self-contact kernels of a batch read (a uniform): the triangles and edges of the
/// cloths with self-contact, and the hashed grid they are sorted into each substep. 48 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuContactFrame {
    /// Triangles of the cloths with self-contact: one thread each in the grid's build.
    pub triangle_count: u32,
    /// Buckets of the hashed grid, a power of two and a multiple of 256.
    pub buckets: u32,
    /// Blocks of 256 buckets: one workgroup each in the prefix sum.
    pub blocks: u32,
    /// Grid entries (a triangle in a bucket) there is room for.
    pub entry_capacity: u32,
    /// One over the grid's cell width, in 1/m.
    pub inv_cell: f32,
    /// How far each triangle's box is grown: the largest thickness, in metres.
    pub grow: f32,
    /// Threads along `x` of every self-contact dispatch.
    pub dispatch_width: u32,
    /// Particle slots the dispatches cover.
    pub particle_slots: u32,
    /// Edges of the cloths with self-contact, after the triangles in the primitive buffer: one
    /// thread each in the grid's build and in the edges' search.
    pub edge_count: u32,
    /// Cloth slots of the batch the untangling words are laid out for: one more than the
    /// highest slot of a contact cloth.
    pub cloth_slots: u32,
    /// Padding to 16 bytes, in two words as the WGSL struct has them (a uniform holds no array
    /// of `u32`).
    pub pad_a: u32,
    /// Padding.
    pub pad_b: u32,
}

/// Vec4 words per primitive (a triangle or an edge) in the self-contact primitive buffer: its
/// corners and cloth, its rest box, and its box as the particles stand (written on the GPU
/// each substep).
pub const CONTACT_TRIANGLE_WORDS: usize = 5;

/// The third corner of an edge in the self-contact primitive buffer: none.
pub const NO_CORNER: u32 = u32::MAX;

/// A cloth's triangles as the self-contact kernels read them, [`CONTACT_TRIANGLE_WORDS`] vec4s
/// each: the corners' particle slots (the cloth's particles start at `particle_start`) and the
/// cloth's index `slot`; the lower and upper corner of the triangle's box in the rest shape
/// (`f32` bits); and two zero words, the room for its current box.
pub fn gpu_contact_triangles(topology: &ClothTopology, particle_start: u32, slot: u32) -> Vec<[u32; 4]> {
    contact_primitives(topology, topology.triangles().iter().map(|t| t.as_slice()), particle_start, slot)
}

/// A cloth's edges ([`ClothTopology::edges`]) as the self-contact kernels read them, laid out
/// as [`gpu_contact_triangles`] lays out triangles, with [`NO_CORNER`] as the third corner.
pub fn gpu_contact_edges(topology: &ClothTopology, particle_start: u32, slot: u32) -> Vec<[u32; 4]> {
    contact_primitives(topology, topology.edges().iter().map(|e| e.as_slice()), particle_start, slot)
}

/// Each triangle of a cloth's (numbered from `first` among the contact cloths' triangles): its
/// neighbour across each of its edges (corners 0-1, 1-2, 2-0), or [`NO_CLOTH`] for none; where
/// more than two triangles share an edge, the next after it among them in order, the last
/// taking the first, so that joining each triangle to its neighbours joins them all.
pub fn gpu_triangle_neighbours(topology: &ClothTopology, first: u32) -> Vec<[u32; 3]> {
    let triangles = topology.triangles();
    (0..triangles.len())
        .map(|t| {
            let c = triangles[t];
            core::array::from_fn(|k| {
                let (p, q) = (c[k] as usize, c[(k + 1) % 3] as usize);
                let beside = topology.triangles_of(q);
                let mut sharing: Vec<u32> =
                    topology.triangles_of(p).iter().copied().filter(|u| beside.contains(u)).collect();
                sharing.sort_unstable();
                match sharing.iter().position(|&u| u as usize == t) {
                    Some(at) if sharing.len() > 1 => first + sharing[(at + 1) % sharing.len()],
                    _ => NO_CLOTH,
                }
            })
        })
        .collect()
}

/// The primitive words of the triangles or edges `corners` (the cloth's particle indices) of a
/// cloth whose particles start at slot `particle_start`.
fn contact_primitives<'a>(
    topology: &ClothTopology,
    corners: impl ExactSizeIterator<Item = &'a [u32]>,
    particle_start: u32,
    slot: u32,
) -> Vec<[u32; 4]> {
    let rest = topology.rest_positions();
    let bits = |v: Vec3| [v.x.to_bits(), v.y.to_bits(), v.z.to_bits(), 0];
    let mut words = Vec::with_capacity(CONTACT_TRIANGLE_WORDS * corners.len());
    for c in corners {
        let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
        let mut slots = [NO_CORNER; 3];
        for (slot, &k) in slots.iter_mut().zip(c) {
            *slot = k + particle_start;
            (lo, hi) = (lo.min(rest[k as usize]), hi.max(rest[k as usize]));
        }
        words.push([slots[0], slots[1], slots[2], slot]);
        words.push(bits(lo));
        words.push(bits(hi));
        words.push([0; 4]);
        words.push([0; 4]);
    }
    words
}

/// Per particle of a batch, indexed like the particle buffers: its springs (a range of the
/// cloth's spring ends, from [`ClothTopology::spring_offsets`]), its inverse mass share (`f32`
/// bits) and its cloth's index in the [`GpuBatchCloth`] array.
pub fn gpu_particle_info(topology: &ClothTopology, slot: u32) -> Vec<[u32; 4]> {
    let offsets = topology.spring_offsets();
    (0..topology.len()).map(|i| [offsets[i], offsets[i + 1], topology.inv_mass_share()[i].to_bits(), slot]).collect()
}

/// A cloth's tethers as the GPU reads them, one entry per particle after its springs in the
/// spring-end buffer: the pin (relative to the cloth, [`bvh_cloth_core::backend::UNTETHERED`] for none)
/// and the rest distance's bits; the other two words are unused. Empty for a cloth with no pin.
pub fn gpu_tether_ends(tethers: &TetherSet) -> Vec<[u32; 4]> {
    tethers.pin.iter().zip(&tethers.length).map(|(&pin, length)| [pin, 0, length.to_bits(), 0]).collect()
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

/// One collider's frame, its shape, and (for a mesh collider) where its tree lies in the shared
/// node and sphere arrays. 208 bytes.
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
    /// Index of its first sphere in the tree buffer, which holds every collider's nodes (two
    /// `vec4`s each) and then every sphere (one `vec4` each), counted in `vec4`s.
    pub sphere_offset: u32,
    /// Number of inner nodes (0 for a single-sphere collider and for a primitive).
    pub node_count: u32,
    /// Number of spheres (0 for a primitive).
    pub sphere_count: u32,
    /// How far beyond a node's box a contact can be (see [`ColliderFrame::contact_reach`]).
    pub contact_reach: f32,
    /// [`SHAPE_SPHERES`] for a sphere tree, else [`Primitive::kind`](bvh_cloth_core::Primitive::kind).
    pub shape: u32,
    /// A primitive's sizes in local units ([`Primitive::size`](bvh_cloth_core::Primitive::size)); zero for a sphere tree;
    /// for exact contact ([`SHAPE_TRIANGLES`]) `x` is the surface's least thickness and `y` its
    /// [`sweep_slack`](bvh_cloth_core::backend::TriangleSurface::sweep_slack).
    pub size: [f32; 4],
    /// The layers the collider is a member of ([`Collider::layers`]).
    pub memberships: u32,
    /// The layers whose cloths it collides with ([`Collider::layers`]).
    pub filters: u32,
    /// Padding.
    pub pad: [u32; 2],
}

/// [`GpuCollider::shape`] of a mesh collider's sphere tree.
pub const SHAPE_SPHERES: u32 = 0;

/// [`GpuCollider::shape`] of a mesh collider with exact contact: its tree is the triangle
/// surface's ([`bvh_cloth_core::backend::TriangleSurface`]), and right after its `sphere_count`
/// spheres come the triangles in leaf order, three `vec4`s each (the corners, `w` unused).
pub const SHAPE_TRIANGLES: u32 = 5;

/// The tree a collider's frame points at on the GPU: a collider with exact contact uploads its
/// triangle surface's binary tree (built again from its triangles, see
/// [`TriangleSurface::binary_tree`](bvh_cloth_core::backend::TriangleSurface::binary_tree)), with
/// the triangles after its spheres, any other mesh collider its sphere tree; `None` for a
/// primitive.
pub fn gpu_tree(collider: &Collider) -> Option<Cow<'_, Lbvh>> {
    match &collider.shape {
        ColliderShape::Spheres { surface: Some(surface), .. } => Some(Cow::Owned(surface.binary_tree())),
        ColliderShape::Spheres { lbvh, .. } => Some(Cow::Borrowed(lbvh)),
        ColliderShape::Primitive(_) => None,
    }
}

/// The nodes of a collider's tree on the GPU ([`gpu_tree`]) and its spheres, without building
/// it: a binary LBVH over `n` leaves has `n - 1` nodes (none for one leaf).
fn gpu_tree_counts(collider: &Collider) -> (usize, usize) {
    match &collider.shape {
        ColliderShape::Spheres { surface: Some(surface), .. } => {
            let leaves = surface.triangles.len();
            (leaves.saturating_sub(1), leaves)
        }
        ColliderShape::Spheres { lbvh, .. } => (lbvh.nodes.len(), lbvh.spheres.len()),
        ColliderShape::Primitive(_) => (0, 0),
    }
}

/// The node count of a collider's tree on the GPU ([`gpu_tree`]), and the `vec4`s of its
/// sphere region ([`gpu_sphere_region`]); zeros for a primitive.
pub fn gpu_tree_size(collider: &Collider) -> (usize, usize) {
    let (nodes, spheres) = gpu_tree_counts(collider);
    let triangles = collider.surface().map_or(0, |surface| 3 * surface.triangles.len());
    (nodes, spheres + triangles)
}

/// A collider's part of the tree buffer's sphere region, as `vec4`s: the spheres of `tree`
/// (its [`gpu_tree`]), then for exact contact its triangles' corners in leaf order.
pub fn gpu_sphere_region(collider: &Collider, tree: &Lbvh) -> Vec<[f32; 4]> {
    let mut words: Vec<[f32; 4]> = Vec::with_capacity(gpu_tree_size(collider).1);
    words.extend(tree.spheres.iter().map(|s| [s.center[0], s.center[1], s.center[2], s.radius]));
    if let Some(surface) = collider.surface() {
        words.extend(surface.triangles.iter().flatten().map(|p| p.extend(0.0).to_array()));
    }
    words
}

impl GpuCollider {
    /// The frame of `collider`, whose tree starts at the given offsets; `None` when the collider
    /// cannot be used (see [`ColliderFrame::new`]).
    pub fn new(collider: &Collider, node_offset: u32, sphere_offset: u32) -> Option<Self> {
        let frame = ColliderFrame::new(collider)?;
        let world_from_local = collider.pose.to_affine();
        let (node_count, sphere_count, shape, size) = match &collider.shape {
            ColliderShape::Spheres { surface: Some(surface), .. } => {
                let (nodes, spheres) = gpu_tree_counts(collider);
                let size = [surface.least_thickness(&collider.pose), surface.sweep_slack(), 0.0, 0.0];
                (nodes as u32, spheres as u32, SHAPE_TRIANGLES, size)
            }
            ColliderShape::Spheres { lbvh, .. } => {
                (lbvh.nodes.len() as u32, lbvh.spheres.len() as u32, SHAPE_SPHERES, [0.0; 4])
            }
            ColliderShape::Primitive(primitive) => (0, 0, primitive.kind(), primitive.size()),
        };
        let mat = |a: Affine3A| Mat4::from(a).to_cols_array_2d();
        Some(Self {
            local_from_world: mat(world_from_local.inverse()),
            world_from_local: mat(world_from_local),
            rotation: collider.pose.rotation.normalize().to_array(),
            margin_local: frame.margin_local,
            friction: frame.friction,
            node_offset,
            sphere_offset,
            node_count,
            sphere_count,
            contact_reach: frame.contact_reach,
            shape,
            size,
            memberships: collider.layers.memberships,
            filters: collider.layers.filters,
            pad: [0; 2],
        })
    }
}

/// A batched cloth's [`GpuMeshWriteback`] with where its data lies (an array of these is one
/// storage buffer, indexed by cloth). 176 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuBatchWriteback {
    /// Where and how the vertices are written.
    pub mesh: GpuMeshWriteback,
    /// Index of the cloth's first particle in the particle buffers.
    pub particle_start: u32,
    /// Index of the cloth's first word in the surface buffer ([`gpu_surface_words`]).
    pub surface_start: u32,
    /// Number of render vertices.
    pub vertex_count: u32,
    /// Number of particles.
    pub particle_count: u32,
    /// The thread of its group's dispatch that writes its first vertex.
    pub group_first: u32,
    /// Padding.
    pub _pad: [u32; 3],
}

/// One `normal_shader` dispatch: every cloth written into one vertex buffer (a uniform bound at
/// a dynamic offset, one per group). 16 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuWritebackGroup {
    /// Where the group's threads start in the owner table.
    pub first_owner: u32,
    /// Render vertices of all its cloths: one thread each.
    pub vertex_count: u32,
    /// Threads along `x` of the dispatch.
    pub dispatch_width: u32,
    /// Padding.
    pub pad: u32,
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
/// held one, `velocity.w` 1 where a collider touched it in the last substep.
pub fn gpu_particles(sim: &ClothSim) -> Vec<GpuParticle> {
    (0..sim.len())
        .map(|i| GpuParticle {
            position: sim.position(i).extend(if sim.is_pinned(i) { 0.0 } else { 1.0 }).to_array(),
            velocity: sim.velocity(i).extend(if sim.touched(i) { 1.0 } else { 0.0 }).to_array(),
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

/// One vertex of a skinned collider, as the GPU refit skins it: the bind position, four joints
/// (two to a word, low half first) and their weights. 48 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuSkinVertex {
    /// Bind-pose position, in the mesh's coordinates.
    pub position: [f32; 3],
    /// Joints 0 (low half) and 1.
    pub joints_low: u32,
    /// The weights of the four joints.
    pub weights: [f32; 4],
    /// Joints 2 (low half) and 3.
    pub joints_high: u32,
    /// Padding to the WGSL struct's 16-byte alignment.
    pub pad: [u32; 3],
}

/// The vertices of `vertices`, for the GPU refit.
pub fn gpu_skin_vertices(vertices: &SkinnedVertices) -> Vec<GpuSkinVertex> {
    let pair = |a: u16, b: u16| u32::from(a) | (u32::from(b) << 16);
    vertices
        .positions
        .iter()
        .zip(&vertices.joints)
        .zip(&vertices.weights)
        .map(|((p, j), w)| GpuSkinVertex {
            position: p.to_array(),
            joints_low: pair(j[0], j[1]),
            weights: *w,
            joints_high: pair(j[2], j[3]),
            pad: [0; 3],
        })
        .collect()
}

/// What one dispatch of the GPU refit works on. 32 bytes, one per dispatch at the device's
/// uniform offset alignment.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuRefitParams {
    /// Vertices to skin.
    pub vertex_count: u32,
    /// Spheres (leaves) to fit.
    pub leaf_count: u32,
    /// The collider's first node in the tree buffer, in nodes.
    pub node_offset: u32,
    /// Its first sphere in the tree buffer, in `vec4`s.
    pub sphere_offset: u32,
    /// This dispatch's first entry of the level list, and its number of nodes.
    pub level_start: u32,
    /// Number of nodes in this level.
    pub level_count: u32,
    /// The collider's index in the frame buffer, whose `contact_reach` the refit sets.
    pub collider: u32,
    /// How far each sphere reaches past its points (the skin's clearance at this pose).
    pub clearance: f32,
}

/// Mat4 columns of an affine transform, as the GPU refit reads joint matrices.
pub fn gpu_joint_matrix(matrix: &Affine3A) -> [[f32; 4]; 4] {
    Mat4::from(*matrix).to_cols_array_2d()
}

/// One cloth's multigrid correction (`multigrid.wgsl`), indexed like the [`GpuBatchCloth`]
/// array: where its hierarchy lies in the multigrid buffers, what the host sets, and the state
/// the kernels keep between substeps. A cloth without the correction has `levels` 0. 96 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuMultigridCloth {
    /// Levels of the hierarchy (0: no correction for this cloth).
    pub levels: u32,
    /// The first of the cloth's level-1 nodes, and how many there are.
    pub node_start: u32,
    /// See [`Self::node_start`].
    pub node_count: u32,
    /// The first node of the cloth's coarsest level, and how many it has.
    pub coarsest_start: u32,
    /// See [`Self::coarsest_start`].
    pub coarsest_count: u32,
    /// The first of the cloth's crossing springs in the spring list, and how many.
    pub crossing_start: u32,
    /// See [`Self::crossing_start`].
    pub crossing_count: u32,
    /// Where the cloth's particles' aggregates start in the index buffer.
    pub aggregate_start: u32,
    /// Where the coarsest level's dense factor starts in the value buffer (`vec4` entries),
    /// and its order (`3 x coarsest_count`; 0 when the coarsest level is smoothed instead).
    pub dense_start: u32,
    /// See [`Self::dense_start`].
    pub dense_order: u32,
    /// The kernels': 1 while the cloth runs the current substep.
    pub running: u32,
    /// The host's: 1 when the cloth is too stiff for BDF2 (every substep is then implicit
    /// Euler, and assembles the levels).
    pub stiff: u32,
    /// The host's: 1 when the cloth's substeps blend BDF2 with implicit Euler and its
    /// correction runs the first level's W-cycle
    /// (`bvh_cloth_core::backend::MultigridStepping::Blend`).
    pub blend: u32,
    /// The kernels': substeps since the levels were assembled, and whether this substep
    /// assembles and factors them.
    pub age: u32,
    /// See [`Self::age`].
    pub assemble: u32,
    /// See [`Self::age`].
    pub refactor: u32,
    /// 1 while the coarsest level's dense factor is valid.
    pub dense_ok: u32,
    /// This substep's `1 + c h` and `h²`, and those the levels are factored for.
    pub damp: f32,
    /// See [`Self::damp`].
    pub h2: f32,
    /// See [`Self::damp`].
    pub factored_damp: f32,
    /// See [`Self::damp`].
    pub factored_h2: f32,
    /// This substep's step along the correction (the line search's).
    pub alpha: f32,
    /// The cloth's first chunk of level-1 nodes in the chunk table (the line search's first
    /// level sums each chunk), and how many it has.
    pub chunk_start: u32,
    /// See [`Self::chunk_start`].
    pub chunk_count: u32,
}

/// One dispatch of the multigrid correction (a uniform at a dynamic offset): the range of
/// threads, the level, and where each section of the multigrid buffers starts. 48 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuMultigridPass {
    /// The first node (or spring, or cloth) of the dispatch, and how many.
    pub start: u32,
    /// See [`Self::start`].
    pub count: u32,
    /// Threads along `x`: a thread's index is `y * width + x`.
    pub width: u32,
    /// The level the dispatch works on (0 is level 1, the aggregates of particles).
    pub level: u32,
    /// Where the blocks', the shares', the springs' and the chunks' words start in the index
    /// buffer.
    pub block_words: u32,
    /// See [`Self::block_words`].
    pub share_words: u32,
    /// See [`Self::block_words`].
    pub spring_words: u32,
    /// Where the chunk table (per chunk its first level-1 node and its count, up to 64) starts
    /// in the index buffer.
    pub chunk_words: u32,
    /// Where the nodes', the blocks' and the crossing springs' values start in the value
    /// buffer (`vec4` entries).
    pub node_values: u32,
    /// See [`Self::node_values`].
    pub block_values: u32,
    /// See [`Self::node_values`].
    pub spring_values: u32,
    /// Where the chunks' sums start in the value buffer.
    pub chunk_values: u32,
}

/// `u32` words per node at the start of the multigrid index buffer: its off-diagonal blocks
/// (a range), its children (a range of the index buffer), its aggregate on the next level, its
/// cloth, its shares of the crossing springs and its inner springs (ranges; level 1 only), and
/// its level.
pub const MULTIGRID_NODE_WORDS: u32 = 12;

/// `vec4` values per node in the multigrid value buffer: its masses (`x` assembled, `y` this
/// substep's free mass, `z` 1 when a collider holds one of its particles), its stiffness
/// block and its diagonal block's inverse (each symmetric: the diagonal, then `xy`, `xz`,
/// `yz`), its right-hand side, and its solutions on the way down and up the V-cycle.
pub const MULTIGRID_NODE_VALUES: u32 = 8;

/// `vec4` values per crossing spring: its force on its first end, its direction and clamped
/// stretch, and its Hessian (symmetric, as a node's blocks).
pub const MULTIGRID_SPRING_VALUES: u32 = 4;
