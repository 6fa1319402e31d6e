//! What a cloth collides with, and the response to it: meshes voxelised into spheres in an
//! LBVH (paper 2.4.1), the mesh's own triangles for exact contact, exact primitives, skinned
//! colliders that follow their joints, and the push out of a particle from each (paper 2.4.4).
//!
//! The shapes and their responses share this folder because each response reads its shape's
//! own structure (the sphere tree, the triangle surface, the primitive) and [`Collider`]
//! dispatches over them; a folder of shapes and another of responses would import each other.
//! The files below keep their own floors: [`Response`] and the pose import nothing, the
//! shapes' responses import them, and [`Collider`] sits on top.
//!
//! It uses [`crate::mesh`] and [`crate::bvh`]; nothing here knows the cloth.

pub(crate) mod collider;
pub mod collision;
pub(crate) mod error;
pub mod exact_contact;
pub(crate) mod layers;
pub(crate) mod pose;
pub(crate) mod primitive_shape;
pub mod primitives;
pub(crate) mod response;
pub(crate) mod skinning;
pub(crate) mod voxel_grid;
pub mod voxel_spheres;

pub use collider::{Collider, ColliderShape};
pub use error::ColliderError;
pub use layers::CollisionLayers;
pub use pose::ColliderPose;
pub use primitive_shape::Primitive;
pub use response::Response;
pub use skinning::{SkinRef, SkinScratch, SkinnedSpheres};
pub use voxel_spheres::Voxels;
