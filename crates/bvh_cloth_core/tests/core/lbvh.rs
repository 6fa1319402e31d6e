//! LBVH invariants on random sphere sets, and traversal against brute force.

use crate::common;

use std::collections::BTreeSet;

use bvh_cloth_core::backend::LEAF_BIT;
use bvh_cloth_core::backend::STACK_SIZE;
use bvh_cloth_core::{Lbvh, Sphere, Vec3};
use common::Rng;

fn check_invariants(bvh: &Lbvh) {
    let n = bvh.spheres.len();
    assert_eq!(bvh.nodes.len(), n.saturating_sub(1), "N leaves need N - 1 inner nodes");
    assert!((bvh.depth as usize) < STACK_SIZE);
    if n == 1 {
        assert_eq!(bvh.root(), LEAF_BIT);
        return;
    }
    let bounds_of = |child: u32| -> (Vec3, Vec3) {
        if child & LEAF_BIT != 0 {
            let s = bvh.spheres[(child & !LEAF_BIT) as usize];
            (s.centre() - s.radius, s.centre() + s.radius)
        } else {
            let node = bvh.nodes[child as usize];
            (node.aabb_min.into(), node.aabb_max.into())
        }
    };
    let mut leaves_seen = vec![0u32; n];
    let mut inner_seen = vec![0u32; n - 1];
    let mut stack = vec![0u32];
    while let Some(i) = stack.pop() {
        inner_seen[i as usize] += 1;
        let node = bvh.nodes[i as usize];
        for child in [node.left, node.right] {
            let (lo, hi) = bounds_of(child);
            assert!(
                Vec3::from(node.aabb_min).cmple(lo).all() && Vec3::from(node.aabb_max).cmpge(hi).all(),
                "inner node {i} does not contain child {child:#x}"
            );
            if child & LEAF_BIT != 0 {
                leaves_seen[(child & !LEAF_BIT) as usize] += 1;
            } else {
                stack.push(child);
            }
        }
    }
    assert!(leaves_seen.iter().all(|&c| c == 1), "a leaf is not reached exactly once");
    assert!(inner_seen.iter().all(|&c| c == 1), "an inner node is not reached exactly once");
}

fn check_queries(bvh: &Lbvh, rng: &mut Rng, lo: f32, hi: f32, queries: usize) {
    for _ in 0..queries {
        let p = rng.vec3(lo, hi);
        let margin = if rng.range(0.0, 1.0) < 0.5 { 0.0 } else { rng.range(0.0, 0.2) };
        let mut fast = BTreeSet::new();
        bvh.for_each_containing(p, margin, |i, _| assert!(fast.insert(i), "sphere {i} reported twice"));
        let mut slow = BTreeSet::new();
        bvh.brute_force_containing(p, margin, |i, _| {
            slow.insert(i);
        });
        assert_eq!(fast, slow, "traversal and brute force disagree at {p}");
    }
}

fn random_spheres(rng: &mut Rng, count: usize) -> Vec<Sphere> {
    (0..count).map(|_| Sphere::new(rng.vec3(-1.0, 1.0), rng.range(0.0, 0.3))).collect()
}

#[test]
fn tiny_trees() {
    let mut rng = Rng::new(1);
    for count in 1..=3 {
        let bvh = Lbvh::build(&random_spheres(&mut rng, count));
        check_invariants(&bvh);
        check_queries(&bvh, &mut rng, -1.5, 1.5, 2000);
    }
    assert!(Lbvh::build(&[]).spheres.is_empty());
}

#[test]
fn random_sets() {
    let mut rng = Rng::new(7);
    for count in [4, 5, 17, 64, 100, 1000, 5000] {
        let bvh = Lbvh::build(&random_spheres(&mut rng, count));
        check_invariants(&bvh);
        check_queries(&bvh, &mut rng, -1.4, 1.4, 3000);
    }
}

#[test]
fn duplicate_morton_codes() {
    let mut rng = Rng::new(11);
    // Every sphere at the same centre: all codes equal, ties broken by index.
    let same: Vec<Sphere> = (0..300).map(|i| Sphere::new(Vec3::splat(0.25), 0.01 * (i % 7) as f32)).collect();
    let bvh = Lbvh::build(&same);
    check_invariants(&bvh);
    check_queries(&bvh, &mut rng, 0.1, 0.4, 2000);
    // Clusters of coincident centres mixed with distinct ones, and centres closer together than
    // the 10-bit Morton grid resolves.
    let mut mixed = random_spheres(&mut rng, 200);
    for k in 0..200 {
        let base = mixed[k % 13];
        mixed.push(Sphere::new(base.centre() + Vec3::splat(1.0e-6 * (k % 3) as f32), base.radius));
    }
    let bvh = Lbvh::build(&mixed);
    check_invariants(&bvh);
    check_queries(&bvh, &mut rng, -1.4, 1.4, 3000);
}

#[test]
fn parallel_build_matches_invariants() {
    // Above the parallel threshold the inner nodes are built on the pool.
    let mut rng = Rng::new(3);
    let bvh = Lbvh::build(&random_spheres(&mut rng, 20_000));
    check_invariants(&bvh);
    check_queries(&bvh, &mut rng, -1.2, 1.2, 500);
}

/// The level order a parallel refit walks: every inner node once, each node's inner children in
/// an earlier level than it, the root last; and boxes refitted level by level in that order
/// are the boxes the tree was built with.
#[test]
fn levels_put_children_before_parents() {
    let mut rng = Rng::new(5);
    for count in [1, 2, 3, 17, 1000, 20_000] {
        let bvh = Lbvh::build(&random_spheres(&mut rng, count));
        let (levels, starts) = bvh.levels();
        let mut level_of = vec![usize::MAX; bvh.nodes.len()];
        for l in 0..starts.len() - 1 {
            for &n in &levels[starts[l] as usize..starts[l + 1] as usize] {
                assert_eq!(level_of[n as usize], usize::MAX, "node {n} listed twice");
                level_of[n as usize] = l;
            }
        }
        assert!(level_of.iter().all(|&l| l != usize::MAX), "every node is listed");
        for (n, node) in bvh.nodes.iter().enumerate() {
            for child in [node.left, node.right].into_iter().filter(|c| c & LEAF_BIT == 0) {
                assert!(level_of[child as usize] < level_of[n], "child {child} is not before its parent {n}");
            }
        }
        if !bvh.nodes.is_empty() {
            assert_eq!(*levels.last().unwrap(), 0, "the root is last");
            assert_eq!(starts.len() - 1, bvh.depth as usize, "one level per depth");
        }
        // Refit in that order from scratch.
        let mut refit = bvh.clone();
        for node in &mut refit.nodes {
            node.aabb_min = [f32::NAN; 3];
            node.aabb_max = [f32::NAN; 3];
        }
        for &n in &levels {
            let node = refit.nodes[n as usize];
            let bounds = |child: u32| -> (Vec3, Vec3) {
                if child & LEAF_BIT != 0 {
                    let s = refit.spheres[(child & !LEAF_BIT) as usize];
                    (s.centre() - s.radius, s.centre() + s.radius)
                } else {
                    let c = refit.nodes[child as usize];
                    (c.aabb_min.into(), c.aabb_max.into())
                }
            };
            let ((a, b), (c, d)) = (bounds(node.left), bounds(node.right));
            refit.nodes[n as usize].aabb_min = a.min(c).to_array();
            refit.nodes[n as usize].aabb_max = b.max(d).to_array();
        }
        assert_eq!(refit.nodes, bvh.nodes);
    }
}
