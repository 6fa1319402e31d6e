//! A four-wide copy of an [`Lbvh`] for queries on the CPU: each node holds the boxes of up to
//! four children side by side, one SIMD lane each, so a query tests four boxes at once and
//! descends two levels of the binary tree or more per node.
//!
//! The wide tree is the binary tree with every other level folded into its parent: a wide node
//! stands for a binary node, and its children are that node's grandchildren (or its children where
//! those are leaves). A grandchild over two or three leaves, the most common nodes at the bottom of
//! the tree, is no node of its own: the lane holds the run of leaves, with their box, and the wide
//! tree has about half as many nodes (the bundled dragon's surface 47,968, against 101,278 with a
//! node over each). Its boxes are the binary tree's, and a leaf's is the box the tree was fitted to
//! (a triangle's own box for exact contact), each rounded outwards to 8 bits a bound across its
//! node ([`WideNode`]), so a node is one 64-byte cache line. A query finds what a descent of the
//! binary tree would have found, with half the dependent loads or fewer, and may meet a few more
//! leaves, whose rounded box (or their run's) reaches the query where their own does not.
//!
//! [`WideBvh::for_each_overlapping`] meets the leaves the binary walk
//! ([`Lbvh::for_each_overlapping`], the GPU's) meets in the same order, so a response that
//! depends on the order of its contacts is the same on both.

use glam::{BVec4A, Vec3, Vec4};
use rayon::prelude::*;

use crate::bvh::lbvh::{BvhNode, LEAF_BIT, Lbvh, split};
use crate::bvh::traversal::STACK_SIZE;

/// A node of the wide tree, one 64-byte cache line: the boxes of up to four children, one SIMD
/// lane each, and the children's references.
///
/// The boxes are kept in 8 bits a bound: each axis of the node is cut into 255 steps from
/// `origin`, and each child's box is rounded outwards to whole steps, so the box a query tests
/// holds the child's own (and reaches at most a step of the node past it). Half the size of
/// boxes in `f32`, so a walk pulls in half the memory; a caller's exact test at the leaf
/// decides what a slightly larger box lets through.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
pub struct WideNode {
    /// The corner the boxes are measured from.
    origin: [f32; 3],
    /// The size of one step, per axis.
    step: [f32; 3],
    /// The children's box minima in steps from `origin`, per axis (x, y, z), one lane per child.
    lo: [[u8; 4]; 3],
    /// The children's box maxima in steps.
    hi: [[u8; 4]; 3],
    /// `LEAF_BIT | run << RUN_SHIFT | leaf` for a run of one to three leaves from `leaf` on
    /// (the leaves of one binary node of two or three, [`WideNode::leaves`]), or a wide node's
    /// index, in the order a depth-first walk of the binary tree meets them; the used lanes come
    /// first, and an unused lane holds `u32::MAX`.
    pub child: [u32; 4],
}

/// Where a child reference's run of leaves begins: bits 29 and 30 say which of [`RUNS`] its
/// lane holds, and the bits below are the first leaf's index.
pub const RUN_SHIFT: u32 = 29;

/// The first leaf's index in a child reference that holds leaves.
const LEAF_INDEX: u32 = (1 << RUN_SHIFT) - 1;

/// The most leaves a wide tree holds: a leaf's index leaves room for the run's bits.
pub const MAX_LEAVES: usize = 1 << RUN_SHIFT;

/// The runs of leaves a lane holds, by their bits: how many, and the offsets from the first in
/// the order the binary walk meets them (a node's leaf children right, then left, then its
/// inner children's): one leaf; the two children of a node; a leaf and a pair after it (the
/// node's left child alone); a pair and a leaf after it.
const RUNS: [(usize, [u32; 3]); 4] = [(1, [0, 0, 0]), (2, [1, 0, 0]), (3, [0, 2, 1]), (3, [2, 1, 0])];

/// The leaves of a child reference that holds leaves, in the binary walk's order, and how many.
#[inline]
fn run_leaves(reference: u32) -> ([u32; 3], usize) {
    let first = reference & LEAF_INDEX;
    let (count, offsets) = RUNS[((reference >> RUN_SHIFT) & 3) as usize];
    (offsets.map(|offset| first + offset), count)
}

/// The bounds `q` steps from `origin`, as the queries compute them: the build rounds each
/// bound outwards with the same arithmetic (a product, then a sum, each rounded once), so that
/// what it checks is what the queries see.
#[inline]
fn bound(origin: Vec4, q: Vec4, step: Vec4) -> Vec4 {
    origin + q * step
}

/// The four bounds of one axis, as `f32` lanes.
#[inline]
fn lanes(q: [u8; 4]) -> Vec4 {
    Vec4::new(q[0] as f32, q[1] as f32, q[2] as f32, q[3] as f32)
}

impl WideNode {
    const EMPTY: Self =
        Self { origin: [0.0; 3], step: [0.0; 3], lo: [[u8::MAX; 4]; 3], hi: [[0; 4]; 3], child: [u32::MAX; 4] };

    /// The node of the given children (the used lanes first) and their boxes.
    fn new(children: &[u32], boxes: &[(Vec3, Vec3)]) -> Self {
        let mut node = Self::EMPTY;
        let lo = boxes.iter().fold(Vec3::INFINITY, |m, b| m.min(b.0));
        let hi = boxes.iter().fold(Vec3::NEG_INFINITY, |m, b| m.max(b.1));
        // Per axis, the least step whose 255th reaches the top; the three axes side by side
        // (their rounding loops are independent, so they overlap).
        let (origin, top_of) = (lo.extend(0.0), hi.extend(0.0));
        let mut step = ((top_of - origin) / 255.0).max(Vec4::ZERO);
        loop {
            let short = bound(origin, Vec4::splat(255.0), step).cmplt(top_of) & step.is_finite_mask();
            if !short.any() {
                break;
            }
            // The next `f32` up from a positive finite step (or from zero).
            let up = Vec4::from_array(step.to_array().map(|s| f32::from_bits(s.to_bits() + 1)));
            step = Vec4::select(short, up, step);
        }
        node.origin = lo.to_array();
        node.step = step.truncate().to_array();
        // The children's boxes one lane each; an unused lane repeats the first child and is not
        // written.
        let lane_box = |lane: usize| boxes.get(lane).unwrap_or(&boxes[0]);
        let (one, top) = (Vec4::ONE, Vec4::splat(255.0));
        // The three axes' inverse steps in one division (0 for a flat axis).
        let inverses = Vec4::select(step.cmpgt(Vec4::ZERO), Vec4::ONE / step, Vec4::ZERO);
        let axes: [_; 3] = std::array::from_fn(|axis| {
            let (origin4, step4) = (Vec4::splat(origin[axis]), Vec4::splat(step[axis]));
            let inverse = Vec4::splat(inverses[axis]);
            let mins = Vec4::from_array(std::array::from_fn(|lane| lane_box(lane).0[axis]));
            let maxs = Vec4::from_array(std::array::from_fn(|lane| lane_box(lane).1[axis]));
            // A first guess in whole steps, rounded outwards below with the queries'
            // arithmetic (`bound`): down for the minima, up for the maxima.
            let guess = |x: Vec4| ((x - origin4) * inverse).max(Vec4::ZERO).floor().min(top);
            (origin4, step4, mins, maxs, guess(mins), guess(maxs))
        });
        let mut q: [(Vec4, Vec4); 3] = axes.map(|(_, _, _, _, lo, hi)| (lo, hi));
        // The guesses are off by a step at most, so this runs once or twice; the six roundings
        // are independent.
        loop {
            let mut moved = false;
            for ((origin4, step4, mins, maxs, _, _), (q_lo, q_hi)) in axes.iter().zip(q.iter_mut()) {
                let over = bound(*origin4, *q_lo, *step4).cmpgt(*mins) & q_lo.cmpgt(Vec4::ZERO);
                let under = bound(*origin4, *q_hi, *step4).cmplt(*maxs) & q_hi.cmplt(top);
                moved |= over.any() | under.any();
                *q_lo = Vec4::select(over, *q_lo - one, *q_lo);
                *q_hi = Vec4::select(under, *q_hi + one, *q_hi);
            }
            if !moved {
                break;
            }
        }
        // Whole steps in [0, 255], converted four lanes at a time.
        for (axis, (q_lo, q_hi)) in q.iter().enumerate() {
            let (q_lo, q_hi) = (q_lo.as_uvec4().to_array(), q_hi.as_uvec4().to_array());
            for lane in 0..boxes.len() {
                node.lo[axis][lane] = q_lo[lane] as u8;
                node.hi[axis][lane] = q_hi[lane] as u8;
            }
        }
        node.child[..children.len()].copy_from_slice(children);
        node
    }

    /// The children's boxes, per axis: minima and maxima, one lane per child (unused lanes
    /// hold an inverted box).
    #[inline]
    fn boxes(&self, axis: usize) -> (Vec4, Vec4) {
        let (origin, step) = (Vec4::splat(self.origin[axis]), Vec4::splat(self.step[axis]));
        (bound(origin, lanes(self.lo[axis]), step), bound(origin, lanes(self.hi[axis]), step))
    }

    /// The lanes in use, as a bit mask.
    #[inline]
    fn used(&self) -> u32 {
        self.child.iter().enumerate().fold(0, |m, (lane, &c)| m | (((c != u32::MAX) as u32) << lane))
    }

    /// The leaves lane `lane` holds, in the order the binary walk meets them (none for an inner
    /// or unused lane).
    pub fn leaves(&self, lane: usize) -> impl Iterator<Item = u32> {
        let reference = self.child[lane];
        let (leaves, count) =
            if reference != u32::MAX && reference & LEAF_BIT != 0 { run_leaves(reference) } else { ([0; 3], 0) };
        leaves.into_iter().take(count)
    }

    /// The box of child `lane`, as the queries see it.
    pub fn child_box(&self, lane: usize) -> (Vec3, Vec3) {
        let mut lo = Vec3::ZERO;
        let mut hi = Vec3::ZERO;
        for axis in 0..3 {
            let (l, h) = self.boxes(axis);
            lo[axis] = l[lane];
            hi[axis] = h[lane];
        }
        (lo, hi)
    }

    /// The four squared distances from `p` to the children's boxes (infinite in unused lanes).
    #[inline]
    fn distances_squared(&self, p: Vec3) -> Vec4 {
        let mut sum = Vec4::ZERO;
        for axis in 0..3 {
            let (lo, hi) = self.boxes(axis);
            let at = Vec4::splat(p[axis]);
            let outside = (lo - at).max(at - hi).max(Vec4::ZERO);
            sum += outside * outside;
        }
        let used = BVec4A::from_array(std::array::from_fn(|lane| self.child[lane] != u32::MAX));
        Vec4::select(used, sum, Vec4::INFINITY)
    }

    /// The lanes (bit `i` for child `i`) whose box overlaps `[lo, hi]`; none for a query with a
    /// NaN.
    #[inline]
    fn overlapping(&self, lo: Vec3, hi: Vec3) -> u32 {
        let mut lanes = self.used();
        for axis in 0..3 {
            let (box_lo, box_hi) = self.boxes(axis);
            let meet = box_lo.cmple(Vec4::splat(hi[axis])) & box_hi.cmpge(Vec4::splat(lo[axis]));
            lanes &= meet.bitmask();
        }
        lanes
    }
}

/// The wide tree: node 0 is the root; empty when the binary tree has no leaf.
#[derive(Clone, Debug, Default)]
pub struct WideBvh {
    /// The nodes, each before its children (a depth-first order).
    pub nodes: Vec<WideNode>,
    /// The least leaf under each node. The leaves under a node are a range of the leaves'
    /// numbers (the binary tree's leaves are in key order), so they are that one and those
    /// after it, up to twelve for a node at the bottom of the tree: [`WideBvh::nearest`] asks
    /// for their data ahead of its visit.
    pub first_leaf: Vec<u32>,
}

/// The traversal stack. The binary tree has fewer than [`STACK_SIZE`] levels, so the wide one
/// has at most half as many; a walk holds at most three entries for each level above the node
/// it pops and the four that node pushes, well within this.
const WIDE_STACK: usize = 2 * STACK_SIZE + 4;

impl WideBvh {
    /// Folds `tree` into a wide tree. `leaf_box(k)` is leaf `k`'s box, and each wide node's
    /// boxes are the unions of its children's (the boxes a fit to `leaf_box` gives; `tree`'s
    /// own inner boxes are not read). A large tree's subtrees under its top three wide levels
    /// are folded in parallel.
    pub fn from_lbvh(tree: &Lbvh, leaf_box: impl Fn(u32) -> (Vec3, Vec3) + Sync) -> Self {
        Self::from_unfitted(&tree.nodes, tree.spheres.len(), leaf_box).0
    }

    /// [`Self::from_lbvh`] for the inner nodes `binary` of a tree of `leaves` leaves, whose
    /// boxes need not be fitted: each wide node's boxes are found on the way up, so the binary
    /// tree's are never read (a box's bounds are the least and greatest of its leaves' however
    /// they are grouped, so a fitted tree gives the same nodes). Returns the root's box too.
    pub(crate) fn from_unfitted(
        binary: &[BvhNode],
        leaves: usize,
        leaf_box: impl Fn(u32) -> (Vec3, Vec3) + Sync,
    ) -> (Self, (Vec3, Vec3)) {
        Self::fold_tree(&Nodes(binary), 0, leaves, &leaf_box)
    }

    /// [`Self::from_unfitted`] for the tree of the leaves' sorted keys
    /// ([`Lbvh::sorted_keys`]), whose binary nodes are never built: each is found as a range of
    /// leaves and its split ([`split`]) as the fold meets it. The same tree, so the same wide
    /// nodes.
    pub(crate) fn from_keys(keys: &[u64], leaf_box: impl Fn(u32) -> (Vec3, Vec3) + Sync) -> (Self, (Vec3, Vec3)) {
        let last = keys.len().saturating_sub(1) as u32;
        Self::fold_tree(&Keys(keys), (0, last), keys.len(), &leaf_box)
    }

    /// Folds the binary `tree` of `leaves` leaves (at most [`MAX_LEAVES`]), whose root is
    /// `root` (when it has two leaves or more).
    fn fold_tree<B: Binary>(
        tree: &B,
        root: B::Node,
        leaves: usize,
        leaf_box: &(impl Fn(u32) -> (Vec3, Vec3) + Sync),
    ) -> (Self, (Vec3, Vec3)) {
        assert!(leaves <= MAX_LEAVES, "{leaves} leaves in a wide tree, above {MAX_LEAVES}");
        if leaves < 2 {
            if leaves == 0 {
                return (Self::default(), (Vec3::ZERO, Vec3::ZERO));
            }
            let only = leaf_box(0);
            return (Self::with_first_leaves(vec![WideNode::new(&[LEAF_BIT], &[only])]), only);
        }
        let fold = Fold { tree, leaf_box };
        let mut nodes = Vec::new();
        if leaves - 1 < PARALLEL_FOLD_MIN_NODES {
            let box_ = fold.fold(root, 0, &mut nodes, &mut None);
            return (Self::with_first_leaves(nodes), box_);
        }
        // The subtrees under the top `PART_DEPTH` levels are folded in parallel, each into its
        // own nodes; the top is folded here, each part copied in after the node that points to
        // it, so the whole stays in depth-first order.
        let mut roots = Vec::new();
        fold.part_roots(root, 0, &mut roots);
        let parts: Vec<FoldedPart> = roots
            .par_iter()
            .map(|&part_root| {
                let mut part = Vec::with_capacity(tree.wide_bound(part_root));
                let root_box = fold.fold(part_root, 0, &mut part, &mut None);
                (part, root_box)
            })
            .collect();
        nodes.reserve(parts.iter().map(|(part, _)| part.len()).sum::<usize>() + PART_DEPTH_NODES);
        let mut parts = parts.into_iter();
        let box_ = fold.fold(root, 0, &mut nodes, &mut Some(&mut parts));
        (Self::with_first_leaves(nodes), box_)
    }

    /// The tree of `nodes`, with each node's least leaf: the least of its lanes' (a run's
    /// first leaf, an inner child's least), found from the last node up (a node's children
    /// follow it).
    fn with_first_leaves(nodes: Vec<WideNode>) -> Self {
        let mut first_leaf = vec![0u32; nodes.len()];
        for index in (0..nodes.len()).rev() {
            let least = |child: u32| match child {
                u32::MAX => u32::MAX,
                leaves if leaves & LEAF_BIT != 0 => leaves & LEAF_INDEX,
                inner => first_leaf[inner as usize],
            };
            first_leaf[index] = nodes[index].child.iter().map(|&child| least(child)).min().unwrap_or(0);
        }
        Self { nodes, first_leaf }
    }

    /// The bytes the tree keeps on the heap.
    pub fn bytes(&self) -> usize {
        self.nodes.capacity() * size_of::<WideNode>() + self.first_leaf.capacity() * size_of::<u32>()
    }

    /// Calls `visit(leaf)` for every leaf whose box overlaps `[lo, hi]` grown by `margin`, in
    /// the order [`Lbvh::for_each_overlapping`] meets them. (That one tests a leaf's sphere,
    /// this one the leaf's own box, so each may meet a leaf the other does not whose sphere or
    /// box alone overlaps; a caller's exact test decides either way.)
    #[inline]
    pub fn for_each_overlapping(&self, lo: Vec3, hi: Vec3, margin: f32, mut visit: impl FnMut(u32)) {
        if self.nodes.is_empty() {
            return;
        }
        let (lo, hi) = (lo - margin, hi + margin);
        // Leaves go through the stack too, so that each is met where the binary walk meets it.
        let mut stack = [0u32; WIDE_STACK];
        let mut top = 1usize;
        while top > 0 {
            top -= 1;
            let entry = stack[top];
            if entry & LEAF_BIT != 0 {
                let (leaves, count) = run_leaves(entry);
                leaves[..count].iter().for_each(|&k| visit(k));
                continue;
            }
            let node = &self.nodes[entry as usize];
            let lanes = node.overlapping(lo, hi);
            for lane in (0..4).rev() {
                if lanes & (1 << lane) != 0 {
                    stack[top] = node.child[lane];
                    top += 1;
                }
            }
        }
    }

    /// A nearest-first search: `leaves(ks, best)` is called with the leaves of a node whose
    /// boxes (or runs' boxes) lie closer to `p` than `best`, the squared distance found so far
    /// (`limit` at first), up to twelve at once, and returns the new `best` (the least of its
    /// own and the leaves' squared distances to `p`). Returns the last `best`, which is `limit`
    /// for a point with a NaN or a `limit` that is not positive. `leaf_data` is what `leaves`
    /// reads, one item per leaf in the leaves' order (or nothing).
    ///
    /// The walk waits on memory more than on arithmetic: the children it will visit are
    /// fetched into the cache while it tests a node's leaves, and with each the node after it
    /// (its first inner child when it has one: the nodes are in depth-first order) and its
    /// first leaves' data (six cache lines of `leaf_data` from its least leaf on: most of a
    /// bottom node's triangles); a node's leaves come together, so that a caller can test them
    /// side by side.
    #[inline]
    pub fn nearest<T>(&self, p: Vec3, limit: f32, leaf_data: &[T], mut leaves: impl FnMut(&[u32], f32) -> f32) -> f32 {
        let mut best = limit;
        // A NaN coordinate would count as inside every box along its axis (the lanes' `max`
        // keeps the zero), and a NaN limit would let the unused lanes through, so both are
        // answered here.
        if self.nodes.is_empty() || p.is_nan() || limit.is_nan() || limit <= 0.0 {
            return best;
        }
        // Each entry keeps its box's squared distance, checked again against `best` when popped.
        let mut stack = [(0u32, 0.0f32); WIDE_STACK];
        let mut top = 1usize;
        while top > 0 {
            top -= 1;
            let (index, d2) = stack[top];
            if d2 >= best {
                continue;
            }
            let node = &self.nodes[index as usize];
            let distances = node.distances_squared(p);
            // Unused lanes are infinitely far, so they are never near.
            let near = distances.cmplt(Vec4::splat(best)).bitmask();
            let distances = distances.to_array();
            // The inner children sorted farthest first, so that the nearest is popped first,
            // each fetched while the leaves are tested; the leaves in lane order.
            let mut inner = [(0u32, 0.0f32); 4];
            let mut inner_count = 0;
            // Room for a run of three after nine leaves: each run is copied whole (a copy of a
            // length known at compile time), and only its `count` leaves are kept.
            let mut found = [0u32; 12];
            let mut found_count = 0;
            let mut lanes = near;
            while lanes != 0 {
                let lane = lanes.trailing_zeros() as usize;
                lanes &= lanes - 1;
                let (child, d2) = (node.child[lane], distances[lane]);
                if child & LEAF_BIT != 0 {
                    let (leaves, count) = run_leaves(child);
                    found[found_count..found_count + 3].copy_from_slice(&leaves);
                    found_count += count;
                    continue;
                }
                prefetch(&self.nodes[child as usize]);
                if let Some(first_inner) = self.nodes.get(child as usize + 1) {
                    prefetch(first_inner);
                }
                prefetch_lines(leaf_data, self.first_leaf[child as usize]);
                let mut slot = inner_count;
                while slot > 0 && inner[slot - 1].1 < d2 {
                    inner[slot] = inner[slot - 1];
                    slot -= 1;
                }
                inner[slot] = (child, d2);
                inner_count += 1;
            }
            if found_count > 0 {
                best = leaves(&found[..found_count], best);
            }
            for &(child, d2) in &inner[..inner_count] {
                if d2 < best {
                    stack[top] = (child, d2);
                    top += 1;
                }
            }
        }
        best
    }
}

/// Asks for the cache line that holds `value` ahead of its use (a hint: nothing waits on it).
#[inline(always)]
fn prefetch<T>(value: &T) {
    #[cfg(target_arch = "x86_64")]
    safe_arch::prefetch_t0(value);
    #[cfg(not(target_arch = "x86_64"))]
    let _ = value;
}

/// The cache lines of leaf data [`WideBvh::nearest`] asks for ahead of a node's visit: 384
/// bytes, ten triangles' corners, most of what a node at the bottom of the tree holds.
const LEAF_DATA_LINES: usize = 6;

/// Asks for [`LEAF_DATA_LINES`] cache lines of `data` from item `first` on: one item in each
/// 64 bytes, none when they run past the end (a tree's last few leaves).
#[inline(always)]
fn prefetch_lines<T>(data: &[T], first: u32) {
    let size = size_of::<T>().max(1);
    let span = (64 * (LEAF_DATA_LINES - 1)).div_ceil(size) + 1;
    if let Some(items) = data.get(first as usize..first as usize + span) {
        for line in 0..LEAF_DATA_LINES {
            prefetch(&items[(64 * line).div_ceil(size)]);
        }
    }
}

/// Below this many binary nodes a tree is folded on one thread.
const PARALLEL_FOLD_MIN_NODES: usize = 16_384;

/// The wide levels above the parts a large tree is folded in: up to 4^3 = 64 parts, enough to
/// share among the threads however unevenly the tree splits.
const PART_DEPTH: usize = 3;

/// The most wide nodes above the parts: 1 + 4 + 16.
const PART_DEPTH_NODES: usize = 21;

/// A binary tree as the fold reads it: each inner node's two children.
trait Binary: Sync {
    /// An inner node.
    type Node: Copy + Send + Sync;
    /// Inner node `node`'s children: left, then right.
    fn children(&self, node: Self::Node) -> [Child<Self::Node>; 2];
    /// `Some((k, run))` when inner node `node` stands over two or three leaves from `k` on, as
    /// the run `run` of [`RUNS`] says (a node's leaves are a range, so they are neighbours).
    #[inline]
    fn run(&self, node: Self::Node) -> Option<(u32, u32)> {
        let pair = |inner| matches!(self.children(inner), [Child::Leaf(_), Child::Leaf(_)]);
        match self.children(node) {
            [Child::Leaf(k), Child::Leaf(_)] => Some((k, 1)),
            [Child::Leaf(k), Child::Inner(right)] => pair(right).then_some((k, 2)),
            [Child::Inner(left), Child::Leaf(last)] => pair(left).then_some((last - 2, 3)),
            [Child::Inner(_), Child::Inner(_)] => None,
        }
    }
    /// At least as many as the wide nodes of the subtree under `node` (0 when unknown).
    fn wide_bound(&self, node: Self::Node) -> usize;
}

/// A binary node's child.
#[derive(Clone, Copy)]
enum Child<N> {
    /// Leaf `k`.
    Leaf(u32),
    /// An inner node.
    Inner(N),
}

/// An [`Lbvh`]'s inner nodes, each named by its index.
struct Nodes<'a>(&'a [BvhNode]);

impl Binary for Nodes<'_> {
    type Node = u32;

    #[inline]
    fn children(&self, node: u32) -> [Child<u32>; 2] {
        let node = &self.0[node as usize];
        [node.left, node.right].map(|c| if c & LEAF_BIT != 0 { Child::Leaf(c & !LEAF_BIT) } else { Child::Inner(c) })
    }

    fn wide_bound(&self, _: u32) -> usize {
        0
    }
}

/// The tree of the leaves' sorted, distinct keys, each inner node named by its range of leaves
/// (first and last).
struct Keys<'a>(&'a [u64]);

impl Binary for Keys<'_> {
    type Node = (u32, u32);

    #[inline]
    fn children(&self, (first, last): (u32, u32)) -> [Child<(u32, u32)>; 2] {
        let at = split(self.0, first as usize, last as usize) as u32;
        let child =
            |first: u32, last: u32| if first == last { Child::Leaf(first) } else { Child::Inner((first, last)) };
        [child(first, at), child(at + 1, last)]
    }

    /// From the range's length: no split is searched for a range of four leaves or more.
    #[inline]
    fn run(&self, (first, last): (u32, u32)) -> Option<(u32, u32)> {
        match last - first {
            1 => Some((first, 1)),
            2 if split(self.0, first as usize, last as usize) == first as usize => Some((first, 2)),
            2 => Some((first, 3)),
            _ => None,
        }
    }

    /// The subtree's binary inner nodes, one fewer than its leaves: a wide node stands for one.
    fn wide_bound(&self, (first, last): (u32, u32)) -> usize {
        (last - first) as usize
    }
}

/// Folding a binary tree whose leaf `k` has the box `leaf_box(k)`.
struct Fold<'a, B, F> {
    tree: &'a B,
    leaf_box: &'a F,
}

impl<B: Binary, F: Fn(u32) -> (Vec3, Vec3) + Sync> Fold<'_, B, F> {
    /// Pushes, in depth-first order, the binary nodes whose wide nodes lie `PART_DEPTH` wide
    /// levels under binary node `binary` (at wide level `level`): the roots of the parts.
    fn part_roots(&self, binary: B::Node, level: usize, roots: &mut Vec<B::Node>) {
        let (children, count) = wide_children(self.tree, binary);
        for child in &children[..count] {
            if let Child::Inner(child) = *child
                && self.tree.run(child).is_none()
            {
                if level + 1 == PART_DEPTH {
                    roots.push(child);
                } else {
                    self.part_roots(child, level + 1, roots);
                }
            }
        }
    }

    /// Folds the subtree under binary node `binary` (at wide level `level`) onto `out`, depth
    /// first: each node is placed before its children and written once their boxes are known,
    /// its references absolute in `out`. With `parts`, the subtrees `PART_DEPTH` wide levels
    /// down come from it, folded already, each with its root's box. Returns the subtree's box.
    fn fold(
        &self,
        binary: B::Node,
        level: usize,
        out: &mut Vec<WideNode>,
        parts: &mut Option<&mut dyn Iterator<Item = FoldedPart>>,
    ) -> (Vec3, Vec3) {
        let at = out.len();
        out.push(WideNode::EMPTY);
        let (children, count) = wide_children(self.tree, binary);
        let mut refs = [u32::MAX; 4];
        let mut boxes = [(Vec3::ZERO, Vec3::ZERO); 4];
        for lane in 0..count {
            let child = match children[lane] {
                Child::Leaf(k) => {
                    (refs[lane], boxes[lane]) = (LEAF_BIT | k, (self.leaf_box)(k));
                    continue;
                }
                Child::Inner(child) => match self.tree.run(child) {
                    Some((k, run)) => {
                        let count = RUNS[run as usize].0 as u32;
                        refs[lane] = LEAF_BIT | run << RUN_SHIFT | k;
                        boxes[lane] = (k + 1..k + count).fold((self.leaf_box)(k), |(lo, hi), leaf| {
                            let (l, h) = (self.leaf_box)(leaf);
                            (lo.min(l), hi.max(h))
                        });
                        continue;
                    }
                    None => child,
                },
            };
            refs[lane] = out.len() as u32;
            boxes[lane] = match parts.as_deref_mut() {
                Some(parts) if level + 1 == PART_DEPTH => {
                    let (part, part_box) = parts.next().expect("a part for every root");
                    append_part(out, part);
                    part_box
                }
                _ => self.fold(child, level + 1, out, parts),
            };
        }
        out[at] = WideNode::new(&refs[..count], &boxes[..count]);
        union(&boxes[..count])
    }
}

/// A subtree folded on its own, and its root's box.
type FoldedPart = (Vec<WideNode>, (Vec3, Vec3));

/// Appends a part folded on its own (its references counted from its first node) to `out`, its
/// references moved by where it begins.
fn append_part(out: &mut Vec<WideNode>, part: Vec<WideNode>) {
    let base = out.len() as u32;
    out.extend(part.into_iter().map(|mut node| {
        for c in node.child.iter_mut().filter(|c| **c != u32::MAX && **c & LEAF_BIT == 0) {
            *c += base;
        }
        node
    }));
}

/// The union of `boxes`.
fn union(boxes: &[(Vec3, Vec3)]) -> (Vec3, Vec3) {
    boxes.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), b| (lo.min(b.0), hi.max(b.1)))
}

/// The wide node's children for binary node `binary`, in the order a depth-first walk of the
/// binary tree ([`Lbvh::for_each_overlapping`]) meets them. That walk, at a node, meets its leaf
/// children at once (right, then left), then walks its left subtree, then its right one; so
/// the grandchildren under each inner child come as that child's leaves (right, then left) and
/// then its inner children (left, then right).
#[inline]
fn wide_children<B: Binary>(tree: &B, binary: B::Node) -> ([Child<B::Node>; 4], usize) {
    let [left, right] = tree.children(binary);
    let mut children = [Child::Leaf(u32::MAX); 4];
    let mut count = 0;
    let mut push = |child: Child<B::Node>| {
        children[count] = child;
        count += 1;
    };
    for child in [right, left] {
        if let Child::Leaf(_) = child {
            push(child);
        }
    }
    for child in [left, right] {
        if let Child::Inner(inner) = child {
            let [inner_left, inner_right] = tree.children(inner);
            for grandchild in [inner_right, inner_left] {
                if let Child::Leaf(_) = grandchild {
                    push(grandchild);
                }
            }
            for grandchild in [inner_left, inner_right] {
                if let Child::Inner(_) = grandchild {
                    push(grandchild);
                }
            }
        }
    }
    (children, count)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::lbvh::Sphere;

    /// Spheres at seeded centres in the unit cube, a share of them on a coarse lattice so that
    /// many Morton codes repeat.
    fn spheres(count: usize, seed: u32) -> Vec<Sphere> {
        let mut state = seed;
        let mut unit = move || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            (state >> 8) as f32 / (1u32 << 24) as f32
        };
        (0..count)
            .map(|k| {
                let c = Vec3::new(unit(), unit(), unit());
                let c = if k % 3 == 0 { (c * 4.0).floor() / 4.0 } else { c };
                Sphere::new(c, 0.01 + 0.02 * unit())
            })
            .collect()
    }

    /// The tree of the sorted keys, each node found from its range and [`split`], is the
    /// binary tree the LBVH builds node by node from one end of each range, and folds into the
    /// same wide tree: from no leaf to a tree folded in parallel, with repeated codes.
    #[test]
    fn the_keys_tree_is_the_lbvh_and_folds_the_same() {
        for (count, seed) in [(0, 1), (1, 2), (2, 3), (3, 4), (17, 5), (1000, 6), (40_000, 7)] {
            let spheres = spheres(count, seed);
            let (keys, order) = Lbvh::sorted_keys(&spheres);
            let (nodes, order_again) = Lbvh::build_topology(&spheres);
            assert_eq!(order, order_again, "{count} leaves");
            // Node `i` of the LBVH over leaves `first..=last`: its children are `split` and
            // `split + 1` (a leaf when its range is one leaf).
            let mut ranges = if count > 1 { vec![(0u32, 0, count - 1)] } else { Vec::new() };
            let mut inner = 0;
            while let Some((i, first, last)) = ranges.pop() {
                inner += 1;
                let at = split(&keys, first, last);
                let node = nodes[i as usize];
                let expect = |first: usize, last: usize, index: usize| {
                    if first == last { LEAF_BIT | index as u32 } else { index as u32 }
                };
                assert_eq!(node.left, expect(first, at, at), "{count} leaves, node {i}");
                assert_eq!(node.right, expect(at + 1, last, at + 1), "{count} leaves, node {i}");
                if first < at {
                    ranges.push((at as u32, first, at));
                }
                if at + 1 < last {
                    ranges.push((at as u32 + 1, at + 1, last));
                }
            }
            assert_eq!(inner, count.saturating_sub(1), "{count} leaves: every inner node once");
            let leaf_box = |k: u32| {
                let s = spheres[order[k as usize] as usize];
                (s.centre() - s.radius, s.centre() + s.radius)
            };
            let (from_keys, keys_box) = WideBvh::from_keys(&keys, leaf_box);
            let (from_nodes, nodes_box) = WideBvh::from_unfitted(&nodes, count, leaf_box);
            assert!(from_keys.nodes == from_nodes.nodes, "{count} leaves: another wide tree");
            assert_eq!(keys_box, nodes_box, "{count} leaves");
        }
    }
}
