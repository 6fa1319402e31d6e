//! Where a collider is in the world. It imports nothing of the crate, so that the shapes'
//! responses can read a pose without importing the collider.

use glam::{Affine3A, Quat, Vec3};

/// Where a collider is in the world: rotation, uniform scale, translation.
///
/// Only uniform scale is supported, because it maps spheres to spheres; a caller with a
/// non-uniform scale should bake it into the mesh.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ColliderPose {
    /// World position of the collider's local origin.
    pub translation: Vec3,
    /// World orientation.
    pub rotation: Quat,
    /// Uniform scale, local to world. Must be positive.
    pub scale: f32,
}

impl Default for ColliderPose {
    fn default() -> Self {
        Self { translation: Vec3::ZERO, rotation: Quat::IDENTITY, scale: 1.0 }
    }
}

impl ColliderPose {
    /// The local-to-world transform.
    pub fn to_affine(&self) -> Affine3A {
        Affine3A::from_scale_rotation_translation(Vec3::splat(self.scale), self.rotation, self.translation)
    }

    /// Whether the pose can be used: finite, with a positive scale and a non-degenerate rotation.
    pub fn is_valid(&self) -> bool {
        self.translation.is_finite()
            && self.rotation.is_finite()
            && self.rotation.length_squared() > 0.5
            && self.scale.is_finite()
            && self.scale > 0.0
    }
}
