// NodeUpdate: spring forces (paper eq. 1-3) and one integrator stage (eq. 4) for every particle
// of every cloth of the batch. Stages 0-2 (this file's `node_update`, the stage named by the step
// uniform) are RK4's first three; `node_update_final` is RK4's last (or semi-implicit Euler's
// landing), fused with the collision response. A cloth with fewer substeps than the batch sits
// out the rest.

#import bvh_cloth::types::{GpuParticle, BatchCloth, NO_CLOTH, INTEGRATOR_EULER, frame, step, thread_index}

@group(0) @binding(2) var<storage, read> base: array<GpuParticle>;      // state at substep start
@group(0) @binding(3) var<storage, read> source: array<GpuParticle>;    // state the slope is taken at
@group(0) @binding(4) var<storage, read_write> slope_sum: array<GpuParticle>;
@group(0) @binding(5) var<storage, read_write> stage_out: array<GpuParticle>;
// Per particle: first and past-the-last spring end (relative to its cloth's), inverse mass
// share (f32 bits), its cloth (bvh_cloth_core::gpu_layout::gpu_particle_info).
@group(0) @binding(6) var<storage, read> particle_info: array<vec4<u32>>;
// Spring ends (bvh_cloth_core::SpringEnd): other particle (relative to the cloth), kind, rest
// length bits, weight bits.
@group(0) @binding(7) var<storage, read> ends: array<vec4<u32>>;
@group(0) @binding(8) var<storage, read_write> cloths: array<BatchCloth>;

// The cloth particle i belongs to, if it is active in this substep.
fn active_cloth(i: u32) -> u32 {
    if (i >= frame.particle_slots) {
        return NO_CLOTH;
    }
    let c = particle_info[i].w;
    if (c == NO_CLOTH || step.substep >= cloths[c].substeps) {
        return NO_CLOTH;
    }
    return c;
}

// Acceleration of particle i, with its springs' other ends read at `source` (or at `base`
// when from_base), gathered as bvh_cloth_core::forces::ForceModel::band_acceleration_general;
// zero for a held particle.
fn acceleration(i: u32, c: u32, me: GpuParticle, from_base: bool) -> vec3<f32> {
    let info = particle_info[i];
    let start = cloths[c].particle_start;
    let first_end = cloths[c].ends_start;
    let p = me.position.xyz;
    var a = cloths[c].uniform_accel.xyz - cloths[c].damping * me.velocity.xyz;
    let inv_share = bitcast<f32>(info.z);
    for (var s = info.x; s < info.y; s++) {
        let e = ends[first_end + s];
        let k = cloths[c].k_over_mass[e.y] * bitcast<f32>(e.w) * inv_share;
        if (k == 0.0) {
            continue;
        }
        let rest = bitcast<f32>(e.z);
        var other: vec3<f32>;
        if (from_base) {
            other = base[start + e.x].position.xyz;
        } else {
            other = source[start + e.x].position.xyz;
        }
        let d = other - p;
        let len = sqrt(d.x * d.x + d.y * d.y + d.z * d.z);
        a += k * (1.0 - rest / max(len, 1.0e-6 * rest)) * d;
    }
    return a * me.position.w;
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
    // Which RK4 stage this is: 0, 1 or 2. Semi-implicit Euler cloths integrate in stage 2.
    let stage = step.stage;
    var out: GpuParticle;
    out.position.w = free;
    if (cloths[c].integrator == INTEGRATOR_EULER) {
        // v' = v + h a(x, v), x' = x + h v', landed in node_update_final.
        if (stage != 2u) {
            return;
        }
        let acc = acceleration(i, c, b, true);
        let v = b.velocity.xyz + h * acc;
        out.velocity = vec4(v, 0.0);
        out.position = vec4(b.position.xyz + h * v * free, free);
        stage_out[i] = out;
        return;
    }
    let me = source[i];
    let acc = acceleration(i, c, me, false);
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
