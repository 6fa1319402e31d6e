//! A tablecloth dropped onto a table: the table is a mesh (a top and four legs) made a collider
//! by `AutoCollider`, and the cloth, a cotton weighed by the square metre, settles over it with
//! self-contact, so that the corners that fold on themselves keep their layers apart.
//!
//! `cargo run --release -p bevy_bvh_cloth --features egui --example tablecloth`
//!
//! Drag to orbit, scroll to zoom, R resets, Space pauses, B shows the collider's spheres.

mod common;

use bevy::prelude::*;
use bevy_bvh_cloth::prelude::*;

/// The table: a 1.2 x 0.8 m top 0.75 m above the floor, 4 cm thick.
const TOP: Vec3 = Vec3::new(1.2, 0.04, 0.8);
const HEIGHT: f32 = 0.75;

fn main() {
    common::example_app("bevy_bvh_cloth: tablecloth").add_systems(Startup, setup).run();
}

/// The table as one mesh: its top and four legs, each a box.
fn table() -> Mesh {
    let leg = |x: f32, z: f32| {
        Cuboid::new(0.05, HEIGHT - TOP.y, 0.05).mesh().build().translated_by(Vec3::new(x, 0.5 * (HEIGHT - TOP.y), z))
    };
    let (x, z) = (0.5 * TOP.x - 0.06, 0.5 * TOP.z - 0.06);
    let mut mesh = Cuboid::from_size(TOP).mesh().build().translated_by(Vec3::Y * (HEIGHT - 0.5 * TOP.y));
    for (sx, sz) in [(1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)] {
        mesh.merge(&leg(sx * x, sz * z)).expect("boxes share their attributes");
    }
    mesh
}

fn setup(mut commands: Commands, mut meshes: ResMut<Assets<Mesh>>, mut materials: ResMut<Assets<StandardMaterial>>) {
    common::spawn_camera(&mut commands, Vec3::new(0.0, 0.6, 0.0), 3.0);
    commands.spawn((
        Mesh3d(meshes.add(table())),
        MeshMaterial3d(materials.add(Color::srgb(0.45, 0.3, 0.2))),
        AutoCollider::new(32).with_margin(0.015),
    ));
    // 1.8 x 1.4 m of cotton, 0.15 kg/m², falling flat from 20 cm above the top.
    let cotton =
        ClothParams { density: Some(0.15), damping: 1.0, self_contact: Some(SelfContact::default()), ..default() };
    commands.spawn((
        Cloth::grid(Vec2::new(1.8, 1.4), UVec2::new(72, 56)).with_params(cotton),
        common::cloth_material(&mut materials, Color::srgb(0.9, 0.88, 0.8)),
        Transform::from_xyz(0.0, HEIGHT + 0.2, 0.0),
    ));
}
