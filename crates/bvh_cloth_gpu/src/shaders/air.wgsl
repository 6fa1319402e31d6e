// Aerodynamics (bvh_cloth_core::air) for every cloth of the batch with drag or lift:
// - air_sample, once per tick, one thread per particle slot: the wind at the particle (the
//   cloth's ambient wind for the tick, its turbulence, every wind source);
// - air_forces, once per substep before the integrators: the drag and lift of every triangle,
//   each found once (a cloth's particle threads share its triangles out);
// - the kick: each free particle sums its triangles' forces (in its triangle list's order, no
//   atomics) and adds its capped change of velocity to its own velocity. A separate pass,
//   since air_forces reads the velocities of every corner: air_kick for the explicit
//   integrators' cloths, and block descent's own vbd_predict_air for its cloths (so that a
//   block-descent cloth in the wind costs one dispatch more per substep, not two).
// A cloth past its own substeps sits the substep out.
//
// Bindings 41-44, 46 and 47 (see types.wgsl).

#define_import_path bvh_cloth::air
#import bvh_cloth::types::{GpuParticle, frame, step, thread_index}
#import bvh_cloth::springs::{particle_info, cloths}
#import bvh_cloth::constants::{NO_CLOTH, INTEGRATOR_BLOCK_DESCENT, NOISE_TIME_PERIOD, SOURCE_FAN}

struct AirCloth {
    surface_start: u32,
    vertex_count: u32,
    seed: u32,
    source_count: u32,
    turbulence: f32,
    inv_scale: f32,
    drag: f32,
    lift: f32,
    // Where the cloth's triangles' forces start in air_state, and how many it has (padded to 48
    // bytes).
    triangle_start: u32,
    @size(12) triangle_count: u32,
}

struct WindSource {
    origin: vec4<f32>,  // w: SOURCE_FAN or SOURCE_BLAST
    axis: vec4<f32>,    // the fan's unit axis; w: speed
    reach: vec4<f32>,   // range (or radius), cosine of the fan's spread
}

// Per cloth, this tick: the ambient wind (gusts included) and the turbulence's lattice time
// (bound at the tick's dynamic offset).
@group(0) @binding(41) var<storage, read> air_ticks: array<vec4<f32>>;
@group(0) @binding(42) var<storage, read> air_cloths: array<AirCloth>;
@group(0) @binding(43) var<storage, read> wind_sources: array<WindSource>;
// The wind at each particle slot, then each air cloth's triangle forces from its
// triangle_start: one buffer, so that vbd_predict_air stays within eight storage buffers.
@group(0) @binding(44) var<storage, read_write> air_state: array<vec4<f32>>;
@group(0) @binding(46) var<storage, read_write> air_particles: array<GpuParticle>;
@group(0) @binding(47) var<storage, read> air_surface: array<u32>;

// The cloth slot i belongs to if it has aerodynamics, else NO_CLOTH.
fn air_cloth(i: u32) -> u32 {
    if (i >= frame.particle_slots) {
        return NO_CLOTH;
    }
    let c = particle_info[i].w;
    if (c == NO_CLOTH || (air_cloths[c].drag == 0.0 && air_cloths[c].lift == 0.0)) {
        return NO_CLOTH;
    }
    return c;
}

// bvh_cloth_core::air::hash (lowbias32).
fn noise_hash(v: u32) -> u32 {
    var x = v;
    x ^= x >> 16u;
    x *= 0x7feb352du;
    x ^= x >> 15u;
    x *= 0x846ca68bu;
    x ^= x >> 16u;
    return x;
}

fn noise_unit(bits: u32) -> f32 {
    return (f32(bits & 0x3ffu) - 511.5) * (1.0 / 511.5);
}

fn noise_smooth(f: f32) -> f32 {
    return f * f * (3.0 - 2.0 * f);
}

fn noise_corner(x: i32, y: i32, z: i32, t: u32, seed: u32) -> vec3<f32> {
    let h = noise_hash(
        (bitcast<u32>(x) * 0x8da6b343u)
            ^ (bitcast<u32>(y) * 0xd8163841u)
            ^ (bitcast<u32>(z) * 0xcb1ab31fu)
            ^ ((t % NOISE_TIME_PERIOD) * 0x165667b1u)
            ^ seed
    );
    return vec3(noise_unit(h), noise_unit(h >> 10u), noise_unit(h >> 20u));
}

fn noise_lerp(a: vec3<f32>, b: vec3<f32>, s: f32) -> vec3<f32> {
    return a + (b - a) * s;
}

// bvh_cloth_core::air::value_noise_4d, with the same arithmetic in the same order.
fn value_noise_4d(q: vec3<f32>, t: f32, seed: u32) -> vec3<f32> {
    let cell = floor(q);
    let tc = floor(t);
    let x = i32(cell.x);
    let y = i32(cell.y);
    let z = i32(cell.z);
    let ti = u32(tc);
    let f = q - cell;
    let sx = noise_smooth(f.x);
    let sy = noise_smooth(f.y);
    let sz = noise_smooth(f.z);
    let st = noise_smooth(t - tc);
    // Each corner is blended in time first, then along x, y and z, as on the CPU.
    var by_z: array<vec3<f32>, 2>;
    for (var dz = 0; dz < 2; dz++) {
        let zk = z + dz;
        var by_y: array<vec3<f32>, 2>;
        for (var dy = 0; dy < 2; dy++) {
            let yk = y + dy;
            let a0 = noise_corner(x, yk, zk, ti, seed);
            let a = noise_lerp(a0, noise_corner(x, yk, zk, ti + 1u, seed), st);
            let b0 = noise_corner(x + 1, yk, zk, ti, seed);
            let b = noise_lerp(b0, noise_corner(x + 1, yk, zk, ti + 1u, seed), st);
            by_y[dy] = noise_lerp(a, b, sx);
        }
        by_z[dz] = noise_lerp(by_y[0], by_y[1], sy);
    }
    return noise_lerp(by_z[0], by_z[1], sz);
}

// bvh_cloth_core::air::AirSource::velocity_at.
fn source_wind(s: WindSource, p: vec3<f32>) -> vec3<f32> {
    let d = p - s.origin.xyz;
    let dist = sqrt(dot(d, d));
    let range = s.reach.x;
    if (!(dist > 0.0 && dist < range)) {
        return vec3(0.0);
    }
    let inv = 1.0 / dist;
    var strength = s.axis.w * (1.0 - dist * (1.0 / range));
    if (s.origin.w == SOURCE_FAN) {
        let cos_spread = s.reach.y;
        let c = dot(d, s.axis.xyz) * inv;
        if (c <= cos_spread) {
            return vec3(0.0);
        }
        let f = (c - cos_spread) / (1.0 - cos_spread);
        strength *= f * f * (3.0 - 2.0 * f);
    }
    return d * (strength * inv);
}

@compute @workgroup_size(8, 8, 1)
fn air_sample(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = thread_index(id, frame.dispatch_width);
    let c = air_cloth(i);
    if (c == NO_CLOTH) {
        return;
    }
    let air = air_cloths[c];
    let tick = air_ticks[c];
    let p = air_particles[i].position.xyz;
    var w = tick.xyz;
    if (air.turbulence > 0.0) {
        w += air.turbulence * value_noise_4d(p * air.inv_scale, tick.w, air.seed);
    }
    for (var s = 0u; s < air.source_count; s++) {
        w += source_wind(wind_sources[s], p);
    }
    air_state[i] = vec4(w, 0.0);
}

// bvh_cloth_core::air::AirModel::triangle_force: corner k of triangle t of cloth c.
fn triangle_air(air: AirCloth, start: u32, corners: u32, t: u32) -> vec3<f32> {
    let a = start + air_surface[corners + 3u * t];
    let b = start + air_surface[corners + 3u * t + 1u];
    let cc = start + air_surface[corners + 3u * t + 2u];
    let xa = air_particles[a].position.xyz;
    let m = cross(air_particles[b].position.xyz - xa, air_particles[cc].position.xyz - xa);
    let m2 = dot(m, m);
    let ua = air_state[a].xyz - air_particles[a].velocity.xyz;
    let ub = air_state[b].xyz - air_particles[b].velocity.xyz;
    let uc = air_state[cc].xyz - air_particles[cc].velocity.xyz;
    let u = ((ua + ub) + uc) * (1.0 / 3.0);
    let u2 = dot(u, u);
    if (!(m2 > 0.0 && u2 > 0.0)) {
        return vec3(0.0);
    }
    let d = dot(m, u);
    let drag = (0.5 * air.drag * abs(d)) * u;
    let lift = (0.5 * air.lift * d * sqrt(u2 / m2)) * (m - u * (d / u2));
    return drag + lift;
}

// bvh_cloth_core::air::capped_kick.
fn capped_kick(dv: vec3<f32>, relative: vec3<f32>) -> vec3<f32> {
    let dv2 = dot(dv, dv);
    let rel2 = dot(relative, relative);
    if (dv2 > rel2) {
        return dv * sqrt(rel2 / dv2);
    }
    return dv;
}

// Where a cloth's lists lie in the surface buffer: its triangle offsets, its triangle list and
// its triangles' corners (bvh_cloth_gpu::layout::gpu_surface_words).
struct AirSurface {
    offsets: u32,
    lists: u32,
    corners: u32,
}

fn air_surface_of(air: AirCloth, count: u32) -> AirSurface {
    let offsets = air.surface_start + air.vertex_count;
    let lists = offsets + count + 1u;
    return AirSurface(offsets, lists, lists + air_surface[offsets + count]);
}

@compute @workgroup_size(8, 8, 1)
fn air_forces(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = thread_index(id, frame.dispatch_width);
    let c = air_cloth(i);
    if (c == NO_CLOTH || step.substep >= cloths[c].substeps) {
        return;
    }
    // The cloth's particles share its triangles out, in strides of its particle count: every
    // thread takes about as many (two on a sheet), pinned or not, so none waits on another.
    let air = air_cloths[c];
    let start = cloths[c].particle_start;
    let count = cloths[c].particle_count;
    let surface = air_surface_of(air, count);
    for (var t = i - start; t < air.triangle_count; t += count) {
        air_state[air.triangle_start + t] = vec4(triangle_air(air, start, surface.corners, t), 0.0);
    }
}

// The capped change of velocity of free particle i of air cloth c, moving at `velocity`, from
// its triangles' forces this substep (the CPU's Air::kick).
fn air_kick_of(i: u32, c: u32, velocity: vec3<f32>) -> vec3<f32> {
    let air = air_cloths[c];
    let start = cloths[c].particle_start;
    let surface = air_surface_of(air, cloths[c].particle_count);
    let local = i - start;
    var f = vec3(0.0);
    for (var k = air_surface[surface.offsets + local]; k < air_surface[surface.offsets + local + 1u]; k++) {
        f += air_state[air.triangle_start + air_surface[surface.lists + k]].xyz;
    }
    let dv = f * (cloths[c].h * bitcast<f32>(particle_info[i].z));
    return capped_kick(dv, air_state[i].xyz - velocity);
}

// The kick of the explicit integrators' cloths (vbd_predict_air kicks block descent's).
@compute @workgroup_size(8, 8, 1)
fn air_kick(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = thread_index(id, frame.dispatch_width);
    let c = air_cloth(i);
    if (c == NO_CLOTH || step.substep >= cloths[c].substeps || cloths[c].integrator >= INTEGRATOR_BLOCK_DESCENT) {
        return;
    }
    let me = air_particles[i];
    if (me.position.w == 0.0) {
        return;
    }
    air_particles[i].velocity = vec4(me.velocity.xyz + air_kick_of(i, c, me.velocity.xyz), me.velocity.w);
}
