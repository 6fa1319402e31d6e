//! What the cloths collide with: [`AutoCollider`](crate::AutoCollider) (any mesh, voxelised
//! into spheres at start-up, or its own triangles), [`PrimitiveCollider`](crate::PrimitiveCollider),
//! [`ColliderHierarchy`](crate::ColliderHierarchy) over a scene's meshes, skinned colliders, and
//! each collider's pose every frame ([`ColliderPlugin`]).
//!
//! Stands on the backend choice, the settings, the messages and the events; the cloth, the
//! backends and the debug view read the [`ClothCollider`](crate::ClothCollider)s built here.

pub(crate) mod auto;
pub(crate) mod hierarchy;
pub(crate) mod mesh;
pub(crate) mod pose;
pub(crate) mod primitive;

use bevy::ecs::schedule::{InternedScheduleLabel, ScheduleLabel};
use bevy::prelude::*;

use crate::schedule::ClothSystems;
use auto::{AutoCollider, ColliderContact, ColliderStatus};
use hierarchy::{ColliderHierarchy, ColliderPart, ExcludeFromColliders};
use primitive::PrimitiveCollider;

/// The colliders: built (or their async builds polled) and placed where their entities are, in
/// [`ClothSystems::BuildColliders`].
#[derive(Debug, Clone)]
pub struct ColliderPlugin {
    schedule: InternedScheduleLabel,
}

impl ColliderPlugin {
    /// The collider systems in `schedule`.
    pub fn new(schedule: impl ScheduleLabel) -> Self {
        Self { schedule: schedule.intern() }
    }
}

impl Plugin for ColliderPlugin {
    fn build(&self, app: &mut App) {
        app.register_type::<AutoCollider>()
            .register_type::<ColliderContact>()
            .register_type::<PrimitiveCollider>()
            .register_type::<ColliderHierarchy>()
            .register_type::<ColliderPart>()
            .register_type::<ExcludeFromColliders>()
            .register_type::<ColliderStatus>()
            .add_systems(
                self.schedule,
                (
                    pose::drop_removed_colliders,
                    hierarchy::spread_colliders,
                    auto::build_colliders,
                    primitive::build_primitive_colliders,
                    pose::update_collider_poses,
                )
                    .chain()
                    .in_set(ClothSystems::BuildColliders),
            );
    }
}
