//! Wind: the ambient wind every cloth is in ([`AmbientWind`]), a cloth's own ([`LocalWind`]),
//! and local sources that follow their entity ([`WindFan`], [`WindBlast`]). Only a cloth whose
//! [`ClothParams::aerodynamics`](crate::ClothParams) has drag or lift feels any of them.

use bevy::ecs::entity::EntityHashSet;
use bevy::ecs::schedule::{InternedScheduleLabel, ScheduleLabel};
use bevy::prelude::*;
use bvh_cloth_core::{ClothError, Wind, WindSource};

use crate::clock::ClothClock;
use crate::cloth::simulation::{ClothSimulation, plan_anchors};
use crate::messages::ClothMessage;
use crate::schedule::ClothSystems;

/// The wind: every cloth's wind and the sources gathered each frame in [`ClothSystems::Step`],
/// before the cloths are stepped.
#[derive(Debug, Clone)]
pub struct WindPlugin {
    schedule: InternedScheduleLabel,
}

impl WindPlugin {
    /// The wind systems in `schedule`.
    pub fn new(schedule: impl ScheduleLabel) -> Self {
        Self { schedule: schedule.intern() }
    }
}

impl Plugin for WindPlugin {
    fn build(&self, app: &mut App) {
        app.register_type::<AmbientWind>()
            .register_type::<LocalWind>()
            .register_type::<WindFan>()
            .register_type::<WindBlast>()
            .init_resource::<AmbientWind>()
            .init_resource::<WindSources>()
            .add_systems(
                self.schedule,
                (gather_wind_sources, gather_wind).chain().before(plan_anchors).in_set(ClothSystems::Step),
            );
    }
}

/// The wind every cloth is in, unless it has a [`LocalWind`]: a mean velocity in m/s, gusts and
/// turbulence (see [`Wind`]). Still air by default.
///
/// ```
/// # use bevy::prelude::*;
/// # use bevy_bvh_cloth::prelude::*;
/// # let mut app = App::new();
/// app.insert_resource(AmbientWind(Wind::gusty(Vec3::new(8.0, 0.0, 0.0))));
/// ```
#[derive(Resource, Clone, Copy, Debug, Default, PartialEq, Reflect)]
#[reflect(Resource, Default, Debug, PartialEq)]
pub struct AmbientWind(pub Wind);

/// A cloth's own wind, in place of the [`AmbientWind`] (a curtain indoors, a banner in a
/// draught). [`WindFan`]s and [`WindBlast`]s still reach it.
#[derive(Component, Clone, Copy, Debug, Default, PartialEq, Reflect)]
#[reflect(Component, Default, Debug, PartialEq)]
pub struct LocalWind(pub Wind);

/// A fan at its entity's position, blowing along the entity's forward (`-Z`) in a cone: the
/// air leaves it at `speed`, weakening linearly to nothing at `range` and smoothly to nothing
/// at the cone's edge.
#[derive(Component, Clone, Copy, Debug, PartialEq, Reflect)]
#[reflect(Component, Default, Debug, PartialEq)]
#[require(Transform)]
pub struct WindFan {
    /// Speed on the axis at the fan, in m/s; a negative speed sucks.
    pub speed: f32,
    /// Reach in metres.
    pub range: f32,
    /// The cone's half-angle in radians, up to π.
    pub spread: f32,
}

impl Default for WindFan {
    fn default() -> Self {
        Self { speed: 10.0, range: 5.0, spread: 0.5 }
    }
}

impl WindFan {
    /// A fan blowing `speed` m/s along its entity's forward, with the default reach (5 m) and
    /// cone (a half-angle of 0.5 rad).
    pub fn new(speed: f32) -> Self {
        Self { speed, ..default() }
    }

    /// The same fan reaching `range` metres.
    pub fn with_range(mut self, range: f32) -> Self {
        self.range = range;
        self
    }

    /// The same fan blowing in a cone of half-angle `spread` radians.
    pub fn with_spread(mut self, spread: f32) -> Self {
        self.spread = spread;
        self
    }
}

/// A blast at its entity's position: air pushed out in every direction at `speed`, weakening
/// linearly to nothing at `radius`, and over `duration` seconds of cloth time to nothing. Spawn
/// one for an explosion; it stops blowing once it has run its course, and the entity is left to
/// the game.
#[derive(Component, Clone, Copy, Debug, PartialEq, Reflect)]
#[reflect(Component, Default, Debug, PartialEq)]
#[require(Transform)]
pub struct WindBlast {
    /// Speed at the centre when the blast starts, in m/s; a negative speed sucks.
    pub speed: f32,
    /// Reach in metres.
    pub radius: f32,
    /// Seconds over which it dies down.
    pub duration: f32,
    /// Seconds of cloth time since it started.
    pub age: f32,
}

impl Default for WindBlast {
    fn default() -> Self {
        Self { speed: 30.0, radius: 4.0, duration: 0.5, age: 0.0 }
    }
}

impl WindBlast {
    /// A blast of `speed` m/s reaching `radius` metres, dying down over `duration` seconds.
    pub fn new(speed: f32, radius: f32, duration: f32) -> Self {
        Self { speed, radius, duration, age: 0.0 }
    }

    /// Checks the fields a [`WindSource::Blast`] does not hold: a positive, finite duration and
    /// a finite age of at least 0. (The speed and the radius are checked with the blast's
    /// position, as a wind source.)
    pub fn validate(&self) -> Result<(), ClothError> {
        ClothError::check_positive("blast.duration", self.duration)?;
        ClothError::check_non_negative("blast.age", self.age)
    }

    /// Its speed at the centre now: `speed` falling linearly to zero over `duration`.
    pub fn current_speed(&self) -> f32 {
        if self.duration > 0.0 { self.speed * (1.0 - self.age / self.duration).max(0.0) } else { 0.0 }
    }
}

/// This frame's wind sources, as [`gather_wind_sources`] found them (the invalid ones left
/// out).
#[derive(Resource, Clone, Debug, Default)]
pub(crate) struct WindSources(pub(crate) Vec<WindSource>);

/// Collects the fans and blasts into [`WindSources`] and ages the blasts by this frame's ticks.
/// A source whose values are invalid is left out, and sent as
/// [`ClothMessage::WindSourceRejected`] when it turns bad (not every frame it stays bad: a
/// blast changes every frame, as it ages, so change detection cannot tell).
pub(crate) fn gather_wind_sources(
    clock: Res<ClothClock>,
    mut sources: ResMut<WindSources>,
    fans: Query<(Entity, &WindFan, &GlobalTransform)>,
    mut blasts: Query<(Entity, &mut WindBlast, &GlobalTransform)>,
    mut messages: MessageWriter<ClothMessage>,
    mut refused: Local<EntityHashSet>,
) {
    sources.0.clear();
    let mut keep = |entity: Entity, checked: Result<WindSource, ClothError>| match checked {
        Ok(source) => {
            refused.remove(&entity);
            sources.0.push(source);
        }
        Err(error) => {
            if refused.insert(entity) {
                error!("Wind source on {entity}: {error}; it does not blow until fixed");
                messages.write(ClothMessage::WindSourceRejected { entity, error });
            }
        }
    };
    for (entity, fan, transform) in &fans {
        let source = WindSource::Fan {
            origin: transform.translation(),
            direction: transform.forward().into(),
            speed: fan.speed,
            range: fan.range,
            spread: fan.spread,
        };
        keep(entity, source.validate().map(|()| source));
    }
    let elapsed = clock.ticks as f32 * clock.tick_seconds;
    for (entity, mut blast, transform) in &mut blasts {
        // A blast that has run its course blows no more, and is not checked again; one whose
        // duration or age is not valid would never blow, so it is refused.
        match blast.validate() {
            Ok(()) if blast.current_speed() == 0.0 => {}
            Ok(()) => {
                let source = WindSource::Blast {
                    center: transform.translation(),
                    speed: blast.current_speed(),
                    radius: blast.radius,
                };
                keep(entity, source.validate().map(|()| source));
            }
            Err(error) => keep(entity, Err(error)),
        }
        if elapsed > 0.0 && blast.age < blast.duration {
            blast.age += elapsed;
        }
    }
    refused.retain(|&entity| fans.contains(entity) || blasts.contains(entity));
}

/// Gives every cloth its wind, this frame's [`WindSources`] and the wind clock of this frame's
/// first tick. A cloth whose wind is invalid keeps its last one, and the error is sent as
/// [`ClothMessage::Rejected`] (once per change).
pub(crate) fn gather_wind(
    clock: Res<ClothClock>,
    ambient: Res<AmbientWind>,
    sources: Res<WindSources>,
    mut cloths: Query<(Entity, &mut ClothSimulation, Option<Ref<LocalWind>>)>,
    mut messages: MessageWriter<ClothMessage>,
    mut unfelt: Local<EntityHashSet>,
) {
    let first_tick = clock.total_ticks.saturating_sub(u64::from(clock.ticks)) as f64 * f64::from(clock.tick_seconds);
    let ambient_changed = ambient.is_changed();
    for (entity, mut state, local) in &mut cloths {
        let changed = ambient_changed || local.as_ref().is_some_and(|l| l.is_changed());
        let wind = local.map_or(ambient.0, |l| l.0);
        // A wind blows where the cloth cannot feel it: said once per cloth, since the cloth
        // still falls as it should and drag is a cost some cloths do without.
        let speed = wind.velocity.length() + wind.turbulence;
        if speed > 0.0 && speed.is_finite() && !state.sim.params().aerodynamics.is_active() && unfelt.insert(entity) {
            warn!(
                "Cloth on {entity}: a {speed:.1} m/s wind blows, but its params.aerodynamics has no drag or lift, so \
                 it does not feel it; set Aerodynamics::FABRIC"
            );
            messages.write(ClothMessage::WindNotFelt { entity, speed });
        }
        state.sim.set_wind_time(first_tick);
        let result = state.sim.set_wind(wind, &sources.0);
        if let Err(error) = result {
            // The sources were checked by `gather_wind_sources`: the cloth's own wind is at
            // fault. Keep the last wind, with this frame's sources.
            let last = *state.sim.wind();
            let _ = state.sim.set_wind(last, &sources.0);
            if changed {
                report(entity, error, &mut messages);
            }
        }
    }
    unfelt.retain(|&entity| cloths.contains(entity));
}

fn report(entity: Entity, error: ClothError, messages: &mut MessageWriter<ClothMessage>) {
    error!("Cloth on {entity}: {error}; keeping its last valid wind");
    messages.write(ClothMessage::Rejected { entity, error });
}
