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
//! `x_i -= H_i⁻¹ f_i`. Particles of one colour share no spring (see `cloth::colouring`), so a
//! colour is updated in parallel; one iteration is one sweep over the colours. Each update can
//! only lower `G` up to the clamped curvature, and the inertia term bounds the step, so no
//! stiffness makes it diverge. After the iterations, `v = (x - x⁰)/h`, and the collision
//! response runs as for the explicit integrators, from `x⁰` to `x`.
//!
//! ## Free fall and momentum, whatever the sweeps leave unconverged
//! Two things keep an unconverged sweep from changing how a cloth falls and drifts:
//! - **The first iterate** is where inertia, damping and the acceleration the particle is
//!   estimated to follow take it, `x⁰ + (h v⁰ + h² ã) / (1 + c h)` (`first_iterate`), with
//!   `ã` the part of the uniform acceleration the particle followed in its last substep, along
//!   it and clamped to `[0, |g|]` (`AccelAxis::estimate`; the adaptive initial guess of Chen
//!   et al. 2024, with the damping taken out of the estimate so that a falling particle's is the
//!   whole of `g`). A cloth in free fall starts each substep at the exact minimiser of `G`, so
//!   the sweeps have nothing to carry; a cloth at rest on a collider or hanging still starts
//!   where it was, so its equilibrium stays the springs' own. Starting from `x⁰ + h v⁰` instead
//!   left gravity to a sweep that moves a particle held by stiff springs to neighbours that
//!   have not moved yet by a fraction of it: a 64 x 64 grid turned upright fell 1.82 m in 1 s
//!   instead of 4.18 m.
//! - **The centre of mass.** The springs are internal forces, so the exact minimiser of `G`
//!   moves the centre of mass of a cloth that nothing holds exactly as inertia, damping and
//!   the uniform acceleration say; a Gauss–Seidel sweep that has not converged does not. For
//!   such a cloth (no particle with mass pinned), the sweeps' drift of the centre of mass
//!   (`centre_of_mass_drift`) is taken back from every free particle before the collision
//!   response, which changes no spring's length. A held cloth's pins take up momentum anyway,
//!   and its drift is not summed.
//!
//! Measured on the 2-core development machine with the cloths of the core's `free_fall` tests
//! (default parameters, 60 ticks of 1/60 s; the bundled bunny and dragon as authored cloth
//! 0.5 m across, dropped flat here, their particles' masses their area shares without the
//! mass floor), each part switched off in turn: the drop in 1 s, against
//! `g/c (t - (1 - e^{-ct})/c)` = 4.180 m, and how far the centre of mass moves sideways on a
//! frictionless ground in 3 s. The report's `motion` section gives the solver as it is, and
//! `cargo test -p bvh_cloth_core --release --test core -- --nocapture free_fall::` prints
//! its figures for the tests' poses.
//!
//! | cloth | before: fell | drifted on the ground | first iterate alone: fell | on the ground | both: fell | on the ground |
//! |---|---|---|---|---|---|---|
//! | 64 x 64 grid upright | 1.825 m | | 4.168 m | | 4.182 m | |
//! | bunny (1,839 particles) | 3.158 m | 139 mm | 4.180 m | 144 mm | 4.184 m | 0.25 mm |
//! | dragon (5,205 particles) | 2.136 m | 290 mm | 4.169 m | 301 mm | 4.183 m | 0.12 mm |
//!
//! The drift that remains on the ground comes from the collision response, which moves a
//! particle that crossed the ground back along its path and so takes back the sideways part of
//! the rest of that path too: it depends on how a cloth lands (a 30 x 30 grid upright from
//! 0.3 m, about 10 mm on both backends; the tests' sheet with sliver triangles landing on an
//! edge, 0.2 mm).
//!
//! Every quantity is divided by the particle's mass and multiplied by `h²`, so that the 3x3
//! system is of order one (`H = (1 + c h) I + h² Σ κ H_spring`, `κ` the spring's stiffness over
//! the particle's mass, as in the spring forces) and stays well inside `f32`.
//!
//! ## Displacements, so that `f32` holds a substep wherever the cloth is
//! The sweeps solve for each particle's displacement over the substep, `d = x - x⁰`, not for its
//! position: the first iterate, the inertial target (`y - x⁰`) and the Newton steps are
//! displacements, a spring's vector is `(x⁰_j - x⁰_i) + (d_j - d_i)`, and the substep ends
//! with `x = x⁰ + d` and `v = d / h`. A displacement is a few millimetres, which `f32` keeps to
//! a fraction of a nanometre, while a position 1 km from the origin is kept to 61 µm, more than
//! gravity moves a particle at rest in a substep (`h² g` = 11 µm at Looper 16): solving for
//! positions, a cloth hanging 1 km from the origin never moved (its first iterate and its
//! target rounded back to its start), 100 m up it sagged 25 % less than near the origin at
//! 0.25 s and 54 % more at 1 s, and near the origin at Looper 64 it fell 10 % faster than
//! gravity. Solving for displacements, 1 km out it sags within 0.7 % of the same cloth near the
//! origin (the core's `motion` tests); what remains is the positions' own rounding, which RK4
//! shares (1.9 %).
//!
//! ## Why block descent, and not XPBD
//! Both are unconditionally stable and both turn stiffness into a fixed cost. What decided it
//! is the layout the other kernels already have: each particle gathers its springs from its
//! own list (CSR) and writes only itself. Block descent is exactly that gather, once per colour,
//! so it reuses the spring buffers and needs no per-spring state, and the grid needs 5 colours:
//! 5 passes per sweep. XPBD solves one spring at a time and writes both ends: it needs a
//! Lagrange multiplier per spring and a colouring of the springs, which on the grid's
//! 12-spring stencil takes at least 12 colours (every spring at a particle needs its own), so
//! at least 12 passes per sweep, or Jacobi averaging with its slower convergence.
//!
//! Measured with `cargo bench -p bvh_cloth_bench --bench report -- solver` on the 2-core
//! development machine (BENCHMARKS.md has the tables): a 64x64 cloth hanging from two corners
//! settles within 0.04 % of RK4's sag at the same Looper 16, and within 3.2 % at Looper 4, which
//! costs 1.4 ms per tick against RK4's 4.2 ms on one thread. Raising SpringK from 200 to 20,000
//! N/m makes RK4's guard take 157 substeps (42 ms per tick); block descent stays at 16 (6 ms).
//!
//! ## Its limits
//! One sweep per substep moves information one spring per colour pass, so the slowest, largest
//! modes of a big cloth converge over many substeps: the same 64x64 cloth at Looper 2 still hangs
//! 29 % short of its sag after 8 s. While a fine cloth moves, the load of the particles far from
//! its pins reaches them late, and the cloth stretches far more than RK4's would, the more the
//! finer. A held cloth's tethers ([`crate::cloth::tethers`], on by default) carry that load to the pins
//! in every substep; the figures with and without them are in that module's docs. A cloth that
//! nothing holds has no tethers, and there the stretch of a fine cloth in motion remains. The
//! default integrator adds a multigrid correction to the sweep ([`crate::solver::multigrid`]),
//! which carries the load across the whole cloth in every substep, held or not.
//! Implicit Euler also damps fast motion more than RK4. Converged (no tethers, and sweeps
//! beyond the [`MAX_ITERATIONS`](crate::solver::params::MAX_ITERATIONS) a cloth may ask for,
//! 64 and 256 a substep giving the same sag), the hanging cloth of the core's `motion` tests
//! sags more than RK4's at 1 s, having given up some of the springs' energy that swings RK4's
//! cloth back up:
//!
//! | substeps a 60 Hz tick | 32 x 32 | 64 x 64 | 128 x 128 |
//! |---|---|---|---|
//! | 16 (the default) | +7 % | +11 % | +9 % |
//! | 32 | +3 % | +8 % | |
//! | 64 | +2 % | +4 % | |
//!
//! For a given number of sweeps a tick, substeps buy more than sweeps: at 64 x 64 without
//! tethers, 16 substeps of one sweep sag 45 % more than RK4 at 1 s, 8 of two 74 %, 4 of four
//! 138 %. All of these shrink as `looper` grows; at rest every setting reaches the springs'
//! own equilibrium (the tethers take speed, not position).
//!
//! ## The multigrid integrator: BDF2, one sweep and a coarse correction
//! [`Integrator::Multigrid`](crate::solver::params::Integrator::Multigrid) answers both limits
//! with the same stepper. Each substep is a BDF2 step (Curtiss and Hirschfelder's backward
//! differentiation of second order): `x = x̂ + ĥ v` and `v = v̂ + ĥ a(x, v)` with `ĥ = 2h/3`,
//! `x̂ = (4x⁰ - x⁻¹)/3` and `v̂ = (4v⁰ - v⁻¹)/3`, which is implicit Euler's minimisation of `G`
//! with `ĥ` for `h` and `x̂`, `v̂` for the substep's start: only the inertial target, the
//! damping's centre and the first iterate change (`x̂ + (ĥ v̂ + ĥ² ã) / (1 + c ĥ)`), and the
//! velocity is `(x - x̂) / ĥ`. An aerodynamic kick, applied to `v⁰` before the substep, enters
//! `v̂` as `ĥ a_air`. BDF2 is second-order accurate and damps a cloth's visible modes far less
//! than implicit Euler, while still damping the springs' fastest ones; it needs the last
//! substep, so a substep is implicit Euler instead when the history does not hold: the first
//! one, one after anything but the springs moved a particle (a collider, self-contact, the
//! quarantine, or a write to the cloth's state between ticks), one of another length, and one
//! where `ĥ² k_max / m_min` passes `BDF2_STIFFNESS_LIMIT` (springs far stiffer than a cloth's,
//! where BDF2 rings). Between `BLEND_LIMIT` and that limit (the finest cloths at the default
//! Looper: 512 x 512's substeps sit at 88, 1024 x 1024's at 354) a substep blends the two, `x̂ = x⁰ + θ (x⁰ -
//! x⁻¹)/3`, `v̂` alike and `ĥ = (1 - θ/3) h` at `θ = 0.8` ([`BLEND_LAG`]; BDF2 at 1, implicit
//! Euler at 0), and the correction runs its first level's W-cycle: there one sweep and a
//! V-cycle leave a stretch that BDF2's two-step history rings on, and implicit Euler damps the
//! swing (the multigrid module's docs have the figures). After the sweep, the multigrid
//! correction ([`crate::solver::multigrid`]) carries the load across the cloth within the
//! substep, so it needs no tethers. The centre of mass is kept as for block descent, about
//! where inertia, damping and the uniform acceleration take the BDF2 step.

use std::sync::atomic::{AtomicUsize, Ordering};

use glam::{Vec3, Vec3A};
use rayon::prelude::*;

use crate::cloth::colouring::ParticleColouring;
use crate::cloth::grid::SpringEnd;
use crate::cloth::tethers::TetherSet;
use crate::cloth::topology::ClothTopology;
use crate::colliders::collision::ColliderFrame;
use crate::solver::forces::ForceModel;
use crate::solver::multigrid::{Cycle, Multigrid, MultigridCorrection};

/// Particles one rayon task updates at least: below that, a pass is not split, since a fork
/// and join costs more than the updates it would share (a 64x64 cloth's colours are not split).
const MIN_TASK: usize = 4096;

/// The new displacement of one particle over the substep: one Newton step on its block of the
/// incremental potential (see the [module docs](self)). `d` is its current displacement from
/// `start`, its position at the start of the substep, `target` its inertial target less
/// `start`, `springs` its springs (their other ends' starts and displacements read through
/// `other`) and `inv_share` its inverse mass share. The GPU's `vbd_solve`
/// repeats this arithmetic in the same order; the solver runs it four lanes at a time
/// (`descend_lanes`), and the tests hold the lanes to this one bit for bit.
#[cfg(test)]
#[allow(clippy::too_many_arguments)]
fn descend(
    model: &ForceModel,
    h: f32,
    inv_share: f32,
    springs: &[SpringEnd],
    d: Vec3A,
    start: Vec3A,
    target: Vec3A,
    other: impl Fn(u32) -> (Vec3A, Vec3A),
) -> Vec3A {
    use glam::Vec3Swizzles;

    let h2 = h * h;
    let ch = model.damping * h;
    // h² f / m, and h² H / m: H is symmetric, kept as its diagonal (xx, yy, zz) and its
    // off-diagonal (xy, xz, yz).
    let mut g = (d - target) + ch * d;
    let mut diag = Vec3A::splat(1.0 + ch);
    let mut off = Vec3A::ZERO;
    for end in springs {
        let k = model.k_over_mass[end.kind as usize] * end.weight * inv_share * h2;
        if k == 0.0 {
            continue;
        }
        let (other_start, other_d) = other(end.other);
        let delta = (other_start - start) + (other_d - d);
        let len = delta.dot(delta).sqrt();
        let inv_l = 1.0 / len.max(1.0e-6 * end.rest);
        let stretch = 1.0 - end.rest * inv_l;
        g -= k * stretch * delta;
        // k (s⁺ I + (1 - s⁺) u uᵀ): the spring's Hessian with its compressive part clamped.
        let s = stretch.max(0.0);
        let u = delta * inv_l;
        let t = k * (1.0 - s);
        diag += k * s + t * (u * u);
        off += t * (u.xxy() * u.yzz());
    }
    newton_step(d, g, diag, off)
}

/// `x - H⁻¹ g` for the symmetric 3x3 `H` of diagonal `diag` (xx, yy, zz) and off-diagonal `off`
/// (xy, xz, yz), by cofactors; its determinant is positive (`H >= (1 + ch) I`).
#[inline]
fn newton_step(x: Vec3A, g: Vec3A, diag: Vec3A, off: Vec3A) -> Vec3A {
    let (a, d, f) = (diag.x, diag.y, diag.z);
    let (b, c, e) = (off.x, off.y, off.z);
    let ca = d * f - e * e;
    let cb = c * e - b * f;
    let cc = b * e - c * d;
    let cd = a * f - c * c;
    let ce = b * c - a * e;
    let cf = a * d - b * b;
    let det = a * ca + b * cb + c * cc;
    let step =
        Vec3A::new(ca * g.x + cb * g.y + cc * g.z, cb * g.x + cd * g.y + ce * g.z, cc * g.x + ce * g.y + cf * g.z)
            / det;
    x - step
}

/// Particles [`descend_lanes`] updates at once: two SSE vectors, whose square roots and
/// divisions overlap.
const WIDTH: usize = 8;

/// [`descend`] for [`WIDTH`] particles at once: lane by lane the same arithmetic in the same
/// order, so the results are bit-identical, but laid out as arrays over the lanes so that the
/// compiler runs the particles' square roots, divisions and products in SIMD lanes. A lane
/// whose particle has run out of springs adds a spring of zero stiffness, which adds exactly
/// zero.
#[allow(clippy::too_many_arguments)]
#[inline]
fn descend_lanes(
    model: &ForceModel,
    h: f32,
    inv_share: [f32; WIDTH],
    springs: [&[SpringEnd]; WIDTH],
    d: [Vec3A; WIDTH],
    start: [Vec3A; WIDTH],
    target: [Vec3A; WIDTH],
    starts: &[Vec3A],
    displacements: &[Vec3A],
) -> [Vec3A; WIDTH] {
    let h2 = h * h;
    let ch = model.damping * h;
    let mut g = [[0.0f32; WIDTH]; 3];
    let mut diag = [[1.0 + ch; WIDTH]; 3];
    let mut off = [[0.0f32; WIDTH]; 3];
    for l in 0..WIDTH {
        let gl = (d[l] - target[l]) + ch * d[l];
        for axis in 0..3 {
            g[axis][l] = gl[axis];
        }
    }
    let count = springs.iter().map(|s| s.len()).max().unwrap_or(0);
    for s in 0..count {
        let mut delta = [[1.0f32; WIDTH], [0.0; WIDTH], [0.0; WIDTH]];
        let mut k = [0.0f32; WIDTH];
        let mut rest = [1.0f32; WIDTH];
        for l in 0..WIDTH {
            if let Some(end) = springs[l].get(s) {
                let o = end.other as usize;
                let e = (starts[o] - start[l]) + (displacements[o] - d[l]);
                (delta[0][l], delta[1][l], delta[2][l]) = (e.x, e.y, e.z);
                k[l] = model.k_over_mass[end.kind as usize] * end.weight * inv_share[l] * h2;
                rest[l] = end.rest;
            }
        }
        let [dx, dy, dz] = delta;
        for l in 0..WIDTH {
            let len = (dx[l] * dx[l] + dy[l] * dy[l] + dz[l] * dz[l]).sqrt();
            let inv_l = 1.0 / len.max(1.0e-6 * rest[l]);
            let stretch = 1.0 - rest[l] * inv_l;
            let pull = k[l] * stretch;
            let sp = stretch.max(0.0);
            let t = k[l] * (1.0 - sp);
            let along = k[l] * sp;
            let u = [dx[l] * inv_l, dy[l] * inv_l, dz[l] * inv_l];
            for axis in 0..3 {
                g[axis][l] -= pull * delta[axis][l];
                diag[axis][l] += along + t * (u[axis] * u[axis]);
            }
            off[0][l] += t * (u[0] * u[1]);
            off[1][l] += t * (u[0] * u[2]);
            off[2][l] += t * (u[1] * u[2]);
        }
    }
    let lane = |v: &[[f32; WIDTH]; 3], l: usize| Vec3A::new(v[0][l], v[1][l], v[2][l]);
    core::array::from_fn(|l| newton_step(d[l], lane(&g, l), lane(&diag, l), lane(&off, l)))
}

/// The block-descent stepper's working state for one cloth: positions and velocities by
/// particle, the substep's start and inertial target, and what the multigrid integrator keeps
/// between substeps.
#[derive(Clone, Debug, Default)]
pub(crate) struct BlockDescent {
    /// Positions between substeps; within one, during the sweeps, each particle's displacement
    /// from `start` (see the module docs on precision).
    pub(crate) x: Vec<Vec3A>,
    pub(crate) v: Vec<Vec3A>,
    /// Each particle's estimate of the uniform acceleration it follows, along the uniform
    /// acceleration, in m/s² (see [`AccelAxis::estimate`]).
    pub(crate) accel: Vec<f32>,
    /// The last substep's start; between substeps, with `x`, BDF2's history.
    start: Vec<Vec3A>,
    /// The inertial target less the substep's start.
    target: Vec<Vec3A>,
    moved: Vec<Vec3A>,
    /// The velocities at the last substep's start, BDF2's history.
    v_prev: Vec<Vec3A>,
    /// BDF2's `x̂ - x⁰` for each particle (zero for an implicit Euler substep).
    lag: Vec<Vec3A>,
    /// The velocities before this substep's aerodynamic kick, when it has one
    /// ([`Self::before_kick`]): BDF2 takes the kick over `2h/3`, not `h`.
    unkicked: Vec<Vec3A>,
    kicked: bool,
    /// 1 for a particle self-contact moved after the last substep, else 0
    /// ([`Self::moved_by_contact`]); the multigrid correction leaves it where the sweep puts it.
    contact_moved: Vec<f32>,
    any_contact_moved: bool,
    /// The length of the last substep when BDF2 may build on it: the cloth's state is what it
    /// left, and nothing but the springs, inertia and the uniform acceleration moved a particle
    /// in it (no collider, no self-contact, no quarantine).
    pub(crate) history: Option<f32>,
    multigrid: Multigrid,
}

/// How a block-descent substep solves its implicit step.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Solve<'a> {
    /// Implicit Euler by `iterations` sweeps, and the tethers (with their length scale) when
    /// the cloth has them.
    Sweeps { iterations: u32, tethers: Option<(&'a TetherSet, f32)> },
    /// BDF2 where its history allows (implicit Euler otherwise), by one sweep and the
    /// multigrid correction ([`crate::solver::multigrid`]).
    Multigrid,
}

/// BDF2's limit on `(2h/3)² k_max / m_min` (the stiffest spring over the lightest particle,
/// in units of the substep): beyond it a substep is implicit Euler, which damps what BDF2 would
/// let ring. The default cloths at Looper 16 sit at 0.35 (32 x 32), 22 (256 x 256) and 354
/// (1024 x 1024). Measured with the multigrid correction (a cloth hanging from two corners,
/// the fastest particle in its second second): calm at 3,000 on 64 x 64 and at 550 on
/// 128 x 128; at 1,000 on 128 x 128 it rang at 21 m/s; at 354 on 256 x 256 its fastest
/// particle moved at 9.3 m/s, where the default 256 x 256 cloth's moves at 8.5 m/s.
pub(crate) const BDF2_STIFFNESS_LIMIT: f32 = 400.0;

/// The stiffness `(2h/3)² k_max / m_min` past which a substep blends BDF2 with implicit Euler
/// ([`BLEND_LAG`]) and the correction runs [`Cycle::TopW`], up to [`BDF2_STIFFNESS_LIMIT`]:
/// between 256 x 256's 22 and 512 x 512's 88 at Looper 16 (the multigrid module's docs have
/// the measurements).
pub(crate) const BLEND_LIMIT: f32 = 50.0;

/// The blended step's weight of the last substep, `θ/3` with `θ = 0.8`: `x̂ = x⁰ + θ (x⁰ -
/// x⁻¹)/3`, `v̂` alike, for `ĥ = (1 - θ/3) h` ([`BLEND_STEP`]); `θ = 1` is BDF2, `θ = 0`
/// implicit Euler.
pub const BLEND_LAG: f32 = 0.8 / 3.0;

/// The blended step's `ĥ / h`, `1 - θ/3` ([`BLEND_LAG`]).
pub const BLEND_STEP: f32 = 1.0 - BLEND_LAG;

/// How the multigrid integrator steps a cloth, by the stiffness of its substep,
/// `(2h/3)² k_max / m_min` (the stiffest spring over the lightest particle, in units of BDF2's
/// step).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MultigridStepping {
    /// BDF2 where the history allows, with V-cycles: a stiffness up to 50.
    Bdf2,
    /// The blend of BDF2 and implicit Euler ([`BLEND_LAG`]) where the history allows, with
    /// [`Cycle::TopW`]: a stiffness from 50 to 400.
    Blend,
    /// Implicit Euler in every substep, the levels assembled in every one, with V-cycles: a
    /// stiffness past 400.
    Stiff,
}

impl MultigridStepping {
    /// The stepping for a cloth of `topology` under `model` in substeps of `h` seconds.
    pub fn of(model: &ForceModel, topology: &ClothTopology, h: f32) -> Self {
        let stiffness = bdf2_stiffness(model, topology, h);
        if stiffness > BDF2_STIFFNESS_LIMIT {
            Self::Stiff
        } else if stiffness > BLEND_LIMIT {
            Self::Blend
        } else {
            Self::Bdf2
        }
    }

    /// The coarse cycle the correction runs.
    pub fn cycle(self) -> Cycle {
        if self == Self::Blend { Cycle::TopW } else { Cycle::V }
    }
}

/// How a substep steps in time.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Step {
    Euler,
    Bdf2,
    Blend,
}

impl Step {
    /// The length `ĥ` of the implicit step a substep of `h` seconds minimises over.
    fn length(self, h: f32) -> f32 {
        match self {
            Self::Euler => h,
            Self::Bdf2 => h * (2.0 / 3.0),
            Self::Blend => h * BLEND_STEP,
        }
    }
}

impl BlockDescent {
    /// Keeps the velocities as they are before the next substep's aerodynamic kick changes
    /// them.
    pub(crate) fn before_kick(&mut self) {
        self.unkicked.clone_from(&self.v);
        self.kicked = true;
    }

    /// Marks particle `i` as moved by self-contact after the last substep: BDF2 starts again,
    /// and the multigrid correction leaves the particle alone in the next substep.
    pub(crate) fn moved_by_contact(&mut self, i: usize) {
        self.history = None;
        if self.contact_moved.len() != self.x.len() {
            self.contact_moved = vec![0.0; self.x.len()];
        }
        self.contact_moved[i] = 1.0;
        self.any_contact_moved = true;
    }

    /// The substep's start, inertial targets and first iterate of every particle for a substep
    /// of `h` seconds stepped as `how` says.
    fn predict(&mut self, model: &ForceModel, free: &[f32], h: f32, how: Step) {
        let step = how.length(h);
        let kicked = core::mem::take(&mut self.kicked);
        let Self { x, v, accel, start, target, v_prev, lag, unkicked, .. } = self;
        let uniform = Vec3A::from(model.uniform_accel);
        let axis = AccelAxis::new(uniform);
        let damp = 1.0 + model.damping * step;
        let inv_damp = 1.0 / damp;
        let before_kick: &[Vec3A] = if kicked { unkicked } else { &[] };
        x.par_iter_mut()
            .zip(v.par_iter_mut())
            .zip(start.par_iter_mut())
            .zip(v_prev.par_iter_mut())
            .zip(lag.par_iter_mut())
            .zip(target.par_iter_mut())
            .zip(accel.par_iter())
            .zip(free.par_iter())
            .enumerate()
            .with_min_len(MIN_TASK)
            .for_each(|(i, (((((((x, v), start), v_prev), lag), target), &estimate), &free))| {
                let (x0, v0) = (*x, *v);
                // The velocity before the kick, and the kick `h a_air`, which the step takes as
                // `ĥ a_air`.
                let unkicked = before_kick.get(i).copied().unwrap_or(v0);
                let v_hat = match how {
                    Step::Euler => v0,
                    Step::Bdf2 => unkicked + (unkicked - *v_prev) / 3.0 + (v0 - unkicked) * (2.0 / 3.0),
                    Step::Blend => unkicked + (unkicked - *v_prev) * BLEND_LAG + (v0 - unkicked) * BLEND_STEP,
                };
                *lag = match how {
                    Step::Euler => Vec3A::ZERO,
                    Step::Bdf2 => (x0 - *start) / 3.0,
                    Step::Blend => (x0 - *start) * BLEND_LAG,
                };
                // A pinned particle keeps its velocity.
                (*start, *v_prev, *v) = (x0, unkicked, if free == 0.0 { v0 } else { v_hat });
                if free == 0.0 {
                    (*target, *x) = (Vec3A::ZERO, Vec3A::ZERO);
                } else if how != Step::Euler {
                    *target = *lag * damp + step * v_hat + (step * step) * uniform;
                    *x = *lag + first_iterate(v_hat, step, inv_damp, axis.dir * estimate);
                } else {
                    *target = h * v0 + (h * h) * uniform;
                    *x = first_iterate(v0, h, inv_damp, axis.dir * estimate);
                }
            });
    }

    /// `iterations` Gauss–Seidel sweeps over the colours on the substep of `step` seconds that
    /// [`Self::predict`] began: each particle's displacement in `x`.
    fn sweep(
        &mut self,
        topology: &ClothTopology,
        colouring: &ParticleColouring,
        model: &ForceModel,
        free: &[f32],
        step: f32,
        iterations: u32,
    ) {
        let Self { x, start, target, moved, .. } = self;
        let inv_share = topology.inv_mass_share();
        for _ in 0..iterations {
            for k in 0..colouring.len() {
                let colour = colouring.colour(k);
                moved.resize(colour.len(), Vec3A::ZERO);
                let current: &[Vec3A] = x;
                colour.par_chunks(WIDTH).zip(moved.par_chunks_mut(WIDTH)).with_min_len(MIN_TASK / WIDTH).for_each(
                    |(ids, out)| {
                        // A short last chunk repeats its last particle in the spare lanes.
                        let ids: [usize; WIDTH] = core::array::from_fn(|l| ids[l.min(ids.len() - 1)] as usize);
                        let new = descend_lanes(
                            model,
                            step,
                            ids.map(|i| inv_share[i]),
                            ids.map(|i| topology.springs_of(i)),
                            ids.map(|i| current[i]),
                            ids.map(|i| start[i]),
                            ids.map(|i| target[i]),
                            start,
                            current,
                        );
                        for (l, out) in out.iter_mut().enumerate() {
                            *out = if free[ids[l]] != 0.0 { new[l] } else { current[ids[l]] };
                        }
                    },
                );
                for (&i, &p) in colour.iter().zip(moved.iter()) {
                    x[i as usize] = p;
                }
            }
        }
    }

    /// Sizes the buffers for `n` particles.
    pub(crate) fn resize(&mut self, n: usize) {
        if self.x.len() != n {
            self.history = None;
        }
        for buffer in [&mut self.x, &mut self.v, &mut self.start, &mut self.target, &mut self.v_prev, &mut self.lag] {
            buffer.resize(n, Vec3A::ZERO);
        }
        self.accel.resize(n, 0.0);
    }

    /// One substep of `h` seconds solved as `solve` says, then the velocity update, the
    /// quarantine and the collision response. `free[i]` is 0 for a held particle, which neither
    /// moves nor changes velocity; `held[i]` becomes 1 where a collider touched particle `i`,
    /// else 0. Returns how many particles the quarantine stopped: a particle whose substep went
    /// NaN or infinite keeps its start, at rest (as `vbd_finish` does).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn substep(
        &mut self,
        topology: &ClothTopology,
        model: &ForceModel,
        free: &[f32],
        held: &mut [f32],
        h: f32,
        solve: Solve<'_>,
        free_body: bool,
        frames: &[ColliderFrame<'_>],
    ) -> usize {
        let Ok(colouring) = topology.colouring() else { return 0 };
        let (iterations, tethers) = match solve {
            Solve::Sweeps { iterations, tethers } => (iterations, tethers),
            Solve::Multigrid => (1, None),
        };
        // BDF2 (`x = x̂ + ĥ v`, `v = v̂ + ĥ a` with `ĥ = 2h/3`, `x̂ = (4x⁰ - x⁻¹)/3` and
        // `v̂ = (4v⁰ - v⁻¹)/3`) is implicit Euler's minimisation with `ĥ` for `h` and `x̂`, `v̂`
        // for the start: only the targets and the first iterate change (the blend's likewise,
        // with its own weights).
        let stepping = MultigridStepping::of(model, topology, h);
        let stiff = stepping == MultigridStepping::Stiff;
        let how = match solve {
            Solve::Multigrid if self.history == Some(h) => match stepping {
                MultigridStepping::Bdf2 => Step::Bdf2,
                MultigridStepping::Blend => Step::Blend,
                MultigridStepping::Stiff => Step::Euler,
            },
            _ => Step::Euler,
        };
        let step = how.length(h);
        let contact_moved = core::mem::take(&mut self.any_contact_moved);
        self.predict(model, free, h, how);
        self.sweep(topology, colouring, model, free, step, iterations);
        let damp = 1.0 + model.damping * step;
        let inv_damp = 1.0 / damp;
        let uniform = Vec3A::from(model.uniform_accel);
        let axis = AccelAxis::new(uniform);
        let Self { x, v, accel, start, target, lag, history, multigrid, contact_moved: moved, .. } = self;
        // The particles the correction leaves alone: those a collider held, and those contact
        // moved.
        if contact_moved && matches!(solve, Solve::Multigrid) {
            for (c, &h) in moved.iter_mut().zip(held.iter()) {
                *c = c.max(h);
            }
        }
        let moved: &[f32] = moved;
        let correction = match solve {
            Solve::Multigrid => {
                let left_alone = if contact_moved { moved } else { &*held };
                multigrid.correct(topology, model, free, left_alone, step, x, start, target, stiff, stepping.cycle())
            }
            Solve::Sweeps { .. } => None,
        };
        // Particle `i`'s displacement at the end of the solve (`left_alone` as above).
        let solved = |i: usize, d: Vec3A, left_alone: f32| match &correction {
            Some(correction) => correction.apply(i, d, left_alone),
            None => d,
        };
        // The springs are internal forces: whatever the sweeps left unconverged, a cloth that
        // nothing holds keeps the centre of mass that inertia, damping and the uniform
        // acceleration give it (the exact minimiser of `G` does).
        let drift = if free_body {
            let left_alone: &[f32] = if contact_moved { moved } else { held };
            centre_of_mass_drift(|i| solved(i, x[i], left_alone[i]), target, topology.mass_share(), free, inv_damp)
        } else {
            Vec3A::ZERO
        };
        let inv_step = 1.0 / step;
        let starts: &[Vec3A] = start;
        let quarantined = AtomicUsize::new(0);
        let touched_any = AtomicUsize::new(0);
        x.par_iter_mut()
            .zip(v.par_iter_mut())
            .zip(accel.par_iter_mut())
            .zip(start.par_iter())
            .zip(lag.par_iter())
            .zip(free.par_iter())
            .zip(held.par_iter_mut())
            .enumerate()
            .with_min_len(MIN_TASK)
            .for_each(|(i, ((((((x, v), estimate), &start), &lag), &free), held))| {
                let left_alone = if contact_moved { moved[i] } else { *held };
                *held = 0.0;
                if free == 0.0 {
                    *x = start;
                    return;
                }
                let v_hat = *v;
                let d = solved(i, *x, left_alone) - drift;
                *x = start + d;
                *v = (d - lag) * inv_step;
                // The pins are held, so their positions are the substep's start.
                if let Some((tethers, scale)) = tethers {
                    tethers.hold(i, *x, v, scale, |pin| starts[pin as usize]);
                }
                if !(x.is_finite() && v.is_finite()) {
                    (*x, *v) = (start, Vec3A::ZERO);
                    quarantined.fetch_add(1, Ordering::Relaxed);
                }
                if !frames.is_empty() {
                    let (mut p, mut velocity) = (Vec3::from(*x), Vec3::from(*v));
                    let mut touched = false;
                    for frame in frames {
                        touched |= frame.resolve(start.into(), &mut p, &mut velocity);
                    }
                    (*x, *v) = (p.into(), velocity.into());
                    *held = f32::from(u8::from(touched));
                    if touched {
                        touched_any.fetch_add(1, Ordering::Relaxed);
                    }
                }
                *estimate = axis.estimate(v_hat, *v, step, inv_damp);
            });
        if contact_moved {
            self.contact_moved.fill(0.0);
        }
        let quarantined = quarantined.into_inner();
        // A collider or the quarantine moved particles by more than the springs: BDF2 starts
        // again from implicit Euler, so that its history never runs through a contact.
        *history = (quarantined == 0 && touched_any.into_inner() == 0).then_some(h);
        quarantined
    }
}

impl MultigridCorrection {
    /// The hierarchy the multigrid integrator builds for a cloth at positions `x` with
    /// velocities `v` (nothing held but its pins, `free[i]` 0 for a pinned particle; `held[i]`
    /// 1 for a particle a collider touched in the last substep) in its first substep of `h`
    /// seconds: its aggregates grouped by the springs after that substep's implicit Euler
    /// prediction and sweep, as [`MultigridCorrection::new`] takes the rest.
    pub fn for_first_substep(
        topology: &ClothTopology,
        model: &ForceModel,
        free: &[f32],
        held: &[f32],
        h: f32,
        x: &[Vec3A],
        v: &[Vec3A],
    ) -> Self {
        let mut descent = BlockDescent::default();
        descent.resize(x.len());
        descent.x.copy_from_slice(x);
        descent.v.copy_from_slice(v);
        let mut multigrid = Multigrid::default();
        if let Ok(colouring) = topology.colouring() {
            descent.predict(model, free, h, Step::Euler);
            descent.sweep(topology, colouring, model, free, h, 1);
            multigrid.build(topology, model, free, held, &descent.start, &descent.x);
        }
        Self::with_hierarchy(topology, model, free, multigrid)
    }
}

/// `(2h/3)² k_max / m_min` for a substep of `h` seconds: BDF2's stiffness in units of its step.
fn bdf2_stiffness(model: &ForceModel, topology: &ClothTopology, h: f32) -> f32 {
    let step = h * (2.0 / 3.0);
    let bound = topology.stiffness_bound();
    step * step * (0..3).map(|k| model.k_over_mass[k] * bound[k]).sum::<f32>()
}

/// The direction and size of the uniform acceleration (gravity and the external force per unit
/// mass), along which block descent estimates each particle's acceleration.
#[derive(Clone, Copy, Debug)]
pub(crate) struct AccelAxis {
    /// Unit direction, zero when there is no uniform acceleration.
    pub(crate) dir: Vec3A,
    /// Size in m/s².
    pub(crate) size: f32,
}

impl AccelAxis {
    pub(crate) fn new(uniform: Vec3A) -> Self {
        let size = uniform.length();
        if size > 0.0 && size.is_finite() {
            Self { dir: uniform / size, size }
        } else {
            Self { dir: Vec3A::ZERO, size: 0.0 }
        }
    }

    /// The acceleration a particle followed over a substep of `h` seconds from velocity `v0` to
    /// `v1`, less the damping (`inv_damp = 1 / (1 + c h)`), taken along the axis and clamped to
    /// `[0, size]`: the share of the uniform acceleration the particle is free to follow. A
    /// free-falling particle gives the whole of it, one resting on a collider or hanging at
    /// rest none, and a non-finite velocity none.
    #[inline]
    pub(crate) fn estimate(&self, v0: Vec3A, v1: Vec3A, h: f32, inv_damp: f32) -> f32 {
        let along = (v1 / inv_damp - v0).dot(self.dir) / h;
        // `max` first: NaN against 0 gives 0.
        along.max(0.0).min(self.size)
    }
}

/// The first iterate of a free particle moving at `v`, as a displacement from where it is: where
/// inertia, damping and the acceleration it is estimated to follow, `accel`, take it in `h`
/// seconds, `(h v + h² accel) / (1 + c h)`.
///
/// This is the adaptive initial guess of Chen et al. (2024): a falling particle
/// starts where gravity takes it, so that a sweep never has to carry the fall against stiff
/// springs whose other ends have not moved yet, while a particle at rest on a collider or
/// hanging still starts where it was, so that the sweeps settle on the springs' own
/// equilibrium. A whole cloth in free fall starts each substep at the exact minimiser of `G`,
/// and falls `g/c (t - (1 - e^{-ct}) / c)` up to implicit Euler's `O(h)` whatever its shape,
/// orientation or resolution.
#[inline]
pub(crate) fn first_iterate(v: Vec3A, h: f32, inv_damp: f32, accel: Vec3A) -> Vec3A {
    (h * v + (h * h) * accel) * inv_damp
}

/// Particles one partial sum of [`centre_of_mass_drift`] takes: fixed, so the sum does not
/// depend on the thread count.
const DRIFT_CHUNK: usize = 4096;

/// How far the sweeps moved the centre of mass of the free particles from where inertia,
/// damping and the uniform acceleration take it, from the particles' displacements (`d(i)`
/// particle `i`'s) and inertial targets `target` (both less the substep's start;
/// `inv_damp = 1 / (1 + c h)`):
/// `Σ m_i (d_i - d*_i) / Σ m_i` with `d*_i = target_i / (1 + c h)`, where a particle that
/// only inertia, damping and the uniform acceleration moved would be. The exact minimiser of
/// `G` moves the centre of mass by nothing more (the springs' forces cancel in pairs); an
/// unconverged Gauss–Seidel sweep does not, and shifting the free particles back by this much
/// restores the cloth's momentum without changing any spring's length.
pub(crate) fn centre_of_mass_drift(
    d: impl Fn(usize) -> Vec3A + Sync,
    target: &[Vec3A],
    share: &[f32],
    free: &[f32],
    inv_damp: f32,
) -> Vec3A {
    let n = target.len();
    let partial: Vec<(glam::DVec3, f64)> = (0..n.div_ceil(DRIFT_CHUNK))
        .into_par_iter()
        .map(|chunk| {
            let range = chunk * DRIFT_CHUNK..((chunk + 1) * DRIFT_CHUNK).min(n);
            let mut sum = (glam::DVec3::ZERO, 0.0f64);
            for i in range {
                let off = d(i) - target[i] * inv_damp;
                // A particle that went non-finite is quarantined after the sums; it must not
                // carry the rest of the cloth with it.
                if free[i] != 0.0 && off.is_finite() {
                    let m = f64::from(share[i]);
                    sum.0 += m * off.as_dvec3();
                    sum.1 += m;
                }
            }
            sum
        })
        .collect();
    let (moment, mass) = partial.into_iter().fold((glam::DVec3::ZERO, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
    if mass > 0.0 { (moment / mass).as_vec3a() } else { Vec3A::ZERO }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solver::params::ClothParams;

    /// `G` of one particle's block, in the units [`descend`] minimises (times `h² / m`).
    fn block_potential(
        model: &ForceModel,
        h: f32,
        springs: &[SpringEnd],
        others: &[Vec3],
        x: Vec3A,
        start: Vec3A,
        target: Vec3A,
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

    /// The many-lane update is the scalar one, bit for bit, lane by lane, whatever each lane's
    /// spring count.
    #[test]
    fn lanes_match_the_scalar_update_bit_for_bit() {
        let jiggle = |i: u32, axis: u32| ((i * 7 + axis * 13) % 17) as f32 / 17.0 - 0.5;
        let positions: Vec<Vec3A> =
            (0..40).map(|i| Vec3A::new(i as f32 * 0.1 + jiggle(i, 0), jiggle(i, 1), jiggle(i, 2))).collect();
        let ends: Vec<SpringEnd> = (0..12)
            .map(|j| SpringEnd {
                other: 10 + j * 2,
                kind: j % 3,
                rest: 0.1 + 0.05 * j as f32,
                weight: 1.0 + j as f32 * 0.1,
            })
            .collect();
        let patterns = [&ends[..12], &ends[..3], &ends[5..12], &ends[..0]];
        let springs: [&[SpringEnd]; WIDTH] = core::array::from_fn(|l| patterns[l % 4]);
        let model = ForceModel::new(&ClothParams { spring_k: 300.0, damping: 1.5, ..Default::default() });
        let ids: [usize; WIDTH] = core::array::from_fn(|l| l);
        let inv_share: [f32; WIDTH] = core::array::from_fn(|l| [40.0, 20.0, 0.0, 33.0][l % 4] + l as f32);
        let h = 1.0 / 240.0;
        let displacements: Vec<Vec3A> =
            (0..40).map(|i| Vec3A::new(jiggle(i, 2), jiggle(i, 0), jiggle(i, 1)) * 0.01).collect();
        let d = ids.map(|i| displacements[i]);
        let start = ids.map(|i| positions[i]);
        let target = ids.map(|i| displacements[i] - Vec3A::new(0.0, 0.002, 0.0));
        let lanes = descend_lanes(&model, h, inv_share, springs, d, start, target, &positions, &displacements);
        for l in 0..WIDTH {
            let one = descend(&model, h, inv_share[l], springs[l], d[l], start[l], target[l], |j| {
                (positions[j as usize], displacements[j as usize])
            });
            assert_eq!(lanes[l].to_array().map(f32::to_bits), one.to_array().map(f32::to_bits), "lane {l}");
        }
    }

    #[test]
    fn each_update_lowers_its_block_potential_at_any_stiffness() {
        let others = [Vec3::new(1.2, 0.1, 0.0), Vec3::new(-0.3, 0.9, 0.2), Vec3::new(0.1, -0.2, -1.4)];
        let springs: Vec<SpringEnd> = (0..3).map(|j| SpringEnd { other: j, kind: j, rest: 1.0, weight: 1.0 }).collect();
        let (start, target) = (Vec3A::new(0.05, 0.0, 0.02), Vec3A::new(0.1, -0.05, 0.0));
        for spring_k in [0.0, 10.0, 400.0, 1.0e4, 1.0e7] {
            let model = ForceModel::new(&ClothParams { spring_k, damping: 2.0, ..Default::default() });
            for h in [1.0 / 960.0, 1.0 / 60.0] {
                let mut x = target;
                let mut before = block_potential(&model, h, &springs, &others, x, start, target);
                for _ in 0..4 {
                    let d = descend(&model, h, 1.0, &springs, x - start, start, target - start, |j| {
                        (others[j as usize].into(), Vec3A::ZERO)
                    });
                    x = start + d;
                    assert!(x.is_finite(), "k {spring_k}, h {h}");
                    let after = block_potential(&model, h, &springs, &others, x, start, target);
                    assert!(after <= before * (1.0 + 1e-5) + 1e-12, "k {spring_k}, h {h}: {before} -> {after}");
                    before = after;
                }
            }
        }
    }
}
