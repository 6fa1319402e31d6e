//! A cloth's working state for aerodynamics ([`Air`]): the wind sampled at each particle once
//! a tick, and each substep's change of velocity, capped at the particle's speed relative to
//! the wind.

use glam::{Vec3, Vec3A, Vec4};
use rayon::prelude::*;

use super::model::AirModel;
use super::noise::{NoiseLattice, value_noise_4d};
use super::source::AirSource;
use super::{MIN_TASK, grid_kick};
use crate::cloth::topology::ClothTopology;

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
    /// its speed relative to the wind (see [the air's docs](crate::air)). Needs [`Self::sample`]
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
pub(super) fn capped_kick_simd(dv: Vec3A, relative: Vec3A) -> Vec3A {
    let dv2 = dv.dot(dv);
    let rel2 = relative.dot(relative);
    if dv2 > rel2 { dv * (rel2 / dv2).sqrt() } else { dv }
}

/// [`capped_kick`] of four particles, one per lane, by coordinate, with the bits of
/// [`capped_kick_simd`] in each lane.
#[inline]
pub(super) fn capped_kick_lanes(dv: [Vec4; 3], relative: [Vec4; 3]) -> [Vec4; 3] {
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
