//! Tethers (after the long-range attachments of Kim, Chentanez and Müller 2012): a particle of a
//! held cloth farther than `(1 + slack)` times its rest distance over the cloth from its
//! nearest pinned particle moves away from it no faster.
//!
//! ## Why
//! Block descent's sweeps carry a load one spring per colour pass, so while a fine cloth
//! moves, the weight of the particles far from the pins reaches the pins over many substeps and
//! the cloth stretches like rubber in the meantime (the [`crate::solver::block_descent`] docs give the
//! figures). A tether is one constraint from each particle straight to the pin that holds it, so
//! the load of the whole cloth reaches the pins in the same substep, whatever the resolution:
//! the cape, flag and curtain tethers of game cloth solvers.
//!
//! ## How
//! - **Lengths.** When a cloth is built, a shortest-path search over the springs' rest lengths
//!   from every pinned particle at once gives each particle its nearest pin and its distance
//!   over the rest shape. A path runs straight from its last corner while the springs it walked
//!   since are at most 10 % longer than that straight line, so on a flat sheet the distance is
//!   the straight one, not the grid's staircase (up to 8.2 % longer), while around a gap or a
//!   fold the path bends and the tether is as long as the way over the cloth. The distance is
//!   never shorter than the straight chord in the rest shape, so the rest shape satisfies
//!   every tether.
//! - **Holding.** After the sweeps and the velocity update of each block-descent substep, a
//!   particle farther than `(1 + slack) L` from its pin loses its velocity away from the pin:
//!   an inelastic rope. It carries no momentum outwards into the next substep, so the weight of
//!   the cloth beyond it hangs on the pin from then on instead of stretching the springs
//!   between, which pull it back at their own pace. Only kinetic energy is taken, so the
//!   tethers never add energy at any stiffness, and a cloth that starts stretched, or whose
//!   anchor jumps, is not flung. Kim et al. also move the particle back onto its reach; on
//!   this solver that move stores energy in stiff springs across the tether: a 16 x 16 cloth
//!   at SpringK 1e5 falling from its rest shape without damping rose above its starting
//!   energy, which `energy_never_grows_without_input` (the core's `block_descent` tests)
//!   forbids. The pin does not move (it is held).
//! - Only block descent is tethered: the explicit integrators carry a load through the cloth
//!   within each substep, and RK4 stays the reference of the spring model.
//!
//! A cloth with no pin has no tethers. `slack` is how far beyond its rest distance a particle
//! may move away from its pin at its own speed. The rope takes speed, not position, so a
//! cloth still settles where its springs hold it: hanging from two corners (damping 2, after
//! 8 s), 0.32 % short of RK4's sag at 32 x 32
//! (`cargo test -p bvh_cloth_core --release --test core -- --nocapture hangs_to`).
//!
//! ## Measured
//! The same cloth, dropped flat, at the defaults (Looper 16, one sweep), against RK4 at the same
//! resolution; the sag of the last row's middle below the pins and the p99 strain of the
//! structural springs at 1 s, the top of the first swing back. With tethers from 32 x 32 to
//! 128 x 128: `cargo test -p bvh_cloth_core --release --test core -- --nocapture motion::`;
//! without them, and 256 x 256: the report's `motion` section (BENCHMARKS.md, "Motion"):
//!
//! | side | no tethers: sag vs RK4 | p99 strain vs RK4 | tethers 3 %: sag vs RK4 | p99 strain vs RK4 |
//! |---|---|---|---|---|
//! | 32 | +14 % | 1.06x | +18.3 % | 1.21x |
//! | 64 | +45 % | 2.62x | +16.7 % | 1.03x |
//! | 128 | +134 % | 9.1x | +15.7 % | 1.38x |
//! | 256 | +284 % | 36.6x | +45 % | 3.4x |
//!
//! Their cost, one distance test per particle and substep: 1.06x to 1.07x the untethered tick
//! at 64 x 64 and 1.04x to 1.11x at 256 x 256 (`cargo bench -p bvh_cloth_bench --bench report
//! -- motion_cost`: the same state ticked with and without, alternated, best of 40 and of 20,
//! three runs on the 2-core development machine, an AMD EPYC, on 2026-11-29 and 30).
//!
//! The tethers take out most of the rubber, not all: a tether bounds how fast a particle moves
//! away from its pin, not each spring's stretch, so at 256 x 256 the springs between still
//! stretch unevenly while the cloth swings. At 32 x 32 the springs alone converge; what remains
//! there is implicit Euler's damping ([`crate::solver::block_descent`]). The flag of the report's
//! `wind` section, held along its pole, flutters at 3.1 Hz with a swing (the standard deviation
//! of its free edge's cross-wind position) of 23.5 mm at the default, against RK4's 5.1 Hz and
//! 33.5 mm (the report's `motion` section).

use glam::Vec3A;

use crate::cloth::error::ClothError;
use crate::cloth::topology::ClothTopology;

/// Largest [`Tethers::slack`] accepted: a tether that lets a particle twice its rest distance
/// from its pin no longer holds anything a spring would not.
pub const MAX_SLACK: f32 = 1.0;

/// How far tethers let a particle stretch away from its nearest pin (see the
/// [module docs](self)).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "bevy_reflect", derive(bevy_reflect::Reflect), reflect(Default, Debug, PartialEq))]
pub struct Tethers {
    /// The fraction of its rest distance (over the cloth) from its nearest pin by which a
    /// particle may exceed it: 0 holds every particle within its rest distance, 0.05 within
    /// 105 % of it. From 0 to [`MAX_SLACK`].
    pub slack: f32,
}

#[cfg(feature = "bevy_reflect")]
use bevy_reflect::std_traits::ReflectDefault;

impl Default for Tethers {
    fn default() -> Self {
        Self { slack: 0.03 }
    }
}

impl Tethers {
    /// Checks the slack: finite, from 0 to [`MAX_SLACK`].
    pub fn validate(&self) -> Result<(), ClothError> {
        if self.slack.is_finite() && (0.0..=MAX_SLACK).contains(&self.slack) {
            Ok(())
        } else {
            Err(ClothError::OutOfRange { field: "tethers.slack", value: self.slack, min: 0.0, max: MAX_SLACK })
        }
    }
}

/// How much longer than the straight line the springs walked from a path's corner may be for
/// the path to run straight from that corner: above the square grid's 8.2 % (its structural
/// and shear springs' longest detour, at 22.5° to the rows), below what a gap or a fold adds.
const STRAIGHT_DETOUR: f32 = 1.1;

/// No pin: the particle is pinned itself, or no path of springs reaches a pin.
pub const UNTETHERED: u32 = u32::MAX;

/// Each particle's nearest pin and its rest distance over the cloth.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TetherSet {
    /// The nearest pinned particle of each particle, or [`UNTETHERED`].
    pub pin: Vec<u32>,
    /// The rest distance to that pin, in metres (0 where untethered).
    pub length: Vec<f32>,
}

impl TetherSet {
    /// Every particle's nearest pin among `pins` over `topology`'s springs, by any-angle
    /// shortest paths on the rest shape (see the [module docs](self)); the empty set when
    /// there is no pin.
    pub fn new(topology: &ClothTopology, pins: &[u32]) -> Self {
        if pins.is_empty() {
            return Self::default();
        }
        let n = topology.len();
        let rest = topology.rest_positions();
        let mut pin = vec![UNTETHERED; n];
        let mut length = vec![f32::INFINITY; n];
        // The node each particle's path runs straight from, and the length of the springs the
        // search walked from there.
        let mut from = vec![u32::MAX; n];
        let mut walked = vec![0.0f32; n];
        let mut queue = std::collections::BinaryHeap::new();
        for &p in pins {
            let p = p as usize;
            if p < n {
                (pin[p], length[p], from[p]) = (p as u32, 0.0, p as u32);
                queue.push(Entry { distance: 0.0, node: p as u32 });
            }
        }
        while let Some(Entry { distance, node }) = queue.pop() {
            let i = node as usize;
            if distance > length[i] {
                continue;
            }
            let corner = from[i] as usize;
            for end in topology.springs_of(i) {
                let j = end.other as usize;
                // Straight from the corner while the springs walked stay within
                // `STRAIGHT_DETOUR` of the straight line: on a flat sheet that is the straight
                // distance; around a gap or a fold, the path bends there.
                let straight = rest[j].distance(rest[corner]);
                let (candidate, via, walk) = if walked[i] + end.rest <= STRAIGHT_DETOUR * straight {
                    (length[corner] + straight, corner, walked[i] + end.rest)
                } else {
                    (distance + end.rest, i, end.rest)
                };
                if candidate < length[j] {
                    (pin[j], length[j], from[j], walked[j]) = (pin[i], candidate, via as u32, walk);
                    queue.push(Entry { distance: candidate, node: j as u32 });
                }
            }
        }
        for (p, l) in pin.iter_mut().zip(&mut length) {
            if !l.is_finite() {
                (*p, *l) = (UNTETHERED, 0.0);
            }
        }
        for &p in pins {
            if (p as usize) < n {
                pin[p as usize] = UNTETHERED;
            }
        }
        Self { pin, length }
    }

    /// Whether the set holds no tether: the cloth has no pin.
    pub fn is_empty(&self) -> bool {
        self.pin.is_empty()
    }

    /// Holds particle `i`, at `x` moving at `v`, by its tether of `scale` times its length to
    /// its pin (at `pin_at(pin)`): beyond that reach, its velocity away from the pin is taken
    /// out. Its position and the rest of its velocity are left alone.
    #[inline]
    pub(crate) fn hold(&self, i: usize, x: Vec3A, v: &mut Vec3A, scale: f32, pin_at: impl Fn(u32) -> Vec3A) {
        let pin = self.pin[i];
        if pin == UNTETHERED {
            return;
        }
        if let Some(out) = beyond(x, pin_at(pin), scale * self.length[i]) {
            *v -= v.dot(out).max(0.0) * out;
        }
    }
}

/// The unit direction from `pin` out to `x` when `x` lies farther than `limit` from it, else
/// `None`. The GPU's `vbd_finish` repeats this arithmetic.
#[inline]
pub fn beyond(x: Vec3A, pin: Vec3A, limit: f32) -> Option<Vec3A> {
    let d = x - pin;
    let len2 = d.dot(d);
    (len2 > limit * limit).then(|| d / len2.sqrt())
}

/// A queue entry of the shortest-path search: nearest first.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Entry {
    distance: f32,
    node: u32,
}

impl Eq for Entry {}

impl Ord for Entry {
    fn cmp(&self, other: &Self) -> core::cmp::Ordering {
        other.distance.total_cmp(&self.distance).then(other.node.cmp(&self.node))
    }
}

impl PartialOrd for Entry {
    fn partial_cmp(&self, other: &Self) -> Option<core::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

#[cfg(test)]
mod tests {
    use glam::{UVec2, Vec2, Vec3};

    use super::*;
    use crate::cloth::grid::ClothGrid;
    use crate::mesh::MeshRef;

    #[test]
    fn on_a_flat_sheet_each_tether_is_the_straight_distance_to_the_nearest_pin() {
        let grid = ClothGrid::new(Vec2::new(1.5, 1.0), UVec2::new(24, 16));
        let topology = ClothTopology::grid(grid).unwrap();
        let pins = [grid.index(0, 0) as u32, grid.index(0, 23) as u32];
        let set = TetherSet::new(&topology, &pins);
        let rest = topology.rest_positions();
        for i in 0..topology.len() {
            if pins.contains(&(i as u32)) {
                assert_eq!(set.pin[i], UNTETHERED, "a pin has no tether");
                continue;
            }
            let nearest = pins.iter().map(|&p| rest[i].distance(rest[p as usize])).fold(f32::INFINITY, f32::min);
            assert!(pins.contains(&set.pin[i]));
            assert!((set.length[i] - nearest).abs() <= 1e-5 * nearest, "{i}: {} against {nearest}", set.length[i]);
            assert!(
                (rest[i].distance(rest[set.pin[i] as usize]) - nearest).abs() <= 1e-6,
                "{i} tethers to the nearer pin"
            );
        }
    }

    #[test]
    fn around_a_gap_a_tether_is_the_way_over_the_cloth_and_the_rest_shape_satisfies_it() {
        // A U of three strips: its two arms' tips are close in space, far over the cloth.
        let mut positions = Vec::new();
        let mut indices = Vec::new();
        let cells = [(0, 0), (0, 1), (0, 2), (1, 0), (2, 0), (2, 1), (2, 2)];
        let mut corner = std::collections::HashMap::new();
        let mut vertex = |x: u32, y: u32, positions: &mut Vec<[f32; 3]>| {
            *corner.entry((x, y)).or_insert_with(|| {
                positions.push([x as f32 * 0.1, 0.0, y as f32 * 0.1]);
                positions.len() as u32 - 1
            })
        };
        for (x, y) in cells {
            let [a, b, c, d] =
                [(x, y), (x + 1, y), (x + 1, y + 1), (x, y + 1)].map(|(x, y)| vertex(x, y, &mut positions));
            indices.extend([a, b, c, a, c, d]);
        }
        let topology = ClothTopology::from_mesh(MeshRef { positions: &positions, indices: Some(&indices) }).unwrap();
        let rest = topology.rest_positions();
        let tip = |x: f32| (0..topology.len()).find(|&i| rest[i] == Vec3::new(x, 0.0, 0.3)).unwrap();
        let (pin, far) = (tip(0.0), tip(0.3));
        let set = TetherSet::new(&topology, &[pin as u32]);
        let chord = rest[far].distance(rest[pin]);
        // The way over the cloth: to the inner corner of the left arm, across, and up.
        let around = 2.0 * 0.05f32.sqrt() + 0.1;
        assert!((set.length[far] - around).abs() <= 1e-5, "{} against {around} (the chord: {chord})", set.length[far]);
        for i in 0..topology.len() {
            if i != pin {
                assert!(rest[i].distance(rest[pin]) <= set.length[i] * (1.0 + 1e-6), "{i}");
            }
        }
    }

    #[test]
    fn a_cloth_without_pins_has_no_tethers_and_a_tether_holds_only_beyond_its_reach() {
        let topology = ClothTopology::grid(ClothGrid::new(Vec2::ONE, UVec2::splat(4))).unwrap();
        assert!(TetherSet::new(&topology, &[]).is_empty());
        let set = TetherSet::new(&topology, &[0]);
        let rest: Vec<Vec3A> = topology.rest_positions().iter().map(|&p| p.into()).collect();
        let pin_at = |p: u32| rest[p as usize];
        // 10 % beyond its rest distance from the pin, moving away and sideways: the outward
        // velocity is taken out, the sideways kept.
        let far = 15;
        let out = (rest[far] - rest[0]).normalize();
        let side = out.cross(Vec3A::Y).normalize();
        let stretched = rest[0] + (rest[far] - rest[0]) * 1.1;
        let mut v = 2.0 * out + 0.5 * side;
        set.hold(far, stretched, &mut v, 1.05, pin_at);
        assert!(v.abs_diff_eq(0.5 * side, 1e-6), "{v}");
        // Moving inwards, it keeps its velocity; within its reach, whatever its velocity.
        let mut v = -out;
        set.hold(far, stretched, &mut v, 1.05, pin_at);
        assert_eq!(v, -out);
        let mut v = 2.0 * out;
        set.hold(far, rest[0] + (rest[far] - rest[0]) * 1.04, &mut v, 1.05, pin_at);
        assert_eq!(v, 2.0 * out, "within its reach, a particle is left alone");
        // The pin itself is untethered.
        let mut v = Vec3A::ONE;
        set.hold(0, rest[0] + Vec3A::ONE, &mut v, 1.05, pin_at);
        assert_eq!(v, Vec3A::ONE);
    }

    #[test]
    fn the_slack_is_refused_outside_its_range() {
        for slack in [f32::NAN, -0.01, 1.5, f32::INFINITY] {
            let error = Tethers { slack }.validate().unwrap_err();
            assert!(matches!(error, ClothError::OutOfRange { field: "tethers.slack", .. }), "{error}");
        }
        for slack in [0.0, 0.03, MAX_SLACK] {
            Tethers { slack }.validate().unwrap();
        }
    }
}
