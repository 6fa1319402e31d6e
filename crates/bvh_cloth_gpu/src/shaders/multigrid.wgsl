// The multigrid correction of block descent's sweep (bvh_cloth_core::solver::multigrid), per
// substep for every cloth of the batch that has it, after the sweeps and before vbd_finish:
// - mg_begin, one thread per cloth: the substep's step (BDF2's, the blend's or implicit
//   Euler's), and whether it assembles and factors the levels;
// - mg_springs, one thread per crossing spring: its force, direction and clamped stretch, and
//   at an assembly its Hessian;
// - mg_residual, one thread per level-1 node: the residual P^T r, its free mass, and at an
//   assembly its row of level 1;
// - mg_galerkin, one dispatch per coarser level, one thread per node: at an assembly, its row of
//   P^T A P gathered from its children;
// - mg_factor over every node (the diagonal blocks' inverses) and mg_dense_factor, one
//   workgroup per cloth (the coarsest level's Cholesky factor), when the step or the levels
//   changed;
// - the V-cycle: per level down, mg_smooth_down (a damped Jacobi step from zero) and
//   mg_restrict (each coarse node gathers its children's residuals); mg_coarsest, one
//   workgroup per cloth (the dense solve, or smoothing when the level has no factor); per level
//   up, mg_smooth_up (the prolongation and a damped Jacobi step in one); where a cloth runs the
//   first level's W-cycle, mg_keep, then level 1's second visit (mg_restrict, the V-cycle below,
//   mg_smooth_up);
// - mg_line_chunks, one workgroup per chunk of 64 of a cloth's level-1 nodes, and
//   mg_line_search, one workgroup per cloth: the step along P e on the substep's quadratic
//   model, summed in two levels, and whether the kept levels have gone stale;
// - mg_apply, one thread per particle slot: d += alpha e of its aggregate.
// Every thread sums what it gathers in the order the CPU reference does; the f32 sums of the
// line search and the dense factor (f64 on the CPU) are the only differences.

#import bvh_cloth::types::{GpuParticle, frame, step, thread_index, all_finite}
#import bvh_cloth::springs::{particle_info, cloths}
#import bvh_cloth::constants::{NO_CLOTH, INTEGRATOR_MULTIGRID, NO_NODE, REASSEMBLE_EVERY, STALE_CURVATURE, JACOBI_WEIGHT, BLEND_STEP, COARSEST_SMOOTHING, DENSE_ORDER, MULTIGRID_NODE_WORDS, MULTIGRID_NODE_VALUES, MULTIGRID_SPRING_VALUES}
#import bvh_cloth::block_descent::{iterate, substep_start, inertial, drift_sums, sum_lanes}

struct MultigridCloth {
    levels: u32,
    node_start: u32,
    node_count: u32,
    coarsest_start: u32,
    coarsest_count: u32,
    crossing_start: u32,
    crossing_count: u32,
    aggregate_start: u32,
    dense_start: u32,
    dense_order: u32,
    running: u32,
    stiff: u32,
    blend: u32,
    age: u32,
    assemble: u32,
    refactor: u32,
    dense_ok: u32,
    damp: f32,
    h2: f32,
    factored_damp: f32,
    factored_h2: f32,
    alpha: f32,
    chunk_start: u32,
    chunk_count: u32,
}

struct MultigridPass {
    start: u32,
    count: u32,
    width: u32,
    level: u32,
    block_words: u32,
    share_words: u32,
    spring_words: u32,
    chunk_words: u32,
    node_values: u32,
    block_values: u32,
    spring_values: u32,
    chunk_values: u32,
}

@group(0) @binding(49) var<storage, read> mg_index: array<u32>;
@group(0) @binding(50) var<storage, read_write> mg_values: array<vec4<f32>>;
@group(0) @binding(51) var<storage, read_write> mg_cloths: array<MultigridCloth>;
@group(0) @binding(52) var<uniform> mg_pass: MultigridPass;

// The node (or spring) this thread of a pass takes, or NO_NODE past the pass's count.
fn pass_item(id: vec3<u32>) -> u32 {
    let t = thread_index(id, mg_pass.width);
    if (t >= mg_pass.count) {
        return NO_NODE;
    }
    return mg_pass.start + t;
}

// A node's words (bvh_cloth_gpu::layout::MULTIGRID_NODE_WORDS).
struct NodeInfo {
    row_start: u32,
    row_end: u32,
    child_start: u32,
    child_end: u32,
    parent: u32,
    cloth: u32,
    share_start: u32,
    share_end: u32,
    inner_start: u32,
    inner_end: u32,
    level: u32,
}

fn node_info(a: u32) -> NodeInfo {
    let w = a * MULTIGRID_NODE_WORDS;
    return NodeInfo(
        mg_index[w], mg_index[w + 1u], mg_index[w + 2u], mg_index[w + 3u], mg_index[w + 4u], mg_index[w + 5u],
        mg_index[w + 6u], mg_index[w + 7u], mg_index[w + 8u], mg_index[w + 9u], mg_index[w + 10u],
    );
}

// The value entries of node a.
const V_MASS: u32 = 0u;
const V_K_DIAG: u32 = 1u;
const V_INV: u32 = 3u;
const V_B: u32 = 5u;
const V_DOWN: u32 = 6u;
const V_UP: u32 = 7u;

fn node_value(a: u32, entry: u32) -> u32 {
    return mg_pass.node_values + a * MULTIGRID_NODE_VALUES + entry;
}

fn block_value(k: u32) -> u32 {
    return mg_pass.block_values + 2u * k;
}

fn spring_value(s: u32) -> u32 {
    return mg_pass.spring_values + s * MULTIGRID_SPRING_VALUES;
}

// Block k's column and where it adds on the next level.
fn block_col(k: u32) -> u32 {
    return mg_index[mg_pass.block_words + 2u * k];
}

fn block_slot(k: u32) -> u32 {
    return mg_index[mg_pass.block_words + 2u * k + 1u];
}

// A spring: its two particle slots, k / M and its rest length.
struct Spring {
    i: u32,
    j: u32,
    stiffness: f32,
    rest: f32,
}

fn spring(s: u32) -> Spring {
    let w = mg_pass.spring_words + 4u * s;
    return Spring(mg_index[w], mg_index[w + 1u], bitcast<f32>(mg_index[w + 2u]), bitcast<f32>(mg_index[w + 3u]));
}

// A symmetric 3x3 matrix as two vec4: the diagonal, then xy, xz, yz.
fn sym_mul(d: vec4<f32>, o: vec4<f32>, v: vec3<f32>) -> vec3<f32> {
    return vec3(
        d.x * v.x + o.x * v.y + o.y * v.z,
        o.x * v.x + d.y * v.y + o.z * v.z,
        o.y * v.x + o.z * v.y + d.z * v.z,
    );
}

fn load_mul(entry: u32, v: vec3<f32>) -> vec3<f32> {
    return sym_mul(mg_values[entry], mg_values[entry + 1u], v);
}

// Whether particle i is held in this substep: a collider touched it in the last one.
fn held(i: u32) -> bool {
    return substep_start[i].velocity.w != 0.0;
}

// The vector between spring s's ends at the sweep's displacements.
fn spring_delta(s: Spring) -> vec3<f32> {
    return (substep_start[s.j].position.xyz - substep_start[s.i].position.xyz)
        + (iterate[s.j].position.xyz - iterate[s.i].position.xyz);
}

// bvh_cloth_core::solver::multigrid::spring_axis: the unit direction and clamped stretch.
fn spring_axis(rest: f32, delta: vec3<f32>) -> vec4<f32> {
    let inv_l = 1.0 / max(sqrt(dot(delta, delta)), 1.0e-6 * rest);
    return vec4(delta * inv_l, max(1.0 - rest * inv_l, 0.0));
}

// The force on a spring's first end, in the sweep's units.
fn spring_force(s: Spring, h2: f32) -> vec3<f32> {
    let delta = spring_delta(s);
    let stretch = 1.0 - s.rest / max(sqrt(dot(delta, delta)), 1.0e-6 * s.rest);
    return (s.stiffness * h2 * stretch) * delta;
}

// bvh_cloth_core::solver::multigrid::spring_hessian, as its diagonal and off-diagonal entries.
fn spring_hessian(k: f32, rest: f32, delta: vec3<f32>) -> array<vec4<f32>, 2> {
    let inv_l = 1.0 / max(sqrt(dot(delta, delta)), 1.0e-6 * rest);
    let s = max(1.0 - rest * inv_l, 0.0);
    let u = delta * inv_l;
    let t = k * (1.0 - s);
    return array(vec4(k * s + t * u * u, 0.0), vec4(t * (u.xxy * u.yzz), 0.0));
}

// Whether cloth c is corrected in this substep (mg_begin decides).
fn corrected(c: u32) -> bool {
    return c != NO_CLOTH && c < arrayLength(&mg_cloths) && mg_cloths[c].running != 0u;
}

// Before the substep's prediction, one thread per cloth: whether the cloth runs this substep,
// its step (when its last substep allows, BDF2's 2h/3, or the blend's (1 - theta/3) h where its
// springs are stiff; else implicit Euler's h), and whether the levels are assembled and
// factored in it.
@compute @workgroup_size(8, 8, 1)
fn mg_begin(@builtin(global_invocation_id) id: vec3<u32>) {
    let c = thread_index(id, mg_pass.width);
    if (c >= mg_pass.count || c >= arrayLength(&mg_cloths) || mg_cloths[c].levels == 0u) {
        return;
    }
    let runs = step.substep < cloths[c].substeps && cloths[c].integrator == INTEGRATOR_MULTIGRID;
    mg_cloths[c].running = select(0u, 1u, runs);
    if (!runs) {
        return;
    }
    let broken = atomicExchange(&cloths[c].broken, 0u);
    var length = cloths[c].h;
    var blend = 0u;
    if (broken == 0u && mg_cloths[c].stiff == 0u) {
        if (mg_cloths[c].blend != 0u) {
            length = cloths[c].h * BLEND_STEP;
            blend = 1u;
        } else {
            length = cloths[c].h * (2.0 / 3.0);
        }
    }
    cloths[c].step = length;
    cloths[c].blend = blend;
    let damp = 1.0 + cloths[c].damping * length;
    let h2 = length * length;
    var assemble = 0u;
    if (mg_cloths[c].age >= REASSEMBLE_EVERY || mg_cloths[c].stiff != 0u) {
        assemble = 1u;
        mg_cloths[c].age = 0u;
    }
    mg_cloths[c].age += 1u;
    var refactor = assemble;
    if (mg_cloths[c].factored_damp != damp || mg_cloths[c].factored_h2 != h2) {
        refactor = 1u;
    }
    mg_cloths[c].assemble = assemble;
    mg_cloths[c].refactor = refactor;
    mg_cloths[c].damp = damp;
    mg_cloths[c].h2 = h2;
    mg_cloths[c].factored_damp = damp;
    mg_cloths[c].factored_h2 = h2;
}

@compute @workgroup_size(8, 8, 1)
fn mg_springs(@builtin(global_invocation_id) id: vec3<u32>) {
    let index = pass_item(id);
    if (index == NO_NODE) {
        return;
    }
    let s = spring(index);
    let c = particle_info[s.i].w;
    let h2 = mg_cloths[c].h2;
    let delta = spring_delta(s);
    let len = sqrt(dot(delta, delta));
    let inv_l = 1.0 / max(len, 1.0e-6 * s.rest);
    let stretch = 1.0 - s.rest * inv_l;
    let out = spring_value(index);
    mg_values[out] = vec4((s.stiffness * h2 * stretch) * delta, 0.0);
    mg_values[out + 1u] = vec4(delta * inv_l, max(stretch, 0.0));
    if (mg_cloths[c].assemble != 0u) {
        let hessian = spring_hessian(s.stiffness, s.rest, delta);
        mg_values[out + 2u] = hessian[0];
        mg_values[out + 3u] = hessian[1];
    }
}

// The other end of a crossing spring's share, and its own.
fn share_ends(s: Spring, side: u32) -> vec2<u32> {
    if (side == 0u) {
        return vec2(s.i, s.j);
    }
    return vec2(s.j, s.i);
}

@compute @workgroup_size(8, 8, 1)
fn mg_residual(@builtin(global_invocation_id) id: vec3<u32>) {
    let a = pass_item(id);
    if (a == NO_NODE) {
        return;
    }
    let node = node_info(a);
    let c = node.cloth;
    let damp = mg_cloths[c].damp;
    let h2 = mg_cloths[c].h2;
    let assemble = mg_cloths[c].assemble != 0u;
    var mass = 0.0;
    var sum = vec3(0.0);
    var any_held = false;
    for (var m = node.child_start; m < node.child_end; m++) {
        let i = mg_index[m];
        if (held(i)) {
            any_held = true;
        } else {
            let share = 1.0 / bitcast<f32>(particle_info[i].z);
            sum += share * (inertial[i].position.xyz - damp * iterate[i].position.xyz);
            mass += share;
        }
    }
    var diag = array(vec4(0.0), vec4(0.0));
    if (assemble) {
        for (var k = node.row_start; k < node.row_end; k++) {
            mg_values[block_value(k)] = vec4(0.0);
            mg_values[block_value(k) + 1u] = vec4(0.0);
        }
    }
    for (var k = node.share_start; k < node.share_end; k++) {
        let w = mg_pass.share_words + 4u * k;
        let index = mg_index[w];
        let side = mg_index[w + 1u];
        let slot = mg_index[w + 2u];
        let ends = share_ends(spring(index), side);
        if (held(ends.x)) {
            continue;
        }
        let f = mg_values[spring_value(index)].xyz;
        if (side == 0u) {
            sum += f;
        } else {
            sum -= f;
        }
        if (assemble) {
            let hd = mg_values[spring_value(index) + 2u];
            let ho = mg_values[spring_value(index) + 3u];
            diag[0] += hd;
            diag[1] += ho;
            if (slot != NO_NODE && !held(ends.y)) {
                mg_values[block_value(slot)] -= hd;
                mg_values[block_value(slot) + 1u] -= ho;
            }
        }
    }
    if (any_held) {
        for (var k = node.inner_start; k < node.inner_end; k++) {
            let s = spring(k);
            let hi = held(s.i);
            let hj = held(s.j);
            if (hi != hj) {
                let f = spring_force(s, h2);
                if (hj) {
                    sum += f;
                } else {
                    sum -= f;
                }
                if (assemble) {
                    let hessian = spring_hessian(s.stiffness, s.rest, spring_delta(s));
                    diag[0] += hessian[0];
                    diag[1] += hessian[1];
                }
            }
        }
    }
    let old = mg_values[node_value(a, V_MASS)];
    var assembled = old.x;
    if (assemble) {
        assembled = mass;
        mg_values[node_value(a, V_K_DIAG)] = diag[0];
        mg_values[node_value(a, V_K_DIAG) + 1u] = diag[1];
    }
    mg_values[node_value(a, V_MASS)] = vec4(assembled, mass, select(0.0, 1.0, any_held), 0.0);
    mg_values[node_value(a, V_B)] = vec4(sum, 0.0);
}

@compute @workgroup_size(8, 8, 1)
fn mg_galerkin(@builtin(global_invocation_id) id: vec3<u32>) {
    let a = pass_item(id);
    if (a == NO_NODE) {
        return;
    }
    let node = node_info(a);
    if (mg_cloths[node.cloth].assemble == 0u) {
        return;
    }
    for (var k = node.row_start; k < node.row_end; k++) {
        mg_values[block_value(k)] = vec4(0.0);
        mg_values[block_value(k) + 1u] = vec4(0.0);
    }
    var mass = 0.0;
    var d = vec4(0.0);
    var o = vec4(0.0);
    for (var m = node.child_start; m < node.child_end; m++) {
        let child = node_info(mg_index[m]);
        let b = mg_index[m];
        mass += mg_values[node_value(b, V_MASS)].x;
        d += mg_values[node_value(b, V_K_DIAG)];
        o += mg_values[node_value(b, V_K_DIAG) + 1u];
        for (var k = child.row_start; k < child.row_end; k++) {
            let slot = block_slot(k);
            if (slot == NO_NODE) {
                d += mg_values[block_value(k)];
                o += mg_values[block_value(k) + 1u];
            } else {
                mg_values[block_value(slot)] += mg_values[block_value(k)];
                mg_values[block_value(slot) + 1u] += mg_values[block_value(k) + 1u];
            }
        }
    }
    mg_values[node_value(a, V_MASS)] = vec4(mass, 0.0, 0.0, 0.0);
    mg_values[node_value(a, V_K_DIAG)] = d;
    mg_values[node_value(a, V_K_DIAG) + 1u] = o;
}

// Node a's diagonal block, (1 + c h) m I + h^2 K_aa, as a symmetric pair.
fn diagonal_block(a: u32, damp: f32, h2: f32) -> array<vec4<f32>, 2> {
    let mass = mg_values[node_value(a, V_MASS)].x;
    let d = mg_values[node_value(a, V_K_DIAG)];
    let o = mg_values[node_value(a, V_K_DIAG) + 1u];
    return array(vec4(vec3(damp * mass) + h2 * d.xyz, 0.0), vec4(h2 * o.xyz, 0.0));
}

@compute @workgroup_size(8, 8, 1)
fn mg_factor(@builtin(global_invocation_id) id: vec3<u32>) {
    let a = pass_item(id);
    if (a == NO_NODE) {
        return;
    }
    let c = node_info(a).cloth;
    if (mg_cloths[c].refactor == 0u) {
        return;
    }
    let block = diagonal_block(a, mg_cloths[c].damp, mg_cloths[c].h2);
    let d = block[0];
    let o = block[1];
    // The cofactors of the symmetric block.
    let ca = d.y * d.z - o.z * o.z;
    let cb = o.y * o.z - o.x * d.z;
    let cc = o.x * o.z - o.y * d.y;
    let cd = d.x * d.z - o.y * o.y;
    let ce = o.x * o.y - d.x * o.z;
    let cf = d.x * d.y - o.x * o.x;
    let inv_det = 1.0 / (d.x * ca + o.x * cb + o.y * cc);
    mg_values[node_value(a, V_INV)] = vec4(ca, cd, cf, 0.0) * inv_det;
    mg_values[node_value(a, V_INV) + 1u] = vec4(cb, cc, ce, 0.0) * inv_det;
}

// The dense factor's entry (r, col) of cloth c, as an index into a vec4's lanes.
fn dense_at(c: u32, r: u32, col: u32) -> vec2<u32> {
    let flat = r * mg_cloths[c].dense_order + col;
    return vec2(mg_cloths[c].dense_start + flat / 4u, flat % 4u);
}

fn dense_get(c: u32, r: u32, col: u32) -> f32 {
    let at = dense_at(c, r, col);
    return mg_values[at.x][at.y];
}

fn dense_set(c: u32, r: u32, col: u32, value: f32) {
    let at = dense_at(c, r, col);
    mg_values[at.x][at.y] = value;
}

// What a cloth's workgroup shares: its order (0 when it has nothing to do), and a failure.
var<workgroup> wg_order: u32;
var<workgroup> wg_failed: u32;
var<workgroup> wg_vector: array<f32, DENSE_ORDER>;

// Entry (r, col), both 0 to 2, of the symmetric block `m` (its diagonal, then xy, xz, yz).
fn block_entry(m: array<vec4<f32>, 2>, r: u32, col: u32) -> f32 {
    if (r == col) {
        return m[0][r];
    }
    let pair = r + col; // xy 1, xz 2, yz 3
    return m[1][pair - 1u];
}

// The coarsest level's Cholesky factor, lower triangle in place, one workgroup per cloth
// (bvh_cloth_core::solver::multigrid's Dense::factor, in f32).
@compute @workgroup_size(64, 1, 1)
fn mg_dense_factor(@builtin(workgroup_id) group: vec3<u32>, @builtin(local_invocation_index) lane: u32) {
    let c = group.x;
    if (lane == 0u) {
        var order = 0u;
        if (corrected(c) && mg_cloths[c].refactor != 0u) {
            order = mg_cloths[c].dense_order;
        }
        wg_order = order;
        wg_failed = 0u;
    }
    let order = workgroupUniformLoad(&wg_order);
    if (order == 0u) {
        return;
    }
    let damp = mg_cloths[c].damp;
    let h2 = mg_cloths[c].h2;
    let first = mg_cloths[c].coarsest_start;
    // The matrix: every entry of the lower triangle and the diagonal, zero where no block.
    for (var e = lane; e < order * order; e += 64u) {
        dense_set(c, e / order, e % order, 0.0);
    }
    storageBarrier();
    for (var n = lane; n < order / 3u; n += 64u) {
        let a = first + n;
        let block = diagonal_block(a, damp, h2);
        for (var r = 0u; r < 3u; r++) {
            for (var col = 0u; col < 3u; col++) {
                dense_set(c, 3u * n + r, 3u * n + col, block_entry(block, r, col));
            }
        }
        let node = node_info(a);
        for (var k = node.row_start; k < node.row_end; k++) {
            let other = block_col(k) - first;
            let off = array(mg_values[block_value(k)] * h2, mg_values[block_value(k) + 1u] * h2);
            for (var r = 0u; r < 3u; r++) {
                for (var col = 0u; col < 3u; col++) {
                    dense_set(c, 3u * n + r, 3u * other + col, block_entry(off, r, col));
                }
            }
        }
    }
    storageBarrier();
    workgroupBarrier();
    // Right-looking: column j's diagonal, then its entries below, then the trailing update.
    for (var j = 0u; j < order; j++) {
        if (lane == 0u) {
            let diag = dense_get(c, j, j);
            if (!(diag > 0.0) || !all_finite(vec3(diag))) {
                wg_failed = 1u;
            }
            dense_set(c, j, j, sqrt(max(diag, 0.0)));
        }
        storageBarrier();
        workgroupBarrier();
        let diag = dense_get(c, j, j);
        for (var i = j + 1u + lane; i < order; i += 64u) {
            dense_set(c, i, j, dense_get(c, i, j) / diag);
        }
        storageBarrier();
        workgroupBarrier();
        let rest = order - j - 1u;
        for (var e = lane; e < rest * rest; e += 64u) {
            let i = j + 1u + e / rest;
            let k = j + 1u + e % rest;
            if (k <= i) {
                dense_set(c, i, k, dense_get(c, i, k) - dense_get(c, i, j) * dense_get(c, k, j));
            }
        }
        storageBarrier();
        workgroupBarrier();
    }
    if (lane == 0u) {
        mg_cloths[c].dense_ok = 1u - wg_failed;
    }
}

// Whether node a, on the level of this dispatch, is its cloth's coarsest.
fn coarsest(node: NodeInfo) -> bool {
    return node.level + 1u >= mg_cloths[node.cloth].levels;
}

@compute @workgroup_size(8, 8, 1)
fn mg_smooth_down(@builtin(global_invocation_id) id: vec3<u32>) {
    let a = pass_item(id);
    if (a == NO_NODE) {
        return;
    }
    if (coarsest(node_info(a))) {
        return;
    }
    let b = mg_values[node_value(a, V_B)].xyz;
    mg_values[node_value(a, V_DOWN)] = vec4(JACOBI_WEIGHT * load_mul(node_value(a, V_INV), b), 0.0);
}

// A e at node a, less the diagonal block, for the solution at `entry` (plus, when `up`, each
// neighbour's aggregate's solution on the way up).
fn off_product(node: NodeInfo, h2: f32, entry: u32, up: bool) -> vec3<f32> {
    var sum = vec3(0.0);
    for (var k = node.row_start; k < node.row_end; k++) {
        let col = block_col(k);
        var e = mg_values[node_value(col, entry)].xyz;
        if (up) {
            e += mg_values[node_value(mg_index[col * MULTIGRID_NODE_WORDS + 4u], V_UP)].xyz;
        }
        sum += load_mul(block_value(k), e);
    }
    return h2 * sum;
}

@compute @workgroup_size(8, 8, 1)
fn mg_restrict(@builtin(global_invocation_id) id: vec3<u32>) {
    let a = pass_item(id);
    if (a == NO_NODE) {
        return;
    }
    let node = node_info(a);
    let c = node.cloth;
    let damp = mg_cloths[c].damp;
    let h2 = mg_cloths[c].h2;
    var sum = vec3(0.0);
    for (var m = node.child_start; m < node.child_end; m++) {
        let b = mg_index[m];
        let child = node_info(b);
        let e = mg_values[node_value(b, V_DOWN)].xyz;
        let block = diagonal_block(b, damp, h2);
        sum += mg_values[node_value(b, V_B)].xyz - sym_mul(block[0], block[1], e) - off_product(child, h2, V_DOWN, false);
    }
    mg_values[node_value(a, V_B)] = vec4(sum, 0.0);
}

// The coarsest level's solution, one workgroup per cloth: the dense factor's two triangular
// solves, or (without a factor) damped Jacobi steps from zero.
@compute @workgroup_size(64, 1, 1)
fn mg_coarsest(@builtin(workgroup_id) group: vec3<u32>, @builtin(local_invocation_index) lane: u32) {
    let c = group.x;
    if (lane == 0u) {
        var order = 0u;
        var failed = 1u;
        if (corrected(c)) {
            order = 3u * mg_cloths[c].coarsest_count;
            if (mg_cloths[c].dense_order > 0u && mg_cloths[c].dense_ok != 0u) {
                failed = 0u;
            }
        }
        wg_order = order;
        wg_failed = failed;
    }
    let order = workgroupUniformLoad(&wg_order);
    let smoothing = workgroupUniformLoad(&wg_failed) != 0u;
    if (order == 0u) {
        return;
    }
    let first = mg_cloths[c].coarsest_start;
    let damp = mg_cloths[c].damp;
    let h2 = mg_cloths[c].h2;
    if (smoothing) {
        for (var n = lane; n < order / 3u; n += 64u) {
            mg_values[node_value(first + n, V_UP)] = vec4(0.0);
        }
        storageBarrier();
        for (var step = 0u; step < COARSEST_SMOOTHING; step++) {
            // Even steps read V_UP and write V_DOWN; odd ones the other way, ending in V_UP.
            var read_at = V_UP;
            var write_at = V_DOWN;
            if (step % 2u == 1u) {
                read_at = V_DOWN;
                write_at = V_UP;
            }
            for (var n = lane; n < order / 3u; n += 64u) {
                let a = first + n;
                let e = mg_values[node_value(a, read_at)].xyz;
                let rhs = mg_values[node_value(a, V_B)].xyz - off_product(node_info(a), h2, read_at, false);
                let next = (1.0 - JACOBI_WEIGHT) * e + JACOBI_WEIGHT * load_mul(node_value(a, V_INV), rhs);
                mg_values[node_value(a, write_at)] = vec4(next, 0.0);
            }
            storageBarrier();
            workgroupBarrier();
        }
        return;
    }
    for (var r = lane; r < order; r += 64u) {
        wg_vector[r] = mg_values[node_value(first + r / 3u, V_B)][r % 3u];
    }
    workgroupBarrier();
    // L y = b, column by column.
    for (var i = 0u; i < order; i++) {
        if (lane == 0u) {
            wg_vector[i] = wg_vector[i] / dense_get(c, i, i);
        }
        workgroupBarrier();
        let yi = wg_vector[i];
        for (var r = i + 1u + lane; r < order; r += 64u) {
            wg_vector[r] -= dense_get(c, r, i) * yi;
        }
        workgroupBarrier();
    }
    // L^T e = y, from the last row up.
    for (var step = 0u; step < order; step++) {
        let i = order - 1u - step;
        if (lane == 0u) {
            wg_vector[i] = wg_vector[i] / dense_get(c, i, i);
        }
        workgroupBarrier();
        let yi = wg_vector[i];
        for (var r = lane; r < i; r += 64u) {
            wg_vector[r] -= dense_get(c, i, r) * yi;
        }
        workgroupBarrier();
    }
    for (var n = lane; n < order / 3u; n += 64u) {
        let e = vec3(wg_vector[3u * n], wg_vector[3u * n + 1u], wg_vector[3u * n + 2u]);
        mg_values[node_value(first + n, V_UP)] = vec4(e, 0.0);
    }
}

@compute @workgroup_size(8, 8, 1)
fn mg_smooth_up(@builtin(global_invocation_id) id: vec3<u32>) {
    let a = pass_item(id);
    if (a == NO_NODE) {
        return;
    }
    let node = node_info(a);
    if (coarsest(node)) {
        return;
    }
    let c = node.cloth;
    let e = mg_values[node_value(a, V_DOWN)].xyz + mg_values[node_value(node.parent, V_UP)].xyz;
    let rhs = mg_values[node_value(a, V_B)].xyz - off_product(node, mg_cloths[c].h2, V_DOWN, true);
    let next = (1.0 - JACOBI_WEIGHT) * e + JACOBI_WEIGHT * load_mul(node_value(a, V_INV), rhs);
    mg_values[node_value(a, V_UP)] = vec4(next, 0.0);
}

// The second visit from the first level (bvh_cloth_core's Cycle::TopW): node a's answer on the
// way up becomes the start that mg_restrict takes the residual of and mg_smooth_up adds the next
// level's answer to. A cloth that runs V-cycles keeps its first answer, so that the second
// visit's passes compute it again, unchanged.
@compute @workgroup_size(8, 8, 1)
fn mg_keep(@builtin(global_invocation_id) id: vec3<u32>) {
    let a = pass_item(id);
    if (a == NO_NODE) {
        return;
    }
    let node = node_info(a);
    if (coarsest(node) || mg_cloths[node.cloth].blend == 0u) {
        return;
    }
    mg_values[node_value(a, V_DOWN)] = mg_values[node_value(a, V_UP)];
}

// The correction of particle i on level 1 (zero at a pinned or held particle).
fn moved(c: u32, i: u32) -> vec3<f32> {
    let a = mg_index[mg_cloths[c].aggregate_start + (i - cloths[c].particle_start)];
    if (a == NO_NODE || held(i)) {
        return vec3(0.0);
    }
    return mg_values[node_value(a, V_UP)].xyz;
}

// A spring's curvature term along the correction, from its direction and clamped stretch.
fn spring_term(c: u32, s: Spring, axis: vec4<f32>, h2: f32) -> f32 {
    let de = moved(c, s.j) - moved(c, s.i);
    let along = dot(axis.xyz, de);
    return s.stiffness * h2 * (axis.w * dot(de, de) + (1.0 - axis.w) * along * along);
}

// Node a's terms of the line search: x r.e; y the substep's curvature (its free mass, its inner
// springs where a collider holds one end, and the crossing springs whose first end lies in it);
// z the kept levels' curvature.
fn line_terms(a: u32) -> vec4<f32> {
    let node = node_info(a);
    let c = node.cloth;
    let damp = mg_cloths[c].damp;
    let h2 = mg_cloths[c].h2;
    let e = mg_values[node_value(a, V_UP)].xyz;
    let masses = mg_values[node_value(a, V_MASS)];
    let block = diagonal_block(a, damp, h2);
    var terms = vec4(
        dot(mg_values[node_value(a, V_B)].xyz, e),
        damp * masses.y * dot(e, e),
        dot(sym_mul(block[0], block[1], e) + off_product(node, h2, V_UP, false), e),
        0.0,
    );
    if (masses.z != 0.0) {
        for (var k = node.inner_start; k < node.inner_end; k++) {
            let s = spring(k);
            terms.y += spring_term(c, s, spring_axis(s.rest, spring_delta(s)), h2);
        }
    }
    for (var k = node.share_start; k < node.share_end; k++) {
        let w = mg_pass.share_words + 4u * k;
        if (mg_index[w + 1u] == 0u) {
            let index = mg_index[w];
            terms.y += spring_term(c, spring(index), mg_values[spring_value(index) + 1u], h2);
        }
    }
    return terms;
}

// The line search's first level, one workgroup per chunk (up to 64 of one cloth's level-1
// nodes, from the chunk table): the chunk's sums of line_terms.
@compute @workgroup_size(64, 1, 1)
fn mg_line_chunks(
    @builtin(workgroup_id) group: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) lane: u32,
) {
    let chunk = group.y * groups.x + group.x;
    var terms = vec4(0.0);
    if (chunk < mg_pass.count) {
        let first = mg_index[mg_pass.chunk_words + 2u * chunk];
        let count = mg_index[mg_pass.chunk_words + 2u * chunk + 1u];
        if (lane < count && corrected(node_info(first).cloth)) {
            terms = line_terms(first + lane);
        }
    }
    drift_sums[lane] = terms;
    let total = sum_lanes(lane);
    if (lane == 0u && chunk < mg_pass.count) {
        mg_values[mg_pass.chunk_values + chunk] = total;
    }
}

// The line search's second level, one workgroup per cloth: alpha = r.e / (Pe)^T H (Pe), with H
// at this substep's displacements, clamped to [0, 1] (0 when the sums are not finite); and the
// kept levels' curvature along e against the substep's, which marks them stale.
@compute @workgroup_size(64, 1, 1)
fn mg_line_search(@builtin(workgroup_id) group: vec3<u32>, @builtin(local_invocation_index) lane: u32) {
    let c = group.x;
    if (lane == 0u) {
        var count = 0u;
        if (corrected(c)) {
            count = 1u;
        }
        wg_order = count;
    }
    if (workgroupUniformLoad(&wg_order) == 0u) {
        return;
    }
    var sums = vec4(0.0);
    let first = mg_cloths[c].chunk_start;
    for (var k = lane; k < mg_cloths[c].chunk_count; k += 64u) {
        sums += mg_values[mg_pass.chunk_values + first + k];
    }
    drift_sums[lane] = sums;
    let total = sum_lanes(lane);
    if (lane == 0u) {
        let along = total.x;
        let curvature = total.y;
        let kept = total.z;
        if (abs(kept / curvature - 1.0) > STALE_CURVATURE) {
            mg_cloths[c].age = REASSEMBLE_EVERY;
        }
        var alpha = clamp(along / curvature, 0.0, 1.0);
        if (!(curvature > 0.0 && all_finite(vec3(along, curvature, alpha)) && alpha > 0.0)) {
            alpha = 0.0;
        }
        mg_cloths[c].alpha = alpha;
    }
}

@compute @workgroup_size(8, 8, 1)
fn mg_apply(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = thread_index(id, frame.dispatch_width);
    if (i >= frame.particle_slots) {
        return;
    }
    let c = particle_info[i].w;
    if (!corrected(c) || mg_cloths[c].alpha == 0.0) {
        return;
    }
    let e = moved(c, i);
    iterate[i].position = vec4(iterate[i].position.xyz + mg_cloths[c].alpha * e, iterate[i].position.w);
}
