//! AutoCollider on a skinned mesh: the collider follows the joints as the animation moves them,
//! checked against the skinned triangles themselves; bad skins and despawned joints.

use bevy::asset::RenderAssetUsages;
use bevy::math::Affine3A;
use bevy::mesh::skinning::{SkinnedMesh, SkinnedMeshInverseBindposes};
use bevy::mesh::{Indices, PrimitiveTopology};
use bevy::prelude::*;
use bevy_bvh_cloth::bvh_cloth_core::skinning::SkinnedVertices;
use bevy_bvh_cloth::prelude::*;
use bevy_bvh_cloth::{ClothCollider, ColliderFailure};

use crate::harness::{add_mesh, app, positions, run, sent, wait_for_collider};

const LENGTH: f32 = 1.2;
const RADIUS: f32 = 0.12;
const ELBOW: f32 = 0.6;

/// Positions, indices, joints and weights.
type SkinnedArm = (Vec<[f32; 3]>, Vec<u32>, Vec<[u16; 4]>, Vec<[f32; 4]>);

/// A closed arm along +x from the origin: a 16-sided tube of `LENGTH` with capped ends. The part
/// before the elbow is on joint 0, the part after it on joint 1, blended over 20 cm.
fn arm() -> SkinnedArm {
    let (rings, slices) = (30u32, 16u32);
    let mut positions = Vec::new();
    let mut weights = Vec::new();
    let weight = |x: f32| ((x - (ELBOW - 0.1)) / 0.2).clamp(0.0, 1.0);
    for i in 0..=rings {
        let x = LENGTH * i as f32 / rings as f32;
        for j in 0..slices {
            let angle = std::f32::consts::TAU * j as f32 / slices as f32;
            positions.push([x, RADIUS * angle.cos(), RADIUS * angle.sin()]);
            weights.push([1.0 - weight(x), weight(x), 0.0, 0.0]);
        }
    }
    let mut indices = Vec::new();
    for i in 0..rings {
        for j in 0..slices {
            let a = i * slices + j;
            let b = i * slices + (j + 1) % slices;
            let (c, d) = (a + slices, b + slices);
            indices.extend_from_slice(&[a, b, c, b, d, c]);
        }
    }
    // The caps: a centre vertex at each end.
    for (ring, x) in [(0, 0.0), (rings, LENGTH)] {
        let centre = positions.len() as u32;
        positions.push([x, 0.0, 0.0]);
        weights.push([1.0 - weight(x), weight(x), 0.0, 0.0]);
        for j in 0..slices {
            let (a, b) = (ring * slices + j, ring * slices + (j + 1) % slices);
            indices.extend_from_slice(&[centre, a, b]);
        }
    }
    let joints = vec![[0, 1, 0, 0]; positions.len()];
    (positions, indices, joints, weights)
}

fn arm_mesh() -> Mesh {
    let (positions, indices, joints, weights) = arm();
    Mesh::new(PrimitiveTopology::TriangleList, RenderAssetUsages::default())
        .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, positions)
        .with_inserted_attribute(Mesh::ATTRIBUTE_JOINT_INDEX, bevy::mesh::VertexAttributeValues::Uint16x4(joints))
        .with_inserted_attribute(Mesh::ATTRIBUTE_JOINT_WEIGHT, weights)
        .with_inserted_indices(Indices::U32(indices))
}

/// A shoulder joint at `at` and an elbow joint under it, a skinned arm mesh on them with an
/// `AutoCollider`; returns (arm, shoulder, elbow).
fn spawn_arm(app: &mut App, mesh: Mesh, at: Vec3) -> (Entity, Entity, Entity) {
    let mesh = add_mesh(app, mesh);
    let inverse = app
        .world_mut()
        .resource_mut::<Assets<SkinnedMeshInverseBindposes>>()
        .add(vec![Mat4::IDENTITY, Mat4::from_translation(Vec3::new(-ELBOW, 0.0, 0.0))]);
    let shoulder = app.world_mut().spawn(Transform::from_translation(at)).id();
    let elbow = app.world_mut().spawn((Transform::from_xyz(ELBOW, 0.0, 0.0), ChildOf(shoulder))).id();
    let arm = app
        .world_mut()
        .spawn((
            Mesh3d(mesh),
            SkinnedMesh { inverse_bindposes: inverse, joints: vec![shoulder, elbow] },
            AutoCollider { margin: 0.01, ..AutoCollider::with_voxel_size(0.06) },
        ))
        .id();
    (arm, shoulder, elbow)
}

/// The arm's triangles as the renderer draws them this frame.
fn skinned_triangles(app: &App, shoulder: Entity, elbow: Entity) -> Vec<[Vec3; 3]> {
    let (positions, indices, joints, weights) = arm();
    let vertices = SkinnedVertices { positions: positions.iter().map(|&p| Vec3A::from(p)).collect(), joints, weights };
    let global = |e: Entity| app.world().get::<GlobalTransform>(e).unwrap().affine();
    let matrices = [global(shoulder), global(elbow) * Affine3A::from_translation(Vec3::new(-ELBOW, 0.0, 0.0))];
    let mut skinned = Vec::new();
    vertices.skin_into(&matrices, &mut skinned);
    indices.chunks_exact(3).map(|t| [0, 1, 2].map(|k| Vec3::from(skinned[t[k] as usize]))).collect()
}

/// Whether `p` is inside the closed triangle mesh: the parity of a ray's crossings.
fn inside(p: Vec3, triangles: &[[Vec3; 3]]) -> bool {
    let dir = Vec3::new(0.1234, 1.0, 0.0457).normalize();
    let crossings = triangles
        .iter()
        .filter(|[a, b, c]| {
            // Möller–Trumbore.
            let (e1, e2) = (*b - *a, *c - *a);
            let h = dir.cross(e2);
            let det = e1.dot(h);
            if det.abs() < 1e-12 {
                return false;
            }
            let s = p - *a;
            let u = s.dot(h) / det;
            let q = s.cross(e1);
            let v = dir.dot(q) / det;
            u >= 0.0 && v >= 0.0 && u + v <= 1.0 && e2.dot(q) / det > 0.0
        })
        .count();
    crossings % 2 == 1
}

/// A cloth dropped on an arm that then swings at the shoulder and bends at the elbow for 10 s:
/// after every tick no particle is inside the skinned body (the parity test against the triangles the
/// renderer draws), while the arm carries the cloth up and down.
#[test]
fn a_cloth_on_an_animated_arm_never_ends_a_tick_inside_it() {
    let mut app = app();
    let (arm, shoulder, elbow) = spawn_arm(&mut app, arm_mesh(), Vec3::new(-0.6, 1.0, 0.0));
    wait_for_collider(&mut app, arm);
    let cloth = app
        .world_mut()
        .spawn((
            Cloth {
                params: ClothParams { damping: 1.0, ..default() },
                ..Cloth::grid(Vec2::splat(1.0), UVec2::splat(24))
            },
            // Over the upper arm, between the shoulder and the elbow.
            Transform::from_xyz(-0.3, 1.3, 0.0),
        ))
        .id();
    let (mut lifted, mut checked, mut touching) = (0.0f32, 0, 0);
    // One second to land on the arm at rest, then ten of animation.
    for frame in 0..660 {
        let t = (frame as f32 / 60.0 - 1.0).max(0.0);
        // The shoulder swings the arm up and down by 0.3 rad, the elbow bends up to 0.6 rad.
        let swing = 0.3 * (std::f32::consts::TAU * t / 4.0).sin();
        let bend = 0.3 - 0.3 * (std::f32::consts::TAU * t / 3.0).cos();
        app.world_mut().get_mut::<Transform>(shoulder).unwrap().rotation = Quat::from_rotation_z(swing);
        app.world_mut().get_mut::<Transform>(elbow).unwrap().rotation = Quat::from_rotation_z(bend);
        run(&mut app, 1.0 / 60.0);
        let triangles = skinned_triangles(&app, shoulder, elbow);
        let p = positions(&app, cloth);
        let bad: Vec<usize> = (0..p.len()).filter(|&i| inside(p[i], &triangles)).collect();
        assert!(bad.is_empty(), "at {t:.2} s particles {bad:?} are inside the arm");
        checked += p.len();
        // The cloth is on the arm: many particles within 5 cm of its collider.
        let near = app.world().get::<ClothCollider>(arm).unwrap().collider().clone().with_margin(0.05);
        touching += usize::from(p.iter().filter(|&&q| near.contains(q)).count() >= 50);
        let tip = triangles.iter().flatten().map(|v| v.y).fold(f32::NEG_INFINITY, f32::max);
        lifted = lifted.max(tip);
    }
    assert_eq!(checked, 660 * 24 * 24);
    eprintln!("animated arm: highest point {lifted:.3} m, cloth on the arm in {touching} of 660 ticks");
    // The arm rose well above its rest height, carrying the cloth all along.
    assert!(lifted > 1.0 + RADIUS + 0.25, "the arm's highest point reached only {lifted}");
    assert!(touching >= 620, "the cloth lay on the arm in only {touching} of 660 ticks");
    // The collider is where the arm is: its spheres are in world space, around the bent arm.
    let collider = app.world().get::<ClothCollider>(arm).unwrap().collider();
    let tip = skinned_triangles(&app, shoulder, elbow).iter().flatten().fold(
        Vec3::ZERO,
        |a, &b| {
            if b.x > a.x { b } else { a }
        },
    );
    assert!(collider.contains(tip), "the arm's far tip {tip} is outside its collider");
}

/// A skinned mesh without joint weights, and one weighted to a joint the skin lacks, fail with
/// a clear reason on their entity; a despawned joint leaves the collider at its last pose and
/// the rest of the scene runs.
#[test]
fn bad_skins_fail_and_a_despawned_joint_holds_the_last_pose() {
    let mut app = app();
    let mut unweighted = arm_mesh();
    unweighted.remove_attribute(Mesh::ATTRIBUTE_JOINT_WEIGHT);
    let (no_weights, ..) = spawn_arm(&mut app, unweighted, Vec3::ZERO);
    let mut far_joint = arm_mesh();
    let (_, _, joints, _) = arm();
    let joints: Vec<[u16; 4]> = joints.iter().map(|_| [0, 7, 0, 0]).collect();
    far_joint.insert_attribute(Mesh::ATTRIBUTE_JOINT_INDEX, bevy::mesh::VertexAttributeValues::Uint16x4(joints));
    let (out_of_range, ..) = spawn_arm(&mut app, far_joint, Vec3::new(0.0, 0.0, 2.0));
    let (good, shoulder, elbow) = spawn_arm(&mut app, arm_mesh(), Vec3::new(0.0, 0.0, -2.0));
    wait_for_collider(&mut app, good);
    run(&mut app, 0.1);
    let failure = |entity| match app.world().get::<ColliderStatus>(entity) {
        Some(ColliderStatus::Failed(reason)) => reason.clone(),
        other => panic!("{entity} is {other:?}"),
    };
    assert!(failure(no_weights).contains("joint weights"), "{}", failure(no_weights));
    assert!(failure(out_of_range).contains("joint 7"), "{}", failure(out_of_range));
    let failed: Vec<Entity> = sent(&app)
        .iter()
        .filter_map(|m| match m {
            ClothMessage::ColliderFailed {
                entity,
                failure: ColliderFailure::NoSkin | ColliderFailure::Rejected(_),
            } => Some(*entity),
            _ => None,
        })
        .collect();
    assert!(failed.contains(&no_weights) && failed.contains(&out_of_range), "{failed:?}");

    // Bend the elbow, then despawn it: the collider keeps the bent pose.
    app.world_mut().get_mut::<Transform>(elbow).unwrap().rotation = Quat::from_rotation_z(1.0);
    run(&mut app, 0.1);
    let bent = app.world().get::<ClothCollider>(good).unwrap().collider().lbvh().unwrap().spheres.clone();
    app.world_mut().entity_mut(elbow).despawn();
    app.world_mut().get_mut::<Transform>(shoulder).unwrap().rotation = Quat::from_rotation_z(0.5);
    run(&mut app, 0.1);
    let held = app.world().get::<ClothCollider>(good).unwrap().collider().lbvh().unwrap().spheres.clone();
    assert_eq!(held, bent, "the collider holds its last complete pose");
    assert!(matches!(app.world().get::<ColliderStatus>(good), Some(ColliderStatus::Ready { .. })));
}
