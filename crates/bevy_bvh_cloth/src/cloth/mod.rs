//! The cloths: the [`Cloth`](crate::Cloth) component and its mesh, the meshes a scene's
//! [`ClothHierarchy`](crate::ClothHierarchy) makes cloth, each cloth's simulation kept in step
//! with it ([`ClothSimulation`](crate::ClothSimulation)), a skinned mesh's pins on its skin
//! ([`ClothSkin`](crate::ClothSkin)), its pins planned tick by tick, and
//! the plugin's statistics ([`ClothPlugin`]).
//!
//! Stands on the colliders, the clock, the settings and the messages; the wind and the two
//! backends step what is built here.

pub(crate) mod component;
pub(crate) mod hierarchy;
pub(crate) mod mesh;
pub(crate) mod simulation;
pub(crate) mod skin;
pub(crate) mod stats;

use bevy::ecs::schedule::{InternedScheduleLabel, ScheduleLabel};
use bevy::prelude::*;

use crate::clock::advance_clock;
use crate::schedule::ClothSystems;
use component::Cloth;
use component::ClothPart;
use hierarchy::ClothHierarchy;
use stats::ClothStats;

/// The cloths: a scene's [`ClothHierarchy`] applied before [`ClothSystems::BuildColliders`],
/// [`Cloth`] changes and resets applied in [`ClothSystems::Prepare`], pins planned and
/// statistics updated in [`ClothSystems::Step`] (around the backend's step).
#[derive(Debug, Clone)]
pub struct ClothPlugin {
    schedule: InternedScheduleLabel,
}

impl ClothPlugin {
    /// The cloth systems in `schedule`.
    pub fn new(schedule: impl ScheduleLabel) -> Self {
        Self { schedule: schedule.intern() }
    }
}

impl Plugin for ClothPlugin {
    fn build(&self, app: &mut App) {
        app.register_type::<Cloth>()
            .register_type::<ClothHierarchy>()
            .register_type::<ClothPart>()
            .register_type::<ClothStats>()
            .init_resource::<ClothStats>()
            .add_systems(
                self.schedule,
                (
                    // Before the colliders, so that a hierarchy's collider never takes a mesh
                    // that is about to be cloth.
                    hierarchy::spread_cloths.before(ClothSystems::BuildColliders),
                    (
                        simulation::drop_removed_cloths,
                        simulation::sync_cloths.after(advance_clock),
                        simulation::warn_stiff_cloths,
                    )
                        .chain()
                        .in_set(ClothSystems::Prepare),
                    (simulation::plan_anchors, stats::update_stats).chain().in_set(ClothSystems::Step),
                    skin::redraw_unskinned.in_set(ClothSystems::Prepare),
                ),
            );
    }
}
