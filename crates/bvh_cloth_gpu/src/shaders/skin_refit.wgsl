// The refit of a skinned collider (bvh_cloth_core::colliders::skinning::SkinnedSpheres::refit, in the same
// order of operations): the vertices are skinned, every sphere is fitted again around its
// points (each a blend of three skinned vertices), the tree's boxes are refitted level by level
// from the deepest, and the collider's contact reach follows its largest sphere. One collider
// per dispatch sequence; the host binds each dispatch's RefitParams at a dynamic offset.
//
// Workgroups are 64x1x1; a thread's index is id.y * num_workgroups.x * 64 + id.x.

#import bvh_cloth::types::{GpuCollider}
#import bvh_cloth::constants::{LEAF_BIT, CONTACT_BAND}

struct RefitParams {
    vertex_count: u32,
    leaf_count: u32,
    node_offset: u32,
    sphere_offset: u32,
    level_start: u32,
    level_count: u32,
    collider: u32,
    clearance: f32,
}

struct GpuSkinVertex {
    position: vec3<f32>,
    joints_low: u32,
    weights: vec4<f32>,
    joints_high: u32,
}

// A point: three vertices and the barycentric weights of the second and third.
struct SkinPoint {
    a: u32,
    b: u32,
    c: u32,
    u: f32,
    v: f32,
}

@group(0) @binding(26) var<uniform> refit: RefitParams;
@group(0) @binding(27) var<storage, read> bind_vertices: array<GpuSkinVertex>;
// Each joint's world transform times its inverse bind pose.
@group(0) @binding(28) var<storage, read> joints: array<mat4x4<f32>>;
@group(0) @binding(29) var<storage, read_write> skinned: array<vec4<f32>>;
@group(0) @binding(30) var<storage, read> skin_points: array<SkinPoint>;
// Leaf k's points are skin_points[leaf_starts[k]..leaf_starts[k + 1]].
@group(0) @binding(31) var<storage, read> leaf_starts: array<u32>;
// Inner nodes by depth, deepest first (bvh_cloth_core::Lbvh::levels).
@group(0) @binding(32) var<storage, read> level_nodes: array<u32>;
// The tree buffer of every collider (collision.wgsl's `tree`), written here.
@group(0) @binding(33) var<storage, read_write> refit_tree: array<vec4<f32>>;
@group(0) @binding(34) var<storage, read_write> refit_colliders: array<GpuCollider>;

const REFIT_WORKGROUP: u32 = 64u;

fn refit_index(id: vec3<u32>, groups: vec3<u32>) -> u32 {
    return id.y * groups.x * REFIT_WORKGROUP + id.x;
}

@compute @workgroup_size(64, 1, 1)
fn skin_vertices(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = refit_index(id, groups);
    if (i >= refit.vertex_count) {
        return;
    }
    let vertex = bind_vertices[i];
    let p = vec4(vertex.position, 1.0);
    let ids = vec4(
        vertex.joints_low & 0xffffu,
        vertex.joints_low >> 16u,
        vertex.joints_high & 0xffffu,
        vertex.joints_high >> 16u,
    );
    var sum = vec3(0.0);
    for (var k = 0u; k < 4u; k++) {
        let w = vertex.weights[k];
        if (w != 0.0) {
            sum += w * (joints[ids[k]] * p).xyz;
        }
    }
    skinned[i] = vec4(sum, 0.0);
}

fn place(point: SkinPoint) -> vec3<f32> {
    let a = skinned[point.a].xyz;
    if (point.u == 0.0 && point.v == 0.0) {
        return a;
    }
    let b = skinned[point.b].xyz;
    let c = skinned[point.c].xyz;
    return a + point.u * (b - a) + point.v * (c - a);
}

// The smaller of the box-centre and centroid spheres around the leaf's points, grown by the
// clearance.
@compute @workgroup_size(64, 1, 1)
fn fit_leaves(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let k = refit_index(id, groups);
    if (k >= refit.leaf_count) {
        return;
    }
    let start = leaf_starts[k];
    let end = leaf_starts[k + 1u];
    var lo = vec3(3.0e38);
    var hi = vec3(-3.0e38);
    var sum = vec3(0.0);
    for (var i = start; i < end; i++) {
        let p = place(skin_points[i]);
        lo = min(lo, p);
        hi = max(hi, p);
        sum += p;
    }
    let box_centre = 0.5 * (lo + hi);
    let centroid = sum / f32(max(end - start, 1u));
    var far_box = 0.0;
    var far_centroid = 0.0;
    for (var i = start; i < end; i++) {
        let p = place(skin_points[i]);
        let to_box = p - box_centre;
        let to_centroid = p - centroid;
        far_box = max(far_box, dot(to_box, to_box));
        far_centroid = max(far_centroid, dot(to_centroid, to_centroid));
    }
    var centre = box_centre;
    var far = far_box;
    if (far_centroid < far_box) {
        centre = centroid;
        far = far_centroid;
    }
    refit_tree[refit.sphere_offset + k] = vec4(centre, sqrt(far) + refit.clearance);
}

fn child_bounds(child: u32) -> array<vec3<f32>, 2> {
    if ((child & LEAF_BIT) != 0u) {
        let s = refit_tree[refit.sphere_offset + (child & ~LEAF_BIT)];
        return array(s.xyz - s.w, s.xyz + s.w);
    }
    let at = 2u * (refit.node_offset + child);
    return array(refit_tree[at].xyz, refit_tree[at + 1u].xyz);
}

// One level of inner nodes: each box around its children's.
@compute @workgroup_size(64, 1, 1)
fn refit_nodes(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let k = refit_index(id, groups);
    if (k >= refit.level_count) {
        return;
    }
    let at = 2u * (refit.node_offset + level_nodes[refit.level_start + k]);
    let lo = refit_tree[at];
    let hi = refit_tree[at + 1u];
    let left = child_bounds(bitcast<u32>(lo.w));
    let right = child_bounds(bitcast<u32>(hi.w));
    refit_tree[at] = vec4(min(left[0], right[0]), lo.w);
    refit_tree[at + 1u] = vec4(max(left[1], right[1]), hi.w);
}

var<workgroup> refit_largest: array<f32, 64>;

// One workgroup: the largest radius, and from it the collider's contact reach
// (bvh_cloth_core::colliders::collision::contact_reach).
@compute @workgroup_size(64, 1, 1)
fn refit_reach(@builtin(local_invocation_index) t: u32) {
    var r = 0.0;
    for (var k = t; k < refit.leaf_count; k += REFIT_WORKGROUP) {
        r = max(r, refit_tree[refit.sphere_offset + k].w);
    }
    refit_largest[t] = r;
    workgroupBarrier();
    for (var half = REFIT_WORKGROUP / 2u; half > 0u; half /= 2u) {
        if (t < half) {
            refit_largest[t] = max(refit_largest[t], refit_largest[t + half]);
        }
        workgroupBarrier();
    }
    if (t == 0u) {
        let margin = refit_colliders[refit.collider].margin_local;
        refit_colliders[refit.collider].contact_reach = CONTACT_BAND * (refit_largest[0] + margin);
    }
}
