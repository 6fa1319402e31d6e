//! AutoCollider on a skinned mesh: the collider follows the joints as the animation moves them,
//! checked against the skinned triangles themselves; bad skins and despawned joints.

use bevy::prelude::*;
use bevy_bvh_cloth::prelude::*;
use bevy_bvh_cloth::{ClothCollider, ColliderFailure};

use crate::headless::harness::{app, positions, run, sent, wait_for_collider};
use crate::skinned_arm::{RADIUS, Solid, arm, arm_mesh, skinned_triangles, spawn_arm};

/// A cloth dropped on an arm that then swings at the shoulder and bends at the elbow for 10 s:
/// after every tick no particle is inside the skinned body (the parity test against the triangles the
/// renderer draws), while the arm carries the cloth up and down.
#[test]
fn a_cloth_on_an_animated_arm_never_ends_a_tick_inside_it() {
    let mut app = app();
    let (arm, shoulder, elbow) = spawn_arm(&mut app, arm_mesh(), Vec3::new(-0.6, 1.0, 0.0));
    wait_for_collider(&mut app, arm);
    let cloth = app
        .world_mut()
        .spawn((
            Cloth {
                params: ClothParams { damping: 1.0, ..default() },
                ..Cloth::grid(Vec2::splat(1.0), UVec2::splat(24))
            },
            // Over the upper arm, between the shoulder and the elbow.
            Transform::from_xyz(-0.3, 1.3, 0.0),
        ))
        .id();
    let (mut lifted, mut checked, mut touching) = (0.0f32, 0, 0);
    // One second to land on the arm at rest, then ten of animation.
    for frame in 0..660 {
        let t = (frame as f32 / 60.0 - 1.0).max(0.0);
        // The shoulder swings the arm up and down by 0.3 rad, the elbow bends up to 0.6 rad.
        let swing = 0.3 * (std::f32::consts::TAU * t / 4.0).sin();
        let bend = 0.3 - 0.3 * (std::f32::consts::TAU * t / 3.0).cos();
        app.world_mut().get_mut::<Transform>(shoulder).unwrap().rotation = Quat::from_rotation_z(swing);
        app.world_mut().get_mut::<Transform>(elbow).unwrap().rotation = Quat::from_rotation_z(bend);
        run(&mut app, 1.0 / 60.0);
        let body = Solid::new(skinned_triangles(&app, shoulder, elbow));
        let p = positions(&app, cloth);
        let bad: Vec<usize> = (0..p.len()).filter(|&i| body.contains(p[i])).collect();
        assert!(bad.is_empty(), "at {t:.2} s particles {bad:?} are inside the arm");
        checked += p.len();
        // The cloth is on the arm: many particles within 5 cm of its collider.
        let near = app.world().get::<ClothCollider>(arm).unwrap().collider().clone().with_margin(0.05);
        touching += usize::from(p.iter().filter(|&&q| near.contains(q)).count() >= 50);
        let tip = body.triangles().iter().flatten().map(|v| v.y).fold(f32::NEG_INFINITY, f32::max);
        lifted = lifted.max(tip);
    }
    assert_eq!(checked, 660 * 24 * 24);
    eprintln!("animated arm: highest point {lifted:.3} m, cloth on the arm in {touching} of 660 ticks");
    // The arm rose well above its rest height, carrying the cloth all along.
    assert!(lifted > 1.0 + RADIUS + 0.25, "the arm's highest point reached only {lifted}");
    assert!(touching >= 620, "the cloth lay on the arm in only {touching} of 660 ticks");
    // The collider is where the arm is: its spheres are in world space, around the bent arm.
    let collider = app.world().get::<ClothCollider>(arm).unwrap().collider();
    let tip = skinned_triangles(&app, shoulder, elbow).iter().flatten().fold(
        Vec3::ZERO,
        |a, &b| {
            if b.x > a.x { b } else { a }
        },
    );
    assert!(collider.contains(tip), "the arm's far tip {tip} is outside its collider");
}

/// A skinned mesh without joint weights, and one weighted to a joint the skin lacks, fail with
/// a clear reason on their entity; a despawned joint leaves the collider at its last pose and
/// the rest of the scene runs.
#[test]
fn bad_skins_fail_and_a_despawned_joint_holds_the_last_pose() {
    let mut app = app();
    let mut unweighted = arm_mesh();
    unweighted.remove_attribute(Mesh::ATTRIBUTE_JOINT_WEIGHT);
    let (no_weights, ..) = spawn_arm(&mut app, unweighted, Vec3::ZERO);
    let mut far_joint = arm_mesh();
    let (_, _, joints, _) = arm();
    let joints: Vec<[u16; 4]> = joints.iter().map(|_| [0, 7, 0, 0]).collect();
    far_joint.insert_attribute(Mesh::ATTRIBUTE_JOINT_INDEX, bevy::mesh::VertexAttributeValues::Uint16x4(joints));
    let (out_of_range, ..) = spawn_arm(&mut app, far_joint, Vec3::new(0.0, 0.0, 2.0));
    let (good, shoulder, elbow) = spawn_arm(&mut app, arm_mesh(), Vec3::new(0.0, 0.0, -2.0));
    wait_for_collider(&mut app, good);
    run(&mut app, 0.1);
    let failure = |entity| match app.world().get::<ColliderStatus>(entity) {
        Some(ColliderStatus::Failed(reason)) => reason.clone(),
        other => panic!("{entity} is {other:?}"),
    };
    assert!(failure(no_weights).contains("joint weights"), "{}", failure(no_weights));
    assert!(failure(out_of_range).contains("joint 7"), "{}", failure(out_of_range));
    let failed: Vec<Entity> = sent(&app)
        .iter()
        .filter_map(|m| match m {
            ClothMessage::ColliderFailed {
                entity,
                failure: ColliderFailure::NoSkin | ColliderFailure::Rejected(_),
            } => Some(*entity),
            _ => None,
        })
        .collect();
    assert!(failed.contains(&no_weights) && failed.contains(&out_of_range), "{failed:?}");

    // Bend the elbow, then despawn it: the collider keeps the bent pose.
    app.world_mut().get_mut::<Transform>(elbow).unwrap().rotation = Quat::from_rotation_z(1.0);
    run(&mut app, 0.1);
    let bent = app.world().get::<ClothCollider>(good).unwrap().collider().lbvh().unwrap().spheres.clone();
    app.world_mut().entity_mut(elbow).despawn();
    app.world_mut().get_mut::<Transform>(shoulder).unwrap().rotation = Quat::from_rotation_z(0.5);
    run(&mut app, 0.1);
    let held = app.world().get::<ClothCollider>(good).unwrap().collider().lbvh().unwrap().spheres.clone();
    assert_eq!(held, bent, "the collider holds its last complete pose");
    assert!(matches!(app.world().get::<ColliderStatus>(good), Some(ColliderStatus::Ready { .. })));
}
