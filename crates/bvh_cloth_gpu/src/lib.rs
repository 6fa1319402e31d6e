//! # bvh_cloth_gpu
//!
//! The paper's three compute kernels (Table I) in WGSL, on plain wgpu: `node_update` (spring
//! forces and one RK4 or semi-implicit Euler stage per dispatch), `collision_detection_with_bvh`
//! (stack traversal of every collider's LBVH and the collision response) and `normal_shader`
//! (normals, written with the positions into an interleaved vertex buffer such as a mesh's
//! vertex slab).
//!
//! It knows no engine, so that the kernels can be tested against the CPU reference of
//! [`bvh_cloth_core`] and benchmarked without one; `bevy_bvh_cloth` drives the same kernels
//! from Bevy's render world with the device Bevy renders with. Buffer layouts are the core's
//! [`bvh_cloth_core::gpu_layout`] structs.
//!
//! | type | what it holds |
//! |---|---|
//! | [`ClothKernels`] | the compiled pipelines and their bind group layouts (one per device) |
//! | [`GpuColliders`] | every collider's frame, nodes and spheres |
//! | [`GpuCloth`] | one cloth's particle buffers and parameters; encodes ticks and writeback |
//! | [`FaultReadback`] | reads a cloth's count of quarantined particles without stalling |
//! | [`ParticleReadback`] | reads a cloth's positions and velocities without stalling |
//! | [`headless`] | a device without a window, and blocking readback, for tests and benchmarks |

#![deny(missing_docs)]

mod cloth;
mod colliders;
pub mod headless;
mod kernels;
mod readback;

pub use cloth::GpuCloth;
pub use colliders::GpuColliders;
pub use kernels::{ClothKernels, KernelError, SHADER_SOURCE, STORAGE_BUFFERS_NEEDED, WORKGROUP_SIZE};
pub use readback::{FaultReadback, ParticleReadback};
pub use wgpu;
