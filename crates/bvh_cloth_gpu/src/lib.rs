//! # bvh_cloth_gpu
//!
//! The paper's three compute kernels (Table I) in WGSL, on plain wgpu, for every cloth of a
//! scene at once: `node_update` (spring forces and one RK4 stage per dispatch, semi-implicit
//! Euler in one of them), `node_update_final` (the last stage, fused with the paper's
//! `collision_detection_with_bvh`: stack traversal of every collider's LBVH and the collision
//! response), `apply_anchors` (pins moved at the start of each tick) and `normal_shader`
//! (normals, written with the positions into an interleaved vertex buffer such as a mesh's
//! vertex slab), block descent's three kernels, self-contact's nine ([`EntryPoint::CONTACT`]:
//! a hashed grid of the cloths' triangles and edges rebuilt by counting sort each substep, then
//! point–triangle and edge–edge contacts within and between cloths), and aerodynamics' three
//! ([`EntryPoint::AIR`]: the wind sampled at every particle each tick, then drag and lift gathered
//! from each particle's triangles each substep). The WGSL is one file per kernel beside a shared types file
//! ([`SHADER_FILES`]).
//!
//! It knows no engine, so that the kernels can be tested against the CPU reference of
//! [`bvh_cloth_core`] and benchmarked without one; `bevy_bvh_cloth` drives the same kernels
//! from Bevy's render world with the device Bevy renders with. Buffer layouts are the core's
//! [`layout`] structs.
//!
//! | type | what it holds |
//! |---|---|
//! | [`ClothKernels`] | the compiled pipelines and their bind group layouts (one per device) |
//! | [`GpuColliders`] | every collider's frame, nodes and spheres |
//! | [`SkinRefit`] | a skinned collider's spheres and boxes refitted on the device from its joint matrices |
//! | [`ClothBatch`] | every cloth's particles, shapes and constants in shared buffers; encodes the ticks of all of them and each one's writeback |
//! | [`FaultReadback`] | reads a cloth's count of quarantined particles without stalling |
//! | [`ParticleReadback`] | reads a cloth's positions and velocities without stalling |
//! | [`PassTimer`] | measures the GPU time of a batch's ticks with timestamp queries, without stalling |
//! | [`headless`] | a device without a window, and blocking readback, for tests and benchmarks |

//! ## Layout
//! The crate's modules stand on floors, each importing only from those below it (the core's
//! `tests/core/house.rs` checks it): [`layout`] (the buffers' structs) and `buffer`;
//! `constants` (the WGSL constants written from the core); `kernels` (the entry points,
//! their bind group layouts and pipelines); [`headless`] (a device with the kernels, for tests
//! and benchmarks); `colliders` (the colliders' trees and a skinned collider's refit),
//! `readback` and `stages` (the air, self-contact and the multigrid correction, each with its
//! buffers and dispatches); and `batch` on top (`allocation` of the shared buffers,
//! `bind_groups`, the tick's `schedule` and each cloth's `writeback`).

#![deny(missing_docs)]

mod batch;
mod buffer;
mod colliders;
mod constants;
pub mod headless;
mod kernels;
pub mod layout;
mod readback;
mod stages;

pub use batch::{ClothBatch, ClothId};
pub use colliders::GpuColliders;
pub use colliders::skin_refit::SkinRefit;
pub use constants::{CONSTANTS_FILE, shared_constants};
pub use kernels::{
    ClothKernels, EntryPoint, Kernel, KernelDescriptor, KernelError, SHADER_FILES, STORAGE_BUFFERS_NEEDED,
    WORKGROUP_SIZE, shader_source,
};
pub use readback::{FaultReadback, ParticleReadback, PassTimer};
pub use wgpu;
