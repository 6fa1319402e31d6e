//! The cloth's parameters (paper Table V) and their validation.

#[cfg(feature = "bevy_reflect")]
use bevy_reflect::std_traits::ReflectDefault;
use glam::Vec3;

use crate::air::Aerodynamics;
use crate::cloth::error::ClothError;
use crate::cloth::tethers::Tethers;
use crate::cloth::topology::ClothTopology;
use crate::colliders::layers::CollisionLayers;
use crate::self_contact::SelfContact;

/// Most block-descent iterations per substep. More buys less than more substeps do.
pub const MAX_ITERATIONS: u32 = 16;

/// Most substeps one tick may take when the stability guard raises `looper` (see
/// [`ClothParams::max_stable_substep`]). Beyond it the springs are too stiff for the tick rate
/// to be worth simulating explicitly.
pub const MAX_SUBSTEPS_PER_TICK: u32 = 256;

/// The heaviest fabric accepted, in kg/m²: ten times heavy canvas (about 0.6 kg/m²), past any
/// cloth; more is a unit mistake (grams for kilograms, say).
pub const MAX_DENSITY: f32 = 10.0;

/// Which time integrator advances the cloth (paper section 2.2, block descent and multigrid).
///
/// The default is [`Integrator::Multigrid`]: a game sets a stiffness and a budget (`looper`
/// substeps) and gets that cost, stable whatever the stiffness, and a cloth that falls,
/// swings and stretches as RK4's does (the hanging cloth's sag at 1 s within 10 % of RK4's
/// and its strain within 1.5x from 32 x 32 to 1024 x 1024; BENCHMARKS.md, "Motion"). Its
/// tick costs 1.2x to 1.45x block descent's with one sweep, which converges a
/// fine cloth's load only one ring of springs per colour pass and so lets a big sheet stretch
/// like rubber while it moves (held by the tethers, 45 % more sag than RK4 at 256 x 256). With RK4 a
/// 64x64 sheet made 100x stiffer (200 to 20,000 N/m) takes 157 substeps a tick instead of 16
/// (the stability guard), and a cloth that would need more than [`MAX_SUBSTEPS_PER_TICK`]
/// steps past its stability limit; a designer's slider should do neither. RK4 stays for
/// reproducing the paper and as the reference the other integrators are measured against.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "bevy_reflect", derive(bevy_reflect::Reflect), reflect(Default, Debug, PartialEq, Hash))]
pub enum Integrator {
    /// Classic fourth-order Runge–Kutta over the whole system (paper eq. 4): each of the four
    /// slopes is evaluated for every particle before the next stage starts.
    Rk4,
    /// Semi-implicit (symplectic) Euler: `v += h a(x, v)`, then `x += h v` (paper eq. 3).
    SemiImplicitEuler,
    /// Vertex block descent ([`crate::solver::block_descent`]): each substep an implicit Euler step,
    /// solved by `iterations` Gauss–Seidel sweeps over the particles' colours. Stable at every
    /// stiffness, so the stability guard never adds substeps: a tick costs
    /// `looper x iterations` sweeps.
    BlockDescent {
        /// Sweeps per substep, 1 to [`MAX_ITERATIONS`].
        iterations: u32,
    },
    /// The default. Each substep a BDF2 step (implicit Euler after a contact), solved by one
    /// block-descent sweep and an aggregation multigrid correction
    /// ([`crate::solver::multigrid`]): a fine cloth's load reaches its pins within the substep,
    /// so it swings and stretches close to RK4's (the hanging cloth's sag at 1 s within -1 % to
    /// +8 % of RK4's from 32 x 32 to 1024 x 1024, BENCHMARKS.md "Motion"), and BDF2 damps its
    /// motion far less than implicit Euler. On the stiffest substeps (1024 x 1024 at Looper 16)
    /// the step blends BDF2 with implicit Euler and the correction visits its coarse levels
    /// twice ([`crate::solver::block_descent`]). Stable at every stiffness, and
    /// needs no tethers ([`ClothParams::tethers`] is not used). Both backends run it; the GPU's
    /// kernels agree with the CPU within the tolerances `bvh_cloth_gpu`'s tests state.
    #[default]
    Multigrid,
}

impl Integrator {
    /// Block descent with one sweep per substep, the block-descent setting that spends the
    /// budget best: more substeps of one sweep converge faster than fewer substeps of several
    /// (Macklin et al. 2019, "Small Steps in Physics Simulation").
    pub const BLOCK_DESCENT: Self = Self::BlockDescent { iterations: 1 };

    /// Whether the integrator is explicit, and so bound by the stability guard.
    pub fn is_explicit(self) -> bool {
        matches!(self, Self::Rk4 | Self::SemiImplicitEuler)
    }
}

/// Per-kind stiffness scales applied on top of [`ClothParams::spring_k`].
///
/// The paper (section 2.1) distinguishes structural, shear and bending springs but gives them
/// one coefficient `c_e`; separate scales let a bending-soft cloth fold while staying
/// inextensible. A scale of zero removes that kind of spring.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "bevy_reflect", derive(bevy_reflect::Reflect), reflect(Default, Debug, PartialEq))]
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

/// Everything that defines a cloth's material and how it is stepped (paper Table V, plus
/// gravity and the integrator). The cloth's shape is its [`ClothTopology`].
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "bevy_reflect", derive(bevy_reflect::Reflect), reflect(Default, Debug, PartialEq))]
pub struct ClothParams {
    /// Total mass of the cloth in kilograms ("Cloth Mass"). Each particle carries the share of
    /// it that [`ClothTopology::mass_share`] gives: its share of the surface for an authored
    /// mesh, an equal share on the generated grid (as in the paper).
    pub mass: f32,
    /// The fabric's weight in kg/m² (voile about 0.05, cotton shirting 0.12, denim 0.4): when
    /// set, the cloth's mass is this times its rest area ([`ClothTopology::rest_area`]) and
    /// `mass` is ignored, so that resizing or remeshing a cloth keeps its fabric. At most
    /// [`MAX_DENSITY`]. `None` (the default) takes `mass` as given.
    pub density: Option<f32>,
    /// Simulation substeps per tick ("Looper").
    pub looper: u32,
    /// Stiffness of the cloth in N/m ("SpringK", the `c_e` of paper eq. 1), independent of the
    /// resolution: each spring gets `spring_k * scale * A / L²`, where `L` is its rest length
    /// and `A` the rest area it spans (see [`crate::cloth::topology`]). On a grid with square cells that
    /// is `spring_k` times its kind's scale for every spring, as in the paper; a finer grid or
    /// an irregular mesh of the same sheet stretches the same under the same load.
    pub spring_k: f32,
    /// Velocity damping rate in 1/s ("Damping"): each particle feels `-damping * m * v`,
    /// which is paper eq. 2 with `c_d = damping * m`, so the same value behaves the same at
    /// every resolution.
    pub damping: f32,
    /// A non-gravity force on the whole cloth, in newtons ("External Force"), shared by the
    /// particles in proportion to their mass: a push that ignores the cloth's shape (for wind that
    /// catches the cloth by its area and orientation, see [`Self::aerodynamics`]).
    pub external_force: Vec3,
    /// Gravitational acceleration in m/s².
    pub gravity: Vec3,
    /// Per-kind stiffness scales.
    pub stiffness: SpringStiffness,
    /// The time integrator.
    pub integrator: Integrator,
    /// Self-contact ([`crate::self_contact`]): `None`, the default, lets the cloth pass
    /// through itself. Off by default because it costs a neighbour search every substep, and
    /// a flag or a banner never folds onto itself; a cape, a skirt or a dropped towel needs it.
    pub self_contact: Option<SelfContact>,
    /// How the cloth catches the air ([`crate::air`]): drag and lift against the
    /// wind and against its own motion. The default, [`Aerodynamics::NONE`], is the paper's
    /// model, a cloth in vacuum that no wind moves; [`Aerodynamics::FABRIC`] is a woven fabric.
    pub aerodynamics: Aerodynamics,
    /// Tethers from each particle to its nearest pin ([`crate::cloth::tethers`]), for block descent:
    /// they keep a fine held cloth from stretching like rubber while it moves. `None` leaves
    /// the load to the springs alone. A cloth with no pin has no tethers, and
    /// [`Integrator::Multigrid`] none either: its correction carries the load to the pins.
    pub tethers: Option<Tethers>,
    /// Which colliders the cloth collides with, and which other cloths it keeps off when both
    /// have self-contact: those whose layers and these meet
    /// ([`CollisionLayers::interacts_with`]). The default meets everything.
    pub layers: CollisionLayers,
}

impl Default for ClothParams {
    fn default() -> Self {
        Self {
            mass: 1.0,
            density: None,
            looper: 16,
            spring_k: 200.0,
            damping: 0.5,
            external_force: Vec3::ZERO,
            gravity: Vec3::new(0.0, -9.81, 0.0),
            stiffness: SpringStiffness::default(),
            integrator: Integrator::default(),
            self_contact: None,
            aerodynamics: Aerodynamics::NONE,
            tethers: Some(Tethers::default()),
            layers: CollisionLayers::DEFAULT,
        }
    }
}

impl ClothParams {
    /// The longest substep, in seconds, for which the integrator stays stable on `topology`
    /// (unbounded for block descent).
    ///
    /// The fastest mode of the springs has `w² <= 2 max_i λ_i / m_i`, where `λ_i` is the largest
    /// eigenvalue of `Σ k_ij d_ij d_ijᵀ` over particle `i`'s springs (unit rest directions
    /// `d_ij`): a Gershgorin bound on the stiffness matrix per unit mass, which
    /// [`ClothTopology::stiffness_bound`] precomputes per spring kind. On the square grid it is
    /// `4 (k_structural + k_shear + k_bending) / m`, and the grid's real top mode, the
    /// checkerboard, reaches `6 k / m` with the default scales. Damping adds its rate to that.
    /// RK4 is stable up to `h w = 2√2` on the imaginary axis and semi-implicit Euler up to
    /// `h w = 2`; 10 % is kept in hand.
    pub fn max_stable_substep(&self, topology: &ClothTopology) -> f32 {
        let s = self.stiffness;
        let bound = topology.stiffness_bound();
        let per_mass = s.structural * bound[0] + s.shear * bound[1] + s.bending * bound[2];
        let omega = (2.0 * self.spring_k / self.total_mass(topology) * per_mass).sqrt() + self.damping;
        let limit = match self.integrator {
            Integrator::Rk4 => 2.0 * core::f32::consts::SQRT_2,
            Integrator::SemiImplicitEuler => 2.0,
            Integrator::BlockDescent { .. } | Integrator::Multigrid => return f32::INFINITY,
        };
        if omega > 0.0 { 0.9 * limit / omega } else { f32::INFINITY }
    }

    /// Substeps one tick of `dt` seconds takes on `topology`: `looper`, or more when a substep
    /// of `dt / looper` would be longer than [`Self::max_stable_substep`], up to
    /// [`MAX_SUBSTEPS_PER_TICK`].
    pub fn substeps(&self, dt: f32, topology: &ClothTopology) -> u32 {
        let needed = (dt / self.max_stable_substep(topology)).ceil();
        if needed.is_finite() && needed > self.looper as f32 {
            (needed as u32).min(MAX_SUBSTEPS_PER_TICK).max(self.looper)
        } else {
            self.looper
        }
    }

    /// Substeps one tick of `dt` seconds needs on `topology` to keep an explicit integrator
    /// within its stability limit, without the guard's cap: at least `looper`, and `looper`
    /// for block descent. Beyond [`MAX_SUBSTEPS_PER_TICK`], see [`Self::check_tick`].
    pub fn substeps_needed(&self, dt: f32, topology: &ClothTopology) -> u32 {
        let needed = (dt / self.max_stable_substep(topology)).ceil();
        if needed.is_finite() && needed > self.looper as f32 {
            if needed >= u32::MAX as f32 { u32::MAX } else { needed as u32 }
        } else if needed.is_finite() {
            self.looper
        } else {
            u32::MAX
        }
    }

    /// Whether a cloth on `topology` can be stepped with these parameters at ticks of `dt`
    /// seconds: an explicit integrator that would need more than [`MAX_SUBSTEPS_PER_TICK`]
    /// substeps a tick is refused with [`ClothError::BeyondStabilityGuard`], naming the count,
    /// since the guard's cap would leave it unstable and the cloth would go non-finite.
    /// [`crate::ClothSim::new`] and [`crate::ClothSim::set_params`] do not know the tick; the
    /// plugin checks this with its clock's tick when a cloth is built or its parameters change.
    pub fn check_tick(&self, dt: f32, topology: &ClothTopology) -> Result<(), ClothError> {
        let needed = self.substeps_needed(dt, topology);
        if self.integrator.is_explicit() && needed > MAX_SUBSTEPS_PER_TICK {
            return Err(ClothError::BeyondStabilityGuard { needed, max: MAX_SUBSTEPS_PER_TICK });
        }
        Ok(())
    }

    /// Checks that a cloth can be stepped with these parameters.
    pub fn validate(&self) -> Result<(), ClothError> {
        ClothError::check_positive("mass", self.mass)?;
        if let Some(density) = self.density {
            ClothError::check_positive("density", density)?;
            if density > MAX_DENSITY {
                return Err(ClothError::OutOfRange { field: "density", value: density, min: 0.0, max: MAX_DENSITY });
            }
        }
        if self.looper == 0 {
            return Err(ClothError::ZeroLooper);
        }
        if self.looper > MAX_SUBSTEPS_PER_TICK {
            return Err(ClothError::CountOutOfRange {
                field: "looper",
                value: self.looper,
                min: 1,
                max: MAX_SUBSTEPS_PER_TICK,
            });
        }
        if let Integrator::BlockDescent { iterations } = self.integrator
            && !(1..=MAX_ITERATIONS).contains(&iterations)
        {
            return Err(ClothError::CountOutOfRange {
                field: "integrator.iterations",
                value: iterations,
                min: 1,
                max: MAX_ITERATIONS,
            });
        }
        ClothError::check_non_negative("spring_k", self.spring_k)?;
        ClothError::check_non_negative("damping", self.damping)?;
        ClothError::check_non_negative("stiffness.structural", self.stiffness.structural)?;
        ClothError::check_non_negative("stiffness.shear", self.stiffness.shear)?;
        ClothError::check_non_negative("stiffness.bending", self.stiffness.bending)?;
        finite("external_force", self.external_force)?;
        finite("gravity", self.gravity)?;
        if let Some(contact) = &self.self_contact {
            contact.validate()?;
        }
        if let Some(tethers) = &self.tethers {
            tethers.validate()?;
        }
        self.aerodynamics.validate()
    }

    /// The same parameters with what depends on the cloth filled in from `topology`: the
    /// `mass` a `density` gives ([`Self::total_mass`]), and a self-contact thickness of 0 as its
    /// share of the particle spacing ([`SelfContact::resolved_for`]). A
    /// [`ClothSim`](crate::ClothSim) holds its parameters so.
    pub fn resolved_for(mut self, topology: &ClothTopology) -> Self {
        self.mass = self.total_mass(topology);
        self.self_contact = self.self_contact.map(|contact| contact.resolved_for(topology));
        self
    }

    /// The cloth's mass in kilograms on `topology`: `density` times its rest area when a
    /// density is set, otherwise `mass`.
    pub fn total_mass(&self, topology: &ClothTopology) -> f32 {
        self.density.map_or(self.mass, |density| density * topology.rest_area())
    }

    /// [`Self::validate`], and whether `topology` can be stepped with these parameters: block
    /// descent needs the topology's colouring.
    pub fn validate_for(&self, topology: &ClothTopology) -> Result<(), ClothError> {
        self.validate()?;
        if !self.integrator.is_explicit() {
            topology.colouring()?;
        }
        if let Some(contact) = &self.self_contact {
            contact.validate_for(topology)?;
        }
        Ok(())
    }
}

fn finite(field: &'static str, value: Vec3) -> Result<(), ClothError> {
    if value.is_finite() { Ok(()) } else { Err(ClothError::NotFinite { field }) }
}

#[cfg(test)]
mod tests {
    use glam::{UVec2, Vec2};

    use super::*;
    use crate::cloth::grid::ClothGrid;

    #[test]
    fn defaults_are_valid() {
        ClothParams::default().validate().unwrap();
    }

    #[test]
    fn stability_guard_adds_substeps_only_when_needed() {
        let grid = ClothTopology::grid(ClothGrid::new(Vec2::splat(2.0), UVec2::splat(64))).unwrap();
        let base = ClothParams { integrator: Integrator::Rk4, ..Default::default() };
        assert_eq!(base.substeps(1.0 / 60.0, &grid), base.looper, "the defaults are stable as given");
        let stiff = ClothParams { spring_k: 5000.0, ..base.clone() };
        let n = stiff.substeps(1.0 / 60.0, &grid);
        assert!(n > base.looper && (1.0 / 60.0) / n as f32 <= stiff.max_stable_substep(&grid), "{n}");
        let absurd = ClothParams { spring_k: 1.0e12, ..base.clone() };
        assert_eq!(absurd.substeps(1.0 / 60.0, &grid), MAX_SUBSTEPS_PER_TICK);
        // Beyond the cap the guard cannot keep it stable: refused, naming the count it needs.
        assert_eq!(base.check_tick(1.0 / 60.0, &grid), Ok(()));
        assert_eq!(stiff.check_tick(1.0 / 60.0, &grid), Ok(()));
        let needed = absurd.substeps_needed(1.0 / 60.0, &grid);
        assert!(needed > MAX_SUBSTEPS_PER_TICK && needed < u32::MAX, "{needed}");
        let error = absurd.check_tick(1.0 / 60.0, &grid).unwrap_err();
        assert_eq!(error, ClothError::BeyondStabilityGuard { needed, max: MAX_SUBSTEPS_PER_TICK });
        assert!(error.to_string().contains(&format!("{needed} substeps")), "{error}");
        assert_eq!(
            ClothParams { integrator: Integrator::BLOCK_DESCENT, ..absurd.clone() }.check_tick(1.0 / 60.0, &grid),
            Ok(())
        );
        // Block descent is stable at any stiffness: the guard leaves it alone.
        let descent = ClothParams { integrator: Integrator::BLOCK_DESCENT, ..absurd.clone() };
        assert_eq!(descent.substeps(1.0 / 60.0, &grid), descent.looper);
        // On the square grid the bound is the closed form 4 (k_s + k_sh + k_b) / m.
        let m = base.mass / grid.len() as f32;
        let k_sum = base.spring_k * (1.0 + 0.5 + 0.25);
        let closed = 0.9 * 2.0 * core::f32::consts::SQRT_2 / ((4.0 * k_sum / m).sqrt() + base.damping);
        let got = base.max_stable_substep(&grid);
        assert!((got - closed).abs() <= 1e-5 * closed, "{got} vs {closed}");
    }

    #[test]
    fn rejects_what_cannot_work() {
        let base = ClothParams::default();
        let cases: Vec<(ClothParams, ClothError)> = vec![
            (ClothParams { mass: -1.0, ..base.clone() }, ClothError::NotPositive { field: "mass", value: -1.0 }),
            (ClothParams { looper: 0, ..base.clone() }, ClothError::ZeroLooper),
            (
                ClothParams { spring_k: f32::INFINITY, ..base.clone() },
                ClothError::Negative { field: "spring_k", value: f32::INFINITY },
            ),
            (ClothParams { damping: -0.5, ..base.clone() }, ClothError::Negative { field: "damping", value: -0.5 }),
            (
                ClothParams { external_force: Vec3::new(0.0, f32::NAN, 0.0), ..base.clone() },
                ClothError::NotFinite { field: "external_force" },
            ),
        ];
        for (params, expected) in cases {
            assert_eq!(params.validate().unwrap_err(), expected);
        }
        let nan_mass = ClothParams { mass: f32::NAN, ..base };
        // NaN != NaN, so compare the message, which carries the field and the value.
        assert_eq!(
            nan_mass.validate().unwrap_err().to_string(),
            ClothError::NotPositive { field: "mass", value: f32::NAN }.to_string()
        );
    }

    #[test]
    fn grids_refuse_what_cannot_work() {
        let grid =
            |x: f32, y: f32, cols: u32, rows: u32| ClothGrid::new(Vec2::new(x, y), UVec2::new(cols, rows)).validate();
        assert_eq!(grid(1.0, 1.0, 8, 1), Err(ClothError::GridTooSmall { rows: 1, cols: 8 }));
        assert_eq!(grid(1.0, 1.0, 0, 8), Err(ClothError::GridTooSmall { rows: 8, cols: 0 }));
        assert_eq!(grid(1.0, -2.0, 8, 8), Err(ClothError::NotPositive { field: "size.y", value: -2.0 }));
        assert!(matches!(grid(1.0, 1.0, 100_000, 100_000), Err(ClothError::GridTooLarge { .. })));
        assert_eq!(grid(3.0, 0.5, 8, 2), Ok(()));
    }
}
