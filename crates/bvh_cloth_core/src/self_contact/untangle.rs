//! Cloth that already crosses: which particles lie on the wrong side of another cloth, or of
//! another sheet of their own cloth, so that their contacts with it take them back through (a
//! global intersection analysis after Baraff, Witkin and Kass 2003, "Untangling Cloth"). See
//! the [module docs](super).

use std::collections::{BTreeSet, HashMap};

use rayon::prelude::*;

use super::{ContactBody, ContactSolver};
use crate::cloth::topology::ClothTopology;
use crate::mesh::triangles::{share_a_corner, triangles_intersect};

/// No body: a particle on the right side of every other.
pub(super) const NO_BODY: u32 = u32::MAX;

/// Resolutions between two tests for crossing cloth while none crosses: a tick at Looper 16,
/// so that cloth something forces through itself or another is found within a tick, and the
/// test costs a sixteenth of a test of the pairs the search found where nothing crosses.
pub const UNTANGLE_EVERY: u32 = 16;

/// A triangle in no part or ring (the floods' mark).
const UNSET: u32 = u32::MAX;

impl ContactSolver {
    /// Marks in `wrong_side` (by flat particle index) the particles that lie on the wrong side
    /// of another body, or of another sheet of their own body, at the substep's start, with
    /// that body's or sheet's label (`sheet`: a body's particles carry the body's index, and a
    /// sheet of one body that another sheet of it passes through gets a label of its own);
    /// returns how many it marked.
    ///
    /// For every two bodies whose triangles intersect there: the triangles of each that meet
    /// the other cut it, and its other triangles fall into the parts the cuts leave, joined
    /// across shared edges. The largest part lies on the right side of the other body; the
    /// corners of the other parts' triangles and of the cut triangles that are no corner of a
    /// triangle of the largest part lie through it, on the wrong side. Of the two bodies, the
    /// one with fewer particles on the wrong side is taken back: those particles are marked.
    /// Where neither body has any (each cut leaves all its corners on the largest part, as
    /// where only an edge of each passes through the other), nothing is marked. Within one
    /// body, see [`Self::self_crossings`]. After a test that finds nothing crossing, the next
    /// [`UNTANGLE_EVERY`] - 1 resolutions skip it.
    pub(super) fn find_wrong_sides(&mut self, bodies: &[ContactBody<'_>], near: &[(u32, u32)]) -> usize {
        self.wrong_side.clear();
        self.wrong_side.resize(self.x.len(), NO_BODY);
        self.tangled = false;
        if self.untangle_wait > 0 {
            self.untangle_wait -= 1;
            return 0;
        }
        let corners = |t: u32| self.triangles[t as usize].1.map(|k| self.prev[k as usize]);
        // Every pair of triangles that meet each other, once, among those whose boxes over the
        // substep meet: of two bodies whose layers meet, or of one body sharing no corner and
        // lying farther apart than its thickness in the rest shape (the pairs its contacts
        // test).
        let meets = |&(t, u): &(u32, u32)| {
            let ((tb, tc), (ub, uc)) = (self.triangles[t as usize], self.triangles[u as usize]);
            let tested = if ub == tb {
                let h = bodies[tb as usize].contact.thickness;
                let ([t_lo, t_hi], [u_lo, u_hi]) = (self.tree.rest_boxes[t as usize], self.tree.rest_boxes[u as usize]);
                let neighbours = (t_lo - h).cmple(u_hi).all() && (t_hi + h).cmpge(u_lo).all();
                !(neighbours || share_a_corner(tc, uc))
            } else {
                bodies[tb as usize].layers.interacts_with(bodies[ub as usize].layers)
            };
            tested && triangles_intersect(corners(t), corners(u))
        };
        let pairs: Vec<(u32, u32)> = if near.len() >= super::PARALLEL_MIN {
            near.par_iter().copied().filter(meets).collect()
        } else {
            near.iter().copied().filter(meets).collect()
        };
        if pairs.is_empty() {
            self.untangle_wait = UNTANGLE_EVERY - 1;
            return 0;
        }
        // Every particle's label is its body's until a sheet of one body gets its own (read
        // only while something is marked).
        self.sheet.clear();
        self.sheet.extend(self.owner.iter().map(|&(body, _)| body));
        // Each pair of bodies that cross, and the triangles of each that the other cuts; and
        // each body that crosses itself, with its pairs.
        let mut crossing: HashMap<(u32, u32), (Vec<u32>, Vec<u32>)> = HashMap::new();
        let mut own: HashMap<u32, Vec<(u32, u32)>> = HashMap::new();
        for &(t, u) in &pairs {
            let (tb, ub) = (self.triangles[t as usize].0, self.triangles[u as usize].0);
            if tb == ub {
                own.entry(tb).or_default().push((t, u));
                continue;
            }
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
        let mut own: Vec<_> = own.into_iter().collect();
        own.sort_unstable_by_key(|&(body, _)| body);
        let mut label = bodies.len() as u32;
        for (body, pairs) in own {
            for (wrong, other) in self.self_crossings(body, bodies[body as usize].topology, &pairs) {
                let moved: BTreeSet<u32> = wrong.iter().copied().collect();
                for k in other.into_iter().filter(|k| !moved.contains(k)) {
                    self.sheet[k as usize] = label;
                }
                for k in wrong {
                    if self.wrong_side[k as usize] == NO_BODY {
                        self.wrong_side[k as usize] = label;
                        marked += 1;
                    }
                }
                label += 1;
            }
        }
        self.tangled = marked > 0;
        marked
    }

    /// Whether a contact between the particles `ours` and `theirs` (flat indices) takes the
    /// side opposite the one it is on as the side to go back to: a particle of either lies on
    /// the wrong side of a body or sheet a particle of the other belongs to.
    pub(super) fn inverted(&self, ours: &[u32], theirs: &[u32]) -> bool {
        let through = |a: &[u32], b: &[u32]| {
            a.iter().any(|&k| {
                let wrong = self.wrong_side[k as usize];
                wrong != NO_BODY && b.iter().any(|&c| self.sheet[c as usize] == wrong)
            })
        };
        self.tangled && (through(ours, theirs) || through(theirs, ours))
    }

    /// Where body `body` (of shape `topology`) passes through itself: `pairs` are its
    /// intersecting triangles (flat indices). The triangles in a pair are cut; the cut ones
    /// joined across shared edges form rings (each ring one side of an intersection curve: a
    /// bump of the cloth poked through another sheet of it is ringed on the bump and on the
    /// sheet), and the others fall into parts. A ring's wrong side is the corners of its
    /// triangles and of the parts beside it other than the largest part, less the corners of
    /// the largest part's triangles: what the ring encloses. For every two rings a pair joins,
    /// the one with the fewer particles on its wrong side is taken back through the other:
    /// returns those particles, and the other's (the corners of its triangles and its wrong
    /// side), which get a sheet label of their own. A ring with nothing on its wrong side (a
    /// curve that runs out to the cloth's border on both sides of it, an edge through an edge)
    /// is left alone, as two bodies are.
    fn self_crossings(&self, body: u32, topology: &ClothTopology, pairs: &[(u32, u32)]) -> Vec<(Vec<u32>, Vec<u32>)> {
        let cut = pairs.iter().flat_map(|&(t, u)| [t, u]);
        let Some(Cut { first, first_particle, is_cut, part, parts, largest, on_largest }) =
            self.cut(body, topology, cut)
        else {
            return Vec::new();
        };
        let triangles = topology.triangles();
        let (ring, rings) = flood(topology, |t| is_cut[t]);
        // Each ring's corners, and the parts beside it other than the largest.
        let mut ring_corners: Vec<BTreeSet<u32>> = vec![BTreeSet::new(); rings.len()];
        let mut beside: Vec<BTreeSet<u32>> = vec![BTreeSet::new(); rings.len()];
        for (t, c) in triangles.iter().enumerate().filter(|&(t, _)| is_cut[t]) {
            let r = ring[t] as usize;
            ring_corners[r].extend(c.iter().copied());
            for_each_neighbour(topology, t, |u| {
                if !is_cut[u] && part[u] != largest {
                    beside[r].insert(part[u]);
                }
            });
        }
        let mut part_corners: Vec<Vec<u32>> = vec![Vec::new(); parts];
        for (c, &p) in triangles.iter().zip(&part) {
            if p != UNSET && p != largest {
                part_corners[p as usize].extend(c.iter().copied());
            }
        }
        let wrong_of = |r: usize| -> BTreeSet<u32> {
            let inside = beside[r].iter().flat_map(|&p| part_corners[p as usize].iter().copied());
            ring_corners[r].iter().copied().chain(inside).filter(|&k| !on_largest[k as usize]).collect()
        };
        let wrong: Vec<BTreeSet<u32>> = (0..rings.len()).map(wrong_of).collect();
        let links: BTreeSet<(u32, u32)> = pairs
            .iter()
            .map(|&(t, u)| (ring[t as usize - first], ring[u as usize - first]))
            .filter(|(a, b)| a != b)
            .map(|(a, b)| (a.min(b), a.max(b)))
            .collect();
        let flat = |set: &BTreeSet<u32>| set.iter().map(|&k| first_particle + k).collect::<Vec<u32>>();
        links
            .into_iter()
            .filter_map(|(a, b)| {
                let (a, b) = (a as usize, b as usize);
                let (moved, other) = match (wrong[a].is_empty(), wrong[b].is_empty()) {
                    (true, true) => return None,
                    (false, true) => (a, b),
                    (true, false) => (b, a),
                    (false, false) if wrong[a].len() <= wrong[b].len() => (a, b),
                    (false, false) => (b, a),
                };
                let sheet: BTreeSet<u32> = ring_corners[other].union(&wrong[other]).copied().collect();
                Some((flat(&wrong[moved]), flat(&sheet)))
            })
            .collect()
    }

    /// The particles of body `body` (whose shape is `topology`) on the wrong side of the body
    /// whose cuts of it are `cut` (flat triangle indices): the corners of the cut triangles and
    /// of the parts the cuts leave besides the largest, less the corners of the largest part's
    /// triangles; `None` for none.
    fn wrong_part(&self, body: u32, topology: &ClothTopology, cut: &[u32]) -> Option<Vec<u32>> {
        let Cut { first_particle, part, largest, on_largest, .. } = self.cut(body, topology, cut.iter().copied())?;
        // Each particle that is a corner of a triangle outside the largest part.
        let mut rest = vec![false; topology.len()];
        for (c, _) in topology.triangles().iter().zip(&part).filter(|&(_, &p)| p != largest) {
            for &k in c {
                rest[k as usize] = true;
            }
        }
        let wrong: Vec<u32> =
            (0..topology.len()).filter(|&k| rest[k] && !on_largest[k]).map(|k| first_particle + k as u32).collect();
        (!wrong.is_empty()).then_some(wrong)
    }

    /// Body `body` (of shape `topology`) cut by the triangles `cut` (flat indices, repeats
    /// allowed): its other triangles' parts and the largest of them; `None` when every
    /// triangle is cut.
    fn cut(&self, body: u32, topology: &ClothTopology, cut: impl Iterator<Item = u32>) -> Option<Cut> {
        // The body's first triangle and first particle (flat indices): its triangles and
        // particles are in the topology's order from there.
        let first = self.triangles.partition_point(|&(b, _)| b < body);
        let first_particle = self.owner.partition_point(|&(b, _)| b < body) as u32;
        let triangles = topology.triangles();
        let mut is_cut = vec![false; triangles.len()];
        for t in cut {
            is_cut[t as usize - first] = true;
        }
        // The parts: a flood over the triangles that share an edge (two corners) with each.
        let (part, sizes) = flood(topology, |t| !is_cut[t]);
        let largest = (0..sizes.len()).max_by_key(|&k| (sizes[k], usize::MAX - k))? as u32;
        let mut on_largest = vec![false; topology.len()];
        for (c, _) in triangles.iter().zip(&part).filter(|&(_, &p)| p == largest) {
            for &k in c {
                on_largest[k as usize] = true;
            }
        }
        Some(Cut { first, first_particle, is_cut, part, parts: sizes.len(), largest, on_largest })
    }
}

/// A body cut by the triangles that cross (local triangle and particle indices).
struct Cut {
    /// The body's first triangle and first particle, as flat indices.
    first: usize,
    first_particle: u32,
    /// Whether each triangle is cut.
    is_cut: Vec<bool>,
    /// Each uncut triangle's part ([`UNSET`] for a cut one), the count of parts and the largest.
    part: Vec<u32>,
    parts: usize,
    largest: u32,
    /// Whether each particle is a corner of a triangle of the largest part.
    on_largest: Vec<bool>,
}

/// Groups the triangles of `topology` that `within(t)` keeps into sets joined across shared
/// edges (two corners): each kept triangle's set, [`UNSET`] for the others, and each set's
/// size.
fn flood(topology: &ClothTopology, within: impl Fn(usize) -> bool) -> (Vec<u32>, Vec<usize>) {
    let count = topology.triangles().len();
    let mut set = vec![UNSET; count];
    let mut sizes = Vec::new();
    let mut stack = Vec::new();
    for seed in 0..count {
        if !within(seed) || set[seed] != UNSET {
            continue;
        }
        let id = sizes.len() as u32;
        sizes.push(0usize);
        set[seed] = id;
        stack.push(seed);
        while let Some(t) = stack.pop() {
            sizes[id as usize] += 1;
            for_each_neighbour(topology, t, |u| {
                if within(u) && set[u] == UNSET {
                    set[u] = id;
                    stack.push(u);
                }
            });
        }
    }
    (set, sizes)
}

/// Calls `f(u)` for each triangle `u` that shares an edge (two corners) with triangle `t`.
fn for_each_neighbour(topology: &ClothTopology, t: usize, mut f: impl FnMut(usize)) {
    let c = topology.triangles()[t];
    for [p, q] in [[c[0], c[1]], [c[1], c[2]], [c[2], c[0]]] {
        let beside = topology.triangles_of(q as usize);
        for &u in topology.triangles_of(p as usize).iter().filter(|u| beside.contains(u)) {
            if u as usize != t {
                f(u as usize);
            }
        }
    }
}
