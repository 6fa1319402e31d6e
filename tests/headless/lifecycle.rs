//! Spawning and despawning leaves no state behind.

use bevy::prelude::*;
use bevy_bvh_cloth::prelude::*;

use crate::harness::{add_mesh, app, run, wait_for_collider};

#[test]
fn despawning_cloths_and_colliders_leaves_nothing_behind() {
    let mut app = app();
    let meshes_at_start = app.world().resource::<Assets<Mesh>>().len();
    for round in 0..20 {
        let mesh = add_mesh(&mut app, Sphere::new(0.5).mesh().uv(16, 8));
        let collider = app.world_mut().spawn((Mesh3d(mesh), AutoCollider::new(3))).id();
        wait_for_collider(&mut app, collider);
        let cloth = app.world_mut().spawn((Cloth::new(10, 10 + round, 1.0), Transform::from_xyz(0.0, 1.0, 0.0))).id();
        run(&mut app, 0.1);
        let stats = app.world().resource::<ClothStats>();
        assert_eq!((stats.cloths, stats.colliders), (1, 1));
        app.world_mut().despawn(cloth);
        app.world_mut().despawn(collider);
        run(&mut app, 0.05);
    }
    let stats = app.world().resource::<ClothStats>();
    assert_eq!((stats.cloths, stats.particles, stats.colliders, stats.spheres), (0, 0, 0, 0));
    assert_eq!(app.world().resource::<Assets<Mesh>>().len(), meshes_at_start, "a mesh asset leaked");
    let world = app.world_mut();
    assert_eq!(world.query::<&ClothSimulation>().iter(world).count(), 0);
}
