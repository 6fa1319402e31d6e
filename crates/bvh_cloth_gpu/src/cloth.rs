//! One cloth on the GPU: its particle buffers (paper Table II), its parameters, and the
//! dispatches that step it and write it into a vertex buffer.

use std::sync::Arc;

use bvh_cloth_core::gpu_layout::{GpuClothParams, GpuParticle, gpu_particles, gpu_surface_words, gpu_topology_words};
use bvh_cloth_core::{ClothParams, ClothSim, ClothTopology, Integrator, Vec3};
use wgpu::util::DeviceExt;
use wgpu::{BindGroup, Buffer, BufferUsages, CommandEncoder, Device, Queue};

use crate::colliders::GpuColliders;
use crate::kernels::{ClothKernels, KernelError, WORKGROUP_SIZE, storage_binding_limit};

/// A cloth's GPU state.
///
/// Four particle buffers: `base` holds the state at the start of a substep (the previous
/// positions the collision response needs) and, after the collision dispatch, the state at its
/// end; `stage_a` and `stage_b` take the RK4 intermediate states in turn; `slope_sum` holds
/// `k1 + 2 k2 + 2 k3` of RK4. A one-word buffer counts the particles `node_update`
/// quarantined (a substep that went NaN or infinite); see [`crate::FaultReadback`]. Two
/// read-only buffers hold the shape: the springs (`node_update`) and the surface
/// (`normal_shader`). The anchor targets of each tick of a frame wait in one more buffer.
#[derive(Debug)]
pub struct GpuCloth {
    topology: Arc<ClothTopology>,
    integrator: Integrator,
    workgroups: (u32, u32),
    substeps: u32,
    anchor_count: u32,
    params: Buffer,
    base: Buffer,
    stage_b: Buffer,
    faults: Buffer,
    surface: Buffer,
    /// RK4 stages 1–4, then semi-implicit Euler.
    node_update_groups: [BindGroup; 5],
    anchors: Option<AnchorTargets>,
}

/// Every tick's anchor targets for one frame: tick `k`'s targets start at `k * stride` bytes.
#[derive(Debug)]
struct AnchorTargets {
    buffer: Buffer,
    group: BindGroup,
    stride: u64,
    /// Ticks the buffer has room for.
    capacity: u32,
    /// Ticks written for the coming frame.
    written: u32,
}

impl GpuCloth {
    /// Buffers for `sim`, filled with its current state.
    pub fn new(device: &Device, kernels: &ClothKernels, sim: &ClothSim) -> Result<Self, KernelError> {
        let topology = Arc::clone(sim.topology());
        let count = topology.len().max(topology.vertex_particle().len());
        let workgroups = ClothKernels::workgroups(device, u32::try_from(count).unwrap_or(u32::MAX))?;
        let topology_words = gpu_topology_words(&topology);
        let surface_words = gpu_surface_words(&topology);
        let bytes = (sim.len() * size_of::<GpuParticle>()) as u64;
        let max = storage_binding_limit(device);
        for needed in [bytes, 4 * topology_words.len() as u64, 4 * surface_words.len() as u64] {
            if needed > max {
                return Err(KernelError::BufferTooLarge { bytes: needed, max });
            }
        }
        let particles = |label: &str| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes,
                usage: BufferUsages::STORAGE | BufferUsages::COPY_DST | BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            })
        };
        let base = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("bvh_cloth_particles"),
            contents: bytemuck::cast_slice(&gpu_particles(sim)),
            usage: BufferUsages::STORAGE | BufferUsages::COPY_DST | BufferUsages::COPY_SRC,
        });
        let (stage_a, stage_b, slope_sum) =
            (particles("bvh_cloth_stage_a"), particles("bvh_cloth_stage_b"), particles("bvh_cloth_slope_sum"));
        let params = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("bvh_cloth_params"),
            size: size_of::<GpuClothParams>() as u64,
            usage: BufferUsages::UNIFORM | BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let faults = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("bvh_cloth_faults"),
            contents: bytemuck::bytes_of(&0u32),
            usage: BufferUsages::STORAGE | BufferUsages::COPY_DST | BufferUsages::COPY_SRC,
        });
        let words = |label: &str, words: &[u32]| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: bytemuck::cast_slice(words),
                usage: BufferUsages::STORAGE,
            })
        };
        let springs = words("bvh_cloth_topology", &topology_words);
        let surface = words("bvh_cloth_surface", &surface_words);
        let group = |source: &Buffer, target: &Buffer| {
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("bvh_cloth_node_update"),
                layout: &kernels.node_update_layout,
                entries: &[
                    wgpu::BindGroupEntry { binding: 0, resource: params.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 1, resource: base.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 2, resource: source.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 3, resource: slope_sum.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 4, resource: target.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 13, resource: faults.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 16, resource: springs.as_entire_binding() },
                ],
            })
        };
        // y -> a -> b -> a -> b, as the CPU stepper; Euler reads y and writes b.
        let node_update_groups = [
            group(&base, &stage_a),
            group(&stage_a, &stage_b),
            group(&stage_b, &stage_a),
            group(&stage_a, &stage_b),
            group(&base, &stage_b),
        ];
        Ok(Self {
            topology,
            integrator: sim.params().integrator,
            workgroups,
            substeps: sim.params().looper,
            anchor_count: sim.pins().len() as u32,
            params,
            base,
            stage_b,
            faults,
            surface,
            node_update_groups,
            anchors: None,
        })
    }

    /// Uploads the parameters for ticks of `tick_seconds` against `colliders`: the same
    /// substep count and length the CPU stepper would use (stability guard included). The shape
    /// is the one the buffers were made for; `params` may change anything else.
    pub fn set_params(&mut self, queue: &Queue, params: &ClothParams, tick_seconds: f32, colliders: &GpuColliders) {
        self.substeps = params.substeps(tick_seconds, &self.topology);
        self.integrator = params.integrator;
        let h = tick_seconds / self.substeps as f32;
        let width = self.workgroups.0 * WORKGROUP_SIZE;
        let uniform = GpuClothParams::new(params, &self.topology, self.anchor_count, h, colliders.len(), width);
        queue.write_buffer(&self.params, 0, bytemuck::bytes_of(&uniform));
    }

    /// Where the pinned particles go in each tick of the coming frame: `ticks[k]` holds tick
    /// `k`'s `(index, world position)` pairs, at most one per pin (as [`ClothSim::pin_targets`]
    /// gives them), applied at the start of that tick, as the CPU stepper's
    /// [`ClothSim::move_pins`]. Pins, and ticks, left without targets stay where they are.
    pub fn write_anchor_targets(
        &mut self,
        device: &Device,
        queue: &Queue,
        kernels: &ClothKernels,
        ticks: &[Vec<(u32, Vec3)>],
    ) {
        if self.anchor_count == 0 || ticks.is_empty() {
            if let Some(anchors) = &mut self.anchors {
                anchors.written = 0;
            }
            return;
        }
        let needed = ticks.len() as u32;
        if self.anchors.as_ref().is_none_or(|a| a.capacity < needed) {
            let align = u64::from(device.limits().min_storage_buffer_offset_alignment);
            let stride = (u64::from(self.anchor_count) * 16).div_ceil(align) * align;
            let capacity = needed.max(4);
            let buffer = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("bvh_cloth_anchor_targets"),
                size: stride * u64::from(capacity),
                usage: BufferUsages::STORAGE | BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("bvh_cloth_anchors"),
                layout: &kernels.anchors_layout,
                entries: &[
                    wgpu::BindGroupEntry { binding: 0, resource: self.params.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 14, resource: self.base.as_entire_binding() },
                    wgpu::BindGroupEntry {
                        binding: 15,
                        resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                            buffer: &buffer,
                            offset: 0,
                            size: wgpu::BufferSize::new(stride),
                        }),
                    },
                ],
            });
            self.anchors = Some(AnchorTargets { buffer, group, stride, capacity, written: 0 });
        }
        let Some(anchors) = &mut self.anchors else { return };
        let mut bytes = vec![0u8; (anchors.stride * u64::from(needed)) as usize];
        // A tick with fewer targets than pins leaves the rest where they are: their slots name
        // no particle, which apply_anchors skips.
        let unused = [0.0, 0.0, 0.0, f32::from_bits(u32::MAX)];
        for (k, targets) in ticks.iter().enumerate() {
            let words: Vec<[f32; 4]> = targets
                .iter()
                .take(self.anchor_count as usize)
                .map(|&(index, p)| [p.x, p.y, p.z, f32::from_bits(index)])
                .chain(std::iter::repeat(unused))
                .take(self.anchor_count as usize)
                .collect();
            let start = k * anchors.stride as usize;
            let data: &[u8] = bytemuck::cast_slice(&words);
            bytes[start..start + data.len()].copy_from_slice(data);
        }
        queue.write_buffer(&anchors.buffer, 0, &bytes);
        anchors.written = needed;
    }

    /// Replaces the GPU state with `sim`'s (a reset, or pins moved by the caller), and clears
    /// the fault count.
    pub fn upload_state(&self, queue: &Queue, sim: &ClothSim) {
        queue.write_buffer(&self.base, 0, bytemuck::cast_slice(&gpu_particles(sim)));
        queue.write_buffer(&self.faults, 0, bytemuck::bytes_of(&0u32));
    }

    /// Records `ticks` ticks: per tick the anchors (where [`Self::write_anchor_targets`] gave
    /// targets for it), then per substep the integrator stages and the collision response.
    pub fn encode_ticks(
        &self,
        device: &Device,
        encoder: &mut CommandEncoder,
        kernels: &ClothKernels,
        colliders: &GpuColliders,
        ticks: u32,
    ) {
        if ticks == 0 {
            return;
        }
        let collision_group = self.collision_group(device, kernels, colliders);
        let stages: &[usize] = match self.integrator {
            Integrator::Rk4 => &[0, 1, 2, 3],
            Integrator::SemiImplicitEuler => &[4],
        };
        let (x, y) = self.workgroups;
        let mut pass = encoder
            .begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("bvh_cloth_step"), timestamp_writes: None });
        for tick in 0..ticks {
            if let Some(anchors) = self.anchors.as_ref().filter(|a| tick < a.written) {
                pass.set_pipeline(&kernels.anchors);
                pass.set_bind_group(0, &anchors.group, &[(u64::from(tick) * anchors.stride) as u32]);
                // As wide as every other dispatch, since threads find their index by that width.
                let rows = self.anchor_count.div_ceil(x * WORKGROUP_SIZE * WORKGROUP_SIZE);
                pass.dispatch_workgroups(x, rows, 1);
            }
            for _ in 0..self.substeps {
                for &stage in stages {
                    pass.set_pipeline(&kernels.node_update[stage]);
                    pass.set_bind_group(0, &self.node_update_groups[stage], &[]);
                    pass.dispatch_workgroups(x, y, 1);
                }
                pass.set_pipeline(&kernels.collision);
                pass.set_bind_group(0, &collision_group, &[]);
                pass.dispatch_workgroups(x, y, 1);
            }
        }
    }

    /// Records `collision_detection_with_bvh` alone: the state set by
    /// [`Self::upload_integrated`] is resolved against `colliders`, with the current state as
    /// the previous positions, and becomes the current state. For driving the kernel on its own
    /// (tests, or a caller's own integrator).
    pub fn encode_collision(
        &self,
        device: &Device,
        encoder: &mut CommandEncoder,
        kernels: &ClothKernels,
        colliders: &GpuColliders,
    ) {
        let group = self.collision_group(device, kernels, colliders);
        self.dispatch_once(encoder, "bvh_cloth_collision", &kernels.collision, &group);
    }

    /// Sets the integrated state that the collision dispatch reads (see
    /// [`Self::encode_collision`]).
    pub fn upload_integrated(&self, queue: &Queue, particles: &[GpuParticle]) {
        queue.write_buffer(&self.stage_b, 0, bytemuck::cast_slice(particles));
    }

    fn collision_group(&self, device: &Device, kernels: &ClothKernels, colliders: &GpuColliders) -> BindGroup {
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("bvh_cloth_collision"),
            layout: &kernels.collision_layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: self.params.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 5, resource: self.base.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 6, resource: self.stage_b.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 7, resource: colliders.frames.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 8, resource: colliders.nodes.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 9, resource: colliders.spheres.as_entire_binding() },
            ],
        })
    }

    /// Records `normal_shader`: positions and normals into `vertices` (a storage buffer of
    /// `f32` words) as `writeback` (a uniform [`bvh_cloth_core::gpu_layout::GpuMeshWriteback`])
    /// lays them out.
    pub fn encode_writeback(
        &self,
        device: &Device,
        encoder: &mut CommandEncoder,
        kernels: &ClothKernels,
        writeback: &Buffer,
        vertices: wgpu::BufferBinding<'_>,
    ) {
        let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("bvh_cloth_normal_shader"),
            layout: &kernels.normal_layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: self.params.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 10, resource: self.base.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 11, resource: writeback.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 12, resource: wgpu::BindingResource::Buffer(vertices) },
                wgpu::BindGroupEntry { binding: 17, resource: self.surface.as_entire_binding() },
            ],
        });
        self.dispatch_once(encoder, "bvh_cloth_writeback", &kernels.normal, &group);
    }

    /// One compute pass with a single dispatch of `pipeline` over the particles or vertices.
    fn dispatch_once(
        &self,
        encoder: &mut CommandEncoder,
        label: &str,
        pipeline: &wgpu::ComputePipeline,
        group: &BindGroup,
    ) {
        let (x, y) = self.workgroups;
        let mut pass =
            encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some(label), timestamp_writes: None });
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, group, &[]);
        pass.dispatch_workgroups(x, y, 1);
    }

    /// The particle state (`GpuParticle`s, `COPY_SRC`), for readback in tests.
    pub fn particles(&self) -> &Buffer {
        &self.base
    }

    /// The count of quarantined particles (one `u32`, `COPY_SRC | COPY_DST`): one per particle
    /// and substep whose new state was not finite, since it was last cleared.
    pub fn faults(&self) -> &Buffer {
        &self.faults
    }

    /// The shape the buffers were made for.
    pub fn topology(&self) -> &Arc<ClothTopology> {
        &self.topology
    }

    /// Substeps per tick under the last parameters.
    pub fn substeps(&self) -> u32 {
        self.substeps
    }
}
