//! The kernels' entry points ([`EntryPoint`]), and each one's WGSL file and bind group
//! layout ([`KernelDescriptor`]).

use wgpu::{BindGroupLayoutEntry, BindingType, BufferBindingType, ShaderStages};

/// Every entry point of the kernels, in the order [`ClothKernels::descriptors`](crate::ClothKernels::descriptors) lists them.
/// Self-contact's twenty-one run in a substep as [`Self::CONTACT`] lists them, as do
/// aerodynamics' three ([`Self::AIR`]) and a skinned collider's refit ([`Self::REFIT`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum EntryPoint {
    /// `node_update`: one of RK4's first three stages (semi-implicit Euler in the first).
    NodeUpdate,
    /// `node_update_final`: the last stage, with the collision response.
    NodeUpdateFinal,
    /// `vbd_predict`: block descent's inertial target, the first iterate.
    VbdPredict,
    /// `vbd_predict_air`: the prediction after the air kick, in a batch with aerodynamics.
    VbdPredictAir,
    /// `vbd_solve`: one block-descent sweep over one colour.
    VbdSolve,
    /// `vbd_drift_blocks`: the first level of the drift sums of the cloths nothing holds.
    VbdDriftBlocks,
    /// `vbd_drift`: the second level of the drift sums, and the drift itself.
    VbdDrift,
    /// `vbd_finish`: block descent's velocity update, with the collision response.
    VbdFinish,
    /// `apply_anchors`: the pins moved at the start of a tick.
    ApplyAnchors,
    /// `normal_shader`: normals, written with the positions into the vertex buffer.
    NormalShader,
    /// `skin_vertices`: a skinned collider's vertices skinned by its joints.
    SkinVertices,
    /// `fit_leaves`: its spheres fitted to their skinned vertices.
    FitLeaves,
    /// `refit_nodes`: its tree's boxes refitted bottom-up.
    RefitNodes,
    /// `refit_reach`: its contact reach.
    RefitReach,
    /// `contact_begin`: self-contact's substep start kept, its sums and bucket counts cleared.
    ContactBegin,
    /// `contact_count`: each triangle counted in its grid buckets.
    ContactCount,
    /// `contact_scan_blocks`: the buckets' prefix sum within blocks.
    ContactScanBlocks,
    /// `contact_scan_top`: the prefix sum of the blocks' totals.
    ContactScanTop,
    /// `contact_scan_add`: the blocks' offsets added back.
    ContactScanAdd,
    /// `contact_scatter`: each triangle entered in its grid buckets.
    ContactScatter,
    /// `contact_find`: each particle's contacts, their corrections summed.
    ContactFind,
    /// `contact_apply`: each particle's mean correction, then the collision response.
    ContactApply,
    /// `contact_find_edges`: each edge's contacts with the edges after it, their corrections
    /// summed.
    ContactFindEdges,
    /// `untangle_find`: each triangle tested against the other cloths' triangles in its buckets, at the substep's start.
    UntangleFind,
    /// `untangle_join`: each uncut triangle joined to its uncut neighbours' part.
    UntangleJoin,
    /// `untangle_size`: each part's size.
    UntangleSize,
    /// `untangle_largest`: each cloth's largest part's size.
    UntangleLargest,
    /// `untangle_first`: the first of each cloth's largest parts.
    UntangleFirst,
    /// `untangle_corners`: the corners of each cloth's largest part.
    UntangleCorners,
    /// `untangle_outside`: each cloth's particles through the other, counted; each part's ring.
    UntangleOutside,
    /// `untangle_enclose`: the particles each ring encloses.
    UntangleEnclose,
    /// `untangle_rings`: each ring's enclosed particles counted.
    UntangleRings,
    /// `untangle_link`: of two linked rings, the one taken back.
    UntangleLink,
    /// `untangle_mark`: the particles of the cloth taken back, marked.
    UntangleMark,
    /// `untangle_sheets`: the corners of a ring another goes back through labelled with its
    /// sheet.
    UntangleSheets,
    /// `air_sample`: the wind at every particle of the cloths with aerodynamics, once a tick.
    AirSample,
    /// `air_forces`: each triangle's drag and lift, every substep.
    AirForces,
    /// `air_kick`: each particle's velocity changed by its triangles' drag and lift.
    AirKick,
    /// `mg_begin`: the multigrid correction's substep: its step, and whether it assembles and factors.
    MgBegin,
    /// `mg_springs`: each crossing spring's force, direction and stretch (and Hessian at an assembly).
    MgSprings,
    /// `mg_residual`: level 1's residual (and its matrix at an assembly).
    MgResidual,
    /// `mg_galerkin`: a coarser level's matrix gathered from its children, at an assembly.
    MgGalerkin,
    /// `mg_factor`: the diagonal blocks' inverses, when the step or the levels changed.
    MgFactor,
    /// `mg_dense_factor`: the coarsest level's Cholesky factor, one workgroup per cloth.
    MgDenseFactor,
    /// `mg_smooth_down`: a level's damped Jacobi step from zero, on the way down the V-cycle.
    MgSmoothDown,
    /// `mg_restrict`: the residual restricted to the next level.
    MgRestrict,
    /// `mg_coarsest`: the coarsest level's solve, one workgroup per cloth.
    MgCoarsest,
    /// `mg_smooth_up`: the prolongation and a damped Jacobi step, on the way up.
    MgSmoothUp,
    /// `mg_keep`: the first level's answer kept as the start of its second visit to the next
    /// level (the cloths that run `Cycle::TopW` only).
    MgKeep,
    /// `mg_line_chunks`: the line search's sums over chunks of 64 nodes.
    MgLineChunks,
    /// `mg_line_search`: the step along the correction, one workgroup per cloth.
    MgLineSearch,
    /// `mg_apply`: each particle's share of the correction.
    MgApply,
}

impl EntryPoint {
    /// Every entry point, in order.
    pub const ALL: [Self; 52] = [
        Self::NodeUpdate,
        Self::NodeUpdateFinal,
        Self::VbdPredict,
        Self::VbdPredictAir,
        Self::VbdSolve,
        Self::VbdDriftBlocks,
        Self::VbdDrift,
        Self::VbdFinish,
        Self::ApplyAnchors,
        Self::NormalShader,
        Self::SkinVertices,
        Self::FitLeaves,
        Self::RefitNodes,
        Self::RefitReach,
        Self::ContactBegin,
        Self::ContactCount,
        Self::ContactScanBlocks,
        Self::ContactScanTop,
        Self::ContactScanAdd,
        Self::ContactScatter,
        Self::ContactFind,
        Self::ContactApply,
        Self::ContactFindEdges,
        Self::UntangleFind,
        Self::UntangleJoin,
        Self::UntangleSize,
        Self::UntangleLargest,
        Self::UntangleFirst,
        Self::UntangleCorners,
        Self::UntangleOutside,
        Self::UntangleEnclose,
        Self::UntangleRings,
        Self::UntangleLink,
        Self::UntangleMark,
        Self::UntangleSheets,
        Self::AirSample,
        Self::AirForces,
        Self::AirKick,
        Self::MgBegin,
        Self::MgSprings,
        Self::MgResidual,
        Self::MgGalerkin,
        Self::MgFactor,
        Self::MgDenseFactor,
        Self::MgSmoothDown,
        Self::MgRestrict,
        Self::MgCoarsest,
        Self::MgSmoothUp,
        Self::MgKeep,
        Self::MgLineChunks,
        Self::MgLineSearch,
        Self::MgApply,
    ];

    /// A skinned collider's refit, in the order it runs.
    pub const REFIT: [Self; 4] = [Self::SkinVertices, Self::FitLeaves, Self::RefitNodes, Self::RefitReach];

    /// Self-contact's kernels (`untangle_*` from `untangle.wgsl`, the others from
    /// `self_contact.wgsl`): `contact_begin` before the integrator, the others after it, from
    /// the grid's build to `contact_scatter`, then untangling's, then the contacts'
    /// (`contact_apply` runs again after `contact_find_edges`).
    pub const CONTACT: [Self; 21] = [
        Self::ContactBegin,
        Self::ContactCount,
        Self::ContactScanBlocks,
        Self::ContactScanTop,
        Self::ContactScanAdd,
        Self::ContactScatter,
        Self::ContactFind,
        Self::ContactApply,
        Self::ContactFindEdges,
        Self::UntangleFind,
        Self::UntangleJoin,
        Self::UntangleSize,
        Self::UntangleLargest,
        Self::UntangleFirst,
        Self::UntangleCorners,
        Self::UntangleOutside,
        Self::UntangleEnclose,
        Self::UntangleRings,
        Self::UntangleLink,
        Self::UntangleMark,
        Self::UntangleSheets,
    ];

    /// Aerodynamics' kernels: `air_sample` once per tick, then `air_forces` at the start of
    /// every substep, and `air_kick` for the explicit integrators' cloths. Block descent's
    /// cloths take their kick in `vbd_predict_air`.
    pub const AIR: [Self; 3] = [Self::AirSample, Self::AirForces, Self::AirKick];

    /// The entry point's name in the WGSL.
    pub const fn name(self) -> &'static str {
        match self {
            Self::NodeUpdate => "node_update",
            Self::NodeUpdateFinal => "node_update_final",
            Self::VbdPredict => "vbd_predict",
            Self::VbdPredictAir => "vbd_predict_air",
            Self::VbdSolve => "vbd_solve",
            Self::VbdDriftBlocks => "vbd_drift_blocks",
            Self::VbdDrift => "vbd_drift",
            Self::VbdFinish => "vbd_finish",
            Self::ApplyAnchors => "apply_anchors",
            Self::NormalShader => "normal_shader",
            Self::SkinVertices => "skin_vertices",
            Self::FitLeaves => "fit_leaves",
            Self::RefitNodes => "refit_nodes",
            Self::RefitReach => "refit_reach",
            Self::ContactBegin => "contact_begin",
            Self::ContactCount => "contact_count",
            Self::ContactScanBlocks => "contact_scan_blocks",
            Self::ContactScanTop => "contact_scan_top",
            Self::ContactScanAdd => "contact_scan_add",
            Self::ContactScatter => "contact_scatter",
            Self::ContactFind => "contact_find",
            Self::ContactApply => "contact_apply",
            Self::ContactFindEdges => "contact_find_edges",
            Self::UntangleFind => "untangle_find",
            Self::UntangleJoin => "untangle_join",
            Self::UntangleSize => "untangle_size",
            Self::UntangleLargest => "untangle_largest",
            Self::UntangleFirst => "untangle_first",
            Self::UntangleCorners => "untangle_corners",
            Self::UntangleOutside => "untangle_outside",
            Self::UntangleEnclose => "untangle_enclose",
            Self::UntangleRings => "untangle_rings",
            Self::UntangleLink => "untangle_link",
            Self::UntangleMark => "untangle_mark",
            Self::UntangleSheets => "untangle_sheets",
            Self::AirSample => "air_sample",
            Self::AirForces => "air_forces",
            Self::AirKick => "air_kick",
            Self::MgBegin => "mg_begin",
            Self::MgSprings => "mg_springs",
            Self::MgResidual => "mg_residual",
            Self::MgGalerkin => "mg_galerkin",
            Self::MgFactor => "mg_factor",
            Self::MgDenseFactor => "mg_dense_factor",
            Self::MgSmoothDown => "mg_smooth_down",
            Self::MgRestrict => "mg_restrict",
            Self::MgCoarsest => "mg_coarsest",
            Self::MgSmoothUp => "mg_smooth_up",
            Self::MgKeep => "mg_keep",
            Self::MgLineChunks => "mg_line_chunks",
            Self::MgLineSearch => "mg_line_search",
            Self::MgApply => "mg_apply",
        }
    }
}

/// One kernel: its entry point, the WGSL file that holds it, and its bind group layout's
/// entries (group 0). An engine that compiles shaders itself (Bevy's pipeline cache) builds the
/// same pipelines from these and hands them over with [`ClothKernels::from_parts`](crate::ClothKernels::from_parts).
#[derive(Clone, Debug)]
pub struct KernelDescriptor {
    /// The entry point.
    pub entry: EntryPoint,
    /// The [`SHADER_FILES`](crate::SHADER_FILES) entry that holds it.
    pub file: &'static str,
    /// The entries of its bind group layout.
    pub layout: Vec<BindGroupLayoutEntry>,
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

/// Every kernel's descriptor, in [`EntryPoint::ALL`]'s order.
pub(super) fn descriptors() -> [KernelDescriptor; EntryPoint::ALL.len()] {
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
    // Both levels of the drift sums: the prediction's bindings and the per-block sums.
    let drift = [&predict[..], &[storage(48, false)]].concat();
    // The air's two substep kernels bind the same buffers: the forces and the kick.
    let air_substep = vec![
        frame,
        step,
        storage(6, true),
        storage(8, false),
        storage(42, true),
        storage(44, false),
        storage(46, false),
        storage(47, true),
    ];
    let contact = |point: EntryPoint, mut layout: Vec<BindGroupLayoutEntry>| {
        layout.insert(0, entry(35, BufferBindingType::Uniform, false));
        KernelDescriptor { entry: point, file: "self_contact.wgsl", layout }
    };
    // Untangling's kernels bind the contact frame, the particles' cloths, the cloths, and the
    // contact buffers they read and write.
    let untangle = |point: EntryPoint| KernelDescriptor {
        entry: point,
        file: "untangle.wgsl",
        layout: vec![
            entry(35, BufferBindingType::Uniform, false),
            storage(6, true),
            storage(8, false),
            storage(36, false),
            storage(37, false),
            storage(38, false),
        ],
    };
    // Every multigrid kernel binds the same buffers: block descent's state, and the hierarchy.
    let multigrid = |point: EntryPoint| KernelDescriptor {
        entry: point,
        file: "multigrid.wgsl",
        layout: vec![
            frame,
            step,
            storage(6, true),
            storage(8, false),
            storage(19, false),
            storage(20, false),
            storage(21, false),
            storage(49, true),
            storage(50, false),
            storage(51, false),
            entry(52, BufferBindingType::Uniform, true),
        ],
    };
    let refit = |point: EntryPoint| KernelDescriptor {
        entry: point,
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
            entry: EntryPoint::NodeUpdate,
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
            entry: EntryPoint::NodeUpdateFinal,
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
        KernelDescriptor { entry: EntryPoint::VbdPredict, file: "block_descent.wgsl", layout: predict.clone() },
        // The prediction, and the air's cloth constants, state and surface lists.
        KernelDescriptor {
            entry: EntryPoint::VbdPredictAir,
            file: "block_descent.wgsl",
            layout: [predict, vec![storage(42, true), storage(44, false), storage(47, true)]].concat(),
        },
        KernelDescriptor {
            entry: EntryPoint::VbdSolve,
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
        KernelDescriptor { entry: EntryPoint::VbdDriftBlocks, file: "block_descent.wgsl", layout: drift.clone() },
        KernelDescriptor { entry: EntryPoint::VbdDrift, file: "block_descent.wgsl", layout: drift },
        KernelDescriptor {
            entry: EntryPoint::VbdFinish,
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
            entry: EntryPoint::ApplyAnchors,
            file: "apply_anchors.wgsl",
            layout: vec![frame, storage(13, false), entry(14, BufferBindingType::Storage { read_only: true }, true)],
        },
        KernelDescriptor {
            entry: EntryPoint::NormalShader,
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
        refit(EntryPoint::SkinVertices),
        refit(EntryPoint::FitLeaves),
        refit(EntryPoint::RefitNodes),
        refit(EntryPoint::RefitReach),
        contact(
            EntryPoint::ContactBegin,
            vec![
                storage(6, true),
                storage(8, false),
                storage(36, false),
                storage(38, false),
                storage(39, false),
                storage(40, false),
            ],
        ),
        contact(
            EntryPoint::ContactCount,
            vec![storage(36, false), storage(37, false), storage(38, false), storage(40, false)],
        ),
        contact(EntryPoint::ContactScanBlocks, vec![storage(38, false)]),
        contact(EntryPoint::ContactScanTop, vec![storage(38, false)]),
        contact(EntryPoint::ContactScanAdd, vec![storage(38, false)]),
        contact(
            EntryPoint::ContactScatter,
            vec![storage(36, false), storage(37, false), storage(38, false), storage(40, false)],
        ),
        contact(
            EntryPoint::ContactFind,
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
            EntryPoint::ContactApply,
            vec![
                frame,
                storage(6, true),
                storage(8, false),
                storage(11, true),
                storage(12, true),
                storage(38, false),
                storage(39, false),
                storage(40, false),
                storage(21, false),
            ],
        ),
        contact(
            EntryPoint::ContactFindEdges,
            vec![
                storage(8, false),
                storage(36, false),
                storage(37, false),
                storage(38, false),
                storage(39, false),
                storage(40, false),
            ],
        ),
        untangle(EntryPoint::UntangleFind),
        untangle(EntryPoint::UntangleJoin),
        untangle(EntryPoint::UntangleSize),
        untangle(EntryPoint::UntangleLargest),
        untangle(EntryPoint::UntangleFirst),
        untangle(EntryPoint::UntangleCorners),
        untangle(EntryPoint::UntangleOutside),
        untangle(EntryPoint::UntangleEnclose),
        untangle(EntryPoint::UntangleRings),
        untangle(EntryPoint::UntangleLink),
        untangle(EntryPoint::UntangleMark),
        untangle(EntryPoint::UntangleSheets),
        KernelDescriptor {
            entry: EntryPoint::AirSample,
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
        KernelDescriptor { entry: EntryPoint::AirForces, file: "air.wgsl", layout: air_substep.clone() },
        KernelDescriptor { entry: EntryPoint::AirKick, file: "air.wgsl", layout: air_substep },
        multigrid(EntryPoint::MgBegin),
        multigrid(EntryPoint::MgSprings),
        multigrid(EntryPoint::MgResidual),
        multigrid(EntryPoint::MgGalerkin),
        multigrid(EntryPoint::MgFactor),
        multigrid(EntryPoint::MgDenseFactor),
        multigrid(EntryPoint::MgSmoothDown),
        multigrid(EntryPoint::MgRestrict),
        multigrid(EntryPoint::MgCoarsest),
        multigrid(EntryPoint::MgSmoothUp),
        multigrid(EntryPoint::MgKeep),
        multigrid(EntryPoint::MgLineChunks),
        multigrid(EntryPoint::MgLineSearch),
        multigrid(EntryPoint::MgApply),
    ]
}
