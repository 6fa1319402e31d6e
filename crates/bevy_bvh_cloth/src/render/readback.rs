//! Reading where a GPU cloth is, for gameplay: opt in with [`ClothReadback`].

use bevy::prelude::*;
use bvh_cloth_gpu::layout::{GpuParticle, load_gpu_particles};

use crate::clock::ClothClock;
use crate::cloth::simulation::ClothSimulation;

/// Put this on a [`Cloth`](crate::Cloth) entity to have its state read back from the GPU, so
/// that [`ClothSimulation::sim`] gives its live positions and velocities on the GPU backend
/// too.
///
/// The read never stalls a frame: each frame's state is copied on the GPU and mapped after the
/// submit, and it reaches the main world at the first extract after the map completes: with
/// Bevy's pipelined rendering two or three frames after the frame that ran it. [`ClothReadback::ticks_late`] says how late the state in [`ClothSimulation`] is. A
/// copy costs the cloth's particle buffer (32 bytes per particle) per frame, so read back only
/// the cloths gameplay looks at. On the CPU backend the state is always live and this does
/// nothing.
///
/// ```
/// # use bevy::prelude::*;
/// # use bevy_bvh_cloth::prelude::*;
/// # fn setup(mut commands: Commands) {
/// // A flag whose tip gameplay follows, on either backend.
/// commands.spawn((
///     Cloth::grid(Vec2::new(1.0, 0.6), UVec2::new(24, 16)).with_pins(ClothPins::FirstRow),
///     ClothReadback::default(),
/// ));
/// # }
/// ```
#[derive(Component, Clone, Debug, Default, PartialEq, Reflect)]
#[reflect(Component, Default, Debug)]
pub struct ClothReadback {
    /// How many ticks the state in [`ClothSimulation`] is behind the one drawn this frame
    /// (about one frame's worth per frame of delay); `None` until the first read arrives.
    pub ticks_late: Option<u64>,
    /// How many ticks the state in [`ClothSimulation`] has run since the cloth was built or
    /// reset. The GPU starts a cloth once its kernels are compiled (a few frames after start-up;
    /// the cloth waits at rest until then), so this can be less than the clock's ticks.
    pub ticks_run: Option<u64>,
}

/// A cloth's particles read back from the GPU, sent from the render world to the main world.
#[derive(Message, Clone, Debug)]
pub(crate) struct GpuClothState {
    pub(crate) entity: Entity,
    /// The [`ClothSimulation`] generation read: a state read before a rebuild or reset is stale.
    pub(crate) generation: u64,
    /// [`ClothClock::total_ticks`] of the frame that copied the state.
    pub(crate) ticks: u64,
    /// Ticks the state has run since the cloth was built or reset.
    pub(crate) ticks_run: u64,
    pub(crate) particles: Vec<GpuParticle>,
}

/// Main world: loads each state that arrived into its cloth's simulation (unless the cloth was
/// rebuilt or reset since), and counts how late each read-back cloth is.
pub(crate) fn apply_gpu_readbacks(
    mut states: MessageReader<GpuClothState>,
    mut cloths: Query<(&mut ClothSimulation, &mut ClothReadback)>,
    clock: Res<ClothClock>,
) {
    for (_, mut readback) in &mut cloths {
        if let Some(late) = &mut readback.ticks_late {
            *late += u64::from(clock.ticks);
        }
    }
    for state in states.read() {
        let Ok((mut sim, mut readback)) = cloths.get_mut(state.entity) else { continue };
        if sim.generation != state.generation {
            continue;
        }
        load_gpu_particles(&mut sim.sim, &state.particles);
        readback.ticks_late = Some(clock.total_ticks.saturating_sub(state.ticks));
        readback.ticks_run = Some(state.ticks_run);
    }
}
