//! The sections `step_scaling`, `topology` and `build_scaling`: step time against cloth size,
//! an authored mesh against the grid, and the collider build against the resolution.

use super::*;

/// Step time against cloth size: ns per particle per substep, on the bunny at n = 5.
pub(crate) fn step_scaling(gpu: Option<&Gpu>, single: &rayon::ThreadPool, threads: usize) {
    println!("\n## Scaling with cloth size: ns per particle per substep, falling onto the bunny (n = 5)\n");
    println!("| integrator | cloth | CPU 1 thread | CPU {threads} threads | GPU |");
    println!("|---|---|---|---|---|");
    let bunny = [collider(&model("bunny"), 5)];
    let gpu_sizes: &[u32] =
        if gpu.is_some_and(|g| !g.is_software()) { &[32, 64, 128, 256, 512, 1024] } else { &[32, 64, 128] };
    for integrator in [Integrator::Rk4, Integrator::SemiImplicitEuler] {
        for size in [32u32, 64, 128, 256, 512, 1024] {
            let particles = f64::from(size * size);
            let ns = |seconds: f64, substeps: f64| seconds * 1e9 / (particles * substeps);
            let cpu = (size <= 256).then(|| {
                let sim = cloth_above(&bunny[0], size, integrator);
                let substeps = f64::from(sim.params().looper);
                let run = |sim: &mut ClothSim| ns(best_of(5, || _ = sim.tick(TICK, &bunny)), substeps);
                (single.install(|| run(&mut sim.clone())), run(&mut sim.clone()))
            });
            let gpu_ns = gpu.filter(|_| gpu_sizes.contains(&size) && integrator == Integrator::Rk4).map(|gpu| {
                let looper = cloth_above(&bunny[0], size, integrator).params().looper;
                ns(gpu_frame_ms(gpu, &bunny, size, 1) * 1e-3, f64::from(looper))
            });
            if cpu.is_none() && gpu_ns.is_none() {
                continue;
            }
            let (one, all) = cpu.map_or(("-".into(), "-".into()), |(a, b)| (format!("{a:.1}"), format!("{b:.1}")));
            let gpu_ns = gpu_ns.map_or("-".into(), |g| format!("{g:.2}"));
            println!("| {integrator:?} | {size}x{size} | {one} | {all} | {gpu_ns} |");
        }
    }
    println!(
        "\n- means not run: the CPU stops at 256x256; the GPU runs RK4 only, up to 1024x1024 on a hardware GPU and 128x128 on a software one."
    );
}

/// The cost of any topology: ns per particle per substep of an RK4 cloth falling onto the bunny
/// (n = 5), for the grid on its fast path, the grid's springs through the general per-particle
/// path, and the grid's triangles built as an authored mesh, at the same particle count.
pub(crate) fn topology(gpu: Option<&Gpu>, single: &rayon::ThreadPool, threads: usize) {
    println!("\n## Any topology: ns per particle per substep, RK4, falling onto the bunny (n = 5)\n");
    println!("| cloth | springs | CPU 1 thread | CPU {threads} threads | GPU |");
    println!("|---|---|---|---|---|");
    let bunny = [collider(&model("bunny"), 5)];
    for size in [64u32, 128] {
        let cases = [
            ("grid, fast path", ClothTopology::grid(square_grid(size)).expect("a valid grid")),
            ("grid, general path", ClothTopology::grid_as_mesh(square_grid(size)).expect("a valid grid")),
            ("authored mesh", authored_grid(size)),
        ];
        for (name, t) in cases {
            let springs = t.spring_count();
            let sim = topology_above(&bunny[0], t, Integrator::Rk4);
            let substeps = f64::from(sim.params().looper);
            let ns = |seconds: f64| seconds * 1e9 / (sim.len() as f64 * substeps);
            let run = |sim: &mut ClothSim| ns(best_of(5, || _ = sim.tick(TICK, &bunny)));
            let (one, all) = (single.install(|| run(&mut sim.clone())), run(&mut sim.clone()));
            // The GPU has one path for every topology; the grid's fast path is the CPU's.
            let gpu_ns = gpu
                .filter(|_| name != "grid, fast path")
                .map_or("-".into(), |gpu| format!("{:.2}", ns(gpu_sim_frame_ms(gpu, &bunny, &sim, 1) * 1e-3)));
            println!("| {size}x{size} {name} | {springs} | {one:.1} | {all:.1} | {gpu_ns} |");
        }
    }
}

/// Collider build time (voxel spheres + LBVH, all threads) against n.
pub(crate) fn build_scaling(meshes: &[ObjMesh]) {
    println!("\n## Collider build (voxel spheres + LBVH), all threads, best of 9\n");
    print!("| model | vertices |");
    for n in RESOLUTIONS.iter().chain(&[128]) {
        print!(" n = {n} |");
    }
    println!("\n|---|---|{}", "---|".repeat(RESOLUTIONS.len() + 1));
    for (name, mesh) in MODELS.iter().zip(meshes) {
        print!("| {name} | {} |", mesh.positions.len());
        for &n in RESOLUTIONS.iter().chain(&[128]) {
            let ms = best_of(9, || _ = std::hint::black_box(collider(mesh, n))) * 1e3;
            print!(" {ms:.2} ms |");
        }
        println!();
    }
}
