//! Anchors: groups of particles chosen by index, painted weight or region, carried by another
//! entity tick by tick; a target that goes away.

use bevy::mesh::VertexAttributeValues;
use bevy::prelude::*;
use bevy_bvh_cloth::bvh_cloth_core::{Affine3A, ClothError};
use bevy_bvh_cloth::prelude::*;

use crate::headless::authored::{pole_vertices, seamed_flag};
use crate::headless::harness::{add_mesh, app, app_at, max_distance, positions, run, sent};

/// The first row of a 1 m grid (z = -0.5 in its local frame).
fn first_row() -> ClothPins {
    ClothPins::Region { min: Vec3::new(-1.0, -0.01, -0.51), max: Vec3::new(1.0, 0.01, -0.49) }
}

fn rigid(transform: &GlobalTransform) -> Affine3A {
    let (_, rotation, translation) = transform.to_scale_rotation_translation();
    Affine3A::from_rotation_translation(rotation, translation)
}

fn lerp_pose(from: &Affine3A, to: &Affine3A, t: f32) -> Affine3A {
    let (_, r0, t0) = from.to_scale_rotation_translation();
    let (_, r1, t1) = to.to_scale_rotation_translation();
    Affine3A::from_rotation_translation(r0.slerp(r1, t), t0.lerp(t1, t))
}

#[test]
fn an_anchored_row_rides_its_target_tick_by_tick_as_the_core_would() {
    // Four ticks per frame, so the target's motion within a frame must be spread over them.
    let mut app = app_at(15.0);
    let pole = app.world_mut().spawn(Transform::from_xyz(0.5, 2.0, -0.5)).id();
    let cloth_pose = Transform::from_xyz(0.0, 2.0, 0.0);
    let cloth = Cloth { params: ClothParams { damping: 0.5, ..default() }, ..Cloth::grid(Vec2::ONE, UVec2::splat(8)) }
        .with_anchor(ClothAnchor::new(first_row(), pole));
    let cloth = app.world_mut().spawn((cloth, cloth_pose)).id();
    app.update();

    let state = app.world().get::<ClothSimulation>(cloth).expect("the cloth is simulated");
    assert_eq!(state.sim().pins(), &[0, 1, 2, 3, 4, 5, 6, 7], "the region picks the first row");
    // The core's own cloth, from the plugin's state after its first frame, moved by hand.
    let mut core = state.sim().clone();
    let rest = core.topology().rest_positions().to_vec();
    let mut was = rigid(app.world().get::<GlobalTransform>(pole).unwrap());
    let bound: Vec<(u32, Vec3)> =
        (0..8).map(|i| (i, was.inverse().transform_point3(cloth_pose.transform_point(rest[i as usize])))).collect();

    // One second: the pole swings and climbs while the cloth entity stays put.
    for frame in 1..=15 {
        let t = frame as f32 / 15.0;
        *app.world_mut().get_mut::<Transform>(pole).unwrap() =
            Transform::from_xyz(0.5 + 0.3 * t, 2.0 + 0.4 * t, -0.5).with_rotation(Quat::from_rotation_y(2.0 * t));
        app.update();
        let clock = app.world().resource::<ClothClock>();
        let (ticks, dt) = (clock.ticks, clock.tick_seconds);
        assert_eq!(ticks, 4);
        let now = rigid(app.world().get::<GlobalTransform>(pole).unwrap());
        for k in 1..=ticks {
            let pose = lerp_pose(&was, &now, k as f32 / ticks as f32);
            let targets: Vec<(u32, Vec3)> = bound.iter().map(|&(i, local)| (i, pose.transform_point3(local))).collect();
            core.move_pins(&targets);
            core.tick(dt, &[]);
        }
        was = now;
    }
    let p = positions(&app, cloth);
    let gap = max_distance(&p, &core.positions());
    assert!(gap < 1e-5, "the plugin's anchored cloth is {gap} m from the core's");
    for &(i, local) in &bound {
        let target = was.transform_point3(local);
        assert!(p[i as usize].distance(target) < 1e-5, "anchored particle {i} at {} not {target}", p[i as usize]);
    }
    // The rest of the cloth hangs below the row it is held by.
    assert!(p[8..].iter().all(|q| q.y < was.translation.y + 1e-3));
}

#[test]
fn the_offset_moves_the_group_along_the_target_axes_without_a_rebuild() {
    let mut app = app();
    let turned = Transform::from_xyz(1.0, 2.0, 0.0).with_rotation(Quat::from_rotation_z(core::f32::consts::FRAC_PI_2));
    let pole = app.world_mut().spawn(turned).id();
    let cloth = app
        .world_mut()
        .spawn((
            Cloth::grid(Vec2::ONE, UVec2::splat(8)).with_anchor(ClothAnchor::new(ClothPins::Indices(vec![0, 7]), pole)),
            Transform::from_xyz(0.0, 2.0, 0.0),
        ))
        .id();
    run(&mut app, 0.5);
    let held = |app: &App| {
        let p = positions(app, cloth);
        [p[0], p[7]]
    };
    let before = held(&app);
    let moving = positions(&app, cloth);
    // Ten centimetres along the pole's own y axis, which the turn points along world -x.
    app.world_mut().get_mut::<Cloth>(cloth).unwrap().anchors[0].offset = Vec3::new(0.0, 0.1, 0.0);
    app.update();
    let after = held(&app);
    for (a, b) in after.iter().zip(&before) {
        assert!(a.distance(*b + Vec3::new(-0.1, 0.0, 0.0)) < 1e-5, "{a} should be 10 cm along -x of {b}");
    }
    // Not rebuilt: the free particles carried on from where they were (the flat rest pose is
    // at y = 2 m; half a second of falling put them well below it).
    let p = positions(&app, cloth);
    assert!(moving[8..].iter().all(|q| q.y < 2.0 - 0.1));
    assert!(p[8..].iter().all(|q| q.y < 2.0 - 0.1), "the cloth was rebuilt at rest");
}

#[test]
fn a_despawned_target_is_reported_once_and_its_particles_stay_put() {
    let mut app = app();
    let pole = app.world_mut().spawn(Transform::from_xyz(0.0, 2.0, -0.5)).id();
    let cloth = app
        .world_mut()
        .spawn((
            Cloth { params: ClothParams { damping: 1.0, ..default() }, ..Cloth::grid(Vec2::ONE, UVec2::splat(8)) }
                .with_anchor(ClothAnchor::new(first_row(), pole)),
            Transform::from_xyz(0.0, 2.0, 0.0),
        ))
        .id();
    // A target that never existed: the particles it names are held where the cloth starts.
    let nobody = app.world_mut().spawn_empty().id();
    app.world_mut().despawn(nobody);
    let orphan = app
        .world_mut()
        .spawn((
            Cloth::grid(Vec2::ONE, UVec2::splat(8)).with_anchor(ClothAnchor::new(ClothPins::TwoEnds, nobody)),
            Transform::from_xyz(3.0, 2.0, 0.0),
        ))
        .id();
    let free =
        app.world_mut().spawn((Cloth::grid(Vec2::ONE, UVec2::splat(8)), Transform::from_xyz(-3.0, 2.0, 0.0))).id();
    for frame in 1..=30 {
        *app.world_mut().get_mut::<Transform>(pole).unwrap() = Transform::from_xyz(0.01 * frame as f32, 2.0, -0.5);
        app.update();
    }
    let lost = |app: &App, entity, target| {
        sent(app).iter().filter(|m| **m == ClothMessage::AnchorLost { entity, target }).count()
    };
    assert_eq!(lost(&app, cloth, pole), 0);
    assert_eq!(lost(&app, orphan, nobody), 1);
    let orphan_ends = positions(&app, orphan);
    assert!(orphan_ends[0].distance(Vec3::new(2.5, 2.0, -0.5)) < 1e-5, "held at its rest: {}", orphan_ends[0]);
    assert!(orphan_ends[7].distance(Vec3::new(3.5, 2.0, -0.5)) < 1e-5, "held at its rest: {}", orphan_ends[7]);

    let row = positions(&app, cloth)[..8].to_vec();
    app.world_mut().despawn(pole);
    let falling = positions(&app, free);
    run(&mut app, 1.0);
    assert_eq!(lost(&app, cloth, pole), 1, "reported once: {:?}", sent(&app));
    let p = positions(&app, cloth);
    assert_eq!(&p[..8], &row[..], "the row stays where the pole last held it");
    assert!(p.iter().all(|q| q.is_finite()));
    assert!(p[60].y < 2.0 - 0.5, "the rest of the cloth still hangs from the row");
    let fallen = positions(&app, free);
    assert!(fallen.iter().zip(&falling).all(|(a, b)| a.y < b.y - 1.0), "the scene kept running");
}

#[test]
fn painted_and_region_pins_on_an_authored_mesh_pick_the_pole_and_anchors_take_precedence() {
    let mut app = app();
    let mut flag = seamed_flag(13, 9);
    let pole = pole_vertices(&flag);
    let Some(VertexAttributeValues::Float32x3(p)) = flag.attribute(Mesh::ATTRIBUTE_POSITION) else { unreachable!() };
    // An artist's paint: red 1 on the pole, fading to 0 over the first column.
    let colors: Vec<[f32; 4]> = p.iter().map(|p| [(1.0 - p[0] / 0.1).max(0.0), 0.0, 0.0, 1.0]).collect();
    flag.insert_attribute(Mesh::ATTRIBUTE_COLOR, colors);
    let handle = add_mesh(&mut app, flag);
    let painted = ClothPins::Painted { channel: ColorChannel::Red, threshold: 0.99 };
    let region = ClothPins::Region { min: Vec3::new(-0.01, -1.0, -0.01), max: Vec3::new(0.01, 0.1, 0.01) };
    let spawn = |app: &mut App, pins: ClothPins| {
        app.world_mut()
            .spawn((Mesh3d(handle.clone()), Cloth::mesh().with_pins(pins), Transform::from_xyz(0.0, 2.0, 0.0)))
            .id()
    };
    let (by_index, by_paint, by_region) =
        (spawn(&mut app, ClothPins::Indices(pole.clone())), spawn(&mut app, painted), spawn(&mut app, region.clone()));
    // The top half of the pole is carried by another entity; the rest stays on the cloth's.
    let holder = app.world_mut().spawn(Transform::from_xyz(0.0, 2.0, 0.0)).id();
    let top = ClothPins::Region { min: Vec3::new(-0.01, -0.41, -0.01), max: Vec3::new(0.01, 0.1, 0.01) };
    let both = app
        .world_mut()
        .spawn((
            Mesh3d(handle.clone()),
            Cloth::mesh().with_pins(region).with_anchor(ClothAnchor::new(top, holder)),
            Transform::from_xyz(0.0, 2.0, 0.0),
        ))
        .id();
    // Paint on a mesh without colours is refused by name.
    let bare = add_mesh(&mut app, seamed_flag(5, 4));
    let unpainted = app
        .world_mut()
        .spawn((
            Mesh3d(bare),
            Cloth::mesh().with_pins(ClothPins::Painted { channel: ColorChannel::Green, threshold: 0.5 }),
        ))
        .id();
    app.update();
    let pins = |app: &App, entity| app.world().get::<ClothSimulation>(entity).unwrap().sim().pins().to_vec();
    let pole_particles = pins(&app, by_index);
    assert_eq!(pole_particles.len(), 9);
    assert_eq!(pins(&app, by_paint), pole_particles);
    assert_eq!(pins(&app, by_region), pole_particles);
    assert_eq!(pins(&app, both), pole_particles);
    assert!(sent(&app).contains(&ClothMessage::Rejected { entity: unpainted, error: ClothError::PinsNeedColors }));

    // Lift the holder: the top five pole particles (y >= -0.4) rise with it, the others stay.
    *app.world_mut().get_mut::<Transform>(holder).unwrap() = Transform::from_xyz(0.0, 2.3, 0.0);
    run(&mut app, 0.5);
    let sim = app.world().get::<ClothSimulation>(both).unwrap().sim();
    let rest = sim.topology().rest_positions();
    for i in pole_particles {
        let lift = if rest[i as usize].y >= -0.41 { 0.3 } else { 0.0 };
        let want = rest[i as usize] + Vec3::new(0.0, 2.0 + lift, 0.0);
        assert!(
            sim.position(i as usize).distance(want) < 1e-5,
            "pole particle {i} at {} not {want}",
            sim.position(i as usize)
        );
    }
}

/// Pins and anchors changed on a running cloth keep its state, with no rebuild at rest: a
/// 12 x 12 cloth hanging from its two ends for 0.5 s lets one go, and the frame after, its state
/// is the core's after `ClothSim::set_pins` and one tick (the core's own cloth cloned from the
/// plugin's state before the change, to 1e-6 m); 0.5 s on the released corner has fallen. A
/// pin out of range is refused with a message and changes nothing. Then an anchor on a hook
/// catches the corner: it goes to its rest place under the cloth and rides the hook from there.
#[test]
fn a_corner_let_go_and_caught_again_while_the_cloth_moves() {
    let mut app = app();
    let cloth_pose = Transform::from_xyz(0.0, 2.0, 0.0);
    let grid = Cloth { params: ClothParams { damping: 0.5, ..default() }, ..Cloth::grid(Vec2::ONE, UVec2::splat(12)) }
        .with_pins(ClothPins::TwoEnds);
    let cloth = app.world_mut().spawn((grid, cloth_pose)).id();
    run(&mut app, 0.5);
    let mut core = app.world().get::<ClothSimulation>(cloth).unwrap().sim().clone();
    assert_eq!(core.pins(), &[0, 11]);
    let held_at = core.position(11);

    app.world_mut().get_mut::<Cloth>(cloth).unwrap().pins = ClothPins::Indices(vec![0]);
    app.update();
    core.set_pins(&[0]).unwrap();
    core.tick(1.0 / 60.0, &[]);
    let gap = max_distance(&positions(&app, cloth), &core.positions());
    assert!(gap < 1e-6, "the plugin's cloth is not the core's after letting go ({gap} m): was it rebuilt?");
    assert_eq!(app.world().get::<ClothSimulation>(cloth).unwrap().sim().pins(), &[0]);
    run(&mut app, 0.5);
    let fell = held_at.y - positions(&app, cloth)[11].y;
    assert!(fell > 0.2, "the released corner fell only {fell} m in 0.5 s");

    let mut core = app.world().get::<ClothSimulation>(cloth).unwrap().sim().clone();
    app.world_mut().get_mut::<Cloth>(cloth).unwrap().pins = ClothPins::Indices(vec![0, 999]);
    app.update();
    assert!(
        sent(&app).iter().any(|m| matches!(m, ClothMessage::Rejected { entity, error: ClothError::PinOutOfRange { .. } } if *entity == cloth)),
        "a pin out of range is refused with a message: {:?}",
        sent(&app)
    );
    let state = app.world().get::<ClothSimulation>(cloth).unwrap();
    assert_eq!(state.sim().pins(), &[0], "a refused change keeps the pins");
    core.tick(1.0 / 60.0, &[]);
    let gap = max_distance(&positions(&app, cloth), &core.positions());
    assert!(gap < 1e-6, "a refused change moved the cloth off its course ({gap} m)");

    let hook = app.world_mut().spawn(Transform::from_xyz(0.5, 2.0, -0.5)).id();
    app.update();
    let mut component = app.world_mut().get_mut::<Cloth>(cloth).unwrap();
    component.pins = ClothPins::Indices(vec![0]);
    component.anchors.push(ClothAnchor::new(ClothPins::Indices(vec![11]), hook));
    app.update();
    let rest = cloth_pose
        .transform_point(app.world().get::<ClothSimulation>(cloth).unwrap().sim().topology().rest_positions()[11]);
    assert!(positions(&app, cloth)[11].distance(rest) < 1e-5, "the caught corner is not at its rest place");
    for frame in 1..=30 {
        app.world_mut().get_mut::<Transform>(hook).unwrap().translation.x = 0.5 + 0.01 * frame as f32;
        app.update();
    }
    let rode = positions(&app, cloth)[11] - rest;
    assert!(rode.distance(Vec3::new(0.3, 0.0, 0.0)) < 1e-5, "the caught corner did not ride its hook: moved {rode}");
    assert_eq!(app.world().get::<ClothSimulation>(cloth).unwrap().sim().pins(), &[0, 11]);
}

/// The `grab` example's grip: a hand entity put at a moving particle, in its transform and its
/// global transform, and an anchor whose offset takes the particle's rest place under the cloth
/// to where the particle is. The particle stays where it was taken (1e-5 m), then follows the
/// hand exactly as it moves, and drops when the anchor is removed.
#[test]
fn a_hand_takes_a_particle_where_it_is_and_drags_it() {
    let mut app = app();
    let grid = Cloth { params: ClothParams { damping: 0.5, ..default() }, ..Cloth::grid(Vec2::ONE, UVec2::splat(12)) }
        .with_pins(ClothPins::TwoEnds);
    let cloth_pose = Transform::from_xyz(0.0, 2.0, 0.0);
    let cloth = app.world_mut().spawn((grid, cloth_pose)).id();
    run(&mut app, 1.0);
    let particle = 11 * 12 + 6;
    let at = positions(&app, cloth)[particle];
    let rest = cloth_pose.transform_point(
        app.world().get::<ClothSimulation>(cloth).unwrap().sim().topology().rest_positions()[particle],
    );
    let hand = app.world_mut().spawn((Transform::from_translation(at), GlobalTransform::from_translation(at))).id();
    app.world_mut()
        .get_mut::<Cloth>(cloth)
        .unwrap()
        .anchors
        .push(ClothAnchor::new(ClothPins::Indices(vec![particle as u32]), hand).with_offset(at - rest));
    app.update();
    let taken = positions(&app, cloth)[particle];
    assert!(taken.distance(at) < 1e-5, "the particle jumped from {at} to {taken} when taken");
    for frame in 1..=30 {
        app.world_mut().get_mut::<Transform>(hand).unwrap().translation =
            at + Vec3::new(0.01, 0.005, 0.0) * frame as f32;
        app.update();
    }
    let dragged = positions(&app, cloth)[particle];
    let hand_at = app.world().get::<GlobalTransform>(hand).unwrap().translation();
    assert!(dragged.distance(hand_at) < 1e-5, "the particle at {dragged} is not in the hand at {hand_at}");
    app.world_mut().get_mut::<Cloth>(cloth).unwrap().anchors.clear();
    run(&mut app, 0.25);
    let dropped = positions(&app, cloth)[particle];
    assert!(dropped.y < dragged.y - 0.05, "let go at {dragged}, the particle is at {dropped}");
}
