//! A skinned collider refitted on the GPU, where its tree lives: the same refit as
//! [`SkinnedSpheres::refit`] (skin the vertices, fit every sphere around its points, refit the
//! boxes children first), so the host uploads only the joint matrices each frame.

use crate::layout::{GpuRefitParams, gpu_joint_matrix, gpu_skin_vertices};
use bvh_cloth_core::{Affine3A, Lbvh, SkinnedSpheres};
use wgpu::util::DeviceExt;
use wgpu::{BindGroup, Buffer, BufferUsages, ComputePass, Device, Queue};

use crate::colliders::GpuColliders;
use crate::kernels::{ClothKernels, EntryPoint, KernelError};

/// Bytes between two dispatches' parameters (the largest uniform offset alignment wgpu allows
/// a device to ask for).
const PARAMS_STRIDE: u64 = 256;

/// One skinned collider's refit: its vertices, points and levels on the device (uploaded once),
/// its joint matrices (each frame), and where its tree lies in a [`GpuColliders`].
#[derive(Debug)]
pub struct SkinRefit {
    vertices: Buffer,
    joints: Buffer,
    skinned: Buffer,
    points: Buffer,
    leaf_starts: Buffer,
    levels: Buffer,
    /// Dispatch parameters: entry 0 for the vertices, the leaves and the reach, entry `1 + l`
    /// for level `l`.
    params: Buffer,
    /// Each level's first entry in `levels` and its number of nodes, deepest first.
    level_ranges: Vec<(u32, u32)>,
    vertex_count: u32,
    leaf_count: u32,
    joint_count: usize,
    /// Workgroups of the vertex, leaf and level dispatches.
    vertex_groups: (u32, u32),
    leaf_groups: (u32, u32),
    level_groups: Vec<(u32, u32)>,
    /// The collider's tree and frame in the [`GpuColliders`] bound, and the bind groups of the
    /// four kernels.
    target: Option<(GpuRefitParams, [BindGroup; 4])>,
}

fn whole(binding: u32, buffer: &Buffer) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry { binding, resource: buffer.as_entire_binding() }
}

fn buffer<T: bytemuck::Pod + Default>(device: &Device, label: &str, items: &[T], usage: BufferUsages) -> Buffer {
    // wgpu rejects zero-sized bindings: an empty array is one zeroed element.
    let fallback = [T::default()];
    let contents: &[T] = if items.is_empty() { &fallback } else { items };
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents: bytemuck::cast_slice(contents),
        usage,
    })
}

impl SkinRefit {
    /// Uploads what refits `skin`, whose bind-pose tree is `tree`. Fails when a dispatch would
    /// need more workgroups than the device allows.
    pub fn new(device: &Device, skin: &SkinnedSpheres, tree: &Lbvh) -> Result<Self, KernelError> {
        let storage = BufferUsages::STORAGE;
        let vertex_count = skin.vertices.positions.len() as u32;
        let leaf_count = skin.leaf_count() as u32;
        let (levels, starts) = tree.levels();
        let level_ranges: Vec<(u32, u32)> = starts.windows(2).map(|w| (w[0], w[1] - w[0])).collect();
        let level_groups =
            level_ranges.iter().map(|&(_, count)| ClothKernels::workgroups(device, count)).collect::<Result<_, _>>()?;
        let joints = vec![[[0.0f32; 4]; 4]; skin.joint_count.max(1)];
        Ok(Self {
            vertices: buffer(device, "bvh_cloth_skin_vertices", &gpu_skin_vertices(&skin.vertices), storage),
            joints: buffer(device, "bvh_cloth_skin_joints", &joints, storage | BufferUsages::COPY_DST),
            skinned: buffer(device, "bvh_cloth_skinned", &vec![[0.0f32; 4]; vertex_count as usize], storage),
            points: buffer(device, "bvh_cloth_skin_points", &skin.points, storage),
            leaf_starts: buffer(device, "bvh_cloth_skin_leaf_starts", &skin.leaf_starts, storage),
            levels: buffer(device, "bvh_cloth_skin_levels", &levels, storage),
            params: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("bvh_cloth_skin_refit_params"),
                size: PARAMS_STRIDE * (1 + level_ranges.len() as u64),
                usage: BufferUsages::UNIFORM | BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            vertex_groups: ClothKernels::workgroups(device, vertex_count)?,
            leaf_groups: ClothKernels::workgroups(device, leaf_count)?,
            level_groups,
            level_ranges,
            vertex_count,
            leaf_count,
            joint_count: skin.joint_count,
            target: None,
        })
    }

    /// Points the refit at collider `k` of `colliders` (the index [`GpuColliders::new`] was
    /// given it at) and makes its bind groups. Returns `false`, and refits nothing until bound
    /// again, when that collider's tree is not on the device or has another number of spheres.
    pub fn bind(&mut self, device: &Device, kernels: &ClothKernels, colliders: &GpuColliders, k: usize) -> bool {
        let placed = colliders.tree_offsets(k).zip(colliders.frame_index(k));
        let Some(((node_offset, sphere_offset), collider)) =
            placed.filter(|_| colliders.spheres_of(k) == self.leaf_count)
        else {
            self.target = None;
            return false;
        };
        let base = GpuRefitParams {
            vertex_count: self.vertex_count,
            leaf_count: self.leaf_count,
            node_offset,
            sphere_offset,
            collider,
            ..Default::default()
        };
        let groups = EntryPoint::REFIT.map(|entry| {
            let layout = kernels.layout(entry);
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("bvh_cloth_skin_refit"),
                layout,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 26,
                        resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                            buffer: &self.params,
                            offset: 0,
                            size: wgpu::BufferSize::new(size_of::<GpuRefitParams>() as u64),
                        }),
                    },
                    whole(27, &self.vertices),
                    whole(28, &self.joints),
                    whole(29, &self.skinned),
                    whole(30, &self.points),
                    whole(31, &self.leaf_starts),
                    whole(32, &self.levels),
                    whole(33, &colliders.tree),
                    whole(34, &colliders.frames),
                ],
            })
        });
        self.target = Some((base, groups));
        true
    }

    /// Whether [`Self::bind`] found the collider.
    pub fn is_bound(&self) -> bool {
        self.target.is_some()
    }

    /// Uploads a pose: each joint's world transform times its inverse bind pose, and the
    /// clearance [`SkinnedSpheres::check_pose`] gave for it (which also checked the matrices).
    pub fn write_pose(&self, queue: &Queue, joint_matrices: &[Affine3A], clearance: f32) {
        let Some((base, _)) = &self.target else { return };
        let matrices: Vec<[[f32; 4]; 4]> = joint_matrices.iter().take(self.joint_count).map(gpu_joint_matrix).collect();
        if !matrices.is_empty() {
            queue.write_buffer(&self.joints, 0, bytemuck::cast_slice(&matrices));
        }
        let mut params = vec![0u8; self.params.size() as usize];
        let entries = std::iter::once((0, 0)).chain(self.level_ranges.iter().copied());
        for (k, (level_start, level_count)) in entries.enumerate() {
            let entry = GpuRefitParams { level_start, level_count, clearance, ..*base };
            let at = k * PARAMS_STRIDE as usize;
            params[at..at + size_of::<GpuRefitParams>()].copy_from_slice(bytemuck::bytes_of(&entry));
        }
        queue.write_buffer(&self.params, 0, &params);
    }

    /// Records the refit into `pass`: the vertices, the spheres, the boxes level by level, and
    /// the contact reach. Dispatches in one pass run in order, each seeing the last one's
    /// writes. Records nothing unless bound.
    pub fn encode(&self, pass: &mut ComputePass<'_>, kernels: &ClothKernels) {
        let Some((_, groups)) = &self.target else { return };
        let [skin, fit, nodes, reach] = EntryPoint::REFIT.map(|entry| kernels.pipeline(entry));
        let dispatch = |pass: &mut ComputePass<'_>, pipeline, group: &BindGroup, entry: usize, (x, y): (u32, u32)| {
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, group, &[(entry as u64 * PARAMS_STRIDE) as u32]);
            pass.dispatch_workgroups(x, y, 1);
        };
        dispatch(pass, skin, &groups[0], 0, self.vertex_groups);
        dispatch(pass, fit, &groups[1], 0, self.leaf_groups);
        for (l, &workgroups) in self.level_groups.iter().enumerate() {
            dispatch(pass, nodes, &groups[2], 1 + l, workgroups);
        }
        dispatch(pass, reach, &groups[3], 0, (1, 1));
    }

    /// Dispatches one refit records: two, one per level of the tree, and one.
    pub fn dispatches(&self) -> usize {
        3 + self.level_groups.len()
    }
}
