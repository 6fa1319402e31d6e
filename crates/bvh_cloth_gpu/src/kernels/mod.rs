//! The compute pipelines of the kernels and their bind group layouts, and the WGSL they are
//! built from.

mod entry_point;

use core::fmt;

pub use entry_point::{EntryPoint, KernelDescriptor};

use wgpu::{BindGroupLayout, ComputePipeline, Device};

/// The kernel a dispatch runs, as [`ClothBatch::encode_ticks_timed`](crate::ClothBatch::encode_ticks_timed) reports it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Kernel {
    /// `apply_anchors`: the pins moved at the start of a tick.
    ApplyAnchors,
    /// `node_update`: one of RK4's first three stages (semi-implicit Euler in the first).
    NodeUpdate,
    /// `node_update_final`: the last stage, with the collision response.
    NodeUpdateFinal,
    /// `vbd_predict`: block descent's inertial target, the first iterate.
    VbdPredict,
    /// `vbd_solve`: one block-descent sweep over one colour.
    VbdSolve,
    /// `vbd_finish`: block descent's velocity update, with the collision response.
    VbdFinish,
    /// `vbd_drift_blocks` or `vbd_drift`: the drift of the centre of mass of the block-descent
    /// cloths that nothing holds.
    VbdDrift,
    /// `contact_begin`: self-contact's substep start kept, its sums and bucket counts cleared.
    ContactBegin,
    /// `contact_count`: each triangle counted in its grid buckets.
    ContactCount,
    /// `contact_scan_blocks`, `contact_scan_top` or `contact_scan_add`: the buckets' prefix sum.
    ContactScan,
    /// `contact_scatter`: each triangle entered in its grid buckets.
    ContactScatter,
    /// `contact_find`: each particle's contacts, their corrections summed.
    ContactFind,
    /// `contact_apply`: each particle's mean correction, then the collision response.
    ContactApply,
    /// `contact_find_edges`: each edge's contacts with the edges after it.
    ContactFindEdges,
    /// `untangle_*`: which particles lie through another cloth, or another sheet of their own,
    /// at the substep's start.
    Untangle,
    /// `air_sample`: the wind at every particle of the cloths with aerodynamics, once a tick.
    AirSample,
    /// `air_forces`: each triangle's drag and lift.
    AirForces,
    /// `air_kick`: each particle's velocity changed by the drag and lift of its triangles (the
    /// explicit integrators' cloths).
    AirKick,
    /// `vbd_predict_air`: block descent's prediction after the air kick of its cloths in the
    /// wind, in a batch with aerodynamics.
    VbdPredictAir,
    /// One of the multigrid correction's kernels (`mg_*`).
    Multigrid,
}

/// The kernels' WGSL files, in the order [`shader_source`] joins them: the shared types, the
/// spring forces, the collision response, then one file per kernel. Each starts with naga_oil
/// directives (`#define_import_path`, `#import`) for engines that compose shaders that way;
/// with them goes the module of the constants shared with the core,
/// [`shared_constants`](crate::shared_constants), written from the Rust side.
pub const SHADER_FILES: [(&str, &str); 14] = [
    ("types.wgsl", include_str!("../shaders/types.wgsl")),
    ("springs.wgsl", include_str!("../shaders/springs.wgsl")),
    ("primitives.wgsl", include_str!("../shaders/primitives.wgsl")),
    ("collision.wgsl", include_str!("../shaders/collision.wgsl")),
    ("node_update.wgsl", include_str!("../shaders/node_update.wgsl")),
    ("node_update_final.wgsl", include_str!("../shaders/node_update_final.wgsl")),
    ("block_descent.wgsl", include_str!("../shaders/block_descent.wgsl")),
    ("apply_anchors.wgsl", include_str!("../shaders/apply_anchors.wgsl")),
    ("normal_shader.wgsl", include_str!("../shaders/normal_shader.wgsl")),
    ("skin_refit.wgsl", include_str!("../shaders/skin_refit.wgsl")),
    ("self_contact.wgsl", include_str!("../shaders/self_contact.wgsl")),
    ("untangle.wgsl", include_str!("../shaders/untangle.wgsl")),
    ("air.wgsl", include_str!("../shaders/air.wgsl")),
    ("multigrid.wgsl", include_str!("../shaders/multigrid.wgsl")),
];

/// The kernels as one WGSL module: the shared constants ([`crate::shared_constants`]) and
/// [`SHADER_FILES`] joined, their import directives dropped.
pub fn shader_source() -> String {
    let mut source = String::new();
    let constants = crate::shared_constants();
    for (name, text) in std::iter::once((crate::CONSTANTS_FILE, constants.as_str())).chain(SHADER_FILES) {
        source.push_str(&format!("// ---- {name}\n"));
        for line in text.lines().filter(|line| !line.starts_with("#define_import_path") && !line.starts_with("#import"))
        {
            source.push_str(line);
            source.push('\n');
        }
    }
    source
}

/// Threads per workgroup along each grid axis (workgroups are 8 x 8 x 1, paper Table I).
pub const WORKGROUP_SIZE: u32 = 8;

/// Storage buffers the busiest kernel (`node_update_final`) binds at once.
pub const STORAGE_BUFFERS_NEEDED: u32 = 8;

/// Threads per workgroup (8 x 8 x 1).
const THREADS_PER_WORKGROUP: u32 = WORKGROUP_SIZE * WORKGROUP_SIZE;

/// The largest buffer the kernels may bind as storage on `device`: its largest storage binding,
/// or its largest buffer where that is smaller.
pub(crate) fn storage_binding_limit(device: &Device) -> u64 {
    let limits = device.limits();
    limits.max_storage_buffer_binding_size.min(limits.max_buffer_size)
}

/// Why the kernels cannot run on a device, or a cloth cannot join a batch.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum KernelError {
    /// The device allows fewer storage buffers per shader stage than the kernels bind.
    TooFewStorageBuffers {
        /// What the device allows.
        allowed: u32,
    },
    /// The batch would have more particles (or a cloth more render vertices) than one
    /// dispatch can cover on this device.
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
                "{count} particles or vertices need more than the device's {max_workgroups} x {max_workgroups} \
                 workgroups per dispatch"
            ),
            Self::BufferTooLarge { bytes, max } => {
                write!(f, "a buffer of {bytes} bytes is larger than the device's largest storage binding ({max} bytes)")
            }
        }
    }
}

impl std::error::Error for KernelError {}

/// The compiled kernels: one pipeline and one bind group layout per [`EntryPoint`].
#[derive(Debug)]
pub struct ClothKernels {
    /// The pipelines, one per [`EntryPoint`] in its order.
    pipelines: Vec<ComputePipeline>,
    /// Their bind group layouts (group 0), in the same order.
    layouts: Vec<BindGroupLayout>,
}

impl ClothKernels {
    /// Every kernel, in [`EntryPoint::ALL`]'s order.
    pub fn descriptors() -> [KernelDescriptor; EntryPoint::ALL.len()] {
        entry_point::descriptors()
    }

    /// Checks the device's limits and compiles the kernels from [`shader_source`].
    pub fn new(device: &Device) -> Result<Self, KernelError> {
        Self::check(device)?;
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("bvh_cloth_kernels"),
            source: wgpu::ShaderSource::Wgsl(shader_source().into()),
        });
        let built = Self::descriptors().map(|kernel| {
            let label = format!("bvh_cloth_{}", kernel.entry.name());
            let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some(&label),
                entries: &kernel.layout,
            });
            let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some(&label),
                bind_group_layouts: &[Some(&layout)],
                immediate_size: 0,
            });
            let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(&label),
                layout: Some(&pipeline_layout),
                module: &module,
                entry_point: Some(kernel.entry.name()),
                compilation_options: Default::default(),
                cache: None,
            });
            (pipeline, layout)
        });
        let (pipelines, layouts) = built.into_iter().unzip();
        Ok(Self { pipelines, layouts })
    }

    /// Why `device` cannot run the kernels, if it cannot.
    pub fn check(device: &Device) -> Result<(), KernelError> {
        let allowed = device.limits().max_storage_buffers_per_shader_stage;
        if allowed < STORAGE_BUFFERS_NEEDED {
            return Err(KernelError::TooFewStorageBuffers { allowed });
        }
        Ok(())
    }

    /// Kernels compiled elsewhere (by an engine's pipeline cache, from [`Self::descriptors`]):
    /// `part` gives each entry point's pipeline and bind group layout, or `None` while one is
    /// not ready, and then so is the whole.
    pub fn from_parts(mut part: impl FnMut(EntryPoint) -> Option<(ComputePipeline, BindGroupLayout)>) -> Option<Self> {
        let (pipelines, layouts) =
            EntryPoint::ALL.into_iter().map(&mut part).collect::<Option<Vec<_>>>()?.into_iter().unzip();
        Some(Self { pipelines, layouts })
    }

    /// The pipeline of `entry`.
    pub(crate) fn pipeline(&self, entry: EntryPoint) -> &ComputePipeline {
        &self.pipelines[entry as usize]
    }

    /// The bind group layout of `entry`.
    pub(crate) fn layout(&self, entry: EntryPoint) -> &BindGroupLayout {
        &self.layouts[entry as usize]
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
