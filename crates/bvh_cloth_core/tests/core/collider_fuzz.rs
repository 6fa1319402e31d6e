//! Property test: arbitrary meshes never make the collider builder panic, and on success every
//! vertex and every sampled point of every triangle lies inside the sphere of its voxel, and the
//! tree is sound. Then the named extremes: a
//! single point, and millions of coincident vertices.

use bvh_cloth_core::MeshRef;

use bvh_cloth_core::backend::SURFACE_CLEARANCE;

use bvh_cloth_core::backend::voxel_spheres;
use bvh_cloth_core::{Collider, ColliderError, Vec3};
use proptest::prelude::*;

/// Any float at all: NaN, infinities, 1e30, subnormals.
fn hostile_coordinate() -> impl Strategy<Value = f32> {
    prop_oneof![
        prop::num::f32::ANY,
        Just(1.0e30f32),
        Just(-1.0e17f32),
        Just(f32::NAN),
        Just(f32::INFINITY),
        Just(0.0f32),
    ]
}

/// Vertex positions: a clean cloud (sometimes on a grid, so vertices and whole triangles
/// coincide), and now and then one hostile coordinate planted in it.
fn positions() -> impl Strategy<Value = Vec<[f32; 3]>> {
    let clean = prop_oneof![
        3 => -10.0f32..10.0,
        1 => (-3i32..3).prop_map(|v| v as f32),
    ];
    (
        prop::collection::vec([clean.clone(), clean.clone(), clean], 0..60),
        prop::option::weighted(0.25, (any::<prop::sample::Index>(), 0usize..3, hostile_coordinate())),
    )
        .prop_map(|(mut positions, corruption)| {
            if let (Some((slot, axis, value)), false) = (corruption, positions.is_empty()) {
                let vertex = slot.index(positions.len());
                positions[vertex][axis] = value;
            }
            positions
        })
}

fn mesh() -> impl Strategy<Value = (Vec<[f32; 3]>, Option<Vec<u32>>)> {
    positions().prop_flat_map(|positions| {
        // Indices in range, now and then one past the end; absent for a triangle soup.
        let n = positions.len() as u32;
        let triangles = prop::collection::vec([0..n.max(1), 0..n.max(1), 0..n.max(1)], 0..30);
        let flaw = prop::option::weighted(0.15, (any::<bool>(), any::<prop::sample::Index>()));
        let indices = (triangles, flaw).prop_map(move |(triangles, flaw)| {
            let mut idx: Vec<u32> = triangles.into_iter().flatten().collect();
            match (flaw, idx.is_empty()) {
                // One index past the end.
                (Some((true, slot)), false) => {
                    let position = slot.index(idx.len());
                    idx[position] = n;
                }
                // A partial triangle.
                (Some((false, _)), false) => {
                    idx.pop();
                }
                _ => {}
            }
            idx
        });
        (Just(positions), prop::option::weighted(0.8, indices))
    })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]

    #[test]
    fn arbitrary_meshes_build_or_fail_cleanly((positions, indices) in mesh(), n in 0u32..40) {
        let mesh = MeshRef { positions: &positions, indices: indices.as_deref() };
        match voxel_spheres(mesh, n) {
            Ok(voxels) => {
                let used: Vec<usize> = match &indices {
                    Some(idx) => idx.iter().map(|&i| i as usize).collect(),
                    None => (0..positions.len()).collect(),
                };
                for i in used {
                    let p = Vec3::from(positions[i]);
                    let s = voxels.sphere_of(p).expect("a vertex's voxel has a sphere");
                    prop_assert!(p.distance(s.centre()) <= s.radius, "vertex {} outside its sphere", i);
                }
                // The surface, not only the vertices: points inside each triangle lie in a
                // sphere with the clearance to spare, up to rounding relative to the mesh's size.
                // (In some sphere, not necessarily their own voxel's: a point exactly on a voxel
                // corner may be numbered into a voxel the triangle only touches there.)
                let extent = voxels.mesh_max - voxels.mesh_min;
                let tolerance = 1e-5 * extent.max_element();
                let clearance = SURFACE_CLEARANCE * (extent / n as f32).length();
                let corner = |t: usize, k: usize| {
                    Vec3::from(positions[indices.as_ref().map_or(3 * t + k, |idx| idx[3 * t + k] as usize)])
                };
                let triangles = indices.as_ref().map_or(positions.len(), |idx| idx.len()) / 3;
                for t in 0..triangles {
                    let [a, b, c] = [0, 1, 2].map(|k| corner(t, k));
                    for p in [(a + b + c) / 3.0, (a + b) / 2.0, (b + c) / 2.0, (a + c) / 2.0] {
                        let covered = voxels
                            .spheres
                            .iter()
                            .any(|s| p.distance(s.centre()) <= s.radius - clearance + tolerance);
                        prop_assert!(covered, "triangle {}: {} is in no sphere", t, p);
                    }
                }
                let collider = Collider::from_mesh(mesh, n).unwrap();
                prop_assert_eq!(collider.lbvh().expect("a mesh collider").spheres.len(), voxels.spheres.len());
                prop_assert_eq!(collider.lbvh().expect("a mesh collider").nodes.len(), voxels.spheres.len() - 1);
            }
            Err(e) => {
                // Every error names something that is really wrong with the input.
                prop_assert!(error_holds(&e, &positions, indices.as_deref(), n), "{:?} is not true of the input", e);
                prop_assert_eq!(Collider::from_mesh(mesh, n).unwrap_err(), e);
            }
        }
    }
}

#[test]
fn a_single_point_is_a_typed_error() {
    let point = [[1.0, 2.0, 3.0]];
    let alone = MeshRef { positions: &point, indices: None };
    assert_eq!(Collider::from_mesh(alone, 5).unwrap_err(), ColliderError::VerticesNotTriangles { vertices: 1 });
    let repeated = MeshRef { positions: &point, indices: Some(&[0, 0, 0]) };
    assert_eq!(Collider::from_mesh(repeated, 5).unwrap_err(), ColliderError::ZeroExtent);
}

/// Three million vertices on one point: refused as having no extent; with one real triangle
/// beside them, a valid tree whose coincident vertices all share one point-sized sphere, and
/// whose other spheres cover the triangle.
#[test]
fn millions_of_coincident_vertices_build_or_fail_cleanly() {
    const VERTICES: usize = 3_000_000;
    let mut positions = vec![[0.25f32, 0.5, 0.75]; VERTICES];
    let indices: Vec<u32> = (0..VERTICES as u32).collect();
    let mesh = MeshRef { positions: &positions, indices: Some(&indices) };
    assert_eq!(Collider::from_mesh(mesh, 32).unwrap_err(), ColliderError::ZeroExtent);
    assert_eq!(
        Collider::from_mesh(MeshRef { positions: &positions, indices: None }, 32).unwrap_err(),
        ColliderError::ZeroExtent
    );

    positions.extend([[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 1.0]]);
    let indices: Vec<u32> = (0..positions.len() as u32).collect();
    let mesh = MeshRef { positions: &positions, indices: Some(&indices) };
    let voxels = voxel_spheres(mesh, 32).unwrap();
    let shared = voxels.sphere_of(Vec3::from(positions[0])).expect("the point's voxel has a sphere");
    assert!(Vec3::from(positions[0]).distance(shared.centre()) <= shared.radius);
    // Point-sized: only the clearance every sphere reaches past the surface.
    let clearance = SURFACE_CLEARANCE * ((voxels.mesh_max - voxels.mesh_min) / 32.0).length();
    assert!(shared.radius <= clearance * 1.0001, "{shared:?}");
    let [a, b, c] = [VERTICES, VERTICES + 1, VERTICES + 2].map(|i| Vec3::from(positions[i]));
    for (u, v) in [(0.0, 0.0), (0.5, 0.0), (0.0, 0.5), (0.5, 0.5), (0.3, 0.3), (0.9, 0.05)] {
        let p = a + u * (b - a) + v * (c - a);
        let s = voxels.sphere_of(p).expect("the triangle's voxels have spheres");
        assert!(p.distance(s.centre()) <= s.radius + 1e-6, "{p} is outside its voxel's sphere");
    }
    let collider = Collider::from_mesh(mesh, 32).unwrap();
    assert_eq!(
        collider.lbvh().expect("a mesh collider").nodes.len(),
        collider.lbvh().expect("a mesh collider").spheres.len() - 1
    );
}

/// Whether what `error` says of a mesh (`positions`, `indices`) voxelised at `n` is true of it.
fn error_holds(error: &ColliderError, positions: &[[f32; 3]], indices: Option<&[u32]>, n: u32) -> bool {
    let used: Vec<u32> = indices.map_or_else(|| (0..positions.len() as u32).collect(), <[u32]>::to_vec);
    let used_points = || used.iter().filter_map(|&i| positions.get(i as usize)).map(|&p| Vec3::from(p));
    match *error {
        ColliderError::EmptyMesh => positions.is_empty(),
        ColliderError::NoTriangles => used.is_empty(),
        ColliderError::IndicesNotTriangles { len } => indices.is_some_and(|i| i.len() == len) && len % 3 != 0,
        ColliderError::VerticesNotTriangles { vertices } => {
            indices.is_none() && vertices == positions.len() && vertices % 3 != 0
        }
        ColliderError::NonFiniteVertex { vertex } => positions.get(vertex).is_some_and(|&p| !Vec3::from(p).is_finite()),
        ColliderError::VertexTooFar { vertex, limit } => {
            positions.get(vertex).is_some_and(|&p| Vec3::from(p).abs().max_element() > limit)
        }
        ColliderError::IndexOutOfRange { position, index, vertices } => {
            indices.and_then(|i| i.get(position)) == Some(&index)
                && vertices == positions.len()
                && index as usize >= vertices
        }
        ColliderError::ZeroExtent => {
            let first = used_points().next();
            first.is_some_and(|f| used_points().all(|p| p == f))
        }
        ColliderError::ZeroResolution => n == 0,
        ColliderError::ResolutionTooHigh { n: asked, max } => asked == n && n > max,
        // The property test's meshes are far too small to run out of memory.
        ColliderError::OutOfMemory { .. } => false,
        // The property test gives counts, not sizes, and a mesh is never a primitive.
        ColliderError::BadVoxelSize(_) | ColliderError::TooManyVoxels { .. } | ColliderError::BadPrimitive(_) => false,
        // The property test builds with sphere contact only.
        ColliderError::NoArea | ColliderError::ExactMeshMismatch | ColliderError::TooManyTriangles { .. } => false,
        // Nor is it skinned.
        ColliderError::SkinLength { .. }
        | ColliderError::BadSkinWeights { .. }
        | ColliderError::JointOutOfRange { .. }
        | ColliderError::MissingJoints { .. }
        | ColliderError::NonFiniteJoint { .. }
        | ColliderError::SkinTreeMismatch { .. } => false,
    }
}
