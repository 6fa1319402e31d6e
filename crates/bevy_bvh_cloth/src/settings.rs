//! Global simulation settings: the fixed tick rate, pause and the debug view.

use bevy::prelude::*;

/// Settings shared by every cloth. Edit the resource at any time; changes apply next frame.
///
/// ```
/// # use bevy::prelude::*;
/// # use bevy_bvh_cloth::prelude::*;
/// // A game that steps its cloth at 120 Hz, and pauses it with the game.
/// let settings = ClothSettings { tick_rate: 120.0, ..default() };
/// App::new().insert_resource(settings);
///
/// fn pause(mut settings: ResMut<ClothSettings>, keys: Res<ButtonInput<KeyCode>>) {
///     if keys.just_pressed(KeyCode::Escape) {
///         settings.paused = !settings.paused;
///     }
/// }
/// ```
#[derive(Resource, Clone, Debug, PartialEq, Reflect)]
#[reflect(Resource, Default, Debug)]
pub struct ClothSettings {
    /// Simulation ticks per second. Each tick runs `looper` substeps of every cloth, so the
    /// cloth behaves the same at 30 and at 144 frames per second. Under a fixed-timestep
    /// schedule each run of it is a whole number of ticks, this rate rounded to that step
    /// (see [`ClothClock`](crate::ClothClock)).
    pub tick_rate: f32,
    /// Most ticks run in one frame. After a long hitch the simulation drops time instead of
    /// trying to catch up (which would make the next frame slower still).
    pub max_ticks_per_frame: u32,
    /// While `true`, no tick runs: cloths freeze where they are.
    pub paused: bool,
    /// Draw every collider's leaf spheres and inner boxes with gizmos (paper Table VI).
    pub debug_view: bool,
    /// Longest a new cloth waits, in seconds, for [`AutoCollider`](crate::AutoCollider)s still
    /// being built before it starts without them (a warning names them). Such a collider may
    /// never finish: a mesh-less root whose scene never spawns waits forever.
    pub collider_wait: f32,
    /// How long, in seconds, a [`ClothHierarchy`](crate::ClothHierarchy) root waits for its
    /// scene to spawn a mesh before it says so once
    /// ([`ClothMessage::SceneNotSpawned`](crate::ClothMessage::SceneNotSpawned)); it keeps
    /// waiting, and a scene that arrives later is dressed as any other.
    pub scene_wait: f32,
}

impl Default for ClothSettings {
    fn default() -> Self {
        Self {
            tick_rate: 60.0,
            max_ticks_per_frame: 4,
            paused: false,
            debug_view: false,
            collider_wait: 10.0,
            scene_wait: 10.0,
        }
    }
}
