//! AutoCollider: building from OBJ and primitive meshes, draping, moving, rebuilding, failing.

use bevy::asset::RenderAssetUsages;
use bevy::mesh::{Indices, PrimitiveTopology};
use bevy::prelude::*;
use bevy_bvh_cloth::bvh_cloth_core::{Collider, ColliderShape, MeshRef, parse_obj};
use bevy_bvh_cloth::prelude::*;
use bevy_bvh_cloth::{ClothCollider, ColliderFailure, ColliderPart, collider_from_mesh};

use crate::headless::harness::{add_mesh, app, positions, run, sent, wait_for_collider};

fn ball(app: &mut App, radius: f32) -> Handle<Mesh> {
    add_mesh(app, Sphere::new(radius).mesh().uv(32, 18))
}

/// Every particle of `cloth` that lies inside a sphere of `collider` (margin included, beyond
/// the core's surface tolerance of 1e-5 of a radius).
fn inside(app: &App, cloth: Entity, collider: Entity) -> usize {
    let collider = app.world().get::<ClothCollider>(collider).unwrap().collider();
    positions(app, cloth).iter().filter(|&&p| collider.contains(p)).count()
}

/// A mesh becomes a collider only as an indexed or plain triangle list the main world can read;
/// every other mesh is refused with its reason.
#[test]
fn reads_triangles_and_refuses_the_rest() {
    let mut mesh = Mesh::new(PrimitiveTopology::TriangleList, RenderAssetUsages::default());
    assert_eq!(collider_from_mesh(&mesh, 3).unwrap_err(), ColliderFailure::NoPositions);
    mesh.insert_attribute(
        Mesh::ATTRIBUTE_POSITION,
        vec![[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
    );
    mesh.insert_indices(Indices::U16(vec![0, 1, 2, 0, 3, 1, 0, 2, 3, 1, 3, 2]));
    let tetrahedron = collider_from_mesh(&mesh, 3).unwrap();
    assert!(tetrahedron.sphere_count() > 0);
    // With exact contact, against the triangles read from the index list: the closest point
    // to one just below the face in z = 0 lies on that face.
    let surface = tetrahedron.surface().expect("the default collider has exact contact");
    let closest = surface.closest_within(Vec3::new(0.2, 0.2, -0.05), 0.1).expect("a face within reach");
    assert!(closest.distance(Vec3::new(0.2, 0.2, 0.0)) < 1e-6, "closest point {closest}");

    let lines = Mesh::new(PrimitiveTopology::LineList, RenderAssetUsages::default());
    assert_eq!(collider_from_mesh(&lines, 3).unwrap_err(), ColliderFailure::NotTriangles(PrimitiveTopology::LineList));
    let render_only = Mesh::new(PrimitiveTopology::TriangleList, RenderAssetUsages::RENDER_WORLD);
    assert_eq!(collider_from_mesh(&render_only, 3).unwrap_err(), ColliderFailure::NotInMainWorld);
}

#[test]
fn cloth_drapes_over_the_low_resolution_bunny() {
    let mut app = app();
    let bunny_mesh = app.world().resource::<AssetServer>().load("models/bunny_low.obj");
    let bunny = app.world_mut().spawn((Mesh3d(bunny_mesh), AutoCollider::new(5))).id();
    let (spheres, inner) = wait_for_collider(&mut app, bunny);
    // The same mesh through the core directly gives the same tree.
    let text = std::fs::read_to_string(format!(
        "{}/../../assets/models/bunny_low.obj",
        std::env::var("CARGO_MANIFEST_DIR").expect("run by cargo")
    ))
    .unwrap();
    let obj = parse_obj(&text).unwrap();
    let reference = Collider::from_mesh(MeshRef { positions: &obj.positions, indices: Some(&obj.indices) }, 5).unwrap();
    assert_eq!(
        (spheres as usize, inner as usize),
        (reference.sphere_count(), reference.lbvh().expect("a mesh collider").nodes.len())
    );

    // The bunny stands on y = 0 and is 1 m at its largest; its back lies on the -x side of its
    // box (the top spheres are at -0.4 < x < 0). Drop a 1.2 m cloth over it from 1.2 m.
    let cloth = app
        .world_mut()
        .spawn((
            Cloth {
                params: ClothParams { damping: 1.0, ..default() },
                ..Cloth::grid(Vec2::splat(1.2), UVec2::splat(32))
            },
            Transform::from_xyz(-0.2, 1.2, 0.0),
        ))
        .id();
    let top = reference.lbvh().expect("a mesh collider").bounds().unwrap().1.y;
    for _ in 0..6 {
        run(&mut app, 1.0);
        assert_eq!(inside(&app, cloth, bunny), 0, "particles inside the bunny's spheres");
    }
    let centroid = |app: &App| positions(app, cloth).iter().copied().sum::<Vec3>() / (32.0 * 32.0);
    let before = centroid(&app);
    run(&mut app, 1.0);
    assert_eq!(inside(&app, cloth, bunny), 0, "particles inside the bunny's spheres");

    let p = positions(&app, cloth);
    let lowest = p.iter().map(|p| p.y).fold(f32::INFINITY, f32::min);
    let highest = p.iter().map(|p| p.y).fold(f32::NEG_INFINITY, f32::max);
    // Resting on the bunny: the top of the cloth lies on the top spheres, nothing has passed
    // through to the ground under it, and it has stopped: the cloth as a whole moved less than
    // a centimetre in the last second, and no particle is faster than a slow flap of an edge.
    // (Its centroid moved 3.9 mm in the 7th second and 10.6 mm in the 6th at the default
    // integrator; RK4 6.4 mm and block descent 3.0 mm in the 6th.)
    assert!(highest > top - 0.1 && highest < top + 0.1, "cloth top at {highest}, bunny top at {top}");
    assert!(lowest > 0.1, "the cloth reached the ground under the bunny: {lowest}");
    let drift = before.distance(centroid(&app));
    assert!(drift < 0.01, "the cloth is sliding: its centroid moved {drift} m in 1 s");
    let sim = app.world().get::<ClothSimulation>(cloth).unwrap().sim();
    let speed = sim.velocities().iter().map(|v| v.length()).fold(0.0f32, f32::max);
    assert!(speed < 0.5, "a particle still moves at {speed} m/s after 7 s");
}

#[test]
fn moving_the_collider_moves_the_collision() {
    let mut app = app();
    let mesh = ball(&mut app, 0.5);
    let collider = app.world_mut().spawn((Mesh3d(mesh), AutoCollider::new(1))).id();
    wait_for_collider(&mut app, collider);
    let cloth = app
        .world_mut()
        .spawn((
            Cloth {
                params: ClothParams { damping: 2.0, ..default() },
                ..Cloth::grid(Vec2::splat(0.6), UVec2::splat(16))
            },
            Transform::from_xyz(0.0, 1.0, 0.0),
        ))
        .id();
    run(&mut app, 1.0);
    let centre = |app: &App| positions(app, cloth)[8 * 16 + 8];
    // Held up by the ball (radius 0.5 plus the 0.01 margin).
    assert!((centre(&app).y - 0.51).abs() < 0.02, "cloth centre at {}", centre(&app));

    // Move the ball out from under the cloth: the cloth falls.
    app.world_mut().get_mut::<Transform>(collider).unwrap().translation.x = 5.0;
    run(&mut app, 1.0);
    assert!(centre(&app).y < -1.0, "the cloth stayed up at {}", centre(&app));
    let pose = app.world().get::<ClothCollider>(collider).unwrap().collider().pose;
    assert_eq!(pose.translation, Vec3::new(5.0, 0.0, 0.0));
}

#[test]
fn changing_n_rebuilds_with_the_expected_leaf_count() {
    let mut app = app();
    // A cuboid's faces pass through every voxel but the inner ones: n = 1 gives one sphere,
    // n = 3 gives 3³ - 1 = 26.
    let mesh = add_mesh(&mut app, Cuboid::new(1.0, 2.0, 3.0));
    let collider = app.world_mut().spawn((Mesh3d(mesh), AutoCollider::new(1))).id();
    assert_eq!(wait_for_collider(&mut app, collider), (1, 0));
    app.world_mut().get_mut::<AutoCollider>(collider).unwrap().resolution = 3;
    run(&mut app, 0.05);
    assert_eq!(wait_for_collider(&mut app, collider), (26, 25));
    let tree = &app.world().get::<ClothCollider>(collider).unwrap().collider().lbvh().expect("a mesh collider");
    assert_eq!((tree.spheres.len(), tree.nodes.len()), (26, 25));
}

#[test]
fn big_meshes_are_built_off_the_main_thread() {
    let mut app = app();
    let bunny_mesh = app.world().resource::<AssetServer>().load("models/bunny.obj");
    let bunny = app.world_mut().spawn((Mesh3d(bunny_mesh), AutoCollider::new(5))).id();
    let mut saw_building = false;
    for _ in 0..20_000 {
        match app.world().get::<ColliderStatus>(bunny).unwrap() {
            ColliderStatus::Building => saw_building = true,
            ColliderStatus::Ready { .. } => break,
            _ => {}
        }
        app.update();
    }
    assert!(saw_building, "a 34,817-vertex mesh is above the async threshold");
    let (spheres, inner_nodes) = wait_for_collider(&mut app, bunny);
    // The same tree as the core builds from the same file, synchronously.
    let path = format!("{}/../../assets/models/bunny.obj", std::env::var("CARGO_MANIFEST_DIR").unwrap());
    let obj = parse_obj(&std::fs::read_to_string(path).unwrap()).unwrap();
    let expected = Collider::from_mesh(MeshRef { positions: &obj.positions, indices: Some(&obj.indices) }, 5).unwrap();
    assert_eq!(spheres as usize, expected.lbvh().expect("a mesh collider").spheres.len(), "spheres at n = 5");
    assert_eq!(inner_nodes as usize, expected.lbvh().expect("a mesh collider").nodes.len());
    let built = &app.world().get::<ClothCollider>(bunny).unwrap().collider().lbvh().expect("a mesh collider");
    assert_eq!(
        built.spheres,
        expected.lbvh().expect("a mesh collider").spheres,
        "the async build gives the synchronous tree"
    );
}

#[test]
fn a_broken_collider_reports_and_a_valid_one_still_works() {
    let mut app = app();
    let mut nan_mesh = Mesh::new(PrimitiveTopology::TriangleList, RenderAssetUsages::default());
    nan_mesh
        .insert_attribute(Mesh::ATTRIBUTE_POSITION, vec![[0.0f32, 0.0, 0.0], [f32::NAN, 1.0, 0.0], [0.0, 0.0, 1.0]]);
    nan_mesh.insert_indices(Indices::U32(vec![0, 1, 2]));
    let broken_meshes = [
        add_mesh(&mut app, nan_mesh),
        add_mesh(&mut app, Mesh::new(PrimitiveTopology::LineList, RenderAssetUsages::default())),
        add_mesh(&mut app, Mesh::new(PrimitiveTopology::TriangleList, RenderAssetUsages::default())),
    ];
    let broken: Vec<Entity> = broken_meshes
        .into_iter()
        .map(|mesh| app.world_mut().spawn((Mesh3d(mesh), AutoCollider::new(5))).id())
        .collect();
    // No mesh, and children without one: nothing to build from. (With no children at all it
    // waits, as a scene root does before its scene spawns.)
    let no_mesh = app.world_mut().spawn(AutoCollider::new(5)).with_child(Transform::default()).id();
    let childless = app.world_mut().spawn(AutoCollider::new(5)).id();
    let missing_file = app.world().resource::<AssetServer>().load("models/no_such_model.obj");
    let missing = app.world_mut().spawn((Mesh3d(missing_file), AutoCollider::new(5))).id();
    let valid_mesh = ball(&mut app, 0.5);
    let valid = app.world_mut().spawn((Mesh3d(valid_mesh), AutoCollider::new(1))).id();
    wait_for_collider(&mut app, valid);
    for _ in 0..500 {
        if matches!(app.world().get::<ColliderStatus>(missing), Some(ColliderStatus::Failed(_))) {
            break;
        }
        app.update();
        std::thread::sleep(core::time::Duration::from_millis(2));
    }

    let expected = [
        (broken[0], "vertex 1 has a NaN"),
        (broken[1], "LineList"),
        (broken[2], "no vertex positions"),
        (no_mesh, "nor any of its descendants has a Mesh3d"),
        (missing, "failed to load"),
    ];
    for (entity, reason) in expected {
        let status = app.world().get::<ColliderStatus>(entity).unwrap();
        let ColliderStatus::Failed(message) = status else { panic!("{entity}: {status:?}") };
        assert!(message.contains(reason), "{entity}: {message:?} does not say {reason:?}");
        assert!(app.world().get::<ClothCollider>(entity).is_none());
        let reported = sent(&app)
            .iter()
            .filter(|m| matches!(m, ClothMessage::ColliderFailed { entity: e, .. } if *e == entity))
            .count();
        assert_eq!(reported, 1, "{entity} reported {reported} times");
    }
    assert!(sent(&app).iter().any(|m| matches!(
        m,
        ClothMessage::ColliderFailed { failure: ColliderFailure::NotTriangles(PrimitiveTopology::LineList), .. }
    )));

    assert_eq!(app.world().get::<ColliderStatus>(childless), Some(&ColliderStatus::Waiting));

    // The valid collider still catches a cloth. (The childless root waits for ever, so the
    // cloth does not wait for colliders.)
    let cloth = app
        .world_mut()
        .spawn((
            Cloth {
                params: ClothParams { damping: 2.0, ..default() },
                start_at_once: true,
                ..Cloth::grid(Vec2::splat(0.6), UVec2::splat(16))
            },
            Transform::from_xyz(0.0, 1.0, 0.0),
        ))
        .id();
    run(&mut app, 1.0);
    assert!(positions(&app, cloth)[8 * 16 + 8].y > 0.45);
    assert_eq!(inside(&app, cloth, valid), 0);
}

/// An AutoCollider on an entity without a mesh covers every mesh under it, at any depth, with
/// the root's settings, except the meshes its `ColliderHierarchy` leaves out or overrides by
/// name (their own or their parent's, as glTF names nodes). The root's status sums its parts;
/// a part is removed with the root's collider; a mesh the user gave its own collider keeps it.
#[test]
fn an_auto_collider_on_a_root_covers_the_meshes_under_it() {
    let mut app = app();
    let ball_mesh = ball(&mut app, 0.2);
    let mesh = |name: &str| (Mesh3d(ball_mesh.clone()), Name::new(name.to_string()), Transform::default());
    let root = app
        .world_mut()
        .spawn((
            AutoCollider::new(3),
            ColliderHierarchy::default().exclude("Hair").with("Hand", AutoCollider::new(1)),
            Transform::default(),
        ))
        .id();
    let body = app.world_mut().spawn(mesh("Body")).insert(ChildOf(root)).id();
    let hair = app.world_mut().spawn(mesh("Hair")).insert(ChildOf(root)).id();
    let arm = app.world_mut().spawn((Name::new("Hand"), Transform::default())).insert(ChildOf(body)).id();
    let hand = app.world_mut().spawn(mesh("Hand.0")).insert(ChildOf(arm)).id();
    let own = app.world_mut().spawn((mesh("Prop"), AutoCollider::new(2))).insert(ChildOf(root)).id();
    run(&mut app, 0.1);

    let spheres = |app: &App, entity: Entity| match app.world().get::<ColliderStatus>(entity) {
        Some(ColliderStatus::Ready { spheres, .. }) => *spheres,
        other => panic!("{entity} is not ready: {other:?}"),
    };
    assert_eq!(app.world().get::<AutoCollider>(body), Some(&AutoCollider::new(3)));
    assert_eq!(app.world().get::<AutoCollider>(hand), Some(&AutoCollider::new(1)), "overridden by its parent's name");
    assert!(app.world().get::<AutoCollider>(hair).is_none(), "excluded by name");
    assert!(app.world().get::<ColliderPart>(own).is_none(), "the user's own collider stays theirs");
    assert_eq!(app.world().get::<AutoCollider>(own), Some(&AutoCollider::new(2)));
    assert_eq!(spheres(&app, hand), 1);
    assert!(spheres(&app, body) > 1);
    assert_eq!(spheres(&app, root), spheres(&app, body) + spheres(&app, hand), "the root sums its parts");

    // A cloth dropped on the body lands on it.
    let cloth = app
        .world_mut()
        .spawn((
            Cloth {
                params: ClothParams { damping: 2.0, ..default() },
                ..Cloth::grid(Vec2::splat(0.3), UVec2::splat(8))
            },
            Transform::from_xyz(0.0, 0.5, 0.0),
        ))
        .id();
    run(&mut app, 1.0);
    assert_eq!(inside(&app, cloth, body), 0);
    assert!(positions(&app, cloth).iter().any(|p| p.y > 0.15), "the cloth rests on the body's top");

    // Without the root's collider the parts go; the user's own stays.
    app.world_mut().entity_mut(root).remove::<AutoCollider>();
    run(&mut app, 0.05);
    for part in [body, hand] {
        assert!(app.world().get::<ClothCollider>(part).is_none(), "{part} still collides");
        assert!(app.world().get::<AutoCollider>(part).is_none());
    }
    assert!(app.world().get::<ClothCollider>(own).is_some());
}

/// Heard on a hierarchy's root: what `ColliderHierarchyReady` said, in order.
#[derive(Resource, Default)]
struct HierarchyReady(Vec<(Entity, u32, u32)>);

/// A hierarchy never makes a collider of a mesh that is cloth (the cape of a glTF character must
/// not collide with a copy of itself), drops the part of a mesh that becomes cloth, and tells
/// the root once every part collides.
#[test]
fn a_hierarchy_leaves_its_cloth_out_and_tells_the_root_when_it_is_ready() {
    let mut app = app();
    app.init_resource::<HierarchyReady>();
    let ball_mesh = ball(&mut app, 0.2);
    let mesh = |name: &str| (Mesh3d(ball_mesh.clone()), Name::new(name.to_string()), Transform::default());
    let root = app
        .world_mut()
        .spawn((AutoCollider::new(3), Transform::default()))
        .observe(|ready: On<ColliderHierarchyReady>, mut heard: ResMut<HierarchyReady>| {
            heard.0.push((ready.entity, ready.parts, ready.spheres));
        })
        .id();
    let body = app.world_mut().spawn(mesh("Body")).insert(ChildOf(root)).id();
    let head = app.world_mut().spawn(mesh("Head")).insert(ChildOf(root)).id();
    let cape = app.world_mut().spawn((mesh("Cape"), Cloth::mesh())).insert(ChildOf(root)).id();
    run(&mut app, 0.1);

    assert!(app.world().get::<AutoCollider>(cape).is_none(), "the cape is cloth, not a collider");
    assert!(app.world().get::<ClothCollider>(cape).is_none());
    let status = |app: &App, entity: Entity| app.world().get::<ColliderStatus>(entity).cloned();
    let spheres = match (status(&app, body), status(&app, head)) {
        (Some(ColliderStatus::Ready { spheres: a, .. }), Some(ColliderStatus::Ready { spheres: b, .. })) => a + b,
        other => panic!("the parts are not ready: {other:?}"),
    };
    assert_eq!(app.world().resource::<HierarchyReady>().0, [(root, 2, spheres)], "once, on the root");

    // A part that becomes cloth stops colliding; the root, still ready, is not told again.
    app.world_mut().entity_mut(head).insert(Cloth::mesh());
    run(&mut app, 0.1);
    assert!(app.world().get::<ColliderPart>(head).is_none() && app.world().get::<ClothCollider>(head).is_none());
    assert_eq!(app.world().resource::<HierarchyReady>().0.len(), 1);
}

/// A voxel size in metres gives every mesh under one root voxels of that size, whatever its
/// extent or its entity's scale; a size that would make too many voxels fails that collider
/// with a clear error.
#[test]
fn a_voxel_size_in_metres_is_the_same_for_every_mesh() {
    let mut app = app();
    let small = ball(&mut app, 0.2);
    let big = ball(&mut app, 0.8);
    let root = app.world_mut().spawn((AutoCollider::from_voxel_size(0.1), Transform::default())).id();
    let parts = [
        app.world_mut().spawn(Mesh3d(small.clone())).insert(ChildOf(root)).id(),
        app.world_mut().spawn(Mesh3d(big)).insert(ChildOf(root)).id(),
        app.world_mut()
            .spawn((Mesh3d(small.clone()), Transform::from_scale(Vec3::splat(2.0))))
            .insert(ChildOf(root))
            .id(),
    ];
    let tiny = app.world_mut().spawn((Mesh3d(small), AutoCollider::from_voxel_size(1e-5))).id();
    run(&mut app, 0.1);
    let counts: Vec<UVec3> = parts
        .iter()
        .map(|&part| match &app.world().get::<ClothCollider>(part).expect("built").collider().shape {
            ColliderShape::Spheres { counts, .. } => *counts,
            other => panic!("{other:?}"),
        })
        .collect();
    // 0.4 m, 1.6 m and (scaled by 2) 0.8 m across, in 10 cm voxels.
    assert_eq!(counts, [UVec3::splat(4), UVec3::splat(16), UVec3::splat(8)]);
    let Some(ColliderStatus::Failed(reason)) = app.world().get::<ColliderStatus>(tiny) else {
        panic!("a 10 µm voxel on a 0.4 m ball must fail")
    };
    assert!(reason.contains("voxels; at most 2097152 are accepted"), "{reason}");
}

/// A cloth spawned while its collider's mesh is still loading waits, unbuilt, and starts at
/// rest once the collider is ready, so that it lands on the ball instead of falling through
/// where the ball will be; a cloth that starts at once falls meanwhile.
#[test]
fn a_new_cloth_waits_for_a_collider_being_built() {
    let mut app = app();
    let handle = app.world_mut().resource_mut::<Assets<Mesh>>().reserve_handle();
    let ball_entity = app.world_mut().spawn((Mesh3d(handle.clone()), AutoCollider::new(8))).id();
    let grid = || Cloth {
        params: ClothParams { damping: 1.0, ..default() },
        ..Cloth::grid(Vec2::splat(1.2), UVec2::splat(16))
    };
    let waiting = app.world_mut().spawn((grid(), Transform::from_xyz(0.0, 1.0, 0.0))).id();
    let eager = app.world_mut().spawn((grid().starting_at_once(), Transform::from_xyz(3.0, 1.0, 0.0))).id();
    run(&mut app, 1.0);
    assert_eq!(app.world().get::<ColliderStatus>(ball_entity), Some(&ColliderStatus::Waiting));
    assert!(app.world().get::<ClothSimulation>(waiting).is_none(), "the cloth must wait for the ball");
    let fallen = positions(&app, eager).iter().map(|p| p.y).fold(f32::INFINITY, f32::min);
    assert!(fallen < 0.0, "the eager cloth falls meanwhile: lowest {fallen}");

    // The mesh arrives: the collider is built, and the cloth starts where it was spawned.
    app.world_mut().resource_mut::<Assets<Mesh>>().insert(&handle, Sphere::new(0.5).mesh().uv(32, 18)).unwrap();
    wait_for_collider(&mut app, ball_entity);
    run(&mut app, 0.1);
    let start = positions(&app, waiting);
    assert!(start.iter().all(|p| p.y > 0.9), "the cloth starts at rest where it was spawned");
    run(&mut app, 2.0);
    let highest = positions(&app, waiting).iter().map(|p| p.y).fold(f32::NEG_INFINITY, f32::max);
    assert!(highest > 0.45, "the cloth rests on the ball: highest particle at {highest}");
    assert_eq!(inside(&app, waiting, ball_entity), 0);
}

/// A collider that never finishes (a mesh-less root whose scene never spawns) holds a new cloth
/// only for `ClothSettings::collider_wait`.
#[test]
fn a_cloth_waits_no_longer_than_the_settings_allow() {
    let mut app = app();
    app.world_mut().resource_mut::<ClothSettings>().collider_wait = 0.5;
    let root = app.world_mut().spawn(AutoCollider::new(5)).id();
    let cloth =
        app.world_mut().spawn((Cloth::grid(Vec2::ONE, UVec2::splat(8)), Transform::from_xyz(0.0, 1.0, 0.0))).id();
    run(&mut app, 0.4);
    assert!(app.world().get::<ClothSimulation>(cloth).is_none(), "within the limit the cloth waits");
    run(&mut app, 0.3);
    assert!(app.world().get::<ClothSimulation>(cloth).is_some(), "past the limit the cloth starts");
    assert_eq!(app.world().get::<ColliderStatus>(root), Some(&ColliderStatus::Waiting));
}

/// Removing an `AutoCollider` from a mesh entity takes its collider away; on an entity that
/// also has a `PrimitiveCollider`, the primitive then takes over.
#[test]
fn removing_a_collider_component_stops_the_collision() {
    let mut app = app();
    let mesh = ball(&mut app, 0.5);
    let plain = app.world_mut().spawn((Mesh3d(mesh.clone()), AutoCollider::new(3))).id();
    let both = app
        .world_mut()
        .spawn((Mesh3d(mesh), AutoCollider::new(3), PrimitiveCollider::sphere(0.5), Transform::from_xyz(2.0, 0.0, 0.0)))
        .id();
    wait_for_collider(&mut app, plain);
    wait_for_collider(&mut app, both);
    let mesh_collider =
        |app: &App, entity| app.world().get::<ClothCollider>(entity).map(|c| c.collider().lbvh().is_some());
    assert_eq!(mesh_collider(&app, both), Some(true), "the AutoCollider wins while both are there");

    app.world_mut().entity_mut(plain).remove::<AutoCollider>();
    app.world_mut().entity_mut(both).remove::<AutoCollider>();
    run(&mut app, 0.1);
    assert!(app.world().get::<ClothCollider>(plain).is_none(), "a removed AutoCollider leaves no collider");
    let primitive = app.world().get::<ClothCollider>(both).and_then(|c| c.collider().as_primitive().copied());
    assert!(
        matches!(primitive, Some(bevy_bvh_cloth::bvh_cloth_core::Primitive::Sphere { radius: 0.5 })),
        "{primitive:?}"
    );
}

/// How many times each entity heard `ColliderReady`.
#[derive(Resource, Default)]
struct ReadyCount(Vec<Entity>);

/// A mesh asset reported modified is built again only when what the collider is made of
/// changed: touched with its triangles as they were (as a glTF mesh is right after it loads), the
/// collider is not rebuilt and `ColliderReady` is not heard again; grown to twice its size, it
/// is rebuilt, its shell where the new surface is.
#[test]
fn a_collider_is_rebuilt_when_its_mesh_changes_and_only_then() {
    let mut app = app();
    app.init_resource::<ReadyCount>();
    app.add_observer(|ready: On<ColliderReady>, mut heard: ResMut<ReadyCount>| heard.0.push(ready.entity));
    let mesh = ball(&mut app, 0.5);
    let body = app.world_mut().spawn((Mesh3d(mesh.clone()), AutoCollider::new(8))).id();
    wait_for_collider(&mut app, body);
    run(&mut app, 0.1);
    assert_eq!(app.world().resource::<ReadyCount>().0, [body]);
    let reach =
        |app: &App| app.world().get::<ClothCollider>(body).unwrap().collider().contains(Vec3::new(0.0, 1.0, 0.0));
    assert!(!reach(&app), "the shell of a 0.5 m ball does not reach 1 m");

    // Touched, unchanged.
    {
        let mut meshes = app.world_mut().resource_mut::<Assets<Mesh>>();
        let mut touched = meshes.get_mut(&mesh).unwrap();
        let _: &mut Mesh = &mut touched;
    }
    run(&mut app, 0.2);
    assert_eq!(app.world().resource::<ReadyCount>().0, [body], "an unchanged mesh is not built again");

    // Grown to twice its size.
    {
        let mut meshes = app.world_mut().resource_mut::<Assets<Mesh>>();
        let mut grown = meshes.get_mut(&mesh).unwrap();
        let Some(bevy::mesh::VertexAttributeValues::Float32x3(positions)) =
            grown.attribute_mut(Mesh::ATTRIBUTE_POSITION)
        else {
            unreachable!()
        };
        positions.iter_mut().for_each(|p| *p = (Vec3::from(*p) * 2.0).to_array());
    }
    for _ in 0..500 {
        if app.world().resource::<ReadyCount>().0.len() == 2 {
            break;
        }
        run(&mut app, 1.0 / 60.0);
    }
    assert_eq!(app.world().resource::<ReadyCount>().0, [body, body], "a changed mesh is built again");
    assert!(reach(&app), "the grown ball's shell reaches 1 m");
}
