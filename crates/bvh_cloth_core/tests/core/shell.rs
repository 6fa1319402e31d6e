//! The guarantee of `bvh_cloth_core::colliders::collision`: a particle that starts a substep outside every
//! sphere of a still collider ends it outside every sphere, and its path between the two
//! positions passes through none, so a cloth never crosses the shell of spheres into the hollow
//! inside, however thin the spheres are.
//!
//! Each scene drops a 64 x 64 cloth (`ClothParams::default()`, 1.5 m) from 0.1 m above a collider
//! with no margin and checks every particle after every substep. The bundled models run at
//! n = 32, 64 and 128, where the spheres are thinnest; two thin procedural shapes (a plate one
//! voxel thick and a torus) are also checked against their exact inside.

use crate::common;

use bvh_cloth_core::backend::SURFACE_TOLERANCE;
use bvh_cloth_core::{Affine3A, ClothParams, ClothSim, Collider, MeshRef, Vec3};
use rayon::prelude::*;

/// A path that comes closer to a centre than `(1 - TOLERANCE) r` has passed through that sphere:
/// the containment test's own tolerance, plus one percent of it for the rounding of a path
/// computed in another order.
const TOLERANCE: f32 = SURFACE_TOLERANCE * 1.01;

/// The closest point of segment `a`–`b` to `c`.
fn closest_on_segment(a: Vec3, b: Vec3, c: Vec3) -> Vec3 {
    let d = b - a;
    let len2 = d.length_squared();
    if len2 == 0.0 {
        return a;
    }
    a + ((c - a).dot(d) / len2).clamp(0.0, 1.0) * d
}

/// The spheres (local frame, with the collider's margin) whose inside the segment `a`–`b` reaches.
fn spheres_crossed(collider: &Collider, a: Vec3, b: Vec3) -> Vec<(Vec3, f32)> {
    let margin = collider.margin;
    let mut crossed = Vec::new();
    collider.lbvh().expect("a mesh collider").for_each_overlapping(a.min(b), a.max(b), margin, |_, s| {
        let r = (s.radius + margin) * (1.0 - TOLERANCE);
        if closest_on_segment(a, b, s.centre()).distance_squared(s.centre()) < r * r {
            crossed.push((s.centre(), s.radius + margin));
        }
    });
    crossed
}

/// What went wrong in a drop: the first few violations, and how many particles ended inside the
/// solid (when the scene knows its exact inside).
struct Drop {
    violations: Vec<String>,
    substeps: u32,
    inside_solid: usize,
}

/// Drops the cloth on `collider` (identity pose) for `seconds` and checks every substep.
fn drop_on(collider: &Collider, seconds: f32, solid: Option<&(dyn Fn(Vec3) -> bool + Sync)>) -> Drop {
    let top = collider.lbvh().expect("a mesh collider").bounds().expect("spheres").1.y;
    let params = ClothParams { looper: 16, ..ClothParams::default() };
    let pose = Affine3A::from_translation(Vec3::new(0.0, top + 0.1, 0.0));
    let mut sim = ClothSim::new(params, common::grid_topology(2.0, 64, 64), pose, &[]).expect("a valid cloth");
    let colliders = std::slice::from_ref(collider);
    let dt = 1.0 / 60.0;
    let substeps = sim.substeps(dt);
    let h = dt / substeps as f32;
    let mut violations = Vec::new();
    let mut steps = 0;
    for _ in 0..(seconds / dt).round() as u32 {
        for _ in 0..substeps {
            let before = sim.positions();
            sim.substep(h, colliders);
            steps += 1;
            let after = sim.positions();
            let found: Vec<String> = (0..after.len())
                .into_par_iter()
                .filter_map(|i| {
                    if collider.contains(after[i]) {
                        return Some(format!("substep {steps}: particle {i} ends inside a sphere at {}", after[i]));
                    }
                    let crossed = spheres_crossed(collider, before[i], after[i]);
                    (!crossed.is_empty()).then(|| {
                        format!(
                            "substep {steps}: particle {i} went from {} to {} through the sphere {:?}",
                            before[i], after[i], crossed[0]
                        )
                    })
                })
                .collect();
            violations.extend(found.into_iter().take(5));
            if violations.len() >= 5 {
                return Drop { violations, substeps: steps, inside_solid: 0 };
            }
        }
    }
    let inside_solid = solid.map_or(0, |inside| sim.positions().iter().filter(|&&p| inside(p)).count());
    Drop { violations, substeps: steps, inside_solid }
}

fn assert_holds(name: &str, drop: &Drop) {
    assert!(drop.violations.is_empty(), "{name}: {}", drop.violations.join("\n"));
    assert!(drop.substeps > 0);
    assert_eq!(drop.inside_solid, 0, "{name}: particles ended inside the solid");
}

/// The bundled model `name` at n = 32, 64 and 128.
fn assert_model_shell_holds(name: &str) {
    let mesh = common::bundled_model(name);
    for n in [32, 64, 128] {
        let collider = Collider::from_mesh(mesh.as_mesh_ref(), n).expect("a bundled model voxelises");
        assert_holds(&format!("{name} n = {n}"), &drop_on(&collider, 4.0, None));
    }
}

#[test]
fn the_cloth_never_crosses_the_bunny_shell() {
    assert_model_shell_holds("bunny");
}

#[test]
fn the_cloth_never_crosses_the_dragon_shell() {
    assert_model_shell_holds("dragon");
}

/// A 1 m plate exactly one voxel thick at n = 64: the mesh's box is a 1 m cube (two specks at
/// opposite corners fix it), so each voxel is 1/64 m tall and the plate is that thick. Its six
/// faces are single big triangles pairs, so every sphere comes from clipped pieces.
#[test]
fn the_cloth_never_crosses_a_plate_one_voxel_thick() {
    let n = 64;
    let thickness = 1.0 / n as f32;
    let (lo, hi) = (Vec3::new(-0.5, 0.5, -0.5), Vec3::new(0.5, 0.5 + thickness, 0.5));
    let (mut positions, mut indices) = (Vec::new(), Vec::new());
    common::box_mesh(lo, hi, &mut positions, &mut indices);
    let speck = 1.0e-4;
    common::box_mesh(Vec3::new(-0.5, 0.0, -0.5), Vec3::new(-0.5, 0.0, -0.5) + speck, &mut positions, &mut indices);
    common::box_mesh(Vec3::new(0.5, 1.0, 0.5) - speck, Vec3::new(0.5, 1.0, 0.5), &mut positions, &mut indices);
    let collider = Collider::from_mesh(MeshRef { positions: &positions, indices: Some(&indices) }, n).unwrap();
    let inside = move |p: Vec3| p.cmpgt(lo).all() && p.cmplt(hi).all();
    let drop = drop_on(&collider, 4.0, Some(&inside));
    assert_holds("plate", &drop);
}

/// A torus lying flat (major radius 0.35 m, tube radius 0.06 m), voxelised at n = 128: the cloth
/// drapes over the ring and sags through its hole.
#[test]
fn the_cloth_never_crosses_a_torus() {
    let (major, minor, sides) = (0.35f32, 0.06f32, 24u32);
    let (positions, indices) = common::torus(major, minor, 96, sides);
    let collider = Collider::from_mesh(MeshRef { positions: &positions, indices: Some(&indices) }, 128).unwrap();
    // The polygonal tube lies inside the round one; count only particles inside the polygon's
    // inscribed tube.
    let inscribed = minor * (std::f32::consts::PI / sides as f32).cos();
    let inside = move |p: Vec3| {
        let ring = (p.x * p.x + p.z * p.z).sqrt() - major;
        ring * ring + p.y * p.y < inscribed * inscribed * 0.999
    };
    let drop = drop_on(&collider, 4.0, Some(&inside));
    assert_holds("torus", &drop);
}
