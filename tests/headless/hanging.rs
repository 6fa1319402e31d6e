//! The paper's Fig. 5 scene: a cloth with two ends fixed sags under gravity.

use std::sync::Arc;

use bevy::mesh::VertexAttributeValues;
use bevy::prelude::*;
use bevy_bvh_cloth::bvh_cloth_core::{Affine3A, ClothGrid, ClothParams, ClothSim, ClothTopology};
use bevy_bvh_cloth::prelude::*;

use crate::headless::harness::{app, app_at, positions, run};

fn hanging_cloth() -> Cloth {
    Cloth {
        params: ClothParams { damping: 2.0, ..default() },
        ..Cloth::grid(Vec2::splat(1.0), UVec2::splat(16)).with_pins(ClothPins::TwoEnds)
    }
}

/// Where pin `index` of a 16 x 16, 1 m cloth belongs under `transform`.
fn pin_target(transform: &Transform, col: u32) -> Vec3 {
    transform.transform_point(Vec3::new(col as f32 / 15.0 - 0.5, 0.0, -0.5))
}

#[test]
fn sags_settles_and_pins_follow_the_transform() {
    let mut app = app();
    let transform = Transform::from_xyz(0.0, 2.0, 0.0);
    let cloth = app.world_mut().spawn((hanging_cloth(), transform)).id();
    run(&mut app, 15.0);

    let p = positions(&app, cloth);
    let sim = app.world().get::<ClothSimulation>(cloth).unwrap().sim();
    assert_eq!(sim.pins(), &[0, 15]);
    assert!(p[0].distance(pin_target(&transform, 0)) < 1e-5, "pin 0 at {}", p[0]);
    assert!(p[15].distance(pin_target(&transform, 15)) < 1e-5, "pin 15 at {}", p[15]);
    // The plugin runs the core's stepper: the same 900 ticks of the core's own cloth, built
    // from the same parameters, land on the same bits.
    let topology = Arc::new(ClothTopology::grid(ClothGrid::new(Vec2::ONE, UVec2::splat(16))).unwrap());
    let params = ClothParams { damping: 2.0, ..ClothParams::default() };
    let pose = Affine3A::from_translation(Vec3::new(0.0, 2.0, 0.0));
    let mut core = ClothSim::new(params, topology, pose, &[0, 15]).unwrap();
    let ticks = app.world().resource::<ClothClock>().total_ticks;
    assert_eq!(ticks, 900, "15 s at 60 Hz");
    for _ in 0..ticks {
        core.tick(1.0 / 60.0, &[]);
    }
    assert_eq!(p, core.positions(), "the plugin's cloth left the core's trajectory");
    // Sagged: the middle of the pinned row hangs below the pins. Measured 6.8 cm; the band
    // allows about 30 % either way. A taut edge's sag grows roughly with the square root of its
    // strain, so it catches the weight-to-stiffness ratio changing by about 1.7x.
    let sag = 2.0 - p[8].y;
    assert!(sag > 0.05 && sag < 0.09, "the top edge sags {sag} m");
    // Settled.
    let speed = sim.velocities().iter().map(|v| v.length()).fold(0.0f32, f32::max);
    assert!(speed < 1e-2, "still moving at {speed} m/s");
    // The mesh shows the cloth in the entity's frame: the pins sit at their rest spots.
    let handle = app.world().get::<Mesh3d>(cloth).unwrap().0.clone();
    let meshes = app.world().resource::<Assets<Mesh>>();
    let Some(VertexAttributeValues::Float32x3(mesh_positions)) =
        meshes.get(&handle).unwrap().attribute(Mesh::ATTRIBUTE_POSITION)
    else {
        panic!("the cloth mesh has positions");
    };
    assert!(Vec3::from(mesh_positions[15]).distance(Vec3::new(0.5, 0.0, -0.5)) < 1e-5);
    assert!((Vec3::from(mesh_positions[8]).y - (p[8].y - 2.0)).abs() < 1e-5);

    // Move and turn the entity: the pins go with it.
    let moved = Transform::from_xyz(1.0, 2.5, -1.0).with_rotation(Quat::from_rotation_y(0.6));
    *app.world_mut().get_mut::<Transform>(cloth).unwrap() = moved;
    run(&mut app, 0.1);
    let p = positions(&app, cloth);
    assert!(p[0].distance(pin_target(&moved, 0)) < 1e-5, "pin 0 at {}", p[0]);
    assert!(p[15].distance(pin_target(&moved, 15)) < 1e-5, "pin 15 at {}", p[15]);
}

#[test]
fn same_result_at_30_and_144_frames_per_second() {
    let simulate = |fps: f64| {
        let mut app = app_at(fps);
        let cloth = app.world_mut().spawn((hanging_cloth(), Transform::from_xyz(0.0, 2.0, 0.0))).id();
        run(&mut app, 2.0);
        (app.world().resource::<ClothClock>().total_ticks, positions(&app, cloth))
    };
    let (ticks_30, at_30) = simulate(30.0);
    let (ticks_144, at_144) = simulate(144.0);
    // Two seconds are 120 ticks at 60 Hz; rounding may leave the last one for the next frame.
    assert!((119..=120).contains(&ticks_30) && ticks_30 == ticks_144, "{ticks_30} vs {ticks_144} ticks");
    // Whole ticks of the same length: the same arithmetic, so the same bits.
    assert_eq!(at_30, at_144);
}
