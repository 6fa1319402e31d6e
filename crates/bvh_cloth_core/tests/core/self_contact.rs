//! Self-contact (`bvh_cloth_core::self_contact`): a cloth folding over a thin bar, two cloths
//! dropped on each other onto a ball, and bad input. Each scene is run with contact and, as its
//! control, without: the control shows the scene makes the layers meet, and contact keeps them
//! apart. "Apart" is checked two ways: no particle closer than half the thickness to one it
//! shares no spring with, and no two triangles (sharing no corner) that intersect, by an exact
//! segment–triangle test of every edge against every triangle.

use crate::common;

use std::sync::Arc;

use bvh_cloth_core::backend::crossing_pairs as crossing_triangles;
use bvh_cloth_core::backend::{ContactBody, ContactSolver, MAX_TESTS_PER_TRIANGLE, closest_point, particle_spacing};
use bvh_cloth_core::{
    Affine3A, ClothError, ClothParams, ClothSim, ClothTopology, Collider, ColliderPose, Integrator, MeshRef, Primitive,
    Quat, SelfContact, Vec3,
};

/// The contact thickness, in metres (the 48 x 48 cloth of 1 m has a spacing of 21 mm).
const THICKNESS: f32 = 0.01;

fn params(contact: bool, integrator: Integrator) -> ClothParams {
    ClothParams {
        self_contact: contact.then_some(SelfContact { thickness: THICKNESS, friction: 0.3 }),
        integrator,
        ..ClothParams::default()
    }
}

/// Pairs of particles of one cloth closer than `limit` that share no spring and lie farther
/// apart than the thickness in the rest shape.
fn close_pairs(topology: &ClothTopology, x: &[Vec3], limit: f32) -> usize {
    let rest = topology.rest_positions();
    let mut count = 0;
    for i in 0..x.len() {
        for j in i + 1..x.len() {
            if x[i].distance(x[j]) < limit
                && rest[i].distance(rest[j]) >= THICKNESS
                && !topology.springs_of(i).iter().any(|e| e.other as usize == j)
            {
                count += 1;
            }
        }
    }
    count
}

/// Pairs of particles of two cloths closer than `limit`.
fn close_between(a: &[Vec3], b: &[Vec3], limit: f32) -> usize {
    a.iter().map(|p| b.iter().filter(|q| p.distance(**q) < limit).count()).sum()
}

/// A bar of radius 3 cm along Z through the origin (a capsule 2 m long), friction 0.5.
fn thin_bar() -> Collider {
    Collider::primitive(Primitive::Capsule { radius: 0.03, half_length: 1.0 })
        .unwrap()
        .with_pose(ColliderPose { rotation: Quat::from_rotation_x(core::f32::consts::FRAC_PI_2), ..Default::default() })
        .with_friction(0.5)
}

/// A 48 x 48 cloth of 1 m dropped from 0.8 m onto a bar of radius 3 cm (a capsule along Z), off
/// its centre line so that one side is longer: it folds over the bar and its two sides whip
/// down and into each other under it. After 3 s: no close pair, no crossing triangle; without
/// contact the two sides swing through each other (measured: 3,218 crossing triangles; from
/// 0.3 m, where the sides only swing down, none). A
/// thinner bar than the particle spacing would let the cloth slip through between particles.
#[test]
fn a_cloth_folding_over_a_thin_bar_keeps_off_itself() {
    let bar = thin_bar();
    let colliders = [bar];
    let mut results = Vec::new();
    for (contact, integrator) in [(true, Integrator::BLOCK_DESCENT), (false, Integrator::BLOCK_DESCENT)] {
        let topology = common::grid_topology(1.0, 48, 48);
        let pose = Affine3A::from_translation(Vec3::new(0.12, 0.8, 0.0));
        let mut sim = ClothSim::new(params(contact, integrator), Arc::clone(&topology), pose, &[]).unwrap();
        for _ in 0..180 {
            sim.tick(1.0 / 60.0, &colliders);
        }
        assert!(sim.is_finite(), "contact {contact}: the cloth went non-finite");
        let x = sim.positions();
        let close = close_pairs(&topology, &x, 0.5 * THICKNESS);
        let crossing = crossing_triangles(topology.triangles(), &x, None);
        // Hanging over the bar: a side below it, and the fold still on it.
        let on_bar = x.iter().filter(|p| p.truncate().length() < 0.1).count();
        let folded = if on_bar > 200 { x.iter().filter(|p| p.y < -0.2).count() } else { 0 };
        eprintln!(
            "{integrator:?}, contact {contact}: {close} close pairs, {crossing} crossing triangles, {folded} particles hanging"
        );
        results.push((close, crossing, folded));
    }
    let [(close, crossing, folded), (_, control_crossing, _)] = results[..] else { unreachable!() };
    assert!(folded > 800, "{folded} particles hang below the bar: the cloth did not fold over it");
    assert!(control_crossing > 100, "without contact only {control_crossing} triangles cross: the scene tests nothing");
    assert_eq!(close, 0, "particles closer than half the thickness to a non-neighbour");
    assert_eq!(crossing, 0, "the cloth's triangles intersect");
}

/// Two 32 x 32 cloths of 0.8 m dropped 0.1 m apart onto a ball of radius 0.25 m, the upper
/// turned and stepped by RK4, the lower by block descent (and again by the default, the
/// multigrid integrator), together: after 3 s the upper one rests on the lower, none of their
/// particles closer than half the thickness and none of their triangles crossing; stepped
/// together without contact, the upper falls through the lower.
#[test]
fn two_cloths_dropped_on_a_ball_keep_apart() {
    // The lower cloth by block descent, then by the default (the multigrid integrator).
    for integrator in [Integrator::BLOCK_DESCENT, Integrator::default()] {
        two_cloths_on_a_ball_keep_apart(integrator);
    }
}

fn two_cloths_on_a_ball_keep_apart(integrator: Integrator) {
    let ball = Collider::primitive(Primitive::Sphere { radius: 0.25 }).unwrap().with_friction(0.5);
    let colliders = [ball];
    let topology = common::grid_topology(0.8, 32, 32);
    let mut results = Vec::new();
    for contact in [true, false] {
        let thickness = SelfContact { thickness: THICKNESS, friction: 0.3 };
        let p = ClothParams { self_contact: contact.then_some(thickness), integrator, ..ClothParams::default() };
        let place = |y: f32, turn: f32| Affine3A::from_rotation_translation(Quat::from_rotation_y(turn), Vec3::Y * y);
        let mut lower = ClothSim::new(p.clone(), Arc::clone(&topology), place(0.35, 0.0), &[]).unwrap();
        // The upper cloth is RK4: cloths of either integrator step together.
        let rk4 = ClothParams { integrator: Integrator::Rk4, damping: 1.0, ..p.clone() };
        let mut upper = ClothSim::new(rk4, Arc::clone(&topology), place(0.45, 0.4), &[]).unwrap();
        let mut solver = ContactSolver::default();
        for _ in 0..180 {
            ClothSim::tick_together(&mut [&mut lower, &mut upper], 1.0 / 60.0, &colliders, &mut solver);
        }
        let (a, b) = (lower.positions(), upper.positions());
        assert!(lower.is_finite() && upper.is_finite());
        let close = close_between(&a, &b, 0.5 * THICKNESS);
        let crossing = crossing_triangles(topology.triangles(), &a, Some((topology.triangles(), &b)));
        let own = close_pairs(&topology, &a, 0.5 * THICKNESS) + close_pairs(&topology, &b, 0.5 * THICKNESS);
        eprintln!(
            "{integrator:?} below, contact {contact}: {close} close pairs between, {crossing} crossing triangles, {own} close within"
        );
        results.push((close, crossing, own));
    }
    let [(close, crossing, own), (_, control_crossing, _)] = results[..] else { unreachable!() };
    assert!(control_crossing > 100, "{integrator:?}: without contact only {control_crossing} triangles cross");
    assert_eq!(close, 0, "{integrator:?}: particles of the two cloths closer than half the thickness");
    assert_eq!(crossing, 0, "{integrator:?}: triangles of the two cloths intersect");
    assert_eq!(own, 0, "{integrator:?}: a cloth's particles closer than half the thickness to each other");
}

/// Two 32 x 32 cloths of 0.8 m that start crossed along a line (one flat, the other turned
/// 10 degrees about the line across both middles) fall onto a ball together: within 1 s with
/// contact, no triangle of one intersects a triangle of the other, and no particle of one is
/// within half the thickness of the other's; the part of one cloth that started through the
/// other has gone back. Each half second the pairs between them are printed.
#[test]
fn two_cloths_started_crossed_come_apart() {
    let ball = Collider::primitive(Primitive::Sphere { radius: 0.25 }).unwrap().with_friction(0.5);
    let colliders = [ball];
    let topology = common::grid_topology(0.8, 32, 32);
    let params = ClothParams {
        self_contact: Some(SelfContact { thickness: THICKNESS, friction: 0.3 }),
        ..ClothParams::default()
    };
    let middle = Vec3::Y * 0.45;
    let turned = Affine3A::from_rotation_translation(Quat::from_rotation_z(10f32.to_radians()), middle);
    let mut a = ClothSim::new(params.clone(), Arc::clone(&topology), Affine3A::from_translation(middle), &[]).unwrap();
    let mut b = ClothSim::new(params, Arc::clone(&topology), turned, &[]).unwrap();
    let between = |a: &ClothSim, b: &ClothSim| {
        crossing_triangles(topology.triangles(), &a.positions(), Some((topology.triangles(), &b.positions())))
    };
    let start = between(&a, &b);
    assert!(start > 50, "the cloths start crossed at only {start} pairs of triangles");
    let mut solver = ContactSolver::default();
    let mut pairs = vec![start];
    for _ in 0..2 {
        for _ in 0..30 {
            ClothSim::tick_together(&mut [&mut a, &mut b], 1.0 / 60.0, &colliders, &mut solver);
        }
        pairs.push(between(&a, &b));
    }
    let close = close_between(&a.positions(), &b.positions(), 0.5 * THICKNESS);
    eprintln!("two cloths started crossed: {pairs:?} intersecting pairs at 0, 0.5 and 1 s; {close} close pairs at 1 s");
    assert!(a.is_finite() && b.is_finite());
    assert_eq!(pairs[2], 0, "triangles of the two cloths still intersect at 1 s");
    assert_eq!(close, 0, "particles of the two cloths closer than half the thickness at 1 s");
}

/// The folded cloth of [`a_cloth_poked_through_itself_comes_apart`] (with self-contact at
/// [`THICKNESS`], the rest of the parameters the default's): 32 x 66 particles, 0.8 m wide,
/// its lower half 2 cm over the ground and its upper half 5 cm above that, joined by a round
/// fold, the lower half raised by a bump of height `bump` about its middle; and the index of
/// the particle at the top of the bump.
fn folded_cloth(bump: f32) -> (ClothSim, u32) {
    let params = ClothParams {
        self_contact: Some(SelfContact { thickness: THICKNESS, friction: 0.3 }),
        ..ClothParams::default()
    };
    let (cols, rows) = (32u32, 66u32);
    let topology = common::grid_topology(0.8, cols, rows);
    let spacing = 0.8 / (cols - 1) as f32;
    let (floor, radius, width) = (0.02, 3.0 * spacing / core::f32::consts::PI, 0.06);
    let mut cloth = ClothSim::new(params, topology, Affine3A::IDENTITY, &[]).unwrap();
    for r in 0..rows {
        for c in 0..cols {
            let x = -0.4 + c as f32 * spacing;
            let position = match r {
                // The lower half, with the bump about its middle.
                0..=31 => {
                    let z = -0.4 + r as f32 * spacing;
                    Vec3::new(x, floor + bump * (-(x * x + z * z) / (2.0 * width * width)).exp(), z)
                }
                // The fold: a half turn of radius `radius` over three spacings.
                32..=33 => {
                    let angle = (r - 31) as f32 * core::f32::consts::PI / 3.0;
                    Vec3::new(x, floor + radius * (1.0 - angle.cos()), 0.4 + radius * angle.sin())
                }
                // The upper half, back over the lower.
                _ => Vec3::new(x, floor + 2.0 * radius, 0.4 - (r - 34) as f32 * spacing),
            };
            cloth.set_position((r * cols + c) as usize, position);
        }
    }
    // The lower half's particle nearest its middle (x and z both within half a spacing of 0).
    (cloth, 16 * cols + 16)
}

/// The ground the folded cloth lies on (friction 0.5).
fn ground() -> [Collider; 1] {
    [Collider::primitive(Primitive::HalfSpace { normal: Vec3::Y }).unwrap().with_friction(0.5)]
}

/// Ticks `cloth` alone on `colliders` for a second with `solver`: the pairs of its triangles
/// that intersect after 0.5 s and after 1 s, and its close pairs at the end.
fn one_second(cloth: &mut ClothSim, colliders: &[Collider], solver: &mut ContactSolver) -> ([usize; 2], usize) {
    let topology = Arc::clone(cloth.topology());
    let pairs = [(); 2].map(|_| {
        for _ in 0..30 {
            ClothSim::tick_together(&mut [&mut *cloth], 1.0 / 60.0, colliders, solver);
        }
        crossing_triangles(topology.triangles(), &cloth.positions(), None)
    });
    (pairs, close_pairs(&topology, &cloth.positions(), 0.5 * THICKNESS))
}

/// A cloth folded over itself on the ground (32 x 66 particles, 0.8 m wide, its lower half and
/// its upper half 5 cm apart, joined by a round fold), with a bump of its lower half poked
/// up through its upper half, as a pin dragged through it would leave it: a closed curve of
/// intersection on each half. Contact alone keeps each particle on the side it is on, so the
/// bump stays through; the untangling finds the two rings of cut triangles, the bump's tip and
/// the patch of the upper half it passes through, and takes the smaller back through the
/// other. Within 1 s no two triangles of the cloth intersect, and no two particles that share
/// no spring lie closer than half the thickness.
#[test]
fn a_cloth_poked_through_itself_comes_apart() {
    let (mut cloth, _) = folded_cloth(0.15);
    let start = crossing_triangles(cloth.topology().triangles(), &cloth.positions(), None);
    assert!(start > 20, "the bump crosses the upper half at only {start} pairs of triangles");
    let ([half, end], close) = one_second(&mut cloth, &ground(), &mut ContactSolver::default());
    eprintln!(
        "a cloth poked through itself: {:?} intersecting pairs at 0, 0.5 and 1 s; {close} close pairs at 1 s",
        [start, half, end]
    );
    assert!(cloth.is_finite());
    assert_eq!(end, 0, "triangles of the cloth still intersect each other at 1 s");
    assert_eq!(close, 0, "particles of the cloth closer than half the thickness at 1 s");
}

/// The same folded cloth without the bump, its lower half's middle particle pinned and
/// dragged straight up through the upper half (2.5 cm a tick, 0.2 m in all: a pin moved by an
/// animation jumps, and contact cannot hold what a pin forces), then released: the dragged
/// bump lies through the upper half when the pin lets go, and within 1 s after that no two
/// triangles of the cloth intersect.
#[test]
fn a_pin_dragged_through_the_cloth_leaves_no_tangle() {
    let colliders = ground();
    let (mut cloth, middle) = folded_cloth(0.0);
    let topology = Arc::clone(cloth.topology());
    let crossing = |cloth: &ClothSim| crossing_triangles(topology.triangles(), &cloth.positions(), None);
    let mut solver = ContactSolver::default();
    cloth.set_pins(&[middle]).unwrap();
    let start = cloth.position(middle as usize);
    let mut most = 0;
    for tick in 1..=8 {
        cloth.move_pins(&[(middle, start + Vec3::Y * (0.025 * tick as f32))]);
        ClothSim::tick_together(&mut [&mut cloth], 1.0 / 60.0, &colliders, &mut solver);
        most = most.max(crossing(&cloth));
    }
    let released = crossing(&cloth);
    cloth.set_pins(&[]).unwrap();
    let ([half, end], close) = one_second(&mut cloth, &colliders, &mut solver);
    eprintln!(
        "a pin dragged through the cloth: at most {most} intersecting pairs while dragged; {:?} at the release, 0.5 and 1 s after; {close} close pairs at 1 s",
        [released, half, end]
    );
    assert!(cloth.is_finite());
    assert!(released > 10, "the drag left only {released} intersecting pairs: the scene does not tangle the cloth");
    assert_eq!(end, 0, "triangles of the cloth still intersect each other 1 s after the release");
    assert_eq!(close, 0, "particles of the cloth closer than half the thickness 1 s after the release");
}

/// Thicknesses below zero, NaN and above the particle spacing are refused, naming the field; so
/// is a negative friction.
#[test]
fn bad_thickness_and_friction_are_refused() {
    let topology = common::grid_topology(1.0, 48, 48);
    let spacing = particle_spacing(&topology);
    assert!((spacing - 1.0 / 47.0).abs() < 1e-6, "spacing {spacing}");
    for thickness in [-0.01, f32::NAN, f32::INFINITY, -0.0 - f32::MIN_POSITIVE] {
        let contact = SelfContact { thickness, friction: 0.0 };
        let err = contact.validate_for(&topology).unwrap_err();
        assert!(err.to_string().contains("self_contact.thickness"), "{err}");
        let p = ClothParams { self_contact: Some(contact), ..ClothParams::default() };
        assert!(ClothSim::new(p, Arc::clone(&topology), Affine3A::IDENTITY, &[]).is_err());
    }
    let thick = SelfContact { thickness: 0.05, friction: 0.0 };
    let err = thick.validate_for(&topology).unwrap_err();
    assert!(matches!(err, ClothError::ThicknessAboveSpacing { .. }), "{err}");
    assert!(err.to_string().contains("self_contact.thickness"), "{err}");
    let err = SelfContact { thickness: 0.01, friction: -1.0 }.validate().unwrap_err();
    assert!(err.to_string().contains("self_contact.friction"), "{err}");
}

/// `SelfContact::default()` fits any cloth: its thickness of 0 becomes half of each cloth's
/// own particle spacing when the cloth is built (and when its parameters change), on a coarse
/// and a fine grid alike.
#[test]
fn the_default_thickness_is_half_of_each_cloths_spacing() {
    for (side, cells) in [(1.0, 8), (1.0, 96), (3.0, 24)] {
        let topology = common::grid_topology(side, cells, cells);
        let spacing = particle_spacing(&topology);
        let p = ClothParams { self_contact: Some(SelfContact::default()), ..ClothParams::default() };
        let mut sim = ClothSim::new(p.clone(), Arc::clone(&topology), Affine3A::IDENTITY, &[]).unwrap();
        let resolved = sim.params().self_contact.unwrap();
        assert!((resolved.thickness - 0.5 * spacing).abs() < 1e-7, "{} for a spacing of {spacing}", resolved.thickness);
        assert_eq!(resolved.friction, 0.3);
        sim.set_params(p).unwrap();
        assert_eq!(sim.params().self_contact.unwrap().thickness, resolved.thickness);
        // A thickness given is kept.
        let given = SelfContact { thickness: 0.25 * spacing, friction: 0.1 };
        sim.set_params(ClothParams { self_contact: Some(given), ..ClothParams::default() }).unwrap();
        assert_eq!(sim.params().self_contact, Some(given));
    }
}

/// Every particle of a 64 x 64 cloth at one point: the walk of the triangles' tree stops at
/// `MAX_TESTS_PER_TRIANGLE` node pairs per triangle and reports what it left, the pass ends,
/// nothing goes non-finite, and the particles move apart.
#[test]
fn everything_at_one_point_is_bounded() {
    let topology = common::grid_topology(1.0, 64, 64);
    let n = topology.len();
    let prev = vec![Vec3::splat(0.5); n];
    let mut x = vec![Vec3::splat(0.5); n];
    let mut v = vec![Vec3::ZERO; n];
    let free = vec![1.0; n];
    let contact = SelfContact { thickness: THICKNESS, friction: 0.3 };
    let mut solver = ContactSolver::default();
    let stats = solver.resolve(
        &mut [ContactBody {
            topology: &topology,
            contact,
            layers: Default::default(),
            free: &free,
            held: &[],
            prev: &prev,
            x: &mut x,
            v: &mut v,
        }],
        &[],
    );
    assert!(stats.clamped > 0, "the walk met no bound");
    // Each node pair tested brings at most one pair of triangles, which stands for at most six
    // point-triangle and nine edge-edge contacts, each counted by four particles.
    let tests = MAX_TESTS_PER_TRIANGLE * topology.triangles().len();
    assert!(stats.contacts <= tests * 15 * 4, "{} contacts", stats.contacts);
    assert!(x.iter().chain(&v).all(|p| p.is_finite()), "a particle went non-finite");
    let spread = x.iter().map(|p| p.distance(Vec3::splat(0.5))).fold(0.0f32, f32::max);
    assert!(spread > 0.1 * THICKNESS, "the particles did not move apart ({spread} m)");
}

/// `topology`'s rest positions moved to height `y` (the tests' sheets lie flat).
fn flat(topology: &ClothTopology, y: f32) -> Vec<Vec3> {
    topology.rest_positions().iter().map(|p| Vec3::new(p.x, y, p.z)).collect()
}

/// What one substep of contact left: the stats, the lower body's positions, and the upper
/// body's positions and velocities.
struct Substep {
    stats: bvh_cloth_core::self_contact::ContactStats,
    lower: Vec<Vec3>,
    upper: Vec<Vec3>,
    upper_v: Vec<Vec3>,
}

/// One [`ContactSolver::resolve`] of two bodies with contact at [`THICKNESS`] and no friction:
/// `lower` lying flat at rest at `y = 0`, its particles' `free` and `held` masks as given, and
/// `upper` (every particle free) that went flat from height `from` to height `to` during the
/// substep, moving at `speed` downwards.
fn flat_substep(
    lower: (&ClothTopology, &[f32], &[f32]),
    upper: &ClothTopology,
    heights: (f32, f32),
    speed: f32,
) -> Substep {
    flat_substep_with(&mut ContactSolver::default(), lower, upper, heights, speed)
}

/// [`flat_substep`] with `solver`.
fn flat_substep_with(
    solver: &mut ContactSolver,
    (lower, free, held): (&ClothTopology, &[f32], &[f32]),
    upper: &ClothTopology,
    (from, to): (f32, f32),
    speed: f32,
) -> Substep {
    let contact = SelfContact { thickness: THICKNESS, friction: 0.0 };
    let (lower_prev, upper_prev) = (flat(lower, 0.0), flat(upper, from));
    let (mut lower_x, mut upper_x) = (lower_prev.clone(), flat(upper, to));
    let mut lower_v = vec![Vec3::ZERO; lower.len()];
    let mut upper_v = vec![Vec3::new(0.0, -speed, 0.0); upper.len()];
    let upper_free = vec![1.0; upper.len()];
    let stats = solver.resolve(
        &mut [
            ContactBody {
                layers: Default::default(),
                topology: lower,
                contact,
                free,
                held,
                prev: &lower_prev,
                x: &mut lower_x,
                v: &mut lower_v,
            },
            ContactBody {
                layers: Default::default(),
                topology: upper,
                contact,
                free: &upper_free,
                held: &[],
                prev: &upper_prev,
                x: &mut upper_x,
                v: &mut upper_v,
            },
        ],
        &[],
    );
    Substep { stats, lower: lower_x, upper: upper_x, upper_v }
}

/// A small sheet that went through a large pinned one during the substep, from 3 mm above to 3
/// mm below, is put back above it at the thickness; given the same end positions but starting
/// below, it is held below. The side comes from where the points were, not where they are.
#[test]
fn a_point_that_went_through_goes_back_to_its_side() {
    let floor = common::grid_topology(1.0, 2, 2);
    let sheet = common::grid_topology(0.1, 2, 2);
    for (from, want_above) in [(0.003, true), (-0.004, false)] {
        let after = flat_substep((&floor, &[0.0; 4], &[]), &sheet, (from, -0.003), 1.0);
        for p in &after.upper {
            if want_above {
                assert!((p.y - THICKNESS).abs() < 1e-5, "from above: the point ends at {}", p.y);
            } else {
                assert!((p.y + THICKNESS).abs() < 1e-5, "from below: the point ends at {}", p.y);
            }
        }
        assert_eq!(after.lower, flat(&floor, 0.0), "the pinned sheet moved");
    }
}

/// A solver kept from one pair of cloths for another builds its tree of their triangles again:
/// a sheet through a pinned floor after a smaller sheet through it comes out as from a new
/// solver, bit for bit.
#[test]
fn a_solver_kept_for_other_cloths_builds_its_tree_again() {
    let floor = common::grid_topology(1.0, 4, 4);
    let pinned = vec![0.0; floor.len()];
    let (small, large) = (common::grid_topology(0.1, 2, 2), common::grid_topology(0.3, 5, 5));
    let through = |solver: &mut ContactSolver, sheet: &ClothTopology| {
        flat_substep_with(solver, (&floor, &pinned, &[]), sheet, (0.003, -0.003), 1.0)
    };
    let fresh = through(&mut ContactSolver::default(), &large);
    assert!(fresh.stats.contacts > 0, "no contact");
    let mut kept = ContactSolver::default();
    assert!(through(&mut kept, &small).stats.contacts > 0, "no contact");
    let again = through(&mut kept, &large);
    assert_eq!(again.stats, fresh.stats);
    assert_eq!(again.upper, fresh.upper);
    assert_eq!(again.upper_v, fresh.upper_v);
}

/// A solver kept for a cloth whose rest shape changed, its particles and triangles the same,
/// takes the new rest shape's neighbours: one body of two sheets, a pinned one at y = 0 and a
/// small one going through it during the substep, whose rest shape first holds the small sheet
/// 0.5 m above the large one (two layers: it goes back) and then in its plane (neighbours on
/// the cloth: no contact), comes out as from a new solver.
#[test]
fn a_solver_kept_for_a_new_rest_shape_takes_its_neighbours() {
    let sheets = |height: f32| {
        let positions = [
            [-0.1, 0.0, -0.1],
            [0.1, 0.0, -0.1],
            [0.1, 0.0, 0.1],
            [-0.1, 0.0, 0.1],
            [-0.01, height, -0.01],
            [0.01, height, -0.01],
            [0.01, height, 0.01],
            [-0.01, height, 0.01],
        ];
        let indices = [0, 1, 2, 0, 2, 3, 4, 5, 6, 4, 6, 7];
        ClothTopology::from_mesh(MeshRef { positions: &positions, indices: Some(&indices) }).unwrap()
    };
    let (apart, together) = (sheets(0.5), sheets(0.0));
    let free = [0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0];
    let through = |solver: &mut ContactSolver, topology: &ClothTopology| {
        let at = |y: f32| -> Vec<Vec3> {
            let rest = topology.rest_positions();
            (0..8).map(|k| if k < 4 { rest[k] } else { Vec3::new(rest[k].x, y, rest[k].z) }).collect()
        };
        let (prev, mut x) = (at(0.003), at(-0.003));
        let mut v = vec![Vec3::new(0.0, -1.0, 0.0); 8];
        let contact = SelfContact { thickness: THICKNESS, friction: 0.0 };
        let body = ContactBody {
            layers: Default::default(),
            topology,
            contact,
            free: &free,
            held: &[],
            prev: &prev,
            x: &mut x,
            v: &mut v,
        };
        let stats = solver.resolve(&mut [body], &[]);
        (stats, x, v)
    };
    let mut kept = ContactSolver::default();
    let (stats, x, _) = through(&mut kept, &apart);
    assert!(stats.contacts > 0 && x[4].y > 0.0, "two layers apart in the rest shape: the sheet goes back");
    let fresh = through(&mut ContactSolver::default(), &together);
    assert_eq!(fresh.0.contacts, 0, "neighbours in the rest shape: no contact");
    assert_eq!(through(&mut kept, &together), fresh);
}

/// Two strips 2 cm wide laid crosswise, one pinned at y = 0 and the other moving from 3 mm above
/// to 3 mm below it during the substep: their long edges pass through each other in the 2 cm
/// square where they overlap, and no particle of either comes within 0.48 m of a triangle of the
/// other, so only edge against edge sees it. The moving strip goes back above the pinned one,
/// its edges the thickness apart from the other's; given the same end positions but starting
/// below, it is held the thickness below. Points against triangles alone leave the strips
/// crossed.
#[test]
fn edges_that_went_through_edges_go_back_to_their_side() {
    let strip = |corners: [[f32; 3]; 4]| {
        ClothTopology::from_mesh(MeshRef { positions: &corners, indices: Some(&[0, 1, 2, 0, 2, 3]) }).unwrap()
    };
    let pinned_strip = strip([[-0.5, 0.0, -0.02], [0.5, 0.0, -0.02], [0.5, 0.0, 0.0], [-0.5, 0.0, 0.0]]);
    let moving_strip = strip([[-0.02, 0.0, -0.5], [0.0, 0.0, -0.5], [0.0, 0.0, 0.5], [-0.02, 0.0, 0.5]]);
    // No particle of either strip within 0.4 m of a triangle of the other, where it starts or
    // where it ends: only edges meet edges.
    let farthest_reach = |points: &[Vec3], topology: &ClothTopology, at: &[Vec3]| {
        let triangles = topology.triangles().iter().map(|t| t.map(|k| at[k as usize]));
        triangles.flat_map(|t| points.iter().map(move |&p| p.distance(closest_point(p, t)))).fold(f32::MAX, f32::min)
    };
    let floor = flat(&pinned_strip, 0.0);
    for (from, above) in [(0.003, true), (-0.004, false)] {
        for points in [flat(&moving_strip, from), flat(&moving_strip, -0.003)] {
            assert!(farthest_reach(&points, &pinned_strip, &floor) > 0.4, "a point reaches the pinned strip");
            assert!(farthest_reach(&floor, &moving_strip, &points) > 0.4, "a point reaches the moving strip");
        }
        let after = flat_substep((&pinned_strip, &[0.0; 4], &[]), &moving_strip, (from, -0.003), 0.36);
        assert!(after.stats.contacts > 0, "no contact");
        assert_eq!(after.lower, floor, "the pinned strip moved");
        // Each edge contact puts the pair's closest points the thickness apart; the strip's
        // ends, at up to 4% of its length from the middle, take shares of 0.48 to 0.52.
        let sign = if above { 1.0 } else { -1.0 };
        for p in &after.upper {
            assert!((p.y * sign - THICKNESS).abs() < 0.1 * THICKNESS, "from {from} m: a particle ends at {}", p.y);
        }
        // From above its approach speed (0.36 m/s) is taken off, but for the shares' spread.
        if above {
            let v = &after.upper_v;
            assert!(v.iter().all(|v| v.y.abs() < 0.03), "from {from} m: the strip still approaches: {v:?}");
        }
    }
}

/// A free sheet that a collider holds (every particle touched in the substep) does not yield to
/// a small free sheet pressed 2 mm into it from above: the small sheet alone goes back the whole
/// thickness. The control, the same sheets with nothing held, share the correction and the
/// large sheet moves down.
#[test]
fn a_particle_a_collider_holds_does_not_yield() {
    let floor = common::grid_topology(1.0, 2, 2);
    let sheet = common::grid_topology(0.1, 2, 2);
    for held in [vec![1.0; 4], vec![]] {
        let after = flat_substep((&floor, &[1.0; 4], &held), &sheet, (0.004, 0.002), 1.0);
        assert!(after.stats.contacts > 0);
        let gap = after.upper.iter().map(|p| p.y).fold(f32::INFINITY, f32::min)
            - after.lower.iter().map(|p| p.y).fold(f32::NEG_INFINITY, f32::max);
        if held.is_empty() {
            assert!(after.lower.iter().any(|p| p.y < -1e-4), "with nothing held the large sheet yields");
        } else {
            assert_eq!(after.lower, flat(&floor, 0.0), "the held sheet moved");
            let (x, v) = (&after.upper, &after.upper_v);
            assert!(x.iter().all(|p| (p.y - THICKNESS).abs() < 1e-5), "the small sheet ends at {x:?}");
            assert!(v.iter().all(|v| v.y.abs() < 1e-5), "the small sheet still approaches: {v:?}");
        }
        assert!(gap > 0.0, "the sheets cross");
    }
}

/// A 64 x 64 cloth of 1 m with self-contact at 8 mm (or none) thrown down at `speed` from 0.1 m
/// above `top`, the highest point of `collider`, 0.12 m off its centre: where the collider stops
/// its middle, its sides wrap round and whip into each other at up to twice that speed. After
/// 1 s: the crossing triangle pairs, the close pairs (closer than half the thickness) and the
/// fastest particle's speed over the second.
fn fast_fold(collider: &Collider, top: f32, speed: f32, contact: bool, integrator: Integrator) -> (usize, usize, f32) {
    let topology = common::grid_topology(1.0, 64, 64);
    let params = ClothParams {
        self_contact: contact.then_some(SelfContact { thickness: 0.008, friction: 0.3 }),
        integrator,
        ..ClothParams::default()
    };
    let pose = Affine3A::from_translation(Vec3::new(0.12, top + 0.1, 0.0));
    let mut sim = ClothSim::new(params, Arc::clone(&topology), pose, &[]).unwrap();
    for i in 0..sim.len() {
        sim.set_velocity(i, Vec3::new(0.0, -speed, 0.0));
    }
    let mut fastest = 0.0f32;
    for _ in 0..60 {
        sim.tick(1.0 / 60.0, std::slice::from_ref(collider));
        fastest = fastest.max(sim.velocities().iter().map(|v| v.length()).fold(0.0, f32::max));
    }
    assert!(sim.is_finite());
    let x = sim.positions();
    (crossing_triangles(topology.triangles(), &x, None), close_pairs(&topology, &x, 0.004), fastest)
}

/// The colliders the fast folds land on, each with its top: the thin bar and the bundled bunny
/// (exact contact at n = 5, margin 5 mm, friction 1).
fn fold_scenes() -> [(&'static str, Collider, f32); 2] {
    let mesh = common::bundled_model("bunny");
    let bunny = Collider::from_mesh_exact(mesh.as_mesh_ref(), 5).unwrap().with_margin(0.005).with_friction(1.0);
    let bunny_top = mesh.positions.iter().map(|p| p[1]).fold(f32::MIN, f32::max);
    [("bar", thin_bar(), 0.03), ("bunny", bunny, bunny_top)]
}

/// Folds at speed: the 64 x 64 cloth thrown at 7 and 15 m/s onto a bar of radius 3 cm and onto
/// the bundled bunny (exact contact at n = 5, margin 5 mm, friction 1), at the default (the
/// multigrid integrator, whose correction moves whole aggregates at once and so whips the
/// layers harder), ends 1 s later with no close pair and no crossing triangle pair, where
/// without contact its layers cross. The correction leaves alone the particles self-contact
/// moved after the last substep, as it does those a collider held; without that, the bunny at
/// 7 m/s ended with 3 crossing pairs. With Gauss–Seidel sweeps on the coarse levels in place of
/// damped Jacobi steps, the bar at 15 m/s ended with 4.
#[test]
fn fast_folds_keep_off_themselves() {
    for (scene, collider, top) in fold_scenes() {
        let collider = &collider;
        for speed in [7.0, 15.0] {
            let (crossing, close, fastest) = fast_fold(collider, top, speed, true, Integrator::default());
            let (control, _, _) = fast_fold(collider, top, speed, false, Integrator::default());
            eprintln!(
                "{scene} at {speed} m/s: {crossing} crossing pairs, {close} close pairs, fastest {fastest:.1} m/s; \
                 without contact {control} crossing pairs"
            );
            assert!(control > 0, "{scene} at {speed} m/s: without contact nothing crosses, the scene tests nothing");
            assert_eq!(crossing, 0, "{scene} at {speed} m/s: the cloth's triangles intersect");
            assert_eq!(close, 0, "{scene} at {speed} m/s: particles closer than half the thickness");
        }
    }
}

/// The same folds with block descent's one sweep. A point is tested against the triangles its
/// path over the substep met, not only those it ends near, and an edge against the edges it
/// passed: with points tested at the end alone, the bar at 15 m/s ended with 20 crossing pairs
/// and the bunny at 15 m/s with 138; with swept points and no edges, the bunny at 15 m/s ended
/// with 16 (measured with this integrator).
#[test]
fn fast_folds_keep_off_themselves_with_block_descent() {
    for (scene, collider, top) in fold_scenes() {
        let collider = &collider;
        for speed in [7.0, 15.0] {
            let (crossing, close, fastest) = fast_fold(collider, top, speed, true, Integrator::BLOCK_DESCENT);
            eprintln!(
                "block descent, {scene} at {speed} m/s: {crossing} crossing pairs, {close} close pairs, fastest {fastest:.1} m/s"
            );
            assert_eq!(crossing, 0, "{scene} at {speed} m/s: crossing triangle pairs");
            assert_eq!(close, 0, "{scene} at {speed} m/s: particles closer than half the thickness");
        }
    }
}
