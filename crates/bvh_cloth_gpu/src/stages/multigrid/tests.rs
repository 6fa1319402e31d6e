//! The multigrid kernels against the CPU reference ([`MultigridCorrection::correct`]): two
//! cloths of one plan, two substeps (the first implicit Euler's, assembling and factoring the
//! levels; the second BDF2's or the blend's, keeping them and factoring them for its step), by
//! V-cycles and the first level's W-cycle, the corrected displacements compared particle by
//! particle.

use bvh_cloth_core::backend::{BLEND_STEP, ForceModel, MultigridCorrection, MultigridStepping};
use bvh_cloth_core::{ClothGrid, ClothParams, ClothTopology, Integrator, UVec2, Vec2, Vec3A};

use super::{MultigridCloth, MultigridPlan, SharedBuffers};
use crate::buffer::storage_buffer_with;
use crate::headless::{self, KernelRig};
use crate::kernels::ClothKernels;
use crate::layout::{GpuBatchCloth, GpuBatchFrame, GpuBatchStep, GpuParticle, gpu_particle_info};

fn rig() -> Option<KernelRig> {
    let Some(rig) = headless::kernel_rig() else {
        assert!(
            std::env::var_os("BVH_CLOTH_REQUIRE_GPU").is_none(),
            "no GPU adapter (install mesa-vulkan-drivers for lavapipe and set WGPU_BACKEND=vulkan)"
        );
        eprintln!("no GPU adapter: skipped");
        return None;
    };
    eprintln!("adapter: {:?}", rig.info.name);
    Some(rig)
}

/// One cloth's substep as both sides take it: the pins, the held particles, the substep's start,
/// its inertial target (less the start) and the sweep's displacements.
struct Case {
    topology: ClothTopology,
    free: Vec<f32>,
    held: Vec<f32>,
    start: Vec<Vec3A>,
    target: Vec<Vec3A>,
    d: Vec<Vec3A>,
}

/// A `side x side` cloth of `size` metres pinned at `pins`, with the particles of `held`
/// held, its start bent out of plane, and a smooth bulge for the sweep's displacements.
fn case(side: u32, size: f32, pins: &[usize], held: core::ops::Range<usize>, h: f32) -> Case {
    let topology = ClothTopology::grid(ClothGrid::new(Vec2::splat(size), UVec2::splat(side))).expect("a grid");
    let n = topology.len();
    let mut free = vec![1.0; n];
    for &p in pins {
        free[p] = 0.0;
    }
    let mut held_mask = vec![0.0; n];
    held_mask[held].fill(1.0);
    let start: Vec<Vec3A> = topology
        .rest_positions()
        .iter()
        .map(|&p| Vec3A::from(p) + Vec3A::new(0.0, 0.05 * (p.x * 4.0).sin() * p.z, 0.0))
        .collect();
    let target = (0..n).map(|i| free[i] * Vec3A::new(0.2 * h, -h * h * 9.81, 0.0)).collect();
    let d = start
        .iter()
        .enumerate()
        .map(|(i, p)| free[i] * Vec3A::new(0.002 * p.z, -0.01 * (p.x * 3.0).sin() * (p.z * 3.0 + 1.0).cos(), 0.0))
        .collect();
    Case { topology, free, held: held_mask, start, target, d }
}

/// Two corrections in a row of two cloths on the GPU agree with the CPU's: every particle's
/// displacement within 1e-4 of the largest change the CPU's correction made (f32 dense factor
/// and line-search sums against the CPU's f64).
#[test]
fn the_multigrid_kernels_correct_as_the_cpu_does() {
    corrections_agree(32, [MultigridStepping::Bdf2; 2]);
}

/// The same with one cloth blending BDF2 with implicit Euler and running `Cycle::TopW`, in one
/// plan with a cloth of V-cycles, whose second visit must leave its answer as it was: the deeper
/// cloth (four levels) each way.
#[test]
fn the_multigrid_kernels_run_w_cycles_as_the_cpu_does() {
    corrections_agree(128, [MultigridStepping::Blend, MultigridStepping::Bdf2]);
    corrections_agree(128, [MultigridStepping::Bdf2, MultigridStepping::Blend]);
}

/// Two cloths, `side` x `side` pinned at two corners and a free 20 x 20, stepped as
/// `steppings` says.
fn corrections_agree(side: u32, steppings: [MultigridStepping; 2]) {
    let Some(rig) = rig() else { return };
    let (device, queue) = (&rig.device, &rig.queue);
    let h = 1.0 / 960.0;
    let params = ClothParams { integrator: Integrator::Multigrid, ..Default::default() };
    let model = ForceModel::new(&params);
    let last = side as usize - 1;
    let mut cases = [case(side, 1.0, &[0, last], 100..110, h), case(20, 0.6, &[], 0..0, h)];
    let mut cpu: Vec<MultigridCorrection> =
        cases.iter().map(|c| MultigridCorrection::new(&c.topology, &model, &c.free, &c.held, &c.start, &c.d)).collect();
    let layouts: Vec<_> = cpu.iter().map(MultigridCorrection::layout).collect();
    let starts: Vec<u32> =
        cases.iter().scan(0, |at, c| Some(core::mem::replace(at, *at + c.topology.len() as u32))).collect();
    let slots = cases.iter().map(|c| c.topology.len() as u32).sum::<u32>();
    let plan_cloths: Vec<MultigridCloth<'_>> = layouts
        .iter()
        .zip(&starts)
        .enumerate()
        .map(|(k, (layout, &particle_start))| MultigridCloth {
            slot: k as u32,
            particle_start,
            layout,
            stepping: steppings[k],
        })
        .collect();
    let plan = MultigridPlan::new(device, &plan_cloths, 2).expect("the plan fits");
    let workgroups = ClothKernels::workgroups(device, slots).expect("one dispatch");
    let frame = GpuBatchFrame { particle_slots: slots, dispatch_width: workgroups.0 * 8, ..Default::default() };
    let uniform = |bytes: &[u8]| {
        wgpu::util::DeviceExt::create_buffer_init(
            device,
            &wgpu::util::BufferInitDescriptor { label: None, contents: bytes, usage: wgpu::BufferUsages::UNIFORM },
        )
    };
    let frame = uniform(bytemuck::bytes_of(&frame));
    let steps = uniform(bytemuck::bytes_of(&GpuBatchStep::default()));
    let info: Vec<[u32; 4]> =
        cases.iter().enumerate().flat_map(|(k, c)| gpu_particle_info(&c.topology, k as u32)).collect();
    let batch_cloths: Vec<GpuBatchCloth> =
        cases.iter().zip(&starts).map(|(c, &start)| GpuBatchCloth::new(&params, &c.topology, start, 0, 1, h)).collect();
    let info = storage_buffer_with(device, "info", &info);
    let batch_cloths = storage_buffer_with(device, "cloths", &batch_cloths);
    fn particles(cases: &[Case], f: &dyn Fn(&Case, usize) -> GpuParticle) -> Vec<GpuParticle> {
        cases.iter().flat_map(|c| (0..c.topology.len()).map(move |i| f(c, i))).collect()
    }
    let substep_start = storage_buffer_with(
        device,
        "start",
        &particles(&cases, &|c, i| GpuParticle {
            position: c.start[i].extend(c.free[i]).into(),
            velocity: [0.0, 0.0, 0.0, c.held[i]],
        }),
    );
    let inertial = storage_buffer_with(
        device,
        "inertial",
        &particles(&cases, &|c, i| GpuParticle { position: c.target[i].extend(c.free[i]).into(), velocity: [0.0; 4] }),
    );
    let iterate = storage_buffer_with(
        device,
        "iterate",
        &particles(&cases, &|c, i| GpuParticle { position: c.d[i].extend(c.free[i]).into(), velocity: [0.0; 4] }),
    );
    let shared = SharedBuffers {
        frame: &frame,
        steps: &steps,
        info: &info,
        cloths: &batch_cloths,
        iterate: &iterate,
        substep_start: &substep_start,
        inertial: &inertial,
    };
    let group = plan.bind_group(device, &rig.kernels, &shared);
    for substep in 0..2 {
        let before: Vec<Vec<Vec3A>> = cases.iter().map(|c| c.d.clone()).collect();
        // The first substep is implicit Euler's (the cloth has no history), the second BDF2's
        // or the blend's.
        for ((c, correction), stepping) in cases.iter_mut().zip(&mut cpu).zip(steppings) {
            let step = match (substep, stepping) {
                (0, _) => h,
                (_, MultigridStepping::Blend) => h * BLEND_STEP,
                _ => h * (2.0 / 3.0),
            };
            correction.correct(&c.held, step, &mut c.d, &c.start, &c.target, substep == 0, stepping.cycle());
        }
        let mut encoder = device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            let mut each = |_, run: &dyn Fn(&mut wgpu::ComputePass<'_>)| run(&mut pass);
            plan.begin(&rig.kernels, &group, 0, &mut each);
            plan.correct(&rig.kernels, &group, 0, workgroups, &mut each);
        }
        queue.submit([encoder.finish()]);
        let gpu: Vec<GpuParticle> = headless::read(device, queue, &iterate);
        for (k, c) in cases.iter().enumerate() {
            let moved = c.d.iter().zip(&before[k]).map(|(a, b)| (*a - *b).length()).fold(0.0, f32::max);
            let worst = (0..c.topology.len())
                .map(|i| (Vec3A::from_slice(&gpu[(starts[k] as usize) + i].position[..3]) - c.d[i]).length())
                .fold(0.0, f32::max);
            eprintln!(
                "{:?}, {} levels, substep {substep}, cloth {k}: the CPU moved {moved:.3e}, the GPU differs by {worst:.3e}",
                steppings[k],
                layouts[k].levels.len()
            );
            assert!(moved > 1.0e-5, "substep {substep}, cloth {k}: the correction moved nothing");
            assert!(worst <= 1.0e-4 * moved, "substep {substep}, cloth {k}: {worst} against {moved}");
        }
        // The next substep's sweep: both sides start from the CPU's result, moved a little.
        for c in &mut cases {
            for (i, d) in c.d.iter_mut().enumerate() {
                *d += c.free[i] * Vec3A::new(0.0, 0.003 * ((i % 7) as f32 - 3.0) / 3.0, 0.0);
            }
        }
        queue.write_buffer(
            &iterate,
            0,
            bytemuck::cast_slice(&particles(&cases, &|c, i| GpuParticle {
                position: c.d[i].extend(c.free[i]).into(),
                velocity: [0.0; 4],
            })),
        );
    }
}
