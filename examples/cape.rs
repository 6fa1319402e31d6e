//! A cape on a walking figure. The figure is a hierarchy of joints built in code (hips, chest,
//! shoulders, head, arms, legs) and animated by a walk cycle; its chest and legs are exact
//! capsule `PrimitiveCollider`s carried by their joints, and the floor is a ground primitive.
//! The cape is a mesh built in code whose top edge carries a pin weight of 1 in the alpha
//! channel of its vertex colours, the way an artist marks pinned vertices; `ClothPins::Painted`
//! picks that edge and a `ClothAnchor` hangs it from the shoulders joint, so it rides the figure
//! tick by tick. A joint of a loaded glTF skeleton is an entity like any other and anchors the
//! same way. (The `character` example wears the same cape on a skinned body.)
//!
//! `cargo run --release -p bevy_bvh_cloth --features egui --example cape`
//!
//! Drag to orbit, scroll to zoom, R resets, Space pauses.

mod common;
#[path = "common/walk.rs"]
mod walk;

use bevy::prelude::*;
use bevy_bvh_cloth::prelude::*;
use walk::{ARM_DROP, HIP_HEIGHT, HIP_WIDTH, Hips, SHOULDER_WIDTH, SHOULDERS_ABOVE_HIPS, Walker, arm_swing, leg_swing};

fn main() {
    common::example_app("bevy_bvh_cloth: cape").add_systems(Startup, setup).add_systems(Update, walk::walk).run();
}

fn setup(mut commands: Commands, mut meshes: ResMut<Assets<Mesh>>, mut materials: ResMut<Assets<StandardMaterial>>) {
    common::spawn_camera(&mut commands, Vec3::new(0.0, 0.9, 0.0), 5.0);
    let skin = materials.add(StandardMaterial { base_color: Color::srgb(0.85, 0.75, 0.65), ..default() });
    let tunic = materials.add(StandardMaterial { base_color: Color::srgb(0.35, 0.42, 0.3), ..default() });
    let limb = meshes.add(Capsule3d::new(0.07, 0.62));
    let leg = |left: bool| {
        (
            leg_swing(left),
            Transform::from_xyz(if left { -HIP_WIDTH } else { HIP_WIDTH }, HIP_HEIGHT, 0.0),
            Visibility::default(),
            // The leg hangs from the hip joint; its capsule, exactly the mesh's, collides with the
            // hem.
            children![(
                Mesh3d(limb.clone()),
                MeshMaterial3d(tunic.clone()),
                Transform::from_xyz(0.0, -0.42, 0.0),
                PrimitiveCollider::capsule(0.07, 0.62),
            )],
        )
    };
    let arm = |left: bool| {
        (
            arm_swing(left),
            Transform::from_xyz(if left { -SHOULDER_WIDTH } else { SHOULDER_WIDTH }, -ARM_DROP, 0.0),
            Visibility::default(),
            children![(Mesh3d(limb.clone()), MeshMaterial3d(skin.clone()), Transform::from_xyz(0.0, -0.36, 0.0))],
        )
    };
    let walker =
        commands.spawn((Walker, walk::walker_pose(0.0), Visibility::default(), children![leg(true), leg(false)])).id();
    let hips =
        commands.spawn((Hips, Transform::from_xyz(0.0, HIP_HEIGHT, 0.0), Visibility::default(), ChildOf(walker))).id();
    commands.spawn((
        Mesh3d(meshes.add(Capsule3d::new(0.16, 0.36))),
        MeshMaterial3d(tunic.clone()),
        Transform::from_xyz(0.0, 0.3, 0.0),
        PrimitiveCollider::capsule(0.16, 0.36),
        ChildOf(hips),
    ));
    let shoulders = commands
        .spawn((
            Name::new("shoulders"),
            Transform::from_xyz(0.0, SHOULDERS_ABOVE_HIPS, 0.0),
            Visibility::default(),
            ChildOf(hips),
            children![
                (
                    Mesh3d(meshes.add(Sphere::new(0.12))),
                    MeshMaterial3d(skin.clone()),
                    Transform::from_xyz(0.0, 0.2, 0.0)
                ),
                arm(true),
                arm(false),
            ],
        ))
        .id();
    let material = common::cloth_material(&mut materials, Color::srgb(0.6, 0.08, 0.1));
    commands.spawn(walk::cape(shoulders, &mut meshes, material));
}
