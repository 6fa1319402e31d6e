//! Collision layers: a cloth meets only the colliders, and the other cloths, whose layers and
//! its own meet; one it does not meet changes nothing, bit for bit.

use std::sync::Arc;

use bvh_cloth_core::self_contact::ContactSolver;
use bvh_cloth_core::*;

use crate::common;

const CLOTH: u32 = 1 << 1;
const TABLE: u32 = 1 << 2;
const GHOST: u32 = 1 << 3;

/// A box under the cloth's middle, its top 0.3 m below the cloth.
fn table(layers: CollisionLayers) -> Collider {
    Collider::primitive(Primitive::Cuboid { half_extents: Vec3::new(0.3, 0.1, 0.3) })
        .unwrap()
        .with_pose(ColliderPose { translation: Vec3::new(0.0, 0.6, 0.0), ..Default::default() })
        .with_layers(layers)
}

fn dropped(integrator: Integrator, self_contact: bool, layers: CollisionLayers) -> ClothSim {
    let params = ClothParams {
        integrator,
        layers,
        self_contact: self_contact.then_some(SelfContact { thickness: 0.01, friction: 0.0 }),
        ..Default::default()
    };
    let pose = Affine3A::from_translation(Vec3::new(0.0, 1.0, 0.0));
    ClothSim::new(params, common::grid_topology(0.5, 16, 16), pose, &[]).unwrap()
}

fn run(sim: &mut ClothSim, colliders: &[Collider]) -> Vec<Vec3> {
    for _ in 0..60 {
        sim.tick(1.0 / 60.0, colliders);
    }
    sim.positions()
}

/// On each integrator, with and without self-contact: a table on a layer the cloth does not
/// filter for leaves its fall bit for bit as with no collider at all; one it does filter for
/// holds it above its top; a list of both acts as the second alone.
#[test]
fn a_cloth_meets_only_the_colliders_its_layers_meet() {
    let cloth = CollisionLayers::new(CLOTH, TABLE);
    let solid = table(CollisionLayers::new(TABLE, CollisionLayers::ALL));
    let ghost = table(CollisionLayers::new(GHOST, CollisionLayers::ALL));
    // Filters for the cloth's layer, but the cloth does not filter for it: they do not meet.
    let one_sided = table(CollisionLayers::new(GHOST, CLOTH));
    for integrator in [Integrator::Rk4, Integrator::default()] {
        for self_contact in [false, true] {
            let case = format!("{integrator:?}, self-contact {self_contact}");
            let alone = run(&mut dropped(integrator, self_contact, cloth), &[]);
            for passed in [&ghost, &one_sided] {
                let through = run(&mut dropped(integrator, self_contact, cloth), std::slice::from_ref(passed));
                assert_eq!(through, alone, "{case}: a collider the cloth does not meet changed its fall");
            }
            let held = run(&mut dropped(integrator, self_contact, cloth), std::slice::from_ref(&solid));
            let lowest = |ps: &[Vec3]| ps.iter().map(|p| p.y).fold(f32::INFINITY, f32::min);
            assert!(lowest(&alone) < 0.0, "{case}: the free fall reached {}", lowest(&alone));
            let middle = held.iter().filter(|p| p.x.abs() < 0.2 && p.z.abs() < 0.2);
            assert!(
                middle.clone().count() > 0 && middle.clone().all(|p| p.y > 0.69),
                "{case}: the table let the cloth through"
            );
            let both = run(&mut dropped(integrator, self_contact, cloth), &[ghost.clone(), solid.clone()]);
            assert_eq!(both, held, "{case}: the collider it does not meet changed the contact");
            // The default layers meet every collider's default layers.
            let default = run(
                &mut dropped(integrator, self_contact, CollisionLayers::DEFAULT),
                &[table(CollisionLayers::DEFAULT)],
            );
            assert_eq!(default, held, "{case}: the default layers do not meet");
        }
    }
}

/// Two cloths with self-contact stepped together: a small sheet dropped on a pinned one rests
/// on it when their layers meet and falls through when they do not; in the same tick each
/// keeps to its own colliders, so a table only the small sheet does not meet lets it through
/// while it holds the other.
#[test]
fn cloths_stepped_together_keep_off_each_other_and_their_colliders_by_layers() {
    let contact = SelfContact { thickness: 0.01, friction: 0.0 };
    let sheet = |layers: CollisionLayers, at: Vec3, size: f32, pinned: bool| {
        let params = ClothParams { self_contact: Some(contact), layers, ..Default::default() };
        let topology: Arc<ClothTopology> = common::grid_topology(size, 12, 12);
        let pins: Vec<u32> = if pinned { (0..topology.len() as u32).collect() } else { Vec::new() };
        ClothSim::new(params, topology, Affine3A::from_translation(at), &pins).unwrap()
    };
    let lowest = |sim: &ClothSim| sim.positions().iter().map(|p| p.y).fold(f32::INFINITY, f32::min);
    for meet in [true, false] {
        let small = if meet { CollisionLayers::new(CLOTH, CLOTH) } else { CollisionLayers::new(CLOTH, 0) };
        let mut floor = sheet(CollisionLayers::new(CLOTH, CollisionLayers::ALL), Vec3::Y * 0.5, 1.0, true);
        let mut falling = sheet(small, Vec3::Y * 0.6, 0.4, false);
        let mut solver = ContactSolver::default();
        for _ in 0..30 {
            ClothSim::tick_together(&mut [&mut floor, &mut falling], 1.0 / 60.0, &[], &mut solver);
        }
        if meet {
            assert!(lowest(&falling) > 0.5, "the sheets meet, and the small one fell to {}", lowest(&falling));
        } else {
            assert!(lowest(&falling) < 0.3, "the sheets do not meet, and the small one stayed at {}", lowest(&falling));
        }
    }
    // A table under both free sheets, met only by the second.
    let table = table(CollisionLayers::new(TABLE, CollisionLayers::ALL));
    // Side by side over the table, a little apart (and the second does not filter for cloth).
    let mut passes = sheet(CollisionLayers::new(CLOTH, CLOTH), Vec3::new(0.0, 1.0, -0.15), 0.2, false);
    let mut rests = sheet(CollisionLayers::new(CLOTH, TABLE), Vec3::new(0.0, 1.0, 0.15), 0.2, false);
    let mut solver = ContactSolver::default();
    for _ in 0..60 {
        ClothSim::tick_together(&mut [&mut passes, &mut rests], 1.0 / 60.0, std::slice::from_ref(&table), &mut solver);
    }
    assert!(lowest(&passes) < 0.0, "the table stopped the sheet that does not meet it ({})", lowest(&passes));
    assert!(lowest(&rests) > 0.69, "the table let through the sheet that meets it ({})", lowest(&rests));
}
