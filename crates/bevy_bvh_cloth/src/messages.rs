//! Messages the plugin sends and receives.

use bevy::prelude::*;
use bvh_cloth_core::ClothError;

use crate::collider_mesh::ColliderFailure;

/// Something went wrong with one cloth or collider. Every message is also logged; read them to
/// show the problem in a game's own UI. The rest of the scene keeps running in every case.
#[derive(Message, Clone, Debug, PartialEq)]
pub enum ClothMessage {
    /// A [`Cloth`](crate::Cloth)'s parameters were refused. A cloth that was already running
    /// keeps its last valid parameters; a new one is not created until they are fixed.
    Rejected {
        /// The cloth entity.
        entity: Entity,
        /// What is wrong.
        error: ClothError,
    },
    /// A cloth's state became NaN or infinite, and it was reset to its rest pose under its
    /// entity's current transform. Other cloths are untouched.
    ///
    /// On the CPU backend the reset comes in the tick it happened. On the GPU backend each
    /// particle whose substep goes non-finite is first held at its last finite state (so that
    /// it cannot spread through the springs), and the reset follows once the count reaches the
    /// main world, a frame or two later.
    Diverged {
        /// The cloth entity.
        entity: Entity,
        /// The cause: how many particles went non-finite. On the GPU, counted per substep
        /// since the last report, so one particle may count more than once.
        particles: u32,
    },
    /// A [`ClothAnchor`](crate::ClothAnchor)'s target was despawned (or lost its
    /// [`GlobalTransform`]). The particles it held stay where they were last held, and the
    /// cloth keeps running; give the cloth a new anchor to carry them again.
    AnchorLost {
        /// The cloth entity.
        entity: Entity,
        /// The anchor's target.
        target: Entity,
    },
    /// A [`WindFan`](crate::WindFan)'s or [`WindBlast`](crate::WindBlast)'s values were
    /// refused: it does not blow until they are fixed, and every other source and cloth runs
    /// on. Sent once each time it turns bad.
    WindSourceRejected {
        /// The fan or blast entity.
        entity: Entity,
        /// What is wrong, naming the field.
        error: ClothError,
    },
    /// An [`AutoCollider`](crate::AutoCollider) could not be built; that entity does not collide.
    ColliderFailed {
        /// The collider entity.
        entity: Entity,
        /// Why.
        failure: ColliderFailure,
    },
}

/// Ask for cloths to go back to their rest pose under their entity's current transform.
#[derive(Message, Clone, Copy, Debug, PartialEq, Eq)]
pub enum ResetCloth {
    /// Every cloth.
    All,
    /// One cloth entity.
    One(Entity),
}
