//! A cloth whose state goes NaN or infinite is reset to its rest pose and reported; the other
//! cloths do not notice.

use bevy::prelude::*;
use bevy_bvh_cloth::prelude::*;

use crate::headless::harness::{app, positions, run, sent};

/// Far enough that a spring from a pin to its free neighbour overflows `f32` at once.
const OUT_OF_RANGE: f32 = 3.0e38;

fn hanging(x: f32) -> (Cloth, Transform) {
    (
        Cloth {
            params: ClothParams { damping: 0.5, ..default() },
            ..Cloth::grid(Vec2::splat(1.0), UVec2::splat(12)).with_pins(ClothPins::TwoEnds)
        },
        Transform::from_xyz(x, 2.0, 0.0),
    )
}

fn diverged(app: &App) -> Vec<(Entity, u32)> {
    sent(app)
        .iter()
        .filter_map(|m| match m {
            ClothMessage::Diverged { entity, particles } => Some((*entity, *particles)),
            _ => None,
        })
        .collect()
}

#[test]
fn a_diverged_cloth_is_reset_and_reported_and_the_others_go_on() {
    // The calm cloth alone, as the reference for its trajectory.
    let mut lone = app();
    let reference = lone.world_mut().spawn(hanging(0.0)).id();

    let mut app = app();
    let calm = app.world_mut().spawn(hanging(0.0)).id();
    let wild = app.world_mut().spawn(hanging(3.0)).id();
    run(&mut app, 0.5);
    run(&mut lone, 0.5);

    // Teleporting the entity drags the pins 3e38 m in one tick; the springs to them overflow.
    app.world_mut().get_mut::<Transform>(wild).unwrap().translation.x = OUT_OF_RANGE;
    run(&mut app, 0.5);
    run(&mut lone, 0.5);

    let reports = diverged(&app);
    assert_eq!(reports.len(), 1, "one reset, then the cloth hangs finitely where it was sent: {reports:?}");
    let (entity, particles) = reports[0];
    assert_eq!(entity, wild);
    // Counted per substep: at most each of the 144 particles in each of the tick's 16 substeps.
    assert!(particles > 0 && particles <= 144 * 16, "{particles} particles reported non-finite");

    // Reset to its rest pose under the new transform, and finite since.
    let wild_positions = positions(&app, wild);
    assert!(wild_positions.iter().all(|p| p.is_finite() && p.x > 1e38), "{:?}", &wild_positions[..3]);
    // The calm cloth went on exactly as if alone.
    assert_eq!(positions(&app, calm), positions(&lone, reference));
}

/// A force too large for `f32` makes an RK4 cloth diverge in every tick: it is reset and
/// reported every tick, stays finite, and runs normally again once the force is fixed. (Block
/// descent takes the same force as a finite, enormous step: `h²` scales it back into range.)
#[test]
fn a_cloth_that_diverges_every_tick_recovers_when_its_parameters_are_fixed() {
    let mut app = app();
    let (cloth, transform) = hanging(0.0);
    let entity = app
        .world_mut()
        .spawn((
            Cloth {
                params: ClothParams {
                    external_force: Vec3::new(0.0, 0.0, 1e38),
                    integrator: Integrator::Rk4,
                    ..cloth.params.clone()
                },
                ..cloth
            },
            transform,
        ))
        .id();
    run(&mut app, 0.5);
    assert_eq!(diverged(&app).len(), 30, "one reset per tick");
    assert!(positions(&app, entity).iter().all(|p| p.is_finite()));

    app.world_mut().get_mut::<Cloth>(entity).unwrap().params.external_force = Vec3::ZERO;
    run(&mut app, 0.5);
    assert_eq!(diverged(&app).len(), 30, "no reset once the force is fixed");
    let lowest = positions(&app, entity).iter().map(|p| p.y).fold(f32::INFINITY, f32::min);
    assert!(lowest < 1.9, "the cloth sags again: lowest particle at {lowest} m");
}
