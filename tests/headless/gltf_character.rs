//! A glTF character from a file (`assets/models/character.glb`, written by
//! `scripts/make_character.py`) dressed by name: the scene loads, its body collides through a
//! hierarchy collider that leaves the cloth out, the cape's and the skirt's sewn edges follow
//! their skin (the cape's over the shoulders blended with the arms), and the walk loop plays
//! for 10 s.

use bevy::gltf::GltfAssetLabel;
use bevy::math::Affine3A;
use bevy::mesh::VertexAttributeValues;
use bevy::mesh::skinning::{SkinnedMesh, SkinnedMeshInverseBindposes};
use bevy::prelude::*;
use bevy::world_serialization::WorldAssetRoot;
use bevy_bvh_cloth::ClothSkin;
use bevy_bvh_cloth::bvh_cloth_core::backend::crossing_pairs;
use bevy_bvh_cloth::prelude::*;

use crate::headless::harness::{gltf_app, positions, run, sent};

/// What the character's root heard.
#[derive(Resource, Default)]
struct Heard {
    colliders: u32,
    cloths: u32,
    /// Each `ColliderReady`'s entity.
    parts: Vec<Entity>,
}

/// The file.
pub(crate) const CHARACTER: &str = "models/character.glb";

/// The cape and the skirt held by their skin where they are painted red, keeping off
/// themselves and each other.
pub(crate) fn dressed() -> ClothHierarchy {
    let sewn = ClothPins::Painted { channel: ColorChannel::Red, threshold: 0.5 };
    let contact = Some(SelfContact { thickness: 0.006, friction: 0.3 });
    let cloth = Cloth::mesh().with_params(ClothParams { damping: 1.0, self_contact: contact, ..default() });
    ClothHierarchy::default()
        .with("Cape", SceneCloth::new(cloth.clone()).pinned(sewn.clone()))
        .with("Skirt", SceneCloth::new(cloth).pinned(sewn))
}

/// Where linear blend skinning draws each pinned particle of `cloth` now, from the file's mesh
/// (`mesh`, its index in the file), the skin the plugin kept and the joints' transforms: the
/// sum of each vertex's weights times its joints' world transforms times their inverse bind
/// poses, applied to its bind position, as Bevy's vertex shader places it.
pub(crate) fn skinned_pins(app: &App, cloth: Entity, mesh: usize) -> Vec<(u32, Vec3)> {
    let world = app.world();
    let handle = world
        .resource::<AssetServer>()
        .get_handle::<Mesh>(GltfAssetLabel::Primitive { mesh, primitive: 0 }.from_asset(CHARACTER))
        .expect("the scene holds the mesh");
    let source = world.resource::<Assets<Mesh>>().get(&handle).unwrap();
    let (
        Some(VertexAttributeValues::Float32x3(bind)),
        Some(VertexAttributeValues::Uint16x4(joints)),
        Some(VertexAttributeValues::Float32x4(weights)),
    ) = (
        source.attribute(Mesh::ATTRIBUTE_POSITION),
        source.attribute(Mesh::ATTRIBUTE_JOINT_INDEX),
        source.attribute(Mesh::ATTRIBUTE_JOINT_WEIGHT),
    )
    else {
        panic!("the file's mesh is skinned")
    };
    let ClothSkin(skin) = world.get::<ClothSkin>(cloth).expect("the plugin kept the skin");
    let inverse = world.resource::<Assets<SkinnedMeshInverseBindposes>>().get(&skin.inverse_bindposes).unwrap();
    let simulation = world.get::<ClothSimulation>(cloth).unwrap();
    let map = simulation.sim().topology().vertex_particle();
    simulation
        .sim()
        .pins()
        .iter()
        .map(|&pin| {
            let v = map.iter().position(|&p| p == pin).unwrap();
            let place = (0..4)
                .filter(|&k| weights[v][k] != 0.0)
                .map(|k| {
                    let j = joints[v][k] as usize;
                    let joint = world.get::<GlobalTransform>(skin.joints[j]).unwrap().to_matrix();
                    weights[v][k] * (joint * inverse[j]).transform_point3(Vec3::from(bind[v]))
                })
                .sum();
            (pin, place)
        })
        .collect()
}

/// The entity called `name`.
pub(crate) fn named(app: &mut App, name: &str) -> Entity {
    let mut query = app.world_mut().query::<(Entity, &Name)>();
    query.iter(app.world()).find(|(_, n)| n.as_str() == name).map(|(e, _)| e).unwrap_or_else(|| panic!("no {name}"))
}

/// The body's boxes as the skin draws them now: each 24-vertex box of the file's body mesh
/// (mesh 0), bound to one joint, as that joint's matrix (world transform times inverse bind
/// pose) and the box's bind-pose bounds. A point is inside the body when it is inside one.
pub(crate) fn body_boxes(app: &App, body: Entity) -> Vec<(Affine3A, Vec3, Vec3)> {
    let world = app.world();
    let handle = world
        .resource::<AssetServer>()
        .get_handle::<Mesh>(GltfAssetLabel::Primitive { mesh: 0, primitive: 0 }.from_asset(CHARACTER))
        .expect("the scene holds the body");
    let mesh = world.resource::<Assets<Mesh>>().get(&handle).unwrap();
    let (Some(VertexAttributeValues::Float32x3(bind)), Some(VertexAttributeValues::Uint16x4(joints))) =
        (mesh.attribute(Mesh::ATTRIBUTE_POSITION), mesh.attribute(Mesh::ATTRIBUTE_JOINT_INDEX))
    else {
        panic!("the body is skinned")
    };
    let skin = world.get::<SkinnedMesh>(body).expect("the body keeps its skin");
    let inverse = world.resource::<Assets<SkinnedMeshInverseBindposes>>().get(&skin.inverse_bindposes).unwrap();
    bind.chunks_exact(24)
        .zip(joints.chunks_exact(24))
        .map(|(corners, joints)| {
            let j = joints[0][0] as usize;
            let joint = world.get::<GlobalTransform>(skin.joints[j]).unwrap().affine();
            let (lo, hi) = corners.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &c| {
                (lo.min(Vec3::from(c)), hi.max(Vec3::from(c)))
            });
            (joint * Affine3A::from_mat4(inverse[j]), lo, hi)
        })
        .collect()
}

/// Whether `p` is inside one of the body's `boxes` (see [`body_boxes`]).
pub(crate) fn inside_body(boxes: &[(Affine3A, Vec3, Vec3)], p: Vec3) -> bool {
    boxes.iter().any(|(to_world, lo, hi)| {
        let q = to_world.inverse().transform_point3(p);
        q.cmpgt(*lo).all() && q.cmplt(*hi).all()
    })
}

/// The mesh entity of the node `node`: glTF names the node, and its primitive is the entity
/// with the mesh, under it or on it.
pub(crate) fn mesh_of(app: &mut App, node: Entity) -> Entity {
    let mut query = app.world_mut().query_filtered::<(Entity, Option<&ChildOf>), With<Mesh3d>>();
    query
        .iter(app.world())
        .find(|(e, parent)| *e == node || parent.is_some_and(|p| p.parent() == node))
        .map(|(e, _)| e)
        .expect("a mesh")
}

#[test]
fn a_gltf_character_wears_its_cape_and_skirt_while_it_walks() {
    let mut app = gltf_app();
    app.init_resource::<Heard>();
    app.add_observer(|ready: On<ColliderReady>, mut heard: ResMut<Heard>| heard.parts.push(ready.entity));
    // The scene and the walk loop from one load of the file (a label asked for after the file's
    // own asset is dropped would load it again, and respawn the scene).
    let server = app.world().resource::<AssetServer>();
    let scene = server.load(GltfAssetLabel::Scene(0).from_asset(CHARACTER));
    let clip = server.load(GltfAssetLabel::Animation(0).from_asset(CHARACTER));
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
    let tris = |app: &App, cloth: Entity| {
        app.world().get::<ClothSimulation>(cloth).unwrap().sim().topology().triangles().to_vec()
    };
    let (body, cape, skirt) = (mesh_of(&mut app, body), mesh_of(&mut app, cape), mesh_of(&mut app, skirt));
    for cloth in [cape, skirt] {
        assert!(app.world().get::<ClothSimulation>(cloth).is_some(), "{cloth} is simulated");
        assert!(app.world().get::<SkinnedMesh>(cloth).is_none(), "{cloth} is not skinned a second time");
        assert!(app.world().get::<ClothCollider>(cloth).is_none(), "{cloth} is not part of the body's collider");
    }
    assert!(app.world().get::<ClothCollider>(body).is_some(), "the body collides");
    assert_eq!(app.world().resource::<Heard>().parts, [body], "the body's part said it was ready, once");

    // Play the walk loop.
    let (graph, walk) = AnimationGraph::from_clip(clip);
    let graph = app.world_mut().resource_mut::<Assets<AnimationGraph>>().add(graph);
    let mut players = app.world_mut().query_filtered::<Entity, With<AnimationPlayer>>();
    let player = players.iter(app.world()).next().expect("the glTF loader gives the animated scene a player");
    app.world_mut().entity_mut(player).insert(AnimationGraphHandle(graph));
    app.world_mut().get_mut::<AnimationPlayer>(player).unwrap().play(walk).repeat();

    // The cape's seam in the chest's frame: over the shoulders it follows the arms too.
    let in_chest = |app: &App| -> Vec<Vec3> {
        let frame = app.world().get::<GlobalTransform>(chest).unwrap().affine().inverse();
        let sim = app.world().get::<ClothSimulation>(cape).unwrap().sim();
        sim.pins().iter().map(|&p| frame.transform_point3(sim.position(p as usize))).collect()
    };
    run(&mut app, 0.1);
    let chest_start = in_chest(&app);
    assert!(!chest_start.is_empty(), "the painted rows are sewn on");
    let hips_start = app.world().get::<GlobalTransform>(hips).unwrap().translation();
    let (mut hips_travel, mut worst_seam, mut off_chest, mut ever_inside, mut crossed) = (0.0f32, 0.0f32, 0.0f32, 0, 0);
    for frame in 0..600 {
        run(&mut app, 1.0 / 60.0);
        let hips_now = app.world().get::<GlobalTransform>(hips).unwrap().translation();
        hips_travel = hips_travel.max(hips_now.distance(hips_start));
        for (a, b) in in_chest(&app).iter().zip(&chest_start) {
            off_chest = off_chest.max(a.distance(*b));
        }
        for (cloth, mesh) in [(cape, 1), (skirt, 2)] {
            let sim = app.world().get::<ClothSimulation>(cloth).unwrap().sim();
            for (pin, place) in skinned_pins(&app, cloth, mesh) {
                worst_seam = worst_seam.max(sim.position(pin as usize).distance(place));
            }
            let points = positions(&app, cloth);
            assert!(points.iter().all(|p| p.is_finite()), "{cloth} stays finite");
            // The free particles: the sewn ones sit where the seam holds them.
            let held = app.world().get::<ClothSimulation>(cloth).unwrap().sim().pins().to_vec();
            let body = app.world().get::<ClothCollider>(body).unwrap().collider();
            let inside = points.iter().enumerate().filter(|&(i, &p)| !held.contains(&(i as u32)) && body.contains(p));
            ever_inside += inside.count();
        }
        // The garments' triangles, each against itself and the other, four times a second.
        if frame % 15 == 14 {
            let (a, b) = (positions(&app, cape), positions(&app, skirt));
            let (ta, tb) = (tris(&app, cape), tris(&app, skirt));
            crossed += crossing_pairs(&ta, &a, None) + crossing_pairs(&tb, &b, None);
            crossed += crossing_pairs(&ta, &a, Some((&tb, &b)));
        }
    }
    println!("hips travel {hips_travel} m, seam off its skin {worst_seam} m, cape seam off the chest {off_chest} m");
    assert!(hips_travel > 0.02, "the walk loop moved the hips ({hips_travel} m)");
    assert!(worst_seam < 1.0e-3, "the seams followed their skin within 1 mm (worst {worst_seam} m)");
    assert!(
        off_chest > 0.01,
        "over the shoulders the cape's seam follows the arms, not the chest alone ({off_chest} m)"
    );
    // Without self-contact the cape, swinging down, goes through the skirt's back (6 pairs
    // crossed at the first check): this fails then.
    assert_eq!(crossed, 0, "garment triangles crossed themselves or each other");
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

/// A root whose scene file does not exist says so once, naming the root, after
/// `ClothSettings::scene_wait`; nothing panics and a cloth beside it keeps falling.
#[test]
fn a_scene_that_never_spawns_is_reported_on_its_root() {
    let mut app = gltf_app();
    app.world_mut().resource_mut::<ClothSettings>().scene_wait = 2.0;
    let scene = app.world().resource::<AssetServer>().load(GltfAssetLabel::Scene(0).from_asset("models/missing.glb"));
    let root = app.world_mut().spawn((WorldAssetRoot(scene), AutoCollider::new(8), dressed())).id();
    let beside = app.world_mut().spawn(Cloth::grid(Vec2::ONE, UVec2::splat(8)).starting_at_once()).id();
    run(&mut app, 1.5);
    let not_spawned = |app: &App| {
        sent(app)
            .iter()
            .filter(|m| matches!(m, ClothMessage::SceneNotSpawned { entity, .. } if *entity == root))
            .count()
    };
    assert_eq!(not_spawned(&app), 0, "not before the wait");
    let height = positions(&app, beside)[0].y;
    run(&mut app, 3.0);
    assert_eq!(not_spawned(&app), 1, "said once, naming the root");
    let now = positions(&app, beside);
    assert!(now.iter().all(|p| p.is_finite()) && now[0].y < height - 1.0, "the cloth beside it kept falling");
}
