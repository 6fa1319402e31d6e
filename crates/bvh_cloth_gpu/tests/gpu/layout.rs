//! The WGSL (the kernel files joined as the crate compiles them) passes naga's validation,
//! and every struct it shares with Rust has the same size and the same member offsets as the
//! core's `#[repr(C)]` definition. Needs no GPU.

use core::mem::{offset_of, size_of};

use bvh_cloth_core::backend::AirSource;
use bvh_cloth_core::backend::SkinPoint;
use bvh_cloth_core::{BvhNode, Sphere, Vec3};
use bvh_cloth_gpu::layout::{
    GpuAirCloth, GpuBatchCloth, GpuBatchFrame, GpuBatchStep, GpuBatchWriteback, GpuCollider, GpuColourPass,
    GpuContactFrame, GpuMeshWriteback, GpuMultigridCloth, GpuMultigridPass, GpuParticle, GpuRefitParams, GpuSkinVertex,
    GpuWritebackGroup, NO_CLOTH, gpu_triangle_neighbours,
};
use bvh_cloth_gpu::{SHADER_FILES, shader_source};
use naga::valid::{Capabilities, ValidationFlags, Validator};

fn module() -> naga::Module {
    let source = shader_source();
    naga::front::wgsl::parse_str(&source).unwrap_or_else(|e| panic!("{}", e.emit_to_string(&source)))
}

/// `(size, [(member, offset)])` of the WGSL struct called `name`.
fn wgsl_layout(module: &naga::Module, name: &str) -> (u32, Vec<(String, u32)>) {
    let ty = module
        .types
        .iter()
        .find(|(_, t)| t.name.as_deref() == Some(name))
        .unwrap_or_else(|| panic!("no struct {name}"));
    let naga::TypeInner::Struct { members, span } = &ty.1.inner else { panic!("{name} is not a struct") };
    (*span, members.iter().map(|m| (m.name.clone().unwrap(), m.offset)).collect())
}

macro_rules! assert_layout {
    ($module:expr, $wgsl:literal, $rust:ty, [$($field:ident),* $(,)?]) => {{
        let (size, members) = wgsl_layout($module, $wgsl);
        assert_eq!(size as usize, size_of::<$rust>(), "size of {}", $wgsl);
        let rust: Vec<(String, u32)> = vec![$((stringify!($field).to_string(), offset_of!($rust, $field) as u32)),*];
        assert_eq!(members, rust, "members of {}", $wgsl);
    }};
}

#[test]
fn wgsl_is_valid() {
    let module = module();
    Validator::new(ValidationFlags::all(), Capabilities::all())
        .validate(&module)
        .unwrap_or_else(|e| panic!("{}", e.emit_to_string(&shader_source())));
    let entry_points: Vec<&str> = module.entry_points.iter().map(|e| e.name.as_str()).collect();
    assert_eq!(
        entry_points,
        [
            "node_update",
            "node_update_final",
            "vbd_predict",
            "vbd_predict_air",
            "vbd_solve",
            "vbd_drift_blocks",
            "vbd_drift",
            "vbd_finish",
            "apply_anchors",
            "normal_shader",
            "skin_vertices",
            "fit_leaves",
            "refit_nodes",
            "refit_reach",
            "contact_begin",
            "contact_count",
            "contact_scan_blocks",
            "contact_scan_top",
            "contact_scan_add",
            "contact_scatter",
            "contact_find",
            "contact_apply",
            "contact_find_edges",
            "untangle_find",
            "untangle_join",
            "untangle_size",
            "untangle_largest",
            "untangle_first",
            "untangle_corners",
            "untangle_outside",
            "untangle_enclose",
            "untangle_rings",
            "untangle_link",
            "untangle_mark",
            "untangle_sheets",
            "air_sample",
            "air_forces",
            "air_kick",
            "mg_begin",
            "mg_springs",
            "mg_residual",
            "mg_galerkin",
            "mg_factor",
            "mg_dense_factor",
            "mg_smooth_down",
            "mg_restrict",
            "mg_coarsest",
            "mg_smooth_up",
            "mg_keep",
            "mg_line_chunks",
            "mg_line_search",
            "mg_apply",
        ]
    );
    for entry in &module.entry_points {
        // The refit's kernels, the prefix sum's, the drift sums and the multigrid's per-cloth
        // kernels run one row of 64 threads.
        let size = if entry.name.contains("refit")
            || ["mg_dense_factor", "mg_coarsest", "mg_line_chunks", "mg_line_search"].contains(&entry.name.as_str())
            || entry.name.ends_with("_leaves")
            || entry.name.starts_with("skin")
            || entry.name.contains("_scan_")
            || entry.name.starts_with("vbd_drift")
        {
            [64, 1, 1]
        } else {
            [8, 8, 1]
        };
        assert_eq!(entry.workgroup_size, size, "{} runs {size:?} workgroups", entry.name);
    }
    let descriptors: Vec<&str> = bvh_cloth_gpu::ClothKernels::descriptors().iter().map(|k| k.entry.name()).collect();
    let all: Vec<&str> = bvh_cloth_gpu::EntryPoint::ALL.iter().map(|e| e.name()).collect();
    assert_eq!(descriptors, all, "the descriptors list every entry point in EntryPoint::ALL's order");
    assert_eq!(descriptors, entry_points, "one descriptor per entry point, in order");
}

#[test]
fn wgsl_structs_match_the_rust_layouts() {
    let module = module();
    assert_layout!(&module, "GpuParticle", GpuParticle, [position, velocity]);
    assert_layout!(
        &module,
        "BatchCloth",
        GpuBatchCloth,
        [
            k_over_mass,
            uniform_accel,
            particle_start,
            particle_count,
            ends_start,
            substeps,
            h,
            damping,
            integrator,
            iterations,
            contact_thickness,
            contact_friction,
            free_body,
            tether_start,
            tether_scale,
            memberships,
            filters,
            faults,
            drift,
            step,
            broken,
            blend,
            pad
        ]
    );
    assert_layout!(
        &module,
        "MultigridCloth",
        GpuMultigridCloth,
        [
            levels,
            node_start,
            node_count,
            coarsest_start,
            coarsest_count,
            crossing_start,
            crossing_count,
            aggregate_start,
            dense_start,
            dense_order,
            running,
            stiff,
            blend,
            age,
            assemble,
            refactor,
            dense_ok,
            damp,
            h2,
            factored_damp,
            factored_h2,
            alpha,
            chunk_start,
            chunk_count
        ]
    );
    assert_layout!(
        &module,
        "MultigridPass",
        GpuMultigridPass,
        [
            start,
            count,
            width,
            level,
            block_words,
            share_words,
            spring_words,
            chunk_words,
            node_values,
            block_values,
            spring_values,
            chunk_values
        ]
    );
    assert_layout!(
        &module,
        "BatchFrame",
        GpuBatchFrame,
        [particle_slots, anchor_count, collider_count, dispatch_width]
    );
    let (size, members) = wgsl_layout(&module, "BatchStep");
    assert_eq!(size as usize, size_of::<GpuBatchStep>());
    assert_eq!(
        (members[0].1, members[1].1),
        (offset_of!(GpuBatchStep, substep) as u32, offset_of!(GpuBatchStep, stage) as u32)
    );
    let (size, members) = wgsl_layout(&module, "BatchWriteback");
    assert_eq!(size as usize, size_of::<GpuBatchWriteback>());
    let rust = [
        offset_of!(GpuBatchWriteback, mesh),
        offset_of!(GpuBatchWriteback, particle_start),
        offset_of!(GpuBatchWriteback, surface_start),
        offset_of!(GpuBatchWriteback, vertex_count),
        offset_of!(GpuBatchWriteback, particle_count),
        offset_of!(GpuBatchWriteback, group_first),
    ];
    assert_eq!(members[..6].iter().map(|m| m.1 as usize).collect::<Vec<_>>(), rust, "members of BatchWriteback");
    assert_layout!(&module, "ColourPass", GpuColourPass, [start, count, iteration, dispatch_width]);
    assert_layout!(
        &module,
        "ContactFrame",
        GpuContactFrame,
        [
            triangle_count,
            buckets,
            blocks,
            entry_capacity,
            inv_cell,
            grow,
            dispatch_width,
            particle_slots,
            edge_count,
            cloth_slots,
            pad_a,
            pad_b
        ]
    );
    assert_layout!(&module, "WritebackGroup", GpuWritebackGroup, [first_owner, vertex_count, dispatch_width, pad]);
    assert_layout!(
        &module,
        "GpuCollider",
        GpuCollider,
        [
            local_from_world,
            world_from_local,
            rotation,
            margin_local,
            friction,
            node_offset,
            sphere_offset,
            node_count,
            sphere_count,
            contact_reach,
            shape,
            size,
            memberships,
            filters,
            pad
        ]
    );
    assert_layout!(&module, "BvhNode", BvhNode, [aabb_min, left, aabb_max, right]);
    assert_layout!(
        &module,
        "AirCloth",
        GpuAirCloth,
        [
            surface_start,
            vertex_count,
            seed,
            source_count,
            turbulence,
            inv_scale,
            drag,
            lift,
            triangle_start,
            triangle_count
        ]
    );
    assert_layout!(&module, "WindSource", AirSource, [origin, axis, reach]);
    assert_layout!(
        &module,
        "GpuMeshWriteback",
        GpuMeshWriteback,
        [local_from_world, normal_from_world, first_word, stride_words, position_word, normal_word]
    );
    assert_layout!(
        &module,
        "RefitParams",
        GpuRefitParams,
        [vertex_count, leaf_count, node_offset, sphere_offset, level_start, level_count, collider, clearance]
    );
    let (size, members) = wgsl_layout(&module, "GpuSkinVertex");
    assert_eq!(size as usize, size_of::<GpuSkinVertex>(), "size of GpuSkinVertex");
    let rust = [
        ("position", offset_of!(GpuSkinVertex, position)),
        ("joints_low", offset_of!(GpuSkinVertex, joints_low)),
        ("weights", offset_of!(GpuSkinVertex, weights)),
        ("joints_high", offset_of!(GpuSkinVertex, joints_high)),
    ];
    assert_eq!(
        members.iter().map(|(n, o)| (n.as_str(), *o as usize)).collect::<Vec<_>>(),
        rust,
        "members of GpuSkinVertex (the Rust struct's padding ends it)"
    );
    // A point: three vertex indices, then two barycentric weights.
    let (size, members) = wgsl_layout(&module, "SkinPoint");
    assert_eq!(size as usize, size_of::<SkinPoint>());
    assert_eq!(members.iter().map(|m| m.1 as usize).collect::<Vec<_>>(), [0, 4, 8, 12, 16]);
    assert_eq!((offset_of!(SkinPoint, vertices), offset_of!(SkinPoint, weights)), (0, 12));
    // Nodes and spheres share one array of vec4<f32>: a node is two (box minimum and left
    // child, box maximum and right child), a sphere one (centre and radius).
    assert_eq!(size_of::<BvhNode>(), 32);
    assert_eq!(size_of::<Sphere>(), 16);
    assert_eq!((offset_of!(Sphere, center), offset_of!(Sphere, radius)), (0, 12));
}

/// Every struct a kernel reads as an array member is a multiple of 16 bytes, the alignment of the
/// `vec4` members WGSL lays out, and the host's part of a batch cloth ends where the kernels'
/// fault counter begins.
#[test]
fn sizes_are_multiples_of_sixteen() {
    assert_eq!(size_of::<GpuParticle>(), 32);
    assert_eq!(size_of::<GpuBatchCloth>(), 128);
    assert_eq!(size_of::<GpuMultigridCloth>(), 96);
    assert_eq!(size_of::<GpuMultigridPass>(), 48);
    assert_eq!(size_of::<GpuColourPass>(), 16);
    assert_eq!(size_of::<GpuContactFrame>(), 48);
    assert_eq!(offset_of!(GpuBatchCloth, faults) as u64, GpuBatchCloth::HOST_BYTES);
    assert_eq!(size_of::<GpuBatchFrame>(), 16);
    assert_eq!(size_of::<GpuBatchStep>(), 16);
    assert_eq!(size_of::<GpuBatchWriteback>(), 176);
    assert_eq!(size_of::<GpuWritebackGroup>(), 16);
    assert_eq!(size_of::<GpuCollider>(), 208);
    assert_eq!(size_of::<GpuMeshWriteback>(), 144);
}

/// The constants the kernels share with the core are written from the Rust side: no shader file
/// defines one of them by hand, each file that uses one imports it from `bvh_cloth::constants`,
/// and every one of them is used.
#[test]
fn shared_constants_are_written_once_from_the_core() {
    let generated = bvh_cloth_gpu::shared_constants();
    assert!(generated.starts_with("#define_import_path bvh_cloth::constants"));
    let names: Vec<&str> =
        generated.lines().filter_map(|l| l.strip_prefix("const ")).map(|l| l.split(':').next().unwrap()).collect();
    assert!(names.len() >= 20, "{names:?}");
    let word = |text: &str, name: &str| {
        text.match_indices(name).any(|(at, _)| {
            let before = text[..at].chars().last().is_none_or(|c| !(c.is_alphanumeric() || c == '_'));
            let after = text[at + name.len()..].chars().next().is_none_or(|c| !(c.is_alphanumeric() || c == '_'));
            before && after
        })
    };
    for name in &names {
        let mut used = false;
        for (file, text) in SHADER_FILES {
            assert!(!text.contains(&format!("const {name}:")), "{file} defines {name} by hand");
            let code: String = text
                .lines()
                .filter(|l| !l.starts_with("#import"))
                .map(|l| l.split("//").next().unwrap())
                .collect::<Vec<_>>()
                .join("\n");
            if word(&code, name) {
                used = true;
                let imports = text.lines().find(|l| l.starts_with("#import bvh_cloth::constants::{"));
                assert!(imports.is_some_and(|l| word(l, name)), "{file} uses {name} without importing it");
            }
        }
        assert!(used, "{name} is written but no kernel uses it");
    }
}

#[test]
fn shared_constants_match_the_core() {
    let source = shader_source();
    let constant = |name: &str| -> String {
        let line = source.lines().find(|l| l.starts_with(&format!("const {name}:"))).unwrap();
        line.split('=').nth(1).unwrap().split(';').next().unwrap().trim().to_string()
    };
    assert_eq!(constant("STACK_SIZE"), format!("{}u", bvh_cloth_core::backend::STACK_SIZE));
    assert_eq!(constant("MAX_PASSES"), format!("{}u", bvh_cloth_core::backend::MAX_PASSES));
    assert_eq!(constant("LEAF_BIT"), format!("{:#x}u", bvh_cloth_core::backend::LEAF_BIT));
    assert_eq!(constant("SURFACE_TOLERANCE").parse::<f32>().unwrap(), bvh_cloth_core::backend::SURFACE_TOLERANCE);
    assert_eq!(constant("CONTACT_BAND").parse::<f32>().unwrap(), bvh_cloth_core::backend::CONTACT_BAND);
    assert_eq!(constant("LOOKOUT_ROUNDING").parse::<f32>().unwrap(), bvh_cloth_core::backend::LOOKOUT_ROUNDING);
    assert_eq!(constant("NO_CLOTH"), format!("{:#x}u", bvh_cloth_gpu::layout::NO_CLOTH));
    assert_eq!(constant("UNTETHERED"), format!("{:#x}u", bvh_cloth_core::backend::UNTETHERED));
    assert_eq!(constant("SHAPE_SPHERES"), format!("{}u", bvh_cloth_gpu::layout::SHAPE_SPHERES));
    assert_eq!(constant("SHAPE_TRIANGLES"), format!("{}u", bvh_cloth_gpu::layout::SHAPE_TRIANGLES));
    assert_eq!(constant("EDGE_SLACK").parse::<f32>().unwrap(), bvh_cloth_core::backend::EDGE_SLACK);
    assert_eq!(constant("PLANE_ROUNDING").parse::<f32>().unwrap(), bvh_cloth_core::backend::PLANE_ROUNDING);
    use bvh_cloth_core::Primitive;
    let shapes = [
        ("SHAPE_SPHERE", Primitive::Sphere { radius: 1.0 }),
        ("SHAPE_CAPSULE", Primitive::Capsule { radius: 1.0, half_length: 1.0 }),
        ("SHAPE_CUBOID", Primitive::Cuboid { half_extents: Vec3::ONE }),
        ("SHAPE_HALF_SPACE", Primitive::HalfSpace { normal: Vec3::Y }),
    ];
    for (name, shape) in shapes {
        assert_eq!(constant(name), format!("{}u", shape.kind()), "{name}");
    }
    assert_eq!(constant("SWEEP_STEPS"), format!("{}u", bvh_cloth_core::backend::SWEEP_STEPS));
    assert_eq!(constant("CLOSEST_STEPS"), format!("{}u", bvh_cloth_core::backend::CLOSEST_STEPS));
    assert_eq!(constant("NOISE_TIME_PERIOD"), format!("{}u", bvh_cloth_core::backend::NOISE_TIME_PERIOD));
    assert_eq!(constant("SOURCE_FAN").parse::<f32>().unwrap(), bvh_cloth_core::backend::SOURCE_FAN as f32);
    assert_eq!(constant("INTEGRATOR_EULER"), format!("{}u", bvh_cloth_gpu::layout::INTEGRATOR_EULER));
    assert_eq!(constant("INTEGRATOR_BLOCK_DESCENT"), format!("{}u", bvh_cloth_gpu::layout::INTEGRATOR_BLOCK_DESCENT));
}

/// Each kernel file names its import path or imports as naga_oil reads them, so that an engine
/// composing shaders that way (Bevy's shader assets) can load the files as they are.
#[test]
fn every_file_declares_what_it_imports() {
    for (name, text) in SHADER_FILES {
        let imports: Vec<&str> = text.lines().filter(|l| l.starts_with("#import")).collect();
        if name == "types.wgsl" {
            assert!(text.contains("#define_import_path bvh_cloth::types"), "{name}");
            assert!(imports.is_empty(), "{name} imports nothing");
        } else {
            assert!(
                imports.iter().any(|i| i.starts_with("#import bvh_cloth::types::{")),
                "{name} imports the shared types"
            );
        }
    }
}

/// The triangles' neighbours the untangling's union-find joins across: on a 4 x 3 grid (12
/// triangles), numbered from 100, each neighbour is mutual and shares the edge it stands for,
/// an edge on the border has none, and every triangle is reached from the first.
#[test]
fn triangle_neighbours_are_mutual_and_join_the_cloth() {
    let grid = bvh_cloth_core::ClothGrid::new(bvh_cloth_core::Vec2::ONE, bvh_cloth_core::UVec2::new(4, 3));
    let topology = bvh_cloth_core::ClothTopology::grid(grid).unwrap();
    let triangles = topology.triangles();
    let neighbours = gpu_triangle_neighbours(&topology, 100);
    assert_eq!(neighbours.len(), triangles.len());
    let mut border = 0;
    for (t, (c, across)) in triangles.iter().zip(&neighbours).enumerate() {
        for (k, &u) in across.iter().enumerate() {
            if u == NO_CLOTH {
                border += 1;
                continue;
            }
            let u = (u - 100) as usize;
            let edge = [c[k], c[(k + 1) % 3]];
            assert!(edge.iter().all(|p| triangles[u].contains(p)), "triangle {t}: {u} does not share edge {k}");
            assert!(neighbours[u].contains(&(100 + t as u32)), "triangle {t}: {u} does not name it back");
        }
    }
    // The grid's border: 2 x (3 + 2) edges.
    assert_eq!(border, 10);
    let mut reached = vec![false; triangles.len()];
    let mut stack = vec![0usize];
    while let Some(t) = stack.pop() {
        if !std::mem::replace(&mut reached[t], true) {
            stack.extend(neighbours[t].iter().filter(|&&u| u != NO_CLOTH).map(|&u| (u - 100) as usize));
        }
    }
    assert!(reached.iter().all(|&r| r), "the neighbours leave part of the grid unreached");
}
