//! Every built collider, mesh or primitive, placed where its entity is each frame: moved by
//! its [`GlobalTransform`], or by its joints when skinned, with its margin, friction and collision layers applied
//! (no rebuild); and taken off an entity whose collider component was removed.

use bevy::mesh::skinning::SkinnedMesh;
use bevy::prelude::*;
use bvh_cloth_core::{Affine3A, ColliderPose};

use crate::backend::ActiveClothBackend;
use crate::colliders::auto::{AutoCollider, ClothCollider, ColliderBuild, ColliderStatus, SkinPose, Skins};
use crate::colliders::primitive::PrimitiveCollider;
use crate::messages::ColliderFailure;
use crate::settings::ClothSettings;

/// Places every collider (mesh or primitive) where its entity is, moves skinned colliders with
/// their joints, and applies margin, friction and layer changes (no rebuild).
#[allow(clippy::type_complexity)]
pub(crate) fn update_collider_poses(
    mut colliders: Query<(
        Entity,
        AnyOf<(&AutoCollider, &PrimitiveCollider)>,
        &GlobalTransform,
        Option<&SkinnedMesh>,
        &mut ClothCollider,
        &mut ColliderStatus,
    )>,
    skins: Skins,
    mut matrices: Local<Vec<Affine3A>>,
    backend: Res<ActiveClothBackend>,
    settings: Res<ClothSettings>,
) {
    // On the GPU backend the render world refits skinned colliders; the copy here is refitted
    // too only while the debug view draws it.
    let refit_here = *backend != ActiveClothBackend::Gpu || settings.debug_view;
    for (entity, source, transform, skinned, mut built, mut status) in &mut colliders {
        let (margin, friction, layers) = match source {
            (Some(auto), _) => (auto.margin, auto.friction, auto.layers),
            (None, Some(primitive)) => (primitive.margin, primitive.friction, primitive.layers),
            (None, None) => continue,
        };
        // A skinned collider follows its joints; until its first pose it is placed as a rigid one.
        if built.collider.skin().is_some()
            && let Some(pose) = skinned.and_then(|skinned| skins.pose(skinned))
        {
            let built = built.bypass_change_detection();
            built.collider.margin = margin;
            built.collider.friction = friction;
            built.collider.layers = layers;
            pose_skinned(entity, &pose, built, &mut matrices, refit_here);
            if built.skin_posed {
                continue;
            }
        }
        let (scale, rotation, translation) = transform.to_scale_rotation_translation();
        let uniform = scale.max_element();
        if !(scale.is_finite() && scale.min_element() > 0.0) {
            if !matches!(*status, ColliderStatus::Failed(_)) {
                error!("Collider on {entity}: {}; it will not collide", ColliderFailure::BadScale(scale));
                *status = ColliderStatus::Failed(ColliderFailure::BadScale(scale).to_string());
            }
        } else if uniform > scale.min_element() * 1.001 && !built.warned_non_uniform {
            warn!("Collider on {entity}: non-uniform scale {scale} is not supported; the shape is scaled by {uniform}");
            built.warned_non_uniform = true;
        }
        let pose = ColliderPose { translation, rotation, scale: uniform };
        let collider = &mut built.bypass_change_detection().collider;
        collider.pose = pose;
        collider.margin = margin;
        collider.friction = friction;
        collider.layers = layers;
        if matches!(*status, ColliderStatus::Failed(_)) && pose.is_valid() {
            *status = ColliderStatus::ready(collider);
        }
    }
}

/// Moves a skinned collider to its joints' pose: refitted here when `refit_here`, otherwise
/// accepted and kept for the render world's refit. A pose that cannot be read (a despawned
/// joint, a non-finite matrix) keeps the last one and is said once.
fn pose_skinned(
    entity: Entity,
    pose: &SkinPose<'_, '_, '_>,
    built: &mut ClothCollider,
    matrices: &mut Vec<Affine3A>,
    refit_here: bool,
) {
    let outcome = match pose.matrices(matrices) {
        Err((k, joint)) => Err(format!("joint {k} ({joint}) has no GlobalTransform (was it despawned?)")),
        Ok(()) if refit_here => {
            built.gpu_skin_pose = None;
            built.collider.pose_skin(matrices, &mut built.skin_scratch).map_err(|error| error.to_string())
        }
        Ok(()) => match built.collider.accept_skin_pose(matrices) {
            Ok(clearance) => {
                let kept = built.gpu_skin_pose.get_or_insert_with(Default::default);
                kept.0.clone_from(matrices);
                kept.1 = clearance.unwrap_or_default();
                Ok(())
            }
            Err(error) => Err(error.to_string()),
        },
    };
    match outcome {
        Ok(()) => {
            built.skin_posed = true;
            built.skin_warning = None;
        }
        Err(reason) => {
            if built.skin_warning.as_ref() != Some(&reason) {
                let held = if built.skin_posed { "its last pose" } else { "its bind pose at the entity" };
                warn!("Skinned collider on {entity}: {reason}; it stays at {held}");
                built.skin_warning = Some(reason);
            }
        }
    }
}

/// Takes the built collider off an entity whose [`AutoCollider`] or [`PrimitiveCollider`] was
/// removed, so that it stops colliding; an entity that still has an `AutoCollider` keeps its
/// collider, and one left with a `PrimitiveCollider` gets that built next.
pub(crate) fn drop_removed_colliders(
    mut commands: Commands,
    mut removed_auto: RemovedComponents<AutoCollider>,
    mut removed_primitive: RemovedComponents<PrimitiveCollider>,
    autos: Query<(), With<AutoCollider>>,
) {
    for entity in removed_auto.read().chain(removed_primitive.read()) {
        if !autos.contains(entity) {
            commands.entity(entity).try_remove::<(ClothCollider, ColliderBuild)>();
        }
    }
}
