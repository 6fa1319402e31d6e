//! A headless app with the plugin: MinimalPlugins, assets, meshes, transforms, OBJ loading (glTF
//! scenes and animation too, for the glTF character), and a clock advanced by hand.

use core::time::Duration;

use bevy::animation::AnimationPlugin;
use bevy::asset::AssetPlugin;
use bevy::gltf::GltfPlugin;
use bevy::mesh::MeshPlugin;
use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use bevy::world_serialization::WorldSerializationPlugin;
use bevy_bvh_cloth::prelude::*;
use bevy_obj::ObjPlugin;

/// Every message the plugin sent, kept for the test to read.
#[derive(Resource, Default)]
pub struct Sent(pub Vec<ClothMessage>);

fn collect(mut reader: MessageReader<ClothMessage>, mut sent: ResMut<Sent>) {
    sent.0.extend(reader.read().cloned());
}

/// An app stepping `fps` frames per (simulated) second.
pub fn app_at(fps: f64) -> App {
    app_with(fps, BvhClothPlugin::default(), |_| {})
}

/// An app stepping 60 frames per second that also loads glTF scenes and plays their
/// animations.
pub fn gltf_app() -> App {
    app_with(60.0, BvhClothPlugin::default(), |app| {
        app.add_plugins((WorldSerializationPlugin, GltfPlugin::default(), AnimationPlugin));
        // The glTF loader is registered when the plugins finish, as `App::run` would do.
        app.finish();
        app.cleanup();
    })
}

/// An app stepping `fps` frames per (simulated) second with the cloth `plugin` (in the schedule
/// it names), and what `more` adds. Its first update, run here, starts the clock at zero.
pub fn app_with(fps: f64, plugin: BvhClothPlugin, more: impl FnOnce(&mut App)) -> App {
    let mut app = App::new();
    app.add_plugins((MinimalPlugins, TransformPlugin, AssetPlugin::default(), MeshPlugin, ObjPlugin, plugin));
    more(&mut app);
    app.insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_secs_f64(1.0 / fps)))
        .init_resource::<Sent>()
        .add_systems(Last, collect);
    // The first update starts the clock at zero.
    app.update();
    app
}

/// An app stepping 60 frames per second: one tick per frame at the default tick rate.
pub fn app() -> App {
    app_at(60.0)
}

/// Runs `seconds` of simulated time.
pub fn run(app: &mut App, seconds: f32) {
    let fps = match app.world().resource::<TimeUpdateStrategy>() {
        TimeUpdateStrategy::ManualDuration(d) => 1.0 / d.as_secs_f32(),
        _ => unreachable!("the harness sets a manual duration"),
    };
    for _ in 0..(seconds * fps).round() as u32 {
        app.update();
    }
}

/// Updates until `entity`'s collider is ready (assets load on other threads), or panics after
/// a generous bound with the status it was stuck in.
pub fn wait_for_collider(app: &mut App, entity: Entity) -> (u32, u32) {
    for _ in 0..5000 {
        if let ColliderStatus::Ready { spheres, inner_nodes } = app.world().get::<ColliderStatus>(entity).unwrap() {
            return (*spheres, *inner_nodes);
        }
        app.update();
        std::thread::sleep(Duration::from_millis(2));
    }
    panic!("collider never became ready: {:?}", app.world().get::<ColliderStatus>(entity));
}

/// World-space particle positions of a cloth.
pub fn positions(app: &App, cloth: Entity) -> Vec<Vec3> {
    app.world().get::<ClothSimulation>(cloth).expect("the cloth is simulated").sim().positions()
}

/// The messages sent so far.
pub fn sent(app: &App) -> &[ClothMessage] {
    &app.world().resource::<Sent>().0
}

/// A mesh asset added directly.
pub fn add_mesh(app: &mut App, mesh: impl Into<Mesh>) -> Handle<Mesh> {
    app.world_mut().resource_mut::<Assets<Mesh>>().add(mesh.into())
}

/// Largest distance between two position sets.
pub fn max_distance(a: &[Vec3], b: &[Vec3]) -> f32 {
    a.iter().zip(b).map(|(p, q)| p.distance(*q)).fold(0.0, f32::max)
}
