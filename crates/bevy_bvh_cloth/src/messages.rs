//! Messages the plugin sends and receives, and why a collider could not be built
//! ([`ColliderFailure`]), which they carry. It imports nothing of the crate.

use core::fmt;

use bevy::mesh::PrimitiveTopology;
use bevy::prelude::*;
use bvh_cloth_core::{ClothError, ColliderError};

/// Something went wrong with one cloth or collider. Every message is also logged; read them to
/// show the problem in a game's own UI. The rest of the scene keeps running in every case.
///
/// ```
/// # use bevy::prelude::*;
/// # use bevy_bvh_cloth::prelude::*;
/// fn show_cloth_problems(mut messages: MessageReader<ClothMessage>) {
///     for message in messages.read() {
///         if let ClothMessage::Rejected { entity, error } = message {
///             warn!("the cloth on {entity} was refused: {error}");
///         }
///     }
/// }
/// ```
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
    /// On both backends each particle whose substep goes non-finite is first held at its
    /// last finite state (so that it cannot spread through the springs). On the CPU backend
    /// the reset comes in the frame it happened; on the GPU backend once the count reaches the
    /// main world, two or three frames later.
    Diverged {
        /// The cloth entity.
        entity: Entity,
        /// The cause: how many particles went non-finite, counted per substep since the last
        /// report (so one particle may count more than once), plus those a state written
        /// non-finite left so.
        particles: u32,
    },
    /// A [`ClothAnchor`](crate::ClothAnchor)'s target, or a joint of the skin that carries a
    /// skinned cloth's pins ([`ClothSkin`](crate::ClothSkin)), was despawned (or lost its
    /// [`GlobalTransform`]). The particles it held stay where they were last held, and the
    /// cloth keeps running; give the cloth a new anchor to carry them again.
    AnchorLost {
        /// The cloth entity.
        entity: Entity,
        /// The anchor's target, or the skin's joint.
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
    /// A [`ClothHierarchy`](crate::ClothHierarchy) names a mesh or a joint that the scene
    /// spawned under its root does not have: the cloth that needs it is not made, and the rest
    /// of the scene runs. Sent once per root and name.
    NameNotFound {
        /// The root entity.
        entity: Entity,
        /// The name that matched nothing.
        name: String,
    },
    /// A wind blows on a cloth whose [`Aerodynamics`](crate::Aerodynamics) has no drag or lift,
    /// so it does not feel it (set `Aerodynamics::FABRIC`). Sent once per cloth; the cloth runs
    /// on as it was.
    WindNotFelt {
        /// The cloth entity.
        entity: Entity,
        /// The wind's speed plus its turbulence, in m/s.
        speed: f32,
    },
    /// A [`ClothHierarchy`](crate::ClothHierarchy)'s root has no mesh under it after
    /// [`ClothSettings::scene_wait`](crate::ClothSettings) seconds: its scene failed to load
    /// (the asset server logs why, with the path), is still loading, or was never given. Sent
    /// once per root; a scene that spawns later is still dressed.
    SceneNotSpawned {
        /// The root entity.
        entity: Entity,
        /// How long it had waited, in seconds.
        waited: f32,
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
///
/// ```
/// # use bevy::prelude::*;
/// # use bevy_bvh_cloth::prelude::*;
/// fn reset_on_r(keys: Res<ButtonInput<KeyCode>>, mut resets: MessageWriter<ResetCloth>) {
///     if keys.just_pressed(KeyCode::KeyR) {
///         resets.write(ResetCloth::All);
///     }
/// }
/// ```
#[derive(Message, Clone, Copy, Debug, PartialEq, Eq)]
pub enum ResetCloth {
    /// Every cloth.
    All,
    /// One cloth entity.
    One(Entity),
}

/// Why an [`AutoCollider`](crate::AutoCollider) or a [`PrimitiveCollider`](crate::PrimitiveCollider)
/// could not be built.
#[derive(Clone, Debug, PartialEq)]
pub enum ColliderFailure {
    /// The entity has no [`Mesh3d`], and none of its descendants has one.
    NoMesh3d,
    /// The mesh asset failed to load.
    LoadFailed(String),
    /// The mesh's data lives only in the render world (`RenderAssetUsages::RENDER_WORLD`), so
    /// the main world cannot read its vertices.
    NotInMainWorld,
    /// The mesh is not a triangle list.
    NotTriangles(PrimitiveTopology),
    /// The mesh has no `Mesh::ATTRIBUTE_POSITION`.
    NoPositions,
    /// The positions are not `Float32x3`.
    PositionsNotFloat3,
    /// The transform's scale is zero, negative or not finite.
    BadScale(Vec3),
    /// The entity has a `SkinnedMesh`, but its mesh has no `Mesh::ATTRIBUTE_JOINT_INDEX`
    /// (`Uint16x4`) or no `Mesh::ATTRIBUTE_JOINT_WEIGHT` (`Float32x4`).
    NoSkin,
    /// The mesh data or the primitive's sizes were rejected by the collider builder.
    Rejected(ColliderError),
}

impl fmt::Display for ColliderFailure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NoMesh3d => {
                write!(f, "neither the entity nor any of its descendants has a Mesh3d to build a collider from")
            }
            Self::LoadFailed(reason) => write!(f, "the mesh failed to load: {reason}"),
            Self::NotInMainWorld => write!(
                f,
                "the mesh data was moved to the render world (RenderAssetUsages::RENDER_WORLD only); \
                 keep MAIN_WORLD so a collider can be built from it"
            ),
            Self::NotTriangles(topology) => {
                write!(f, "the mesh is a {topology:?}, but a collider needs a TriangleList")
            }
            Self::NoPositions => write!(f, "the mesh has no vertex positions"),
            Self::PositionsNotFloat3 => write!(f, "the mesh positions are not Float32x3"),
            Self::BadScale(scale) => write!(f, "the collider's scale {scale} is not positive and finite"),
            Self::NoSkin => write!(
                f,
                "the entity has a SkinnedMesh, but its mesh lacks Uint16x4 joint indices or Float32x4 joint weights"
            ),
            Self::Rejected(error) => error.fmt(f),
        }
    }
}

impl std::error::Error for ColliderFailure {}
