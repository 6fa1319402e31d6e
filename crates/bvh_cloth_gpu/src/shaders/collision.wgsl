// CollisionDetectionWithBVH: stack traversal (Algorithm 2) and the response of section 2.4.4,
// as a function the final integrator stage calls for each free particle; primitives answer in
// primitives.wgsl. A collider with exact contact (SHAPE_TRIANGLES) answers from its triangles
// (bvh_cloth_core::colliders::exact_contact), through the same traversal of its tree.

#define_import_path bvh_cloth::collision
#import bvh_cloth::types::{GpuParticle, GpuCollider, frame}
#import bvh_cloth::primitives::respond_primitive
#import bvh_cloth::constants::{SHAPE_SPHERES, SHAPE_TRIANGLES, LEAF_BIT, STACK_SIZE, SURFACE_TOLERANCE, CONTACT_BAND, MAX_PASSES, LOOKOUT_ROUNDING, EDGE_SLACK, PLANE_ROUNDING}

@group(0) @binding(11) var<storage, read> colliders: array<GpuCollider>;
// Every collider's tree: the nodes (bvh_cloth_core::BvhNode, two vec4 each: the box's minimum
// and left child, its maximum and right child, children as bits; references with LEAF_BIT set
// name spheres), then the spheres (xyz centre, w radius). GpuCollider::node_offset counts
// nodes, GpuCollider::sphere_offset vec4s.
@group(0) @binding(12) var<storage, read> tree: array<vec4<f32>>;

struct BvhNode {
    aabb_min: vec3<f32>,
    left: u32,
    aabb_max: vec3<f32>,
    right: u32,
}

fn tree_node(col: GpuCollider, index: u32) -> BvhNode {
    let at = 2u * (col.node_offset + index);
    let lo = tree[at];
    let hi = tree[at + 1u];
    return BvhNode(lo.xyz, bitcast<u32>(lo.w), hi.xyz, bitcast<u32>(hi.w));
}

fn sphere_contains(sphere: vec4<f32>, p: vec3<f32>, margin: f32) -> bool {
    let r = sphere.w + margin;
    let shrunk = r * (1.0 - SURFACE_TOLERANCE);
    let d = p - sphere.xyz;
    return dot(d, d) < shrunk * shrunk;
}

// The exact test a query makes on each sphere whose box it reaches (bvh_cloth_core::colliders::collision):
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
        let s = tree[col.sphere_offset];
        if (sphere_box_overlaps(s, lo, hi, margin)) {
            consider(q, col, s);
        }
        return;
    }
    let root = tree_node(col, 0u);
    if (!boxes_overlap(root.aabb_min, root.aabb_max, lo, hi, margin)) {
        return;
    }
    var stack: array<u32, STACK_SIZE>;
    var top = 1u;
    stack[0] = 0u;
    while (top > 0u) {
        top -= 1u;
        let node = tree_node(col, stack[top]);
        var children = array<u32, 2>(node.right, node.left);
        for (var k = 0; k < 2; k++) {
            let child = children[k];
            if ((child & LEAF_BIT) != 0u) {
                let s = tree[col.sphere_offset + (child & ~LEAF_BIT)];
                if (sphere_box_overlaps(s, lo, hi, margin)) {
                    consider(q, col, s);
                }
            } else if (top < STACK_SIZE) {
                let inner = tree_node(col, child);
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

// The result of the response against one collider (bvh_cloth_core::colliders::collision::Response):
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

// bvh_cloth_core::CollisionLayers::interacts_with, of two (memberships, filters) pairs.
fn layers_meet(a: vec2<u32>, b: vec2<u32>) -> bool {
    return (a.x & b.y) != 0u && (b.x & a.y) != 0u;
}

// The response of a free particle of a cloth whose collision layers are `layers` (memberships,
// filters) that moved from `prev_world` to `moved` in this substep, against every collider it
// meets in turn. The velocity's w says whether any collider touched it (1) or none did (0):
// self-contact weighs a touched particle as pinned.
fn collide(prev_world: vec3<f32>, moved: GpuParticle, layers: vec2<u32>) -> GpuParticle {
    var position = moved.position.xyz;
    var velocity = moved.velocity.xyz;
    var touched = false;
    for (var c = 0u; c < frame.collider_count; c++) {
        let col = colliders[c];
        if (!layers_meet(layers, vec2(col.memberships, col.filters))) {
            continue;
        }
        let prev = (col.local_from_world * vec4(prev_world, 1.0)).xyz;
        let p = (col.local_from_world * vec4(position, 1.0)).xyz;
        if (col.shape == SHAPE_TRIANGLES) {
            let response = respond_triangles(col, prev, p, velocity);
            velocity = response.velocity;
            touched = touched || response.kind != 0u;
            if (response.kind == 1u) {
                position = (col.world_from_local * vec4(response.position, 1.0)).xyz;
            } else if (response.kind == 2u) {
                position = prev_world;
            }
            continue;
        }
        if (col.shape != SHAPE_SPHERES) {
            let contact = respond_primitive(col, prev, p);
            touched = touched || contact.moved;
            if (contact.moved) {
                velocity = contact_velocity(velocity, rotate(col.rotation, contact.normal), col.friction);
                position = (col.world_from_local * vec4(contact.position, 1.0)).xyz;
            }
            continue;
        }
        let response = respond(col, prev, p, velocity);
        velocity = response.velocity;
        touched = touched || response.kind != 0u;
        if (response.kind == 1u) {
            position = (col.world_from_local * vec4(response.position, 1.0)).xyz;
        } else if (response.kind == 2u) {
            position = prev_world;
        }
    }
    return GpuParticle(vec4(position, moved.position.w), vec4(velocity, select(0.0, 1.0, touched)));
}

// ---- Exact contact (bvh_cloth_core::colliders::exact_contact and triangles), in the same order of
// operations: the CPU walks a four-wide copy of this tree (bvh_cloth_core::bvh::wide), which
// meets the triangles in this walk's order. A collider's triangles follow its spheres in
// `tree`, three vec4s each.

fn triangle_corner(col: GpuCollider, k: u32, corner: u32) -> vec3<f32> {
    return tree[col.sphere_offset + col.sphere_count + 3u * k + corner].xyz;
}

// bvh_cloth_core::mesh::triangles::closest_point: the Voronoi regions in turn.
fn closest_on_triangle(p: vec3<f32>, a: vec3<f32>, b: vec3<f32>, c: vec3<f32>) -> vec3<f32> {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = dot(ab, ap);
    let d2 = dot(ac, ap);
    if (d1 <= 0.0 && d2 <= 0.0) {
        return a;
    }
    let bp = p - b;
    let d3 = dot(ab, bp);
    let d4 = dot(ac, bp);
    if (d3 >= 0.0 && d4 <= d3) {
        return b;
    }
    let cp = p - c;
    let d5 = dot(ab, cp);
    let d6 = dot(ac, cp);
    if (d6 >= 0.0 && d5 <= d6) {
        return c;
    }
    let vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
        return a + ab * (d1 / (d1 - d3));
    }
    let vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let sum = va + vb + vc;
    if (!(sum > 0.0)) {
        // Only a degenerate triangle gets here; the build leaves those out.
        return a;
    }
    return a + ab * (vb / sum) + ac * (vc / sum);
}

// One edge's signed volume against the line from `origin` along `dir`, from its corners in a
// fixed order, so that the two triangles sharing the edge get the same number.
fn edge_volume(s: vec3<f32>, e: vec3<f32>, origin: vec3<f32>, dir: vec3<f32>) -> f32 {
    var swap = s.x > e.x;
    if (s.x == e.x) {
        swap = s.y > e.y || (s.y == e.y && s.z > e.z);
    }
    if (swap) {
        return -dot(cross(dir, e - origin), s - origin);
    }
    return dot(cross(dir, s - origin), e - origin);
}

// bvh_cloth_core::mesh::triangles::segment_hit: the parameter along p..q, or -1 for a miss.
fn segment_hit(p: vec3<f32>, q: vec3<f32>, a: vec3<f32>, b: vec3<f32>, c: vec3<f32>) -> f32 {
    let n = cross(b - a, c - a);
    let sp = dot(p - a, n);
    let sq = dot(q - a, n);
    let corner = PLANE_ROUNDING * PLANE_ROUNDING * dot(b - a, b - a) * dot(c - a, c - a);
    let on_p = sp * sp <= corner * dot(p - a, p - a);
    let on_q = sq * sq <= corner * dot(q - a, q - a);
    if (!(abs(sp) <= 3.0e38 && abs(sq) <= 3.0e38) || all(n == vec3<f32>(0.0))) {
        return -1.0;
    }
    var t = 0.0;
    var dir = q - p;
    if (on_p) {
        if (on_q) {
            return -1.0;
        }
        dir = n;
    } else if (on_q || (sp > 0.0) != (sq > 0.0)) {
        t = clamp(sp / (sp - sq), 0.0, 1.0);
    } else {
        return -1.0;
    }
    let va = edge_volume(b, c, p, dir);
    let vb = edge_volume(c, a, p, dir);
    let vc = edge_volume(a, b, p, dir);
    let sum = va + vb + vc;
    if (!(abs(sum) > 0.0)) {
        return -1.0;
    }
    if (va / sum >= -EDGE_SLACK && vb / sum >= -EDGE_SLACK && vc / sum >= -EDGE_SLACK) {
        return t;
    }
    return -1.0;
}

// The triangle's unit normal turned to the side `towards` points to (+Y without one).
fn facing(a: vec3<f32>, b: vec3<f32>, c: vec3<f32>, towards: vec3<f32>) -> vec3<f32> {
    let m = cross(b - a, c - a);
    var n = vec3<f32>(0.0, 1.0, 0.0);
    if (dot(m, m) > 0.0) {
        n = normalize(m);
    }
    if (dot(n, towards) < 0.0) {
        return -n;
    }
    return n;
}

// What one query over the triangles does with each triangle whose sphere it reaches:
// TRI_CONTACTS holds the end point off the triangles within `reach` of `prev` and sets `found`
// for any within `lookout`, TRI_SWEEP finds the first triangle the path crosses, TRI_CLOSEST
// the closest point within `reach`.
const TRI_CONTACTS: u32 = 0u;
const TRI_SWEEP: u32 = 1u;
const TRI_CLOSEST: u32 = 2u;

struct TriQuery {
    kind: u32,
    prev: vec3<f32>,
    start_end: vec3<f32>,
    end_point: vec3<f32>,
    thickness: f32,
    reach: f32,
    lookout: f32,
    found: u32,
    value: f32,
    point: vec3<f32>,
    triangle: u32,
    touched: bool,
    velocity: vec3<f32>,
}

fn sphere_reaches(sphere: vec4<f32>, p: vec3<f32>, reach: f32) -> bool {
    let r = sphere.w + reach;
    let d = p - sphere.xyz;
    return dot(d, d) <= r * r;
}

// The triangle's corners are read only once its sphere is within reach.
// Whether the path from p to q may cross the sphere's triangle: whether it passes within the
// sphere's radius of its centre, grown by a thousandth of the radius and a hundred-thousandth
// of the path's length, more than a crossing within EDGE_SLACK of an edge and the rounding of
// the closest point need. (The CPU tests the triangle's box grown by the sweep's slack.)
fn segment_near_sphere(sphere: vec4<f32>, p: vec3<f32>, q: vec3<f32>) -> bool {
    let d = q - p;
    let a = dot(d, d);
    var t = 0.0;
    if (a > 0.0) {
        t = clamp(dot(sphere.xyz - p, d) / a, 0.0, 1.0);
    }
    let e = p + t * d - sphere.xyz;
    let r = sphere.w * 1.001;
    return dot(e, e) <= r * r + 1.0e-10 * a;
}

fn consider_triangle(q: ptr<function, TriQuery>, col: GpuCollider, k: u32, sphere: vec4<f32>) {
    switch (*q).kind {
        case TRI_CONTACTS: {
            if (!sphere_reaches(sphere, (*q).prev, (*q).lookout)) {
                return;
            }
            let a = triangle_corner(col, k, 0u);
            let b = triangle_corner(col, k, 1u);
            let c = triangle_corner(col, k, 2u);
            let closest = closest_on_triangle((*q).prev, a, b, c);
            let away = (*q).prev - closest;
            let dist = length(away);
            if (dist >= (*q).lookout) {
                return;
            }
            (*q).found = 1u;
            if (dist >= (*q).reach) {
                return;
            }
            var n = facing(a, b, c, (*q).prev - (*q).start_end);
            if (dist > 1.0e-3 * (*q).thickness) {
                n = away / dist;
            }
            let below = dot((*q).end_point - closest, n) - (*q).thickness;
            if (below < 0.0) {
                (*q).end_point = (*q).end_point - below * n;
                (*q).touched = true;
                (*q).velocity = contact_velocity((*q).velocity, rotate(col.rotation, n), col.friction);
            }
        }
        case TRI_SWEEP: {
            if (!segment_near_sphere(sphere, (*q).prev, (*q).end_point)) {
                return;
            }
            let a = triangle_corner(col, k, 0u);
            let b = triangle_corner(col, k, 1u);
            let c = triangle_corner(col, k, 2u);
            let t = segment_hit((*q).prev, (*q).end_point, a, b, c);
            if (t >= 0.0 && ((*q).found == 0u || t < (*q).value)) {
                (*q).found = 1u;
                (*q).value = t;
                (*q).triangle = k;
            }
        }
        default: {
            if (!sphere_reaches(sphere, (*q).end_point, (*q).reach)) {
                return;
            }
            let a = triangle_corner(col, k, 0u);
            let b = triangle_corner(col, k, 1u);
            let c = triangle_corner(col, k, 2u);
            let closest = closest_on_triangle((*q).end_point, a, b, c);
            let d = closest - (*q).end_point;
            let d2 = dot(d, d);
            if (d2 < (*q).reach * (*q).reach && ((*q).found == 0u || d2 < (*q).value)) {
                (*q).found = 1u;
                (*q).value = d2;
                (*q).point = closest;
            }
        }
    }
}

// As run_query, over the triangle surface's tree, with the boxes grown by `margin`.
fn run_triangle_query(q: ptr<function, TriQuery>, col: GpuCollider, lo: vec3<f32>, hi: vec3<f32>, margin: f32) {
    if (col.node_count == 0u) {
        let s = tree[col.sphere_offset];
        if (sphere_box_overlaps(s, lo, hi, margin)) {
            consider_triangle(q, col, 0u, s);
        }
        return;
    }
    let root = tree_node(col, 0u);
    if (!boxes_overlap(root.aabb_min, root.aabb_max, lo, hi, margin)) {
        return;
    }
    var stack: array<u32, STACK_SIZE>;
    var top = 1u;
    stack[0] = 0u;
    while (top > 0u) {
        top -= 1u;
        let node = tree_node(col, stack[top]);
        var children = array<u32, 2>(node.right, node.left);
        for (var k = 0; k < 2; k++) {
            let child = children[k];
            if ((child & LEAF_BIT) != 0u) {
                let leaf = child & ~LEAF_BIT;
                let s = tree[col.sphere_offset + leaf];
                if (sphere_box_overlaps(s, lo, hi, margin)) {
                    consider_triangle(q, col, leaf, s);
                }
            } else if (top < STACK_SIZE) {
                let inner = tree_node(col, child);
                if (boxes_overlap(inner.aabb_min, inner.aabb_max, lo, hi, margin)) {
                    stack[top] = child;
                    top += 1u;
                }
            }
        }
    }
}

fn triangle_query(kind: u32, prev: vec3<f32>, end_point: vec3<f32>, thickness: f32, reach: f32, v: vec3<f32>) -> TriQuery {
    return TriQuery(kind, prev, end_point, end_point, thickness, reach, reach, 0u, 0.0, vec3<f32>(0.0), 0u, false, v);
}

// bvh_cloth_core::colliders::exact_contact::TriangleSurface::respond.
fn respond_triangles(col: GpuCollider, prev: vec3<f32>, p: vec3<f32>, velocity: vec3<f32>) -> Response {
    let h = max(col.margin_local, col.size.x);
    let band = h * (1.0 + CONTACT_BAND);
    // 1. Contacts at the previous position, looking along a short path too: with no triangle
    // that near, the particle is free.
    let path = distance(prev, p);
    let short = path <= band;
    var q = triangle_query(TRI_CONTACTS, prev, p, h, band, velocity);
    if (short) {
        let size = max(max(abs(prev.x), abs(prev.y)), abs(prev.z));
        q.lookout = band + path + col.size.y + LOOKOUT_ROUNDING * size;
    }
    run_triangle_query(&q, col, prev, prev, q.lookout);
    if (short && q.found == 0u) {
        return Response(0u, p, q.velocity);
    }
    var target_point = q.end_point;
    var v = q.velocity;
    var touched = q.touched;
    // 2. Sweep.
    var sweep = triangle_query(TRI_SWEEP, prev, target_point, h, 0.0, v);
    run_triangle_query(&sweep, col, min(prev, target_point), max(prev, target_point), 0.0);
    // Whether the path to `target_point` is known to cross nothing.
    var path_clear = sweep.found == 0u;
    if (sweep.found != 0u) {
        let k = sweep.triangle;
        let hit = mix(prev, target_point, sweep.value);
        let n = facing(triangle_corner(col, k, 0u), triangle_corner(col, k, 1u), triangle_corner(col, k, 2u), prev - hit);
        target_point = hit + n * h;
        touched = true;
        v = contact_velocity(v, rotate(col.rotation, n), col.friction);
    }
    // 3. Clearance.
    let clear = h * (1.0 - CONTACT_BAND);
    for (var round = 0u; round < MAX_PASSES; round++) {
        var near = triangle_query(TRI_CLOSEST, prev, target_point, h, clear, v);
        run_triangle_query(&near, col, target_point, target_point, clear);
        if (near.found == 0u) {
            break;
        }
        let away = target_point - near.point;
        var n = vec3<f32>(0.0, 1.0, 0.0);
        if (dot(away, away) > 0.0) {
            n = normalize(away);
        } else if (dot(prev - target_point, prev - target_point) > 0.0) {
            n = normalize(prev - target_point);
        }
        target_point = near.point + n * h;
        touched = true;
        path_clear = false;
        v = contact_velocity(v, rotate(col.rotation, n), col.friction);
    }
    // 4. Guard, unless the sweep has just found this very path clear.
    if (!touched) {
        return Response(0u, p, v);
    }
    if (path_clear) {
        return Response(1u, target_point, v);
    }
    var guard = triangle_query(TRI_SWEEP, prev, target_point, h, 0.0, v);
    run_triangle_query(&guard, col, min(prev, target_point), max(prev, target_point), 0.0);
    if (guard.found != 0u) {
        return Response(2u, target_point, v);
    }
    return Response(1u, target_point, v);
}
