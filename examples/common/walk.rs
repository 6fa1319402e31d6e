//! The walking figure that the `cape` and `character` examples share: its skeleton's
//! proportions, the walk cycle that drives its joints, and the cape it wears.
//!
//! The figure faces +Z. Its root ([`Walker`]) goes round a circle on the ground; the legs swing
//! from hip joints on the root, and the chest rides a [`Hips`] joint that bobs and rolls with
//! each step, with the arms swinging from the shoulders.

use std::f32::consts::TAU;

use bevy::asset::RenderAssetUsages;
use bevy::mesh::{Indices, PrimitiveTopology};
use bevy::prelude::*;
use bevy_bvh_cloth::prelude::*;

/// Radius of the circle the figure walks, in metres.
const PATH_RADIUS: f32 = 1.3;
/// Walking speed in m/s, and steps per second.
const SPEED: f32 = 1.1;
const CADENCE: f32 = 1.8;
/// Height of the hip joints, and of the shoulders joint above the hips.
pub const HIP_HEIGHT: f32 = 0.9;
pub const SHOULDERS_ABOVE_HIPS: f32 = 0.55;
/// The hip joints' and the arms' sideways offsets, and the arms' drop below the shoulders.
pub const HIP_WIDTH: f32 = 0.11;
pub const SHOULDER_WIDTH: f32 = 0.24;
pub const ARM_DROP: f32 = 0.04;
/// The cape: width at the shoulders and at the hem, length, and its vertices across and down.
const CAPE_TOP: f32 = 0.36;
const CAPE_HEM: f32 = 0.8;
const CAPE_LENGTH: f32 = 0.95;
const CAPE_VERTICES: UVec2 = UVec2::new(17, 24);

/// The walking figure's root, on the ground.
#[derive(Component)]
pub struct Walker;

/// A joint that swings with the walk cycle: `amplitude` radians about local X, in phase
/// `phase` (in turns) with the stride.
#[derive(Component)]
pub struct Swing {
    pub amplitude: f32,
    pub phase: f32,
}

/// The joint the chest rolls and bobs on.
#[derive(Component)]
pub struct Hips;

/// A leg's swing: the left leg leads.
pub fn leg_swing(left: bool) -> Swing {
    Swing { amplitude: 0.45, phase: if left { 0.0 } else { 0.5 } }
}

/// An arm's swing, against its leg.
pub fn arm_swing(left: bool) -> Swing {
    Swing { amplitude: 0.35, phase: if left { 0.5 } else { 0.0 } }
}

/// The cape, anchored by its painted top edge to `shoulders`. Built around the shoulders where
/// they stand at the start, in world space; the anchor then carries the edge.
pub fn cape(
    shoulders: Entity,
    meshes: &mut Assets<Mesh>,
    material: MeshMaterial3d<StandardMaterial>,
) -> (Mesh3d, Cloth, MeshMaterial3d<StandardMaterial>, Transform) {
    let at_shoulders = walker_pose(0.0) * Transform::from_xyz(0.0, HIP_HEIGHT + SHOULDERS_ABOVE_HIPS, 0.0);
    let painted = ClothPins::Painted { channel: ColorChannel::Alpha, threshold: 0.5 };
    (
        Mesh3d(meshes.add(cape_mesh())),
        Cloth {
            params: ClothParams { mass: 0.5, damping: 0.6, spring_k: 300.0, looper: 20, ..default() },
            ..Cloth::mesh()
        }
        .with_anchor(ClothAnchor::new(painted, shoulders)),
        material,
        at_shoulders,
    )
}

/// The cape, in the shoulders' frame: a trapezoid hanging down the back, curved around it,
/// flaring towards the hem. The vertex colours are white, with the pin weight in alpha: 1 on
/// the top row, 0 elsewhere (alpha, so that an opaque material draws the cape in its own
/// colour).
fn cape_mesh() -> Mesh {
    let (cols, rows) = (CAPE_VERTICES.x, CAPE_VERTICES.y);
    let mut positions = Vec::new();
    let mut colors = Vec::new();
    let mut uvs = Vec::new();
    for r in 0..rows {
        let v = r as f32 / (rows - 1) as f32;
        let half_width = 0.5 * (CAPE_TOP + (CAPE_HEM - CAPE_TOP) * v);
        for c in 0..cols {
            let u = c as f32 / (cols - 1) as f32;
            let across = 2.0 * u - 1.0;
            // Around the back at the top (the chest is 0.16 m deep behind the shoulders, its
            // collider a few centimetres more), then straighter and further back as it falls.
            let z = -0.22 - 0.06 * (1.0 - across * across) * (1.0 - v) - 0.1 * v;
            positions.push([across * half_width, -CAPE_LENGTH * v, z]);
            colors.push([1.0, 1.0, 1.0, if r == 0 { 1.0 } else { 0.0 }]);
            uvs.push([u, v]);
        }
    }
    let mut indices = Vec::new();
    for r in 0..rows - 1 {
        for c in 0..cols - 1 {
            let i = r * cols + c;
            indices.extend_from_slice(&[i, i + 1, i + cols, i + 1, i + cols + 1, i + cols]);
        }
    }
    Mesh::new(PrimitiveTopology::TriangleList, RenderAssetUsages::default())
        .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, positions)
        .with_inserted_attribute(Mesh::ATTRIBUTE_COLOR, colors)
        .with_inserted_attribute(Mesh::ATTRIBUTE_UV_0, uvs)
        .with_inserted_indices(Indices::U32(indices))
}

/// Distance walked after `t` seconds: standing for a second, then speeding up over two.
fn walked(t: f32) -> f32 {
    let ramp = 2.0;
    let t = (t - 1.0).max(0.0);
    if t < ramp { SPEED * t * t / (2.0 * ramp) } else { SPEED * (t - ramp / 2.0) }
}

/// The figure on its circle after walking `distance` metres, facing where it goes.
pub fn walker_pose(distance: f32) -> Transform {
    let angle = distance / PATH_RADIUS;
    Transform::from_xyz(PATH_RADIUS * angle.cos(), 0.0, PATH_RADIUS * angle.sin())
        .with_rotation(Quat::from_rotation_y(-angle))
}

/// The walk cycle: the figure goes round its circle, the hips bob and roll with each step, and
/// the legs and arms swing in opposition. The stride follows the distance walked, so the figure
/// stands still while it stands. The walk keeps the cloth's time ([`ClothClock`]), so the two
/// stay in step when rendering is slow (the cloth then runs behind the wall clock) or paused.
#[allow(clippy::type_complexity)]
pub fn walk(
    clock: Res<ClothClock>,
    mut walkers: Query<&mut Transform, (With<Walker>, Without<Hips>, Without<Swing>)>,
    mut hips: Query<&mut Transform, (With<Hips>, Without<Swing>)>,
    mut swings: Query<(&mut Transform, &Swing)>,
) {
    let distance = walked(clock.total_ticks as f32 * clock.tick_seconds);
    let stride = TAU * CADENCE * distance / SPEED / 2.0;
    for mut transform in &mut walkers {
        *transform = walker_pose(distance);
    }
    let lift = (distance / (distance + 0.3)).min(1.0);
    for mut transform in &mut hips {
        transform.translation.y = HIP_HEIGHT + lift * 0.025 * (2.0 * stride).cos();
        transform.rotation =
            Quat::from_rotation_z(lift * 0.06 * stride.sin()) * Quat::from_rotation_y(lift * 0.12 * stride.sin());
    }
    for (mut transform, swing) in &mut swings {
        transform.rotation = Quat::from_rotation_x(lift * swing.amplitude * (stride + TAU * swing.phase).sin());
    }
}
