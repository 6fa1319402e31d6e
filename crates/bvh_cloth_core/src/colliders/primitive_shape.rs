//! The exact primitives' shapes, apart from their response ([`crate::colliders::primitives`]): it imports
//! nothing of the crate, so that an error can hold a shape.

use glam::Vec3;

/// A convex shape in its collider's local frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Primitive {
    /// A ball around the origin.
    Sphere {
        /// Radius.
        radius: f32,
    },
    /// The points within `radius` of the segment from `-half_length` to `+half_length` on the
    /// local Y axis (Bevy's `Capsule3d`).
    Capsule {
        /// Radius of the rounded ends and the body.
        radius: f32,
        /// Half the length of the axis segment (0 makes a sphere).
        half_length: f32,
    },
    /// An axis-aligned box around the origin (Bevy's `Cuboid`).
    Cuboid {
        /// Half the size along each local axis.
        half_extents: Vec3,
    },
    /// Everything below the plane through the origin with the given outward normal: the ground
    /// when the normal is `+Y`.
    HalfSpace {
        /// Outward unit normal of the surface (normalised by [`Primitive::validate`]'s users).
        normal: Vec3,
    },
}
