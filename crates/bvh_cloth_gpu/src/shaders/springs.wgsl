// The spring forces of paper eq. 1-3, gathered per particle over its springs, for the
// integrator stages (node_update and node_update_final): the particle state the slope is taken
// at, each particle's springs, and each cloth's constants.

#define_import_path bvh_cloth::springs
#import bvh_cloth::types::{GpuParticle, BatchCloth}

@group(0) @binding(3) var<storage, read> source: array<GpuParticle>;    // state the slope is taken at
// Per particle: first and past-the-last spring end (relative to its cloth's), inverse mass
// share (f32 bits), its cloth (bvh_cloth_gpu::layout::gpu_particle_info).
@group(0) @binding(6) var<storage, read> particle_info: array<vec4<u32>>;
// Spring ends (bvh_cloth_core::SpringEnd): other particle (relative to the cloth), kind, rest
// length bits, weight bits.
@group(0) @binding(7) var<storage, read> ends: array<vec4<u32>>;
@group(0) @binding(8) var<storage, read_write> cloths: array<BatchCloth>;

// Acceleration of particle i (of cloth c, in state `me`), with its springs' other ends read at
// `source`, gathered as bvh_cloth_core::solver::forces::ForceModel::band_acceleration_general; zero for
// a held particle.
fn acceleration(i: u32, c: u32, me: GpuParticle) -> vec3<f32> {
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
        let d = source[start + e.x].position.xyz - p;
        let len = sqrt(d.x * d.x + d.y * d.y + d.z * d.z);
        a += k * (1.0 - rest / max(len, 1.0e-6 * rest)) * d;
    }
    return a * me.position.w;
}
