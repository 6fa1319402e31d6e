// Vertex block descent (bvh_cloth_core::solver::block_descent), per substep for every block-descent
// cloth of the batch:
// - vbd_predict, one thread per particle slot: keeps the substep's start state, the inertial
//   target less the start, h v + h^2 g, and the first iterate as a displacement from the start,
//   (h v + h^2 a) / (1 + c h), with a the particle's estimate of the acceleration it follows
//   (the sweeps solve for displacements, so that f32 keeps them whatever the coordinates'
//   magnitude); in a batch with aerodynamics,
//   vbd_predict_air instead, which first gives a cloth in the wind its kick (air.wgsl);
// - vbd_solve, one dispatch per iteration and colour, one thread per particle of that colour in
//   the batch's colour list: one Newton step on the particle's block of the incremental
//   potential, against its neighbours' current displacements (no neighbour shares its colour, so
//   no thread reads what another writes);
// - for a batch with a cloth that nothing holds, vbd_drift_blocks (one workgroup per 64 particle
//   slots) and vbd_drift (one workgroup per cloth): the drift of each such cloth's centre of
//   mass, summed in two levels;
// - vbd_finish, one thread per particle slot: the drift taken back, x = x0 + d, v = d / h,
//   quarantine, the collision response from x0 to x, as node_update_final does, and the
//   particle's acceleration estimate for the next substep.
// Cloths of other integrators, and cloths past their own substeps or iterations, sit out.

#import bvh_cloth::types::{GpuParticle, ColourPass, frame, step, thread_index, all_finite}
#import bvh_cloth::springs::{particle_info, ends, cloths}
#import bvh_cloth::collision::collide
#import bvh_cloth::air::{air_cloth, air_kick_of}
#import bvh_cloth::constants::{NO_CLOTH, UNTETHERED, INTEGRATOR_BLOCK_DESCENT}

@group(0) @binding(19) var<storage, read_write> iterate: array<GpuParticle>;       // the state; during the sweeps, d = x - x0 in position.xyz
@group(0) @binding(20) var<storage, read_write> substep_start: array<GpuParticle>; // x0, v0
@group(0) @binding(21) var<storage, read_write> inertial: array<GpuParticle>;      // y - x0 in position.xyz, the estimate in velocity.x
@group(0) @binding(48) var<storage, read_write> drift_blocks: array<vec4<f32>>;   // per 64 slots: sum of m (d - d*), sum of m
@group(0) @binding(22) var<storage, read> colour_list: array<u32>;                 // particles, colour by colour
@group(0) @binding(25) var<uniform> colour_pass: ColourPass;

// The block-descent cloth particle slot i belongs to, if it is active in this substep.
fn descent_cloth(i: u32) -> u32 {
    if (i >= frame.particle_slots) {
        return NO_CLOTH;
    }
    let c = particle_info[i].w;
    if (c == NO_CLOTH || step.substep >= cloths[c].substeps || cloths[c].integrator != INTEGRATOR_BLOCK_DESCENT) {
        return NO_CLOTH;
    }
    return c;
}

// The direction of cloth c's uniform acceleration (zero when it has none) and its size:
// bvh_cloth_core::solver::block_descent::AccelAxis.
fn accel_axis(c: u32) -> vec4<f32> {
    let uniform = cloths[c].uniform_accel.xyz;
    let size = sqrt(dot(uniform, uniform));
    if (size > 0.0) {
        return vec4(uniform / size, size);
    }
    return vec4(0.0);
}

// 1 / (1 + c h) of cloth c.
fn inverse_damping(c: u32) -> f32 {
    return 1.0 / (1.0 + cloths[c].damping * cloths[c].h);
}

// The substep's start of particle i of block-descent cloth c, whose state is `me`.
fn predict(i: u32, c: u32, me: GpuParticle) {
    // The acceleration the particle followed in its last substep (vbd_finish), before the
    // target overwrites it.
    let estimate = inertial[i].velocity.x;
    substep_start[i] = me;
    let free = me.position.w;
    let h = cloths[c].h;
    // bvh_cloth_core::solver::block_descent::first_iterate: a falling particle starts where gravity
    // takes it, one at rest where it was.
    var x = vec3(0.0);
    var y = vec3(0.0);
    if (free != 0.0) {
        y = h * me.velocity.xyz + (h * h) * cloths[c].uniform_accel.xyz;
        let accel = accel_axis(c).xyz * estimate;
        x = (h * me.velocity.xyz + (h * h) * accel) * inverse_damping(c);
    }
    var goal: GpuParticle;
    goal.position = vec4(y, free);
    goal.velocity = vec4(0.0);
    inertial[i] = goal;
    iterate[i] = GpuParticle(vec4(x, free), me.velocity);
}

@compute @workgroup_size(8, 8, 1)
fn vbd_predict(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = thread_index(id, frame.dispatch_width);
    let c = descent_cloth(i);
    if (c == NO_CLOTH) {
        return;
    }
    predict(i, c, iterate[i]);
}

// vbd_predict after the aerodynamic kick of a free particle of a cloth with drag or lift (what
// air_kick does for the explicit integrators): one dispatch for both.
@compute @workgroup_size(8, 8, 1)
fn vbd_predict_air(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = thread_index(id, frame.dispatch_width);
    let c = descent_cloth(i);
    if (c == NO_CLOTH) {
        return;
    }
    var me = iterate[i];
    if (me.position.w != 0.0 && air_cloth(i) != NO_CLOTH) {
        me.velocity = vec4(me.velocity.xyz + air_kick_of(i, c, me.velocity.xyz), me.velocity.w);
    }
    predict(i, c, me);
}

// bvh_cloth_core::solver::block_descent::descend: the new displacement of particle i (of cloth c)
// from its start, at displacement x, with the same arithmetic in the same order.
fn descend(i: u32, c: u32, x: vec3<f32>, start: vec3<f32>, goal: vec3<f32>) -> vec3<f32> {
    let info = particle_info[i];
    let first = cloths[c].particle_start;
    let first_end = cloths[c].ends_start;
    let h = cloths[c].h;
    let h2 = h * h;
    let ch = cloths[c].damping * h;
    var g = (x - goal) + ch * x;
    var diag = vec3(1.0 + ch);
    var off = vec3(0.0);
    let inv_share = bitcast<f32>(info.z);
    for (var s = info.x; s < info.y; s++) {
        let spring = ends[first_end + s];
        let k = cloths[c].k_over_mass[spring.y] * bitcast<f32>(spring.w) * inv_share * h2;
        if (k == 0.0) {
            continue;
        }
        let rest = bitcast<f32>(spring.z);
        let other = first + spring.x;
        let delta = (substep_start[other].position.xyz - start) + (iterate[other].position.xyz - x);
        let len = sqrt(dot(delta, delta));
        let inv_l = 1.0 / max(len, 1.0e-6 * rest);
        let stretch = 1.0 - rest * inv_l;
        g -= k * stretch * delta;
        let sp = max(stretch, 0.0);
        let u = delta * inv_l;
        let t = k * (1.0 - sp);
        diag += k * sp + t * (u * u);
        off += t * (u.xxy * u.yzz);
    }
    let a = diag.x;
    let d = diag.y;
    let f = diag.z;
    let b = off.x;
    let cc = off.y;
    let e = off.z;
    let ca = d * f - e * e;
    let cb = cc * e - b * f;
    let ccf = b * e - cc * d;
    let cd = a * f - cc * cc;
    let ce = b * cc - a * e;
    let cf = a * d - b * b;
    let det = a * ca + b * cb + cc * ccf;
    let step_x = vec3(
        ca * g.x + cb * g.y + ccf * g.z,
        cb * g.x + cd * g.y + ce * g.z,
        ccf * g.x + ce * g.y + cf * g.z,
    ) / det;
    return x - step_x;
}

@compute @workgroup_size(8, 8, 1)
fn vbd_solve(@builtin(global_invocation_id) id: vec3<u32>) {
    let t = thread_index(id, colour_pass.dispatch_width);
    if (t >= colour_pass.count) {
        return;
    }
    let i = colour_list[colour_pass.start + t];
    let c = descent_cloth(i);
    if (c == NO_CLOTH || colour_pass.iteration >= cloths[c].iterations) {
        return;
    }
    let me = iterate[i];
    if (me.position.w == 0.0) {
        return;
    }
    let x = descend(i, c, me.position.xyz, substep_start[i].position.xyz, inertial[i].position.xyz);
    iterate[i].position = vec4(x, me.position.w);
}

// Sums of the drift terms of the 64 threads of a workgroup.
var<workgroup> drift_sums: array<vec4<f32>, 64>;

// The sum of every lane's drift_sums entry, for every lane: a tree over the workgroup. Call it
// from uniform control flow.
fn sum_lanes(lane: u32) -> vec4<f32> {
    for (var width = 32u; width > 0u; width >>= 1u) {
        workgroupBarrier();
        if (lane < width) {
            drift_sums[lane] += drift_sums[lane + width];
        }
    }
    workgroupBarrier();
    return drift_sums[0];
}

// Particle i's term of cloth c's centre-of-mass drift, m (d - d*) and m, with m its mass share, d
// its displacement and d* = (h v0 + h^2 g) / (1 + c h)
// (bvh_cloth_core::solver::block_descent::centre_of_mass_drift);
// zero for a held particle.
fn drift_term(i: u32, c: u32) -> vec4<f32> {
    let me = iterate[i];
    if (me.position.w == 0.0) {
        return vec4(0.0);
    }
    let b = substep_start[i];
    let h = cloths[c].h;
    let fall = (h * h) * cloths[c].uniform_accel.xyz;
    let off = me.position.xyz - (h * b.velocity.xyz + fall) * inverse_damping(c);
    // A particle that went non-finite is quarantined after the sums (vbd_finish); it must not
    // carry the rest of the cloth with it.
    if (!all_finite(off)) {
        return vec4(0.0);
    }
    let m = 1.0 / bitcast<f32>(particle_info[i].z);
    return vec4(m * off, m);
}

// The block-descent cloth particle slot i belongs to, if it is active in this substep and
// nothing holds it.
fn free_body(i: u32) -> u32 {
    let c = descent_cloth(i);
    if (c == NO_CLOTH || cloths[c].free_body == 0u) {
        return NO_CLOTH;
    }
    return c;
}

// The first level of the drift sums: block b of 64 slots sums the terms of the slots that
// belong to the cloth of its first slot. vbd_drift adds the slots of a cloth that starts
// inside a block led by another.
@compute @workgroup_size(64, 1, 1)
fn vbd_drift_blocks(
    @builtin(workgroup_id) group: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) lane: u32,
) {
    let block = group.y * groups.x + group.x;
    let first = block * 64u;
    let owner = free_body(first);
    var term = vec4(0.0);
    if (owner != NO_CLOTH && free_body(first + lane) == owner) {
        term = drift_term(first + lane, owner);
    }
    drift_sums[lane] = term;
    let total = sum_lanes(lane);
    if (lane == 0u && first < frame.particle_slots) {
        drift_blocks[block] = total;
    }
}

// The second level: workgroup c sums cloth c's blocks and the slots of its first block when
// another cloth leads that block, and keeps the drift in cloths[c].drift.
@compute @workgroup_size(64, 1, 1)
fn vbd_drift(@builtin(workgroup_id) group: vec3<u32>, @builtin(local_invocation_index) lane: u32) {
    let c = group.x;
    var summed = false;
    var term = vec4(0.0);
    if (c < arrayLength(&cloths) && cloths[c].particle_count > 0u) {
        let start = cloths[c].particle_start;
        summed = free_body(start) == c;
        if (summed) {
            let end = start + cloths[c].particle_count;
            let first_block = (start + 63u) / 64u;
            let head = start + lane;
            if (head < min(first_block * 64u, end)) {
                term = drift_term(head, c);
            }
            for (var b = first_block + lane; b * 64u < end; b += 64u) {
                term += drift_blocks[b];
            }
        }
    }
    drift_sums[lane] = term;
    let total = sum_lanes(lane);
    if (summed && lane == 0u) {
        var drift = vec3(0.0);
        if (total.w > 0.0) {
            drift = total.xyz / total.w;
        }
        cloths[c].drift = vec4(drift, 0.0);
    }
}

@compute @workgroup_size(8, 8, 1)
fn vbd_finish(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = thread_index(id, frame.dispatch_width);
    let c = descent_cloth(i);
    if (c == NO_CLOTH) {
        return;
    }
    let b = substep_start[i];
    let free = b.position.w;
    var out = iterate[i];
    if (free == 0.0) {
        iterate[i] = b;
        return;
    }
    // The springs are internal forces: a cloth that nothing holds keeps the centre of mass
    // that inertia, damping and the uniform acceleration give it.
    var d = out.position.xyz;
    if (cloths[c].free_body != 0u) {
        d = d - cloths[c].drift.xyz;
    }
    let h = cloths[c].h;
    let inv_h = 1.0 / h;
    out.position = vec4(b.position.xyz + d, out.position.w);
    out.velocity = vec4(d * inv_h, 0.0);
    // bvh_cloth_core::cloth::tethers: beyond its tether's reach of its pin (held, so at the substep's
    // start), a particle loses its velocity away from the pin.
    let scale = cloths[c].tether_scale;
    if (scale > 0.0) {
        let first = cloths[c].particle_start;
        let tether = ends[cloths[c].tether_start + (i - first)];
        if (tether.x != UNTETHERED) {
            let limit = scale * bitcast<f32>(tether.z);
            let d = out.position.xyz - substep_start[first + tether.x].position.xyz;
            let len2 = dot(d, d);
            if (len2 > limit * limit) {
                let away = d / sqrt(len2);
                out.velocity = vec4(out.velocity.xyz - max(dot(out.velocity.xyz, away), 0.0) * away, 0.0);
            }
        }
    }
    // Quarantine, as node_update_final: a particle whose substep went non-finite keeps its last
    // finite state, at rest.
    if (!(all_finite(out.position.xyz) && all_finite(out.velocity.xyz))) {
        out.position = b.position;
        out.velocity = vec4(0.0);
        atomicAdd(&cloths[c].faults, 1u);
    }
    let done = collide(b.position.xyz, out, vec2(cloths[c].memberships, cloths[c].filters));
    iterate[i] = done;
    // bvh_cloth_core::solver::block_descent::AccelAxis::estimate.
    let axis = accel_axis(c);
    let along = dot(done.velocity.xyz / inverse_damping(c) - b.velocity.xyz, axis.xyz) / h;
    inertial[i].velocity = vec4(clamp(along, 0.0, axis.w), 0.0, 0.0, 0.0);
}
