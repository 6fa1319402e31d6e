//! The `Cloth` component: the paper's parameters (Table V) as a Bevy component.

use bevy::prelude::*;
use bvh_cloth_core::{ClothError, ClothParams, ClothPins, CollisionLayers};

use crate::colliders::hierarchy::ExcludeFromColliders;

/// A simulated cloth. Put it on an entity with a material: either with a generated sheet
/// ([`Cloth::grid`]), for which the plugin makes the mesh, or on an entity with an authored
/// triangle [`Mesh3d`] ([`Cloth::mesh`]), which then moves as cloth.
///
/// The cloth starts in its rest shape under the entity's transform, at the moment it is spawned
/// (or rebuilt). Particles chosen by `pins` stay at their rest position under the entity's
/// transform, so moving the entity drags them (on a skinned mesh, they go where its skin draws
/// them: see [`ClothSkin`](crate::ClothSkin)); particles chosen by an [`anchor`](ClothAnchor)
/// are carried by another entity (a pole, a character's joint). Both move every tick, their
/// holder's motion over the frame spread evenly over the frame's ticks. The free particles are
/// simulated in world space.
///
/// A new cloth waits for the [`AutoCollider`](crate::AutoCollider)s still being built (their
/// mesh still loading, or a big mesh voxelised off the main thread) before it starts, so that it
/// does not fall through a body that is not there yet; it then starts at rest under the
/// entity's transform of that moment. While it waits, an authored cloth shows its mesh as
/// authored and a grid cloth has no mesh yet. [`ClothSettings::collider_wait`](crate::ClothSettings)
/// bounds the wait; `start_at_once` opts out.
///
/// A cloth's own mesh is never made a collider by an [`AutoCollider`](crate::AutoCollider) on an
/// ancestor (it requires [`ExcludeFromColliders`]).
///
/// Editing `params`, `pins` or `anchors` takes effect on the next tick and keeps the cloth's
/// state, so a corner can be let go, or caught, while the cloth moves: a particle let go
/// starts from rest where it was held (its springs take it along at once); a particle newly
/// held goes to its holder, an anchor's bound as when the cloth is built (its rest place under
/// the cloth entity, carried from where the target is now). Editing `shape` rebuilds the cloth
/// at rest. Invalid values are refused with an error (see
/// [`ClothMessage::Rejected`](crate::ClothMessage)), and the cloth keeps running with its last
/// valid parameters.
///
/// ```
/// # use bevy::prelude::*;
/// # use bevy_bvh_cloth::prelude::*;
/// let curtain = Cloth::grid(Vec2::new(2.0, 1.5), UVec2::new(48, 36))
///     .with_params(ClothParams { spring_k: 300.0, damping: 1.0, ..default() })
///     .with_pins(ClothPins::FirstRow);
/// ```
#[derive(Component, Clone, Debug, Default, PartialEq, Reflect)]
#[reflect(Component, Default, Debug)]
#[require(Transform, Visibility, ExcludeFromColliders)]
pub struct Cloth {
    /// What the cloth is made of: a generated grid, or the entity's own mesh.
    pub shape: ClothShape,
    /// The material and how it is stepped: the paper's Cloth Mass, Looper, SpringK, Damping and
    /// External Force (Table V), gravity, the per-kind stiffness scales and the integrator. When
    /// `spring_k` is too stiff for `looper` substeps, more are run (and a warning says so), so
    /// that no setting can make the cloth explode; see [`ClothParams::max_stable_substep`].
    pub params: ClothParams,
    /// Which particles the entity itself holds.
    pub pins: ClothPins,
    /// Groups of particles held by other entities. Where a particle is chosen more than once,
    /// the last anchor that chooses it holds it, and any anchor overrides `pins`.
    pub anchors: Vec<ClothAnchor>,
    /// Start as soon as the cloth is spawned, without waiting for colliders still being built.
    pub start_at_once: bool,
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

/// A cloth the plugin made from a mesh under a root's
/// [`ClothHierarchy`](crate::ClothHierarchy).
#[derive(Component, Clone, Copy, Debug, PartialEq, Eq, Reflect)]
#[reflect(Component, Debug)]
pub struct ClothPart {
    /// The entity whose [`ClothHierarchy`](crate::ClothHierarchy) this cloth comes from.
    pub root: Entity,
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

    /// Sets the material and solver parameters.
    pub fn with_params(mut self, params: ClothParams) -> Self {
        self.params = params;
        self
    }

    /// Sets the collision layers ([`ClothParams::layers`]): the cloth collides only with the
    /// colliders, and keeps off only the cloths, whose layers meet these.
    pub fn with_layers(mut self, layers: CollisionLayers) -> Self {
        self.params.layers = layers;
        self
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

    /// Starts the cloth as soon as it is spawned, without waiting for colliders still being
    /// built.
    pub fn starting_at_once(mut self) -> Self {
        self.start_at_once = true;
        self
    }

    /// The parameters, validated.
    pub fn to_params(&self) -> Result<ClothParams, ClothError> {
        self.params.validate()?;
        Ok(self.params.clone())
    }

    /// Whether going from `self` to `other` needs a new topology (and a new mesh).
    pub(crate) fn shape_differs(&self, other: &Cloth) -> bool {
        self.shape != other.shape
    }

    /// Whether going from `self` to `other` changes who holds which particles (the running
    /// cloth keeps its state through it; an anchor's offset alone is not such a change).
    pub(crate) fn holders_differ(&self, other: &Cloth) -> bool {
        fn holds(a: &ClothAnchor) -> (&ClothPins, Entity) {
            (&a.pins, a.target)
        }
        self.pins != other.pins || !self.anchors.iter().map(holds).eq(other.anchors.iter().map(holds))
    }
}
