//! Towels thrown over a rail: each folds over the bar onto itself, and the second lands on the
//! first. Self-contact keeps every layer off the others (within one towel and between the two);
//! without it (the panel's checkbox) they sink through each other.
//!
//! `cargo run --release -p bevy_bvh_cloth --features egui --example towel`
//!
//! Drag to orbit, scroll to zoom, R resets, Space pauses.

mod common;

use bevy::prelude::*;
use bevy_bvh_cloth::prelude::*;

fn main() {
    common::example_app("bevy_bvh_cloth: towel").add_systems(Startup, setup).run();
}

fn setup(mut commands: Commands, mut meshes: ResMut<Assets<Mesh>>, mut materials: ResMut<Assets<StandardMaterial>>) {
    common::spawn_camera(&mut commands, Vec3::new(0.0, 0.9, 0.0), 2.5);
    // A rail 1 m long and 3 cm thick, 1 m above the floor, along x.
    let rail = Transform::from_xyz(0.0, 1.0, 0.0).with_rotation(Quat::from_rotation_z(core::f32::consts::FRAC_PI_2));
    commands.spawn((
        Mesh3d(meshes.add(Capsule3d::new(0.015, 1.0))),
        MeshMaterial3d(materials.add(Color::srgb(0.7, 0.7, 0.75))),
        PrimitiveCollider::capsule(0.015, 1.0).with_friction(0.6),
        rail,
    ));
    // Terry cloth, heavy and soft, 0.5 x 0.9 m; the second is dropped crosswise above the first.
    let terry = ClothParams {
        density: Some(0.45),
        spring_k: 150.0,
        damping: 1.0,
        self_contact: Some(SelfContact::default()),
        ..default()
    };
    for (k, (color, height, turn)) in
        [(Color::srgb(0.2, 0.45, 0.7), 1.15, 0.0), (Color::srgb(0.85, 0.55, 0.2), 1.35, 0.4)].into_iter().enumerate()
    {
        commands.spawn((
            Cloth::grid(Vec2::new(0.5, 0.9), UVec2::new(25, 45)).with_params(terry.clone()),
            common::cloth_material(&mut materials, color),
            Transform::from_xyz(0.1 * k as f32, height, 0.0).with_rotation(Quat::from_rotation_y(turn)),
        ));
    }
}
