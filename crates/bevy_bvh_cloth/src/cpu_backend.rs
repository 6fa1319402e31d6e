//! The CPU backend: every cloth stepped against every collider with the core's rayon stepper,
//! and the results written into the cloths' meshes.

use bevy::platform::time::Instant;

use bevy::camera::primitives::Aabb;
use bevy::ecs::schedule::{InternedScheduleLabel, ScheduleLabel};
use bevy::prelude::*;
use bvh_cloth_core::backend::ContactSolver;
use bvh_cloth_core::{ClothSim, Collider, Ticked};
use rayon::prelude::*;

use crate::backend::cpu_backend_active;
use crate::clock::ClothClock;
use crate::cloth::mesh::write_cloth_mesh;
use crate::cloth::simulation::{ClothSimulation, plan_anchors, rigid_pose};
use crate::cloth::stats::{ClothStats, update_stats};
use crate::colliders::auto::ClothCollider;
use crate::messages::ClothMessage;
use crate::schedule::ClothSystems;

/// The CPU backend, while it is the active one ([`ActiveClothBackend::Cpu`](crate::ActiveClothBackend)):
/// the cloths stepped in [`ClothSystems::Step`] and written into their meshes in
/// [`ClothSystems::Writeback`].
#[derive(Debug, Clone)]
pub struct CpuBackendPlugin {
    schedule: InternedScheduleLabel,
}

impl CpuBackendPlugin {
    /// The CPU backend's systems in `schedule`.
    pub fn new(schedule: impl ScheduleLabel) -> Self {
        Self { schedule: schedule.intern() }
    }
}

impl Plugin for CpuBackendPlugin {
    fn build(&self, app: &mut App) {
        app.add_systems(
            self.schedule,
            (
                step_cloths.after(plan_anchors).before(update_stats).in_set(ClothSystems::Step),
                write_back_cloths.in_set(ClothSystems::Writeback),
            )
                .run_if(cpu_backend_active),
        );
    }
}

/// Runs this frame's ticks for every cloth, each tick after moving the pins where
/// [`plan_anchors`](crate::cloth::simulation::plan_anchors) put them for it. The cloths without
/// self-contact are stepped side by side, one on each of rayon's threads at a time, since a
/// cloth's own parallel passes leave a thread idle much of a small cloth's tick (eight 32 x 32
/// cloths: 2.01x as fast as one after another on 2 cores, the report's `cpu_cloths` section);
/// each cloth's state is the same either way. The cloths with self-contact are stepped together
/// ([`ClothSim::tick_together`]), so that they also keep off each other.
pub(crate) fn step_cloths(
    clock: Res<ClothClock>,
    colliders: Query<&ClothCollider>,
    mut cloths: Query<(Entity, &mut ClothSimulation, &GlobalTransform)>,
    mut stats: ResMut<ClothStats>,
    mut messages: MessageWriter<ClothMessage>,
    mut contact: Local<ContactSolver>,
) {
    let start = Instant::now();
    let ticks = clock.ticks as usize;
    // Cheap copies: the sphere trees are shared, only the poses are per frame.
    let colliders: Vec<Collider> = colliders.iter().map(|c| c.collider().clone()).collect();
    let (mut alone, mut together) = (Vec::new(), Vec::new());
    for (entity, state, transform) in &mut cloths {
        if ticks == 0 {
            continue;
        }
        if state.sim.params().self_contact.is_some() {
            together.push((entity, state, transform));
        } else {
            alone.push((entity, state, transform));
        }
    }
    let faults: Vec<Faults> = alone
        .par_iter_mut()
        .map(|(_, state, _)| {
            let state: &mut ClothSimulation = state;
            let mut faults = Faults::default();
            for k in 0..ticks {
                if let Some(targets) = state.anchor_targets.get(k) {
                    state.sim.move_pins(targets);
                }
                faults.add(state.sim.tick(clock.tick_seconds, &colliders));
            }
            faults
        })
        .collect();
    for ((entity, mut state, transform), faults) in alone.into_iter().zip(faults) {
        finish_ticks(entity, &mut state, faults.particles(), transform, &mut messages);
    }
    if !together.is_empty() {
        let mut faults = vec![Faults::default(); together.len()];
        for k in 0..ticks {
            let mut sims: Vec<&mut ClothSim> = Vec::with_capacity(together.len());
            for (_, state, _) in &mut together {
                let state: &mut ClothSimulation = state;
                if let Some(targets) = state.anchor_targets.get(k) {
                    state.sim.move_pins(targets);
                }
                sims.push(&mut state.sim);
            }
            let (ticked, _) = ClothSim::tick_together(&mut sims, clock.tick_seconds, &colliders, &mut contact);
            for (faults, ticked) in faults.iter_mut().zip(ticked) {
                faults.add(ticked);
            }
        }
        for ((entity, mut state, transform), faults) in together.into_iter().zip(faults) {
            finish_ticks(entity, &mut state, faults.particles(), transform, &mut messages);
        }
    }
    stats.step_time = start.elapsed();
}

/// What a frame's ticks of one cloth went through: the particles they quarantined, counted
/// per substep as the GPU counts them, and those the last tick left non-finite.
#[derive(Clone, Copy, Debug, Default)]
struct Faults {
    quarantined: usize,
    non_finite: usize,
}

impl Faults {
    fn add(&mut self, ticked: Ticked) {
        self.quarantined += ticked.quarantined;
        self.non_finite = ticked.non_finite;
    }

    /// The particles to report: quarantined or left non-finite.
    fn particles(&self) -> usize {
        self.quarantined + self.non_finite
    }
}

/// Marks a stepped cloth for write-back, and resets it if its ticks quarantined particles or
/// left them non-finite (`faulty` of them).
fn finish_ticks(
    entity: Entity,
    state: &mut ClothSimulation,
    faulty: usize,
    transform: &GlobalTransform,
    messages: &mut MessageWriter<ClothMessage>,
) {
    state.dirty = true;
    if faulty > 0 {
        let particles = u32::try_from(faulty).unwrap_or(u32::MAX);
        state.diverged(entity, particles, rigid_pose(transform), messages);
    }
}

/// Writes every cloth that moved into its mesh, and sets its bounds for frustum culling.
pub(crate) fn write_back_cloths(
    mut meshes: ResMut<Assets<Mesh>>,
    mut cloths: Query<(&mut ClothSimulation, &GlobalTransform, Option<&mut Aabb>, Entity)>,
    mut commands: Commands,
) {
    for (mut state, transform, aabb, entity) in &mut cloths {
        if !state.dirty {
            continue;
        }
        let Some(mut mesh) = meshes.get_mut(&state.mesh) else {
            continue;
        };
        let Some(bounds) = write_cloth_mesh(&mut mesh, state.sim(), transform) else {
            continue;
        };
        state.dirty = false;
        match aabb {
            Some(mut aabb) => *aabb = bounds,
            None => {
                commands.entity(entity).try_insert(bounds);
            }
        }
    }
}
