//! Self-contact through the plugin: cloths with `ClothParams::self_contact` keep off each other
//! on the CPU backend, and a thickness above the particle spacing is refused with a message.

use bevy::prelude::*;
use bevy_bvh_cloth::bvh_cloth_core::backend::crossing_pairs;
use bevy_bvh_cloth::bvh_cloth_core::{ClothError, ClothGrid};
use bevy_bvh_cloth::prelude::*;

use crate::headless::harness::{app, positions, run, sent};

/// Side and resolution of the cloths: 1.2 m over 24 x 24 particles, a spacing of 52 mm.
const SIZE: f32 = 1.2;
const PARTICLES: u32 = 24;

fn spawn_cloth(app: &mut App, contact: Option<SelfContact>, height: f32, turn: f32) -> Entity {
    let cloth = Cloth {
        params: ClothParams { damping: 1.0, self_contact: contact, ..default() },
        ..Cloth::grid(Vec2::splat(SIZE), UVec2::splat(PARTICLES))
    };
    app.world_mut()
        .spawn((cloth, Transform::from_xyz(0.0, height, 0.0).with_rotation(Quat::from_rotation_y(turn))))
        .id()
}

/// Pairs of intersecting triangles, one of each cloth.
fn crossing(a: &[Vec3], b: &[Vec3]) -> usize {
    let triangles: Vec<[u32; 3]> = ClothGrid::new(Vec2::splat(SIZE), UVec2::splat(PARTICLES))
        .triangle_indices()
        .chunks_exact(3)
        .map(|t| [t[0], t[1], t[2]])
        .collect();
    crossing_pairs(&triangles, a, Some((&triangles, b)))
}

/// Two cloths dropped one above the other onto a ball on the ground. With self-contact they end
/// with no triangles crossing and no particle of one within half the thickness of the other;
/// without it (the control) the upper falls through the lower.
#[test]
fn two_cloths_with_self_contact_keep_apart_on_the_cpu() {
    let thickness = 0.03;
    let mut results = Vec::new();
    for contact in [Some(SelfContact { thickness, friction: 0.3 }), None] {
        let mut app = app();
        app.world_mut().spawn(PrimitiveCollider::ground());
        app.world_mut().spawn((PrimitiveCollider::sphere(0.25), Transform::from_xyz(0.0, 0.25, 0.0)));
        let lower = spawn_cloth(&mut app, contact, 0.7, 0.0);
        let upper = spawn_cloth(&mut app, contact, 0.85, 0.5);
        run(&mut app, 3.0);
        let (a, b) = (positions(&app, lower), positions(&app, upper));
        assert!(a.iter().chain(&b).all(|p| p.is_finite()));
        let close = a.iter().map(|p| b.iter().filter(|q| p.distance(**q) < 0.5 * thickness).count()).sum::<usize>();
        results.push((crossing(&a, &b), close));
    }
    let [(crossed, close), (control, _)] = results[..] else { unreachable!() };
    assert!(control > 50, "without self-contact only {control} triangle pairs cross: the cloths never met");
    assert_eq!((crossed, close), (0, 0), "crossing triangles and close particles with self-contact");
}

/// A thickness above the cloth's particle spacing is refused, naming the cloth.
#[test]
fn a_thickness_above_the_spacing_is_refused() {
    let mut app = app();
    let bad = spawn_cloth(&mut app, Some(SelfContact { thickness: 0.2, friction: 0.0 }), 1.0, 0.0);
    run(&mut app, 0.1);
    assert!(
        sent(&app).iter().any(|m| matches!(
            m,
            ClothMessage::Rejected { entity, error: ClothError::ThicknessAboveSpacing { .. } } if *entity == bad
        )),
        "{:?}",
        sent(&app)
    );
}
