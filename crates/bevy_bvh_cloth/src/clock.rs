//! The fixed-rate simulation clock: how many whole ticks this frame runs.

use bevy::prelude::*;

use crate::settings::ClothSettings;

/// The simulation clock, advanced once per frame from [`Time`] (virtual time, so pausing or
/// slowing `Time<Virtual>` slows the cloth too).
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
}

impl ClothClock {
    /// Advances the clock by `delta` seconds and sets [`Self::ticks`].
    pub fn advance(&mut self, delta: f32, settings: &ClothSettings) {
        let rate = settings.tick_rate;
        if settings.paused || !(rate.is_finite() && rate > 0.0) || !(delta.is_finite() && delta >= 0.0) {
            self.ticks = 0;
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
