//! The browser check: a cloth dropped on a ball collider and a second one falling free, without
//! a window, on the backend the device gives (or the one asked for). After two seconds of
//! simulation it logs one line, `web_check: PASS ...` or `web_check: FAIL ...`: the backend that
//! ran, the particles, whether every one is finite, whether the first cloth rests on the ball
//! (none inside it, its top on the ball's), how far the free cloth is from the core's own
//! stepper after the same ticks (the GPU against the CPU reference), the mean frame time and
//! the GPU time of a tick (from timestamp queries, where the device has them).
//!
//! `bash scripts/web_check.sh` builds it for WebGPU and runs it in headless Chromium on both
//! backends (`.ci/run` does); natively `cargo run -p bevy_bvh_cloth --example web_check` runs the
//! same check and exits with its verdict. `CLOTH_EXAMPLE_BACKEND=cpu|gpu` (natively) or
//! `?backend=cpu|gpu` (in the page's address) asks for a backend.

use std::sync::Arc;

use bevy::prelude::*;
use bevy::window::ExitCondition;
use bevy_bvh_cloth::bvh_cloth_core::{ClothSim, ClothTopology};
use bevy_bvh_cloth::prelude::*;

/// Ticks of simulation before the verdict (2 s at the default 60 Hz: the draped cloth has
/// landed and settled; SwiftShader takes about half a second a tick).
const TICKS: u64 = 120;
/// The ball's radius, at the origin; the collider's margin.
const RADIUS: f32 = 0.3;
const MARGIN: f32 = 0.01;
/// How far the free cloth may be from the core's stepper after the same ticks, where a tick's
/// error would be over 0.1 m: the default integrator's kernels and the core part by a few
/// 1e-5 of a free fall (4.2e-4 m after 113 ticks in Chromium's SwiftShader, 1.5e-4 m after 73
/// on lavapipe; the native render test holds its fall to the same 1e-3 m).
const FALL_TOLERANCE: f32 = 1e-3;

fn main() {
    let plugins = DefaultPlugins.set(WindowPlugin {
        primary_window: None,
        exit_condition: ExitCondition::DontExit,
        close_when_requested: false,
        ..default()
    });
    // In a browser winit's loop runs the app (it waits for the adapter without blocking the
    // page); natively, without a display, a plain loop at 60 Hz.
    #[cfg(not(target_arch = "wasm32"))]
    let plugins = plugins
        .disable::<bevy::winit::WinitPlugin>()
        .add(bevy::app::ScheduleRunnerPlugin::run_loop(core::time::Duration::from_secs_f64(1.0 / 60.0)));
    let mut app = App::new();
    app.add_plugins((plugins, BvhClothPlugins::default()))
        .add_systems(Startup, setup)
        .add_systems(Update, (keep_the_gpu_in_step, check));
    match asked_backend().as_deref() {
        Some("cpu") => _ = app.insert_resource(ClothBackend::Cpu),
        Some("gpu") => _ = app.insert_resource(ClothBackend::Gpu),
        _ => {}
    }
    app.run();
}

/// The backend the page's address (`?backend=`) or, natively, `CLOTH_EXAMPLE_BACKEND` asks for.
fn asked_backend() -> Option<String> {
    #[cfg(target_arch = "wasm32")]
    {
        let search = web_sys::window()?.location().search().ok()?;
        search.trim_start_matches('?').split('&').find_map(|pair| pair.strip_prefix("backend=").map(String::from))
    }
    #[cfg(not(target_arch = "wasm32"))]
    {
        std::env::var("CLOTH_EXAMPLE_BACKEND").ok()
    }
}

/// The two cloths and the ball.
#[derive(Resource)]
struct Scene {
    draped: Entity,
    falling: Entity,
    ball: Entity,
    /// The falling cloth's parameters and pose, for the core's reference.
    fall: (ClothParams, Vec3),
}

fn falling_cloth() -> Cloth {
    // On no layer: it meets nothing, so the core steps it alone as the reference.
    Cloth::grid(Vec2::splat(0.5), UVec2::splat(16)).with_layers(CollisionLayers::NONE)
}

fn setup(mut commands: Commands, mut meshes: ResMut<Assets<Mesh>>) {
    let ball = commands
        .spawn((Mesh3d(meshes.add(Sphere::new(RADIUS).mesh().uv(32, 18))), AutoCollider::new(8).with_margin(MARGIN)))
        .id();
    let draped = commands
        .spawn((
            Cloth::grid(Vec2::splat(1.0), UVec2::splat(32)).with_params(ClothParams { damping: 1.0, ..default() }),
            ClothReadback::default(),
            Transform::from_xyz(0.02, 0.6, -0.01),
        ))
        .id();
    let at = Vec3::new(3.0, 10.0, 0.0);
    let falling = commands.spawn((falling_cloth(), ClothReadback::default(), Transform::from_translation(at))).id();
    commands.insert_resource(Scene { draped, falling, ball, fall: (falling_cloth().params, at) });
}

/// Without a window nothing holds the frames back to the GPU's pace (a page's canvas does):
/// where the device is slow (SwiftShader in a headless browser) the queue of submitted ticks
/// would grow without end, and no read would ever come back. So on the GPU backend the cloth
/// waits, paused, while its read-back state is more than a few ticks late.
fn keep_the_gpu_in_step(
    backend: Res<ActiveClothBackend>,
    clock: Res<ClothClock>,
    reads: Query<&ClothReadback>,
    mut settings: ResMut<ClothSettings>,
) {
    const AHEAD: u64 = 8;
    if *backend != ActiveClothBackend::Gpu {
        return;
    }
    let behind = reads.iter().any(|read| read.ticks_late.map_or(clock.total_ticks > AHEAD, |late| late > AHEAD));
    if settings.paused != behind {
        settings.paused = behind;
    }
}

/// Once the clock has run [`TICKS`] and both cloths' states are read back, logs the verdict
/// (natively, exits with it).
#[allow(clippy::too_many_arguments)]
fn check(
    scene: Res<Scene>,
    clock: Res<ClothClock>,
    backend: Res<ActiveClothBackend>,
    stats: Res<ClothStats>,
    time: Res<Time<Real>>,
    cloths: Query<(&ClothSimulation, &ClothReadback)>,
    colliders: Query<&ClothCollider>,
    mut frames: Local<(f32, u32)>,
    mut done: Local<bool>,
    mut exit: MessageWriter<AppExit>,
) {
    if clock.total_ticks > 0 {
        frames.0 += time.delta_secs();
        frames.1 += 1;
    }
    if frames.1 % 60 == 1 {
        info!("web check: {} of {TICKS} ticks on the {} backend", clock.total_ticks, backend.name());
    }
    if *done || clock.total_ticks < TICKS {
        return;
    }
    let (Ok((draped, _)), Ok((falling, read)), Ok(ball)) =
        (cloths.get(scene.draped), cloths.get(scene.falling), colliders.get(scene.ball))
    else {
        return;
    };
    // On the GPU backend, the states once read back; the CPU backend's are live, and its clock
    // of the wind counts the ticks the cloth has run.
    let ran = match *backend {
        ActiveClothBackend::Gpu => match read.ticks_run {
            Some(ran) if ran >= TICKS / 2 => ran,
            _ => return,
        },
        ActiveClothBackend::Cpu => (falling.sim().wind_time() / f64::from(clock.tick_seconds)).round() as u64,
    };
    *done = true;
    let positions = draped.sim().positions();
    let fall = falling.sim().positions();
    let finite = positions.iter().chain(&fall).all(|p| p.is_finite());
    let inside = positions.iter().filter(|&&p| ball.collider().contains(p)).count();
    let top = positions.iter().map(|p| p.y).fold(f32::NEG_INFINITY, f32::max);
    let resting = inside == 0 && (top - (RADIUS + MARGIN)).abs() < 0.02;
    let gap = gap_to_core(&scene.fall, ran, clock.tick_seconds, &fall);
    let frame_ms = 1e3 * frames.0 / frames.1.max(1) as f32;
    let gpu_tick = stats.gpu_time.map_or("none".to_string(), |(time, ticks)| {
        format!("{:.1} ms", time.as_secs_f64() * 1e3 / f64::from(ticks.max(1)))
    });
    let pass = finite && resting && gap < FALL_TOLERANCE && stats.particles == positions.len() + fall.len();
    let verdict = if pass { "PASS" } else { "FAIL" };
    let line = format!(
        "web_check: {verdict} backend={} particles={} finite={finite} inside={inside} top={top:.4} m \
         (ball {:.2} m) fall_gap={gap:.2e} m after {ran} ticks (tolerance {FALL_TOLERANCE:.0e}) frame={frame_ms:.1} ms gpu_tick={gpu_tick}",
        backend.name(),
        stats.particles,
        RADIUS + MARGIN
    );
    if pass {
        info!("{line}");
    } else {
        error!("{line}");
    }
    exit.write(if pass { AppExit::Success } else { AppExit::error() });
}

/// The largest distance between `got` and the core's own stepper running the falling cloth for
/// `ticks` ticks of `tick` seconds, built as the plugin builds it.
fn gap_to_core((params, at): &(ClothParams, Vec3), ticks: u64, tick: f32, got: &[Vec3]) -> f32 {
    let grid = bevy_bvh_cloth::bvh_cloth_core::ClothGrid::new(Vec2::splat(0.5), UVec2::splat(16));
    let Ok(topology) = ClothTopology::grid(grid) else { return f32::INFINITY };
    let pose = bevy_bvh_cloth::bvh_cloth_core::Affine3A::from_translation(*at);
    let Ok(mut sim) = ClothSim::new(params.clone(), Arc::new(topology), pose, &[]) else { return f32::INFINITY };
    for _ in 0..ticks {
        sim.tick(tick, &[]);
    }
    let want = sim.positions();
    if want.len() != got.len() {
        return f32::INFINITY;
    }
    want.iter().zip(got).map(|(a, b)| a.distance(*b)).fold(0.0, f32::max)
}
