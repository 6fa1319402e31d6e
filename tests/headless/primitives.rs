//! PrimitiveCollider: exact shapes that follow their entity, bad sizes, and entity events.

use bevy::prelude::*;
use bevy_bvh_cloth::prelude::*;
use bevy_bvh_cloth::{ClothCollider, ColliderFailure};

use crate::headless::harness::{app, positions, run, sent};

/// A 2 m cloth of 32 x 32 particles, flat at `height`.
fn drop_cloth(app: &mut App, height: f32) -> Entity {
    app.world_mut()
        .spawn((
            Cloth {
                params: ClothParams { damping: 1.0, ..default() },
                ..Cloth::grid(Vec2::splat(2.0), UVec2::splat(32))
            },
            Transform::from_xyz(0.0, height, 0.0),
        ))
        .id()
}

/// A cloth dropped on a ball that stands on the ground: it drapes over the ball and rests on the
/// ground at the margin, no particle ever inside either, and the ball's top holds the cloth up.
#[test]
fn a_cloth_rests_on_a_ball_and_the_ground() {
    let mut app = app();
    let ground = app.world_mut().spawn(PrimitiveCollider::ground()).id();
    let ball = app.world_mut().spawn((PrimitiveCollider::sphere(0.3), Transform::from_xyz(0.0, 0.3, 0.0))).id();
    let cloth = drop_cloth(&mut app, 1.0);
    for _ in 0..6 {
        run(&mut app, 0.5);
        for collider in [ground, ball] {
            let collider = app.world().get::<ClothCollider>(collider).expect("built").collider();
            let inside = positions(&app, cloth).iter().filter(|&&p| collider.contains(p)).count();
            assert_eq!(inside, 0, "particles inside {:?}", collider.shape);
        }
    }
    let p = positions(&app, cloth);
    let lowest = p.iter().map(|p| p.y).fold(f32::INFINITY, f32::min);
    let highest = p.iter().map(|p| p.y).fold(f32::NEG_INFINITY, f32::max);
    // The margin is 1 cm: the lowest particles rest on the ground within a millimetre of it.
    assert!((lowest - 0.01).abs() < 1e-3, "lowest particle at {lowest}");
    // The ball's top, 0.6 m plus the margin, carries the cloth's middle.
    assert!((highest - 0.61).abs() < 0.02, "highest particle at {highest}");
    assert_eq!(app.world().get::<ColliderStatus>(ball), Some(&ColliderStatus::Ready { spheres: 0, inner_nodes: 0 }));
}

/// A capsule carried by its entity (as a bone's would be) sweeps through the space where a
/// pinned cloth hangs: the cloth is pushed aside and no particle ends inside it.
#[test]
fn a_moving_capsule_pushes_a_hanging_cloth_aside() {
    let mut app = app();
    let cloth = app
        .world_mut()
        .spawn((
            Cloth {
                params: ClothParams { damping: 1.0, ..default() },
                pins: ClothPins::Indices(vec![0, 23]),
                ..Cloth::grid(Vec2::splat(1.0), UVec2::splat(24))
            },
            Transform::from_xyz(0.0, 1.5, 0.0).with_rotation(Quat::from_rotation_x(core::f32::consts::FRAC_PI_2)),
        ))
        .id();
    run(&mut app, 2.0);
    let hanging = positions(&app, cloth);
    let capsule =
        app.world_mut().spawn((PrimitiveCollider::capsule(0.1, 0.6), Transform::from_xyz(0.0, 1.0, -1.0))).id();
    for step in 0..60 {
        app.world_mut().get_mut::<Transform>(capsule).unwrap().translation.z = -1.0 + step as f32 / 30.0;
        run(&mut app, 1.0 / 60.0);
        let collider = app.world().get::<ClothCollider>(capsule).expect("built").collider();
        let inside = positions(&app, cloth).iter().filter(|&&p| collider.contains(p)).count();
        assert_eq!(inside, 0, "particles inside the capsule at step {step}");
    }
    let pushed = positions(&app, cloth);
    let moved = hanging.iter().zip(&pushed).map(|(a, b)| b.z - a.z).fold(0.0f32, f32::max);
    assert!(moved > 0.3, "the capsule carried the cloth by {moved} m");
}

/// A zero radius is refused with a clear error on that entity, observed on it as
/// `ColliderFailed`; fixing it makes the collider ready, observed as `ColliderReady`; the
/// cloth runs throughout.
#[test]
fn a_bad_size_fails_that_collider_and_observers_hear_of_it() {
    #[derive(Resource, Default)]
    struct Heard(Vec<String>);
    let mut app = app();
    app.init_resource::<Heard>();
    let bad = app
        .world_mut()
        .spawn(PrimitiveCollider::sphere(0.0))
        .observe(|failed: On<ColliderFailed>, mut heard: ResMut<Heard>| {
            heard.0.push(format!("failed {}: {}", failed.entity, failed.failure));
        })
        .observe(|ready: On<ColliderReady>, mut heard: ResMut<Heard>| {
            heard.0.push(format!("ready {} with {} spheres", ready.entity, ready.spheres));
        })
        .id();
    let cloth = drop_cloth(&mut app, 1.0);
    run(&mut app, 0.5);
    let Some(ColliderStatus::Failed(reason)) = app.world().get::<ColliderStatus>(bad) else {
        panic!("a zero radius must fail")
    };
    assert!(reason.contains("positive sizes"), "{reason}");
    assert!(app.world().get::<ClothCollider>(bad).is_none());
    assert!(sent(&app).iter().any(|m| matches!(m,
        ClothMessage::ColliderFailed { entity, failure: ColliderFailure::Rejected(_) } if *entity == bad)));
    assert!(positions(&app, cloth).iter().all(|p| p.is_finite()));

    app.world_mut().get_mut::<PrimitiveCollider>(bad).unwrap().shape = PrimitiveShape::Sphere(Sphere::new(0.2));
    run(&mut app, 0.1);
    assert_eq!(app.world().get::<ColliderStatus>(bad), Some(&ColliderStatus::Ready { spheres: 0, inner_nodes: 0 }));
    let heard = &app.world().resource::<Heard>().0;
    assert_eq!(heard.len(), 2, "{heard:?}");
    assert!(heard[0].starts_with(&format!("failed {bad}: collider primitive")), "{heard:?}");
    assert_eq!(heard[1], format!("ready {bad} with 0 spheres"));
}

/// An observer on a cloth hears `ClothRejected` when its parameters are refused.
#[test]
fn a_cloth_observer_hears_its_rejection() {
    #[derive(Resource, Default)]
    struct Rejections(u32);
    let mut app = app();
    app.init_resource::<Rejections>();
    let cloth = app
        .world_mut()
        .spawn(Cloth { params: ClothParams { mass: -1.0, ..default() }, ..Cloth::grid(Vec2::ONE, UVec2::splat(4)) })
        .observe(|_: On<ClothRejected>, mut count: ResMut<Rejections>| count.0 += 1)
        .id();
    run(&mut app, 0.1);
    assert!(app.world().get::<ClothSimulation>(cloth).is_none());
    assert_eq!(app.world().resource::<Rejections>().0, 1, "heard once, not every frame");
}

/// Collision layers: over a table on its own layer, a cloth that filters for it rests on it and
/// one that does not falls past; put on a layer no cloth filters for, the table lets the first
/// go as well, at once (no rebuild).
#[test]
fn a_cloth_meets_only_the_colliders_its_layers_meet() {
    const TABLE: u32 = 1 << 1;
    let mut app = app();
    let table = app
        .world_mut()
        .spawn((
            PrimitiveCollider::cuboid(1.0, 0.2, 1.0).with_layers(CollisionLayers::new(TABLE, CollisionLayers::ALL)),
            Transform::from_xyz(0.0, 0.5, 0.0),
        ))
        .id();
    let cloth = |app: &mut App, filters: u32| {
        let layers = CollisionLayers::new(CollisionLayers::DEFAULT.memberships, filters);
        let cloth = Cloth::grid(Vec2::splat(0.6), UVec2::splat(12))
            .with_params(ClothParams { damping: 1.0, ..default() })
            .with_layers(layers);
        app.world_mut().spawn((cloth, Transform::from_xyz(0.0, 1.0, 0.0))).id()
    };
    let meets = cloth(&mut app, TABLE);
    let passes = cloth(&mut app, !TABLE);
    let lowest = |app: &App, cloth: Entity| positions(app, cloth).iter().map(|p| p.y).fold(f32::INFINITY, f32::min);
    run(&mut app, 1.0);
    // The table's top is at 0.6 m and its margin 1 cm.
    assert!((lowest(&app, meets) - 0.61).abs() < 2e-3, "the cloth that meets the table is at {}", lowest(&app, meets));
    assert!(lowest(&app, passes) < 0.0, "the cloth that does not meet the table is at {}", lowest(&app, passes));
    app.world_mut().get_mut::<PrimitiveCollider>(table).unwrap().layers =
        CollisionLayers::new(1 << 5, CollisionLayers::ALL);
    run(&mut app, 1.0);
    assert!(lowest(&app, meets) < 0.0, "the table still holds the cloth at {}", lowest(&app, meets));
    assert_eq!(app.world().get::<ClothCollider>(table).expect("built").collider().layers.memberships, 1 << 5);
}
