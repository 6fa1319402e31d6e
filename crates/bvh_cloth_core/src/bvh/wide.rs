//! A four-wide copy of an [`Lbvh`] for queries on the CPU: each node holds the boxes of up to
//! four children side by side, one SIMD lane each, so a query tests four boxes at once and
//! descends two levels of the binary tree per node.
//!
//! The wide tree is the binary tree with every other level folded into its parent: a wide node
//! stands for a binary node, and its children are that node's grandchildren (or its children
//! where those are leaves). Its boxes are the binary tree's, and a leaf's is the box the tree
//! was fitted to (a triangle's own box for exact contact), each rounded outwards to 8 bits a
//! bound across its node ([`WideNode`]), so a node is one 64-byte cache line. A query finds what
//! a descent of the binary tree would have found, with half the dependent loads, and may meet a
//! few more leaves, whose rounded box reaches the query where their own does not.
//!
//! [`WideBvh::for_each_overlapping`] meets the leaves the binary walk
//! ([`Lbvh::for_each_overlapping`], the GPU's) meets in the same order, so a response that
//! depends on the order of its contacts is the same on both.

use glam::{BVec4A, Vec3, Vec4};
use rayon::prelude::*;

use crate::bvh::lbvh::{LEAF_BIT, Lbvh};
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
    /// `LEAF_BIT | leaf` or a wide node's index, in the order a depth-first walk of the binary
    /// tree meets them; the used lanes come first, and an unused lane holds `u32::MAX`.
    pub child: [u32; 4],
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
        for axis in 0..3 {
            let origin = lo[axis];
            // The least step whose 255th reaches the top.
            let mut step = ((hi[axis] - origin) / 255.0).max(0.0);
            while step.is_finite() && origin + 255.0 * step < hi[axis] {
                step = step.next_up();
            }
            node.origin[axis] = origin;
            node.step[axis] = step;
            // The same arithmetic as `bound`, one lane at a time.
            let at = |q: u32| origin + q as f32 * step;
            let inverse = if step > 0.0 { 1.0 / step } else { 0.0 };
            // A first guess (truncation is the floor of a non-negative number), then rounded
            // outwards exactly: down for the minimum, up for the maximum.
            let guess = |x: f32| (((x - origin) * inverse).max(0.0) as u32).min(255);
            for (lane, &(l, h)) in boxes.iter().enumerate() {
                let mut q = guess(l[axis]);
                while q > 0 && at(q) > l[axis] {
                    q -= 1;
                }
                node.lo[axis][lane] = q as u8;
                let mut q = guess(h[axis]);
                while q < 255 && at(q) < h[axis] {
                    q += 1;
                }
                node.hi[axis][lane] = q as u8;
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
}

/// The traversal stack. The binary tree has fewer than [`STACK_SIZE`] levels, so the wide one
/// has at most half as many; a walk holds at most three entries for each level above the node
/// it pops and the four that node pushes, well within this.
const WIDE_STACK: usize = 2 * STACK_SIZE + 4;

impl WideBvh {
    /// Folds `tree` into a wide tree. `leaf_box(k)` is leaf `k`'s box, the one `tree`'s inner
    /// boxes were fitted to. A large tree's subtrees under the root are folded in parallel.
    pub fn from_lbvh(tree: &Lbvh, leaf_box: impl Fn(u32) -> (Vec3, Vec3) + Sync) -> Self {
        if tree.nodes.is_empty() {
            if tree.spheres.is_empty() {
                return Self::default();
            }
            return Self { nodes: vec![WideNode::new(&[LEAF_BIT], &[leaf_box(0)])] };
        }
        let fold = Fold { tree, leaf_box: &leaf_box };
        if tree.nodes.len() < PARALLEL_FOLD_MIN_NODES {
            let mut nodes = vec![WideNode::EMPTY; fold.count(0)];
            fold.fill(0, &mut nodes, 0);
            return Self { nodes };
        }
        // The root, then each of its inner children's subtrees in turn, each folded on its own
        // into its own slice of the nodes.
        let (children, count) = wide_children(tree, 0);
        let inner: Vec<(usize, u32)> =
            children[..count].iter().enumerate().filter(|&(_, &c)| c & LEAF_BIT == 0).map(|(l, &c)| (l, c)).collect();
        let sizes: Vec<usize> = inner.par_iter().map(|&(_, c)| fold.count(c)).collect();
        let total = 1 + sizes.iter().sum::<usize>();
        let mut nodes: Vec<WideNode> = (0..total).into_par_iter().map(|_| WideNode::EMPTY).collect();
        let (root, mut rest) = nodes.split_at_mut(1);
        fold.node(0, &mut root[0]);
        let mut parts = Vec::with_capacity(inner.len());
        let mut base = 1;
        for (&(lane, child), &size) in inner.iter().zip(&sizes) {
            root[0].child[lane] = base as u32;
            let (part, after) = std::mem::take(&mut rest).split_at_mut(size);
            parts.push((child, part, base as u32));
            rest = after;
            base += size;
        }
        parts.into_par_iter().for_each(|(child, part, base)| fold.fill(child, part, base));
        Self { nodes }
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
                visit(entry & !LEAF_BIT);
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

    /// A nearest-first search: `leaf(k, best)` is called for every leaf whose box lies closer
    /// to `p` than `best`, the squared distance found so far (`limit` at first), and returns the
    /// new `best` (its own squared distance to `p` when nearer). Returns the last `best`, which
    /// is `limit` for a point with a NaN or a `limit` that is not positive.
    #[inline]
    pub fn nearest(&self, p: Vec3, limit: f32, mut leaf: impl FnMut(u32, f32) -> f32) -> f32 {
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
            let distances = node.distances_squared(p).to_array();
            // The leaves at once; the inner children sorted farthest first, so that the
            // nearest is popped first.
            let mut inner = [(0u32, 0.0f32); 4];
            let mut inner_count = 0;
            for (&child, &d2) in node.child.iter().zip(&distances) {
                if d2 >= best {
                    continue;
                }
                if child & LEAF_BIT != 0 {
                    best = leaf(child & !LEAF_BIT, best);
                } else {
                    let mut slot = inner_count;
                    while slot > 0 && inner[slot - 1].1 < d2 {
                        inner[slot] = inner[slot - 1];
                        slot -= 1;
                    }
                    inner[slot] = (child, d2);
                    inner_count += 1;
                }
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

/// Below this many binary nodes a tree is folded on one thread.
const PARALLEL_FOLD_MIN_NODES: usize = 16_384;

/// Folding a binary tree whose leaf `k` has the box `leaf_box(k)`.
struct Fold<'a, F> {
    tree: &'a Lbvh,
    leaf_box: &'a F,
}

impl<F: Fn(u32) -> (Vec3, Vec3) + Sync> Fold<'_, F> {
    /// The number of wide nodes under (and with) binary node `binary`, a wide node's.
    fn count(&self, binary: u32) -> usize {
        let mut count = 0;
        let mut stack = Vec::with_capacity(WIDE_STACK);
        stack.push(binary);
        while let Some(binary) = stack.pop() {
            count += 1;
            let (children, n) = wide_children(self.tree, binary);
            stack.extend(children[..n].iter().filter(|&&c| c & LEAF_BIT == 0));
        }
        count
    }

    /// Writes the wide node of binary node `binary` into `node`, its inner children's
    /// references still binary.
    fn node(&self, binary: u32, node: &mut WideNode) {
        let (children, count) = wide_children(self.tree, binary);
        let boxes: [(Vec3, Vec3); 4] = std::array::from_fn(|lane| match children[lane] {
            _ if lane >= count => (Vec3::ZERO, Vec3::ZERO),
            child if child & LEAF_BIT != 0 => (self.leaf_box)(child & !LEAF_BIT),
            child => {
                let n = &self.tree.nodes[child as usize];
                (Vec3::from(n.aabb_min), Vec3::from(n.aabb_max))
            }
        });
        *node = WideNode::new(&children[..count], &boxes[..count]);
    }

    /// Folds the subtree under binary node `binary` into `out` (exactly its size), depth first,
    /// `out[0]` being wide node `base`.
    fn fill(&self, binary: u32, out: &mut [WideNode], base: u32) {
        let mut next = 0;
        // Binary nodes still to fold, each with the wide node and lane that will point to it.
        let mut stack: Vec<(u32, Option<(usize, usize)>)> = Vec::with_capacity(WIDE_STACK);
        stack.push((binary, None));
        while let Some((binary, parent)) = stack.pop() {
            let at = next;
            next += 1;
            if let Some((parent, lane)) = parent {
                out[parent].child[lane] = base + at as u32;
            }
            let node = &mut out[at];
            self.node(binary, node);
            // The first inner child is popped first.
            for (lane, &child) in node.child.iter().enumerate().rev() {
                if child != u32::MAX && child & LEAF_BIT == 0 {
                    stack.push((child, Some((at, lane))));
                }
            }
        }
        debug_assert_eq!(next, out.len());
    }
}

/// The wide node's children for binary node `binary`, in the order a depth-first walk of the
/// binary tree ([`Lbvh::for_each_overlapping`]) meets them. That walk, at a node, meets its leaf
/// children at once (right, then left), then walks its left subtree, then its right one; so
/// the grandchildren under each inner child come as that child's leaves (right, then left) and
/// then its inner children (left, then right).
fn wide_children(tree: &Lbvh, binary: u32) -> ([u32; 4], usize) {
    let node = &tree.nodes[binary as usize];
    let mut children = [u32::MAX; 4];
    let mut count = 0;
    let mut push = |child: u32| {
        children[count] = child;
        count += 1;
    };
    for child in [node.right, node.left] {
        if child & LEAF_BIT != 0 {
            push(child);
        }
    }
    for child in [node.left, node.right] {
        if child & LEAF_BIT == 0 {
            let inner = &tree.nodes[child as usize];
            for grandchild in [inner.right, inner.left] {
                if grandchild & LEAF_BIT != 0 {
                    push(grandchild);
                }
            }
            for grandchild in [inner.left, inner.right] {
                if grandchild & LEAF_BIT == 0 {
                    push(grandchild);
                }
            }
        }
    }
    (children, count)
}
