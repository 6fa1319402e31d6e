//! The `Cloth` component: the paper's parameters (Table V) as a Bevy component.

use bevy::prelude::*;
use bvh_cloth_core::{ClothError, ClothGrid, ClothParams, ClothTopology, Integrator, Pins, SpringStiffness};

/// A simulated cloth. Put it on an entity with a material: either with a generated sheet
/// ([`Cloth::grid`]), for which the plugin makes the mesh, or on an entity with an authored
/// triangle [`Mesh3d`] ([`Cloth::mesh`]), which then moves as cloth.
///
/// The cloth starts in its rest shape under the entity's transform, at the moment it is spawned
/// (or rebuilt). Pinned particles stay at their rest position under the entity's transform,
/// so moving the entity drags them, tick by tick; the free particles are simulated in world
/// space.
///
/// Editing `looper`, `spring_k`, `damping`, `external_force`, `mass`, `stiffness` or
/// `integrator` takes effect on the next tick and keeps the cloth's state. Editing `shape` or
/// `pins` rebuilds the cloth at rest. Invalid values are refused with an error (see
/// [`ClothMessage::Rejected`](crate::ClothMessage)), and the cloth keeps running with its last
/// valid parameters.
#[derive(Component, Clone, Debug, PartialEq, Reflect)]
#[reflect(Component, Default, Debug)]
#[require(Transform, Visibility)]
pub struct Cloth {
    /// What the cloth is made of: a generated grid, or the entity's own mesh.
    pub shape: ClothShape,
    /// Total mass in kilograms ("Cloth Mass"). On a mesh each particle carries the share of
    /// the surface its triangles give it; on the grid the particles share it equally.
    pub mass: f32,
    /// Simulation substeps per tick ("Looper"). When `spring_k` is too stiff for substeps this
    /// long, more are run (and a warning says so), so that no slider setting can make the
    /// cloth explode; see [`ClothParams::max_stable_substep`].
    pub looper: u32,
    /// Stiffness of the fabric in N/m ("SpringK", paper eq. 1), the same material at any
    /// resolution: see [`ClothParams::spring_k`].
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

/// What a [`Cloth`] is made of.
#[derive(Clone, Debug, PartialEq, Reflect)]
#[reflect(Default, Debug)]
pub enum ClothShape {
    /// A flat sheet the plugin generates, in the entity's local XZ plane, centred on its origin
    /// and facing local +Y: `particles.x` columns along local +X and `particles.y` rows along
    /// local +Z, spanning `size` metres (`x` by `y`).
    Grid {
        /// Extent in metres from the first to the last column (`x`) and row (`y`).
        size: Vec2,
        /// Particle columns (`x`) and rows (`y`), at least 2 each.
        particles: UVec2,
    },
    /// The entity's own [`Mesh3d`], as authored (a triangle list with `Float32x3` positions,
    /// from glTF, OBJ or code). Vertices at the same position (split at UV or normal seams)
    /// become one particle, so seams stay closed. The entity's scale at build time is applied to
    /// the rest shape. The plugin simulates a copy of the mesh and puts it in [`Mesh3d`]; the
    /// original is kept for rebuilds.
    Mesh,
}

impl Default for ClothShape {
    fn default() -> Self {
        Self::Grid { size: Vec2::splat(2.0), particles: UVec2::splat(64) }
    }
}

impl Default for Cloth {
    fn default() -> Self {
        let core = ClothParams::default();
        Self {
            shape: ClothShape::default(),
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
    /// A generated sheet `size` metres across (`x` along the columns, `y` along the rows) of
    /// `particles.x` columns by `particles.y` rows, with every other parameter at its default.
    pub fn grid(size: Vec2, particles: UVec2) -> Self {
        Self { shape: ClothShape::Grid { size, particles }, ..default() }
    }

    /// The entity's own [`Mesh3d`] as cloth, with every other parameter at its default.
    pub fn mesh() -> Self {
        Self { shape: ClothShape::Mesh, ..default() }
    }

    /// Sets which particles are pinned.
    pub fn with_pins(mut self, pins: ClothPins) -> Self {
        self.pins = pins;
        self
    }

    /// The core parameters under the given gravity, validated.
    pub fn to_params(&self, gravity: Vec3) -> Result<ClothParams, ClothError> {
        let params = ClothParams {
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

    /// Whether going from `self` to `other` needs a new topology (and a new mesh).
    pub(crate) fn shape_differs(&self, other: &Cloth) -> bool {
        self.shape != other.shape || self.pins != other.pins
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
    /// The two corners of a grid's first row (paper Fig. 5, "two ends fixed").
    TwoEnds,
    /// A grid's whole first row, like a curtain.
    FirstRow,
    /// Vertex indices of the cloth's mesh (on the grid, `row * cols + col`). Every vertex
    /// welded to the same particle is held with it.
    Indices(Vec<u32>),
}

impl ClothPins {
    /// The pinned particles of `topology` (`grid` when it is a generated grid).
    pub(crate) fn particles(&self, topology: &ClothTopology, grid: Option<&ClothGrid>) -> Result<Vec<u32>, ClothError> {
        let by_grid = |pins: Pins| grid.map(|grid| pins.indices(grid)).ok_or(ClothError::PinsNeedGrid);
        match self {
            ClothPins::None => Ok(Vec::new()),
            ClothPins::TwoEnds => by_grid(Pins::TwoEnds),
            ClothPins::FirstRow => by_grid(Pins::FirstRow),
            ClothPins::Indices(vertices) => {
                let map = topology.vertex_particle();
                let mut particles = vertices
                    .iter()
                    .map(|&v| {
                        map.get(v as usize)
                            .copied()
                            .ok_or(ClothError::PinOutOfRange { index: v, particles: map.len() as u32 })
                    })
                    .collect::<Result<Vec<u32>, _>>()?;
                particles.sort_unstable();
                particles.dedup();
                Ok(particles)
            }
        }
    }
}
