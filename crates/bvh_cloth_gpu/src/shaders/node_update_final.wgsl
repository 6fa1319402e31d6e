// The last stage of a substep, fused with the collision response: RK4's fourth stage (or, for
// a semi-implicit Euler cloth, the state node_update's stage 0 integrated), a particle whose
// new state is not finite held at its last finite state (quarantine), then the response
// against every collider, written over the substep's start state in place (each thread reads
// and writes only its own particle there).

#import bvh_cloth::types::{GpuParticle, frame, step, thread_index, all_finite}
#import bvh_cloth::springs::{source, particle_info, cloths, acceleration}
#import bvh_cloth::collision::collide
#import bvh_cloth::constants::{NO_CLOTH, INTEGRATOR_EULER, INTEGRATOR_BLOCK_DESCENT}

@group(0) @binding(9) var<storage, read_write> state: array<GpuParticle>;
@group(0) @binding(10) var<storage, read> slopes: array<GpuParticle>;

@compute @workgroup_size(8, 8, 1)
fn node_update_final(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = thread_index(id, frame.dispatch_width);
    if (i >= frame.particle_slots) {
        return;
    }
    let c = particle_info[i].w;
    if (c == NO_CLOTH || step.substep >= cloths[c].substeps || cloths[c].integrator >= INTEGRATOR_BLOCK_DESCENT) {
        return;
    }
    let b = state[i];
    let free = b.position.w;
    var out: GpuParticle;
    if (cloths[c].integrator == INTEGRATOR_EULER) {
        out = source[i];
    } else {
        let me = source[i];
        let acc = acceleration(i, c, me);
        let kx = me.velocity.xyz * free;
        let sum = slopes[i];
        let h6 = cloths[c].h / 6.0;
        out.position = vec4(b.position.xyz + h6 * (sum.position.xyz + kx), free);
        out.velocity = vec4(b.velocity.xyz + h6 * (sum.velocity.xyz + acc), 0.0);
    }
    // Quarantine: a particle whose substep went non-finite keeps its last finite state, at rest,
    // so one bad particle cannot poison its neighbours through the springs.
    if (!(all_finite(out.position.xyz) && all_finite(out.velocity.xyz))) {
        out.position = b.position;
        out.velocity = vec4(0.0);
        atomicAdd(&cloths[c].faults, 1u);
    }
    if (free != 0.0) {
        out = collide(b.position.xyz, out, vec2(cloths[c].memberships, cloths[c].filters));
    }
    state[i] = out;
}
