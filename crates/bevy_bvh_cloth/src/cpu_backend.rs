//! The CPU backend: every cloth stepped against every collider with the core's rayon stepper,
//! and the results written into the cloths' meshes.

use std::time::Instant;

use bevy::camera::primitives::Aabb;
use bevy::prelude::*;
use bvh_cloth_core::Collider;

use crate::clock::ClothClock;
use crate::cloth_mesh::write_cloth_mesh;
use crate::collider::ClothCollider;
use crate::messages::ClothMessage;
use crate::simulation::{ClothSimulation, rigid_pose};
use crate::stats::ClothStats;

/// Runs this frame's ticks for every cloth, each tick after moving the pins where
/// [`plan_anchors`](crate::simulation::plan_anchors) put them for it.
pub(crate) fn step_cloths(
    clock: Res<ClothClock>,
    colliders: Query<&ClothCollider>,
    mut cloths: Query<(Entity, &mut ClothSimulation, &GlobalTransform)>,
    mut stats: ResMut<ClothStats>,
    mut messages: MessageWriter<ClothMessage>,
) {
    let start = Instant::now();
    // Cheap copies: the sphere trees are shared, only the poses are per frame.
    let colliders: Vec<Collider> = colliders.iter().map(|c| c.collider().clone()).collect();
    let ticks = clock.ticks;
    for (entity, mut state, transform) in &mut cloths {
        if ticks == 0 {
            continue;
        }
        let state = &mut *state;
        for k in 0..ticks as usize {
            if let Some(targets) = state.anchor_targets.get(k) {
                state.sim.move_pins(targets);
            }
            state.sim.tick(clock.tick_seconds, &colliders);
        }
        state.dirty = true;
        if !state.sim.is_finite() {
            let particles = u32::try_from(state.sim.non_finite_particles()).unwrap_or(u32::MAX);
            state.diverged(entity, particles, rigid_pose(transform), &mut messages);
        }
    }
    stats.step_time = start.elapsed();
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
