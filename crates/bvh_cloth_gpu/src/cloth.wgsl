// Bindings: 0 is shared; node_update uses 1-4, 13 and 16, collision_detection_with_bvh 5-9,
// normal_shader 10-12 and 17, apply_anchors 14-15, so every (group, binding) names one variable.
//
// The paper's three compute kernels (Table I): node_update, collision_detection_with_bvh and
// normal_shader, plus apply_anchors, which moves pinned particles at the start of each tick.
// Each thread owns one particle (one render vertex in normal_shader) of a cloth of any
// topology; workgroups are 8x8x1, and a thread's index is id.y * dispatch_width + id.x.
// Every struct mirrors a #[repr(C)] struct of bvh_cloth_core::gpu_layout field for field, and
// every formula follows the CPU reference (bvh_cloth_core's forces, sim, collision, traversal
// and normals modules) in the same order of operations.

struct GpuParticle {
    position: vec4<f32>, // w: 1 free, 0 held
    velocity: vec4<f32>,
}

struct GpuClothParams {
    particle_count: u32,
    vertex_count: u32,
    collider_count: u32,
    dispatch_width: u32,
    h: f32,
    damping: f32,
    anchor_count: u32,
    _pad: u32,
    k_over_mass: vec4<f32>,
    uniform_accel: vec4<f32>,
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
    _pad: u32,
}

// bvh_cloth_core::BvhNode: child references with LEAF_BIT set name spheres.
struct BvhNode {
    aabb_min: vec3<f32>,
    left: u32,
    aabb_max: vec3<f32>,
    right: u32,
}

struct GpuMeshWriteback {
    local_from_world: mat4x4<f32>,
    normal_from_world: mat4x4<f32>,
    first_word: u32,
    stride_words: u32,
    position_word: u32,
    normal_word: u32,
}

const LEAF_BIT: u32 = 0x80000000u;
const STACK_SIZE: u32 = 64u;          // bvh_cloth_core::traversal::STACK_SIZE
const SURFACE_TOLERANCE: f32 = 1.0e-3; // bvh_cloth_core::traversal::SURFACE_TOLERANCE
const CONTACT_BAND: f32 = 1.0e-2;      // bvh_cloth_core::collision::CONTACT_BAND
const MAX_PASSES: u32 = 4u;            // bvh_cloth_core::collision::MAX_PASSES

// Which integrator stage a node_update pipeline runs: 0..3 are the four RK4 stages, 4 is
// semi-implicit Euler.
override STAGE: u32 = 0u;

@group(0) @binding(0) var<uniform> params: GpuClothParams;

// ---------------------------------------------------------------------------------------------
// NodeUpdate: spring forces (paper eq. 1-3) and one integrator stage (eq. 4).
// ---------------------------------------------------------------------------------------------

@group(0) @binding(1) var<storage, read> base: array<GpuParticle>;      // state at substep start
@group(0) @binding(2) var<storage, read> source: array<GpuParticle>;    // state the slope is taken at
@group(0) @binding(3) var<storage, read_write> slope_sum: array<GpuParticle>;
@group(0) @binding(4) var<storage, read_write> stage_out: array<GpuParticle>;
// Particles quarantined since the host last read and cleared it (one per particle and substep).
@group(0) @binding(13) var<storage, read_write> faults: atomic<u32>;
// The cloth's springs (bvh_cloth_core::gpu_layout::gpu_topology_words): N + 1 offsets, N inverse
// mass shares, then four words per spring end (other, kind, rest, weight).
@group(0) @binding(16) var<storage, read> topology: array<u32>;

// The index of the particle (or vertex) this thread owns.
fn thread_index(id: vec3<u32>) -> u32 {
    return id.y * params.dispatch_width + id.x;
}

// Acceleration of particle i at the `source` state, gathered over its springs
// (bvh_cloth_core::forces::ForceModel::band_acceleration_general); zero for a held particle.
fn acceleration(i: u32) -> vec3<f32> {
    let n = params.particle_count;
    let me = source[i];
    let p = me.position.xyz;
    var a = params.uniform_accel.xyz - params.damping * me.velocity.xyz;
    let inv_share = bitcast<f32>(topology[n + 1u + i]);
    let ends = 2u * n + 1u;
    for (var s = topology[i]; s < topology[i + 1u]; s++) {
        let e = ends + 4u * s;
        let k = params.k_over_mass[topology[e + 1u]] * bitcast<f32>(topology[e + 3u]) * inv_share;
        if (k == 0.0) {
            continue;
        }
        let rest = bitcast<f32>(topology[e + 2u]);
        let d = source[topology[e]].position.xyz - p;
        let len = sqrt(d.x * d.x + d.y * d.y + d.z * d.z);
        a += k * (1.0 - rest / max(len, 1.0e-6 * rest)) * d;
    }
    return a * me.position.w;
}

@compute @workgroup_size(8, 8, 1)
fn node_update(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = thread_index(id);
    if (i >= params.particle_count) {
        return;
    }
    let acc = acceleration(i);
    let b = base[i];
    let free = b.position.w;
    let h = params.h;
    // Slope of the state: (velocity, acceleration), the velocity masked for pinned particles.
    let kx = source[i].velocity.xyz * free;
    var out: GpuParticle;
    out.position.w = free;
    switch STAGE {
        case 0u, 1u, 2u: {
            let weight = select(2.0, 1.0, STAGE == 0u);
            let coef = select(0.5, 1.0, STAGE == 2u) * h;
            var sum = slope_sum[i];
            if (STAGE == 0u) {
                sum.position = vec4(kx, 0.0);
                sum.velocity = vec4(acc, 0.0);
            } else {
                sum.position = vec4(sum.position.xyz + weight * kx, 0.0);
                sum.velocity = vec4(sum.velocity.xyz + weight * acc, 0.0);
            }
            slope_sum[i] = sum;
            out.position = vec4(b.position.xyz + coef * kx, free);
            out.velocity = vec4(b.velocity.xyz + coef * acc, 0.0);
        }
        case 3u: {
            let sum = slope_sum[i];
            let h6 = h / 6.0;
            out.position = vec4(b.position.xyz + h6 * (sum.position.xyz + kx), free);
            out.velocity = vec4(b.velocity.xyz + h6 * (sum.velocity.xyz + acc), 0.0);
        }
        default: {
            let v = b.velocity.xyz + h * acc;
            out.velocity = vec4(v, 0.0);
            out.position = vec4(b.position.xyz + h * v * free, free);
        }
    }
    // Quarantine: a particle whose substep went non-finite keeps its last finite state, at rest,
    // so one bad particle cannot poison its neighbours through the springs.
    if (STAGE >= 3u && !(all_finite(out.position.xyz) && all_finite(out.velocity.xyz))) {
        out.position = b.position;
        out.velocity = vec4(0.0);
        atomicAdd(&faults, 1u);
    }
    stage_out[i] = out;
}

/// Whether every component is finite, read from the exponent bits: WGSL lets an implementation
/// assume that floats are never NaN or infinite, so `x != x` cannot be trusted.
fn all_finite(v: vec3<f32>) -> bool {
    let exponent = bitcast<vec3<u32>>(v) & vec3(0x7f800000u);
    return all(exponent != vec3(0x7f800000u));
}

// ---------------------------------------------------------------------------------------------
// CollisionDetectionWithBVH: stack traversal (Algorithm 2) and the response of section 2.4.4.
// ---------------------------------------------------------------------------------------------

@group(0) @binding(5) var<storage, read_write> state: array<GpuParticle>;   // in: previous; out: result
@group(0) @binding(6) var<storage, read> moved: array<GpuParticle>;         // the integrated state
@group(0) @binding(7) var<storage, read> colliders: array<GpuCollider>;
@group(0) @binding(8) var<storage, read> nodes: array<BvhNode>;
@group(0) @binding(9) var<storage, read> spheres: array<vec4<f32>>;        // xyz centre, w radius

fn sphere_contains(sphere: vec4<f32>, p: vec3<f32>, margin: f32) -> bool {
    let r = sphere.w + margin;
    let shrunk = r * (1.0 - SURFACE_TOLERANCE);
    let d = p - sphere.xyz;
    return dot(d, d) < shrunk * shrunk;
}

// The exact test a query makes on each sphere whose box it reaches (bvh_cloth_core::collision):
// QUERY_CONTACTS gathers the contacts at the previous position, QUERY_SWEEP finds the first
// sphere the path enters, QUERY_INSIDE whether a point is inside any sphere, QUERY_DEEPEST the
// sphere a point is deepest in.
const QUERY_CONTACTS: u32 = 0u;
const QUERY_SWEEP: u32 = 1u;
const QUERY_INSIDE: u32 = 2u;
const QUERY_DEEPEST: u32 = 3u;

// One query's input and what it found. `end_point` is the path's end (held by contacts);
// `found` is 0 when nothing was found; `value` the entry parameter or the depth; `sphere` the
// sphere found; `touched`/`inside` what the contact query saw; `velocity` has each contact's
// normal part removed as it is found.
struct Query {
    kind: u32,
    prev: vec3<f32>,
    end_point: vec3<f32>,
    found: u32,
    value: f32,
    sphere: vec4<f32>,
    touched: bool,
    inside: bool,
    velocity: vec3<f32>,
}

fn entry_parameter(prev: vec3<f32>, p: vec3<f32>, c: vec3<f32>, r: f32) -> f32 {
    let d = p - prev;
    let f = prev - c;
    let a = dot(d, d);
    let b = dot(f, d);
    let k = dot(f, f) - r * r;
    let disc = max(b * b - a * k, 0.0);
    return clamp((-b - sqrt(disc)) / a, 0.0, 1.0);
}

fn segment_enters(sphere: vec4<f32>, prev: vec3<f32>, p: vec3<f32>, margin: f32) -> bool {
    if (sphere_contains(sphere, p, margin)) {
        return true;
    }
    let d = p - prev;
    let a = dot(d, d);
    if (a == 0.0) {
        return false;
    }
    let t = clamp(dot(sphere.xyz - prev, d) / a, 0.0, 1.0);
    return sphere_contains(sphere, prev + t * d, margin);
}

fn outward_normal(p: vec3<f32>, prev: vec3<f32>, c: vec3<f32>) -> vec3<f32> {
    let a = p - c;
    if (dot(a, a) > 0.0) {
        return normalize(a);
    }
    let b = prev - c;
    if (dot(b, b) > 0.0) {
        return normalize(b);
    }
    return vec3<f32>(0.0, 1.0, 0.0);
}

fn consider(q: ptr<function, Query>, col: GpuCollider, sphere: vec4<f32>) {
    let margin = col.margin_local;
    let c = sphere.xyz;
    let r = sphere.w + margin;
    switch (*q).kind {
        case QUERY_CONTACTS: {
            let band = r * (1.0 + CONTACT_BAND);
            let f = (*q).prev - c;
            if (dot(f, f) >= band * band) {
                return;
            }
            if (sphere_contains(sphere, (*q).prev, margin)) {
                (*q).inside = true;
                return;
            }
            let n = outward_normal((*q).prev, (*q).prev, c);
            let below = dot((*q).end_point - (c + n * r), n);
            if (below < 0.0) {
                (*q).end_point = (*q).end_point - below * n;
                (*q).touched = true;
                (*q).velocity = contact_velocity((*q).velocity, rotate(col.rotation, n), col.friction);
            }
        }
        case QUERY_SWEEP: {
            if (segment_enters(sphere, (*q).prev, (*q).end_point, margin)) {
                let t = entry_parameter((*q).prev, (*q).end_point, c, r);
                if ((*q).found == 0u || t < (*q).value) {
                    (*q).found = 1u;
                    (*q).value = t;
                    (*q).sphere = sphere;
                }
            }
        }
        case QUERY_INSIDE: {
            if (sphere_contains(sphere, (*q).end_point, margin)) {
                (*q).found = 1u;
            }
        }
        default: {
            if (sphere_contains(sphere, (*q).end_point, margin)) {
                let depth = r - distance((*q).end_point, c);
                if ((*q).found == 0u || depth > (*q).value) {
                    (*q).found = 1u;
                    (*q).value = depth;
                    (*q).sphere = sphere;
                }
            }
        }
    }
}

fn boxes_overlap(node_min: vec3<f32>, node_max: vec3<f32>, lo: vec3<f32>, hi: vec3<f32>, margin: f32) -> bool {
    return all(hi >= node_min - margin) && all(lo <= node_max + margin);
}

fn sphere_box_overlaps(sphere: vec4<f32>, lo: vec3<f32>, hi: vec3<f32>, margin: f32) -> bool {
    let r = sphere.w + margin;
    return all(hi >= sphere.xyz - r) && all(lo <= sphere.xyz + r);
}

// Runs query `q` on every sphere whose box (grown by the margin) overlaps [lo, hi], in the CPU's
// depth-first order (bvh_cloth_core::Lbvh::for_each_overlapping: right child pushed first, so
// the left subtree is visited first).
fn run_query(q: ptr<function, Query>, col: GpuCollider, lo: vec3<f32>, hi: vec3<f32>) {
    let margin = col.margin_local;
    if (col.node_count == 0u) {
        let s = spheres[col.sphere_offset];
        if (sphere_box_overlaps(s, lo, hi, margin)) {
            consider(q, col, s);
        }
        return;
    }
    let root = nodes[col.node_offset];
    if (!boxes_overlap(root.aabb_min, root.aabb_max, lo, hi, margin)) {
        return;
    }
    var stack: array<u32, STACK_SIZE>;
    var top = 1u;
    stack[0] = 0u;
    while (top > 0u) {
        top -= 1u;
        let node = nodes[col.node_offset + stack[top]];
        var children = array<u32, 2>(node.right, node.left);
        for (var k = 0; k < 2; k++) {
            let child = children[k];
            if ((child & LEAF_BIT) != 0u) {
                let s = spheres[col.sphere_offset + (child & ~LEAF_BIT)];
                if (sphere_box_overlaps(s, lo, hi, margin)) {
                    consider(q, col, s);
                }
            } else if (top < STACK_SIZE) {
                let inner = nodes[col.node_offset + child];
                if (boxes_overlap(inner.aabb_min, inner.aabb_max, lo, hi, margin)) {
                    stack[top] = child;
                    top += 1u;
                }
            }
        }
    }
}

fn point_query(kind: u32, col: GpuCollider, prev: vec3<f32>, p: vec3<f32>) -> Query {
    var q = Query(kind, prev, p, 0u, 0.0, vec4<f32>(0.0), false, false, vec3<f32>(0.0));
    run_query(&q, col, p, p);
    return q;
}

// The result of the response against one collider (bvh_cloth_core::collision::Response):
// kind 0 free, 1 moved to `position` (local), 2 stay at the previous position.
struct Response {
    kind: u32,
    position: vec3<f32>,
    velocity: vec3<f32>,
}

fn respond(col: GpuCollider, prev: vec3<f32>, p: vec3<f32>, velocity: vec3<f32>) -> Response {
    // 1. Contacts at the previous position.
    let reach = vec3<f32>(col.contact_reach);
    var q = Query(QUERY_CONTACTS, prev, p, 0u, 0.0, vec4<f32>(0.0), false, false, velocity);
    run_query(&q, col, prev - reach, prev + reach);
    if (q.inside) {
        return push_out(col, prev, p, q.velocity);
    }
    // 2. Sweep.
    let end_point = q.end_point;
    var v = q.velocity;
    var sweep = Query(QUERY_SWEEP, prev, end_point, 0u, 0.0, vec4<f32>(0.0), false, false, v);
    run_query(&sweep, col, min(prev, end_point), max(prev, end_point));
    if (sweep.found == 0u) {
        return Response(select(0u, 1u, q.touched), end_point, v);
    }
    let c = sweep.sphere.xyz;
    let normal = outward_normal(mix(prev, end_point, sweep.value), prev, c);
    let entry = c + normal * (sweep.sphere.w + col.margin_local);
    v = contact_velocity(v, rotate(col.rotation, normal), col.friction);
    // 3. Guard.
    if (point_query(QUERY_INSIDE, col, prev, entry).found != 0u) {
        return Response(2u, entry, v);
    }
    return Response(1u, entry, v);
}

fn push_out(col: GpuCollider, prev: vec3<f32>, start: vec3<f32>, velocity: vec3<f32>) -> Response {
    var p = start;
    var v = velocity;
    var moved = false;
    for (var round = 0u; round < MAX_PASSES; round++) {
        let deepest = point_query(QUERY_DEEPEST, col, prev, p);
        if (deepest.found == 0u) {
            break;
        }
        let c = deepest.sphere.xyz;
        let normal = outward_normal(p, prev, c);
        p = c + normal * (deepest.sphere.w + col.margin_local);
        moved = true;
        v = contact_velocity(v, rotate(col.rotation, normal), col.friction);
    }
    return Response(select(0u, 1u, moved), p, v);
}

fn rotate(q: vec4<f32>, v: vec3<f32>) -> vec3<f32> {
    let t = 2.0 * cross(q.xyz, v);
    return v + q.w * t + cross(q.xyz, t);
}

fn contact_velocity(velocity: vec3<f32>, n: vec3<f32>, friction: f32) -> vec3<f32> {
    let vn = dot(velocity, n);
    let tangential = velocity - vn * n;
    if (vn >= 0.0 || friction == 0.0) {
        return tangential;
    }
    let speed = length(tangential);
    let slowdown = friction * -vn;
    if (speed > slowdown) {
        return tangential * (1.0 - slowdown / speed);
    }
    return vec3<f32>(0.0);
}

@compute @workgroup_size(8, 8, 1)
fn collision_detection_with_bvh(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = thread_index(id);
    if (i >= params.particle_count) {
        return;
    }
    let prev_world = state[i].position.xyz;
    var out = moved[i];
    if (out.position.w != 0.0) {
        var position = out.position.xyz;
        var velocity = out.velocity.xyz;
        for (var c = 0u; c < params.collider_count; c++) {
            let col = colliders[c];
            let prev = (col.local_from_world * vec4(prev_world, 1.0)).xyz;
            let p = (col.local_from_world * vec4(position, 1.0)).xyz;
            let response = respond(col, prev, p, velocity);
            velocity = response.velocity;
            if (response.kind == 1u) {
                position = (col.world_from_local * vec4(response.position, 1.0)).xyz;
            } else if (response.kind == 2u) {
                position = prev_world;
            }
        }
        out.position = vec4(position, out.position.w);
        out.velocity = vec4(velocity, 0.0);
    }
    state[i] = out;
}

// ---------------------------------------------------------------------------------------------
// NormalShader (Algorithm 3): per-vertex normals from the triangles around each particle,
// written with the positions into an interleaved vertex buffer; one thread per render vertex.
// ---------------------------------------------------------------------------------------------

@group(0) @binding(10) var<storage, read> particles: array<GpuParticle>;
@group(0) @binding(11) var<uniform> writeback: GpuMeshWriteback;
@group(0) @binding(12) var<storage, read_write> vertices: array<f32>;
// The cloth's surface (bvh_cloth_core::gpu_layout::gpu_surface_words): the particle of each of
// the V vertices, N + 1 triangle offsets, the per-particle triangle lists, then three corners
// per triangle.
@group(0) @binding(17) var<storage, read> surface: array<u32>;

fn corner(triangles: u32, t: u32, k: u32) -> vec3<f32> {
    return particles[surface[triangles + 3u * t + k]].position.xyz;
}

@compute @workgroup_size(8, 8, 1)
fn normal_shader(@builtin(global_invocation_id) id: vec3<u32>) {
    let v = thread_index(id);
    if (v >= params.vertex_count) {
        return;
    }
    let offsets = params.vertex_count;
    let lists = offsets + params.particle_count + 1u;
    let triangles = lists + surface[offsets + params.particle_count];
    let i = surface[v];
    // The CPU's order: the particle's triangles as listed (bvh_cloth_core::normals).
    var n = vec3<f32>(0.0);
    for (var k = surface[offsets + i]; k < surface[offsets + i + 1u]; k++) {
        let t = surface[lists + k];
        let a = corner(triangles, t, 0u);
        n += cross(corner(triangles, t, 1u) - a, corner(triangles, t, 2u) - a);
    }
    var world_normal = vec3<f32>(0.0, 1.0, 0.0);
    let len2 = dot(n, n);
    if (len2 > 0.0 && len2 < 3.0e38) {
        world_normal = n * inverseSqrt(len2);
    }
    let p = particles[i].position.xyz;
    let local_position = (writeback.local_from_world * vec4(p, 1.0)).xyz;
    var local_normal = (writeback.normal_from_world * vec4(world_normal, 0.0)).xyz;
    let nl2 = dot(local_normal, local_normal);
    local_normal = select(vec3<f32>(0.0, 1.0, 0.0), local_normal * inverseSqrt(nl2), nl2 > 0.0);
    let w = writeback.first_word + v * writeback.stride_words;
    vertices[w + writeback.position_word] = local_position.x;
    vertices[w + writeback.position_word + 1u] = local_position.y;
    vertices[w + writeback.position_word + 2u] = local_position.z;
    vertices[w + writeback.normal_word] = local_normal.x;
    vertices[w + writeback.normal_word + 1u] = local_normal.y;
    vertices[w + writeback.normal_word + 2u] = local_normal.z;
}

// ---------------------------------------------------------------------------------------------
// Anchors: at the start of each tick, every pinned particle moves to where its anchor holds it
// during that tick (bvh_cloth_core::ClothSim::move_pins). The host binds that tick's targets
// with a dynamic offset.
// ---------------------------------------------------------------------------------------------

@group(0) @binding(14) var<storage, read_write> anchored: array<GpuParticle>;
// xyz: the target; w: the particle index, as bits.
@group(0) @binding(15) var<storage, read> anchor_targets: array<vec4<f32>>;

@compute @workgroup_size(8, 8, 1)
fn apply_anchors(@builtin(global_invocation_id) id: vec3<u32>) {
    let k = thread_index(id);
    if (k >= params.anchor_count) {
        return;
    }
    let goal = anchor_targets[k];
    let i = bitcast<u32>(goal.w);
    if (i < params.particle_count) {
        anchored[i].position = vec4(goal.xyz, anchored[i].position.w);
    }
}
