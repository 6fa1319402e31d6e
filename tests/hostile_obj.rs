//! The plugin's OBJ-to-collider path under hostile files: bevy_obj's loader (what an
//! `AutoCollider` on a loaded `.obj` goes through), then the mesh reader and the collider
//! builder (with exact contact, as an `AutoCollider` builds by default). Whatever the text,
//! nothing panics, and the result is a typed error or a collider whose every vertex lies inside
//! its voxel's sphere.

use bevy::mesh::{PrimitiveTopology, VertexAttributeValues};
use bevy_bvh_cloth::bvh_cloth_core::MeshRef;
use bevy_bvh_cloth::bvh_cloth_core::backend::TriangleSurface;
use bevy_bvh_cloth::bvh_cloth_core::backend::voxel_spheres;
use bevy_bvh_cloth::{ColliderFailure, collider_from_mesh};
use bevy_obj::ObjSettings;
use bevy_obj::mesh::load_obj_as_mesh;
use proptest::prelude::*;

/// A coordinate: ordinary, or a grid value (so vertices and whole triangles coincide).
fn coordinate() -> impl Strategy<Value = String> {
    prop_oneof![2 => (-5.0f32..5.0).prop_map(|v| v.to_string()), 1 => (-2i32..3).prop_map(|v| v.to_string())]
}

/// One flaw planted in a file: a line the parser or the builder must survive.
fn flaw(vertices: usize) -> impl Strategy<Value = String> {
    let n = vertices as i64;
    prop_oneof![
        Just("v 1e30 0 0".to_string()),
        Just("v 0 -3e38 0".to_string()),
        Just("v 1e-45 1e-45 1e-45".to_string()),
        Just("v nan 0 0".to_string()),
        Just("v 0 inf 0".to_string()),
        Just("v 1 2".to_string()),
        Just("f 0 1 2".to_string()),
        Just("f 1 2".to_string()),
        Just(format!("f 1 2 {}", n + 7)),
        Just(format!("f -{} 1 2", n + 3)),
        Just("f 1 2 4294967296".to_string()),
        "[ -~]{0,20}",
    ]
}

/// An OBJ file: up to 40 vertices, one normal, and up to 30 faces of 3 to 5 corners (indices
/// absolute or relative; repeats make degenerate and duplicated triangles), and in one file in
/// three a single flaw. One file in five gives every corner a normal slot (bevy_obj's parser
/// wants one corner format per file).
fn obj_text() -> impl Strategy<Value = String> {
    (1usize..40, prop::bool::weighted(0.2)).prop_flat_map(|(vertices, normals)| {
        let n = vertices as i64;
        let slot = if normals { "//1" } else { "" };
        let corner = prop_oneof![6 => 1..=n, 1 => -n..0].prop_map(move |i| format!("{i}{slot}"));
        let v_lines = prop::collection::vec([coordinate(), coordinate(), coordinate()], vertices)
            .prop_map(|vs| vs.into_iter().map(|[x, y, z]| format!("v {x} {y} {z}")).collect::<Vec<_>>());
        let f_lines = prop::collection::vec(prop::collection::vec(corner, 3..6), 0..30)
            .prop_map(|fs| fs.into_iter().map(|f| format!("f {}", f.join(" "))).collect::<Vec<_>>());
        let flaw = prop::option::weighted(0.33, flaw(vertices)).prop_map(|f| f.into_iter().collect::<Vec<_>>());
        let normal = vec!["vn 0 0 1".to_string()];
        (v_lines, f_lines, flaw).prop_map(move |(v, f, flaw)| [v, normal.clone(), f, flaw].concat().join("\n"))
    })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]

    #[test]
    fn hostile_obj_files_give_an_error_or_a_sound_collider(text in obj_text(), n in 0u32..12) {
        let Ok(mesh) = load_obj_as_mesh(text.as_bytes(), &ObjSettings::default()) else {
            return Ok(()); // bevy_obj refused the file: the asset fails to load, the collider reports it
        };
        match collider_from_mesh(&mesh, n) {
            Ok(collider) => {
                prop_assert_eq!(collider.lbvh().expect("a mesh collider").nodes.len() + 1, collider.lbvh().expect("a mesh collider").spheres.len());
                // Every vertex a triangle uses lies inside its voxel's sphere.
                let positions = match mesh.attribute(bevy::mesh::Mesh::ATTRIBUTE_POSITION) {
                    Some(bevy::mesh::VertexAttributeValues::Float32x3(p)) => p.clone(),
                    _ => unreachable!("the collider was built from Float32x3 positions"),
                };
                let indices: Vec<u32> = mesh.indices().map(|i| i.iter().map(|i| i as u32).collect()).unwrap_or_default();
                let voxels = voxel_spheres(MeshRef { positions: &positions, indices: Some(&indices) }, n).unwrap();
                for &i in &indices {
                    let p = bevy::math::Vec3::from(positions[i as usize]);
                    let sphere = voxels.sphere_of(p).expect("a used vertex's voxel has a sphere");
                    prop_assert!(p.distance(sphere.centre()) <= sphere.radius, "vertex {} outside its sphere", i);
                }
            }
            Err(failure) => {
                // The reason is true of the mesh: a plugin-level one holds, and a builder error is
                // the core's own verdict on the same data (whose truth the core's fuzz test checks).
                let positions = mesh.attribute(bevy::mesh::Mesh::ATTRIBUTE_POSITION);
                match failure {
                    ColliderFailure::NotTriangles(topology) => {
                        prop_assert!(topology == mesh.primitive_topology() && topology != PrimitiveTopology::TriangleList);
                    }
                    ColliderFailure::NoPositions => prop_assert!(positions.is_none()),
                    ColliderFailure::PositionsNotFloat3 => {
                        prop_assert!(!matches!(positions, Some(VertexAttributeValues::Float32x3(_))));
                    }
                    ColliderFailure::Rejected(error) => {
                        let Some(VertexAttributeValues::Float32x3(positions)) = positions else {
                            return Err(TestCaseError::fail("a builder error needs Float32x3 positions"));
                        };
                        let indices: Option<Vec<u32>> = mesh.indices().map(|i| i.iter().map(|i| i as u32).collect());
                        // The voxel spheres first, then the triangle surface of exact contact.
                        let mesh = MeshRef { positions, indices: indices.as_deref() };
                        let core = voxel_spheres(mesh, n).map(drop).and_then(|()| TriangleSurface::build(mesh).map(drop));
                        prop_assert_eq!(core.err(), Some(error));
                    }
                    other => prop_assert!(false, "{:?} cannot happen to a loaded mesh on an unscaled entity", other),
                }
            }
        }
    }
}
