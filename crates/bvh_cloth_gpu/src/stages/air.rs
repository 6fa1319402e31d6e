//! Aerodynamics on the GPU: the buffers, bind groups and dispatches of `air.wgsl` for the
//! cloths of a batch that have drag or lift.
//!
//! Per tick, `air_sample` samples the wind at every particle of those cloths; per substep,
//! before the integrators, `air_forces` finds the drag and lift of every triangle once (a
//! cloth's particle threads share its triangles out), and then each particle sums its
//! triangles and adds the change of velocity, as [`bvh_cloth_core::ClothSim::tick`] does on the
//! CPU: `air_kick` does it for the explicit integrators' cloths, and block descent's prediction
//! does it for its own (`vbd_predict_air` in place of `vbd_predict`), so that a block-descent
//! cloth in the wind adds one dispatch to its substep, not two: on a hardware GPU a small
//! cloth's substep is bound by its dependent dispatches (BENCHMARKS.md, "Wind").
//!
//! What changes per frame (each cloth's constants, the wind sources, each tick's ambient wind
//! and lattice time, which the host computes from the wind clock as the CPU does) is written by
//! [`AirPlan::write`]; the buffers are replaced only when they must grow.

use crate::layout::GpuAirCloth;
use bvh_cloth_core::backend::AirSource;
use wgpu::{BindGroup, Buffer, ComputePass, ComputePipeline, Device, Queue};

use crate::buffer::{UNIFORM_STRIDE, storage_buffer};
use crate::kernels::{ClothKernels, EntryPoint, Kernel, KernelError, storage_binding_limit};

/// What one frame of air needs written: each cloth slot's constants (zero for a cloth without
/// aerodynamics), the wind sources, and per tick each cloth slot's ambient wind and lattice time.
pub(crate) struct AirFrame {
    pub cloths: Vec<GpuAirCloth>,
    /// Triangles of the cloths with aerodynamics, all together.
    pub triangles: u32,
    pub sources: Vec<AirSource>,
    pub ticks: Vec<Vec<[f32; 4]>>,
    /// Most substeps of a cloth with aerodynamics.
    pub substeps: u32,
    /// Whether a cloth with aerodynamics runs an explicit integrator (and so needs `air_kick`).
    pub explicit: bool,
}

/// The bytes of the air state buffer for `particles` particle slots and `triangles` triangles:
/// the wind at every particle slot, then the triangles' forces.
fn state_bytes(particles: u32, triangles: u32) -> u64 {
    (u64::from(particles) + u64::from(triangles)) * 16
}

/// Whether the air state of `particles` particle slots and `triangles` triangles fits one
/// storage binding of `device`; the error gives its size where it does not.
pub(crate) fn check_state(device: &Device, particles: u32, triangles: u32) -> Result<(), KernelError> {
    let (bytes, max) = (state_bytes(particles, triangles), storage_binding_limit(device));
    if bytes > max { Err(KernelError::BufferTooLarge { bytes, max }) } else { Ok(()) }
}

/// What the air bind groups bind besides the plan's own buffers.
pub(crate) struct SharedBuffers<'a> {
    pub frame: &'a Buffer,
    pub steps: &'a Buffer,
    pub particles: &'a Buffer,
    pub info: &'a Buffer,
    pub cloths: &'a Buffer,
    pub surface: &'a Buffer,
    /// Block descent's substep start and inertial targets.
    pub substep_start: &'a Buffer,
    pub inertial: &'a Buffer,
}

/// The air buffers of a batch.
#[derive(Debug)]
pub(crate) struct AirPlan {
    /// Particle slots and cloth slots the buffers have room for.
    pub particle_capacity: u32,
    cloth_capacity: u32,
    source_capacity: u32,
    triangle_capacity: u32,
    tick_capacity: u32,
    /// Bytes between two ticks' words.
    tick_stride: u64,
    cloths: Buffer,
    sources: Buffer,
    ticks: Buffer,
    /// The wind at each particle slot, then each triangle's force per corner, over its cloth's
    /// mass (from its cloth's `triangle_start`, past the particle slots).
    state: Buffer,
    /// Ticks written this frame, the substeps the air cloths run, and whether one of them runs
    /// an explicit integrator.
    ticks_written: u32,
    pub substeps: u32,
    explicit: bool,
}

impl AirPlan {
    /// Buffers for `particles` particle slots and `cloths` cloth slots.
    pub fn new(device: &Device, particles: u32, cloths: u32) -> Self {
        let mut plan = Self {
            particle_capacity: particles,
            cloth_capacity: cloths,
            source_capacity: 0,
            triangle_capacity: 0,
            tick_capacity: 0,
            tick_stride: 0,
            cloths: storage_buffer(device, "bvh_cloth_air_cloths", u64::from(cloths) * size_of::<GpuAirCloth>() as u64),
            sources: storage_buffer(device, "bvh_cloth_wind_sources", 16),
            ticks: storage_buffer(device, "bvh_cloth_air_ticks", 16),
            state: storage_buffer(device, "bvh_cloth_air_state", 16),
            ticks_written: 0,
            substeps: 0,
            explicit: false,
        };
        plan.grow_sources(device, 4);
        plan.grow_triangles(device, 0);
        plan.grow_ticks(device, 4);
        plan
    }

    /// Whether the plan still fits a batch of `particles` and `cloths` slots.
    pub fn fits(&self, particles: u32, cloths: u32) -> bool {
        self.particle_capacity == particles && self.cloth_capacity >= cloths
    }

    fn grow_sources(&mut self, device: &Device, count: u32) {
        self.source_capacity = count.max(4);
        let bytes = u64::from(self.source_capacity) * size_of::<AirSource>() as u64;
        self.sources = storage_buffer(device, "bvh_cloth_wind_sources", bytes);
    }

    fn grow_triangles(&mut self, device: &Device, count: u32) {
        // Room for `count` and, where one binding allows it, for half as many again.
        let max = storage_binding_limit(device) / 16;
        let room = u32::try_from(max.saturating_sub(u64::from(self.particle_capacity))).unwrap_or(u32::MAX);
        self.triangle_capacity = count.saturating_add(count / 2).max(64).min(room.max(count));
        let bytes = state_bytes(self.particle_capacity, self.triangle_capacity);
        self.state = storage_buffer(device, "bvh_cloth_air_state", bytes);
    }

    fn grow_ticks(&mut self, device: &Device, ticks: u32) {
        let align = u64::from(device.limits().min_storage_buffer_offset_alignment);
        self.tick_stride = (u64::from(self.cloth_capacity) * 16).div_ceil(align) * align;
        self.tick_capacity = ticks.max(4);
        self.ticks = storage_buffer(device, "bvh_cloth_air_ticks", self.tick_stride * u64::from(self.tick_capacity));
    }

    /// Writes `frame`, whose triangles passed [`check_state`]. Returns whether a
    /// buffer was replaced (the bind groups must be made again).
    pub fn write(&mut self, device: &Device, queue: &Queue, frame: &AirFrame) -> bool {
        let mut replaced = false;
        if frame.sources.len() as u32 > self.source_capacity {
            self.grow_sources(device, 2 * frame.sources.len() as u32);
            replaced = true;
        }
        if frame.triangles > self.triangle_capacity {
            self.grow_triangles(device, frame.triangles);
            replaced = true;
        }
        let ticks = frame.ticks.len().max(1) as u32;
        if ticks > self.tick_capacity {
            self.grow_ticks(device, 2 * ticks);
            replaced = true;
        }
        queue.write_buffer(&self.cloths, 0, bytemuck::cast_slice(&frame.cloths));
        if !frame.sources.is_empty() {
            queue.write_buffer(&self.sources, 0, bytemuck::cast_slice(&frame.sources));
        }
        let stride_words = (self.tick_stride / 16) as usize;
        let mut words = vec![[0.0f32; 4]; stride_words * frame.ticks.len()];
        for (k, tick) in frame.ticks.iter().enumerate() {
            words[k * stride_words..k * stride_words + tick.len()].copy_from_slice(tick);
        }
        if !words.is_empty() {
            queue.write_buffer(&self.ticks, 0, bytemuck::cast_slice(&words));
        }
        self.ticks_written = frame.ticks.len() as u32;
        self.substeps = frame.substeps;
        self.explicit = frame.explicit;
        replaced
    }

    /// The bind groups of [`EntryPoint::AIR`], then of `vbd_predict_air`.
    pub fn bind_groups(&self, device: &Device, kernels: &ClothKernels, shared: &SharedBuffers<'_>) -> [BindGroup; 4] {
        fn buffer(binding: u32, buffer: &Buffer) -> wgpu::BindGroupEntry<'_> {
            wgpu::BindGroupEntry { binding, resource: buffer.as_entire_binding() }
        }
        fn sized(binding: u32, buffer: &Buffer, size: u64) -> wgpu::BindGroupEntry<'_> {
            let binding_size = wgpu::BufferSize::new(size);
            let resource = wgpu::BindingResource::Buffer(wgpu::BufferBinding { buffer, offset: 0, size: binding_size });
            wgpu::BindGroupEntry { binding, resource }
        }
        let step = sized(1, shared.steps, size_of::<crate::layout::GpuBatchStep>() as u64);
        let group = |k: usize, entries: &[wgpu::BindGroupEntry<'_>]| {
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some(EntryPoint::AIR[k].name()),
                layout: kernels.layout(EntryPoint::AIR[k]),
                entries,
            })
        };
        let per_substep = [
            buffer(0, shared.frame),
            step.clone(),
            buffer(6, shared.info),
            buffer(8, shared.cloths),
            buffer(42, &self.cloths),
            buffer(44, &self.state),
            buffer(46, shared.particles),
            buffer(47, shared.surface),
        ];
        [
            group(
                0,
                &[
                    buffer(0, shared.frame),
                    buffer(6, shared.info),
                    sized(41, &self.ticks, self.tick_stride),
                    buffer(42, &self.cloths),
                    buffer(43, &self.sources),
                    buffer(44, &self.state),
                    buffer(46, shared.particles),
                ],
            ),
            group(1, &per_substep),
            group(2, &per_substep),
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("vbd_predict_air"),
                layout: kernels.layout(EntryPoint::VbdPredictAir),
                entries: &[
                    buffer(0, shared.frame),
                    step,
                    buffer(6, shared.info),
                    buffer(8, shared.cloths),
                    buffer(19, shared.particles),
                    buffer(20, shared.substep_start),
                    buffer(21, shared.inertial),
                    buffer(42, &self.cloths),
                    buffer(44, &self.state),
                    buffer(47, shared.surface),
                ],
            }),
        ]
    }

    /// Calls `each` with tick `tick`'s wind sampling (a tick past those written takes the last
    /// written one's air).
    pub fn sample(
        &self,
        kernels: &ClothKernels,
        groups: &[BindGroup; 4],
        workgroups: (u32, u32),
        tick: u32,
        each: &mut impl FnMut(Kernel, &dyn Fn(&mut ComputePass<'_>)),
    ) {
        let tick = tick.min(self.ticks_written.saturating_sub(1));
        let offset = [(u64::from(tick) * self.tick_stride) as u32];
        each(Kernel::AirSample, &|pass| {
            record(pass, kernels.pipeline(EntryPoint::AirSample), &groups[0], &offset, workgroups)
        });
    }

    /// Calls `each` with substep `k`'s forces, and the explicit integrators' kick, when an air
    /// cloth runs that substep (block descent's cloths take theirs in [`Self::predict`]).
    pub fn kick(
        &self,
        kernels: &ClothKernels,
        groups: &[BindGroup; 4],
        workgroups: (u32, u32),
        k: u32,
        each: &mut impl FnMut(Kernel, &dyn Fn(&mut ComputePass<'_>)),
    ) {
        if k >= self.substeps {
            return;
        }
        let offset = [(u64::from(3 * k) * UNIFORM_STRIDE) as u32];
        let kicks = if self.explicit { 2 } else { 1 };
        for (kernel, index) in [(Kernel::AirForces, 1), (Kernel::AirKick, 2)].into_iter().take(kicks) {
            each(kernel, &|pass| {
                record(pass, kernels.pipeline(EntryPoint::AIR[index]), &groups[index], &offset, workgroups)
            });
        }
    }

    /// Calls `each` with block descent's prediction of substep `k` after its cloths' kick
    /// (`vbd_predict_air`, which runs where `vbd_predict` would: every block-descent cloth,
    /// with or without aerodynamics).
    pub fn predict(
        &self,
        kernels: &ClothKernels,
        groups: &[BindGroup; 4],
        workgroups: (u32, u32),
        k: u32,
        each: &mut impl FnMut(Kernel, &dyn Fn(&mut ComputePass<'_>)),
    ) {
        let offset = [(u64::from(3 * k) * UNIFORM_STRIDE) as u32];
        each(Kernel::VbdPredictAir, &|pass| {
            record(pass, kernels.pipeline(EntryPoint::VbdPredictAir), &groups[3], &offset, workgroups)
        });
    }
}

/// Records one dispatch of `pipeline` over `workgroups`, with `group` at the dynamic `offset`.
fn record(
    pass: &mut ComputePass<'_>,
    pipeline: &ComputePipeline,
    group: &BindGroup,
    offset: &[u32],
    workgroups: (u32, u32),
) {
    pass.set_pipeline(pipeline);
    pass.set_bind_group(0, group, offset);
    pass.dispatch_workgroups(workgroups.0, workgroups.1, 1);
}
