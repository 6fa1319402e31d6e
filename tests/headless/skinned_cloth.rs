//! A skinned mesh as cloth: its pins go where its skin draws them (blended over their joints),
//! it starts where the skin drew it, a despawned joint holds the pins and is reported, a skin
//! that cannot carry pins leaves them to the entity, and removing the cloth gives the skin back.

use bevy::math::{Affine3A, Vec3A};
use bevy::mesh::skinning::SkinnedMesh;
use bevy::prelude::*;
use bevy_bvh_cloth::bvh_cloth_core::backend::SkinnedVertices;
use bevy_bvh_cloth::prelude::*;
use bevy_bvh_cloth::{ClothSimulation, ClothSkin};

use crate::headless::harness::{app, positions, run, sent};
use crate::skinned_arm::{ELBOW, LENGTH, arm, arm_mesh, spawn_arm};

/// The sleeve's pins: the ring half-way along it, whose vertices are weighted half to the
/// shoulder and half to the elbow.
fn middle_ring() -> ClothPins {
    let x = 0.5 * LENGTH;
    ClothPins::Region { min: Vec3::new(x - 0.01, -1.0, -1.0), max: Vec3::new(x + 0.01, 1.0, 1.0) }
}

/// Every vertex of the arm as the renderer skins it now.
fn skinned(app: &App, shoulder: Entity, elbow: Entity) -> Vec<Vec3> {
    let (positions, _, joints, weights) = arm();
    let vertices = SkinnedVertices { positions: positions.iter().map(|&p| Vec3A::from(p)).collect(), joints, weights };
    let global = |e: Entity| app.world().get::<GlobalTransform>(e).unwrap().affine();
    let matrices = [global(shoulder), global(elbow) * Affine3A::from_translation(Vec3::new(-ELBOW, 0.0, 0.0))];
    let mut out = Vec::new();
    vertices.skin_into(&matrices, &mut out);
    out.into_iter().map(Vec3::from).collect()
}

/// The arm as a sleeve: its skinned mesh becomes cloth (no collider of its own).
fn spawn_sleeve(app: &mut App, mesh: Mesh) -> (Entity, Entity, Entity, Handle<Mesh>) {
    let (sleeve, shoulder, elbow) = spawn_arm(app, mesh, Vec3::new(0.0, 1.5, 0.0));
    // Bent before the cloth is built, so that the start is not the bind pose.
    app.world_mut().get_mut::<Transform>(elbow).unwrap().rotation = Quat::from_rotation_z(0.5);
    let source = app.world().get::<Mesh3d>(sleeve).unwrap().0.clone();
    app.world_mut().entity_mut(sleeve).remove::<AutoCollider>().insert(
        Cloth::mesh()
            .with_params(ClothParams { damping: 1.0, ..default() })
            .with_pins(middle_ring())
            .starting_at_once(),
    );
    (sleeve, shoulder, elbow, source)
}

#[test]
fn a_skinned_sleeve_keeps_its_pins_on_its_skin_and_gets_its_skin_back() {
    let mut app = app();
    let (sleeve, shoulder, elbow, source) = spawn_sleeve(&mut app, arm_mesh());
    run(&mut app, 1.0 / 60.0);
    assert!(app.world().get::<SkinnedMesh>(sleeve).is_none(), "the renderer does not skin the cloth again");
    assert!(app.world().get::<ClothSkin>(sleeve).is_some(), "the plugin keeps the skin");
    let map = app.world().get::<ClothSimulation>(sleeve).unwrap().sim().topology().vertex_particle().to_vec();
    let pins = app.world().get::<ClothSimulation>(sleeve).unwrap().sim().pins().to_vec();
    assert_eq!(pins.len(), 16, "the middle ring is pinned");
    // Each pin's place on the skin, against the particle.
    let worst = |app: &App| {
        let (skin, p) = (skinned(app, shoulder, elbow), positions(app, sleeve));
        let vertex = |pin: u32| map.iter().position(|&q| q == pin).unwrap();
        pins.iter().map(|&pin| p[pin as usize].distance(skin[vertex(pin)])).fold(0.0f32, f32::max)
    };
    // It started where the skin drew it, bent: every particle on its skinned vertex (the pins
    // are still there after one tick; the free ones have fallen a little).
    assert!(worst(&app) < 1.0e-4, "the pins start on the skin ({} m off)", worst(&app));
    let start = positions(&app, sleeve);
    let bent_tip = skinned(&app, shoulder, elbow)[map.iter().position(|&q| q as usize == start.len() - 1).unwrap()];
    assert!(start.last().unwrap().distance(bent_tip) < 0.02, "the free tip started on the bent skin");

    // The shoulder swings and the elbow bends for 2 s: the pins, weighted half to each joint,
    // follow neither joint alone.
    let ring_in = |app: &App, joint: Entity| {
        let frame = app.world().get::<GlobalTransform>(joint).unwrap().affine().inverse();
        let p = positions(app, sleeve);
        pins.iter().map(|&pin| frame.transform_point3(p[pin as usize])).collect::<Vec<_>>()
    };
    let (shoulder_start, elbow_start) = (ring_in(&app, shoulder), ring_in(&app, elbow));
    let (mut off_skin, mut off_shoulder, mut off_elbow) = (0.0f32, 0.0f32, 0.0f32);
    for frame in 0..120 {
        let t = frame as f32 / 60.0;
        app.world_mut().get_mut::<Transform>(shoulder).unwrap().rotation = Quat::from_rotation_z(0.4 * t.sin());
        app.world_mut().get_mut::<Transform>(elbow).unwrap().rotation = Quat::from_rotation_z(0.5 + 0.6 * t.sin());
        run(&mut app, 1.0 / 60.0);
        off_skin = off_skin.max(worst(&app));
        let far =
            |now: Vec<Vec3>, then: &[Vec3]| now.iter().zip(then).map(|(a, b)| a.distance(*b)).fold(0.0f32, f32::max);
        off_shoulder = off_shoulder.max(far(ring_in(&app, shoulder), &shoulder_start));
        off_elbow = off_elbow.max(far(ring_in(&app, elbow), &elbow_start));
    }
    assert!(off_skin < 1.0e-4, "the pins stayed on the skin within 0.1 mm (worst {off_skin} m)");
    assert!(
        off_shoulder > 0.02 && off_elbow > 0.02,
        "the blended ring follows neither joint alone ({off_shoulder} m off the shoulder's frame, {off_elbow} m off the elbow's)"
    );

    // The elbow goes: said once, naming it; the pins stay where they were.
    let held: Vec<Vec3> = pins.iter().map(|&pin| positions(&app, sleeve)[pin as usize]).collect();
    app.world_mut().despawn(elbow);
    run(&mut app, 0.5);
    let lost = sent(&app).iter().filter(|m| **m == ClothMessage::AnchorLost { entity: sleeve, target: elbow }).count();
    assert_eq!(lost, 1, "the lost joint is reported once");
    let p = positions(&app, sleeve);
    assert!(p.iter().all(|q| q.is_finite()));
    for (&pin, was) in pins.iter().zip(&held) {
        assert!(p[pin as usize].distance(*was) < 1.0e-5, "pin {pin} stayed where it was held");
    }

    // Removing the cloth gives the mesh its skin and its own mesh back.
    app.world_mut().entity_mut(sleeve).remove::<Cloth>();
    run(&mut app, 1.0 / 60.0);
    let world = app.world();
    assert!(world.get::<ClothSimulation>(sleeve).is_none(), "no longer simulated");
    assert!(world.get::<ClothSkin>(sleeve).is_none());
    assert_eq!(world.get::<SkinnedMesh>(sleeve).map(|s| s.joints.len()), Some(2), "skinned again");
    assert_eq!(world.get::<Mesh3d>(sleeve).unwrap().0, source, "drawing its own mesh again");
}

/// A skinned mesh whose skin cannot carry the pins (no joint weights): the cloth is built all
/// the same, its pins held by the entity, and the renderer does not skin it.
#[test]
fn a_skin_without_weights_leaves_the_pins_to_the_entity() {
    let mut app = app();
    let mut unweighted = arm_mesh();
    unweighted.remove_attribute(Mesh::ATTRIBUTE_JOINT_WEIGHT);
    let (sleeve, ..) = spawn_sleeve(&mut app, unweighted);
    run(&mut app, 1.0);
    let simulation = app.world().get::<ClothSimulation>(sleeve).expect("the cloth is built");
    let rest = simulation.sim().topology().rest_positions().to_vec();
    let pins = simulation.sim().pins().to_vec();
    assert_eq!(pins.len(), 16);
    let p = positions(&app, sleeve);
    // The entity is at the origin: the pins stay at their rest positions.
    for &pin in &pins {
        assert!(p[pin as usize].distance(rest[pin as usize]) < 1.0e-5, "pin {pin} is held by the entity");
    }
    assert!(p.iter().all(|q| q.is_finite()));
    assert!(app.world().get::<SkinnedMesh>(sleeve).is_none());
}
