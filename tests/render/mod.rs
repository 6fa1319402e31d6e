//! Rendering smoke tests: the bunny scene rendered without a window into an image, once on the
//! backend `Auto` picks (the GPU kernels on a device that runs them: lavapipe in CI) and once on
//! the CPU backend through the same renderer. Either way the cloth must be visible and draped
//! over the bunny. The pictures are kept as `$CARGO_TARGET_TMPDIR/bunny_render_{gpu,cpu}.png`.
//!
//! Also on the GPU backend, through the whole renderer: a diverged cloth is reset and reported,
//! and hundreds of spawn, rebuild and despawn rounds leave no wgpu buffer or bind group behind.
//!
//! (The fallback decision for a device without compute shaders is tested on its own, through
//! `ActiveClothBackend::choose`, in the headless `backend` tests. It cannot be staged here:
//! constraining lavapipe's limits below what the kernels need also breaks Bevy 0.19's own GPU
//! preprocessing and clustering, which key on the adapter's compute support.)
//!
//! Without an adapter this test passes with a note, unless `BVH_CLOTH_REQUIRE_GPU` is set (as
//! `.ci/run` sets it).

use std::sync::{Arc, Mutex};
use std::time::Duration;

use bevy::app::PluginsState;
use bevy::asset::RenderAssetUsages;
use bevy::camera::RenderTarget;
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::prelude::*;
use bevy::render::RenderApp;
use bevy::render::render_resource::TextureFormat;
use bevy::render::renderer::RenderInstance;
use bevy::render::view::screenshot::{Screenshot, ScreenshotCaptured};
use bevy::time::TimeUpdateStrategy;
use bevy::window::ExitCondition;
use bevy::winit::WinitPlugin;
use bevy_bvh_cloth::prelude::*;

mod gltf_character;

const WIDTH: u32 = 320;
const HEIGHT: u32 = 240;
const CLOTH: Color = Color::srgb(0.0, 0.0, 1.0);
const BUNNY: Color = Color::srgb(1.0, 0.0, 0.0);

fn unlit(materials: &mut Assets<StandardMaterial>, color: Color) -> MeshMaterial3d<StandardMaterial> {
    MeshMaterial3d(materials.add(StandardMaterial {
        base_color: color,
        unlit: true,
        double_sided: true,
        cull_mode: None,
        ..default()
    }))
}

/// A headless app with the whole renderer, asking for `backend`, ready to update.
fn render_app(backend: ClothBackend) -> App {
    render_app_with(backend, BvhClothPlugins::default())
}

/// As [`render_app`], with the cloth plugins given.
fn render_app_with(backend: ClothBackend, plugins: BvhClothPlugins) -> App {
    let mut app = App::new();
    app.add_plugins((
        DefaultPlugins.build().disable::<WinitPlugin>().set(WindowPlugin {
            primary_window: None,
            exit_condition: ExitCondition::DontExit,
            close_when_requested: false,
            ..default()
        }),
        bevy_obj::ObjPlugin,
        plugins,
    ))
    .insert_resource(backend)
    .insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_secs_f64(1.0 / 60.0)))
    .insert_resource(ClearColor(Color::BLACK));
    while app.plugins_state() == PluginsState::Adding {
        bevy::tasks::tick_global_task_pools_on_main_thread();
    }
    app.finish();
    // Kept before pipelined rendering moves the render app to its own thread.
    let instance = app.sub_app(RenderApp).world().resource::<RenderInstance>().clone();
    app.insert_resource(GpuInstance(instance));
    app.cleanup();
    app
}

/// The render app's wgpu instance, reachable from the main world.
#[derive(Resource)]
struct GpuInstance(RenderInstance);

/// Whether there is an adapter to render with; without one the tests pass with a note unless
/// `BVH_CLOTH_REQUIRE_GPU` is set.
fn adapter_present() -> bool {
    if bvh_cloth_gpu::headless::device().is_some() {
        return true;
    }
    assert!(std::env::var_os("BVH_CLOTH_REQUIRE_GPU").is_none(), "no GPU adapter (install mesa-vulkan-drivers)");
    eprintln!("no GPU adapter: skipped");
    false
}

/// A render app on the GPU backend whose kernels are compiled, or `None` (with a note) where
/// there is no adapter. The pipeline cache compiles the kernels in the background, and cloths
/// wait at rest until they are ready: a probe cloth is read back until it has run a tick (at
/// most five minutes), then despawned.
fn gpu_backend_app() -> Option<App> {
    gpu_backend_app_with(BvhClothPlugins::new(FixedPostUpdate))
}

/// As [`gpu_backend_app`], with the cloth plugins given.
fn gpu_backend_app_with(plugins: BvhClothPlugins) -> Option<App> {
    if !adapter_present() {
        return None;
    }
    let mut app = render_app_with(ClothBackend::Gpu, plugins);
    assert_eq!(*app.world().resource::<ActiveClothBackend>(), ActiveClothBackend::Gpu);
    wait_for_kernels(&mut app);
    Some(app)
}

/// Waits until the GPU backend's kernels are compiled: a probe cloth is read back until it has
/// run a tick (at most five minutes), then despawned.
fn wait_for_kernels(app: &mut App) {
    let probe = app.world_mut().spawn((Cloth::grid(Vec2::ONE, UVec2::splat(4)), ClothReadback::default())).id();
    let ran = |app: &App| app.world().get::<ClothReadback>(probe).unwrap().ticks_run.is_some_and(|t| t > 0);
    // Compiling the kernels takes lavapipe tens of seconds, longer with other tests compiling
    // beside it: wait on the clock, not on a count of frames.
    assert!(update_until(app, Duration::from_secs(300), ran), "the GPU kernels never became ready");
    app.world_mut().despawn(probe);
    app.update();
}

#[test]
fn the_gpu_backend_drapes_the_cloth_over_the_bunny() {
    if !adapter_present() {
        return;
    }
    let mut app = render_app(ClothBackend::Auto);
    let backend = *app.world().resource::<ActiveClothBackend>();
    if std::env::var_os("BVH_CLOTH_REQUIRE_GPU").is_some() {
        assert_eq!(backend, ActiveClothBackend::Gpu, "lavapipe runs compute shaders: Auto must pick the GPU");
    }
    // The scene counts frames: the kernels, compiled in the background (slowly beside other
    // tests compiling theirs), must be ready before its cloth is spawned.
    if backend == ActiveClothBackend::Gpu {
        wait_for_kernels(&mut app);
    }
    assert_draped(&render_bunny_scene(&mut app), "gpu");
}

#[test]
fn the_cpu_backend_drapes_the_same_scene_through_the_renderer() {
    if !adapter_present() {
        return;
    }
    let mut app = render_app(ClothBackend::Cpu);
    assert_eq!(*app.world().resource::<ActiveClothBackend>(), ActiveClothBackend::Cpu);
    assert_draped(&render_bunny_scene(&mut app), "cpu");
}

/// A `WIDTH` x `HEIGHT` image for a camera to render into.
fn image_target(world: &mut World) -> Handle<Image> {
    world.resource_mut::<Assets<Image>>().add({
        let mut image = Image::new_target_texture(WIDTH, HEIGHT, TextureFormat::Rgba8UnormSrgb, None);
        image.asset_usage = RenderAssetUsages::default();
        image
    })
}

/// Updates `app` until `done` says so or `limit` of wall-clock time has passed; whether it did.
/// What lavapipe compiles or reads back arrives after a time, not after a count of frames.
fn update_until(app: &mut App, limit: Duration, done: impl Fn(&App) -> bool) -> bool {
    let start = std::time::Instant::now();
    while !done(app) {
        if start.elapsed() > limit {
            return false;
        }
        app.update();
        std::thread::sleep(Duration::from_millis(5));
    }
    true
}

/// The picture in `target`. It arrives a few frames after it is asked for, once the render
/// pipelines it draws with are compiled, which lavapipe does slowly beside other tests
/// compiling theirs: wait on the clock (at most two minutes), not on a count of frames.
fn capture(app: &mut App, target: Handle<Image>) -> Image {
    let captured: Arc<Mutex<Option<Image>>> = Arc::default();
    let slot = captured.clone();
    app.world_mut().spawn(Screenshot::image(target)).observe(move |shot: On<ScreenshotCaptured>| {
        *slot.lock().unwrap() = Some(shot.image.clone());
    });
    update_until(app, Duration::from_secs(120), |_| captured.lock().unwrap().is_some());
    captured.lock().unwrap().take().expect("a screenshot within two minutes")
}

/// Loads the bunny with an `AutoCollider`, drops a 48 x 48 cloth on it, runs three seconds and
/// returns a picture of the scene.
fn render_bunny_scene(app: &mut App) -> Image {
    let world = app.world_mut();
    let target = image_target(world);
    world.spawn((
        Camera3d::default(),
        RenderTarget::Image(target.clone().into()),
        Tonemapping::None,
        Transform::from_xyz(0.2, 0.7, 2.6).looking_at(Vec3::new(-0.1, 0.45, 0.0), Vec3::Y),
    ));
    let bunny_mesh = world.resource::<AssetServer>().load("models/bunny_low.obj");
    let bunny_material = unlit(&mut world.resource_mut::<Assets<StandardMaterial>>(), BUNNY);
    let bunny = world.spawn((Mesh3d(bunny_mesh), bunny_material, AutoCollider::new(5))).id();
    for _ in 0..2000 {
        if matches!(app.world().get::<ColliderStatus>(bunny), Some(ColliderStatus::Ready { .. })) {
            break;
        }
        app.update();
    }
    assert!(matches!(app.world().get::<ColliderStatus>(bunny), Some(ColliderStatus::Ready { .. })));

    let world = app.world_mut();
    let cloth_material = unlit(&mut world.resource_mut::<Assets<StandardMaterial>>(), CLOTH);
    world.spawn((
        Cloth { params: ClothParams { damping: 1.0, ..default() }, ..Cloth::grid(Vec2::splat(1.2), UVec2::splat(48)) },
        cloth_material,
        Transform::from_xyz(-0.2, 1.3, 0.0),
    ));
    // Three seconds: it falls, lands and drapes.
    for _ in 0..180 {
        app.update();
    }
    capture(app, target)
}

/// The cloth is visible, covers the bunny's top and hangs down its sides. Saves the picture.
fn assert_draped(image: &Image, name: &str) {
    let png = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("bunny_render_{name}.png"));
    image.clone().try_into_dynamic().unwrap().to_rgb8().save(&png).unwrap();
    eprintln!("saved {}", png.display());

    // Classify pixels: cloth blue, bunny red, black background.
    let (mut cloth, mut bunny_px) = (Vec::new(), Vec::new());
    for y in 0..HEIGHT {
        for x in 0..WIDTH {
            let c = image.get_color_at(x, y).unwrap().to_srgba();
            if c.blue > 0.6 && c.red < 0.3 && c.green < 0.3 {
                cloth.push((x, y));
            } else if c.red > 0.6 && c.blue < 0.3 && c.green < 0.3 {
                bunny_px.push((x, y));
            }
        }
    }
    let area = (WIDTH * HEIGHT) as usize;
    eprintln!("cloth pixels: {}, bunny pixels: {}", cloth.len(), bunny_px.len());
    assert!(cloth.len() > area / 20, "the cloth covers only {} pixels", cloth.len());
    assert!(bunny_px.len() > area / 100, "the bunny shows only {} pixels", bunny_px.len());
    let rows = |px: &[(u32, u32)]| (px.iter().map(|p| p.1).min().unwrap(), px.iter().map(|p| p.1).max().unwrap());
    let ((cloth_top, cloth_bottom), (bunny_top, bunny_bottom)) = (rows(&cloth), rows(&bunny_px));
    eprintln!("rows: cloth {cloth_top}..{cloth_bottom}, bunny {bunny_top}..{bunny_bottom}");
    // Draped: the cloth covers the top of the bunny and hangs down past it, well above the
    // bunny's bottom (it has not fallen through). The cloth rests a centimetre off the true
    // surface (exact contact), and between its particles, 4 cm apart, its flat triangles may
    // cut under a sharp feature: the bunny's highest point may show a pixel or two above it.
    assert!(cloth_top <= bunny_top + 2, "the cloth is not on top of the bunny");
    let bunny_height = bunny_bottom - bunny_top;
    assert!(cloth_bottom > bunny_top + bunny_height / 4, "the cloth does not hang down the bunny's sides");
    assert!(cloth_top < bunny_top + bunny_height / 2, "the cloth fell through the bunny");
}

/// Every `Diverged` report, kept for the test.
#[derive(Resource, Default)]
struct DivergedReports(Vec<(Entity, u32)>);

fn collect_diverged(mut reader: MessageReader<ClothMessage>, mut reports: ResMut<DivergedReports>) {
    for message in reader.read() {
        if let ClothMessage::Diverged { entity, particles } = message {
            reports.0.push((*entity, *particles));
        }
    }
}

/// On the GPU backend a cloth whose springs overflow is held by the kernel's quarantine, its
/// fault count reaches the main world without a blocking read, and it is reset and reported
/// there; a cloth beside it is not.
#[test]
fn the_gpu_backend_resets_and_reports_a_diverged_cloth() {
    let Some(mut app) = gpu_backend_app() else { return };
    app.init_resource::<DivergedReports>().add_systems(Last, collect_diverged);
    let hanging = |x: f32| {
        (
            Cloth {
                params: ClothParams { damping: 0.5, ..default() },
                ..Cloth::grid(Vec2::splat(1.0), UVec2::splat(16)).with_pins(ClothPins::TwoEnds)
            },
            Transform::from_xyz(x, 2.0, 0.0),
        )
    };
    let calm = app.world_mut().spawn(hanging(0.0)).id();
    let wild = app.world_mut().spawn(hanging(3.0)).id();
    for _ in 0..10 {
        app.update();
    }
    assert!(app.world().resource::<DivergedReports>().0.is_empty());

    // Teleporting the entity drags the pins 3e38 m in one tick: the springs to them overflow.
    app.world_mut().get_mut::<Transform>(wild).unwrap().translation.x = 3.0e38;
    let mut frames = 0;
    while app.world().resource::<DivergedReports>().0.is_empty() && frames < 60 {
        app.update();
        frames += 1;
    }
    // A few more frames: stale or repeated reports would show up here.
    for _ in 0..30 {
        app.update();
    }
    let reports = &app.world().resource::<DivergedReports>().0;
    eprintln!("reported after {frames} frames: {reports:?}");
    assert_eq!(reports.len(), 1, "one reset, then the cloth hangs finitely where it was sent: {reports:?}");
    assert_eq!(reports[0].0, wild);
    assert!(reports[0].1 > 0);
    assert!(!reports.iter().any(|(entity, _)| *entity == calm));
    // The main world's copy is the rest pose under the new transform.
    let sim = app.world().get::<ClothSimulation>(wild).unwrap().sim();
    assert!(sim.positions().iter().all(|p| p.is_finite() && p.x > 1e38));
}

/// wgpu buffers and bind groups alive in the render app: every handle Bevy and the plugin hold.
fn live_gpu_resources(app: &App) -> (usize, usize) {
    let report = app.world().resource::<GpuInstance>().0.generate_report().expect("a wgpu-core instance reports");
    (report.hub.buffers.num_kept_from_user, report.hub.bind_groups.num_kept_from_user)
}

/// One round on the GPU backend: a collider and a cloth spawned, the grid changed (new
/// buffers) and the collider's mesh swapped (new trees), then both despawned. Returns the live
/// resources counted while they were alive.
fn gpu_round(app: &mut App, round: u32, meshes: &[Handle<Mesh>; 2]) -> (usize, usize) {
    let world = app.world_mut();
    let collider = world.spawn((Mesh3d(meshes[0].clone()), AutoCollider::new(1 + round % 4))).id();
    let cloth =
        world.spawn((Cloth::grid(Vec2::ONE, UVec2::new(6, 4 + round % 5)), Transform::from_xyz(0.0, 1.0, 0.0))).id();
    app.update();
    app.world_mut().get_mut::<Cloth>(cloth).unwrap().shape =
        ClothShape::Grid { size: Vec2::ONE, particles: UVec2::new(6, 5 + round % 5) };
    app.world_mut().entity_mut(collider).insert(Mesh3d(meshes[1].clone()));
    app.update();
    app.update();
    let alive = live_gpu_resources(app);
    app.world_mut().despawn(cloth);
    app.world_mut().despawn(collider);
    app.update();
    alive
}

/// Spawning, rebuilding and despawning cloths and colliders on the GPU backend does not grow the
/// render app's GPU resources: after a warm-up (Bevy's own pools and slabs settle), hundreds of
/// further rounds end with exactly as many live wgpu buffers and bind groups as they began.
#[test]
fn gpu_cloths_spawned_changed_and_despawned_leave_no_gpu_resource() {
    let Some(mut app) = gpu_backend_app() else { return };
    let meshes = {
        let mut assets = app.world_mut().resource_mut::<Assets<Mesh>>();
        [assets.add(Sphere::new(0.5).mesh().uv(16, 8)), assets.add(Cuboid::new(0.8, 0.3, 0.8))]
    };
    // Counted with nothing spawned, a few frames on: the render app runs a frame behind.
    let idle = |app: &mut App| {
        for _ in 0..5 {
            app.update();
        }
        live_gpu_resources(app)
    };
    for round in 0..20 {
        gpu_round(&mut app, round, &meshes);
    }
    let before = idle(&mut app);
    let mut busiest = before;
    for round in 20..320 {
        busiest = busiest.max(gpu_round(&mut app, round, &meshes));
    }
    // The rounds did reach the GPU: the cloths live in the batch's shared buffers (which stay,
    // sized for the largest round), and each holds its own fault staging buffer and is written
    // through a bind group of its mesh's slab.
    assert!(busiest.0 > before.0 && busiest.1 > before.1, "{busiest:?} while running, {before:?} idle");
    let after = idle(&mut app);
    eprintln!("live (buffers, bind groups): {before:?} after the warm-up, {after:?} after 300 more rounds");
    assert_eq!(after, before, "GPU resources grew over 300 rounds");
}

/// The largest distance between `got` and the core's 12 x 12 cloth (1 m, damping 0.5) after
/// `ticks` ticks of `tick` seconds falling from 10 m, with no pins and no colliders.
fn gap_to_core_fall(ticks: u64, tick: f32, got: &[Vec3]) -> f32 {
    let grid = bvh_cloth_core::ClothGrid::new(Vec2::ONE, UVec2::splat(12));
    let topology = std::sync::Arc::new(bvh_cloth_core::ClothTopology::grid(grid).unwrap());
    let params = bvh_cloth_core::ClothParams { damping: 0.5, ..Default::default() };
    let start = bvh_cloth_core::Affine3A::from_translation(Vec3::new(0.0, 10.0, 0.0));
    let mut core = bvh_cloth_core::ClothSim::new(params, topology, start, &[]).unwrap();
    for _ in 0..ticks {
        core.tick(tick, &[]);
    }
    core.positions().iter().zip(got).map(|(a, b)| a.distance(*b)).fold(0.0f32, f32::max)
}

/// On the GPU backend a cloth with `ClothReadback` has its live state in `ClothSimulation`, two
/// or three frames late and without a blocking read; a cloth without it keeps the state it was
/// built with. A free fall (no pins, no colliders: the springs stay at rest) is compared with
/// the core's CPU stepper: the state read back must be the core's after exactly the ticks
/// `ticks_run` says it has run (1e-4 m; a tick of fall at this speed moves the cloth over
/// 0.1 m, so a tick's error would show).
#[test]
fn the_gpu_backend_reads_a_cloth_back_when_asked() {
    let Some(mut app) = gpu_backend_app() else { return };
    let cloth = |x: f32| {
        (
            Cloth { params: ClothParams { damping: 0.5, ..default() }, ..Cloth::grid(Vec2::ONE, UVec2::splat(12)) },
            Transform::from_xyz(x, 10.0, 0.0),
        )
    };
    let read = app.world_mut().spawn((cloth(0.0), ClothReadback::default())).id();
    let unread = app.world_mut().spawn(cloth(3.0)).id();
    // How late each frame's state is, over the last 30 frames. One tick per frame here (two in
    // one frame of 16); with Bevy's pipelined rendering a state copied in one frame's render
    // reaches the main world two or three frames later: 3 to 5 ticks on an idle machine.
    // lavapipe shares the CPU with the other tests, so a frame can be later; a read that stops
    // arriving, or a queue of copies that grows, goes past both bounds within 30 frames.
    let mut lates = Vec::new();
    for frame in 0..60 {
        app.update();
        if frame >= 30 {
            lates.push(app.world().get::<ClothReadback>(read).unwrap().ticks_late.expect("a state arrived"));
        }
    }
    lates.sort_unstable();
    let (least, most) = (lates[0], lates[lates.len() - 1]);
    assert!(least <= 4 && most <= 10, "the state is {least} to {most} ticks late (one tick per frame here)");
    let late = app.world().get::<ClothReadback>(read).unwrap().ticks_late.unwrap();
    let ran = app.world().get::<ClothReadback>(read).unwrap().ticks_run.expect("a state arrived");
    let got = app.world().get::<ClothSimulation>(read).unwrap().sim().positions();
    let (ticks, tick) =
        (app.world().resource::<ClothClock>().total_ticks, app.world().resource::<ClothClock>().tick_seconds);
    assert!(ran + late <= ticks && ran > 30, "{ran} ticks run, {late} late, of {ticks}");
    // `FixedPostUpdate` at Bevy's default 64 Hz: one tick of 1/64 s per run.
    assert_eq!(tick, 1.0 / 64.0);
    let gap = gap_to_core_fall(ran, tick, &got);
    eprintln!(
        "read back {least} to {most} ticks late over 30 frames, {late} at the end, {ran} run (of {ticks}): within {gap:e} m of the core's state"
    );
    assert!(gap < 1e-4, "the read-back state is not the core's after {ran} ticks ({gap} m)");
    assert!(got.iter().all(|p| p.y < 8.0), "the read-back cloth has fallen");
    let rest = app.world().get::<ClothSimulation>(unread).unwrap().sim().positions();
    assert!(rest.iter().all(|p| p.y == 10.0), "a cloth without ClothReadback keeps its built state");
    // The ticks' GPU time reached ClothStats too, where the device has timestamp queries.
    // The adapter the render app runs on, as a headless device asks for it.
    let timestamps = bvh_cloth_gpu::headless::device()
        .is_some_and(|gpu| gpu.device.features().contains(bvh_cloth_gpu::wgpu::Features::TIMESTAMP_QUERY));
    let gpu_time = app.world().resource::<ClothStats>().gpu_time;
    eprintln!("GPU step time: {gpu_time:?} (timestamp queries: {timestamps})");
    if timestamps {
        let (time, ticks) = gpu_time.expect("a step time arrived");
        assert!(time > Duration::ZERO && (1..=2).contains(&ticks), "{time:?} for {ticks} ticks");
    } else {
        assert_eq!(gpu_time, None, "a step time without timestamp queries");
    }
}

/// On the GPU backend pins change on the running cloth, keeping its state on the GPU: a
/// 12 x 12 cloth on RK4, read back, hangs from its two ends; one is let go. The state read back
/// afterwards has run on from before the change (its ticks were not restarted by a rebuild),
/// and it is the core's after as many ticks with `ClothSim::set_pins` between them at the same
/// tick: within 1e-3 m, and ten times nearer than the core's letting go a tick earlier or later
/// (measured on lavapipe: 1.0e-4 m after 40 ticks of the swinging corner, against 0.11 and
/// 0.14 m).
#[test]
fn the_gpu_backend_lets_a_corner_go_without_a_rebuild() {
    let Some(mut app) = gpu_backend_app() else { return };
    let params = ClothParams { damping: 0.5, integrator: Integrator::Rk4, ..default() };
    let cloth =
        Cloth { params: params.clone(), ..Cloth::grid(Vec2::ONE, UVec2::splat(12)) }.with_pins(ClothPins::TwoEnds);
    let cloth = app.world_mut().spawn((cloth, Transform::from_xyz(0.0, 2.0, 0.0), ClothReadback::default())).id();
    let read = |app: &App| {
        let readback = app.world().get::<ClothReadback>(cloth).unwrap();
        (readback.ticks_run.unwrap_or(0), readback.ticks_late.unwrap_or(0))
    };
    let limit = Duration::from_secs(120);
    assert!(update_until(&mut app, limit, |app| read(app).0 >= 30), "no state read back within two minutes");
    let (ran, late) = read(&app);
    let before = ran + late;
    app.world_mut().get_mut::<Cloth>(cloth).unwrap().pins = ClothPins::Indices(vec![0]);
    assert!(
        update_until(&mut app, limit, |app| read(app).0 >= before + 40),
        "the cloth did not run 40 ticks past the change within two minutes"
    );
    let (ran, _) = read(&app);
    let got = app.world().get::<ClothSimulation>(cloth).unwrap().sim().positions();
    let tick = app.world().resource::<ClothClock>().tick_seconds;
    let grid = bvh_cloth_core::ClothGrid::new(Vec2::ONE, UVec2::splat(12));
    let topology = std::sync::Arc::new(bvh_cloth_core::ClothTopology::grid(grid).unwrap());
    let start = bvh_cloth_core::Affine3A::from_translation(Vec3::new(0.0, 2.0, 0.0));
    // The gap to the core letting go at tick `at`.
    let gap_letting_go_at = |at: u64| {
        let mut core = bvh_cloth_core::ClothSim::new(params.clone(), topology.clone(), start, &[0, 11]).unwrap();
        for k in 0..ran {
            if k == at {
                core.set_pins(&[0]).unwrap();
            }
            core.tick(tick, &[]);
        }
        core.positions().iter().zip(&got).map(|(a, b)| a.distance(*b)).fold(0.0f32, f32::max)
    };
    let gaps = [gap_letting_go_at(before - 1), gap_letting_go_at(before), gap_letting_go_at(before + 1)];
    eprintln!(
        "let go after {before} ticks, read back after {ran}: {gaps:?} m from the core's letting go a tick earlier, then, later"
    );
    assert!(
        gaps[1] < 1e-3 && gaps[1] * 10.0 < gaps[0].min(gaps[2]),
        "the GPU cloth is not the core's that let go at tick {before}"
    );
    assert!(2.0 - got[11].y > 0.2, "the released corner has not fallen: {}", got[11]);
}

/// In `FixedPostUpdate` (60 Hz steps) the render world runs every tick of every run: two runs
/// in a 30 fps frame run two ticks in that frame's pass, and a 120 fps frame without a run runs
/// none. The state read back is the core's after exactly the ticks the cloth has run, and those
/// are the clock's (1e-3 m, where a tick's error would move the cloth over 0.1 m: in this free
/// fall the default integrator's kernels and the core part by about 2.5e-5 of the distance
/// fallen, 1.5e-4 m after 73 ticks on lavapipe, the same whether the ticks run one or three to
/// a pass; block descent's agree to the bit). Running only the last run's ticks would leave the
/// cloth half as far fallen; running them again in a frame without a run, twice as far.
#[test]
fn the_gpu_backend_runs_every_tick_of_a_fixed_schedule() {
    let Some(mut app) = gpu_backend_app_with(BvhClothPlugins::new(FixedPostUpdate)) else { return };
    app.insert_resource(Time::<Fixed>::from_hz(60.0));
    let start = app.world().resource::<ClothClock>().total_ticks;
    let cloth = app
        .world_mut()
        .spawn((
            Cloth { params: ClothParams { damping: 0.5, ..default() }, ..Cloth::grid(Vec2::ONE, UVec2::splat(12)) },
            Transform::from_xyz(0.0, 10.0, 0.0),
            ClothReadback::default(),
        ))
        .id();
    let frames = |app: &mut App, fps: f64, count: u32| {
        app.insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_secs_f64(1.0 / fps)));
        for _ in 0..count {
            app.update();
        }
    };
    frames(&mut app, 30.0, 20);
    frames(&mut app, 120.0, 40);
    frames(&mut app, 30.0, 10);
    let readback = app.world().get::<ClothReadback>(cloth).unwrap();
    let (late, ran) = (readback.ticks_late.expect("a state arrived"), readback.ticks_run.expect("a state arrived"));
    let ticks = app.world().resource::<ClothClock>().total_ticks - start;
    assert!(late <= 6, "the state is {late} ticks late (two ticks per frame at the end)");
    assert!(ran > 60, "{ran} ticks run");
    let got = app.world().get::<ClothSimulation>(cloth).unwrap().sim().positions();
    // Each run's step, f32 rounding aside 1/60 s: the core takes the same ticks.
    let tick = app.world().resource::<ClothClock>().tick_seconds;
    assert!((tick - 1.0 / 60.0).abs() < 1e-7, "ticks of {tick} s");
    let gap = gap_to_core_fall(ran, tick, &got);
    eprintln!(
        "fixed schedule: {ran} ticks run + {late} late of {ticks} since it spawned; within {gap:e} m of the core's state"
    );
    assert_eq!(ran + late, ticks, "the cloth ran {ran} ticks and is {late} behind {ticks} since it spawned");
    assert!(gap < 1e-3, "the read-back state is not the core's after {ran} ticks ({gap} m)");
}

/// On the GPU backend a skinned collider is refitted on the GPU from its joint matrices: a
/// cloth lands on an arm that is then lifted 0.4 m and bent at the elbow, and the state read
/// back lies on the lifted arm with no particle inside its skinned triangles. (Unrefitted, the
/// collider would sit at the mesh's origin in its bind pose, and the cloth would fall through
/// the arm.) Then with the debug view on, the main world refits it on the CPU and writes the
/// tree in place instead; the arm is lowered and the cloth still rests on it.
#[test]
fn the_gpu_backend_refits_a_skinned_collider() {
    use crate::skinned_arm::{RADIUS, Solid, arm_mesh, skinned_triangles, spawn_arm};
    let Some(mut app) = gpu_backend_app() else { return };
    let (arm, shoulder, elbow) = spawn_arm(&mut app, arm_mesh(), Vec3::new(-0.6, 1.0, 0.0));
    let cloth = app
        .world_mut()
        .spawn((
            Cloth {
                params: ClothParams { damping: 1.0, ..default() },
                ..Cloth::grid(Vec2::splat(1.0), UVec2::splat(20))
            },
            Transform::from_xyz(-0.3, 1.3, 0.0),
            ClothReadback::default(),
        ))
        .id();
    let check = |app: &mut App, frames: u32, pose: &dyn Fn(f32) -> (f32, f32)| -> f32 {
        for frame in 0..frames {
            let (lift, bend) = pose((frame as f32 / 60.0).min(1.0));
            app.world_mut().get_mut::<Transform>(shoulder).unwrap().translation.y = 1.0 + lift;
            app.world_mut().get_mut::<Transform>(elbow).unwrap().rotation = Quat::from_rotation_z(bend);
            app.update();
        }
        assert!(app.world().get::<ClothReadback>(cloth).unwrap().ticks_late.is_some(), "a state arrived");
        let body = Solid::new(skinned_triangles(app, shoulder, elbow));
        let p = app.world().get::<ClothSimulation>(cloth).unwrap().sim().positions().to_vec();
        let bad = p.iter().filter(|&&q| body.contains(q)).count();
        assert_eq!(bad, 0, "{bad} particles read back inside the arm");
        p.iter().map(|q| q.y).fold(f32::MIN, f32::max)
    };
    // Landing, then the lift and bend over a second, then half a second held.
    check(&mut app, 60, &|_| (0.0, 0.0));
    let top = check(&mut app, 90, &|t| (0.4 * t, 0.4 * t));
    eprintln!("skinned arm lifted on the GPU backend: the cloth's highest particle at {top:.3} m");
    assert!(top > 1.4 + RADIUS, "the cloth was not lifted with the arm (highest particle at {top} m)");
    app.world_mut().resource_mut::<ClothSettings>().debug_view = true;
    let top = check(&mut app, 90, &|t| (0.4 - 0.2 * t, 0.4));
    eprintln!("lowered with the debug view on (CPU refit): highest particle at {top:.3} m");
    assert!(top > 1.2 + RADIUS && top < 1.4 + RADIUS, "the cloth did not follow the arm down ({top} m)");
    assert!(matches!(app.world().get::<ColliderStatus>(arm), Some(ColliderStatus::Ready { .. })));
}

/// On the GPU backend a row anchored to another entity rides it: after the target has swung
/// and climbed and then stopped, the state read back holds the row exactly where the target
/// carries it (1e-5 m), the rest hangs below it, and nothing went non-finite.
#[test]
fn the_gpu_backend_carries_anchors_on_another_entity() {
    let Some(mut app) = gpu_backend_app() else { return };
    let pole = app.world_mut().spawn(Transform::from_xyz(0.0, 2.0, -0.5)).id();
    let row = ClothPins::Region { min: Vec3::new(-1.0, -0.01, -0.51), max: Vec3::new(1.0, 0.01, -0.49) };
    let cloth = app
        .world_mut()
        .spawn((
            Cloth { params: ClothParams { damping: 1.0, ..default() }, ..Cloth::grid(Vec2::ONE, UVec2::splat(12)) }
                .with_anchor(ClothAnchor::new(row, pole)),
            Transform::from_xyz(0.0, 2.0, 0.0),
            ClothReadback::default(),
        ))
        .id();
    for frame in 0..90 {
        let t = (frame as f32 / 60.0).min(1.0);
        *app.world_mut().get_mut::<Transform>(pole).unwrap() =
            Transform::from_xyz(0.4 * t, 2.0 + 0.5 * t, -0.5).with_rotation(Quat::from_rotation_y(1.5 * t));
        app.update();
    }
    let pole_pose = Transform::from_xyz(0.4, 2.5, -0.5).with_rotation(Quat::from_rotation_y(1.5));
    let sim = app.world().get::<ClothSimulation>(cloth).unwrap().sim();
    assert!(app.world().get::<ClothReadback>(cloth).unwrap().ticks_late.is_some(), "a state arrived");
    let rest = sim.topology().rest_positions();
    let p = sim.positions();
    assert!(p.iter().all(|q| q.is_finite()));
    for i in 0..12 {
        // Bound at the start: the pole at (0, 2, -0.5) unturned, the cloth at (0, 2, 0).
        let local = rest[i] + Vec3::new(0.0, 0.0, 0.5);
        let want = pole_pose.transform_point(local);
        assert!(p[i].distance(want) < 1e-5, "anchored particle {i} at {} not {want}", p[i]);
    }
    assert!(p[12..].iter().all(|q| q.y < 2.5), "the cloth hangs below its row");
}

/// Self-contact through the whole renderer on the GPU backend (its kernels composed and
/// compiled by Bevy's pipeline cache): two cloths with self-contact dropped one above the other
/// onto a ball end with none of their triangles crossing and the upper one above the lower.
/// Without self-contact the upper falls through the lower (as the GPU crate's test of this scene
/// shows), so either check fails when the kernels do not run.
#[test]
fn the_gpu_backend_keeps_cloths_with_self_contact_apart() {
    let Some(mut app) = gpu_backend_app() else { return };
    let contact = Some(SelfContact { thickness: 0.02, friction: 0.3 });
    app.world_mut().spawn((PrimitiveCollider::sphere(0.25), Transform::from_xyz(0.0, 0.25, 0.0)));
    let mut spawn = |height: f32, turn: f32| {
        let cloth = Cloth {
            params: ClothParams { damping: 1.0, self_contact: contact, ..default() },
            ..Cloth::grid(Vec2::splat(1.0), UVec2::splat(20))
        };
        let at = Transform::from_xyz(0.0, height, 0.0).with_rotation(Quat::from_rotation_y(turn));
        app.world_mut().spawn((cloth, at, ClothReadback::default())).id()
    };
    let (lower, upper) = (spawn(0.7, 0.0), spawn(0.85, 0.5));
    for _ in 0..150 {
        app.update();
    }
    let positions = |e: Entity| app.world().get::<ClothSimulation>(e).unwrap().sim().positions();
    let (a, b) = (positions(lower), positions(upper));
    assert!(app.world().get::<ClothReadback>(upper).unwrap().ticks_run.is_some_and(|t| t > 100));
    let triangles = app.world().get::<ClothSimulation>(lower).unwrap().sim().topology().triangles().to_vec();
    let crossing = bevy_bvh_cloth::bvh_cloth_core::backend::crossing_pairs(&triangles, &a, Some((&triangles, &b)));
    let mean_y = |x: &[Vec3]| x.iter().map(|p| p.y).sum::<f32>() / x.len() as f32;
    eprintln!(
        "GPU backend, self-contact: {crossing} crossing triangles, upper {} m above lower",
        mean_y(&b) - mean_y(&a)
    );
    assert_eq!(crossing, 0, "triangles of the two cloths cross");
    assert!(mean_y(&b) > mean_y(&a) + 0.01, "the upper cloth is not resting on the lower");
}

/// Wind through the whole renderer on the GPU backend (the air kernels composed and compiled
/// by Bevy's pipeline cache, the wind, the sources and the clock extracted each frame): in an
/// ambient 6 m/s wind square to them, a curtain that catches the air blows out; one without
/// aerodynamics, and one in still air of its own, hang where they are; and a curtain in still
/// air of its own with a fan behind it blows out, since sources reach every cloth. When the wind
/// turns round, the blown curtain follows it. Negative controls: with the batch's sources left
/// unset the fanned curtain stays at 1e-7 m; with each cloth's wind not passed to the batch
/// each frame, the blown curtain keeps the wind it started in (0.47 m downwind after the turn).
#[test]
fn the_gpu_backend_blows_cloths_in_the_wind() {
    let Some(mut app) = gpu_backend_app() else { return };
    app.insert_resource(AmbientWind(Wind::steady(Vec3::new(0.0, 0.0, 6.0))));
    let mut spawn = |x: f32, aerodynamics: Aerodynamics, local: Option<Wind>| {
        let cloth = Cloth {
            params: ClothParams { damping: 1.0, aerodynamics, ..default() },
            ..Cloth::grid(Vec2::splat(1.0), UVec2::splat(16)).with_pins(ClothPins::FirstRow)
        };
        let at = Transform::from_xyz(x, 2.0, 0.0).with_rotation(Quat::from_rotation_x(core::f32::consts::FRAC_PI_2));
        let mut entity = app.world_mut().spawn((cloth, at, ClothReadback::default()));
        if let Some(wind) = local {
            entity.insert(LocalWind(wind));
        }
        entity.id()
    };
    let blown = spawn(0.0, Aerodynamics::FABRIC, None);
    let vacuum = spawn(2.0, Aerodynamics::NONE, None);
    let sheltered = spawn(4.0, Aerodynamics::FABRIC, Some(Wind::STILL));
    let fanned = spawn(6.0, Aerodynamics::FABRIC, Some(Wind::STILL));
    let fan_at = Transform::from_xyz(6.0, 1.5, -1.0).looking_at(Vec3::new(6.0, 1.5, 0.0), Vec3::Y);
    app.world_mut().spawn((WindFan { speed: 10.0, range: 4.0, spread: 0.8 }, fan_at));
    for _ in 0..120 {
        app.update();
    }
    assert!(app.world().get::<ClothReadback>(blown).unwrap().ticks_run.is_some_and(|t| t > 60));
    let downwind = |app: &App, e: Entity| {
        let p = app.world().get::<ClothSimulation>(e).unwrap().sim().positions();
        assert!(p.iter().all(|q| q.is_finite()));
        p.iter().map(|q| q.z).sum::<f32>() / p.len() as f32
    };
    let [b, v, s, f] = [blown, vacuum, sheltered, fanned].map(|e| downwind(&app, e));
    eprintln!("GPU backend, wind: blown {b} m, no aerodynamics {v} m, sheltered {s} m, fanned {f} m downwind");
    assert!(b > 0.2 && f > 0.1, "the wind and the fan blow their curtains out: {b} m, {f} m");
    assert!(v.abs() < 1e-3 && s.abs() < 1e-3, "no aerodynamics, or still air of its own: {v} m, {s} m");
    // The wind turns round: the running cloths take it up.
    app.insert_resource(AmbientWind(Wind::steady(Vec3::new(0.0, 0.0, -6.0))));
    for _ in 0..120 {
        app.update();
    }
    let back = downwind(&app, blown);
    assert!(back < -0.2, "the turned wind blows the curtain the other way: {back} m");
}
