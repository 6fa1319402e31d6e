//! An [`AutoCollider`] on an entity without a [`Mesh3d`] (a glTF scene root, a character's
//! root) covers every mesh under it: each descendant with a `Mesh3d` gets a collider of its own,
//! with the root's settings or an override named in [`ColliderHierarchy`]. A mesh marked
//! [`ExcludeFromColliders`], as every [`Cloth`](crate::Cloth) is, never does: a cape must not
//! collide with a copy of itself. When every part is built, the root hears
//! [`ColliderHierarchyReady`].

use bevy::platform::collections::HashMap;
use bevy::prelude::*;

use crate::colliders::auto::{AutoCollider, ClothCollider, ColliderBuild, ColliderStatus};
use crate::colliders::primitive::PrimitiveCollider;
use crate::events::ColliderHierarchyReady;
use crate::messages::ClothMessage;
use crate::messages::ColliderFailure;

/// Per-mesh settings for the meshes under an [`AutoCollider`] placed on an entity without a
/// mesh, looked up by the [`Name`] of the mesh entity or, failing that, of its parent (glTF
/// names the node, and its primitives are children of it).
///
/// On a glTF scene, put both on the `WorldAssetRoot` entity; the meshes are covered as the
/// scene spawns them, and [`ColliderHierarchyReady`] is triggered on that entity once they all
/// collide. Meshes that are [`Cloth`](crate::Cloth) are left out without being named.
///
/// ```
/// # use bevy::prelude::*;
/// # use bevy_bvh_cloth::prelude::*;
/// # fn setup(mut commands: Commands, mut meshes: ResMut<Assets<Mesh>>) {
/// commands
///     .spawn((
///         Transform::default(),
///         AutoCollider::new(8),
///         // The hair does not collide; the hands get a finer collider.
///         ColliderHierarchy::default().exclude("Hair").with("Hands", AutoCollider::new(16)),
///     ))
///     .with_children(|character| {
///         character.spawn((Name::new("Body"), Mesh3d(meshes.add(Capsule3d::new(0.2, 1.2)))));
///         character.spawn((Name::new("Hair"), Mesh3d(meshes.add(Sphere::new(0.15)))));
///         character.spawn((Name::new("Hands"), Mesh3d(meshes.add(Sphere::new(0.05)))));
///     });
/// # }
/// ```
#[derive(Component, Clone, Debug, Default, PartialEq, Reflect)]
#[reflect(Component, Default, Debug)]
pub struct ColliderHierarchy {
    /// By name: `None` leaves that mesh out, `Some` builds it with those settings instead of the
    /// root's.
    pub overrides: HashMap<String, Option<AutoCollider>>,
}

impl ColliderHierarchy {
    /// Leaves the mesh called `name` out.
    pub fn exclude(mut self, name: impl Into<String>) -> Self {
        self.overrides.insert(name.into(), None);
        self
    }

    /// Builds the mesh called `name` with `collider` instead of the root's settings.
    pub fn with(mut self, name: impl Into<String>, collider: AutoCollider) -> Self {
        self.overrides.insert(name.into(), Some(collider));
        self
    }
}

/// A mesh entity that no [`AutoCollider`] above it makes a collider of. Every
/// [`Cloth`](crate::Cloth) requires it, so that a cloth never collides with its own mesh; put it
/// on any other mesh a hierarchy should leave out whatever its name (it stays when the cloth is
/// removed).
#[derive(Component, Clone, Copy, Debug, Default, PartialEq, Eq, Reflect)]
#[reflect(Component, Default, Debug)]
pub struct ExcludeFromColliders;

/// A collider the plugin put on a mesh under a root's [`AutoCollider`]; it goes when the root's
/// collider does.
#[derive(Component, Clone, Copy, Debug, PartialEq, Eq, Reflect)]
#[reflect(Component, Debug)]
pub struct ColliderPart {
    /// The entity whose [`AutoCollider`] this collider comes from.
    pub root: Entity,
}

/// What a part carries, all removed together when it stops being one.
type PartComponents = (AutoCollider, ColliderPart, ClothCollider, ColliderStatus, ColliderBuild);

/// Gives every mesh under a mesh-less [`AutoCollider`] its collider (those marked
/// [`ExcludeFromColliders`] left out), keeps the
/// parts' settings in step with the root, removes parts whose root is gone, sums the parts'
/// statuses into the root's, and triggers [`ColliderHierarchyReady`] on the root when the sum
/// becomes ready (again after a rebuild).
#[allow(clippy::type_complexity)]
pub(crate) fn spread_colliders(
    mut commands: Commands,
    mut roots: Query<(Entity, &AutoCollider, Option<&ColliderHierarchy>, &mut ColliderStatus), Without<Mesh3d>>,
    descendants: Query<&Children>,
    meshes: Query<
        (
            Option<&Name>,
            Option<&ChildOf>,
            Option<&ColliderPart>,
            Option<&AutoCollider>,
            Has<PrimitiveCollider>,
            Has<ExcludeFromColliders>,
        ),
        With<Mesh3d>,
    >,
    parts: Query<(Entity, &ColliderPart, &ColliderStatus), With<Mesh3d>>,
    names: Query<&Name>,
    mut messages: MessageWriter<ClothMessage>,
) {
    // Parts whose root no longer has a mesh-less AutoCollider stop colliding.
    for (entity, part, _) in &parts {
        if !roots.contains(part.root) {
            commands.entity(entity).try_remove::<PartComponents>();
        }
    }
    for (root, auto, hierarchy, mut status) in &mut roots {
        let mut found_child = false;
        let mut found_mesh = false;
        for entity in descendants.iter_descendants(root) {
            found_child = true;
            let Ok((name, parent, part, existing, has_primitive, excluded)) = meshes.get(entity) else { continue };
            found_mesh = true;
            // A collider the user put there is theirs.
            let ours = part.is_some_and(|part| part.root == root);
            if (existing.is_some() && !ours) || has_primitive {
                continue;
            }
            // A cloth never collides with its own mesh.
            if excluded {
                if ours {
                    commands.entity(entity).try_remove::<PartComponents>();
                }
                continue;
            }
            let parent_name = parent.and_then(|parent| names.get(parent.parent()).ok());
            let setting = hierarchy.and_then(|hierarchy| {
                [name, parent_name].into_iter().flatten().find_map(|name| hierarchy.overrides.get(name.as_str()))
            });
            match setting {
                Some(None) => {
                    if ours {
                        commands.entity(entity).try_remove::<PartComponents>();
                    }
                }
                Some(Some(collider)) => set_part(&mut commands, entity, root, existing, collider),
                None => set_part(&mut commands, entity, root, existing, auto),
            }
        }
        let summed = sum_statuses(parts.iter().filter(|(_, part, _)| part.root == root).map(|(_, _, status)| status));
        let has_parts = summed.is_some();
        let next = match summed {
            Some(summed) => summed,
            None if found_mesh || !found_child => ColliderStatus::Waiting,
            None => ColliderStatus::Failed(ColliderFailure::NoMesh3d.to_string()),
        };
        if next != *status {
            if matches!(next, ColliderStatus::Failed(_)) && !has_parts {
                error!("AutoCollider on {root}: {}; it will not collide", ColliderFailure::NoMesh3d);
                messages.write(ClothMessage::ColliderFailed { entity: root, failure: ColliderFailure::NoMesh3d });
            }
            // Told when it becomes ready, not when a ready hierarchy gains or loses a part.
            if let ColliderStatus::Ready { spheres, .. } = next
                && !matches!(*status, ColliderStatus::Ready { .. })
            {
                let parts = parts
                    .iter()
                    .filter(|(_, part, status)| part.root == root && matches!(status, ColliderStatus::Ready { .. }));
                commands.trigger(ColliderHierarchyReady { entity: root, parts: parts.count() as u32, spheres });
            }
            *status = next;
        }
    }
}

fn set_part(
    commands: &mut Commands,
    entity: Entity,
    root: Entity,
    existing: Option<&AutoCollider>,
    wanted: &AutoCollider,
) {
    if existing != Some(wanted) {
        commands.entity(entity).try_insert((wanted.clone(), ColliderPart { root }));
    }
}

/// The root's status from its parts': ready with the sums when all are ready, else the first
/// that is not; `None` without parts.
fn sum_statuses<'a>(statuses: impl Iterator<Item = &'a ColliderStatus>) -> Option<ColliderStatus> {
    let mut sum: Option<(u32, u32)> = None;
    let mut pending: Option<ColliderStatus> = None;
    for status in statuses {
        match status {
            ColliderStatus::Ready { spheres, inner_nodes } => {
                let (s, n) = sum.get_or_insert((0, 0));
                *s += spheres;
                *n += inner_nodes;
            }
            // A failed part says so itself; the others still collide.
            ColliderStatus::Failed(_) => {
                sum.get_or_insert((0, 0));
            }
            other => pending = Some(other.clone()),
        }
    }
    pending.or(sum.map(|(spheres, inner_nodes)| ColliderStatus::Ready { spheres, inner_nodes }))
}
