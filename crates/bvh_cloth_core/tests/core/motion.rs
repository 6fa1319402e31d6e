//! What a user sees of a cloth in motion at the default settings, against RK4 at the same
//! resolution (the reference of the same spring model).
//!
//! A cloth of 1 m hanging from its two first-row corners, dropped flat, swings down and back
//! without stretching like rubber. Measured at 0.5 s (the bottom of the swing) and 1 s (near
//! its top): the sag of the last row's middle below the pins and the p99 strain of the
//! structural springs. The default integrator (multigrid) carries a fine cloth's load to its
//! pins within each substep; block descent's one sweep leaves it unconverged while the cloth
//! moves, and without tethers its sag at 1 s is 45 % above RK4's at 64 x 64 and 134 % at
//! 128 x 128, its p99 strain 2.6x and 9.1x RK4's (the report's `motion` section); with the
//! tethers ([`bvh_cloth_core::cloth::tethers`]) 17 % and 16 % above, and 18 % at 32 x 32. The
//! default's test fails on both.
//!
//! A free cloth landing on the bunny stretches at most half again as much as RK4's.
//!
//! A flag in steady wind flutters at RK4's pace and with RK4's swing.

use crate::common;

use std::sync::Arc;

use bvh_cloth_core::{
    Aerodynamics, Affine3A, ClothGrid, ClothParams, ClothSim, ClothTopology, Collider, Integrator, Vec3, Wind,
};
use common::grid_topology;

const TICK: f32 = 1.0 / 60.0;

/// The sag below the pins and the p99 structural strain of a `side` x `side` cloth of 1 m
/// hanging from its first-row corners, dropped flat 2 m up, at 0.5 s and 1 s.
fn swing(side: u32, params: ClothParams) -> [(f32, f32); 2] {
    swing_at(side, params, Vec3::new(0.0, 2.0, 0.0), 2)
}

/// [`swing`] with the first pin at `origin`, sampled every `1 / samples` s to 1 s.
fn swing_at<const N: usize>(side: u32, params: ClothParams, origin: Vec3, samples: u32) -> [(f32, f32); N] {
    let topology = grid_topology(1.0, side, side);
    let grid = *topology.stencil().unwrap();
    let mut sim = ClothSim::new(params, topology, Affine3A::from_translation(origin), &[0, side - 1]).unwrap();
    let mut out = [(0.0, 0.0); N];
    for sample in &mut out {
        for _ in 0..60 / samples {
            sim.tick(TICK, &[]);
        }
        *sample = (origin.y - sim.position(grid.index(grid.rows - 1, grid.cols / 2)).y, strain_p99(&sim));
    }
    out
}

/// The 99th percentile of the structural springs' stretch (0 for a compressed spring).
fn strain_p99(sim: &ClothSim) -> f32 {
    let topology = sim.topology();
    let mut strains: Vec<f32> = (0..sim.len())
        .flat_map(|i| {
            topology.springs_of(i).iter().filter(move |e| e.kind == 0 && e.other as usize > i).map(move |e| (i, *e))
        })
        .map(|(i, e)| (sim.position(i).distance(sim.position(e.other as usize)) / e.rest - 1.0).max(0.0))
        .collect();
    strains.sort_by(f32::total_cmp);
    strains[strains.len() * 99 / 100]
}

/// `integrator`'s sag within `sag_bound` (a fraction) of RK4's and its p99 strain at most
/// `strain_bound` times RK4's, at 0.5 s and 1 s, on the `side` x `side` hanging cloth, the other
/// parameters the defaults.
fn swings_within(integrator: Integrator, side: u32, sag_bound: f32, strain_bound: f32) {
    each_swings_within(side, &[(ClothParams { integrator, ..Default::default() }, sag_bound, strain_bound)]);
}

/// [`swings_within`] for each of `cases` (the parameters, the sag's bound and the strain's),
/// against one run of RK4 at the defaults: its stiffness guard takes more substeps than any
/// Looper the cases ask for.
fn each_swings_within(side: u32, cases: &[(ClothParams, f32, f32)]) {
    let rk4 = swing(side, ClothParams { integrator: Integrator::Rk4, ..Default::default() });
    for (params, sag_bound, strain_bound) in cases {
        let own = swing(side, params.clone());
        for ((t, (sag, strain)), (rk4_sag, rk4_strain)) in [0.5, 1.0].into_iter().zip(own).zip(rk4) {
            let case = format!("{:?} at Looper {}, {side}x{side} at {t} s", params.integrator, params.looper);
            eprintln!(
                "{case}: sag {sag:.3} m (RK4 {rk4_sag:.3}, {:+.1} %), p99 strain {:.2} % (RK4 {:.2} %, {:.2}x)",
                (sag / rk4_sag - 1.0) * 100.0,
                strain * 100.0,
                rk4_strain * 100.0,
                strain / rk4_strain
            );
            assert!((sag / rk4_sag - 1.0).abs() <= *sag_bound, "{case}: sag {sag} against RK4's {rk4_sag}");
            assert!(strain <= strain_bound * rk4_strain, "{case}: p99 strain {strain} against RK4's {rk4_strain}");
        }
    }
}

/// The default integrator (multigrid, no tethers) at the default Looper 16: the sag at 0.5 s
/// and 1 s within 5 % of RK4's (10 % at 128 x 128) and the p99 strain at most 1.5x RK4's, from
/// 32 x 32 to 128 x 128. Block descent with one sweep sags 18 %, 17 % and 16 % more than RK4
/// at 1 s with its tethers (45 % and 134 % more at 64 x 64 and 128 x 128 without), and fails
/// this; with Gauss–Seidel sweeps on the coarse levels in place of damped Jacobi steps, the
/// multigrid integrator sagged 12.1 % more than RK4 at 1 s at 128 x 128, and failed it too.
/// At 128 x 128 the sag at 1 s lies within rounding's reach of the bound: with the cloth's
/// starting height moved by 1 to 3 mm (RK4's alike) it came out between +6.5 % and +10.6 % of
/// RK4's (a scratch program).
#[test]
fn the_default_swings_like_rk4_without_stretching_like_rubber() {
    assert_eq!(Integrator::default(), Integrator::Multigrid);
    // Measured: the sag against RK4's at 0.5 s and 1 s, the strain ratio at 1 s.
    swings_within(Integrator::default(), 32, 0.05, 1.5); // +0.2 %, -1.2 %; 0.96x
    swings_within(Integrator::default(), 64, 0.05, 1.5); // +1.1 %, +3.6 %; 1.04x
    swings_within(Integrator::default(), 128, 0.1, 1.5); // +2.5 %, +9.7 %; 0.92x
}

/// Block descent with one sweep, held by its tethers: the sag within 25 % of RK4's and the
/// p99 strain at most 1.5x RK4's, at 0.5 s and 1 s. The bounds are the measured figures (in the
/// comments, sag against RK4's at 0.5 s and 1 s, then the strain ratio at 1 s) with a margin.
#[test]
fn block_descent_held_by_tethers_swings_within_a_quarter_of_rk4s() {
    swings_within(Integrator::BLOCK_DESCENT, 32, 0.25, 1.5); // -5.6 %, +18.3 %; 1.21x (implicit Euler's damping: converged, +7 %)
    swings_within(Integrator::BLOCK_DESCENT, 64, 0.25, 1.5); // -5.7 %, +16.7 %; 1.03x
    swings_within(Integrator::BLOCK_DESCENT, 128, 0.25, 1.5); // -9.1 %, +15.7 %; 1.38x
}

/// At 512 x 512 too, against RK4 at 1 s: the sag within 10 % and the p99 strain at most 1.5x
/// (measured: -0.1 % and 1.15x; at 0.5 s +4.1 % and 1.00x). Its substeps are stiff enough
/// (`(2h/3)² k_max / m_min` 88, past 50) that the multigrid integrator blends BDF2 with
/// implicit Euler and runs the first level's W-cycle; with BDF2 and V-cycles its strain at 1 s
/// came out between 1.48x and 1.64x RK4's as rounding changed, and failed this. The multigrid's
/// coarse levels are kept for a few substeps; when the cloth snaps taut under them their
/// curvature along the correction falls to a twentieth of the cloth's own, and kept
/// regardless, this cloth blew up between 0.5 s and 1 s (its p99 strain passed 180x). They are
/// assembled again when the two differ by half.
///
/// At Looper 8 its substeps are as stiff as 1024 x 1024's at Looper 16 (352 against 354): the
/// sag within 15 % of RK4's and the p99 strain at most 1.5x (measured: +2.4 % and 1.01x at
/// 0.5 s, +10.1 % and 1.06x at 1 s; with BDF2 and V-cycles, +18.3 % and 1.86x at 1 s, which
/// fails this).
#[test]
fn a_512_cloth_swings_like_rk4_at_the_default() {
    let default = ClothParams::default();
    each_swings_within(512, &[(default.clone(), 0.1, 1.5), (ClothParams { looper: 8, ..default }, 0.15, 1.5)]);
}

/// A 128 x 128 cloth of 1.4 m dropped 0.2 m onto the bundled bunny (n = 5): at 1 s, with the
/// cloth on the bunny, its p99 structural strain is at most 1.5x RK4's at the default
/// (measured: 3.3 % against 2.7 %, 1.23x), and with block descent's one sweep too (3.4 %,
/// 1.25x; at 0.5 s, landing, 6.7 % against 4.8 %).
#[test]
fn a_free_cloth_landing_on_the_bunny_stretches_at_most_half_again_rk4s() {
    let mesh = common::bundled_model("bunny");
    let bunny = Collider::from_mesh(mesh.as_mesh_ref(), 5).unwrap().with_margin(0.01).with_friction(1.0);
    let top = mesh.positions.iter().map(|p| p[1]).fold(f32::MIN, f32::max);
    let strain_at_1_s = |integrator| {
        let topology = Arc::new(bvh_cloth_core::ClothTopology::grid(common::square_grid(1.4, 128, 128)).unwrap());
        let params = ClothParams { integrator, ..Default::default() };
        let pose = Affine3A::from_translation(Vec3::new(-0.1, top + 0.2, 0.0));
        let mut sim = ClothSim::new(params, topology, pose, &[]).unwrap();
        for _ in 0..60 {
            sim.tick(TICK, std::slice::from_ref(&bunny));
        }
        strain_p99(&sim)
    };
    let rk4 = strain_at_1_s(Integrator::Rk4);
    for integrator in [Integrator::default(), Integrator::BLOCK_DESCENT] {
        let strain = strain_at_1_s(integrator);
        eprintln!(
            "128x128 on the bunny at 1 s, {integrator:?}: p99 strain {:.2} % (RK4 {:.2} %, {:.2}x)",
            strain * 100.0,
            rk4 * 100.0,
            strain / rk4
        );
        assert!(strain <= 1.5 * rk4, "{integrator:?}: p99 strain {strain} against RK4's {rk4}");
    }
}

/// A cloth far from the origin moves as the same cloth near it: the hanging cloth's sag every
/// quarter second to 1 s within 2.5 % (or 2 mm) on either integrator, 100 m up and 1 km out on
/// every axis, where `f32` keeps a position to 61 µm and the springs are 31 mm long (measured
/// at 1 km: block descent 0.7 % off at 1 s, RK4 1.9 %; 100 m up, 0.04 % and 0.7 %). Block
/// descent solves for each particle's displacement over the substep, which `f32` keeps whatever
/// the coordinates; solving for positions instead, the same cloth 1 km out did not move (its
/// first iterate and its inertial target rounded back to where it was), and 100 m up it sagged
/// 25 % less at 0.25 s and 54 % more at 1 s.
#[test]
fn a_cloth_far_from_the_origin_moves_as_one_near_it() {
    for integrator in [Integrator::default(), Integrator::BLOCK_DESCENT, Integrator::Rk4] {
        let params = ClothParams { integrator, ..Default::default() };
        let near: [(f32, f32); 4] = swing_at(32, params.clone(), Vec3::new(0.0, 2.0, 0.0), 4);
        for origin in [Vec3::new(0.0, 100.0, 0.0), Vec3::new(1000.0, 1000.0, -1000.0)] {
            let far: [(f32, f32); 4] = swing_at(32, params.clone(), origin, 4);
            for (quarter, ((near, _), (far, _))) in near.into_iter().zip(far).enumerate() {
                let t = 0.25 * (quarter + 1) as f32;
                eprintln!("{integrator:?} at {origin}, {t} s: sag {far:.4} m, near the origin {near:.4} m");
                assert!(
                    (far - near).abs() <= (0.025 * near).max(0.002),
                    "{integrator:?} at {origin}, {t} s: sag {far} m, near the origin {near} m"
                );
            }
        }
    }
}

/// The report's flag (1.5 m x 1 m, 48 x 32 particles, 0.3 kg, SpringK 400, held along a
/// vertical pole) in a steady 8 m/s wind along its plane, stepped by `integrator`: after 4 s,
/// the cross-wind position of the middle of its free edge every tick for 12 s, as its
/// flutter's frequency (the spectrum's largest peak away from zero, in Hz) and its swing (the
/// position's standard deviation, in m).
fn flutter(integrator: Integrator) -> (f64, f64) {
    let (cols, rows) = (48u32, 32u32);
    let grid = ClothGrid::new([1.5, 1.0].into(), [cols, rows].into());
    let pole: Vec<u32> = (0..rows).map(|r| r * cols).collect();
    let params = ClothParams {
        mass: 0.3,
        spring_k: 400.0,
        damping: 0.3,
        integrator,
        aerodynamics: Aerodynamics::FABRIC,
        ..Default::default()
    };
    let pose =
        Affine3A::from_translation(Vec3::new(0.75, 2.0, 0.0)) * Affine3A::from_rotation_x(core::f32::consts::FRAC_PI_2);
    let topology = Arc::new(ClothTopology::grid(grid).unwrap());
    let mut sim = ClothSim::new(params, topology, pose, &pole).unwrap();
    sim.set_wind(Wind::steady(Vec3::new(8.0, 0.0, 0.0)), &[]).unwrap();
    let probe = (rows / 2 * cols + cols - 1) as usize;
    let mut z = Vec::new();
    for tick in 0..240 + 720 {
        sim.tick(TICK, &[]);
        if tick >= 240 {
            z.push(f64::from(sim.position(probe).z));
        }
    }
    let n = z.len();
    let mean = z.iter().sum::<f64>() / n as f64;
    let swing = (z.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / n as f64).sqrt();
    let power = |k: usize| {
        let (re, im) = z.iter().enumerate().fold((0.0, 0.0), |(re, im), (j, v)| {
            let angle = core::f64::consts::TAU * (k * j) as f64 / n as f64;
            (re + (v - mean) * angle.cos(), im - (v - mean) * angle.sin())
        });
        re * re + im * im
    };
    let peak = (1..n / 2).max_by(|&a, &b| power(a).total_cmp(&power(b))).unwrap();
    (peak as f64 / (n as f64 * f64::from(TICK)), swing)
}

/// At the default (the multigrid integrator) the flag flutters within 30 % of RK4's frequency,
/// and swings within 20 % of RK4's standard deviation of the free edge's cross-wind position
/// (measured: 5.83 Hz and 33.2 mm against RK4's 5.08 Hz and 33.5 mm). Block descent with one
/// sweep flutters at 3.08 Hz with a swing of 23.5 mm, and fails this.
///
/// The swing is the standard deviation rather than the spectrum's peak: the flutter is no
/// sinusoid, and its peak's height moves with the window and the step (RK4's is 17.4 mm over
/// 6 s and 14.0 mm over 12 s at Looper 16, 28.3 mm over 6 s at Looper 32, where its standard
/// deviation is 33.9, 33.5 and 35.0 mm).
#[test]
fn the_default_flag_flutters_like_rk4s() {
    let (rk4_hz, rk4_swing) = flutter(Integrator::Rk4);
    let (hz, swing) = flutter(Integrator::default());
    eprintln!(
        "flag in 8 m/s wind: default {hz:.2} Hz, {:.1} mm; RK4 {rk4_hz:.2} Hz, {:.1} mm",
        swing * 1e3,
        rk4_swing * 1e3
    );
    assert!((hz / rk4_hz - 1.0).abs() <= 0.3, "flutter at {hz} Hz against RK4's {rk4_hz} Hz");
    assert!((swing / rk4_swing - 1.0).abs() <= 0.2, "swing of {swing} m against RK4's {rk4_swing} m");
}
