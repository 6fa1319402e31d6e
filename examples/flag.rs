//! A flag on a swaying pole: an authored mesh (built here in code, as an exporter writes one,
//! with a UV seam down its middle) becomes cloth with `Cloth::mesh()`, held along its pole edge
//! by vertex index, and flaps in a gusting wind (External Force).
//!
//! `cargo run --release -p bevy_bvh_cloth --features egui --example flag`
//!
//! Drag to orbit, scroll to zoom, R resets, Space pauses.

mod common;

use bevy::asset::RenderAssetUsages;
use bevy::mesh::{Indices, PrimitiveTopology, VertexAttributeValues};
use bevy::prelude::*;
use bevy_bvh_cloth::prelude::*;

/// The flag's size in metres and its resolution (points along the fly and the hoist).
const FLAG: Vec2 = Vec2::new(1.5, 1.0);
const POINTS: UVec2 = UVec2::new(36, 24);

fn main() {
    common::example_app("bevy_bvh_cloth: flag").add_systems(Startup, setup).add_systems(Update, (sway, gusts)).run();
}

/// The pole the flag hangs from; it sways, and the flag's entity with it.
#[derive(Component)]
struct Pole;

fn setup(mut commands: Commands, mut meshes: ResMut<Assets<Mesh>>, mut materials: ResMut<Assets<StandardMaterial>>) {
    common::spawn_camera(&mut commands, Vec3::new(0.8, 2.0, 0.0), 4.5);
    let flag = flag_mesh();
    let pole_edge = pole_vertices(&flag);
    let pole = commands
        .spawn((
            Pole,
            Transform::from_xyz(0.0, 0.0, 0.0),
            Visibility::default(),
            children![(
                Mesh3d(meshes.add(Cylinder::new(0.03, 3.0))),
                MeshMaterial3d(materials.add(Color::srgb(0.55, 0.5, 0.45))),
                Transform::from_xyz(-0.03, 1.5, 0.0),
            )],
        ))
        .id();
    commands.spawn((
        Mesh3d(meshes.add(flag)),
        Cloth { damping: 0.3, spring_k: 400.0, mass: 0.3, ..Cloth::mesh() }.with_pins(ClothPins::Indices(pole_edge)),
        common::cloth_material(&mut materials, Color::srgb(0.15, 0.3, 0.7)),
        Transform::from_xyz(0.0, 2.9, 0.0),
        ChildOf(pole),
    ));
}

/// A flag in the local XY plane, hoist edge on x = 0, top edge on y = 0, split at a UV seam down
/// its middle column (each half has its own vertices there, as a textured export would).
fn flag_mesh() -> Mesh {
    let seam = POINTS.x / 2;
    let (mut positions, mut uvs, mut indices) = (Vec::new(), Vec::new(), Vec::<u32>::new());
    for (first, last) in [(0, seam), (seam, POINTS.x - 1)] {
        let start = positions.len() as u32;
        let span = last - first + 1;
        for r in 0..POINTS.y {
            for c in first..=last {
                let uv = Vec2::new(c as f32 / (POINTS.x - 1) as f32, r as f32 / (POINTS.y - 1) as f32);
                positions.push([FLAG.x * uv.x, -FLAG.y * uv.y, 0.0]);
                uvs.push(uv.to_array());
            }
        }
        for r in 0..POINTS.y - 1 {
            for c in 0..span - 1 {
                let i = start + r * span + c;
                indices.extend_from_slice(&[i, i + span, i + 1, i + 1, i + span, i + span + 1]);
            }
        }
    }
    Mesh::new(PrimitiveTopology::TriangleList, RenderAssetUsages::default())
        .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, positions)
        .with_inserted_attribute(Mesh::ATTRIBUTE_UV_0, uvs)
        .with_inserted_indices(Indices::U32(indices))
}

/// The vertices along the hoist edge, where the flag meets the pole.
fn pole_vertices(mesh: &Mesh) -> Vec<u32> {
    let Some(VertexAttributeValues::Float32x3(positions)) = mesh.attribute(Mesh::ATTRIBUTE_POSITION) else {
        return Vec::new();
    };
    (0..positions.len() as u32).filter(|&v| positions[v as usize][0] == 0.0).collect()
}

/// The pole sways about its foot: the flag's pins follow it tick by tick.
fn sway(time: Res<Time>, mut poles: Query<&mut Transform, With<Pole>>) {
    let t = time.elapsed_secs();
    for mut transform in &mut poles {
        transform.rotation =
            Quat::from_rotation_z(0.08 * (1.3 * t).sin()) * Quat::from_rotation_y(0.6 * (0.4 * t).sin());
    }
}

/// A wind along +X that gusts, with a little lift and sideways push.
fn gusts(time: Res<Time>, mut cloths: Query<&mut Cloth>) {
    let t = time.elapsed_secs();
    for mut cloth in &mut cloths {
        let gust = 1.0 + 0.5 * (0.9 * t).sin() + 0.25 * (2.3 * t).sin();
        cloth.external_force = Vec3::new(2.5 * gust, 0.4, 0.6 * (1.7 * t).sin());
    }
}
