//! Grab the cloth: hold the right mouse button over a hanging sheet to take the particle under
//! the cursor and drag it about; let go and it drops. Keys 1 and 2 let go of the sheet's top
//! corners, or catch them again, while it moves: pins and anchors change on the running cloth.
//! The grip is an anchor on a hand entity that follows the cursor at the grabbed depth.
//!
//! `cargo run --release -p bevy_bvh_cloth --features egui --example grab`
//!
//! Right drag grabs, left drag orbits, scroll zooms, 1 and 2 toggle the corners, R resets.

mod common;

use bevy::prelude::*;
use bevy::window::PrimaryWindow;
use bevy_bvh_cloth::prelude::*;

/// Particles across the sheet.
const SIDE: u32 = 32;
/// The top corners, which keys 1 and 2 let go of and catch again.
const CORNERS: [u32; 2] = [0, SIDE - 1];
/// How near the cursor's ray a particle must pass to be taken, in metres.
const REACH: f32 = 0.08;

fn main() {
    common::example_app("bevy_bvh_cloth: grab")
        .add_systems(Startup, setup)
        .add_systems(Update, (point.pipe(grab), corners))
        .run();
}

/// What the hand is asked to do this frame: the ray it reaches along, and whether it takes,
/// holds or lets go.
#[derive(Default)]
struct Pointer {
    ray: Option<Ray3d>,
    take: bool,
    hold: bool,
    release: bool,
}

/// The right mouse button and the cursor; when the example runs for its screenshot
/// (`CLOTH_EXAMPLE_SCREENSHOT`), a scripted hand instead: after 2 s it takes the middle of the
/// sheet's bottom edge and draws it up and aside over the next 2 s.
fn point(
    buttons: Res<ButtonInput<MouseButton>>,
    window: Single<&Window, With<PrimaryWindow>>,
    camera: Single<(&Camera, &GlobalTransform), Without<Hand>>,
    clock: Res<ClothClock>,
    cloths: Query<&ClothSimulation>,
    mut scripted: Local<Option<Vec3>>,
) -> Pointer {
    let (camera, view) = *camera;
    if !common::taking_screenshot() {
        let ray = window.cursor_position().and_then(|cursor| camera.viewport_to_world(view, cursor).ok());
        return Pointer {
            ray,
            take: buttons.just_pressed(MouseButton::Right),
            hold: buttons.pressed(MouseButton::Right),
            release: buttons.just_released(MouseButton::Right),
        };
    }
    const TAKE: u64 = 120;
    let ticks = clock.total_ticks;
    let towards = |target: Vec3| Some(Ray3d::new(view.translation(), Dir3::new(target - view.translation()).ok()?));
    match *scripted {
        None if ticks >= TAKE => {
            let Some(cloth) = cloths.iter().next() else { return Pointer::default() };
            let bottom_middle = cloth.sim().position((SIDE * (SIDE - 1) + SIDE / 2) as usize);
            *scripted = Some(bottom_middle);
            Pointer { ray: towards(bottom_middle), take: true, hold: true, release: false }
        }
        Some(start) => {
            let t = ((ticks - TAKE) as f32 / 120.0).min(1.0);
            Pointer { ray: towards(start + t * Vec3::new(0.4, 0.4, 0.15)), take: false, hold: true, release: false }
        }
        None => Pointer::default(),
    }
}

/// The entity that holds a grabbed particle: it follows the cursor.
#[derive(Component)]
struct Hand;

/// The hand as the grab moves it.
type HandParts = (Entity, &'static mut Transform, &'static mut GlobalTransform, &'static mut Visibility);

fn setup(mut commands: Commands, mut meshes: ResMut<Assets<Mesh>>, mut materials: ResMut<Assets<StandardMaterial>>) {
    common::spawn_camera(&mut commands, Vec3::new(0.0, 1.0, 0.0), 2.8);
    // A 1 m sheet hanging from its top corners, upright, read back so that the cursor can find
    // its particles on the GPU backend too.
    commands.spawn((
        Cloth::grid(Vec2::ONE, UVec2::splat(SIDE))
            .with_pins(ClothPins::Indices(CORNERS.to_vec()))
            .with_params(ClothParams { damping: 1.0, ..default() }),
        ClothReadback::default(),
        common::cloth_material(&mut materials, Color::srgb(0.75, 0.25, 0.3)),
        Transform::from_xyz(0.0, 1.5, 0.0).with_rotation(Quat::from_rotation_x(core::f32::consts::FRAC_PI_2)),
    ));
    commands.spawn((
        Hand,
        Mesh3d(meshes.add(Sphere::new(0.02))),
        MeshMaterial3d(materials.add(Color::srgb(0.95, 0.85, 0.3))),
        Transform::default(),
        Visibility::Hidden,
    ));
}

/// Takes the particle nearest the pointer's ray when it takes, moves the hand along the ray
/// while it holds, and lets go on release.
fn grab(
    pointer: In<Pointer>,
    mut cloths: Query<(Entity, &mut Cloth, &ClothSimulation, &GlobalTransform)>,
    hand: Single<HandParts, (With<Hand>, Without<Cloth>)>,
    // The cloth the hand holds, and how far along the cursor's ray it was taken.
    mut held: Local<Option<(Entity, f32)>>,
) {
    let (hand, mut transform, mut global, mut visibility) = hand.into_inner();
    if pointer.release {
        if let Some((cloth, _)) = held.take()
            && let Ok((_, mut cloth, _, _)) = cloths.get_mut(cloth)
        {
            cloth.anchors.retain(|anchor| anchor.target != hand);
        }
        *visibility = Visibility::Hidden;
        return;
    }
    let Some(ray) = pointer.ray else { return };
    if let Some((_, depth)) = *held {
        if pointer.hold {
            transform.translation = ray.origin + ray.direction * depth;
        }
        return;
    }
    if !pointer.take {
        return;
    }
    // The particle nearest the ray, within reach, over every cloth.
    let mut best: Option<(Entity, u32, Vec3, f32, f32)> = None;
    for (entity, _, state, _) in &cloths {
        for (i, p) in state.sim().positions().into_iter().enumerate() {
            let along = (p - ray.origin).dot(*ray.direction);
            let off = p.distance(ray.origin + ray.direction * along);
            if along > 0.0 && off < REACH && best.is_none_or(|b| off < b.4) {
                best = Some((entity, i as u32, p, along, off));
            }
        }
    }
    let Some((entity, particle, at, depth, _)) = best else { return };
    let Ok((_, mut cloth, state, cloth_transform)) = cloths.get_mut(entity) else { return };
    // An anchor binds its particle's rest place under the cloth to where its target is now and
    // adds its offset: the hand is put at the particle, in this frame's transform and global
    // transform both, and the offset takes the rest place to where the particle is.
    let (_, rotation, translation) = cloth_transform.to_scale_rotation_translation();
    let rest = translation + rotation * state.sim().topology().rest_positions()[particle as usize];
    *transform = Transform::from_translation(at);
    *global = GlobalTransform::from(*transform);
    *visibility = Visibility::Visible;
    cloth.anchors.push(ClothAnchor::new(ClothPins::Indices(vec![particle]), hand).with_offset(at - rest));
    *held = Some((entity, depth));
}

/// Keys 1 and 2 let go of the top corners, or catch them again at their place under the cloth.
fn corners(keys: Res<ButtonInput<KeyCode>>, mut cloths: Query<&mut Cloth>) {
    for (key, corner) in [(KeyCode::Digit1, CORNERS[0]), (KeyCode::Digit2, CORNERS[1])] {
        if !keys.just_pressed(key) {
            continue;
        }
        for mut cloth in &mut cloths {
            let ClothPins::Indices(pins) = &mut cloth.pins else { continue };
            match pins.iter().position(|&p| p == corner) {
                Some(at) => _ = pins.remove(at),
                None => pins.push(corner),
            }
        }
    }
}
