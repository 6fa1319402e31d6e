//! The render world's cloth state ([`GpuClothWorld`]): what the main world sent this frame,
//! the batch of every cloth, the colliders, and each cloth's place in its mesh's vertex slab.

use std::sync::Arc;
use std::sync::atomic::{AtomicU32, AtomicU64};

use bevy::ecs::entity::EntityHashMap;
use bevy::prelude::*;
use bvh_cloth_core::backend::TetherSet;
use bvh_cloth_core::{Affine3A, ClothParams, ClothSim, Collider, Lbvh, SkinnedSpheres, Wind, WindSource};
use bvh_cloth_gpu::{
    ClothBatch, ClothId, ClothKernels, FaultReadback, GpuColliders, ParticleReadback, PassTimer, SkinRefit,
};

use super::shaders::QueuedKernels;

/// One cloth as extracted this frame.
pub(super) struct ExtractedCloth {
    pub(super) entity: Entity,
    pub(super) generation: u64,
    /// The whole state, when the render world does not have this generation yet.
    pub(super) fresh: Option<ClothSim>,
    /// Its pinned particles and tethers, when the render world does not have this pin
    /// generation yet ([`ClothSimulation::pins_generation`](crate::ClothSimulation)).
    pub(super) pins: Option<(Vec<u32>, Arc<TetherSet>)>,
    pub(super) pins_generation: u64,
    pub(super) params: ClothParams,
    /// Its ambient wind (the sources are the world's).
    pub(super) wind: Wind,
    /// Where the pins go in each of this frame's ticks.
    pub(super) anchor_targets: Vec<Vec<(u32, Vec3)>>,
    pub(super) mesh: AssetId<Mesh>,
    pub(super) mesh_to_world: Affine3A,
    /// Whether gameplay reads this cloth's state back ([`ClothReadback`]).
    pub(super) read_back: bool,
}

/// A cloth in the render world: its place in the batch and its readbacks.
pub(super) struct RenderCloth {
    pub(super) id: ClothId,
    pub(super) generation: u64,
    /// The pin generation its slot of the batch holds.
    pub(super) pins_generation: u64,
    pub(super) faults: FaultReadback,
    /// Ticks run since the cloth was added or its state uploaded, this frame's included.
    pub(super) ticks_run: u64,
    /// The state read back for gameplay, and the clock's ticks and the cloth's ticks run at the
    /// copy in flight.
    pub(super) state: Option<(ParticleReadback, [AtomicU64; 2])>,
    /// Whether its parameters ask for self-contact, and for drag or lift.
    pub(super) self_contact: bool,
    pub(super) aerodynamics: bool,
    /// Whether its parameters ask for [`Integrator::Multigrid`](bvh_cloth_core::Integrator).
    pub(super) multigrid: bool,
}

/// The render world's cloth state.
#[derive(Resource, Default)]
pub(crate) struct GpuClothWorld {
    pub(super) kernels: Option<ClothKernels>,
    /// The kernels while the pipeline cache compiles them.
    pub(super) queued: Option<QueuedKernels>,
    /// Every cloth's GPU state.
    pub(super) batch: Option<ClothBatch>,
    /// Times the batch's ticks on the GPU, where the device has timestamp queries, with the
    /// ticks of the frame being measured.
    pub(super) step_timer: Option<(PassTimer, AtomicU32)>,
    /// The kernels could not be built; said once.
    pub(super) failed: bool,
    /// The colliders, keyed by their (shared) trees. Holding the trees keeps them alive, so an
    /// identical pointer always means the same tree.
    pub(super) colliders: Option<(Vec<Option<Arc<Lbvh>>>, GpuColliders)>,
    pub(super) cloths: EntityHashMap<RenderCloth>,
    /// Cloths the device refused (too big for it), with the generation refused: said once, and
    /// tried again only when the cloth changes.
    pub(super) refused: EntityHashMap<u64>,
    /// This frame's input.
    pub(super) ticks: u32,
    /// Ticks run since start-up, this frame's included.
    pub(super) total_ticks: u64,
    pub(super) tick_seconds: f32,
    /// This frame's wind sources.
    pub(super) wind_sources: Vec<WindSource>,
    pub(super) extracted: Vec<ExtractedCloth>,
    pub(super) extracted_colliders: Vec<Collider>,
    /// Their entities, in the same order.
    pub(super) collider_entities: Vec<Entity>,
    /// Each extracted collider's joint matrices and clearance, when it is skinned and refitted
    /// here on the GPU.
    pub(super) extracted_skin_poses: Vec<Option<(Vec<Affine3A>, f32)>>,
    /// The skinned colliders refitted on the GPU this frame, keyed by their (shared) skins.
    pub(super) skin_refits: Vec<GpuSkin>,
    /// Skins whose refit the device refused, said once.
    pub(super) refused_skins: Vec<Arc<SkinnedSpheres>>,
    /// Self-contact's buffers did not fit the device: said once, until they fit again.
    pub(super) contact_refused: bool,
    /// The air's buffer did not fit the device: said once, until it fits again.
    pub(super) air_refused: bool,
    /// The multigrid correction's buffers did not fit the device: said once, until they fit.
    pub(super) multigrid_refused: bool,
}

/// A skinned collider refitted on the GPU: its skin, its refit, and where the refit was bound
/// (the collider's index, its tree's offsets and its frame).
pub(super) struct GpuSkin {
    pub(super) skin: Arc<SkinnedSpheres>,
    pub(super) refit: SkinRefit,
    pub(super) bound: Option<SkinPlace>,
}

/// Where a skinned collider's refit is bound: the collider's index, its tree's node and sphere
/// offsets, and its frame.
pub(super) type SkinPlace = (usize, Option<(u32, u32)>, Option<u32>);
