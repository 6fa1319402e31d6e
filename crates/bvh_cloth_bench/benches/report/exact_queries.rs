//! Exact contact's surface on its own. The section `exact_contact_queries`: its point query
//! against parry3d's on one thread, like with like. Both answer the same question, the closest
//! point of the surface within a reach: ours with `TriangleSurface::closest_within`, parry3d
//! with `project_local_point_with_max_dist` on a `TriMesh` of the same triangles. The unbounded
//! projection is printed beside them for scale only. The section `exact_contact_build`: the
//! build with and without the surface, and the memory it keeps, from the bundled models to a
//! heightfield of 2 million triangles.

use bvh_cloth_bench::{MODELS, best_of, collider, drape, time};
use bvh_cloth_core::ObjMesh;
use bvh_cloth_core::backend::CONTACT_BAND;
use bvh_cloth_core::backend::TriangleSurface;
use bvh_cloth_core::backend::face_normal;
use bvh_cloth_core::{Collider, MeshRef, Vec3};
use parry3d::math::Vector;
use parry3d::query::PointQuery;
use parry3d::shape::{TriMesh, TriMeshFlags};

use super::{EXACT_THICKNESS, train_other_branches, write_every_line};

/// The reach of the near-surface points' queries, and how far off the surface they lie (m).
const NEAR_REACH: f32 = 0.02;
/// How many near-surface points each model gets.
const NEAR_POINTS: usize = 65_536;

/// The surface's triangles as parry3d's `TriMesh`, without the pseudo-normals that only an
/// inside test needs: a projection on the surface, as ours is.
fn plain_mesh(surface: &TriangleSurface) -> TriMesh {
    let vertices = surface.triangles.iter().flatten().map(|p| Vector::from(p.to_array())).collect();
    let triangles = (0..surface.triangles.len() as u32).map(|k| [3 * k, 3 * k + 1, 3 * k + 2]).collect();
    TriMesh::with_flags(vertices, triangles, TriMeshFlags::empty()).expect("triangles with area")
}

/// A seeded xorshift generator of numbers uniform in `[0, 1)`, so that the tables' points
/// are the same in every run.
fn seeded_unit(seed: u64) -> impl FnMut() -> f32 {
    let mut state = seed;
    move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 40) as f32 / (1u64 << 24) as f32
    }
}

/// `count` points within `reach` of the surface: a seeded point of a seeded triangle (each
/// triangle alike), moved along its normal by up to `reach` either way.
fn near_points(surface: &TriangleSurface, count: usize, reach: f32) -> Vec<Vec3> {
    let mut unit = seeded_unit(0x9E37_79B9_7F4A_7C15);
    let triangles = &surface.triangles;
    (0..count)
        .map(|_| {
            let tri = triangles[((unit() * triangles.len() as f32) as usize).min(triangles.len() - 1)];
            let (u, v) = (unit(), unit());
            let (u, v) = if u + v > 1.0 { (1.0 - u, 1.0 - v) } else { (u, v) };
            let on = tri[0] + u * (tri[1] - tri[0]) + v * (tri[2] - tri[0]);
            on + face_normal(tri).unwrap_or(Vec3::Y) * reach * (2.0 * unit() - 1.0)
        })
        .collect()
}

/// How many of the points the two queries answer differently: one finds a point within the
/// reach and the other none, or their distances differ by more than a micrometre (a point
/// within a micrometre of the reach may go either way).
fn disagreements(surface: &TriangleSurface, mesh: &TriMesh, points: &[Vec3], reach: f32) -> usize {
    points
        .iter()
        .filter(|&&p| {
            let ours = surface.closest_within(p, reach).map(|q| q.distance(p));
            let theirs = mesh
                .project_local_point_with_max_dist(Vector::from(p.to_array()), false, reach)
                .map(|proj| Vec3::from(proj.point.to_array()).distance(p));
            match (ours, theirs) {
                (Some(a), Some(b)) => (a - b).abs() > 1e-6,
                (Some(d), None) | (None, Some(d)) => d < reach - 1e-6,
                (None, None) => false,
            }
        })
        .count()
}

/// The section: one table of query rates, and one of what slows the exact query's pass after
/// other work.
pub fn exact_queries(meshes: &[ObjMesh], single: &rayon::ThreadPool) {
    let contact_reach = EXACT_THICKNESS * (1.0 + CONTACT_BAND);
    println!("\n### Point queries against parry3d, one thread\n");
    println!(
        "Both find the closest point of the surface within a reach: exact contact with `TriangleSurface::closest_within`, parry3d with `project_local_point_with_max_dist` on a `TriMesh` of the same triangles (no pseudo-normals: a projection, not an inside test). Points: the 4,096 positions of a 64 x 64 cloth draped 2 s on the model's exact collider at n = 5, at the reach a contact asks ({:.2} mm, the {} mm thickness and its band), and {NEAR_POINTS} seeded points within {} mm of the surface (a point of a triangle moved along its normal), at a reach of {} mm. The passes alternate, best of 9 each; each is timed right after the other library's pass (its data pushed out of the caches) and then repeated (its data cached). parry3d's unbounded `project_local_point` is shown for scale. Disagreements: points where the two answers differ by more than 1 µm.\n",
        contact_reach * 1e3,
        EXACT_THICKNESS * 1e3,
        NEAR_REACH * 1e3,
        NEAR_REACH * 1e3,
    );
    println!(
        "| model | triangles | points | reach mm | found within | exact M/s | parry3d bounded M/s | exact / parry3d | repeated: exact M/s | parry3d bounded M/s | exact / parry3d | parry3d unbounded M/s | disagreements |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    let mut after_rows = Vec::new();
    let mut lines = vec![0u8; 64 << 20];
    let mut words = [1u32; 4096];
    for (name, mesh) in MODELS.iter().zip(meshes) {
        let c = collider(mesh, 5).with_margin(EXACT_THICKNESS);
        let c = c.with_exact_contact(mesh.as_mesh_ref()).expect("the bundled models have area");
        let surface = c.surface().expect("exact contact").clone();
        let parry = plain_mesh(&surface);
        let cloth = drape(&c, 2.0).positions();
        let near = near_points(&surface, NEAR_POINTS, NEAR_REACH);
        for (points_name, points, reach) in
            [("draped cloth", &cloth, contact_reach), ("near the surface", &near, NEAR_REACH)]
        {
            let rate = |seconds: f64| points.len() as f64 / seconds;
            let ours = || {
                for &p in points {
                    std::hint::black_box(surface.closest_within(p, reach));
                }
            };
            let bounded = || {
                for &p in points {
                    let p = Vector::from(p.to_array());
                    std::hint::black_box(parry.project_local_point_with_max_dist(p, false, reach));
                }
            };
            let unbounded = || {
                for &p in points {
                    std::hint::black_box(parry.project_local_point(Vector::from(p.to_array()), false));
                }
            };
            let [ours_after, ours_repeated, theirs_after, theirs_repeated, unbounded_s] = single.install(|| {
                bounded();
                (0..9).fold([f64::INFINITY; 5], |best, _| {
                    let times = [time(ours), time(ours), time(bounded), time(bounded), time(unbounded)];
                    std::array::from_fn(|i| best[i].min(times[i]))
                })
            });
            let found = points.iter().filter(|&&p| surface.closest_within(p, reach).is_some()).count();
            let differ = disagreements(&surface, &parry, points, reach);
            println!(
                "| {name} | {} | {points_name}, {} | {:.2} | {:.0} % | {:.2} | {:.2} | {:.2}x | {:.2} | {:.2} | {:.2}x | {:.3} | {differ} |",
                surface.triangles.len(),
                points.len(),
                reach * 1e3,
                100.0 * found as f64 / points.len() as f64,
                rate(ours_after) / 1e6,
                rate(theirs_after) / 1e6,
                theirs_after / ours_after,
                rate(ours_repeated) / 1e6,
                rate(theirs_repeated) / 1e6,
                theirs_repeated / ours_repeated,
                rate(unbounded_s) / 1e6,
            );
            if points_name == "draped cloth" {
                let [after_write, after_branches, after_both] = single.install(|| {
                    (0..9).fold([f64::INFINITY; 3], |best, _| {
                        write_every_line(&mut lines);
                        let write = time(ours);
                        train_other_branches(&mut words);
                        let branches = time(ours);
                        write_every_line(&mut lines);
                        train_other_branches(&mut words);
                        let both = time(ours);
                        [best[0].min(write), best[1].min(branches), best[2].min(both)]
                    })
                });
                after_rows.push(format!(
                    "| {name} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} |",
                    rate(ours_repeated) / 1e6,
                    rate(after_write) / 1e6,
                    rate(after_branches) / 1e6,
                    rate(after_both) / 1e6,
                    rate(ours_after) / 1e6
                ));
            }
        }
    }

    println!("\n### What slows the exact query's pass after other work\n");
    println!(
        "M/s of the draped cloth's exact queries on one thread, each pass timed right after: the same pass (repeated, as above); a write to every cache line of 64 MiB (which evicts the caches and trains few branches); 3 million steps of a loop whose branches follow a pseudo-random sequence over 16 KiB (which trains the branch predictors on other code and evicts little); both; parry3d's bounded pass (as above). Best of 9 each, in that order within each round.\n"
    );
    println!("| model | repeated | after the write | after the branches | after both | after parry3d |");
    println!("|---|---|---|---|---|---|");
    for row in after_rows {
        println!("{row}");
    }
    drop(lines);
}

/// A mesh's positions and triangle indices.
type Mesh = (Vec<[f32; 3]>, Vec<u32>);

/// A bumpy heightfield 1 m across of `side x side` vertices (`2 (side - 1)^2` triangles),
/// seeded heights up to 5 cm.
fn heightfield(side: u32) -> Mesh {
    let mut unit = seeded_unit(0x2545_F491_4F6C_DD1D);
    let step = 1.0 / (side - 1) as f32;
    let mut positions = Vec::with_capacity((side * side) as usize);
    for r in 0..side {
        for c in 0..side {
            let height = 0.05 * unit();
            positions.push([c as f32 * step - 0.5, height, r as f32 * step - 0.5]);
        }
    }
    let mut indices = Vec::with_capacity(6 * ((side - 1) * (side - 1)) as usize);
    for r in 0..side - 1 {
        for c in 0..side - 1 {
            let a = r * side + c;
            indices.extend_from_slice(&[a, a + side, a + 1, a + 1, a + side, a + side + 1]);
        }
    }
    (positions, indices)
}

/// The section `exact_contact_build`.
pub fn exact_build(meshes: &[ObjMesh]) {
    println!("\n### Build and memory of the triangle surface\n");
    println!(
        "`Collider::from_mesh` at n = 16, and `Collider::from_mesh_exact` at n = 16 (the same spheres and the triangle surface), on the whole pool ({} threads), alternating, best of 5 each (3 above a million triangles). Kept: the surface's heap bytes (`TriangleSurface::heap_bytes`: its triangles and its wide tree; the sphere tree is the other column's). The heightfields are 1 m across with seeded bumps up to 5 cm.\n",
        rayon::current_num_threads()
    );
    println!("| mesh | triangles | build ms | build with surface ms | ratio | surface kept MiB | bytes a triangle |");
    println!("|---|---|---|---|---|---|---|");
    let fields: Vec<(String, Mesh)> = [354u32, 708, 1001]
        .into_iter()
        .map(|side| (format!("heightfield {side} x {side}"), heightfield(side)))
        .collect();
    let mut rows: Vec<(String, MeshRef<'_>)> =
        MODELS.iter().zip(meshes).map(|(name, mesh)| (name.to_string(), mesh.as_mesh_ref())).collect();
    rows.extend(fields.iter().map(|(name, (p, i))| (name.clone(), MeshRef { positions: p, indices: Some(i) })));
    for (name, mesh) in rows {
        let triangles = mesh.indices.map_or(0, |i| i.len() / 3);
        let reps = if triangles > 1_000_000 { 3 } else { 5 };
        let (build_s, with_s) = (0..reps).fold((f64::INFINITY, f64::INFINITY), |(plain, with), _| {
            let p = best_of(1, || {
                std::hint::black_box(Collider::from_mesh(mesh, 16).expect("valid"));
            });
            let w = best_of(1, || {
                std::hint::black_box(Collider::from_mesh_exact(mesh, 16).expect("valid"));
            });
            (plain.min(p), with.min(w))
        });
        let collider = Collider::from_mesh_exact(mesh, 16).expect("valid");
        let surface = collider.surface().expect("exact contact");
        let kept = surface.heap_bytes();
        println!(
            "| {name} | {triangles} | {:.1} | {:.1} | {:.2}x | {:.1} | {:.0} |",
            build_s * 1e3,
            with_s * 1e3,
            with_s / build_s,
            kept as f64 / (1 << 20) as f64,
            kept as f64 / surface.triangles.len() as f64,
        );
    }
}
