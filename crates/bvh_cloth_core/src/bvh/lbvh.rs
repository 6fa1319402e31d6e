//! Morton-code linear BVH over sphere leaves (paper section 2.4.2, after Karras 2012,
//! "Maximizing parallelism in the construction of BVHs, octrees, and k-d trees").
//!
//! Leaves are spheres sorted by the Morton code of their centres; inner nodes are AABBs. Every
//! one of the `N - 1` inner nodes finds its key range and split on its own, so the build is
//! data-parallel (rayon here, one GPU thread per node on a device). Inner node 0 is the root.
//!
//! The node and sphere arrays are `#[repr(C)]` Pod: the GPU backend uploads them unchanged.

use bytemuck::{Pod, Zeroable};
use glam::Vec3;
use rayon::prelude::*;

use crate::bvh::morton::{morton_code, sort_by_code};

/// A child reference with this bit set names a leaf (a sphere index); without it, an inner node.
pub const LEAF_BIT: u32 = 1 << 31;

/// Above this many leaves the inner nodes are built on the rayon pool.
const PARALLEL_BUILD_MIN_LEAVES: usize = 4096;

/// A bounding sphere: a leaf of the BVH. Layout: 16 bytes, `vec4<f32>` in WGSL.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct Sphere {
    /// Centre in the collider's local frame.
    pub center: [f32; 3],
    /// Radius (local units).
    pub radius: f32,
}

impl Sphere {
    /// A sphere from its centre and radius.
    pub fn new(center: Vec3, radius: f32) -> Self {
        Self { center: center.to_array(), radius }
    }

    /// The centre as a vector.
    pub fn centre(&self) -> Vec3 {
        Vec3::from(self.center)
    }
}

/// An inner node of the BVH: an AABB and two child references (see [`LEAF_BIT`]).
/// Layout: 32 bytes, two `vec4`-sized halves in WGSL.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct BvhNode {
    /// Minimum corner of the box bounding every sphere below this node.
    pub aabb_min: [f32; 3],
    /// Left child: an inner node index, or `LEAF_BIT | sphere index`.
    pub left: u32,
    /// Maximum corner of the box.
    pub aabb_max: [f32; 3],
    /// Right child, encoded like `left`.
    pub right: u32,
}

/// A built LBVH: `N` sphere leaves in Morton order and `N - 1` inner nodes.
#[derive(Clone, Debug, Default)]
pub struct Lbvh {
    /// Inner nodes; index 0 is the root. Empty when there is a single leaf.
    pub nodes: Vec<BvhNode>,
    /// Leaves, sorted by Morton code (ties by their input order).
    pub spheres: Vec<Sphere>,
    /// Number of inner levels on the longest root-to-leaf path (0 for a single leaf).
    pub depth: u32,
    /// The largest sphere radius (0 for an empty tree).
    pub max_radius: f32,
}

/// Length of the longest common prefix of keys `i` and `j`; -1 when `j` is outside the array.
/// A key is a leaf's Morton code above its index in the sorted order, so equal codes are made
/// distinct by their indices (Karras section 4) without a branch.
#[inline]
fn common_prefix(keys: &[u64], i: i64, j: i64) -> i32 {
    match usize::try_from(j).ok().and_then(|j| keys.get(j)) {
        Some(&b) => (keys[i as usize] ^ b).leading_zeros() as i32,
        None => -1,
    }
}

/// The split of the inner node over the leaves `first..=last` (`first < last`) of the sorted,
/// distinct `keys`: its left child is `first..=split`, its right `split + 1..=last`. The keys of
/// the range share their bits above the highest one in which its first and last differ, and
/// that bit is clear up to the split and set after it ([`build_inner_node`] finds the same
/// split from one end of the range).
#[inline]
pub(crate) fn split(keys: &[u64], first: usize, last: usize) -> usize {
    let bit = 1u64 << (63 - (keys[first] ^ keys[last]).leading_zeros());
    first + keys[first..=last].partition_point(|&k| k & bit == 0) - 1
}

/// Builds inner node `i` from the sorted keys: its key range, its split and its children.
fn build_inner_node(keys: &[u64], i: usize) -> BvhNode {
    let i = i as i64;
    let d: i64 = if common_prefix(keys, i, i + 1) - common_prefix(keys, i, i - 1) >= 0 { 1 } else { -1 };
    // Upper bound on the range length, then binary search for its far end.
    let delta_min = common_prefix(keys, i, i - d);
    let mut l_max: i64 = 2;
    while common_prefix(keys, i, i + l_max * d) > delta_min {
        l_max *= 2;
    }
    let mut l: i64 = 0;
    let mut t = l_max / 2;
    while t >= 1 {
        if common_prefix(keys, i, i + (l + t) * d) > delta_min {
            l += t;
        }
        t /= 2;
    }
    let j = i + l * d;
    // Binary search for the split: the last key sharing more than the range's common prefix.
    let delta_node = common_prefix(keys, i, j);
    let mut s: i64 = 0;
    let mut t = l;
    loop {
        t = (t + 1) / 2;
        if common_prefix(keys, i, i + (s + t) * d) > delta_node {
            s += t;
        }
        if t <= 1 {
            break;
        }
    }
    let gamma = i + s * d + d.min(0);
    let (first, last) = (i.min(j), i.max(j));
    let left = if first == gamma { LEAF_BIT | gamma as u32 } else { gamma as u32 };
    let right = if last == gamma + 1 { LEAF_BIT | (gamma + 1) as u32 } else { (gamma + 1) as u32 };
    BvhNode { left, right, ..Default::default() }
}

impl Lbvh {
    /// Builds the tree over `spheres`, whose Morton codes are taken inside the box of their
    /// centres. An empty input gives an empty tree; one sphere gives no inner node.
    pub fn build(spheres: &[Sphere]) -> Self {
        Self::build_with_order(spheres).0
    }

    /// As [`Self::build`], and the input index of every leaf: leaf `k` is `spheres[order[k]]`.
    pub fn build_with_order(spheres: &[Sphere]) -> (Self, Vec<u32>) {
        let (mut lbvh, order) = Self::build_unfitted(spheres);
        lbvh.depth = fit_bounds(&mut lbvh.nodes, &lbvh.spheres);
        (lbvh, order)
    }

    /// As [`Self::build_with_order`], with the inner boxes not fitted yet: the caller fits them
    /// with [`Self::fit_boxes_by`] to what its leaves stand for.
    pub(crate) fn build_unfitted(spheres: &[Sphere]) -> (Self, Vec<u32>) {
        let (nodes, order) = Self::build_topology(spheres);
        let sorted: Vec<Sphere> = if spheres.len() >= PARALLEL_BUILD_MIN_LEAVES {
            order.par_iter().map(|&i| spheres[i as usize]).collect()
        } else {
            order.iter().map(|&i| spheres[i as usize]).collect()
        };
        let max_radius = sorted.iter().fold(0.0f32, |r, s| r.max(s.radius));
        (Self { nodes, spheres: sorted, depth: 0, max_radius }, order)
    }

    /// The inner nodes of the tree over `spheres`, their boxes not fitted, and the input index
    /// of every leaf.
    pub(crate) fn build_topology(spheres: &[Sphere]) -> (Vec<BvhNode>, Vec<u32>) {
        let (keys, order) = Self::sorted_keys(spheres);
        if keys.is_empty() {
            return (Vec::new(), order);
        }
        let inner = keys.len() - 1;
        let nodes: Vec<BvhNode> = if keys.len() >= PARALLEL_BUILD_MIN_LEAVES {
            (0..inner).into_par_iter().map(|i| build_inner_node(&keys, i)).collect()
        } else {
            (0..inner).map(|i| build_inner_node(&keys, i)).collect()
        };
        (nodes, order)
    }

    /// The leaves' keys in leaf order (each Morton code above the leaf's index, so that all are
    /// distinct), which define the tree: an inner node is a range of leaves split where their
    /// keys first differ ([`split`]). And the input index of every leaf (a triangle surface
    /// keeps its triangles in leaf order, not their spheres).
    pub(crate) fn sorted_keys(spheres: &[Sphere]) -> (Vec<u64>, Vec<u32>) {
        if spheres.is_empty() {
            return (Vec::new(), Vec::new());
        }
        let parallel = spheres.len() >= PARALLEL_BUILD_MIN_LEAVES;
        // The box of the centres (a least and a greatest, the same in any order of the sums).
        let empty = (Vec3::INFINITY, Vec3::NEG_INFINITY);
        let grow = |(lo, hi): (Vec3, Vec3), s: &Sphere| (lo.min(s.centre()), hi.max(s.centre()));
        let (lo, hi) = if parallel {
            spheres.par_iter().fold(|| empty, grow).reduce(|| empty, |a, b| (a.0.min(b.0), a.1.max(b.1)))
        } else {
            spheres.iter().fold(empty, grow)
        };
        let code = |s: &Sphere| morton_code(s.centre(), lo, hi);
        let codes: Vec<u32> =
            if parallel { spheres.par_iter().map(code).collect() } else { spheres.iter().map(code).collect() };
        let keyed = sort_by_code(codes.into_iter());
        let key = |k: usize, &(c, _): &(u32, u32)| (u64::from(c) << 32) | k as u64;
        let keys: Vec<u64> = if parallel {
            keyed.par_iter().enumerate().map(|(k, ci)| key(k, ci)).collect()
        } else {
            keyed.iter().enumerate().map(|(k, ci)| key(k, ci)).collect()
        };
        let order = keyed.into_iter().map(|(_, i)| i).collect();
        (keys, order)
    }

    /// Fits every inner node's box to `leaf_box(k)` for leaf `k` instead of its sphere's box:
    /// for leaves that stand for something tighter than their sphere (a triangle).
    pub(crate) fn fit_boxes_by(&mut self, leaf_box: impl Fn(u32) -> (Vec3, Vec3) + Sync) {
        self.depth = fit_bounds_by(&mut self.nodes, leaf_box);
    }

    /// Fits every inner node's box to the spheres as they are now, keeping the tree's topology
    /// (after the spheres moved: a skinned collider's refit).
    pub fn refit(&mut self) {
        fit_bounds(&mut self.nodes, &self.spheres);
        self.max_radius = self.spheres.iter().fold(0.0f32, |r, s| r.max(s.radius));
    }

    /// The inner nodes grouped by depth, deepest first: `levels[starts[l]..starts[l + 1]]` are
    /// level `l`'s nodes, and every node's inner children lie in earlier levels. Boxes refitted
    /// level after level in this order (each level in parallel) are refitted children first.
    pub fn levels(&self) -> (Vec<u32>, Vec<u32>) {
        if self.nodes.is_empty() {
            return (Vec::new(), vec![0]);
        }
        let mut depth = vec![0u32; self.nodes.len()];
        // Children always come after a parent in a walk from the root.
        let mut stack = vec![0u32];
        while let Some(node) = stack.pop() {
            let BvhNode { left, right, .. } = self.nodes[node as usize];
            for child in [left, right] {
                if child & LEAF_BIT == 0 {
                    depth[child as usize] = depth[node as usize] + 1;
                    stack.push(child);
                }
            }
        }
        let deepest = depth.iter().copied().max().unwrap_or(0);
        let mut levels: Vec<u32> = (0..self.nodes.len() as u32).collect();
        levels.sort_by_key(|&n| deepest - depth[n as usize]);
        let mut starts = vec![0u32];
        for k in 1..levels.len() {
            if depth[levels[k] as usize] != depth[levels[k - 1] as usize] {
                starts.push(k as u32);
            }
        }
        starts.push(levels.len() as u32);
        (levels, starts)
    }

    /// The reference to start a traversal from: inner node 0, or the only leaf.
    pub fn root(&self) -> u32 {
        if self.nodes.is_empty() { LEAF_BIT } else { 0 }
    }

    /// Number of leaves.
    pub fn leaf_count(&self) -> usize {
        self.spheres.len()
    }

    /// The box around every sphere, or `None` for an empty tree.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        match (self.nodes.first(), self.spheres.first()) {
            (Some(root), _) => Some((Vec3::from(root.aabb_min), Vec3::from(root.aabb_max))),
            (None, Some(s)) => Some((s.centre() - s.radius, s.centre() + s.radius)),
            (None, None) => None,
        }
    }
}

/// Fits every inner node's AABB to the spheres below it, bottom-up, and returns the depth.
/// A post-order walk with an explicit stack: O(N), no recursion, far cheaper than the build.
fn fit_bounds(nodes: &mut [BvhNode], spheres: &[Sphere]) -> u32 {
    fit_bounds_by(nodes, |k| {
        let s = spheres[k as usize];
        (s.centre() - s.radius, s.centre() + s.radius)
    })
}

/// As [`fit_bounds`], with leaf `k`'s box given by `leaf_box(k)`.
///
/// A Karras tree's subtree over the leaves `[a, b]` holds the inner nodes of one contiguous
/// range of indices (its root is `a` or `b`, its left child's subtree lies in `[a, γ]` and its
/// right child's in `[γ + 1, b]`), so the two subtrees of a node are disjoint slices and are
/// fitted in parallel when they are large.
fn fit_bounds_by(nodes: &mut [BvhNode], leaf_box: impl Fn(u32) -> (Vec3, Vec3) + Sync) -> u32 {
    if nodes.is_empty() {
        return 0;
    }
    fit_subtree(nodes, 0, 0, &leaf_box).2
}

/// Subtrees with fewer inner nodes than this are fitted on one thread.
const PARALLEL_FIT_MIN_NODES: usize = 4096;

/// Fits the subtree rooted at inner node `root`, whose inner nodes are `nodes` (global indices
/// from `base`; the root is the first or the last of them). Returns its box and its depth.
fn fit_subtree<F>(nodes: &mut [BvhNode], base: usize, root: usize, leaf_box: &F) -> (Vec3, Vec3, u32)
where
    F: Fn(u32) -> (Vec3, Vec3) + Sync,
{
    let (node, rest, rest_base) = if root == base {
        let (node, rest) = nodes.split_first_mut().expect("a subtree has its root");
        (node, rest, base + 1)
    } else {
        debug_assert_eq!(root, base + nodes.len() - 1, "a subtree's root is its first or last node");
        let (node, rest) = nodes.split_last_mut().expect("a subtree has its root");
        (node, rest, base)
    };
    let (left, right) = (node.left, node.right);
    // The left child's subtree ends at the split γ, its index; the right one starts after it.
    let split = ((left & !LEAF_BIT) as usize + 1).saturating_sub(rest_base).min(rest.len());
    let parallel = rest.len() >= PARALLEL_FIT_MIN_NODES;
    let (left_nodes, right_nodes) = rest.split_at_mut(split);
    let right_base = rest_base + split;
    let fit_child = |child: u32, slice: &mut [BvhNode], slice_base: usize| {
        if child & LEAF_BIT != 0 {
            let (lo, hi) = leaf_box(child & !LEAF_BIT);
            (lo, hi, 0)
        } else {
            fit_subtree(slice, slice_base, child as usize, leaf_box)
        }
    };
    let ((lmin, lmax, ldepth), (rmin, rmax, rdepth)) = if parallel {
        rayon::join(|| fit_child(left, left_nodes, rest_base), || fit_child(right, right_nodes, right_base))
    } else {
        (fit_child(left, left_nodes, rest_base), fit_child(right, right_nodes, right_base))
    };
    let (lo, hi) = (lmin.min(rmin), lmax.max(rmax));
    node.aabb_min = lo.to_array();
    node.aabb_max = hi.to_array();
    (lo, hi, 1 + ldepth.max(rdepth))
}
