//! The fixed-rate simulation clock: how many whole ticks this frame runs.

use bevy::prelude::*;

use crate::settings::ClothSettings;

/// The simulation clock, advanced once per run of the cloth's schedule from that schedule's
/// [`Time`] (virtual time in `PostUpdate`, so pausing or slowing `Time<Virtual>` slows the cloth
/// too).
///
/// In `PostUpdate` (the default) it runs whole ticks of `1 / tick_rate` seconds and carries the
/// rest over. In one of Bevy's fixed-timestep schedules (`FixedPostUpdate` and its siblings,
/// where a physics engine steps) it is in [`lockstep`](Self::lockstep): every run of the
/// schedule advances the cloth by exactly that run's step, as a whole number of ticks (the
/// step times [`ClothSettings::tick_rate`], rounded, at least one), so that cloth and physics
/// step one to one at any fixed rate.
#[derive(Resource, Clone, Debug, Default, Reflect)]
#[reflect(Resource, Default, Debug)]
pub struct ClothClock {
    /// Time carried over to the next frame, in seconds (always less than one tick).
    pub accumulated: f32,
    /// Whole ticks to run this frame.
    pub ticks: u32,
    /// Length of one tick in seconds.
    pub tick_seconds: f32,
    /// Ticks run since start-up.
    pub total_ticks: u64,
    /// Each run advances by that run's whole step (see above); set by the plugin when its
    /// schedule is one of Bevy's fixed-timestep schedules.
    pub lockstep: bool,
}

impl ClothClock {
    /// Advances the clock by `delta` seconds and sets [`Self::ticks`].
    pub fn advance(&mut self, delta: f32, settings: &ClothSettings) {
        let rate = settings.tick_rate;
        if settings.paused || !(rate.is_finite() && rate > 0.0) || !(delta.is_finite() && delta >= 0.0) {
            self.ticks = 0;
            return;
        }
        if self.lockstep {
            // The whole step, in as many ticks as the tick rate asks (at least one).
            let ticks = ((delta * rate).round() as u32).clamp(1, settings.max_ticks_per_frame.max(1));
            self.ticks = if delta > 0.0 { ticks } else { 0 };
            self.tick_seconds = if delta > 0.0 { delta / ticks as f32 } else { 1.0 / rate };
            self.accumulated = 0.0;
            self.total_ticks += u64::from(self.ticks);
            return;
        }
        self.tick_seconds = 1.0 / rate;
        self.accumulated += delta;
        let due = (self.accumulated * rate).floor();
        let ticks = (due as u32).min(settings.max_ticks_per_frame);
        self.accumulated -= ticks as f32 * self.tick_seconds;
        // Behind by more than the cap allows: drop the backlog rather than spiral.
        self.accumulated = self.accumulated.clamp(0.0, self.tick_seconds);
        self.ticks = ticks;
        self.total_ticks += u64::from(ticks);
    }

    /// The length of a tick the clock runs, for checks made before it runs one: the last tick's
    /// in lockstep, otherwise `1 / tick_rate`. `None` for a rate that is not positive.
    pub(crate) fn tick_length(&self, settings: &ClothSettings) -> Option<f32> {
        if self.lockstep && self.tick_seconds > 0.0 {
            return Some(self.tick_seconds);
        }
        let rate = settings.tick_rate;
        (rate.is_finite() && rate > 0.0).then(|| 1.0 / rate)
    }
}

pub(crate) fn advance_clock(time: Res<Time>, settings: Res<ClothSettings>, mut clock: ResMut<ClothClock>) {
    clock.advance(time.delta_secs(), &settings);
}
