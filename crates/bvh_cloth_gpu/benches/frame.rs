//! The paper's Table VII setup on the GPU kernels: a 64 x 64 cloth (Looper 16, one 60 Hz tick
//! per frame) draped over the bunny and the dragon at n = 1, 3, 5. Prints a markdown table of
//! wall time per frame around a blocking submit, with the CPU stepper's time for the same frame
//! measured in the same run, and the paper's own figures quoted beside them.
//!
//! `WGPU_BACKEND=vulkan cargo bench -p bvh_cloth_gpu --bench frame`

use std::time::Instant;

use bvh_cloth_core::obj::parse_obj;
use bvh_cloth_core::{Affine3A, ClothParams, ClothSim, Collider, Vec3};
use bvh_cloth_gpu::{ClothKernels, GpuCloth, GpuColliders, headless};

const TICK: f32 = 1.0 / 60.0;
/// Frames timed per case, after one simulated second of falling and landing.
const FRAMES: u32 = 60;

/// The paper's Table VII (GTX 1650, quoted, not rerun): its method's ms per frame at n = 1, 3, 5.
const PAPER: [(&str, [f32; 3]); 2] = [("bunny", [8.0, 12.0, 12.0]), ("dragon", [13.0, 13.0, 15.0])];

fn median(mut samples: Vec<f64>) -> f64 {
    samples.sort_by(f64::total_cmp);
    samples[samples.len() / 2]
}

fn main() {
    let Some((adapter, device, queue)) = headless::device() else {
        eprintln!("no GPU adapter: set WGPU_BACKEND (vulkan for lavapipe) and install a driver");
        std::process::exit(1);
    };
    let kernels = ClothKernels::new(&device).expect("the kernels fit the device");
    let info = adapter.get_info();
    println!(
        "GPU: {} ({:?}, driver {}); CPU threads: {}",
        info.name,
        info.device_type,
        info.driver_info,
        cpu_threads()
    );
    println!();
    println!("| model | n | spheres | GPU ms/frame | CPU ms/frame | CPU / GPU | paper ms/frame (GTX 1650, quoted) |");
    println!("|---|---|---|---|---|---|---|");
    for (model, (_, paper)) in ["bunny", "dragon"].into_iter().zip(PAPER) {
        let path = format!("{}/../../assets/models/{model}.obj", env!("CARGO_MANIFEST_DIR"));
        let mesh = parse_obj(&std::fs::read_to_string(path).expect("model file")).expect("valid OBJ");
        for (k, n) in [1u32, 3, 5].into_iter().enumerate() {
            let collider = Collider::from_mesh(mesh.as_mesh_ref(), n).unwrap().with_margin(0.01).with_friction(1.0);
            let colliders = [collider];
            let top = colliders[0].lbvh.bounds().unwrap().1.y;
            let params = ClothParams { rows: 64, cols: 64, size: 1.4, damping: 1.0, ..Default::default() };
            let mut cpu =
                ClothSim::new(params, Affine3A::from_translation(Vec3::new(-0.2, top + 0.3, 0.0)), &[]).unwrap();
            let gpu_colliders = GpuColliders::new(&device, &colliders);
            let mut gpu = GpuCloth::new(&device, &kernels, &cpu).unwrap();
            gpu.set_params(&queue, cpu.params(), TICK, &gpu_colliders);

            let gpu_frame = |ticks: u32| {
                let start = Instant::now();
                let mut encoder = device.create_command_encoder(&Default::default());
                gpu.encode_ticks(&device, &mut encoder, &kernels, &gpu_colliders, ticks);
                queue.submit([encoder.finish()]);
                headless::wait(&device);
                start.elapsed().as_secs_f64() * 1e3
            };
            gpu_frame(60); // fall and land
            let gpu_ms = median((0..FRAMES).map(|_| gpu_frame(1)).collect());

            for _ in 0..60 {
                cpu.tick(TICK, &colliders);
            }
            let cpu_ms = median(
                (0..FRAMES)
                    .map(|_| {
                        let start = Instant::now();
                        cpu.tick(TICK, &colliders);
                        start.elapsed().as_secs_f64() * 1e3
                    })
                    .collect(),
            );
            println!(
                "| {model} | {n} | {} | {gpu_ms:.2} | {cpu_ms:.2} | {:.2} | {} |",
                colliders[0].sphere_count(),
                cpu_ms / gpu_ms,
                paper[k]
            );
        }
    }
}

fn cpu_threads() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}
