//! Each cloth's writeback: its normals and positions written into a mesh's vertex buffer
//! (paper Algorithm 3, `normal_shader`).

use crate::layout::{GpuBatchWriteback, GpuMeshWriteback, GpuWritebackGroup};
use wgpu::util::DeviceExt;
use wgpu::{BindGroup, Buffer, BufferUsages, CommandEncoder, Device, Queue};

use crate::buffer::UNIFORM_STRIDE;
use crate::kernels::{ClothKernels, EntryPoint, WORKGROUP_SIZE};

use super::{ClothBatch, ClothId};

/// One `normal_shader` dispatch: the cloths written into one vertex buffer.
#[derive(Debug)]
pub(super) struct WritebackGroup {
    pub(super) vertices: Buffer,
    /// The cloths, in the order their vertices follow one another among the threads.
    pub(super) cloths: Vec<u32>,
    pub(super) bind_group: BindGroup,
    pub(super) workgroups: (u32, u32),
}

/// The writeback dispatches. Their bind groups hold what they share: the owner of each thread
/// (its cloth) and each group's constants.
#[derive(Debug)]
pub(super) struct Writebacks {
    pub(super) groups: Vec<WritebackGroup>,
}

impl ClothBatch {
    /// Sets where [`Self::encode_writebacks`] writes `id` (until it is set again or cleared):
    /// into `vertices` (a storage buffer of `f32` words, such as a mesh's vertex slab), laid out
    /// by `mesh`. All cloths written into one vertex buffer share one dispatch.
    pub fn set_writeback(&mut self, id: ClothId, mesh: GpuMeshWriteback, vertices: &Buffer) {
        if let Some(slot) = self.slots.get_mut(id.0 as usize).and_then(Option::as_mut) {
            slot.writeback = Some((mesh, vertices.clone()));
        }
    }

    /// Stops writing `id` into a vertex buffer (its mesh is not allocated this frame, say).
    pub fn clear_writeback(&mut self, id: ClothId) {
        if let Some(slot) = self.slots.get_mut(id.0 as usize).and_then(Option::as_mut) {
            slot.writeback = None;
        }
    }

    /// Uploads every cloth's writeback and, when the cloths or their vertex buffers changed,
    /// the owner table, the group constants and the bind groups.
    pub(super) fn prepare_writebacks(&mut self, device: &Device, queue: &Queue, kernels: &ClothKernels) {
        let mut groups: Vec<(Buffer, Vec<u32>)> = Vec::new();
        for (index, slot) in self.slots.iter().enumerate() {
            let Some((_, vertices)) = slot.as_ref().and_then(|slot| slot.writeback.as_ref()) else { continue };
            match groups.iter_mut().find(|(buffer, _)| buffer == vertices) {
                Some((_, cloths)) => cloths.push(index as u32),
                None => groups.push((vertices.clone(), vec![index as u32])),
            }
        }
        let vertex_count =
            |index: u32| self.slots[index as usize].as_ref().map_or(0, |s| s.topology.vertex_particle().len() as u32);
        // Every cloth's writeback, each cloth's first thread counted within its group.
        let mut constants = vec![GpuBatchWriteback::default(); self.slots.len()];
        for (_, cloths) in &groups {
            let mut first = 0;
            for &index in cloths {
                let Some(slot) = self.slots[index as usize].as_ref() else { continue };
                let Some((mesh, _)) = slot.writeback else { continue };
                constants[index as usize] = GpuBatchWriteback {
                    mesh,
                    particle_start: slot.particle_start,
                    surface_start: slot.surface_start,
                    vertex_count: vertex_count(index),
                    particle_count: slot.topology.len() as u32,
                    group_first: first,
                    _pad: [0; 3],
                };
                first += vertex_count(index);
            }
        }
        if !constants.is_empty() {
            queue.write_buffer(&self.buffers.writebacks, 0, bytemuck::cast_slice(&constants));
        }
        let same = self.writebacks.as_ref().is_some_and(|w| {
            w.groups.len() == groups.len()
                && w.groups
                    .iter()
                    .zip(&groups)
                    .all(|(g, (vertices, cloths))| g.vertices == *vertices && g.cloths == *cloths)
        });
        if same {
            return;
        }
        if groups.is_empty() {
            self.writebacks = None;
            return;
        }
        let mut owners = Vec::new();
        let mut infos = vec![0u8; groups.len() * UNIFORM_STRIDE as usize];
        let mut sizes = Vec::with_capacity(groups.len());
        for (k, (_, cloths)) in groups.iter().enumerate() {
            let first_owner = owners.len() as u32;
            for &index in cloths {
                owners.extend(std::iter::repeat_n(index, vertex_count(index) as usize));
            }
            let count = owners.len() as u32 - first_owner;
            let workgroups = ClothKernels::workgroups(device, count).unwrap_or((0, 0));
            let info = GpuWritebackGroup {
                first_owner,
                vertex_count: count,
                dispatch_width: workgroups.0 * WORKGROUP_SIZE,
                pad: 0,
            };
            let at = k * UNIFORM_STRIDE as usize;
            infos[at..at + size_of::<GpuWritebackGroup>()].copy_from_slice(bytemuck::bytes_of(&info));
            sizes.push(workgroups);
        }
        let owners = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("bvh_cloth_writeback_owners"),
            contents: bytemuck::cast_slice(&owners),
            usage: BufferUsages::STORAGE,
        });
        let group_constants = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("bvh_cloth_writeback_groups"),
            contents: &infos,
            usage: BufferUsages::UNIFORM,
        });
        let b = &self.buffers;
        let groups = groups
            .into_iter()
            .zip(sizes)
            .map(|((vertices, cloths), workgroups)| {
                let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("bvh_cloth_normal_shader"),
                    layout: kernels.layout(EntryPoint::NormalShader),
                    entries: &[
                        wgpu::BindGroupEntry { binding: 15, resource: b.writebacks.as_entire_binding() },
                        wgpu::BindGroupEntry { binding: 16, resource: b.base.as_entire_binding() },
                        wgpu::BindGroupEntry { binding: 17, resource: b.surface_words.as_entire_binding() },
                        wgpu::BindGroupEntry { binding: 18, resource: vertices.as_entire_binding() },
                        wgpu::BindGroupEntry { binding: 23, resource: owners.as_entire_binding() },
                        wgpu::BindGroupEntry {
                            binding: 24,
                            resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                                buffer: &group_constants,
                                offset: 0,
                                size: wgpu::BufferSize::new(size_of::<GpuWritebackGroup>() as u64),
                            }),
                        },
                    ],
                });
                WritebackGroup { vertices, cloths, bind_group, workgroups }
            })
            .collect();
        self.writebacks = Some(Writebacks { groups });
    }

    /// Records `normal_shader` for every cloth with a writeback: positions and normals into
    /// their vertex buffers, one dispatch per vertex buffer. Needs [`Self::prepare`] this frame.
    pub fn encode_writebacks(&self, encoder: &mut CommandEncoder, kernels: &ClothKernels) {
        let Some(writebacks) = &self.writebacks else { return };
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("bvh_cloth_writeback"),
            timestamp_writes: None,
        });
        pass.set_pipeline(kernels.pipeline(EntryPoint::NormalShader));
        for (k, group) in writebacks.groups.iter().enumerate() {
            if group.workgroups.0 == 0 {
                continue;
            }
            pass.set_bind_group(0, &group.bind_group, &[(k as u64 * UNIFORM_STRIDE) as u32]);
            pass.dispatch_workgroups(group.workgroups.0, group.workgroups.1, 1);
        }
    }
}
