// Anchors: at the start of each tick, every held particle of every cloth moves to where its
// anchor holds it during that tick (bvh_cloth_core::ClothSim::move_pins). The host binds that
// tick's targets at a dynamic offset.

#import bvh_cloth::types::{GpuParticle, frame, thread_index}

@group(0) @binding(13) var<storage, read_write> anchored: array<GpuParticle>;
// xyz: the target; w: the particle's index in the batch, as bits (past the particles: none).
@group(0) @binding(14) var<storage, read> anchor_targets: array<vec4<f32>>;

@compute @workgroup_size(8, 8, 1)
fn apply_anchors(@builtin(global_invocation_id) id: vec3<u32>) {
    let k = thread_index(id, frame.dispatch_width);
    if (k >= frame.anchor_count) {
        return;
    }
    let goal = anchor_targets[k];
    let i = bitcast<u32>(goal.w);
    if (i < frame.particle_slots) {
        anchored[i].position = vec4(goal.xyz, anchored[i].position.w);
    }
}
