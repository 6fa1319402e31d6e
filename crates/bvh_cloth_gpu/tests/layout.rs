//! The WGSL passes naga's validation, and every struct it shares with Rust has the same size
//! and the same member offsets as the core's `#[repr(C)]` definition. Needs no GPU.

use core::mem::{offset_of, size_of};

use bvh_cloth_core::gpu_layout::{GpuClothParams, GpuCollider, GpuMeshWriteback, GpuParticle};
use bvh_cloth_core::{BvhNode, Sphere};
use bvh_cloth_gpu::SHADER_SOURCE;
use naga::valid::{Capabilities, ValidationFlags, Validator};

fn module() -> naga::Module {
    naga::front::wgsl::parse_str(SHADER_SOURCE).unwrap_or_else(|e| panic!("{}", e.emit_to_string(SHADER_SOURCE)))
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
        .unwrap_or_else(|e| panic!("{}", e.emit_to_string(SHADER_SOURCE)));
    let entry_points: Vec<&str> = module.entry_points.iter().map(|e| e.name.as_str()).collect();
    assert_eq!(entry_points, ["node_update", "collision_detection_with_bvh", "normal_shader", "apply_anchors"]);
    for entry in &module.entry_points {
        assert_eq!(entry.workgroup_size, [8, 8, 1], "{} runs 8x8x1 workgroups", entry.name);
    }
}

#[test]
fn wgsl_structs_match_the_rust_layouts() {
    let module = module();
    assert_layout!(&module, "GpuParticle", GpuParticle, [position, velocity]);
    assert_layout!(
        &module,
        "GpuClothParams",
        GpuClothParams,
        [
            particle_count,
            vertex_count,
            collider_count,
            dispatch_width,
            h,
            damping,
            anchor_count,
            _pad,
            k_over_mass,
            uniform_accel
        ]
    );
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
            _pad
        ]
    );
    assert_layout!(&module, "BvhNode", BvhNode, [aabb_min, left, aabb_max, right]);
    assert_layout!(
        &module,
        "GpuMeshWriteback",
        GpuMeshWriteback,
        [local_from_world, normal_from_world, first_word, stride_words, position_word, normal_word]
    );
    // Spheres are bound as vec4<f32>: centre and radius.
    assert_eq!(size_of::<Sphere>(), 16);
    assert_eq!((offset_of!(Sphere, center), offset_of!(Sphere, radius)), (0, 12));
}

#[test]
fn shared_constants_match_the_core() {
    let constant = |name: &str| -> String {
        let line = SHADER_SOURCE.lines().find(|l| l.starts_with(&format!("const {name}:"))).unwrap();
        line.split('=').nth(1).unwrap().split(';').next().unwrap().trim().to_string()
    };
    assert_eq!(constant("STACK_SIZE"), format!("{}u", bvh_cloth_core::traversal::STACK_SIZE));
    assert_eq!(constant("MAX_PASSES"), format!("{}u", bvh_cloth_core::collision::MAX_PASSES));
    assert_eq!(constant("LEAF_BIT"), format!("{:#x}u", bvh_cloth_core::lbvh::LEAF_BIT));
    assert_eq!(constant("SURFACE_TOLERANCE").parse::<f32>().unwrap(), bvh_cloth_core::traversal::SURFACE_TOLERANCE);
    assert_eq!(constant("CONTACT_BAND").parse::<f32>().unwrap(), bvh_cloth_core::collision::CONTACT_BAND);
}
