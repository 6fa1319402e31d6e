//! Exact contact at a zero margin: seeded drapes of a default 64 x 64 cloth onto the bundled
//! models and onto procedural meshes, each scaled to a 1 m diagonal, with every substep path of
//! every particle checked against every nearby triangle by a crossing test of this file's own:
//! exact orientation signs in `f64`, over a uniform grid of its own, sharing no code with the
//! response.
//!
//! A path crosses a triangle when it starts strictly on one side of its plane and ends on the
//! plane or past it, through the triangle (its edges included). The collider holds the cloth at
//! its least thickness ([`Collider::contact_thickness`]), which at a zero margin is set by the
//! rounding of `f32` at the coordinates' magnitude.

use crate::common;

use std::collections::HashMap;

use bvh_cloth_core::backend::TriangleSurface;
use bvh_cloth_core::backend::face_normal;
use bvh_cloth_core::{Affine3A, ClothParams, ClothSim, Collider, MeshRef, Quat, Vec3};
use glam::DVec3;
use rayon::prelude::*;

/// The signed volume of `(b - a) x (c - a) . (d - a)`: six times the tetrahedron's, exact to
/// the last bits of `f64` for `f32` corners.
fn orient(a: DVec3, b: DVec3, c: DVec3, d: DVec3) -> f64 {
    (b - a).cross(c - a).dot(d - a)
}

/// Whether the path from `p` to `q` crosses the triangle: `p` strictly on one side of its
/// plane, `q` on it or past it, and the line through them within the triangle's three edges.
fn crosses(p: DVec3, q: DVec3, [a, b, c]: [DVec3; 3]) -> bool {
    let (sp, sq) = (orient(a, b, c, p), orient(a, b, c, q));
    if !((sp > 0.0 && sq <= 0.0) || (sp < 0.0 && sq >= 0.0)) {
        return false;
    }
    let edges = [orient(p, q, a, b), orient(p, q, b, c), orient(p, q, c, a)];
    edges.iter().all(|&v| v >= 0.0) || edges.iter().all(|&v| v <= 0.0)
}

/// The mesh's triangles in `f64`, binned by their boxes into cubes of `cell` metres.
struct Checker {
    triangles: Vec<[DVec3; 3]>,
    cells: HashMap<[i64; 3], Vec<u32>>,
    cell: f64,
}

impl Checker {
    fn new(positions: &[[f32; 3]], indices: &[u32], cell: f64) -> Self {
        let corner = |k: u32| Vec3::from(positions[k as usize]).as_dvec3();
        let triangles: Vec<[DVec3; 3]> =
            indices.chunks_exact(3).map(|t| [corner(t[0]), corner(t[1]), corner(t[2])]).collect();
        let mut cells: HashMap<[i64; 3], Vec<u32>> = HashMap::new();
        for (k, t) in triangles.iter().enumerate() {
            let (lo, hi) = (t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2]));
            for key in Self::keys(lo, hi, cell) {
                cells.entry(key).or_default().push(k as u32);
            }
        }
        Self { triangles, cells, cell }
    }

    fn keys(lo: DVec3, hi: DVec3, cell: f64) -> impl Iterator<Item = [i64; 3]> {
        let (a, b) = ((lo / cell).floor().as_i64vec3(), (hi / cell).floor().as_i64vec3());
        (a.x..=b.x).flat_map(move |x| (a.y..=b.y).flat_map(move |y| (a.z..=b.z).map(move |z| [x, y, z])))
    }

    /// A triangle the path crosses, if any.
    fn crossed(&self, p: Vec3, q: Vec3) -> Option<u32> {
        let (p, q) = (p.as_dvec3(), q.as_dvec3());
        Self::keys(p.min(q), p.max(q), self.cell)
            .filter_map(|key| self.cells.get(&key))
            .flatten()
            .copied()
            .find(|&k| crosses(p, q, self.triangles[k as usize]))
    }
}

/// The mesh moved and scaled so that its box has a 1 m diagonal, centred on the y axis and
/// standing on y = 0.
fn fit(positions: &[[f32; 3]]) -> Vec<[f32; 3]> {
    let lo = positions.iter().fold(Vec3::INFINITY, |m, &p| m.min(Vec3::from(p)));
    let hi = positions.iter().fold(Vec3::NEG_INFINITY, |m, &p| m.max(Vec3::from(p)));
    let scale = 1.0 / lo.distance(hi);
    let base = Vec3::new(0.5 * (lo.x + hi.x), lo.y, 0.5 * (lo.z + hi.z));
    positions.iter().map(|&p| ((Vec3::from(p) - base) * scale).to_array()).collect()
}

fn model(name: &str) -> (Vec<[f32; 3]>, Vec<u32>) {
    let model = common::bundled_model(name);
    (fit(&model.positions), model.indices)
}

/// A bumpy heightfield 0.7 m across: `side x side` vertices with seeded heights up to 6 cm,
/// sharp enough that neighbouring triangles meet at steep creases.
fn heightfield(side: u32, seed: u64) -> (Vec<[f32; 3]>, Vec<u32>) {
    let mut rng = common::Rng::new(seed);
    let step = 0.7 / (side - 1) as f32;
    let mut positions = Vec::new();
    for r in 0..side {
        for c in 0..side {
            positions.push([c as f32 * step - 0.35, rng.range(0.0, 0.06), r as f32 * step - 0.35]);
        }
    }
    let mut indices = Vec::new();
    for r in 0..side - 1 {
        for c in 0..side - 1 {
            let a = r * side + c;
            indices.extend_from_slice(&[a, a + side, a + 1, a + 1, a + side, a + side + 1]);
        }
    }
    (positions, indices)
}

/// What a drape found: the first few crossings, and how many paths were checked.
struct Drape {
    crossings: Vec<String>,
    paths: u64,
}

/// Drops a default 64 x 64 cloth, 1 m square, 0.1 m above the top of the mesh (shifted and
/// turned by the seed) onto its exact collider at a zero margin, for `seconds`, checking every
/// substep path.
fn drape(positions: &[[f32; 3]], indices: &[u32], seed: u64, seconds: f32) -> Drape {
    let mesh = MeshRef { positions, indices: Some(indices) };
    let collider = Collider::from_mesh_exact(mesh, 5).expect("a valid mesh");
    assert_eq!(collider.margin, 0.0);
    let top = positions.iter().map(|p| p[1]).fold(f32::NEG_INFINITY, f32::max);
    let mut rng = common::Rng::new(seed);
    let shift = Vec3::new(rng.range(-0.1, 0.1), top + 0.1, rng.range(-0.1, 0.1));
    let turn = Quat::from_rotation_y(rng.range(0.0, std::f32::consts::TAU));
    let pose =
        Affine3A::from_rotation_translation(turn, shift) * Affine3A::from_translation(Vec3::new(-0.5, 0.0, -0.5));
    let mut sim = ClothSim::new(ClothParams::default(), common::grid_topology(1.0, 64, 64), pose, &[]).unwrap();
    let checker = Checker::new(positions, indices, 0.02);
    let colliders = std::slice::from_ref(&collider);
    let dt = 1.0 / 60.0;
    let substeps = sim.substeps(dt);
    let h = dt / substeps as f32;
    let mut crossings = Vec::new();
    let mut paths = 0;
    for tick in 0..(seconds / dt).round() as u32 {
        for substep in 0..substeps {
            let before = sim.positions();
            sim.substep(h, colliders);
            let after = sim.positions();
            paths += after.len() as u64;
            assert!(after.iter().all(|p| p.is_finite()), "tick {tick}: a particle went non-finite");
            let found: Vec<String> = (0..after.len())
                .into_par_iter()
                .filter_map(|i| {
                    let k = checker.crossed(before[i], after[i])?;
                    Some(format!(
                        "tick {tick}, substep {substep}: particle {i} from {:?} to {:?} through triangle {k}",
                        before[i].to_array(),
                        after[i].to_array()
                    ))
                })
                .collect();
            crossings.extend(found.into_iter().take(5));
            if crossings.len() >= 5 {
                return Drape { crossings, paths };
            }
        }
    }
    Drape { crossings, paths }
}

fn assert_drapes_cross_nothing(name: &str, positions: &[[f32; 3]], indices: &[u32], seeds: &[u64], seconds: f32) {
    for &seed in seeds {
        let drape = drape(positions, indices, seed, seconds);
        eprintln!("{name}, seed {seed}: {} paths checked", drape.paths);
        assert!(drape.crossings.is_empty(), "{name}, seed {seed}:\n{}", drape.crossings.join("\n"));
    }
}

/// The bundled models, low and full resolution.
#[test]
fn drapes_at_a_zero_margin_cross_no_triangle_of_the_bundled_models() {
    for (name, seeds) in [("dragon_low", &[1, 2][..]), ("bunny_low", &[1, 2]), ("bunny", &[3]), ("dragon", &[4])] {
        let (positions, indices) = model(name);
        assert_drapes_cross_nothing(name, &positions, &indices, seeds, 1.2);
    }
}

/// Procedural meshes: a torus, a bumpy heightfield, and a closed box whose top the cloth
/// covers and whose edges it folds over.
#[test]
fn drapes_at_a_zero_margin_cross_no_triangle_of_procedural_meshes() {
    let (torus, torus_indices) = common::torus(0.35, 0.08, 64, 20);
    let (field, field_indices) = heightfield(48, 5);
    let (mut boxes, mut box_indices) = (Vec::new(), Vec::new());
    common::box_mesh(Vec3::new(-0.3, 0.0, -0.3), Vec3::new(0.3, 0.4, 0.3), &mut boxes, &mut box_indices);
    for (name, positions, indices, seeds) in [
        ("torus", fit(&torus), torus_indices, &[5][..]),
        ("heightfield", fit(&field), field_indices, &[6, 7]),
        ("box", fit(&boxes), box_indices, &[8]),
    ] {
        assert_drapes_cross_nothing(name, &positions, &indices, seeds, 1.2);
    }
}

/// A seeded point of a seeded triangle of `surface`, and one of the triangle's two unit normals
/// at random: the side a path starts on. `None` for a triangle without a normal.
fn point_and_side(surface: &TriangleSurface, rng: &mut common::Rng) -> Option<(Vec3, Vec3)> {
    let tri = surface.triangles[(rng.next_u64() % surface.triangles.len() as u64) as usize];
    let n = face_normal(tri)?;
    let (u, v) = (rng.range(0.0, 1.0), rng.range(0.0, 1.0));
    let (u, v) = if u + v > 1.0 { (1.0 - u, 1.0 - v) } else { (u, v) };
    let on = tri[0] + u * (tri[1] - tri[0]) + v * (tri[2] - tri[0]);
    Some((on, if rng.next_u64().is_multiple_of(2) { n } else { -n }))
}

/// Paths that end on a triangle's plane, or a nanometre either side of it, from 3 µm to 1 mm
/// off it at angles down to a grazing 3°, against the models' triangles: the sweep
/// ([`TriangleSurface::first_crossing`]) finds a crossing wherever this file's test does.
#[test]
fn the_sweep_finds_every_path_that_ends_on_or_just_past_a_plane() {
    for name in ["dragon_low", "bunny", "dragon"] {
        let (positions, indices) = model(name);
        let surface = TriangleSurface::build(MeshRef { positions: &positions, indices: Some(&indices) }).unwrap();
        let checker = Checker::new(&positions, &indices, 0.02);
        let mut rng = common::Rng::new(9);
        let (mut missed, mut crossing) = (Vec::new(), 0);
        for _ in 0..300_000 {
            let Some((on, side)) = point_and_side(&surface, &mut rng) else { continue };
            let dir = rng.vec3(-1.0, 1.0).normalize_or(side);
            let dir = (dir - dir.dot(side) * side).normalize_or(Vec3::X) + side * rng.range(0.05, 2.0);
            let prev = on + dir.normalize() * 10f32.powf(rng.range(-5.5, -3.0));
            let end = on - side * (1e-9 * rng.range(-1.0, 1.0));
            if checker.crossed(prev, end).is_some() {
                crossing += 1;
                if surface.first_crossing(prev, end).is_none() {
                    missed.push(format!("{:?} to {:?}", prev.to_array(), end.to_array()));
                }
            }
        }
        eprintln!("{name}: {} of {crossing} crossing paths missed", missed.len());
        assert!(crossing > 50_000, "{name}: only {crossing} of the paths cross: the test does not test");
        assert!(
            missed.is_empty(),
            "{name}: the sweep missed {} crossings:\n{}",
            missed.len(),
            missed[..missed.len().min(5)].join("\n")
        );
    }
}

/// The whole response at a zero margin, given the paths above: no end point it chooses is
/// across a triangle from where the particle started.
#[test]
fn responses_at_a_zero_margin_keep_every_path_on_its_side() {
    use bvh_cloth_core::colliders::Response;
    for name in ["dragon_low", "bunny", "dragon"] {
        let (positions, indices) = model(name);
        let surface = TriangleSurface::build(MeshRef { positions: &positions, indices: Some(&indices) }).unwrap();
        let checker = Checker::new(&positions, &indices, 0.02);
        let mut rng = common::Rng::new(11);
        let mut crossed = Vec::new();
        let least = surface.min_thickness;
        for _ in 0..200_000 {
            let Some((on, side)) = point_and_side(&surface, &mut rng) else { continue };
            let prev = on + side * least * rng.range(1.0, 30.0) + rng.vec3(-1.0, 1.0) * least;
            let end = on + rng.vec3(-1.0, 1.0) * 3e-4 - side * (1e-9 * rng.range(-1.0, 1.0));
            let out = match surface.respond(prev, end, 0.0, |_| {}) {
                Response::Free => end,
                Response::Moved(q) => q,
                Response::Stay => prev,
            };
            if checker.crossed(prev, out).is_some() {
                crossed.push(format!("{:?} to {:?}: {:?}", prev.to_array(), end.to_array(), out.to_array()));
            }
        }
        assert!(
            crossed.is_empty(),
            "{name}: {} responses crossed:\n{}",
            crossed.len(),
            crossed[..crossed.len().min(5)].join("\n")
        );
    }
}
