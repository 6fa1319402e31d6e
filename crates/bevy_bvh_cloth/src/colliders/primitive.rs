//! `PrimitiveCollider`: an exact sphere, capsule, box or ground that follows its entity.

use bevy::ecs::entity::EntityHashSet;
use bevy::prelude::*;
use bvh_cloth_core::{Collider, CollisionLayers, Primitive};

use crate::colliders::auto::{AutoCollider, ClothCollider, ColliderStatus, settle};
use crate::messages::ClothMessage;
use crate::messages::ColliderFailure;

/// The shape of a [`PrimitiveCollider`], in the entity's local frame, with Bevy's math
/// primitives.
#[derive(Clone, Copy, Debug, PartialEq, Reflect)]
#[reflect(Debug, PartialEq)]
pub enum PrimitiveShape {
    /// A ball around the entity's origin.
    Sphere(Sphere),
    /// A capsule along the entity's local Y axis.
    Capsule(Capsule3d),
    /// A box around the entity's origin, aligned with its local axes.
    Cuboid(Cuboid),
    /// Everything below the plane through the entity's origin with this outward normal (local):
    /// an endless ground when the normal is `Dir3::Y`.
    HalfSpace(Dir3),
}

impl PrimitiveShape {
    /// The core's shape.
    pub fn to_primitive(self) -> Primitive {
        match self {
            Self::Sphere(sphere) => Primitive::Sphere { radius: sphere.radius },
            Self::Capsule(capsule) => Primitive::Capsule { radius: capsule.radius, half_length: capsule.half_length },
            Self::Cuboid(cuboid) => Primitive::Cuboid { half_extents: cuboid.half_size },
            Self::HalfSpace(normal) => Primitive::HalfSpace { normal: normal.as_vec3() },
        }
    }
}

/// Makes the entity an exact collider for every cloth: a sphere, a capsule, a box or a ground.
///
/// The shape is tested by its exact distance, so a cloth rests on the true surface, and it costs
/// less per particle than a voxelised mesh (about a quarter of the bunny's at `n = 5` on the
/// CPU; see BENCHMARKS.md). It follows the entity's
/// [`GlobalTransform`] every frame, so a primitive on a bone's entity moves with the bone: that
/// is how to collide with an animated character. Sizes are in the entity's local units and are
/// scaled with it (uniformly: with a non-uniform scale the largest axis is used, and a warning
/// says so). An entity with an [`AutoCollider`] too keeps the `AutoCollider` only, with a
/// warning.
///
/// ```
/// # use bevy::prelude::*;
/// # use bevy_bvh_cloth::prelude::*;
/// # fn setup(mut commands: Commands) {
/// // The ground, and a ball one metre above it.
/// commands.spawn(PrimitiveCollider::ground());
/// commands.spawn((PrimitiveCollider::sphere(0.5), Transform::from_xyz(0.0, 1.0, 0.0)));
/// # }
/// ```
#[derive(Component, Clone, Debug, PartialEq, Reflect)]
#[reflect(Component, Debug)]
#[require(Transform, ColliderStatus)]
pub struct PrimitiveCollider {
    /// The shape.
    pub shape: PrimitiveShape,
    /// Extra thickness in world units around the surface, so that the cloth rests a little above
    /// it instead of on it.
    pub margin: f32,
    /// Coulomb friction coefficient of the surface (see [`AutoCollider::friction`](crate::AutoCollider::friction)).
    pub friction: f32,
    /// Which cloths collide with it (see [`AutoCollider::layers`](crate::AutoCollider::layers)).
    pub layers: CollisionLayers,
}

impl PrimitiveCollider {
    /// A collider of `shape` with the default margin (1 cm) and friction (1).
    pub fn new(shape: PrimitiveShape) -> Self {
        Self { shape, margin: 0.01, friction: 1.0, layers: CollisionLayers::DEFAULT }
    }

    /// A ball of `radius` around the entity's origin.
    pub fn sphere(radius: f32) -> Self {
        Self::new(PrimitiveShape::Sphere(Sphere::new(radius)))
    }

    /// A capsule along the local Y axis, with `length` between the centres of its rounded ends
    /// (as [`Capsule3d::new`]).
    pub fn capsule(radius: f32, length: f32) -> Self {
        Self::new(PrimitiveShape::Capsule(Capsule3d::new(radius, length)))
    }

    /// A box of the given full lengths along the local axes (as [`Cuboid::new`]).
    pub fn cuboid(x_length: f32, y_length: f32, z_length: f32) -> Self {
        Self::new(PrimitiveShape::Cuboid(Cuboid::new(x_length, y_length, z_length)))
    }

    /// An endless ground: everything below the entity's local XZ plane.
    pub fn ground() -> Self {
        Self::new(PrimitiveShape::HalfSpace(Dir3::Y))
    }

    /// Sets the margin.
    pub fn with_margin(mut self, margin: f32) -> Self {
        self.margin = margin;
        self
    }

    /// Sets the friction coefficient.
    pub fn with_friction(mut self, friction: f32) -> Self {
        self.friction = friction;
        self
    }

    /// Sets the collision layers: only the cloths whose layers meet these collide with it.
    pub fn with_layers(mut self, layers: CollisionLayers) -> Self {
        self.layers = layers;
        self
    }
}

/// Builds (or rebuilds, when the shape changed) each primitive's collider; refuses bad sizes.
#[allow(clippy::type_complexity)]
pub(crate) fn build_primitive_colliders(
    mut commands: Commands,
    mut primitives: Query<
        (Entity, Ref<PrimitiveCollider>, Option<&ClothCollider>, &mut ColliderStatus, Has<AutoCollider>),
        Or<(Changed<PrimitiveCollider>, Without<ClothCollider>)>,
    >,
    mut messages: MessageWriter<ClothMessage>,
    mut warned: Local<EntityHashSet>,
) {
    for (entity, primitive, built, mut status, has_auto) in &mut primitives {
        if has_auto {
            if warned.insert(entity) {
                warn!(
                    "Entity {entity} has both an AutoCollider and a PrimitiveCollider; the PrimitiveCollider is ignored"
                );
            }
            continue;
        }
        let shape = primitive.shape.to_primitive();
        if built.and_then(|built| built.collider().as_primitive()) == Some(&shape) {
            continue;
        }
        if built.is_none() && matches!(*status, ColliderStatus::Failed(_)) && !primitive.is_changed() {
            continue;
        }
        let outcome = Collider::primitive(shape).map_err(ColliderFailure::Rejected);
        settle(&mut commands, &mut messages, entity, "PrimitiveCollider", &mut status, outcome);
    }
}
