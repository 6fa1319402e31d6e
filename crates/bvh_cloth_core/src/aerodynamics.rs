//! Aerodynamics: drag and lift on every triangle of a cloth from its velocity relative to the
//! air, and the air itself: a wind with gusts and turbulence, and local sources (a fan, a
//! blast).
//!
//! ## The force on a triangle
//! A triangle of area `A` and unit normal `n`, whose corners move on average at `v` in air whose
//! velocity averaged over the corners is `w`, meets the relative flow `u = w - v`. With
//! `cos θ = n · û` (θ the angle between the normal and the flow):
//! - drag, along the flow: `½ ρ C_d A |u|² |cos θ| û`. A triangle square to the flow catches
//!   all of it, one edge-on catches none.
//! - lift, across the flow: `½ ρ C_l A |u|² cos θ (n - cos θ û)`, of size
//!   `½ ρ C_l A |u|² cos θ sin θ`: zero square to the flow and edge-on, largest at 45°, and
//!   pushing the triangle away from the side the air strikes.
//!
//! Both are unchanged when the normal flips, so the mesh's winding does not matter. Each corner
//! takes a third of its triangle's force. This split into a drag and a lift coefficient is the
//! one game cloth solvers expose (NvCloth's `setDragCoefficient` and `setLiftCoefficient`).
//!
//! ## How it is stepped
//! The wind is sampled at every particle once per tick, at the tick's start. The forces are
//! evaluated once per substep from the substep's start state and applied as a change of
//! velocity before the integrator runs, `v += h a`: the same splitting for every integrator
//! and on both backends. A particle's change of velocity is capped at its speed relative to the
//! wind, so drag can bring a particle up to the wind's speed but never past it, and a light
//! cloth in a gale stays stable at any substep length.
//!
//! On the CPU the triangles' forces are found four at a time, one triangle per SIMD lane
//! ([`AirModel::triangle_forces`]); on a generated grid four cells of a row are read straight
//! into the lanes, with no gather, and four particles sum their forces at once. A tick's
//! sampling hashes each corner of the noise's lattice round the cloth and blends it in time
//! once, not once per particle in its cells (the noise blends each corner in time first, then
//! in space). All of these give the bits of the one-at-a-time arithmetic that the GPU repeats.
//!
//! ## The wind
//! At a point `p` and time `t`, the air moves at
//! `velocity (1 + gust_strength g(t / gust_period)) + turbulence N(p / turbulence_scale, t / turbulence_period)`
//! plus every source's velocity there. `g` is a value noise in time and `N` a vector value
//! noise in space and time, each component in `[-1, 1]`: lattice values from an integer hash,
//! blended with smoothstep weights, so the same integers give the same values on every device.
//! The time lattice repeats every [`NOISE_TIME_PERIOD`] steps, which keeps the lattice time in
//! `f32` precise however long a game runs, with no seam.

use glam::{BVec4A, Mat4, Vec3, Vec3A, Vec4};
use rayon::prelude::*;

#[cfg(feature = "bevy_reflect")]
use bevy_reflect::std_traits::ReflectDefault;

mod grid_kick;

use crate::error::ClothError;
use crate::topology::ClothTopology;

/// The fastest wind accepted, in m/s: above the strongest gusts measured on Earth (113 m/s,
/// Barrow Island, 1996). Faster air is compressible, and the model no longer holds.
pub const MAX_WIND_SPEED: f32 = 150.0;

/// The largest drag or lift coefficient accepted. A flat plate square to the flow has a drag
/// coefficient of about 1.2; ten times that is no fabric.
pub const MAX_COEFFICIENT: f32 = 10.0;

/// The densest air accepted, in kg/m³ (sea-level air is 1.225).
pub const MAX_AIR_DENSITY: f32 = 10.0;

/// Lattice steps after which the noise's time axis repeats.
pub const NOISE_TIME_PERIOD: u32 = 4096;

/// Particles (or triangles) one rayon task handles at least: below that a pass is not split,
/// since a fork and join costs more than the work it would share (a 64x64 cloth's 7,938
/// triangles are not split).
const MIN_TASK: usize = 8192;

/// How a cloth catches the air: its drag and lift coefficients.
///
/// The default is no aerodynamics at all, the paper's model: the cloth moves as if in vacuum
/// (its `damping` aside), and wind does not touch it. [`Self::FABRIC`] is a woven fabric.
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
    /// sampling needs of the clock (see [`AirModel::new`]).
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

/// [`AirSource`]'s kind (in `origin[3]`) of a fan.
pub const SOURCE_FAN: u32 = 0;
/// [`AirSource`]'s kind of a blast.
pub const SOURCE_BLAST: u32 = 1;

/// A [`WindSource`] ready to sample, as both backends read it (the GPU's `WindSource`, 48
/// bytes): `origin` (`w`: [`SOURCE_FAN`] or [`SOURCE_BLAST`]), `axis` (the fan's unit axis;
/// `w`: the speed) and `reach` (the range or radius, and the cosine of the fan's spread).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct AirSource {
    /// Origin, and the kind.
    pub origin: [f32; 4],
    /// Unit axis, and the speed.
    pub axis: [f32; 4],
    /// Range, cosine of the spread, and two unused words.
    pub reach: [f32; 4],
}

impl AirSource {
    /// The source's wind at `p`. The GPU's `source_wind` repeats this arithmetic.
    pub fn velocity_at(&self, p: Vec3) -> Vec3 {
        let origin = Vec3::new(self.origin[0], self.origin[1], self.origin[2]);
        let d = p - origin;
        let dist = d.length();
        let range = self.reach[0];
        if !(dist > 0.0 && dist < range) {
            return Vec3::ZERO;
        }
        let inv = 1.0 / dist;
        let mut strength = self.axis[3] * (1.0 - dist * (1.0 / range));
        if self.origin[3] == SOURCE_FAN as f32 {
            let axis = Vec3::new(self.axis[0], self.axis[1], self.axis[2]);
            let cos_spread = self.reach[1];
            let c = d.dot(axis) * inv;
            if c <= cos_spread {
                return Vec3::ZERO;
            }
            let s = (c - cos_spread) / (1.0 - cos_spread);
            strength *= s * s * (3.0 - 2.0 * s);
        }
        d * (strength * inv)
    }
}

/// One tick's air for one cloth: the wind's constants and clock, and the cloth's drag and lift
/// per unit of `A |u|²`, over three times its mass.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AirModel {
    /// The mean wind times the gust factor of this tick.
    pub ambient: Vec3,
    /// Turbulence in m/s.
    pub turbulence: f32,
    /// One over the eddy size, 1/m.
    pub inv_scale: f32,
    /// The turbulence's lattice time this tick, in `[0, NOISE_TIME_PERIOD)`.
    pub lattice_time: f32,
    /// The noise's seed.
    pub seed: u32,
    /// `½ ρ C_d / (3 m)`: a corner's share of drag per unit of `A |u|² |cos θ|`, over the
    /// cloth's mass (a particle's acceleration is this times its inverse mass share).
    pub drag: f32,
    /// `½ ρ C_l / (3 m)`, as `drag`.
    pub lift: f32,
}

impl AirModel {
    /// The air of a cloth of `mass` kg with `aerodynamics`, in `wind`, for the tick that starts
    /// at `time` seconds.
    pub fn new(aerodynamics: Aerodynamics, mass: f32, wind: &Wind, time: f64) -> Self {
        let [gust, lattice_time] = wind.clock(time);
        let per_corner = 0.5 * wind.density / (3.0 * mass);
        Self {
            ambient: wind.velocity * gust,
            turbulence: wind.turbulence,
            inv_scale: 1.0 / wind.turbulence_scale,
            lattice_time,
            seed: wind.seed,
            drag: per_corner * aerodynamics.drag,
            lift: per_corner * aerodynamics.lift,
        }
    }

    /// The wind at `p`: the ambient wind, the turbulence and every source. The GPU's
    /// `air_sample` repeats this arithmetic.
    pub fn wind_at(&self, p: Vec3, sources: &[AirSource]) -> Vec3 {
        self.wind_with(p, sources, |q| value_noise_4d(q, self.lattice_time, self.seed))
    }

    /// [`Self::wind_at`] with the turbulence's noise at `q` (lattice units) from `noise`.
    #[inline]
    fn wind_with(&self, p: Vec3, sources: &[AirSource], noise: impl Fn(Vec3) -> Vec3) -> Vec3 {
        let mut w = self.ambient;
        if self.turbulence > 0.0 {
            w += self.turbulence * noise(p * self.inv_scale);
        }
        for source in sources {
            w += source.velocity_at(p);
        }
        w
    }

    /// The aerodynamic force on one triangle (corners `x`, velocities `v`, winds `w`), per
    /// corner and over the cloth's mass: a corner's acceleration is the sum over its triangles
    /// times its inverse mass share. The relative flow is the mean of the corners' relative
    /// velocities, `((w₀ - v₀) + (w₁ - v₁) + (w₂ - v₂)) / 3`. The GPU's `triangle_air` repeats
    /// this arithmetic.
    #[inline]
    pub fn triangle_force(&self, x: [Vec3; 3], v: [Vec3; 3], w: [Vec3; 3]) -> Vec3 {
        let relative = [0, 1, 2].map(|k| Vec3A::from(w[k]) - Vec3A::from(v[k]));
        self.triangle_force_simd(x.map(Vec3A::from), mean_flow(relative)).into()
    }

    /// [`Self::triangle_force`] on SIMD vectors, from the corners and the relative flow `u`.
    ///
    /// With the cross product `m = 2 A n` and `d = m · u` (so `cos θ = d / (|m| |u|)`), the drag
    /// `½ ρ C_d A |u|² |cos θ| û` is `½ ρ C_d |d| u / 2` and the lift
    /// `½ ρ C_l A |u|² cos θ (n - cos θ û)` is `½ ρ C_l d (|u| / |m|) (m - (d / |u|²) u) / 2`:
    /// one square root and two divisions, the factor `½ ρ C / (3 m)` being in `drag` and `lift`.
    #[inline]
    fn triangle_force_simd(&self, x: [Vec3A; 3], u: Vec3A) -> Vec3A {
        let m = (x[1] - x[0]).cross(x[2] - x[0]);
        let m2 = m.dot(m);
        let u2 = u.dot(u);
        if !(m2 > 0.0 && u2 > 0.0) {
            return Vec3A::ZERO;
        }
        let d = m.dot(u);
        let drag = (0.5 * self.drag * d.abs()) * u;
        let lift = (0.5 * self.lift * d * (u2 / m2).sqrt()) * (m - u * (d / u2));
        drag + lift
    }

    /// The arithmetic of [`Self::triangle_force_simd`] on four triangles, one per lane, by
    /// coordinate: edges `[ax, ay, az]` and `b` from each triangle's first corner, and the flow
    /// `u`. Lane by lane it runs the same operations in the same order, so each lane gives the
    /// bits of its triangle alone. A lane not `valid` gives no force.
    #[inline]
    fn lane_forces(&self, [ax, ay, az]: [Vec4; 3], [bx, by, bz]: [Vec4; 3], u: [Vec4; 3], valid: BVec4A) -> [Vec4; 3] {
        // The cross product, coordinate by coordinate as `Vec3A::cross` forms it.
        let m = [ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx];
        let dot = |p: [Vec4; 3], q: [Vec4; 3]| (p[0] * q[0] + p[1] * q[1]) + p[2] * q[2];
        let (m2, u2, d) = (dot(m, m), dot(u, u), dot(m, u));
        let live = m2.cmpgt(Vec4::ZERO) & u2.cmpgt(Vec4::ZERO) & valid;
        let drag = Vec4::splat(0.5 * self.drag) * d.abs();
        let lift = Vec4::splat(0.5 * self.lift) * d * (u2 / m2).sqrt();
        let along = d / u2;
        let force = |k: usize| Vec4::select(live, drag * u[k] + lift * (m[k] - u[k] * along), Vec4::ZERO);
        [force(0), force(1), force(2)]
    }

    /// [`Self::triangle_force`] for every triangle of `triangles`, bit for bit: `each(k, force)`
    /// for triangle `k` of the slice, in order. Its corners index `corners`, each particle's
    /// position and its wind less its velocity, side by side so that a corner is one read.
    ///
    /// Four triangles at a time, one per SIMD lane: their edges and flows are transposed so
    /// that each vector holds one coordinate of the four, and the arithmetic of
    /// `triangle_force_simd` runs lane-wise, its square root and divisions shared. The
    /// operations and their order are the same, so the lanes give the same bits.
    #[inline]
    pub fn triangle_forces(&self, triangles: &[[u32; 3]], corners: &[[Vec3A; 2]], mut each: impl FnMut(usize, Vec3A)) {
        let mut groups = triangles.chunks_exact(4);
        let mut first = 0;
        for group in &mut groups {
            let mut e1 = [Vec4::ZERO; 4];
            let mut e2 = [Vec4::ZERO; 4];
            let mut flow = [Vec4::ZERO; 4];
            for (lane, t) in group.iter().enumerate() {
                let [[xa, ua], [xb, ub], [xc, uc]] = t.map(|k| corners[k as usize]);
                e1[lane] = wide(xb - xa);
                e2[lane] = wide(xc - xa);
                flow[lane] = wide(mean_flow([ua, ub, uc]));
            }
            // Row k of a transposed matrix is coordinate k of the four triangles.
            let lanes = |v: [Vec4; 4]| {
                let t = Mat4::from_cols(v[0], v[1], v[2], v[3]).transpose();
                [t.x_axis, t.y_axis, t.z_axis]
            };
            let [fx, fy, fz] = self.lane_forces(lanes(e1), lanes(e2), lanes(flow), BVec4A::splat(true));
            let f = Mat4::from_cols(fx, fy, fz, Vec4::ZERO).transpose();
            each(first, Vec3A::from_vec4(f.x_axis));
            each(first + 1, Vec3A::from_vec4(f.y_axis));
            each(first + 2, Vec3A::from_vec4(f.z_axis));
            each(first + 3, Vec3A::from_vec4(f.w_axis));
            first += 4;
        }
        for (k, t) in groups.remainder().iter().enumerate() {
            let [[xa, ua], [xb, ub], [xc, uc]] = t.map(|k| corners[k as usize]);
            each(first + k, self.triangle_force_simd([xa, xb, xc], mean_flow([ua, ub, uc])));
        }
    }
}

/// `v` as a four-vector, for a lane-wise transpose (its fourth coordinate is not read).
#[inline]
fn wide(v: Vec3A) -> Vec4 {
    v.extend(0.0)
}

/// The relative flow over a triangle: the mean of its corners' relative velocities.
#[inline]
fn mean_flow([a, b, c]: [Vec3A; 3]) -> Vec3A {
    ((a + b) + c) * (1.0 / 3.0)
}

/// [`mean_flow`] of four triangles, one per lane, by coordinate.
#[inline]
fn mean_flow_lanes(a: [Vec4; 3], b: [Vec4; 3], c: [Vec4; 3]) -> [Vec4; 3] {
    let third = Vec4::splat(1.0 / 3.0);
    [((a[0] + b[0]) + c[0]) * third, ((a[1] + b[1]) + c[1]) * third, ((a[2] + b[2]) + c[2]) * third]
}

/// A cloth's working state for aerodynamics: the wind at each particle this tick, and each
/// triangle's force this substep.
#[derive(Clone, Debug, Default)]
pub struct Air {
    /// The wind at each particle, sampled at the tick's start.
    pub wind: Vec<Vec3A>,
    /// Each particle's position, and its wind less its velocity, this substep.
    corners: Vec<[Vec3A; 2]>,
    /// Each triangle's force per corner (see [`AirModel::triangle_force`]): in triangle order
    /// on a large cloth, and on a small one in the particle-major order of the topology's
    /// triangle list (a copy under each corner).
    forces: Vec<Vec3A>,
    /// The kick's working state on a generated grid.
    grid: grid_kick::GridAir,
}

impl Air {
    /// Samples the wind at every particle of `x`.
    pub fn sample(&mut self, model: &AirModel, sources: &[AirSource], x: &[Vec3A]) {
        self.wind.resize(x.len(), Vec3A::ZERO);
        let (t, seed) = (model.lattice_time, model.seed);
        let lattice = if model.turbulence > 0.0 {
            let q = x.iter().map(|&p| p * model.inv_scale);
            NoiseLattice::around(q, t, seed, x.len())
        } else {
            None
        };
        let noise = |q: Vec3| match &lattice {
            Some(lattice) => lattice.noise(q, t, seed),
            None => value_noise_4d(q, t, seed),
        };
        self.wind
            .par_iter_mut()
            .zip(x.par_iter())
            .with_min_len(MIN_TASK)
            .for_each(|(w, &p)| *w = model.wind_with(p.into(), sources, noise).into());
    }

    /// One substep's kick: every free particle's velocity changes by `h` times its aerodynamic
    /// acceleration from its triangles, summed in the order of its triangle list, at most by
    /// its speed relative to the wind (see the [module docs](self)). Needs [`Self::sample`]
    /// first.
    pub fn kick(
        &mut self,
        model: &AirModel,
        topology: &ClothTopology,
        free: &[f32],
        h: f32,
        x: &[Vec3A],
        v: &mut [Vec3A],
    ) {
        let inv_share = topology.inv_mass_share();
        if let Some(grid) = topology.stencil() {
            self.grid.kick(model, grid, inv_share, free, h, x, &self.wind, v);
            return;
        }
        let triangles = topology.triangles();
        self.corners.clear();
        self.corners.extend(x.iter().zip(&self.wind).zip(v.iter()).map(|((&x, &w), &v)| [x, w - v]));
        let corners = &self.corners[..];
        let apply = |f: Vec3A, free: f32, inv_share: f32, [_, relative]: [Vec3A; 2], v: &mut Vec3A| {
            if free != 0.0 {
                *v += capped_kick_simd(f * (h * inv_share), relative);
            }
        };
        if v.len() < MIN_TASK {
            // Each triangle's force goes under each of its corners in the triangle list, so that
            // a particle's forces lie together, in the order of its list, as the gather below
            // and the GPU's take them.
            let (slots, offsets) = (topology.triangle_slots(), topology.triangle_offsets());
            self.forces.resize(topology.triangle_list().len(), Vec3A::ZERO);
            let forces = &mut self.forces[..];
            model.triangle_forces(triangles, corners, |t, f| {
                for slot in slots[t] {
                    forces[slot as usize] = f;
                }
            });
            // Each particle's run follows the one before it.
            let mut rest = &forces[..];
            let each = v.iter_mut().zip(offsets.windows(2)).zip(free.iter().zip(inv_share).zip(corners));
            for ((v, run), ((&free, &inv_share), &corner)) in each {
                let (mine, after) = rest.split_at((run[1] - run[0]) as usize);
                rest = after;
                apply(mine.iter().fold(Vec3A::ZERO, |f, &share| f + share), free, inv_share, corner, v);
            }
        } else {
            self.forces.resize(triangles.len(), Vec3A::ZERO);
            // Tasks of whole groups of four triangles, so that only the last has a remainder.
            const TASK: usize = MIN_TASK / 4 * 4;
            self.forces.par_chunks_mut(TASK).zip(triangles.par_chunks(TASK)).for_each(|(out, triangles)| {
                model.triangle_forces(triangles, corners, |t, f| out[t] = f);
            });
            let forces = &self.forces;
            v.par_iter_mut().enumerate().with_min_len(MIN_TASK).for_each(|(i, v)| {
                let f = topology.triangles_of(i).iter().fold(Vec3A::ZERO, |f, &t| f + forces[t as usize]);
                apply(f, free[i], inv_share[i], corners[i], v);
            });
        }
    }
}

/// `dv`, shortened to the length of `relative` (the particle's velocity relative to the wind)
/// where it is longer. The GPU's `air_kick` repeats this arithmetic.
#[inline]
pub fn capped_kick(dv: Vec3, relative: Vec3) -> Vec3 {
    capped_kick_simd(dv.into(), relative.into()).into()
}

/// [`capped_kick`] on SIMD vectors.
#[inline]
fn capped_kick_simd(dv: Vec3A, relative: Vec3A) -> Vec3A {
    let dv2 = dv.dot(dv);
    let rel2 = relative.dot(relative);
    if dv2 > rel2 { dv * (rel2 / dv2).sqrt() } else { dv }
}

/// [`capped_kick`] of four particles, one per lane, by coordinate, with the bits of
/// [`capped_kick_simd`] in each lane.
#[inline]
fn capped_kick_lanes(dv: [Vec4; 3], relative: [Vec4; 3]) -> [Vec4; 3] {
    let dot = |p: [Vec4; 3]| (p[0] * p[0] + p[1] * p[1]) + p[2] * p[2];
    let (dv2, rel2) = (dot(dv), dot(relative));
    let long = dv2.cmpgt(rel2);
    if !long.any() {
        return dv;
    }
    let shorten = (rel2 / dv2).sqrt();
    let cap = |d: Vec4| Vec4::select(long, d * shorten, d);
    [cap(dv[0]), cap(dv[1]), cap(dv[2])]
}

/// The integer hash behind the noise (Wellons' `lowbias32`): every input bit flips about half
/// of the output bits.
#[inline]
pub fn hash(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^= x >> 16;
    x
}

/// One lattice value in `[-1, 1]` from 10 bits of a hash.
#[inline]
fn unit(bits: u32) -> f32 {
    ((bits & 0x3ff) as f32 - 511.5) * (1.0 / 511.5)
}

/// Smoothstep weight of a fraction in `[0, 1)`.
#[inline]
fn smooth(f: f32) -> f32 {
    f * f * (3.0 - 2.0 * f)
}

/// A one-dimensional value noise in `[-1, 1]` at lattice time `t` (`0 <= t`), repeating every
/// [`NOISE_TIME_PERIOD`] steps.
pub fn value_noise_1d(t: f32, seed: u32) -> f32 {
    let cell = t.floor();
    let i = cell as u32;
    let s = smooth(t - cell);
    let key = |k: u32| hash((k % NOISE_TIME_PERIOD) ^ seed.wrapping_mul(0x9e37_79b9));
    let (a, b) = (unit(key(i)), unit(key(i.wrapping_add(1))));
    a + (b - a) * s
}

/// One coordinate's key in a lattice corner's hash: the coordinate times its own odd constant.
/// A corner's hash is that of its four keys and the seed, XORed.
#[inline]
fn lattice_key(coordinate: i32, prime: u32) -> u32 {
    (coordinate as u32).wrapping_mul(prime)
}

#[inline]
fn time_key(t: u32) -> u32 {
    (t % NOISE_TIME_PERIOD).wrapping_mul(0x1656_67b1)
}

/// The lattice cell of `q`: `Vec3::floor` on SIMD lanes, inline where `f32::floor` is a call.
#[inline]
fn floor(q: Vec3) -> Vec3 {
    Vec3A::from(q).floor().into()
}

/// A corner's vector: three lattice values from one hash.
#[inline]
fn corner_vector(h: u32) -> Vec3A {
    Vec3A::new(unit(h), unit(h >> 10), unit(h >> 20))
}

/// A vector value noise in space and time, each component in `[-1, 1]`: at `q` (lattice
/// units) and lattice time `t` (`0 <= t`), smoothstep-blended over the 16 corners of its cell.
/// The GPU's `value_noise_4d` repeats this arithmetic.
pub fn value_noise_4d(q: Vec3, t: f32, seed: u32) -> Vec3 {
    let cell = floor(q);
    let tc = t.floor();
    let [x, y, z] = [cell.x as i32, cell.y as i32, cell.z as i32];
    let ti = tc as u32;
    // The corners' hashes XOR one key per coordinate (as `corner` does): each key is found once.
    let xs = [lattice_key(x, X_KEY), lattice_key(x.wrapping_add(1), X_KEY)];
    let ys = [lattice_key(y, Y_KEY), lattice_key(y.wrapping_add(1), Y_KEY)];
    let zs = [lattice_key(z, Z_KEY), lattice_key(z.wrapping_add(1), Z_KEY)];
    let ts = [time_key(ti) ^ seed, time_key(ti.wrapping_add(1)) ^ seed];
    let st = smooth(t - tc);
    blend_cell(q - cell, |[i, j, k]| {
        let key = xs[i] ^ ys[j] ^ zs[k];
        corner_at(key, ts, st)
    })
}

/// The odd constants of the lattice's x, y and z keys.
const X_KEY: u32 = 0x8da6_b343;
const Y_KEY: u32 = 0xd816_3841;
const Z_KEY: u32 = 0xcb1a_b31f;

/// The vector of the lattice corner whose spatial keys XOR to `key`, at a time between two
/// lattice times (keys `ts`, seed included): its vectors at the two blended by the time's
/// smoothstep weight `st`. Time is blended first, so that one tick's corners are blended once,
/// whatever the number of points in their cells.
#[inline(always)]
fn corner_at(key: u32, ts: [u32; 2], st: f32) -> Vec3A {
    lerp(corner_vector(hash(key ^ ts[0])), corner_vector(hash(key ^ ts[1])), st)
}

/// `a` blended towards `b` by the weight `s`.
#[inline(always)]
fn lerp(a: Vec3A, b: Vec3A, s: f32) -> Vec3A {
    a + (b - a) * s
}

/// The smoothstep blend of a cell's 8 corner vectors (already blended in time), `corner([x, y,
/// z])` with each index 0 or 1, at the fractions `f`: along x, then y, then z.
#[inline(always)]
fn blend_cell(f: Vec3, corner: impl Fn([usize; 3]) -> Vec3A) -> Vec3 {
    let (sx, sy, sz) = (smooth(f.x), smooth(f.y), smooth(f.z));
    let mut by_z = [Vec3A::ZERO; 2];
    for (k, plane) in by_z.iter_mut().enumerate() {
        let mut by_y = [Vec3A::ZERO; 2];
        for (j, row) in by_y.iter_mut().enumerate() {
            *row = lerp(corner([0, j, k]), corner([1, j, k]), sx);
        }
        *plane = lerp(by_y[0], by_y[1], sy);
    }
    lerp(by_z[0], by_z[1], sz).into()
}

/// The most corner vectors a [`NoiseLattice`] holds per particle it serves (and 4,096 at
/// least): eddies far smaller than the cloth are sampled corner by corner instead.
const LATTICE_PER_PARTICLE: usize = 2;

/// The turbulence's corner vectors over the cells a cloth's particles lie in, at one lattice
/// time: one tick's [`value_noise_4d`] for every particle, each of the cells' corners hashed
/// and blended in time once instead of once for each particle in them. The same corners and
/// the same blend give the same bits.
struct NoiseLattice {
    /// The first corner, in lattice coordinates.
    lo: [i32; 3],
    /// Corners along x, y and z.
    dims: [usize; 3],
    /// The vectors at the lattice time, x fastest, then y and z.
    vectors: Vec<Vec3A>,
}

impl NoiseLattice {
    /// The corners round the cells of every finite `q` (lattice units) at lattice time `t`;
    /// `None` when there is no finite point or the lattice would be too large.
    fn around(q: impl Iterator<Item = Vec3A>, t: f32, seed: u32, particles: usize) -> Option<Self> {
        // The cells' bounds are those of the points, floored (floor does not decrease).
        let (lo, hi) = q
            .filter(|q| q.is_finite())
            .fold((Vec3A::INFINITY, Vec3A::NEG_INFINITY), |(lo, hi), q| (lo.min(q), hi.max(q)));
        let (lo, hi) = (Vec3::from(lo.floor()), Vec3::from(hi.floor()));
        if !(lo.is_finite() && hi.is_finite())
            || lo.min_element() < i32::MIN as f32 / 2.0
            || hi.max_element() > i32::MAX as f32 / 2.0
        {
            return None;
        }
        let span = hi - lo + 2.0;
        let count = f64::from(span.x) * f64::from(span.y) * f64::from(span.z);
        if count > (LATTICE_PER_PARTICLE * particles).max(4096) as f64 {
            return None;
        }
        let lo = [lo.x as i32, lo.y as i32, lo.z as i32];
        let dims = [span.x as usize, span.y as usize, span.z as usize];
        let tc = t.floor();
        let st = smooth(t - tc);
        let ti = tc as u32;
        let ts = [time_key(ti) ^ seed, time_key(ti.wrapping_add(1)) ^ seed];
        let mut vectors = Vec::with_capacity(count as usize);
        for z in 0..dims[2] as i32 {
            let zk = lattice_key(lo[2].wrapping_add(z), Z_KEY);
            for y in 0..dims[1] as i32 {
                let yk = lattice_key(lo[1].wrapping_add(y), Y_KEY);
                for x in 0..dims[0] as i32 {
                    let key = lattice_key(lo[0].wrapping_add(x), X_KEY) ^ yk ^ zk;
                    vectors.push(corner_at(key, ts, st));
                }
            }
        }
        Some(Self { lo, dims, vectors })
    }

    /// [`value_noise_4d`] at `q` and the lattice's time `t`: from the stored corners when `q`'s
    /// cell is among them, else hashed.
    #[inline]
    fn noise(&self, q: Vec3, t: f32, seed: u32) -> Vec3 {
        let cell = floor(q);
        let c = [cell.x as i32, cell.y as i32, cell.z as i32];
        let mut base = [0usize; 3];
        for axis in 0..3 {
            let offset = c[axis].wrapping_sub(self.lo[axis]);
            if !(0..self.dims[axis] as i32 - 1).contains(&offset) {
                return value_noise_4d(q, t, seed);
            }
            base[axis] = offset as usize;
        }
        let [dx, dy, _] = self.dims;
        let first = (base[2] * dy + base[1]) * dx + base[0];
        let (y_stride, z_stride) = (dx, dx * dy);
        blend_cell(q - cell, |[i, j, k]| self.vectors[first + i + j * y_stride + k * z_stride])
    }
}

fn in_range(field: &'static str, value: f32, min: f32, max: f32) -> Result<(), ClothError> {
    if value >= min && value <= max { Ok(()) } else { Err(ClothError::OutOfRange { field, value, min, max }) }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model(aerodynamics: Aerodynamics, wind: &Wind) -> AirModel {
        AirModel::new(aerodynamics, 3.0, wind, 0.0)
    }

    /// A unit right triangle in the XZ plane (area 0.5, normal ±Y), at rest.
    fn plate() -> [Vec3; 3] {
        [Vec3::ZERO, Vec3::X, Vec3::Z]
    }

    #[test]
    fn drag_square_to_the_flow_is_half_rho_cd_a_u_squared() {
        let wind = Wind::steady(Vec3::new(0.0, -10.0, 0.0));
        let m = model(Aerodynamics { drag: 1.2, lift: 0.7 }, &wind);
        let w = [wind.velocity; 3];
        let f = m.triangle_force(plate(), [Vec3::ZERO; 3], w);
        // Per corner over the mass: ½ 1.225 1.2 0.5 100 / (3 * 3), all along the flow; no lift
        // square to it.
        let want = 0.5 * 1.225 * 1.2 * 0.5 * 100.0 / 9.0;
        assert!((f - Vec3::new(0.0, -want, 0.0)).length() < 1e-5 * want, "{f}");
        // Edge-on: neither drag nor lift.
        let edge_on = m.triangle_force(plate(), [Vec3::ZERO; 3], [Vec3::new(10.0, 0.0, 0.0); 3]);
        assert!(edge_on.length() < 1e-6, "{edge_on}");
    }

    #[test]
    fn lift_at_45_degrees_pushes_away_from_the_struck_side() {
        // Air from above and behind at 45°: cos θ = sin θ = √½.
        let u = Vec3::new(1.0, -1.0, 0.0).normalize() * 10.0;
        let m = model(Aerodynamics { drag: 0.0, lift: 1.0 }, &Wind::steady(u));
        let f = m.triangle_force(plate(), [Vec3::ZERO; 3], [u; 3]);
        let q = 0.5 * 100.0;
        let want = 0.5 * 1.225 / 9.0 * q * 0.5;
        assert!((f.length() - want).abs() < 1e-4 * want, "{} vs {want}", f.length());
        assert!(f.dot(u).abs() < 1e-4 * want, "lift is across the flow");
        assert!(f.y < 0.0, "air striking the top pushes the plate down: {f}");
        // The winding does not matter.
        let [a, b, c] = plate();
        let flipped = m.triangle_force([a, c, b], [Vec3::ZERO; 3], [u; 3]);
        assert!((flipped - f).length() < 1e-6 * want);
    }

    /// The three-lane pass gives every triangle's force bit for bit as one triangle at a time
    /// does, for every remainder of three, with triangles of no area, corners moving with the
    /// air, and corners that are not finite among them.
    #[test]
    fn lanes_give_the_bits_of_one_triangle_at_a_time() {
        let m = model(Aerodynamics::FABRIC, &Wind::steady(Vec3::new(6.0, -1.0, 2.0)));
        let mut seed = 17u32;
        let mut next = || {
            seed = hash(seed);
            unit(seed) * 2.0
        };
        let count = 40;
        let x: Vec<Vec3A> = (0..count).map(|_| Vec3A::new(next(), next(), next())).collect();
        let mut v: Vec<Vec3A> = (0..count).map(|_| Vec3A::new(next(), next(), next())).collect();
        let w: Vec<Vec3A> = (0..count).map(|_| Vec3A::new(next(), next(), next()) * 5.0).collect();
        // Particles 0 to 2 move with their air, and 3 is not finite.
        v[..3].copy_from_slice(&w[..3]);
        v[3] = Vec3A::NAN;
        let mut triangles: Vec<[u32; 3]> =
            (0..count as u32 - 2).map(|i| [i, (i * 7 + 1) % 40, (i * 13 + 2) % 40]).collect();
        // No area: a corner twice, and three corners in a line.
        triangles.extend([[5, 5, 9], [0, 1, 2], [0, 1, 3]]);
        let x = {
            let mut x = x;
            x[11] = x[10] * 2.0 - x[9];
            x
        };
        triangles.push([9, 10, 11]);
        let corners: Vec<[Vec3A; 2]> = (0..count).map(|i| [x[i], w[i] - v[i]]).collect();
        // Four lengths in a row: every remainder of four, after whole groups and alone.
        let n = triangles.len();
        for len in [n, n - 1, n - 2, n - 3, 3, 2, 1, 0] {
            let mut lanes = vec![Vec3A::splat(7.0); len];
            m.triangle_forces(&triangles[..len], &corners, |t, f| lanes[t] = f);
            for (t, (corners, got)) in triangles.iter().zip(&lanes).enumerate() {
                let [a, b, c] = corners.map(|k| k as usize);
                let one = m.triangle_force(
                    [x[a], x[b], x[c]].map(Vec3::from),
                    [v[a], v[b], v[c]].map(Vec3::from),
                    [w[a], w[b], w[c]].map(Vec3::from),
                );
                let got = Vec3::from(*got);
                assert!(
                    got.to_array().map(f32::to_bits) == one.to_array().map(f32::to_bits),
                    "triangle {t} of {len}: {got} in lanes, {one} alone"
                );
            }
        }
    }

    /// A tick's sampling, which hashes and blends each lattice corner once, gives every particle
    /// the bits of [`AirModel::wind_at`]: in eddies larger than the cloth, in eddies so small
    /// that the corners are hashed point by point, and with a point that is not finite among
    /// them.
    #[test]
    fn sampling_gives_the_bits_of_the_wind_at_each_point() {
        let mut seed = 5u32;
        let mut next = || {
            seed = hash(seed);
            unit(seed)
        };
        let mut x: Vec<Vec3A> = (0..3000).map(|_| Vec3A::new(next(), next() + 3.0, next()) * 1.5).collect();
        x[17] = Vec3A::new(f32::NAN, 0.0, 0.0);
        let sources = [WindSource::Blast { center: Vec3::ZERO, speed: 4.0, radius: 3.0 }.prepare()];
        for (scale, corners) in [(2.0, true), (0.3, true), (0.001, false)] {
            let wind = Wind { turbulence_scale: scale, ..Wind::gusty(Vec3::new(7.0, 0.0, 3.0)) };
            let model = AirModel::new(Aerodynamics::FABRIC, 0.3, &wind, 1234.5);
            let q = x.iter().map(|&p| p * model.inv_scale);
            let lattice = NoiseLattice::around(q, model.lattice_time, model.seed, x.len());
            assert_eq!(lattice.is_some(), corners, "eddies of {scale} m");
            let mut air = Air::default();
            air.sample(&model, &sources, &x);
            for (i, (&p, &got)) in x.iter().zip(&air.wind).enumerate() {
                let want = model.wind_at(p.into(), &sources);
                let same = Vec3::from(got).to_array().map(f32::to_bits) == want.to_array().map(f32::to_bits);
                assert!(
                    same || (got.is_nan() && want.is_nan()),
                    "eddies of {scale} m, particle {i}: {got} sampled, {want} at the point"
                );
            }
        }
    }

    #[test]
    fn a_triangle_moving_with_the_air_feels_nothing() {
        let wind = Wind::steady(Vec3::new(3.0, 1.0, -2.0));
        let m = model(Aerodynamics::FABRIC, &wind);
        assert_eq!(m.triangle_force(plate(), [wind.velocity; 3], [wind.velocity; 3]), Vec3::ZERO);
        // A degenerate triangle neither.
        let line = [Vec3::ZERO, Vec3::X, 2.0 * Vec3::X];
        assert_eq!(m.triangle_force(line, [Vec3::ZERO; 3], [wind.velocity; 3]), Vec3::ZERO);
    }

    /// A kick gives each particle the bits of its triangles' forces found one at a time and
    /// summed in the order of its list, on every path: a generated grid's rows of lanes (on one
    /// thread and on the pool, with rows and columns that leave partial groups of four), and
    /// the same grid as a general mesh, small enough for one thread (each force copied under
    /// its corners) and large enough for the pool (gathered per particle). A long substep caps
    /// some particles' kicks and not others', so that both sides of the cap are held too.
    #[test]
    fn kicks_sum_each_particles_triangles_in_the_order_of_its_list() {
        use crate::grid::ClothGrid;
        use glam::{UVec2, Vec2};
        let wind = Wind::gusty(Vec3::new(6.0, 1.0, -2.0));
        let m = model(Aerodynamics::FABRIC, &wind);
        let mut seed = 11u32;
        let mut next = || {
            seed = hash(seed);
            unit(seed)
        };
        let cases = [
            (UVec2::splat(24), 1.0 / 960.0, false),
            (UVec2::splat(100), 1.0 / 960.0, false),
            (UVec2::new(6, 9), 8.0, true),
            (UVec2::new(13, 5), 8.0, true),
            (UVec2::new(2, 2), 8.0, false),
        ];
        // Substeps this long cap some kicks, and not others.
        for (shape, h, both_sides_of_the_cap) in cases {
            let grid = ClothGrid::new(Vec2::splat(1.0), shape);
            for topology in [ClothTopology::grid(grid).unwrap(), ClothTopology::grid_as_mesh(grid).unwrap()] {
                let n = topology.len();
                let x: Vec<Vec3A> = topology
                    .rest_positions()
                    .iter()
                    .map(|&p| Vec3A::from(p) + 0.01 * Vec3A::new(next(), next(), next()))
                    .collect();
                let v0: Vec<Vec3A> = (0..n).map(|_| 3.0 * Vec3A::new(next(), next(), next())).collect();
                let free: Vec<f32> = (0..n).map(|i| if i % 7 == 0 { 0.0 } else { 1.0 }).collect();
                let mut air = Air::default();
                air.sample(&m, &[], &x);
                let mut v = v0.clone();
                air.kick(&m, &topology, &free, h, &x, &mut v);
                let corners = |t: [u32; 3], a: &[Vec3A]| t.map(|k| Vec3::from(a[k as usize]));
                let mut capped = [0; 2];
                for i in 0..n {
                    let mut f = Vec3::ZERO;
                    for &t in topology.triangles_of(i) {
                        let tri = topology.triangles()[t as usize];
                        f += m.triangle_force(corners(tri, &x), corners(tri, &v0), corners(tri, &air.wind));
                    }
                    let mut want = Vec3::from(v0[i]);
                    if free[i] != 0.0 {
                        let (dv, relative) = (f * (h * topology.inv_mass_share()[i]), Vec3::from(air.wind[i] - v0[i]));
                        capped[usize::from(dv.length_squared() > relative.length_squared())] += 1;
                        want += capped_kick(dv, relative);
                    }
                    assert_eq!(
                        Vec3::from(v[i]).to_array().map(f32::to_bits),
                        want.to_array().map(f32::to_bits),
                        "{shape} particles, grid path {}, particle {i}: {} kicked, {want} one at a time",
                        topology.stencil().is_some(),
                        v[i]
                    );
                }
                if both_sides_of_the_cap {
                    assert!(capped[0] > 0 && capped[1] > 0, "{shape} particles: {capped:?} kicks whole and capped");
                }
            }
        }
    }

    #[test]
    fn a_kick_never_takes_a_particle_past_the_wind() {
        let dv = capped_kick(Vec3::new(50.0, 0.0, 0.0), Vec3::new(2.0, 0.0, 0.0));
        assert!((dv - Vec3::new(2.0, 0.0, 0.0)).length() < 1e-6, "{dv}");
        assert_eq!(capped_kick(Vec3::new(0.5, 0.0, 0.0), Vec3::new(2.0, 0.0, 0.0)), Vec3::new(0.5, 0.0, 0.0));
    }

    #[test]
    fn noise_is_smooth_bounded_and_repeats_in_time() {
        let mut max = 0.0f32;
        let mut mean = Vec3::ZERO;
        let n = 4000;
        for i in 0..n {
            let q = Vec3::new(i as f32 * 0.173, i as f32 * 0.071 - 30.0, (i % 97) as f32 * 0.31);
            let t = i as f32 * 0.013;
            let v = value_noise_4d(q, t, 7);
            max = max.max(v.abs().max_element());
            mean += v;
            // A small step moves the value a little: the noise is continuous.
            let near = value_noise_4d(q + Vec3::splat(1e-3), t + 1e-3, 7);
            assert!((near - v).abs().max_element() < 0.02, "{q} {t}: {v} -> {near}");
        }
        assert!(max <= 1.0 && max > 0.5, "{max}");
        assert!((mean / n as f32).abs().max_element() < 0.1, "{mean}");
        // The lattice time repeats with no seam.
        let q = Vec3::new(0.3, 1.7, -2.2);
        let a = value_noise_4d(q, 0.25, 3);
        let b = value_noise_4d(q, NOISE_TIME_PERIOD as f32 + 0.25, 3);
        assert!((a - b).length() < 1e-3, "{a} vs {b}");
        assert!((value_noise_1d(0.5, 9) - value_noise_1d(NOISE_TIME_PERIOD as f32 + 0.5, 9)).abs() < 1e-3);
        // Another seed, another field.
        assert_ne!(value_noise_4d(q, 0.25, 4), a);
    }

    #[test]
    fn a_fan_blows_inside_its_cone_and_reach_only() {
        let fan = WindSource::Fan {
            origin: Vec3::ZERO,
            direction: Vec3::new(0.0, 0.0, 2.0),
            speed: 10.0,
            range: 5.0,
            spread: 0.5,
        }
        .prepare();
        let on_axis = fan.velocity_at(Vec3::new(0.0, 0.0, 1.0));
        assert!((on_axis - Vec3::new(0.0, 0.0, 8.0)).length() < 1e-5, "{on_axis}");
        assert_eq!(fan.velocity_at(Vec3::new(0.0, 0.0, 6.0)), Vec3::ZERO, "past its range");
        assert_eq!(fan.velocity_at(Vec3::new(1.0, 0.0, 1.0)), Vec3::ZERO, "outside its cone");
        assert_eq!(fan.velocity_at(Vec3::new(0.0, 0.0, -1.0)), Vec3::ZERO, "behind it");
        let blast = WindSource::Blast { center: Vec3::ONE, speed: 20.0, radius: 4.0 }.prepare();
        let v = blast.velocity_at(Vec3::new(1.0, 3.0, 1.0));
        assert!((v - Vec3::new(0.0, 10.0, 0.0)).length() < 1e-5, "{v}");
    }

    #[test]
    fn absurd_air_is_refused_naming_the_field() {
        let field = |e: ClothError| match e {
            ClothError::OutOfRange { field, .. }
            | ClothError::NotFinite { field }
            | ClothError::NotPositive { field, .. } => field,
            other => panic!("{other}"),
        };
        let wind = Wind::STILL;
        let cases = [
            (Wind { velocity: Vec3::new(f32::NAN, 0.0, 0.0), ..wind }, "wind.velocity"),
            (Wind { velocity: Vec3::new(400.0, 0.0, 0.0), ..wind }, "wind.velocity"),
            (Wind { density: -1.0, ..wind }, "wind.density"),
            (Wind { gust_strength: 2.0, ..wind }, "wind.gust_strength"),
            (Wind { gust_period: 0.0, ..wind }, "wind.gust_period"),
            (Wind { turbulence: f32::INFINITY, ..wind }, "wind.turbulence"),
            (Wind { turbulence_scale: f32::NAN, ..wind }, "wind.turbulence_scale"),
        ];
        for (wind, name) in cases {
            assert_eq!(field(wind.validate().unwrap_err()), name);
        }
        Wind::gusty(Vec3::new(8.0, 0.0, 0.0)).validate().unwrap();
        assert_eq!(field(Aerodynamics { drag: f32::NAN, lift: 0.0 }.validate().unwrap_err()), "aerodynamics.drag");
        assert_eq!(field(Aerodynamics { drag: 1.0, lift: 50.0 }.validate().unwrap_err()), "aerodynamics.lift");
        let fan = |speed, spread| WindSource::Fan { origin: Vec3::ZERO, direction: Vec3::X, speed, range: 1.0, spread };
        assert_eq!(field(fan(1e6, 0.5).validate().unwrap_err()), "fan.speed");
        assert_eq!(field(fan(5.0, 0.0).validate().unwrap_err()), "fan.spread");
        let zero_axis =
            WindSource::Fan { origin: Vec3::ZERO, direction: Vec3::ZERO, speed: 1.0, range: 1.0, spread: 1.0 };
        assert_eq!(field(zero_axis.validate().unwrap_err()), "fan.direction");
        let blast = WindSource::Blast { center: Vec3::ZERO, speed: 1.0, radius: -2.0 };
        assert_eq!(field(blast.validate().unwrap_err()), "blast.radius");
    }
}
