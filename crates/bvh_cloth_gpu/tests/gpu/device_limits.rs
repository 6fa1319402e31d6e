//! Devices smaller than the work: each limit the kernels depend on, lowered on a real device
//! (lavapipe in CI), gives a typed refusal instead of a wgpu validation error. wgpu's default
//! error handler panics on a validation error, so a test that returns had none.
//!
//! Also: thousands of cloths added to a batch, stepped and removed leave no GPU resource behind.

use bvh_cloth_gpu::layout::GpuParticle;
use std::sync::Arc;

use bvh_cloth_core::{Affine3A, ClothGrid, ClothParams, ClothSim, ClothTopology, Collider, MeshRef, UVec2, Vec2, Vec3};
use bvh_cloth_gpu::headless::{self, HeadlessGpu};
use bvh_cloth_gpu::wgpu;
use bvh_cloth_gpu::{
    ClothBatch, ClothId, ClothKernels, FaultReadback, GpuColliders, KernelError, STORAGE_BUFFERS_NEEDED,
};

/// A device with the limits `limit` makes of the adapter's, or `None` (with a note) when there
/// is no adapter and none is required.
fn gpu(limit: impl FnOnce(wgpu::Limits) -> wgpu::Limits) -> Option<HeadlessGpu> {
    let gpu = headless::device_with_limits(limit);
    if gpu.is_none() {
        assert!(std::env::var_os("BVH_CLOTH_REQUIRE_GPU").is_none(), "no GPU adapter (install mesa-vulkan-drivers)");
        eprintln!("no GPU adapter: skipped");
    }
    gpu
}

fn cloth(rows: u32, cols: u32) -> ClothSim {
    let grid = ClothTopology::grid(ClothGrid::new(Vec2::ONE, UVec2::new(cols, rows))).unwrap();
    ClothSim::new(ClothParams::default(), Arc::new(grid), Affine3A::from_translation(Vec3::Y), &[]).unwrap()
}

/// A closed box of `2 x 2 x 2` unit cells' worth of triangles, voxelised at `n`.
fn boxy(n: u32) -> Collider {
    let positions: Vec<[f32; 3]> = (0..8).map(|k| [(k & 1) as f32, ((k >> 1) & 1) as f32, (k >> 2) as f32]).collect();
    let indices =
        [0, 1, 3, 0, 3, 2, 4, 6, 7, 4, 7, 5, 0, 4, 5, 0, 5, 1, 2, 3, 7, 2, 7, 6, 0, 2, 6, 0, 6, 4, 1, 5, 7, 1, 7, 3];
    Collider::from_mesh(MeshRef { positions: &positions, indices: Some(&indices) }, n).unwrap()
}

/// Cloth `id`'s particles after `ticks` ticks of `batch` with no collider.
fn ticked(
    gpu: &HeadlessGpu,
    batch: &mut ClothBatch,
    kernels: &ClothKernels,
    id: ClothId,
    ticks: u32,
) -> Vec<GpuParticle> {
    batch.prepare(&gpu.device, &gpu.queue, kernels, &GpuColliders::new(&gpu.device, &[]));
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    batch.encode_ticks(&mut encoder, kernels, ticks);
    gpu.queue.submit([encoder.finish()]);
    batch.read_particles(&gpu.device, &gpu.queue, id).expect("the cloth is in the batch")
}

#[test]
fn a_device_with_too_few_storage_buffers_is_refused() {
    let allowed = STORAGE_BUFFERS_NEEDED - 1;
    let Some(gpu) = gpu(|limits| wgpu::Limits { max_storage_buffers_per_shader_stage: allowed, ..limits }) else {
        return;
    };
    let error = ClothKernels::new(&gpu.device).unwrap_err();
    assert_eq!(error, KernelError::TooFewStorageBuffers { allowed });
    assert!(error.to_string().contains(&format!("need {STORAGE_BUFFERS_NEEDED}")), "{error}");
}

#[test]
fn a_cloth_beyond_one_dispatch_is_refused_and_smaller_ones_run() {
    // Four by four workgroups of 8 x 8 threads: at most 1,024 particles.
    let Some(gpu) = gpu(|limits| wgpu::Limits { max_compute_workgroups_per_dimension: 4, ..limits }) else { return };
    let kernels = ClothKernels::new(&gpu.device).unwrap();
    let mut batch = ClothBatch::new(&gpu.device, &gpu.queue);
    let error = batch.insert(&gpu.device, &gpu.queue, &cloth(33, 32)).unwrap_err();
    assert_eq!(error, KernelError::TooManyThreads { count: 33 * 32, max_workgroups: 4 });
    assert!(error.to_string().contains("1056 particles"), "{error}");
    assert!(batch.is_empty(), "the refused cloth left nothing behind");

    let sim = cloth(32, 32);
    let id = batch.insert(&gpu.device, &gpu.queue, &sim).expect("32 x 32 fits 4 x 4 workgroups");
    let error = batch.insert(&gpu.device, &gpu.queue, &cloth(2, 2)).unwrap_err();
    assert_eq!(error, KernelError::TooManyThreads { count: 32 * 32 + 4, max_workgroups: 4 }, "the batch is full");
    batch.set_params(&gpu.queue, id, sim.params(), 1.0 / 60.0);
    let particles = ticked(&gpu, &mut batch, &kernels, id, 2);
    assert!(particles.iter().all(|p| p.position[1] < 1.0 && p.position.iter().all(|x| x.is_finite())), "it fell");
}

#[test]
fn a_cloth_beyond_one_storage_binding_is_refused() {
    // The largest buffer of a cloth is its spring list (16 bytes per spring end, about 12 per
    // particle): bindings of exactly a 16 x 16 grid's spring list take that cloth and refuse one
    // row more.
    let spring_bytes = |sim: &ClothSim| 16 * sim.topology().spring_ends().len() as u64;
    let (fits, too_big) = (cloth(16, 16), cloth(17, 16));
    let max = spring_bytes(&fits);
    assert!(max > 16 * 16 * size_of::<GpuParticle>() as u64, "the springs are the largest buffer");
    let Some(gpu) = gpu(|limits| wgpu::Limits { max_storage_buffer_binding_size: max, ..limits }) else { return };
    let mut batch = ClothBatch::new(&gpu.device, &gpu.queue);
    let error = batch.insert(&gpu.device, &gpu.queue, &too_big).unwrap_err();
    assert_eq!(error, KernelError::BufferTooLarge { bytes: spring_bytes(&too_big), max });
    assert!(error.to_string().contains(&format!("{} bytes", spring_bytes(&too_big))), "{error}");
    assert!(batch.insert(&gpu.device, &gpu.queue, &fits).is_ok(), "a spring list of exactly the limit fits");
}

#[test]
fn colliders_beyond_one_storage_binding_are_left_out_and_the_rest_kept() {
    let (small, large) = (boxy(1), boxy(8));
    let node_bytes =
        |c: &Collider| c.lbvh().expect("a mesh collider").nodes.len() * size_of::<bvh_cloth_core::BvhNode>();
    let sphere_bytes =
        |c: &Collider| c.lbvh().expect("a mesh collider").spheres.len() * size_of::<bvh_cloth_core::Sphere>();
    // Room for the small tree twice (nodes and spheres share one buffer), not for the large
    // one beside it.
    let room = (2 * (node_bytes(&small) + sphere_bytes(&small))) as u64;
    assert!((node_bytes(&large) + sphere_bytes(&large)) as u64 > room);
    let Some(gpu) = gpu(|limits| wgpu::Limits { max_storage_buffer_binding_size: room.next_multiple_of(4), ..limits })
    else {
        return;
    };
    let colliders = GpuColliders::new(&gpu.device, &[small.clone(), large, small]);
    assert_eq!(colliders.left_out(), [1]);
    assert_eq!(colliders.len(), 2);
}

/// A cloth whose wind and triangle forces would not fit one storage binding, though all its
/// other buffers do, runs without drag and lift and says why; on a device with room an updraft
/// slows its fall. The cloth is a square of two triangles listed 50 times over, so that it has many
/// triangles for its few particles and springs.
#[test]
fn air_beyond_one_storage_binding_is_refused_and_the_cloth_runs_without_it() {
    use bvh_cloth_core::{Aerodynamics, Wind};
    let positions = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 1.0]];
    let indices: Vec<u32> = [0, 2, 1, 1, 2, 3].repeat(50);
    let topology = ClothTopology::from_mesh(MeshRef { positions: &positions, indices: Some(&indices) }).unwrap();
    assert_eq!(topology.triangles().len(), 100, "repeated triangles are kept");
    let params = ClothParams { aerodynamics: Aerodynamics::FABRIC, ..Default::default() };
    let mut sim = ClothSim::new(params, Arc::new(topology), Affine3A::from_translation(Vec3::Y), &[]).unwrap();
    sim.set_wind(Wind::steady(Vec3::new(0.0, 5.0, 0.0)), &[]).unwrap();
    // The surface words are the cloth's largest buffer: a binding of exactly their size.
    let surface = 4 * bvh_cloth_gpu::layout::gpu_surface_words(sim.topology()).len() as u64;
    let air_bytes = |particle_slots: u64| 16 * (particle_slots + 100);
    let run = |gpu: &HeadlessGpu| {
        let kernels = ClothKernels::new(&gpu.device).unwrap();
        let mut batch = ClothBatch::new(&gpu.device, &gpu.queue);
        let id = batch.insert(&gpu.device, &gpu.queue, &sim).expect("every buffer of the cloth fits");
        batch.set_params(&gpu.queue, id, sim.params(), 1.0 / 60.0);
        batch.set_wind(id, *sim.wind()).unwrap();
        let particles = ticked(gpu, &mut batch, &kernels, id, 3);
        let fall = particles.iter().map(|p| p.velocity[1]).sum::<f32>() / 4.0;
        assert!(particles.iter().all(|p| p.position.iter().chain(&p.velocity).all(|x| x.is_finite())));
        (batch.air_error().cloned(), fall)
    };
    let Some(small) = gpu(|limits| wgpu::Limits { max_storage_buffer_binding_size: surface, ..limits }) else { return };
    let (error, still) = run(&small);
    // The batch gives a cloth of 4 particles 64 particle slots.
    assert_eq!(error, Some(KernelError::BufferTooLarge { bytes: air_bytes(64), max: surface }));
    assert!(error.unwrap().to_string().contains(&format!("{} bytes", air_bytes(64))));

    let roomy = gpu(|limits| limits).expect("the same adapter");
    let (error, blown) = run(&roomy);
    assert_eq!(error, None);
    assert!(still < -0.1, "in still air the cloth falls: {still} m/s");
    // An updraft under the flat cloth slows its fall.
    assert!(blown > still + 0.05, "falling at {blown} m/s in the updraft, {still} m/s without it");
}

/// Live wgpu buffers and bind groups: the handles the program holds.
fn live(gpu: &HeadlessGpu) -> (usize, usize) {
    let report = gpu.instance.generate_report().expect("a wgpu-core instance reports");
    (report.hub.buffers.num_kept_from_user, report.hub.bind_groups.num_kept_from_user)
}

#[test]
fn thousands_of_cloths_added_stepped_and_removed_leave_no_gpu_resource() {
    let Some(gpu) = gpu(|limits| limits) else { return };
    let kernels = ClothKernels::new(&gpu.device).unwrap();
    let collider = boxy(3);
    let before = live(&gpu);
    let colliders = GpuColliders::new(&gpu.device, std::slice::from_ref(&collider));
    let mut batch = ClothBatch::new(&gpu.device, &gpu.queue);
    let resident = batch.insert(&gpu.device, &gpu.queue, &cloth(8, 8)).unwrap();
    batch.set_params(&gpu.queue, resident, &ClothParams::default(), 1.0 / 60.0);
    let mut settled = None;
    for round in 0..2000u32 {
        let sim = cloth(2 + round % 13, 2 + round % 7);
        let id = batch.insert(&gpu.device, &gpu.queue, &sim).unwrap();
        batch.set_params(&gpu.queue, id, sim.params(), 1.0 / 60.0);
        batch.prepare(&gpu.device, &gpu.queue, &kernels, &colliders);
        let faults = FaultReadback::new(&gpu.device);
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        batch.encode_ticks(&mut encoder, &kernels, 1);
        faults.record(&mut encoder, &batch, id);
        gpu.queue.submit([encoder.finish()]);
        faults.submitted();
        batch.remove(&gpu.queue, id);
        // Dropped with its map possibly still in flight.
        drop(faults);
        if round % 100 == 0 {
            headless::wait(&gpu.device);
        }
        // The batch settles on buffers big enough for the largest round; from then on the
        // rounds reuse them.
        if round == 200 {
            headless::wait(&gpu.device);
            settled = Some(live(&gpu));
        }
    }
    headless::wait(&gpu.device);
    assert_eq!(Some(live(&gpu)), settled, "(buffers, bind groups) alive after round 200 and after round 2,000");
    assert_eq!(batch.len(), 1);
    drop((batch, colliders));
    headless::wait(&gpu.device);
    assert_eq!(live(&gpu), before, "(buffers, bind groups) alive before and after");
}
