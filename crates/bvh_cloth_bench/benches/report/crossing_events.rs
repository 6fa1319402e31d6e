//! The section `self_contact_events`: how the layers of a fast fold get through each other.
//! The bunny fold of the core's self-contact tests (a 64 x 64 cloth with self-contact at 8 mm
//! thrown at the bunny) is stepped one substep at a time; after each, every pair of triangles
//! that intersects and did not before is sorted by what went through what over the substep,
//! every particle taken along a straight line from its start to its end: a corner of one
//! triangle through the other's face, or else an edge of one through an edge of the other.

use super::*;

/// Steps along a substep at which the crossings are looked for.
const SAMPLES: u32 = 2000;

/// Where `k` is a fraction `t` of the way along its substep, in `f64`.
fn along(start: &[Vec3], end: &[Vec3], k: u32, t: f64) -> glam::DVec3 {
    start[k as usize].as_dvec3() * (1.0 - t) + end[k as usize].as_dvec3() * t
}

/// Whether particle `v` goes through the face `f` during the substep: it changes sides of the
/// face's plane inside the face.
fn through_face(start: &[Vec3], end: &[Vec3], v: u32, f: [u32; 3]) -> bool {
    let side = |t: f64| {
        let [a, b, c] = f.map(|k| along(start, end, k, t));
        let p = along(start, end, v, t);
        let n = (b - a).cross(c - a);
        ((p - a).dot(n), [a, b, c], p, n)
    };
    let mut before = side(0.0).0;
    (1..=SAMPLES).any(|s| {
        let (d, [a, b, c], p, n) = side(f64::from(s) / f64::from(SAMPLES));
        let crossed = (d > 0.0) != (before > 0.0);
        before = d;
        let q = p - n * ((p - a).dot(n) / n.length_squared());
        let edge = |u: glam::DVec3, w: glam::DVec3| (w - u).cross(q - u).dot(n);
        let sides = [edge(a, b), edge(b, c), edge(c, a)];
        crossed && (sides.iter().all(|&e| e >= 0.0) || sides.iter().all(|&e| e <= 0.0))
    })
}

/// Whether the edges `e` and `g` go through each other during the substep: the volume of
/// their tetrahedron changes sign where their closest points lie within both.
fn through_edge(start: &[Vec3], end: &[Vec3], e: [u32; 2], g: [u32; 2]) -> bool {
    let volume = |t: f64| {
        let [a, b, c, d] = [e[0], e[1], g[0], g[1]].map(|k| along(start, end, k, t));
        ((b - a).cross(d - c).dot(c - a), [a, b, c, d])
    };
    let mut before = volume(0.0).0;
    (1..=SAMPLES).any(|s| {
        let (v, [a, b, c, d]) = volume(f64::from(s) / f64::from(SAMPLES));
        let crossed = (v > 0.0) != (before > 0.0);
        before = v;
        let (u, w, r) = (b - a, d - c, a - c);
        let (uu, uw, ww, ur, wr) = (u.dot(u), u.dot(w), w.dot(w), u.dot(r), w.dot(r));
        let den = uu * ww - uw * uw;
        crossed && den > 0.0 && {
            let (s, t) = ((uw * wr - ww * ur) / den, (uu * wr - uw * ur) / den);
            (0.0..=1.0).contains(&s) && (0.0..=1.0).contains(&t)
        }
    })
}

/// How the pairs that came to intersect in one run did: a corner through a face that contact
/// skips (within the thickness of the face's box in the rest shape), a corner through a face
/// it tests, an edge through an edge only, or neither found.
#[derive(Default)]
struct Events {
    skipped_face: usize,
    tested_face: usize,
    edge_only: usize,
    neither: usize,
}

pub(crate) fn self_contact_events(bunny: &ObjMesh) {
    println!("\n## Self-contact: how a fast fold's layers get through each other (CPU)\n");
    println!(
        "The core's bunny fold: a 64 x 64 cloth of 1 m, self-contact {} mm (friction 0.3), block descent at Looper 16, thrown down at the speed given from 0.1 m above the bundled bunny (exact contact at n = 5, margin 5 mm, friction 1), 0.12 m off its centre; 1 s, stepped one substep at a time. After each substep, every pair of triangles sharing no corner that intersects (an exact segment–triangle test of each edge) and did not after the substep before is an event, sorted by what went through what over the substep, each particle taken along a straight line ({SAMPLES} steps): a corner of one through the face of the other, the face one that contact skips for that corner (the corner within the thickness of the face's box in the rest shape: a neighbour on the cloth) or one it tests; or else an edge through an edge. At 1 s, the closest pair of particles that share no spring and lie at least the thickness apart in the rest shape, and the pairs of them closer than half the thickness.\n",
        SELF_CONTACT.thickness * 1e3
    );
    println!(
        "| speed m/s | events | a corner through a face contact skips | through a face it tests | an edge through an edge only | neither | intersecting pairs at 1 s | closest pair at 1 s mm | close pairs at 1 s |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    let collider = Collider::from_mesh_exact(bunny.as_mesh_ref(), 5)
        .expect("the bundled bunny")
        .with_margin(0.005)
        .with_friction(1.0);
    let top = bunny.positions.iter().map(|p| p[1]).fold(f32::MIN, f32::max);
    let grid = ClothGrid::new(Vec2::ONE, UVec2::splat(64));
    let topology = Arc::new(ClothTopology::grid(grid).expect("a valid grid"));
    let triangles = topology.triangles().to_vec();
    let rest = topology.rest_positions();
    let skipped = |v: u32, f: [u32; 3]| {
        let (lo, hi) = f.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &k| {
            (lo.min(rest[k as usize]), hi.max(rest[k as usize]))
        });
        let r = rest[v as usize];
        (lo - r).max(r - hi).max(Vec3::ZERO).length() < SELF_CONTACT.thickness
    };
    for speed in [7.0f32, 15.0] {
        // One substep a tick of 1/960 s: the substeps of Looper 16 at 60 Hz, checked between.
        let params = ClothParams {
            self_contact: Some(SELF_CONTACT),
            looper: 1,
            integrator: Integrator::BLOCK_DESCENT,
            ..Default::default()
        };
        let pose = Affine3A::from_translation(Vec3::new(0.12, top + 0.1, 0.0));
        let mut sim = ClothSim::new(params, Arc::clone(&topology), pose, &[]).expect("a valid cloth");
        for i in 0..sim.len() {
            sim.set_velocity(i, Vec3::new(0.0, -speed, 0.0));
        }
        let (mut known, mut events) = (std::collections::HashSet::new(), Events::default());
        for _ in 0..960 {
            let start = sim.positions();
            sim.tick(TICK / 16.0, std::slice::from_ref(&collider));
            let end = sim.positions();
            let now: std::collections::HashSet<(usize, usize)> =
                intersecting_pairs(&triangles, &end, None).into_iter().collect();
            for &(i, j) in now.difference(&known) {
                let (a, b) = (triangles[i], triangles[j]);
                let faces: Vec<bool> = a
                    .iter()
                    .filter(|&&v| through_face(&start, &end, v, b))
                    .map(|&v| skipped(v, b))
                    .chain(b.iter().filter(|&&v| through_face(&start, &end, v, a)).map(|&v| skipped(v, a)))
                    .collect();
                let edges = |t: [u32; 3]| [[t[0], t[1]], [t[1], t[2]], [t[2], t[0]]];
                if faces.iter().any(|&skip| !skip) {
                    events.tested_face += 1;
                } else if !faces.is_empty() {
                    events.skipped_face += 1;
                } else if edges(a).iter().any(|&e| edges(b).iter().any(|&g| through_edge(&start, &end, e, g))) {
                    events.edge_only += 1;
                } else {
                    events.neither += 1;
                }
            }
            known = now;
        }
        let Events { skipped_face, tested_face, edge_only, neither } = events;
        let end = sim.positions();
        let close = close_pairs(&topology, &end, None, 0.5 * SELF_CONTACT.thickness);
        println!(
            "| {speed:.0} | {} | {skipped_face} | {tested_face} | {edge_only} | {neither} | {} | {:.2} | {close} |",
            skipped_face + tested_face + edge_only + neither,
            known.len(),
            closest_pair(&topology, &end, SELF_CONTACT.thickness) * 1e3
        );
    }
}

/// The least distance at `x` between two particles of `topology`'s cloth that share no spring
/// and lie at least `thickness` apart in the rest shape (those [`close_pairs`] counts at half
/// the thickness).
fn closest_pair(topology: &ClothTopology, x: &[Vec3], thickness: f32) -> f32 {
    let rest = topology.rest_positions();
    (0..x.len())
        .into_par_iter()
        .map(|i| {
            (i + 1..x.len())
                .filter(|&j| {
                    rest[i].distance(rest[j]) >= thickness
                        && !topology.springs_of(i).iter().any(|e| e.other as usize == j)
                })
                .map(|j| x[i].distance(x[j]))
                .fold(f32::INFINITY, f32::min)
        })
        .reduce(|| f32::INFINITY, f32::min)
}
