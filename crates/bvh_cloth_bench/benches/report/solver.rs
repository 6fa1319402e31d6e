//! The sections `solver` and `solver_gpu`: block descent against RK4 for the same sag,
//! across stiffness, and big cloths on the GPU.

use super::*;

/// A `side x side` cloth 1 m wide hanging from its two first-row corners, 2 m up.
pub(crate) fn hanging(side: u32, params: ClothParams) -> ClothSim {
    let topology = Arc::new(ClothTopology::grid(ClothGrid::new(Vec2::ONE, UVec2::splat(side))).expect("a valid grid"));
    let pose = Affine3A::from_translation(Vec3::new(0.0, 2.0, 0.0));
    ClothSim::new(params, topology, pose, &[0, side - 1]).expect("valid cloth")
}

/// How far the middle of the last row hangs below the pins.
pub(crate) fn sag_of(sim: &ClothSim) -> f32 {
    let grid = *sim.topology().stencil().expect("a grid");
    2.0 - sim.position(grid.index(grid.rows - 1, grid.cols / 2)).y
}

/// The solvers head to head: block descent against RK4 for the same sag on the CPU, the cost of
/// stiffness for each, and big cloth on the GPU.
pub(crate) fn solver(single: &rayon::ThreadPool, threads: usize) {
    println!("\n## Solvers: a 64x64 cloth hanging from two corners, settled for 8 s (SpringK 200, damping 2)\n");
    println!(
        "| integrator | Looper | substeps/tick | sag m | sag vs RK4 | CPU 1 thread ms/tick | CPU {threads} threads ms/tick | speed-up (1 thread) |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    let base = ClothParams { damping: 2.0, ..Default::default() };
    let settle = |params: ClothParams| {
        let mut sim = hanging(64, params);
        for _ in 0..(8.0 / TICK) as u32 {
            sim.tick(TICK, &[]);
        }
        sim
    };
    let tick_ms = |sim: &ClothSim| {
        // Best of 5 runs of 10 ticks, in ms per tick.
        let run = |sim: &mut ClothSim| {
            best_of(5, || {
                for _ in 0..10 {
                    sim.tick(TICK, &[]);
                }
            }) * 1e2
        };
        (single.install(|| run(&mut sim.clone())), run(&mut sim.clone()))
    };
    let cases = [
        (Integrator::Rk4, 16),
        (Integrator::BLOCK_DESCENT, 16),
        (Integrator::BLOCK_DESCENT, 8),
        (Integrator::BLOCK_DESCENT, 4),
        (Integrator::BLOCK_DESCENT, 2),
        (Integrator::BlockDescent { iterations: 2 }, 4),
    ];
    let mut reference = None;
    for (integrator, looper) in cases {
        let sim = settle(ClothParams { integrator, looper, ..base.clone() });
        let sag = sag_of(&sim);
        let (one, all) = tick_ms(&sim);
        let (ref_sag, ref_ms) = *reference.get_or_insert((sag, one));
        println!(
            "| {integrator:?} | {looper} | {} | {sag:.4} | {:+.2} % | {one:.3} | {all:.3} | {:.1}x |",
            sim.substeps(TICK),
            100.0 * (sag - ref_sag) / ref_sag,
            ref_ms / one
        );
    }

    println!("\n### Stiffness: the same cloth at Looper 16, ms per tick (1 thread) after 1 s of hanging\n");
    println!(
        "| SpringK N/m | RK4 substeps/tick | RK4 ms/tick | block descent substeps/tick | block descent ms/tick | block descent finite after 1 s |"
    );
    println!("|---|---|---|---|---|---|");
    for spring_k in [20.0f32, 200.0, 2_000.0, 20_000.0, 200_000.0] {
        let run = |integrator: Integrator| {
            let mut sim = hanging(64, ClothParams { spring_k, integrator, ..base.clone() });
            for _ in 0..60 {
                sim.tick(TICK, &[]);
            }
            let ms = single.install(|| best_of(3, || _ = sim.clone().tick(TICK, &[])) * 1e3);
            (sim.substeps(TICK), ms, sim.is_finite())
        };
        let (rk_steps, rk_ms, _) = run(Integrator::Rk4);
        let (bd_steps, bd_ms, finite) = run(Integrator::BLOCK_DESCENT);
        println!("| {spring_k} | {rk_steps} | {rk_ms:.3} | {bd_steps} | {bd_ms:.3} | {finite} |");
    }

    println!(
        "\n### Resolution: block descent at Looper 16 from 8x8 to 1024x1024, the panel's softest and stiffest SpringK\n"
    );
    println!(
        "| cloth | SpringK N/m | ticks | substeps per tick (all ticks) | finite | fastest particle m/s | lowest point m below the pins |"
    );
    println!("|---|---|---|---|---|---|---|");
    for side in [8u32, 64, 256, 1024] {
        for spring_k in [10.0f32, 400.0] {
            let mut sim =
                hanging(side, ClothParams { spring_k, integrator: Integrator::BLOCK_DESCENT, ..base.clone() });
            let ticks = if side >= 1024 { 3 } else { 60 };
            let substeps: Vec<u32> = (0..ticks).map(|_| sim.tick(TICK, &[]).substeps).collect();
            let same = if substeps.iter().all(|&n| n == substeps[0]) {
                format!("{}", substeps[0])
            } else {
                format!("{substeps:?}")
            };
            let speed = sim.velocities().iter().map(|v| v.length()).fold(0.0f32, f32::max);
            let lowest = sim.positions().iter().map(|p| p.y).fold(f32::INFINITY, f32::min);
            println!(
                "| {side}x{side} | {spring_k} | {ticks} | {same} | {} | {speed:.2} | {:.3} |",
                sim.is_finite(),
                2.0 - lowest
            );
        }
    }
}

/// Big cloth on the GPU: RK4, block descent and the multigrid integrator per tick on the dragon
/// at n = 16 (the `solver_gpu` section, after `solver`).
pub(crate) fn solver_on_gpu(meshes: &[ObjMesh], gpu: Option<&Gpu>) {
    println!("\n### Big cloth on the GPU: ms per 60 Hz tick on the dragon at n = 16, Looper 16\n");
    let Some(gpu) = gpu else {
        println!("No GPU adapter: skipped.");
        return;
    };
    let dragon = collider(&meshes[1], 16);
    let sizes: &[u32] = if gpu.is_software() { &[64, 128] } else { &[64, 256, 1024] };
    let timed = gpu.device.features().contains(wgpu::Features::TIMESTAMP_QUERY);
    let clock = if timed { "GPU ms (timestamps)" } else { "ms (wall)" };
    println!(
        "| cloth | RK4 substeps | RK4 {clock} | block descent substeps | block descent {clock} | of it vbd_solve | \
         speed-up | multigrid {clock} | of it the correction | multigrid / block descent |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for &size in sizes {
        let rk4 = cloth_above(&dragon, size, Integrator::Rk4);
        let descent = cloth_above(&dragon, size, Integrator::BLOCK_DESCENT);
        let multigrid = cloth_above(&dragon, size, Integrator::Multigrid);
        let tick = |cloth: &ClothSim, part: usize| match kernel_ms(gpu, &dragon, std::slice::from_ref(cloth)) {
            Some((column, total)) => (total, format!("{:.3}", column[part])),
            None => (gpu_sim_frame_ms(gpu, std::slice::from_ref(&dragon), cloth, 1), "-".into()),
        };
        let ((rk_ms, _), (bd_ms, solve)) = (tick(&rk4, 4), tick(&descent, 4));
        let (mg_ms, correction) = tick(&multigrid, kernel_column(Kernel::Multigrid));
        println!(
            "| {size}x{size} | {} | {rk_ms:.3} | {} | {bd_ms:.3} | {solve} | {:.1}x | {mg_ms:.3} | {correction} | {:.2}x |",
            rk4.substeps(TICK),
            descent.substeps(TICK),
            rk_ms / bd_ms,
            mg_ms / bd_ms
        );
    }
    if gpu.is_software() {
        println!("\nThe GPU here is a software adapter on the same CPU cores: its times are not GPU figures.");
    }
}
