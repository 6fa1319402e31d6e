//! The debug view: every collider's leaf spheres and inner AABBs drawn with gizmos, like the
//! paper's Table VI pictures. Toggle it with [`ClothSettings::debug_view`].

use bevy::color::palettes::css::{LIME, ORANGE};
use bevy::math::bounding::Aabb3d;
use bevy::prelude::*;

use crate::collider::ClothCollider;
use crate::settings::ClothSettings;

/// Above this many leaves only the spheres are drawn: thousands of nested boxes are noise.
const MAX_LEAVES_WITH_BOXES: usize = 512;

pub(crate) fn draw_colliders(settings: Res<ClothSettings>, colliders: Query<&ClothCollider>, mut gizmos: Gizmos) {
    if !settings.debug_view {
        return;
    }
    for built in &colliders {
        let collider = built.collider();
        let pose = collider.pose;
        if !pose.is_valid() {
            continue;
        }
        let to_world =
            Transform { translation: pose.translation, rotation: pose.rotation, scale: Vec3::splat(pose.scale) };
        for sphere in &collider.lbvh.spheres {
            let centre = to_world.transform_point(sphere.centre());
            let radius = sphere.radius * pose.scale + collider.margin;
            gizmos.sphere(Isometry3d::new(centre, pose.rotation), radius, LIME).resolution(16);
        }
        if collider.sphere_count() <= MAX_LEAVES_WITH_BOXES {
            for node in &collider.lbvh.nodes {
                let aabb = Aabb3d { min: Vec3::from(node.aabb_min).into(), max: Vec3::from(node.aabb_max).into() };
                gizmos.aabb_3d(aabb, to_world, ORANGE);
            }
        }
    }
}
