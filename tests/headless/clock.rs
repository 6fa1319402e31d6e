//! The fixed-rate clock ([`ClothClock`]) on its own: whole ticks at any frame rate, a whole step
//! per run in lockstep, a capped hitch, and pause.

use bevy::prelude::*;
use bevy_bvh_cloth::prelude::*;

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
