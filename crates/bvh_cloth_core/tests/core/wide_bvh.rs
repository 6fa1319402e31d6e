//! The four-wide tree against the binary tree it is folded from: the same leaves in the same
//! order for box queries (and a few more, from the wide tree's rounded boxes), and the nearest leaf of brute force for nearest-first queries.

use crate::common;

use bvh_cloth_core::backend::LEAF_BIT;
use bvh_cloth_core::backend::WideBvh;
use bvh_cloth_core::{Lbvh, Sphere, Vec3};
use common::Rng;

/// Leaf data for a walk that reads none.
const NO_DATA: &[u8] = &[];

fn random_spheres(rng: &mut Rng, count: usize) -> Vec<Sphere> {
    (0..count).map(|_| Sphere::new(rng.vec3(-1.0, 1.0), rng.range(0.0, 0.3))).collect()
}

/// The binary tree over `spheres` (its boxes fitted to the spheres' boxes) and its wide copy.
fn trees(spheres: &[Sphere]) -> (Lbvh, WideBvh) {
    let bvh = Lbvh::build(spheres);
    let wide = WideBvh::from_lbvh(&bvh, |k| {
        let s = bvh.spheres[k as usize];
        (s.centre() - s.radius, s.centre() + s.radius)
    });
    (bvh, wide)
}

/// No node but the root stands over three leaves or fewer: its parent's lane holds them.
fn assert_no_small_nodes(wide: &WideBvh) {
    for (index, node) in wide.nodes.iter().enumerate().skip(1) {
        let inner = node.child.iter().any(|&c| c & LEAF_BIT == 0);
        let leaves: Vec<u32> = (0..4).flat_map(|lane| node.leaves(lane)).collect();
        assert!(inner || leaves.len() > 3, "node {index} holds only the leaves {leaves:?}");
    }
}

/// Each node's `first_leaf` is the least leaf under it, and the leaves under it are the next
/// ones: the walk asks for their data from there on.
fn assert_first_leaves(wide: &WideBvh) {
    assert_eq!(wide.first_leaf.len(), wide.nodes.len());
    for index in 0..wide.nodes.len() {
        let mut under = Vec::new();
        let mut stack = vec![index as u32];
        while let Some(node) = stack.pop() {
            let node = &wide.nodes[node as usize];
            for lane in 0..4 {
                under.extend(node.leaves(lane));
                if node.child[lane] != u32::MAX && node.child[lane] & LEAF_BIT == 0 {
                    stack.push(node.child[lane]);
                }
            }
        }
        under.sort_unstable();
        let first = wide.first_leaf[index];
        let want: Vec<u32> = (first..first + under.len() as u32).collect();
        assert_eq!(under, want, "the leaves under node {index}");
    }
}

/// The number of wide levels on the longest path from the root to a leaf.
fn levels(wide: &WideBvh) -> u32 {
    let mut deepest = 0;
    let mut stack = vec![(0u32, 1u32)];
    while let Some((node, level)) = stack.pop() {
        deepest = deepest.max(level);
        for &child in &wide.nodes[node as usize].child {
            if child != u32::MAX && child & LEAF_BIT == 0 {
                stack.push((child, level + 1));
            }
        }
    }
    deepest
}

/// With the leaves' boxes the spheres' own, a box query of the wide tree meets every leaf the
/// binary walk meets, in the same order; it may meet more, whose own box misses the query but
/// whose box rounded to the node's 8-bit steps overlaps it (and reaches at most one step of the
/// node past the leaf's own). Points, boxes and segments' boxes, with and without a margin, and
/// every leaf is met once at most.
fn check_order(bvh: &Lbvh, wide: &WideBvh, rng: &mut Rng, queries: usize) {
    let own_box = |k: u32| {
        let s = bvh.spheres[k as usize];
        (s.centre() - s.radius, s.centre() + s.radius)
    };
    for _ in 0..queries {
        let a = rng.vec3(-1.4, 1.4);
        let b = if rng.range(0.0, 1.0) < 0.5 { a } else { a + rng.vec3(-0.3, 0.3) };
        let margin = if rng.range(0.0, 1.0) < 0.5 { 0.0 } else { rng.range(0.0, 0.2) };
        let (lo, hi) = (a.min(b), a.max(b));
        let mut binary = Vec::new();
        bvh.for_each_overlapping(lo, hi, margin, |k, _| binary.push(k));
        let mut folded = Vec::new();
        wide.for_each_overlapping(lo, hi, margin, |k| folded.push(k));
        let overlapping: Vec<u32> = folded
            .iter()
            .copied()
            .filter(|&k| {
                let (l, h) = own_box(k);
                l.cmple(hi + margin).all() && h.cmpge(lo - margin).all()
            })
            .collect();
        assert_eq!(overlapping, binary, "box {lo}..{hi} grown by {margin}");
        let mut once = folded.clone();
        once.sort_unstable();
        once.dedup();
        assert_eq!(once.len(), folded.len(), "a leaf met twice");
    }
}

/// Nearest-first: the leaf value is the squared distance from the point to the sphere (zero
/// inside it), which is never less than the distance to the leaf's box; the query's answer is
/// brute force's least value below the limit, or the limit.
fn check_nearest(bvh: &Lbvh, wide: &WideBvh, rng: &mut Rng, queries: usize) {
    let to_sphere = |s: &Sphere, p: Vec3| (s.centre().distance(p) - s.radius).max(0.0).powi(2);
    for _ in 0..queries {
        let p = rng.vec3(-1.6, 1.6);
        let limit = rng.range(0.0, 0.5).powi(2);
        let mut calls = 0;
        let got = wide.nearest(p, limit, &bvh.spheres, |leaves, best| {
            assert!((1..=12).contains(&leaves.len()));
            calls += leaves.len();
            leaves.iter().fold(best, |best, &k| to_sphere(&bvh.spheres[k as usize], p).min(best))
        });
        let want = bvh.spheres.iter().map(|s| to_sphere(s, p)).fold(limit, f32::min);
        assert_eq!(got, want, "nearest from {p} within {limit}");
        assert!(calls <= bvh.spheres.len());
    }
}

#[test]
fn tiny_trees() {
    let mut rng = Rng::new(2);
    for count in 1..=5 {
        let (bvh, wide) = trees(&random_spheres(&mut rng, count));
        assert_first_leaves(&wide);
        check_order(&bvh, &wide, &mut rng, 2000);
        check_nearest(&bvh, &wide, &mut rng, 2000);
    }
    let (bvh, wide) = trees(&[]);
    assert!(wide.nodes.is_empty());
    check_order(&bvh, &wide, &mut rng, 10);
    assert_eq!(wide.nearest(Vec3::ZERO, 1.0, NO_DATA, |_, _| unreachable!("no leaf")), 1.0);
}

#[test]
fn random_sets_meet_the_same_leaves_in_the_same_order() {
    let mut rng = Rng::new(9);
    for count in [6, 17, 64, 100, 1000, 20_000] {
        let (bvh, wide) = trees(&random_spheres(&mut rng, count));
        // A wide node folds two binary levels into one, and a run of two or three leaves is no
        // node: the deepest path may end a level higher.
        let folded = bvh.depth.div_ceil(2);
        assert!((folded - 1..=folded).contains(&levels(&wide)), "{count} leaves: {} levels", levels(&wide));
        assert_no_small_nodes(&wide);
        assert_first_leaves(&wide);
        check_order(&bvh, &wide, &mut rng, 2000);
        check_nearest(&bvh, &wide, &mut rng, 2000);
    }
}

/// A query with a NaN (point, box, margin or limit) meets no leaf, as the binary walk does.
#[test]
fn a_nan_query_meets_nothing() {
    let mut rng = Rng::new(21);
    let (bvh, wide) = trees(&random_spheres(&mut rng, 1000));
    let nan = Vec3::new(f32::NAN, 0.0, 0.0);
    for (lo, hi, margin) in [(nan, nan, 0.0), (Vec3::ZERO, nan, 0.1), (Vec3::ZERO, Vec3::ONE, f32::NAN)] {
        wide.for_each_overlapping(lo, hi, margin, |k| panic!("leaf {k} met by {lo}..{hi} grown by {margin}"));
        bvh.for_each_overlapping(lo, hi, margin, |k, _| panic!("the binary walk met leaf {k}"));
    }
    for p in [nan, Vec3::new(0.0, 0.0, f32::NAN)] {
        let best = wide.nearest(p, 1.0, NO_DATA, |k, _| panic!("leaves {k:?} tried from {p}"));
        assert_eq!(best, 1.0);
    }
    // Small trees too: their root has leaves and unused lanes.
    for count in [1, 2, 3, 5, 1000] {
        let (_, wide) = trees(&random_spheres(&mut rng, count));
        let best = wide.nearest(Vec3::ZERO, f32::NAN, NO_DATA, |k, _| panic!("leaves {k:?} tried within a NaN limit"));
        assert!(best.is_nan());
    }
}

/// Every child's box as the queries see it holds the box it was made from, and reaches past it
/// by at most one of the node's 255 steps a side.
#[test]
fn rounded_boxes_hold_their_children_within_a_step() {
    let mut rng = Rng::new(31);
    let (bvh, wide) = trees(&random_spheres(&mut rng, 5000));
    let mut checked = 0;
    for node in &wide.nodes {
        for (lane, &child) in node.child.iter().enumerate() {
            if child == u32::MAX || child & LEAF_BIT == 0 {
                continue;
            }
            // A run's lane holds the box of its leaves.
            let leaves: Vec<u32> = node.leaves(lane).collect();
            let (lo, hi) = leaves
                .iter()
                .map(|&k| bvh.spheres[k as usize])
                .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), s| {
                    (lo.min(s.centre() - s.radius), hi.max(s.centre() + s.radius))
                });
            let (got_lo, got_hi) = node.child_box(lane);
            assert!(got_lo.cmple(lo).all() && got_hi.cmpge(hi).all(), "{got_lo}..{got_hi} does not hold {lo}..{hi}");
            let (node_lo, node_hi) = (0..4).filter(|&l| node.child[l] != u32::MAX).fold(
                (Vec3::INFINITY, Vec3::NEG_INFINITY),
                |(lo, hi), l| {
                    let (a, b) = node.child_box(l);
                    (lo.min(a), hi.max(b))
                },
            );
            let node_size = node_hi - node_lo;
            let slack = (lo - got_lo).max(got_hi - hi);
            assert!(slack.cmple(node_size / 255.0 * 1.01 + 1e-6).all(), "{slack} past {lo}..{hi}");
            checked += leaves.len();
        }
    }
    assert_eq!(checked, 5000);
}

#[test]
fn coincident_centres() {
    // Equal Morton codes, ties broken by index: the deepest trees a set of leaves makes.
    let mut rng = Rng::new(13);
    let same: Vec<Sphere> = (0..300).map(|i| Sphere::new(Vec3::splat(0.25), 0.01 * (i % 7) as f32)).collect();
    let (bvh, wide) = trees(&same);
    check_order(&bvh, &wide, &mut rng, 2000);
    check_nearest(&bvh, &wide, &mut rng, 2000);
}
