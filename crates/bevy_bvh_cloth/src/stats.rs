//! Live figures of the simulation, for panels and overlays.

use core::time::Duration;

use bevy::prelude::*;

/// What the simulation did in the last frame. Updated by the backend every frame.
#[derive(Resource, Clone, Debug, Default, Reflect)]
#[reflect(Resource, Default, Debug)]
pub struct ClothStats {
    /// Cloths being simulated.
    pub cloths: usize,
    /// Particles over every cloth.
    pub particles: usize,
    /// Colliders in use.
    pub colliders: usize,
    /// Leaf spheres over every collider.
    pub spheres: usize,
    /// Ticks run in the last frame.
    pub ticks: u32,
    /// Wall time the simulation took in the last frame.
    pub step_time: Duration,
    /// The backend that ran it.
    pub backend: &'static str,
}
