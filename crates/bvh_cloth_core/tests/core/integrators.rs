//! Integrator accuracy on a single spring–mass oscillator with a known analytic solution.
//!
//! A 2 x 2 cloth with only shear springs and three pinned particles leaves one free particle on
//! one spring: along the diagonal it is the linear oscillator `x(t) = A cos(w t)`,
//! `w = sqrt(k / m)`.

use std::sync::Arc;

use bvh_cloth_core::{Affine3A, ClothGrid, ClothParams, ClothSim, ClothTopology, Integrator, SpringStiffness, Vec3};

const AMPLITUDE: f32 = 0.2;
const OMEGA: f32 = core::f32::consts::TAU; // one period per second

fn oscillator(integrator: Integrator) -> (ClothSim, Vec3, Vec3, f32) {
    // 4 particles of 0.25 kg; k = w^2 m puts the period at 1 s.
    let m = 0.25f32;
    let params = ClothParams {
        mass: 4.0 * m,
        looper: 1,
        spring_k: OMEGA * OMEGA * m,
        damping: 0.0,
        gravity: Vec3::ZERO,
        stiffness: SpringStiffness { structural: 0.0, shear: 1.0, bending: 0.0 },
        integrator,
        ..Default::default()
    };
    let grid = Arc::new(ClothTopology::grid(ClothGrid::new([1.0, 1.0].into(), [2, 2].into())).unwrap());
    let mut sim = ClothSim::new(params, grid, Affine3A::IDENTITY, &[0, 1, 2]).unwrap();
    let anchor = sim.position(0);
    let dir = (sim.position(3) - anchor).normalize();
    let rest = core::f32::consts::SQRT_2;
    sim.set_position(3, anchor + dir * (rest + AMPLITUDE));
    (sim, anchor, dir, rest)
}

/// Largest deviation from the analytic solution over one second stepped at `h`.
fn max_error(integrator: Integrator, steps: u32) -> f32 {
    let (mut sim, anchor, dir, rest) = oscillator(integrator);
    let h = 1.0 / steps as f32;
    let mut worst = 0.0f32;
    for step in 1..=steps {
        sim.substep(h, &[]);
        let t = step as f32 * h;
        let exact = anchor + dir * (rest + AMPLITUDE * (OMEGA * t).cos());
        worst = worst.max(sim.position(3).distance(exact));
    }
    worst
}

#[test]
fn rk4_is_fourth_order() {
    let coarse = max_error(Integrator::Rk4, 10);
    let fine = max_error(Integrator::Rk4, 20);
    let ratio = coarse / fine;
    assert!((12.0..=20.0).contains(&ratio), "halving dt divided the RK4 error by {ratio} ({coarse} -> {fine})");
}

#[test]
fn semi_implicit_euler_is_first_order() {
    let coarse = max_error(Integrator::SemiImplicitEuler, 200);
    let fine = max_error(Integrator::SemiImplicitEuler, 400);
    let ratio = coarse / fine;
    assert!((1.6..=2.5).contains(&ratio), "halving dt divided the Euler error by {ratio} ({coarse} -> {fine})");
}

/// Undamped RK4 over 100 periods at 100 steps per period: the energy drifts by less than
/// 0.1 %. (RK4's own dissipation is about (w h)^6 / 72 per step, about 1e-5 in all; the rest of
/// the budget is f32 rounding.)
#[test]
fn rk4_energy_drift_is_small() {
    let (mut sim, ..) = oscillator(Integrator::Rk4);
    let e0 = sim.energy();
    for _ in 0..100 * 100 {
        sim.substep(0.01, &[]);
    }
    let drift = ((sim.energy() - e0) / e0).abs();
    assert!(drift < 1.0e-3, "energy drifted by {drift}");
}
