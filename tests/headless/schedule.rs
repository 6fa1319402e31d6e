//! The cloth systems in a schedule the app chooses: `FixedPostUpdate`, as a game that steps its
//! physics there would put them.

use core::time::Duration;

use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use bevy_bvh_cloth::bvh_cloth_core::{self, ClothGrid, ClothSim, ClothTopology};
use bevy_bvh_cloth::prelude::*;

use crate::headless::harness::app_with;

/// The largest `ClothClock::ticks` seen by a system after the cloth's step in the fixed
/// schedule, and how many ticks such systems saw in all.
#[derive(Resource, Default)]
struct SeenInFixed {
    most: u32,
    total: u64,
}

fn watch(clock: Res<ClothClock>, mut seen: ResMut<SeenInFixed>) {
    seen.most = seen.most.max(clock.ticks);
    seen.total += u64::from(clock.ticks);
}

/// Fixed steps of 1/30 s, first at 30 then at 120 frames per second: the schedule runs every
/// frame, then every fourth, and its clock advances a whole step (two 60 Hz ticks) each time,
/// not a frame's 1/120 s. The cloths are spawned just before a frame whose fixed run comes
/// before `PostUpdate`'s propagation, so they are built where their `Transform`s say only
/// because the plugin propagates in its schedule. After 2 s the falling cloth is exactly the
/// core's after the clock's ticks (1e-5 m), all of them seen in the fixed schedule, and the
/// other rests on a ball.
#[test]
fn the_cloth_runs_in_fixed_post_update() {
    let mut app = fixed_app(30.0, 30.0);
    let params = ClothParams { damping: 0.5, ..default() };
    let cloth = app
        .world_mut()
        .spawn((
            Cloth { params: params.clone(), ..Cloth::grid(Vec2::ONE, UVec2::splat(10)) },
            Transform::from_xyz(0.0, 10.0, 0.0),
        ))
        .id();
    let ball = app.world_mut().spawn((PrimitiveCollider::sphere(0.5), Transform::from_xyz(5.0, 0.0, 0.0))).id();
    let draped = app
        .world_mut()
        .spawn((
            Cloth { params: params.clone(), ..Cloth::grid(Vec2::ONE, UVec2::splat(10)) },
            Transform::from_xyz(5.0, 1.0, 0.0),
        ))
        .id();
    for _ in 0..10 {
        app.update();
    }
    app.insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_secs_f64(1.0 / 120.0)));
    for _ in 0..200 {
        app.update();
    }
    let seen = app.world().resource::<SeenInFixed>();
    let clock = app.world().resource::<ClothClock>();
    assert_eq!(seen.most, 2, "each fixed run advances two 60 Hz ticks");
    assert_eq!(seen.total, clock.total_ticks, "every tick ran in the fixed schedule");
    assert!((116..=120).contains(&clock.total_ticks), "{} ticks in 2 s", clock.total_ticks);

    // Each run's step in two ticks (f32 rounding aside, 1/60 s): the same ticks for the core.
    assert!((clock.tick_seconds - 1.0 / 60.0).abs() < 1e-7, "ticks of {} s", clock.tick_seconds);
    let gap = gap_to_core(&app, cloth, params, clock.total_ticks, clock.tick_seconds);
    assert!(gap < 1e-5, "the fixed-schedule cloth is {gap} m from the core's after the same ticks");

    assert!(matches!(app.world().get::<ColliderStatus>(ball), Some(ColliderStatus::Ready { .. })));
    let on_ball = app.world().get::<ClothSimulation>(draped).unwrap().sim().positions();
    let top = on_ball.iter().map(|p| p.y).fold(f32::MIN, f32::max);
    assert!(top > 0.45, "the cloth rests on the ball (highest particle at {top} m)");
    assert!(on_ball.iter().all(|p| p.distance(Vec3::new(5.0, 0.0, 0.0)) > 0.49), "no particle inside the ball");
}

/// An app with the cloth systems in `FixedPostUpdate` at `fixed_hz`, `fps` frames per
/// (simulated) second, and [`watch`] after the cloth's step; its first update has run.
fn fixed_app(fps: f64, fixed_hz: f64) -> App {
    app_with(fps, BvhClothPlugin::new(FixedPostUpdate), |app| {
        app.insert_resource(Time::<Fixed>::from_hz(fixed_hz))
            .init_resource::<SeenInFixed>()
            .add_systems(FixedPostUpdate, watch.after(ClothSystems::Step));
    })
}

/// The largest distance between `cloth` (a 1 m, 10 x 10 grid dropped from 10 m with `params`)
/// and the core's same cloth after `ticks` ticks of `tick` seconds.
fn gap_to_core(app: &App, cloth: Entity, params: ClothParams, ticks: u64, tick: f32) -> f32 {
    let topology = std::sync::Arc::new(ClothTopology::grid(ClothGrid::new(Vec2::ONE, UVec2::splat(10))).unwrap());
    let start = bvh_cloth_core::Affine3A::from_translation(Vec3::new(0.0, 10.0, 0.0));
    let mut core = ClothSim::new(params, topology, start, &[]).unwrap();
    for _ in 0..ticks {
        core.tick(tick, &[]);
    }
    let got = app.world().get::<ClothSimulation>(cloth).unwrap().sim().positions();
    core.positions().iter().zip(got.iter()).map(|(a, b)| a.distance(*b)).fold(0.0f32, f32::max)
}

/// How many times the fixed schedule ran.
#[derive(Resource, Default)]
struct FixedRuns(u64);

fn count_runs(mut runs: ResMut<FixedRuns>) {
    runs.0 += 1;
}

/// At Bevy's default fixed step (64 Hz) and 60 frames per second, the cloth steps once per run
/// of `FixedPostUpdate`, by that run's 1/64 s, as a physics engine there does: 120 runs are
/// 120 ticks and the cloth is exactly the core's after 120 ticks of 1/64 s. (With the cloth's
/// own 60 Hz accumulator, 4 of every 64 runs advanced no cloth.)
#[test]
fn at_any_fixed_rate_cloth_and_physics_step_one_to_one() {
    let mut app = fixed_app(60.0, 64.0);
    app.init_resource::<FixedRuns>().add_systems(FixedPostUpdate, count_runs);
    let params = ClothParams { damping: 0.5, ..default() };
    let cloth = app
        .world_mut()
        .spawn((
            Cloth { params: params.clone(), ..Cloth::grid(Vec2::ONE, UVec2::splat(10)) },
            Transform::from_xyz(0.0, 10.0, 0.0),
        ))
        .id();
    app.update();
    let (runs_before, ticks_before) =
        (app.world().resource::<FixedRuns>().0, app.world().resource::<ClothClock>().total_ticks);
    for _ in 0..120 {
        app.update();
    }
    let runs = app.world().resource::<FixedRuns>().0 - runs_before;
    let clock = app.world().resource::<ClothClock>();
    assert!(runs >= 120, "the fixed schedule ran {runs} times in 2 s");
    assert_eq!(clock.total_ticks - ticks_before, runs, "one tick per fixed run");
    assert_eq!(app.world().resource::<SeenInFixed>().most, 1);
    assert!((clock.tick_seconds - 1.0 / 64.0).abs() < 1e-7, "each tick is the fixed step, {} s", clock.tick_seconds);

    let gap = gap_to_core(&app, cloth, params, clock.total_ticks, 1.0 / 64.0);
    assert!(gap < 1e-5, "the cloth is {gap} m from the core's after the same ticks of 1/64 s");
}
