//! Vertex Block Descent (Chen, Macklin et al., SIGGRAPH 2024) for the mass-spring cloth: an
//! integrator whose cost per tick is `looper x iterations` sweeps, whatever the stiffness and the
//! resolution, and which stays stable at every stiffness.
//!
//! ## The method
//! Each substep of `h` seconds is one step of implicit Euler, found by minimising, over the new
//! positions `x`, the incremental potential
//! `G(x) = Σ m_i/(2h²) |x_i - y_i|² + Σ c m_i/(2h) |x_i - x_i⁰|² + Σ_springs ½ k (|x_j - x_i| - L)²`,
//! where `x⁰` is the substep's start, `y = x⁰ + h v⁰ + h² g` the inertial target (`g` gravity
//! plus the external force per unit mass) and `c` the damping rate. The middle term is the
//! cloth's damping force `-c m v`, taken implicitly. The springs are those of the explicit
//! integrators, with the same stiffness `spring_k x scale x weight`, so switching integrator
//! keeps the material: at rest both settle on the same equilibrium.
//!
//! Block descent minimises `G` one particle at a time, with the others held: a particle's
//! gradient `f_i` and its 3x3 Hessian `H_i` (inertia, damping and each spring's Hessian with its
//! compressive part clamped to zero, so `H_i` is positive definite) give the Newton step
//! `x_i -= H_i⁻¹ f_i`. Particles of one colour share no spring ([`crate::colouring`]), so a
//! colour is updated in parallel; one iteration is one sweep over the colours. Each update can
//! only lower `G` up to the clamped curvature, and the inertia term bounds the step, so no
//! stiffness makes it diverge. After the iterations, `v = (x - x⁰)/h`, and the collision
//! response runs as for the explicit integrators, from `x⁰` to `x`.
//!
//! Every quantity is divided by the particle's mass and multiplied by `h²`, so that the 3x3
//! system is of order one (`H = (1 + c h) I + h² Σ κ H_spring`, `κ` the spring's stiffness over
//! the particle's mass, as in [`crate::forces`]) and stays well inside `f32`.
//!
//! ## Why block descent, and not XPBD
//! Both are unconditionally stable and both turn stiffness into a fixed cost. What decided it
//! is the layout the other kernels already have: each particle gathers its springs from its
//! own list (CSR) and writes only itself. Block descent is exactly that gather, once per colour,
//! so it reuses the spring buffers and needs no per-spring state; the grid needs 5 colours.
//! XPBD solves one spring at a time and writes both ends: it needs a Lagrange multiplier per
//! spring, and a colouring of the springs, which on the grid's 12-spring stencil takes at least
//! 12 colours (every spring at a particle needs its own), or Jacobi averaging with its slower
//! convergence. Measured on this crate's 2-core CPU reference (`cargo bench -p
//! bvh_cloth_bench --bench report -- solver`), a 64x64 cloth hanging from two corners settles
//! to RK4's sag at a fraction of RK4's cost; BENCHMARKS.md gives the figures.
//!
//! ## Its limits
//! With few iterations a stiff, fine cloth stretches more than RK4 would while it moves (the
//! sweeps have not converged); at rest it reaches the same equilibrium. Implicit Euler also
//! damps fast motion a little more than RK4. Both shrink as `looper` grows.

use glam::Vec3;
use rayon::prelude::*;

use crate::collision::ColliderFrame;
use crate::forces::ForceModel;
use crate::topology::{ClothTopology, SpringEnd};

/// Most block-descent iterations per substep. More buys less than more substeps do.
pub const MAX_ITERATIONS: u32 = 16;

/// Particles one rayon task updates at least: below that, the colour is not split.
const MIN_TASK: usize = 512;

/// The new position of one particle: one Newton step on its block of the incremental potential
/// (see the [module docs](self)). `x` is its current position, `start` its position at the
/// start of the substep, `target` its inertial target, `springs` its springs (their other ends
/// read through `position`) and `inv_share` its inverse mass share. The GPU's `vbd_solve`
/// repeats this arithmetic in the same order.
#[allow(clippy::too_many_arguments)]
#[inline]
pub fn descend(
    model: &ForceModel,
    h: f32,
    inv_share: f32,
    springs: &[SpringEnd],
    x: Vec3,
    start: Vec3,
    target: Vec3,
    position: impl Fn(u32) -> Vec3,
) -> Vec3 {
    let h2 = h * h;
    let ch = model.damping * h;
    // h² f / m and h² H / m, H symmetric: diagonal (a, d, f), off-diagonal (b, c, e).
    let mut g = (x - target) + ch * (x - start);
    let inertia = 1.0 + ch;
    let (mut a, mut d, mut f) = (inertia, inertia, inertia);
    let (mut b, mut c, mut e) = (0.0f32, 0.0f32, 0.0f32);
    for end in springs {
        let k = model.k_over_mass[end.kind as usize] * end.weight * inv_share * h2;
        if k == 0.0 {
            continue;
        }
        let delta = position(end.other) - x;
        let len = (delta.x * delta.x + delta.y * delta.y + delta.z * delta.z).sqrt();
        let l = len.max(1.0e-6 * end.rest);
        let stretch = 1.0 - end.rest / l;
        g -= k * stretch * delta;
        // k (s⁺ I + (1 - s⁺) u uᵀ): the spring's Hessian with its compressive part clamped.
        let s = stretch.max(0.0);
        let u = delta / l;
        let t = k * (1.0 - s);
        a += k * s + t * u.x * u.x;
        d += k * s + t * u.y * u.y;
        f += k * s + t * u.z * u.z;
        b += t * u.x * u.y;
        c += t * u.x * u.z;
        e += t * u.y * u.z;
    }
    // The cofactors of the symmetric matrix; its determinant is positive (H >= (1 + ch) I).
    let ca = d * f - e * e;
    let cb = c * e - b * f;
    let cc = b * e - c * d;
    let cd = a * f - c * c;
    let ce = b * c - a * e;
    let cf = a * d - b * b;
    let det = a * ca + b * cb + c * cc;
    let step =
        Vec3::new(ca * g.x + cb * g.y + cc * g.z, cb * g.x + cd * g.y + ce * g.z, cc * g.x + ce * g.y + cf * g.z) / det;
    x - step
}

/// The block-descent stepper's working state for one cloth: positions and velocities by
/// particle, and the substep's start and inertial target.
#[derive(Clone, Debug, Default)]
pub(crate) struct BlockDescent {
    pub(crate) x: Vec<Vec3>,
    pub(crate) v: Vec<Vec3>,
    start: Vec<Vec3>,
    target: Vec<Vec3>,
    moved: Vec<Vec3>,
}

impl BlockDescent {
    /// Sizes the buffers for `n` particles.
    pub(crate) fn resize(&mut self, n: usize) {
        for buffer in [&mut self.x, &mut self.v, &mut self.start, &mut self.target] {
            buffer.resize(n, Vec3::ZERO);
        }
    }

    /// One substep of `h` seconds with `iterations` sweeps over the colours, then the velocity
    /// update and the collision response. `free[i]` is 0 for a held particle, which neither
    /// moves nor changes velocity.
    pub(crate) fn substep(
        &mut self,
        topology: &ClothTopology,
        model: &ForceModel,
        free: &[f32],
        h: f32,
        iterations: u32,
        frames: &[ColliderFrame<'_>],
    ) {
        let Ok(colouring) = topology.colouring() else { return };
        let Self { x, v, start, target, moved } = self;
        let accel = model.uniform_accel;
        start.copy_from_slice(x);
        // The first iterate moves with the velocity only: a cloth at rest starts where it was,
        // so that with any number of sweeps its equilibrium is the springs' own.
        x.par_iter_mut()
            .zip(target.par_iter_mut())
            .zip(v.par_iter())
            .zip(free.par_iter())
            .with_min_len(MIN_TASK)
            .for_each(|(((x, target), &v), &free)| {
                if free != 0.0 {
                    *x += h * v;
                    *target = *x + (h * h) * accel;
                } else {
                    *target = *x;
                }
            });
        let inv_share = topology.inv_mass_share();
        for _ in 0..iterations {
            for k in 0..colouring.len() {
                let colour = colouring.colour(k);
                moved.resize(colour.len(), Vec3::ZERO);
                let current: &[Vec3] = x;
                colour.par_iter().zip(moved.par_iter_mut()).with_min_len(MIN_TASK).for_each(|(&i, out)| {
                    let i = i as usize;
                    *out = if free[i] != 0.0 {
                        descend(model, h, inv_share[i], topology.springs_of(i), current[i], start[i], target[i], |j| {
                            current[j as usize]
                        })
                    } else {
                        current[i]
                    };
                });
                for (&i, &p) in colour.iter().zip(moved.iter()) {
                    x[i as usize] = p;
                }
            }
        }
        let inv_h = 1.0 / h;
        x.par_iter_mut()
            .zip(v.par_iter_mut())
            .zip(start.par_iter())
            .zip(free.par_iter())
            .with_min_len(MIN_TASK)
            .for_each(|(((x, v), &start), &free)| {
                if free == 0.0 {
                    return;
                }
                *v = (*x - start) * inv_h;
                for frame in frames {
                    frame.resolve(start, x, v);
                }
            });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::ClothParams;

    /// `G` of one particle's block, in the units [`descend`] minimises (times `h² / m`).
    fn block_potential(
        model: &ForceModel,
        h: f32,
        springs: &[SpringEnd],
        others: &[Vec3],
        x: Vec3,
        start: Vec3,
        target: Vec3,
    ) -> f64 {
        let (x, start, target) = (x.as_dvec3(), start.as_dvec3(), target.as_dvec3());
        let h = f64::from(h);
        let mut g =
            0.5 * (x - target).length_squared() + 0.5 * f64::from(model.damping) * h * (x - start).length_squared();
        for (end, &q) in springs.iter().zip(others) {
            let k = f64::from(model.k_over_mass[end.kind as usize] * end.weight) * h * h;
            let stretch = (q.as_dvec3() - x).length() - f64::from(end.rest);
            g += 0.5 * k * stretch * stretch;
        }
        g
    }

    #[test]
    fn each_update_lowers_its_block_potential_at_any_stiffness() {
        let others = [Vec3::new(1.2, 0.1, 0.0), Vec3::new(-0.3, 0.9, 0.2), Vec3::new(0.1, -0.2, -1.4)];
        let springs: Vec<SpringEnd> = (0..3).map(|j| SpringEnd { other: j, kind: j, rest: 1.0, weight: 1.0 }).collect();
        let (start, target) = (Vec3::new(0.05, 0.0, 0.02), Vec3::new(0.1, -0.05, 0.0));
        for spring_k in [0.0, 10.0, 400.0, 1.0e4, 1.0e7] {
            let model = ForceModel::new(&ClothParams { spring_k, damping: 2.0, ..Default::default() });
            for h in [1.0 / 960.0, 1.0 / 60.0] {
                let mut x = target;
                let mut before = block_potential(&model, h, &springs, &others, x, start, target);
                for _ in 0..4 {
                    x = descend(&model, h, 1.0, &springs, x, start, target, |j| others[j as usize]);
                    assert!(x.is_finite(), "k {spring_k}, h {h}");
                    let after = block_potential(&model, h, &springs, &others, x, start, target);
                    assert!(after <= before * (1.0 + 1e-5) + 1e-12, "k {spring_k}, h {h}: {before} -> {after}");
                    before = after;
                }
            }
        }
    }
}
