//! Particle accelerations of the mass-spring model (paper eq. 1–3), one band of rows at a time.
//!
//! The cloth state is stored row by row, each row as six contiguous lanes
//! `[x | y | z | vx | vy | vz]` of `width` floats: a grid row, or a run of consecutive particles
//! of any other topology. Two paths fill a band's accelerations:
//! - [`ForceModel::band_acceleration`], the grid's fast path: for every stencil offset the inner
//!   loop runs over a contiguous column range with no branch, which the compiler vectorises;
//!   borders are handled by shortening that range, not by tests inside the loop.
//! - [`ForceModel::band_acceleration_general`], for any topology: each particle gathers its
//!   springs from the [`ClothTopology`]'s per-particle lists, in the order and with the
//!   arithmetic of the GPU's `node_update`.

use core::ops::Range;

use glam::Vec3;

use crate::cloth::grid::{ClothGrid, STENCIL};
use crate::cloth::topology::ClothTopology;
use crate::solver::params::ClothParams;

/// Number of `f32` lanes per particle in the row layout (position and velocity).
pub const LANES: usize = 6;

/// Constants of the force model for one parameter set, precomputed per tick.
#[derive(Clone, Copy, Debug)]
pub struct ForceModel {
    /// `stiffness scale * spring_k / mass` per spring kind: a spring's stiffness over a
    /// particle's mass is this times the spring's weight times the particle's inverse mass
    /// share.
    pub k_over_mass: [f32; 3],
    /// Damping rate (1/s).
    pub damping: f32,
    /// Gravity plus the external force per unit mass.
    pub uniform_accel: Vec3,
}

impl ForceModel {
    /// Precomputes the model from validated parameters.
    pub fn new(params: &ClothParams) -> Self {
        let s = params.stiffness;
        let k = params.spring_k / params.mass;
        Self {
            k_over_mass: [s.structural * k, s.shear * k, s.bending * k],
            damping: params.damping,
            uniform_accel: params.gravity + params.external_force / params.mass,
        }
    }

    /// The acceleration of every particle of rows `band` of any topology, as
    /// [`Self::band_acceleration`] lays it out, with rows `width` particles long (the last one
    /// may be short: its tail is padding and gets zero). Pinned particles get zero.
    #[allow(clippy::too_many_arguments)]
    pub fn band_acceleration_general(
        &self,
        topology: &ClothTopology,
        width: usize,
        state: &[f32],
        free: &[f32],
        band: Range<usize>,
        acc: &mut [f32],
    ) {
        let w = LANES * width;
        let position = |i: usize| {
            let o = (i / width) * w + i % width;
            Vec3::new(state[o], state[o + width], state[o + 2 * width])
        };
        let inv_share = topology.inv_mass_share();
        for (j, r) in band.enumerate() {
            for c in 0..width {
                let i = r * width + c;
                let mut a = Vec3::ZERO;
                if i < topology.len() && free[i] != 0.0 {
                    let o = r * w + c;
                    let p = Vec3::new(state[o], state[o + width], state[o + 2 * width]);
                    let v = Vec3::new(state[o + 3 * width], state[o + 4 * width], state[o + 5 * width]);
                    a = self.uniform_accel - self.damping * v;
                    for end in topology.springs_of(i) {
                        let k = self.k_over_mass[end.kind as usize] * end.weight * inv_share[i];
                        if k == 0.0 {
                            continue;
                        }
                        let d = position(end.other as usize) - p;
                        let len = (d.x * d.x + d.y * d.y + d.z * d.z).sqrt();
                        a += k * (1.0 - end.rest / len.max(1.0e-6 * end.rest)) * d;
                    }
                    a *= free[i];
                }
                for (axis, value) in a.to_array().into_iter().enumerate() {
                    acc[j * 3 * width + axis * width + c] = value;
                }
            }
        }
    }

    /// Writes the acceleration of every particle of rows `band` into `acc` (for each row of the
    /// band in turn, `[ax | ay | az]`, each `cols` long), reading positions and velocities from
    /// `state` (the whole cloth, row layout). Pinned particles (`free == 0`) get zero.
    ///
    /// Each spring is evaluated once and applied to both of its ends (Newton's third law), so a
    /// band pays for the springs inside it once and only re-evaluates the few that cross its
    /// edges. The band split is fixed by the caller, so the sums are the same on any thread count.
    /// Every particle of the grid has the mass share whose inverse is `inv_mass_share`.
    #[allow(clippy::too_many_arguments)]
    pub fn band_acceleration(
        &self,
        grid: &ClothGrid,
        inv_mass_share: f32,
        state: &[f32],
        free: &[f32],
        band: Range<usize>,
        acc: &mut [f32],
        scratch: &mut SpringScratch,
    ) {
        let cols = grid.cols;
        let w = LANES * cols;
        let g = self.uniform_accel;
        let c = self.damping;
        for (j, r) in band.clone().enumerate() {
            let v = &state[r * w + 3 * cols..(r + 1) * w];
            let a = &mut acc[j * 3 * cols..(j + 1) * 3 * cols];
            for (axis, g) in [g.x, g.y, g.z].into_iter().enumerate() {
                let (a, v) = (&mut a[axis * cols..(axis + 1) * cols], &v[axis * cols..(axis + 1) * cols]);
                for i in 0..cols {
                    a[i] = g - c * v[i];
                }
            }
        }
        let position = |r: usize, lo: usize, hi: usize| -> [&[f32]; 3] {
            let row = &state[r * w..r * w + 3 * cols];
            [&row[lo..hi], &row[cols + lo..cols + hi], &row[2 * cols + lo..2 * cols + hi]]
        };
        for s in STENCIL.iter().filter(|s| s.dr > 0 || (s.dr == 0 && s.dc > 0)) {
            let k = self.k_over_mass[s.kind as usize] * grid.weight(s.dr, s.dc) * inv_mass_share;
            let rest_len = grid.rest_length(s.dr, s.dc);
            let (dr, dc) = (s.dr as usize, i64::from(s.dc));
            // Columns c of the first end whose second end c + dc lies in the grid.
            let lo = (-dc).max(0) as usize;
            let hi = (cols as i64 - dc.max(0)).max(0) as usize;
            if k == 0.0 || lo >= hi || dr >= grid.rows {
                continue;
            }
            let (nlo, nhi) = ((lo as i64 + dc) as usize, (hi as i64 + dc) as usize);
            // Every spring with at least one end in the band: first end in rows first..last.
            let first = band.start.saturating_sub(dr);
            let last = band.end.min(grid.rows - dr);
            for r in first..last {
                let f = scratch.spans(hi - lo);
                spring_span(k, rest_len, position(r, lo, hi), position(r + dr, nlo, nhi), f);
                if band.contains(&r) {
                    add_span(acc, (r - band.start) * 3 * cols, cols, lo, &scratch.force, hi - lo, 1.0);
                }
                if band.contains(&(r + dr)) {
                    add_span(acc, (r + dr - band.start) * 3 * cols, cols, nlo, &scratch.force, hi - lo, -1.0);
                }
            }
        }
        for (j, r) in band.enumerate() {
            let f = &free[r * cols..(r + 1) * cols];
            for a in acc[j * 3 * cols..(j + 1) * 3 * cols].chunks_exact_mut(cols) {
                for i in 0..cols {
                    a[i] *= f[i];
                }
            }
        }
    }
}

/// Per-task scratch space for [`ForceModel::band_acceleration`]: one span of spring forces.
#[derive(Clone, Debug, Default)]
pub struct SpringScratch {
    /// `[fx | fy | fz]` of the span being applied, each `len` long.
    force: Vec<f32>,
}

impl SpringScratch {
    fn spans(&mut self, len: usize) -> [&mut [f32]; 3] {
        self.force.resize(3 * len, 0.0);
        let (x, rest) = self.force.split_at_mut(len);
        let (y, z) = rest.split_at_mut(len);
        [x, y, z]
    }
}

/// Adds `sign * force` (`[fx | fy | fz]`, each `len` long) to columns `col..col + len` of the
/// acceleration row starting at `acc[offset]`.
#[inline(always)]
fn add_span(acc: &mut [f32], offset: usize, cols: usize, col: usize, force: &[f32], len: usize, sign: f32) {
    for axis in 0..3 {
        let a = &mut acc[offset + axis * cols + col..][..len];
        let f = &force[axis * len..(axis + 1) * len];
        for i in 0..len {
            a[i] += sign * f[i];
        }
    }
}

/// The Hooke force (paper eq. 1, divided by the mass) of one spring kind over a contiguous span:
/// `f[i]` pulls the particle at `p[i]` towards its neighbour at `q[i]` (and the neighbour back by
/// `-f[i]`).
#[inline(always)]
fn spring_span(k: f32, rest: f32, p: [&[f32]; 3], q: [&[f32]; 3], f: [&mut [f32]; 3]) {
    let n = p[0].len();
    let [px, py, pz] = p.map(|s| &s[..n]);
    let [qx, qy, qz] = q.map(|s| &s[..n]);
    let [fx, fy, fz] = f;
    let (fx, fy, fz) = (&mut fx[..n], &mut fy[..n], &mut fz[..n]);
    for i in 0..n {
        let dx = qx[i] - px[i];
        let dy = qy[i] - py[i];
        let dz = qz[i] - pz[i];
        let len = (dx * dx + dy * dy + dz * dz).sqrt();
        // k (|d| - rest) / |d|. The floor keeps a coincident pair (d = 0) finite: it then
        // contributes 0 * finite = 0.
        let s = k * (1.0 - rest / len.max(1.0e-6 * rest));
        fx[i] = s * dx;
        fy[i] = s * dy;
        fz[i] = s * dz;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solver::params::ClothParams;

    /// The acceleration of particle `(r, c)` straight from eq. 1–3, every spring seen from this
    /// end, in f64.
    fn naive(
        model: &ForceModel,
        grid: &ClothGrid,
        inv_share: f64,
        p: &[glam::DVec3],
        v: &[glam::DVec3],
        r: usize,
        c: usize,
    ) -> glam::DVec3 {
        let i = r * grid.cols + c;
        let mut a = model.uniform_accel.as_dvec3() - f64::from(model.damping) * v[i];
        for s in STENCIL {
            let (rr, cc) = (r as i64 + i64::from(s.dr), c as i64 + i64::from(s.dc));
            if rr < 0 || cc < 0 || rr >= grid.rows as i64 || cc >= grid.cols as i64 {
                continue;
            }
            let d = p[rr as usize * grid.cols + cc as usize] - p[i];
            let k = f64::from(model.k_over_mass[s.kind as usize]) * f64::from(grid.weight(s.dr, s.dc)) * inv_share;
            a += k * (d.length() - f64::from(grid.rest_length(s.dr, s.dc))) * d / d.length();
        }
        a
    }

    /// A `rows x cols` grid of rectangular cells, jiggled deterministically, with a few pinned
    /// particles: its row-layout state, positions, velocities and free flags.
    #[allow(clippy::type_complexity)]
    fn jiggled(grid: &ClothGrid) -> (Vec<f32>, Vec<glam::DVec3>, Vec<glam::DVec3>, Vec<f32>) {
        let (rows, cols) = (grid.rows, grid.cols);
        let s = grid.spacing();
        let jiggle = |i: usize, axis: usize| ((i * 7 + axis * 13) % 17) as f32 / 17.0 - 0.5;
        let mut state = vec![0.0f32; rows * cols * LANES];
        let (mut p, mut v) = (Vec::new(), Vec::new());
        for r in 0..rows {
            for c in 0..cols {
                let i = r * cols + c;
                let pos = Vec3::new(c as f32 * s.x, 0.0, r as f32 * s.y)
                    + 0.3 * s.min_element() * Vec3::new(jiggle(i, 0), jiggle(i, 1), jiggle(i, 2));
                let vel = Vec3::new(jiggle(i, 3), jiggle(i, 4), jiggle(i, 5));
                for (l, x) in [pos.x, pos.y, pos.z, vel.x, vel.y, vel.z].into_iter().enumerate() {
                    state[r * LANES * cols + l * cols + c] = x;
                }
                p.push(pos.as_dvec3());
                v.push(vel.as_dvec3());
            }
        }
        let free: Vec<f32> = (0..rows * cols).map(|i| if i % 10 == 3 { 0.0 } else { 1.0 }).collect();
        (state, p, v, free)
    }

    fn model() -> ForceModel {
        ForceModel::new(&ClothParams { spring_k: 700.0, damping: 0.3, mass: 2.0, ..Default::default() })
    }

    #[test]
    fn bands_apply_each_spring_to_both_ends_like_the_full_stencil() {
        let grid = ClothGrid::new(glam::Vec2::new(1.3, 0.8), glam::UVec2::new(11, 13));
        let model = model();
        let (rows, cols) = (grid.rows, grid.cols);
        let (state, p, v, free) = jiggled(&grid);
        let inv_share = (rows * cols) as f32;
        for band_rows in [1, 2, 3, 5, 13] {
            let mut scratch = SpringScratch::default();
            for first in (0..rows).step_by(band_rows) {
                let band = first..(first + band_rows).min(rows);
                let mut acc = vec![f32::NAN; 3 * cols * band.len()];
                model.band_acceleration(&grid, inv_share, &state, &free, band.clone(), &mut acc, &mut scratch);
                for (j, r) in band.enumerate() {
                    for c in 0..cols {
                        let got = Vec3::new(
                            acc[j * 3 * cols + c],
                            acc[j * 3 * cols + cols + c],
                            acc[j * 3 * cols + 2 * cols + c],
                        );
                        let want =
                            naive(&model, &grid, f64::from(inv_share), &p, &v, r, c) * f64::from(free[r * cols + c]);
                        let err = (got.as_dvec3() - want).length();
                        assert!(
                            err <= 1e-4 * want.length().max(1.0),
                            "band of {band_rows}, ({r}, {c}): {got} vs {want}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn the_general_path_gathers_the_same_springs_as_the_stencil() {
        let grid = ClothGrid::new(glam::Vec2::new(1.3, 0.8), glam::UVec2::new(11, 13));
        let topology = ClothTopology::grid_as_mesh(grid).unwrap();
        let model = model();
        let (state, p, v, free) = jiggled(&grid);
        let inv_share = f64::from(topology.inv_mass_share()[0]);
        let mut acc = vec![f32::NAN; 3 * grid.cols * grid.rows];
        model.band_acceleration_general(&topology, grid.cols, &state, &free, 0..grid.rows, &mut acc);
        for r in 0..grid.rows {
            for c in 0..grid.cols {
                let o = r * 3 * grid.cols + c;
                let got = Vec3::new(acc[o], acc[o + grid.cols], acc[o + 2 * grid.cols]);
                let want = naive(&model, &grid, inv_share, &p, &v, r, c) * f64::from(free[r * grid.cols + c]);
                assert!((got.as_dvec3() - want).length() <= 1e-4 * want.length().max(1.0), "({r}, {c})");
            }
        }
    }
}
