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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn whole_ticks_at_any_frame_rate() {
        let settings = ClothSettings::default();
        for fps in [30.0f32, 60.0, 144.0] {
            let mut clock = ClothClock::default();
            for _ in 0..(fps as usize * 10) {
                clock.advance(1.0 / fps, &settings);
            }
            // Ten seconds are 600 ticks at 60 Hz whatever the frame rate (one may still be due).
            assert!((599..=600).contains(&clock.total_ticks), "{fps} fps ran {} ticks", clock.total_ticks);
        }
    }

    #[test]
    fn in_lockstep_every_run_advances_its_whole_step() {
        let settings = ClothSettings::default();
        for (hz, per_run) in [(64.0f32, 1), (50.0, 1), (30.0, 2), (20.0, 3), (120.0, 1)] {
            let mut clock = ClothClock { lockstep: true, ..default() };
            for _ in 0..hz as usize {
                clock.advance(1.0 / hz, &settings);
                assert_eq!(clock.ticks, per_run, "at {hz} Hz");
            }
            // One second of runs is one second of cloth, whatever the rate.
            let simulated = clock.total_ticks as f32 * clock.tick_seconds;
            assert!((simulated - 1.0).abs() < 1e-4, "{hz} Hz simulated {simulated} s");
        }
    }

    #[test]
    fn a_hitch_is_capped_and_pause_stops_time() {
        let mut settings = ClothSettings::default();
        let mut clock = ClothClock::default();
        clock.advance(5.0, &settings);
        assert_eq!(clock.ticks, settings.max_ticks_per_frame);
        assert!(clock.accumulated <= clock.tick_seconds);
        settings.paused = true;
        clock.advance(1.0, &settings);
        assert_eq!(clock.ticks, 0);
        settings.paused = false;
        clock.advance(f32::NAN, &settings);
        assert_eq!(clock.ticks, 0);
    }
}
