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

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use bevy::core_pipeline::schedule::camera_driver;
use bevy::ecs::entity::EntityHashMap;
use bevy::mesh::VertexFormat;
use bevy::prelude::*;
use bevy::render::mesh::RenderMesh;
use bevy::render::mesh::allocator::MeshAllocator;
use bevy::render::render_asset::RenderAssets;
use bevy::render::render_resource::{
    BindGroupLayoutDescriptor, CachedComputePipelineId, CachedPipelineState, ComputePipelineDescriptor, PipelineCache,
};
use bevy::render::renderer::{RenderContext, RenderDevice, RenderGraph, RenderQueue};
use bevy::render::{Extract, ExtractSchedule, MainWorld, Render, RenderSystems};
use bevy::shader::Shader;
use bvh_cloth_core::{Affine3A, ClothParams, ClothSim, Collider, Lbvh, SkinnedSpheres, Wind, WindSource};
use bvh_cloth_gpu::layout::GpuMeshWriteback;
use bvh_cloth_gpu::{
    CONSTANTS_FILE, ClothBatch, ClothId, ClothKernels, FaultReadback, GpuColliders, KERNEL_COUNT, ParticleReadback,
    SHADER_FILES, SkinRefit, shared_constants, wgpu,
};

use crate::clock::ClothClock;
use crate::collider::ClothCollider;
use crate::messages::ClothMessage;
use crate::readback::{ClothReadback, GpuClothState};
use crate::simulation::{ClothSimulation, rigid_pose};
use crate::wind::WindSources;

/// The kernels' WGSL files as shader assets, one per [`SHADER_FILES`] entry, then the module of
/// the constants they share with the core, held for the app's lifetime: the pipeline cache
/// compiles the kernels from them, resolving their imports.
#[derive(Resource, Clone)]
pub(crate) struct ClothShaders(Vec<Handle<Shader>>);

impl ClothShaders {
    /// Adds the files to `shaders`.
    pub(crate) fn add(shaders: &mut Assets<Shader>) -> Self {
        let constants = Shader::from_wgsl(shared_constants(), format!("bvh_cloth_gpu/{CONSTANTS_FILE}"));
        let files = SHADER_FILES.iter().map(|(name, text)| Shader::from_wgsl(*text, format!("bvh_cloth_gpu/{name}")));
        Self(files.chain([constants]).map(|shader| shaders.add(shader)).collect())
    }

    fn file(&self, name: &str) -> Option<Handle<Shader>> {
        SHADER_FILES.iter().position(|(file, _)| *file == name).map(|k| self.0[k].clone())
    }
}

/// The kernels' pipelines, queued on Bevy's pipeline cache (compiled off the render thread),
/// and their bind group layouts.
struct QueuedKernels {
    pipelines: [CachedComputePipelineId; KERNEL_COUNT],
    layouts: [BindGroupLayoutDescriptor; KERNEL_COUNT],
}

impl QueuedKernels {
    fn queue(cache: &PipelineCache, shaders: &ClothShaders) -> Option<Self> {
        let descriptors = ClothKernels::descriptors();
        let layouts = descriptors
            .clone()
            .map(|kernel| BindGroupLayoutDescriptor::new(format!("bvh_cloth_{}", kernel.entry_point), &kernel.layout));
        let mut pipelines = Vec::with_capacity(KERNEL_COUNT);
        for (kernel, layout) in descriptors.iter().zip(&layouts) {
            pipelines.push(cache.queue_compute_pipeline(ComputePipelineDescriptor {
                label: Some(format!("bvh_cloth_{}", kernel.entry_point).into()),
                layout: vec![layout.clone()],
                immediate_size: 0,
                shader: shaders.file(kernel.file)?,
                shader_defs: Vec::new(),
                entry_point: Some(kernel.entry_point.into()),
                zero_initialize_workgroup_memory: false,
            }));
        }
        Some(Self { pipelines: pipelines.try_into().ok()?, layouts })
    }

    /// The kernels once every pipeline is compiled; `Err` with the reason if one failed.
    fn ready(&self, cache: &PipelineCache) -> Result<Option<ClothKernels>, String> {
        for &id in &self.pipelines {
            if let CachedPipelineState::Err(error) = cache.get_compute_pipeline_state(id) {
                return Err(error.to_string());
            }
        }
        let mut pipelines = Vec::with_capacity(KERNEL_COUNT);
        for &id in &self.pipelines {
            let Some(pipeline) = cache.get_compute_pipeline(id) else { return Ok(None) };
            pipelines.push((**pipeline).clone());
        }
        let Ok(pipelines) = pipelines.try_into() else { return Ok(None) };
        let layouts = self.layouts.clone().map(|layout| (*cache.get_bind_group_layout(&layout)).clone());
        Ok(Some(ClothKernels::from_parts(pipelines, layouts)))
    }
}

/// Adds the render-world systems. Called by the plugin when the GPU backend is active.
pub(crate) fn add_render_systems(render_app: &mut SubApp, shaders: ClothShaders) {
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

/// One cloth as extracted this frame.
struct ExtractedCloth {
    entity: Entity,
    generation: u64,
    /// The whole state, when the render world does not have this generation yet.
    fresh: Option<ClothSim>,
    params: ClothParams,
    /// Its ambient wind (the sources are the world's).
    wind: Wind,
    /// Where the pins go in each of this frame's ticks.
    anchor_targets: Vec<Vec<(u32, Vec3)>>,
    mesh: AssetId<Mesh>,
    mesh_to_world: Affine3A,
    /// Whether gameplay reads this cloth's state back ([`ClothReadback`]).
    read_back: bool,
}

/// A cloth in the render world: its place in the batch and its readbacks.
struct RenderCloth {
    id: ClothId,
    generation: u64,
    faults: FaultReadback,
    /// Ticks run since the cloth was added or its state uploaded, this frame's included.
    ticks_run: u64,
    /// The state read back for gameplay, and the clock's ticks and the cloth's ticks run at the
    /// copy in flight.
    state: Option<(ParticleReadback, [AtomicU64; 2])>,
    /// Whether its parameters ask for self-contact, and for drag or lift.
    self_contact: bool,
    aerodynamics: bool,
}

/// The render world's cloth state.
#[derive(Resource, Default)]
pub(crate) struct GpuClothWorld {
    kernels: Option<ClothKernels>,
    /// The kernels while the pipeline cache compiles them.
    queued: Option<QueuedKernels>,
    /// Every cloth's GPU state.
    batch: Option<ClothBatch>,
    /// The kernels could not be built; said once.
    failed: bool,
    /// The colliders, keyed by their (shared) trees. Holding the trees keeps them alive, so an
    /// identical pointer always means the same tree.
    colliders: Option<(Vec<Option<Arc<Lbvh>>>, GpuColliders)>,
    cloths: EntityHashMap<RenderCloth>,
    /// Cloths the device refused (too big for it), with the generation refused: said once, and
    /// tried again only when the cloth changes.
    refused: EntityHashMap<u64>,
    /// This frame's input.
    ticks: u32,
    /// Ticks run since start-up, this frame's included.
    total_ticks: u64,
    tick_seconds: f32,
    /// This frame's wind sources.
    wind_sources: Vec<WindSource>,
    extracted: Vec<ExtractedCloth>,
    extracted_colliders: Vec<Collider>,
    /// Their entities, in the same order.
    collider_entities: Vec<Entity>,
    /// Each extracted collider's joint matrices and clearance, when it is skinned and refitted
    /// here on the GPU.
    extracted_skin_poses: Vec<Option<(Vec<Affine3A>, f32)>>,
    /// The skinned colliders refitted on the GPU this frame, keyed by their (shared) skins.
    skin_refits: Vec<GpuSkin>,
    /// Skins whose refit the device refused, said once.
    refused_skins: Vec<Arc<SkinnedSpheres>>,
    /// Self-contact's buffers did not fit the device: said once, until they fit again.
    contact_refused: bool,
    /// The air's buffer did not fit the device: said once, until it fits again.
    air_refused: bool,
}

/// A skinned collider refitted on the GPU: its skin, its refit, and where the refit was bound
/// (the collider's index, its tree's offsets and its frame).
struct GpuSkin {
    skin: Arc<SkinnedSpheres>,
    refit: SkinRefit,
    bound: Option<SkinPlace>,
}

/// Where a skinned collider's refit is bound: the collider's index, its tree's node and sphere
/// offsets, and its frame.
type SkinPlace = (usize, Option<(u32, u32)>, Option<u32>);

/// What [`extract_cloths`] reads of each cloth entity.
type ClothToExtract = (Entity, &'static ClothSimulation, &'static GlobalTransform, &'static Mesh3d, Has<ClothReadback>);

fn extract_cloths(
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
            let sim = state.sim();
            ExtractedCloth {
                entity,
                generation: state.generation,
                fresh: (known != Some(state.generation)).then(|| sim.clone()),
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

/// Word offsets of the position and normal in a mesh's vertices, and its stride in words;
/// `None` unless both are `Float32x3`.
fn vertex_words(mesh: &RenderMesh) -> Option<(u32, u32, u32)> {
    let layout = &mesh.layout.0;
    let word = |id| {
        let k = layout.attribute_ids().iter().position(|&a| a == id)?;
        let attribute = layout.layout().attributes.get(k)?;
        (attribute.format == VertexFormat::Float32x3 && attribute.offset % 4 == 0)
            .then_some(attribute.offset as u32 / 4)
    };
    let stride = layout.layout().array_stride;
    if !stride.is_multiple_of(4) {
        return None;
    }
    Some((stride as u32 / 4, word(Mesh::ATTRIBUTE_POSITION.id)?, word(Mesh::ATTRIBUTE_NORMAL.id)?))
}

#[allow(clippy::too_many_arguments)]
fn prepare_cloths(
    mut world: ResMut<GpuClothWorld>,
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
    mesh_allocator: Res<MeshAllocator>,
    render_meshes: Res<RenderAssets<RenderMesh>>,
    pipeline_cache: Res<PipelineCache>,
    shaders: Res<ClothShaders>,
) {
    let world = &mut *world;
    let device = device.wgpu_device();
    if world.kernels.is_none() && !world.failed {
        // Queued on the pipeline cache, which compiles them off the render thread; the cloths
        // wait (at rest) until they are ready, a frame or a few after start-up.
        let fail = |error: String| {
            error!("bevy_bvh_cloth: the GPU kernels cannot run on this device: {error}");
            true
        };
        if let Err(error) = ClothKernels::check(device) {
            world.failed = fail(error.to_string());
        } else if world.queued.is_none() {
            world.queued = QueuedKernels::queue(&pipeline_cache, &shaders);
        }
        if let Some(queued) = &world.queued {
            match queued.ready(&pipeline_cache) {
                Ok(Some(kernels)) => world.kernels = Some(kernels),
                Ok(None) => {}
                Err(error) => world.failed = fail(error),
            }
        }
    }
    if world.kernels.is_none() {
        return;
    }

    // Colliders: new buffers when the set of trees changed, otherwise only the frames (which
    // hold the primitives' shapes).
    let trees: Vec<Option<Arc<Lbvh>>> = world.extracted_colliders.iter().map(|c| c.lbvh().cloned()).collect();
    let same_tree = |a: &Option<Arc<Lbvh>>, b: &Option<Arc<Lbvh>>| match (a, b) {
        (Some(a), Some(b)) => Arc::ptr_eq(a, b),
        (a, b) => a.is_none() && b.is_none(),
    };
    // Trees that changed with the same layout (a skinned collider's refit) are written in place.
    let changed: Option<Vec<usize>> = match &world.colliders {
        Some((old, _)) if old.len() == trees.len() => {
            Some((0..trees.len()).filter(|&k| !same_tree(&old[k], &trees[k])).collect())
        }
        _ => None,
    };
    let GpuClothWorld { colliders, extracted_colliders, .. } = &mut *world;
    let rewritten = match (colliders.as_mut(), &changed) {
        (Some((_, gpu)), Some(changed)) if changed.is_empty() => {
            gpu.update_frames(&queue, extracted_colliders);
            true
        }
        (Some((old, gpu)), Some(changed)) => {
            let done = gpu.rewrite_trees(&queue, extracted_colliders, changed);
            if done {
                *old = trees.clone();
            }
            done
        }
        _ => false,
    };
    match &mut world.colliders {
        Some(_) if rewritten => {}
        slot => {
            let gpu = GpuColliders::new(device, &world.extracted_colliders);
            for &k in gpu.left_out() {
                error!(
                    "Collider on {}: its tree does not fit the device's storage bindings beside the others; \
                     cloths on the GPU pass through it",
                    world.collider_entities[k]
                );
            }
            *slot = Some((trees, gpu));
        }
    }
    prepare_skin_refits(world, device, &queue, !rewritten);
    let batch = world.batch.get_or_insert_with(|| ClothBatch::new(device, &queue));
    // The sources were checked in the main world (`gather_wind_sources`); the clock is the CPU
    // backend's: this frame's first tick starts at its index times the tick length.
    let _ = batch.set_wind_sources(&world.wind_sources);
    let first_tick = world.total_ticks.saturating_sub(u64::from(world.ticks));
    batch.set_wind_clock(first_tick as f64 * f64::from(world.tick_seconds), world.tick_seconds, world.ticks);

    // Cloths that are gone leave the batch.
    let present: bevy::ecs::entity::EntityHashSet = world.extracted.iter().map(|c| c.entity).collect();
    world.cloths.retain(|entity, render| {
        let keep = present.contains(entity);
        if !keep {
            batch.remove(&queue, render.id);
        }
        keep
    });
    world.refused.retain(|entity, _| present.contains(entity));

    for cloth in world.extracted.drain(..) {
        let existing = world.cloths.remove(&cloth.entity);
        let render = match (existing, &cloth.fresh) {
            (Some(render), None) => Some(render),
            (Some(render), Some(sim)) if batch.topology(render.id).is_some_and(|t| Arc::ptr_eq(t, sim.topology())) => {
                // The upload clears the fault count; reads in flight are of the old state, so
                // they are dropped with their readbacks.
                batch.upload_state(&queue, render.id, sim);
                Some(RenderCloth {
                    generation: cloth.generation,
                    faults: FaultReadback::new(device),
                    ticks_run: 0,
                    state: None,
                    ..render
                })
            }
            (existing, Some(sim)) => {
                if let Some(old) = existing {
                    batch.remove(&queue, old.id);
                }
                match batch.insert(device, &queue, sim) {
                    Ok(id) => Some(RenderCloth {
                        id,
                        generation: cloth.generation,
                        faults: FaultReadback::new(device),
                        ticks_run: 0,
                        state: None,
                        self_contact: false,
                        aerodynamics: false,
                    }),
                    Err(error) => {
                        error!("Cloth on {}: cannot run on the GPU: {error}; it stays at rest", cloth.entity);
                        world.refused.insert(cloth.entity, cloth.generation);
                        None
                    }
                }
            }
            (None, None) => None,
        };
        let Some(mut render) = render else { continue };
        let particles = batch.topology(render.id).map_or(0, |t| t.len());
        if !cloth.read_back {
            render.state = None;
        } else if render.state.is_none() {
            render.state = Some((ParticleReadback::new(device, particles), [AtomicU64::new(0), AtomicU64::new(0)]));
        }
        render.ticks_run += u64::from(world.ticks);
        batch.set_params(&queue, render.id, &cloth.params, world.tick_seconds.max(f32::MIN_POSITIVE));
        render.self_contact = cloth.params.self_contact.is_some();
        render.aerodynamics = cloth.params.aerodynamics.is_active();
        batch.set_anchor_targets(render.id, &cloth.anchor_targets);
        // Checked in the main world (`gather_wind`): it cannot be refused here.
        let _ = batch.set_wind(render.id, cloth.wind);

        // Where the mesh's vertices are this frame (slabs can move).
        let layout = render_meshes.get(cloth.mesh).and_then(vertex_words);
        let slice = mesh_allocator.mesh_vertex_slice(&cloth.mesh);
        match (layout, slice) {
            (Some((stride, position, normal)), Some(slice)) => {
                let writeback =
                    GpuMeshWriteback::new(cloth.mesh_to_world, slice.range.start * stride, stride, position, normal);
                batch.set_writeback(render.id, writeback, slice.buffer);
            }
            _ => batch.clear_writeback(render.id),
        }
        world.cloths.insert(cloth.entity, render);
    }
}

/// Makes a refit for every skinned collider the main world left to the GPU (reusing last
/// frame's for the same skin), binds it where its tree now lies (again whenever the collider
/// buffers were rebuilt, `rebuilt`, or it moved), and uploads its pose. Refits of skins no
/// longer extracted are dropped.
fn prepare_skin_refits(world: &mut GpuClothWorld, device: &wgpu::Device, queue: &wgpu::Queue, rebuilt: bool) {
    let (Some(kernels), Some((_, colliders))) = (&world.kernels, &world.colliders) else { return };
    let mut refits = Vec::with_capacity(world.skin_refits.len());
    let mut previous = std::mem::take(&mut world.skin_refits);
    for (k, pose) in world.extracted_skin_poses.iter().enumerate() {
        let Some((matrices, clearance)) = pose else { continue };
        let collider = &world.extracted_colliders[k];
        let (Some(skin), Some(tree)) = (collider.skin(), collider.lbvh()) else { continue };
        let mut entry = match previous.iter().position(|g| Arc::ptr_eq(&g.skin, skin)) {
            Some(at) => previous.swap_remove(at),
            None => {
                if world.refused_skins.iter().any(|refused| Arc::ptr_eq(refused, skin)) {
                    continue;
                }
                match SkinRefit::new(device, skin, tree) {
                    Ok(refit) => GpuSkin { skin: skin.clone(), refit, bound: None },
                    Err(error) => {
                        error!(
                            "Skinned collider on {}: it cannot be refitted on this device ({error}); cloths \
                             on the GPU meet it in its bind pose",
                            world.collider_entities[k]
                        );
                        world.refused_skins.push(skin.clone());
                        continue;
                    }
                }
            }
        };
        let place = Some((k, colliders.tree_offsets(k), colliders.frame_index(k)));
        if rebuilt || entry.bound != place {
            entry.refit.bind(device, kernels, colliders, k);
            entry.bound = place;
        }
        entry.refit.write_pose(queue, matrices, *clearance);
        refits.push(entry);
    }
    world
        .refused_skins
        .retain(|refused| world.extracted_colliders.iter().any(|c| c.skin().is_some_and(|s| Arc::ptr_eq(s, refused))));
    world.skin_refits = refits;
}

/// Uploads the frame's constants and anchor targets and makes the bind groups that changed,
/// once every buffer is (re)allocated for the frame.
fn prepare_cloth_bind_groups(mut world: ResMut<GpuClothWorld>, device: Res<RenderDevice>, queue: Res<RenderQueue>) {
    let world = &mut *world;
    let (Some(kernels), Some((_, colliders)), Some(batch)) = (&world.kernels, &world.colliders, &mut world.batch)
    else {
        return;
    };
    batch.prepare(device.wgpu_device(), &queue, kernels, colliders);
    match batch.contact_error() {
        Some(error) if !world.contact_refused => {
            let entities: Vec<Entity> = world.cloths.iter().filter(|(_, c)| c.self_contact).map(|(e, _)| *e).collect();
            error!(
                "Cloths on {entities:?}: self-contact cannot run on this device ({error}); on the GPU they pass \
                 through themselves and each other (ClothBackend::Cpu runs it)"
            );
            world.contact_refused = true;
        }
        Some(_) => {}
        None => world.contact_refused = false,
    }
    match batch.air_error() {
        Some(error) if !world.air_refused => {
            let entities: Vec<Entity> = world.cloths.iter().filter(|(_, c)| c.aerodynamics).map(|(e, _)| *e).collect();
            error!(
                "Cloths on {entities:?}: drag and lift cannot run on this device ({error}); on the GPU they \
                 move as if in still air (ClothBackend::Cpu runs them)"
            );
            world.air_refused = true;
        }
        Some(_) => {}
        None => world.air_refused = false,
    }
}

fn simulate_cloths(mut render_context: RenderContext, world: Res<GpuClothWorld>) {
    let (Some(kernels), Some(batch)) = (&world.kernels, &world.batch) else { return };
    let encoder = render_context.command_encoder();
    // Skinned colliders first: the ticks meet them in this frame's pose.
    if world.skin_refits.iter().any(|g| g.refit.is_bound()) {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("bvh_cloth_skin_refit"),
            timestamp_writes: None,
        });
        for skin in &world.skin_refits {
            skin.refit.encode(&mut pass, kernels);
        }
    }
    batch.encode_ticks(encoder, kernels, world.ticks);
    for render in world.cloths.values() {
        render.faults.record(encoder, batch, render.id);
        if let Some((state, [ticks, ticks_run])) = &render.state
            && state.record(encoder, batch, render.id)
        {
            ticks.store(world.total_ticks, Ordering::Relaxed);
            ticks_run.store(render.ticks_run, Ordering::Relaxed);
        }
    }
    batch.encode_writebacks(encoder, kernels);
}

/// Asks for this frame's fault-count and state copies to be mapped, now that they are
/// submitted.
fn request_fault_reads(world: Res<GpuClothWorld>) {
    for render in world.cloths.values() {
        render.faults.submitted();
        if let Some((state, _)) = &render.state {
            state.submitted();
        }
    }
}

/// Sends the fault counts that have arrived, where non-zero, and the read-back states to the
/// main world.
fn report_faults(mut main_world: ResMut<MainWorld>, world: Res<GpuClothWorld>) {
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
