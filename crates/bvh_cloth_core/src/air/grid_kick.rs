//! Drag and lift on a generated grid ([`ClothTopology::grid`](crate::ClothTopology::grid)),
//! with the bits of the general path.
//!
//! The general path gathers each triangle's corners by index and transposes them into SIMD
//! lanes. On a grid the neighbours are known, so the particles are laid out once per substep
//! by coordinate, row by row, and four cells of a row are read straight into the lanes: a
//! cell's corners are its row's lanes, the same lanes one column on, and the next row's. The
//! two triangles of each cell, `(i, down, right)` and `(right, down, diagonal)` as
//! [`ClothGrid::triangle_indices`] lists them, run the same lane arithmetic
//! ([`AirModel::lane_forces`]).
//!
//! A particle's triangles, in the ascending order of its list, are the second triangle of the
//! cell up and to its left, both of the cell up, both of the cell to its left, and the first of
//! its own cell. Each particle sums them in that order from zero, four particles at a time,
//! with a zero force for a cell beyond the grid's edge: adding `+0` to a sum that started at
//! `+0` changes no bit, so the edges need no branch.

use glam::{BVec4A, Mat4, Vec3A, Vec4};
use rayon::prelude::*;

use super::MIN_TASK;
use super::kick::capped_kick_lanes;
use super::model::{AirModel, mean_flow_lanes};
use crate::cloth::grid::ClothGrid;

/// Lanes a row of particles is padded with at its end: a group of four cells reads its
/// corners one column on.
const PAD: usize = 4;

/// A grid's working state for the kick: positions and relative flows by coordinate, and the
/// cells' forces by coordinate.
#[derive(Clone, Debug, Default)]
pub(super) struct GridAir {
    /// The rows and columns the buffers are laid out for.
    shape: (usize, usize),
    /// Per row of particles, six runs of `cols + PAD` lanes: `x`, `y`, `z` of the positions,
    /// then of the wind less the velocity.
    particles: Vec<f32>,
    /// Per row of cells, and an empty row above and below, six runs of `cols + PAD` lanes: the
    /// first triangle's force by coordinate, then the second's. Cell `c` is lane `c + 1`;
    /// lane 0 and the lanes from `cols` on stay zero.
    cells: Vec<f32>,
}

/// Four lanes of `run` from `at`, in one unaligned read.
#[inline(always)]
fn load(run: &[f32], at: usize) -> Vec4 {
    Vec4::from(*run[at..].first_chunk::<4>().expect("a run is padded for its last group"))
}

/// Writes the four lanes of `v` into `run` from `at`.
#[inline(always)]
fn store(v: Vec4, run: &mut [f32], at: usize) {
    v.write_to_slice(&mut run[at..at + 4]);
}

/// Four lanes of each of three runs from `at`.
#[inline(always)]
fn load3(runs: [&[f32]; 3], at: usize) -> [Vec4; 3] {
    [load(runs[0], at), load(runs[1], at), load(runs[2], at)]
}

/// `p - q`, coordinate by coordinate.
#[inline(always)]
fn minus(p: [Vec4; 3], q: [Vec4; 3]) -> [Vec4; 3] {
    [p[0] - q[0], p[1] - q[1], p[2] - q[2]]
}

/// The three coordinate runs of `rows` (one run every `stride` lanes, from run `first`).
#[inline]
fn runs(rows: &[f32], first: usize, stride: usize) -> [&[f32]; 3] {
    [0, 1, 2].map(|k| &rows[(first + k) * stride..(first + k + 1) * stride])
}

impl GridAir {
    /// Lays the buffers out for `grid`, zeroing them when its shape changed.
    fn lay_out(&mut self, grid: &ClothGrid) {
        if self.shape != (grid.rows, grid.cols) {
            let stride = grid.cols + PAD;
            self.shape = (grid.rows, grid.cols);
            self.particles = vec![0.0; grid.rows * 6 * stride];
            self.cells = vec![0.0; (grid.rows + 1) * 6 * stride];
        }
    }

    /// One substep's kick on `grid`: [`Air::kick`](super::Air::kick) with the same bits.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn kick(
        &mut self,
        model: &AirModel,
        grid: &ClothGrid,
        inv_share: &[f32],
        free: &[f32],
        h: f32,
        x: &[Vec3A],
        wind: &[Vec3A],
        v: &mut [Vec3A],
    ) {
        self.lay_out(grid);
        let (rows, cols) = (grid.rows, grid.cols);
        let stride = cols + PAD;
        let pool = rows * cols >= MIN_TASK;
        // The particles by coordinate.
        let spread = |(r, out): (usize, &mut [f32])| {
            let row = r * cols..(r + 1) * cols;
            let (x, wind, v) = (&x[row.clone()], &wind[row.clone()], &v[row]);
            let (positions, flows) = out.split_at_mut(3 * stride);
            by_coordinate(positions, stride, |c| x[c], cols);
            by_coordinate(flows, stride, |c| wind[c] - v[c], cols);
        };
        if pool {
            self.particles.par_chunks_mut(6 * stride).enumerate().for_each(spread);
        } else {
            self.particles.chunks_mut(6 * stride).enumerate().for_each(spread);
        }
        // Each cell's two forces, from its row of particles and the next.
        let particles = &self.particles[..];
        let forces = |(r, out): (usize, &mut [f32])| {
            let (top, bottom) = (&particles[r * 6 * stride..], &particles[(r + 1) * 6 * stride..]);
            cell_row(
                model,
                runs(top, 0, stride),
                runs(top, 3, stride),
                runs(bottom, 0, stride),
                runs(bottom, 3, stride),
                out,
                stride,
                cols,
            );
        };
        let inner = &mut self.cells[6 * stride..rows * 6 * stride];
        if pool {
            inner.par_chunks_mut(6 * stride).enumerate().for_each(forces);
        } else {
            inner.chunks_mut(6 * stride).enumerate().for_each(forces);
        }
        // Each particle's sum and kick, from the cells above and below its row.
        let (cells, particles) = (&self.cells[..], &self.particles[..]);
        let kick = |(r, v): (usize, &mut [Vec3A])| {
            let (above, below) = (&cells[r * 6 * stride..], &cells[(r + 1) * 6 * stride..]);
            let flows = runs(&particles[r * 6 * stride..], 3, stride);
            let row = r * cols..(r + 1) * cols;
            particle_row(above, below, flows, &inv_share[row.clone()], &free[row], h, v, stride);
        };
        if pool {
            v.par_chunks_mut(cols).enumerate().for_each(kick);
        } else {
            v.chunks_mut(cols).enumerate().for_each(kick);
        }
    }
}

/// Writes `at(c)` for each of `cols` columns into the three runs of `out` (`stride` lanes
/// each), four columns at a time through a transpose.
#[inline]
fn by_coordinate(out: &mut [f32], stride: usize, at: impl Fn(usize) -> Vec3A, cols: usize) {
    let (xs, rest) = out.split_at_mut(stride);
    let (ys, zs) = rest.split_at_mut(stride);
    let whole = cols / 4 * 4;
    for c in (0..whole).step_by(4) {
        let t = Mat4::from_cols(at(c).extend(0.0), at(c + 1).extend(0.0), at(c + 2).extend(0.0), at(c + 3).extend(0.0))
            .transpose();
        t.x_axis.write_to_slice(&mut xs[c..c + 4]);
        t.y_axis.write_to_slice(&mut ys[c..c + 4]);
        t.z_axis.write_to_slice(&mut zs[c..c + 4]);
    }
    for c in whole..cols {
        let p = at(c);
        (xs[c], ys[c], zs[c]) = (p.x, p.y, p.z);
    }
}

/// The forces of one row of cells, between the particle rows `top` and `bottom` (positions
/// and flows by coordinate), into `out` (the first triangle's three runs, then the second's;
/// cell `c` at lane `c + 1`).
#[allow(clippy::too_many_arguments)]
#[inline]
fn cell_row(
    model: &AirModel,
    top: [&[f32]; 3],
    top_flow: [&[f32]; 3],
    bottom: [&[f32]; 3],
    bottom_flow: [&[f32]; 3],
    out: &mut [f32],
    stride: usize,
    cols: usize,
) {
    let lane = Vec4::new(0.0, 1.0, 2.0, 3.0);
    let cells = cols - 1;
    for c in (0..cells).step_by(4) {
        // Lanes past the last cell give no force, so that its neighbours' sums read zero there.
        let valid: BVec4A = (Vec4::splat(c as f32) + lane).cmplt(Vec4::splat(cells as f32));
        let (i, right, down, diagonal) = (load3(top, c), load3(top, c + 1), load3(bottom, c), load3(bottom, c + 1));
        let (ui, uright, udown, udiagonal) =
            (load3(top_flow, c), load3(top_flow, c + 1), load3(bottom_flow, c), load3(bottom_flow, c + 1));
        let first = model.lane_forces(minus(down, i), minus(right, i), mean_flow_lanes(ui, udown, uright), valid);
        let second = model.lane_forces(
            minus(down, right),
            minus(diagonal, right),
            mean_flow_lanes(uright, udown, udiagonal),
            valid,
        );
        let [f0, f1, f2] = first;
        let [s0, s1, s2] = second;
        store(f0, out, c + 1);
        store(f1, out, stride + c + 1);
        store(f2, out, 2 * stride + c + 1);
        store(s0, out, 3 * stride + c + 1);
        store(s1, out, 4 * stride + c + 1);
        store(s2, out, 5 * stride + c + 1);
    }
}

/// One row of particles' kicks: each sums its six triangles (from the cell rows `above` and
/// `below`) in the order of its list, and its velocity in `v` changes as the general path's
/// would.
#[allow(clippy::too_many_arguments)]
#[inline]
fn particle_row(
    above: &[f32],
    below: &[f32],
    flows: [&[f32]; 3],
    inv_share: &[f32],
    free: &[f32],
    h: f32,
    v: &mut [Vec3A],
    stride: usize,
) {
    let cols = v.len();
    let (up_first, up_second) = (runs(above, 0, stride), runs(above, 3, stride));
    let (first, second) = (runs(below, 0, stride), runs(below, 3, stride));
    for c in (0..cols).step_by(4) {
        // Lane `c + 1` of a cell run is cell `c`: the cell to the left is lane `c`.
        let f = [
            sum_six(up_first[0], up_second[0], first[0], second[0], c),
            sum_six(up_first[1], up_second[1], first[1], second[1], c),
            sum_six(up_first[2], up_second[2], first[2], second[2], c),
        ];
        let share = Vec4::from_array(core::array::from_fn(|l| inv_share[(c + l).min(cols - 1)]));
        let scale = Vec4::splat(h) * share;
        let kick = capped_kick_lanes([f[0] * scale, f[1] * scale, f[2] * scale], load3(flows, c));
        let t = Mat4::from_cols(kick[0], kick[1], kick[2], Vec4::ZERO).transpose();
        let lanes = [t.x_axis, t.y_axis, t.z_axis, t.w_axis];
        for (l, kick) in lanes.into_iter().enumerate().take(cols - c) {
            if free[c + l] != 0.0 {
                v[c + l] += Vec3A::from_vec4(kick);
            }
        }
    }
}

/// The sum of one coordinate of the forces on particles `c` to `c + 3` of a row, from zero in
/// the order of their lists: the second triangle of the cell up and to the left, the first and
/// second of the cell up, the first and second of the cell to the left, the first of their own
/// cell (a cell run's lane `c` is cell `c - 1`).
#[inline(always)]
fn sum_six(up_first: &[f32], up_second: &[f32], first: &[f32], second: &[f32], c: usize) -> Vec4 {
    let mut f = Vec4::ZERO + load(up_second, c);
    f += load(up_first, c + 1);
    f += load(up_second, c + 1);
    f += load(first, c);
    f += load(second, c);
    f + load(first, c + 1)
}
