//! A tick: its substeps by the cloth's integrator, collision after each, and several cloths
//! stepped together so that they collide with each other.

use std::sync::Arc;

use glam::{Vec3, Vec3A};

use super::*;
use crate::colliders::collider::Collider;
use crate::colliders::collision::ColliderFrame;
use crate::self_contact::{ContactBody, ContactSolver, ContactStats, SelfContact, shared_substeps};
use crate::solver::block_descent::Solve;
use crate::solver::forces::{ForceModel, LANES};
use crate::solver::params::Integrator;

impl ClothSim {
    /// Advances one tick of `dt` seconds: `looper` substeps of equal length (more when the
    /// stability guard asks for them, see [`ClothParams::substeps`]), each followed by collision
    /// against every collider. Returns the substeps run and how many particles went
    /// non-finite. An explicit integrator that would need more substeps than the guard takes
    /// goes non-finite: check the parameters against the tick with [`ClothParams::check_tick`]
    /// first (the plugin does).
    ///
    /// The tick runs on a thread of rayon's pool, which its parallel passes share from there:
    /// called from outside the pool, it hands the pool one job a tick rather than one per pass
    /// (a block-descent substep has a pass per colour, and the multigrid correction several
    /// more), and between passes the pool's threads are less often asleep.
    pub fn tick(&mut self, dt: f32, colliders: &[Collider]) -> Ticked {
        rayon::scope(|_| self.tick_in_pool(dt, colliders))
    }

    /// [`Self::tick`], on the thread it is called from.
    fn tick_in_pool(&mut self, dt: f32, colliders: &[Collider]) -> Ticked {
        self.quarantined = 0;
        if !(dt.is_finite() && dt > 0.0) {
            return self.ticked(0);
        }
        let substeps = self.substeps(dt);
        let h = dt / substeps as f32;
        self.sample_air();
        if self.params.integrator.is_explicit() {
            for _ in 0..substeps {
                self.explicit_substep(h, colliders);
            }
        } else {
            self.descend(h, substeps, colliders);
        }
        self.wind_time += f64::from(dt);
        self.ticked(substeps)
    }

    /// What the tick that ran `substeps` did.
    fn ticked(&self, substeps: u32) -> Ticked {
        Ticked { substeps, non_finite: self.non_finite_particles(), quarantined: self.quarantined }
    }

    /// Runs `substeps` block-descent or multigrid substeps of `h` seconds on positions kept by
    /// particle.
    fn descend(&mut self, h: f32, substeps: u32, colliders: &[Collider]) {
        let frames = self.frames(colliders);
        let model = ForceModel::new(&self.params);
        let n = self.len();
        let mut descent = core::mem::take(&mut self.descent);
        descent.resize(n);
        let free_body = self.is_free_body();
        let tether_set = Arc::clone(&self.tethers);
        let solve = match self.params.integrator {
            Integrator::BlockDescent { iterations } => Solve::Sweeps {
                iterations,
                tethers: self.params.tethers.filter(|_| !tether_set.is_empty()).map(|t| (&*tether_set, 1.0 + t.slack)),
            },
            _ => Solve::Multigrid,
        };
        let w = self.width;
        // BDF2 builds on the last substep only if nothing changed a free particle since.
        let mut changed = false;
        for (r, row) in self.state.chunks_exact(LANES * w).enumerate() {
            for c in 0..w.min(n.saturating_sub(r * w)) {
                let i = r * w + c;
                let (x, v) = (
                    Vec3A::new(row[c], row[w + c], row[2 * w + c]),
                    Vec3A::new(row[3 * w + c], row[4 * w + c], row[5 * w + c]),
                );
                changed |= self.free[i] != 0.0 && (x != descent.x[i] || v != descent.v[i]);
                (descent.x[i], descent.v[i]) = (x, v);
            }
        }
        if changed {
            descent.history = None;
        }
        for _ in 0..substeps {
            if self.params.self_contact.is_some() {
                self.contact_prev.clear();
                self.contact_prev.extend(descent.x.iter().map(|&p| Vec3::from(p)));
            }
            if let Some(model) = self.air_model {
                descent.before_kick();
                self.air.kick(&model, &self.topology, &self.free[..n], h, &descent.x, &mut descent.v);
            }
            self.quarantined += descent.substep(
                &self.topology,
                &model,
                &self.free[..n],
                &mut self.held[..n],
                h,
                solve,
                free_body,
                &frames,
            );
            if let Some(contact) = self.params.self_contact {
                self.contact_x.clear();
                self.contact_x.extend(descent.x.iter().map(|&p| Vec3::from(p)));
                self.contact_v.clear();
                self.contact_v.extend(descent.v.iter().map(|&p| Vec3::from(p)));
                self.resolve_own_contact(contact, &frames);
                for (k, (p, v)) in self.contact_x.iter().zip(&self.contact_v).enumerate() {
                    let (p, v) = (Vec3A::from(*p), Vec3A::from(*v));
                    if p != descent.x[k] || v != descent.v[k] {
                        descent.moved_by_contact(k);
                    }
                    (descent.x[k], descent.v[k]) = (p, v);
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
        if self.params.integrator.is_explicit() {
            self.explicit_substep(h, colliders);
        } else {
            self.descend(h, 1, colliders);
        }
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
        let frames = self.frames(colliders);
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
            layers: self.params.layers,
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
    /// are resolved at once by `solver`. Returns what the tick did to each cloth, in order (as
    /// [`ClothSim::tick`] does for one), and the last substep's contact figures.
    ///
    /// As [`Self::tick`], the tick runs on a thread of rayon's pool.
    pub fn tick_together(
        sims: &mut [&mut ClothSim],
        dt: f32,
        colliders: &[Collider],
        solver: &mut ContactSolver,
    ) -> (Vec<Ticked>, ContactStats) {
        rayon::scope(|_| Self::tick_together_in_pool(sims, dt, colliders, solver))
    }

    /// [`Self::tick_together`], on the thread it is called from.
    fn tick_together_in_pool(
        sims: &mut [&mut ClothSim],
        dt: f32,
        colliders: &[Collider],
        solver: &mut ContactSolver,
    ) -> (Vec<Ticked>, ContactStats) {
        for sim in sims.iter_mut() {
            sim.quarantined = 0;
        }
        if !(dt.is_finite() && dt > 0.0) || sims.is_empty() {
            let ticked = sims.iter().map(|sim| sim.ticked(0)).collect();
            return (ticked, ContactStats::default());
        }
        let substeps = shared_substeps(sims.iter().map(|s| s.substeps(dt))).unwrap_or(1);
        let h = dt / substeps as f32;
        // Every usable collider: the contact pass checks each body's layers against them.
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
                if sim.params.integrator.is_explicit() {
                    sim.integrate(h, colliders);
                } else {
                    // One substep, its contact left to the joint pass below.
                    let contact = sim.params.self_contact.take();
                    sim.descend(h, 1, colliders);
                    sim.params.self_contact = contact;
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
                    layers: sim.params.layers,
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
                    // What the joint pass moved, the multigrid correction leaves alone in the
                    // next substep, as after a cloth's own pass.
                    if sim.params.integrator == Integrator::Multigrid {
                        for (k, (p, u)) in x.iter().zip(v).enumerate() {
                            if *p != sim.position(k) || *u != sim.velocity(k) {
                                sim.descent.moved_by_contact(k);
                            }
                        }
                    }
                    sim.write_state(x, v);
                }
            }
        }
        for sim in sims.iter_mut() {
            sim.wind_time += f64::from(dt);
        }
        (sims.iter().map(|sim| sim.ticked(substeps)).collect(), stats)
    }
}
