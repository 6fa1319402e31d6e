//! The explicit integrators, RK4 and semi-implicit Euler (paper 2.2, eq. 4): each stage over
//! bands of rows in parallel, with collision response fused into the last stage (paper
//! Fig. 1).

use std::sync::atomic::{AtomicUsize, Ordering};

use glam::Vec3;
use rayon::prelude::*;

use super::*;
use crate::cloth::topology::ClothTopology;
use crate::colliders::collider::Collider;
use crate::colliders::collision::ColliderFrame;
use crate::solver::forces::{ForceModel, LANES, SpringScratch};
use crate::solver::params::Integrator;

/// Rows per band: the unit of parallel work, and of spring reuse (see
/// [`ForceModel::band_acceleration`]). It is fixed, so results do not depend on the thread count.
const BAND_ROWS: usize = 8;

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
    /// Every particle's position and velocity, into `x` and `v`.
    pub(super) fn read_state(&self, x: &mut Vec<Vec3>, v: &mut Vec<Vec3>) {
        self.read_positions(x);
        v.clear();
        v.extend((0..self.len()).map(|i| self.velocity(i)));
    }

    /// Every particle's position, into `x`.
    pub(super) fn read_positions(&self, x: &mut Vec<Vec3>) {
        x.clear();
        x.extend((0..self.len()).map(|i| self.position(i)));
    }

    /// Sets every particle's position and velocity from `x` and `v`.
    pub(super) fn write_state(&mut self, x: &[Vec3], v: &[Vec3]) {
        for (i, (&p, &vel)) in x.iter().zip(v).enumerate() {
            self.set_position(i, p);
            self.set_velocity(i, vel);
        }
    }

    /// One substep of an explicit integrator: integration with collision fused into its last
    /// stage.
    pub(super) fn integrate(&mut self, h: f32, colliders: &[Collider]) {
        self.kick_explicit(h);
        let frames = self.frames(colliders);
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
            Integrator::BlockDescent { .. } | Integrator::Multigrid => {
                unreachable!("the implicit integrators are stepped by `descend`")
            }
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
        let quarantined = AtomicUsize::new(0);
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
                            let stopped = quarantine_row(width, base_row, out_row);
                            if stopped > 0 {
                                quarantined.fetch_add(stopped, Ordering::Relaxed);
                            }
                            let held_row = &mut held_band[j * width..(j + 1) * width];
                            collide_row(frames, width, base_row, free_row, out_row, held_row);
                        }
                    }
                },
            );
        self.quarantined += quarantined.into_inner();
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

/// The quarantine of a row's last stage, as the GPU's `node_update_final` does: a particle
/// whose substep went NaN or infinite keeps its position at the substep's start (`base`), at
/// rest, so that it cannot spread through the springs. Returns how many it stopped.
fn quarantine_row(cols: usize, base: &[f32], out: &mut [f32]) -> usize {
    let mut stopped = 0;
    for i in 0..cols {
        if (0..LANES).all(|l| out[l * cols + i].is_finite()) {
            continue;
        }
        for l in 0..LANES {
            out[l * cols + i] = if l < 3 { base[l * cols + i] } else { 0.0 };
        }
        stopped += 1;
    }
    stopped
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
