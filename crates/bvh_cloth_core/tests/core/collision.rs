//! Collision response on analytic cases (paper section 2.4.4 plus the cases it leaves open).

use crate::common;

use bvh_cloth_core::backend::ColliderFrame;
use bvh_cloth_core::{ColliderPose, Quat, Sphere, Vec3};
use common::sphere_collider;

const EPS: f32 = 1.0e-5;

fn unit_ball() -> bvh_cloth_core::Collider {
    sphere_collider(&[Sphere::new(Vec3::ZERO, 1.0)])
}

fn resolve(c: &bvh_cloth_core::Collider, prev: Vec3, p: Vec3, v: Vec3) -> (bool, Vec3, Vec3) {
    let frame = ColliderFrame::new(c).unwrap();
    let (mut p, mut v) = (p, v);
    let hit = frame.resolve(prev, &mut p, &mut v);
    (hit, p, v)
}

#[test]
fn flying_into_a_sphere_stops_at_the_entry_point() {
    let (hit, p, v) =
        resolve(&unit_ball(), Vec3::new(0.0, 2.0, 0.0), Vec3::new(0.0, 0.5, 0.0), Vec3::new(1.0, -3.0, 0.0));
    assert!(hit);
    assert!(p.distance(Vec3::Y) < EPS, "{p}");
    assert!(v.distance(Vec3::X) < EPS, "only the tangential velocity is kept: {v}");
}

#[test]
fn oblique_entry_lies_on_the_segment() {
    let prev = Vec3::new(-2.0, 0.5, 0.0);
    let end = Vec3::new(0.0, 0.5, 0.0);
    let (hit, p, v) = resolve(&unit_ball(), prev, end, Vec3::new(3.0, 0.0, 0.0));
    assert!(hit);
    let expected = Vec3::new(-(0.75f32).sqrt(), 0.5, 0.0);
    assert!(p.distance(expected) < EPS, "{p}");
    assert!(v.dot(expected).abs() < EPS, "normal velocity removed: {v}");
    assert!((v.length() - 1.5).abs() < 1e-4, "tangential part kept: {v}");
}

#[test]
fn starting_inside_pushes_out_along_the_normal() {
    let (hit, p, _) = resolve(&unit_ball(), Vec3::new(0.1, 0.2, 0.0), Vec3::new(0.3, 0.4, 0.0), Vec3::ZERO);
    assert!(hit);
    assert!(p.distance(Vec3::new(0.6, 0.8, 0.0)) < EPS, "{p}");
}

#[test]
fn zero_velocity_inside_and_at_the_centre() {
    let ball = unit_ball();
    let (hit, p, v) = resolve(&ball, Vec3::new(0.0, 0.0, 0.5), Vec3::new(0.0, 0.0, 0.5), Vec3::ZERO);
    assert!(hit && p.distance(Vec3::Z) < EPS && v == Vec3::ZERO);
    let (hit, p, _) = resolve(&ball, Vec3::ZERO, Vec3::ZERO, Vec3::ZERO);
    assert!(hit && p.distance(Vec3::Y) < EPS, "the centre falls back to +Y: {p}");
}

#[test]
fn grazing_and_resting_particles() {
    let ball = unit_ball();
    // A path that dips just under the surface is caught near its end, on the surface.
    let prev = Vec3::new(-0.5, 0.9, 0.0);
    let end = Vec3::new(0.0, 0.9999, 0.0);
    let (hit, p, _) = resolve(&ball, prev, end, Vec3::X);
    assert!(hit);
    assert!((p.length() - 1.0).abs() < EPS && p.x < 0.0 && p.x > -0.5, "{p}");
    // A path that stays outside is untouched.
    let (hit, ..) = resolve(&ball, Vec3::new(-1.0, 1.01, 0.0), Vec3::new(1.0, 1.01, 0.0), Vec3::X);
    assert!(!hit);
    // A particle at rest on the surface stays at rest.
    let (hit, p, v) = resolve(&ball, Vec3::Y, Vec3::Y, Vec3::ZERO);
    assert!(!hit && p == Vec3::Y && v == Vec3::ZERO);
}

#[test]
fn overlapping_spheres_stop_at_the_first_one_entered() {
    // Two overlapping balls along x; a path from the left ends inside both.
    let c = sphere_collider(&[Sphere::new(Vec3::ZERO, 1.0), Sphere::new(Vec3::new(1.0, 0.0, 0.0), 1.0)]);
    let (hit, p, _) = resolve(&c, Vec3::new(-3.0, 0.0, 0.0), Vec3::new(0.5, 0.0, 0.0), Vec3::X);
    assert!(hit);
    assert!(p.distance(Vec3::new(-1.0, 0.0, 0.0)) < EPS, "{p}");
    // A path into a big ball whose entry point lies inside a small ball stops at the small one.
    let c = sphere_collider(&[Sphere::new(Vec3::new(0.0, 0.1, 0.0), 0.3), Sphere::new(Vec3::new(0.0, -2.0, 0.0), 2.0)]);
    let (hit, p, _) = resolve(&c, Vec3::new(0.0, 2.0, 0.0), Vec3::new(0.0, -0.5, 0.0), Vec3::NEG_Y);
    assert!(hit);
    assert!(p.distance(Vec3::new(0.0, 0.4, 0.0)) < EPS, "{p}");
}

#[test]
fn margin_and_pose_are_applied() {
    let pose =
        ColliderPose { translation: Vec3::new(5.0, 1.0, -2.0), rotation: Quat::from_rotation_z(0.7), scale: 2.0 };
    let c = unit_ball().with_pose(pose).with_margin(0.1);
    // World radius 2 * 1 + 0.1 around the translation.
    let centre = pose.translation;
    let (hit, p, _) = resolve(&c, centre + Vec3::new(0.0, 5.0, 0.0), centre + Vec3::new(0.0, 1.0, 0.0), Vec3::NEG_Y);
    assert!(hit);
    assert!(p.distance(centre + Vec3::new(0.0, 2.1, 0.0)) < 1e-4, "{p}");
    assert!(!c.contains(centre + Vec3::new(2.11, 0.0, 0.0)));
    assert!(c.contains(centre + Vec3::new(2.09, 0.0, 0.0)));
}

#[test]
fn friction_slows_the_tangential_velocity() {
    // Falling onto the top of the ball at 0.5 m/s while sliding at 1 m/s.
    let prev = Vec3::new(0.0, 1.1, 0.0);
    let end = Vec3::new(0.0, 0.99, 0.0);
    let v = Vec3::new(1.0, -0.5, 0.0);
    let (_, _, frictionless) = resolve(&unit_ball(), prev, end, v);
    assert!(frictionless.distance(Vec3::X) < EPS, "{frictionless}");
    // mu = 0.4 takes 0.4 * 0.5 = 0.2 m/s off the tangential speed.
    let (_, p, slowed) = resolve(&unit_ball().with_friction(0.4), prev, end, v);
    assert!(slowed.distance(Vec3::new(0.8, 0.0, 0.0)) < 1e-4, "{slowed}");
    assert!(p.distance(Vec3::Y) < EPS);
    // Enough friction stops it, and never reverses it.
    let (_, _, stopped) = resolve(&unit_ball().with_friction(5.0), prev, end, v);
    assert_eq!(stopped, Vec3::ZERO);
    // A particle leaving the surface feels no friction, and a hostile coefficient is ignored.
    let (_, _, leaving) = resolve(
        &unit_ball().with_friction(5.0),
        Vec3::new(0.0, 0.5, 0.0),
        Vec3::new(0.0, 0.9, 0.0),
        Vec3::new(1.0, 0.5, 0.0),
    );
    assert!(leaving.distance(Vec3::X) < EPS, "{leaving}");
    let (_, _, nan) = resolve(&unit_ball().with_friction(f32::NAN), prev, end, v);
    assert!(nan.distance(Vec3::X) < EPS, "{nan}");
}

#[test]
fn a_particle_pressed_against_a_sphere_slides_along_it() {
    // On the surface, pushed into it and sideways: it slides, and only the normal speed goes.
    let ball = unit_ball();
    let prev = Vec3::Y;
    let end = Vec3::new(0.01, 0.995, 0.0);
    let (hit, p, v) = resolve(&ball, prev, end, Vec3::new(1.0, -0.5, 0.0));
    assert!(hit);
    // Held on the plane tangent at the previous position: outside, a hair above the surface
    // (the plane rises 0.01^2 / 2 over a 0.01 slide on a unit ball).
    assert!(p.x > 0.009 && (p.y - 1.0).abs() < EPS, "it slid to {p}");
    assert!(!ball.contains(p) && p.length() - 1.0 < 1e-4, "{p}");
    assert!(v.dot(Vec3::Y).abs() < EPS, "no normal velocity is left: {v}");
    assert!(v.x > 0.9, "the tangential velocity is kept: {v}");
    // A slide across two touching balls stops where the path meets the second, on its surface.
    let pair = sphere_collider(&[Sphere::new(Vec3::ZERO, 1.0), Sphere::new(Vec3::new(1.5, 0.5, 0.0), 1.0)]);
    let (hit, p, _) = resolve(&pair, Vec3::Y, Vec3::new(1.0, 0.9, 0.0), Vec3::X);
    assert!(hit);
    assert!(!pair.contains(p), "{p}");
    assert!((p.distance(Vec3::new(1.5, 0.5, 0.0)) - 1.0).abs() < EPS && (p.y - 1.0).abs() < EPS, "{p}");
}

/// The path is tested whole: a substep that passes straight through a thin sphere, ending
/// outside it, is caught where it enters.
#[test]
fn a_path_through_a_thin_sphere_stops_at_its_surface() {
    let thin = sphere_collider(&[Sphere::new(Vec3::ZERO, 0.01)]);
    let (hit, p, v) = resolve(&thin, Vec3::new(0.0, 0.5, 0.0), Vec3::new(0.0, -0.5, 0.0), Vec3::new(0.2, -60.0, 0.0));
    assert!(hit);
    assert!(p.distance(Vec3::new(0.0, 0.01, 0.0)) < EPS, "{p}");
    assert!(v.distance(Vec3::new(0.2, 0.0, 0.0)) < EPS, "{v}");
    // Passing beside it touches nothing.
    let (hit, ..) = resolve(&thin, Vec3::new(0.02, 0.5, 0.0), Vec3::new(0.02, -0.5, 0.0), Vec3::NEG_Y);
    assert!(!hit);
}
