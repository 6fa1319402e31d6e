// The exact primitives (bvh_cloth_core::colliders::primitives): signed distances and the convex response,
// in the collider's local frame, step for step as on the CPU.

#define_import_path bvh_cloth::primitives
#import bvh_cloth::types::{GpuCollider}
#import bvh_cloth::constants::{SURFACE_TOLERANCE, CONTACT_BAND, SHAPE_SPHERE, SHAPE_CAPSULE, SHAPE_CUBOID, SHAPE_HALF_SPACE, SWEEP_STEPS, CLOSEST_STEPS}

// GpuCollider::shape (bvh_cloth_core::colliders::primitives::Primitive::kind).
const INV_PHI: f32 = 0.618034;

// A signed distance (w) and the outward unit normal of the closest surface point (xyz).
fn round_distance(offset: vec3<f32>, radius: f32) -> vec4<f32> {
    let len = length(offset);
    var normal = vec3<f32>(0.0, 1.0, 0.0);
    if (len > 0.0) {
        normal = offset / len;
    }
    return vec4(normal, len - radius);
}

// glam's signum: +1 for +0.
fn signum(v: vec3<f32>) -> vec3<f32> {
    return select(vec3(1.0), vec3(-1.0), v < vec3(0.0));
}

fn box_distance(p: vec3<f32>, h: vec3<f32>) -> vec4<f32> {
    let q = abs(p) - h;
    let largest = max(q.x, max(q.y, q.z));
    if (largest > 0.0) {
        let outside = max(q, vec3(0.0));
        let len = length(outside);
        return vec4((outside / len) * signum(p), len);
    }
    var axis = vec3<f32>(0.0, 0.0, 1.0);
    if (q.x >= q.y && q.x >= q.z) {
        axis = vec3<f32>(1.0, 0.0, 0.0);
    } else if (q.y >= q.z) {
        axis = vec3<f32>(0.0, 1.0, 0.0);
    }
    return vec4(axis * signum(p), largest);
}

fn primitive_distance(col: GpuCollider, p: vec3<f32>) -> vec4<f32> {
    let size = col.size;
    switch col.shape {
        case SHAPE_SPHERE: {
            return round_distance(p, size.x);
        }
        case SHAPE_CAPSULE: {
            let axis = vec3<f32>(0.0, clamp(p.y, -size.y, size.y), 0.0);
            return round_distance(p - axis, size.x);
        }
        case SHAPE_CUBOID: {
            return box_distance(p, size.xyz);
        }
        default: {
            return vec4(size.xyz, dot(p, size.xyz));
        }
    }
}

fn primitive_thickness(col: GpuCollider) -> f32 {
    switch col.shape {
        case SHAPE_CUBOID: {
            return min(col.size.x, min(col.size.y, col.size.z));
        }
        default: {
            return col.size.x;
        }
    }
}

fn primitive_tolerance(col: GpuCollider) -> f32 {
    if (col.shape == SHAPE_HALF_SPACE) {
        return SURFACE_TOLERANCE * col.margin_local;
    }
    return SURFACE_TOLERANCE * (primitive_thickness(col) + col.margin_local);
}

fn primitive_gap(col: GpuCollider, prev: vec3<f32>, p: vec3<f32>, t: f32) -> f32 {
    return primitive_distance(col, mix(prev, p, t)).w - col.margin_local;
}

// Where the gap along the path is smallest (it is convex), by golden-section search.
fn closest_parameter(col: GpuCollider, prev: vec3<f32>, p: vec3<f32>) -> f32 {
    var a = 0.0;
    var b = 1.0;
    var c = b - INV_PHI * (b - a);
    var d = a + INV_PHI * (b - a);
    var fc = primitive_gap(col, prev, p, c);
    var fd = primitive_gap(col, prev, p, d);
    for (var k = 0u; k < CLOSEST_STEPS; k++) {
        if (fc < fd) {
            b = d;
            d = c;
            fd = fc;
            c = b - INV_PHI * (b - a);
            fc = primitive_gap(col, prev, p, c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + INV_PHI * (b - a);
            fd = primitive_gap(col, prev, p, d);
        }
    }
    return select(d, c, fc < fd);
}

// What the response did: `moved` false leaves the particle free; otherwise it moves to
// `position` (local) and `normal` (local) is the contact's.
struct PrimitiveResponse {
    moved: bool,
    position: vec3<f32>,
    normal: vec3<f32>,
}

fn respond_primitive(col: GpuCollider, prev: vec3<f32>, p: vec3<f32>) -> PrimitiveResponse {
    let margin = col.margin_local;
    let at_prev = primitive_distance(col, prev);
    let d_prev = at_prev.w;
    let n_prev = at_prev.xyz;
    // 1. Inside: onto the surface along the end point's own normal.
    if (d_prev < margin - primitive_tolerance(col)) {
        let at_end = primitive_distance(col, p);
        if (at_end.w >= margin) {
            return PrimitiveResponse(false, p, vec3(0.0));
        }
        return PrimitiveResponse(true, p + (margin - at_end.w) * at_end.xyz, at_end.xyz);
    }
    // 2. The separating plane at `prev`.
    let surface = prev - (d_prev - margin) * n_prev;
    let below = dot(p - surface, n_prev);
    if (below >= 0.0) {
        return PrimitiveResponse(false, p, vec3(0.0));
    }
    // 3. Contact: held on the plane (always for the half-space, whose band is unbounded).
    if (col.shape == SHAPE_HALF_SPACE || d_prev - margin <= CONTACT_BAND * (primitive_thickness(col) + margin)) {
        return PrimitiveResponse(true, p - below * n_prev, n_prev);
    }
    // 4. Sweep.
    var hi = 1.0;
    if (primitive_gap(col, prev, p, 1.0) > 0.0) {
        let t = closest_parameter(col, prev, p);
        if (primitive_gap(col, prev, p, t) > 0.0) {
            return PrimitiveResponse(false, p, vec3(0.0));
        }
        hi = t;
    }
    var lo = 0.0;
    for (var k = 0u; k < SWEEP_STEPS; k++) {
        let mid = 0.5 * (lo + hi);
        if (primitive_gap(col, prev, p, mid) > 0.0) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let entry = mix(prev, p, lo);
    let at_entry = primitive_distance(col, entry);
    return PrimitiveResponse(true, entry + (margin - at_entry.w) * at_entry.xyz, at_entry.xyz);
}
