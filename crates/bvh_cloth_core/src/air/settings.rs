//! What a user sets: how a cloth catches the air ([`Aerodynamics`]), the wind ([`Wind`])
//! and local sources of air ([`WindSource`]), each checked against the model's limits.

use glam::Vec3;

#[cfg(feature = "bevy_reflect")]
use bevy_reflect::std_traits::ReflectDefault;

use super::noise::{NOISE_TIME_PERIOD, value_noise_1d};
use super::source::{AirSource, SOURCE_BLAST, SOURCE_FAN};
use crate::cloth::error::ClothError;

/// The fastest wind accepted, in m/s: above the strongest gusts measured on Earth (113 m/s,
/// Barrow Island, 1996). Faster air is compressible, and the model no longer holds.
pub const MAX_WIND_SPEED: f32 = 150.0;

/// The largest drag or lift coefficient accepted. A flat plate square to the flow has a drag
/// coefficient of about 1.2; ten times that is no fabric.
pub const MAX_COEFFICIENT: f32 = 10.0;

/// The densest air accepted, in kg/m³ (sea-level air is 1.225).
pub const MAX_AIR_DENSITY: f32 = 10.0;

/// How a cloth catches the air: its drag and lift coefficients.
///
/// The default is no aerodynamics at all, the paper's model: the cloth moves as if in vacuum
/// (its `damping` aside), and wind does not touch it. [`Self::FABRIC`] is a woven fabric.
///
/// Why not `FABRIC` by default: drag acts in still air too, so it would change how every cloth
/// falls (a free cloth would no longer drop as gravity and damping say), and it costs a pass
/// over the triangles each substep (about 15 % of a tick on the GPU; BENCHMARKS.md, wind). A
/// cloth in a wind it cannot feel is named instead: the Bevy plugin sends
/// `ClothMessage::WindNotFelt` once for it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "bevy_reflect", derive(bevy_reflect::Reflect), reflect(Default, Debug, PartialEq))]
pub struct Aerodynamics {
    /// Drag coefficient `C_d`, 0 to [`MAX_COEFFICIENT`].
    pub drag: f32,
    /// Lift coefficient `C_l`, 0 to [`MAX_COEFFICIENT`].
    pub lift: f32,
}

impl Aerodynamics {
    /// No drag and no lift: the cloth ignores the air.
    pub const NONE: Self = Self { drag: 0.0, lift: 0.0 };

    /// A woven fabric: the drag of a flat plate square to the flow (about 1.2, Hoerner,
    /// "Fluid-Dynamic Drag", 1965), and a lift coefficient that gives a plate at 45° a lift
    /// about half its drag.
    pub const FABRIC: Self = Self { drag: 1.2, lift: 0.8 };

    /// Whether the cloth feels the air at all.
    pub fn is_active(&self) -> bool {
        self.drag > 0.0 || self.lift > 0.0
    }

    /// Checks both coefficients.
    pub fn validate(&self) -> Result<(), ClothError> {
        in_range("aerodynamics.drag", self.drag, 0.0, MAX_COEFFICIENT)?;
        in_range("aerodynamics.lift", self.lift, 0.0, MAX_COEFFICIENT)
    }
}

/// The air around a cloth: a steady velocity, gusts that raise and lower it over time, and
/// turbulence, a smooth random field in space and time.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "bevy_reflect", derive(bevy_reflect::Reflect), reflect(Default, Debug, PartialEq))]
pub struct Wind {
    /// The mean wind in m/s, at most [`MAX_WIND_SPEED`].
    pub velocity: Vec3,
    /// Air density in kg/m³ (sea level: 1.225).
    pub density: f32,
    /// How far gusts raise and lower the mean wind, as a fraction of it: 0 is steady, 0.5 swings
    /// between half and one and a half times the mean. 0 to 1.
    pub gust_strength: f32,
    /// Seconds between one gust and the next, roughly; above 0.
    pub gust_period: f32,
    /// Turbulence in m/s: each component of the random field is within this of the mean.
    /// 0 to [`MAX_WIND_SPEED`].
    pub turbulence: f32,
    /// Size of the turbulence's eddies in metres; above 0.
    pub turbulence_scale: f32,
    /// Seconds over which the turbulence at a point changes; above 0.
    pub turbulence_period: f32,
    /// Picks the noise: two winds that differ only in their seed blow alike but not in step.
    pub seed: u32,
}

impl Default for Wind {
    fn default() -> Self {
        Self::STILL
    }
}

impl Wind {
    /// Still air at sea level.
    pub const STILL: Self = Self {
        velocity: Vec3::ZERO,
        density: 1.225,
        gust_strength: 0.0,
        gust_period: 4.0,
        turbulence: 0.0,
        turbulence_scale: 2.0,
        turbulence_period: 1.0,
        seed: 0,
    };

    /// A steady wind of `velocity` m/s, with no gusts and no turbulence.
    pub fn steady(velocity: Vec3) -> Self {
        Self { velocity, ..Self::STILL }
    }

    /// A wind of mean `velocity` m/s that gusts by 40% every few seconds, with turbulence of a
    /// fifth of its speed in eddies of 2 m.
    pub fn gusty(velocity: Vec3) -> Self {
        Self { velocity, gust_strength: 0.4, gust_period: 3.0, turbulence: 0.2 * velocity.length(), ..Self::STILL }
    }

    /// The same wind with gusts that raise and lower it by `strength` (a fraction of the mean, 0
    /// to 1) every `period` seconds or so.
    pub fn with_gusts(mut self, strength: f32, period: f32) -> Self {
        (self.gust_strength, self.gust_period) = (strength, period);
        self
    }

    /// The same wind with turbulence of `speed` m/s in eddies of `scale` metres.
    pub fn with_turbulence(mut self, speed: f32, scale: f32) -> Self {
        (self.turbulence, self.turbulence_scale) = (speed, scale);
        self
    }

    /// The same wind in air of `density` kg/m³ (sea level: 1.225).
    pub fn with_density(mut self, density: f32) -> Self {
        self.density = density;
        self
    }

    /// The same wind with another noise: `seed` picks it.
    pub fn with_seed(mut self, seed: u32) -> Self {
        self.seed = seed;
        self
    }

    /// Checks every field.
    pub fn validate(&self) -> Result<(), ClothError> {
        if !self.velocity.is_finite() {
            return Err(ClothError::NotFinite { field: "wind.velocity" });
        }
        in_range("wind.velocity", self.velocity.length(), 0.0, MAX_WIND_SPEED)?;
        in_range("wind.density", self.density, 0.0, MAX_AIR_DENSITY)?;
        in_range("wind.gust_strength", self.gust_strength, 0.0, 1.0)?;
        ClothError::check_positive("wind.gust_period", self.gust_period)?;
        in_range("wind.turbulence", self.turbulence, 0.0, MAX_WIND_SPEED)?;
        ClothError::check_positive("wind.turbulence_scale", self.turbulence_scale)?;
        ClothError::check_positive("wind.turbulence_period", self.turbulence_period)
    }

    /// The gust factor and the turbulence's lattice time at `time` seconds: what one tick's
    /// sampling needs of the clock (see [`AirModel::new`](crate::air::AirModel::new)).
    pub fn clock(&self, time: f64) -> [f32; 2] {
        let period = f64::from(NOISE_TIME_PERIOD);
        let gust_time = (time / f64::from(self.gust_period)).rem_euclid(period) as f32;
        let gust = 1.0 + self.gust_strength * value_noise_1d(gust_time, self.seed);
        [gust, (time / f64::from(self.turbulence_period)).rem_euclid(period) as f32]
    }
}

/// A local source of wind. Sources add to the ambient wind of every cloth in reach.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "bevy_reflect", derive(bevy_reflect::Reflect), reflect(Debug, PartialEq))]
pub enum WindSource {
    /// A fan at `origin` blowing along `direction` in a cone of half-angle `spread`: the air
    /// leaves it radially at `speed`, weakening linearly to nothing at `range` metres and
    /// smoothly to nothing at the cone's edge.
    Fan {
        /// Where the air comes from.
        origin: Vec3,
        /// The cone's axis (any length above zero).
        direction: Vec3,
        /// Speed on the axis at the origin in m/s, at most [`MAX_WIND_SPEED`]; a negative speed
        /// sucks.
        speed: f32,
        /// Reach in metres, above 0.
        range: f32,
        /// The cone's half-angle in radians, in `(0, π]`.
        spread: f32,
    },
    /// Air pushed out of `center` in every direction: `speed` at the centre, weakening linearly
    /// to nothing at `radius` metres (an explosion's blast, a helicopter's downwash seen from
    /// below).
    Blast {
        /// Where the air comes from.
        center: Vec3,
        /// Speed at the centre in m/s, at most [`MAX_WIND_SPEED`]; a negative speed sucks.
        speed: f32,
        /// Reach in metres, above 0.
        radius: f32,
    },
}

impl WindSource {
    /// Checks every field.
    pub fn validate(&self) -> Result<(), ClothError> {
        match *self {
            Self::Fan { origin, direction, speed, range, spread } => {
                if !origin.is_finite() {
                    return Err(ClothError::NotFinite { field: "fan.origin" });
                }
                if !(direction.is_finite() && direction.length_squared() > 0.0) {
                    return Err(ClothError::NotFinite { field: "fan.direction" });
                }
                in_range("fan.speed", speed, -MAX_WIND_SPEED, MAX_WIND_SPEED)?;
                ClothError::check_positive("fan.range", range)?;
                in_range("fan.spread", spread, f32::MIN_POSITIVE, core::f32::consts::PI)
            }
            Self::Blast { center, speed, radius } => {
                if !center.is_finite() {
                    return Err(ClothError::NotFinite { field: "blast.center" });
                }
                in_range("blast.speed", speed, -MAX_WIND_SPEED, MAX_WIND_SPEED)?;
                ClothError::check_positive("blast.radius", radius)
            }
        }
    }

    /// The source as the samplers read it: three rows of four numbers (see [`AirSource`]).
    pub fn prepare(&self) -> AirSource {
        match *self {
            Self::Fan { origin, direction, speed, range, spread } => AirSource {
                origin: origin.extend(SOURCE_FAN as f32).to_array(),
                axis: direction.normalize_or_zero().extend(speed).to_array(),
                reach: [range, spread.cos(), 0.0, 0.0],
            },
            Self::Blast { center, speed, radius } => AirSource {
                origin: center.extend(SOURCE_BLAST as f32).to_array(),
                axis: [0.0, 0.0, 0.0, speed],
                reach: [radius, -1.0, 0.0, 0.0],
            },
        }
    }
}

pub(super) fn in_range(field: &'static str, value: f32, min: f32, max: f32) -> Result<(), ClothError> {
    if value >= min && value <= max { Ok(()) } else { Err(ClothError::OutOfRange { field, value, min, max }) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_builders_set_what_they_name() {
        let v = Vec3::new(8.0, 0.0, 0.0);
        assert_eq!(Wind::steady(v).with_gusts(0.4, 3.0).with_turbulence(1.6, 2.0), Wind::gusty(v));
        let wind = Wind::STILL.with_density(1.0).with_seed(7);
        assert_eq!((wind.density, wind.seed), (1.0, 7));
        assert!(Wind::steady(v).with_gusts(2.0, 3.0).validate().is_err(), "a gust strength above 1 is refused");
    }
}
