//! Wind through the plugin: the ambient wind, a cloth's own, fans and blasts, and bad values
//! refused with a message while the scene runs on.

use bevy::prelude::*;
use bevy_bvh_cloth::bvh_cloth_core::ClothError;
use bevy_bvh_cloth::prelude::*;

use crate::headless::harness::{app, positions, run, sent};

/// A 1 m curtain of 16 x 16 particles hanging from its first row in the XY plane at `x`,
/// facing +Z, with `aerodynamics`.
fn curtain(app: &mut App, x: f32, aerodynamics: Aerodynamics) -> Entity {
    let cloth = Cloth {
        params: ClothParams { damping: 1.0, aerodynamics, ..default() },
        ..Cloth::grid(Vec2::splat(1.0), UVec2::splat(16)).with_pins(ClothPins::FirstRow)
    };
    let transform = Transform::from_xyz(x, 2.0, 0.0).with_rotation(Quat::from_rotation_x(core::f32::consts::FRAC_PI_2));
    app.world_mut().spawn((cloth, transform)).id()
}

/// How far a cloth has moved along +Z on average.
fn downwind(app: &App, cloth: Entity) -> f32 {
    let p = positions(app, cloth);
    p.iter().map(|p| p.z).sum::<f32>() / p.len() as f32
}

/// The ambient wind blows a cloth with aerodynamics out, leaves one without them hanging (and
/// says so once), and a cloth's own still air shelters it.
#[test]
fn the_ambient_wind_blows_cloths_that_catch_the_air() {
    let mut app = app();
    app.insert_resource(AmbientWind(Wind::steady(Vec3::new(0.0, 0.0, 6.0))));
    let blown = curtain(&mut app, 0.0, Aerodynamics::FABRIC);
    let vacuum = curtain(&mut app, 2.0, Aerodynamics::NONE);
    let sheltered = curtain(&mut app, 4.0, Aerodynamics::FABRIC);
    app.world_mut().entity_mut(sheltered).insert(LocalWind(Wind::STILL));
    run(&mut app, 2.0);
    let (b, v, s) = (downwind(&app, blown), downwind(&app, vacuum), downwind(&app, sheltered));
    assert!(b > 0.2, "the wind blows the curtain out: {b} m");
    assert!(v.abs() < 1e-3 && s.abs() < 1e-3, "no aerodynamics, or still air of its own: {v} m, {s} m");
    // The one that cannot feel the wind is told so, once; the others are not.
    let unfelt: Vec<(Entity, f32)> = sent(&app)
        .iter()
        .filter_map(|m| match m {
            ClothMessage::WindNotFelt { entity, speed } => Some((*entity, *speed)),
            _ => None,
        })
        .collect();
    assert_eq!(unfelt, [(vacuum, 6.0)], "said once, naming the cloth without aerodynamics and the wind's speed");
}

/// A fan behind a curtain, pointing at it, blows it out; turned away, it does not. A blast
/// pushes the curtain while it lasts.
#[test]
fn fans_and_blasts_blow_what_they_reach() {
    let mut app = app();
    let cloth = curtain(&mut app, 0.0, Aerodynamics::FABRIC);
    // Forward (-Z) of a fan looking at the curtain from 1 m behind it.
    let fan = app
        .world_mut()
        .spawn((
            WindFan::new(10.0).with_range(4.0).with_spread(0.8),
            Transform::from_xyz(0.0, 1.5, -1.0).looking_at(Vec3::new(0.0, 1.5, 0.0), Vec3::Y),
        ))
        .id();
    run(&mut app, 1.5);
    let pushed = downwind(&app, cloth);
    assert!(pushed > 0.1, "the fan blows the curtain: {pushed} m");
    app.world_mut()
        .entity_mut(fan)
        .insert(Transform::from_xyz(0.0, 1.5, -1.0).looking_at(Vec3::new(0.0, 1.5, -5.0), Vec3::Y));
    run(&mut app, 3.0);
    let back = downwind(&app, cloth);
    assert!(back < 0.2 * pushed, "turned away, it lets the curtain fall back: {pushed} m -> {back} m");
    app.world_mut().spawn((WindBlast::new(30.0, 3.0, 0.3), Transform::from_xyz(0.0, 1.5, -0.5)));
    run(&mut app, 0.3);
    let blasted = downwind(&app, cloth);
    assert!(blasted > back + 0.05, "the blast pushes the curtain: {back} m -> {blasted} m");
    let blast = app.world_mut().query::<&WindBlast>().single(app.world()).unwrap().current_speed();
    assert!(blast.abs() < 1.0, "the blast has died down: {blast} m/s");
}

/// A NaN or absurd wind is refused naming the cloth, which keeps its last wind and runs on; a
/// fan with absurd values is left out.
#[test]
fn bad_wind_is_refused_and_the_scene_runs_on() {
    let mut app = app();
    app.insert_resource(AmbientWind(Wind::steady(Vec3::new(0.0, 0.0, 6.0))));
    let cloth = curtain(&mut app, 0.0, Aerodynamics::FABRIC);
    run(&mut app, 0.5);
    app.insert_resource(AmbientWind(Wind::steady(Vec3::new(f32::NAN, 0.0, 0.0))));
    app.world_mut().spawn((WindFan { speed: 1.0e6, range: 4.0, spread: 0.8 }, Transform::from_xyz(0.0, 1.5, -1.0)));
    run(&mut app, 1.0);
    let rejected: Vec<&ClothMessage> =
        sent(&app).iter().filter(|m| matches!(m, ClothMessage::Rejected { entity, .. } if *entity == cloth)).collect();
    assert_eq!(
        rejected,
        [&ClothMessage::Rejected { entity: cloth, error: ClothError::NotFinite { field: "wind.velocity" } }],
        "refused once, naming the cloth and the field"
    );
    assert!(positions(&app, cloth).iter().all(|p| p.is_finite()));
    assert!(downwind(&app, cloth) > 0.2, "it keeps its last wind");
    app.insert_resource(AmbientWind(Wind::steady(Vec3::new(0.0, 0.0, 500.0))));
    run(&mut app, 0.1);
    assert!(sent(&app).iter().any(|m| matches!(
        m,
        ClothMessage::Rejected { entity, error: ClothError::OutOfRange { field: "wind.velocity", .. } } if *entity == cloth
    )));
}

/// A fan or a blast whose values are refused is reported each time it turns bad, naming it and
/// the field, both as a message and as an event on its entity, and not every frame it stays
/// bad; it is left out while the cloth runs on, and blows again once fixed. A blast without a
/// duration, which could never blow, is refused too.
#[test]
fn bad_wind_sources_are_reported_when_they_turn_bad() {
    let mut app = app();
    let cloth = curtain(&mut app, 0.0, Aerodynamics::FABRIC);
    let fan = app
        .world_mut()
        .spawn((WindFan { speed: 1.0e6, range: 4.0, spread: 0.8 }, Transform::from_xyz(0.0, 1.5, -1.0)))
        .id();
    let blast = app.world_mut().spawn((WindBlast::new(20.0, 3.0, 5.0), Transform::from_xyz(0.0, 1.5, -0.5))).id();
    let observed = std::sync::Arc::new(std::sync::atomic::AtomicUsize::new(0));
    let seen = observed.clone();
    app.world_mut().entity_mut(blast).observe(move |_: On<WindSourceRejected>| {
        seen.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    });
    let refused = |app: &App, source: Entity, field: &str| {
        sent(app)
            .iter()
            .filter(|m| {
                matches!(m, ClothMessage::WindSourceRejected { entity, error: ClothError::OutOfRange { field: f, .. } }
                    if *entity == source && *f == field)
            })
            .count()
    };
    run(&mut app, 0.5);
    assert_eq!(refused(&app, fan, "fan.speed"), 1, "the fan is refused once, naming its speed");
    assert_eq!(refused(&app, blast, "blast.speed"), 0, "the blast is valid");
    let pushed = downwind(&app, cloth);
    assert!(pushed > 0.05, "the valid blast still blows: {pushed} m");

    app.world_mut().get_mut::<WindBlast>(blast).unwrap().speed = f32::NAN;
    run(&mut app, 0.5);
    assert_eq!(refused(&app, blast, "blast.speed"), 1, "a blast turned bad after its spawn is refused once");
    app.world_mut().get_mut::<WindBlast>(blast).unwrap().speed = 20.0;
    run(&mut app, 0.2);
    app.world_mut().get_mut::<WindBlast>(blast).unwrap().speed = 1.0e6;
    run(&mut app, 0.2);
    assert_eq!(refused(&app, blast, "blast.speed"), 2, "turned bad again, it is refused again");
    assert_eq!(observed.load(std::sync::atomic::Ordering::Relaxed), 2, "each refusal is triggered on the blast");
    assert_eq!(refused(&app, fan, "fan.speed"), 1, "the fan, bad all along, is not reported again");
    // A blast that could never blow: no duration.
    let still_born = app.world_mut().spawn((WindBlast::new(20.0, 3.0, f32::NAN), Transform::default())).id();
    run(&mut app, 0.2);
    let no_duration = sent(&app)
        .iter()
        .filter(|m| {
            matches!(m, ClothMessage::WindSourceRejected { entity, error: ClothError::NotPositive { field: "blast.duration", .. } }
                if *entity == still_born)
        })
        .count();
    assert_eq!(no_duration, 1, "a blast without a duration is refused once, naming it");
    assert!(positions(&app, cloth).iter().all(|p| p.is_finite()), "the cloth runs on");
    assert!(
        !sent(&app).iter().any(|m| matches!(m, ClothMessage::Rejected { .. })),
        "the cloth's own wind is not at fault"
    );
}
