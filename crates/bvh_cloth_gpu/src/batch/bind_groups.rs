//! What a batch binds before it encodes: the per-cloth constants and plans of block descent,
//! self-contact and the air written each frame, the anchors' targets, and the bind groups of
//! every kernel over the shared buffers.

use std::sync::Arc;

use bvh_cloth_core::backend::AirModel;

use crate::layout::GpuAirCloth;
use crate::layout::{
    GpuBatchCloth, GpuBatchFrame, GpuBatchStep, GpuColourPass, INTEGRATOR_BLOCK_DESCENT, INTEGRATOR_MULTIGRID,
};
use bvh_cloth_core::ClothTopology;
use bvh_cloth_core::backend::MAX_COLOURS;
use bvh_cloth_core::backend::MAX_ITERATIONS;
use bvh_cloth_core::backend::MultigridCorrection;
use bvh_cloth_core::backend::ParticleColouring;
use bvh_cloth_core::backend::shared_substeps;
use wgpu::{BindGroup, Buffer, BufferUsages, Device, Queue};

use crate::buffer::UNIFORM_STRIDE;
use crate::colliders::GpuColliders;
use crate::kernels::{ClothKernels, EntryPoint, WORKGROUP_SIZE};
use crate::stages::air::{AirFrame, AirPlan};
use crate::stages::multigrid::{MultigridCloth, MultigridPlan};
use crate::stages::self_contact::{ContactCloth, ContactPlan, SharedBuffers};

use super::{ClothBatch, MultigridStage, Slot};

/// This frame's anchor targets: tick `k`'s start at `k * stride` bytes.
#[derive(Debug)]
pub(super) struct AnchorTargets {
    pub(super) buffer: Buffer,
    pub(super) stride: u64,
    /// Ticks the buffer has room for.
    pub(super) ticks: u32,
}

/// Bind groups that stay valid until the buffers (or the colliders') are replaced.
#[derive(Debug)]
pub(super) struct Groups {
    /// The collider buffers they were made with.
    pub(super) colliders: (Buffer, Buffer),
    /// The anchor buffer they were made with.
    pub(super) anchors: Option<Buffer>,
    pub(super) stages: [BindGroup; 3],
    pub(super) last: BindGroup,
    pub(super) predict: BindGroup,
    pub(super) solve: BindGroup,
    pub(super) finish: BindGroup,
    /// The two levels of the drift sums.
    pub(super) drift: [BindGroup; 2],
    pub(super) apply_anchors: Option<BindGroup>,
    /// Self-contact's kernels, when a cloth has it.
    pub(super) contact: Option<[BindGroup; EntryPoint::CONTACT.len()]>,
    /// Aerodynamics' kernels, when a cloth has drag or lift.
    pub(super) air: Option<[BindGroup; 4]>,
    /// The multigrid correction's kernels, when a cloth has it.
    pub(super) multigrid: Option<BindGroup>,
}

/// One colour of the colour list: where it starts, how many particles it has, and the
/// workgroups of its dispatch.
#[derive(Debug, PartialEq)]
pub(super) struct ColourRange {
    pub(super) start: u32,
    pub(super) count: u32,
    pub(super) workgroups: (u32, u32),
}

/// The block-descent dispatches of the batch, and what they were written for.
#[derive(Debug, Default)]
pub(super) struct DescentPlan {
    /// The block-descent cloths: slot, first particle and the address of its shape.
    pub(super) cloths: Vec<(u32, u32, usize)>,
    pub(super) colours: Vec<ColourRange>,
    /// Most iterations and substeps of any block-descent cloth.
    pub(super) iterations: u32,
    pub(super) substeps: u32,
    /// Whether a block-descent cloth is held by nothing, so that its drift is summed.
    pub(super) free_bodies: bool,
}

impl ClothBatch {
    /// Uploads what the coming frame's ticks need: the frame constants, every cloth's anchor
    /// targets, and the bind groups where buffers changed. Call it once per frame, after the
    /// cloths' [`Self::set_params`] and [`Self::set_anchor_targets`] and before
    /// [`Self::encode_ticks`].
    pub fn prepare(&mut self, device: &Device, queue: &Queue, kernels: &ClothKernels, colliders: &GpuColliders) {
        self.prepare_contact(device, queue);
        self.prepare_air(device, queue);
        let explicit = |slot: &&Slot| slot.constants.integrator < INTEGRATOR_BLOCK_DESCENT;
        self.substeps =
            self.slots.iter().flatten().filter(explicit).map(|slot| slot.constants.substeps).max().unwrap_or(0);
        self.prepare_multigrid(device, queue);
        self.prepare_descent(device, queue);
        self.write_anchor_targets(device, queue);
        let width = self.workgroups.0 * WORKGROUP_SIZE;
        let frame = GpuBatchFrame {
            particle_slots: self.used.0,
            anchor_count: self.anchor_count,
            collider_count: colliders.len(),
            dispatch_width: width,
        };
        queue.write_buffer(&self.frame, 0, bytemuck::bytes_of(&frame));
        self.prepare_writebacks(device, queue, kernels);
        let key = (colliders.frames.clone(), colliders.tree.clone());
        let anchors = self.anchors.as_ref().map(|a| a.buffer.clone());
        if self.groups.as_ref().is_none_or(|g| g.colliders != key || g.anchors != anchors) {
            self.groups = Some(self.bind_groups(device, kernels, key, anchors));
        }
    }

    /// Gives every cloth with self-contact the largest substep count among them, as
    /// [`ClothSim::tick_together`] does, and writes the contact buffers when the contact cloths,
    /// or where they lie, changed; the contact constants every frame.
    pub(super) fn prepare_contact(&mut self, device: &Device, queue: &Queue) {
        let in_contact = |slot: &Slot| slot.constants.contact_thickness > 0.0;
        let substeps =
            shared_substeps(self.slots.iter().flatten().filter(|s| in_contact(s)).map(|s| s.own_substeps)).unwrap_or(0);
        let mut thickest = 0.0f32;
        for (index, slot) in self.slots.iter_mut().enumerate() {
            let Some(slot) = slot.as_mut().filter(|slot| in_contact(slot)) else { continue };
            thickest = thickest.max(slot.constants.contact_thickness);
            if slot.constants.substeps != substeps {
                slot.constants.substeps = substeps;
                slot.constants.h = slot.tick_seconds / substeps as f32;
                queue.write_buffer(
                    &self.buffers.cloth_constants,
                    index as u64 * size_of::<GpuBatchCloth>() as u64,
                    &bytemuck::bytes_of(&slot.constants)[..GpuBatchCloth::HOST_BYTES as usize],
                );
            }
        }
        let cloths: Vec<(ContactCloth, &ClothTopology)> = self
            .slots
            .iter()
            .enumerate()
            .filter_map(|(index, slot)| Some((index as u32, slot.as_ref().filter(|slot| in_contact(slot))?)))
            .map(|(index, slot)| ((index, slot.particle_start, Arc::as_ptr(&slot.topology) as usize), &*slot.topology))
            .collect();
        if cloths.is_empty() {
            if self.contact.take().is_some() {
                self.groups = None;
            }
            self.contact_error = None;
            return;
        }
        let same = self.contact.as_ref().is_some_and(|plan| {
            plan.particle_capacity == self.buffers.particles
                && plan.cloths.len() == cloths.len()
                && plan.cloths.iter().zip(&cloths).all(|(a, (b, _))| a == b)
        });
        if !same {
            self.groups = None;
            match ContactPlan::new(device, queue, &cloths, self.buffers.particles) {
                Ok(plan) => {
                    self.contact = Some(plan);
                    self.contact_error = None;
                }
                Err(error) => {
                    self.contact = None;
                    self.contact_error = Some(error);
                }
            }
        }
        if let Some(plan) = self.contact.as_mut() {
            plan.substeps = substeps;
            plan.write_frame(device, queue, self.used.0, thickest);
        }
    }

    /// Writes the air of the coming frame's ticks for the cloths with drag or lift, making the
    /// air buffers when there are none or they no longer fit.
    pub(super) fn prepare_air(&mut self, device: &Device, queue: &Queue) {
        let active = |slot: &Slot| slot.aerodynamics.is_active();
        if !self.slots.iter().flatten().any(active) {
            if self.air.take().is_some() {
                self.groups = None;
            }
            self.air_error = None;
            return;
        }
        let capacity = self.buffers.cloths as usize;
        let (start, tick_seconds, ticks) = self.wind_clock;
        let mut frame = AirFrame {
            cloths: vec![GpuAirCloth::default(); capacity],
            triangles: 0,
            sources: self.wind_sources.clone(),
            ticks: vec![vec![[0.0; 4]; capacity]; ticks as usize],
            substeps: 0,
            explicit: false,
        };
        // The triangles' forces lie after the wind at every particle slot, in one buffer.
        let first_triangle = self.buffers.particles;
        for (index, slot) in self.slots.iter().enumerate() {
            let Some(slot) = slot.as_ref().filter(|slot| active(slot)) else { continue };
            frame.substeps = frame.substeps.max(slot.constants.substeps);
            frame.explicit |= slot.constants.integrator < INTEGRATOR_BLOCK_DESCENT;
            for (k, words) in frame.ticks.iter_mut().enumerate() {
                let time = start + k as f64 * tick_seconds;
                let model = AirModel::new(slot.aerodynamics, slot.mass, &slot.wind, time);
                if k == 0 {
                    let sources = self.wind_sources.len() as u32;
                    let triangle_start = first_triangle + frame.triangles;
                    frame.cloths[index] =
                        GpuAirCloth::new(&model, &slot.topology, slot.surface_start, triangle_start, sources);
                }
                words[index] = GpuAirCloth::tick_word(&model);
            }
            frame.triangles += slot.topology.triangles().len() as u32;
        }
        if let Err(error) = crate::stages::air::check_state(device, self.buffers.particles, frame.triangles) {
            // The cloths run without drag and lift until their air fits again.
            if self.air.take().is_some() {
                self.groups = None;
            }
            self.air_error = Some(error);
            return;
        }
        self.air_error = None;
        if self.air.as_ref().is_none_or(|plan| !plan.fits(self.buffers.particles, self.buffers.cloths)) {
            self.air = Some(AirPlan::new(device, self.buffers.particles, self.buffers.cloths));
            self.groups = None;
        }
        if let Some(plan) = self.air.as_mut()
            && plan.write(device, queue, &frame)
        {
            self.groups = None;
        }
    }

    /// Writes the colour list and the colour passes when the block-descent cloths, or where
    /// they lie, changed; updates the plan's iteration and substep counts every frame.
    pub(super) fn prepare_descent(&mut self, device: &Device, queue: &Queue) {
        let descent: Vec<(u32, &Slot, &ParticleColouring)> = self
            .slots
            .iter()
            .enumerate()
            .filter_map(|(index, slot)| Some((index as u32, slot.as_ref()?)))
            .filter(|(_, slot)| slot.constants.integrator >= INTEGRATOR_BLOCK_DESCENT)
            .filter_map(|(index, slot)| Some((index, slot, slot.topology.colouring().ok()?)))
            .collect();
        let cloths: Vec<(u32, u32, usize)> = descent
            .iter()
            .map(|(index, slot, _)| (*index, slot.particle_start, Arc::as_ptr(&slot.topology) as usize))
            .collect();
        let iterations =
            descent.iter().map(|(_, slot, _)| slot.constants.iterations).max().unwrap_or(0).min(MAX_ITERATIONS);
        let substeps = descent.iter().map(|(_, slot, _)| slot.constants.substeps).max().unwrap_or(0);
        let free_bodies = descent.iter().any(|(_, slot, _)| slot.free_body);
        if let Some(plan) = self.descent.as_mut()
            && plan.cloths == cloths
        {
            plan.iterations = iterations;
            plan.substeps = substeps;
            plan.free_bodies = free_bodies;
            return;
        }
        let colours = descent.iter().map(|(_, _, colouring)| colouring.len()).max().unwrap_or(0);
        let mut list = Vec::with_capacity(descent.iter().map(|(_, slot, _)| slot.topology.len()).sum());
        let mut ranges = Vec::with_capacity(colours);
        for k in 0..colours {
            let start = list.len() as u32;
            for (_, slot, colouring) in &descent {
                if k < colouring.len() {
                    list.extend(colouring.colour(k).iter().map(|&i| slot.particle_start + i));
                }
            }
            let count = list.len() as u32 - start;
            // The batch's particles already fit one dispatch, so each colour does too.
            let workgroups = ClothKernels::workgroups(device, count).unwrap_or((1, 1));
            ranges.push(ColourRange { start, count, workgroups });
        }
        queue.write_buffer(&self.buffers.colour_list, 0, bytemuck::cast_slice(&list));
        let mut bytes = vec![0u8; (u64::from(MAX_ITERATIONS) * u64::from(MAX_COLOURS) * UNIFORM_STRIDE) as usize];
        for iteration in 0..MAX_ITERATIONS {
            for (k, range) in ranges.iter().enumerate() {
                let entry = GpuColourPass {
                    start: range.start,
                    count: range.count,
                    iteration,
                    dispatch_width: range.workgroups.0 * WORKGROUP_SIZE,
                };
                let at = ((u64::from(iteration * MAX_COLOURS) + k as u64) * UNIFORM_STRIDE) as usize;
                bytes[at..at + size_of::<GpuColourPass>()].copy_from_slice(bytemuck::bytes_of(&entry));
            }
        }
        queue.write_buffer(&self.colour_passes, 0, &bytes);
        self.descent = Some(DescentPlan { cloths, colours: ranges, iterations, substeps, free_bodies });
    }

    /// Builds the multigrid correction's plan when the multigrid cloths, where they lie, their
    /// pins or their stiffness changed. When it would not fit the device, they run as block
    /// descent with one sweep ([`ClothBatch::multigrid_error`]).
    pub(super) fn prepare_multigrid(&mut self, device: &Device, queue: &Queue) {
        let mut key = Vec::new();
        for (index, slot) in self.slots.iter_mut().enumerate() {
            let Some(slot) = slot.as_mut().filter(|s| s.constants.integrator == INTEGRATOR_MULTIGRID) else { continue };
            let hierarchy = slot.multigrid();
            key.push((index as u32, slot.particle_start, Arc::as_ptr(&hierarchy) as usize, slot.stepping));
        }
        if self.multigrid.as_ref().is_some_and(|stage| stage.key == key && stage.plan.is_none()) {
            self.multigrid_as_descent(queue);
            return;
        }
        if key.is_empty() {
            self.multigrid = None;
            self.multigrid_error = None;
            return;
        }
        if self.multigrid.as_ref().is_some_and(|stage| stage.key == key) {
            return;
        }
        let hierarchies: Vec<Arc<MultigridCorrection>> = key
            .iter()
            .map(|&(index, ..)| {
                Arc::clone(self.slots[index as usize].as_ref().and_then(|s| s.multigrid.as_ref()).expect("built above"))
            })
            .collect();
        let layouts: Vec<_> = hierarchies.iter().map(|h| h.layout()).collect();
        let cloths: Vec<MultigridCloth<'_>> = key
            .iter()
            .zip(&layouts)
            .map(|(&(slot, particle_start, _, stepping), layout)| MultigridCloth {
                slot,
                particle_start,
                layout,
                stepping,
            })
            .collect();
        let plan = match MultigridPlan::new(device, &cloths, self.buffers.cloths) {
            Ok(plan) => Some(plan),
            Err(error) => {
                self.multigrid_error = Some(error);
                None
            }
        };
        let failed = plan.is_none();
        if !failed {
            self.multigrid_error = None;
        }
        self.multigrid = Some(MultigridStage { key, plan });
        self.groups = None;
        if failed {
            self.multigrid_as_descent(queue);
        }
    }

    /// Steps the multigrid cloths as block descent with one sweep, their correction's buffers
    /// not fitting the device, until the set of multigrid cloths changes.
    fn multigrid_as_descent(&mut self, queue: &Queue) {
        for (index, slot) in self.slots.iter_mut().enumerate() {
            let Some(slot) = slot.as_mut().filter(|s| s.constants.integrator == INTEGRATOR_MULTIGRID) else { continue };
            slot.constants.integrator = INTEGRATOR_BLOCK_DESCENT;
            queue.write_buffer(
                &self.buffers.cloth_constants,
                index as u64 * size_of::<GpuBatchCloth>() as u64,
                &bytemuck::bytes_of(&slot.constants)[..GpuBatchCloth::HOST_BYTES as usize],
            );
        }
    }

    pub(super) fn write_anchor_targets(&mut self, device: &Device, queue: &Queue) {
        let ticks = self.slots.iter().flatten().map(|slot| slot.targets.len()).max().unwrap_or(0) as u32;
        let per_tick: u32 = self
            .slots
            .iter()
            .flatten()
            .filter(|slot| !slot.targets.is_empty())
            .map(|slot| slot.pins.len() as u32)
            .sum();
        self.anchor_count = if ticks == 0 { 0 } else { per_tick };
        if self.anchor_count == 0 {
            return;
        }
        let align = u64::from(device.limits().min_storage_buffer_offset_alignment);
        let stride = (u64::from(per_tick) * 16).div_ceil(align) * align;
        if self.anchors.as_ref().is_none_or(|a| a.ticks < ticks || a.stride < stride) {
            let capacity = ticks.max(4);
            let buffer = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("bvh_cloth_anchor_targets"),
                size: stride * u64::from(capacity),
                usage: BufferUsages::STORAGE | BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            self.anchors = Some(AnchorTargets { buffer, stride, ticks: capacity });
        }
        let Some(anchors) = self.anchors.as_ref() else { return };
        // A pin without a target this tick keeps its slot, naming no particle.
        let unused = [0.0, 0.0, 0.0, f32::from_bits(u32::MAX)];
        let mut words: Vec<[f32; 4]> = vec![unused; (anchors.stride / 16 * u64::from(ticks)) as usize];
        for k in 0..ticks as usize {
            let mut at = k * (anchors.stride / 16) as usize;
            for slot in self.slots.iter().flatten().filter(|slot| !slot.targets.is_empty()) {
                if let Some(targets) = slot.targets.get(k) {
                    for (j, &(i, p)) in targets.iter().enumerate() {
                        words[at + j] = [p.x, p.y, p.z, f32::from_bits(slot.particle_start + i)];
                    }
                }
                at += slot.pins.len();
            }
        }
        queue.write_buffer(&anchors.buffer, 0, bytemuck::cast_slice(&words));
    }

    pub(super) fn bind_groups(
        &self,
        device: &Device,
        kernels: &ClothKernels,
        colliders: (Buffer, Buffer),
        anchors: Option<Buffer>,
    ) -> Groups {
        let b = &self.buffers;
        let step = wgpu::BindGroupEntry {
            binding: 1,
            resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                buffer: &self.steps,
                offset: 0,
                size: wgpu::BufferSize::new(size_of::<GpuBatchStep>() as u64),
            }),
        };
        let frame = wgpu::BindGroupEntry { binding: 0, resource: self.frame.as_entire_binding() };
        let stage = |source: &Buffer, target: &Buffer| {
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("bvh_cloth_node_update"),
                layout: kernels.layout(EntryPoint::NodeUpdate),
                entries: &[
                    frame.clone(),
                    step.clone(),
                    wgpu::BindGroupEntry { binding: 2, resource: b.base.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 3, resource: source.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 4, resource: b.slope_sum.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 5, resource: target.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 6, resource: b.info.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 7, resource: b.spring_ends.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 8, resource: b.cloth_constants.as_entire_binding() },
                ],
            })
        };
        // y -> a -> b -> a, then the last stage reads a and lands on y, as the CPU stepper.
        let stages = [stage(&b.base, &b.stage_a), stage(&b.stage_a, &b.stage_b), stage(&b.stage_b, &b.stage_a)];
        let last = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("bvh_cloth_node_update_final"),
            layout: kernels.layout(EntryPoint::NodeUpdateFinal),
            entries: &[
                frame.clone(),
                step.clone(),
                wgpu::BindGroupEntry { binding: 3, resource: b.stage_a.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 6, resource: b.info.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 7, resource: b.spring_ends.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 8, resource: b.cloth_constants.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 9, resource: b.base.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 10, resource: b.slope_sum.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 11, resource: colliders.0.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 12, resource: colliders.1.as_entire_binding() },
            ],
        });
        let apply_anchors = self.anchors.as_ref().map(|anchors| {
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("bvh_cloth_anchors"),
                layout: kernels.layout(EntryPoint::ApplyAnchors),
                entries: &[
                    frame.clone(),
                    wgpu::BindGroupEntry { binding: 13, resource: b.base.as_entire_binding() },
                    wgpu::BindGroupEntry {
                        binding: 14,
                        resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                            buffer: &anchors.buffer,
                            offset: 0,
                            size: wgpu::BufferSize::new(anchors.stride),
                        }),
                    },
                ],
            })
        });
        let colour_pass = wgpu::BindGroupEntry {
            binding: 25,
            resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                buffer: &self.colour_passes,
                offset: 0,
                size: wgpu::BufferSize::new(size_of::<GpuColourPass>() as u64),
            }),
        };
        fn buffer(binding: u32, buffer: &Buffer) -> wgpu::BindGroupEntry<'_> {
            wgpu::BindGroupEntry { binding, resource: buffer.as_entire_binding() }
        }
        let predict_entries = [
            frame.clone(),
            step.clone(),
            buffer(6, &b.info),
            buffer(8, &b.cloth_constants),
            buffer(19, &b.base),
            buffer(20, &b.stage_a),
            buffer(21, &b.stage_b),
        ];
        let predict = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("bvh_cloth_vbd_predict"),
            layout: kernels.layout(EntryPoint::VbdPredict),
            entries: &predict_entries,
        });
        let solve = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("bvh_cloth_vbd_solve"),
            layout: kernels.layout(EntryPoint::VbdSolve),
            entries: &[
                frame.clone(),
                step.clone(),
                buffer(6, &b.info),
                buffer(7, &b.spring_ends),
                buffer(8, &b.cloth_constants),
                buffer(19, &b.base),
                buffer(20, &b.stage_a),
                buffer(21, &b.stage_b),
                buffer(22, &b.colour_list),
                colour_pass,
            ],
        });
        let finish = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("bvh_cloth_vbd_finish"),
            layout: kernels.layout(EntryPoint::VbdFinish),
            entries: &[
                frame.clone(),
                step.clone(),
                buffer(6, &b.info),
                buffer(7, &b.spring_ends),
                buffer(8, &b.cloth_constants),
                buffer(11, &colliders.0),
                buffer(12, &colliders.1),
                buffer(19, &b.base),
                buffer(20, &b.stage_a),
                buffer(21, &b.stage_b),
            ],
        });
        // The prediction's bindings and the per-block sums (as the kernels' layouts say).
        let drift_entries = [&predict_entries[..], &[buffer(48, &b.drift_blocks)]].concat();
        let drift = [0, 1].map(|level| {
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("bvh_cloth_vbd_drift"),
                layout: kernels.layout([EntryPoint::VbdDriftBlocks, EntryPoint::VbdDrift][level]),
                entries: &drift_entries,
            })
        });
        let contact = self.contact.as_ref().map(|plan| {
            let shared = SharedBuffers {
                frame: &self.frame,
                particles: &b.base,
                info: &b.info,
                cloths: &b.cloth_constants,
                colliders: (&colliders.0, &colliders.1),
                inertial: &b.stage_b,
            };
            plan.bind_groups(device, kernels, &shared)
        });
        let air = self.air.as_ref().map(|plan| {
            let shared = crate::stages::air::SharedBuffers {
                frame: &self.frame,
                steps: &self.steps,
                particles: &b.base,
                info: &b.info,
                cloths: &b.cloth_constants,
                surface: &b.surface_words,
                substep_start: &b.stage_a,
                inertial: &b.stage_b,
            };
            plan.bind_groups(device, kernels, &shared)
        });
        let multigrid = self.multigrid.as_ref().and_then(|stage| stage.plan.as_ref()).map(|plan| {
            let shared = crate::stages::multigrid::SharedBuffers {
                frame: &self.frame,
                steps: &self.steps,
                info: &b.info,
                cloths: &b.cloth_constants,
                iterate: &b.base,
                substep_start: &b.stage_a,
                inertial: &b.stage_b,
            };
            plan.bind_group(device, kernels, &shared)
        });
        Groups {
            colliders,
            anchors,
            stages,
            last,
            predict,
            solve,
            finish,
            drift,
            apply_anchors,
            contact,
            air,
            multigrid,
        }
    }
}
