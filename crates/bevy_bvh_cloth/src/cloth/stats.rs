//! Live figures of the simulation, for panels and overlays.

use core::time::Duration;

use bevy::prelude::*;

use crate::backend::ActiveClothBackend;
use crate::clock::ClothClock;
use crate::cloth::simulation::ClothSimulation;
use crate::colliders::auto::ClothCollider;

/// What the simulation did in the last frame.
///
/// ```
/// # use bevy::prelude::*;
/// # use bevy_bvh_cloth::prelude::*;
/// // The cloth's cost per tick, for a game's performance overlay.
/// fn cloth_cost(stats: Res<ClothStats>) -> Option<f64> {
///     match stats.gpu_time {
///         Some((time, ticks)) => Some(time.as_secs_f64() * 1e3 / f64::from(ticks.max(1))),
///         None if stats.ticks > 0 => Some(stats.step_time.as_secs_f64() * 1e3 / f64::from(stats.ticks)),
///         None => None,
///     }
/// }
/// ```
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
    /// Wall time the CPU backend took in the last frame. Zero on the GPU backend: see
    /// [`Self::gpu_time`].
    pub step_time: Duration,
    /// On the GPU backend, the GPU time of every cloth's ticks in one recent frame, and how many
    /// ticks that frame ran: measured with timestamp queries around the batch's compute pass and
    /// read back without stalling, so it arrives two or three frames late, and frames in
    /// between are not measured. `None` on the CPU backend, until the first measure arrives, and
    /// on a device without timestamp queries (WebGL2, some mobile GPUs).
    pub gpu_time: Option<(Duration, u32)>,
    /// The backend that ran it.
    pub backend: &'static str,
}

pub(crate) fn update_stats(
    active: Res<ActiveClothBackend>,
    clock: Res<ClothClock>,
    cloths: Query<&ClothSimulation>,
    colliders: Query<&ClothCollider>,
    mut stats: ResMut<ClothStats>,
) {
    let step_time = if *active == ActiveClothBackend::Cpu { stats.step_time } else { Duration::ZERO };
    let gpu_time = if *active == ActiveClothBackend::Gpu { stats.gpu_time } else { None };
    *stats = ClothStats {
        cloths: cloths.iter().count(),
        particles: cloths.iter().map(|c| c.sim().len()).sum(),
        colliders: colliders.iter().count(),
        spheres: colliders.iter().map(|c| c.collider().sphere_count()).sum(),
        ticks: clock.ticks,
        step_time,
        gpu_time,
        backend: active.name(),
    };
}
