//! The `Cloth` component: the paper's parameters (Table V) as a Bevy component.

use bevy::prelude::*;
use bvh_cloth_core::{ClothError, ClothGrid, ClothParams, Integrator, Pins, SpringStiffness};

/// A simulated cloth. Put it on an entity with a material, and the plugin gives the entity a
/// grid [`Mesh3d`] and simulates it every frame.
///
/// The cloth is a flat `rows x cols` sheet in the entity's local XZ plane, centred on its origin
/// and facing local +Y, at the moment it is spawned (or rebuilt). Pinned particles stay at their
/// rest position under the entity's transform, so moving the entity drags them; the free
/// particles are simulated in world space.
///
/// Editing `looper`, `spring_k`, `damping`, `external_force`, `mass`, `stiffness` or
/// `integrator` takes effect on the next tick and keeps the cloth's state. Editing `rows`,
/// `cols`, `size` or `pins` rebuilds the cloth at rest. Invalid values are refused with an
/// error (see [`ClothMessage::Rejected`](crate::ClothMessage)), and the cloth keeps running
/// with its last valid parameters.
#[derive(Component, Clone, Debug, PartialEq, Reflect)]
#[reflect(Component, Default, Debug)]
#[require(Transform, Visibility)]
pub struct Cloth {
    /// Number of particle rows ("Vertex Row"), along the entity's local +Z.
    pub rows: u32,
    /// Number of particle columns ("Vertex Column"), along the entity's local +X.
    pub cols: u32,
    /// Width of the cloth along its columns, in metres ("Cloth Size"); cells are square.
    pub size: f32,
    /// Total mass in kilograms ("Cloth Mass").
    pub mass: f32,
    /// Simulation substeps per tick ("Looper"). When `spring_k` is too stiff for substeps this
    /// long, more are run (and a warning says so), so that no slider setting can make the
    /// cloth explode; see [`ClothParams::max_stable_substep`].
    pub looper: u32,
    /// Spring stiffness in N/m ("SpringK", paper eq. 1).
    pub spring_k: f32,
    /// Velocity damping rate in 1/s ("Damping", paper eq. 2).
    pub damping: f32,
    /// A force on the whole cloth in newtons, world axes ("External Force"): wind, a push.
    pub external_force: Vec3,
    /// Per-kind stiffness scales on top of `spring_k`.
    pub stiffness: SpringScales,
    /// The time integrator.
    pub integrator: ClothIntegrator,
    /// Which particles are held in place.
    pub pins: ClothPins,
}

impl Default for Cloth {
    fn default() -> Self {
        let core = ClothParams::default();
        Self {
            rows: core.rows,
            cols: core.cols,
            size: core.size,
            mass: core.mass,
            looper: core.looper,
            spring_k: core.spring_k,
            damping: core.damping,
            external_force: Vec3::ZERO,
            stiffness: SpringScales::default(),
            integrator: ClothIntegrator::default(),
            pins: ClothPins::default(),
        }
    }
}

impl Cloth {
    /// A `rows x cols` cloth `size` metres wide, with every other parameter at its default.
    pub fn new(rows: u32, cols: u32, size: f32) -> Self {
        Self { rows, cols, size, ..default() }
    }

    /// Sets which particles are pinned.
    pub fn with_pins(mut self, pins: ClothPins) -> Self {
        self.pins = pins;
        self
    }

    /// Number of particles.
    pub fn particle_count(&self) -> usize {
        self.rows as usize * self.cols as usize
    }

    /// The core parameters under the given gravity, validated.
    pub fn to_params(&self, gravity: Vec3) -> Result<ClothParams, ClothError> {
        let params = ClothParams {
            rows: self.rows,
            cols: self.cols,
            size: self.size,
            mass: self.mass,
            looper: self.looper,
            spring_k: self.spring_k,
            damping: self.damping,
            external_force: self.external_force,
            gravity,
            stiffness: self.stiffness.into(),
            integrator: self.integrator.into(),
        };
        params.validate()?;
        Ok(params)
    }

    /// Whether going from `self` to `other` needs a new grid (and a new mesh).
    pub(crate) fn shape_differs(&self, other: &Cloth) -> bool {
        (self.rows, self.cols, self.size.to_bits()) != (other.rows, other.cols, other.size.to_bits())
            || self.pins != other.pins
    }
}

/// Per-kind stiffness scales applied on top of [`Cloth::spring_k`] (paper section 2.1).
#[derive(Clone, Copy, Debug, PartialEq, Reflect)]
#[reflect(Default, Debug)]
pub struct SpringScales {
    /// Springs to the 4-neighbourhood.
    pub structural: f32,
    /// Springs to the diagonals.
    pub shear: f32,
    /// Springs two particles away along rows and columns.
    pub bending: f32,
}

impl Default for SpringScales {
    fn default() -> Self {
        let s = SpringStiffness::default();
        Self { structural: s.structural, shear: s.shear, bending: s.bending }
    }
}

impl From<SpringScales> for SpringStiffness {
    fn from(s: SpringScales) -> Self {
        Self { structural: s.structural, shear: s.shear, bending: s.bending }
    }
}

/// The time integrator of a cloth (paper section 2.2).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Reflect)]
#[reflect(Default, Debug)]
pub enum ClothIntegrator {
    /// Fourth-order Runge–Kutta over the whole system (paper eq. 4).
    #[default]
    Rk4,
    /// Semi-implicit Euler: cheaper, first order.
    SemiImplicitEuler,
}

impl From<ClothIntegrator> for Integrator {
    fn from(i: ClothIntegrator) -> Self {
        match i {
            ClothIntegrator::Rk4 => Integrator::Rk4,
            ClothIntegrator::SemiImplicitEuler => Integrator::SemiImplicitEuler,
        }
    }
}

/// Which particles of a cloth are held in place.
#[derive(Clone, Debug, Default, PartialEq, Eq, Reflect)]
#[reflect(Default, Debug)]
pub enum ClothPins {
    /// Nothing: the cloth falls freely.
    #[default]
    None,
    /// The two corners of the first row (paper Fig. 5, "two ends fixed").
    TwoEnds,
    /// The whole first row, like a curtain.
    FirstRow,
    /// Explicit row-major particle indices (`row * cols + col`).
    Indices(Vec<u32>),
}

impl ClothPins {
    /// The pinned indices for a `rows x cols` grid.
    pub(crate) fn indices(&self, rows: u32, cols: u32) -> Vec<u32> {
        let grid = ClothGrid { rows: rows as usize, cols: cols as usize, spacing: 1.0 };
        let pins = match self {
            ClothPins::None => Pins::None,
            ClothPins::TwoEnds => Pins::TwoEnds,
            ClothPins::FirstRow => Pins::FirstRow,
            ClothPins::Indices(indices) => Pins::Indices(indices.clone()),
        };
        pins.indices(&grid)
    }
}
