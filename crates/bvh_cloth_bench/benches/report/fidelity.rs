//! The section `fidelity`: cloths resting on the spheres, measured against the true mesh; and
//! the penetration check the exact-contact section shares.

use super::*;

/// Voxel resolutions of the fidelity table: the query table's and the highest accepted.
pub(crate) const FIDELITY_RESOLUTIONS: [u32; 8] = [1, 3, 5, 8, 16, 32, 64, 128];

/// How far the sphere collider is from the true surface: a cloth falls onto the spheres at each
/// n and rests there. Every particle is tested against the exact mesh every [`CHECK_TICKS`]
/// ticks of the run, so a particle that went through the spheres into the model counts even if
/// it left again; the particles resting on the spheres at the end give the air gap. Returns the
/// CSV rows.
pub(crate) fn fidelity(meshes: &[ObjMesh], parry: &[TriMesh]) -> String {
    /// A particle within this distance (m) of a sphere's surface is resting on it.
    const TOUCH: f32 = 2.0e-3;
    /// Ticks between two checks against the exact mesh.
    const CHECK_TICKS: u32 = 20;
    const SECONDS: f32 = 3.0;
    println!(
        "\n## Collider fidelity: a 64 x 64 cloth falling onto the spheres and resting 3 s, against the exact mesh (parry3d)\n"
    );
    println!(
        "Every particle is tested against the exact mesh every {CHECK_TICKS} ticks; a particle resting at the end lies within {} mm of a sphere's surface (margin 0 here).\n",
        TOUCH * 1e3
    );
    println!(
        "The exact-contact columns: the same cloth on the same model with exact contact (`Collider::with_exact_contact`, margin 0, so the surface's least thickness: a millionth of its diagonal, and at least 256 steps of `f32` at its coordinates' magnitude). Exact contact does not use the voxel spheres, so it is run once per model and its figures stand in every row of that model; resting means within {} mm of the triangles.\n",
        TOUCH * 1e3
    );
    println!(
        "| model | n | spheres | fell past the model | ever inside the true mesh | deepest mm | inside at the end | resting at the end | mean air gap mm | exact contact: ever inside | deepest mm | resting | mean air gap mm |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    let mut csv = String::from(
        "model,n,spheres,fell,ever_inside,deepest_mm,inside_at_end,resting,mean_gap_mm,exact_ever_inside,exact_deepest_mm,exact_resting,exact_mean_gap_mm\n",
    );
    for ((name, mesh), exact) in MODELS.iter().zip(meshes).zip(parry) {
        let exact_contact = {
            let c = collider(mesh, 5).with_margin(0.0).with_exact_contact(mesh.as_mesh_ref()).expect("area");
            let surface = c.surface().expect("exact contact").clone();
            let mut sim = cloth_above(&c, 64, Integrator::Rk4);
            let Penetration { ever_inside, deepest, .. } =
                run_checking_penetration(&mut sim, &c, exact, SECONDS, CHECK_TICKS);
            let gaps: Vec<f32> = sim
                .positions()
                .into_iter()
                .filter(|&p| surface.closest_within(p, TOUCH).is_some() && !inside(exact, p))
                .map(|p| exact.distance_to_local_point(Vector::from(p.to_array()), false).abs() * 1e3)
                .collect();
            let mean_gap = gaps.iter().sum::<f32>() / gaps.len().max(1) as f32;
            (ever_inside, deepest, gaps.len(), mean_gap)
        };
        let (exact_ever, exact_deepest, exact_resting, exact_gap) = exact_contact;
        for n in FIDELITY_RESOLUTIONS {
            let c = collider(mesh, n).with_margin(0.0);
            let mut sim = cloth_above(&c, 64, Integrator::Rk4);
            let Penetration { ever_inside, deepest, inside_at_end } =
                run_checking_penetration(&mut sim, &c, exact, SECONDS, CHECK_TICKS);
            let positions = sim.positions();
            let fell = positions.iter().filter(|p| p.y < 0.0).count();
            let gaps: Vec<f32> = positions
                .iter()
                .filter(|&&p| {
                    let gap = c
                        .lbvh()
                        .expect("a mesh collider")
                        .spheres
                        .iter()
                        .map(|s| p.distance(s.centre()) - s.radius)
                        .fold(f32::INFINITY, f32::min);
                    gap.abs() <= TOUCH && !inside(exact, p)
                })
                .map(|&p| exact.distance_to_local_point(Vector::from(p.to_array()), false).abs() * 1e3)
                .collect();
            let mean_gap = if gaps.is_empty() { 0.0 } else { gaps.iter().sum::<f32>() / gaps.len() as f32 };
            println!(
                "| {name} | {n} | {} | {fell} | {ever_inside} | {deepest:.1} | {inside_at_end} | {} | {mean_gap:.1} | {exact_ever} | {exact_deepest:.2} | {exact_resting} | {exact_gap:.3} |",
                c.sphere_count(),
                gaps.len(),
            );
            writeln!(
                csv,
                "{name},{n},{},{fell},{ever_inside},{deepest:.3},{inside_at_end},{},{mean_gap:.3},{exact_ever},{exact_deepest:.3},{exact_resting},{exact_gap:.4}",
                c.sphere_count(),
                gaps.len()
            )
            .unwrap();
        }
    }
    csv
}

/// What [`run_checking_penetration`] saw of a cloth against the exact mesh.
pub(crate) struct Penetration {
    /// Particles found inside the true mesh at some check.
    pub(crate) ever_inside: usize,
    /// The deepest any was, in mm.
    pub(crate) deepest: f32,
    /// Particles inside at the last check (the end).
    pub(crate) inside_at_end: usize,
}

/// Runs `sim` for `seconds` of 60 Hz ticks against `c`, checking every particle against the
/// exact mesh every `check_ticks` ticks and at the end.
pub(crate) fn run_checking_penetration(
    sim: &mut ClothSim,
    c: &Collider,
    exact: &TriMesh,
    seconds: f32,
    check_ticks: u32,
) -> Penetration {
    let colliders = std::slice::from_ref(c);
    let depth_inside = |p: Vec3| {
        inside(exact, p).then(|| exact.distance_to_local_point(Vector::from(p.to_array()), false).abs() * 1e3)
    };
    let mut ever = vec![false; sim.len()];
    let (mut deepest, mut inside_at_end) = (0.0f32, 0usize);
    let ticks = (seconds / TICK).round() as u32;
    for tick in 1..=ticks {
        sim.tick(TICK, colliders);
        if tick % check_ticks != 0 && tick != ticks {
            continue;
        }
        let depths: Vec<Option<f32>> = sim.positions().into_iter().map(depth_inside).collect();
        for (seen, depth) in ever.iter_mut().zip(&depths) {
            if let Some(d) = *depth {
                *seen = true;
                deepest = deepest.max(d);
            }
        }
        inside_at_end = depths.iter().flatten().count();
    }
    Penetration { ever_inside: ever.iter().filter(|&&e| e).count(), deepest, inside_at_end }
}

/// Whether `p` is inside the exact mesh: the majority vote of the crossing parities of three
/// rays. Parity needs no consistent orientation, and the vote outlasts a ray that slips through
/// one of the scanned models' small holes.
pub(crate) fn inside(mesh: &TriMesh, p: Vec3) -> bool {
    const DIRECTIONS: [[f32; 3]; 3] = [[0.577, 0.613, 0.539], [-0.642, 0.298, -0.706], [0.331, -0.874, 0.355]];
    let odd = |dir: [f32; 3]| {
        let (dir, mut origin, mut crossings) = (Vec3::from(dir).normalize(), p, 0u32);
        while crossings < 256 {
            let ray = Ray::new(Vector::from(origin.to_array()), Vector::from(dir.to_array()));
            let Some(t) = mesh.cast_local_ray(&ray, 10.0, false) else { break };
            crossings += 1;
            origin += dir * (t + 1.0e-5);
        }
        crossings % 2 == 1
    };
    DIRECTIONS.into_iter().filter(|&d| odd(d)).count() >= 2
}
