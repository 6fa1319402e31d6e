//! The pairs of triangles that may touch: each body's triangles in a binary tree built once
//! from its rest shape, its boxes, extents along the diagonals and normal cones refitted each
//! substep, and walked for the pairs of triangles whose bounds over the substep meet and that
//! no line between them separates, skipping every part of a body that is flat enough not to
//! touch itself. See the [module docs](super).

use glam::{Vec3, Vec3A};
use rayon::prelude::*;

use crate::cloth::topology::ClothTopology;
use crate::mesh::triangles::share_a_corner;

/// Most node pairs the walk tests, per triangle of the bodies: a walk that reaches it stops
/// (everything at one point would otherwise cost the square of the triangle count).
pub const MAX_TESTS_PER_TRIANGLE: usize = 256;

/// The least cosine between every normal of a part of a cloth (at the substep's start and
/// end) and one direction for the part to be taken as flat, and skipped by self-contact's
/// search on the CPU: 45°. See the [module docs](super).
pub const FLAT_COS: f32 = core::f32::consts::FRAC_1_SQRT_2;

/// The walk's first steps make node pairs of at most this share of the triangles for the
/// threads to share.
const TASKS: usize = 256;

/// Most triangles in a leaf of the tree: a pair of leaves tests the boxes of their triangles
/// against each other rather than walk a level further. (With four, fewer node pairs are
/// walked, but the pairs within a leaf are not skipped for halves of it that lie flat
/// together: more pairs of the sheet's own neighbours, and the fold onto the bunny at 7 m/s of
/// the core's `fast_folds_keep_off_themselves` ended with 7 pairs of its triangles
/// intersecting.)
const LEAF_SIZE: usize = 2;

/// A thread's part of the walk: the pairs of triangles its tasks found, in order, its stack,
/// and the node pairs it left unwalked.
type Walked = (Vec<(u32, u32)>, Vec<(u32, u32)>, usize);

/// Fewest nodes in a subtree whose two subtrees the refit hands to the rayon pool side by
/// side; a smaller one is refitted on its own thread from its leaves up.
const SUBTREE_MIN: usize = 2048;

/// A box that meets nothing.
const EMPTY: [Vec3A; 2] = [Vec3A::INFINITY, Vec3A::NEG_INFINITY];

/// Where something lies along the six diagonals of the axes: the least and the greatest of the
/// sums `x + y`, `x + z`, `y + z`, then of the differences `x - y`, `x - z`, `y - z`. With a box,
/// it bounds what it holds by 18 planes (a k-DOP: Klosowski et al. 1998, "Efficient collision
/// detection using bounding volume hierarchies of k-DOPs"), which follow a crumpled cloth's
/// parts, askew to the axes, more closely than the box alone.
type Span = [Vec3A; 4];

/// A cone of directions: every direction it holds lies within the angle whose cosine and sine
/// are `cos` and `sin` of `axis` (a unit vector). A cone of every direction has a `cos` of -1.
#[derive(Clone, Copy, Debug)]
struct Cone {
    axis: Vec3A,
    cos: f32,
    sin: f32,
}

impl Cone {
    /// Every direction.
    const WIDE: Self = Self { axis: Vec3A::Z, cos: -1.0, sin: 0.0 };

    /// The cone of the unit `normals` about their mean direction, exactly; [`Self::WIDE`] when
    /// one is 0 (a triangle without area), or when it is wider than 45° ([`Self::about`]).
    #[inline]
    fn of(normals: &[Vec3A]) -> Self {
        let mut sum = Vec3A::ZERO;
        for &n in normals {
            if n == Vec3A::ZERO {
                return Self::WIDE;
            }
            sum += n;
        }
        let axis = sum.normalize_or_zero();
        let cos = normals.iter().fold(1.0f32, |least, n| least.min(n.dot(axis)));
        Self::about(axis, cos)
    }

    /// The cone about `axis` of half-angle `acos(cos)`: [`Self::WIDE`] when wider than 45°
    /// ([`FLAT_COS`]; NaN too). The walk skips parts within 45° alone, and a join only widens,
    /// so a wider cone is of no use above it: taken as every direction, the joins above it cost
    /// nothing.
    #[inline]
    fn about(axis: Vec3A, cos: f32) -> Self {
        if cos >= FLAT_COS && axis != Vec3A::ZERO {
            Self { axis, cos: cos.min(1.0), sin: (1.0 - cos * cos).max(0.0).sqrt() }
        } else {
            Self::WIDE
        }
    }

    /// A cone holding both cones, about the direction halfway between their axes: each
    /// cone's angle grown by the angle between its axis and that direction.
    #[inline]
    fn join(self, other: Self) -> Self {
        if self.cos < FLAT_COS || other.cos < FLAT_COS {
            return Self::WIDE;
        }
        let axis = (self.axis + other.axis).normalize_or_zero();
        // cos(a + b) = cos a cos b - sin a sin b, for each cone grown to the new axis (the sine
        // of the axes' angle from their cross product: from the cosine, it is lost to rounding
        // where the axes nearly agree).
        let grown = |c: Self| c.cos * c.axis.dot(axis) - c.sin * c.axis.cross(axis).length();
        Self::about(axis, grown(self).min(grown(other)))
    }

    /// Whether the directions of both cones lie within 45° of one direction ([`FLAT_COS`]): the
    /// least cone holding both, of half the angle spanned by their axes' angle and both cones'
    /// angles, is no wider than that. (Its half-angle `(a + b + φ) / 2` is at most 45° when
    /// `cos φ >= sin(a + b)`, both cones being within 45° themselves.)
    #[inline(always)]
    fn flat_with(self, other: Self) -> bool {
        self.cos >= FLAT_COS
            && other.cos >= FLAT_COS
            && self.axis.dot(other.axis) >= self.sin * other.cos + self.cos * other.sin
    }
}

/// A node's bounds over the substep: its box, grown by half the largest thickness (two boxes
/// meet where their triangles come within the thickness), its span, grown likewise (by the
/// diagonals' length times as much), and a cone holding its triangles' normals at the
/// substep's start and end. Kept together, a node's bounds fill two cache lines.
#[derive(Clone, Copy, Debug)]
#[repr(align(64))]
struct Fit {
    bounds: [Vec3A; 2],
    span: Span,
    cone: Cone,
}

impl Fit {
    /// Bounds that meet nothing, of every direction.
    const EMPTY: Self = Self { bounds: EMPTY, span: NO_SPAN, cone: Cone::WIDE };

    /// The bounds of a node whose children's bounds are `self` and `other`.
    #[inline]
    fn join(&self, other: &Self) -> Self {
        Self {
            bounds: [self.bounds[0].min(other.bounds[0]), self.bounds[1].max(other.bounds[1])],
            span: join_spans(self.span, other.span),
            cone: self.cone.join(other.cone),
        }
    }

    /// Whether the boxes and spans of `self` and `other` meet.
    #[inline(always)]
    fn meets(&self, other: &Self) -> bool {
        let ([a_lo, a_hi], [b_lo, b_hi]) = (self.bounds, other.bounds);
        a_lo.cmple(b_hi).all() && a_hi.cmpge(b_lo).all() && spans_meet(&self.span, &other.span)
    }
}

/// A span that meets nothing.
const NO_SPAN: Span = [Vec3A::INFINITY, Vec3A::NEG_INFINITY, Vec3A::INFINITY, Vec3A::NEG_INFINITY];

/// No child: the node is a leaf.
const LEAF: u32 = u32::MAX;

/// A node of the tree, in depth-first order: a leaf, or an inner node whose left child is the
/// next node and whose right child is `right`. Its triangles lie together in
/// [`SurfaceTree::order`].
#[derive(Clone, Copy, Debug)]
struct Node {
    /// The right child, or [`LEAF`].
    right: u32,
    /// Where its triangles start in [`SurfaceTree::order`], and how many it holds.
    start: u32,
    count: u32,
    /// The node's body.
    body: u32,
    /// Its particles that also belong to triangles outside it (local to its body, in
    /// increasing order): where it and a node beside it share a corner. Start and length in
    /// [`SurfaceTree::border`].
    border: (u32, u32),
    /// Whether the node's triangles are joined to each other through shared corners: only
    /// such a part is skipped for being flat.
    connected: bool,
}

/// The tree of every body's triangles, and what each triangle stands for in the pairs.
#[derive(Clone, Debug, Default)]
pub(super) struct SurfaceTree {
    /// Each primitive's box in the rest shape: every body's triangles, then every body's edges
    /// (primitive `triangles + e` is edge `e`), in their flat order.
    pub(super) rest_boxes: Vec<[Vec3A; 2]>,
    nodes: Vec<Node>,
    /// The nodes' border particles.
    border: Vec<u32>,
    /// Each node's box of its triangles in the rest shape: two nodes whose boxes there lie
    /// apart share no corner.
    rests: Vec<[Vec3A; 2]>,
    /// Each body's root ([`LEAF`] for a body without triangles).
    roots: Vec<u32>,
    /// Each node's bounds over the substep, side by side for the walk.
    fits: Vec<Fit>,
    /// What the boxes were grown by.
    grow: f32,
    /// Every body's triangles (their indices among every body's), leaf after leaf in the
    /// nodes' order, and where each triangle lies in it.
    order: Vec<u32>,
    slot: Vec<u32>,
    /// The corners of the triangle at each place of `order` (flat indices) and its box over
    /// the substep, grown like the nodes'.
    corners: Vec<[u32; 3]>,
    triangle_boxes: Vec<[Vec3A; 2]>,
    /// The span over the substep of each particle (flat indices), grown like the nodes': the
    /// leaves' spans are joined from their corners'.
    particle_spans: Vec<Span>,
    /// The corners now of the triangle at each place of `order`, and the farthest any of them
    /// moved over the substep.
    now: Vec<([Vec3; 3], f32)>,
    /// The unit normal of the triangle at each place of `order` at the substep's start and
    /// end (0 for a triangle without area then): the point–triangle tests take them rather
    /// than work them out per pair.
    pub(super) faces: Vec<[Vec3; 2]>,
    /// The particles (flat indices) and the edges (indices among every body's edges) the
    /// triangle at each place of `order` stands for in a pair, each particle and edge by
    /// exactly one of its triangles; `u32::MAX` for none.
    pub(super) points: Vec<[u32; 3]>,
    pub(super) edges: Vec<[u32; 3]>,
    /// Each particle's box over the substep (flat indices; empty for one that is not finite):
    /// what the edges' boxes are joined from ([`Self::edge_box`]).
    paths: Vec<[Vec3A; 2]>,
}

impl SurfaceTree {
    /// Builds the tree of the bodies' triangles (`topologies`, in body order; their triangles
    /// come first to last in the flat triangle order, and their particles and edges likewise).
    pub(super) fn build(&mut self, topologies: &[&ClothTopology]) {
        self.rest_boxes.clear();
        for topology in topologies {
            let rest = topology.rest_positions();
            self.rest_boxes.extend(topology.triangles().iter().map(|t| {
                let [a, b, c] = t.map(|k| rest[k as usize]);
                [a.min(b).min(c).into(), a.max(b).max(c).into()]
            }));
        }
        for topology in topologies {
            let rest = topology.rest_positions();
            self.rest_boxes.extend(topology.edges().iter().map(|&[p, q]| {
                let (a, b) = (rest[p as usize], rest[q as usize]);
                [a.min(b).into(), a.max(b).into()]
            }));
        }
        self.nodes.clear();
        self.border.clear();
        self.rests.clear();
        self.roots.clear();
        self.points.clear();
        self.edges.clear();
        self.order.clear();
        let (mut first_triangle, mut first_particle, mut first_edge) = (0u32, 0u32, 0u32);
        let mut corners = Vec::new();
        for (body, topology) in topologies.iter().enumerate() {
            let triangles = topology.triangles();
            corners.extend(triangles.iter().map(|t| t.map(|k| first_particle + k)));
            if triangles.is_empty() {
                self.roots.push(LEAF);
            } else {
                self.roots.push(self.nodes.len() as u32);
                let lists = (&mut self.nodes, &mut self.rests, &mut self.border, &mut self.order);
                build(topology, body as u32, first_triangle, lists);
            }
            let start = self.points.len();
            self.points.resize(start + triangles.len(), [u32::MAX; 3]);
            self.edges.resize(start + triangles.len(), [u32::MAX; 3]);
            // Each particle with its first triangle, each edge with the first triangle of its
            // first end that holds its other end.
            let (offsets, list) = (topology.triangle_offsets(), topology.triangle_list());
            for k in 0..topology.len() {
                if let Some(&t) = list.get(offsets[k] as usize..offsets[k + 1] as usize).and_then(|l| l.first()) {
                    let slot = &mut self.points[start + t as usize];
                    slot[slot.iter().position(|&s| s == u32::MAX).expect("three corners")] = first_particle + k as u32;
                }
            }
            for (e, &[p, q]) in topology.edges().iter().enumerate() {
                let of_p = &list[offsets[p as usize] as usize..offsets[p as usize + 1] as usize];
                if let Some(&t) = of_p.iter().find(|&&t| triangles[t as usize].contains(&q)) {
                    let slot = &mut self.edges[start + t as usize];
                    slot[slot.iter().position(|&s| s == u32::MAX).expect("three edges")] = first_edge + e as u32;
                }
            }
            first_triangle += triangles.len() as u32;
            first_particle += topology.len() as u32;
            first_edge += topology.edges().len() as u32;
        }
        self.slot.clear();
        self.slot.resize(self.order.len(), 0);
        for (at, &t) in self.order.iter().enumerate() {
            self.slot[t as usize] = at as u32;
        }
        // Found by triangle above; kept by place, so that a pair's tests read them side by side.
        self.corners = self.order.iter().map(|&t| corners[t as usize]).collect();
        self.points = self.order.iter().map(|&t| self.points[t as usize]).collect();
        self.edges = self.order.iter().map(|&t| self.edges[t as usize]).collect();
    }

    /// Each particle's span, each triangle's box and each node's box and span over the substep
    /// (from the particles at the substep's start, `prev`, and end, `x`), grown by `grow` (the
    /// spans by `grow` times the diagonals' length, `√2`), and a cone holding a node's
    /// triangles' normals then and now; a leaf's span is joined from its corners'. A triangle
    /// with a corner that is not finite has an empty box (it meets nothing); one without area
    /// makes its node's cone hold every direction (never flat). The particles and the triangles
    /// are taken in parallel, then the nodes from the leaves up, the subtrees side by side
    /// ([`Self::fit_nodes`]). A triangle whose corners start the substep where the last refit
    /// left them keeps the normal it had then.
    pub(super) fn refit(&mut self, prev: &[Vec3], x: &[Vec3], grow: f32) {
        self.grow = grow;
        let places = self.order.len();
        let parallel = places >= super::PARALLEL_MIN;
        // Grown here, once a particle: a span joined from grown ones is the same as one grown
        // after the join (the rounding keeps the order).
        let span = |(&a, &b): (&Vec3, &Vec3)| widen_span(path_span(a, b), grow);
        self.particle_spans.clear();
        if parallel {
            self.particle_spans.par_extend(prev.par_iter().zip(x).map(span));
        } else {
            self.particle_spans.extend(prev.iter().zip(x).map(span));
        }
        self.triangle_boxes.resize(places, [Vec3A::ZERO; 2]);
        self.now.resize(places, ([Vec3::ZERO; 3], 0.0));
        self.faces.resize(places, [Vec3::ZERO; 2]);
        let fit = |corners: &[u32; 3], own: &mut [Vec3A; 2], now: &mut ([Vec3; 3], f32), faces: &mut [Vec3; 2]| {
            let last = (now.0, faces[1]);
            (*own, *now, *faces) = fit_triangle(*corners, prev, x, grow, last);
        };
        let (boxes, now, faces) = (&mut self.triangle_boxes, &mut self.now, &mut self.faces);
        if parallel {
            let each = boxes.par_iter_mut().zip(now.par_iter_mut()).zip(faces.par_iter_mut());
            self.corners.par_iter().zip(each).for_each(|(corners, ((own, now), faces))| fit(corners, own, now, faces));
        } else {
            let each = boxes.iter_mut().zip(now.iter_mut()).zip(faces.iter_mut());
            self.corners.iter().zip(each).for_each(|(corners, ((own, now), faces))| fit(corners, own, now, faces));
        }
        let mut fits = core::mem::take(&mut self.fits);
        fits.resize(self.nodes.len(), Fit::EMPTY);
        let mut rest = &mut fits[..];
        // Each body's nodes follow its root, up to the next body's root.
        for &root in self.roots.iter().filter(|&&r| r != LEAF) {
            let next = self.roots.iter().copied().filter(|&r| r != LEAF && r > root).min();
            let len = next.unwrap_or(self.nodes.len() as u32) - root;
            let (body, after) = core::mem::take(&mut rest).split_at_mut(len as usize);
            self.fit_nodes(body, root as usize);
            rest = after;
        }
        self.fits = fits;
    }

    /// The bounds of the subtree whose root is node `root`, written to `fits` (its nodes,
    /// `root` first): its two subtrees side by side on the rayon pool while they are large,
    /// then each from its leaves up.
    fn fit_nodes(&self, fits: &mut [Fit], root: usize) {
        if fits.len() < SUBTREE_MIN {
            for k in (0..fits.len()).rev() {
                let node = self.nodes[root + k];
                fits[k] = if node.right == LEAF {
                    self.fit_leaf(node)
                } else {
                    fits[k + 1].join(&fits[node.right as usize - root])
                };
            }
            return;
        }
        let node = self.nodes[root];
        let (own, below) = fits.split_first_mut().expect("a subtree holds its root");
        let (left, right) = below.split_at_mut(node.right as usize - root - 1);
        rayon::join(|| self.fit_nodes(left, root + 1), || self.fit_nodes(right, node.right as usize));
        *own = left[0].join(&right[0]);
    }

    /// The bounds of the leaf `node`: its triangles' boxes and spans, and the cone of their
    /// normals.
    #[inline]
    fn fit_leaf(&self, node: Node) -> Fit {
        let (mut bounds, mut span) = (EMPTY, NO_SPAN);
        let mut normals = [Vec3A::ZERO; 2 * LEAF_SIZE];
        let range = node.start as usize..(node.start + node.count) as usize;
        for (k, at) in range.clone().enumerate() {
            let own = self.triangle_boxes[at];
            bounds = [bounds[0].min(own[0]), bounds[1].max(own[1])];
            for corner in self.corners[at] {
                span = join_spans(span, self.particle_spans[corner as usize]);
            }
            let [then, now] = self.faces[at];
            normals[2 * k..2 * k + 2].copy_from_slice(&[then.into(), now.into()]);
        }
        Fit { bounds, span, cone: Cone::of(&normals[..2 * range.len()]) }
    }

    /// Each particle's box over the substep, from its position at the substep's start, `prev`,
    /// and now, `x`, in parallel: what [`Self::edge_box`] joins.
    pub(super) fn sweep_particles(&mut self, prev: &[Vec3], x: &[Vec3]) {
        let path = |(&a, &b): (&Vec3, &Vec3)| {
            if a.is_finite() && b.is_finite() { [a.min(b).into(), a.max(b).into()] } else { EMPTY }
        };
        self.paths.clear();
        if x.len() >= super::PARALLEL_MIN {
            self.paths.par_extend(prev.par_iter().zip(x).map(path));
        } else {
            self.paths.extend(prev.iter().zip(x).map(path));
        }
    }

    /// The box over the substep of the edge whose ends are the particles `ends` (flat indices),
    /// not grown: its ends' boxes joined ([`Self::sweep_particles`]).
    #[inline]
    pub(super) fn edge_box(&self, [p, q]: [u32; 2]) -> [Vec3A; 2] {
        let ([p_lo, p_hi], [q_lo, q_hi]) = (self.paths[p as usize], self.paths[q as usize]);
        [p_lo.min(q_lo), p_hi.max(q_hi)]
    }

    /// Where triangle `t` lies in the tree's order: the place its tests' data are kept at.
    #[inline]
    pub(super) fn place(&self, t: u32) -> usize {
        self.slot[t as usize] as usize
    }

    /// The triangle at place `at` of the tree's order.
    #[inline]
    pub(super) fn triangle_at(&self, at: usize) -> u32 {
        self.order[at]
    }

    /// How far the boxes were grown: half the largest thickness.
    #[inline]
    pub(super) fn grow(&self) -> f32 {
        self.grow
    }

    /// The box over the substep of the triangle at place `at`, grown by the largest thickness:
    /// what a point's path meets where it comes within the thickness of the triangle.
    #[inline]
    pub(super) fn reach_box(&self, at: usize) -> [Vec3A; 2] {
        let [lo, hi] = self.triangle_boxes[at];
        [lo - self.grow, hi + self.grow]
    }

    /// Every pair of triangles (indices among every body's triangles) that may touch over the
    /// substep ([`Self::meet`]), each pair once, in an order that depends on the positions
    /// alone, whatever the threads: within each body, less those in a part of it that is flat
    /// within 45° ([`FLAT_COS`]); and between every two bodies for which `meet(a, b)` holds.
    /// Writes them to `pairs`; returns how many node pairs were left unwalked when the walk
    /// reached its bound ([`MAX_TESTS_PER_TRIANGLE`] tests a triangle), 0 when none.
    ///
    /// The walk's first steps make node pairs of at most a [`TASKS`]th of the triangles, which
    /// are walked on the rayon pool, each with a share of the bound by its count of triangles,
    /// and their pairs joined in order: the order of one walk of the whole.
    pub(super) fn pairs(&self, meet: impl Fn(usize, usize) -> bool, pairs: &mut Vec<(u32, u32)>) -> usize {
        pairs.clear();
        // A task (a, a) is a node against itself; (a, b) two nodes.
        let mut tasks: Vec<(u32, u32)> = Vec::new();
        for (body, &root) in self.roots.iter().enumerate().filter(|(_, r)| **r != LEAF) {
            tasks.push((root, root));
            for (other_body, &other) in self.roots.iter().enumerate().skip(body + 1) {
                if other != LEAF && meet(body, other_body) {
                    tasks.push((root, other));
                }
            }
        }
        tasks.retain(|&task| !self.apart(task));
        let triangles = self.points.len();
        let size = |(a, b): (u32, u32)| self.size(a) + if a == b { 0 } else { self.size(b) };
        if triangles >= super::PARALLEL_MIN {
            // Depth first, as the walk goes, down to node pairs of at most a `TASKS`th of the
            // triangles: walked one after the other, they give the pairs in the order of one
            // walk of the whole.
            // A pair of leaves is no larger than the limit: only inner nodes are stepped here,
            // and they find no pairs of triangles.
            let limit = (triangles / TASKS).max(2 * LEAF_SIZE);
            let mut stack: Vec<(u32, u32)> = tasks.drain(..).rev().collect();
            while let Some(task) = stack.pop() {
                if size(task) <= limit {
                    tasks.push(task);
                } else {
                    self.step(
                        task,
                        &mut |child| {
                            if !self.apart(child) {
                                stack.push(child)
                            }
                        },
                        pairs,
                    );
                }
            }
        }
        let total: usize = tasks.iter().map(|&t| size(t)).sum();
        let bound = MAX_TESTS_PER_TRIANGLE * triangles;
        let budget = |task| (bound as u128 * size(task) as u128 / total.max(1) as u128) as usize;
        // Each thread's tasks in order, into one list of pairs and with one stack.
        let walk = |(mut found, mut stack, left): Walked, &task: &(u32, u32)| {
            let untested = self.walk(task, budget(task), &mut stack, &mut found);
            (found, stack, left + untested)
        };
        let walked: Vec<Walked> = if tasks.len() > 1 {
            tasks.par_iter().fold(Walked::default, walk).collect()
        } else {
            vec![tasks.iter().fold(Walked::default(), walk)]
        };
        let mut left = 0;
        for (found, _, untested) in walked {
            pairs.extend(found);
            left += untested;
        }
        left
    }

    /// The pairs of triangles under the node pair `task` (one that meets), depth first, added
    /// to `pairs`, with at most `budget` node pairs tested; returns how many were left
    /// unwalked when it ran out. `stack` is scratch.
    fn walk(
        &self,
        task: (u32, u32),
        mut budget: usize,
        stack: &mut Vec<(u32, u32)>,
        pairs: &mut Vec<(u32, u32)>,
    ) -> usize {
        stack.clear();
        stack.push(task);
        let mut untested = 0;
        while let Some(task) = stack.pop() {
            self.step(
                task,
                &mut |child| {
                    if budget == 0 {
                        untested += 1;
                    } else {
                        budget -= 1;
                        if !self.apart(child) {
                            stack.push(child);
                        }
                    }
                },
                pairs,
            );
            // The bound is spent: the walk stops, and the pairs it stacked are left too.
            if untested > 0 {
                return untested + stack.len();
            }
        }
        0
    }

    /// Whether the node pair `(a, b)` (a node against itself when `a == b`) holds no pair of
    /// triangles that may touch: a node that is a flat part, or two nodes whose boxes or spans
    /// lie apart or that are flat together.
    #[inline(always)]
    fn apart(&self, (a, b): (u32, u32)) -> bool {
        let (na, nb) = (self.nodes[a as usize], self.nodes[b as usize]);
        let (fa, fb) = (&self.fits[a as usize], &self.fits[b as usize]);
        if a == b {
            return na.connected && fa.cone.cos >= FLAT_COS;
        }
        !fa.meets(fb) || self.flat_together(na, nb, fa, fb, a, b)
    }

    /// One step of the walk at the node pair `(a, b)` (a node against itself when `a == b`),
    /// one not [`Self::apart`]: the pairs of their triangles that may touch added to `pairs`
    /// when both are leaves ([`Self::meet`]), or the node pairs to walk instead handed to
    /// `split`.
    #[inline]
    fn step(&self, (a, b): (u32, u32), split: &mut impl FnMut((u32, u32)), pairs: &mut Vec<(u32, u32)>) {
        let (na, nb) = (self.nodes[a as usize], self.nodes[b as usize]);
        if a == b {
            if na.right == LEAF {
                let range = na.start as usize..(na.start + na.count) as usize;
                for i in range.clone() {
                    for j in i + 1..range.end {
                        self.meet(i, j, pairs);
                    }
                }
            } else {
                let (l, r) = (a + 1, na.right);
                [(l, r), (r, r), (l, l)].into_iter().for_each(split);
            }
            return;
        }
        let (a_leaf, b_leaf) = (na.right == LEAF, nb.right == LEAF);
        if a_leaf && b_leaf {
            let [b_lo, b_hi] = self.fits[b as usize].bounds;
            for i in na.start as usize..(na.start + na.count) as usize {
                let [lo, hi] = self.triangle_boxes[i];
                if lo.cmple(b_hi).all() && hi.cmpge(b_lo).all() {
                    for j in nb.start as usize..(nb.start + nb.count) as usize {
                        self.meet(i, j, pairs);
                    }
                }
            }
            return;
        }
        // The larger node is split; both when they are of about one size.
        if a_leaf || (!b_leaf && nb.count > 2 * na.count) {
            [(a, nb.right), (a, b + 1)].into_iter().for_each(split);
        } else if b_leaf || na.count > 2 * nb.count {
            [(na.right, b), (a + 1, b)].into_iter().for_each(split);
        } else {
            let (al, ar, bl, br) = (a + 1, na.right, b + 1, nb.right);
            [(ar, br), (ar, bl), (al, br), (al, bl)].into_iter().for_each(split);
        }
    }

    /// Adds the triangles at places `i` and `j` of [`Self::order`] to `pairs` if they may
    /// touch: their boxes meet, and they neither share a corner and lie flat together nor are
    /// [`Self::separated`].
    #[inline(always)]
    fn meet(&self, i: usize, j: usize, pairs: &mut Vec<(u32, u32)>) {
        let ([a_lo, a_hi], [b_lo, b_hi]) = (self.triangle_boxes[i], self.triangle_boxes[j]);
        if !(a_lo.cmple(b_hi).all() && a_hi.cmpge(b_lo).all()) {
            return;
        }
        // A shared corner (flat indices: of one body) leaves them no gap along any line.
        if share_a_corner(self.corners[i], self.corners[j]) {
            let ([a0, a1], [b0, b1]) = (self.faces[i].map(Vec3A::from), self.faces[j].map(Vec3A::from));
            if Cone::of(&[a0, a1, b0, b1]).cos >= FLAT_COS {
                return;
            }
        } else if self.separated(i, j) {
            return;
        }
        pairs.push((self.order[i], self.order[j]));
    }

    /// Whether the triangles at places `i` and `j` lie farther apart than the largest
    /// thickness along the line between their centroids now, over the whole substep.
    #[inline]
    fn separated(&self, i: usize, j: usize) -> bool {
        let ((a, a_moved), (b, b_moved)) = (self.now[i], self.now[j]);
        let (a, b) = (a.map(Vec3A::from), b.map(Vec3A::from));
        let axis = (b[0] + b[1] + b[2]) - (a[0] + a[1] + a[2]);
        let a_hi = a[0].dot(axis).max(a[1].dot(axis)).max(a[2].dot(axis));
        let b_lo = b[0].dot(axis).min(b[1].dot(axis)).min(b[2].dot(axis));
        // NaN is not apart.
        let length = axis.length();
        length > 0.0 && b_lo - a_hi >= (2.0 * self.grow + a_moved + b_moved) * length
    }

    /// Node `i`'s count of triangles.
    fn size(&self, i: u32) -> usize {
        self.nodes[i as usize].count as usize
    }

    /// Whether the nodes `na` and `nb` (numbered `a` and `b`, their bounds `fa` and `fb`) form
    /// a connected part of one body whose normals lie within 45° of one direction: each
    /// connected, their boxes in the rest shape touching and sharing a corner.
    #[inline(always)]
    fn flat_together(&self, na: Node, nb: Node, fa: &Fit, fb: &Fit, a: u32, b: u32) -> bool {
        na.body == nb.body
            && na.connected
            && nb.connected
            && fa.cone.flat_with(fb.cone)
            && self.rests[a as usize][0].cmple(self.rests[b as usize][1]).all()
            && self.rests[b as usize][0].cmple(self.rests[a as usize][1]).all()
            && self.share_a_corner(na, nb, a, b)
    }

    /// Whether the nodes `na` and `nb` (numbered `a` and `b`), both connected, share a corner.
    /// Two children of one node do when their parent is connected, as the build found it.
    #[inline(always)]
    fn share_a_corner(&self, na: Node, nb: Node, a: u32, b: u32) -> bool {
        // A left child follows its parent.
        match a.checked_sub(1).map(|p| self.nodes[p as usize]) {
            Some(parent) if parent.right == b => parent.connected,
            _ => shares_corner(&self.border, na.border, nb.border),
        }
    }
}

/// The box over the substep of the triangle of `corners` (flat indices) from `prev` to `x`,
/// grown by `grow` (empty when a corner is not finite); its corners now and the farthest one
/// moved; its unit normals then and now (0 for none: without area). `last` is its corners and
/// normal when it was last fitted: where its corners start the substep there, that normal is
/// the one they had, not worked out again.
#[inline]
fn fit_triangle(
    corners: [u32; 3],
    prev: &[Vec3],
    x: &[Vec3],
    grow: f32,
    last: ([Vec3; 3], Vec3),
) -> ([Vec3A; 2], ([Vec3; 3], f32), [Vec3; 2]) {
    let (before, now) = (corners.map(|k| Vec3A::from(prev[k as usize])), corners.map(|k| Vec3A::from(x[k as usize])));
    let lo = before[0].min(before[1]).min(before[2]).min(now[0].min(now[1]).min(now[2]));
    let hi = before[0].max(before[1]).max(before[2]).max(now[0].max(now[1]).max(now[2]));
    let own = if lo.is_finite() && hi.is_finite() { [lo - grow, hi + grow] } else { EMPTY };
    let moved = (0..3).fold(0.0f32, |m, k| m.max(before[k].distance_squared(now[k]))).sqrt();
    let normal = |[a, b, c]: [Vec3A; 3]| Vec3::from((b - a).cross(c - a).try_normalize().unwrap_or(Vec3A::ZERO));
    // Equal corners (NaN never is) give the same normal.
    let then = if before == last.0.map(Vec3A::from) { last.1 } else { normal(before) };
    (own, (now.map(Vec3::from), moved), [then, normal(now)])
}

/// The span of a particle's path from `a` to `b` ([`NO_SPAN`] for one that is not finite).
#[inline]
fn path_span(a: Vec3, b: Vec3) -> Span {
    if !(a.is_finite() && b.is_finite()) {
        return NO_SPAN;
    }
    let diagonals = |p: Vec3| {
        let (u, v) = (Vec3A::new(p.x, p.x, p.y), Vec3A::new(p.y, p.z, p.z));
        (u + v, u - v)
    };
    let ((sa, da), (sb, db)) = (diagonals(a), diagonals(b));
    [sa.min(sb), sa.max(sb), da.min(db), da.max(db)]
}

/// `span` grown by `grow` times the diagonals' length (`√2`): two spans grown by half a
/// distance meet wherever two points they hold lie within that distance of each other.
#[inline]
fn widen_span([lo_sum, hi_sum, lo_difference, hi_difference]: Span, grow: f32) -> Span {
    let grow = Vec3A::splat(grow * core::f32::consts::SQRT_2);
    [lo_sum - grow, hi_sum + grow, lo_difference - grow, hi_difference + grow]
}

/// The span of what the spans `a` and `b` hold.
#[inline(always)]
fn join_spans(a: Span, b: Span) -> Span {
    [a[0].min(b[0]), a[1].max(b[1]), a[2].min(b[2]), a[3].max(b[3])]
}

/// Whether the spans `a` and `b` meet along every diagonal.
#[inline(always)]
fn spans_meet(a: &Span, b: &Span) -> bool {
    a[0].cmple(b[1]).all() && a[1].cmpge(b[0]).all() && a[2].cmple(b[3]).all() && a[3].cmpge(b[2]).all()
}

/// The tree's lists a body's build appends to: the nodes, their boxes in the rest shape, their
/// border particles and the triangles leaf after leaf.
type Lists<'a> = (&'a mut Vec<Node>, &'a mut Vec<[Vec3A; 2]>, &'a mut Vec<u32>, &'a mut Vec<u32>);

/// Appends the tree of `topology`'s triangles (numbered from `first` among every body's; the
/// body's index is `body`) to `lists`: its nodes, their boxes in the rest shape, each node's
/// particles on its border, and its triangles leaf after leaf. The triangles are halved again
/// and again at the median of their centroids in the rest shape along the longest side of
/// their box, so that a node is a compact piece of the surface, down to leaves of at most
/// [`LEAF_SIZE`].
fn build(topology: &ClothTopology, body: u32, first: u32, (nodes, rests, border, order): Lists<'_>) {
    let (rest, triangles) = (topology.rest_positions(), topology.triangles());
    let mut centroids: Vec<(Vec3, u32)> = triangles
        .iter()
        .enumerate()
        .map(|(t, c)| ((rest[c[0] as usize] + rest[c[1] as usize] + rest[c[2] as usize]) / 3.0, t as u32))
        .collect();
    let offsets = topology.triangle_offsets();
    let mut builder = Builder {
        triangles,
        rest,
        valence: offsets.windows(2).map(|w| w[1] - w[0]).collect(),
        mark: vec![u32::MAX; topology.len()],
        count: vec![0; topology.len()],
        body,
        first,
        nodes,
        rests,
        border,
        order,
    };
    builder.split(&mut centroids);
}

/// The scratch of a body's tree's build.
struct Builder<'a> {
    triangles: &'a [[u32; 3]],
    rest: &'a [Vec3],
    /// Each particle's count of triangles.
    valence: Vec<u32>,
    /// The node that last marked each particle, and how many of its triangles that node holds.
    mark: Vec<u32>,
    count: Vec<u32>,
    body: u32,
    first: u32,
    nodes: &'a mut Vec<Node>,
    rests: &'a mut Vec<[Vec3A; 2]>,
    border: &'a mut Vec<u32>,
    order: &'a mut Vec<u32>,
}

impl Builder<'_> {
    /// Appends the subtree of the triangles `order` (their rest centroids and local indices);
    /// returns whether they are connected through shared corners.
    fn split(&mut self, order: &mut [(Vec3, u32)]) -> bool {
        let at = self.nodes.len();
        let border = self.border(at as u32, order);
        let body = self.body;
        self.rests.push(self.rest_box(order));
        let (start, count) = (self.order.len() as u32, order.len() as u32);
        if order.len() <= LEAF_SIZE {
            self.order.extend(order.iter().map(|&(_, t)| self.first + t));
            let connected = self.joined(order);
            self.nodes.push(Node { right: LEAF, start, count, body, border, connected });
            return connected;
        }
        self.nodes.push(Node { right: 0, start, count, body, border, connected: false });
        let (lo, hi) =
            order.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &(c, _)| (lo.min(c), hi.max(c)));
        let axis = (hi - lo).max_position();
        let half = order.len() / 2;
        order.select_nth_unstable_by(half, |a, b| a.0[axis].total_cmp(&b.0[axis]).then(a.1.cmp(&b.1)));
        let (left, right) = order.split_at_mut(half);
        let joined_left = self.split(left);
        self.nodes[at].right = self.nodes.len() as u32;
        let joined_right = self.split(right);
        let (l, r) = (self.nodes[at + 1].border, self.nodes[self.nodes[at].right as usize].border);
        let connected = joined_left && joined_right && shares_corner(self.border, l, r);
        self.nodes[at].connected = connected;
        connected
    }

    /// Whether the few triangles `order` are joined to each other through shared corners.
    fn joined(&self, order: &[(Vec3, u32)]) -> bool {
        let corners: Vec<[u32; 3]> = order.iter().map(|&(_, t)| self.triangles[t as usize]).collect();
        // Grown from the first triangle: each pass takes in every triangle touching one taken.
        let mut taken = vec![false; corners.len()];
        taken[0] = true;
        for _ in 1..corners.len() {
            for i in 0..corners.len() {
                if !taken[i] && (0..corners.len()).any(|j| taken[j] && share_a_corner(corners[i], corners[j])) {
                    taken[i] = true;
                }
            }
        }
        taken.into_iter().all(|t| t)
    }

    /// The box of the triangles `order` in the rest shape.
    fn rest_box(&self, order: &[(Vec3, u32)]) -> [Vec3A; 2] {
        let corners =
            order.iter().flat_map(|&(_, t)| self.triangles[t as usize]).map(|k| Vec3A::from(self.rest[k as usize]));
        let (lo, hi) = corners.fold((Vec3A::INFINITY, Vec3A::NEG_INFINITY), |(lo, hi), p| (lo.min(p), hi.max(p)));
        [lo, hi]
    }

    /// Appends the particles of the triangles `order` that also belong to other triangles (in
    /// increasing order) to the border list, marked as node `at`'s; returns where they lie in
    /// it.
    fn border(&mut self, at: u32, order: &[(Vec3, u32)]) -> (u32, u32) {
        for &(_, t) in order {
            for k in self.triangles[t as usize] {
                let k = k as usize;
                if self.mark[k] != at {
                    (self.mark[k], self.count[k]) = (at, 0);
                }
                self.count[k] += 1;
            }
        }
        let start = self.border.len();
        for &(_, t) in order {
            for k in self.triangles[t as usize] {
                // Taken once: its count is cleared once it is listed.
                if self.count[k as usize] != 0 && self.count[k as usize] < self.valence[k as usize] {
                    self.border.push(k);
                }
                self.count[k as usize] = 0;
            }
        }
        self.border[start..].sort_unstable();
        (start as u32, (self.border.len() - start) as u32)
    }
}

/// Whether the sorted particle lists `a` and `b` (start and length in `border`) share one.
fn shares_corner(border: &[u32], a: (u32, u32), b: (u32, u32)) -> bool {
    let list = |(start, len): (u32, u32)| &border[start as usize..(start + len) as usize];
    let (mut a, mut b) = (list(a), list(b));
    while let (Some(&x), Some(&y)) = (a.first(), b.first()) {
        match x.cmp(&y) {
            core::cmp::Ordering::Less => a = &a[1..],
            core::cmp::Ordering::Greater => b = &b[1..],
            core::cmp::Ordering::Equal => return true,
        }
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Unit directions within about `spread` radians of `towards`, from a fixed sequence.
    fn directions(towards: Vec3A, spread: f32, count: usize, seed: &mut u32) -> Vec<Vec3A> {
        let mut next = || {
            *seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (*seed >> 8) as f32 / (1u32 << 24) as f32 * 2.0 - 1.0
        };
        (0..count).map(|_| (towards + Vec3A::new(next(), next(), next()) * spread).normalize()).collect()
    }

    /// The least cosine between `normals` and `axis`.
    fn least_cos(normals: &[Vec3A], axis: Vec3A) -> f32 {
        normals.iter().fold(1.0f32, |least, n| least.min(n.dot(axis)))
    }

    /// A leaf's cone, and cones joined up a tree, hold every normal under them; two cones taken
    /// as flat together have every normal within 45° of one direction (found among the
    /// directions between their axes), and two that a direction between their axes cannot hold
    /// within 45° are not taken as flat (200 random trees of 8 leaves).
    #[test]
    fn normal_cones_hold_their_normals_and_say_flat_only_within_45_degrees() {
        let mut seed = 7;
        let (mut flat, mut not_flat) = (0, 0);
        for case in 0..200 {
            let towards = directions(Vec3A::Y, 1.0, 1, &mut seed)[0];
            let spread = 0.05 + 0.6 * (case % 10) as f32 / 10.0;
            let leaves: Vec<Vec<Vec3A>> = (0..8).map(|_| directions(towards, spread, 4, &mut seed)).collect();
            let mut cones: Vec<(Cone, Vec<Vec3A>)> = leaves.iter().map(|l| (Cone::of(l), l.clone())).collect();
            for (cone, normals) in &cones {
                assert!(cone.cos <= 0.0 || least_cos(normals, cone.axis) >= cone.cos - 1e-5, "case {case}: a leaf");
            }
            while cones.len() > 1 {
                let (a, b) = (cones.remove(0), cones.remove(0));
                let both: Vec<Vec3A> = a.1.iter().chain(&b.1).copied().collect();
                let took = a.0.flat_with(b.0);
                let best = (0..=200)
                    .map(|k| a.0.axis.lerp(b.0.axis, k as f32 / 200.0).normalize_or_zero())
                    .map(|axis| least_cos(&both, axis))
                    .fold(-1.0f32, f32::max);
                if took {
                    assert!(
                        best >= FLAT_COS - 1e-4,
                        "case {case}: taken as flat, {} degrees",
                        best.acos().to_degrees()
                    );
                    flat += 1;
                } else {
                    not_flat += 1;
                }
                let joined = a.0.join(b.0);
                assert!(
                    joined.cos <= 0.0 || least_cos(&both, joined.axis) >= joined.cos - 1e-5,
                    "case {case}: a join {joined:?} holds {} of {:?} {:?}",
                    least_cos(&both, joined.axis),
                    a.0,
                    b.0
                );
                cones.push((joined, both));
            }
        }
        assert!(flat > 100 && not_flat > 100, "the cases test both answers: {flat} flat, {not_flat} not");
    }

    /// The spans of two points, grown as the refit grows them for a thickness, meet wherever
    /// the points lie within the thickness of each other (500 directions), and lie apart for
    /// points a little farther than that along a diagonal.
    #[test]
    fn spans_of_points_within_the_thickness_meet() {
        let h = 0.008;
        let grown = |p: Vec3| widen_span(path_span(p, p), 0.5 * h);
        let a = Vec3::new(0.31, -0.27, 0.73);
        let count = 500;
        for k in 0..count {
            // Directions spread over the sphere (a Fibonacci lattice).
            let z = 1.0 - 2.0 * (k as f32 + 0.5) / count as f32;
            let angle = k as f32 * core::f32::consts::PI * (3.0 - 5.0f32.sqrt());
            let r = (1.0 - z * z).sqrt();
            let b = a + Vec3::new(r * angle.cos(), r * angle.sin(), z) * (0.999 * h);
            assert!(spans_meet(&grown(a), &grown(b)), "{b} within {h} m of {a}");
        }
        for diagonal in [Vec3::new(1.0, 1.0, 0.0), Vec3::new(1.0, 0.0, -1.0), Vec3::new(0.0, -1.0, 1.0)] {
            let b = a + diagonal.normalize() * (1.01 * h);
            assert!(!spans_meet(&grown(a), &grown(b)), "{b} farther than {h} m from {a} along {diagonal}");
        }
    }
}
