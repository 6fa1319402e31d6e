// NodeUpdate: one of RK4's first three stages (eq. 4, the stage named by the step uniform) for
// every particle of every cloth of the batch; a semi-implicit Euler cloth integrates in stage 0,
// whose source is the substep's start state. `node_update_final` does RK4's last stage (or lands
// the Euler step), fused with the collision response. A cloth with fewer substeps than the batch
// sits out the rest.

#import bvh_cloth::types::{GpuParticle, frame, step, thread_index}
#import bvh_cloth::springs::{source, particle_info, cloths, acceleration}
#import bvh_cloth::constants::{NO_CLOTH, INTEGRATOR_EULER, INTEGRATOR_BLOCK_DESCENT}

@group(0) @binding(2) var<storage, read> base: array<GpuParticle>;      // state at substep start
@group(0) @binding(4) var<storage, read_write> slope_sum: array<GpuParticle>;
@group(0) @binding(5) var<storage, read_write> stage_out: array<GpuParticle>;

// The explicitly integrated cloth particle i belongs to, if it is active in this substep.
fn active_cloth(i: u32) -> u32 {
    if (i >= frame.particle_slots) {
        return NO_CLOTH;
    }
    let c = particle_info[i].w;
    if (c == NO_CLOTH || step.substep >= cloths[c].substeps || cloths[c].integrator >= INTEGRATOR_BLOCK_DESCENT) {
        return NO_CLOTH;
    }
    return c;
}

@compute @workgroup_size(8, 8, 1)
fn node_update(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = thread_index(id, frame.dispatch_width);
    let c = active_cloth(i);
    if (c == NO_CLOTH) {
        return;
    }
    let b = base[i];
    let free = b.position.w;
    let h = cloths[c].h;
    // Which RK4 stage this is: 0, 1 or 2.
    let stage = step.stage;
    let euler = cloths[c].integrator == INTEGRATOR_EULER;
    // A semi-implicit Euler step is taken in stage 0, whose source is the substep's start
    // state; the later stages leave its result alone.
    if (euler && stage != 0u) {
        return;
    }
    let me = source[i];
    let acc = acceleration(i, c, me);
    var out: GpuParticle;
    out.position.w = free;
    if (euler) {
        // v' = v + h a(x, v), x' = x + h v', landed in node_update_final.
        let v = b.velocity.xyz + h * acc;
        out.velocity = vec4(v, 0.0);
        out.position = vec4(b.position.xyz + h * v * free, free);
        stage_out[i] = out;
        return;
    }
    // Slope of the state: (velocity, acceleration), the velocity masked for held particles.
    let kx = me.velocity.xyz * free;
    let weight = select(2.0, 1.0, stage == 0u);
    let coef = select(0.5, 1.0, stage == 2u) * h;
    var sum = slope_sum[i];
    if (stage == 0u) {
        sum.position = vec4(kx, 0.0);
        sum.velocity = vec4(acc, 0.0);
    } else {
        sum.position = vec4(sum.position.xyz + weight * kx, 0.0);
        sum.velocity = vec4(sum.velocity.xyz + weight * acc, 0.0);
    }
    slope_sum[i] = sum;
    out.position = vec4(b.position.xyz + coef * kx, free);
    out.velocity = vec4(b.velocity.xyz + coef * acc, 0.0);
    stage_out[i] = out;
}
