//! The `Cloth` component: the paper's parameters (Table V) as a Bevy component.

use bevy::prelude::*;
use bvh_cloth_core::{ClothError, ClothParams, ClothPins, Integrator, SpringStiffness};

/// A simulated cloth. Put it on an entity with a material: either with a generated sheet
/// ([`Cloth::grid`]), for which the plugin makes the mesh, or on an entity with an authored
/// triangle [`Mesh3d`] ([`Cloth::mesh`]), which then moves as cloth.
///
/// The cloth starts in its rest shape under the entity's transform, at the moment it is spawned
/// (or rebuilt). Particles chosen by `pins` stay at their rest position under the entity's
/// transform, so moving the entity drags them; particles chosen by an [`anchor`](ClothAnchor)
/// are carried by another entity (a pole, a character's joint). Both move every tick, their
/// holder's motion over the frame spread evenly over the frame's ticks. The free particles are
/// simulated in world space.
///
/// Editing `looper`, `spring_k`, `damping`, `external_force`, `mass`, `stiffness`,
/// `integrator` or an anchor's `offset` takes effect on the next tick and keeps the cloth's
/// state. Editing `shape`, `pins` or which vertices or entity an anchor holds rebuilds the
/// cloth at rest. Invalid values are refused with an error (see
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
    pub stiffness: SpringStiffness,
    /// The time integrator.
    pub integrator: Integrator,
    /// Which particles the entity itself holds.
    pub pins: ClothPins,
    /// Groups of particles held by other entities. Where a particle is chosen more than once,
    /// the last anchor that chooses it holds it, and any anchor overrides `pins`.
    pub anchors: Vec<ClothAnchor>,
}

/// A group of a cloth's particles carried by another entity: a flagpole, a character's
/// shoulder joint, a ring on a curtain rod.
///
/// When the cloth is built, each chosen particle's rest position is taken into the target's
/// frame (its rotation and translation; its scale is left out). From then on the particle goes
/// where the target's frame carries that point, moved by `offset` along the target's own axes.
/// If the target is despawned, or has no [`GlobalTransform`], the particles stay where they
/// were last held and [`ClothMessage::AnchorLost`](crate::ClothMessage::AnchorLost) says so.
#[derive(Clone, Debug, PartialEq, Reflect)]
#[reflect(Debug, PartialEq)]
pub struct ClothAnchor {
    /// The particles the anchor holds.
    pub pins: ClothPins,
    /// The entity that carries them.
    pub target: Entity,
    /// A shift in metres along the target's axes, applied to every particle of the group.
    pub offset: Vec3,
}

impl ClothAnchor {
    /// `pins` carried by `target`, without offset.
    pub fn new(pins: ClothPins, target: Entity) -> Self {
        Self { pins, target, offset: Vec3::ZERO }
    }

    /// The same anchor, shifted by `offset` metres along the target's axes.
    pub fn with_offset(mut self, offset: Vec3) -> Self {
        self.offset = offset;
        self
    }
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
            stiffness: core.stiffness,
            integrator: core.integrator,
            pins: ClothPins::default(),
            anchors: Vec::new(),
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

    /// Sets which particles the entity itself holds.
    pub fn with_pins(mut self, pins: ClothPins) -> Self {
        self.pins = pins;
        self
    }

    /// Adds a group of particles carried by another entity.
    pub fn with_anchor(mut self, anchor: ClothAnchor) -> Self {
        self.anchors.push(anchor);
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
            stiffness: self.stiffness,
            integrator: self.integrator,
        };
        params.validate()?;
        Ok(params)
    }

    /// Whether going from `self` to `other` needs a new topology (and a new mesh).
    pub(crate) fn shape_differs(&self, other: &Cloth) -> bool {
        fn holds(a: &ClothAnchor) -> (&ClothPins, Entity) {
            (&a.pins, a.target)
        }
        self.shape != other.shape
            || self.pins != other.pins
            || !self.anchors.iter().map(holds).eq(other.anchors.iter().map(holds))
    }
}
