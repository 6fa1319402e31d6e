//! Shared fixtures for the core's integration tests.
#![allow(missing_docs)]
#![allow(dead_code)]

use std::sync::Arc;

use bvh_cloth_core::{ClothGrid, ClothTopology, Collider, Lbvh, ObjMesh, Sphere, UVec2, Vec2, Vec3, parse_obj};

/// A small deterministic xorshift generator, so tests need no RNG crate and never flake.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Self(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }

    pub fn next_u64(&mut self) -> u64 {
        let mut x = self.0;
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        self.0 = x;
        x
    }

    /// Uniform in `[lo, hi)`.
    pub fn range(&mut self, lo: f32, hi: f32) -> f32 {
        let unit = (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32;
        lo + (hi - lo) * unit
    }

    pub fn vec3(&mut self, lo: f32, hi: f32) -> Vec3 {
        Vec3::new(self.range(lo, hi), self.range(lo, hi), self.range(lo, hi))
    }
}

/// A UV sphere mesh of radius `r` around `centre`.
pub fn uv_sphere(centre: Vec3, r: f32, stacks: u32, slices: u32) -> (Vec<[f32; 3]>, Vec<u32>) {
    let mut positions = Vec::new();
    for i in 0..=stacks {
        let theta = core::f32::consts::PI * i as f32 / stacks as f32;
        for j in 0..slices {
            let phi = core::f32::consts::TAU * j as f32 / slices as f32;
            let p = centre + r * Vec3::new(theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin());
            positions.push(p.to_array());
        }
    }
    let mut indices = Vec::new();
    for i in 0..stacks {
        for j in 0..slices {
            let a = i * slices + j;
            let b = i * slices + (j + 1) % slices;
            let (c, d) = (a + slices, b + slices);
            indices.extend_from_slice(&[a, c, b, b, c, d]);
        }
    }
    (positions, indices)
}

/// A collider made of the given spheres directly (no voxelisation).
pub fn sphere_collider(spheres: &[Sphere]) -> Collider {
    let shape = bvh_cloth_core::ColliderShape::Spheres {
        lbvh: Lbvh::build(spheres).into(),
        counts: bvh_cloth_core::UVec3::ONE,
        skin: None,
        surface: None,
    };
    Collider { shape, margin: 0.0, friction: 0.0, pose: Default::default(), layers: Default::default() }
}

/// A square grid `size` metres wide of `cols x rows` particles (square cells, as the paper's).
pub fn square_grid(size: f32, cols: u32, rows: u32) -> ClothGrid {
    let depth = size * (rows - 1) as f32 / (cols - 1) as f32;
    ClothGrid::new(Vec2::new(size, depth), UVec2::new(cols, rows))
}

/// The grid topology of [`square_grid`].
pub fn grid_topology(size: f32, cols: u32, rows: u32) -> Arc<ClothTopology> {
    Arc::new(ClothTopology::grid(square_grid(size, cols, rows)).unwrap())
}

/// A closed box `[lo, hi]` as twelve triangles.
pub fn box_mesh(lo: Vec3, hi: Vec3, positions: &mut Vec<[f32; 3]>, indices: &mut Vec<u32>) {
    let base = positions.len() as u32;
    for i in 0..8u32 {
        let pick = |bit: u32, axis: usize| if i & bit != 0 { hi[axis] } else { lo[axis] };
        positions.push([pick(1, 0), pick(2, 1), pick(4, 2)]);
    }
    let faces = [
        [0, 1, 3, 0, 3, 2],
        [4, 6, 7, 4, 7, 5],
        [0, 4, 5, 0, 5, 1],
        [2, 3, 7, 2, 7, 6],
        [0, 2, 6, 0, 6, 4],
        [1, 5, 7, 1, 7, 3],
    ];
    indices.extend(faces.iter().flatten().map(|&k| base + k));
}

/// A torus lying flat in the XZ plane around the origin: major radius `major`, tube radius
/// `minor`, `rings` rings of `sides` vertices.
pub fn torus(major: f32, minor: f32, rings: u32, sides: u32) -> (Vec<[f32; 3]>, Vec<u32>) {
    let mut positions = Vec::new();
    for i in 0..rings {
        let u = core::f32::consts::TAU * i as f32 / rings as f32;
        for j in 0..sides {
            let v = core::f32::consts::TAU * j as f32 / sides as f32;
            let r = major + minor * v.cos();
            positions.push([r * u.cos(), minor * v.sin(), r * u.sin()]);
        }
    }
    let mut indices = Vec::new();
    for i in 0..rings {
        for j in 0..sides {
            let at = |a: u32, b: u32| (a % rings) * sides + b % sides;
            let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i, j + 1), at(i + 1, j + 1));
            indices.extend_from_slice(&[a, b, c, c, b, d]);
        }
    }
    (positions, indices)
}

/// A 1 m square sheet of `side x side` vertices as an authored mesh (its first row on the x
/// axis, so that a tiny offset from it is representable), with a sliver "ear" on
/// each edge of its first row: a triangle whose third corner sits `offset` metres off the
/// edge's middle, so that the ear's particle carries a mass share of about `offset / 6 side`.
pub fn sliver_sheet(side: u32, offset: f32) -> ClothTopology {
    let step = 1.0 / (side - 1) as f32;
    let mut positions: Vec<[f32; 3]> = Vec::new();
    for r in 0..side {
        for c in 0..side {
            positions.push([c as f32 * step - 0.5, 0.0, r as f32 * step]);
        }
    }
    let mut indices = Vec::new();
    for r in 0..side - 1 {
        for c in 0..side - 1 {
            let a = r * side + c;
            indices.extend_from_slice(&[a, a + side, a + 1, a + 1, a + side, a + side + 1]);
        }
    }
    for c in 0..side - 1 {
        let ear = positions.len() as u32;
        positions.push([(c as f32 + 0.5) * step - 0.5, 0.0, -offset]);
        indices.extend_from_slice(&[c, c + 1, ear]);
    }
    ClothTopology::from_mesh(bvh_cloth_core::MeshRef { positions: &positions, indices: Some(&indices) }).unwrap()
}

/// A model bundled in `assets/models`, by file name without `.obj`.
pub fn bundled_model(name: &str) -> ObjMesh {
    let path = format!("{}/../../assets/models/{name}.obj", std::env::var("CARGO_MANIFEST_DIR").expect("run by cargo"));
    parse_obj(&std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"))).expect("a bundled model")
}
