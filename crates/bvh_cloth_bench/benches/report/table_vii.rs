//! The section `table_vii`: the paper's Table VII, ms per frame of a 64 x 64 cloth on the
//! bunny and the dragon at n = 1, 3, 5, on the CPU and the GPU.

use super::*;

/// The paper's Table VII (GTX 1650, quoted, not rerun): its method's ms per frame at n = 1, 3, 5.
pub(crate) const PAPER_MS: [[f64; 3]; 2] = [[8.0, 12.0, 12.0], [13.0, 13.0, 15.0]];

/// Table VII: ms per frame (one 60 Hz tick of Looper = 16 RK4 substeps, collision included).
pub(crate) fn table_vii(meshes: &[ObjMesh], gpu: Option<&Gpu>, single: &rayon::ThreadPool, threads: usize) {
    println!("\n## Table VII: 64 x 64 cloth, Looper 16, one 60 Hz tick per frame (median of {FRAMES} frames)\n");
    println!(
        "| model | n | spheres | CPU 1 thread ms | CPU {threads} threads ms | CPU substeps/s ({threads} threads) | GPU ms | paper ms (GTX 1650, quoted) |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for (m, mesh) in meshes.iter().enumerate() {
        for (k, n) in [1u32, 3, 5].into_iter().enumerate() {
            let colliders = [collider(mesh, n)];
            let landed = drape(&colliders[0], 1.0);
            let frames = |sim: &mut ClothSim| -> f64 {
                median((0..FRAMES).map(|_| time(|| _ = sim.tick(TICK, &colliders)) * 1e3).collect())
            };
            let one = single.install(|| frames(&mut landed.clone()));
            let all = frames(&mut landed.clone());
            let substeps = f64::from(landed.params().looper);
            let gpu_ms = gpu.map_or("no adapter".into(), |gpu| format!("{:.2}", gpu_frame_ms(gpu, &colliders, 64, 1)));
            println!(
                "| {} | {n} | {} | {one:.2} | {all:.2} | {:.0} | {gpu_ms} | {} |",
                MODELS[m],
                colliders[0].sphere_count(),
                substeps * 1e3 / all,
                PAPER_MS[m][k]
            );
        }
    }
    println!("\nQuoted from the same table of the paper: Kim et al. 2019 took 17-25 ms, Unity Cloth 211-247 ms.");
    if gpu.is_some_and(|g| g.is_software()) {
        println!("The GPU here is a software adapter on the same CPU cores: its column is not a GPU figure.");
    }
}
