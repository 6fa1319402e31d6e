//! Where each cloth lives in the shared buffers: placing a cloth's particles, springs and
//! surface, and growing the buffers (and rebuilding every cloth into them) when one does not fit.

use crate::layout::{
    GpuBatchCloth, GpuBatchWriteback, GpuParticle, NO_CLOTH, gpu_particle_info, gpu_surface_words, gpu_tether_ends,
};
use bvh_cloth_core::ClothTopology;
use wgpu::{Buffer, Device, Queue};

use crate::buffer::storage_buffer;
use crate::kernels::{ClothKernels, KernelError, storage_binding_limit};

use super::ClothBatch;

pub(super) fn surface_len(topology: &ClothTopology) -> u32 {
    (topology.vertex_particle().len()
        + topology.len()
        + 1
        + topology.triangle_list().len()
        + 3 * topology.triangles().len()) as u32
}

/// The shared buffers, sized in elements.
#[derive(Debug)]
pub(super) struct Buffers {
    pub(super) particles: u32,
    pub(super) ends: u32,
    pub(super) surface: u32,
    pub(super) cloths: u32,
    pub(super) base: Buffer,
    pub(super) stage_a: Buffer,
    pub(super) stage_b: Buffer,
    pub(super) slope_sum: Buffer,
    pub(super) info: Buffer,
    pub(super) colour_list: Buffer,
    /// Block descent's drift sums, one per 64 particle slots.
    pub(super) drift_blocks: Buffer,
    pub(super) spring_ends: Buffer,
    pub(super) surface_words: Buffer,
    pub(super) cloth_constants: Buffer,
    pub(super) writebacks: Buffer,
}

impl Buffers {
    pub(super) fn new(device: &Device, particles: u32, ends: u32, surface: u32, cloths: u32) -> Self {
        let storage = |label: &str, bytes: u64| storage_buffer(device, label, bytes);
        let particle_bytes = u64::from(particles) * size_of::<GpuParticle>() as u64;
        Self {
            particles,
            ends,
            surface,
            cloths,
            base: storage("bvh_cloth_particles", particle_bytes),
            stage_a: storage("bvh_cloth_stage_a", particle_bytes),
            stage_b: storage("bvh_cloth_stage_b", particle_bytes),
            slope_sum: storage("bvh_cloth_slope_sum", particle_bytes),
            info: storage("bvh_cloth_particle_info", u64::from(particles) * 16),
            colour_list: storage("bvh_cloth_colour_list", u64::from(particles) * 4),
            drift_blocks: storage("bvh_cloth_drift_blocks", u64::from(particles.div_ceil(64)) * 16),
            spring_ends: storage("bvh_cloth_spring_ends", u64::from(ends) * 16),
            surface_words: storage("bvh_cloth_surface", u64::from(surface) * 4),
            cloth_constants: storage("bvh_cloth_cloths", u64::from(cloths) * size_of::<GpuBatchCloth>() as u64),
            writebacks: storage("bvh_cloth_mesh_writebacks", u64::from(cloths) * size_of::<GpuBatchWriteback>() as u64),
        }
    }
}

/// Where the kernels' part of a [`GpuBatchCloth`] that a rebuild carries over starts: past the
/// fault count, which starts again from zero.
const KERNEL_KEPT: u64 = core::mem::offset_of!(GpuBatchCloth, drift) as u64;

impl ClothBatch {
    /// Writes slot `index`'s shape, constants and pending state at the given starts.
    pub(super) fn place(
        &mut self,
        queue: &Queue,
        index: usize,
        particle_start: u32,
        ends_start: u32,
        surface_start: u32,
    ) {
        let Some(slot) = self.slots[index].as_mut() else { return };
        slot.particle_start = particle_start;
        slot.ends_start = ends_start;
        slot.surface_start = surface_start;
        slot.constants.particle_start = particle_start;
        slot.constants.ends_start = ends_start;
        slot.constants.tether_start = slot.tether_start();
        let b = &self.buffers;
        queue.write_buffer(
            &b.info,
            u64::from(particle_start) * 16,
            bytemuck::cast_slice(&gpu_particle_info(&slot.topology, index as u32)),
        );
        queue.write_buffer(
            &b.spring_ends,
            u64::from(ends_start) * 16,
            bytemuck::cast_slice(slot.topology.spring_ends()),
        );
        queue.write_buffer(
            &b.spring_ends,
            u64::from(slot.tether_start()) * 16,
            bytemuck::cast_slice(&gpu_tether_ends(&slot.tethers)),
        );
        queue.write_buffer(
            &b.surface_words,
            u64::from(surface_start) * 4,
            bytemuck::cast_slice(&gpu_surface_words(&slot.topology)),
        );
        queue.write_buffer(
            &b.cloth_constants,
            index as u64 * size_of::<GpuBatchCloth>() as u64,
            &bytemuck::bytes_of(&slot.constants)[..GpuBatchCloth::HOST_BYTES as usize],
        );
        if core::mem::take(&mut slot.pending) {
            queue.write_buffer(
                &b.base,
                u64::from(particle_start) * size_of::<GpuParticle>() as u64,
                bytemuck::cast_slice(&slot.added),
            );
            // A new cloth has no BDF2 history.
            queue.write_buffer(
                &b.cloth_constants,
                index as u64 * size_of::<GpuBatchCloth>() as u64 + GpuBatchCloth::BROKEN_OFFSET,
                bytemuck::bytes_of(&1u32),
            );
        }
    }

    /// New buffers with the live cloths packed from the start, each about twice what they
    /// use; the live cloths' state (with block descent's and BDF2's history) copied over on the
    /// GPU. The fault counts start again from zero.
    pub(super) fn rebuild(&mut self, device: &Device, queue: &Queue) -> Result<(), KernelError> {
        let (n, e, s) = self.slots.iter().flatten().fold((0u64, 0u64, 0u64), |(n, e, s), slot| {
            (n + slot.topology.len() as u64, e + u64::from(slot.ends_len()), s + u64::from(slot.surface_len()))
        });
        let max = storage_binding_limit(device);
        let particle_size = size_of::<GpuParticle>() as u64;
        for (count, size) in [(n, particle_size), (e, 16), (s, 4)] {
            if count * size > max {
                return Err(KernelError::BufferTooLarge { bytes: count * size, max });
            }
        }
        // Twice the need where that fits a binding, the need where only that does.
        let room = |needed: u64, size: u64| {
            u32::try_from((2 * needed).max(64).min(max / size).max(needed)).unwrap_or(u32::MAX)
        };
        let particles = room(n, particle_size);
        let cloths = (self.slots.len() as u32).saturating_mul(2).max(4);
        let old =
            std::mem::replace(&mut self.buffers, Buffers::new(device, particles, room(e, 16), room(s, 4), cloths));
        // Every particle slot is no cloth's until a cloth is placed on it.
        queue.write_buffer(&self.buffers.info, 0, bytemuck::cast_slice(&vec![[NO_CLOTH; 4]; particles as usize]));
        let mut encoder =
            device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("bvh_cloth_rebuild") });
        let mut used = (0u32, 0u32, 0u32);
        for index in 0..self.slots.len() {
            let Some(slot) = self.slots[index].as_ref() else { continue };
            let (len, ends, surface) = (slot.topology.len() as u32, slot.ends_len(), slot.surface_len());
            if !slot.pending {
                // The state, block descent's acceleration estimates and BDF2's history (kept in
                // the substep start's and the inertial target's buffers between substeps).
                for (from, to) in [
                    (&old.base, &self.buffers.base),
                    (&old.stage_a, &self.buffers.stage_a),
                    (&old.stage_b, &self.buffers.stage_b),
                ] {
                    encoder.copy_buffer_to_buffer(
                        from,
                        u64::from(slot.particle_start) * particle_size,
                        to,
                        u64::from(used.0) * particle_size,
                        u64::from(len) * particle_size,
                    );
                }
                // The kernels' part of its constants past the fault count (the drift, and the
                // multigrid integrator's step and BDF2 flag): a cloth keeps its index.
                let at = index as u64 * size_of::<GpuBatchCloth>() as u64 + KERNEL_KEPT;
                let kept = size_of::<GpuBatchCloth>() as u64 - KERNEL_KEPT;
                encoder.copy_buffer_to_buffer(&old.cloth_constants, at, &self.buffers.cloth_constants, at, kept);
            }
            self.place(queue, index, used.0, used.1, used.2);
            used = (used.0 + len, used.1 + ends, used.2 + surface);
        }
        // The writes above run before this submit's copies, which touch only the ranges of
        // cloths that had a state on the GPU (the writes fill the others').
        queue.submit([encoder.finish()]);
        self.used = used;
        self.groups = None;
        self.writebacks = None;
        self.descent = None;
        self.contact = None;
        self.air = None;
        self.multigrid = None;
        Ok(())
    }

    pub(super) fn refresh_workgroups(&mut self, device: &Device) -> Result<(), KernelError> {
        self.workgroups = ClothKernels::workgroups(device, self.used.0)?;
        Ok(())
    }
}
