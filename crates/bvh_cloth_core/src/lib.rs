//! # bvh_cloth_core
//!
//! The engine-agnostic core of `bevy_bvh_cloth`: a mass-spring cloth integrated by BDF2 steps
//! solved with vertex block descent and a multigrid correction (the default), by block descent
//! alone or by fourth-order Runge–Kutta, colliding with rigid meshes that are voxelised into spheres and
//! arranged in a Morton-code LBVH. It follows Mei, Fan, Zhang and Liu, "A Collision Detection and
//! Cloth Simulation Method Based on Parallel BVH"; the section each module implements is named in
//! its documentation.
//!
//! The crate is laid out by concern, in floors: each folder imports only from the floors
//! below it (a test, `tests/core/house.rs`, holds it to that).
//!
//! | floor | module | what it owns | paper |
//! |---|---|---|---|
//! | 4 | [`sim`] | the [`ClothSim`] state, a tick, RK4 and semi-implicit Euler, several cloths together | 2.2, eq. 4 |
//! | 3 | [`solver`] | [`ClothParams`], the spring forces, vertex block descent | Table V, eq. 1–3 |
//! | 2 | [`air`] | drag, lift and wind | (not in the paper) |
//! | 2 | [`self_contact`] | contact within a cloth and between cloths | (not in the paper) |
//! | 1 | [`cloth`] | the grid or mesh, springs, pins, tethers, colouring, normals | 2.1, Algorithm 3 |
//! | 1 | [`colliders`] | voxel spheres, exact triangles and primitives, skinning, the contact response | 2.4.1, 2.4.4 |
//! | 0 | [`bvh`] | Morton codes, the LBVH and its traversal, the wide tree | 2.4.2, 2.4.3 |
//! | 0 | [`mesh`] | [`MeshRef`] and its check, an OBJ reader, triangle queries | |
//!
//! A game names the types re-exported here at the root. [`backend`] holds what the GPU crate,
//! the tests and the benchmarks read beyond that.
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

pub mod air;
pub mod backend;
pub mod bvh;
pub mod cloth;
pub mod colliders;
pub mod mesh;
pub mod self_contact;
pub mod sim;
pub mod solver;

pub use air::{Aerodynamics, Wind, WindSource};
pub use bvh::{BvhNode, Lbvh, Sphere};
pub use cloth::{
    ClothError, ClothGrid, ClothPins, ClothTopology, ColorChannel, MAX_PARTICLES, MeshVertices, SpringEnd, Tethers,
};
pub use colliders::{
    Collider, ColliderError, ColliderPose, ColliderShape, CollisionLayers, Primitive, SkinRef, SkinScratch,
    SkinnedSpheres, Voxels,
};
pub use glam::{Affine3A, Quat, UVec2, UVec3, Vec2, Vec3, Vec3A};
pub use mesh::MeshRef;
pub use mesh::obj::{ObjError, ObjMesh, parse_obj};
pub use self_contact::SelfContact;
pub use sim::{ClothSim, Ticked};
pub use solver::params::MAX_DENSITY;
pub use solver::{ClothParams, Integrator, SpringStiffness};
