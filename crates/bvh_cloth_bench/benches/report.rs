//! The benchmark report: prints markdown tables, and writes the data of the plot as CSV.
//!
//! 1. The paper's Table VII: a 64 x 64 cloth on the bunny and the dragon at n = 1, 3, 5, per
//!    frame, on the CPU backend (1 thread and all threads) and the GPU kernels.
//! 2. Particle queries head to head: our LBVH, brute force over the same spheres, and parry3d's
//!    exact triangle-mesh projection, on the same draped particle positions.
//! 3. Collider fidelity: cloths resting on the spheres, measured against the true mesh.
//! 4. Scaling: step time against cloth size; the cost of any topology (an authored mesh against
//!    the grid at the same particle count); collider build time against n.
//! 5. The GPU profile: GPU ms per tick by kernel (timestamp queries), and many cloths: one
//!    GPU batch against a batch per cloth, 1 to 512 cloths.
//! 6. Precision far from the origin: how far from it a stiff cloth still steps finitely.
//! 7. The solvers: block descent against RK4 for the same sag, across stiffness, and big cloth
//!    on the GPU.
//! 8. Exact primitives against voxelised meshes: collision cost per particle.
//! 9. Skinned colliders: one frame's refit against skinning the mesh's vertices.
//! 10. Exact contact against sphere contact: the resting air gap; its point query against
//!     parry3d's bounded projection, on a draped cloth and on points near the surface, and its
//!     build and memory up to 2 million triangles ([`exact_queries`], `exact_contact_queries`,
//!     `exact_contact_build`).
//! 11. Self-contact: a cloth folding over a bar and two cloths on the bunny, checked with an
//!     exact triangle–triangle test, and its cost.
//! 12. Wind: a flag's flutter in steady wind (the free edge's spectral peak) and its energy on
//!     both backends, GPU against CPU in gusty wind, and what drag and lift cost.
//! 13. Motion ([`motion`]): each solver setting's free fall and drift against the analytic
//!     answer, a hanging cloth's sag and strain in motion against RK4 from 32 x 32 to 256 x 256,
//!     and the flag's flutter; and what the tethers cost a tick (`motion_cost`).
//!
//! `WGPU_BACKEND=vulkan cargo bench -p bvh_cloth_bench --bench report`
//! (without a GPU adapter the GPU columns say so and the rest still runs). Append `-- NAME...`
//! to run only the sections whose name contains one of the NAMEs: `table_vii`, `queries`,
//! `fidelity`, `step_scaling`, `topology`, `gpu_profile`, `many_cloths`, `build_scaling`,
//! `far_from_origin`, `solver`, `solver_gpu`, `primitives`, `skinned_refit`, `exact_contact`,
//! `exact_contact_queries`, `exact_contact_build`, `exact_contact_gpu`, `self_contact`,
//! `self_contact_gpu`, `wind`, `wind_gpu`, `motion`, `motion_cost`. The
//! GPU halves of the solver, exact-contact, self-contact and wind tables are sections of their
//! own, so `-- gpu` runs every GPU-only table without their CPU simulations.

#[path = "report/exact_queries.rs"]
mod exact_queries;
#[path = "report/motion.rs"]
mod motion;

use std::fmt::Write as _;
use std::sync::Arc;

use bvh_cloth_bench::{
    MODELS, TICK, authored_grid, best_of, cloth_above, collider, drape, median, model, square_grid, time,
    topology_above,
};
use bvh_cloth_core::obj::ObjMesh;

use bvh_cloth_core::collision::ColliderFrame;
use bvh_cloth_core::gpu_layout::{GpuParticle, load_gpu_particles};
use bvh_cloth_core::self_contact::{ContactSolver, SelfContact};
use bvh_cloth_core::skinning::{SkinRef, SkinScratch, SkinnedVertices};
use bvh_cloth_core::triangles::crossing_pairs;
use bvh_cloth_core::{
    Aerodynamics, Affine3A, ClothGrid, ClothParams, ClothSim, ClothTopology, Collider, ColliderPose, Integrator,
    Primitive, Quat, UVec2, Vec2, Vec3, Wind,
};
use bvh_cloth_gpu::{ClothBatch, ClothKernels, GpuColliders, Kernel, SkinRefit, headless, wgpu};
use parry3d::math::Vector;
use parry3d::query::{PointQuery, Ray, RayCast};
use parry3d::shape::{TriMesh, TriMeshFlags};
use rayon::prelude::*;

/// The paper's Table VII (GTX 1650, quoted, not rerun): its method's ms per frame at n = 1, 3, 5.
const PAPER_MS: [[f64; 3]; 2] = [[8.0, 12.0, 12.0], [13.0, 13.0, 15.0]];
/// Voxel resolutions of the query table.
const RESOLUTIONS: [u32; 7] = [1, 3, 5, 8, 16, 32, 64];
/// Voxel resolutions of the fidelity table: the query table's and the highest accepted.
const FIDELITY_RESOLUTIONS: [u32; 8] = [1, 3, 5, 8, 16, 32, 64, 128];
/// Frames timed per Table VII case, after one simulated second of falling and landing.
const FRAMES: usize = 30;

/// A GPU, or why there is none.
struct Gpu {
    device: wgpu::Device,
    queue: wgpu::Queue,
    kernels: ClothKernels,
    /// A software rasteriser such as lavapipe, which runs on the CPU cores.
    software: bool,
    /// The adapter's name.
    name: String,
}

fn main() {
    let threads = rayon::current_num_threads();
    let single = rayon::ThreadPoolBuilder::new().num_threads(1).build().expect("a one-thread pool");
    let gpu = headless::device().map(|headless::HeadlessGpu { adapter, device, queue, .. }| {
        let info = adapter.get_info();
        println!("GPU adapter: {} ({:?}, driver {} {})", info.name, info.device_type, info.driver, info.driver_info);
        let kernels = ClothKernels::new(&device).expect("the kernels fit the device");
        Gpu { device, queue, kernels, software: info.device_type == wgpu::DeviceType::Cpu, name: info.name }
    });
    if gpu.is_none() {
        println!("GPU adapter: none (set WGPU_BACKEND, e.g. vulkan for lavapipe); GPU columns are skipped");
    }
    println!("CPU: {}, {threads} threads", cpu_name());
    let meshes: Vec<ObjMesh> = MODELS.iter().map(|m| model(m)).collect();
    let csv_dir = format!("{}/../../docs/benchmarks", std::env::var("CARGO_MANIFEST_DIR").expect("run by cargo"));
    std::fs::create_dir_all(&csv_dir).expect("docs/benchmarks is writable");

    // `cargo bench ... -- NAME...` runs only the sections whose name contains one of the NAMEs.
    let filters: Vec<String> = std::env::args().skip(1).filter(|a| !a.starts_with("--")).collect();
    let run = |section: &str| filters.is_empty() || filters.iter().any(|f| section.contains(f.as_str()));
    if run("table_vii") {
        table_vii(&meshes, gpu.as_ref(), &single, threads);
    }
    let parry: Vec<TriMesh> = meshes.iter().map(exact_mesh).collect();
    if run("queries") {
        std::fs::write(format!("{csv_dir}/queries.csv"), queries(&meshes, &parry)).expect("write queries.csv");
    }
    if run("fidelity") {
        std::fs::write(format!("{csv_dir}/fidelity.csv"), fidelity(&meshes, &parry)).expect("write fidelity.csv");
    }
    if run("step_scaling") {
        step_scaling(gpu.as_ref(), &single, threads);
    }
    if run("topology") {
        topology(gpu.as_ref(), &single, threads);
    }
    if run("gpu_profile") {
        gpu_profile(&meshes, gpu.as_ref());
    }
    if run("many_cloths") {
        many_cloths(gpu.as_ref());
    }
    if run("build_scaling") {
        build_scaling(&meshes);
    }
    if run("far_from_origin") {
        far_from_origin();
    }
    if run("solver") {
        solver(&single, threads);
    }
    if run("solver_gpu") {
        solver_on_gpu(&meshes, gpu.as_ref());
    }
    if run("primitives") {
        primitives(&meshes[0], gpu.as_ref());
    }
    if run("skinned_refit") {
        skinned_refit(&meshes, &single, gpu.as_ref());
    }
    if run("exact_contact") {
        exact_contact(&meshes, &parry);
    }
    if run("exact_contact_queries") {
        exact_queries::exact_queries(&meshes, &single);
    }
    if run("exact_contact_build") {
        exact_queries::exact_build(&meshes);
    }
    if run("exact_contact_gpu") {
        exact_contact_on_gpu(&meshes, gpu.as_ref());
    }
    if run("self_contact") {
        self_contact(&meshes[0], &single, threads);
    }
    if run("self_contact_gpu") {
        self_contact_on_gpu(&meshes[0], gpu.as_ref());
    }
    if run("wind") {
        wind(&single, threads);
    }
    if run("wind_gpu") {
        wind_on_gpu(&meshes[0], gpu.as_ref());
    }
    if run("motion") {
        motion::motion();
    }
    if run("motion_cost") {
        motion::motion_cost();
    }
    println!("\nCSV written to docs/benchmarks/ (plot: python3 scripts/plot_benchmarks.py)");
}

/// Table VII: ms per frame (one 60 Hz tick of Looper = 16 RK4 substeps, collision included).
fn table_vii(meshes: &[ObjMesh], gpu: Option<&Gpu>, single: &rayon::ThreadPool, threads: usize) {
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
    if gpu.is_some_and(|g| g.software) {
        println!("The GPU here is a software adapter on the same CPU cores: its column is not a GPU figure.");
    }
}

/// Median wall time (ms) of `ticks` ticks of a `size x size` cloth on the GPU, around a blocking
/// submit, after the cloth has fallen onto `colliders` for one simulated second.
fn gpu_frame_ms(gpu: &Gpu, colliders: &[Collider], size: u32, ticks: u32) -> f64 {
    gpu_sim_frame_ms(gpu, colliders, &cloth_above(&colliders[0], size, Integrator::Rk4), ticks)
}

/// Median wall time (ms) of `ticks` ticks of `cpu`'s cloth on the GPU, as [`gpu_frame_ms`].
fn gpu_sim_frame_ms(gpu: &Gpu, colliders: &[Collider], cpu: &ClothSim, ticks: u32) -> f64 {
    let samples = if cpu.len() > 128 * 128 { 5 } else { FRAMES };
    gpu_cloths_frame_ms(gpu, colliders, std::slice::from_ref(cpu), true, ticks, samples)
}

/// Median wall time (ms), around a blocking submit, of `ticks` ticks of every cloth of `cpus`
/// on the GPU, after 60 ticks of falling (10 on a software adapter): all in one batch when
/// `batched`, otherwise each in a batch of its own, encoded one after the other (the cost of
/// dispatching cloth by cloth).
fn gpu_cloths_frame_ms(
    gpu: &Gpu,
    colliders: &[Collider],
    cpus: &[ClothSim],
    batched: bool,
    ticks: u32,
    samples: usize,
) -> f64 {
    let gpu_colliders = GpuColliders::new(&gpu.device, colliders);
    let mut batches: Vec<ClothBatch> = Vec::new();
    for (k, cpu) in cpus.iter().enumerate() {
        if k == 0 || !batched {
            batches.push(ClothBatch::new(&gpu.device, &gpu.queue));
        }
        let batch = batches.last_mut().expect("a batch was pushed");
        let id = batch.insert(&gpu.device, &gpu.queue, cpu).expect("the cloth fits the device");
        batch.set_params(&gpu.queue, id, cpu.params(), TICK);
    }
    for batch in &mut batches {
        batch.prepare(&gpu.device, &gpu.queue, &gpu.kernels, &gpu_colliders);
    }
    let frame = |ticks: u32| {
        time(|| {
            let mut encoder = gpu.device.create_command_encoder(&Default::default());
            for batch in &batches {
                batch.encode_ticks(&mut encoder, &gpu.kernels, ticks);
            }
            gpu.queue.submit([encoder.finish()]);
            headless::wait(&gpu.device);
        }) * 1e3
    };
    frame(if gpu.software { 10 } else { 60 });
    median((0..samples).map(|_| frame(ticks)).collect())
}

/// GPU time per 60 Hz tick by kernel, from timestamp queries written around each dispatch
/// (each in a compute pass of its own), median of 9 ticks after a second of falling; where the
/// adapter has no timestamp queries, the wall time around a blocking submit, marked as such.
fn gpu_profile(meshes: &[ObjMesh], gpu: Option<&Gpu>) {
    println!("\n## GPU profile: ms per 60 Hz tick by kernel, RK4 Looper 16, at n = 5\n");
    let Some(gpu) = gpu else {
        println!("No GPU adapter: skipped.");
        return;
    };
    let timed = gpu.device.features().contains(wgpu::Features::TIMESTAMP_QUERY);
    let many = if gpu.software { 8 } else { 128 };
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
    if gpu.software {
        println!("The GPU here is a software adapter on the same CPU cores: its times are not GPU figures.");
    }
}

/// The column of [`kernel_ms`] a kernel's time goes to.
fn kernel_column(kernel: Kernel) -> usize {
    match kernel {
        Kernel::ApplyAnchors => 0,
        Kernel::NodeUpdate => 1,
        Kernel::NodeUpdateFinal => 2,
        // In a batch with aerodynamics, the prediction follows its cloths' air kick.
        Kernel::VbdPredict | Kernel::VbdPredictAir => 3,
        Kernel::VbdSolve => 4,
        // The drift sums of a free cloth are part of finishing its substep.
        Kernel::VbdDrift | Kernel::VbdFinish => 5,
        Kernel::ContactBegin
        | Kernel::ContactCount
        | Kernel::ContactScan
        | Kernel::ContactScatter
        | Kernel::ContactFind
        | Kernel::ContactApply => 6,
        Kernel::AirSample | Kernel::AirForces | Kernel::AirKick => 7,
    }
}

/// The rows of a with/without cost table: `with` and `without` (the same state, one feature
/// on and off) tick once each from clones, alternating, best of `reps` each, on one thread and
/// on the whole pool of `threads`; ms per tick and the feature's share of the rest.
fn print_with_and_without(
    single: &rayon::ThreadPool,
    threads: usize,
    without: &ClothSim,
    with: &ClothSim,
    colliders: &[Collider],
    reps: u32,
) {
    let measure = || {
        (0..reps).fold((f64::INFINITY, f64::INFINITY), |(off, on), _| {
            let mut a = without.clone();
            let mut b = with.clone();
            let t_off = time(|| _ = a.tick(TICK, colliders));
            let t_on = time(|| _ = b.tick(TICK, colliders));
            (off.min(t_off), on.min(t_on))
        })
    };
    for (label, (off, on)) in [("1", single.install(measure)), (&*threads.to_string(), measure())] {
        println!("| {label} | {:.2} | {:.2} | {:.0}% |", off * 1e3, on * 1e3, (on - off) / off * 100.0);
    }
}

/// The row of a GPU cost table: `cloth` alone in a batch with `c`, the GPU ms per tick of
/// `kernel`'s column of [`kernel_column`] against the rest of the tick ([`kernel_ms`]), and
/// the software adapter's caveat.
fn print_kernel_share(gpu: &Gpu, c: &Collider, cloth: &ClothSim, kernel: Kernel) {
    match kernel_ms(gpu, c, std::slice::from_ref(cloth)) {
        Some((column, total)) => {
            let part = column[kernel_column(kernel)];
            let rest = total - part;
            println!("| {} | {part:.3} | {rest:.3} | {:.0}% |", gpu.name, part / rest * 100.0);
        }
        None => println!("| {} | no timestamp queries | | |", gpu.name),
    }
    if gpu.software {
        println!("\nThe GPU here is a software adapter on the same CPU cores: its times are not GPU figures.");
    }
}

/// GPU ms of one 60 Hz tick of `cloths` (one batch, colliding with `c`) by kernel, in
/// [`kernel_column`] order, and in all: medians of 9 ticks timed with timestamp queries, each
/// dispatch in a compute pass of its own, after a second of falling (10 ticks on a software
/// adapter). `None` without timestamp queries, or when a tick has more dispatches than a query
/// set holds.
fn kernel_ms(gpu: &Gpu, c: &Collider, cloths: &[ClothSim]) -> Option<([f64; 8], f64)> {
    if !gpu.device.features().contains(wgpu::Features::TIMESTAMP_QUERY) {
        return None;
    }
    let colliders = GpuColliders::new(&gpu.device, std::slice::from_ref(c));
    let mut batch = ClothBatch::new(&gpu.device, &gpu.queue);
    for cloth in cloths {
        let id = batch.insert(&gpu.device, &gpu.queue, cloth).expect("the cloth fits the device");
        batch.set_params(&gpu.queue, id, cloth.params(), TICK);
    }
    batch.prepare(&gpu.device, &gpu.queue, &gpu.kernels, &colliders);
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    batch.encode_ticks(&mut encoder, &gpu.kernels, if gpu.software { 10 } else { 60 });
    gpu.queue.submit([encoder.finish()]);
    headless::wait(&gpu.device);
    // The most queries one set may hold (wgpu's limit).
    let capacity = 4096;
    let queries = gpu.device.create_query_set(&wgpu::QuerySetDescriptor {
        label: Some("bvh_cloth_profile"),
        ty: wgpu::QueryType::Timestamp,
        count: capacity,
    });
    let resolved = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("bvh_cloth_profile_resolved"),
        size: u64::from(capacity) * 8,
        usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    let period_ns = f64::from(gpu.queue.get_timestamp_period());
    let mut samples: Vec<[f64; 8]> = Vec::new();
    for _ in 0..9 {
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        let kernels = batch.encode_ticks_timed(&mut encoder, &gpu.kernels, 1, &queries, capacity)?;
        let used = 2 * kernels.len() as u32;
        encoder.resolve_query_set(&queries, 0..used, &resolved, 0);
        gpu.queue.submit([encoder.finish()]);
        let stamps: Vec<u64> = headless::read(&gpu.device, &gpu.queue, &resolved);
        let mut ms = [0.0f64; 8];
        for (k, &kernel) in kernels.iter().enumerate() {
            ms[kernel_column(kernel)] += stamps[2 * k + 1].saturating_sub(stamps[2 * k]) as f64 * period_ns * 1e-6;
        }
        samples.push(ms);
    }
    let total = median(samples.iter().map(|s| s.iter().sum()).collect());
    Some((core::array::from_fn(|k| median(samples.iter().map(|s| s[k]).collect())), total))
}

/// Many cloths at once: ms per 60 Hz tick for 1 to 512 cloths of 16 x 16, 32 x 32 and 64 x 64
/// (Looper 16, RK4), stacked 5 cm apart above the bunny at n = 5 and timed after a second of
/// falling, all in one batch and each in a batch of its own.
fn many_cloths(gpu: Option<&Gpu>) {
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
    let most = if gpu.software { 8 * 1024 } else { 4 * 1024 * 1024 };
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
            let samples = if gpu.software || particles > 256 * 1024 { 5 } else { 15 };
            let one = gpu_cloths_frame_ms(gpu, &bunny, &cloths, true, 1, samples);
            let each = gpu_cloths_frame_ms(gpu, &bunny, &cloths, false, 1, samples);
            println!("| {size}x{size} | {count} | {particles} | {one:.3} | {each:.3} | {:.1}x |", each / one);
        }
    }
    if gpu.software {
        println!(
            "
The GPU here is a software adapter on the same CPU cores: only the ratios mean anything."
        );
    }
}

/// Writes one byte in every 64-byte line of `bytes`: evicts the caches, and its loop's branches
/// are few and always taken.
fn write_every_line(bytes: &mut [u8]) {
    for b in bytes.iter_mut().step_by(64) {
        *b = b.wrapping_add(1);
    }
    std::hint::black_box(bytes);
}

/// Three million steps of a loop over 16 KiB whose branches follow a pseudo-random sequence
/// (xorshift): trains the branch predictors on other code, and evicts little from the caches.
fn train_other_branches(words: &mut [u32; 4096]) {
    let mut state = words[0] | 1;
    for _ in 0..3_000_000 {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        let w = &mut words[(state & 4095) as usize];
        if *w & 1 == 0 {
            *w = w.wrapping_add(state);
        } else if state & 2 == 0 {
            *w ^= 7;
        } else {
            *w = w.rotate_left(3);
        }
    }
    std::hint::black_box(words);
}

/// The exact mesh as parry3d sees it, oriented so that its pseudo-normals tell inside from outside.
fn exact_mesh(mesh: &ObjMesh) -> TriMesh {
    let vertices = mesh.positions.iter().map(|&p| Vector::from(p)).collect();
    let triangles = mesh.indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
    let flags =
        TriMeshFlags::ORIENTED | TriMeshFlags::MERGE_DUPLICATE_VERTICES | TriMeshFlags::DELETE_DEGENERATE_TRIANGLES;
    TriMesh::with_flags(vertices, triangles, flags).expect("the bundled models are valid triangle meshes")
}

/// The particle queries of one collision pass, single-threaded: which spheres hold each point
/// (LBVH, and brute force over the same spheres), against parry3d's projection of each point on
/// the exact mesh. Returns the CSV rows.
fn queries(meshes: &[ObjMesh], parry: &[TriMesh]) -> String {
    println!("\n## Particle queries, 1 thread: 4,096 positions of a cloth draped for 2 s on the n = 16 collider\n");
    println!("LBVH and brute force list the spheres holding each point; parry3d projects it on the exact mesh.\n");
    println!(
        "| model | n | spheres | LBVH M/s | brute force M/s | parry3d TriMesh M/s | LBVH / parry3d | LBVH / brute force |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    let mut csv = String::from("model,n,spheres,lbvh_qps,brute_qps,parry_qps\n");
    for ((name, mesh), exact) in MODELS.iter().zip(meshes).zip(parry) {
        let points = drape(&collider(mesh, 16), 2.0).positions();
        let rate = |seconds: f64| points.len() as f64 / seconds;
        let parry_qps = rate(best_of(7, || {
            for &p in &points {
                std::hint::black_box(exact.project_local_point(Vector::from(p.to_array()), true));
            }
        }));
        for n in RESOLUTIONS {
            let c = collider(mesh, n);
            let lbvh_qps = rate(best_of(7, || {
                let mut hits = 0u32;
                for &p in &points {
                    c.lbvh().expect("a mesh collider").for_each_containing(p, 0.0, |_, _| hits += 1);
                }
                std::hint::black_box(hits);
            }));
            let brute_qps = rate(best_of(3, || {
                let mut hits = 0u32;
                for &p in &points {
                    c.lbvh().expect("a mesh collider").brute_force_containing(p, 0.0, |_, _| hits += 1);
                }
                std::hint::black_box(hits);
            }));
            println!(
                "| {name} | {n} | {} | {:.2} | {:.3} | {:.3} | {:.0}x | {:.1}x |",
                c.sphere_count(),
                lbvh_qps / 1e6,
                brute_qps / 1e6,
                parry_qps / 1e6,
                lbvh_qps / parry_qps,
                lbvh_qps / brute_qps
            );
            writeln!(csv, "{name},{n},{},{lbvh_qps:.0},{brute_qps:.0},{parry_qps:.0}", c.sphere_count()).unwrap();
        }
    }
    csv
}

/// How far the sphere collider is from the true surface: a cloth falls onto the spheres at each
/// n and rests there. Every particle is tested against the exact mesh every [`CHECK_TICKS`]
/// ticks of the run, so a particle that went through the spheres into the model counts even if
/// it left again; the particles resting on the spheres at the end give the air gap. Returns the
/// CSV rows.
fn fidelity(meshes: &[ObjMesh], parry: &[TriMesh]) -> String {
    /// A particle within this distance (m) of a sphere's surface is resting on it.
    const TOUCH: f32 = 2.0e-3;
    /// Ticks between two checks against the exact mesh.
    const CHECK_TICKS: u32 = 20;
    const SECONDS: f32 = 3.0;
    println!(
        "\n## Collider fidelity: a 64 x 64 cloth falling onto the spheres and resting 3 s, against the exact mesh (parry3d)\n"
    );
    println!(
        "Every particle is tested against the exact mesh every {CHECK_TICKS} ticks; a particle resting at the end lies within {} mm of a sphere's surface (margin 0 here).\n",
        TOUCH * 1e3
    );
    println!(
        "The exact-contact columns: the same cloth on the same model with exact contact (`Collider::with_exact_contact`, margin 0, so the surface's least thickness: a millionth of its diagonal, and at least 256 steps of `f32` at its coordinates' magnitude). Exact contact does not use the voxel spheres, so it is run once per model and its figures stand in every row of that model; resting means within {} mm of the triangles.\n",
        TOUCH * 1e3
    );
    println!(
        "| model | n | spheres | fell past the model | ever inside the true mesh | deepest mm | inside at the end | resting at the end | mean air gap mm | exact contact: ever inside | deepest mm | resting | mean air gap mm |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    let mut csv = String::from(
        "model,n,spheres,fell,ever_inside,deepest_mm,inside_at_end,resting,mean_gap_mm,exact_ever_inside,exact_deepest_mm,exact_resting,exact_mean_gap_mm\n",
    );
    for ((name, mesh), exact) in MODELS.iter().zip(meshes).zip(parry) {
        let exact_contact = {
            let c = collider(mesh, 5).with_margin(0.0).with_exact_contact(mesh.as_mesh_ref()).expect("area");
            let surface = c.surface().expect("exact contact").clone();
            let mut sim = cloth_above(&c, 64, Integrator::Rk4);
            let Penetration { ever_inside, deepest, .. } =
                run_checking_penetration(&mut sim, &c, exact, SECONDS, CHECK_TICKS);
            let gaps: Vec<f32> = sim
                .positions()
                .into_iter()
                .filter(|&p| surface.closest_within(p, TOUCH).is_some() && !inside(exact, p))
                .map(|p| exact.distance_to_local_point(Vector::from(p.to_array()), false).abs() * 1e3)
                .collect();
            let mean_gap = gaps.iter().sum::<f32>() / gaps.len().max(1) as f32;
            (ever_inside, deepest, gaps.len(), mean_gap)
        };
        let (exact_ever, exact_deepest, exact_resting, exact_gap) = exact_contact;
        for n in FIDELITY_RESOLUTIONS {
            let c = collider(mesh, n).with_margin(0.0);
            let mut sim = cloth_above(&c, 64, Integrator::Rk4);
            let Penetration { ever_inside, deepest, inside_at_end } =
                run_checking_penetration(&mut sim, &c, exact, SECONDS, CHECK_TICKS);
            let positions = sim.positions();
            let fell = positions.iter().filter(|p| p.y < 0.0).count();
            let gaps: Vec<f32> = positions
                .iter()
                .filter(|&&p| {
                    let gap = c
                        .lbvh()
                        .expect("a mesh collider")
                        .spheres
                        .iter()
                        .map(|s| p.distance(s.centre()) - s.radius)
                        .fold(f32::INFINITY, f32::min);
                    gap.abs() <= TOUCH && !inside(exact, p)
                })
                .map(|&p| exact.distance_to_local_point(Vector::from(p.to_array()), false).abs() * 1e3)
                .collect();
            let mean_gap = if gaps.is_empty() { 0.0 } else { gaps.iter().sum::<f32>() / gaps.len() as f32 };
            println!(
                "| {name} | {n} | {} | {fell} | {ever_inside} | {deepest:.1} | {inside_at_end} | {} | {mean_gap:.1} | {exact_ever} | {exact_deepest:.2} | {exact_resting} | {exact_gap:.3} |",
                c.sphere_count(),
                gaps.len(),
            );
            writeln!(
                csv,
                "{name},{n},{},{fell},{ever_inside},{deepest:.3},{inside_at_end},{},{mean_gap:.3},{exact_ever},{exact_deepest:.3},{exact_resting},{exact_gap:.4}",
                c.sphere_count(),
                gaps.len()
            )
            .unwrap();
        }
    }
    csv
}

/// What [`run_checking_penetration`] saw of a cloth against the exact mesh.
struct Penetration {
    /// Particles found inside the true mesh at some check.
    ever_inside: usize,
    /// The deepest any was, in mm.
    deepest: f32,
    /// Particles inside at the last check (the end).
    inside_at_end: usize,
}

/// Runs `sim` for `seconds` of 60 Hz ticks against `c`, checking every particle against the
/// exact mesh every `check_ticks` ticks and at the end.
fn run_checking_penetration(
    sim: &mut ClothSim,
    c: &Collider,
    exact: &TriMesh,
    seconds: f32,
    check_ticks: u32,
) -> Penetration {
    let colliders = std::slice::from_ref(c);
    let depth_inside = |p: Vec3| {
        inside(exact, p).then(|| exact.distance_to_local_point(Vector::from(p.to_array()), false).abs() * 1e3)
    };
    let mut ever = vec![false; sim.len()];
    let (mut deepest, mut inside_at_end) = (0.0f32, 0usize);
    let ticks = (seconds / TICK).round() as u32;
    for tick in 1..=ticks {
        sim.tick(TICK, colliders);
        if tick % check_ticks != 0 && tick != ticks {
            continue;
        }
        let depths: Vec<Option<f32>> = sim.positions().into_iter().map(depth_inside).collect();
        for (seen, depth) in ever.iter_mut().zip(&depths) {
            if let Some(d) = *depth {
                *seen = true;
                deepest = deepest.max(d);
            }
        }
        inside_at_end = depths.iter().flatten().count();
    }
    Penetration { ever_inside: ever.iter().filter(|&&e| e).count(), deepest, inside_at_end }
}

/// Whether `p` is inside the exact mesh: the majority vote of the crossing parities of three
/// rays. Parity needs no consistent orientation, and the vote outlasts a ray that slips through
/// one of the scanned models' small holes.
fn inside(mesh: &TriMesh, p: Vec3) -> bool {
    const DIRECTIONS: [[f32; 3]; 3] = [[0.577, 0.613, 0.539], [-0.642, 0.298, -0.706], [0.331, -0.874, 0.355]];
    let odd = |dir: [f32; 3]| {
        let (dir, mut origin, mut crossings) = (Vec3::from(dir).normalize(), p, 0u32);
        while crossings < 256 {
            let ray = Ray::new(Vector::from(origin.to_array()), Vector::from(dir.to_array()));
            let Some(t) = mesh.cast_local_ray(&ray, 10.0, false) else { break };
            crossings += 1;
            origin += dir * (t + 1.0e-5);
        }
        crossings % 2 == 1
    };
    DIRECTIONS.into_iter().filter(|&d| odd(d)).count() >= 2
}

/// Step time against cloth size: ns per particle per substep, on the bunny at n = 5.
fn step_scaling(gpu: Option<&Gpu>, single: &rayon::ThreadPool, threads: usize) {
    println!("\n## Scaling with cloth size: ns per particle per substep, falling onto the bunny (n = 5)\n");
    println!("| integrator | cloth | CPU 1 thread | CPU {threads} threads | GPU |");
    println!("|---|---|---|---|---|");
    let bunny = [collider(&model("bunny"), 5)];
    let gpu_sizes: &[u32] =
        if gpu.is_some_and(|g| !g.software) { &[32, 64, 128, 256, 512, 1024] } else { &[32, 64, 128] };
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
fn topology(gpu: Option<&Gpu>, single: &rayon::ThreadPool, threads: usize) {
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
fn build_scaling(meshes: &[ObjMesh]) {
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

/// Particle positions are world-space `f32`: far from the origin their spacing (one ulp) grows
/// towards the springs' rest length. The soak's stiff case (a free 26 x 24 cloth, 1.4 m wide,
/// SpringK 1,390 N/m, semi-implicit Euler, under its swept force) is started at growing
/// distances and run for 10 s.
fn far_from_origin() {
    println!("\n## Precision far from the origin: a free 26 x 24 cloth (5.6 cm springs), SpringK 1,390, 10 s\n");
    println!("| distance from the origin | f32 spacing of each coordinate | first non-finite tick (of 600) |");
    println!("|---|---|---|");
    for distance in [0.0f32, 100.0, 1_000.0, 3_000.0, 10_000.0, 100_000.0] {
        let params = ClothParams {
            looper: 22,
            spring_k: 1_390.0,
            damping: 0.1,
            external_force: Vec3::new(3.9, 17.8, -0.3),
            integrator: Integrator::SemiImplicitEuler,
            ..Default::default()
        };
        let coordinate = distance / 3f32.sqrt();
        let start = Affine3A::from_translation(Vec3::splat(coordinate));
        let grid = ClothGrid::new(Vec2::new(1.4, 1.4 * 25.0 / 23.0), UVec2::new(24, 26));
        let topology = Arc::new(ClothTopology::grid(grid).expect("a valid grid"));
        let mut sim = ClothSim::new(params, topology, start, &[]).expect("valid parameters");
        let first_bad = (1..=600).find(|_| {
            sim.tick(TICK, &[]);
            !sim.is_finite()
        });
        let spacing = f32::from_bits(coordinate.max(1.0).to_bits() + 1) - coordinate.max(1.0);
        let outcome = first_bad.map_or("none: finite throughout".to_string(), |t| t.to_string());
        println!("| {distance} m | {spacing:.1e} m | {outcome} |");
    }
}

/// The CPU's model name, from /proc/cpuinfo where there is one.
fn cpu_name() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|s| s.trim().to_owned())
        })
        .unwrap_or_else(|| "unknown".into())
}

/// A `side x side` cloth 1 m wide hanging from its two first-row corners, 2 m up.
fn hanging(side: u32, params: ClothParams) -> ClothSim {
    let topology = Arc::new(ClothTopology::grid(ClothGrid::new(Vec2::ONE, UVec2::splat(side))).expect("a valid grid"));
    let pose = Affine3A::from_translation(Vec3::new(0.0, 2.0, 0.0));
    ClothSim::new(params, topology, pose, &[0, side - 1]).expect("valid cloth")
}

/// How far the middle of the last row hangs below the pins.
fn sag_of(sim: &ClothSim) -> f32 {
    let grid = *sim.topology().stencil().expect("a grid");
    2.0 - sim.position(grid.index(grid.rows - 1, grid.cols / 2)).y
}

/// The solvers head to head: block descent against RK4 for the same sag on the CPU, the cost of
/// stiffness for each, and big cloth on the GPU.
fn solver(single: &rayon::ThreadPool, threads: usize) {
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

/// Big cloth on the GPU: RK4 against block descent per tick on the dragon at n = 16 (the
/// `solver_gpu` section, after `solver`).
fn solver_on_gpu(meshes: &[ObjMesh], gpu: Option<&Gpu>) {
    println!("\n### Big cloth on the GPU: ms per 60 Hz tick on the dragon at n = 16, Looper 16\n");
    let Some(gpu) = gpu else {
        println!("No GPU adapter: skipped.");
        return;
    };
    let dragon = collider(&meshes[1], 16);
    let sizes: &[u32] = if gpu.software { &[64, 128] } else { &[64, 256, 1024] };
    let timed = gpu.device.features().contains(wgpu::Features::TIMESTAMP_QUERY);
    let clock = if timed { "GPU ms (timestamps)" } else { "ms (wall)" };
    println!(
        "| cloth | RK4 substeps | RK4 {clock} | block descent substeps | block descent {clock} | of it vbd_solve | speed-up |"
    );
    println!("|---|---|---|---|---|---|---|");
    for &size in sizes {
        let rk4 = cloth_above(&dragon, size, Integrator::Rk4);
        let descent = cloth_above(&dragon, size, Integrator::BLOCK_DESCENT);
        let tick = |cloth: &ClothSim| match kernel_ms(gpu, &dragon, std::slice::from_ref(cloth)) {
            Some((column, total)) => (total, format!("{:.3}", column[4])),
            None => (gpu_sim_frame_ms(gpu, std::slice::from_ref(&dragon), cloth, 1), "-".into()),
        };
        let ((rk_ms, _), (bd_ms, solve)) = (tick(&rk4), tick(&descent));
        println!(
            "| {size}x{size} | {} | {rk_ms:.3} | {} | {bd_ms:.3} | {solve} | {:.1}x |",
            rk4.substeps(TICK),
            descent.substeps(TICK),
            rk_ms / bd_ms
        );
    }
    if gpu.software {
        println!("\nThe GPU here is a software adapter on the same CPU cores: its times are not GPU figures.");
    }
}

/// Exact primitives against voxelised meshes: the collision response's cost per particle for a
/// 64 x 64 cloth draped for 2 s on each collider (RK4, Looper 16), each particle pressed into
/// the surface by one substep of gravity, on one thread; and on a hardware GPU the
/// `node_update_final` kernel (integration and collision) of one tick.
fn primitives(bunny: &ObjMesh, gpu: Option<&Gpu>) {
    println!("\n## Primitives against mesh colliders: collision cost per particle, 64 x 64 cloth draped for 2 s\n");
    let shaped = |primitive: Primitive, translation: Vec3, rotation: Quat| {
        Collider::primitive(primitive)
            .expect("valid sizes")
            .with_margin(0.01)
            .with_friction(1.0)
            .with_pose(ColliderPose { translation, rotation, scale: 1.0 })
    };
    let lying = Quat::from_rotation_z(core::f32::consts::FRAC_PI_2);
    let colliders = [
        ("bunny mesh, n = 5".to_string(), collider(bunny, 5)),
        ("bunny mesh, n = 16".to_string(), collider(bunny, 16)),
        (
            "sphere r 0.4".to_string(),
            shaped(Primitive::Sphere { radius: 0.4 }, Vec3::new(0.0, 0.4, 0.0), Quat::IDENTITY),
        ),
        (
            "capsule r 0.2, 0.6 long, lying".to_string(),
            shaped(Primitive::Capsule { radius: 0.2, half_length: 0.3 }, Vec3::new(0.0, 0.2, 0.0), lying),
        ),
        (
            "box 0.8 x 0.4 x 0.6".to_string(),
            shaped(
                Primitive::Cuboid { half_extents: Vec3::new(0.4, 0.2, 0.3) },
                Vec3::new(0.0, 0.2, 0.0),
                Quat::IDENTITY,
            ),
        ),
        ("ground".to_string(), shaped(Primitive::HalfSpace { normal: Vec3::Y }, Vec3::ZERO, Quat::IDENTITY)),
    ];
    let hardware = gpu.filter(|gpu| !gpu.software);
    println!(
        "| collider | particles in contact | CPU ns / particle | mesh n = 5 / this | GPU node_update_final ms / tick |"
    );
    println!("|---|---|---|---|---|");
    let mut reference_ns = None;
    for (name, c) in &colliders {
        let cloth = drape(c, 2.0);
        let frame = ColliderFrame::new(c).expect("a usable collider");
        let h = TICK / 16.0;
        let paths: Vec<(Vec3, Vec3, Vec3)> = cloth
            .positions()
            .into_iter()
            .zip(cloth.velocities())
            .map(|(p, v)| (p, p + h * v + Vec3::new(0.0, -9.81 * h * h, 0.0), v))
            .collect();
        let mut contacts = 0;
        let seconds = best_of(9, || {
            contacts = 0;
            for &(prev, p, v) in &paths {
                let (mut p, mut v) = (p, v);
                contacts += usize::from(frame.resolve(prev, &mut p, &mut v));
                std::hint::black_box((p, v));
            }
        });
        let ns = seconds * 1e9 / paths.len() as f64;
        let reference = *reference_ns.get_or_insert(ns);
        let gpu_ms = hardware
            .and_then(|gpu| kernel_ms(gpu, c, std::slice::from_ref(&cloth)))
            .map_or("-".to_string(), |(ms, _)| format!("{:.3}", ms[kernel_column(Kernel::NodeUpdateFinal)]));
        println!("| {name} | {contacts} | {ns:.1} | {:.1}x | {gpu_ms} |", reference / ns);
    }
    if gpu.is_some_and(|gpu| gpu.software) {
        println!("\nThe GPU here is a software adapter: its column is left out.");
    }
}

/// Skinned colliders: each model given a skeleton of [`BONES`] bones stacked up its height,
/// every vertex weighted to the two bones nearest its height, posed with every bone bent. One
/// frame's collider update (skin the vertices the points use, fit every sphere to its points,
/// refit the tree) against skinning every vertex of the mesh alone (what a renderer or a CPU
/// skinning pass does), both on one thread, best of 15.
fn skinned_refit(meshes: &[ObjMesh], single: &rayon::ThreadPool, gpu: Option<&Gpu>) {
    println!(
        "\n## Skinned colliders: one frame's refit against skinning the vertices, one thread; and the refit on the \
         GPU (median of 15, timestamp queries around its pass)\n"
    );
    println!(
        "| model | vertices | n | spheres | points | skin vertices ms | refit ms | refit / skin | build ms | GPU refit ms | GPU dispatches |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    for (name, mesh) in MODELS.iter().zip(meshes) {
        let (joints, weights) = bone_weights(mesh);
        let skin = SkinRef { joints: &joints, weights: &weights, joint_count: BONES };
        let pose = bent_pose();
        let vertices = SkinnedVertices {
            positions: mesh.positions.iter().map(|&p| p.into()).collect(),
            joints: joints.clone(),
            weights: weights.clone(),
        };
        for n in [5u32, 16] {
            let mut build_s = 0.0;
            let collider = single.install(|| {
                let mut built = None;
                build_s = best_of(3, || {
                    built = Some(
                        Collider::from_skinned_mesh(mesh.as_mesh_ref(), skin, bvh_cloth_core::Voxels::PerAxis(n))
                            .expect("a valid skin"),
                    );
                });
                built.expect("built")
            });
            let skinned = collider.skin().expect("a skinned collider").clone();
            // Skinning and refit alternate, so that both meet the same moments of a shared
            // machine's load; the best of 50 of each.
            let (skin_s, refit_s) = single.install(|| {
                let mut out = Vec::new();
                let mut posed = collider.clone();
                let mut scratch = SkinScratch::default();
                (0..50).fold((f64::INFINITY, f64::INFINITY), |(skin_s, refit_s), _| {
                    let skin = best_of(1, || vertices.skin_into(&pose, &mut out));
                    let refit = best_of(1, || posed.pose_skin(&pose, &mut scratch).expect("a valid pose"));
                    (skin_s.min(skin), refit_s.min(refit))
                })
            });
            let (gpu_ms, dispatches) = gpu
                .and_then(|gpu| gpu_refit_ms(gpu, &collider, &pose))
                .map_or(("—".to_string(), "—".to_string()), |(ms, d)| (format!("{ms:.4}"), d.to_string()));
            println!(
                "| {name} | {} | {n} | {} | {} | {:.3} | {:.3} | {:.2}x | {:.1} | {gpu_ms} | {dispatches} |",
                mesh.positions.len(),
                collider.sphere_count(),
                skinned.points.len(),
                skin_s * 1e3,
                refit_s * 1e3,
                refit_s / skin_s,
                build_s * 1e3,
            );
        }
    }
    if gpu.is_some_and(|g| g.software) {
        println!("\nThe GPU here is a software adapter on the same CPU cores: its column is not a GPU figure.");
    }
}

/// GPU ms of one refit of `collider` (skinned) to `pose` on the GPU (`SkinRefit`): the median of
/// 15, each timed with timestamp queries at the start and end of the refit's compute pass; and
/// the dispatches a refit records. `None` without timestamp queries.
fn gpu_refit_ms(gpu: &Gpu, collider: &Collider, pose: &[Affine3A]) -> Option<(f64, usize)> {
    if !gpu.device.features().contains(wgpu::Features::TIMESTAMP_QUERY) {
        return None;
    }
    let mut collider = collider.clone();
    let clearance = collider.accept_skin_pose(pose).ok()??;
    let colliders = GpuColliders::new(&gpu.device, std::slice::from_ref(&collider));
    let mut refit = SkinRefit::new(&gpu.device, collider.skin()?, collider.lbvh()?).ok()?;
    if !refit.bind(&gpu.device, &gpu.kernels, &colliders, 0) {
        return None;
    }
    refit.write_pose(&gpu.queue, pose, clearance);
    let queries = gpu.device.create_query_set(&wgpu::QuerySetDescriptor {
        label: None,
        ty: wgpu::QueryType::Timestamp,
        count: 2,
    });
    let resolved = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size: 16,
        usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    let period_ns = f64::from(gpu.queue.get_timestamp_period());
    let samples = (0..16)
        .map(|_| {
            let mut encoder = gpu.device.create_command_encoder(&Default::default());
            {
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("bvh_cloth_skin_refit_timed"),
                    timestamp_writes: Some(wgpu::ComputePassTimestampWrites {
                        query_set: &queries,
                        beginning_of_pass_write_index: Some(0),
                        end_of_pass_write_index: Some(1),
                    }),
                });
                refit.encode(&mut pass, &gpu.kernels);
            }
            encoder.resolve_query_set(&queries, 0..2, &resolved, 0);
            gpu.queue.submit([encoder.finish()]);
            let stamps: Vec<u64> = headless::read(&gpu.device, &gpu.queue, &resolved);
            stamps[1].saturating_sub(stamps[0]) as f64 * period_ns * 1e-6
        })
        // The first refit warms the pipelines' caches.
        .skip(1)
        .collect();
    Some((median(samples), refit.dispatches()))
}

/// The exact-contact sections' cloth thickness (m).
const EXACT_THICKNESS: f32 = 0.005;

/// Exact contact against the paper's sphere contact, on the bundled models at n = 5 with a
/// thickness (margin) of 5 mm: a 64 x 64 cloth falls onto each and rests 3 s (RK4, Looper 16),
/// checked against the exact mesh (parry3d) every 20 ticks; then the drape's time with each
/// contact.
fn exact_contact(meshes: &[ObjMesh], parry: &[TriMesh]) {
    const THICKNESS: f32 = EXACT_THICKNESS;
    /// A particle within this distance (m) of the true surface at the end rests on the model.
    const ON_MODEL: f32 = 0.05;
    /// A particle within this distance (m) beyond the thickness of the collider's own surface
    /// at the end is in contact with it.
    const TOUCH: f32 = 0.002;
    const CHECK_TICKS: u32 = 20;
    println!(
        "\n## Exact contact: a 64 x 64 cloth resting 3 s at n = 5, thickness {} mm, against the exact mesh (parry3d)\n",
        THICKNESS * 1e3
    );
    println!(
        "In contact: at the end, within {} mm beyond the thickness of the collider's own surface (the spheres, or the triangles); their air gap is their distance to the true surface beyond the thickness. On the model: within {} mm of the true surface, sagging cloth included. Penetration: depth inside the true mesh, checked every {CHECK_TICKS} ticks.\n",
        TOUCH * 1e3,
        ON_MODEL * 1e3
    );
    println!(
        "| model | contact | fell past | ever inside | deepest mm | inside at the end | in contact | contact air gap mm | on the model | its mean gap mm | closer than the thickness |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    for ((name, mesh), exact) in MODELS.iter().zip(meshes).zip(parry) {
        let spheres = collider(mesh, 5).with_margin(THICKNESS);
        let triangles = spheres.clone().with_exact_contact(mesh.as_mesh_ref()).expect("the bundled models have area");
        for (contact, c) in [("spheres", &spheres), ("exact", &triangles)] {
            let mut sim = cloth_above(c, 64, Integrator::Rk4);
            let Penetration { ever_inside, deepest, inside_at_end } =
                run_checking_penetration(&mut sim, c, exact, 3.0, CHECK_TICKS);
            let positions = sim.positions();
            let fell = positions.iter().filter(|p| p.y < 0.0).count();
            let gaps: Vec<f32> = positions
                .iter()
                .filter(|&&p| !inside(exact, p))
                .map(|&p| exact.distance_to_local_point(Vector::from(p.to_array()), false).abs())
                .filter(|&d| d < ON_MODEL)
                .collect();
            let mean_gap = gaps.iter().map(|d| d - THICKNESS).sum::<f32>() / gaps.len().max(1) as f32;
            let close = gaps.iter().filter(|&&d| d < 0.9 * THICKNESS).count();
            // In contact with the collider's own surface.
            let touching = |p: Vec3| match c.surface() {
                Some(surface) => surface.closest_within(p, THICKNESS + TOUCH).is_some(),
                None => c
                    .lbvh()
                    .expect("a mesh collider")
                    .spheres
                    .iter()
                    .any(|s| (p.distance(s.centre()) - s.radius - THICKNESS).abs() <= TOUCH && !c.contains(p)),
            };
            let contact_gaps: Vec<f32> = positions
                .iter()
                .filter(|&&p| touching(p) && !inside(exact, p))
                .map(|&p| exact.distance_to_local_point(Vector::from(p.to_array()), false).abs() - THICKNESS)
                .collect();
            let contact_gap = contact_gaps.iter().sum::<f32>() / contact_gaps.len().max(1) as f32;
            println!(
                "| {name} | {contact} | {fell} | {ever_inside} | {deepest:.2} | {inside_at_end} | {} | {:.2} | {} | {:.2} | {close} |",
                contact_gaps.len(),
                contact_gap * 1e3,
                gaps.len(),
                mean_gap * 1e3,
            );
        }
    }

    println!("\n### CPU: the drape with exact against sphere contact\n");
    println!(
        "Seconds to drape the 64 x 64 cloth 2 s (120 ticks of RK4, Looper 16) on the model at n = 5, thickness {} mm, on the CPU backend's pool ({} threads): alternating, best of 3 each.\n",
        THICKNESS * 1e3,
        rayon::current_num_threads()
    );
    println!("| model | sphere contact s | exact contact s | exact / spheres |");
    println!("|---|---|---|---|");
    for (name, mesh) in MODELS.iter().zip(meshes) {
        let spheres = collider(mesh, 5).with_margin(THICKNESS);
        let triangles = spheres.clone().with_exact_contact(mesh.as_mesh_ref()).expect("area");
        let (sphere_s, exact_s) = (0..3).fold((f64::INFINITY, f64::INFINITY), |(s, e), _| {
            let sphere = time(|| drop(std::hint::black_box(drape(&spheres, 2.0))));
            let exact = time(|| drop(std::hint::black_box(drape(&triangles, 2.0))));
            (s.min(sphere), e.min(exact))
        });
        println!("| {name} | {sphere_s:.3} | {exact_s:.3} | {:.2}x |", exact_s / sphere_s);
    }
}

/// Exact contact's GPU collision kernel against the sphere kernel (the `exact_contact_gpu`
/// section, after `exact_contact`).
fn exact_contact_on_gpu(meshes: &[ObjMesh], gpu: Option<&Gpu>) {
    const THICKNESS: f32 = EXACT_THICKNESS;
    println!("\n### GPU: the collision kernel with exact against sphere contact\n");
    let Some(gpu) = gpu else {
        println!("No GPU adapter: skipped.");
        return;
    };
    println!(
        "ms of `node_update_final` (the last RK4 stage with the collision response) per 60 Hz tick of a 64 x 64 cloth (Looper 16) resting on the model at n = 5, and of the whole tick: medians of 9 ticks, timestamp queries.\n"
    );
    println!(
        "| model | sphere contact: final stage ms | tick ms | exact contact: final stage ms | tick ms | final stage exact / spheres |"
    );
    println!("|---|---|---|---|---|---|");
    for (name, mesh) in MODELS.iter().zip(meshes) {
        let spheres = collider(mesh, 5).with_margin(THICKNESS);
        let triangles = spheres.clone().with_exact_contact(mesh.as_mesh_ref()).expect("area");
        let times = [&spheres, &triangles].map(|c| kernel_ms(gpu, c, std::slice::from_ref(&drape(c, 1.0))));
        let [Some((s_ms, s_total)), Some((e_ms, e_total))] = times else {
            println!("| {name} | — | — | — | — | — |");
            continue;
        };
        let column = kernel_column(Kernel::NodeUpdateFinal);
        println!(
            "| {name} | {:.4} | {s_total:.4} | {:.4} | {e_total:.4} | {:.2}x |",
            s_ms[column],
            e_ms[column],
            e_ms[column] / s_ms[column]
        );
    }
    if gpu.software {
        println!("\nThe GPU here is a software adapter on the same CPU cores: its times are not GPU figures.");
    }
}

/// Self-contact on the CPU: the two scenes, each with and without contact, checked at
/// the end by an exact triangle–triangle test between every two triangles sharing no corner
/// and by the least distance between particles sharing no spring; then the cost of contact in
/// a tick of a 128 x 128 cloth.
/// The self-contact sections' contact: 8 mm thick, friction 0.3.
const SELF_CONTACT: SelfContact = SelfContact { thickness: 0.008, friction: 0.3 };

fn self_contact(bunny: &ObjMesh, single: &rayon::ThreadPool, threads: usize) {
    const THICKNESS: f32 = SELF_CONTACT.thickness;
    const SECONDS: f32 = 3.0;
    let contact = SELF_CONTACT;
    println!("\n## Self-contact: a cloth folding over a bar, two cloths on the bunny (CPU, {threads} threads)\n");
    println!(
        "Thickness {} mm, friction 0.3, block descent at Looper 16, {SECONDS} s of 60 Hz ticks. Crossing triangles: pairs of triangles sharing no corner (within a cloth) or of two cloths that intersect, by an exact segment–triangle test of each edge. Close pairs: particles sharing no spring, lying farther apart than the thickness in the rest shape, closer than half the thickness at the end.\n",
        THICKNESS * 1e3
    );
    println!(
        "| scene | contact | crossing triangles within a cloth | between the cloths | close pairs | ms per tick |"
    );
    println!("|---|---|---|---|---|---|");
    let bar = Collider::primitive(Primitive::Capsule { radius: 0.03, half_length: 1.0 })
        .expect("a valid capsule")
        .with_pose(ColliderPose { rotation: Quat::from_rotation_x(std::f32::consts::FRAC_PI_2), ..Default::default() })
        .with_friction(0.5);
    let fold = Arc::new(ClothTopology::grid(ClothGrid::new(Vec2::ONE, UVec2::splat(64))).expect("a valid grid"));
    for on in [true, false] {
        let params = ClothParams { self_contact: on.then_some(contact), ..Default::default() };
        // From 0.8 m the two sides whip into each other under the bar; from lower they only
        // swing down.
        let pose = Affine3A::from_translation(Vec3::new(0.12, 0.8, 0.0));
        let mut sim = ClothSim::new(params, Arc::clone(&fold), pose, &[]).expect("a valid cloth");
        let ticks = (SECONDS / TICK).round() as u32;
        let seconds = time(|| {
            for _ in 0..ticks {
                sim.tick(TICK, std::slice::from_ref(&bar));
            }
        });
        let x = sim.positions();
        println!(
            "| 64 x 64 (1 m) over a bar of radius 3 cm | {} | {} | — | {} | {:.2} |",
            if on { "on" } else { "off" },
            crossing_triangles(&fold, &x, None),
            close_pairs(&fold, &x, None, 0.5 * THICKNESS),
            seconds * 1e3 / ticks as f64
        );
    }
    let surface = collider(bunny, 5).with_exact_contact(bunny.as_mesh_ref()).expect("the bunny has area");
    let two = Arc::new(ClothTopology::grid(square_grid(64)).expect("a valid grid"));
    let top = bvh_cloth_bench::top_of(&surface);
    for on in [true, false] {
        let params = ClothParams { self_contact: on.then_some(contact), ..Default::default() };
        let place = |lift: f32, turn: f32| {
            Affine3A::from_rotation_translation(Quat::from_rotation_y(turn), Vec3::new(-0.1, top + lift, 0.0))
        };
        let mut lower = ClothSim::new(params.clone(), Arc::clone(&two), place(0.2, 0.0), &[]).expect("a valid cloth");
        let mut upper = ClothSim::new(params, Arc::clone(&two), place(0.35, 0.5), &[]).expect("a valid cloth");
        let mut solver = ContactSolver::default();
        let ticks = (SECONDS / TICK).round() as u32;
        let seconds = time(|| {
            for _ in 0..ticks {
                ClothSim::tick_together(
                    &mut [&mut lower, &mut upper],
                    TICK,
                    std::slice::from_ref(&surface),
                    &mut solver,
                );
            }
        });
        let (a, b) = (lower.positions(), upper.positions());
        let within = crossing_triangles(&two, &a, None) + crossing_triangles(&two, &b, None);
        let between = crossing_triangles(&two, &a, Some((&two, &b)));
        let close = close_pairs(&two, &a, None, 0.5 * THICKNESS)
            + close_pairs(&two, &b, None, 0.5 * THICKNESS)
            + close_pairs(&two, &a, Some(&b), 0.5 * THICKNESS);
        println!(
            "| two 64 x 64 (1.4 m) dropped on each other onto the bunny (exact contact) | {} | {within} | {between} | {close} | {:.2} |",
            if on { "on" } else { "off" },
            seconds * 1e3 / ticks as f64
        );
    }

    println!("\n### Cost: a 128 x 128 cloth (1.4 m) resting on the bunny\n");
    println!(
        "The cloth falls 1 s with self-contact, then the same state ticks with and without it, alternating, best of 5 each (ms per 60 Hz tick, Looper 16).\n"
    );
    println!("| threads | tick without contact ms | tick with contact ms | contact / rest of the tick |");
    println!("|---|---|---|---|");
    let (surface, with) = resting_with_self_contact(bunny);
    let mut without = with.clone();
    without.set_params(ClothParams { self_contact: None, ..with.params().clone() }).expect("valid parameters");
    print_with_and_without(single, threads, &without, &with, std::slice::from_ref(&surface), 5);
}

/// The self-contact cost scene: the bunny at n = 5 with its exact surface, and a 128 x 128
/// cloth (1.4 m) after falling onto it for 1 s with self-contact.
fn resting_with_self_contact(bunny: &ObjMesh) -> (Collider, ClothSim) {
    let surface = collider(bunny, 5).with_exact_contact(bunny.as_mesh_ref()).expect("the bunny has area");
    let top = bvh_cloth_bench::top_of(&surface);
    let big = Arc::new(ClothTopology::grid(square_grid(128)).expect("a valid grid"));
    let params = ClothParams { self_contact: Some(SELF_CONTACT), ..Default::default() };
    let mut with = ClothSim::new(params, big, Affine3A::from_translation(Vec3::new(-0.1, top + 0.2, 0.0)), &[])
        .expect("a valid cloth");
    for _ in 0..(1.0 / TICK).round() as u32 {
        with.tick(TICK, std::slice::from_ref(&surface));
    }
    (surface, with)
}

/// Self-contact's cost on the GPU (the `self_contact_gpu` section, after `self_contact`).
fn self_contact_on_gpu(bunny: &ObjMesh, gpu: Option<&Gpu>) {
    println!("\n### Cost on the GPU: the same 128 x 128 cloth\n");
    let Some(gpu) = gpu else {
        println!("No GPU adapter.");
        return;
    };
    println!(
        "From the state above, one more second on the GPU, then GPU ms per tick by timestamp queries, each dispatch in a compute pass of its own, median of 9 ticks: the eight self-contact kernels against everything else.\n"
    );
    println!("| adapter | self-contact ms | rest of the tick ms | self-contact / rest |");
    println!("|---|---|---|---|");
    let (surface, with) = resting_with_self_contact(bunny);
    print_kernel_share(gpu, &surface, &with, Kernel::ContactFind);
}

/// Pairs of intersecting triangles: within `topology`'s cloth at `x` (pairs sharing no corner),
/// or between it and `other`'s cloth.
fn crossing_triangles(topology: &ClothTopology, x: &[Vec3], other: Option<(&ClothTopology, &[Vec3])>) -> usize {
    crossing_pairs(topology.triangles(), x, other.map(|(t, y)| (t.triangles(), y)))
}

/// Pairs of particles closer than `limit`: within `topology`'s cloth at `x` (sharing no spring
/// and lying farther apart than the limit's double in the rest shape), or between it and
/// `other` (a cloth of the same topology).
fn close_pairs(topology: &ClothTopology, x: &[Vec3], other: Option<&[Vec3]>, limit: f32) -> usize {
    let rest = topology.rest_positions();
    (0..x.len())
        .into_par_iter()
        .map(|i| match other {
            Some(y) => y.iter().filter(|q| x[i].distance(**q) < limit).count(),
            None => (i + 1..x.len())
                .filter(|&j| {
                    x[i].distance(x[j]) < limit
                        && rest[i].distance(rest[j]) >= 2.0 * limit
                        && !topology.springs_of(i).iter().any(|e| e.other as usize == j)
                })
                .count(),
        })
        .sum()
}

/// Bones of the skinned-collider scenes.
const BONES: usize = 8;

/// Every vertex weighted to the two bones whose centres are nearest its height, linearly.
fn bone_weights(mesh: &ObjMesh) -> (Vec<[u16; 4]>, Vec<[f32; 4]>) {
    let (lo, hi) =
        mesh.positions.iter().fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), p| (lo.min(p[1]), hi.max(p[1])));
    mesh.positions
        .iter()
        .map(|p| {
            let t = ((p[1] - lo) / (hi - lo) * BONES as f32 - 0.5).clamp(0.0, (BONES - 1) as f32);
            let below = (t.floor() as usize).min(BONES - 2);
            let w = t - below as f32;
            ([below as u16, below as u16 + 1, 0, 0], [1.0 - w, w, 0.0, 0.0])
        })
        .unzip()
}

/// Each bone turned 0.15 rad more than the one below it about a horizontal axis through its
/// base, the bones chained: the model bends like a spine.
fn bent_pose() -> Vec<Affine3A> {
    let mut matrices = Vec::with_capacity(BONES);
    let mut parent = Affine3A::IDENTITY;
    for bone in 0..BONES {
        let base = Vec3::new(0.0, bone as f32 / BONES as f32, 0.0);
        let turn =
            Affine3A::from_translation(base) * Affine3A::from_rotation_z(0.15) * Affine3A::from_translation(-base);
        parent *= turn;
        matrices.push(parent);
    }
    matrices
}

/// The flag of the wind section: 1.5 m x 1 m, 48 x 32 particles, 0.3 kg, SpringK 400, held
/// along its hoist (a vertical pole at the origin), standing in the XY plane, with
/// [`Aerodynamics::FABRIC`].
fn flag(integrator: Integrator) -> ClothSim {
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
fn alone_on_gpu(gpu: &Gpu, sim: &ClothSim) -> (ClothBatch, bvh_cloth_gpu::ClothId) {
    let mut batch = ClothBatch::new(&gpu.device, &gpu.queue);
    let id = batch.insert(&gpu.device, &gpu.queue, sim).expect("the cloth fits the device");
    batch.set_params(&gpu.queue, id, sim.params(), TICK);
    (batch, id)
}

/// Runs `ticks` ticks of `batch` against `colliders`, submitted without waiting.
fn run_on_gpu(gpu: &Gpu, batch: &mut ClothBatch, colliders: &GpuColliders, ticks: u32) {
    batch.prepare(&gpu.device, &gpu.queue, &gpu.kernels, colliders);
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    batch.encode_ticks(&mut encoder, &gpu.kernels, ticks);
    gpu.queue.submit([encoder.finish()]);
}

/// Cloth `id`'s particles as the GPU has them (a blocking read).
fn particles_on_gpu(gpu: &Gpu, batch: &ClothBatch, id: bvh_cloth_gpu::ClothId) -> Vec<GpuParticle> {
    let (buffer, offset, size) = batch.particles(id).expect("the cloth is in the batch");
    let all: Vec<GpuParticle> = headless::read(&gpu.device, &gpu.queue, buffer);
    let first = (offset / size_of::<GpuParticle>() as u64) as usize;
    all[first..first + (size / size_of::<GpuParticle>() as u64) as usize].to_vec()
}

/// The solvers of the flutter table: block descent as it comes, block descent converged
/// further in each substep (which a flutter needs, being fast motion), and RK4.
const FLUTTER_INTEGRATORS: [Integrator; 3] =
    [Integrator::BLOCK_DESCENT, Integrator::BlockDescent { iterations: 4 }, Integrator::Rk4];

/// The particle at the middle of the flag's free edge.
const FLAG_PROBE: usize = 16 * 48 + 47;

/// The largest peak of the spectrum of `x` (sampled every `dt` seconds, its mean removed)
/// away from zero frequency: `(frequency in Hz, amplitude)`, by a plain DFT.
fn spectral_peak(x: &[f32], dt: f32) -> (f64, f64) {
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

/// Kinetic energy in joules.
fn kinetic_energy(sim: &ClothSim) -> f64 {
    sim.velocities().iter().enumerate().map(|(i, v)| 0.5 * f64::from(sim.particle_mass(i) * v.length_squared())).sum()
}

/// Ticks the flag settles in the wind before its flutter is sampled, and ticks sampled.
const SETTLE: u32 = 240;
const SAMPLES: usize = 360;

/// The flag stepped by `integrator` on the CPU in a steady 8 m/s wind along its plane: after
/// [`SETTLE`] ticks, the cross-wind position of the middle of its free edge and its kinetic
/// energy at each of [`SAMPLES`] ticks.
fn flutter_on_cpu(integrator: Integrator) -> (Vec<f32>, Vec<f64>) {
    let mut sim = flag(integrator);
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

fn wind(single: &rayon::ThreadPool, threads: usize) {
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
fn print_flag_setup() {
    println!(
        "A flag of 1.5 m x 1 m (48 x 32 particles, 0.3 kg, SpringK 400, Looper 16, drag 1.2, lift 0.8) held along a vertical pole, in a steady 8 m/s wind along its plane. After {:.0} s, the cross-wind (z) position of the middle of its free edge is sampled every tick for {:.0} s; its spectrum's largest peak away from zero frequency is the flutter, and the mean kinetic energy of the two halves of that window shows whether it grows.\n",
        SETTLE as f32 * TICK,
        SAMPLES as f32 * TICK
    );
    println!("| backend | integrator | flutter Hz | amplitude mm | kinetic energy, first half J | second half J |");
    println!("|---|---|---|---|---|---|");
}

/// One row of the flutter table: the free edge's spectral peak and the window's energy halves.
fn print_flutter(backend: &str, integrator: Integrator, z: &[f32], energy: &[f64]) {
    let (hz, amplitude) = spectral_peak(z, TICK);
    let half = energy.len() / 2;
    let mean = |e: &[f64]| e.iter().sum::<f64>() / e.len() as f64;
    println!(
        "| {backend} | {integrator:?} | {hz:.2} | {:.1} | {:.4} | {:.4} |",
        amplitude * 1e3,
        mean(&energy[..half]),
        mean(&energy[half..])
    );
}

/// The wind-cost scene: a 64 x 64 cloth (1.4 m) hanging from two corners after 1 s in gusty
/// wind, without and with drag and lift from that state.
fn hanging_in_gusts() -> (ClothSim, ClothSim) {
    let grid = Arc::new(ClothTopology::grid(square_grid(64)).expect("a valid grid"));
    let params = ClothParams { aerodynamics: Aerodynamics::FABRIC, ..Default::default() };
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
fn wind_on_gpu(bunny: &ObjMesh, gpu: Option<&Gpu>) {
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
        print_flutter(&format!("GPU ({})", gpu.name), integrator, &z, &energy);
    }

    println!("\n### GPU against CPU in gusty wind\n");
    println!(
        "The flag (block descent) in `Wind::gusty` (8 m/s, 40% gusts, 1.6 m/s turbulence), 90 ticks; before each tick the GPU takes the CPU's state, and both sample the wind at the same clock time. Largest distance between the two after one tick:\n"
    );
    let mut sim = flag(Integrator::BLOCK_DESCENT);
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
    println!("| adapter | largest gap m |\n|---|---|\n| {} | {worst:.1e} |", gpu.name);

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
            println!("| {} | {off:.3} | {on:.3} | {:.0}% |", gpu.name, (on - off) / off * 100.0)
        }
        _ => println!("| {} | no timestamp queries | | |", gpu.name),
    }
    if gpu.software {
        println!("\nThe GPU here is a software adapter on the same CPU cores: its times are not GPU figures.");
    }
}
