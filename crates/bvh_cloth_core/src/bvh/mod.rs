//! The bounding volume hierarchies that collision queries descend: 30-bit Morton codes, the
//! linear BVH over sphere leaves (paper 2.4.2, after Karras 2012), its stack traversal (paper
//! 2.4.3, Algorithm 2), and the quantised four-wide tree of the exact-contact surface.
//!
//! A floor of the crate beside [`crate::mesh`]: it imports nothing from the crate.

pub(crate) mod lbvh;
pub(crate) mod morton;
pub(crate) mod traversal;
pub(crate) mod wide;

pub use lbvh::{BvhNode, Lbvh, Sphere};
