//! The paper's Fig. 5: a cloth with two ends fixed sags under gravity.
//!
//! `cargo run --release -p bevy_bvh_cloth --features egui --example hanging_cloth`
//!
//! Drag to orbit, scroll to zoom, R resets, Space pauses.

mod common;

use bevy::prelude::*;
use bevy_bvh_cloth::prelude::*;

fn main() {
    common::example_app("bevy_bvh_cloth: hanging cloth").add_systems(Startup, setup).run();
}

fn setup(mut commands: Commands, mut materials: ResMut<Assets<StandardMaterial>>) {
    common::spawn_camera(&mut commands, Vec3::new(0.0, 1.2, 0.0), 3.5);
    commands.spawn((
        Cloth {
            params: ClothParams { damping: 1.0, ..default() },
            ..Cloth::grid(Vec2::splat(1.5), UVec2::splat(64)).with_pins(ClothPins::TwoEnds)
        },
        common::cloth_material(&mut materials, Color::srgb(0.75, 0.2, 0.25)),
        // Stand the cloth up: its rows hang down from the pinned first row.
        Transform::from_xyz(0.0, 2.0, 0.0).with_rotation(Quat::from_rotation_x(0.2)),
    ));
}
