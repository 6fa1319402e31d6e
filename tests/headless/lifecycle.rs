//! Spawning, changing and despawning cloths and colliders thousands of times leaves no state
//! behind. (Resident memory over a long run is reported by the soak example.)

use bevy::prelude::*;
use bevy_bvh_cloth::prelude::*;

use crate::headless::harness::{add_mesh, app, run};

/// Rounds of spawn, change and despawn.
const ROUNDS: u32 = 2_000;

fn entities(app: &mut App) -> usize {
    let world = app.world_mut();
    world.query::<Entity>().iter(world).count()
}

#[test]
fn thousands_of_spawn_change_despawn_rounds_leave_nothing_behind() {
    let mut app = app();
    let ball = add_mesh(&mut app, Sphere::new(0.5).mesh().uv(16, 8));
    let block = add_mesh(&mut app, Cuboid::new(0.8, 0.3, 0.8));
    let (entities_at_start, meshes_at_start) = (entities(&mut app), app.world().resource::<Assets<Mesh>>().len());
    for round in 0..ROUNDS {
        let collider = app.world_mut().spawn((Mesh3d(ball.clone()), AutoCollider::new(1 + round % 4))).id();
        let cloth = app
            .world_mut()
            .spawn((Cloth::grid(Vec2::ONE, UVec2::new(6, 4 + round % 5)), Transform::from_xyz(0.0, 1.0, 0.0)))
            .id();
        app.update();

        // Change the grid (a rebuild) and swap the collider's mesh, then run a frame.
        app.world_mut().get_mut::<Cloth>(cloth).unwrap().shape =
            ClothShape::Grid { size: Vec2::ONE, particles: UVec2::new(6, 5 + round % 5) };
        app.world_mut().entity_mut(collider).insert(Mesh3d(block.clone()));
        app.update();
        let stats = app.world().resource::<ClothStats>();
        assert_eq!((stats.cloths, stats.colliders), (1, 1), "round {round}");
        assert!(stats.gpu_time.is_none() && stats.backend == "CPU", "round {round}: the CPU backend has no GPU time");
        let particles = app.world().get::<ClothSimulation>(cloth).expect("the cloth is simulated").sim().len();
        assert_eq!(particles as u32, 6 * (5 + round % 5), "round {round}: the grid change was not applied");

        app.world_mut().despawn(cloth);
        app.world_mut().despawn(collider);
        app.update();
    }
    run(&mut app, 0.05);
    let stats = app.world().resource::<ClothStats>();
    assert_eq!((stats.cloths, stats.particles, stats.colliders, stats.spheres), (0, 0, 0, 0));
    assert_eq!(app.world().resource::<Assets<Mesh>>().len(), meshes_at_start, "a mesh asset leaked");
    assert_eq!(entities(&mut app), entities_at_start, "an entity leaked");
    let world = app.world_mut();
    assert_eq!(world.query::<&ClothSimulation>().iter(world).count(), 0);
}
