//! Cloth from an authored mesh: welded seams, pins by vertex index that follow the entity tick
//! by tick, and meshes that cannot be cloth.

use bevy::asset::RenderAssetUsages;
use bevy::mesh::{Indices, PrimitiveTopology, VertexAttributeValues};
use bevy::prelude::*;
use bevy_bvh_cloth::bvh_cloth_core::ClothError;
use bevy_bvh_cloth::prelude::*;

use crate::headless::harness::{add_mesh, app, app_at, positions, run, sent};

/// A flag as an exporter writes one: `cols x rows` points over 1.2 m x 0.8 m in the local XY
/// plane (the pole along x = 0), split at a UV seam down the middle column, with UVs.
pub(crate) fn seamed_flag(cols: u32, rows: u32) -> Mesh {
    let seam = cols / 2;
    let (mut positions, mut uvs, mut indices) = (Vec::new(), Vec::new(), Vec::new());
    for (first, last, u0) in [(0, seam, 0.0f32), (seam, cols - 1, 0.5)] {
        let start = positions.len() as u32;
        let span = last - first + 1;
        for r in 0..rows {
            for c in first..=last {
                let (u, v) = (c as f32 / (cols - 1) as f32, r as f32 / (rows - 1) as f32);
                positions.push([1.2 * u, -0.8 * v, 0.0]);
                uvs.push([u0 + (u - u0), v]);
            }
        }
        for r in 0..rows - 1 {
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

/// The vertices of `mesh` on the pole (x = 0).
pub(crate) fn pole_vertices(mesh: &Mesh) -> Vec<u32> {
    let Some(VertexAttributeValues::Float32x3(p)) = mesh.attribute(Mesh::ATTRIBUTE_POSITION) else { unreachable!() };
    (0..p.len() as u32).filter(|&v| p[v as usize][0] == 0.0).collect()
}

fn mesh_positions(app: &App, cloth: Entity) -> Vec<Vec3> {
    let handle = &app.world().get::<Mesh3d>(cloth).unwrap().0;
    let mesh = app.world().resource::<Assets<Mesh>>().get(handle).unwrap();
    let Some(VertexAttributeValues::Float32x3(p)) = mesh.attribute(Mesh::ATTRIBUTE_POSITION) else { unreachable!() };
    p.iter().map(|&p| Vec3::from(p)).collect()
}

#[test]
fn a_seamed_flag_stays_closed_and_its_pole_follows_the_entity() {
    // 30 frames per second: two ticks per frame, so the pole's pose is interpolated within it.
    let mut app = app_at(30.0);
    let flag = seamed_flag(13, 9);
    let pole = pole_vertices(&flag);
    assert_eq!(pole.len(), 9);
    let handle = add_mesh(&mut app, flag);
    let start = Transform::from_xyz(0.0, 2.0, 0.0);
    let cloth = app
        .world_mut()
        .spawn((
            Mesh3d(handle.clone()),
            Cloth { params: ClothParams { damping: 0.5, ..default() }, ..Cloth::mesh() }
                .with_pins(ClothPins::Indices(pole.clone())),
            start,
        ))
        .id();
    app.update();
    let sim = app.world().get::<ClothSimulation>(cloth).expect("the flag is simulated").sim();
    assert_eq!(sim.len(), 13 * 9, "the seam's duplicate vertices are welded");
    assert_eq!(sim.pins().len(), 9);
    assert_ne!(app.world().get::<Mesh3d>(cloth).unwrap().0, handle, "the cloth draws its own copy");
    assert!(app.world().resource::<Assets<Mesh>>().get(&handle).is_some(), "the authored mesh is kept");

    // Two seconds: the pole swings about the vertical and climbs, the flag flaps.
    for frame in 1..=60 {
        let t = frame as f32 / 30.0;
        *app.world_mut().get_mut::<Transform>(cloth).unwrap() =
            Transform::from_xyz(0.0, 2.0 + 0.5 * t, 0.0).with_rotation(Quat::from_rotation_y(1.2 * (3.0 * t).sin()));
        app.update();
    }
    let p = positions(&app, cloth);
    assert!(p.iter().all(|p| p.is_finite()));
    let transform = *app.world().get::<Transform>(cloth).unwrap();
    let topology = app.world().get::<ClothSimulation>(cloth).unwrap().sim().topology().clone();
    let rest = topology.rest_positions();
    for &v in &pole {
        let i = topology.vertex_particle()[v as usize] as usize;
        let target = transform.transform_point(rest[i]);
        assert!(p[i].distance(target) < 1e-5, "pole particle {i} at {} not {target}", p[i]);
    }
    let hanging = p.iter().map(|p| p.x.hypot(p.z)).fold(0.0f32, f32::max);
    assert!(hanging > 0.5, "the flag hangs out from its pole ({hanging} m)");

    // No crack: every render vertex of a welded point sits exactly where its twins do.
    let drawn = mesh_positions(&app, cloth);
    for (v, &i) in topology.vertex_particle().iter().enumerate() {
        let local = transform.compute_affine().inverse().transform_point3(p[i as usize]);
        assert!(drawn[v].distance(local) < 1e-5, "vertex {v} drawn at {} not {local}", drawn[v]);
        for (w, &j) in topology.vertex_particle().iter().enumerate().skip(v + 1) {
            if i == j {
                assert_eq!(drawn[v], drawn[w], "seam vertices {v} and {w} split apart");
            }
        }
    }
}

#[test]
fn a_mesh_that_is_still_loading_becomes_cloth_when_it_arrives() {
    let mut app = app();
    let handle: Handle<Mesh> = app.world().resource::<Assets<Mesh>>().reserve_handle();
    let cloth = app.world_mut().spawn((Mesh3d(handle.clone()), Cloth::mesh(), Transform::from_xyz(0.0, 2.0, 0.0))).id();
    run(&mut app, 0.2);
    assert!(app.world().get::<ClothSimulation>(cloth).is_none());
    assert!(sent(&app).is_empty(), "waiting for an asset is not an error: {:?}", sent(&app));
    app.world_mut().resource_mut::<Assets<Mesh>>().insert(handle.id(), seamed_flag(5, 4)).unwrap();
    run(&mut app, 0.2);
    let sim = app.world().get::<ClothSimulation>(cloth).expect("built once the mesh arrived").sim();
    assert_eq!(sim.len(), 20);
}

#[test]
fn meshes_that_cannot_be_cloth_are_refused_by_name_and_the_rest_runs() {
    let mut app = app();
    let good =
        app.world_mut().spawn((Cloth::grid(Vec2::ONE, UVec2::splat(8)), Transform::from_xyz(0.0, 2.0, 0.0))).id();
    let mut nan = seamed_flag(5, 4);
    if let Some(VertexAttributeValues::Float32x3(p)) = nan.attribute_mut(Mesh::ATTRIBUTE_POSITION) {
        p[3][1] = f32::NAN;
    }
    let lines = Mesh::new(PrimitiveTopology::LineList, RenderAssetUsages::default())
        .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, vec![[0.0f32; 3], [1.0, 0.0, 0.0]]);
    let flat = Mesh::new(PrimitiveTopology::TriangleList, RenderAssetUsages::default())
        .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, vec![[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]]);
    // Its data is moved to the render world once uploaded: the simulation cannot read it.
    let mut render_only = seamed_flag(5, 4);
    render_only.asset_usage = RenderAssetUsages::RENDER_WORLD;
    let cases: Vec<(Option<Mesh>, ClothPins, ClothError)> = vec![
        (None, ClothPins::None, ClothError::NoTriangleMesh),
        (Some(render_only), ClothPins::None, ClothError::NoTriangleMesh),
        (Some(nan), ClothPins::None, ClothError::MeshVertexNotFinite { vertex: 3 }),
        (Some(lines), ClothPins::None, ClothError::NoTriangleMesh),
        (Some(flat), ClothPins::None, ClothError::MeshWithoutArea),
        (Some(seamed_flag(5, 4)), ClothPins::TwoEnds, ClothError::PinsNeedGrid),
        (
            Some(seamed_flag(5, 4)),
            ClothPins::Indices(vec![2, 24]),
            ClothError::PinOutOfRange { index: 24, particles: 24 },
        ),
    ];
    let mut refused = Vec::new();
    for (mesh, pins, error) in cases {
        let mut entity = app.world_mut().spawn((Cloth::mesh().with_pins(pins), Transform::from_xyz(3.0, 2.0, 0.0)));
        if let Some(mesh) = mesh {
            let handle = entity.world_scope(|world| world.resource_mut::<Assets<Mesh>>().add(mesh));
            entity.insert(Mesh3d(handle));
        }
        refused.push((entity.id(), error));
    }
    app.update();
    let before = positions(&app, good);
    run(&mut app, 0.5);
    for (entity, error) in refused {
        assert!(app.world().get::<ClothSimulation>(entity).is_none());
        assert!(
            sent(&app).contains(&ClothMessage::Rejected { entity, error: error.clone() }),
            "{entity} should be refused with {error}: {:?}",
            sent(&app)
        );
    }
    let after = positions(&app, good);
    assert!(after.iter().zip(&before).all(|(a, b)| a.y < b.y - 0.1), "the grid cloth kept falling");
}
