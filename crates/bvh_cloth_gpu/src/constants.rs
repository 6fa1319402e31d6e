//! The constants the kernels share with the core, written into a WGSL module from the Rust
//! side ([`shared_constants`]), so that no value is copied into a shader by hand.

use bvh_cloth_core::Primitive;
use bvh_cloth_core::{aerodynamics, collision, exact_contact, gpu_layout, lbvh, primitives, self_contact, tethers};
use bvh_cloth_core::{traversal, triangles};

/// The name of the constants' module among the shader files: `#define_import_path
/// bvh_cloth::constants`.
pub const CONSTANTS_FILE: &str = "constants.wgsl";

/// A WGSL constant's value.
enum Value {
    U32(u32),
    I32(i32),
    F32(f32),
}

/// The shared constants, by their WGSL names.
fn values() -> Vec<(&'static str, Value)> {
    use Value::{F32, I32, U32};
    let kind = |shape: Primitive| U32(shape.kind());
    vec![
        ("NO_CLOTH", U32(gpu_layout::NO_CLOTH)),
        ("UNTETHERED", U32(tethers::UNTETHERED)),
        ("INTEGRATOR_EULER", U32(gpu_layout::INTEGRATOR_EULER)),
        ("INTEGRATOR_BLOCK_DESCENT", U32(gpu_layout::INTEGRATOR_BLOCK_DESCENT)),
        ("SHAPE_SPHERES", U32(gpu_layout::SHAPE_SPHERES)),
        ("SHAPE_TRIANGLES", U32(gpu_layout::SHAPE_TRIANGLES)),
        ("SHAPE_SPHERE", kind(Primitive::Sphere { radius: 1.0 })),
        ("SHAPE_CAPSULE", kind(Primitive::Capsule { radius: 1.0, half_length: 1.0 })),
        ("SHAPE_CUBOID", kind(Primitive::Cuboid { half_extents: bvh_cloth_core::Vec3::ONE })),
        ("SHAPE_HALF_SPACE", kind(Primitive::HalfSpace { normal: bvh_cloth_core::Vec3::Y })),
        ("LEAF_BIT", U32(lbvh::LEAF_BIT)),
        ("STACK_SIZE", U32(traversal::STACK_SIZE as u32)),
        ("SURFACE_TOLERANCE", F32(traversal::SURFACE_TOLERANCE)),
        ("CONTACT_BAND", F32(collision::CONTACT_BAND)),
        ("MAX_PASSES", U32(collision::MAX_PASSES as u32)),
        ("LOOKOUT_ROUNDING", F32(exact_contact::LOOKOUT_ROUNDING)),
        ("EDGE_SLACK", F32(triangles::EDGE_SLACK)),
        ("PLANE_ROUNDING", F32(triangles::PLANE_ROUNDING)),
        ("SWEEP_STEPS", U32(primitives::SWEEP_STEPS)),
        ("CLOSEST_STEPS", U32(primitives::CLOSEST_STEPS)),
        ("NOISE_TIME_PERIOD", U32(aerodynamics::NOISE_TIME_PERIOD)),
        ("SOURCE_FAN", F32(aerodynamics::SOURCE_FAN as f32)),
        ("MAX_CANDIDATES", U32(self_contact::MAX_CANDIDATES as u32)),
        ("MAX_SPAN", I32(self_contact::MAX_SPAN)),
        ("MAX_HELD_SCALE", F32(self_contact::MAX_HELD_SCALE)),
        ("CONTACT_TRIANGLE_WORDS", U32(gpu_layout::CONTACT_TRIANGLE_WORDS as u32)),
    ]
}

/// The WGSL module of the constants the kernels share with the core, each written from the
/// core's own value (an `f32` in the shortest form that reads back to the same bits).
pub fn shared_constants() -> String {
    let mut source = String::from(
        "#define_import_path bvh_cloth::constants\n\n// Written by bvh_cloth_gpu::shared_constants from the core's values.\n",
    );
    for (name, value) in values() {
        let (ty, literal) = match value {
            // Bit patterns (`LEAF_BIT`, `NO_CLOTH`) read better in hexadecimal.
            Value::U32(v) if v >= 1 << 16 => ("u32", format!("{v:#x}u")),
            Value::U32(v) => ("u32", format!("{v}u")),
            Value::I32(v) => ("i32", format!("{v}i")),
            Value::F32(v) => ("f32", format!("{v:?}")),
        };
        source.push_str(&format!("const {name}: {ty} = {literal};\n"));
    }
    source
}
