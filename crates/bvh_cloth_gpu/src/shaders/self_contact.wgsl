// Self-contact and contact between cloths (bvh_cloth_core::self_contact), for every cloth of
// the batch with a contact thickness, in the same order of operations as the CPU reference.
// Per substep:
// - contact_begin, before the integrator, one thread per particle slot and per bucket: keeps
//   each contact particle's position at the start of the substep, clears its sums, empties
//   the grid's bucket counts, and clears untangling's words of the substep;
// then, after the integrator's last kernel (collision response included):
// - contact_count, one thread per primitive (every triangle, then every edge): its box over the
//   substep (where its corners were at the start and are now), grown by the largest thickness,
//   and one count in the bucket of each cell the box overlaps (at most MAX_SPAN cells along an
//   axis, each bucket once);
// - contact_scan_blocks, contact_scan_top and contact_scan_add: the exclusive prefix sum of the
//   counts, in blocks of 256 buckets (one workgroup of 64 threads each), then the blocks' sums
//   (one workgroup), then the blocks' offsets added back: each bucket's first entry;
// - contact_scatter, one thread per primitive: the primitive entered in each of its buckets;
// - untangling's kernels (untangle.wgsl): which particles lie through another cloth, or
//   through another sheet of their own cloth, at the substep's start, so that their contacts
//   with it (touch and edge_touch) take them back through;
// - contact_find, one thread per particle: the buckets of the cells its path over the substep
//   overlaps (at most MAX_PATH_SPAN along an axis), at most MAX_CANDIDATES triangles of each,
//   each triangle once, and for each contact (within the thickness at the end, or gone through
//   the triangle during the substep) the corrections of the point and of the triangle's free
//   corners, added to their sums;
// - contact_apply, one thread per particle: the mean of its corrections, then the response
//   against every collider from where it was; its sums cleared;
// - contact_find_edges, one thread per edge: the buckets of the cells its box over the substep
//   (from where the points' corrections left it) overlaps, at most MAX_CANDIDATES later edges
//   of each, each once, tested by their boxes as the corrections left them, grown by the
//   largest thickness, and for each contact (within the thickness, or gone through each other
//   during the substep) the corrections of the four ends;
// - contact_apply again.
//
// A bucket holds its triangles first, from its start up to where the scatter's cursor ends,
// then its edges, placed down from its end, as on the CPU; within each run the entries lie in
// the order the scatter's atomics gave them, not in primitive order. An edge's search reads at
// most SCANNED_ENTRIES edges of a bucket (it skips the edges before its own), and where a
// bucket holds more than MAX_CANDIDATES of the primitives a search looks for, the ones it
// examines may differ from the CPU's (both count the search as clamped).
//
// The sums are fixed-point integers, so that atomic adds give one answer whatever the order
// the threads run in: the result is deterministic, and differs from the CPU's float sums by
// the rounding of each correction to 2^-20 m (positions) and 2^-14 m/s (velocities). Every loop
// is bounded and every write is checked against its buffer: the grid has room for
// `entry_capacity` entries, and entries past it are dropped and counted as clamped.

#define_import_path bvh_cloth::self_contact

#import bvh_cloth::types::{GpuParticle, thread_index, all_finite}
#import bvh_cloth::springs::{particle_info, cloths}
#import bvh_cloth::collision::{collide, closest_on_triangle, layers_meet}
#import bvh_cloth::block_descent::{inertial, CONTACT_MOVED}
#import bvh_cloth::constants::{NO_CLOTH, INTEGRATOR_MULTIGRID, NO_CORNER, MAX_CANDIDATES, MAX_SPAN, MAX_PATH_SPAN, MAX_HELD_SCALE, CONTACT_TRIANGLE_WORDS}

struct ContactFrame {
    triangle_count: u32,
    buckets: u32,
    blocks: u32,
    entry_capacity: u32,
    inv_cell: f32,
    grow: f32,
    dispatch_width: u32,
    particle_slots: u32,
    edge_count: u32,
    cloth_slots: u32,
    pad_a: u32,
    pad_b: u32,
}

@group(0) @binding(35) var<uniform> contact: ContactFrame;
// Per particle slot, two vec4s: the position at the start of the substep, the rest position.
@group(0) @binding(36) var<storage, read_write> contact_points: array<vec4<f32>>;
// Per primitive (every triangle, then every edge), five vec4s
// (bvh_cloth_gpu::layout::gpu_contact_triangles and gpu_contact_edges): corners (NO_CORNER the
// third of an edge) and cloth; rest box; current grown box (f32 bits).
@group(0) @binding(37) var<storage, read_write> contact_triangles: array<vec4<u32>>;
// The grid: 4 statistics words, then the bucket counts, the bucket cursors, the bucket starts
// (one more than the buckets), the blocks' sums, the entries, and untangling's words
// (tangle_at).
@group(0) @binding(38) var<storage, read_write> contact_grid: array<atomic<u32>>;
// Per particle slot, eight words: position correction (3), velocity correction (3), contacts.
@group(0) @binding(39) var<storage, read_write> contact_sums: array<atomic<i32>>;
@group(0) @binding(40) var<storage, read_write> contact_state: array<GpuParticle>;

const SUM_WORDS: u32 = 8u;
const POSITION_SCALE: f32 = 1048576.0;  // 2^20 per metre
const VELOCITY_SCALE: f32 = 16384.0;    // 2^14 per m/s
const POSITION_LIMIT: f32 = 1.0;        // largest correction of one contact, m
const VELOCITY_LIMIT: f32 = 64.0;       // m/s
const STAT_CONTACTS: u32 = 0u;
const STAT_CLAMPED: u32 = 1u;
const STAT_CLAMPED_EDGES: u32 = 2u;
const STAT_CROSSINGS: u32 = 3u;
// The most entries of one bucket an edge's search reads.
const SCANNED_ENTRIES: u32 = 4u * MAX_CANDIDATES;
const GRID_HEADER: u32 = 4u;
const SCAN_BLOCK: u32 = 256u;
const SCAN_THREADS: u32 = 64u;

fn count_at(b: u32) -> u32 {
    return GRID_HEADER + b;
}

fn cursor_at(b: u32) -> u32 {
    return GRID_HEADER + contact.buckets + b;
}

fn start_at(b: u32) -> u32 {
    return GRID_HEADER + 2u * contact.buckets + b;
}

fn block_sum_at(k: u32) -> u32 {
    return GRID_HEADER + 3u * contact.buckets + 1u + k;
}

fn entry_at(e: u32) -> u32 {
    return GRID_HEADER + 3u * contact.buckets + 1u + contact.blocks + e;
}

// Untangling's words (untangle.wgsl), after the grid's entries: the pairs of triangles found
// crossing in this substep and the substeps left before the next search for them;
// TANGLE_CLOTH_WORDS per cloth slot (TANGLE_CLOTH_*); each triangle's neighbours across its
// three edges (NO_CLOTH for none: written once, with the buffers); TANGLE_TRIANGLE_WORDS per
// triangle (TANGLE_TRIANGLE_*); and TANGLE_PARTICLE_WORDS per particle slot
// (TANGLE_PARTICLE_*). A label (what a particle lies through, or the sheet it belongs to) is a
// cloth's slot, or, for a sheet of a cloth that another sheet of it passes through, the cloth
// slots' count plus the sheet's ring's root triangle.
const TANGLE_CROSSINGS: u32 = 0u;
const TANGLE_WAIT: u32 = 1u;
const TANGLE_HEADER: u32 = 2u;
const TANGLE_CLOTH_WORDS: u32 = 5u;
const TANGLE_TRIANGLE_WORDS: u32 = 8u;
const TANGLE_PARTICLE_WORDS: u32 = 5u;
// A cloth's largest part: its size in triangles and its first triangle; its particles on the
// wrong side of another cloth; the other cloth whose triangles cut its own, plus one (0 for
// none); and 1 if its triangles cut each other.
const TANGLE_CLOTH_SIZE: u32 = 0u;
const TANGLE_CLOTH_ROOT: u32 = 1u;
const TANGLE_CLOTH_WRONG: u32 = 2u;
const TANGLE_CLOTH_PARTNER: u32 = 3u;
const TANGLE_CLOTH_SELF: u32 = 4u;
// A triangle: its parent in the union-find of parts and rings; the other cloth that cuts it,
// plus one (0 for none); at a part's root, the part's size; the least triangle of its own
// cloth it intersects (NO_CLOTH for none: it is in no ring); at a part's root, the least root of
// a ring beside the part (NO_CLOTH for none); at a ring's root, its particles on the wrong
// side, the ring whose sheet they are taken back through (NO_CLOTH for none), and 1 if its
// sheet is the one another ring goes back through.
const TANGLE_TRIANGLE_PARENT: u32 = 0u;
const TANGLE_TRIANGLE_CUT: u32 = 1u;
const TANGLE_TRIANGLE_SIZE: u32 = 2u;
const TANGLE_TRIANGLE_SELF: u32 = 3u;
const TANGLE_TRIANGLE_BESIDE: u32 = 4u;
const TANGLE_TRIANGLE_RING_WRONG: u32 = 5u;
const TANGLE_TRIANGLE_RING_MOVED: u32 = 6u;
const TANGLE_TRIANGLE_RING_SHEET: u32 = 7u;
// A particle: 1 if it is a corner of its cloth's largest part; 1 once it is counted among its
// cloth's particles on the wrong side of another; the label it lies through (NO_CLOTH for
// none); the label of its sheet (its cloth's slot unless a sheet of its own); the least ring
// that encloses it (NO_CLOTH for none).
const TANGLE_PARTICLE_ON_LARGEST: u32 = 0u;
const TANGLE_PARTICLE_COUNTED: u32 = 1u;
const TANGLE_PARTICLE_WRONG: u32 = 2u;
const TANGLE_PARTICLE_SHEET: u32 = 3u;
const TANGLE_PARTICLE_RING: u32 = 4u;

fn tangle_at(k: u32) -> u32 {
    return entry_at(contact.entry_capacity) + k;
}

fn cloth_word(c: u32, k: u32) -> u32 {
    return tangle_at(TANGLE_HEADER + TANGLE_CLOTH_WORDS * c + k);
}

fn neighbour_word(t: u32, k: u32) -> u32 {
    return tangle_at(TANGLE_HEADER + TANGLE_CLOTH_WORDS * contact.cloth_slots + 3u * t + k);
}

fn triangle_word(t: u32, k: u32) -> u32 {
    let base = TANGLE_HEADER + TANGLE_CLOTH_WORDS * contact.cloth_slots + 3u * contact.triangle_count;
    return tangle_at(base + TANGLE_TRIANGLE_WORDS * t + k);
}

fn particle_word(p: u32, k: u32) -> u32 {
    let base = TANGLE_HEADER + TANGLE_CLOTH_WORDS * contact.cloth_slots
        + (3u + TANGLE_TRIANGLE_WORDS) * contact.triangle_count;
    return tangle_at(base + TANGLE_PARTICLE_WORDS * p + k);
}

// The label particle slot p lies through, as this substep's analysis found it (untangle.wgsl):
// its contacts with the particles of that label's sheet take it back through. NO_CLOTH for
// none.
fn wrong_side(p: u32) -> u32 {
    return atomicLoad(&contact_grid[particle_word(p, TANGLE_PARTICLE_WRONG)]);
}

// The label of particle slot p's sheet.
fn sheet(p: u32) -> u32 {
    return atomicLoad(&contact_grid[particle_word(p, TANGLE_PARTICLE_SHEET)]);
}

// The pairs of crossing triangles this substep's analysis found (untangle.wgsl): while it is 0,
// no particle lies through anything.
fn crossings() -> u32 {
    return atomicLoad(&contact_grid[tangle_at(TANGLE_CROSSINGS)]);
}

// Whether particle slot a lies through the sheet of one of the particles b (NO_CLOTH for none).
fn lies_through(a: u32, b: vec4<u32>) -> bool {
    let w = wrong_side(a);
    if (w == NO_CLOTH) {
        return false;
    }
    for (var k = 0u; k < 4u; k++) {
        if (b[k] != NO_CLOTH && sheet(b[k]) == w) {
            return true;
        }
    }
    return false;
}

// The cloth of particle slot i if it has self-contact, else NO_CLOTH.
fn contact_cloth(i: u32) -> u32 {
    if (i >= contact.particle_slots) {
        return NO_CLOTH;
    }
    let c = particle_info[i].w;
    if (c == NO_CLOTH || cloths[c].contact_thickness <= 0.0) {
        return NO_CLOTH;
    }
    return c;
}

// bvh_cloth_core::self_contact::cell_of, coordinates held inside i32's range.
fn cell_of(p: vec3<f32>) -> vec3<i32> {
    return vec3<i32>(clamp(floor(p * contact.inv_cell), vec3(-2147483648.0), vec3(2147483520.0)));
}

// bvh_cloth_core::self_contact::bucket.
fn bucket_of(c: vec3<i32>) -> u32 {
    let u = bitcast<vec3<u32>>(c);
    return ((u.x * 73856093u) ^ (u.y * 19349663u) ^ (u.z * 83492791u)) & (contact.buckets - 1u);
}

fn corner_position(i: u32) -> vec3<f32> {
    return contact_state[i].position.xyz;
}

@compute @workgroup_size(8, 8, 1)
fn contact_begin(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = thread_index(id, contact.dispatch_width);
    if (i < contact.buckets) {
        atomicStore(&contact_grid[count_at(i)], 0u);
    }
    // Untangling's words of the substep (untangle.wgsl).
    if (i == 0u) {
        atomicStore(&contact_grid[tangle_at(TANGLE_CROSSINGS)], 0u);
    }
    if (i < contact.cloth_slots) {
        for (var k = 0u; k < TANGLE_CLOTH_WORDS; k++) {
            atomicStore(&contact_grid[cloth_word(i, k)], select(0u, NO_CLOTH, k == TANGLE_CLOTH_ROOT));
        }
    }
    if (i < contact.triangle_count) {
        for (var k = 0u; k < TANGLE_TRIANGLE_WORDS; k++) {
            let none = k == TANGLE_TRIANGLE_SELF || k == TANGLE_TRIANGLE_BESIDE || k == TANGLE_TRIANGLE_RING_MOVED;
            atomicStore(&contact_grid[triangle_word(i, k)], select(select(0u, NO_CLOTH, none), i, k == TANGLE_TRIANGLE_PARENT));
        }
    }
    if (contact_cloth(i) != NO_CLOTH) {
        contact_points[2u * i] = contact_state[i].position;
        for (var k = 0u; k < SUM_WORDS; k++) {
            atomicStore(&contact_sums[SUM_WORDS * i + k], 0);
        }
        atomicStore(&contact_grid[particle_word(i, TANGLE_PARTICLE_ON_LARGEST)], 0u);
        atomicStore(&contact_grid[particle_word(i, TANGLE_PARTICLE_COUNTED)], 0u);
        atomicStore(&contact_grid[particle_word(i, TANGLE_PARTICLE_WRONG)], NO_CLOTH);
        atomicStore(&contact_grid[particle_word(i, TANGLE_PARTICLE_SHEET)], contact_cloth(i));
        atomicStore(&contact_grid[particle_word(i, TANGLE_PARTICLE_RING)], NO_CLOTH);
    }
}

// The cells of a box (bvh_cloth_core::self_contact::cells_of_box), capped at `span` cells along
// each axis; `valid` is false for a box that is not finite, `capped` true where the cap cut it.
struct CellRange {
    lo: vec3<i32>,
    hi: vec3<i32>,
    valid: bool,
    capped: bool,
}

fn cells_of_box(lo: vec3<f32>, hi: vec3<f32>, span: i32) -> CellRange {
    var range: CellRange;
    range.valid = all_finite(lo) && all_finite(hi);
    if (!range.valid) {
        return range;
    }
    range.lo = cell_of(lo);
    let full = cell_of(hi);
    range.hi = min(range.lo + vec3(span - 1), full);
    range.capped = any(range.hi != full);
    range.valid = all(range.hi >= range.lo);
    return range;
}

// Primitive t's cells: the range of its box over the substep, grown (written into the
// primitive's box words), capped at MAX_SPAN cells along each axis.
fn primitive_cells(t: u32, record: bool) -> CellRange {
    let corners = contact_triangles[CONTACT_TRIANGLE_WORDS * t];
    let a = corner_position(corners.x);
    let b = corner_position(corners.y);
    let d = contact_points[2u * corners.x].xyz;
    let e = contact_points[2u * corners.y].xyz;
    var lo = min(min(a, b), min(d, e));
    var hi = max(max(a, b), max(d, e));
    if (corners.z != NO_CORNER) {
        let c = corner_position(corners.z);
        let f = contact_points[2u * corners.z].xyz;
        lo = min(lo, min(c, f));
        hi = max(hi, max(c, f));
    }
    lo -= contact.grow;
    hi += contact.grow;
    let valid = all_finite(lo) && all_finite(hi);
    if (record) {
        // A box that is not finite is stored empty, so that no point is inside it.
        let box_lo = select(vec3(1.0), lo, valid);
        let box_hi = select(vec3(-1.0), hi, valid);
        contact_triangles[CONTACT_TRIANGLE_WORDS * t + 3u] = vec4(bitcast<vec3<u32>>(box_lo), 0u);
        contact_triangles[CONTACT_TRIANGLE_WORDS * t + 4u] = vec4(bitcast<vec3<u32>>(box_hi), 0u);
    }
    let range = cells_of_box(lo, hi, MAX_SPAN);
    if (record && range.valid && range.capped) {
        atomicAdd(&contact_grid[STAT_CLAMPED], 1u);
    }
    return range;
}

// Counts (or, with `place`, enters) primitive t in each bucket its cells hash to, once each.
fn visit_buckets(t: u32, place: bool) {
    let range = primitive_cells(t, !place);
    if (!range.valid) {
        return;
    }
    var used: array<u32, 64>;
    var count = 0u;
    let span = range.hi - range.lo;
    for (var z = 0; z <= span.z; z++) {
        for (var y = 0; y <= span.y; y++) {
            for (var x = 0; x <= span.x; x++) {
                let b = bucket_of(range.lo + vec3(x, y, z));
                var seen = false;
                for (var k = 0u; k < count; k++) {
                    seen = seen || used[k] == b;
                }
                if (seen) {
                    continue;
                }
                used[count] = b;
                count++;
                if (place) {
                    // Triangles from the bucket's start, edges from its end: the cursor ends
                    // where the triangles end and the edges begin.
                    var e: u32;
                    if (t < contact.triangle_count) {
                        e = atomicAdd(&contact_grid[cursor_at(b)], 1u);
                    } else {
                        e = atomicLoad(&contact_grid[start_at(b + 1u)]) - 1u - atomicAdd(&contact_grid[count_at(b)], 1u);
                    }
                    if (e < contact.entry_capacity) {
                        atomicStore(&contact_grid[entry_at(e)], t);
                    }
                } else {
                    atomicAdd(&contact_grid[count_at(b)], 1u);
                }
            }
        }
    }
}

@compute @workgroup_size(8, 8, 1)
fn contact_count(@builtin(global_invocation_id) id: vec3<u32>) {
    let t = thread_index(id, contact.dispatch_width);
    if (t < contact.triangle_count + contact.edge_count) {
        visit_buckets(t, false);
    }
}

var<workgroup> scan_partial: array<u32, 64>;

// The exclusive prefix sum of `value` over the workgroup's 64 threads (Hillis and Steele);
// every thread of the workgroup calls it.
fn workgroup_exclusive_scan(t: u32, value: u32) -> u32 {
    scan_partial[t] = value;
    workgroupBarrier();
    for (var offset = 1u; offset < SCAN_THREADS; offset *= 2u) {
        var add = 0u;
        if (t >= offset) {
            add = scan_partial[t - offset];
        }
        workgroupBarrier();
        scan_partial[t] += add;
        workgroupBarrier();
    }
    return scan_partial[t] - value;
}

fn scan_block(wg: vec3<u32>, groups: vec3<u32>) -> u32 {
    return wg.x + wg.y * groups.x;
}

@compute @workgroup_size(64, 1, 1)
fn contact_scan_blocks(
    @builtin(local_invocation_index) t: u32,
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let block = scan_block(wg, groups);
    if (block >= contact.blocks) {
        return;
    }
    let first = block * SCAN_BLOCK + 4u * t;
    var before_each: array<u32, 4>;
    var sum = 0u;
    for (var k = 0u; k < 4u; k++) {
        before_each[k] = sum;
        sum += atomicLoad(&contact_grid[count_at(first + k)]);
    }
    let before = workgroup_exclusive_scan(t, sum);
    for (var k = 0u; k < 4u; k++) {
        atomicStore(&contact_grid[start_at(first + k)], before + before_each[k]);
    }
    if (t == SCAN_THREADS - 1u) {
        atomicStore(&contact_grid[block_sum_at(block)], before + sum);
    }
}

@compute @workgroup_size(64, 1, 1)
fn contact_scan_top(@builtin(local_invocation_index) t: u32) {
    let per = (contact.blocks + SCAN_THREADS - 1u) / SCAN_THREADS;
    let first = t * per;
    let last = min(first + per, contact.blocks);
    var sum = 0u;
    for (var k = first; k < last; k++) {
        sum += atomicLoad(&contact_grid[block_sum_at(k)]);
    }
    let before = workgroup_exclusive_scan(t, sum);
    var running = before;
    for (var k = first; k < last; k++) {
        let s = atomicLoad(&contact_grid[block_sum_at(k)]);
        atomicStore(&contact_grid[block_sum_at(k)], running);
        running += s;
    }
    if (t == SCAN_THREADS - 1u) {
        let total = before + sum;
        atomicStore(&contact_grid[start_at(contact.buckets)], total);
        if (total > contact.entry_capacity) {
            atomicAdd(&contact_grid[STAT_CLAMPED], 1u);
        }
    }
}

@compute @workgroup_size(64, 1, 1)
fn contact_scan_add(
    @builtin(local_invocation_index) t: u32,
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let block = scan_block(wg, groups);
    if (block >= contact.blocks) {
        return;
    }
    let offset = atomicLoad(&contact_grid[block_sum_at(block)]);
    for (var k = 0u; k < 4u; k++) {
        let b = block * SCAN_BLOCK + 4u * t + k;
        let start = atomicLoad(&contact_grid[start_at(b)]) + offset;
        atomicStore(&contact_grid[start_at(b)], start);
        atomicStore(&contact_grid[cursor_at(b)], start);
        // The count, read by the blocks' sums, now counts the edges placed from the bucket's end.
        atomicStore(&contact_grid[count_at(b)], 0u);
    }
}

@compute @workgroup_size(8, 8, 1)
fn contact_scatter(@builtin(global_invocation_id) id: vec3<u32>) {
    let t = thread_index(id, contact.dispatch_width);
    if (t < contact.triangle_count + contact.edge_count) {
        visit_buckets(t, true);
    }
}

// bvh_cloth_core::mesh::triangles::face_normal: the unit normal, or a zero vector for a triangle
// without one.
fn face_normal(a: vec3<f32>, b: vec3<f32>, c: vec3<f32>) -> vec3<f32> {
    let n = cross(b - a, c - a);
    let rcp = 1.0 / length(n);
    if (all_finite(vec3(rcp)) && rcp > 0.0) {
        return n * rcp;
    }
    return vec3(0.0);
}

// bvh_cloth_core::self_contact::barycentric.
fn barycentric(q: vec3<f32>, a: vec3<f32>, b: vec3<f32>, c: vec3<f32>) -> vec3<f32> {
    let e1 = b - a;
    let e2 = c - a;
    let r = q - a;
    let d11 = dot(e1, e1);
    let d12 = dot(e1, e2);
    let d22 = dot(e2, e2);
    let r1 = dot(r, e1);
    let r2 = dot(r, e2);
    let det = d11 * d22 - d12 * d12;
    let scale = max(d11, d22);
    if (!(det > 1.0e-12 * scale * scale)) {
        return vec3(1.0 / 3.0);
    }
    let u = clamp((d22 * r1 - d12 * r2) / det, 0.0, 1.0);
    let w = clamp((d11 * r2 - d12 * r1) / det, 0.0, 1.0 - u);
    return vec3(1.0 - u - w, u, w);
}

// bvh_cloth_core::self_contact::ContactSolver::project, its corrections added to the sums:
// the contact of particles ids whose constraint sum(coef_k x_k) . n >= h is short by depth,
// their weights free (1 free, 0 pinned) and held (1 for a particle a collider touched in this
// substep, which takes no part unless all four did, its share going to the others), their
// relative velocity along the constraint relative and their friction.
fn project(ids: vec4<u32>, coef: vec4<f32>, free: vec4<f32>, held: vec4<f32>, n: vec3<f32>, depth: f32, relative: vec3<f32>, friction: f32) {
    let denom = dot(free, coef * coef);
    if (denom <= 0.0) {
        return;
    }
    let unheld = free * (vec4(1.0) - held);
    let unheld_denom = dot(unheld, coef * coef);
    var w = free;
    var scale = 1.0;
    if (unheld_denom > 0.0) {
        w = unheld;
        scale = min(denom / unheld_denom, MAX_HELD_SCALE);
    }
    let vn = dot(relative, n);
    var impulse = vec3(0.0);
    if (vn < 0.0) {
        let tangential = relative - vn * n;
        let speed = length(tangential);
        var slow = 0.0;
        if (speed > 0.0) {
            slow = min(friction * -vn / speed, 1.0);
        }
        impulse = -(vn * n + slow * tangential) / denom * scale;
    }
    let lambda = depth / denom * scale;
    for (var k = 0u; k < 4u; k++) {
        if (w[k] > 0.0) {
            add_correction(ids[k], w[k] * coef[k] * lambda * n, w[k] * coef[k] * impulse);
        }
    }
}

fn add_correction(k: u32, dx: vec3<f32>, dv: vec3<f32>) {
    let x = vec3<i32>(round(clamp(dx, vec3(-POSITION_LIMIT), vec3(POSITION_LIMIT)) * POSITION_SCALE));
    let v = vec3<i32>(round(clamp(dv, vec3(-VELOCITY_LIMIT), vec3(VELOCITY_LIMIT)) * VELOCITY_SCALE));
    let at = SUM_WORDS * k;
    atomicAdd(&contact_sums[at], x.x);
    atomicAdd(&contact_sums[at + 1u], x.y);
    atomicAdd(&contact_sums[at + 2u], x.z);
    atomicAdd(&contact_sums[at + 3u], v.x);
    atomicAdd(&contact_sums[at + 4u], v.y);
    atomicAdd(&contact_sums[at + 5u], v.z);
    atomicAdd(&contact_sums[at + 6u], 1);
}

// bvh_cloth_core::self_contact::crossed: whether the point that went from p0 to p1 went through
// the triangle that went from (d, e, f) to (a, b, c), given its sides of the plane before and
// now; in w the point of the triangle as it stands now at the crossing's barycentric weights.
fn crossed(p0: vec3<f32>, p1: vec3<f32>, d: vec3<f32>, e: vec3<f32>, f: vec3<f32>, a: vec3<f32>, b: vec3<f32>, c: vec3<f32>, side_before: f32, side_now: f32, h: f32) -> vec4<f32> {
    if (!(side_before * side_now < 0.0)) {
        return vec4(0.0);
    }
    let s = side_before / (side_before - side_now);
    let ta = mix(d, a, s);
    let tb = mix(e, b, s);
    let tc = mix(f, c, s);
    let at = mix(p0, p1, s);
    let q = closest_on_triangle(at, ta, tb, tc);
    let off = q - at;
    if (!(dot(off, off) < h * h)) {
        return vec4(0.0);
    }
    let w = barycentric(q, ta, tb, tc);
    return vec4(w.x * a + w.y * b + w.z * c, 1.0);
}

// bvh_cloth_core::self_contact::ContactSolver::contact, its corrections added to the sums; the
// triangle is skipped unless its box over the substep meets the point's path's, from path_lo
// to path_hi.
fn touch(p: u32, pc: u32, me: GpuParticle, t: u32, path_lo: vec3<f32>, path_hi: vec3<f32>) {
    let corners = contact_triangles[CONTACT_TRIANGLE_WORDS * t];
    if (corners.x == p || corners.y == p || corners.z == p) {
        return;
    }
    let xp = me.position.xyz;
    let lo = bitcast<vec3<f32>>(contact_triangles[CONTACT_TRIANGLE_WORDS * t + 3u].xyz);
    let hi = bitcast<vec3<f32>>(contact_triangles[CONTACT_TRIANGLE_WORDS * t + 4u].xyz);
    if (!(all(path_lo <= hi) && all(path_hi >= lo))) {
        return;
    }
    let tc = corners.w;
    if (pc != tc && !layers_meet(vec2(cloths[pc].memberships, cloths[pc].filters), vec2(cloths[tc].memberships, cloths[tc].filters))) {
        return;
    }
    let h = 0.5 * (cloths[pc].contact_thickness + cloths[tc].contact_thickness);
    if (pc == tc) {
        let rest_lo = bitcast<vec3<f32>>(contact_triangles[CONTACT_TRIANGLE_WORDS * t + 1u].xyz);
        let rest_hi = bitcast<vec3<f32>>(contact_triangles[CONTACT_TRIANGLE_WORDS * t + 2u].xyz);
        let rest = contact_points[2u * p + 1u].xyz;
        if (all(rest >= rest_lo - h) && all(rest <= rest_hi + h)) {
            return;
        }
    }
    let ca = contact_state[corners.x];
    let cb = contact_state[corners.y];
    let cc = contact_state[corners.z];
    let a = ca.position.xyz;
    let b = cb.position.xyz;
    let c = cc.position.xyz;
    var q = closest_on_triangle(xp, a, b, c);
    let away = xp - q;
    let d2 = dot(away, away);
    if (!all_finite(vec3(d2))) {
        return;
    }
    let d = sqrt(d2);
    let face = face_normal(a, b, c);
    let has_face = any(face != vec3(0.0));
    let pa = contact_points[2u * corners.x].xyz;
    let pb = contact_points[2u * corners.y].xyz;
    let pcorner = contact_points[2u * corners.z].xyz;
    var side_before = dot(contact_points[2u * p].xyz - pa, face_normal(pa, pb, pcorner));
    // A point on the wrong side of the sheet of a corner of the triangle, or a corner on the
    // wrong side of the point's, as untangle.wgsl found them: the side to go back to is the
    // other.
    let only_p = vec4(p, NO_CLOTH, NO_CLOTH, NO_CLOTH);
    let inverted = crossings() != 0u
        && (lies_through(p, vec4(corners.xyz, NO_CLOTH)) || lies_through(corners.x, only_p)
            || lies_through(corners.y, only_p) || lies_through(corners.z, only_p));
    if (inverted) {
        side_before = -side_before;
    }
    let side_now = dot(xp - a, face);
    let through = side_before * side_now < 0.0;
    var n: vec3<f32>;
    var gap: f32;
    if (!(d2 < h * h)) {
        // Farther than the thickness now: a contact only if the point's path went through the
        // triangle during the substep; a point taken back through meets it when it comes
        // within the thickness.
        if (inverted) {
            return;
        }
        let hit = crossed(contact_points[2u * p].xyz, xp, pa, pb, pcorner, a, b, c, side_before, side_now, h);
        if (!has_face || hit.w == 0.0) {
            return;
        }
        n = face * sign(side_before);
        gap = -abs(side_now);
        q = hit.xyz;
    } else if (has_face && through) {
        n = face * sign(side_before);
        gap = -abs(side_now);
    } else if (d > 1.0e-6 * h) {
        n = away / d;
        gap = d;
    } else if (has_face && side_before != 0.0) {
        n = face * sign(side_before);
        gap = 0.0;
    } else {
        n = select(vec3(0.0, 1.0, 0.0), face, has_face);
        gap = 0.0;
    }
    let bary = barycentric(q, a, b, c);
    // Weights 1 free, 0 pinned; a particle a collider touched in this substep (collide's
    // velocity.w) takes no part unless all four did, its share going to the others.
    let free = vec4(me.position.w, ca.position.w, cb.position.w, cc.position.w);
    let held = vec4(me.velocity.w, ca.velocity.w, cb.velocity.w, cc.velocity.w);
    let relative = me.velocity.xyz
        - (bary.x * ca.velocity.xyz + bary.y * cb.velocity.xyz + bary.z * cc.velocity.xyz);
    let friction = 0.5 * (cloths[pc].contact_friction + cloths[tc].contact_friction);
    let ids = vec4(p, corners.x, corners.y, corners.z);
    project(ids, vec4(1.0, -bary), free, held, n, h - gap, relative, friction);
}

@compute @workgroup_size(8, 8, 1)
fn contact_find(@builtin(global_invocation_id) id: vec3<u32>) {
    let p = thread_index(id, contact.dispatch_width);
    let c = contact_cloth(p);
    if (c == NO_CLOTH) {
        return;
    }
    let me = contact_state[p];
    if (!all_finite(me.position.xyz)) {
        return;
    }
    // bvh_cloth_core::self_contact::ContactSolver::contacts_of: the cells of the point's path.
    let prev = contact_points[2u * p].xyz;
    let path_lo = min(prev, me.position.xyz);
    let path_hi = max(prev, me.position.xyz);
    let path = cells_of_box(path_lo, path_hi, MAX_PATH_SPAN);
    if (!path.valid) {
        return;
    }
    var clamped = path.capped;
    let span = path.hi - path.lo;
    for (var z = 0; z <= span.z; z++) {
        for (var y = 0; y <= span.y; y++) {
            for (var x = 0; x <= span.x; x++) {
                let at = path.lo + vec3(x, y, z);
                let b = bucket_of(at);
                // The bucket's triangles: from its start to its cursor.
                let end = min(atomicLoad(&contact_grid[cursor_at(b)]), contact.entry_capacity);
                let start = min(atomicLoad(&contact_grid[start_at(b)]), end);
                clamped = clamped || end - start > MAX_CANDIDATES;
                let last = min(end, start + MAX_CANDIDATES);
                for (var e = start; e < last; e++) {
                    let t = atomicLoad(&contact_grid[entry_at(e)]);
                    // The boxes first, as the CPU's scan: most candidates are beside the path.
                    let lo = bitcast<vec3<f32>>(contact_triangles[CONTACT_TRIANGLE_WORDS * t + 3u].xyz);
                    let hi = bitcast<vec3<f32>>(contact_triangles[CONTACT_TRIANGLE_WORDS * t + 4u].xyz);
                    if (!(all(path_lo <= hi) && all(path_hi >= lo))) {
                        continue;
                    }
                    // Once per triangle: in the first cell both it and the path cover.
                    let cells = cells_of_box(lo, hi, MAX_SPAN);
                    if (!cells.valid || any(max(cells.lo, path.lo) != at)) {
                        continue;
                    }
                    touch(p, c, me, t, path_lo, path_hi);
                }
            }
        }
    }
    if (clamped) {
        atomicAdd(&contact_grid[STAT_CLAMPED], 1u);
    }
}

@compute @workgroup_size(8, 8, 1)
fn contact_apply(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = thread_index(id, contact.dispatch_width);
    if (contact_cloth(i) == NO_CLOTH) {
        return;
    }
    let at = SUM_WORDS * i;
    let count = atomicLoad(&contact_sums[at + 6u]);
    if (count <= 0) {
        return;
    }
    atomicAdd(&contact_grid[STAT_CONTACTS], u32(count));
    let mean = 1.0 / f32(count);
    let dx = vec3<f32>(
        vec3(atomicLoad(&contact_sums[at]), atomicLoad(&contact_sums[at + 1u]), atomicLoad(&contact_sums[at + 2u])),
    ) / POSITION_SCALE;
    let dv = vec3<f32>(
        vec3(atomicLoad(&contact_sums[at + 3u]), atomicLoad(&contact_sums[at + 4u]), atomicLoad(&contact_sums[at + 5u])),
    ) / VELOCITY_SCALE;
    for (var k = 0u; k < SUM_WORDS; k++) {
        atomicStore(&contact_sums[at + k], 0);
    }
    let me = contact_state[i];
    var moved: GpuParticle;
    moved.position = vec4(me.position.xyz + dx * mean, me.position.w);
    moved.velocity = vec4(me.velocity.xyz + dv * mean, 0.0);
    let c = contact_cloth(i);
    var done = collide(me.position.xyz, moved, vec2(cloths[c].memberships, cloths[c].filters));
    // Held by a collider in the integrator's response, as the edges' contacts weigh it.
    done.velocity.w = me.velocity.w;
    contact_state[i] = done;
    // bvh_cloth_core::solver::block_descent's moved_by_contact: a multigrid cloth's BDF2 starts
    // again, and its next correction leaves the particle where the sweep puts it.
    if (cloths[c].integrator == INTEGRATOR_MULTIGRID) {
        atomicStore(&cloths[c].broken, 1u);
        inertial[i].position.w = CONTACT_MOVED;
    }
}

// bvh_cloth_core::self_contact::edge_edge::closest_on_segments: where along the segments p0 p1
// and q0 q1 their closest points lie.
fn closest_on_segments(p0: vec3<f32>, p1: vec3<f32>, q0: vec3<f32>, q1: vec3<f32>) -> vec2<f32> {
    let d = p1 - p0;
    let e = q1 - q0;
    let r = p0 - q0;
    let a = dot(d, d);
    let c = dot(e, e);
    let f = dot(e, r);
    let tiny = 1.1920929e-7 * max(a, c);
    if (a <= tiny && c <= tiny) {
        return vec2(0.0);
    }
    if (a <= tiny) {
        return vec2(0.0, clamp(f / c, 0.0, 1.0));
    }
    let g = dot(d, r);
    if (c <= tiny) {
        return vec2(clamp(-g / a, 0.0, 1.0), 0.0);
    }
    let b = dot(d, e);
    let det = a * c - b * b;
    var s = 0.0;
    if (det > 1.0e-6 * a * c) {
        s = clamp((b * f - g * c) / det, 0.0, 1.0);
    }
    let t = (b * s + f) / c;
    if (t < 0.0) {
        return vec2(clamp(-g / a, 0.0, 1.0), 0.0);
    }
    if (t > 1.0) {
        return vec2(clamp((b - g) / a, 0.0, 1.0), 1.0);
    }
    return vec2(s, t);
}

// bvh_cloth_core::self_contact::edge_edge::common_normal, a zero vector for None.
fn common_normal(p0: vec3<f32>, p1: vec3<f32>, q0: vec3<f32>, q1: vec3<f32>) -> vec3<f32> {
    let d = p1 - p0;
    let e = q1 - q0;
    let c = cross(d, e);
    let c2 = dot(c, c);
    if (c2 > 1.0e-8 * dot(d, d) * dot(e, e) && all_finite(vec3(c2))) {
        return c / sqrt(c2);
    }
    return vec3(0.0);
}

// bvh_cloth_core::self_contact::edge_edge::crossed: whether the edges that went from (r0 r1,
// u0 u1) to (p0 p1, q0 q1) went through each other; where along each they met in xy, z 1 for a
// crossing.
fn edges_crossed(r0: vec3<f32>, r1: vec3<f32>, u0: vec3<f32>, u1: vec3<f32>, p0: vec3<f32>, p1: vec3<f32>, q0: vec3<f32>, q1: vec3<f32>, side_before: f32, side_now: f32, h: f32) -> vec3<f32> {
    if (!(side_before * side_now < 0.0)) {
        return vec3(0.0);
    }
    let at = side_before / (side_before - side_now);
    let a0 = mix(r0, p0, at);
    let a1 = mix(r1, p1, at);
    let b0 = mix(u0, q0, at);
    let b1 = mix(u1, q1, at);
    let st = closest_on_segments(a0, a1, b0, b1);
    let off = mix(a0, a1, st.x) - mix(b0, b1, st.y);
    if (!(dot(off, off) < h * h)) {
        return vec3(0.0);
    }
    return vec3(st, 1.0);
}

// bvh_cloth_core::self_contact::ContactSolver::edge_contact, its corrections added to the sums:
// edge primitive ep against edge primitive fp.
fn edge_touch(ep: u32, fp: u32) {
    let ea = contact_triangles[CONTACT_TRIANGLE_WORDS * ep];
    let fa = contact_triangles[CONTACT_TRIANGLE_WORDS * fp];
    if (ea.x == fa.x || ea.x == fa.y || ea.y == fa.x || ea.y == fa.y) {
        return;
    }
    let ec = ea.w;
    let fc = fa.w;
    if (ec != fc && !layers_meet(vec2(cloths[ec].memberships, cloths[ec].filters), vec2(cloths[fc].memberships, cloths[fc].filters))) {
        return;
    }
    let h = 0.5 * (cloths[ec].contact_thickness + cloths[fc].contact_thickness);
    let ids = vec4(ea.x, ea.y, fa.x, fa.y);
    let s0 = contact_state[ids.x];
    let s1 = contact_state[ids.y];
    let s2 = contact_state[ids.z];
    let s3 = contact_state[ids.w];
    let p0 = s0.position.xyz;
    let p1 = s1.position.xyz;
    let q0 = s2.position.xyz;
    let q1 = s3.position.xyz;
    let r0 = contact_points[2u * ids.x].xyz;
    let r1 = contact_points[2u * ids.y].xyz;
    let u0 = contact_points[2u * ids.z].xyz;
    let u1 = contact_points[2u * ids.w].xyz;
    // Their boxes over the substep as the particles stand now, within the thickness.
    let box_e_lo = min(min(p0, p1), min(r0, r1));
    let box_e_hi = max(max(p0, p1), max(r0, r1));
    let box_f_lo = min(min(q0, q1), min(u0, u1));
    let box_f_hi = max(max(q0, q1), max(u0, u1));
    if (!(all(box_e_lo - h <= box_f_hi) && all(box_e_hi + h >= box_f_lo))) {
        return;
    }
    if (ec == fc) {
        let e_lo = bitcast<vec3<f32>>(contact_triangles[CONTACT_TRIANGLE_WORDS * ep + 1u].xyz);
        let e_hi = bitcast<vec3<f32>>(contact_triangles[CONTACT_TRIANGLE_WORDS * ep + 2u].xyz);
        let f_lo = bitcast<vec3<f32>>(contact_triangles[CONTACT_TRIANGLE_WORDS * fp + 1u].xyz);
        let f_hi = bitcast<vec3<f32>>(contact_triangles[CONTACT_TRIANGLE_WORDS * fp + 2u].xyz);
        if (all(e_lo - h <= f_hi) && all(e_hi + h >= f_lo)) {
            return;
        }
    }
    let closest = closest_on_segments(p0, p1, q0, q1);
    var s = closest.x;
    var t = closest.y;
    let away = mix(p0, p1, s) - mix(q0, q1, t);
    let d2 = dot(away, away);
    if (!all_finite(vec3(d2))) {
        return;
    }
    let normal_before = common_normal(r0, r1, u0, u1);
    var normal_now = common_normal(p0, p1, q0, q1);
    if (dot(normal_before, normal_now) < 0.0) {
        normal_now = -normal_now;
    }
    let has_normal = any(normal_now != vec3(0.0));
    var side_before = dot(r0 - u0, normal_before);
    // An edge with an end on the wrong side of the sheet of an end of the other, as
    // untangle.wgsl found them: the side to go back to is the other one.
    let theirs = vec4(fa.x, fa.y, NO_CLOTH, NO_CLOTH);
    let ours = vec4(ea.x, ea.y, NO_CLOTH, NO_CLOTH);
    let inverted = crossings() != 0u
        && (lies_through(ea.x, theirs) || lies_through(ea.y, theirs) || lies_through(fa.x, ours)
            || lies_through(fa.y, ours));
    if (inverted) {
        side_before = -side_before;
    }
    let side_now = dot(p0 - q0, normal_now);
    let through = side_before * side_now < 0.0;
    var n: vec3<f32>;
    var gap: f32;
    if (!(d2 < h * h)) {
        // Farther than the thickness now: a contact only if they went through each other;
        // edges taken back through meet when they come within the thickness.
        if (inverted) {
            return;
        }
        let hit = edges_crossed(r0, r1, u0, u1, p0, p1, q0, q1, side_before, side_now, h);
        if (!has_normal || hit.z == 0.0) {
            return;
        }
        n = normal_now * sign(side_before);
        gap = -abs(side_now);
        s = hit.x;
        t = hit.y;
    } else if (has_normal && through) {
        n = normal_now * sign(side_before);
        gap = -abs(side_now);
    } else if (sqrt(d2) > 1.0e-6 * h) {
        let d = sqrt(d2);
        n = away / d;
        gap = d;
    } else if (has_normal && side_before != 0.0) {
        n = normal_now * sign(side_before);
        gap = 0.0;
    } else {
        return;
    }
    let free = vec4(s0.position.w, s1.position.w, s2.position.w, s3.position.w);
    let held = vec4(s0.velocity.w, s1.velocity.w, s2.velocity.w, s3.velocity.w);
    let relative = mix(s0.velocity.xyz, s1.velocity.xyz, s) - mix(s2.velocity.xyz, s3.velocity.xyz, t);
    let friction = 0.5 * (cloths[ec].contact_friction + cloths[fc].contact_friction);
    project(ids, vec4(1.0 - s, s, t - 1.0, -t), free, held, n, h - gap, relative, friction);
}

@compute @workgroup_size(8, 8, 1)
fn contact_find_edges(@builtin(global_invocation_id) id: vec3<u32>) {
    let e = thread_index(id, contact.dispatch_width);
    if (e >= contact.edge_count) {
        return;
    }
    // bvh_cloth_core::self_contact::ContactSolver::edge_contacts: the cells of the edge's box
    // over the substep.
    let ep = contact.triangle_count + e;
    let ends = contact_triangles[CONTACT_TRIANGLE_WORDS * ep];
    let a = corner_position(ends.x);
    let b = corner_position(ends.y);
    let pa = contact_points[2u * ends.x].xyz;
    let pb = contact_points[2u * ends.y].xyz;
    let box_lo = min(min(a, b), min(pa, pb));
    let box_hi = max(max(a, b), max(pa, pb));
    let range = cells_of_box(box_lo, box_hi, MAX_SPAN);
    if (!range.valid) {
        return;
    }
    var clamped = range.capped;
    let span = range.hi - range.lo;
    for (var z = 0; z <= span.z; z++) {
        for (var y = 0; y <= span.y; y++) {
            for (var x = 0; x <= span.x; x++) {
                let at = range.lo + vec3(x, y, z);
                let bucket = bucket_of(at);
                // The bucket's edges: from its cursor to its end.
                let end = min(atomicLoad(&contact_grid[start_at(bucket + 1u)]), contact.entry_capacity);
                let start = min(atomicLoad(&contact_grid[cursor_at(bucket)]), end);
                let last = min(end, start + SCANNED_ENTRIES);
                clamped = clamped || end > last;
                var examined = 0u;
                for (var k = start; k < last; k++) {
                    // The edges after this one: each pair once.
                    let f = atomicLoad(&contact_grid[entry_at(k)]);
                    if (f <= ep) {
                        continue;
                    }
                    if (examined == MAX_CANDIDATES) {
                        clamped = true;
                        break;
                    }
                    examined++;
                    // The candidate's box as the points' corrections left it, grown (the CPU's
                    // refreshed grid boxes); its cells, those it was entered in before them.
                    let other = contact_triangles[CONTACT_TRIANGLE_WORDS * f];
                    let c = corner_position(other.x);
                    let d = corner_position(other.y);
                    let pc = contact_points[2u * other.x].xyz;
                    let pd = contact_points[2u * other.y].xyz;
                    let now_lo = min(min(c, d), min(pc, pd)) - contact.grow;
                    let now_hi = max(max(c, d), max(pc, pd)) + contact.grow;
                    if (!(all(box_lo <= now_hi) && all(box_hi >= now_lo))) {
                        continue;
                    }
                    let lo = bitcast<vec3<f32>>(contact_triangles[CONTACT_TRIANGLE_WORDS * f + 3u].xyz);
                    let hi = bitcast<vec3<f32>>(contact_triangles[CONTACT_TRIANGLE_WORDS * f + 4u].xyz);
                    let cells = cells_of_box(lo, hi, MAX_SPAN);
                    if (!cells.valid || any(max(cells.lo, range.lo) != at)) {
                        continue;
                    }
                    edge_touch(ep, f);
                }
            }
        }
    }
    if (clamped) {
        atomicAdd(&contact_grid[STAT_CLAMPED_EDGES], 1u);
    }
}
