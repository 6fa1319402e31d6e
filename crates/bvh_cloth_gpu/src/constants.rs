//! The constants the kernels share with the core, written into a WGSL module from the Rust
//! side ([`shared_constants`]), so that no value is copied into a shader by hand.

use bvh_cloth_core::Primitive;
use bvh_cloth_core::backend as core;

use crate::layout;

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
        ("NO_CLOTH", U32(layout::NO_CLOTH)),
        ("UNTETHERED", U32(core::UNTETHERED)),
        ("INTEGRATOR_EULER", U32(layout::INTEGRATOR_EULER)),
        ("INTEGRATOR_BLOCK_DESCENT", U32(layout::INTEGRATOR_BLOCK_DESCENT)),
        ("INTEGRATOR_MULTIGRID", U32(layout::INTEGRATOR_MULTIGRID)),
        ("SHAPE_SPHERES", U32(layout::SHAPE_SPHERES)),
        ("SHAPE_TRIANGLES", U32(layout::SHAPE_TRIANGLES)),
        ("SHAPE_SPHERE", kind(Primitive::Sphere { radius: 1.0 })),
        ("SHAPE_CAPSULE", kind(Primitive::Capsule { radius: 1.0, half_length: 1.0 })),
        ("SHAPE_CUBOID", kind(Primitive::Cuboid { half_extents: bvh_cloth_core::Vec3::ONE })),
        ("SHAPE_HALF_SPACE", kind(Primitive::HalfSpace { normal: bvh_cloth_core::Vec3::Y })),
        ("LEAF_BIT", U32(core::LEAF_BIT)),
        ("STACK_SIZE", U32(core::STACK_SIZE as u32)),
        ("SURFACE_TOLERANCE", F32(core::SURFACE_TOLERANCE)),
        ("CONTACT_BAND", F32(core::CONTACT_BAND)),
        ("MAX_PASSES", U32(core::MAX_PASSES as u32)),
        ("LOOKOUT_ROUNDING", F32(core::LOOKOUT_ROUNDING)),
        ("EDGE_SLACK", F32(core::EDGE_SLACK)),
        ("PLANE_ROUNDING", F32(core::PLANE_ROUNDING)),
        ("SWEEP_STEPS", U32(core::SWEEP_STEPS)),
        ("CLOSEST_STEPS", U32(core::CLOSEST_STEPS)),
        ("NOISE_TIME_PERIOD", U32(core::NOISE_TIME_PERIOD)),
        ("SOURCE_FAN", F32(core::SOURCE_FAN as f32)),
        ("MAX_CANDIDATES", U32(core::MAX_CANDIDATES as u32)),
        ("MAX_SPAN", I32(core::MAX_SPAN)),
        ("MAX_PATH_SPAN", I32(core::MAX_PATH_SPAN)),
        ("MAX_HELD_SCALE", F32(core::MAX_HELD_SCALE)),
        ("UNTANGLE_EVERY", U32(core::UNTANGLE_EVERY)),
        ("CONTACT_TRIANGLE_WORDS", U32(layout::CONTACT_TRIANGLE_WORDS as u32)),
        ("NO_CORNER", U32(layout::NO_CORNER)),
        ("NO_NODE", U32(core::NO_NODE)),
        ("REASSEMBLE_EVERY", U32(core::REASSEMBLE_EVERY)),
        ("STALE_CURVATURE", F32(core::STALE_CURVATURE as f32)),
        ("JACOBI_WEIGHT", F32(core::JACOBI_WEIGHT)),
        ("BLEND_LAG", F32(core::BLEND_LAG)),
        ("BLEND_STEP", F32(core::BLEND_STEP)),
        ("COARSEST_SMOOTHING", U32(core::COARSEST_SMOOTHING)),
        ("DENSE_ORDER", U32(3 * core::DENSE_NODES as u32)),
        ("MULTIGRID_NODE_WORDS", U32(layout::MULTIGRID_NODE_WORDS)),
        ("MULTIGRID_NODE_VALUES", U32(layout::MULTIGRID_NODE_VALUES)),
        ("MULTIGRID_SPRING_VALUES", U32(layout::MULTIGRID_SPRING_VALUES)),
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
