//! The sections `gpu_profile` (GPU ms per tick by kernel) and `many_cloths` (one batch for
//! many small cloths against a batch each).

use super::*;

/// GPU time per 60 Hz tick by kernel, from timestamp queries written around each dispatch
/// (each in a compute pass of its own), median of 9 ticks after a second of falling; where the
/// adapter has no timestamp queries, the wall time around a blocking submit, marked as such.
pub(crate) fn gpu_profile(meshes: &[ObjMesh], gpu: Option<&Gpu>) {
    println!("\n## GPU profile: ms per 60 Hz tick by kernel, RK4 Looper 16, at n = 5\n");
    let Some(gpu) = gpu else {
        println!("No GPU adapter: skipped.");
        return;
    };
    let timed = gpu.device.features().contains(wgpu::Features::TIMESTAMP_QUERY);
    let many = if gpu.is_software() { 8 } else { 128 };
    let scenes: Vec<(String, Collider, Vec<ClothSim>)> = MODELS
        .iter()
        .zip(meshes)
        .map(|(name, mesh)| {
            let c = collider(mesh, 5);
            let cloth = cloth_above(&c, 64, Integrator::Rk4);
            (format!("one 64x64 on the {name}"), c, vec![cloth])
        })
        .chain(std::iter::once({
            let c = collider(&meshes[0], 5);
            let cloths = (0..many)
                .map(|k| {
                    let mut sim = cloth_above(&c, 32, Integrator::Rk4);
                    sim.reset(Affine3A::from_translation(Vec3::new(-0.2, 1.3 + 0.05 * k as f32, 0.0)));
                    sim
                })
                .collect();
            (format!("{many} of 32x32 on the bunny"), c, cloths)
        }))
        .collect();
    if !timed {
        println!("The adapter has no timestamp queries: wall time around a blocking submit, all kernels together.\n");
        println!("| scene | particles | tick ms (wall) |");
        println!("|---|---|---|");
        for (name, c, cloths) in &scenes {
            let ms = gpu_cloths_frame_ms(gpu, std::slice::from_ref(c), cloths, true, 1, 9);
            println!("| {name} | {} | {ms:.3} |", cloths.iter().map(ClothSim::len).sum::<usize>());
        }
        return;
    }
    println!(
        "| scene | particles | apply_anchors | node_update (stages 1-3) | node_update_final (stage 4 + collision) | tick ms (GPU) |"
    );
    println!("|---|---|---|---|---|---|");
    for (name, c, cloths) in &scenes {
        let Some((column, total)) = kernel_ms(gpu, c, cloths) else {
            println!("| {name} | too many dispatches to time |");
            continue;
        };
        println!(
            "| {name} | {} | {:.3} | {:.3} | {:.3} | {total:.3} |",
            cloths.iter().map(ClothSim::len).sum::<usize>(),
            column[0],
            column[1],
            column[2]
        );
    }
    println!("\nEach dispatch is timed in a compute pass of its own; a tick without profiling is one pass.");
    if gpu.is_software() {
        println!("The GPU here is a software adapter on the same CPU cores: its times are not GPU figures.");
    }
}

/// Many cloths at once: ms per 60 Hz tick for 1 to 512 cloths of 16 x 16, 32 x 32 and 64 x 64
/// (Looper 16, RK4), stacked 5 cm apart above the bunny at n = 5 and timed after a second of
/// falling, all in one batch and each in a batch of its own.
pub(crate) fn many_cloths(gpu: Option<&Gpu>) {
    println!(
        "
## Many cloths: ms per 60 Hz tick, RK4 Looper 16, above the bunny (n = 5), wall time around a blocking submit
"
    );
    let Some(gpu) = gpu else {
        println!("No GPU adapter: skipped.");
        return;
    };
    println!("| cloth | cloths | particles | one batch ms | a batch per cloth ms | per cloth / one batch |");
    println!("|---|---|---|---|---|---|");
    let bunny = [collider(&model("bunny"), 5)];
    // A software adapter runs on the CPU cores: it stops at 8,192 particles.
    let most = if gpu.is_software() { 8 * 1024 } else { 4 * 1024 * 1024 };
    // Untimed: the first dispatches of a pipeline may compile it.
    gpu_cloths_frame_ms(gpu, &bunny, &[cloth_above(&bunny[0], 16, Integrator::Rk4)], true, 1, 1);
    for size in [16u32, 32, 64] {
        for count in [1usize, 8, 32, 128, 512] {
            let particles = count * (size * size) as usize;
            if particles > most {
                continue;
            }
            let cloths: Vec<ClothSim> = (0..count)
                .map(|k| {
                    let mut sim = cloth_above(&bunny[0], size, Integrator::Rk4);
                    sim.reset(Affine3A::from_translation(Vec3::new(-0.2, 1.3 + 0.05 * k as f32, 0.0)));
                    sim
                })
                .collect();
            let samples = if gpu.is_software() || particles > 256 * 1024 { 5 } else { 15 };
            let one = gpu_cloths_frame_ms(gpu, &bunny, &cloths, true, 1, samples);
            let each = gpu_cloths_frame_ms(gpu, &bunny, &cloths, false, 1, samples);
            println!("| {size}x{size} | {count} | {particles} | {one:.3} | {each:.3} | {:.1}x |", each / one);
        }
    }
    if gpu.is_software() {
        println!(
            "
The GPU here is a software adapter on the same CPU cores: only the ratios mean anything."
        );
    }
}
