//! Cloth for a scene's meshes by name, the counterpart of
//! [`ColliderHierarchy`](crate::ColliderHierarchy): on a scene root (a glTF `WorldAssetRoot`, a
//! character's root), [`ClothHierarchy`] names the meshes that become cloth, with their
//! parameters, their pins, and the joints that carry them. Each mesh becomes a [`Cloth`] as
//! soon as the scene has spawned it, on every instance of the scene; the root hears
//! [`ClothHierarchyReady`] once every named cloth is built.

use bevy::platform::collections::{HashMap, HashSet};
use bevy::prelude::*;
use bvh_cloth_core::ClothPins;

use crate::cloth::component::{Cloth, ClothAnchor, ClothPart, ClothShape};
use crate::cloth::simulation::ClothSimulation;
use crate::events::ClothHierarchyReady;
use crate::messages::ClothMessage;
use crate::settings::ClothSettings;

/// Which meshes under this entity become cloth, by the [`Name`] of the mesh entity or, failing
/// that, of its parent (glTF names the node, and its primitives are children of it).
///
/// Put it on the scene's root with the [`AutoCollider`](crate::AutoCollider) that makes the
/// body collide: the meshes named here are left out of the body's collider (every cloth is),
/// and become cloth as the scene spawns them. A skinned mesh (a garment bound to the body's
/// joints, as Blender and Mixamo export them) keeps its skin for its pins: they go where the
/// skin draws them, and the rest is simulated ([`ClothSkin`](crate::ClothSkin)). A joint named
/// in an anchor is looked up among the root's descendants by its `Name`. A name that the spawned
/// scene does not have is reported once as [`ClothMessage::NameNotFound`] on the root, and the
/// cloth that needs it is not made; the rest of the scene runs.
///
/// ```
/// # use bevy::prelude::*;
/// # use bevy_bvh_cloth::prelude::*;
/// # fn setup(mut commands: Commands) {
/// let sewn = ClothPins::Painted { channel: ColorChannel::Red, threshold: 0.5 };
/// commands.spawn((
///     Transform::default(),
///     AutoCollider::new(8),
///     ClothHierarchy::default()
///         // The skinned cape, painted red where it is sewn on, follows its skin there.
///         .with("Cape", SceneCloth::default().pinned(sewn.clone()))
///         // A banner that has no skin rides on the spine joint where it is painted.
///         .with("Banner", SceneCloth::default().anchored(sewn, "Spine")),
/// ));
/// # }
/// ```
#[derive(Component, Clone, Debug, Default, PartialEq, Reflect)]
#[reflect(Component, Default, Debug)]
pub struct ClothHierarchy {
    /// By mesh name, what it becomes.
    pub cloths: HashMap<String, SceneCloth>,
}

impl ClothHierarchy {
    /// Makes the mesh called `name` cloth as `cloth` says.
    pub fn with(mut self, name: impl Into<String>, cloth: SceneCloth) -> Self {
        self.cloths.insert(name.into(), cloth);
        self
    }
}

/// One mesh of a [`ClothHierarchy`]: the [`Cloth`] it becomes, built as any other (its shape
/// is always the mesh's own), and the anchors that name the scene's joints carrying it.
#[derive(Clone, Debug, PartialEq, Reflect)]
#[reflect(Default, Debug, PartialEq)]
pub struct SceneCloth {
    /// The cloth: its parameters, its pins, its anchors to entities outside the scene and
    /// `start_at_once`. Its `shape` is replaced by [`ClothShape::Mesh`].
    pub cloth: Cloth,
    /// Groups of particles carried by the scene's joints.
    pub anchors: Vec<JointAnchor>,
}

impl Default for SceneCloth {
    fn default() -> Self {
        Self::new(Cloth::mesh())
    }
}

impl SceneCloth {
    /// The mesh as `cloth` (for example `Cloth::mesh().with_params(..)`).
    pub fn new(cloth: Cloth) -> Self {
        Self { cloth, anchors: Vec::new() }
    }

    /// The same cloth with `pins` held: by the skin where the mesh is skinned, otherwise by the
    /// mesh's entity (see [`Cloth::pins`]).
    pub fn pinned(mut self, pins: ClothPins) -> Self {
        self.cloth.pins = pins;
        self
    }

    /// The same cloth with `pins` carried by the joint called `joint`.
    pub fn anchored(mut self, pins: ClothPins, joint: impl Into<String>) -> Self {
        self.anchors.push(JointAnchor { pins, joint: joint.into(), offset: Vec3::ZERO });
        self
    }

    /// The [`Cloth`] of this mesh with the joints resolved to `targets`, in anchor order.
    fn to_cloth(&self, targets: &[Entity]) -> Cloth {
        let joints = self
            .anchors
            .iter()
            .zip(targets)
            .map(|(anchor, &target)| ClothAnchor::new(anchor.pins.clone(), target).with_offset(anchor.offset));
        Cloth {
            shape: ClothShape::Mesh,
            anchors: self.cloth.anchors.iter().cloned().chain(joints).collect(),
            ..self.cloth.clone()
        }
    }
}

/// A [`ClothAnchor`] whose target is a joint of the scene, by name.
#[derive(Clone, Debug, PartialEq, Reflect)]
#[reflect(Debug, PartialEq)]
pub struct JointAnchor {
    /// The particles the joint carries.
    pub pins: ClothPins,
    /// The [`Name`] of the joint's entity.
    pub joint: String,
    /// As [`ClothAnchor::offset`].
    pub offset: Vec3,
}

/// What a root has been told: the names reported missing, whether it heard that its cloths
/// are built, and since when it has waited for its scene (and whether it was told it waited
/// too long).
#[derive(Component, Clone, Debug, Default)]
pub(crate) struct HierarchyReports {
    missing: HashSet<String>,
    ready: bool,
    waiting_since: Option<f64>,
    told_waiting: bool,
}

/// A scene's mesh entities: their parent, whether a hierarchy made them cloth, whether they are
/// cloth, and whether that cloth is built.
type SceneMeshes<'w, 's> = Query<
    'w,
    's,
    (Option<&'static ChildOf>, Option<&'static ClothPart>, Has<Cloth>, Has<ClothSimulation>),
    With<Mesh3d>,
>;

/// Makes cloth of the meshes each [`ClothHierarchy`] names once the scene has spawned them,
/// reports names it does not have, and tells the root when every named cloth is built.
#[allow(clippy::too_many_arguments)]
pub(crate) fn spread_cloths(
    mut commands: Commands,
    mut roots: Query<(Entity, &ClothHierarchy, Option<&mut HierarchyReports>)>,
    descendants: Query<&Children>,
    names: Query<&Name>,
    meshes: SceneMeshes,
    mut messages: MessageWriter<ClothMessage>,
    time: Res<Time>,
    settings: Res<ClothSettings>,
) {
    let now = time.elapsed_secs_f64();
    for (root, hierarchy, kept) in &mut roots {
        // A new root's reports are kept from its first frame on.
        let mut created = None;
        let reports: &mut HierarchyReports = match kept {
            Some(kept) => kept.into_inner(),
            None => created.insert(HierarchyReports::default()),
        };
        // The scene's named entities, and its meshes by their own name or their parent's.
        let mut named: HashMap<&str, Entity> = HashMap::default();
        let mut by_name: HashMap<&str, Vec<Entity>> = HashMap::default();
        let mut any_mesh = false;
        for entity in descendants.iter_descendants(root) {
            let own = names.get(entity).ok();
            if let Some(name) = own {
                named.entry(name.as_str()).or_insert(entity);
            }
            let Ok((parent, _, _, _)) = meshes.get(entity) else { continue };
            any_mesh = true;
            // Listed once under a name, also where the mesh and its node share it.
            let parent_name = parent.and_then(|parent| names.get(parent.parent()).ok()).filter(|&p| Some(p) != own);
            for name in [own, parent_name].into_iter().flatten() {
                by_name.entry(name.as_str()).or_default().push(entity);
            }
        }
        // Nothing spawned yet: a scene still loading, or one that never will.
        if any_mesh {
            spread(&mut commands, &mut messages, root, hierarchy, reports, &named, &by_name, &meshes);
        } else {
            let waited = (now - *reports.waiting_since.get_or_insert(now)) as f32;
            if waited >= settings.scene_wait && !reports.told_waiting {
                reports.told_waiting = true;
                warn!(
                    "ClothHierarchy on {root}: no mesh under it after {waited:.1} s; its scene failed to load (the \
                     asset server logs why, with the path), is still loading, or was never given. It keeps waiting"
                );
                messages.write(ClothMessage::SceneNotSpawned { entity: root, waited });
            }
        }
        if let Some(created) = created {
            commands.entity(root).try_insert(created);
        }
    }
}

/// Makes cloth of the meshes of `root`'s spawned scene that `hierarchy` names (`by_name`, the
/// scene's meshes by their own name or their parent's; `named`, its entities by name), and
/// tells the root when they are all built.
#[allow(clippy::too_many_arguments)]
fn spread(
    commands: &mut Commands,
    messages: &mut MessageWriter<ClothMessage>,
    root: Entity,
    hierarchy: &ClothHierarchy,
    reports: &mut HierarchyReports,
    named: &HashMap<&str, Entity>,
    by_name: &HashMap<&str, Vec<Entity>>,
    meshes: &SceneMeshes,
) {
    let (mut wanted, mut built) = (0, 0);
    for (name, scene_cloth) in &hierarchy.cloths {
        let Some(entities) = by_name.get(name.as_str()) else {
            report_missing(reports, messages, root, name);
            continue;
        };
        let targets: Vec<Option<Entity>> =
            scene_cloth.anchors.iter().map(|anchor| named.get(anchor.joint.as_str()).copied()).collect();
        if let Some(missing) = scene_cloth.anchors.iter().zip(&targets).find(|(_, t)| t.is_none()) {
            report_missing(reports, messages, root, &missing.0.joint);
            continue;
        }
        let targets: Vec<Entity> = targets.into_iter().flatten().collect();
        for &entity in entities {
            let Ok((_, part, is_cloth, is_built)) = meshes.get(entity) else { continue };
            // A cloth the user put there is theirs.
            if is_cloth && part.is_none_or(|part| part.root != root) {
                continue;
            }
            wanted += 1;
            built += usize::from(is_built);
            if !is_cloth {
                commands.entity(entity).try_insert((scene_cloth.to_cloth(&targets), ClothPart { root }));
            }
        }
    }
    if wanted > 0 && built == wanted && !reports.ready {
        reports.ready = true;
        commands.trigger(ClothHierarchyReady { entity: root, cloths: built as u32 });
    }
}

/// Says once per root and name that the spawned scene has no entity called `name`.
fn report_missing(
    reports: &mut HierarchyReports,
    messages: &mut MessageWriter<ClothMessage>,
    root: Entity,
    name: &str,
) {
    if reports.missing.insert(name.to_string()) {
        warn!(
            "ClothHierarchy on {root}: the scene has no mesh or joint called \"{name}\"; the cloth that needs it is not made"
        );
        messages.write(ClothMessage::NameNotFound { entity: root, name: name.to_string() });
    }
}
