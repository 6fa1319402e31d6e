//! The paper's Fig. 5: a cloth with two ends fixed sags under gravity. It catches the air: the
//! panel's wind blows it, and G sets off a blast in front of it.
//!
//! `cargo run --release -p bevy_bvh_cloth --features egui --example hanging_cloth`
//!
//! Drag to orbit, scroll to zoom, R resets, Space pauses, G blasts.

mod common;

use bevy::prelude::*;
use bevy_bvh_cloth::prelude::*;

fn main() {
    common::example_app("bevy_bvh_cloth: hanging cloth").add_systems(Startup, setup).add_systems(Update, blast).run();
}

fn setup(mut commands: Commands, mut materials: ResMut<Assets<StandardMaterial>>) {
    common::spawn_camera(&mut commands, Vec3::new(0.0, 1.2, 0.0), 3.5);
    commands.spawn((
        Cloth {
            params: ClothParams { damping: 1.0, aerodynamics: Aerodynamics::FABRIC, ..default() },
            ..Cloth::grid(Vec2::splat(1.5), UVec2::splat(64)).with_pins(ClothPins::TwoEnds)
        },
        common::cloth_material(&mut materials, Color::srgb(0.75, 0.2, 0.25)),
        // Stand the cloth up: its rows hang down from the pinned first row.
        Transform::from_xyz(0.0, 2.0, 0.0).with_rotation(Quat::from_rotation_x(0.2)),
    ));
}

/// G: a blast in front of the cloth, pushing it back for half a second.
fn blast(keys: Res<ButtonInput<KeyCode>>, mut commands: Commands) {
    if keys.just_pressed(KeyCode::KeyG) {
        commands.spawn((WindBlast::new(25.0, 2.5, 0.5), Transform::from_xyz(0.0, 1.3, 0.8)));
    }
}
