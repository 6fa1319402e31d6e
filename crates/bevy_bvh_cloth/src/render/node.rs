//! The simulation's place in the render graph, before the camera driver: the skinned
//! colliders' refits, every tick of the batch (timed where the device can), the fault and
//! state copies, the writeback; and the request to map the copies after the submit.

use std::sync::atomic::Ordering;

use bevy::prelude::*;
use bevy::render::renderer::RenderContext;
use bvh_cloth_gpu::wgpu;

use super::world::GpuClothWorld;

pub(super) fn simulate_cloths(mut render_context: RenderContext, world: Res<GpuClothWorld>) {
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
    // A frame that runs ticks is timed when no measure is in flight.
    let timer = world.step_timer.as_ref().filter(|_| world.ticks > 0);
    let writes = timer.and_then(|(timer, ticks)| {
        let writes = timer.begin()?;
        ticks.store(world.ticks, Ordering::Relaxed);
        Some(writes)
    });
    batch.encode_ticks_with(encoder, kernels, world.ticks, writes);
    if let Some((timer, _)) = timer {
        timer.record(encoder);
    }
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

/// Asks for this frame's fault-count and state copies and its step time to be mapped, now that
/// they are submitted.
pub(super) fn request_fault_reads(world: Res<GpuClothWorld>) {
    if let Some((timer, _)) = &world.step_timer {
        timer.submitted();
    }
    for render in world.cloths.values() {
        render.faults.submitted();
        if let Some((state, _)) = &render.state {
            state.submitted();
        }
    }
}
