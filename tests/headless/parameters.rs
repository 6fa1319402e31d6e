//! The paper's live parameters change the result at runtime; bad values are refused.

use bevy::prelude::*;
use bevy_bvh_cloth::bvh_cloth_core::ClothError;
use bevy_bvh_cloth::prelude::*;

use crate::headless::harness::{app, max_distance, positions, run, sent};

/// A hanging cloth run for one second, `edit` applied to its component, then one more second:
/// its positions and velocities.
fn run_with(edit: impl FnOnce(&mut Cloth)) -> (Vec<Vec3>, Vec<Vec3>) {
    let mut app = app();
    let cloth = Cloth {
        // RK4, whose motion changes little with the substep count (see "looper" below).
        params: ClothParams { damping: 0.5, integrator: Integrator::Rk4, ..default() },
        ..Cloth::grid(Vec2::splat(1.0), UVec2::splat(12)).with_pins(ClothPins::TwoEnds)
    };
    let entity = app.world_mut().spawn((cloth, Transform::from_xyz(0.0, 2.0, 0.0))).id();
    run(&mut app, 1.0);
    edit(&mut app.world_mut().get_mut::<Cloth>(entity).unwrap());
    run(&mut app, 1.0);
    let sim = app.world().get::<ClothSimulation>(entity).unwrap().sim();
    (sim.positions(), sim.velocities())
}

/// A named change to a cloth's component.
type Edit = fn(&mut Cloth);

fn mean(v: impl Iterator<Item = f32>) -> f32 {
    let (sum, n) = v.fold((0.0, 0), |(s, n), x| (s + x, n + 1));
    sum / n as f32
}

/// Mean stretch of the springs between vertical neighbours (12 x 12 over 1 m: rest 1/11 m).
fn stretch(p: &[Vec3]) -> f32 {
    mean((0..11 * 12).map(|i| p[i].distance(p[i + 12]) - 1.0 / 11.0))
}

fn kinetic(v: &[Vec3]) -> f32 {
    mean(v.iter().map(|v| v.length_squared()))
}

#[test]
fn each_live_parameter_changes_the_result_the_way_it_should() {
    let (p0, v0) = run_with(|_| {});
    assert_eq!((p0.clone(), v0.clone()), run_with(|_| {}), "the simulation is deterministic");
    let edits: [(&str, Edit); 4] = [
        ("spring_k", |c| c.params.spring_k *= 3.0),
        ("looper", |c| c.params.looper = 4),
        ("damping", |c| c.params.damping = 5.0),
        ("external_force", |c| c.params.external_force = Vec3::new(0.0, 0.0, 2.0)),
    ];
    for (name, edit) in edits {
        let (p, v) = run_with(edit);
        let moved = max_distance(&p0, &p);
        eprintln!(
            "{name}: moved {moved:.2e} m; stretch {:.2e} vs {:.2e}; kinetic {:.2e} vs {:.2e}; centroid z {:.3} vs {:.3}",
            stretch(&p),
            stretch(&p0),
            kinetic(&v),
            kinetic(&v0),
            mean(p.iter().map(|p| p.z)),
            mean(p0.iter().map(|p| p.z))
        );
        match name {
            // A stiffer fabric stretches less under the same weight.
            "spring_k" => {
                assert!(stretch(&p) < 0.6 * stretch(&p0), "{name}: stretch {} vs {}", stretch(&p), stretch(&p0))
            }
            // More substeps resolve the same motion more finely: a change, but a small one.
            "looper" => assert!(moved > 1e-6 && moved < 1e-2, "{name}: moved {moved} m"),
            // Ten times the damping takes most of the motion out of the swinging cloth.
            "damping" => {
                assert!(kinetic(&v) < 0.5 * kinetic(&v0), "{name}: kinetic {} vs {}", kinetic(&v), kinetic(&v0))
            }
            // A push along +Z moves the cloth that way.
            _ => {
                let shift = mean(p.iter().map(|p| p.z)) - mean(p0.iter().map(|p| p.z));
                assert!(shift > 0.05, "{name}: the centroid moved {shift} m along +Z");
            }
        }
    }
}

#[test]
fn invalid_parameters_are_refused_and_the_cloth_keeps_running() {
    let mut app = app();
    let good = app
        .world_mut()
        .spawn((Cloth::grid(Vec2::splat(1.0), UVec2::splat(8)), Transform::from_xyz(0.0, 2.0, 0.0)))
        .id();
    let bad = app.world_mut().spawn(Cloth::grid(Vec2::splat(1.0), UVec2::new(8, 1))).id();
    run(&mut app, 0.5);
    assert!(app.world().get::<ClothSimulation>(bad).is_none());
    assert!(
        sent(&app)
            .contains(&ClothMessage::Rejected { entity: bad, error: ClothError::GridTooSmall { rows: 1, cols: 8 } })
    );

    // A NaN pushed at runtime is refused; the cloth keeps its last valid parameters and moves on.
    let before = positions(&app, good);
    app.world_mut().get_mut::<Cloth>(good).unwrap().params.external_force = Vec3::NAN;
    run(&mut app, 0.5);
    let after = positions(&app, good);
    assert!(after.iter().all(|p| p.is_finite()));
    assert!(max_distance(&before, &after) > 0.1, "the cloth stopped falling");
    let sim = app.world().get::<ClothSimulation>(good).unwrap().sim();
    assert_eq!(sim.params().external_force, Vec3::ZERO);
    assert!(sent(&app).iter().any(|m| matches!(
        m,
        ClothMessage::Rejected { entity, error: ClothError::NotFinite { field: "external_force" } } if *entity == good
    )));

    // Fixing the bad cloth brings it to life.
    app.world_mut().get_mut::<Cloth>(bad).unwrap().shape =
        ClothShape::Grid { size: Vec2::ONE, particles: UVec2::splat(8) };
    run(&mut app, 0.1);
    assert_eq!(app.world().get::<ClothSimulation>(bad).unwrap().sim().len(), 64);
}

/// Zero or absurd block-descent iteration counts are refused with a message naming the field,
/// at spawn and at run time; a running cloth keeps its last valid solver and carries on.
#[test]
fn absurd_iteration_counts_are_refused_naming_the_field() {
    let mut app = app();
    let grid = || Cloth::grid(Vec2::splat(1.0), UVec2::splat(8));
    let with_iterations = |iterations| {
        grid().with_params(ClothParams { integrator: Integrator::BlockDescent { iterations }, ..default() })
    };
    let bad = app.world_mut().spawn(with_iterations(0)).id();
    let good = app.world_mut().spawn((with_iterations(2), Transform::from_xyz(0.0, 2.0, 0.0))).id();
    run(&mut app, 0.2);
    assert!(app.world().get::<ClothSimulation>(bad).is_none());
    let refused = ClothError::CountOutOfRange { field: "integrator.iterations", value: 0, min: 1, max: 16 };
    assert!(refused.to_string().contains("`integrator.iterations`"), "{refused}");
    assert!(sent(&app).contains(&ClothMessage::Rejected { entity: bad, error: refused }));

    let before = positions(&app, good);
    app.world_mut().get_mut::<Cloth>(good).unwrap().params.integrator = Integrator::BlockDescent { iterations: 1000 };
    run(&mut app, 0.5);
    let sim = app.world().get::<ClothSimulation>(good).unwrap().sim();
    assert_eq!(sim.params().integrator, Integrator::BlockDescent { iterations: 2 }, "the last valid solver is kept");
    assert!(max_distance(&before, &positions(&app, good)) > 0.1, "the cloth stopped falling");
    assert!(sent(&app).contains(&ClothMessage::Rejected {
        entity: good,
        error: ClothError::CountOutOfRange { field: "integrator.iterations", value: 1000, min: 1, max: 16 }
    }));
}

/// A NaN, negative or absurd tether slack is refused with a message naming the field, at spawn
/// and at run time; a running cloth keeps its last valid tethers and carries on.
#[test]
fn absurd_tether_slack_is_refused_naming_the_field() {
    let mut app = app();
    let held = |slack| {
        Cloth::grid(Vec2::splat(1.0), UVec2::splat(8))
            .with_params(ClothParams { tethers: Some(Tethers { slack }), ..default() })
            .with_pins(ClothPins::Indices(vec![0, 7]))
    };
    let bad = app.world_mut().spawn(held(f32::NAN)).id();
    let good = app.world_mut().spawn((held(0.05), Transform::from_xyz(0.0, 2.0, 0.0))).id();
    run(&mut app, 0.2);
    assert!(app.world().get::<ClothSimulation>(bad).is_none());
    assert!(sent(&app).iter().any(|m| matches!(
        m,
        ClothMessage::Rejected { entity, error: ClothError::OutOfRange { field: "tethers.slack", .. } } if *entity == bad
    )));

    for slack in [-0.1, 50.0] {
        let before = positions(&app, good);
        app.world_mut().get_mut::<Cloth>(good).unwrap().params.tethers = Some(Tethers { slack });
        run(&mut app, 0.3);
        let sim = app.world().get::<ClothSimulation>(good).unwrap().sim();
        assert_eq!(sim.params().tethers, Some(Tethers { slack: 0.05 }), "the last valid tethers are kept");
        assert!(max_distance(&before, &positions(&app, good)) > 0.01, "the cloth stopped moving");
        assert!(sent(&app).iter().any(|m| matches!(
            m,
            ClothMessage::Rejected { entity, error: ClothError::OutOfRange { field: "tethers.slack", value, .. } }
                if *entity == good && *value == slack
        )));
    }
}

/// An explicit integrator that its stability guard cannot keep stable at the clock's tick
/// (it would need more than 256 substeps) is refused with a message naming the substeps it
/// needs, at spawn and at run time; a running cloth keeps its last valid stiffness.
#[test]
fn an_explicit_cloth_beyond_its_stability_guard_is_refused_naming_the_substeps() {
    let mut app = app();
    let rk4 = |spring_k| {
        Cloth::grid(Vec2::splat(1.0), UVec2::splat(8)).with_params(ClothParams {
            integrator: Integrator::Rk4,
            spring_k,
            ..default()
        })
    };
    let bad = app.world_mut().spawn(rk4(1.0e9)).id();
    let good = app.world_mut().spawn((rk4(200.0), Transform::from_xyz(0.0, 2.0, 0.0))).id();
    run(&mut app, 0.2);
    assert!(app.world().get::<ClothSimulation>(bad).is_none());
    let beyond = |m: &ClothMessage, cloth: Entity| {
        matches!(m, ClothMessage::Rejected { entity, error: ClothError::BeyondStabilityGuard { needed, max: 256 } }
            if *entity == cloth && *needed > 256)
    };
    assert!(sent(&app).iter().any(|m| beyond(m, bad)));

    let before = positions(&app, good);
    app.world_mut().get_mut::<Cloth>(good).unwrap().params.spring_k = 1.0e9;
    run(&mut app, 0.3);
    let sim = app.world().get::<ClothSimulation>(good).unwrap().sim();
    assert_eq!(sim.params().spring_k, 200.0, "the last valid stiffness is kept");
    assert!(sim.is_finite());
    assert!(max_distance(&before, &positions(&app, good)) > 0.1, "the cloth stopped falling");
    assert!(sent(&app).iter().any(|m| beyond(m, good)));
}

#[test]
fn changing_the_grid_rebuilds_the_cloth_and_its_mesh() {
    let mut app = app();
    let cloth = app.world_mut().spawn(Cloth::grid(Vec2::splat(1.0), UVec2::splat(8))).id();
    run(&mut app, 0.2);
    let handle = app.world().get::<Mesh3d>(cloth).unwrap().0.clone();
    app.world_mut().get_mut::<Cloth>(cloth).unwrap().shape =
        ClothShape::Grid { size: Vec2::new(2.5, 1.0), particles: UVec2::new(20, 8) };
    run(&mut app, 0.2);
    assert_eq!(app.world().get::<ClothSimulation>(cloth).unwrap().sim().len(), 8 * 20);
    assert_eq!(app.world().get::<Mesh3d>(cloth).unwrap().0, handle, "the mesh handle is kept");
    let meshes = app.world().resource::<Assets<Mesh>>();
    assert_eq!(meshes.get(&handle).unwrap().count_vertices(), 8 * 20);
}

#[test]
fn reset_puts_the_cloth_back_at_rest() {
    let mut app = app();
    app.world_mut().resource_mut::<ClothSettings>().paused = true;
    let cloth = app
        .world_mut()
        .spawn((Cloth::grid(Vec2::splat(1.0), UVec2::splat(8)), Transform::from_xyz(0.0, 2.0, 0.0)))
        .id();
    app.update();
    let rest = positions(&app, cloth);
    app.world_mut().resource_mut::<ClothSettings>().paused = false;
    run(&mut app, 1.0);
    assert!(max_distance(&rest, &positions(&app, cloth)) > 1.0, "the cloth fell");
    app.world_mut().resource_mut::<ClothSettings>().paused = true;
    app.world_mut().write_message(ResetCloth::One(cloth));
    app.update();
    assert!(max_distance(&rest, &positions(&app, cloth)) < 1e-6);
}
