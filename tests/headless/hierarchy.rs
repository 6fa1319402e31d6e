//! A scene's meshes made cloth by name (`ClothHierarchy`), as a glTF character's cape: built as
//! the scene appears, anchored to its joints by name, left out of the body's collider, told to
//! the root when ready, and every missing name reported on the root.

use bevy::mesh::skinning::SkinnedMesh;
use bevy::prelude::*;
use bevy_bvh_cloth::prelude::*;

use crate::headless::authored::{pole_vertices, seamed_flag};
use crate::headless::harness::{add_mesh, app, positions, run, sent};

/// What the roots heard: `ClothHierarchyReady`'s root and cloth count, in order.
#[derive(Resource, Default)]
struct Ready(Vec<(Entity, u32)>);

/// A character as a scene spawns one: a body mesh, a spine joint, and a cape node whose mesh
/// primitive (skinned, as glTF loads it) is its child. Returns the root, the spine, the cape's
/// mesh entity and the body.
fn character(app: &mut App, hierarchy: ClothHierarchy, x: f32) -> (Entity, Entity, Entity, Entity) {
    let cape_mesh = add_mesh(app, seamed_flag(13, 9));
    let body_mesh = add_mesh(app, Sphere::new(0.2).mesh().ico(2).unwrap());
    let root = app
        .world_mut()
        .spawn((Transform::from_xyz(x, 0.0, 0.0), AutoCollider::new(3), hierarchy))
        .observe(|ready: On<ClothHierarchyReady>, mut heard: ResMut<Ready>| heard.0.push((ready.entity, ready.cloths)))
        .id();
    let body = app.world_mut().spawn((Mesh3d(body_mesh), Name::new("Body"), Transform::default(), ChildOf(root))).id();
    let spine = app.world_mut().spawn((Name::new("Spine"), Transform::from_xyz(0.0, 0.5, -0.3), ChildOf(root))).id();
    let node = app.world_mut().spawn((Name::new("Cape"), Transform::from_xyz(-0.6, 0.5, -0.3), ChildOf(root))).id();
    let cape = app
        .world_mut()
        .spawn((Mesh3d(cape_mesh), Name::new("Cape.0"), Transform::default(), SkinnedMesh::default(), ChildOf(node)))
        .id();
    (root, spine, cape, body)
}

#[test]
fn a_cloth_hierarchy_dresses_each_instance_and_follows_its_joints() {
    let mut app = app();
    app.init_resource::<Ready>();
    let pole = pole_vertices(&seamed_flag(13, 9));
    let hierarchy = ClothHierarchy::default()
        .with("Cape", SceneCloth::default().anchored(ClothPins::Indices(pole.clone()), "Spine"));
    let (root, spine, cape, body) = character(&mut app, hierarchy.clone(), 0.0);
    let (other_root, _, other_cape, _) = character(&mut app, hierarchy, 3.0);
    let mut ever_a_collider = 0;
    for _ in 0..30 {
        run(&mut app, 1.0 / 60.0);
        ever_a_collider += u32::from(app.world().get::<ColliderPart>(cape).is_some());
    }
    assert_eq!(ever_a_collider, 0, "the body's collider never took the cape, not even for a frame");

    for (root, cape) in [(root, cape), (other_root, other_cape)] {
        let cloth = app.world().get::<Cloth>(cape).expect("the cape is cloth on every instance");
        assert_eq!(cloth.shape, ClothShape::Mesh);
        assert_eq!(app.world().get::<ClothPart>(cape), Some(&ClothPart { root }));
        assert!(app.world().get::<SkinnedMesh>(cape).is_none(), "the skin would move the simulated vertices again");
        assert!(app.world().get::<AutoCollider>(cape).is_none(), "the cape is not part of the body's collider");
    }
    assert_eq!(app.world().get::<Cloth>(cape).unwrap().anchors[0].target, spine);
    assert!(app.world().get::<ClothCollider>(body).is_some(), "the body collides");
    let mut heard = app.world().resource::<Ready>().0.clone();
    heard.sort();
    let mut expected = vec![(root, 1), (other_root, 1)];
    expected.sort();
    assert_eq!(heard, expected, "each root told once its cape is built");

    // The joint carries the cape's pole; the free part hangs below it.
    let before = positions(&app, cape);
    app.world_mut().get_mut::<Transform>(spine).unwrap().translation.x += 0.5;
    run(&mut app, 0.1);
    let after = positions(&app, cape);
    let topology = app.world().get::<ClothSimulation>(cape).unwrap().sim().topology().clone();
    for &v in &pole {
        let p = topology.vertex_particle()[v as usize] as usize;
        let moved = after[p] - before[p];
        assert!((moved - Vec3::X * 0.5).length() < 1.0e-3, "pole vertex {v} moved {moved}");
    }
    assert!(after.iter().all(|p| p.is_finite()));
    assert!(sent(&app).iter().all(|m| !matches!(m, ClothMessage::NameNotFound { .. })));
}

#[test]
fn names_the_scene_lacks_are_reported_on_the_root_and_the_rest_runs() {
    let mut app = app();
    app.init_resource::<Ready>();
    let hierarchy = ClothHierarchy::default()
        .with("Scarf", SceneCloth::default())
        .with("Cape", SceneCloth::default().anchored(ClothPins::Indices(vec![0]), "Neck"));
    let (root, _, cape, body) = character(&mut app, hierarchy, 0.0);
    run(&mut app, 0.5);

    let mut missing: Vec<(Entity, String)> = sent(&app)
        .iter()
        .filter_map(|m| match m {
            ClothMessage::NameNotFound { entity, name } => Some((*entity, name.clone())),
            _ => None,
        })
        .collect();
    missing.sort();
    assert_eq!(missing, [(root, "Neck".to_string()), (root, "Scarf".to_string())], "each once, naming the root");
    assert!(app.world().get::<Cloth>(cape).is_none(), "a cape without its joint is not made");
    assert!(app.world().get::<ClothCollider>(body).is_some(), "the rest of the scene runs");
    assert!(app.world().resource::<Ready>().0.is_empty());
}

/// A named mesh that cannot become cloth (a line list) is refused on its entity, naming the
/// error; the scene's other cloth and its body run on.
#[test]
fn a_named_mesh_that_cannot_be_cloth_is_refused_and_the_rest_runs() {
    let mut app = app();
    app.init_resource::<Ready>();
    let hierarchy = ClothHierarchy::default()
        .with("Cape", SceneCloth::default().anchored(ClothPins::Indices(vec![0]), "Spine"))
        .with("Rope", SceneCloth::default());
    let (root, _, cape, body) = character(&mut app, hierarchy, 0.0);
    let lines = Mesh::new(bevy::mesh::PrimitiveTopology::LineList, bevy::asset::RenderAssetUsages::default())
        .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, vec![[0.0f32, 0.0, 0.0], [0.0, -1.0, 0.0]]);
    let lines = add_mesh(&mut app, lines);
    let rope = app.world_mut().spawn((Mesh3d(lines), Name::new("Rope"), Transform::default(), ChildOf(root))).id();
    run(&mut app, 0.5);
    let refused: Vec<Entity> = sent(&app)
        .iter()
        .filter_map(|m| match m {
            ClothMessage::Rejected { entity, .. } => Some(*entity),
            _ => None,
        })
        .collect();
    assert_eq!(refused, [rope], "the rope is refused once, on its entity");
    assert_eq!(app.world().get::<ClothPart>(rope), Some(&ClothPart { root }));
    assert!(app.world().get::<ClothSimulation>(cape).is_some(), "the cape is built");
    assert!(positions(&app, cape).iter().all(|p| p.is_finite()));
    assert!(app.world().get::<ClothCollider>(body).is_some(), "the body collides");
    assert!(app.world().resource::<Ready>().0.is_empty(), "not every named cloth is built: no ClothHierarchyReady");
}
