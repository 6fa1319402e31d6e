//! The sections `wind` and `wind_gpu`: a flag's flutter in steady wind and its energy on both
//! backends, GPU against CPU in gusty wind, and what drag and lift cost.

use super::*;

/// The flag of the wind section: 1.5 m x 1 m, 48 x 32 particles, 0.3 kg, SpringK 400, held
/// along its hoist (a vertical pole at the origin), standing in the XY plane, with
/// [`Aerodynamics::FABRIC`].
pub(crate) fn flag(integrator: Integrator) -> ClothSim {
    let (cols, rows) = (48u32, 32u32);
    let grid = ClothGrid::new(Vec2::new(1.5, 1.0), UVec2::new(cols, rows));
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
        Affine3A::from_translation(Vec3::new(0.75, 2.0, 0.0)) * Affine3A::from_rotation_x(std::f32::consts::FRAC_PI_2);
    let topology = Arc::new(ClothTopology::grid(grid).expect("a valid grid"));
    ClothSim::new(params, topology, pose, &pole).expect("a valid flag")
}

/// A batch holding `sim` alone, with its parameters for 60 Hz ticks.
pub(crate) fn alone_on_gpu(gpu: &Gpu, sim: &ClothSim) -> (ClothBatch, bvh_cloth_gpu::ClothId) {
    let mut batch = ClothBatch::new(&gpu.device, &gpu.queue);
    let id = batch.insert(&gpu.device, &gpu.queue, sim).expect("the cloth fits the device");
    batch.set_params(&gpu.queue, id, sim.params(), TICK);
    (batch, id)
}

/// Runs `ticks` ticks of `batch` against `colliders`, submitted without waiting.
pub(crate) fn run_on_gpu(gpu: &Gpu, batch: &mut ClothBatch, colliders: &GpuColliders, ticks: u32) {
    batch.prepare(&gpu.device, &gpu.queue, &gpu.kernels, colliders);
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    batch.encode_ticks(&mut encoder, &gpu.kernels, ticks);
    gpu.queue.submit([encoder.finish()]);
}

/// The solvers of the flutter table: block descent with one sweep, block descent converged
/// further in each substep (which a flutter needs, being fast motion), and RK4 (the default,
/// the multigrid integrator, is in the `motion` section's flutter table).
pub(crate) const FLUTTER_INTEGRATORS: [Integrator; 3] =
    [Integrator::BLOCK_DESCENT, Integrator::BlockDescent { iterations: 4 }, Integrator::Rk4];

/// The particle at the middle of the flag's free edge.
pub(crate) const FLAG_PROBE: usize = 16 * 48 + 47;

/// The largest peak of the spectrum of `x` (sampled every `dt` seconds, its mean removed)
/// away from zero frequency: `(frequency in Hz, amplitude)`, by a plain DFT.
pub(crate) fn spectral_peak(x: &[f32], dt: f32) -> (f64, f64) {
    let n = x.len();
    let mean = x.iter().map(|&v| f64::from(v)).sum::<f64>() / n as f64;
    (1..n / 2)
        .map(|k| {
            let (re, im) = x.iter().enumerate().fold((0.0f64, 0.0f64), |(re, im), (j, &v)| {
                let angle = -std::f64::consts::TAU * (k * j) as f64 / n as f64;
                (re + (f64::from(v) - mean) * angle.cos(), im + (f64::from(v) - mean) * angle.sin())
            });
            (k as f64 / (n as f64 * f64::from(dt)), 2.0 * re.hypot(im) / n as f64)
        })
        .fold((0.0, 0.0), |best, peak| if peak.1 > best.1 { peak } else { best })
}

/// The standard deviation of `x`: a flutter's swing, which, unlike the height of its
/// spectrum's peak, a flutter that is no sinusoid does not spread over neighbouring frequencies.
pub(crate) fn swing(x: &[f32]) -> f64 {
    let n = x.len() as f64;
    let mean = x.iter().map(|&v| f64::from(v)).sum::<f64>() / n;
    (x.iter().map(|&v| (f64::from(v) - mean).powi(2)).sum::<f64>() / n).sqrt()
}

/// Kinetic energy in joules.
pub(crate) fn kinetic_energy(sim: &ClothSim) -> f64 {
    sim.velocities().iter().enumerate().map(|(i, v)| 0.5 * f64::from(sim.particle_mass(i) * v.length_squared())).sum()
}

/// Ticks the flag settles in the wind before its flutter is sampled, and ticks sampled.
pub(crate) const SETTLE: u32 = 240;

pub(crate) const SAMPLES: usize = 720;

/// The flag stepped by `integrator` on the CPU in a steady 8 m/s wind along its plane: after
/// [`SETTLE`] ticks, the cross-wind position of the middle of its free edge and its kinetic
/// energy at each of [`SAMPLES`] ticks.
pub(crate) fn flutter_on_cpu(integrator: Integrator) -> (Vec<f32>, Vec<f64>) {
    flutter_of(flag(integrator))
}

/// [`flutter_on_cpu`] for a flag built already.
pub(crate) fn flutter_of(mut sim: ClothSim) -> (Vec<f32>, Vec<f64>) {
    sim.set_wind(Wind::steady(Vec3::new(8.0, 0.0, 0.0)), &[]).expect("a valid wind");
    let (mut z, mut energy) = (Vec::new(), Vec::new());
    for tick in 0..SETTLE as usize + SAMPLES {
        sim.tick(TICK, &[]);
        if tick >= SETTLE as usize {
            z.push(sim.position(FLAG_PROBE).z);
            energy.push(kinetic_energy(&sim));
        }
    }
    (z, energy)
}

pub(crate) fn wind(single: &rayon::ThreadPool, threads: usize) {
    println!("\n## Wind: drag and lift\n");
    print_flag_setup();
    for integrator in FLUTTER_INTEGRATORS {
        let (z, energy) = flutter_on_cpu(integrator);
        print_flutter("CPU", integrator, &z, &energy);
    }

    println!("\n### Cost: a 64 x 64 cloth (1.4 m) hanging from two corners in gusty wind\n");
    println!(
        "After 1 s in `Wind::gusty` (8 m/s), the same state ticks with and without drag and lift, alternating, best of 9 each (ms per 60 Hz tick, block descent, Looper 16): the wind sampled once a tick, drag and lift once a substep.\n"
    );
    println!("| threads | tick without aerodynamics ms | tick with ms | aerodynamics / rest of the tick |");
    println!("|---|---|---|---|");
    let (without, with) = hanging_in_gusts();
    print_with_and_without(single, threads, &without, &with, &[], 9);
}

/// The flutter table's description and header.
pub(crate) fn print_flag_setup() {
    println!(
        "A flag of 1.5 m x 1 m (48 x 32 particles, 0.3 kg, SpringK 400, Looper 16, drag 1.2, lift 0.8) held along a vertical pole, in a steady 8 m/s wind along its plane. After {:.0} s, the cross-wind (z) position of the middle of its free edge is sampled every tick for {:.0} s; its spectrum's largest peak away from zero frequency is the flutter (the peak's height its amplitude), its standard deviation the swing, and the mean kinetic energy of the two halves of that window shows whether it grows.\n",
        SETTLE as f32 * TICK,
        SAMPLES as f32 * TICK
    );
    println!(
        "| backend | integrator | flutter Hz | amplitude mm | swing mm | kinetic energy, first half J | second half J |"
    );
    println!("|---|---|---|---|---|---|---|");
}

/// One row of the flutter table: the free edge's spectral peak and the window's energy halves.
pub(crate) fn print_flutter(backend: &str, integrator: Integrator, z: &[f32], energy: &[f64]) {
    let (hz, amplitude) = spectral_peak(z, TICK);
    let half = energy.len() / 2;
    let mean = |e: &[f64]| e.iter().sum::<f64>() / e.len() as f64;
    println!(
        "| {backend} | {integrator:?} | {hz:.2} | {:.1} | {:.1} | {:.4} | {:.4} |",
        amplitude * 1e3,
        swing(z) * 1e3,
        mean(&energy[..half]),
        mean(&energy[half..])
    );
}

/// The wind-cost scene: a 64 x 64 cloth (1.4 m) hanging from two corners after 1 s in gusty
/// wind, without and with drag and lift from that state.
pub(crate) fn hanging_in_gusts() -> (ClothSim, ClothSim) {
    let grid = Arc::new(ClothTopology::grid(square_grid(64)).expect("a valid grid"));
    let params =
        ClothParams { aerodynamics: Aerodynamics::FABRIC, integrator: Integrator::BLOCK_DESCENT, ..Default::default() };
    let pose = Affine3A::from_translation(Vec3::new(0.0, 2.0, 0.0)) * Affine3A::from_rotation_x(0.3);
    let mut with = ClothSim::new(params, grid, pose, &[0, 63]).expect("a valid cloth");
    with.set_wind(Wind::gusty(Vec3::new(8.0, 0.0, 2.0)), &[]).expect("a valid wind");
    for _ in 0..(1.0 / TICK).round() as u32 {
        with.tick(TICK, &[]);
    }
    let mut without = with.clone();
    without.set_params(ClothParams { aerodynamics: Aerodynamics::NONE, ..with.params().clone() }).expect("valid");
    (without, with)
}

/// Wind on the GPU (the `wind_gpu` section, after `wind`): the flag's flutter, the GPU against
/// the CPU in gusty wind, and what drag and lift cost.
pub(crate) fn wind_on_gpu(bunny: &ObjMesh, gpu: Option<&Gpu>) {
    println!("\n### Flutter on the GPU\n");
    let Some(gpu) = gpu else {
        println!("No GPU adapter.");
        return;
    };
    print_flag_setup();
    let none = GpuColliders::new(&gpu.device, &[]);
    let steady = Wind::steady(Vec3::new(8.0, 0.0, 0.0));
    for integrator in FLUTTER_INTEGRATORS {
        let mut sim = flag(integrator);
        sim.set_wind(steady, &[]).expect("a valid wind");
        let (mut batch, id) = alone_on_gpu(gpu, &sim);
        let (mut z, mut energy) = (Vec::new(), Vec::new());
        run_on_gpu(gpu, &mut batch, &none, SETTLE);
        for _ in 0..SAMPLES {
            run_on_gpu(gpu, &mut batch, &none, 1);
            load_gpu_particles(&mut sim, &particles_on_gpu(gpu, &batch, id));
            z.push(sim.position(FLAG_PROBE).z);
            energy.push(kinetic_energy(&sim));
        }
        print_flutter(&format!("GPU ({})", gpu.info.name), integrator, &z, &energy);
    }

    println!("\n### GPU against CPU in gusty wind\n");
    println!(
        "The flag (block descent, without tethers) in `Wind::gusty` (8 m/s, 40% gusts, 1.6 m/s turbulence), 90 ticks; before each tick the GPU takes the CPU's state, and both sample the wind at the same clock time. Largest distance between the two after one tick:\n"
    );
    // Without tethers: a particle that reaches its tether's length loses its outward speed at
    // once, and rounding can move that jump by a substep, on the CPU alone too.
    let mut sim = flag(Integrator::BLOCK_DESCENT);
    sim.set_params(ClothParams { tethers: None, ..sim.params().clone() }).expect("valid parameters");
    sim.set_wind(Wind { seed: 3, ..Wind::gusty(Vec3::new(8.0, 0.0, 1.0)) }, &[]).expect("a valid wind");
    let (mut batch, id) = alone_on_gpu(gpu, &sim);
    let mut worst = 0.0f32;
    for _ in 0..90 {
        batch.upload_state(&gpu.queue, id, &sim);
        batch.set_wind_clock(sim.wind_time(), TICK, 1);
        sim.tick(TICK, &[]);
        run_on_gpu(gpu, &mut batch, &none, 1);
        for (i, p) in particles_on_gpu(gpu, &batch, id).iter().enumerate() {
            let on_gpu = Vec3::new(p.position[0], p.position[1], p.position[2]);
            worst = worst.max(on_gpu.distance(sim.position(i)));
        }
    }
    println!("| adapter | largest gap m |\n|---|---|\n| {} | {worst:.1e} |", gpu.info.name);

    println!("\n### Cost on the GPU: the 64 x 64 cloth hanging in gusty wind\n");
    println!(
        "The same two states as the CPU's cost table, each alone in a batch: GPU ms per tick by timestamp queries, each dispatch in a compute pass of its own, summed, median of 9 ticks (the cloth stays clear of the bunny, which is only there because the profile needs a collider). Block descent takes its kick in its own prediction (`vbd_predict_air`), so the cost is the difference between the two ticks, not one kernel's time.\n"
    );
    println!("| adapter | tick without aerodynamics ms | tick with ms | aerodynamics / rest of the tick |");
    println!("|---|---|---|---|");
    let (without, with) = hanging_in_gusts();
    let far_away =
        collider(bunny, 5).with_pose(ColliderPose { translation: Vec3::new(50.0, 0.0, 0.0), ..Default::default() });
    match (
        kernel_ms(gpu, &far_away, std::slice::from_ref(&without)),
        kernel_ms(gpu, &far_away, std::slice::from_ref(&with)),
    ) {
        (Some((_, off)), Some((_, on))) => {
            println!("| {} | {off:.3} | {on:.3} | {:.0}% |", gpu.info.name, (on - off) / off * 100.0)
        }
        _ => println!("| {} | no timestamp queries | | |", gpu.info.name),
    }
    if gpu.is_software() {
        println!("\nThe GPU here is a software adapter on the same CPU cores: its times are not GPU figures.");
    }
}
