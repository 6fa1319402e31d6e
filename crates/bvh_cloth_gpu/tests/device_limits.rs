//! Devices smaller than the work: each limit the kernels depend on, lowered on a real device
//! (lavapipe in CI), gives a typed refusal instead of a wgpu validation error. wgpu's default
//! error handler panics on a validation error, so a test that returns had none.
//!
//! Also: thousands of cloths created, stepped and dropped leave no GPU resource behind.

use bvh_cloth_core::gpu_layout::GpuParticle;
use std::sync::Arc;

use bvh_cloth_core::gpu_layout::gpu_topology_words;
use bvh_cloth_core::{Affine3A, ClothGrid, ClothParams, ClothSim, ClothTopology, Collider, MeshRef, UVec2, Vec2, Vec3};
use bvh_cloth_gpu::headless::{self, HeadlessGpu};
use bvh_cloth_gpu::wgpu;
use bvh_cloth_gpu::{ClothKernels, FaultReadback, GpuCloth, GpuColliders, KernelError, STORAGE_BUFFERS_NEEDED};

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

#[test]
fn a_device_with_too_few_storage_buffers_is_refused() {
    let Some(gpu) = gpu(|limits| wgpu::Limits { max_storage_buffers_per_shader_stage: 4, ..limits }) else { return };
    let error = ClothKernels::new(&gpu.device).unwrap_err();
    assert_eq!(error, KernelError::TooFewStorageBuffers { allowed: 4 });
    assert!(error.to_string().contains(&format!("need {STORAGE_BUFFERS_NEEDED}")), "{error}");
}

#[test]
fn a_cloth_beyond_one_dispatch_is_refused_and_smaller_ones_run() {
    // Four by four workgroups of 8 x 8 threads: at most 1,024 particles.
    let Some(gpu) = gpu(|limits| wgpu::Limits { max_compute_workgroups_per_dimension: 4, ..limits }) else { return };
    let kernels = ClothKernels::new(&gpu.device).unwrap();
    let error = GpuCloth::new(&gpu.device, &kernels, &cloth(33, 32)).unwrap_err();
    assert_eq!(error, KernelError::TooManyThreads { count: 33 * 32, max_workgroups: 4 });
    assert!(error.to_string().contains("1056 particles"), "{error}");

    let sim = cloth(32, 32);
    let mut fits = GpuCloth::new(&gpu.device, &kernels, &sim).expect("32 x 32 fits 4 x 4 workgroups");
    let none = GpuColliders::new(&gpu.device, &[]);
    fits.set_params(&gpu.queue, sim.params(), 1.0 / 60.0, &none);
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    fits.encode_ticks(&gpu.device, &mut encoder, &kernels, &none, 2);
    gpu.queue.submit([encoder.finish()]);
    let particles: Vec<GpuParticle> = headless::read(&gpu.device, &gpu.queue, fits.particles());
    assert!(particles.iter().all(|p| p.position[1] < 1.0 && p.position.iter().all(|x| x.is_finite())), "it fell");
}

#[test]
fn a_cloth_beyond_one_storage_binding_is_refused() {
    // The largest buffer of a cloth is its spring list (16 bytes per spring end, about 12 per
    // particle): bindings of exactly a 16 x 16 grid's spring list take that cloth and refuse one
    // row more.
    let spring_bytes = |sim: &ClothSim| 4 * gpu_topology_words(sim.topology()).len() as u64;
    let (fits, too_big) = (cloth(16, 16), cloth(17, 16));
    let max = spring_bytes(&fits);
    assert!(max > 16 * 16 * size_of::<GpuParticle>() as u64, "the springs are the largest buffer");
    let Some(gpu) = gpu(|limits| wgpu::Limits { max_storage_buffer_binding_size: max, ..limits }) else { return };
    let kernels = ClothKernels::new(&gpu.device).unwrap();
    let error = GpuCloth::new(&gpu.device, &kernels, &too_big).unwrap_err();
    assert_eq!(error, KernelError::BufferTooLarge { bytes: spring_bytes(&too_big), max });
    assert!(error.to_string().contains(&format!("{} bytes", spring_bytes(&too_big))), "{error}");
    assert!(GpuCloth::new(&gpu.device, &kernels, &fits).is_ok(), "a spring list of exactly the limit fits");
}

#[test]
fn colliders_beyond_one_storage_binding_are_left_out_and_the_rest_kept() {
    let (small, large) = (boxy(1), boxy(8));
    let node_bytes = |c: &Collider| c.lbvh.nodes.len() * size_of::<bvh_cloth_core::BvhNode>();
    let sphere_bytes = |c: &Collider| c.lbvh.spheres.len() * size_of::<bvh_cloth_core::Sphere>();
    // Room for the small tree twice, not for the large one beside it.
    let room = (2 * node_bytes(&small).max(sphere_bytes(&small))) as u64;
    assert!(node_bytes(&large).max(sphere_bytes(&large)) as u64 > room);
    let Some(gpu) = gpu(|limits| wgpu::Limits { max_storage_buffer_binding_size: room.next_multiple_of(4), ..limits })
    else {
        return;
    };
    let colliders = GpuColliders::new(&gpu.device, &[small.clone(), large, small]);
    assert_eq!(colliders.left_out(), [1]);
    assert_eq!(colliders.len(), 2);
}

/// Live wgpu buffers and bind groups: the handles the program holds.
fn live(gpu: &HeadlessGpu) -> (usize, usize) {
    let report = gpu.instance.generate_report().expect("a wgpu-core instance reports");
    (report.hub.buffers.num_kept_from_user, report.hub.bind_groups.num_kept_from_user)
}

#[test]
fn thousands_of_cloths_created_stepped_and_dropped_leave_no_gpu_resource() {
    let Some(gpu) = gpu(|limits| limits) else { return };
    let kernels = ClothKernels::new(&gpu.device).unwrap();
    let collider = boxy(3);
    let before = live(&gpu);
    for round in 0..2000u32 {
        let sim = cloth(2 + round % 13, 2 + round % 7);
        let colliders = GpuColliders::new(&gpu.device, std::slice::from_ref(&collider));
        let mut cloth = GpuCloth::new(&gpu.device, &kernels, &sim).unwrap();
        cloth.set_params(&gpu.queue, sim.params(), 1.0 / 60.0, &colliders);
        let faults = FaultReadback::new(&gpu.device);
        if round == 0 {
            // The count sees the handles held: the cloth's params, state, stage, fault and
            // surface buffers (two more stages and the springs live inside its bind groups),
            // 3 collider buffers, and the staging buffer.
            assert_eq!(live(&gpu), (before.0 + 9, before.1 + 5));
        }
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        cloth.encode_ticks(&gpu.device, &mut encoder, &kernels, &colliders, 1);
        faults.record(&mut encoder, &cloth);
        gpu.queue.submit([encoder.finish()]);
        faults.submitted();
        if round % 100 == 0 {
            headless::wait(&gpu.device);
        }
        // Everything is dropped here, some of it with work or a map still in flight.
    }
    headless::wait(&gpu.device);
    assert_eq!(live(&gpu), before, "(buffers, bind groups) alive before and after 2,000 cloths");
}
