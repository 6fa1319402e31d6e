//! The section `queries`: the particle queries of one collision pass against the voxel
//! spheres, our LBVH against brute force over the same spheres and parry3d's projection.

use super::*;

/// The particle queries of one collision pass, single-threaded: which spheres hold each point
/// (LBVH, and brute force over the same spheres), against parry3d's projection of each point on
/// the exact mesh. Returns the CSV rows.
pub(crate) fn queries(meshes: &[ObjMesh], parry: &[TriMesh]) -> String {
    println!("\n## Particle queries, 1 thread: 4,096 positions of a cloth draped for 2 s on the n = 16 collider\n");
    println!("LBVH and brute force list the spheres holding each point; parry3d projects it on the exact mesh.\n");
    println!(
        "| model | n | spheres | LBVH M/s | brute force M/s | parry3d TriMesh M/s | LBVH / parry3d | LBVH / brute force |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    let mut csv = String::from("model,n,spheres,lbvh_qps,brute_qps,parry_qps\n");
    for ((name, mesh), exact) in MODELS.iter().zip(meshes).zip(parry) {
        let points = drape(&collider(mesh, 16), 2.0).positions();
        let rate = |seconds: f64| points.len() as f64 / seconds;
        let parry_qps = rate(best_of(7, || {
            for &p in &points {
                std::hint::black_box(exact.project_local_point(Vector::from(p.to_array()), true));
            }
        }));
        for n in RESOLUTIONS {
            let c = collider(mesh, n);
            let lbvh_qps = rate(best_of(7, || {
                let mut hits = 0u32;
                for &p in &points {
                    c.lbvh().expect("a mesh collider").for_each_containing(p, 0.0, |_, _| hits += 1);
                }
                std::hint::black_box(hits);
            }));
            let brute_qps = rate(best_of(3, || {
                let mut hits = 0u32;
                for &p in &points {
                    c.lbvh().expect("a mesh collider").brute_force_containing(p, 0.0, |_, _| hits += 1);
                }
                std::hint::black_box(hits);
            }));
            println!(
                "| {name} | {n} | {} | {:.2} | {:.3} | {:.3} | {:.0}x | {:.1}x |",
                c.sphere_count(),
                lbvh_qps / 1e6,
                brute_qps / 1e6,
                parry_qps / 1e6,
                lbvh_qps / parry_qps,
                lbvh_qps / brute_qps
            );
            writeln!(csv, "{name},{n},{},{lbvh_qps:.0},{brute_qps:.0},{parry_qps:.0}", c.sphere_count()).unwrap();
        }
    }
    csv
}
