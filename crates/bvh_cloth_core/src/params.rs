//! The cloth's parameters (paper Table V) and their validation.

use glam::Vec3;

use crate::error::ClothError;

/// Largest particle count a single cloth may have (4096 x 4096).
pub const MAX_PARTICLES: u32 = 1 << 24;

/// Most substeps one tick may take when the stability guard raises `looper` (see
/// [`ClothParams::max_stable_substep`]). Beyond it the springs are too stiff for the tick rate
/// to be worth simulating explicitly.
pub const MAX_SUBSTEPS_PER_TICK: u32 = 256;

/// Which time integrator advances the cloth (paper section 2.2).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Integrator {
    /// Classic fourth-order Runge–Kutta over the whole system (paper eq. 4): each of the four
    /// slopes is evaluated for every particle before the next stage starts.
    #[default]
    Rk4,
    /// Semi-implicit (symplectic) Euler: `v += h a(x, v)`, then `x += h v` (paper eq. 3).
    SemiImplicitEuler,
}

/// Per-kind stiffness scales applied on top of [`ClothParams::spring_k`].
///
/// The paper (section 2.1) distinguishes structural, shear and bending springs but gives them
/// one coefficient `c_e`; separate scales let a bending-soft cloth fold while staying
/// inextensible. A scale of zero removes that kind of spring.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpringStiffness {
    /// Springs to the 4-neighbourhood.
    pub structural: f32,
    /// Springs to the diagonal neighbours.
    pub shear: f32,
    /// Springs to the neighbours two steps away along rows and columns.
    pub bending: f32,
}

impl Default for SpringStiffness {
    fn default() -> Self {
        Self { structural: 1.0, shear: 0.5, bending: 0.25 }
    }
}

/// Everything that defines a cloth's physics (paper Table V, plus gravity and the integrator).
#[derive(Clone, Debug, PartialEq)]
pub struct ClothParams {
    /// Number of particle rows ("Vertex Row"); the rows run along the cloth's local +Z.
    pub rows: u32,
    /// Number of particle columns ("Vertex Column"); the columns run along the cloth's local +X.
    pub cols: u32,
    /// Length of the cloth along its columns, in metres ("Cloth Size"). Cells are square, so the
    /// cloth is `size * (rows - 1) / (cols - 1)` deep.
    pub size: f32,
    /// Total mass of the cloth in kilograms ("Cloth Mass"), shared equally by the particles.
    pub mass: f32,
    /// Simulation substeps per tick ("Looper").
    pub looper: u32,
    /// Spring stiffness `c_e` of paper eq. 1, in N/m ("SpringK").
    pub spring_k: f32,
    /// Velocity damping rate in 1/s ("Damping"): each particle feels `-damping * m * v`,
    /// which is paper eq. 2 with `c_d = damping * m`, so the same value behaves the same at
    /// every grid resolution.
    pub damping: f32,
    /// A non-gravity force on the whole cloth, in newtons ("External Force"), shared equally by
    /// the particles (wind, a push).
    pub external_force: Vec3,
    /// Gravitational acceleration in m/s².
    pub gravity: Vec3,
    /// Per-kind stiffness scales.
    pub stiffness: SpringStiffness,
    /// The time integrator.
    pub integrator: Integrator,
}

impl Default for ClothParams {
    fn default() -> Self {
        Self {
            rows: 64,
            cols: 64,
            size: 2.0,
            mass: 1.0,
            looper: 16,
            spring_k: 200.0,
            damping: 0.5,
            external_force: Vec3::ZERO,
            gravity: Vec3::new(0.0, -9.81, 0.0),
            stiffness: SpringStiffness::default(),
            integrator: Integrator::Rk4,
        }
    }
}

impl ClothParams {
    /// Number of particles, `rows * cols`.
    pub fn particle_count(&self) -> usize {
        self.rows as usize * self.cols as usize
    }

    /// Mass of one particle in kilograms.
    pub fn particle_mass(&self) -> f32 {
        self.mass / self.particle_count() as f32
    }

    /// Rest distance between neighbouring particles in metres.
    pub fn spacing(&self) -> f32 {
        self.size / (self.cols.max(2) - 1) as f32
    }

    /// The longest substep, in seconds, for which the integrator stays stable.
    ///
    /// The fastest mode of the spring grid has `w² <= 4 (k_structural + k_shear + k_bending) / m`:
    /// each stencil spring adds at most `2 k (d·u)²` to the stiffness along a direction `u`, and
    /// over each kind's four neighbours `(d·u)²` sums to 2 whatever `u` is (a Gershgorin bound;
    /// the grid's real top mode, the checkerboard, reaches `6 k / m` with the default scales).
    /// Damping adds its rate to that. RK4 is stable up to `h w = 2√2` on the imaginary axis and
    /// semi-implicit Euler up to `h w = 2`; 10 % is kept in hand.
    pub fn max_stable_substep(&self) -> f32 {
        let s = self.stiffness;
        let k_sum = self.spring_k * (s.structural + s.shear + s.bending);
        let omega = (4.0 * k_sum / self.particle_mass()).sqrt() + self.damping;
        let limit = match self.integrator {
            Integrator::Rk4 => 2.0 * core::f32::consts::SQRT_2,
            Integrator::SemiImplicitEuler => 2.0,
        };
        if omega > 0.0 { 0.9 * limit / omega } else { f32::INFINITY }
    }

    /// Substeps one tick of `dt` seconds takes: `looper`, or more when a substep of
    /// `dt / looper` would be longer than [`Self::max_stable_substep`], up to
    /// [`MAX_SUBSTEPS_PER_TICK`].
    pub fn substeps(&self, dt: f32) -> u32 {
        let needed = (dt / self.max_stable_substep()).ceil();
        if needed.is_finite() && needed > self.looper as f32 {
            (needed as u32).min(MAX_SUBSTEPS_PER_TICK).max(self.looper)
        } else {
            self.looper
        }
    }

    /// Checks that a cloth can be built and stepped with these parameters.
    pub fn validate(&self) -> Result<(), ClothError> {
        let (rows, cols) = (self.rows, self.cols);
        if rows < 2 || cols < 2 {
            return Err(ClothError::GridTooSmall { rows, cols });
        }
        if u64::from(rows) * u64::from(cols) > u64::from(MAX_PARTICLES) {
            return Err(ClothError::GridTooLarge { rows, cols, max_particles: MAX_PARTICLES });
        }
        positive("size", self.size)?;
        positive("mass", self.mass)?;
        if self.looper == 0 {
            return Err(ClothError::ZeroLooper);
        }
        non_negative("spring_k", self.spring_k)?;
        non_negative("damping", self.damping)?;
        non_negative("stiffness.structural", self.stiffness.structural)?;
        non_negative("stiffness.shear", self.stiffness.shear)?;
        non_negative("stiffness.bending", self.stiffness.bending)?;
        finite("external_force", self.external_force)?;
        finite("gravity", self.gravity)?;
        // The particle mass must itself be a usable positive number.
        positive("mass", self.particle_mass())?;
        Ok(())
    }
}

fn positive(field: &'static str, value: f32) -> Result<(), ClothError> {
    if value.is_finite() && value > 0.0 { Ok(()) } else { Err(ClothError::NotPositive { field, value }) }
}

fn non_negative(field: &'static str, value: f32) -> Result<(), ClothError> {
    if value.is_finite() && value >= 0.0 { Ok(()) } else { Err(ClothError::Negative { field, value }) }
}

fn finite(field: &'static str, value: Vec3) -> Result<(), ClothError> {
    if value.is_finite() { Ok(()) } else { Err(ClothError::NotFinite { field }) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid() {
        ClothParams::default().validate().unwrap();
    }

    #[test]
    fn stability_guard_adds_substeps_only_when_needed() {
        let base = ClothParams::default();
        assert_eq!(base.substeps(1.0 / 60.0), base.looper, "the defaults are stable as given");
        let stiff = ClothParams { spring_k: 5000.0, ..base.clone() };
        let n = stiff.substeps(1.0 / 60.0);
        assert!(n > base.looper && (1.0 / 60.0) / n as f32 <= stiff.max_stable_substep(), "{n}");
        let absurd = ClothParams { spring_k: 1.0e12, ..base };
        assert_eq!(absurd.substeps(1.0 / 60.0), MAX_SUBSTEPS_PER_TICK);
    }

    #[test]
    fn rejects_what_cannot_work() {
        let base = ClothParams::default();
        let cases: Vec<(ClothParams, ClothError)> = vec![
            (ClothParams { rows: 1, ..base.clone() }, ClothError::GridTooSmall { rows: 1, cols: 64 }),
            (ClothParams { cols: 0, ..base.clone() }, ClothError::GridTooSmall { rows: 64, cols: 0 }),
            (
                ClothParams { size: f32::NAN, ..base.clone() },
                ClothError::NotPositive { field: "size", value: f32::NAN },
            ),
            (ClothParams { mass: -1.0, ..base.clone() }, ClothError::NotPositive { field: "mass", value: -1.0 }),
            (ClothParams { looper: 0, ..base.clone() }, ClothError::ZeroLooper),
            (
                ClothParams { spring_k: f32::INFINITY, ..base.clone() },
                ClothError::Negative { field: "spring_k", value: f32::INFINITY },
            ),
            (
                ClothParams { external_force: Vec3::new(0.0, f32::NAN, 0.0), ..base.clone() },
                ClothError::NotFinite { field: "external_force" },
            ),
        ];
        for (params, expected) in cases {
            let err = params.validate().unwrap_err();
            // NaN != NaN, so compare the messages, which carry every field.
            assert_eq!(err.to_string(), expected.to_string());
        }
        let huge = ClothParams { rows: 100_000, cols: 100_000, ..base };
        assert!(matches!(huge.validate(), Err(ClothError::GridTooLarge { .. })));
    }
}
