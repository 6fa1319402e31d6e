//! Block descent against the explicit integrators: the same material settles to the same sag,
//! energy never grows, and no stiffness or resolution needs more substeps or blows up.

use crate::common;

use bvh_cloth_core::{Affine3A, ClothError, ClothParams, ClothSim, Integrator, Tethers, Vec3};
use common::grid_topology;

const TICK: f32 = 1.0 / 60.0;

/// A `side x side` cloth of 1 m, hanging from its two first-row corners.
fn hanging(side: u32, params: ClothParams) -> ClothSim {
    let pins = [0, side - 1];
    ClothSim::new(params, grid_topology(1.0, side, side), Affine3A::from_translation(Vec3::new(0.0, 2.0, 0.0)), &pins)
        .unwrap()
}

/// How far the middle of the cloth's last row hangs below the pins after `seconds`.
fn sag(sim: &mut ClothSim, seconds: f32) -> f32 {
    for _ in 0..(seconds / TICK).round() as u32 {
        sim.tick(TICK, &[]);
    }
    assert!(sim.is_finite());
    let grid = *sim.topology().stencil().unwrap();
    2.0 - sim.position(grid.index(grid.rows - 1, grid.cols / 2)).y
}

/// A 32x32 cloth hanging from two corners settles to within 5 % of RK4's sag at the same
/// stiffness, with one sweep per substep and the default tethers (measured: 0.32 % at 16
/// substeps, 0.20 % at 4).
#[test]
fn hangs_to_the_sag_rk4_hangs_to() {
    let base = ClothParams { damping: 2.0, looper: 16, ..Default::default() };
    let reference = sag(&mut hanging(32, ClothParams { integrator: Integrator::Rk4, ..base.clone() }), 8.0);
    for looper in [16, 4] {
        let params = ClothParams { integrator: Integrator::BLOCK_DESCENT, looper, ..base.clone() };
        let got = sag(&mut hanging(32, params), 8.0);
        let off = (got - reference).abs() / reference;
        eprintln!("looper {looper}: sag {got:.4} m against RK4's {reference:.4} m ({:.2} %)", 100.0 * off);
        assert!(off < 0.05, "looper {looper}: sag {got} m against RK4's {reference} m ({:.1} %)", 100.0 * off);
    }
}

/// With no damping and nothing but gravity, the total energy (kinetic, springs, gravity) of a
/// falling, swinging cloth never exceeds what it started with, at any stiffness, and implicit
/// Euler's own dissipation takes some of it. Tick to tick, a sweep that has not converged can
/// hand energy back from the springs to motion (measured with this cloth: never at SpringK 10 or
/// 400, up to 6 % of the total in one tick at 1e5), but never more than the cloth had.
///
/// With tethers (the default) and without: a tether only takes velocity away from its pin.
#[test]
fn energy_never_grows_without_input() {
    let settings = [10.0, 400.0, 1.0e5].into_iter().flat_map(|k| [(k, Some(Tethers::default())), (k, None)]);
    for (spring_k, tethers) in settings {
        let params = ClothParams {
            damping: 0.0,
            spring_k,
            integrator: Integrator::BLOCK_DESCENT,
            tethers,
            ..Default::default()
        };
        let mut sim = hanging(16, params);
        // Start stretched sideways so the springs hold energy too.
        for i in 0..sim.len() {
            let p = sim.position(i);
            sim.set_position(i, Vec3::new(p.x * 1.1, p.y, p.z));
        }
        let start = sim.energy();
        for tick in 0..240 {
            sim.tick(TICK, &[]);
            let now = sim.energy();
            assert!(
                now <= start + 1e-6 * start.abs(),
                "spring_k {spring_k}, tethers {tethers:?}, tick {tick}: energy rose {start} -> {now}"
            );
        }
        let end = sim.energy();
        assert!(end < 0.9 * start, "spring_k {spring_k}, tethers {tethers:?}: no dissipation, {start} -> {end}");
    }
}

/// The multigrid integrator's BDF2 under the same test: no damping, nothing but gravity, the
/// cloth started stretched. BDF2 is not monotone in energy as implicit Euler is: tick to tick
/// its energy may rise by a rounding's worth, never beyond `RISE` of the start (measured: it
/// never rose); and a cloth's motion (SpringK 10 and 400) loses less to it than to implicit
/// Euler, which is why it swings like RK4. Far stiffer springs (1e5) lose their ringing to
/// both (measured: BDF2 keeps 5 % less), within 10 % of each other.
#[test]
fn bdf2_neither_gains_energy_nor_damps_as_implicit_euler() {
    const RISE: f64 = 1.0e-4;
    for spring_k in [10.0, 400.0, 1.0e5] {
        let energy_after = |integrator| {
            let params = ClothParams { damping: 0.0, spring_k, integrator, tethers: None, ..Default::default() };
            let mut sim = hanging(16, params);
            for i in 0..sim.len() {
                let p = sim.position(i);
                sim.set_position(i, Vec3::new(p.x * 1.1, p.y, p.z));
            }
            let start = sim.energy();
            let mut highest = start;
            for _ in 0..240 {
                sim.tick(TICK, &[]);
                highest = highest.max(sim.energy());
            }
            (start, highest, sim.energy())
        };
        let (start, highest, bdf2) = energy_after(Integrator::Multigrid);
        let (_, _, euler) = energy_after(Integrator::BLOCK_DESCENT);
        eprintln!(
            "spring_k {spring_k}: energy {start:.4} J at the start, at most {:+.2e} of it, after 4 s BDF2 {bdf2:.4} J, implicit Euler {euler:.4} J",
            (highest - start) / start.abs()
        );
        assert!(highest <= start + RISE * start.abs(), "spring_k {spring_k}: energy rose {start} -> {highest}");
        if spring_k < 1.0e3 {
            assert!(bdf2 > euler, "spring_k {spring_k}: BDF2 kept {bdf2} J, implicit Euler {euler} J");
        } else {
            assert!(
                (bdf2 - euler).abs() < 0.1 * euler,
                "spring_k {spring_k}: BDF2 kept {bdf2} J, implicit Euler {euler} J"
            );
        }
    }
}

/// Across the panel's stiffness range and far past it, and from 8x8 to 128x128, a tick takes
/// exactly `looper` substeps and the cloth stays finite, attached and calm.
#[test]
fn any_stiffness_and_resolution_runs_at_looper_substeps() {
    for integrator in [Integrator::BLOCK_DESCENT, Integrator::Multigrid] {
        for side in [8, 32, 128] {
            for spring_k in [10.0, 400.0, 1.0e6] {
                let params = ClothParams { spring_k, damping: 0.5, integrator, ..Default::default() };
                let looper = params.looper;
                let mut sim = hanging(side, params);
                let case = format!("{integrator:?}, {side}x{side}, spring_k {spring_k}");
                for _ in 0..60 {
                    assert_eq!(sim.tick(TICK, &[]).substeps, looper, "{case}");
                }
                assert!(sim.is_finite(), "{case}");
                let speed = sim.velocities().iter().map(|v| v.length()).fold(0.0f32, f32::max);
                assert!(speed < 10.0, "{case}: thrashing at {speed} m/s");
                // Nothing flew off. The softest cloth (SpringK 10, a 2 s period under its own
                // weight) swings down to about 2 m below the pins in its first second.
                let lowest = sim.positions().iter().map(|p| p.y).fold(f32::INFINITY, f32::min);
                assert!(lowest > 2.0 - 4.0, "{case}: fell to {lowest}");
            }
        }
    }
}

/// Stiffer springs stretch less: the ordering RK4 shows holds for block descent.
#[test]
fn stiffer_cloth_sags_less() {
    let sags: Vec<f32> = [20.0, 200.0, 2000.0]
        .into_iter()
        .map(|spring_k| {
            let params =
                ClothParams { spring_k, damping: 2.0, integrator: Integrator::BLOCK_DESCENT, ..Default::default() };
            sag(&mut hanging(16, params), 4.0)
        })
        .collect();
    assert!(sags[0] > sags[1] && sags[1] > sags[2], "{sags:?}");
}

#[test]
fn absurd_counts_are_refused_naming_the_field() {
    let base = ClothParams { integrator: Integrator::BLOCK_DESCENT, ..Default::default() };
    let topology = grid_topology(1.0, 8, 8);
    for iterations in [0, 17, u32::MAX] {
        let params = ClothParams { integrator: Integrator::BlockDescent { iterations }, ..base.clone() };
        let error = ClothSim::new(params, topology.clone(), Affine3A::IDENTITY, &[]).unwrap_err();
        assert_eq!(
            error,
            ClothError::CountOutOfRange { field: "integrator.iterations", value: iterations, min: 1, max: 16 }
        );
        assert!(error.to_string().contains("integrator.iterations"), "{error}");
    }
    let params = ClothParams { looper: 100_000, ..base.clone() };
    assert_eq!(
        params.validate().unwrap_err(),
        ClothError::CountOutOfRange { field: "looper", value: 100_000, min: 1, max: 256 }
    );
    // A refused change keeps the last valid settings.
    let mut sim = ClothSim::new(base.clone(), topology, Affine3A::IDENTITY, &[]).unwrap();
    let bad = ClothParams { integrator: Integrator::BlockDescent { iterations: 0 }, ..base.clone() };
    assert!(sim.set_params(bad).is_err());
    assert_eq!(sim.params(), &base);
}
