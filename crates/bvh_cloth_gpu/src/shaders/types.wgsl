// The types, constants and helpers every kernel of bvh_cloth_gpu shares. Each struct mirrors a
// #[repr(C)] struct of bvh_cloth_gpu::layout field for field (the crate's layout test
// compares them), and every formula follows the CPU reference (bvh_cloth_core's forces, sim,
// collision, traversal and normals modules) in the same order of operations.
//
// All cloths of a batch share the particle buffers: a cloth's particles are a range of them,
// its constants one entry of the cloth array, and each particle knows its cloth. Workgroups are
// 8x8x1; a thread's index is id.y * dispatch_width + id.x.
//
// Bindings (group 0), unique across the kernels so that the files form one module:
// 0 frame, 1 step: shared; 3 and 6-8 (springs.wgsl): the integrator kernels; 2, 4-5:
// node_update; 9-12: node_update_final (11-12 in collision.wgsl, which vbd_finish shares;
// primitives.wgsl has no binding);
// 19-22 and 25: block_descent.wgsl; 13-14: apply_anchors; 15-18 and 23-24: normal_shader;
// 26-34: skin_refit.wgsl; 35-40: self_contact.wgsl; 41-44, 46-47: air.wgsl.

#define_import_path bvh_cloth::types

// Identifiers here and in collision.wgsl avoid leading underscores and trailing digits: naga_oil
// (Bevy's shader composer) refuses them in modules that others import.

struct GpuParticle {
    position: vec4<f32>, // w: 1 free, 0 pinned
    velocity: vec4<f32>, // w: 1 where a collider touched it in the substep's response
}

struct BatchFrame {
    particle_slots: u32,
    anchor_count: u32,
    collider_count: u32,
    dispatch_width: u32,
}

struct BatchStep {
    substep: u32,
    stage: u32,
    pad_a: u32,
    pad_b: u32,
}

struct BatchCloth {
    k_over_mass: vec4<f32>,
    uniform_accel: vec4<f32>,
    particle_start: u32,
    particle_count: u32,
    ends_start: u32,
    substeps: u32,
    h: f32,
    damping: f32,
    integrator: u32,
    iterations: u32,
    contact_thickness: f32,
    contact_friction: f32,
    free_body: u32,
    tether_start: u32,
    tether_scale: f32,
    memberships: u32,
    filters: u32,
    faults: atomic<u32>,
    drift: vec4<f32>,
    step: f32,
    broken: atomic<u32>,
    blend: u32,
    pad: u32,
}

struct ColourPass {
    start: u32,
    count: u32,
    iteration: u32,
    dispatch_width: u32,
}

struct GpuCollider {
    local_from_world: mat4x4<f32>,
    world_from_local: mat4x4<f32>,
    rotation: vec4<f32>,
    margin_local: f32,
    friction: f32,
    node_offset: u32,
    sphere_offset: u32,
    node_count: u32,
    sphere_count: u32,
    contact_reach: f32,
    shape: u32,         // SHAPE_SPHERES, or a primitive (primitives.wgsl)
    size: vec4<f32>,
    memberships: u32,
    filters: u32,
    pad: vec2<u32>,
}

struct GpuMeshWriteback {
    local_from_world: mat4x4<f32>,
    normal_from_world: mat4x4<f32>,
    first_word: u32,
    stride_words: u32,
    position_word: u32,
    normal_word: u32,
}

struct BatchWriteback {
    mesh: GpuMeshWriteback,
    particle_start: u32,
    surface_start: u32,
    vertex_count: u32,
    particle_count: u32,
    group_first: u32,
    pad_a: u32,
    pad_b: u32,
    pad_c: u32,
}

struct WritebackGroup {
    first_owner: u32,
    vertex_count: u32,
    dispatch_width: u32,
    pad: u32,
}

@group(0) @binding(0) var<uniform> frame: BatchFrame;
@group(0) @binding(1) var<uniform> step: BatchStep;

// The index of the particle this thread owns.
fn thread_index(id: vec3<u32>, width: u32) -> u32 {
    return id.y * width + id.x;
}

// Whether every component is finite, read from the exponent bits: WGSL lets an implementation
// assume that floats are never NaN or infinite, so `x != x` cannot be trusted.
fn all_finite(v: vec3<f32>) -> bool {
    let exponent = bitcast<vec3<u32>>(v) & vec3(0x7f800000u);
    return all(exponent != vec3(0x7f800000u));
}
