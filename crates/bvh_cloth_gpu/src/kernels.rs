//! The compute pipelines of the three kernels and their bind group layouts.

use core::fmt;

use wgpu::{
    BindGroupLayout, BindGroupLayoutEntry, BindingType, BufferBindingType, ComputePipeline, Device, ShaderStages,
};

/// The WGSL source of the three kernels.
pub const SHADER_SOURCE: &str = include_str!("cloth.wgsl");

/// Threads per workgroup along each grid axis (workgroups are 8 x 8 x 1, paper Table I).
pub const WORKGROUP_SIZE: u32 = 8;

/// Storage buffers the busiest kernel (`node_update`) binds at once.
pub const STORAGE_BUFFERS_NEEDED: u32 = 6;

/// Threads per workgroup (8 x 8 x 1).
const THREADS_PER_WORKGROUP: u32 = WORKGROUP_SIZE * WORKGROUP_SIZE;

/// The largest buffer the kernels may bind as storage on `device`: its largest storage binding,
/// or its largest buffer where that is smaller.
pub(crate) fn storage_binding_limit(device: &Device) -> u64 {
    let limits = device.limits();
    limits.max_storage_buffer_binding_size.min(limits.max_buffer_size)
}

/// Why the kernels cannot run on a device.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum KernelError {
    /// The device allows fewer storage buffers per shader stage than the kernels bind.
    TooFewStorageBuffers {
        /// What the device allows.
        allowed: u32,
    },
    /// A cloth has more particles (or render vertices) than one dispatch can cover on this
    /// device.
    TooManyThreads {
        /// Particles or vertices to cover.
        count: u32,
        /// The device's largest workgroup count per dispatch dimension.
        max_workgroups: u32,
    },
    /// A buffer would be larger than one storage binding may be on this device.
    BufferTooLarge {
        /// Bytes needed.
        bytes: u64,
        /// The device's largest storage binding.
        max: u64,
    },
}

impl fmt::Display for KernelError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::TooFewStorageBuffers { allowed } => write!(
                f,
                "the device allows {allowed} storage buffers per shader stage; the cloth kernels need {STORAGE_BUFFERS_NEEDED}"
            ),
            Self::TooManyThreads { count, max_workgroups } => write!(
                f,
                "a cloth of {count} particles or vertices needs more than the device's {max_workgroups} x \
                 {max_workgroups} workgroups per dispatch"
            ),
            Self::BufferTooLarge { bytes, max } => {
                write!(f, "a buffer of {bytes} bytes is larger than the device's largest storage binding ({max} bytes)")
            }
        }
    }
}

impl std::error::Error for KernelError {}

/// The compiled kernels: five `node_update` pipelines (the four RK4 stages and semi-implicit
/// Euler, selected by the WGSL override constant `STAGE`), `collision_detection_with_bvh`,
/// `normal_shader` and `apply_anchors`.
#[derive(Debug)]
pub struct ClothKernels {
    pub(crate) node_update: [ComputePipeline; 5],
    pub(crate) collision: ComputePipeline,
    pub(crate) normal: ComputePipeline,
    pub(crate) anchors: ComputePipeline,
    pub(crate) node_update_layout: BindGroupLayout,
    pub(crate) collision_layout: BindGroupLayout,
    pub(crate) normal_layout: BindGroupLayout,
    pub(crate) anchors_layout: BindGroupLayout,
}

fn entry(binding: u32, ty: BufferBindingType) -> BindGroupLayoutEntry {
    BindGroupLayoutEntry {
        binding,
        visibility: ShaderStages::COMPUTE,
        ty: BindingType::Buffer { ty, has_dynamic_offset: false, min_binding_size: None },
        count: None,
    }
}

fn storage(binding: u32, read_only: bool) -> BindGroupLayoutEntry {
    entry(binding, BufferBindingType::Storage { read_only })
}

impl ClothKernels {
    /// Checks the device's limits and compiles the kernels.
    pub fn new(device: &Device) -> Result<Self, KernelError> {
        let allowed = device.limits().max_storage_buffers_per_shader_stage;
        if allowed < STORAGE_BUFFERS_NEEDED {
            return Err(KernelError::TooFewStorageBuffers { allowed });
        }
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("bvh_cloth_kernels"),
            source: wgpu::ShaderSource::Wgsl(SHADER_SOURCE.into()),
        });
        let params = entry(0, BufferBindingType::Uniform);
        let layout = |label: &str, entries: &[BindGroupLayoutEntry]| {
            device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some(label), entries })
        };
        let node_update_layout = layout(
            "bvh_cloth_node_update_layout",
            &[
                params,
                storage(1, true),
                storage(2, true),
                storage(3, false),
                storage(4, false),
                storage(13, false),
                storage(16, true),
            ],
        );
        let collision_layout = layout(
            "bvh_cloth_collision_layout",
            &[params, storage(5, false), storage(6, true), storage(7, true), storage(8, true), storage(9, true)],
        );
        let normal_layout = layout(
            "bvh_cloth_normal_layout",
            &[params, storage(10, true), entry(11, BufferBindingType::Uniform), storage(12, false), storage(17, true)],
        );
        let targets = BindGroupLayoutEntry {
            binding: 15,
            visibility: ShaderStages::COMPUTE,
            ty: BindingType::Buffer {
                ty: BufferBindingType::Storage { read_only: true },
                has_dynamic_offset: true,
                min_binding_size: None,
            },
            count: None,
        };
        let anchors_layout = layout("bvh_cloth_anchors_layout", &[params, storage(14, false), targets]);
        let pipeline = |label: &str, layout: &BindGroupLayout, entry_point: &str, constants: &[(&str, f64)]| {
            let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some(label),
                bind_group_layouts: &[Some(layout)],
                immediate_size: 0,
            });
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(label),
                layout: Some(&pipeline_layout),
                module: &module,
                entry_point: Some(entry_point),
                compilation_options: wgpu::PipelineCompilationOptions { constants, ..Default::default() },
                cache: None,
            })
        };
        let node_update = [0.0, 1.0, 2.0, 3.0, 4.0]
            .map(|stage| pipeline("bvh_cloth_node_update", &node_update_layout, "node_update", &[("STAGE", stage)]));
        Ok(Self {
            node_update,
            collision: pipeline(
                "bvh_cloth_collision_detection_with_bvh",
                &collision_layout,
                "collision_detection_with_bvh",
                &[],
            ),
            normal: pipeline("bvh_cloth_normal_shader", &normal_layout, "normal_shader", &[]),
            anchors: pipeline("bvh_cloth_apply_anchors", &anchors_layout, "apply_anchors", &[]),
            node_update_layout,
            collision_layout,
            normal_layout,
            anchors_layout,
        })
    }

    /// Workgroups (8 x 8 threads each) that give `count` threads, one per particle or vertex,
    /// as `(x, y)`, or why one dispatch cannot. A thread's index is `y * (8 x) + x`.
    pub fn workgroups(device: &Device, count: u32) -> Result<(u32, u32), KernelError> {
        let max_workgroups = device.limits().max_compute_workgroups_per_dimension;
        let groups = count.div_ceil(THREADS_PER_WORKGROUP).max(1);
        let x = groups.min(max_workgroups);
        let y = groups.div_ceil(x);
        if y > max_workgroups {
            return Err(KernelError::TooManyThreads { count, max_workgroups });
        }
        Ok((x, y))
    }
}
