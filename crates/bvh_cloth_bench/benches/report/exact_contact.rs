//! The sections `exact_contact` and `exact_contact_gpu`: exact contact against sphere contact,
//! the resting air gap and the drape's cost, and the GPU kernel's.

use super::*;

/// The exact-contact sections' cloth thickness (m).
pub(crate) const EXACT_THICKNESS: f32 = 0.005;

/// Exact contact against the paper's sphere contact, on the bundled models at n = 5 with a
/// thickness (margin) of 5 mm: a 64 x 64 cloth falls onto each and rests 3 s (RK4, Looper 16),
/// checked against the exact mesh (parry3d) every 20 ticks; then the drape's time with each
/// contact.
pub(crate) fn exact_contact(meshes: &[ObjMesh], parry: &[TriMesh]) {
    const THICKNESS: f32 = EXACT_THICKNESS;
    /// A particle within this distance (m) of the true surface at the end rests on the model.
    const ON_MODEL: f32 = 0.05;
    /// A particle within this distance (m) beyond the thickness of the collider's own surface
    /// at the end is in contact with it.
    const TOUCH: f32 = 0.002;
    const CHECK_TICKS: u32 = 20;
    println!(
        "\n## Exact contact: a 64 x 64 cloth resting 3 s at n = 5, thickness {} mm, against the exact mesh (parry3d)\n",
        THICKNESS * 1e3
    );
    println!(
        "In contact: at the end, within {} mm beyond the thickness of the collider's own surface (the spheres, or the triangles); their air gap is their distance to the true surface beyond the thickness. On the model: within {} mm of the true surface, sagging cloth included. Penetration: depth inside the true mesh, checked every {CHECK_TICKS} ticks.\n",
        TOUCH * 1e3,
        ON_MODEL * 1e3
    );
    println!(
        "| model | contact | fell past | ever inside | deepest mm | inside at the end | in contact | contact air gap mm | on the model | its mean gap mm | closer than the thickness |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    for ((name, mesh), exact) in MODELS.iter().zip(meshes).zip(parry) {
        let spheres = collider(mesh, 5).with_margin(THICKNESS);
        let triangles = spheres.clone().with_exact_contact(mesh.as_mesh_ref()).expect("the bundled models have area");
        for (contact, c) in [("spheres", &spheres), ("exact", &triangles)] {
            let mut sim = cloth_above(c, 64, Integrator::Rk4);
            let Penetration { ever_inside, deepest, inside_at_end } =
                run_checking_penetration(&mut sim, c, exact, 3.0, CHECK_TICKS);
            let positions = sim.positions();
            let fell = positions.iter().filter(|p| p.y < 0.0).count();
            let gaps: Vec<f32> = positions
                .iter()
                .filter(|&&p| !inside(exact, p))
                .map(|&p| exact.distance_to_local_point(Vector::from(p.to_array()), false).abs())
                .filter(|&d| d < ON_MODEL)
                .collect();
            let mean_gap = gaps.iter().map(|d| d - THICKNESS).sum::<f32>() / gaps.len().max(1) as f32;
            let close = gaps.iter().filter(|&&d| d < 0.9 * THICKNESS).count();
            // In contact with the collider's own surface.
            let touching = |p: Vec3| match c.surface() {
                Some(surface) => surface.closest_within(p, THICKNESS + TOUCH).is_some(),
                None => c
                    .lbvh()
                    .expect("a mesh collider")
                    .spheres
                    .iter()
                    .any(|s| (p.distance(s.centre()) - s.radius - THICKNESS).abs() <= TOUCH && !c.contains(p)),
            };
            let contact_gaps: Vec<f32> = positions
                .iter()
                .filter(|&&p| touching(p) && !inside(exact, p))
                .map(|&p| exact.distance_to_local_point(Vector::from(p.to_array()), false).abs() - THICKNESS)
                .collect();
            let contact_gap = contact_gaps.iter().sum::<f32>() / contact_gaps.len().max(1) as f32;
            println!(
                "| {name} | {contact} | {fell} | {ever_inside} | {deepest:.2} | {inside_at_end} | {} | {:.2} | {} | {:.2} | {close} |",
                contact_gaps.len(),
                contact_gap * 1e3,
                gaps.len(),
                mean_gap * 1e3,
            );
        }
    }

    println!("\n### CPU: the drape with exact against sphere contact\n");
    println!(
        "Seconds to drape the 64 x 64 cloth 2 s (120 ticks of RK4, Looper 16) on the model at n = 5, thickness {} mm, on the CPU backend's pool ({} threads): alternating, best of 3 each.\n",
        THICKNESS * 1e3,
        rayon::current_num_threads()
    );
    println!("| model | sphere contact s | exact contact s | exact / spheres |");
    println!("|---|---|---|---|");
    for (name, mesh) in MODELS.iter().zip(meshes) {
        let spheres = collider(mesh, 5).with_margin(THICKNESS);
        let triangles = spheres.clone().with_exact_contact(mesh.as_mesh_ref()).expect("area");
        let (sphere_s, exact_s) = (0..3).fold((f64::INFINITY, f64::INFINITY), |(s, e), _| {
            let sphere = time(|| drop(std::hint::black_box(drape(&spheres, 2.0))));
            let exact = time(|| drop(std::hint::black_box(drape(&triangles, 2.0))));
            (s.min(sphere), e.min(exact))
        });
        println!("| {name} | {sphere_s:.3} | {exact_s:.3} | {:.2}x |", exact_s / sphere_s);
    }
}

/// Exact contact's GPU collision kernel against the sphere kernel (the `exact_contact_gpu`
/// section, after `exact_contact`).
pub(crate) fn exact_contact_on_gpu(meshes: &[ObjMesh], gpu: Option<&Gpu>) {
    const THICKNESS: f32 = EXACT_THICKNESS;
    println!("\n### GPU: the collision kernel with exact against sphere contact\n");
    let Some(gpu) = gpu else {
        println!("No GPU adapter: skipped.");
        return;
    };
    println!(
        "ms of `node_update_final` (the last RK4 stage with the collision response) per 60 Hz tick of a 64 x 64 cloth (Looper 16) resting on the model at n = 5, and of the whole tick: medians of 9 ticks, timestamp queries.\n"
    );
    println!(
        "| model | sphere contact: final stage ms | tick ms | exact contact: final stage ms | tick ms | final stage exact / spheres |"
    );
    println!("|---|---|---|---|---|---|");
    for (name, mesh) in MODELS.iter().zip(meshes) {
        let spheres = collider(mesh, 5).with_margin(THICKNESS);
        let triangles = spheres.clone().with_exact_contact(mesh.as_mesh_ref()).expect("area");
        let times = [&spheres, &triangles].map(|c| kernel_ms(gpu, c, std::slice::from_ref(&drape(c, 1.0))));
        let [Some((s_ms, s_total)), Some((e_ms, e_total))] = times else {
            println!("| {name} | — | — | — | — | — |");
            continue;
        };
        let column = kernel_column(Kernel::NodeUpdateFinal);
        println!(
            "| {name} | {:.4} | {s_total:.4} | {:.4} | {e_total:.4} | {:.2}x |",
            s_ms[column],
            e_ms[column],
            e_ms[column] / s_ms[column]
        );
    }
    if gpu.is_software() {
        println!("\nThe GPU here is a software adapter on the same CPU cores: its times are not GPU figures.");
    }
}
