//! Particle accelerations of the mass-spring model (paper eq. 1–3), one grid row at a time.
//!
//! The cloth state is stored row by row, each row as six contiguous lanes
//! `[x | y | z | vx | vy | vz]` of `cols` floats. For every stencil offset the inner loop runs
//! over a contiguous column range with no branch, which the compiler vectorises; borders are
//! handled by shortening that range, not by tests inside the loop.

use glam::Vec3;

use crate::grid::{ClothGrid, STENCIL};
use crate::params::ClothParams;

/// Number of `f32` lanes per particle in the row layout (position and velocity).
pub const LANES: usize = 6;

/// Constants of the force model for one parameter set, precomputed per tick.
#[derive(Clone, Copy, Debug)]
pub struct ForceModel {
    /// `stiffness scale * spring_k / m` per spring kind.
    pub k_over_m: [f32; 3],
    /// Rest length per spring kind.
    pub rest: [f32; 3],
    /// Damping rate (1/s).
    pub damping: f32,
    /// Gravity plus the external force per unit mass.
    pub uniform_accel: Vec3,
}

impl ForceModel {
    /// Precomputes the model from validated parameters.
    pub fn new(params: &ClothParams, grid: &ClothGrid) -> Self {
        let m = params.particle_mass();
        let s = params.stiffness;
        let k = params.spring_k / m;
        Self {
            k_over_m: [s.structural * k, s.shear * k, s.bending * k],
            rest: [
                grid.rest_length(crate::grid::SpringKind::Structural),
                grid.rest_length(crate::grid::SpringKind::Shear),
                grid.rest_length(crate::grid::SpringKind::Bending),
            ],
            damping: params.damping,
            uniform_accel: params.gravity + params.external_force / params.mass,
        }
    }

    /// Writes the acceleration of every particle of row `r` into `acc` (`[ax | ay | az]`, each
    /// `cols` long), reading positions and velocities from `state` (the whole cloth, row layout).
    /// Pinned particles (`free == 0`) get zero.
    pub fn row_acceleration(&self, grid: &ClothGrid, state: &[f32], free: &[f32], r: usize, acc: &mut [f32]) {
        let cols = grid.cols;
        let w = LANES * cols;
        let row = &state[r * w..(r + 1) * w];
        let (px, py, pz) = (&row[..cols], &row[cols..2 * cols], &row[2 * cols..3 * cols]);
        let (vx, vy, vz) = (&row[3 * cols..4 * cols], &row[4 * cols..5 * cols], &row[5 * cols..]);
        let (ax, rest) = acc.split_at_mut(cols);
        let (ay, az) = rest.split_at_mut(cols);
        let g = self.uniform_accel;
        let c = self.damping;
        for i in 0..cols {
            ax[i] = g.x - c * vx[i];
            ay[i] = g.y - c * vy[i];
            az[i] = g.z - c * vz[i];
        }
        for s in STENCIL {
            let rr = r as i64 + i64::from(s.dr);
            if rr < 0 || rr >= grid.rows as i64 {
                continue;
            }
            let kind = s.kind as usize;
            let (k, rest_len) = (self.k_over_m[kind], self.rest[kind]);
            if k == 0.0 {
                continue;
            }
            let nrow = &state[rr as usize * w..(rr as usize + 1) * w];
            // Columns c whose neighbour c + dc lies in the grid.
            let dc = s.dc as i64;
            let lo = (-dc).max(0) as usize;
            let hi = (cols as i64 - dc.max(0)) as usize;
            if lo >= hi {
                continue;
            }
            let (nlo, nhi) = ((lo as i64 + dc) as usize, (hi as i64 + dc) as usize);
            spring_span(
                k,
                rest_len,
                [&px[lo..hi], &py[lo..hi], &pz[lo..hi]],
                [&nrow[nlo..nhi], &nrow[cols + nlo..cols + nhi], &nrow[2 * cols + nlo..2 * cols + nhi]],
                [&mut ax[lo..hi], &mut ay[lo..hi], &mut az[lo..hi]],
            );
        }
        let f = &free[r * cols..(r + 1) * cols];
        for i in 0..cols {
            ax[i] *= f[i];
            ay[i] *= f[i];
            az[i] *= f[i];
        }
    }
}

/// Adds the Hooke force (paper eq. 1, divided by the mass) of one spring per particle over a
/// contiguous span: particle `i` at `p[i]` pulled towards its neighbour at `q[i]`.
#[inline(always)]
fn spring_span(k: f32, rest: f32, p: [&[f32]; 3], q: [&[f32]; 3], a: [&mut [f32]; 3]) {
    let n = p[0].len();
    let [px, py, pz] = p.map(|s| &s[..n]);
    let [qx, qy, qz] = q.map(|s| &s[..n]);
    let [ax, ay, az] = a;
    let (ax, ay, az) = (&mut ax[..n], &mut ay[..n], &mut az[..n]);
    for i in 0..n {
        let dx = qx[i] - px[i];
        let dy = qy[i] - py[i];
        let dz = qz[i] - pz[i];
        let len = (dx * dx + dy * dy + dz * dz).sqrt();
        // k (|d| - rest) / |d|. The floor keeps a coincident pair (d = 0) finite: it then
        // contributes 0 * finite = 0.
        let s = k * (1.0 - rest / len.max(1.0e-6 * rest));
        ax[i] += s * dx;
        ay[i] += s * dy;
        az[i] += s * dz;
    }
}
