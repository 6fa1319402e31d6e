//! Extraction (`ExtractSchedule`): this frame's ticks, each cloth's parameters, pins, pose and
//! mesh, and every collider's pose copied into [`GpuClothWorld`]; and the fault counts,
//! states and step times that have arrived sent back to the main world.

use std::sync::atomic::Ordering;

use bevy::prelude::*;
use bevy::render::{Extract, MainWorld};

use super::world::{ExtractedCloth, GpuClothWorld};
use super::{GpuClothDiverged, RenderTicks};
use crate::clock::ClothClock;
use crate::cloth::simulation::ClothSimulation;
use crate::cloth::stats::ClothStats;
use crate::colliders::auto::ClothCollider;
use crate::render::readback::{ClothReadback, GpuClothState};
use crate::wind::WindSources;

/// What [`extract_cloths`] reads of each cloth entity.
pub(super) type ClothToExtract =
    (Entity, &'static ClothSimulation, &'static GlobalTransform, &'static Mesh3d, Has<ClothReadback>);

pub(super) fn extract_cloths(
    mut world: ResMut<GpuClothWorld>,
    clock: Extract<Res<ClothClock>>,
    render_ticks: Extract<Res<RenderTicks>>,
    cloths: Extract<Query<ClothToExtract>>,
    colliders: Extract<Query<(Entity, &ClothCollider)>>,
    sources: Extract<Res<WindSources>>,
) {
    world.extracted_skin_poses.clear();
    let poses = colliders.iter().map(|(_, c)| c.gpu_skin_pose().cloned());
    world.extracted_skin_poses.extend(poses);
    world.wind_sources.clone_from(&sources.0);
    world.ticks = render_ticks.ticks;
    world.total_ticks = clock.total_ticks;
    world.tick_seconds = clock.tick_seconds;
    let extracted = cloths
        .iter()
        .map(|(entity, state, transform, mesh, read_back)| {
            let known = world.cloths.get(&entity).map(|c| c.generation).or(world.refused.get(&entity).copied());
            let known_pins = world.cloths.get(&entity).map(|c| c.pins_generation);
            let sim = state.sim();
            ExtractedCloth {
                entity,
                generation: state.generation,
                fresh: (known != Some(state.generation)).then(|| sim.clone()),
                pins: (known_pins != Some(state.pins_generation)).then(|| (sim.pins().to_vec(), sim.tethers().clone())),
                pins_generation: state.pins_generation,
                params: sim.params().clone(),
                wind: *sim.wind(),
                anchor_targets: render_ticks.anchor_targets.get(&entity).cloned().unwrap_or_default(),
                mesh: mesh.id(),
                mesh_to_world: transform.affine(),
                read_back,
            }
        })
        .collect();
    world.extracted = extracted;
    (world.collider_entities, world.extracted_colliders) =
        colliders.iter().map(|(entity, c)| (entity, c.collider().clone())).unzip();
}

/// Sends the fault counts that have arrived, where non-zero, and the read-back states to the
/// main world, and puts the step time that has arrived in its [`ClothStats`].
pub(super) fn report_faults(mut main_world: ResMut<MainWorld>, world: Res<GpuClothWorld>) {
    if let Some((timer, ticks)) = &world.step_timer
        && let Some(time) = timer.take()
        && let Some(mut stats) = main_world.get_resource_mut::<ClothStats>()
    {
        stats.gpu_time = Some((time, ticks.load(Ordering::Relaxed)));
    }
    for (&entity, render) in &world.cloths {
        if let Some(particles @ 1..) = render.faults.take() {
            main_world.write_message(GpuClothDiverged { entity, generation: render.generation, particles });
        }
        if let Some((state, [ticks, ticks_run])) = &render.state
            && let Some(particles) = state.take()
        {
            main_world.write_message(GpuClothState {
                entity,
                generation: render.generation,
                ticks: ticks.load(Ordering::Relaxed),
                ticks_run: ticks_run.load(Ordering::Relaxed),
                particles,
            });
        }
    }
}
