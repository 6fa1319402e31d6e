//! A glTF character from a file (`assets/models/character.glb`, written by
//! `scripts/make_character.py`) dressed by name: the scene loads, its body collides through a
//! hierarchy collider that leaves the cloth out, the cape and the skirt ride on their joints,
//! and the walk loop plays for 10 s.

use bevy::gltf::GltfAssetLabel;
use bevy::prelude::*;
use bevy::world_serialization::WorldAssetRoot;
use bevy_bvh_cloth::prelude::*;

use crate::headless::harness::{gltf_app, positions, run, sent};

/// What the character's root heard.
#[derive(Resource, Default)]
struct Heard {
    colliders: u32,
    cloths: u32,
}

/// The cape sewn to the chest and the skirt to the hips where they are painted red.
fn dressed() -> ClothHierarchy {
    let sewn = ClothPins::Painted { channel: ColorChannel::Red, threshold: 0.5 };
    let cloth = ClothParams { damping: 1.0, ..default() };
    ClothHierarchy::default()
        .with("Cape", SceneCloth::new(Cloth::mesh().with_params(cloth.clone())).anchored(sewn.clone(), "Chest"))
        .with("Skirt", SceneCloth::new(Cloth::mesh().with_params(cloth)).anchored(sewn, "Hips"))
}

/// The entity called `name`.
fn named(app: &mut App, name: &str) -> Entity {
    let mut query = app.world_mut().query::<(Entity, &Name)>();
    query.iter(app.world()).find(|(_, n)| n.as_str() == name).map(|(e, _)| e).unwrap_or_else(|| panic!("no {name}"))
}

#[test]
fn a_gltf_character_wears_its_cape_and_skirt_while_it_walks() {
    let mut app = gltf_app();
    app.init_resource::<Heard>();
    // The scene and the walk loop from one load of the file (a label asked for after the file's
    // own asset is dropped would load it again, and respawn the scene).
    let server = app.world().resource::<AssetServer>();
    let scene = server.load(GltfAssetLabel::Scene(0).from_asset("models/character.glb"));
    let clip = server.load(GltfAssetLabel::Animation(0).from_asset("models/character.glb"));
    let root = app
        .world_mut()
        .spawn((WorldAssetRoot(scene), AutoCollider::new(8), dressed()))
        .observe(|_: On<ColliderHierarchyReady>, mut heard: ResMut<Heard>| heard.colliders += 1)
        .observe(|_: On<ClothHierarchyReady>, mut heard: ResMut<Heard>| heard.cloths += 1)
        .id();
    // The file loads on other threads: wait for the dressed character, 20 s at most.
    for _ in 0..10_000 {
        if app.world().resource::<Heard>().cloths > 0 {
            break;
        }
        app.update();
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    let heard = app.world().resource::<Heard>();
    assert_eq!((heard.colliders, heard.cloths), (1, 1), "the root heard its colliders and its cloths once");
    let (body, cape, skirt, chest, hips) = (
        named(&mut app, "Body"),
        named(&mut app, "Cape"),
        named(&mut app, "Skirt"),
        named(&mut app, "Chest"),
        named(&mut app, "Hips"),
    );
    // glTF names the node; its primitive is the entity with the mesh, under it or on it.
    let mesh_of = |app: &mut App, node: Entity| {
        let mut query = app.world_mut().query_filtered::<(Entity, Option<&ChildOf>), With<Mesh3d>>();
        query
            .iter(app.world())
            .find(|(e, parent)| *e == node || parent.is_some_and(|p| p.parent() == node))
            .map(|(e, _)| e)
            .expect("a mesh")
    };
    let (body, cape, skirt) = (mesh_of(&mut app, body), mesh_of(&mut app, cape), mesh_of(&mut app, skirt));
    for cloth in [cape, skirt] {
        assert!(app.world().get::<ClothSimulation>(cloth).is_some(), "{cloth} is simulated");
        assert!(app.world().get::<ClothCollider>(cloth).is_none(), "{cloth} is not part of the body's collider");
    }
    assert!(app.world().get::<ClothCollider>(body).is_some(), "the body collides");

    // Play the walk loop.
    let (graph, walk) = AnimationGraph::from_clip(clip);
    let graph = app.world_mut().resource_mut::<Assets<AnimationGraph>>().add(graph);
    let mut players = app.world_mut().query_filtered::<Entity, With<AnimationPlayer>>();
    let player = players.iter(app.world()).next().expect("the glTF loader gives the animated scene a player");
    app.world_mut().entity_mut(player).insert(AnimationGraphHandle(graph));
    app.world_mut().get_mut::<AnimationPlayer>(player).unwrap().play(walk).repeat();

    // Each cloth's sewn particles, in the frame of the joint that carries them.
    let joint_frame = |app: &App, joint: Entity| app.world().get::<GlobalTransform>(joint).unwrap().affine().inverse();
    let sewn = |app: &App, cloth: Entity, joint: Entity| -> Vec<Vec3> {
        let simulation = app.world().get::<ClothSimulation>(cloth).unwrap();
        let frame = joint_frame(app, joint);
        simulation.sim().pins().iter().map(|&p| frame.transform_point3(simulation.sim().position(p as usize))).collect()
    };
    run(&mut app, 0.1);
    let start = [sewn(&app, cape, chest), sewn(&app, skirt, hips)];
    assert!(start.iter().all(|s| !s.is_empty()), "the painted rows are sewn on");
    let hips_start = app.world().get::<GlobalTransform>(hips).unwrap().translation();
    let (mut hips_travel, mut worst_seam, mut ever_inside) = (0.0f32, 0.0f32, 0usize);
    for _ in 0..600 {
        run(&mut app, 1.0 / 60.0);
        let hips_now = app.world().get::<GlobalTransform>(hips).unwrap().translation();
        hips_travel = hips_travel.max(hips_now.distance(hips_start));
        for (k, (cloth, joint)) in [(cape, chest), (skirt, hips)].into_iter().enumerate() {
            let now = sewn(&app, cloth, joint);
            for (a, b) in now.iter().zip(&start[k]) {
                worst_seam = worst_seam.max(a.distance(*b));
            }
            let points = positions(&app, cloth);
            assert!(points.iter().all(|p| p.is_finite()), "{cloth} stays finite");
            // The free particles: the sewn ones sit where the seam holds them.
            let held = app.world().get::<ClothSimulation>(cloth).unwrap().sim().pins().to_vec();
            let body = app.world().get::<ClothCollider>(body).unwrap().collider();
            let inside = points.iter().enumerate().filter(|&(i, &p)| !held.contains(&(i as u32)) && body.contains(p));
            ever_inside += inside.count();
        }
    }
    assert!(hips_travel > 0.02, "the walk loop moved the hips ({hips_travel} m)");
    assert!(worst_seam < 1.0e-3, "the seams rode on their joints within 1 mm (worst {worst_seam} m)");
    assert_eq!(ever_inside, 0, "no free particle inside the walking body at any frame");
    let failures: Vec<_> = sent(&app)
        .iter()
        .filter(|m| {
            matches!(
                m,
                ClothMessage::Rejected { .. }
                    | ClothMessage::Diverged { .. }
                    | ClothMessage::ColliderFailed { .. }
                    | ClothMessage::NameNotFound { .. }
                    | ClothMessage::AnchorLost { .. }
            )
        })
        .collect();
    assert!(failures.is_empty(), "{failures:?}");
    assert!(app.world().get::<ColliderStatus>(root).is_some_and(|s| matches!(s, ColliderStatus::Ready { .. })));
}
