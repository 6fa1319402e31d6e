//! The compute pipelines of the kernels and their bind group layouts, and the WGSL they are
//! built from.

use core::fmt;

use wgpu::{
    BindGroupLayout, BindGroupLayoutEntry, BindingType, BufferBindingType, ComputePipeline, Device, ShaderStages,
};

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
}

/// The kernels' WGSL files, in the order [`shader_source`] joins them: the shared types, the
/// spring forces, the collision response, then one file per kernel. Each starts with naga_oil
/// directives (`#define_import_path`, `#import`) for engines that compose shaders that way;
/// with them goes the module of the constants shared with the core,
/// [`shared_constants`](crate::shared_constants), written from the Rust side.
pub const SHADER_FILES: [(&str, &str); 12] = [
    ("types.wgsl", include_str!("shaders/types.wgsl")),
    ("springs.wgsl", include_str!("shaders/springs.wgsl")),
    ("primitives.wgsl", include_str!("shaders/primitives.wgsl")),
    ("collision.wgsl", include_str!("shaders/collision.wgsl")),
    ("node_update.wgsl", include_str!("shaders/node_update.wgsl")),
    ("node_update_final.wgsl", include_str!("shaders/node_update_final.wgsl")),
    ("block_descent.wgsl", include_str!("shaders/block_descent.wgsl")),
    ("apply_anchors.wgsl", include_str!("shaders/apply_anchors.wgsl")),
    ("normal_shader.wgsl", include_str!("shaders/normal_shader.wgsl")),
    ("skin_refit.wgsl", include_str!("shaders/skin_refit.wgsl")),
    ("self_contact.wgsl", include_str!("shaders/self_contact.wgsl")),
    ("air.wgsl", include_str!("shaders/air.wgsl")),
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

/// Self-contact's kernels, in the order they run in a substep (`contact_begin` before the
/// integrator, the others after it).
pub const CONTACT_KERNELS: [&str; 8] = [
    "contact_begin",
    "contact_count",
    "contact_scan_blocks",
    "contact_scan_top",
    "contact_scan_add",
    "contact_scatter",
    "contact_find",
    "contact_apply",
];

/// Aerodynamics' kernels: `air_sample` once per tick, then `air_forces` at the start of every
/// substep, and `air_kick` for the explicit integrators' cloths. Block descent's cloths take
/// their kick in `vbd_predict_air`, its prediction in a batch with aerodynamics.
pub const AIR_KERNELS: [&str; 3] = ["air_sample", "air_forces", "air_kick"];

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

/// One kernel: its entry point, the WGSL file that holds it, and its bind group layout's
/// entries (group 0). An engine that compiles shaders itself (Bevy's pipeline cache) builds the
/// same pipelines from these and hands them over with [`ClothKernels::from_parts`].
#[derive(Clone, Debug)]
pub struct KernelDescriptor {
    /// The entry point.
    pub entry_point: &'static str,
    /// The [`SHADER_FILES`] entry that holds it.
    pub file: &'static str,
    /// The entries of its bind group layout.
    pub layout: Vec<BindGroupLayoutEntry>,
}

/// Number of kernels (entry points): the length of [`ClothKernels::descriptors`].
pub const KERNEL_COUNT: usize = 25;

/// The compiled kernels: `node_update` (RK4's first three stages, the stage named by the step
/// uniform), `node_update_final` (the last stage with the collision response), block descent's
/// `vbd_predict` (or `vbd_predict_air`), `vbd_solve`, `vbd_drift_blocks` and `vbd_drift` (the
/// drift of a free cloth's centre of mass) and `vbd_finish`, `apply_anchors`, `normal_shader`, a skinned
/// collider's refit (`skin_vertices`, `fit_leaves`, `refit_nodes`, `refit_reach`), and
/// self-contact's eight kernels (`contact_begin` to `contact_apply`) and aerodynamics' three
/// ([`AIR_KERNELS`]), with their bind group layouts.
#[derive(Debug)]
pub struct ClothKernels {
    pub(crate) node_update: ComputePipeline,
    pub(crate) node_update_final: ComputePipeline,
    pub(crate) vbd_predict: ComputePipeline,
    /// `vbd_predict` after the air kick, in a batch with aerodynamics.
    pub(crate) vbd_predict_air: ComputePipeline,
    pub(crate) vbd_solve: ComputePipeline,
    pub(crate) vbd_finish: ComputePipeline,
    /// The two levels of the drift sums of the cloths that nothing holds.
    pub(crate) vbd_drift: [ComputePipeline; 2],
    pub(crate) anchors: ComputePipeline,
    pub(crate) normal: ComputePipeline,
    /// The refit's four kernels, in order, and their layouts (the same entries).
    pub(crate) refit: [ComputePipeline; 4],
    pub(crate) refit_layouts: [BindGroupLayout; 4],
    /// Self-contact's kernels in [`CONTACT_KERNELS`] order, and their layouts.
    pub(crate) contact: [ComputePipeline; 8],
    pub(crate) contact_layouts: [BindGroupLayout; 8],
    /// Aerodynamics' kernels in [`AIR_KERNELS`] order, and their layouts.
    pub(crate) air: [ComputePipeline; 3],
    pub(crate) air_layouts: [BindGroupLayout; 3],
    pub(crate) node_update_layout: BindGroupLayout,
    pub(crate) final_layout: BindGroupLayout,
    pub(crate) vbd_predict_layout: BindGroupLayout,
    pub(crate) vbd_predict_air_layout: BindGroupLayout,
    pub(crate) vbd_solve_layout: BindGroupLayout,
    pub(crate) vbd_finish_layout: BindGroupLayout,
    pub(crate) vbd_drift_layouts: [BindGroupLayout; 2],
    pub(crate) anchors_layout: BindGroupLayout,
    pub(crate) normal_layout: BindGroupLayout,
}

fn entry(binding: u32, ty: BufferBindingType, dynamic: bool) -> BindGroupLayoutEntry {
    BindGroupLayoutEntry {
        binding,
        visibility: ShaderStages::COMPUTE,
        ty: BindingType::Buffer { ty, has_dynamic_offset: dynamic, min_binding_size: None },
        count: None,
    }
}

fn storage(binding: u32, read_only: bool) -> BindGroupLayoutEntry {
    entry(binding, BufferBindingType::Storage { read_only }, false)
}

impl ClothKernels {
    /// The kernels, in the order [`Self::from_parts`] takes them: `node_update`,
    /// `node_update_final`, `vbd_predict`, `vbd_predict_air`, `vbd_solve`, `vbd_drift_blocks`,
    /// `vbd_drift`, `vbd_finish`, `apply_anchors`, `normal_shader`, `skin_vertices`, `fit_leaves`, `refit_nodes`,
    /// `refit_reach`, then [`CONTACT_KERNELS`], then [`AIR_KERNELS`].
    pub fn descriptors() -> [KernelDescriptor; KERNEL_COUNT] {
        let frame = entry(0, BufferBindingType::Uniform, false);
        let step = entry(1, BufferBindingType::Uniform, true);
        let predict = vec![
            frame,
            step,
            storage(6, true),
            storage(8, false),
            storage(19, false),
            storage(20, false),
            storage(21, false),
        ];
        // Both levels of the drift sums: the prediction's bindings but the inertial target, and
        // the per-block sums.
        let drift = [&predict[..6], &[storage(48, false)]].concat();
        let contact = |entry_point, mut layout: Vec<BindGroupLayoutEntry>| {
            layout.insert(0, entry(35, BufferBindingType::Uniform, false));
            KernelDescriptor { entry_point, file: "self_contact.wgsl", layout }
        };
        let refit = |entry_point| KernelDescriptor {
            entry_point,
            file: "skin_refit.wgsl",
            layout: vec![
                entry(26, BufferBindingType::Uniform, true),
                storage(27, true),
                storage(28, true),
                storage(29, false),
                storage(30, true),
                storage(31, true),
                storage(32, true),
                storage(33, false),
                storage(34, false),
            ],
        };
        [
            KernelDescriptor {
                entry_point: "node_update",
                file: "node_update.wgsl",
                layout: vec![
                    frame,
                    step,
                    storage(2, true),
                    storage(3, true),
                    storage(4, false),
                    storage(5, false),
                    storage(6, true),
                    storage(7, true),
                    storage(8, false),
                ],
            },
            KernelDescriptor {
                entry_point: "node_update_final",
                file: "node_update_final.wgsl",
                layout: vec![
                    frame,
                    step,
                    storage(3, true),
                    storage(6, true),
                    storage(7, true),
                    storage(8, false),
                    storage(9, false),
                    storage(10, true),
                    storage(11, true),
                    storage(12, true),
                ],
            },
            KernelDescriptor { entry_point: "vbd_predict", file: "block_descent.wgsl", layout: predict.clone() },
            // The prediction, and the air's cloth constants, state and surface lists.
            KernelDescriptor {
                entry_point: "vbd_predict_air",
                file: "block_descent.wgsl",
                layout: [predict, vec![storage(42, true), storage(44, false), storage(47, true)]].concat(),
            },
            KernelDescriptor {
                entry_point: "vbd_solve",
                file: "block_descent.wgsl",
                layout: vec![
                    frame,
                    step,
                    storage(6, true),
                    storage(7, true),
                    storage(8, false),
                    storage(19, false),
                    storage(20, false),
                    storage(21, false),
                    storage(22, true),
                    entry(25, BufferBindingType::Uniform, true),
                ],
            },
            KernelDescriptor { entry_point: "vbd_drift_blocks", file: "block_descent.wgsl", layout: drift.clone() },
            KernelDescriptor { entry_point: "vbd_drift", file: "block_descent.wgsl", layout: drift },
            KernelDescriptor {
                entry_point: "vbd_finish",
                file: "block_descent.wgsl",
                layout: vec![
                    frame,
                    step,
                    storage(6, true),
                    storage(7, true),
                    storage(8, false),
                    storage(11, true),
                    storage(12, true),
                    storage(19, false),
                    storage(20, false),
                    storage(21, false),
                ],
            },
            KernelDescriptor {
                entry_point: "apply_anchors",
                file: "apply_anchors.wgsl",
                layout: vec![
                    frame,
                    storage(13, false),
                    entry(14, BufferBindingType::Storage { read_only: true }, true),
                ],
            },
            KernelDescriptor {
                entry_point: "normal_shader",
                file: "normal_shader.wgsl",
                layout: vec![
                    storage(15, true),
                    storage(16, true),
                    storage(17, true),
                    storage(18, false),
                    storage(23, true),
                    entry(24, BufferBindingType::Uniform, true),
                ],
            },
            refit("skin_vertices"),
            refit("fit_leaves"),
            refit("refit_nodes"),
            refit("refit_reach"),
            contact(
                CONTACT_KERNELS[0],
                vec![
                    storage(6, true),
                    storage(8, false),
                    storage(36, false),
                    storage(38, false),
                    storage(39, false),
                    storage(40, false),
                ],
            ),
            contact(CONTACT_KERNELS[1], vec![storage(37, false), storage(38, false), storage(40, false)]),
            contact(CONTACT_KERNELS[2], vec![storage(38, false)]),
            contact(CONTACT_KERNELS[3], vec![storage(38, false)]),
            contact(CONTACT_KERNELS[4], vec![storage(38, false)]),
            contact(CONTACT_KERNELS[5], vec![storage(37, false), storage(38, false), storage(40, false)]),
            contact(
                CONTACT_KERNELS[6],
                vec![
                    storage(6, true),
                    storage(8, false),
                    storage(36, false),
                    storage(37, false),
                    storage(38, false),
                    storage(39, false),
                    storage(40, false),
                ],
            ),
            contact(
                CONTACT_KERNELS[7],
                vec![
                    frame,
                    storage(6, true),
                    storage(8, false),
                    storage(11, true),
                    storage(12, true),
                    storage(38, false),
                    storage(39, false),
                    storage(40, false),
                ],
            ),
            KernelDescriptor {
                entry_point: AIR_KERNELS[0],
                file: "air.wgsl",
                layout: vec![
                    frame,
                    storage(6, true),
                    entry(41, BufferBindingType::Storage { read_only: true }, true),
                    storage(42, true),
                    storage(43, true),
                    storage(44, false),
                    storage(46, false),
                ],
            },
            KernelDescriptor {
                entry_point: AIR_KERNELS[1],
                file: "air.wgsl",
                layout: vec![
                    frame,
                    step,
                    storage(6, true),
                    storage(8, false),
                    storage(42, true),
                    storage(44, false),
                    storage(46, false),
                    storage(47, true),
                ],
            },
            KernelDescriptor {
                entry_point: AIR_KERNELS[2],
                file: "air.wgsl",
                layout: vec![
                    frame,
                    step,
                    storage(6, true),
                    storage(8, false),
                    storage(42, true),
                    storage(44, false),
                    storage(46, false),
                    storage(47, true),
                ],
            },
        ]
    }

    /// Checks the device's limits and compiles the kernels from [`shader_source`].
    pub fn new(device: &Device) -> Result<Self, KernelError> {
        Self::check(device)?;
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("bvh_cloth_kernels"),
            source: wgpu::ShaderSource::Wgsl(shader_source().into()),
        });
        let built = Self::descriptors().map(|kernel| {
            let label = format!("bvh_cloth_{}", kernel.entry_point);
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
                entry_point: Some(kernel.entry_point),
                compilation_options: Default::default(),
                cache: None,
            });
            (pipeline, layout)
        });
        let layouts = built.each_ref().map(|(_, layout)| layout.clone());
        Ok(Self::from_parts(built.map(|(pipeline, _)| pipeline), layouts))
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
    /// the pipelines and their bind group layouts, in the order of [`Self::descriptors`].
    pub fn from_parts(pipelines: [ComputePipeline; KERNEL_COUNT], layouts: [BindGroupLayout; KERNEL_COUNT]) -> Self {
        let [
            node_update,
            node_update_final,
            vbd_predict,
            vbd_predict_air,
            vbd_solve,
            vbd_drift_blocks,
            vbd_drift,
            vbd_finish,
            anchors,
            normal,
            r0,
            r1,
            r2,
            r3,
            c0,
            c1,
            c2,
            c3,
            c4,
            c5,
            c6,
            c7,
            a0,
            a1,
            a2,
        ] = pipelines;
        let [
            node_update_layout,
            final_layout,
            vbd_predict_layout,
            vbd_predict_air_layout,
            vbd_solve_layout,
            vbd_drift_blocks_layout,
            vbd_drift_layout,
            vbd_finish_layout,
            anchors_layout,
            normal_layout,
            l0,
            l1,
            l2,
            l3,
            k0,
            k1,
            k2,
            k3,
            k4,
            k5,
            k6,
            k7,
            m0,
            m1,
            m2,
        ] = layouts;
        Self {
            node_update,
            node_update_final,
            vbd_predict,
            vbd_predict_air,
            vbd_solve,
            vbd_finish,
            vbd_drift: [vbd_drift_blocks, vbd_drift],
            anchors,
            normal,
            refit: [r0, r1, r2, r3],
            refit_layouts: [l0, l1, l2, l3],
            contact: [c0, c1, c2, c3, c4, c5, c6, c7],
            contact_layouts: [k0, k1, k2, k3, k4, k5, k6, k7],
            air: [a0, a1, a2],
            air_layouts: [m0, m1, m2],
            node_update_layout,
            final_layout,
            vbd_predict_layout,
            vbd_predict_air_layout,
            vbd_solve_layout,
            vbd_finish_layout,
            vbd_drift_layouts: [vbd_drift_blocks_layout, vbd_drift_layout],
            anchors_layout,
            normal_layout,
        }
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
