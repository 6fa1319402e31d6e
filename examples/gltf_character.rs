//! A character loaded from a glTF file walks in a loop wearing a cape and a skirt. The file
//! (`assets/models/character.glb`, written by `scripts/make_character.py`) holds a skinned body,
//! a cape and a skirt as separate meshes whose sewn edges are painted red, named joints, and a
//! walk animation. The whole cloth set-up is the three components on the scene's root:
//! `AutoCollider` makes the body (skinned, so its spheres follow the joints) a collider and
//! leaves the cloth out; `ClothHierarchy` makes the two garments cloth by name, and each painted
//! edge stays where the garment's skin draws it (the cape's over the shoulders follows the arms).
//!
//! `cargo run --release -p bevy_bvh_cloth --features egui --example gltf_character`
//!
//! Drag to orbit, scroll to zoom, R resets, Space pauses, B shows the collider's spheres.

mod common;

use bevy::prelude::*;
use bevy_bvh_cloth::prelude::*;

const CHARACTER: &str = "models/character.glb";

fn main() {
    common::example_app("bevy_bvh_cloth: glTF character")
        .add_systems(Startup, setup)
        .add_systems(Update, start_walking)
        .run();
}

/// The walk loop, as a one-clip animation graph.
#[derive(Resource)]
struct Walk {
    graph: Handle<AnimationGraph>,
    node: AnimationNodeIndex,
}

fn setup(mut commands: Commands, assets: Res<AssetServer>, mut graphs: ResMut<Assets<AnimationGraph>>) {
    common::spawn_camera(&mut commands, Vec3::new(0.0, 1.0, 0.0), 3.0);
    // Asked for with the scene, so that one load of the file gives both.
    let (graph, node) = AnimationGraph::from_clip(assets.load(GltfAssetLabel::Animation(0).from_asset(CHARACTER)));
    commands.insert_resource(Walk { graph: graphs.add(graph), node });

    // The cloth and its colliders: painted red is sewn on, the rest hangs free and keeps off
    // the body and itself.
    let sewn = ClothPins::Painted { channel: ColorChannel::Red, threshold: 0.5 };
    let fabric = ClothParams {
        mass: 0.3,
        damping: 1.0,
        self_contact: Some(SelfContact { thickness: 0.006, friction: 0.3 }),
        ..default()
    };
    commands.spawn((
        WorldAssetRoot(assets.load(GltfAssetLabel::Scene(0).from_asset(CHARACTER))),
        // Turned three-quarters away, so that the camera sees the cape and the skirt.
        Transform::from_rotation(Quat::from_rotation_y(2.4)),
        AutoCollider::new(8),
        ClothHierarchy::default()
            .with("Cape", SceneCloth::new(Cloth::mesh().with_params(fabric.clone())).pinned(sewn.clone()))
            .with("Skirt", SceneCloth::new(Cloth::mesh().with_params(fabric)).pinned(sewn)),
    ));
}

/// Plays the walk loop on the player the glTF loader gives the scene.
fn start_walking(
    mut commands: Commands,
    mut players: Query<(Entity, &mut AnimationPlayer), Added<AnimationPlayer>>,
    walk: Res<Walk>,
) {
    for (entity, mut player) in &mut players {
        commands.entity(entity).insert(AnimationGraphHandle(walk.graph.clone()));
        player.play(walk.node).repeat();
    }
}
