//! The GPU backend: the paper's kernels (from [`bvh_cloth_gpu`]) run in the render world every
//! frame for every cloth at once (one [`ClothBatch`]: shared buffers, one dispatch per
//! integrator stage), and `normal_shader` writes positions and normals straight into each cloth
//! mesh's vertex slab. The only thing read back is each cloth's four-byte count of quarantined
//! particles, without waiting for it.
//!
//! Per frame:
//! 0. In the main world, [`queue_render_ticks`] adds up the ticks of every run of the cloth
//!    systems since the frame began, with each cloth's pin targets for each of them (one run
//!    per frame in `PostUpdate`; none, one or several in a fixed-timestep schedule), and
//!    [`start_render_frame`] (`First`) starts the count again.
//! 1. [`extract_cloths`] (`ExtractSchedule`) copies those ticks, every cloth's parameters, the
//!    targets of its pins for each tick of the frame, its transform and mesh, and every
//!    collider's pose into [`GpuClothWorld`]; a cloth's whole state only when it was rebuilt or
//!    reset.
//! 2. [`prepare_cloths`] (`Render`, `PrepareResources`) adds new or reshaped cloths to the
//!    batch and takes out despawned ones, uploads each cloth's constants (a SpringK change is
//!    one 60-byte write) and the collider frames, and notes the pins' targets and where each
//!    mesh's vertices lie in their slab; [`prepare_cloth_bind_groups`] (`PrepareBindGroups`)
//!    uploads those and makes the bind groups that changed. The simulation itself runs once per
//!    frame, whatever the number of cameras, before the camera driver (where `bevy_hanabi`
//!    runs its particle simulation too).
//! 3. [`simulate_cloths`] (`RenderGraph`, before the camera driver) records the refit of every
//!    skinned collider the main world left to the GPU (prepared with its joint matrices by
//!    `prepare_skin_refits`), then the ticks of the whole batch, a copy of each cloth's fault
//!    count and, for cloths with [`ClothReadback`], a copy of its particles, then the writeback
//!    of all cloths (one dispatch per mesh slab); [`request_fault_reads`] (`Cleanup`, after the
//!    submit) asks for those copies to be mapped.
//! 4. A later frame's [`report_faults`] (`ExtractSchedule`) sends the counts and states that
//!    have arrived to the main world, as [`GpuClothDiverged`] and [`GpuClothState`];
//!    [`reset_diverged_cloths`] resets the diverged cloths there (which the next extract
//!    uploads), and `apply_gpu_readbacks` loads the states into their simulations.

mod extract;
mod node;
mod prepare;
pub(crate) mod readback;
mod shaders;
mod world;

use bevy::camera::visibility::NoFrustumCulling;
use bevy::core_pipeline::schedule::camera_driver;
use bevy::ecs::entity::EntityHashMap;
use bevy::ecs::schedule::{InternedScheduleLabel, ScheduleLabel};
use bevy::prelude::*;
use bevy::render::mesh::allocator::MeshAllocatorSettings;
use bevy::render::render_resource::{BufferUsages, DownlevelFlags};
use bevy::render::renderer::{RenderAdapter, RenderDevice, RenderGraph};
use bevy::render::{ExtractSchedule, Render, RenderApp, RenderSystems};
use bevy::shader::Shader;

use crate::backend::{ActiveClothBackend, ClothBackend, cpu_backend_active};
use crate::clock::ClothClock;
use crate::cloth::simulation::{ClothSimulation, plan_anchors, rigid_pose, sync_cloths, warn_stiff_cloths};
use crate::cloth::stats::update_stats;
use crate::messages::ClothMessage;
use crate::schedule::ClothSystems;
use extract::{extract_cloths, report_faults};
use node::{request_fault_reads, simulate_cloths};
use prepare::{prepare_cloth_bind_groups, prepare_cloths};
use readback::{ClothReadback, GpuClothState, apply_gpu_readbacks};
use shaders::ClothShaders;
use world::GpuClothWorld;

/// The GPU backend: chosen when the app is built if the render device runs compute shaders
/// (see [`ClothBackend`]), and then the cloths are stepped in the render world every frame.
/// Its main-world systems gather each frame's ticks and apply what the render world reports.
#[derive(Debug, Clone)]
pub struct GpuBackendPlugin {
    schedule: InternedScheduleLabel,
}

impl GpuBackendPlugin {
    /// The GPU backend's main-world systems in `schedule`.
    pub fn new(schedule: impl ScheduleLabel) -> Self {
        Self { schedule: schedule.intern() }
    }
}

impl Plugin for GpuBackendPlugin {
    fn build(&self, app: &mut App) {
        let gpu = not(cpu_backend_active);
        app.register_type::<ClothReadback>()
            .init_resource::<RenderTicks>()
            .add_message::<GpuClothDiverged>()
            .add_message::<GpuClothState>()
            .add_systems(First, start_render_frame.run_if(gpu.clone()))
            .add_systems(
                self.schedule,
                (
                    (reset_diverged_cloths, apply_gpu_readbacks)
                        .after(sync_cloths)
                        .before(warn_stiff_cloths)
                        .in_set(ClothSystems::Prepare),
                    queue_render_ticks.after(plan_anchors).before(update_stats).in_set(ClothSystems::Step),
                    gpu_cloths_skip_culling.in_set(ClothSystems::Writeback),
                )
                    .run_if(gpu),
            );
    }

    fn finish(&self, app: &mut App) {
        let requested = *app.world().resource::<ClothBackend>();
        let active = ActiveClothBackend::choose(requested, gpu_capability(app));
        app.insert_resource(active);
        if active != ActiveClothBackend::Gpu {
            return;
        }
        // The kernels' WGSL, as shader assets the render world's pipeline cache compiles.
        let Some(shaders) =
            app.world_mut().get_resource_mut::<Assets<Shader>>().map(|mut shaders| ClothShaders::add(&mut shaders))
        else {
            return;
        };
        app.insert_resource(shaders.clone());
        if let Some(render_app) = app.get_sub_app_mut(RenderApp) {
            // normal_shader writes into the mesh slabs: they must be storage buffers too.
            render_app.world_mut().resource_mut::<MeshAllocatorSettings>().extra_buffer_usages |= BufferUsages::STORAGE;
            add_render_systems(render_app, shaders);
        }
    }
}

/// What the render device offers the GPU backend: `Ok`, or why it cannot run the kernels;
/// `None` when the app does not render.
fn gpu_capability(app: &App) -> Option<Result<(), String>> {
    let render_world = app.get_sub_app(RenderApp)?.world();
    let adapter = render_world.get_resource::<RenderAdapter>()?;
    let device = render_world.get_resource::<RenderDevice>()?;
    if !adapter.get_downlevel_capabilities().flags.contains(DownlevelFlags::COMPUTE_SHADERS) {
        return Some(Err("the render device does not run compute shaders".into()));
    }
    let storage = device.limits().max_storage_buffers_per_shader_stage;
    let needed = bvh_cloth_gpu::STORAGE_BUFFERS_NEEDED;
    if storage < needed {
        return Some(Err(format!(
            "the render device allows {storage} storage buffers per shader stage, the kernels need {needed}"
        )));
    }
    Some(Ok(()))
}

/// A cloth the GPU moves keeps the bounds of its first pose on the CPU side; it opts out of
/// frustum culling instead, so that it never vanishes while in view.
fn gpu_cloths_skip_culling(
    mut commands: Commands,
    cloths: Query<Entity, (With<ClothSimulation>, Without<NoFrustumCulling>)>,
) {
    for entity in &cloths {
        commands.entity(entity).try_insert(NoFrustumCulling);
    }
}

/// Adds the render-world systems, when the GPU backend is the active one.
fn add_render_systems(render_app: &mut SubApp, shaders: ClothShaders) {
    render_app
        .insert_resource(shaders)
        .init_resource::<GpuClothWorld>()
        .add_systems(ExtractSchedule, (report_faults, extract_cloths).chain())
        .add_systems(
            Render,
            (
                prepare_cloths.in_set(RenderSystems::PrepareResources),
                prepare_cloth_bind_groups.in_set(RenderSystems::PrepareBindGroups),
                request_fault_reads.in_set(RenderSystems::Cleanup),
            ),
        )
        .add_systems(RenderGraph, simulate_cloths.before(camera_driver));
}

/// Main world: the ticks the render world runs this frame, gathered from every run of the cloth
/// systems since the frame began.
#[derive(Resource, Default)]
pub(crate) struct RenderTicks {
    ticks: u32,
    /// Each pinned cloth's pin targets for each of those ticks; a cloth that joined in a later
    /// run has empty plans (pins stay) for the ticks before it.
    anchor_targets: EntityHashMap<Vec<Vec<(u32, Vec3)>>>,
}

/// Main world, `First`: the frame's ticks start from none.
pub(crate) fn start_render_frame(mut render_ticks: ResMut<RenderTicks>) {
    render_ticks.ticks = 0;
    render_ticks.anchor_targets.clear();
}

/// Main world, after each run's anchor planning: adds the run's ticks and pin targets to the
/// frame's.
pub(crate) fn queue_render_ticks(
    clock: Res<ClothClock>,
    cloths: Query<(Entity, &ClothSimulation)>,
    mut render_ticks: ResMut<RenderTicks>,
) {
    if clock.ticks == 0 {
        return;
    }
    let before = render_ticks.ticks as usize;
    for (entity, state) in &cloths {
        if state.anchor_targets.is_empty() {
            continue;
        }
        let plans = render_ticks.anchor_targets.entry(entity).or_default();
        plans.resize(before, Vec::new());
        plans.extend(state.anchor_targets.iter().cloned());
    }
    render_ticks.ticks += clock.ticks;
}

/// A cloth whose particles went non-finite on the GPU, sent from the render world to the main
/// world.
#[derive(Message, Clone, Copy, Debug)]
pub(crate) struct GpuClothDiverged {
    entity: Entity,
    /// The [`ClothSimulation::generation`] that diverged: a report that arrives after the cloth
    /// was rebuilt or reset is stale.
    generation: u64,
    /// Particles quarantined, counted per substep.
    particles: u32,
}

/// Main world: resets each cloth the GPU reported (unless it was rebuilt or reset since) to its
/// rest pose, and says so.
pub(crate) fn reset_diverged_cloths(
    mut reports: MessageReader<GpuClothDiverged>,
    mut cloths: Query<(&mut ClothSimulation, &GlobalTransform)>,
    mut messages: MessageWriter<ClothMessage>,
) {
    for report in reports.read() {
        let Ok((mut state, transform)) = cloths.get_mut(report.entity) else { continue };
        if state.generation != report.generation {
            continue;
        }
        state.diverged(report.entity, report.particles, rigid_pose(transform), &mut messages);
    }
}
