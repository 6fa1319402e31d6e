//! The section `cpu_cloths`: several cloths on the CPU backend, stepped one after another
//! (each spreading its own passes over the pool) against side by side (one cloth to a thread at
//! a time), as the plugin's CPU backend steps the cloths without self-contact.

use std::sync::Arc;

use bvh_cloth_bench::TICK;
use bvh_cloth_core::{Affine3A, ClothGrid, ClothParams, ClothSim, ClothTopology, Integrator, UVec2, Vec2, Vec3};
use rayon::prelude::*;

/// The scenes: how many cloths, of how many particles a side.
const SCENES: [(u32, u32); 4] = [(8, 16), (8, 32), (8, 64), (4, 128)];

/// `count` cloths of 1 m, `side` x `side`, each hanging from its first row's corners, 2 m apart.
fn hanging_cloths(count: u32, side: u32) -> Vec<ClothSim> {
    let topology = Arc::new(ClothTopology::grid(ClothGrid::new(Vec2::ONE, UVec2::splat(side))).expect("a valid grid"));
    let params = ClothParams { integrator: Integrator::BLOCK_DESCENT, ..ClothParams::default() };
    (0..count)
        .map(|c| {
            let pose = Affine3A::from_translation(Vec3::new(2.0 * c as f32, 2.0, 0.0));
            ClothSim::new(params.clone(), Arc::clone(&topology), pose, &[0, side - 1]).expect("a valid cloth")
        })
        .collect()
}

/// The section's entry point.
pub(crate) fn cpu_cloths(threads: usize) {
    println!("\n## Several cloths on the CPU\n");
    println!(
        "Cloths of 1 m hanging from two corners, default parameters but block descent with one sweep (Looper 16), after 0.5 s: a tick of every cloth one after another, each tick's passes spread over the pool ({threads} threads), against side by side (`par_iter_mut` over the cloths, as the plugin's CPU backend steps the cloths without self-contact), alternating, best of 20 each, ms per 60 Hz tick of all of them. \"Same state\": every position equal, bit for bit, after the timed ticks.\n"
    );
    println!("| cloths | particles a side | one after another ms | side by side ms | speed-up | same state |");
    println!("|---|---|---|---|---|---|");
    for (count, side) in SCENES {
        let (mut one_by_one, mut side_by_side) = (hanging_cloths(count, side), hanging_cloths(count, side));
        for _ in 0..30 {
            one_by_one.iter_mut().for_each(|sim| _ = sim.tick(TICK, &[]));
            side_by_side.par_iter_mut().for_each(|sim| _ = sim.tick(TICK, &[]));
        }
        let (mut sequential, mut parallel) = (f64::INFINITY, f64::INFINITY);
        for _ in 0..20 {
            sequential =
                sequential.min(bvh_cloth_bench::time(|| one_by_one.iter_mut().for_each(|sim| _ = sim.tick(TICK, &[]))));
            parallel = parallel
                .min(bvh_cloth_bench::time(|| side_by_side.par_iter_mut().for_each(|sim| _ = sim.tick(TICK, &[]))));
        }
        let same = one_by_one.iter().zip(&side_by_side).all(|(a, b)| a.positions() == b.positions());
        println!(
            "| {count} | {side} | {:.2} | {:.2} | {:.2}x | {} |",
            sequential * 1e3,
            parallel * 1e3,
            sequential / parallel,
            if same { "yes" } else { "no" }
        );
    }
}
