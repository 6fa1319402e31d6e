// Vertex block descent (bvh_cloth_core::solver::block_descent), per substep for every block-descent
// and multigrid cloth of the batch:
// - vbd_predict, one thread per particle slot: keeps the substep's start state, the inertial
//   target less the start, h v + h^2 g, and the first iterate as a displacement from the start,
//   (h v + h^2 a) / (1 + c h), with a the particle's estimate of the acceleration it follows
//   (the sweeps solve for displacements, so that f32 keeps them whatever the coordinates'
//   magnitude); for a multigrid cloth's BDF2 substep (mg_begin, before it, chose the step), the
//   same from BDF2's start and velocity; in a batch with aerodynamics,
//   vbd_predict_air instead, which first gives a cloth in the wind its kick (air.wgsl);
// - vbd_solve, one dispatch per iteration and colour, one thread per particle of that colour in
//   the batch's colour list: one Newton step on the particle's block of the incremental
//   potential, against its neighbours' current displacements (no neighbour shares its colour, so
//   no thread reads what another writes);
// - for a batch with a cloth that nothing holds, vbd_drift_blocks (one workgroup per 64 particle
//   slots) and vbd_drift (one workgroup per cloth): the drift of each such cloth's centre of
//   mass, summed in two levels;
// - for a multigrid cloth, the correction of multigrid.wgsl;
// - vbd_finish, one thread per particle slot: the drift taken back, x = x0 + d, v = d / h (BDF2:
//   (d - lag) / h),
//   quarantine, the collision response from x0 to x, as node_update_final does, and the
//   particle's acceleration estimate for the next substep.
// Cloths of other integrators, and cloths past their own substeps or iterations, sit out.

#define_import_path bvh_cloth::block_descent

#import bvh_cloth::types::{GpuParticle, ColourPass, frame, step, thread_index, all_finite}
#import bvh_cloth::springs::{particle_info, ends, cloths}
#import bvh_cloth::collision::collide
#import bvh_cloth::air::{air_cloth, air_kick_of}
#import bvh_cloth::constants::{NO_CLOTH, UNTETHERED, INTEGRATOR_BLOCK_DESCENT, INTEGRATOR_MULTIGRID, BLEND_LAG, BLEND_STEP}

// Between substeps iterate holds the state; during one, d = x - x0 in position.xyz and the
// velocity before the air's kick in velocity.xyz. substep_start holds x0 and the substep's
// starting velocity v^ (v0, or BDF2's (4 v0 - v-1) / 3), w the collider flag of v0. inertial
// holds y - x0 in position.xyz during a substep, and between substeps the acceleration
// estimate in velocity.x and (the multigrid integrator's BDF2) the last start's velocity
// before its kick in velocity.yzw.
// inertial's position.w between substeps: self-contact moved the particle after the last one
// (contact_apply), so the multigrid correction leaves it alone in the next.
const CONTACT_MOVED: f32 = 2.0;

@group(0) @binding(19) var<storage, read_write> iterate: array<GpuParticle>;
@group(0) @binding(20) var<storage, read_write> substep_start: array<GpuParticle>;
@group(0) @binding(21) var<storage, read_write> inertial: array<GpuParticle>;
@group(0) @binding(48) var<storage, read_write> drift_blocks: array<vec4<f32>>;   // per 64 slots: sum of m (d - d*), sum of m
@group(0) @binding(22) var<storage, read> colour_list: array<u32>;                 // particles, colour by colour
@group(0) @binding(25) var<uniform> colour_pass: ColourPass;

// The block-descent cloth particle slot i belongs to, if it is active in this substep.
fn descent_cloth(i: u32) -> u32 {
    if (i >= frame.particle_slots) {
        return NO_CLOTH;
    }
    let c = particle_info[i].w;
    if (c == NO_CLOTH || step.substep >= cloths[c].substeps || cloths[c].integrator < INTEGRATOR_BLOCK_DESCENT) {
        return NO_CLOTH;
    }
    return c;
}

// The length of cloth c's substep: the multigrid integrator's own (mg_begin writes it: h, 2h/3
// for a BDF2 substep, (1 - theta/3) h for a blended one), h for block descent.
fn substep_length(c: u32) -> f32 {
    if (cloths[c].integrator == INTEGRATOR_MULTIGRID) {
        return cloths[c].step;
    }
    return cloths[c].h;
}

// Whether cloth c's substep builds on the last one, BDF2 or the blend (cloths[c].blend)
// (bvh_cloth_core::solver::block_descent's multigrid integrator).
fn bdf2(c: u32) -> bool {
    return cloths[c].integrator == INTEGRATOR_MULTIGRID && cloths[c].step != cloths[c].h;
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

// 1 / (1 + c h) of cloth c, for its substep's length.
fn inverse_damping(c: u32) -> f32 {
    return 1.0 / (1.0 + cloths[c].damping * substep_length(c));
}

// The substep's start of particle i of block-descent cloth c, whose state is `me` and whose
// velocity before the air's kick was `unkicked`.
fn predict(i: u32, c: u32, me: GpuParticle, unkicked: vec3<f32>) {
    // The acceleration the particle followed in its last substep and the velocity before that
    // substep's kick (vbd_finish), and that substep's start, before they are overwritten.
    let estimate = inertial[i].velocity.x;
    let unkicked_before = inertial[i].velocity.yzw;
    let contact_moved = inertial[i].position.w == CONTACT_MOVED;
    let start_before = substep_start[i].position.xyz;
    let free = me.position.w;
    let h = substep_length(c);
    // BDF2 is implicit Euler's minimisation with its start x^ = (4 x0 - x-1) / 3, held as the
    // lag x^ - x0, and v^ = (4 v0 - v-1) / 3 (the kick over 2h/3, not h); the blended step's
    // weights are theta / 3 and 1 - theta / 3.
    var v_hat = me.velocity.xyz;
    var lag = vec3(0.0);
    if (bdf2(c)) {
        if (cloths[c].blend != 0u) {
            v_hat = unkicked + (unkicked - unkicked_before) * BLEND_LAG + (me.velocity.xyz - unkicked) * BLEND_STEP;
            lag = (me.position.xyz - start_before) * BLEND_LAG;
        } else {
            v_hat = unkicked + (unkicked - unkicked_before) / 3.0 + (me.velocity.xyz - unkicked) * (2.0 / 3.0);
            lag = (me.position.xyz - start_before) / 3.0;
        }
    }
    var start = me;
    if (free != 0.0) {
        // The multigrid correction leaves alone what a collider held or contact moved.
        start.velocity = vec4(v_hat, select(me.velocity.w, 1.0, contact_moved));
    }
    substep_start[i] = start;
    // bvh_cloth_core::solver::block_descent::first_iterate: a falling particle starts where gravity
    // takes it, one at rest where it was.
    var x = vec3(0.0);
    var y = vec3(0.0);
    if (free != 0.0) {
        let damp = 1.0 + cloths[c].damping * h;
        y = lag * damp + h * v_hat + (h * h) * cloths[c].uniform_accel.xyz;
        let accel = accel_axis(c).xyz * estimate;
        x = lag + (h * v_hat + (h * h) * accel) * inverse_damping(c);
    }
    var goal: GpuParticle;
    goal.position = vec4(y, free);
    goal.velocity = vec4(0.0);
    inertial[i] = goal;
    iterate[i] = GpuParticle(vec4(x, free), vec4(unkicked, me.velocity.w));
}

@compute @workgroup_size(8, 8, 1)
fn vbd_predict(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = thread_index(id, frame.dispatch_width);
    let c = descent_cloth(i);
    if (c == NO_CLOTH) {
        return;
    }
    let me = iterate[i];
    predict(i, c, me, me.velocity.xyz);
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
    let unkicked = me.velocity.xyz;
    if (me.position.w != 0.0 && air_cloth(i) != NO_CLOTH) {
        me.velocity = vec4(me.velocity.xyz + air_kick_of(i, c, me.velocity.xyz), me.velocity.w);
    }
    predict(i, c, me, unkicked);
}

// bvh_cloth_core::solver::block_descent::descend: the new displacement of particle i (of cloth c)
// from its start, at displacement x, with the same arithmetic in the same order.
fn descend(i: u32, c: u32, x: vec3<f32>, start: vec3<f32>, goal: vec3<f32>) -> vec3<f32> {
    let info = particle_info[i];
    let first = cloths[c].particle_start;
    let first_end = cloths[c].ends_start;
    let h = substep_length(c);
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

// Sums of the 64 threads of a workgroup: the drift terms, and the multigrid line search's.
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
// its displacement and d* = (y - x0) / (1 + c h), y its inertial target
// (bvh_cloth_core::solver::block_descent::centre_of_mass_drift);
// zero for a held particle.
fn drift_term(i: u32, c: u32) -> vec4<f32> {
    let me = iterate[i];
    if (me.position.w == 0.0) {
        return vec4(0.0);
    }
    let off = me.position.xyz - inertial[i].position.xyz * inverse_damping(c);
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
    let unkicked = out.velocity.xyz;
    // The springs are internal forces: a cloth that nothing holds keeps the centre of mass
    // that inertia, damping and the uniform acceleration give it.
    var d = out.position.xyz;
    if (cloths[c].free_body != 0u) {
        d = d - cloths[c].drift.xyz;
    }
    let h = substep_length(c);
    let inv_h = 1.0 / h;
    // BDF2's lag, from the target predict built with it: v = (d - lag) / h.
    var lag = vec3(0.0);
    if (bdf2(c)) {
        let damp = 1.0 + cloths[c].damping * h;
        lag = (inertial[i].position.xyz - h * b.velocity.xyz - (h * h) * cloths[c].uniform_accel.xyz) / damp;
    }
    out.position = vec4(b.position.xyz + d, out.position.w);
    out.velocity = vec4((d - lag) * inv_h, 0.0);
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
    var quarantined = false;
    if (!(all_finite(out.position.xyz) && all_finite(out.velocity.xyz))) {
        out.position = b.position;
        out.velocity = vec4(0.0);
        atomicAdd(&cloths[c].faults, 1u);
        quarantined = true;
    }
    let done = collide(b.position.xyz, out, vec2(cloths[c].memberships, cloths[c].filters));
    iterate[i] = done;
    // A collider or the quarantine moved the particle by more than the springs: BDF2 starts
    // again from implicit Euler in the next substep.
    if (cloths[c].integrator == INTEGRATOR_MULTIGRID && (quarantined || done.velocity.w != 0.0)) {
        atomicStore(&cloths[c].broken, 1u);
    }
    // bvh_cloth_core::solver::block_descent::AccelAxis::estimate.
    let axis = accel_axis(c);
    let along = dot(done.velocity.xyz / inverse_damping(c) - b.velocity.xyz, axis.xyz) / h;
    inertial[i].velocity = vec4(clamp(along, 0.0, axis.w), unkicked);
}
