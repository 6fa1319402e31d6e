//! Preparation (`Render`): cloths added to, reshaped in and taken out of the batch, their
//! constants, pins and colliders uploaded, skinned colliders' refits set up, and the bind
//! groups made.

use std::sync::Arc;
use std::sync::atomic::{AtomicU32, AtomicU64};

use bevy::mesh::VertexFormat;
use bevy::prelude::*;
use bevy::render::mesh::RenderMesh;
use bevy::render::mesh::allocator::MeshAllocator;
use bevy::render::render_asset::RenderAssets;
use bevy::render::render_resource::PipelineCache;
use bevy::render::renderer::{RenderDevice, RenderQueue};
use bvh_cloth_core::{Integrator, Lbvh};
use bvh_cloth_gpu::layout::GpuMeshWriteback;
use bvh_cloth_gpu::{
    ClothBatch, ClothKernels, FaultReadback, GpuColliders, ParticleReadback, PassTimer, SkinRefit, wgpu,
};

use super::shaders::{ClothShaders, QueuedKernels};
use super::world::{GpuClothWorld, GpuSkin, RenderCloth};

/// Word offsets of the position and normal in a mesh's vertices, and its stride in words;
/// `None` unless both are `Float32x3`.
pub(super) fn vertex_words(mesh: &RenderMesh) -> Option<(u32, u32, u32)> {
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
pub(super) fn prepare_cloths(
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
    if world.batch.is_none() {
        world.step_timer = PassTimer::new(device, &queue).map(|timer| (timer, AtomicU32::new(0)));
    }
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
                    pins_generation: render.pins_generation,
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
                        pins_generation: cloth.pins_generation,
                        faults: FaultReadback::new(device),
                        ticks_run: 0,
                        state: None,
                        self_contact: false,
                        aerodynamics: false,
                        multigrid: false,
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
        // Pins changed on the running cloth (a new cloth's slot has its pins already).
        if let Some((pins, tethers)) = cloth.pins
            && let Err(error) = batch.set_pins(device, &queue, render.id, &pins, tethers)
        {
            error!("Cloth on {}: its new pins cannot run on the GPU: {error}; it keeps its old ones", cloth.entity);
        }
        render.pins_generation = cloth.pins_generation;
        let particles = batch.topology(render.id).map_or(0, |t| t.len());
        if !cloth.read_back {
            render.state = None;
        } else if render.state.is_none() {
            render.state = Some((ParticleReadback::new(device, particles), [AtomicU64::new(0), AtomicU64::new(0)]));
        }
        render.ticks_run += u64::from(world.ticks);
        batch.set_params(&queue, render.id, &cloth.params, world.tick_seconds.max(f32::MIN_POSITIVE));
        render.multigrid = cloth.params.integrator == Integrator::Multigrid;
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
pub(super) fn prepare_skin_refits(
    world: &mut GpuClothWorld,
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    rebuilt: bool,
) {
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
pub(super) fn prepare_cloth_bind_groups(
    mut world: ResMut<GpuClothWorld>,
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
) {
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
    match batch.multigrid_error() {
        Some(error) if !world.multigrid_refused => {
            let entities: Vec<Entity> = world.cloths.iter().filter(|(_, c)| c.multigrid).map(|(e, _)| *e).collect();
            error!(
                "Cloths on {entities:?}: the multigrid correction cannot run on this device ({error}); on the GPU \
                 they step as block descent with one sweep (ClothBackend::Cpu runs it)"
            );
            world.multigrid_refused = true;
        }
        Some(_) => {}
        None => world.multigrid_refused = false,
    }
}
