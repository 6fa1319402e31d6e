//! Soak run: a cloth on the bunny for 100,000 ticks while every parameter is swept across its
//! whole range (and past it), the collider's mesh and resolution are swapped, and the cloth is
//! respawned with a new grid now and then. Headless (MinimalPlugins, so no render device: the
//! CPU backend).
//!
//! `cargo run --release -p bevy_bvh_cloth --example soak -- [TICKS] [CLOTH_SIZE]`
//! (defaults: 100000 ticks, a 24 x 24 cloth). Prints what happened: ticks run, resets, rejected
//! parameter sets, the energy, and the process's resident memory at the start and the end.

use core::time::Duration;
use std::time::Instant;

use bevy::asset::AssetPlugin;
use bevy::mesh::MeshPlugin;
use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use bevy_bvh_cloth::prelude::*;
use bevy_obj::ObjPlugin;

/// What the run saw, updated by systems.
#[derive(Resource, Default)]
struct Tally {
    ticks: u64,
    diverged: u32,
    rejected: u32,
    collider_failed: u32,
    anchors_lost: u32,
    /// When each divergence happened, and under which parameters.
    divergences: Vec<String>,
}

fn count(
    mut reader: MessageReader<ClothMessage>,
    stats: Res<ClothStats>,
    cloths: Query<&Cloth>,
    mut tally: ResMut<Tally>,
) {
    tally.ticks += u64::from(stats.ticks);
    for message in reader.read() {
        match message {
            ClothMessage::Diverged { entity, particles } => {
                tally.diverged += 1;
                if let Ok(c) = cloths.get(*entity) {
                    let line = format!(
                        "tick {}: {particles} particles; {:?}, looper {}, spring_k {:.0}, damping {:.2}, force {:.1?}",
                        tally.ticks,
                        c.params.integrator,
                        c.params.looper,
                        c.params.spring_k,
                        c.params.damping,
                        c.params.external_force
                    );
                    tally.divergences.push(line);
                }
            }
            ClothMessage::Rejected { .. }
            | ClothMessage::WindSourceRejected { .. }
            | ClothMessage::NameNotFound { .. }
            | ClothMessage::SceneNotSpawned { .. } => tally.rejected += 1,
            ClothMessage::WindNotFelt { .. } => {}
            ClothMessage::ColliderFailed { .. } => tally.collider_failed += 1,
            ClothMessage::AnchorLost { .. } => tally.anchors_lost += 1,
        }
    }
}

/// Resident memory of this process in MiB (Linux; `None` elsewhere).
fn resident_mib() -> Option<f64> {
    let statm = std::fs::read_to_string("/proc/self/statm").ok()?;
    let pages: f64 = statm.split_whitespace().nth(1)?.parse().ok()?;
    Some(pages * 4096.0 / (1024.0 * 1024.0))
}

/// A value swept back and forth between `lo` and `hi` with period `period` ticks, on a log scale
/// when `log` is set.
fn sweep(tick: u64, period: u64, lo: f32, hi: f32, log: bool) -> f32 {
    let phase = (tick % period) as f32 / period as f32;
    let t = 1.0 - (2.0 * phase - 1.0).abs();
    if log { lo * (hi / lo).powf(t) } else { lo + (hi - lo) * t }
}

/// The parameters at `tick`: the panel's ranges (Looper 1-64, SpringK 10-400 N/m, Damping
/// 0-10 /s, External Force ±20 N), SpringK swept on to 100 times the panel's top, both
/// integrators, and now and then a value the component must refuse.
fn parameters(cloth: &mut Cloth, tick: u64) {
    cloth.params.looper = sweep(tick, 7_919, 1.0, 64.0, false).round() as u32;
    cloth.params.spring_k = sweep(tick, 10_007, 10.0, 40_000.0, true);
    cloth.params.damping = sweep(tick, 3_001, 0.0, 10.0, false);
    let f = |period| sweep(tick, period, -20.0, 20.0, false);
    cloth.params.external_force = Vec3::new(f(1_009), f(2_003), f(4_001));
    cloth.params.integrator =
        if (tick / 25_000).is_multiple_of(2) { Integrator::Rk4 } else { Integrator::SemiImplicitEuler };
    match tick % 9_973 {
        0 => cloth.params.external_force.x = f32::NAN,
        1 => cloth.params.mass = -1.0,
        2 => cloth.params.looper = 0,
        _ => cloth.params.mass = 1.0,
    }
}

fn main() {
    let mut args = std::env::args().skip(1);
    let ticks: u64 = args.next().and_then(|a| a.parse().ok()).unwrap_or(100_000);
    let size: u32 = args.next().and_then(|a| a.parse().ok()).unwrap_or(24);

    let mut app = App::new();
    app.add_plugins((
        MinimalPlugins,
        TransformPlugin,
        AssetPlugin::default(),
        MeshPlugin,
        ObjPlugin,
        BvhClothPlugin::default(),
    ))
    .insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_secs_f64(1.0 / 60.0)))
    .init_resource::<Tally>()
    .add_systems(Last, count);
    app.update();

    let bunny: Handle<Mesh> = app.world().resource::<AssetServer>().load("models/bunny_low.obj");
    let ball = app.world_mut().resource_mut::<Assets<Mesh>>().add(Sphere::new(0.4).mesh().uv(24, 12));
    let collider = app.world_mut().spawn((Mesh3d(bunny.clone()), AutoCollider::new(5))).id();
    let spawn_cloth = |app: &mut App, rows: u32| {
        // Pinned at two corners, over the bunny: a free cloth under a swept upward force flies
        // off, and tens of kilometres from the origin f32 positions are too coarse for its
        // springs (see the README's "When things go wrong").
        let depth = 1.4 * (rows - 1) as f32 / (size - 1) as f32;
        let cloth = Cloth { pins: ClothPins::TwoEnds, ..Cloth::grid(Vec2::new(1.4, depth), UVec2::new(size, rows)) };
        app.world_mut().spawn((cloth, Transform::from_xyz(0.0, 1.2, 0.0))).id()
    };
    let mut cloth = spawn_cloth(&mut app, size);

    let started = Instant::now();
    let (mut memory_start, mut max_energy, mut final_energy) = (None, f64::NEG_INFINITY, 0.0);
    let mut farthest = 0.0f32;
    for tick in 1..=ticks {
        if let Some(mut c) = app.world_mut().get_mut::<Cloth>(cloth) {
            parameters(&mut c, tick);
        }
        if tick.is_multiple_of(5_000) {
            // Lifecycle under load: a new cloth with another grid, another collider mesh and n.
            app.world_mut().despawn(cloth);
            cloth = spawn_cloth(&mut app, size + (tick / 5_000 % 4) as u32);
            let mesh = if (tick / 5_000).is_multiple_of(2) { bunny.clone() } else { ball.clone() };
            let n = [1, 3, 5, 8][(tick / 5_000 % 4) as usize];
            app.world_mut().entity_mut(collider).insert((Mesh3d(mesh), AutoCollider::new(n)));
        }
        app.update();
        if tick == 5_000 {
            memory_start = resident_mib();
        }
        if tick.is_multiple_of(100)
            && let Some(sim) = app.world().get::<ClothSimulation>(cloth)
        {
            let energy = sim.sim().energy();
            max_energy = max_energy.max(energy);
            final_energy = energy;
            farthest = sim.sim().positions().iter().map(|p| p.length()).fold(farthest, f32::max);
        }
    }

    let tally = app.world().resource::<Tally>();
    let stats = app.world().resource::<ClothStats>();
    let mib = |m: Option<f64>| m.map_or("unknown".into(), |m| format!("{m:.1} MiB"));
    println!("| soak ({size} x {size} cloth on the bunny, CPU backend) | |");
    println!("|---|---|");
    println!("| ticks run | {} (wall {:.0} s) |", tally.ticks, started.elapsed().as_secs_f64());
    println!("| resets after a non-finite state (`Diverged`) | {} |", tally.diverged);
    println!("| parameter sets refused (`Rejected`) | {} |", tally.rejected);
    println!("| collider failures | {} |", tally.collider_failed);
    println!("| anchors lost | {} |", tally.anchors_lost);
    println!("| energy: max / final (J) | {max_energy:.3} / {final_energy:.3} |");
    println!("| farthest particle from the origin (m) | {farthest:.1} |");
    println!("| resident memory at tick 5,000 / at the end | {} / {} |", mib(memory_start), mib(resident_mib()));
    println!("| cloths / colliders alive at the end | {} / {} |", stats.cloths, stats.colliders);
    for line in &tally.divergences {
        println!("\ndiverged at {line}");
    }
}
