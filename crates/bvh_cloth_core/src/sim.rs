//! The CPU stepper: a whole cloth of any [`ClothTopology`] advanced by RK4 or semi-implicit
//! Euler, with collision response fused into the last stage of every substep (paper Fig. 1),
//! or by block descent ([`crate::block_descent`]).
//!
//! This is the reference the GPU kernels are checked against and a real backend for machines
//! without compute shaders. Rows are processed in parallel with rayon; every particle's result
//! depends only on the previous stage's buffers, never on which thread ran it, so a step is
//! bit-identical whatever the number of threads.

use std::sync::Arc;

use glam::{Affine3A, Vec3, Vec3A};
use rayon::prelude::*;

use crate::aerodynamics::{Air, AirModel, AirSource, Wind, WindSource};
use crate::block_descent::BlockDescent;
use crate::collider::Collider;
use crate::collision::ColliderFrame;
use crate::error::ClothError;
use crate::forces::{ForceModel, LANES, SpringScratch};
use crate::params::{ClothParams, Integrator};
use crate::self_contact::{ContactBody, ContactSolver, ContactStats, SelfContact};
use crate::tethers::TetherSet;
use crate::topology::ClothTopology;

/// Rows per band: the unit of parallel work, and of spring reuse (see
/// [`ForceModel::band_acceleration`]). It is fixed, so results do not depend on the thread count.
const BAND_ROWS: usize = 8;

/// Particles per row of the state layout when the topology is not the grid (the grid's rows
/// are its own).
const GENERAL_ROW: usize = 64;

/// What one [`ClothSim::tick`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Ticked {
    /// Substeps run (`looper`, or more when the stability guard asked for them).
    pub substeps: u32,
    /// Particles the tick left with a NaN or infinite position or velocity: 0 for a healthy
    /// cloth. A cloth that went non-finite stays so; reset it ([`ClothSim::reset`]) or give it
    /// parameters that [`ClothParams::check_tick`] accepts.
    pub non_finite: usize,
}

impl Ticked {
    /// Whether the tick left any particle non-finite.
    pub fn diverged(&self) -> bool {
        self.non_finite > 0
    }
}

/// A simulated cloth.
#[derive(Clone, Debug)]
pub struct ClothSim {
    params: ClothParams,
    topology: Arc<ClothTopology>,
    /// Particles per row of the state layout; the last row may be padded.
    width: usize,
    /// Current state, row layout (see [`crate::forces`]).
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

/// What one stage of the integrator does with the slope `k = f(src)` of each particle.
#[derive(Clone, Copy, Debug)]
enum Stage {
    /// RK4 stages 1–3: `slope_sum (=|+=) weight k`, `out = base + coef h k`.
    Intermediate { first: bool, weight: f32, coef: f32 },
    /// RK4 stage 4: `out = base + h/6 (slope_sum + k)`, then collision.
    Rk4Final,
    /// Semi-implicit Euler: `v' = v + h a`, `x' = x + h v'`, then collision.
    Euler,
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
        self.params = params;
        Ok(())
    }

    /// Sets the air the cloth moves in: its ambient `wind` and the `sources` in reach (see
    /// [`crate::aerodynamics`]). Only a cloth whose [`ClothParams::aerodynamics`] is active
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
    /// ([`crate::tethers`]; empty for a cloth with no pin).
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

    /// Advances one tick of `dt` seconds: `looper` substeps of equal length (more when the
    /// stability guard asks for them, see [`ClothParams::substeps`]), each followed by collision
    /// against every collider. Returns the substeps run and how many particles went
    /// non-finite. An explicit integrator that would need more substeps than the guard takes
    /// goes non-finite: check the parameters against the tick with [`ClothParams::check_tick`]
    /// first (the plugin does).
    pub fn tick(&mut self, dt: f32, colliders: &[Collider]) -> Ticked {
        if !(dt.is_finite() && dt > 0.0) {
            return Ticked { substeps: 0, non_finite: self.non_finite_particles() };
        }
        let substeps = self.substeps(dt);
        let h = dt / substeps as f32;
        self.sample_air();
        if let Integrator::BlockDescent { iterations } = self.params.integrator {
            self.descend(h, substeps, iterations, colliders);
        } else {
            for _ in 0..substeps {
                self.explicit_substep(h, colliders);
            }
        }
        self.wind_time += f64::from(dt);
        Ticked { substeps, non_finite: self.non_finite_particles() }
    }

    /// Runs `substeps` block-descent substeps of `h` seconds on positions kept by particle.
    fn descend(&mut self, h: f32, substeps: u32, iterations: u32, colliders: &[Collider]) {
        let frames: Vec<ColliderFrame<'_>> = colliders.iter().filter_map(ColliderFrame::new).collect();
        let model = ForceModel::new(&self.params);
        let n = self.len();
        let mut descent = core::mem::take(&mut self.descent);
        descent.resize(n);
        let free_body = self.is_free_body();
        let tether_set = Arc::clone(&self.tethers);
        let tethers = self.params.tethers.filter(|_| !tether_set.is_empty()).map(|t| (&*tether_set, 1.0 + t.slack));
        let w = self.width;
        for (r, row) in self.state.chunks_exact(LANES * w).enumerate() {
            for c in 0..w.min(n.saturating_sub(r * w)) {
                descent.x[r * w + c] = Vec3A::new(row[c], row[w + c], row[2 * w + c]);
                descent.v[r * w + c] = Vec3A::new(row[3 * w + c], row[4 * w + c], row[5 * w + c]);
            }
        }
        for _ in 0..substeps {
            if self.params.self_contact.is_some() {
                self.contact_prev.clear();
                self.contact_prev.extend(descent.x.iter().map(|&p| Vec3::from(p)));
            }
            if let Some(model) = self.air_model {
                self.air.kick(&model, &self.topology, &self.free[..n], h, &descent.x, &mut descent.v);
            }
            descent.substep(
                &self.topology,
                &model,
                &self.free[..n],
                &mut self.held[..n],
                h,
                iterations,
                free_body,
                tethers,
                &frames,
            );
            if let Some(contact) = self.params.self_contact {
                self.contact_x.clear();
                self.contact_x.extend(descent.x.iter().map(|&p| Vec3::from(p)));
                self.contact_v.clear();
                self.contact_v.extend(descent.v.iter().map(|&p| Vec3::from(p)));
                self.resolve_own_contact(contact, &frames);
                for (k, (p, v)) in self.contact_x.iter().zip(&self.contact_v).enumerate() {
                    (descent.x[k], descent.v[k]) = (Vec3A::from(*p), Vec3A::from(*v));
                }
            }
        }
        for (r, row) in self.state.chunks_exact_mut(LANES * w).enumerate() {
            for c in 0..w.min(n.saturating_sub(r * w)) {
                let (p, v) = (descent.x[r * w + c], descent.v[r * w + c]);
                for (lane, value) in [p.x, p.y, p.z, v.x, v.y, v.z].into_iter().enumerate() {
                    row[lane * w + c] = value;
                }
            }
        }
        self.descent = descent;
    }

    /// Advances one substep of `h` seconds (the aerodynamic kick, with the wind sampled at the
    /// wind clock's time, then integration, collision and self-contact). The wind clock does
    /// not move.
    pub fn substep(&mut self, h: f32, colliders: &[Collider]) {
        self.sample_air();
        if let Integrator::BlockDescent { iterations } = self.params.integrator {
            self.descend(h, 1, iterations, colliders);
            return;
        }
        self.explicit_substep(h, colliders);
    }

    /// One substep of an explicit integrator, with this tick's air already sampled.
    fn explicit_substep(&mut self, h: f32, colliders: &[Collider]) {
        let Some(contact) = self.params.self_contact else {
            self.integrate(h, colliders);
            return;
        };
        let (mut prev, mut x, mut v) = (
            core::mem::take(&mut self.contact_prev),
            core::mem::take(&mut self.contact_x),
            core::mem::take(&mut self.contact_v),
        );
        self.read_positions(&mut prev);
        self.integrate(h, colliders);
        self.read_state(&mut x, &mut v);
        (self.contact_prev, self.contact_x, self.contact_v) = (prev, x, v);
        let frames: Vec<ColliderFrame<'_>> = colliders.iter().filter_map(ColliderFrame::new).collect();
        self.resolve_own_contact(contact, &frames);
        let (x, v) = (core::mem::take(&mut self.contact_x), core::mem::take(&mut self.contact_v));
        self.write_state(&x, &v);
        (self.contact_x, self.contact_v) = (x, v);
    }

    /// This cloth's self-contact on the particles in `contact_prev`, `contact_x` and
    /// `contact_v` (the substep's start, and its end), in place.
    fn resolve_own_contact(&mut self, contact: SelfContact, frames: &[ColliderFrame<'_>]) {
        let n = self.topology.len();
        let mut body = [ContactBody {
            topology: &self.topology,
            contact,
            free: &self.free[..n],
            held: &self.held[..n],
            prev: &self.contact_prev,
            x: &mut self.contact_x,
            v: &mut self.contact_v,
        }];
        self.contact.resolve(&mut body, frames);
    }

    /// Steps several cloths together for a tick of `dt` seconds, so that the ones with
    /// self-contact also keep off each other ([`crate::self_contact`]): every cloth takes the
    /// largest substep count among them, and after each substep the contacts of all of them
    /// are resolved at once by `solver`. Returns the substeps run and the last substep's
    /// contact figures.
    pub fn tick_together(
        sims: &mut [&mut ClothSim],
        dt: f32,
        colliders: &[Collider],
        solver: &mut ContactSolver,
    ) -> (u32, ContactStats) {
        if !(dt.is_finite() && dt > 0.0) || sims.is_empty() {
            return (0, ContactStats::default());
        }
        let substeps = sims.iter().map(|s| s.substeps(dt)).max().unwrap_or(1);
        let h = dt / substeps as f32;
        let frames: Vec<ColliderFrame<'_>> = colliders.iter().filter_map(ColliderFrame::new).collect();
        let mut stats = ContactStats::default();
        let mut states: Vec<(Vec<Vec3>, Vec<Vec3>, Vec<Vec3>)> =
            sims.iter().map(|_| (Vec::new(), Vec::new(), Vec::new())).collect();
        for sim in sims.iter_mut() {
            sim.sample_air();
        }
        for _ in 0..substeps {
            for (sim, (prev, _, _)) in sims.iter_mut().zip(states.iter_mut()) {
                if sim.params.self_contact.is_some() {
                    sim.read_positions(prev);
                }
                match sim.params.integrator {
                    Integrator::BlockDescent { iterations } => {
                        // One substep, its contact left to the joint pass below.
                        let contact = sim.params.self_contact.take();
                        sim.descend(h, 1, iterations, colliders);
                        sim.params.self_contact = contact;
                    }
                    _ => sim.integrate(h, colliders),
                }
            }
            let mut bodies = Vec::with_capacity(sims.len());
            for (sim, (prev, x, v)) in sims.iter().zip(states.iter_mut()) {
                let Some(contact) = sim.params.self_contact else { continue };
                sim.read_state(x, v);
                let free = &sim.free[..sim.len()];
                bodies.push(ContactBody {
                    topology: &sim.topology,
                    contact,
                    free,
                    held: &sim.held[..sim.len()],
                    prev,
                    x,
                    v,
                });
            }
            if bodies.is_empty() {
                continue;
            }
            stats = solver.resolve(&mut bodies, &frames);
            drop(bodies);
            for (sim, (_, x, v)) in sims.iter_mut().zip(&states) {
                if sim.params.self_contact.is_some() {
                    sim.write_state(x, v);
                }
            }
        }
        for sim in sims.iter_mut() {
            sim.wind_time += f64::from(dt);
        }
        (substeps, stats)
    }

    /// Every particle's position and velocity, into `x` and `v`.
    fn read_state(&self, x: &mut Vec<Vec3>, v: &mut Vec<Vec3>) {
        self.read_positions(x);
        v.clear();
        v.extend((0..self.len()).map(|i| self.velocity(i)));
    }

    /// Every particle's position, into `x`.
    fn read_positions(&self, x: &mut Vec<Vec3>) {
        x.clear();
        x.extend((0..self.len()).map(|i| self.position(i)));
    }

    /// Sets every particle's position and velocity from `x` and `v`.
    fn write_state(&mut self, x: &[Vec3], v: &[Vec3]) {
        for (i, (&p, &vel)) in x.iter().zip(v).enumerate() {
            self.set_position(i, p);
            self.set_velocity(i, vel);
        }
    }

    /// One substep of an explicit integrator: integration with collision fused into its last
    /// stage.
    fn integrate(&mut self, h: f32, colliders: &[Collider]) {
        self.kick_explicit(h);
        let frames: Vec<ColliderFrame<'_>> = colliders.iter().filter_map(ColliderFrame::new).collect();
        let model = ForceModel::new(&self.params);
        match self.params.integrator {
            Integrator::Rk4 => {
                let stages = [
                    Stage::Intermediate { first: true, weight: 1.0, coef: 0.5 },
                    Stage::Intermediate { first: false, weight: 2.0, coef: 0.5 },
                    Stage::Intermediate { first: false, weight: 2.0, coef: 1.0 },
                ];
                // y -> a -> b -> a, then the final stage reads a and writes b.
                self.run_stage(&model, h, &frames, stages[0], Src::State, Dst::A);
                self.run_stage(&model, h, &frames, stages[1], Src::A, Dst::B);
                self.run_stage(&model, h, &frames, stages[2], Src::B, Dst::A);
                self.run_stage(&model, h, &frames, Stage::Rk4Final, Src::A, Dst::B);
                core::mem::swap(&mut self.state, &mut self.stage_b);
            }
            Integrator::SemiImplicitEuler => {
                self.run_stage(&model, h, &frames, Stage::Euler, Src::State, Dst::A);
                core::mem::swap(&mut self.state, &mut self.stage_a);
            }
            Integrator::BlockDescent { .. } => unreachable!("block descent returned above"),
        }
    }

    fn run_stage(
        &mut self,
        model: &ForceModel,
        h: f32,
        frames: &[ColliderFrame<'_>],
        stage: Stage,
        src: Src,
        dst: Dst,
    ) {
        let width = self.width;
        let w = LANES * width;
        let Self { state, stage_a, stage_b, slope_sum, free, held, topology, .. } = self;
        let topology: &ClothTopology = topology;
        let (src, out): (&[f32], &mut [f32]) = match (src, dst) {
            (Src::State, Dst::A) => (state, stage_a),
            (Src::A, Dst::B) => (stage_a, stage_b),
            (Src::B, Dst::A) => (stage_b, stage_a),
            _ => unreachable!("stage buffers are used in a fixed order"),
        };
        let base: &[f32] = state;
        let free: &[f32] = free;
        let band_len = BAND_ROWS * w;
        let collides = matches!(stage, Stage::Rk4Final | Stage::Euler);
        out.par_chunks_mut(band_len)
            .zip(slope_sum.par_chunks_mut(band_len))
            .zip(held.par_chunks_mut(BAND_ROWS * width))
            .enumerate()
            .for_each_init(
                || (vec![0.0f32; 3 * width * BAND_ROWS], SpringScratch::default()),
                |(acc, scratch), (b, ((out_band, sum_band), held_band))| {
                    let first = b * BAND_ROWS;
                    let band = first..first + out_band.len() / w;
                    match topology.stencil() {
                        Some(grid) => {
                            let inv_share = topology.inv_mass_share()[0];
                            model.band_acceleration(grid, inv_share, src, free, band.clone(), acc, scratch);
                        }
                        None => model.band_acceleration_general(topology, width, src, free, band.clone(), acc),
                    }
                    for (j, r) in band.enumerate() {
                        let row = r * w..(r + 1) * w;
                        let (out_row, sum_row) = (&mut out_band[j * w..(j + 1) * w], &mut sum_band[j * w..(j + 1) * w]);
                        let acc_row = &acc[j * 3 * width..(j + 1) * 3 * width];
                        let (src_row, base_row) = (&src[row.clone()], &base[row]);
                        let free_row = &free[r * width..(r + 1) * width];
                        integrate_row(stage, h, width, src_row, base_row, free_row, acc_row, sum_row, out_row);
                        if collides {
                            let held_row = &mut held_band[j * width..(j + 1) * width];
                            collide_row(frames, width, base_row, free_row, out_row, held_row);
                        }
                    }
                },
            );
    }
}

#[derive(Clone, Copy)]
enum Src {
    State,
    A,
    B,
}

#[derive(Clone, Copy)]
enum Dst {
    A,
    B,
}

/// Applies one integrator stage to a row. `acc` holds `[ax | ay | az]` of `src`.
#[allow(clippy::too_many_arguments)]
fn integrate_row(
    stage: Stage,
    h: f32,
    cols: usize,
    src: &[f32],
    base: &[f32],
    free: &[f32],
    acc: &[f32],
    sum: &mut [f32],
    out: &mut [f32],
) {
    // The slope of lane l (0..6) at column i: the velocity (zero when pinned) for the position
    // lanes, the acceleration for the velocity lanes. Each lane runs one branch-free loop, so
    // that it vectorises.
    let velocity = &src[3 * cols..];
    match stage {
        Stage::Intermediate { first, weight, coef } => {
            let ch = coef * h;
            for l in 0..3 {
                let (v, a) = (&velocity[l * cols..(l + 1) * cols], &acc[l * cols..(l + 1) * cols]);
                for (o, slope) in [(l * cols, Slope::Masked(v, free)), ((l + 3) * cols, Slope::Plain(a))] {
                    let (out, sum, base) = (&mut out[o..o + cols], &mut sum[o..o + cols], &base[o..o + cols]);
                    slope.for_each(|i, k| {
                        sum[i] = if first { k } else { sum[i] + weight * k };
                        out[i] = base[i] + ch * k;
                    });
                }
            }
        }
        Stage::Rk4Final => {
            let h6 = h / 6.0;
            for l in 0..3 {
                let (v, a) = (&velocity[l * cols..(l + 1) * cols], &acc[l * cols..(l + 1) * cols]);
                for (o, slope) in [(l * cols, Slope::Masked(v, free)), ((l + 3) * cols, Slope::Plain(a))] {
                    let (out, sum, base) = (&mut out[o..o + cols], &sum[o..o + cols], &base[o..o + cols]);
                    slope.for_each(|i, k| out[i] = base[i] + h6 * (sum[i] + k));
                }
            }
        }
        Stage::Euler => {
            for l in 3..LANES {
                let o = l * cols;
                for i in 0..cols {
                    out[o + i] = base[o + i] + h * acc[(l - 3) * cols + i];
                }
            }
            for l in 0..3 {
                let o = l * cols;
                for i in 0..cols {
                    out[o + i] = base[o + i] + h * out[(l + 3) * cols + i] * free[i];
                }
            }
        }
    }
}

/// The slope of one lane of a row: a velocity masked by `free` (position lanes) or an
/// acceleration (velocity lanes).
#[derive(Clone, Copy)]
enum Slope<'a> {
    Masked(&'a [f32], &'a [f32]),
    Plain(&'a [f32]),
}

impl Slope<'_> {
    /// Calls `f(i, slope_i)` for every column, with the variant chosen outside the loop so that
    /// each loop vectorises.
    #[inline(always)]
    fn for_each(self, mut f: impl FnMut(usize, f32)) {
        match self {
            Slope::Masked(v, free) => {
                let free = &free[..v.len()];
                for i in 0..v.len() {
                    f(i, v[i] * free[i]);
                }
            }
            Slope::Plain(a) => {
                for (i, &k) in a.iter().enumerate() {
                    f(i, k);
                }
            }
        }
    }
}

/// Collision response for every free particle of a row, from its position before the substep
/// (`base`) to after it (`out`).
fn collide_row(
    frames: &[ColliderFrame<'_>],
    cols: usize,
    base: &[f32],
    free: &[f32],
    out: &mut [f32],
    held: &mut [f32],
) {
    let get = |buf: &[f32], i: usize, l: usize| {
        Vec3::new(buf[l * cols + i], buf[(l + 1) * cols + i], buf[(l + 2) * cols + i])
    };
    for i in 0..cols {
        held[i] = 0.0;
        if free[i] == 0.0 || frames.is_empty() {
            continue;
        }
        let prev = get(base, i, 0);
        let mut p = get(out, i, 0);
        let mut v = get(out, i, 3);
        let mut hit = false;
        for frame in frames {
            hit |= frame.resolve(prev, &mut p, &mut v);
        }
        held[i] = f32::from(u8::from(hit));
        if hit {
            for (l, value) in [p.x, p.y, p.z, v.x, v.y, v.z].into_iter().enumerate() {
                out[l * cols + i] = value;
            }
        }
    }
}
