//! Whole-cloth behaviour: pins, settling, symmetry, collision with a draped collider, and
//! thread-count independence.

mod common;

use bvh_cloth_core::{Affine3A, ClothGrid, ClothParams, ClothSim, Collider, MeshRef, Pins, Vec3};
use common::uv_sphere;

fn hanging(rows: u32, cols: u32) -> ClothSim {
    let params = ClothParams { rows, cols, size: 1.0, damping: 2.0, looper: 16, ..Default::default() };
    let grid = ClothGrid { rows: rows as usize, cols: cols as usize, spacing: params.spacing() };
    let pins = Pins::TwoEnds.indices(&grid);
    ClothSim::new(params, Affine3A::from_translation(Vec3::new(0.0, 2.0, 0.0)), &pins).unwrap()
}

#[test]
fn two_ends_fixed_settles_to_a_still_symmetric_sag() {
    let mut sim = hanging(16, 16);
    let pinned: Vec<Vec3> = sim.pins().iter().map(|&i| sim.position(i as usize)).collect();
    for _ in 0..60 * 20 {
        sim.tick(1.0 / 60.0, &[]);
        for (k, &i) in sim.pins().iter().enumerate() {
            assert_eq!(sim.position(i as usize), pinned[k], "a pinned particle moved");
        }
    }
    assert!(sim.is_finite());
    let max_speed = sim.velocities().iter().map(|v| v.length()).fold(0.0f32, f32::max);
    assert!(max_speed < 1.0e-3, "still moving at {max_speed} m/s after 20 s");
    // It sagged: the free middle of the first row hangs below the pins.
    let grid = *sim.grid();
    let mid = sim.position(grid.index(0, grid.cols / 2));
    assert!(mid.y < pinned[0].y - 0.05, "no sag: {mid}");
    // Left–right symmetric about the plane halfway between the pins.
    let centre_x = 0.5 * (pinned[0].x + pinned[1].x);
    for r in 0..grid.rows {
        for c in 0..grid.cols {
            let a = sim.position(grid.index(r, c));
            let b = sim.position(grid.index(r, grid.cols - 1 - c));
            let mirrored = Vec3::new(2.0 * centre_x - b.x, b.y, b.z);
            assert!(a.distance(mirrored) < 1.0e-4, "asymmetric at ({r},{c}): {a} vs {mirrored}");
        }
    }
}

fn ball_collider(n: u32) -> Collider {
    let (p, i) = uv_sphere(Vec3::ZERO, 0.5, 24, 48);
    Collider::from_mesh(MeshRef { positions: &p, indices: Some(&i) }, n).unwrap()
}

#[test]
fn draped_cloth_ends_outside_every_sphere() {
    let collider = ball_collider(5).with_margin(0.01);
    let params = ClothParams { rows: 32, cols: 32, size: 2.0, damping: 1.0, ..Default::default() };
    let mut sim = ClothSim::new(params, Affine3A::from_translation(Vec3::new(0.05, 1.0, -0.03)), &[]).unwrap();
    let colliders = [collider];
    // One second: long enough to land and fold, short enough that the frictionless cloth has
    // not yet slid off the ball (the offset breaks the symmetry on purpose).
    for _ in 0..60 {
        sim.tick(1.0 / 60.0, &colliders);
    }
    assert!(sim.is_finite());
    // Draped: the cloth centre rests on the ball's top sphere layer, its rim hangs lower.
    let grid = *sim.grid();
    let centre = sim.position(grid.index(16, 16));
    assert!(centre.y > 0.45 && centre.y < 0.75, "centre at {centre}");
    assert!(sim.position(0).y < centre.y - 0.3);
    // Stated epsilon: a particle may sit up to 1e-5 of a radius below a sphere's surface.
    let eps = bvh_cloth_core::traversal::SURFACE_TOLERANCE;
    let inside = sim.positions().iter().filter(|&&p| colliders[0].contains(p)).count();
    assert_eq!(inside, 0, "{inside} particles inside a sphere beyond {eps} of its radius");
}

#[test]
fn step_is_bit_identical_on_any_thread_count() {
    let run = |threads: usize| -> Vec<u32> {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| {
            let colliders = [ball_collider(5)];
            let params = ClothParams { rows: 48, cols: 40, ..Default::default() };
            let mut sim = ClothSim::new(params, Affine3A::from_translation(Vec3::Y), &[]).unwrap();
            for _ in 0..40 {
                sim.tick(1.0 / 60.0, &colliders);
            }
            sim.positions().iter().flat_map(|p| p.to_array().map(f32::to_bits)).collect()
        })
    };
    let one = run(1);
    assert_eq!(one, run(3));
    assert_eq!(one, run(rayon::current_num_threads().max(2)));
}

#[test]
fn pins_out_of_range_are_rejected() {
    let err = ClothSim::new(ClothParams { rows: 4, cols: 4, ..Default::default() }, Affine3A::IDENTITY, &[16]);
    assert!(matches!(err, Err(bvh_cloth_core::ClothError::PinOutOfRange { index: 16, particles: 16 })));
}

#[test]
fn pins_follow_their_pose_and_the_rest_keeps_its_state() {
    let mut sim = hanging(8, 8);
    let grid = *sim.grid();
    let free = grid.index(4, 4);
    let before = sim.position(free);
    let pose =
        Affine3A::from_rotation_translation(bvh_cloth_core::Quat::from_rotation_y(0.5), Vec3::new(1.0, 3.0, -2.0));
    sim.pin_to(&pose);
    for &i in sim.pins() {
        let (r, c) = (i as usize / grid.cols, i as usize % grid.cols);
        let expected = pose.transform_point3(grid.local_rest_position(r, c));
        assert!(sim.position(i as usize).distance(expected) < 1e-6);
    }
    assert_eq!(sim.position(free), before, "free particles are not teleported");
}

#[test]
fn shape_changes_are_refused_by_set_params() {
    let mut sim = hanging(8, 8);
    let mut params = sim.params().clone();
    params.spring_k = 500.0;
    sim.set_params(params.clone()).unwrap();
    assert_eq!(sim.params().spring_k, 500.0);
    params.rows = 9;
    assert_eq!(sim.set_params(params).unwrap_err(), bvh_cloth_core::ClothError::ShapeChanged);
    assert_eq!(sim.params().rows, 8, "the old parameters are kept");
}

#[test]
fn stiff_springs_stay_stable_under_the_guard() {
    // 100x the default stiffness with a quarter of the substeps: far past the explicit limit
    // of `looper` alone (h w is about 20 here), so the guard must add substeps.
    let params = ClothParams { rows: 24, cols: 24, size: 1.0, spring_k: 20_000.0, looper: 4, ..Default::default() };
    let grid = ClothGrid { rows: 24, cols: 24, spacing: params.spacing() };
    let mut sim = ClothSim::new(params, Affine3A::from_translation(Vec3::Y), &Pins::TwoEnds.indices(&grid)).unwrap();
    let mut substeps = 0;
    for _ in 0..120 {
        substeps = sim.tick(1.0 / 60.0, &[]);
    }
    assert!(substeps > 4, "the guard kept {substeps} substeps");
    assert!(sim.is_finite());
    let speed = sim.velocities().iter().map(|v| v.length()).fold(0.0f32, f32::max);
    assert!(speed < 5.0, "the stiff cloth is thrashing at {speed} m/s");
}
