// Cloth that already crosses (bvh_cloth_core::self_contact's untangling): which particles lie
// through another cloth, or through another sheet of their own cloth, at the substep's start,
// so that their contacts with it take them back through (self_contact.wgsl's touch and
// edge_touch). Run per substep after contact_scatter, before contact_find, in this order:
// - untangle_find, one thread per triangle, unless the last search found nothing fewer than
//   UNTANGLE_EVERY substeps ago: the triangles in the buckets of the triangle's cells, each
//   once (in the first cell both cover), tested against it where the particles stood at the
//   substep's start (an edge of either through the other): of another cloth whose layers meet
//   its own, or of its own cloth sharing no corner and lying farther apart than the thickness
//   in the rest shape. A pair of two cloths marks each triangle cut by the other's cloth and
//   each cloth as crossing the other; a pair within a cloth marks each triangle as in a ring,
//   with the least triangle it intersects, and the cloth as crossing itself;
// - untangle_join, one thread per triangle of a crossing cloth: joins it to its neighbours
//   across its edges in the same state (neither cut nor in a ring, or both in rings) by a
//   union-find, each set's root its least triangle: the parts the cuts leave, and the rings;
// - untangle_size, untangle_largest and untangle_first: each part's size, each cloth's largest,
//   and of the largest the one of least root (the CPU's first part, flooded from the least
//   triangle);
// - untangle_corners: the corners of each cloth's largest part;
// - untangle_outside: between two cloths, the corners of the other parts' triangles and of the
//   cut ones that are no corner of the largest part, counted once each per cloth: they lie
//   through the other cloth. Within one, each part other than the largest takes the least ring
//   beside it;
// - untangle_enclose: within one cloth, the corners of a ring's triangles and of the parts
//   beside it that are no corner of the largest part take the least such ring: it encloses
//   them;
// - untangle_rings: each ring's enclosed particles counted;
// - untangle_link: for each two rings a pair of intersecting triangles joins, the one that
//   encloses fewer particles (the other where one encloses none; the lesser root on a tie) is
//   taken back through the other, whose sheet gets a label of its own;
// - untangle_mark, one thread per particle slot: of two crossing cloths the one with fewer
//   particles through the other (the lower slot on a tie; the other where one has none) is
//   taken back, its particles marked with the other's slot; then the particles enclosed by a
//   ring taken back are marked with the other ring's label, and those enclosed by a ring
//   another goes back through get its label as their sheet. Its first thread also counts down
//   the substeps to the next search;
// - untangle_sheets: the corners of the triangles of a ring another goes back through that
//   are not marked get its label as their sheet.
// As on the CPU, what a ring encloses is the corners of its triangles and of the parts beside
// it, less the largest part's corners. Where the CPU keeps sets, the GPU keeps one of each: a
// cloth crossed by several others is taken as crossing the one of highest slot, a part beside
// several rings and a particle enclosed by several are taken by the least ring, and a ring
// linked to several is taken back through the least; a cloth that crosses itself and another at
// once cuts its parts by both.

#define_import_path bvh_cloth::untangle
#import bvh_cloth::types::{thread_index}
#import bvh_cloth::springs::{cloths}
#import bvh_cloth::collision::{segment_hit, layers_meet}
#import bvh_cloth::self_contact::{contact, contact_points, contact_triangles, contact_grid, contact_cloth, crossings, wrong_side, cells_of_box, bucket_of, cursor_at, start_at, entry_at, tangle_at, cloth_word, neighbour_word, triangle_word, particle_word, STAT_CROSSINGS, TANGLE_CROSSINGS, TANGLE_WAIT, TANGLE_CLOTH_SIZE, TANGLE_CLOTH_ROOT, TANGLE_CLOTH_WRONG, TANGLE_CLOTH_PARTNER, TANGLE_CLOTH_SELF, TANGLE_TRIANGLE_PARENT, TANGLE_TRIANGLE_CUT, TANGLE_TRIANGLE_SIZE, TANGLE_TRIANGLE_SELF, TANGLE_TRIANGLE_BESIDE, TANGLE_TRIANGLE_RING_WRONG, TANGLE_TRIANGLE_RING_MOVED, TANGLE_TRIANGLE_RING_SHEET, TANGLE_PARTICLE_ON_LARGEST, TANGLE_PARTICLE_COUNTED, TANGLE_PARTICLE_WRONG, TANGLE_PARTICLE_SHEET, TANGLE_PARTICLE_RING}
#import bvh_cloth::constants::{NO_CLOTH, MAX_CANDIDATES, MAX_SPAN, CONTACT_TRIANGLE_WORDS, UNTANGLE_EVERY}

// The corners of triangle primitive t where they stood at the substep's start.
fn corners_before(t: u32) -> array<vec3<f32>, 3> {
    let c = contact_triangles[CONTACT_TRIANGLE_WORDS * t];
    return array<vec3<f32>, 3>(contact_points[2u * c.x].xyz, contact_points[2u * c.y].xyz, contact_points[2u * c.z].xyz);
}

// bvh_cloth_core::mesh::triangles::triangles_intersect: an edge of either crosses the other.
fn triangles_intersect(first: array<vec3<f32>, 3>, second: array<vec3<f32>, 3>) -> bool {
    var a = first;
    var b = second;
    for (var k = 0u; k < 3u; k++) {
        let next = (k + 1u) % 3u;
        if (segment_hit(a[k], a[next], b[0], b[1], b[2]) >= 0.0 || segment_hit(b[k], b[next], a[0], a[1], a[2]) >= 0.0) {
            return true;
        }
    }
    return false;
}

fn triangle_cloth(t: u32) -> u32 {
    return contact_triangles[CONTACT_TRIANGLE_WORDS * t].w;
}

// Whether triangles t and u of one cloth share a corner or lie within `h` of each other in the
// rest shape: neighbours on the cloth, not two sheets of it.
fn neighbours_at_rest(t: u32, u: u32, h: f32) -> bool {
    let a = contact_triangles[CONTACT_TRIANGLE_WORDS * t];
    let b = contact_triangles[CONTACT_TRIANGLE_WORDS * u];
    if (any(a.xyz == vec3(b.x)) || any(a.xyz == vec3(b.y)) || any(a.xyz == vec3(b.z))) {
        return true;
    }
    let a_lo = bitcast<vec3<f32>>(contact_triangles[CONTACT_TRIANGLE_WORDS * t + 1u].xyz);
    let a_hi = bitcast<vec3<f32>>(contact_triangles[CONTACT_TRIANGLE_WORDS * t + 2u].xyz);
    let b_lo = bitcast<vec3<f32>>(contact_triangles[CONTACT_TRIANGLE_WORDS * u + 1u].xyz);
    let b_hi = bitcast<vec3<f32>>(contact_triangles[CONTACT_TRIANGLE_WORDS * u + 2u].xyz);
    return all(a_lo - h <= b_hi) && all(a_hi + h >= b_lo);
}

fn tangle_word(t: u32, k: u32) -> u32 {
    return atomicLoad(&contact_grid[triangle_word(t, k)]);
}

fn crosses_itself(c: u32) -> bool {
    return atomicLoad(&contact_grid[cloth_word(c, TANGLE_CLOTH_SELF)]) != 0u;
}

// Whether triangle t is in a ring: it intersects a triangle of its own cloth.
fn in_ring(t: u32) -> bool {
    return tangle_word(t, TANGLE_TRIANGLE_SELF) != NO_CLOTH;
}

fn parent(t: u32) -> u32 {
    return atomicLoad(&contact_grid[triangle_word(t, TANGLE_TRIANGLE_PARENT)]);
}

// Whether triangle t is cut: by another cloth, or in a ring of its own.
fn is_cut(t: u32) -> bool {
    return tangle_word(t, TANGLE_TRIANGLE_CUT) != 0u || in_ring(t);
}

// Whether triangle t takes part in the analysis this substep: some triangles crossed, and its
// cloth crosses another or itself.
fn analysed(t: u32) -> bool {
    if (t >= contact.triangle_count || crossings() == 0u) {
        return false;
    }
    let c = triangle_cloth(t);
    return atomicLoad(&contact_grid[cloth_word(c, TANGLE_CLOTH_PARTNER)]) != 0u || crosses_itself(c);
}

@compute @workgroup_size(8, 8, 1)
fn untangle_find(@builtin(global_invocation_id) id: vec3<u32>) {
    let t = thread_index(id, contact.dispatch_width);
    if (t >= contact.triangle_count || atomicLoad(&contact_grid[tangle_at(TANGLE_WAIT)]) != 0u) {
        return;
    }
    let ct = triangle_cloth(t);
    let lo = bitcast<vec3<f32>>(contact_triangles[CONTACT_TRIANGLE_WORDS * t + 3u].xyz);
    let hi = bitcast<vec3<f32>>(contact_triangles[CONTACT_TRIANGLE_WORDS * t + 4u].xyz);
    let cells = cells_of_box(lo, hi, MAX_SPAN);
    if (!cells.valid) {
        return;
    }
    let a = corners_before(t);
    let span = cells.hi - cells.lo;
    for (var z = 0; z <= span.z; z++) {
        for (var y = 0; y <= span.y; y++) {
            for (var x = 0; x <= span.x; x++) {
                let at = cells.lo + vec3(x, y, z);
                let b = bucket_of(at);
                let end = min(atomicLoad(&contact_grid[cursor_at(b)]), contact.entry_capacity);
                let start = min(atomicLoad(&contact_grid[start_at(b)]), end);
                let last = min(end, start + MAX_CANDIDATES);
                for (var e = start; e < last; e++) {
                    let u = atomicLoad(&contact_grid[entry_at(e)]);
                    let cu = triangle_cloth(u);
                    if (u <= t || (cu != ct && !layers_meet(vec2(cloths[ct].memberships, cloths[ct].filters), vec2(cloths[cu].memberships, cloths[cu].filters)))) {
                        continue;
                    }
                    if (cu == ct && neighbours_at_rest(t, u, cloths[ct].contact_thickness)) {
                        continue;
                    }
                    let u_lo = bitcast<vec3<f32>>(contact_triangles[CONTACT_TRIANGLE_WORDS * u + 3u].xyz);
                    let u_hi = bitcast<vec3<f32>>(contact_triangles[CONTACT_TRIANGLE_WORDS * u + 4u].xyz);
                    if (!(all(lo <= u_hi) && all(hi >= u_lo))) {
                        continue;
                    }
                    // Once per pair: in the first cell both cover.
                    let other = cells_of_box(u_lo, u_hi, MAX_SPAN);
                    if (!other.valid || any(max(other.lo, cells.lo) != at) || !triangles_intersect(a, corners_before(u))) {
                        continue;
                    }
                    atomicAdd(&contact_grid[tangle_at(TANGLE_CROSSINGS)], 1u);
                    atomicAdd(&contact_grid[STAT_CROSSINGS], 1u);
                    if (cu == ct) {
                        atomicMin(&contact_grid[triangle_word(t, TANGLE_TRIANGLE_SELF)], u);
                        atomicMin(&contact_grid[triangle_word(u, TANGLE_TRIANGLE_SELF)], t);
                        atomicStore(&contact_grid[cloth_word(ct, TANGLE_CLOTH_SELF)], 1u);
                        continue;
                    }
                    atomicMax(&contact_grid[triangle_word(t, TANGLE_TRIANGLE_CUT)], cu + 1u);
                    atomicMax(&contact_grid[triangle_word(u, TANGLE_TRIANGLE_CUT)], ct + 1u);
                    atomicMax(&contact_grid[cloth_word(ct, TANGLE_CLOTH_PARTNER)], cu + 1u);
                    atomicMax(&contact_grid[cloth_word(cu, TANGLE_CLOTH_PARTNER)], ct + 1u);
                }
            }
        }
    }
}

// The root of triangle t's part, halving the path to it on the way. Parents only ever point to
// lesser triangles, so the walk ends within the triangles' count.
fn part_root(t: u32) -> u32 {
    var r = t;
    for (var k = 0u; k < contact.triangle_count; k++) {
        let p = parent(r);
        if (p == r) {
            break;
        }
        let g = parent(p);
        atomicMin(&contact_grid[triangle_word(r, TANGLE_TRIANGLE_PARENT)], g);
        r = g;
    }
    return r;
}

// Joins the parts of triangles a and b: the root of the greater hooked under the lesser.
fn join(a: u32, b: u32) {
    var x = part_root(a);
    var y = part_root(b);
    for (var k = 0u; k < contact.triangle_count && x != y; k++) {
        let hi = max(x, y);
        let lo = min(x, y);
        let hooked = atomicCompareExchangeWeak(&contact_grid[triangle_word(hi, TANGLE_TRIANGLE_PARENT)], hi, lo);
        if (hooked.exchanged) {
            return;
        }
        // Another thread hooked it first (or the exchange failed spuriously): from the roots
        // again.
        x = part_root(hi);
        y = part_root(lo);
    }
}

@compute @workgroup_size(8, 8, 1)
fn untangle_join(@builtin(global_invocation_id) id: vec3<u32>) {
    let t = thread_index(id, contact.dispatch_width);
    if (!analysed(t)) {
        return;
    }
    // A part's triangles are neither cut nor in a ring; a ring's are all in rings.
    let ring = in_ring(t);
    if (!ring && is_cut(t)) {
        return;
    }
    for (var k = 0u; k < 3u; k++) {
        let u = atomicLoad(&contact_grid[neighbour_word(t, k)]);
        if (u != NO_CLOTH && ((ring && in_ring(u)) || (!ring && !is_cut(u)))) {
            join(t, u);
        }
    }
}

@compute @workgroup_size(8, 8, 1)
fn untangle_size(@builtin(global_invocation_id) id: vec3<u32>) {
    let t = thread_index(id, contact.dispatch_width);
    if (!analysed(t) || is_cut(t)) {
        return;
    }
    let r = part_root(t);
    atomicMin(&contact_grid[triangle_word(t, TANGLE_TRIANGLE_PARENT)], r);
    atomicAdd(&contact_grid[triangle_word(r, TANGLE_TRIANGLE_SIZE)], 1u);
}

@compute @workgroup_size(8, 8, 1)
fn untangle_largest(@builtin(global_invocation_id) id: vec3<u32>) {
    let t = thread_index(id, contact.dispatch_width);
    if (!analysed(t) || is_cut(t) || parent(t) != t) {
        return;
    }
    let size = atomicLoad(&contact_grid[triangle_word(t, TANGLE_TRIANGLE_SIZE)]);
    atomicMax(&contact_grid[cloth_word(triangle_cloth(t), TANGLE_CLOTH_SIZE)], size);
}

@compute @workgroup_size(8, 8, 1)
fn untangle_first(@builtin(global_invocation_id) id: vec3<u32>) {
    let t = thread_index(id, contact.dispatch_width);
    if (!analysed(t) || is_cut(t) || parent(t) != t) {
        return;
    }
    let c = triangle_cloth(t);
    if (atomicLoad(&contact_grid[triangle_word(t, TANGLE_TRIANGLE_SIZE)]) == atomicLoad(&contact_grid[cloth_word(c, TANGLE_CLOTH_SIZE)])) {
        atomicMin(&contact_grid[cloth_word(c, TANGLE_CLOTH_ROOT)], t);
    }
}

// Whether triangle t lies in its cloth's largest part.
fn on_largest_part(t: u32) -> bool {
    return !is_cut(t) && parent(t) == atomicLoad(&contact_grid[cloth_word(triangle_cloth(t), TANGLE_CLOTH_ROOT)]);
}

@compute @workgroup_size(8, 8, 1)
fn untangle_corners(@builtin(global_invocation_id) id: vec3<u32>) {
    let t = thread_index(id, contact.dispatch_width);
    if (!analysed(t) || !on_largest_part(t)) {
        return;
    }
    let c = contact_triangles[CONTACT_TRIANGLE_WORDS * t];
    atomicStore(&contact_grid[particle_word(c.x, TANGLE_PARTICLE_ON_LARGEST)], 1u);
    atomicStore(&contact_grid[particle_word(c.y, TANGLE_PARTICLE_ON_LARGEST)], 1u);
    atomicStore(&contact_grid[particle_word(c.z, TANGLE_PARTICLE_ON_LARGEST)], 1u);
}

@compute @workgroup_size(8, 8, 1)
fn untangle_outside(@builtin(global_invocation_id) id: vec3<u32>) {
    let t = thread_index(id, contact.dispatch_width);
    // A cloth every triangle of which is cut has no largest part, and nothing on a wrong side.
    if (!analysed(t) || on_largest_part(t) || atomicLoad(&contact_grid[cloth_word(triangle_cloth(t), TANGLE_CLOTH_SIZE)]) == 0u) {
        return;
    }
    let c = contact_triangles[CONTACT_TRIANGLE_WORDS * t];
    if (crosses_itself(c.w) && !is_cut(t)) {
        // The least ring beside this part.
        for (var k = 0u; k < 3u; k++) {
            let u = atomicLoad(&contact_grid[neighbour_word(t, k)]);
            if (u != NO_CLOTH && in_ring(u)) {
                atomicMin(&contact_grid[triangle_word(parent(t), TANGLE_TRIANGLE_BESIDE)], part_root(u));
            }
        }
    }
    if (atomicLoad(&contact_grid[cloth_word(c.w, TANGLE_CLOTH_PARTNER)]) == 0u) {
        return;
    }
    for (var k = 0u; k < 3u; k++) {
        let p = c[k];
        if (atomicLoad(&contact_grid[particle_word(p, TANGLE_PARTICLE_ON_LARGEST)]) == 0u
            && atomicExchange(&contact_grid[particle_word(p, TANGLE_PARTICLE_COUNTED)], 1u) == 0u) {
            atomicAdd(&contact_grid[cloth_word(c.w, TANGLE_CLOTH_WRONG)], 1u);
        }
    }
}

@compute @workgroup_size(8, 8, 1)
fn untangle_enclose(@builtin(global_invocation_id) id: vec3<u32>) {
    let t = thread_index(id, contact.dispatch_width);
    if (!analysed(t)) {
        return;
    }
    // As on the CPU, a cloth every triangle of which is cut is left as it is.
    let cloth = triangle_cloth(t);
    if (!crosses_itself(cloth) || atomicLoad(&contact_grid[cloth_word(cloth, TANGLE_CLOTH_SIZE)]) == 0u) {
        return;
    }
    var ring = NO_CLOTH;
    if (in_ring(t)) {
        ring = part_root(t);
    } else if (!is_cut(t) && !on_largest_part(t)) {
        ring = tangle_word(parent(t), TANGLE_TRIANGLE_BESIDE);
    }
    if (ring == NO_CLOTH) {
        return;
    }
    let c = contact_triangles[CONTACT_TRIANGLE_WORDS * t];
    for (var k = 0u; k < 3u; k++) {
        if (atomicLoad(&contact_grid[particle_word(c[k], TANGLE_PARTICLE_ON_LARGEST)]) == 0u) {
            atomicMin(&contact_grid[particle_word(c[k], TANGLE_PARTICLE_RING)], ring);
        }
    }
}

@compute @workgroup_size(8, 8, 1)
fn untangle_rings(@builtin(global_invocation_id) id: vec3<u32>) {
    let p = thread_index(id, contact.dispatch_width);
    if (contact_cloth(p) == NO_CLOTH || crossings() == 0u) {
        return;
    }
    let ring = atomicLoad(&contact_grid[particle_word(p, TANGLE_PARTICLE_RING)]);
    if (ring != NO_CLOTH) {
        atomicAdd(&contact_grid[triangle_word(ring, TANGLE_TRIANGLE_RING_WRONG)], 1u);
    }
}

@compute @workgroup_size(8, 8, 1)
fn untangle_link(@builtin(global_invocation_id) id: vec3<u32>) {
    let t = thread_index(id, contact.dispatch_width);
    if (!analysed(t) || !in_ring(t)) {
        return;
    }
    let x = part_root(t);
    let y = part_root(tangle_word(t, TANGLE_TRIANGLE_SELF));
    if (x == y) {
        return;
    }
    let a = min(x, y);
    let b = max(x, y);
    let wa = tangle_word(a, TANGLE_TRIANGLE_RING_WRONG);
    let wb = tangle_word(b, TANGLE_TRIANGLE_RING_WRONG);
    if (wa == 0u && wb == 0u) {
        return;
    }
    var moved = b;
    var other = a;
    if (wb == 0u || (wa != 0u && wa <= wb)) {
        moved = a;
        other = b;
    }
    atomicMin(&contact_grid[triangle_word(moved, TANGLE_TRIANGLE_RING_MOVED)], other);
    atomicStore(&contact_grid[triangle_word(other, TANGLE_TRIANGLE_RING_SHEET)], 1u);
}

// The label of the sheet of the ring whose root is triangle r.
fn ring_label(r: u32) -> u32 {
    return contact.cloth_slots + r;
}

@compute @workgroup_size(8, 8, 1)
fn untangle_mark(@builtin(global_invocation_id) id: vec3<u32>) {
    let p = thread_index(id, contact.dispatch_width);
    if (p == 0u) {
        // bvh_cloth_core's UNTANGLE_EVERY: while nothing crosses, one search in so many
        // substeps.
        let wait = atomicLoad(&contact_grid[tangle_at(TANGLE_WAIT)]);
        if (wait != 0u) {
            atomicStore(&contact_grid[tangle_at(TANGLE_WAIT)], wait - 1u);
        } else if (crossings() == 0u) {
            atomicStore(&contact_grid[tangle_at(TANGLE_WAIT)], UNTANGLE_EVERY - 1u);
        }
    }
    let c = contact_cloth(p);
    if (c == NO_CLOTH || crossings() == 0u) {
        return;
    }
    let partner = atomicLoad(&contact_grid[cloth_word(c, TANGLE_CLOTH_PARTNER)]);
    if (partner != 0u && atomicLoad(&contact_grid[particle_word(p, TANGLE_PARTICLE_COUNTED)]) != 0u) {
        let other = partner - 1u;
        let mine = atomicLoad(&contact_grid[cloth_word(c, TANGLE_CLOTH_WRONG)]);
        let theirs = atomicLoad(&contact_grid[cloth_word(other, TANGLE_CLOTH_WRONG)]);
        if (theirs == 0u || mine < theirs || (mine == theirs && c < other)) {
            atomicStore(&contact_grid[particle_word(p, TANGLE_PARTICLE_WRONG)], other);
        }
    }
    // Within the cloth: taken back through the sheet of the ring its own is linked to, or, if
    // enclosed by a ring another goes back through, of that ring's sheet.
    let ring = atomicLoad(&contact_grid[particle_word(p, TANGLE_PARTICLE_RING)]);
    if (ring == NO_CLOTH) {
        return;
    }
    let through = tangle_word(ring, TANGLE_TRIANGLE_RING_MOVED);
    if (through != NO_CLOTH) {
        if (wrong_side(p) == NO_CLOTH) {
            atomicStore(&contact_grid[particle_word(p, TANGLE_PARTICLE_WRONG)], ring_label(through));
        }
    } else if (tangle_word(ring, TANGLE_TRIANGLE_RING_SHEET) != 0u) {
        atomicStore(&contact_grid[particle_word(p, TANGLE_PARTICLE_SHEET)], ring_label(ring));
    }
}

@compute @workgroup_size(8, 8, 1)
fn untangle_sheets(@builtin(global_invocation_id) id: vec3<u32>) {
    let t = thread_index(id, contact.dispatch_width);
    if (!analysed(t) || !in_ring(t)) {
        return;
    }
    let ring = part_root(t);
    if (tangle_word(ring, TANGLE_TRIANGLE_RING_SHEET) == 0u) {
        return;
    }
    let c = contact_triangles[CONTACT_TRIANGLE_WORDS * t];
    for (var k = 0u; k < 3u; k++) {
        if (wrong_side(c[k]) == NO_CLOTH) {
            atomicStore(&contact_grid[particle_word(c[k], TANGLE_PARTICLE_SHEET)], ring_label(ring));
        }
    }
}
