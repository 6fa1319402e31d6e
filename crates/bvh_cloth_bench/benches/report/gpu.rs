//! The GPU the report runs on, and the timings its GPU tables share: a frame's wall time on
//! the batch, and each kernel's share of a tick by timestamp queries.

use super::*;

/// The GPU the report runs on: a device with the kernels compiled on it.
pub(crate) type Gpu = headless::KernelRig;

/// Median wall time (ms) of `ticks` ticks of a `size x size` cloth on the GPU, around a blocking
/// submit, after the cloth has fallen onto `colliders` for one simulated second.
pub(crate) fn gpu_frame_ms(gpu: &Gpu, colliders: &[Collider], size: u32, ticks: u32) -> f64 {
    gpu_sim_frame_ms(gpu, colliders, &cloth_above(&colliders[0], size, Integrator::Rk4), ticks)
}

/// Median wall time (ms) of `ticks` ticks of `cpu`'s cloth on the GPU, as [`gpu_frame_ms`].
pub(crate) fn gpu_sim_frame_ms(gpu: &Gpu, colliders: &[Collider], cpu: &ClothSim, ticks: u32) -> f64 {
    let samples = if cpu.len() > 128 * 128 { 5 } else { FRAMES };
    gpu_cloths_frame_ms(gpu, colliders, std::slice::from_ref(cpu), true, ticks, samples)
}

/// Median wall time (ms), around a blocking submit, of `ticks` ticks of every cloth of `cpus`
/// on the GPU, after 60 ticks of falling (10 on a software adapter): all in one batch when
/// `batched`, otherwise each in a batch of its own, encoded one after the other (the cost of
/// dispatching cloth by cloth).
pub(crate) fn gpu_cloths_frame_ms(
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
    frame(if gpu.is_software() { 10 } else { 60 });
    median((0..samples).map(|_| frame(ticks)).collect())
}

/// The column of [`kernel_ms`] a kernel's time goes to.
pub(crate) fn kernel_column(kernel: Kernel) -> usize {
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
        | Kernel::ContactApply
        | Kernel::ContactFindEdges
        | Kernel::Untangle => 6,
        Kernel::AirSample | Kernel::AirForces | Kernel::AirKick => 7,
        Kernel::Multigrid => 8,
    }
}

/// The rows of a with/without cost table: `with` and `without` (the same state, one feature
/// on and off) tick once each from clones, alternating, best of `reps` each, on one thread and
/// on the whole pool of `threads`; ms per tick and the feature's share of the rest.
pub(crate) fn print_with_and_without(
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
/// `kernel`'s column of [`kernel_column`] against the rest of the tick, then each of
/// `breakdown`'s kernels on its own, all from the same timed ticks ([`timed_ticks`]), and the
/// software adapter's caveat.
pub(crate) fn print_kernel_share(gpu: &Gpu, c: &Collider, cloth: &ClothSim, kernel: Kernel, breakdown: &[Kernel]) {
    let ticks = timed_ticks(gpu, c, std::slice::from_ref(cloth));
    match ticks.as_deref().map(by_column) {
        Some((column, total)) => {
            let part = column[kernel_column(kernel)];
            let rest = total - part;
            println!("| {} | {part:.3} | {rest:.3} | {:.0}% |", gpu.info.name, part / rest * 100.0);
        }
        None => println!("| {} | no timestamp queries | | |", gpu.info.name),
    }
    if let Some(ticks) = ticks.as_deref().filter(|_| !breakdown.is_empty()) {
        println!("\nThe same ticks by kernel, all of a tick's dispatches of each together (medians):\n");
        println!("| kernel | ms per tick |\n|---|---|");
        for &k in breakdown {
            let ms = median(ticks.iter().map(|t| t.iter().filter(|d| d.0 == k).map(|d| d.1).sum()).collect());
            println!("| {k:?} | {ms:.3} |");
        }
    }
    if gpu.is_software() {
        println!("\nThe GPU here is a software adapter on the same CPU cores: its times are not GPU figures.");
    }
}

/// GPU ms of one 60 Hz tick of `cloths` (one batch, colliding with `c`) by kernel, in
/// [`kernel_column`] order, and in all: medians of the ticks of [`timed_ticks`].
pub(crate) fn kernel_ms(gpu: &Gpu, c: &Collider, cloths: &[ClothSim]) -> Option<([f64; 9], f64)> {
    timed_ticks(gpu, c, cloths).as_deref().map(by_column)
}

/// The medians of timed ticks summed by [`kernel_column`], and of their totals.
fn by_column(ticks: &[Vec<(Kernel, f64)>]) -> ([f64; 9], f64) {
    let samples: Vec<[f64; 9]> = ticks
        .iter()
        .map(|tick| {
            let mut ms = [0.0f64; 9];
            for &(kernel, t) in tick {
                ms[kernel_column(kernel)] += t;
            }
            ms
        })
        .collect();
    let total = median(samples.iter().map(|s| s.iter().sum()).collect());
    (core::array::from_fn(|k| median(samples.iter().map(|s| s[k]).collect())), total)
}

/// Each dispatch's kernel and GPU ms in 9 ticks of `cloths` (one batch, colliding with `c`),
/// timed with timestamp queries, each dispatch in a compute pass of its own, after a second of
/// falling (10 ticks on a software adapter). `None` without timestamp queries, or when a tick
/// has more dispatches than a query set holds.
fn timed_ticks(gpu: &Gpu, c: &Collider, cloths: &[ClothSim]) -> Option<Vec<Vec<(Kernel, f64)>>> {
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
    batch.encode_ticks(&mut encoder, &gpu.kernels, if gpu.is_software() { 10 } else { 60 });
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
    let mut ticks = Vec::new();
    for _ in 0..9 {
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        let kernels = batch.encode_ticks_timed(&mut encoder, &gpu.kernels, 1, &queries, capacity)?;
        let used = 2 * kernels.len() as u32;
        encoder.resolve_query_set(&queries, 0..used, &resolved, 0);
        gpu.queue.submit([encoder.finish()]);
        let stamps: Vec<u64> = headless::read(&gpu.device, &gpu.queue, &resolved);
        let ms = |k: usize| stamps[2 * k + 1].saturating_sub(stamps[2 * k]) as f64 * period_ns * 1e-6;
        ticks.push(kernels.iter().enumerate().map(|(k, &kernel)| (kernel, ms(k))).collect());
    }
    Some(ticks)
}

/// Cloth `id`'s particles as the GPU has them (a blocking read).
pub(crate) fn particles_on_gpu(gpu: &Gpu, batch: &ClothBatch, id: bvh_cloth_gpu::ClothId) -> Vec<GpuParticle> {
    batch.read_particles(&gpu.device, &gpu.queue, id).expect("the cloth is in the batch")
}
