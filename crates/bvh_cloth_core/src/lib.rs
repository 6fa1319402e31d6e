//! # bvh_cloth_core
//!
//! The engine-agnostic core of `bevy_bvh_cloth`: a mass-spring cloth integrated with vertex
//! block descent or fourth-order Runge–Kutta, colliding with rigid meshes that are voxelised into spheres and
//! arranged in a Morton-code LBVH. It follows Mei, Fan, Zhang and Liu, "A Collision Detection and
//! Cloth Simulation Method Based on Parallel BVH"; the section each module implements is named in
//! its documentation.
//!
//! | module | paper |
//! |---|---|
//! | [`params`], [`grid`], [`topology`], [`pins`], [`forces`] | 2.1, eq. 1–3, Table V |
//! | [`sim`] (RK4, semi-implicit Euler) | 2.2, eq. 4 |
//! | [`aerodynamics`] | (drag, lift and wind; not in the paper) |
//! | [`block_descent`], [`colouring`] | (vertex block descent, Chen et al. 2024; not in the paper) |
//! | [`voxel_spheres`] | 2.4.1 |
//! | [`skinning`] | (skinned colliders: the spheres follow the joints; not in the paper) |
//! | [`morton`], [`lbvh`] | 2.4.2 (Karras 2012) |
//! | [`traversal`] | 2.4.3, Algorithm 2 |
//! | [`collision`] | 2.4.4 |
//! | [`exact_contact`], [`triangles`], [`wide_bvh`] | (contact with the mesh's own triangles; not in the paper) |
//! | [`normals`] | Algorithm 3 |
//! | [`gpu_layout`] | Table II: the buffer layouts of the GPU kernels |
//! | [`obj`] | (a minimal OBJ reader for engine-free tools) |
//!
//! This crate knows nothing of any engine: it is tested, benchmarked and fuzzed on its own.
//!
//! ```
//! use std::sync::Arc;
//!
//! use bvh_cloth_core::{Affine3A, ClothGrid, ClothParams, ClothSim, ClothTopology, Collider, MeshRef, Vec2, Vec3};
//!
//! // A unit box as the collider, voxelised at n = 3.
//! let positions: Vec<[f32; 3]> =
//!     (0..8).map(|i| [(i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32]).collect();
//! let indices = [0, 1, 3, 0, 3, 2, 4, 6, 7, 4, 7, 5, 0, 4, 5, 0, 5, 1, 2, 3, 7, 2, 7, 6];
//! let collider = Collider::from_mesh(MeshRef { positions: &positions, indices: Some(&indices) }, 3)?;
//!
//! // A 2 m x 2 m cloth of 16 x 16 particles, 2 m above it, falling for half a second at 60
//! // ticks per second. Any triangle mesh works too: `ClothTopology::from_mesh`.
//! let grid = Arc::new(ClothTopology::grid(ClothGrid::new(Vec2::splat(2.0), [16, 16].into()))?);
//! let pose = Affine3A::from_translation(Vec3::new(0.5, 2.0, 0.5));
//! let mut cloth = ClothSim::new(ClothParams::default(), grid, pose, &[])?;
//! for _ in 0..30 {
//!     cloth.tick(1.0 / 60.0, std::slice::from_ref(&collider));
//! }
//! assert!(cloth.is_finite());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

#![deny(missing_docs)]

pub mod aerodynamics;
pub mod block_descent;
pub mod collider;
pub mod collision;
pub mod colouring;
pub mod error;
pub mod exact_contact;
pub mod forces;
pub mod gpu_layout;
pub mod grid;
pub mod lbvh;
pub mod morton;
pub mod normals;
pub mod obj;
pub mod params;
pub mod pins;
mod pose;
mod primitive_shape;
pub mod primitives;
mod response;
pub mod self_contact;
pub mod sim;
pub mod skinning;
pub mod tethers;
pub mod topology;
pub mod traversal;
pub mod triangles;
mod voxel_grid;
pub mod voxel_spheres;
pub mod wide_bvh;

pub use aerodynamics::{Aerodynamics, Wind, WindSource};
pub use collider::{Collider, ColliderPose, ColliderShape};
pub use error::{ClothError, ColliderError};
pub use glam::{Affine3A, Quat, UVec2, UVec3, Vec2, Vec3, Vec3A};
pub use grid::{ClothGrid, MAX_PARTICLES};
pub use lbvh::{BvhNode, Lbvh, Sphere};
pub use params::{ClothParams, Integrator, SpringStiffness};
pub use pins::{ClothPins, ColorChannel, MeshVertices};
pub use primitives::Primitive;
pub use self_contact::SelfContact;
pub use sim::{ClothSim, Ticked};
pub use skinning::{SkinRef, SkinScratch, SkinnedSpheres};
pub use tethers::Tethers;
pub use topology::{ClothTopology, SpringEnd};
pub use voxel_spheres::{MeshRef, Voxels};
