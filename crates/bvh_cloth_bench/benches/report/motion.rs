//! The section `motion`: what a user sees of each solver setting over time, against the analytic
//! answer and RK4 at the same resolution (see `bvh_cloth_core::solver::block_descent`).

use std::sync::Arc;

use bvh_cloth_bench::{TICK, model, time};
use bvh_cloth_core::{Affine3A, ClothParams, ClothSim, ClothTopology, Collider, Integrator, MeshRef, Primitive, Vec3};

use super::{SAMPLES, flag, flutter_of, hanging, sag_of, spectral_peak, swing};

/// The solver settings the tables compare: RK4 (the reference), the default (the multigrid
/// integrator), and block descent with one and with four sweeps a substep.
const SETTINGS: [Integrator; 4] =
    [Integrator::Rk4, Integrator::Multigrid, Integrator::BLOCK_DESCENT, Integrator::BlockDescent { iterations: 4 }];

/// The held cloth's settings: RK4, the default (the multigrid integrator, which has no
/// tethers) at Looper 16 and 12, then block descent with and without its tethers (which act
/// only on a held cloth) at one and four sweeps a substep.
fn held_settings() -> Vec<(String, ClothParams)> {
    let default = ClothParams::default();
    let descent = ClothParams { integrator: Integrator::BLOCK_DESCENT, ..default.clone() };
    let no_tethers = ClothParams { tethers: None, ..descent.clone() };
    let four = Integrator::BlockDescent { iterations: 4 };
    let slack = descent.tethers.map_or(0.0, |t| t.slack);
    vec![
        ("RK4".to_string(), ClothParams { integrator: Integrator::Rk4, ..default.clone() }),
        ("multigrid (the default)".to_string(), default.clone()),
        ("multigrid, Looper 12".to_string(), ClothParams { looper: 12, ..default }),
        (format!("block descent, 1 sweep, tethers {:.0} %", slack * 100.0), descent.clone()),
        ("block descent, 1 sweep, no tethers".to_string(), no_tethers.clone()),
        (
            format!("block descent, 4 sweeps, tethers {:.0} %", slack * 100.0),
            ClothParams { integrator: four, ..descent },
        ),
        ("block descent, 4 sweeps, no tethers".to_string(), ClothParams { integrator: four, ..no_tethers }),
    ]
}

/// A bundled model as authored cloth, half a metre across, centred on the origin.
fn model_cloth(name: &str) -> Arc<ClothTopology> {
    let mesh = model(name);
    let (lo, hi) =
        mesh.positions.iter().fold((Vec3::MAX, Vec3::MIN), |(lo, hi), &p| (lo.min(p.into()), hi.max(p.into())));
    let scale = 0.5 / (hi - lo).max_element();
    let positions: Vec<[f32; 3]> =
        mesh.positions.iter().map(|&p| ((Vec3::from(p) - 0.5 * (lo + hi)) * scale).to_array()).collect();
    Arc::new(ClothTopology::from_mesh(MeshRef { positions: &positions, indices: Some(&mesh.indices) }).expect("a mesh"))
}

/// The 99th percentile of the structural springs' stretch (0 for a compressed spring).
fn strain_p99(sim: &ClothSim) -> f32 {
    let topology = sim.topology();
    let mut strains: Vec<f32> = (0..topology.len())
        .flat_map(|i| {
            topology
                .springs_of(i)
                .iter()
                .filter(move |end| end.kind == 0 && end.other as usize > i)
                .map(move |end| (i, end))
        })
        .map(|(i, end)| (sim.position(i).distance(sim.position(end.other as usize)) / end.rest - 1.0).max(0.0))
        .collect();
    strains.sort_by(f32::total_cmp);
    strains[(strains.len() - 1) * 99 / 100]
}

pub(super) fn motion() {
    println!("\n## Motion: free fall, momentum and a hanging cloth in motion, by solver setting\n");
    let params = ClothParams::default();
    let (g, c) = (f64::from(params.gravity.length()), f64::from(params.damping));
    let expected = g / c * (1.0 - (1.0 - (-c).exp()) / c);
    println!(
        "Default parameters (Looper 16) but the integrator. Free fall: each cloth dropped from rest, no collider, 60 ticks; gravity and damping say {expected:.3} m. Then the same cloth, held 0.3 m above a frictionless ground, let go for 3 s: how far its centre of mass moves sideways (RK4: a stiffness guard of at most 256 substeps a tick). The bunny and dragon are the bundled low-resolution models as authored cloth 0.5 m across.\n"
    );
    println!(
        "| cloth | particles | integrator | fell in 1 s m | vs gravity and damping | sideways in 1 s mm | sideways on the ground in 3 s mm |"
    );
    println!("|---|---|---|---|---|---|---|");
    let upright = Affine3A::from_rotation_x(std::f32::consts::FRAC_PI_2);
    let grid = || {
        Arc::new(
            ClothTopology::grid(bvh_cloth_core::ClothGrid::new(bvh_cloth_core::Vec2::ONE, [64, 64].into()))
                .expect("a grid"),
        )
    };
    let cloths = [
        ("64x64 flat", grid(), Affine3A::IDENTITY),
        ("64x64 upright", grid(), upright),
        ("bunny", model_cloth("bunny_low"), Affine3A::IDENTITY),
        ("dragon", model_cloth("dragon_low"), Affine3A::IDENTITY),
    ];
    let ground = Collider::primitive(Primitive::HalfSpace { normal: Vec3::Y }).expect("a valid plane");
    for (name, topology, pose) in &cloths {
        for integrator in SETTINGS {
            let setting = ClothParams { integrator, ..params.clone() };
            let mut sim = ClothSim::new(setting.clone(), Arc::clone(topology), *pose, &[]).expect("a valid cloth");
            let start = sim.centre_of_mass();
            for _ in 0..60 {
                sim.tick(TICK, &[]);
            }
            let moved = sim.centre_of_mass() - start;
            let lift = Affine3A::from_translation(Vec3::new(0.0, 0.3 + 0.25, 0.0)) * *pose;
            let mut landing = ClothSim::new(setting, Arc::clone(topology), lift, &[]).expect("a valid cloth");
            let before = landing.centre_of_mass();
            for _ in 0..180 {
                landing.tick(TICK, std::slice::from_ref(&ground));
            }
            let drift = (landing.centre_of_mass() - before).with_y(0.0).length();
            println!(
                "| {name} | {} | {integrator:?} | {:.3} | {:+.2} % | {:.2} | {:.2} |",
                topology.len(),
                -moved.y,
                100.0 * (f64::from(-moved.y) / expected - 1.0),
                1e3 * moved.with_y(0.0).length(),
                1e3 * drift
            );
        }
    }

    println!(
        "\n### A cloth of 1 m hanging from its two first-row corners, dropped flat\n\nThe sag is how far the middle of the last row hangs below the pins; it swings down and back, so the sag at 1 s measures how the cloth moves, and the sag at 6 s where it settles. Strain: the 99th percentile of the structural springs' stretch at 1 s. ms per tick: the first second's mean, on all threads.\n"
    );
    println!(
        "| side | setting | sag at 1 s m | vs RK4 | p99 strain at 1 s | vs RK4 | sag at 6 s vs RK4 | ms per tick |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for side in [32u32, 64, 128, 256] {
        let mut reference: Option<(f32, f32, f32)> = None;
        for (setting, params) in held_settings() {
            let mut sim = hanging(side, params);
            let clock = std::time::Instant::now();
            for _ in 0..60 {
                sim.tick(TICK, &[]);
            }
            let ms = clock.elapsed().as_secs_f64() * 1e3 / 60.0;
            let (sag, strain) = (sag_of(&sim), strain_p99(&sim));
            for _ in 60..360 {
                sim.tick(TICK, &[]);
            }
            let rest = sag_of(&sim);
            let (ref_sag, ref_strain, ref_rest) = *reference.get_or_insert((sag, strain, rest));
            println!(
                "| {side} | {setting} | {sag:.3} | {:+.0} % | {:.1} % | {:.2}x | {:+.1} % | {ms:.1} |",
                100.0 * (sag / ref_sag - 1.0),
                100.0 * strain,
                strain / ref_strain,
                100.0 * (rest / ref_rest - 1.0)
            );
        }
    }

    println!(
        "\n### The flag's flutter (the `wind` section's flag in steady 8 m/s wind, held along its pole, so tethered), by solver setting\n"
    );
    println!(
        "The swing is the standard deviation of the free edge's cross-wind position over the {:.0} s window; the peak is the height of the spectrum's largest peak, shown for comparison: the flutter is no sinusoid, and that height moves with the step (RK4 at Looper 32, last row, against Looper 16) where the swing does not.\n",
        SAMPLES as f32 * TICK
    );
    println!("| integrator | Looper | flutter Hz | vs RK4 | swing mm | vs RK4 | peak mm | vs RK4 |");
    println!("|---|---|---|---|---|---|---|---|");
    let rows: Vec<(Integrator, u32, Vec<f32>)> = SETTINGS
        .into_iter()
        .map(|integrator| (integrator, 16))
        .chain([(Integrator::Rk4, 32)])
        .map(|(integrator, looper)| {
            let mut sim = flag(integrator);
            sim.set_params(ClothParams { looper, ..sim.params().clone() }).expect("a valid Looper");
            (integrator, looper, flutter_of(sim).0)
        })
        .collect();
    let mut reference = None;
    for (integrator, looper, z) in rows {
        let ((hz, peak), swing) = (spectral_peak(&z, TICK), swing(&z));
        let (ref_hz, ref_swing, ref_peak) = *reference.get_or_insert((hz, swing, peak));
        println!(
            "| {integrator:?} | {looper} | {hz:.2} | {:+.0} % | {:.1} | {:+.0} % | {:.1} | {:+.0} % |",
            100.0 * (hz / ref_hz - 1.0),
            swing * 1e3,
            100.0 * (swing / ref_swing - 1.0),
            peak * 1e3,
            100.0 * (peak / ref_peak - 1.0)
        );
    }
}

/// A `side` x `side` cloth hanging from two corners, 0.5 s after it was let go.
fn settled(side: u32, params: ClothParams) -> ClothSim {
    let mut sim = hanging(side, params);
    for _ in 0..30 {
        sim.tick(TICK, &[]);
    }
    sim
}

/// `rounds` ticks of `a` and of `b`, each from its own state, alternated (`a` first in even
/// rounds, `b` in odd ones): the best of each, in seconds, and the median of the rounds' ratios
/// `a / b`, which a burst of the machine's noise over one side's ticks moves less than it
/// moves a best.
fn best_ticks(a: &ClothSim, b: &ClothSim, rounds: u32) -> (f64, f64, f64) {
    let (mut best_a, mut best_b) = (f64::INFINITY, f64::INFINITY);
    let mut ratios = Vec::with_capacity(rounds as usize);
    for round in 0..rounds {
        let (mut x, mut y) = (a.clone(), b.clone());
        let (ta, tb) = if round % 2 == 0 {
            let ta = time(|| _ = x.tick(TICK, &[]));
            (ta, time(|| _ = y.tick(TICK, &[])))
        } else {
            let tb = time(|| _ = y.tick(TICK, &[]));
            (time(|| _ = x.tick(TICK, &[])), tb)
        };
        (best_a, best_b) = (best_a.min(ta), best_b.min(tb));
        ratios.push(ta / tb);
    }
    ratios.sort_by(f64::total_cmp);
    let mid = ratios.len() / 2;
    let median = if ratios.len() % 2 == 0 { 0.5 * (ratios[mid - 1] + ratios[mid]) } else { ratios[mid] };
    (best_a, best_b, median)
}

/// The sides `motion_cost` times, and how many alternated ticks of each setting it takes the
/// best of (the 256 x 256 tick is sixteen times the 64 x 64's; twenty of them steady its best
/// against the development machine's noise).
const COST_ROUNDS: [(u32, u32); 2] = [(64, 40), (256, 20)];

/// The section `motion_cost`: what the tethers cost block descent a tick of a hanging cloth,
/// the same state ticked with and without them, alternated, best of each and the median of
/// the rounds' ratios; then what the
/// default (the multigrid integrator) costs against block descent with one sweep, with its
/// tethers and without (`tethers: None`), the same way.
pub(super) fn motion_cost() {
    let descent = ClothParams { integrator: Integrator::BLOCK_DESCENT, ..ClothParams::default() };
    // Each side's block-descent states at 0.5 s, with its tethers and without: both tables'.
    let baselines: Vec<(u32, u32, ClothSim, ClothSim)> = COST_ROUNDS
        .into_iter()
        .map(|(side, rounds)| {
            let tethered = settled(side, descent.clone());
            (side, rounds, tethered, settled(side, ClothParams { tethers: None, ..descent.clone() }))
        })
        .collect();
    println!(
        "\n### What the tethers cost: a cloth of 1 m hanging from two corners for 0.5 s, then one tick of block descent\n"
    );
    println!("| side | tick with tethers ms | without ms | with / without | median of the rounds' ratios |");
    println!("|---|---|---|---|---|");
    for (side, rounds, with, without) in &baselines {
        let (best_with, best_without, median) = best_ticks(with, without, *rounds);
        println!(
            "| {side} | {:.3} | {:.3} | {:.2}x | {median:.2}x |",
            best_with * 1e3,
            best_without * 1e3,
            best_with / best_without
        );
    }
    println!(
        "\n### What the default costs: the same cloth, a tick of each setting from its own state at 0.5 s, alternated with block descent's (one sweep, with its tethers and without), best of each, and the median of the rounds' ratios\n"
    );
    println!(
        "| side | setting | block descent | tick ms | block descent ms | setting / block descent | median of the rounds' ratios |"
    );
    println!("|---|---|---|---|---|---|---|");
    for (side, rounds, tethered, untethered) in &baselines {
        let default = settled(*side, ClothParams::default());
        let looper_12 = settled(*side, ClothParams { looper: 12, ..ClothParams::default() });
        let cases = [
            ("multigrid, Looper 16 (the default)", &default, "tethers", tethered),
            ("multigrid, Looper 16 (the default)", &default, "no tethers", untethered),
            ("multigrid, Looper 12", &looper_12, "tethers", tethered),
        ];
        for (name, setting, baseline_name, baseline) in cases {
            let (best, best_baseline, median) = best_ticks(setting, baseline, *rounds);
            println!(
                "| {side} | {name} | {baseline_name} | {:.3} | {:.3} | {:.2}x | {median:.2}x |",
                best * 1e3,
                best_baseline * 1e3,
                best / best_baseline
            );
        }
    }
}

/// The section `fine_swing`: the hanging cloth at 512 x 512 and 1024 x 1024 at the default,
/// against RK4 at the same resolution (the converged reference of the same model: its
/// stiffness guard takes up to 256 substeps a tick), with 256 x 256 for scale and the
/// multigrid integrator at Looper 32 (twice the default's substeps) to show how much of the
/// default's error is the step's. RK4 at 1024 x 1024 takes about a quarter of an hour on the
/// 2-core machine.
pub(super) fn fine_swing() {
    println!("\n### Finer cloths: the hanging cloth at 1 s, the default against RK4\n");
    println!(
        "RK4 at the same resolution is the reference (its stiffness guard: {}, {} and {} substeps a tick at 256, 512 and 1024 a side); the multigrid integrator at Looper 32, twice the default's substeps, shows what halving the step buys. Sag and strain as in the table above, at 1 s.\n",
        substeps(256),
        substeps(512),
        substeps(1024)
    );
    println!("| side | setting | sag at 1 s m | vs RK4 | p99 strain at 1 s | vs RK4 |");
    println!("|---|---|---|---|---|---|");
    let at_1_s = |side: u32, params: ClothParams| {
        let mut sim = hanging(side, params);
        for _ in 0..60 {
            sim.tick(TICK, &[]);
        }
        (sag_of(&sim), strain_p99(&sim))
    };
    for side in [256u32, 512, 1024] {
        let rows = [
            ("RK4 (the reference)", ClothParams { integrator: Integrator::Rk4, ..ClothParams::default() }),
            ("multigrid, Looper 32", ClothParams { looper: 32, ..ClothParams::default() }),
            ("multigrid, Looper 16 (the default)", ClothParams::default()),
        ]
        .map(|(setting, params)| (setting, at_1_s(side, params)));
        let (ref_sag, ref_strain) = rows[0].1;
        for (setting, (sag, strain)) in rows {
            println!(
                "| {side} | {setting} | {sag:.3} | {:+.1} % | {:.1} % | {:.2}x |",
                100.0 * (sag / ref_sag - 1.0),
                100.0 * strain,
                strain / ref_strain
            );
        }
    }
}

/// The substeps a tick RK4's stiffness guard takes on the `side` x `side` hanging cloth.
fn substeps(side: u32) -> u32 {
    hanging(side, ClothParams { integrator: Integrator::Rk4, ..ClothParams::default() }).substeps(TICK)
}
