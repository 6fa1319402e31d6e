//! Two cloths that already cross: which particles lie on the wrong side of the other cloth,
//! so that their contacts with it take them back through (a global intersection analysis after
//! Baraff, Witkin and Kass 2003, "Untangling Cloth", for two bodies). See the
//! [module docs](super).

use std::collections::HashMap;

use glam::Vec3A;
use rayon::prelude::*;

use super::{ContactBody, ContactSolver, MAX_SPAN};
use crate::cloth::topology::ClothTopology;
use crate::mesh::triangles::triangles_intersect;

/// No body: a particle on the right side of every other.
pub(super) const NO_BODY: u32 = u32::MAX;

/// Resolutions between two tests for crossing bodies while none cross: a tick at Looper 16, so
/// that two cloths something forces through each other are found within a tick, and the test
/// costs a sixteenth of a pass of the grid where nothing crosses.
pub(super) const UNTANGLE_EVERY: u32 = 16;

impl ContactSolver {
    /// Marks in `wrong_side` (by flat particle index) the particles that lie on the wrong side
    /// of another body at the substep's start, with that body's index ([`NO_BODY`] for the
    /// others); returns how many it marked.
    ///
    /// For every two bodies whose triangles intersect there: the triangles of each that meet
    /// the other cut it, and its other triangles fall into the parts the cuts leave, joined
    /// across shared edges. The largest part lies on the right side of the other body; the
    /// corners of the other parts' triangles and of the cut triangles that are no corner of a
    /// triangle of the largest part lie through it, on the wrong side. Of the two bodies, the
    /// one with fewer particles on the wrong side is taken back: those particles are marked.
    /// Where neither body has any (each cut leaves all its corners on the largest part, as
    /// where only an edge of each passes through the other), nothing is marked. After a test
    /// that finds no two bodies crossing, the next [`UNTANGLE_EVERY`] - 1 resolutions skip it.
    pub(super) fn find_wrong_sides(&mut self, bodies: &[ContactBody<'_>]) -> usize {
        self.wrong_side.clear();
        self.wrong_side.resize(self.x.len(), NO_BODY);
        if bodies.len() < 2 {
            return 0;
        }
        if self.untangle_wait > 0 {
            self.untangle_wait -= 1;
            return 0;
        }
        let count = self.triangles.len() as u32;
        let corners = |t: u32| self.triangles[t as usize].1.map(|k| self.prev[k as usize]);
        // Every pair of triangles of two bodies that meet each other, once.
        let pairs: Vec<(u32, u32)> = (0..count)
            .into_par_iter()
            .flat_map_iter(|t| {
                let (tb, _) = self.triangles[t as usize];
                let at = corners(t);
                let lo = Vec3A::from(at[0].min(at[1]).min(at[2]));
                let hi = Vec3A::from(at[0].max(at[1]).max(at[2]));
                let mut met = Vec::new();
                self.grid.visit(lo, hi, MAX_SPAN, t + 1..count, |u| {
                    let (ub, _) = self.triangles[u as usize];
                    if ub != tb
                        && bodies[tb as usize].layers.interacts_with(bodies[ub as usize].layers)
                        && triangles_intersect(at, corners(u))
                    {
                        met.push((t, u));
                    }
                });
                met
            })
            .collect();
        if pairs.is_empty() {
            self.untangle_wait = UNTANGLE_EVERY - 1;
            return 0;
        }
        // Each pair of bodies that cross, and the triangles of each that the other cuts.
        let mut crossing: HashMap<(u32, u32), (Vec<u32>, Vec<u32>)> = HashMap::new();
        for &(t, u) in &pairs {
            let (tb, ub) = (self.triangles[t as usize].0, self.triangles[u as usize].0);
            let ((a, ta), (b, ub_t)) = if tb < ub { ((tb, t), (ub, u)) } else { ((ub, u), (tb, t)) };
            let cuts = crossing.entry((a, b)).or_default();
            cuts.0.push(ta);
            cuts.1.push(ub_t);
        }
        let mut pairs_of_bodies: Vec<_> = crossing.into_iter().collect();
        pairs_of_bodies.sort_unstable_by_key(|(bodies, _)| *bodies);
        let mut marked = 0;
        for ((a, b), (cut_a, cut_b)) in pairs_of_bodies {
            let shape = |body: u32| bodies[body as usize].topology;
            let parts = [self.wrong_part(a, shape(a), &cut_a), self.wrong_part(b, shape(b), &cut_b)];
            let chosen = match parts {
                [Some(pa), Some(pb)] => Some(if pa.len() <= pb.len() { (pa, b) } else { (pb, a) }),
                [Some(pa), None] => Some((pa, b)),
                [None, Some(pb)] => Some((pb, a)),
                [None, None] => None,
            };
            if let Some((particles, other)) = chosen {
                for k in particles {
                    if self.wrong_side[k as usize] == NO_BODY {
                        self.wrong_side[k as usize] = other;
                        marked += 1;
                    }
                }
            }
        }
        marked
    }

    /// The particles of body `body` (whose shape is `topology`) on the wrong side of the body
    /// whose cuts of it are `cut` (flat triangle indices): the corners of the cut triangles and
    /// of the parts the cuts leave besides the largest, less the corners of the largest part's
    /// triangles; `None` for none.
    fn wrong_part(&self, body: u32, topology: &ClothTopology, cut: &[u32]) -> Option<Vec<u32>> {
        // The body's first triangle and first particle (flat indices): its triangles and
        // particles are in the topology's order from there.
        let first = self.triangles.partition_point(|&(b, _)| b < body);
        let first_particle = self.owner.partition_point(|&(b, _)| b < body) as u32;
        let triangles = topology.triangles();
        let mut is_cut = vec![false; triangles.len()];
        for &t in cut {
            is_cut[t as usize - first] = true;
        }
        // The parts: a flood over the triangles that share an edge (two corners) with each.
        const UNSET: u32 = u32::MAX;
        let mut part = vec![UNSET; triangles.len()];
        let mut sizes = Vec::new();
        let mut stack = Vec::new();
        for seed in 0..triangles.len() {
            if is_cut[seed] || part[seed] != UNSET {
                continue;
            }
            let id = sizes.len() as u32;
            sizes.push(0usize);
            part[seed] = id;
            stack.push(seed as u32);
            while let Some(t) = stack.pop() {
                sizes[id as usize] += 1;
                let c = triangles[t as usize];
                for [p, q] in [[c[0], c[1]], [c[1], c[2]], [c[2], c[0]]] {
                    let beside = topology.triangles_of(q as usize);
                    for &u in topology.triangles_of(p as usize).iter().filter(|u| beside.contains(u)) {
                        if !is_cut[u as usize] && part[u as usize] == UNSET {
                            part[u as usize] = id;
                            stack.push(u);
                        }
                    }
                }
            }
        }
        let largest = (0..sizes.len()).max_by_key(|&k| (sizes[k], usize::MAX - k))? as u32;
        // Each particle: a corner of the largest part, and a corner of the rest.
        let (mut right, mut rest) = (vec![false; topology.len()], vec![false; topology.len()]);
        for (c, &part) in triangles.iter().zip(&part) {
            let side = if part == largest { &mut right } else { &mut rest };
            for &k in c {
                side[k as usize] = true;
            }
        }
        let wrong: Vec<u32> =
            (0..topology.len()).filter(|&k| rest[k] && !right[k]).map(|k| first_particle + k as u32).collect();
        (!wrong.is_empty()).then_some(wrong)
    }
}
