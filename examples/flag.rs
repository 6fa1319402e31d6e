//! A flag on a swaying pole: a mesh built in code (Bevy's subdivided `Plane3d`; a loaded glTF or
//! OBJ works the same) becomes cloth with `Cloth::mesh()`, held along its pole edge by vertex
//! index, and flutters in a gusty, turbulent wind: drag and lift on each of its triangles.
//!
//! `cargo run --release -p bevy_bvh_cloth --features egui --example flag`
//!
//! Drag to orbit, scroll to zoom, R resets, Space pauses.

mod common;

use bevy::mesh::VertexAttributeValues;
use bevy::prelude::*;
use bevy_bvh_cloth::prelude::*;

/// The flag's size in metres, and the plane's subdivisions (30 gives 32 x 32 vertices).
const FLAG: Vec2 = Vec2::new(1.5, 1.0);
const SUBDIVISIONS: u32 = 30;

fn main() {
    common::example_app("bevy_bvh_cloth: flag")
        // 8 m/s along +X, gusting by 40% and turbulent: see `Wind::gusty`. The panel changes it.
        .insert_resource(AmbientWind(Wind::gusty(Vec3::new(8.0, 0.0, 0.0))))
        .add_systems(Startup, setup)
        .add_systems(Update, sway)
        .run();
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
        Cloth {
            params: ClothParams {
                damping: 0.3,
                spring_k: 400.0,
                mass: 0.3,
                // The default integrator (multigrid) follows the flutter at RK4's pace.
                aerodynamics: Aerodynamics::FABRIC,
                ..default()
            },
            ..Cloth::mesh()
        }
        .with_pins(ClothPins::Indices(pole_edge)),
        common::cloth_material(&mut materials, Color::srgb(0.15, 0.3, 0.7)),
        Transform::from_xyz(0.0, 2.9, 0.0),
        ChildOf(pole),
    ));
}

/// The flag: Bevy's own subdivided plane, standing in the local XY plane (its rows hang along
/// -Y from the top edge), as any mesh a game builds or loads.
fn flag_mesh() -> Mesh {
    let mut mesh = Plane3d::new(Vec3::Z, FLAG / 2.0).mesh().subdivisions(SUBDIVISIONS).build();
    // Hoist edge at x = 0, top edge at y = 0.
    mesh.translate_by(Vec3::new(FLAG.x / 2.0, -FLAG.y / 2.0, 0.0));
    mesh
}

/// The vertices along the hoist edge, where the flag meets the pole.
fn pole_vertices(mesh: &Mesh) -> Vec<u32> {
    let Some(VertexAttributeValues::Float32x3(positions)) = mesh.attribute(Mesh::ATTRIBUTE_POSITION) else {
        return Vec::new();
    };
    (0..positions.len() as u32).filter(|&v| positions[v as usize][0].abs() < 1e-5).collect()
}

/// The pole sways about its foot: the flag's pins follow it tick by tick.
fn sway(time: Res<Time>, mut poles: Query<&mut Transform, With<Pole>>) {
    let t = time.elapsed_secs();
    for mut transform in &mut poles {
        transform.rotation =
            Quat::from_rotation_z(0.08 * (1.3 * t).sin()) * Quat::from_rotation_y(0.6 * (0.4 * t).sin());
    }
}
