//! What the example scenes share: an orbit camera, a light, a ground, the keys, the panel, and
//! an optional screenshot-and-exit for smoke runs and README pictures.

use bevy::input::mouse::{AccumulatedMouseMotion, AccumulatedMouseScroll};
use bevy::prelude::*;
use bevy::render::view::screenshot::{Screenshot, save_to_disk};
use bevy_bvh_cloth::prelude::*;

/// Set this to a PNG path to take a screenshot after a few seconds and exit.
const SCREENSHOT_ENV: &str = "CLOTH_EXAMPLE_SCREENSHOT";
/// Set this to `cpu` or `gpu` to ask for that backend (the plugin's `ClothBackend`).
const BACKEND_ENV: &str = "CLOTH_EXAMPLE_BACKEND";

/// The app every example starts from: a window, the cloth plugins, the panel when the `egui`
/// feature is on, and the shared scene.
pub fn example_app(title: &str) -> App {
    let mut app = App::new();
    app.add_plugins((
        DefaultPlugins
            .set(WindowPlugin { primary_window: Some(Window { title: title.into(), ..default() }), ..default() }),
        bevy_obj::ObjPlugin,
        BvhClothPlugins::default(),
    ))
    .insert_resource(ClearColor(Color::srgb(0.62, 0.72, 0.82)))
    .add_systems(Startup, spawn_stage)
    .add_systems(Update, (orbit_camera, keys, screenshot_and_exit));
    #[cfg(feature = "egui")]
    app.add_plugins(ClothPanelPlugin);
    match std::env::var(BACKEND_ENV).as_deref() {
        Ok("cpu") => _ = app.insert_resource(ClothBackend::Cpu),
        Ok("gpu") => _ = app.insert_resource(ClothBackend::Gpu),
        Ok(other) => warn!("{BACKEND_ENV}={other}: not cpu or gpu; the plugin picks"),
        Err(_) => {}
    }
    app
}

/// Whether the example runs to take its screenshot (`CLOTH_EXAMPLE_SCREENSHOT` is set): an
/// example that waits on the user acts on its own then.
#[allow(dead_code)] // used by `grab`
pub fn taking_screenshot() -> bool {
    std::env::var_os(SCREENSHOT_ENV).is_some()
}

/// The orbiting camera's state: drag with the left mouse button, scroll to zoom.
#[derive(Component)]
pub struct Orbit {
    pub target: Vec3,
    pub distance: f32,
    pub yaw: f32,
    pub pitch: f32,
}

impl Orbit {
    fn transform(&self) -> Transform {
        let rotation = Quat::from_euler(EulerRot::YXZ, self.yaw, -self.pitch, 0.0);
        Transform::from_translation(self.target + rotation * Vec3::new(0.0, 0.0, self.distance))
            .looking_at(self.target, Vec3::Y)
    }
}

/// The camera, looking at `target` from `distance`.
pub fn spawn_camera(commands: &mut Commands, target: Vec3, distance: f32) {
    let orbit = Orbit { target, distance, yaw: 0.5, pitch: 0.35 };
    commands.spawn((Camera3d::default(), orbit.transform(), orbit));
}

fn spawn_stage(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) {
    commands.spawn((
        DirectionalLight { illuminance: 8_000.0, shadow_maps_enabled: true, ..default() },
        Transform::from_xyz(3.0, 6.0, 2.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    commands.spawn((
        Mesh3d(meshes.add(Plane3d::default().mesh().size(8.0, 8.0))),
        MeshMaterial3d(materials.add(Color::srgb(0.35, 0.38, 0.35))),
        // A cloth that slides off a model comes to rest on the floor.
        PrimitiveCollider::ground(),
    ));
}

/// A two-sided cloth material.
pub fn cloth_material(materials: &mut Assets<StandardMaterial>, color: Color) -> MeshMaterial3d<StandardMaterial> {
    MeshMaterial3d(materials.add(StandardMaterial {
        base_color: color,
        perceptual_roughness: 0.8,
        double_sided: true,
        cull_mode: None,
        ..default()
    }))
}

fn orbit_camera(
    buttons: Res<ButtonInput<MouseButton>>,
    motion: Res<AccumulatedMouseMotion>,
    scroll: Res<AccumulatedMouseScroll>,
    mut cameras: Query<(&mut Orbit, &mut Transform)>,
) {
    for (mut orbit, mut transform) in &mut cameras {
        if buttons.pressed(MouseButton::Left) {
            orbit.yaw -= motion.delta.x * 0.005;
            orbit.pitch = (orbit.pitch + motion.delta.y * 0.005).clamp(-0.2, 1.5);
        }
        orbit.distance = (orbit.distance * (1.0 - scroll.delta.y * 0.1)).clamp(0.5, 20.0);
        *transform = orbit.transform();
    }
}

/// R resets the cloths, Space pauses, B toggles the BVH view, 1/3/5 set every collider's `n`.
fn keys(
    input: Res<ButtonInput<KeyCode>>,
    mut settings: ResMut<ClothSettings>,
    mut colliders: Query<&mut AutoCollider>,
    mut resets: MessageWriter<ResetCloth>,
) {
    if input.just_pressed(KeyCode::KeyR) {
        resets.write(ResetCloth::All);
    }
    if input.just_pressed(KeyCode::Space) {
        settings.paused = !settings.paused;
    }
    if input.just_pressed(KeyCode::KeyB) {
        settings.debug_view = !settings.debug_view;
    }
    for (key, n) in [(KeyCode::Digit1, 1), (KeyCode::Digit3, 3), (KeyCode::Digit5, 5)] {
        if input.just_pressed(key) {
            for mut collider in &mut colliders {
                collider.resolution = n;
            }
            resets.write(ResetCloth::All);
        }
    }
}

/// With `CLOTH_EXAMPLE_SCREENSHOT=path.png`, saves a screenshot after five seconds of
/// simulation and exits once it is written.
fn screenshot_and_exit(
    mut commands: Commands,
    clock: Res<ClothClock>,
    mut state: Local<Option<u32>>,
    mut exit: MessageWriter<AppExit>,
) {
    let Ok(path) = std::env::var(SCREENSHOT_ENV) else { return };
    match *state {
        None if clock.total_ticks >= 300 => {
            commands.spawn(Screenshot::primary_window()).observe(save_to_disk(path));
            *state = Some(0);
        }
        Some(frames) if frames > 30 => {
            exit.write(AppExit::Success);
        }
        Some(frames) => *state = Some(frames + 1),
        None => {}
    }
}

/// The paper's Table VI/VIII scene: a 64 x 64 cloth dropped onto `model` (an OBJ under
/// `assets/`), which gets an `AutoCollider` at the paper's n = 5. The cloth falls from 0.3 m
/// above `top`, centred over `(x, z)`: both models are normalised to a 1 m box standing on the
/// ground, and their highest parts (the bunny's back, the dragon's back) lie off the box's
/// centre, so the drop point is where the model's upper quarter is.
#[allow(dead_code)] // used by `bunny` and `dragon`, not by `hanging_cloth`
pub fn model_drop_scene(
    model: &'static str,
    drop_over: Vec2,
    top: f32,
) -> impl Fn(Commands, Res<AssetServer>, ResMut<Assets<StandardMaterial>>) {
    move |mut commands, assets, mut materials| {
        spawn_camera(&mut commands, Vec3::new(0.0, 0.45 * top, 0.0), 3.0);
        commands.spawn((
            Mesh3d(assets.load(model)),
            MeshMaterial3d(materials.add(StandardMaterial {
                base_color: Color::srgb(0.9, 0.88, 0.82),
                perceptual_roughness: 0.6,
                ..default()
            })),
            AutoCollider::new(5),
        ));
        commands.spawn((
            Cloth {
                params: ClothParams { damping: 1.0, ..default() },
                ..Cloth::grid(Vec2::splat(1.4), UVec2::splat(64))
            },
            cloth_material(&mut materials, Color::srgb(0.2, 0.35, 0.75)),
            Transform::from_xyz(drop_over.x, top + 0.3, drop_over.y),
        ));
    }
}
