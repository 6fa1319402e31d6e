//! The debug view: every mesh collider's leaf spheres and inner AABBs drawn with gizmos, like the
//! paper's Table VI pictures, and every primitive's outline. Toggle it with
//! [`ClothSettings::debug_view`].

use bevy::color::palettes::css::{LIME, ORANGE, TURQUOISE};
use bevy::math::bounding::Aabb3d;
use bevy::prelude::*;

use bvh_cloth_core::{Collider, Primitive};

use crate::colliders::auto::ClothCollider;
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
        let Some(lbvh) = collider.lbvh() else {
            draw_primitive(&mut gizmos, collider);
            continue;
        };
        for sphere in &lbvh.spheres {
            let centre = to_world.transform_point(sphere.centre());
            let radius = sphere.radius * pose.scale + collider.margin;
            gizmos.sphere(Isometry3d::new(centre, pose.rotation), radius, LIME).resolution(16);
        }
        if collider.sphere_count() <= MAX_LEAVES_WITH_BOXES {
            for node in &lbvh.nodes {
                let aabb = Aabb3d { min: Vec3::from(node.aabb_min).into(), max: Vec3::from(node.aabb_max).into() };
                gizmos.aabb_3d(aabb, to_world, ORANGE);
            }
        }
    }
}

/// A primitive's surface grown by the margin (a plane square of 10 m for the half-space).
fn draw_primitive(gizmos: &mut Gizmos, collider: &Collider) {
    let Some(primitive) = collider.as_primitive() else { return };
    let pose = collider.pose;
    let at = Isometry3d::new(pose.translation, pose.rotation);
    let grow = |size: f32| size * pose.scale + collider.margin;
    match *primitive {
        Primitive::Sphere { radius } => {
            gizmos.sphere(at, grow(radius), TURQUOISE);
        }
        Primitive::Capsule { radius, half_length } => {
            gizmos.primitive_3d(&Capsule3d::new(grow(radius), 2.0 * half_length * pose.scale), at, TURQUOISE);
        }
        Primitive::Cuboid { half_extents } => {
            let size = 2.0 * (half_extents * pose.scale + collider.margin);
            gizmos.primitive_3d(&Cuboid::from_size(size), at, TURQUOISE);
        }
        Primitive::HalfSpace { normal } => {
            let normal = pose.rotation * normal;
            let Ok(normal) = Dir3::new(normal) else { return };
            let plane = Plane3d { normal, half_size: Vec2::splat(5.0) };
            gizmos.primitive_3d(
                &plane,
                Isometry3d::from_translation(pose.translation + collider.margin * normal),
                TURQUOISE,
            );
        }
    }
}
