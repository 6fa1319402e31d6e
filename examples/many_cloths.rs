//! Hundreds of banners in a gusty wind, all in one GPU batch: every cloth of the scene is
//! stepped by the same dispatches, so 256 banners cost little more than one. The window's title
//! shows the count and the frame time.
//!
//! `cargo run --release -p bevy_bvh_cloth --features egui --example many_cloths`
//!
//! Drag to orbit, scroll to zoom, R resets, Space pauses.

mod common;

use bevy::prelude::*;
use bevy::window::PrimaryWindow;
use bevy_bvh_cloth::prelude::*;

/// Banners along each side of the square they stand in.
const SIDE: u32 = 16;

fn main() {
    common::example_app("bevy_bvh_cloth: many cloths")
        .insert_resource(AmbientWind(Wind::gusty(Vec3::new(4.0, 0.0, 2.0))))
        .add_systems(Startup, setup)
        .add_systems(Update, show_frame_time)
        .run();
}

fn setup(mut commands: Commands, mut materials: ResMut<Assets<StandardMaterial>>) {
    common::spawn_camera(&mut commands, Vec3::new(0.0, 1.0, 0.0), 9.0);
    let banner = ClothParams { density: Some(0.2), damping: 1.0, aerodynamics: Aerodynamics::FABRIC, ..default() };
    for row in 0..SIDE {
        for col in 0..SIDE {
            let hue = 360.0 * (row * SIDE + col) as f32 / (SIDE * SIDE) as f32;
            let (x, z) = ((col as f32 - 0.5 * (SIDE - 1) as f32) * 0.45, (row as f32 - 0.5 * (SIDE - 1) as f32) * 0.45);
            commands.spawn((
                // 0.3 x 0.5 m, 16 x 16 particles, hanging from its first row.
                Cloth::grid(Vec2::new(0.3, 0.5), UVec2::splat(16))
                    .with_params(banner.clone())
                    .with_pins(ClothPins::FirstRow),
                common::cloth_material(&mut materials, Color::hsl(hue, 0.6, 0.5)),
                // Stood up: the first row along the top, the rest hanging below it.
                Transform::from_xyz(x, 1.2, z).with_rotation(Quat::from_rotation_x(core::f32::consts::FRAC_PI_2)),
            ));
        }
    }
}

/// Puts the cloth count, their particles, the backend and the mean frame time of the last
/// second in the window's title.
fn show_frame_time(
    time: Res<Time<Real>>,
    cloths: Query<&ClothSimulation>,
    backend: Res<ActiveClothBackend>,
    mut windows: Query<&mut Window, With<PrimaryWindow>>,
    mut window_clock: Local<(f32, u32)>,
) {
    let (elapsed, frames) = &mut *window_clock;
    *elapsed += time.delta_secs();
    *frames += 1;
    if *elapsed < 1.0 {
        return;
    }
    let particles: usize = cloths.iter().map(|c| c.sim().len()).sum();
    let ms = 1000.0 * *elapsed / *frames as f32;
    for mut window in &mut windows {
        window.title = format!(
            "bevy_bvh_cloth: many cloths: {} banners, {particles} particles, {backend:?} backend, {ms:.1} ms per frame",
            cloths.iter().count()
        );
    }
    (*elapsed, *frames) = (0.0, 0);
}
