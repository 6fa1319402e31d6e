//! The CPU stepper: a whole cloth of any [`ClothTopology`] advanced by RK4 or semi-implicit
//! Euler, with collision response fused into the last stage of every substep (paper Fig. 1),
//! or by block descent ([`crate::solver::block_descent`]).
//!
//! This is the reference the GPU kernels are checked against and a real backend for machines
//! without compute shaders. Rows are processed in parallel with rayon; every particle's result
//! depends only on the previous stage's buffers, never on which thread ran it, so a step is
//! bit-identical whatever the number of threads.

mod explicit;
mod step;

use std::sync::Arc;

use glam::{Affine3A, Vec3, Vec3A};

use crate::air::{Air, AirModel, AirSource, Wind, WindSource};
use crate::cloth::error::ClothError;
use crate::cloth::tethers::TetherSet;
use crate::cloth::topology::ClothTopology;
use crate::colliders::collider::Collider;
use crate::colliders::collision::ColliderFrame;
use crate::self_contact::ContactSolver;
use crate::solver::block_descent::BlockDescent;
use crate::solver::forces::{ForceModel, LANES};
use crate::solver::params::ClothParams;

/// Particles per row of the state layout when the topology is not the grid (the grid's rows
/// are its own).
const GENERAL_ROW: usize = 64;

/// What one [`ClothSim::tick`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Ticked {
    /// Substeps run (`looper`, or more when the stability guard asked for them).
    pub substeps: u32,
    /// Particles the tick left with a NaN or infinite position or velocity: 0 for a healthy
    /// cloth. Only a state written non-finite from outside stays so (the quarantine keeps the
    /// stepper's own results finite); reset it ([`ClothSim::reset`]).
    pub non_finite: usize,
    /// Particles quarantined in the tick, counted per substep (so one particle may count more
    /// than once): a particle whose substep went NaN or infinite keeps its position at the
    /// substep's start, at rest, so that it cannot spread through the springs, as the GPU's
    /// kernels do. A cloth that needs it has parameters its solver cannot hold (an explicit
    /// integrator past its stability guard, see [`ClothParams::check_tick`]) or was given a
    /// non-finite state.
    pub quarantined: usize,
}

impl Ticked {
    /// Whether the tick left any particle non-finite or had to quarantine one.
    pub fn diverged(&self) -> bool {
        self.non_finite > 0 || self.quarantined > 0
    }
}

/// A simulated cloth.
#[derive(Clone, Debug)]
pub struct ClothSim {
    params: ClothParams,
    topology: Arc<ClothTopology>,
    /// Particles per row of the state layout; the last row may be padded.
    width: usize,
    /// Current state, row layout (see [`crate::solver::forces`]).
    state: Vec<f32>,
    /// Stage buffers: intermediate states and the running RK4 slope sum.
    stage_a: Vec<f32>,
    stage_b: Vec<f32>,
    slope_sum: Vec<f32>,
    /// 1 for a free particle, 0 for a pinned or massless one and for padding.
    free: Vec<f32>,
    /// 1 for a particle a collider touched in the last substep's collision response, else 0:
    /// self-contact weighs it as pinned.
    held: Vec<f32>,
    /// Particles quarantined since the tick began (see [`Ticked::quarantined`]).
    quarantined: usize,
    pins: Vec<u32>,
    /// Each particle's nearest pin and rest distance to it, for the tethers.
    tethers: Arc<TetherSet>,
    /// Working state of block descent, which keeps positions by particle during a tick.
    descent: BlockDescent,
    /// Self-contact's grid and scratch, and the positions and velocities it works on.
    contact: ContactSolver,
    contact_prev: Vec<Vec3>,
    contact_x: Vec<Vec3>,
    contact_v: Vec<Vec3>,
    /// The air around the cloth: its ambient wind, the wind sources, and the wind clock in
    /// seconds.
    wind: Wind,
    wind_sources: Vec<AirSource>,
    wind_time: f64,
    /// This tick's air (`None` when the cloth has no aerodynamics), the wind sampled at each
    /// particle, and the explicit integrators' positions and velocities by particle for the kick.
    air_model: Option<AirModel>,
    air: Air,
    air_x: Vec<Vec3A>,
    air_v: Vec<Vec3A>,
}

impl ClothSim {
    /// Builds a cloth at rest: `topology`'s rest shape placed in the world by `pose`, with
    /// `pins` (particle indices) held in place. Particles without mass (used by no triangle
    /// with area) are held too.
    pub fn new(
        params: ClothParams,
        topology: Arc<ClothTopology>,
        pose: Affine3A,
        pins: &[u32],
    ) -> Result<Self, ClothError> {
        params.validate_for(&topology)?;
        let params = params.resolved_for(&topology);
        if !pose.is_finite() {
            return Err(ClothError::NotFinite { field: "pose" });
        }
        let n = topology.len();
        let (width, rows) = match topology.stencil() {
            Some(grid) => (grid.cols, grid.rows),
            None => (GENERAL_ROW.min(n), n.div_ceil(GENERAL_ROW.min(n))),
        };
        let slots = width * rows;
        let mut free = vec![0.0f32; slots];
        for (f, &share) in free.iter_mut().zip(topology.mass_share()) {
            *f = if share > 0.0 { 1.0 } else { 0.0 };
        }
        for &i in pins {
            if i as usize >= n {
                return Err(ClothError::PinOutOfRange { index: i, particles: n as u32 });
            }
            free[i as usize] = 0.0;
        }
        let mut pins = pins.to_vec();
        pins.sort_unstable();
        pins.dedup();
        let tethers = Arc::new(TetherSet::new(&topology, &pins));
        let mut sim = Self {
            params,
            topology,
            width,
            state: vec![0.0; slots * LANES],
            stage_a: vec![0.0; slots * LANES],
            stage_b: vec![0.0; slots * LANES],
            slope_sum: vec![0.0; slots * LANES],
            held: vec![0.0; free.len()],
            quarantined: 0,
            free,
            tethers,
            pins,
            descent: BlockDescent::default(),
            contact: ContactSolver::default(),
            contact_prev: Vec::new(),
            contact_x: Vec::new(),
            contact_v: Vec::new(),
            wind: Wind::STILL,
            wind_sources: Vec::new(),
            wind_time: 0.0,
            air_model: None,
            air: Air::default(),
            air_x: Vec::new(),
            air_v: Vec::new(),
        };
        sim.reset(pose);
        Ok(sim)
    }

    /// The frames of the colliders this cloth collides with: those whose layers meet its own
    /// ([`ClothParams::layers`]) and whose pose is usable.
    pub(crate) fn frames<'a>(&self, colliders: &'a [Collider]) -> Vec<ColliderFrame<'a>> {
        let layers = self.params.layers;
        colliders.iter().filter(|c| layers.interacts_with(c.layers)).filter_map(ColliderFrame::new).collect()
    }

    /// Whether nothing holds the cloth: no particle with mass is pinned, so only the uniform
    /// acceleration, the air and the colliders change its momentum.
    pub fn is_free_body(&self) -> bool {
        let share = self.topology.mass_share();
        self.free[..self.len()].iter().zip(share).all(|(&free, &share)| free != 0.0 || share == 0.0)
    }

    /// Puts every particle back at its rest position under `pose`, at rest.
    pub fn reset(&mut self, pose: Affine3A) {
        self.descent.accel.fill(0.0);
        let topology = Arc::clone(&self.topology);
        for (i, &p) in topology.rest_positions().iter().enumerate() {
            self.set_position(i, pose.transform_point3(p));
            self.set_velocity(i, Vec3::ZERO);
        }
    }

    /// Changes which particles are pinned, keeping the state, so that a corner can be let go,
    /// or caught, while the cloth moves. A particle let go starts from rest where it was held
    /// and its springs take it along at once; a particle newly pinned stays where it is until
    /// its pin moves it ([`Self::move_pins`], [`Self::pin_to`]). The tethers are found again
    /// for the new pins. A particle without mass stays held. Returns an error, and keeps the
    /// old pins, when an index is outside the cloth.
    pub fn set_pins(&mut self, pins: &[u32]) -> Result<(), ClothError> {
        let n = self.len();
        if let Some(&index) = pins.iter().find(|&&i| i as usize >= n) {
            return Err(ClothError::PinOutOfRange { index, particles: n as u32 });
        }
        let mut pins = pins.to_vec();
        pins.sort_unstable();
        pins.dedup();
        if pins == self.pins {
            return Ok(());
        }
        let topology = Arc::clone(&self.topology);
        let released: Vec<usize> =
            self.pins.iter().map(|&i| i as usize).filter(|&i| pins.binary_search(&(i as u32)).is_err()).collect();
        for i in released {
            if topology.mass_share()[i] > 0.0 {
                self.free[i] = 1.0;
                self.set_velocity(i, Vec3::ZERO);
            }
        }
        for &i in &pins {
            self.free[i as usize] = 0.0;
        }
        self.tethers = Arc::new(TetherSet::new(&topology, &pins));
        self.pins = pins;
        Ok(())
    }

    /// Moves every pinned particle to its rest position under `pose`: this is how pins follow
    /// the object that holds the cloth.
    pub fn pin_to(&mut self, pose: &Affine3A) {
        let targets: Vec<(u32, Vec3)> = self.pin_targets(pose).collect();
        self.move_pins(&targets);
    }

    /// Moves particles to the given world positions: `(index, position)` pairs, for pins that
    /// follow targets of their own. Indices outside the cloth are ignored.
    pub fn move_pins(&mut self, targets: &[(u32, Vec3)]) {
        for &(i, p) in targets {
            if (i as usize) < self.len() {
                self.set_position(i as usize, p);
            }
        }
    }

    /// Where each pinned particle belongs under `pose`: `(index, world position)`, its rest
    /// position placed by the pose.
    pub fn pin_targets<'a>(&'a self, pose: &'a Affine3A) -> impl Iterator<Item = (u32, Vec3)> + 'a {
        let rest = self.topology.rest_positions();
        self.pins.iter().map(move |&i| (i, pose.transform_point3(rest[i as usize])))
    }

    /// The parameters.
    pub fn params(&self) -> &ClothParams {
        &self.params
    }

    /// Replaces the parameters, keeping the state. Returns an error, and keeps the old
    /// parameters, when the new ones are invalid.
    pub fn set_params(&mut self, params: ClothParams) -> Result<(), ClothError> {
        params.validate_for(&self.topology)?;
        self.params = params.resolved_for(&self.topology);
        Ok(())
    }

    /// Sets the air the cloth moves in: its ambient `wind` and the `sources` in reach (see
    /// [`crate::air`]). Only a cloth whose [`ClothParams::aerodynamics`] is active
    /// feels it. Returns an error, and keeps the old air, when either is invalid.
    pub fn set_wind(&mut self, wind: Wind, sources: &[WindSource]) -> Result<(), ClothError> {
        wind.validate()?;
        for source in sources {
            source.validate()?;
        }
        self.wind = wind;
        self.wind_sources.clear();
        self.wind_sources.extend(sources.iter().map(WindSource::prepare));
        Ok(())
    }

    /// The ambient wind.
    pub fn wind(&self) -> &Wind {
        &self.wind
    }

    /// Sets the wind clock: the time in seconds at the start of the next tick, which picks the
    /// gusts and the turbulence. Each tick advances it by its length; a world whose cloths
    /// share one wind sets them all to its own clock.
    pub fn set_wind_time(&mut self, seconds: f64) {
        if seconds.is_finite() {
            self.wind_time = seconds;
        }
    }

    /// The wind clock in seconds.
    pub fn wind_time(&self) -> f64 {
        self.wind_time
    }

    /// Samples this tick's air at every particle, at the wind clock's time.
    fn sample_air(&mut self) {
        let aerodynamics = self.params.aerodynamics;
        if !aerodynamics.is_active() {
            self.air_model = None;
            return;
        }
        let model = AirModel::new(aerodynamics, self.params.mass, &self.wind, self.wind_time);
        let n = self.len();
        let mut x = core::mem::take(&mut self.air_x);
        x.clear();
        x.extend((0..n).map(|i| Vec3A::from(self.position(i))));
        self.air.sample(&model, &self.wind_sources, &x);
        self.air_x = x;
        self.air_model = Some(model);
    }

    /// The aerodynamic kick of one explicit substep of `h` seconds, on the row layout.
    fn kick_explicit(&mut self, h: f32) {
        let Some(model) = self.air_model else { return };
        let n = self.len();
        let (mut x, mut v) = (core::mem::take(&mut self.air_x), core::mem::take(&mut self.air_v));
        x.clear();
        x.extend((0..n).map(|i| Vec3A::from(self.position(i))));
        v.clear();
        v.extend((0..n).map(|i| Vec3A::from(self.velocity(i))));
        self.air.kick(&model, &self.topology, &self.free[..n], h, &x, &mut v);
        for (i, &vel) in v.iter().enumerate() {
            self.set_velocity(i, vel.into());
        }
        (self.air_x, self.air_v) = (x, v);
    }

    /// The cloth's shape.
    pub fn topology(&self) -> &Arc<ClothTopology> {
        &self.topology
    }

    /// Substeps a tick of `dt` seconds runs (see [`ClothParams::substeps`]).
    pub fn substeps(&self, dt: f32) -> u32 {
        self.params.substeps(dt, &self.topology)
    }

    /// Number of particles.
    pub fn len(&self) -> usize {
        self.topology.len()
    }

    /// Whether the cloth has no particle (never true for a built topology).
    pub fn is_empty(&self) -> bool {
        self.topology.is_empty()
    }

    /// Each particle's nearest pin and its rest distance to it, which the tethers hold
    /// ([`crate::cloth::tethers`]; empty for a cloth with no pin).
    pub fn tethers(&self) -> &Arc<TetherSet> {
        &self.tethers
    }

    /// The pinned particle indices, sorted.
    pub fn pins(&self) -> &[u32] {
        &self.pins
    }

    /// Whether particle `i` is held still (pinned, or without mass).
    pub fn is_pinned(&self, i: usize) -> bool {
        self.free[i] == 0.0
    }

    /// Whether a collider touched particle `i` in the last substep's response (the block-descent
    /// integrators leave such a particle out of the next substep's multigrid correction).
    pub fn touched(&self, i: usize) -> bool {
        self.held.get(i).is_some_and(|&h| h != 0.0)
    }

    /// Mass of particle `i` in kilograms.
    pub fn particle_mass(&self, i: usize) -> f32 {
        self.params.mass * self.topology.mass_share()[i]
    }

    #[inline]
    fn lane(&self, i: usize) -> (usize, usize) {
        let w = self.width;
        ((i / w) * LANES * w + i % w, w)
    }

    /// Position of particle `i`.
    pub fn position(&self, i: usize) -> Vec3 {
        let (o, s) = self.lane(i);
        Vec3::new(self.state[o], self.state[o + s], self.state[o + 2 * s])
    }

    /// Velocity of particle `i`.
    pub fn velocity(&self, i: usize) -> Vec3 {
        let (o, s) = self.lane(i);
        Vec3::new(self.state[o + 3 * s], self.state[o + 4 * s], self.state[o + 5 * s])
    }

    /// Moves particle `i` (for pinned particles, this is how pins follow their anchor).
    pub fn set_position(&mut self, i: usize, p: Vec3) {
        let (o, s) = self.lane(i);
        self.state[o] = p.x;
        self.state[o + s] = p.y;
        self.state[o + 2 * s] = p.z;
    }

    /// Sets the velocity of particle `i`.
    pub fn set_velocity(&mut self, i: usize, v: Vec3) {
        let (o, s) = self.lane(i);
        self.state[o + 3 * s] = v.x;
        self.state[o + 4 * s] = v.y;
        self.state[o + 5 * s] = v.z;
    }

    /// All positions, by particle index.
    pub fn positions(&self) -> Vec<Vec3> {
        (0..self.len()).map(|i| self.position(i)).collect()
    }

    /// All velocities, by particle index.
    pub fn velocities(&self) -> Vec<Vec3> {
        (0..self.len()).map(|i| self.velocity(i)).collect()
    }

    /// Whether every position and velocity is finite.
    pub fn is_finite(&self) -> bool {
        self.state.iter().all(|v| v.is_finite())
    }

    /// How many particles have a NaN or infinite position or velocity. A healthy cloth is
    /// answered by one vectorised pass over the state.
    pub fn non_finite_particles(&self) -> usize {
        if self.is_finite() {
            return 0;
        }
        (0..self.len()).filter(|&i| !(self.position(i).is_finite() && self.velocity(i).is_finite())).count()
    }

    /// The centre of mass, in metres (each particle weighed by its mass).
    pub fn centre_of_mass(&self) -> Vec3 {
        let (moment, mass) = (0..self.len()).fold((glam::DVec3::ZERO, 0.0f64), |(moment, mass), i| {
            let m = f64::from(self.particle_mass(i));
            (moment + m * self.position(i).as_dvec3(), mass + m)
        });
        (moment / mass).as_vec3()
    }

    /// Total mechanical energy in joules: kinetic + spring potential − work of the uniform
    /// acceleration (gravity and external force, taken from the origin).
    pub fn energy(&self) -> f64 {
        let model = ForceModel::new(&self.params);
        let g = model.uniform_accel.as_dvec3();
        let k_per_weight = model.k_over_mass.map(|k| f64::from(k) * f64::from(self.params.mass));
        let mut e = 0.0f64;
        for i in 0..self.len() {
            let m = f64::from(self.particle_mass(i));
            let (p, v) = (self.position(i).as_dvec3(), self.velocity(i).as_dvec3());
            e += 0.5 * m * v.length_squared() - m * g.dot(p);
            for end in self.topology.springs_of(i).iter().filter(|end| end.other as usize > i) {
                let q = self.position(end.other as usize).as_dvec3();
                let stretch = (q - p).length() - f64::from(end.rest);
                e += 0.5 * k_per_weight[end.kind as usize] * f64::from(end.weight) * stretch * stretch;
            }
        }
        e
    }
}
