//! When the cloth runs: the system sets ([`ClothSystems`]) chained in the schedule the plugin
//! runs in, transform propagation where that schedule is not [`PostUpdate`], the clock, the
//! settings and the messages every other part writes.
//!
//! It stands on the backend choice, the settings, the messages and the clock; every sub-plugin
//! orders its systems in these sets.

use bevy::camera::visibility::VisibilitySystems;
use bevy::ecs::schedule::{InternedScheduleLabel, ScheduleLabel};
use bevy::prelude::*;
use bevy::transform::TransformSystems;
use bevy::transform::systems::{mark_dirty_trees, propagate_parent_transforms, sync_simple_transforms};

use crate::backend::{ActiveClothBackend, ClothBackend};
use crate::clock::{self, ClothClock};
use crate::events;
use crate::messages::{ClothMessage, ResetCloth};
use crate::settings::ClothSettings;

/// The system sets of the plugin, chained in this order in the schedule the plugin runs in
/// ([`PostUpdate`] by default, after [`TransformSystems::Propagate`]). Order your own systems
/// against them.
///
/// ```
/// # use bevy::prelude::*;
/// # use bevy_bvh_cloth::prelude::*;
/// // Reads where the cloths are once this frame's ticks are done.
/// fn lowest_particle(cloths: Query<&ClothSimulation>) {
///     let lowest = cloths.iter().flat_map(|c| c.sim().positions()).map(|p| p.y).fold(f32::INFINITY, f32::min);
///     info!("lowest particle at {lowest} m");
/// }
/// App::new().add_systems(PostUpdate, lowest_particle.after(ClothSystems::Step));
/// ```
#[derive(SystemSet, Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ClothSystems {
    /// [`AutoCollider`](crate::AutoCollider)s are built (or their async builds polled) and placed at their
    /// entity's [`GlobalTransform`].
    BuildColliders,
    /// The clock advances; [`Cloth`](crate::Cloth) changes, [`ResetCloth`] requests and the GPU's divergence
    /// reports are applied.
    Prepare,
    /// Each cloth's pins are planned tick by tick, and the cloths are stepped (on the GPU
    /// backend, in the render world).
    Step,
    /// The results are written into the cloth meshes.
    Writeback,
}

/// Whether `schedule` is one of Bevy's fixed-timestep schedules, where the clock runs in
/// [`lockstep`](ClothClock::lockstep).
fn is_fixed(schedule: InternedScheduleLabel) -> bool {
    [FixedFirst.intern(), FixedPreUpdate.intern(), FixedUpdate.intern(), FixedPostUpdate.intern(), FixedLast.intern()]
        .contains(&schedule)
}

/// The system sets in the cloth's schedule, the clock, the settings and the messages: the
/// ground the other sub-plugins of [`BvhClothPlugin`](crate::BvhClothPlugin) stand on.
#[derive(Debug, Clone)]
pub struct ClothSchedulePlugin {
    schedule: InternedScheduleLabel,
}

impl ClothSchedulePlugin {
    /// The sets and the clock in `schedule`.
    pub fn new(schedule: impl ScheduleLabel) -> Self {
        Self { schedule: schedule.intern() }
    }
}

impl Plugin for ClothSchedulePlugin {
    fn build(&self, app: &mut App) {
        let schedule = self.schedule;
        app.register_type::<ClothSettings>()
            .register_type::<ClothClock>()
            .register_type::<ClothBackend>()
            .register_type::<ActiveClothBackend>()
            .init_resource::<ClothSettings>()
            .insert_resource(ClothClock { lockstep: is_fixed(schedule), ..default() })
            .init_resource::<ClothBackend>()
            .init_resource::<ActiveClothBackend>()
            .add_message::<ClothMessage>()
            .add_message::<ResetCloth>()
            .configure_sets(
                schedule,
                (ClothSystems::BuildColliders, ClothSystems::Prepare, ClothSystems::Step, ClothSystems::Writeback)
                    .chain(),
            )
            .add_systems(
                schedule,
                (
                    clock::advance_clock.in_set(ClothSystems::Prepare),
                    events::trigger_message_events.after(ClothSystems::Writeback),
                ),
            );
        if schedule == PostUpdate.intern() {
            app.configure_sets(
                PostUpdate,
                (ClothSystems::BuildColliders, ClothSystems::Writeback)
                    .after(TransformSystems::Propagate)
                    .before(VisibilitySystems::CheckVisibility),
            );
        } else {
            // Elsewhere the transforms are propagated first, as `TransformPlugin` does in
            // `PostUpdate`: a cloth or collider spawned or moved since is where its `Transform`
            // says, not where the last propagation left it.
            app.add_systems(
                schedule,
                (mark_dirty_trees, propagate_parent_transforms, sync_simple_transforms)
                    .chain()
                    .in_set(TransformSystems::Propagate)
                    .before(ClothSystems::BuildColliders),
            );
        }
    }
}
