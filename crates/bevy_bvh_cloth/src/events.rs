//! Entity events for observers: each [`ClothMessage`] is also triggered on its entity, and a
//! collider that becomes ready says so.
//!
//! ```
//! # use bevy::prelude::*;
//! # use bevy_bvh_cloth::prelude::*;
//! # fn setup(mut commands: Commands) {
//! commands.spawn(PrimitiveCollider::sphere(0.5)).observe(|ready: On<ColliderReady>| {
//!     info!("collider {} is ready", ready.entity);
//! });
//! # }
//! ```

use bevy::prelude::*;
use bvh_cloth_core::ClothError;

use crate::messages::ClothMessage;
use crate::messages::ColliderFailure;

/// A collider was built (or rebuilt) and takes part from the next tick on.
#[derive(EntityEvent, Clone, Debug, PartialEq)]
pub struct ColliderReady {
    /// The collider entity.
    pub entity: Entity,
    /// Its leaf spheres (0 for a primitive).
    pub spheres: u32,
}

/// Every collider under a mesh-less [`AutoCollider`](crate::AutoCollider) (a glTF scene root, a
/// character's root) is built, or has failed and said so on its own entity: triggered on the
/// root when its summed status becomes ready (and again after a part is rebuilt; not when a
/// ready hierarchy gains or loses a part), so that a game can wait for a whole
/// character (see [`ColliderHierarchy`](crate::ColliderHierarchy)). Each part also hears its
/// own [`ColliderReady`].
#[derive(EntityEvent, Clone, Debug, PartialEq)]
pub struct ColliderHierarchyReady {
    /// The root entity.
    pub entity: Entity,
    /// The parts that collide.
    pub parts: u32,
    /// Their leaf spheres, summed.
    pub spheres: u32,
}

/// Every cloth a [`ClothHierarchy`](crate::ClothHierarchy) names is built: triggered once on
/// the root, so that a game can wait for a dressed character.
#[derive(EntityEvent, Clone, Debug, PartialEq)]
pub struct ClothHierarchyReady {
    /// The root entity.
    pub entity: Entity,
    /// The cloths built.
    pub cloths: u32,
}

/// A [`ClothHierarchy`](crate::ClothHierarchy) names what its scene does not have:
/// [`ClothMessage::NameNotFound`] on the root.
#[derive(EntityEvent, Clone, Debug, PartialEq)]
pub struct NameNotFound {
    /// The root entity.
    pub entity: Entity,
    /// The name that matched nothing.
    pub name: String,
}

/// A [`ClothHierarchy`](crate::ClothHierarchy)'s scene has not spawned in time:
/// [`ClothMessage::SceneNotSpawned`] on the root.
#[derive(EntityEvent, Clone, Debug, PartialEq)]
pub struct SceneNotSpawned {
    /// The root entity.
    pub entity: Entity,
    /// How long it had waited, in seconds.
    pub waited: f32,
}

/// A wind blows on a cloth that cannot feel it: [`ClothMessage::WindNotFelt`] on the cloth.
#[derive(EntityEvent, Clone, Debug, PartialEq)]
pub struct WindNotFelt {
    /// The cloth entity.
    pub entity: Entity,
    /// The wind's speed plus its turbulence, in m/s.
    pub speed: f32,
}

/// A collider could not be built: [`ClothMessage::ColliderFailed`] on its entity.
#[derive(EntityEvent, Clone, Debug, PartialEq)]
pub struct ColliderFailed {
    /// The collider entity.
    pub entity: Entity,
    /// Why.
    pub failure: ColliderFailure,
}

/// A cloth's parameters were refused: [`ClothMessage::Rejected`] on its entity.
#[derive(EntityEvent, Clone, Debug, PartialEq)]
pub struct ClothRejected {
    /// The cloth entity.
    pub entity: Entity,
    /// What is wrong.
    pub error: ClothError,
}

/// A cloth went non-finite and was reset: [`ClothMessage::Diverged`] on its entity.
#[derive(EntityEvent, Clone, Debug, PartialEq)]
pub struct ClothDiverged {
    /// The cloth entity.
    pub entity: Entity,
    /// How many particles went non-finite.
    pub particles: u32,
}

/// A cloth's anchor target was despawned: [`ClothMessage::AnchorLost`] on the cloth.
#[derive(EntityEvent, Clone, Debug, PartialEq)]
pub struct AnchorLost {
    /// The cloth entity.
    pub entity: Entity,
    /// The anchor's target.
    pub target: Entity,
}

/// A wind source's values were refused: [`ClothMessage::WindSourceRejected`] on its entity.
#[derive(EntityEvent, Clone, Debug, PartialEq)]
pub struct WindSourceRejected {
    /// The fan or blast entity.
    pub entity: Entity,
    /// What is wrong.
    pub error: ClothError,
}

/// Triggers each message of this frame as its entity event.
pub(crate) fn trigger_message_events(mut commands: Commands, mut messages: MessageReader<ClothMessage>) {
    for message in messages.read() {
        match message.clone() {
            ClothMessage::Rejected { entity, error } => commands.trigger(ClothRejected { entity, error }),
            ClothMessage::Diverged { entity, particles } => commands.trigger(ClothDiverged { entity, particles }),
            ClothMessage::AnchorLost { entity, target } => commands.trigger(AnchorLost { entity, target }),
            ClothMessage::ColliderFailed { entity, failure } => commands.trigger(ColliderFailed { entity, failure }),
            ClothMessage::NameNotFound { entity, name } => commands.trigger(NameNotFound { entity, name }),
            ClothMessage::SceneNotSpawned { entity, waited } => commands.trigger(SceneNotSpawned { entity, waited }),
            ClothMessage::WindNotFelt { entity, speed } => commands.trigger(WindNotFelt { entity, speed }),
            ClothMessage::WindSourceRejected { entity, error } => {
                commands.trigger(WindSourceRejected { entity, error });
            }
        }
    }
}
