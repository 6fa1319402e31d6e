// Vertex block descent (bvh_cloth_core::block_descent), three kernels per substep for every
// block-descent cloth of the batch:
// - vbd_predict, one thread per particle slot: keeps the substep's start state, the inertial
//   target y = x + h v + h^2 g, and the first iterate x + h v; in a batch with aerodynamics,
//   vbd_predict_air instead, which first gives a cloth in the wind its kick (air.wgsl);
// - vbd_solve, one dispatch per iteration and colour, one thread per particle of that colour in
//   the batch's colour list: one Newton step on the particle's block of the incremental
//   potential, against its neighbours' current positions (no neighbour shares its colour, so no
//   thread reads what another writes);
// - vbd_finish, one thread per particle slot: v = (x - x0) / h, quarantine, then the collision
//   response from x0 to x, as node_update_final does.
// Cloths of other integrators, and cloths past their own substeps or iterations, sit out.

#import bvh_cloth::types::{GpuParticle, ColourPass, NO_CLOTH, INTEGRATOR_BLOCK_DESCENT, frame, step, thread_index, all_finite}
#import bvh_cloth::springs::{particle_info, ends, cloths}
#import bvh_cloth::collision::collide
#import bvh_cloth::air::{air_cloth, air_kick_of}

@group(0) @binding(19) var<storage, read_write> iterate: array<GpuParticle>;       // the state, solved in place
@group(0) @binding(20) var<storage, read_write> substep_start: array<GpuParticle>; // x0, v0
@group(0) @binding(21) var<storage, read_write> inertial: array<GpuParticle>;      // y in position.xyz
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

// The substep's start of particle i of block-descent cloth c, whose state is `me`.
fn predict(i: u32, c: u32, me: GpuParticle) {
    substep_start[i] = me;
    let free = me.position.w;
    let h = cloths[c].h;
    // The first iterate moves with the velocity only: a cloth at rest starts where it was, so
    // that with any number of sweeps its equilibrium is the springs' own.
    var x = me.position.xyz;
    var y = x;
    if (free != 0.0) {
        x = x + h * me.velocity.xyz;
        y = x + (h * h) * cloths[c].uniform_accel.xyz;
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

// bvh_cloth_core::block_descent::descend: the new position of particle i (of cloth c) at x,
// with the same arithmetic in the same order.
fn descend(i: u32, c: u32, x: vec3<f32>, start: vec3<f32>, goal: vec3<f32>) -> vec3<f32> {
    let info = particle_info[i];
    let first = cloths[c].particle_start;
    let first_end = cloths[c].ends_start;
    let h = cloths[c].h;
    let h2 = h * h;
    let ch = cloths[c].damping * h;
    var g = (x - goal) + ch * (x - start);
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
        let delta = iterate[first + spring.x].position.xyz - x;
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
        return;
    }
    let inv_h = 1.0 / cloths[c].h;
    out.velocity = vec4((out.position.xyz - b.position.xyz) * inv_h, 0.0);
    // Quarantine, as node_update_final: a particle whose substep went non-finite keeps its last
    // finite state, at rest.
    if (!(all_finite(out.position.xyz) && all_finite(out.velocity.xyz))) {
        out.position = b.position;
        out.velocity = vec4(0.0);
        atomicAdd(&cloths[c].faults, 1u);
    }
    iterate[i] = collide(b.position.xyz, out);
}
