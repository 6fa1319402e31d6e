//! Aerodynamics on whole cloths: a sheet falling flat reaches the terminal speed of a flat
//! plate, a flag in wind streams downwind, and bad air is refused without touching the cloth.

use std::sync::Arc;

use bvh_cloth_core::{
    Aerodynamics, Affine3A, ClothError, ClothGrid, ClothParams, ClothSim, ClothTopology, Integrator, MeshRef, Vec3,
    Wind, WindSource,
};

/// A 1 m square sheet of `cells` x `cells` particles, each carrying its share of the surface
/// (so that drag per unit mass is the same everywhere and a falling sheet stays flat).
fn sheet(params: ClothParams, cells: u32, pins: &[u32]) -> ClothSim {
    let grid = ClothTopology::grid(ClothGrid::new([1.0, 1.0].into(), [cells, cells].into())).unwrap();
    let positions: Vec<[f32; 3]> = grid.rest_positions().iter().map(|p| p.to_array()).collect();
    let indices: Vec<u32> = grid.triangles().iter().flatten().copied().collect();
    let mesh = ClothTopology::from_mesh(MeshRef { positions: &positions, indices: Some(&indices) }).unwrap();
    ClothSim::new(params, Arc::new(mesh), Affine3A::IDENTITY, pins).unwrap()
}

fn mean_velocity(sim: &ClothSim) -> Vec3 {
    sim.velocities().iter().sum::<Vec3>() / sim.len() as f32
}

/// A 1 m² sheet of 0.2 kg falling flat in still air: drag ½ ρ C_d A v² balances its weight at
/// v = sqrt(2 m g / (ρ C_d A)) = 1.63 m/s, on every integrator.
#[test]
fn a_falling_sheet_reaches_the_terminal_speed_of_a_flat_plate() {
    let (mass, drag) = (0.2f32, 1.2f32);
    let terminal = (2.0 * mass * 9.81 / (1.225 * drag * 1.0)).sqrt();
    for integrator in [Integrator::Rk4, Integrator::BLOCK_DESCENT, Integrator::Multigrid] {
        let params = ClothParams {
            mass,
            damping: 0.0,
            integrator,
            aerodynamics: Aerodynamics { drag, lift: 0.0 },
            ..Default::default()
        };
        let mut sim = sheet(params.clone(), 16, &[]);
        for _ in 0..180 {
            sim.tick(1.0 / 60.0, &[]);
        }
        let fall = -mean_velocity(&sim).y;
        assert!((fall - terminal).abs() < 0.05 * terminal, "{integrator:?}: {fall} m/s vs {terminal} m/s");
        // Without aerodynamics the same sheet is in free fall: 29 m/s after 3 s.
        let mut vacuum = sheet(ClothParams { aerodynamics: Aerodynamics::NONE, ..params }, 16, &[]);
        for _ in 0..180 {
            vacuum.tick(1.0 / 60.0, &[]);
        }
        assert!(-mean_velocity(&vacuum).y > 25.0, "{integrator:?}");
    }
}

/// A flag held along one vertical edge, in a wind square to it: it swings round its pole and
/// streams out downwind. Without aerodynamics it hangs near its own plane.
#[test]
fn a_flag_swings_round_to_stream_downwind() {
    let cells = 12u32;
    // The sheet stands in the XY plane, its first column (x = -0.5) the pole.
    let pose = Affine3A::from_rotation_x(core::f32::consts::FRAC_PI_2);
    let pole: Vec<u32> = (0..cells).map(|r| r * cells).collect();
    for aerodynamics in [Aerodynamics::FABRIC, Aerodynamics::NONE] {
        let params = ClothParams { mass: 0.3, aerodynamics, ..Default::default() };
        let grid = Arc::new(ClothTopology::grid(ClothGrid::new([1.0, 1.0].into(), [cells, cells].into())).unwrap());
        let mut sim = ClothSim::new(params, grid, pose, &pole).unwrap();
        sim.set_wind(Wind::steady(Vec3::new(0.0, 0.0, 10.0)), &[]).unwrap();
        for _ in 0..180 {
            sim.tick(1.0 / 60.0, &[]);
        }
        assert!(sim.is_finite());
        let downwind = (0..cells).map(|r| sim.position((r * cells + cells - 1) as usize).z).sum::<f32>() / cells as f32;
        if aerodynamics.is_active() {
            // Streaming straight out would be 1 m.
            assert!(downwind > 0.7, "the wind swings the flag out: its free edge is {downwind} m downwind");
        } else {
            // It buckles out of its plane a little under its own weight, either way.
            assert!(downwind.abs() < 0.3, "without aerodynamics the wind does nothing: {downwind} m");
        }
    }
}

/// A fan pushes a hanging cloth in its cone and leaves one outside it alone; a blast pushes
/// away from its centre.
#[test]
fn sources_push_what_they_reach() {
    let params = ClothParams { mass: 0.3, aerodynamics: Aerodynamics::FABRIC, ..Default::default() };
    // Hanging in the XY plane from its top row, at the origin.
    let pose = Affine3A::from_rotation_x(core::f32::consts::FRAC_PI_2);
    let top: Vec<u32> = (0..10).collect();
    let hang = |sources: &[WindSource]| {
        let grid = Arc::new(ClothTopology::grid(ClothGrid::new([1.0, 1.0].into(), [10, 10].into())).unwrap());
        let mut sim = ClothSim::new(params.clone(), grid, pose, &top).unwrap();
        sim.set_wind(Wind::STILL, sources).unwrap();
        for _ in 0..90 {
            sim.tick(1.0 / 60.0, &[]);
        }
        sim.positions().iter().map(|p| p.z).sum::<f32>() / sim.len() as f32
    };
    let fan = |origin: Vec3| WindSource::Fan { origin, direction: Vec3::Z, speed: 12.0, range: 4.0, spread: 0.6 };
    let still = hang(&[]);
    let blown = hang(&[fan(Vec3::new(0.0, 0.0, -1.0))]);
    let missed = hang(&[fan(Vec3::new(5.0, 0.0, -1.0))]);
    let blast = hang(&[WindSource::Blast { center: Vec3::new(0.0, 0.0, 1.0), speed: -15.0, radius: 3.0 }]);
    assert!(blown - still > 0.1, "the fan blows the cloth along +Z: {still} -> {blown}");
    assert!((missed - still).abs() < 1e-4, "a fan aimed elsewhere does nothing: {still} -> {missed}");
    assert!(blast - still > 0.05, "a sucking blast ahead pulls the cloth towards it: {still} -> {blast}");
}

/// The wind clock picks the gusts: two cloths on the same clock move alike, and the clock
/// moves by each tick's length.
#[test]
fn gusts_follow_the_wind_clock() {
    let params = ClothParams { mass: 0.3, aerodynamics: Aerodynamics::FABRIC, ..Default::default() };
    let wind = Wind { seed: 5, ..Wind::gusty(Vec3::new(6.0, 0.0, 2.0)) };
    let run = |start: f64| {
        let mut sim = sheet(params.clone(), 8, &[0, 7]);
        sim.set_wind(wind, &[]).unwrap();
        sim.set_wind_time(start);
        for _ in 0..30 {
            sim.tick(1.0 / 60.0, &[]);
        }
        assert!((sim.wind_time() - (start + 0.5)).abs() < 1e-6);
        sim.positions()
    };
    assert_eq!(run(2.0), run(2.0), "the same clock, the same motion");
    let apart = run(2.0).iter().zip(run(40.0)).map(|(a, b)| (*a - b).length()).fold(0.0f32, f32::max);
    assert!(apart > 1e-3, "another time, other gusts: {apart} m");
}

#[test]
fn bad_air_is_refused_and_the_cloth_keeps_its_wind() {
    let params = ClothParams { aerodynamics: Aerodynamics::FABRIC, ..Default::default() };
    let mut sim = sheet(params.clone(), 8, &[]);
    let good = Wind::steady(Vec3::new(5.0, 0.0, 0.0));
    sim.set_wind(good, &[]).unwrap();
    let error = sim.set_wind(Wind { velocity: Vec3::new(f32::NAN, 0.0, 0.0), ..good }, &[]).unwrap_err();
    assert_eq!(error, ClothError::NotFinite { field: "wind.velocity" });
    let hurricane = Wind::steady(Vec3::new(0.0, 0.0, 300.0));
    assert!(matches!(sim.set_wind(hurricane, &[]), Err(ClothError::OutOfRange { field: "wind.velocity", .. })));
    let fan = WindSource::Fan { origin: Vec3::ZERO, direction: Vec3::X, speed: f32::NAN, range: 1.0, spread: 1.0 };
    assert!(matches!(sim.set_wind(good, &[fan]), Err(ClothError::OutOfRange { field: "fan.speed", .. })));
    assert_eq!(sim.wind(), &good);
    let absurd = ClothParams { aerodynamics: Aerodynamics { drag: -1.0, lift: 0.0 }, ..params };
    assert!(matches!(sim.set_params(absurd), Err(ClothError::OutOfRange { field: "aerodynamics.drag", .. })));
    sim.tick(1.0 / 60.0, &[]);
    assert!(sim.is_finite());
}
