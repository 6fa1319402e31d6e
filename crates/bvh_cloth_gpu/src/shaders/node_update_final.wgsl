// The last stage of a substep, fused with the collision response: RK4's fourth stage (or, for
// a semi-implicit Euler cloth, the state node_update's stage 2 integrated), a particle whose
// new state is not finite held at its last finite state (quarantine), then the response
// against every collider, written over the substep's start state in place (each thread reads
// and writes only its own particle there).

#import bvh_cloth::types::{GpuParticle, BatchCloth, NO_CLOTH, INTEGRATOR_EULER, frame, step, thread_index, all_finite}
#import bvh_cloth::collision::collide

@group(0) @binding(19) var<storage, read> last_stage: array<GpuParticle>;
@group(0) @binding(20) var<storage, read> final_info: array<vec4<u32>>;
@group(0) @binding(21) var<storage, read> final_ends: array<vec4<u32>>;
@group(0) @binding(22) var<storage, read_write> final_cloths: array<BatchCloth>;
@group(0) @binding(9) var<storage, read_write> state: array<GpuParticle>;
@group(0) @binding(10) var<storage, read> slopes: array<GpuParticle>;

// As node_update's `acceleration`, at `last_stage`.
fn final_acceleration(i: u32, c: u32, me: GpuParticle) -> vec3<f32> {
    let info = final_info[i];
    let start = final_cloths[c].particle_start;
    let first_end = final_cloths[c].ends_start;
    let p = me.position.xyz;
    var a = final_cloths[c].uniform_accel.xyz - final_cloths[c].damping * me.velocity.xyz;
    let inv_share = bitcast<f32>(info.z);
    for (var s = info.x; s < info.y; s++) {
        let e = final_ends[first_end + s];
        let k = final_cloths[c].k_over_mass[e.y] * bitcast<f32>(e.w) * inv_share;
        if (k == 0.0) {
            continue;
        }
        let rest = bitcast<f32>(e.z);
        let d = last_stage[start + e.x].position.xyz - p;
        let len = sqrt(d.x * d.x + d.y * d.y + d.z * d.z);
        a += k * (1.0 - rest / max(len, 1.0e-6 * rest)) * d;
    }
    return a * me.position.w;
}

@compute @workgroup_size(8, 8, 1)
fn node_update_final(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = thread_index(id, frame.dispatch_width);
    if (i >= frame.particle_slots) {
        return;
    }
    let c = final_info[i].w;
    if (c == NO_CLOTH || step.substep >= final_cloths[c].substeps) {
        return;
    }
    let b = state[i];
    let free = b.position.w;
    var out: GpuParticle;
    if (final_cloths[c].integrator == INTEGRATOR_EULER) {
        out = last_stage[i];
    } else {
        let me = last_stage[i];
        let acc = final_acceleration(i, c, me);
        let kx = me.velocity.xyz * free;
        let sum = slopes[i];
        let h6 = final_cloths[c].h / 6.0;
        out.position = vec4(b.position.xyz + h6 * (sum.position.xyz + kx), free);
        out.velocity = vec4(b.velocity.xyz + h6 * (sum.velocity.xyz + acc), 0.0);
    }
    // Quarantine: a particle whose substep went non-finite keeps its last finite state, at rest,
    // so one bad particle cannot poison its neighbours through the springs.
    if (!(all_finite(out.position.xyz) && all_finite(out.velocity.xyz))) {
        out.position = b.position;
        out.velocity = vec4(0.0);
        atomicAdd(&final_cloths[c].faults, 1u);
    }
    if (free != 0.0) {
        out = collide(b.position.xyz, out);
    }
    state[i] = out;
}
