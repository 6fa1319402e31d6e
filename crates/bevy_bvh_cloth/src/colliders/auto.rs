//! `AutoCollider`: any mesh becomes a voxel-sphere LBVH collider (paper sections 2.4.1–2.4.2).
//!
//! When the entity's mesh asset is available, [`build_colliders`] copies its triangles and
//! builds the collider: inline for small meshes, on the [`AsyncComputeTaskPool`] for big ones so
//! that no frame hitches. Until a new build is done the previous collider (if any) keeps working.
//! The collider follows the entity's [`GlobalTransform`] every frame without a rebuild; changing
//! the resolution `n`, the [`Mesh3d`] or the mesh asset rebuilds it. On an entity with a
//! [`SkinnedMesh`] the spheres follow the joints instead, refitted every frame in
//! [`update_collider_poses`](crate::colliders::pose::update_collider_poses) (see
//! `bvh_cloth_core::colliders::skinning`).

use std::collections::HashSet;

use bevy::asset::LoadState;
use bevy::ecs::system::SystemParam;
use bevy::mesh::Indices;
use bevy::mesh::skinning::{SkinnedMesh, SkinnedMeshInverseBindposes};
use bevy::prelude::*;
use bevy::tasks::{AsyncComputeTaskPool, Task, block_on, poll_once};
use bvh_cloth_core::backend::largest_scale;
use bvh_cloth_core::{Affine3A, Collider, CollisionLayers, SkinScratch, Voxels};

use crate::colliders::mesh::TriangleList;
use crate::events::ColliderReady;
use crate::messages::ClothMessage;
use crate::messages::ColliderFailure;

/// Meshes with at least this many vertices are voxelised on the async compute pool.
pub const ASYNC_BUILD_MIN_VERTICES: usize = 20_000;

/// Makes the entity's [`Mesh3d`] a collider for every cloth; on an entity without a `Mesh3d`
/// (a glTF scene root, a character), every mesh under it, each with its own collider (see
/// [`ColliderHierarchy`](crate::ColliderHierarchy) for exclusions and overrides by name).
///
/// By default the cloth collides with the mesh's own triangles ([`ColliderContact::Exact`]),
/// held [`Self::margin`] off them, and no particle's path crosses a triangle (see
/// `bvh_cloth_core::colliders::exact_contact`). The mesh is also cut into `resolution³` voxels over its
/// bounding box; every voxel the surface passes through gets a sphere around the part of the
/// surface in it, and the spheres are arranged in a Morton-code LBVH. With
/// [`ColliderContact::Spheres`] (the paper's method) the cloth collides with those spheres:
/// every sphere reaches a little past the surface part it holds, so they form a closed shell,
/// and the response tests each particle's whole path, so a cloth that starts outside a still
/// collider never crosses it, at any resolution (see `bvh_cloth_core::colliders::collision`). The
/// collider follows the entity's transform (rotation, translation and uniform scale; with a
/// non-uniform scale the largest axis is used, and a warning says so).
///
/// On an entity with a [`SkinnedMesh`] (an animated character's body, as glTF loads it) the
/// collider follows the joints instead: every frame each sphere is fitted again around its part
/// of the skinned surface, so the spheres cover the body in whatever pose the animation puts it
/// (see `bvh_cloth_core::colliders::skinning`). The mesh needs joint indices and weights, every weighted
/// joint must exist, and the collider waits for the skin's inverse bind poses to load. If a
/// joint entity is despawned, the collider stays where the last complete pose put it and a
/// warning names the joint.
#[derive(Component, Clone, Debug, PartialEq, Reflect)]
#[reflect(Component, Default, Debug)]
#[require(Transform, ColliderStatus, ColliderBuild)]
pub struct AutoCollider {
    /// Voxels per axis, `n` in the paper (which uses 1, 3 and 5). Higher is tighter and costs
    /// more memory; between 1 and [`bvh_cloth_core::backend::MAX_RESOLUTION`]. Unused
    /// when [`Self::voxel_size`] is set.
    pub resolution: u32,
    /// The voxels' side in world units (metres), instead of a count per axis: each axis of the
    /// mesh's box gets as many voxels as that size needs, so every mesh built with one size
    /// (all those under one root, say) has voxels of that size, whatever its extent. The
    /// entity's scale when the collider is built converts it to the mesh's units; a size that
    /// would make more than `128³` voxels fails the collider with a clear error.
    pub voxel_size: Option<f32>,
    /// The cloth's thickness against this collider, in world units: how far off the triangles
    /// (or beyond the spheres) it is held, so that it rests a little above the surface instead
    /// of on it.
    pub margin: f32,
    /// Coulomb friction coefficient of the surface. The default, 1.0 (a rough surface), holds a
    /// resting cloth on slopes up to 45°, which keeps a cloth dropped on the bunny or the dragon
    /// draped over it instead of sliding off one side. 0 is the paper's response, which keeps
    /// the whole tangential velocity: that is the paper's model, not a fault, but such a cloth
    /// slides off any rounded collider within a few seconds.
    pub friction: f32,
    /// What the cloth collides with: the mesh's own triangles (the default) or the paper's
    /// voxel spheres. See [`ColliderContact`].
    pub contact: ColliderContact,
    /// Which cloths collide with it: those whose [`ClothParams::layers`](crate::ClothParams::layers)
    /// and these meet ([`CollisionLayers::interacts_with`]). The default meets every cloth.
    /// Changing it takes effect at once, without a rebuild.
    pub layers: CollisionLayers,
}

impl Default for AutoCollider {
    fn default() -> Self {
        Self {
            resolution: 5,
            voxel_size: None,
            margin: 0.01,
            friction: 1.0,
            contact: ColliderContact::default(),
            layers: CollisionLayers::DEFAULT,
        }
    }
}

/// What a mesh collider's surface is to the cloth.
///
/// The default is [`Self::Exact`]: a user who drapes a cloth over a model expects it to rest on
/// the model, not on a shell of spheres that stands off it (at the paper's `n = 5` the spheres
/// hold a resting cloth 80 to 96 mm off the bundled models; exact contact holds it at the
/// margin, 0.3 mm beyond it on average; see BENCHMARKS.md). It costs a second tree, over the
/// mesh's triangles, built with the collider (about 1.5x to 1.9x the build time on the bundled
/// models), and on the GPU a collision stage that walks triangles instead of spheres.
/// [`Self::Spheres`] is the paper's method: cheaper to build and to query at low `n`, and
/// looser.
///
/// A skinned mesh's collider always uses spheres: its triangles move with the joints.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Reflect)]
#[reflect(Default, Debug)]
pub enum ColliderContact {
    /// The cloth collides with the mesh's triangles, held the margin off them; the voxel
    /// spheres only serve the debug view and the collider's outline.
    #[default]
    Exact,
    /// The paper's contact: the cloth collides with the voxel spheres.
    Spheres,
}

impl AutoCollider {
    /// A collider with `resolution³` voxels and the default margin.
    pub fn new(resolution: u32) -> Self {
        Self { resolution, ..default() }
    }

    /// A collider with cubic voxels of `size` world units (metres) and the default margin.
    pub fn from_voxel_size(size: f32) -> Self {
        Self::default().with_voxel_size(size)
    }

    /// The same collider with cubic voxels of `size` world units (metres) instead of a count
    /// per axis: `AutoCollider::new(8).with_voxel_size(0.04)`.
    pub fn with_voxel_size(mut self, size: f32) -> Self {
        self.voxel_size = Some(size);
        self
    }

    /// The same collider with `margin` world units between its surface and the cloth.
    pub fn with_margin(mut self, margin: f32) -> Self {
        self.margin = margin;
        self
    }

    /// The same collider with Coulomb friction `friction` (0 slides freely, 1 holds on 45°).
    pub fn with_friction(mut self, friction: f32) -> Self {
        self.friction = friction;
        self
    }

    /// The same collider on `layers`: only the cloths whose layers meet these collide with it.
    ///
    /// ```
    /// # use bevy::prelude::*;
    /// # use bevy_bvh_cloth::prelude::*;
    /// const BODY: u32 = 1 << 1;
    /// const CAPE: u32 = 1 << 2;
    /// # fn setup(mut commands: Commands) {
    /// // The body is on its own layer and meets every cloth but a cape that leaves it out.
    /// commands.spawn(AutoCollider::new(8).with_layers(CollisionLayers::new(BODY, CollisionLayers::ALL)));
    /// commands.spawn(Cloth::grid(Vec2::ONE, UVec2::splat(16)).with_layers(CollisionLayers::new(CAPE, !BODY)));
    /// # }
    /// ```
    pub fn with_layers(mut self, layers: CollisionLayers) -> Self {
        self.layers = layers;
        self
    }

    /// The same collider with `contact`: the mesh's triangles or the voxel spheres.
    pub fn with_contact(mut self, contact: ColliderContact) -> Self {
        self.contact = contact;
        self
    }

    /// The voxels to build with, in the mesh's units, for an entity whose world scale is
    /// `scale` (its largest axis).
    fn voxels(&self, scale: f32) -> Voxels {
        match self.voxel_size {
            Some(size) => Voxels::Size(size / scale),
            None => Voxels::PerAxis(self.resolution),
        }
    }
}

/// Where an [`AutoCollider`] stands. Added with the collider.
#[derive(Component, Clone, Debug, Default, PartialEq, Reflect)]
#[reflect(Component, Default, Debug)]
pub enum ColliderStatus {
    /// The mesh asset is not loaded yet; or the entity has no [`Mesh3d`] and no children yet
    /// (a scene root before its scene has spawned; see [`ColliderHierarchy`](crate::ColliderHierarchy)).
    #[default]
    Waiting,
    /// A build is running on the async compute pool.
    Building,
    /// The collider is built and active.
    Ready {
        /// Leaf spheres (non-empty voxels).
        spheres: u32,
        /// Inner AABB nodes (`spheres - 1`).
        inner_nodes: u32,
    },
    /// The mesh cannot become a collider; the message says why. Fixing the mesh, the
    /// [`Mesh3d`] or the resolution retries. On an entity without a mesh, the meshes under it
    /// that failed say so on their own entities; the root is `Ready` with the others.
    Failed(String),
}

impl ColliderStatus {
    pub(crate) fn ready(collider: &Collider) -> Self {
        let inner_nodes = collider.lbvh().map_or(0, |lbvh| lbvh.nodes.len());
        Self::Ready { spheres: collider.sphere_count() as u32, inner_nodes: inner_nodes as u32 }
    }
}

/// The built collider of an [`AutoCollider`] or [`PrimitiveCollider`](crate::PrimitiveCollider)
/// entity, with its current pose.
#[derive(Component, Clone, Debug)]
pub struct ClothCollider {
    pub(crate) collider: Collider,
    pub(crate) warned_non_uniform: bool,
    /// A skinned collider's refit memory, and whether it has been posed by its joints yet.
    pub(crate) skin_scratch: SkinScratch,
    pub(crate) skin_posed: bool,
    /// A skinned collider's pose problem, said once until it clears.
    pub(crate) skin_warning: Option<String>,
    /// A skinned collider's last accepted joint matrices and the clearance they give, when the
    /// render world refits it on the GPU instead of this copy being refitted.
    pub(crate) gpu_skin_pose: Option<(Vec<Affine3A>, f32)>,
}

impl ClothCollider {
    pub(crate) fn new(collider: Collider) -> Self {
        Self {
            collider,
            warned_non_uniform: false,
            skin_scratch: SkinScratch::default(),
            skin_posed: false,
            skin_warning: None,
            gpu_skin_pose: None,
        }
    }

    /// The collider: its shape (a sphere tree in the mesh's local frame, or a primitive), its
    /// margin and its pose.
    ///
    /// A skinned collider's spheres follow its joints. On the GPU backend the render world
    /// refits them on the GPU, and this copy is refitted as well only while
    /// [`ClothSettings::debug_view`](crate::ClothSettings::debug_view) draws it; otherwise it
    /// keeps the spheres of its bind pose (or of the last pose it was refitted to).
    pub fn collider(&self) -> &Collider {
        &self.collider
    }

    /// A skinned collider's joint matrices and clearance for a refit on the GPU.
    pub(crate) fn gpu_skin_pose(&self) -> Option<&(Vec<Affine3A>, f32)> {
        self.gpu_skin_pose.as_ref()
    }
}

/// What a build was (or is being) made from. The entity's scale, which converts a voxel size to
/// the mesh's units, is not part of it: an animated scale does not rebuild the collider.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct BuildKey {
    mesh: AssetId<Mesh>,
    resolution: u32,
    /// The voxel size's bits.
    voxel_size: Option<u32>,
    /// A skinned mesh's joint count.
    joints: Option<usize>,
    contact: ColliderContact,
}

/// Per-entity build bookkeeping.
#[derive(Component, Default)]
pub(crate) struct ColliderBuild {
    /// The key of the last build that finished (successfully or not).
    done: Option<BuildKey>,
    /// A build in flight.
    pending: Option<(BuildKey, Task<Result<Collider, ColliderFailure>>)>,
    /// What the last build's mesh held (see [`fingerprint`]).
    fingerprint: Option<u64>,
}

/// A hash of what a collider is built from in `mesh`: its positions, indices, joint indices
/// and weights, bit for bit.
fn fingerprint(mesh: &Mesh) -> u64 {
    use std::hash::{Hash, Hasher};
    let mut hasher = std::collections::hash_map::DefaultHasher::new();
    for attribute in [Mesh::ATTRIBUTE_POSITION, Mesh::ATTRIBUTE_JOINT_INDEX, Mesh::ATTRIBUTE_JOINT_WEIGHT] {
        if let Some(values) = mesh.attribute(attribute) {
            values.get_bytes().hash(&mut hasher);
        }
    }
    match mesh.indices() {
        Some(Indices::U16(indices)) => indices.hash(&mut hasher),
        Some(Indices::U32(indices)) => indices.hash(&mut hasher),
        None => 0u8.hash(&mut hasher),
    }
    mesh.primitive_topology().hash(&mut hasher);
    hasher.finish()
}

/// Starts, polls and finishes collider builds; reports failures.
#[allow(clippy::type_complexity)]
pub(crate) fn build_colliders(
    mut commands: Commands,
    meshes: Res<Assets<Mesh>>,
    asset_server: Option<Res<AssetServer>>,
    mut mesh_events: MessageReader<AssetEvent<Mesh>>,
    mut colliders: Query<(
        Entity,
        &AutoCollider,
        Option<&Mesh3d>,
        Option<&GlobalTransform>,
        Option<&SkinnedMesh>,
        &mut ColliderBuild,
        &mut ColliderStatus,
    )>,
    skins: Skins,
    mut messages: MessageWriter<ClothMessage>,
) {
    let modified: HashSet<AssetId<Mesh>> = mesh_events
        .read()
        .filter_map(|event| match event {
            AssetEvent::Modified { id } => Some(*id),
            _ => None,
        })
        .collect();
    let load_failure = |id: AssetId<Mesh>| match asset_server.as_ref().map(|server| server.load_state(id)) {
        Some(LoadState::Failed(error)) => Some(error.to_string()),
        _ => None,
    };
    for (entity, auto, mesh3d, transform, skinned, mut build, mut status) in &mut colliders {
        let outcome = match mesh3d {
            // An AutoCollider without a mesh covers the meshes under it (collider_hierarchy).
            None => continue,
            Some(mesh3d) => {
                // A skinned mesh waits for its inverse bind poses: they give its joint count.
                let skin = match skinned.map(|skinned| skins.pose(skinned)) {
                    None => None,
                    Some(Some(pose)) => Some(pose),
                    Some(None) => {
                        *status = ColliderStatus::Waiting;
                        continue;
                    }
                };
                // A bad scale is reported where the pose is read (update_collider_poses). A
                // skinned mesh is placed by its joints, so their scale converts a voxel size.
                let scale = match &skin {
                    Some(skin) => skin.scale(),
                    None => transform.map_or(1.0, |t| t.scale().max_element()),
                };
                let scale = if scale.is_finite() && scale > 0.0 { scale } else { 1.0 };
                let key = BuildKey {
                    mesh: mesh3d.id(),
                    resolution: auto.resolution,
                    voxel_size: auto.voxel_size.map(f32::to_bits),
                    joints: skin.as_ref().map(SkinPose::joint_count),
                    contact: auto.contact,
                };
                let voxels = auto.voxels(scale);
                match advance_build(&mut build, key, voxels, &meshes, modified.contains(&key.mesh), load_failure) {
                    Progress::Done(result) => result,
                    Progress::Idle => continue,
                    Progress::Waiting => {
                        *status = ColliderStatus::Waiting;
                        continue;
                    }
                    Progress::Building => {
                        *status = ColliderStatus::Building;
                        continue;
                    }
                }
            }
        };
        settle(&mut commands, &mut messages, entity, "AutoCollider", &mut status, outcome);
    }
}

/// Applies a finished build of `entity`'s collider (a `kind` component): on success the
/// collider goes in, the status says ready and [`ColliderReady`] is triggered; on failure the
/// old collider goes, the status says why, and the failure is logged and sent.
pub(crate) fn settle(
    commands: &mut Commands,
    messages: &mut MessageWriter<ClothMessage>,
    entity: Entity,
    kind: &str,
    status: &mut ColliderStatus,
    outcome: Result<Collider, ColliderFailure>,
) {
    match outcome {
        Ok(collider) => {
            *status = ColliderStatus::ready(&collider);
            let spheres = collider.sphere_count() as u32;
            // Inserted first, so that an observer of the event finds the collider.
            commands.entity(entity).try_insert(ClothCollider::new(collider));
            commands.trigger(ColliderReady { entity, spheres });
        }
        Err(failure) => {
            error!("{kind} on {entity}: {failure}; it will not collide");
            *status = ColliderStatus::Failed(failure.to_string());
            messages.write(ClothMessage::ColliderFailed { entity, failure });
            commands.entity(entity).try_remove::<ClothCollider>();
        }
    }
}

/// Where one entity's build is after [`advance_build`].
enum Progress {
    /// Nothing to do: the collider is up to date.
    Idle,
    /// The mesh asset is not available yet.
    Waiting,
    /// A build is running on the async pool.
    Building,
    /// A build finished (or could not start) this frame.
    Done(Result<Collider, ColliderFailure>),
}

/// Moves one entity's build forward: finishes a task, or starts a build into `voxels` when the
/// collider is out of date with `key` (or its mesh asset was `modified`).
fn advance_build(
    build: &mut ColliderBuild,
    key: BuildKey,
    voxels: Voxels,
    meshes: &Assets<Mesh>,
    modified: bool,
    load_failure: impl Fn(AssetId<Mesh>) -> Option<String>,
) -> Progress {
    // Finish a build in flight, or drop it when what it was built from has changed.
    if let Some((pending_key, task)) = &mut build.pending {
        if *pending_key == key {
            return match block_on(poll_once(task)) {
                Some(result) => {
                    build.pending = None;
                    build.done = Some(key);
                    Progress::Done(result)
                }
                None => Progress::Building,
            };
        }
        build.pending = None;
    }
    if build.done == Some(key) && !modified {
        return Progress::Idle;
    }
    // A mesh can be reported modified with its triangles unchanged (a glTF mesh is, right after
    // it loads): that is no reason to build again, and tell the entity twice that it is ready.
    let fingerprint = meshes.get(key.mesh).map(fingerprint);
    if build.done == Some(key) && fingerprint.is_some() && fingerprint == build.fingerprint {
        return Progress::Idle;
    }
    build.fingerprint = fingerprint;
    let Some(mesh) = meshes.get(key.mesh) else {
        return match load_failure(key.mesh) {
            Some(reason) => {
                build.done = Some(key);
                Progress::Done(Err(ColliderFailure::LoadFailed(reason)))
            }
            None => Progress::Waiting,
        };
    };
    let triangles = match TriangleList::from_mesh(mesh).and_then(|list| match key.joints {
        Some(joints) => list.with_skin(mesh, joints),
        None => Ok(list),
    }) {
        Ok(triangles) => triangles,
        Err(failure) => {
            build.done = Some(key);
            return Progress::Done(Err(failure));
        }
    };
    let big = triangles.len() >= ASYNC_BUILD_MIN_VERTICES;
    let exact = key.contact == ColliderContact::Exact;
    let job = move || triangles.build(voxels, exact);
    if big {
        build.pending = Some((key, AsyncComputeTaskPool::get().spawn(async move { job() })));
        Progress::Building
    } else {
        build.done = Some(key);
        Progress::Done(job())
    }
}

/// What a skinned collider reads of the world: the skins' inverse bind poses and the joints'
/// transforms.
#[derive(SystemParam)]
pub(crate) struct Skins<'w, 's> {
    bindposes: Res<'w, Assets<SkinnedMeshInverseBindposes>>,
    transforms: Query<'w, 's, &'static GlobalTransform>,
}

impl<'w, 's> Skins<'w, 's> {
    /// The joints of `skinned` as this frame places them; `None` while its inverse bind poses
    /// are not loaded.
    pub(crate) fn pose<'a>(&'a self, skinned: &'a SkinnedMesh) -> Option<SkinPose<'a, 'w, 's>> {
        let inverse = self.bindposes.get(&skinned.inverse_bindposes)?;
        Some(SkinPose { skinned, inverse, transforms: &self.transforms })
    }
}

/// A skinned mesh's joints as this frame places them.
pub(crate) struct SkinPose<'a, 'w, 's> {
    skinned: &'a SkinnedMesh,
    inverse: &'a SkinnedMeshInverseBindposes,
    transforms: &'a Query<'w, 's, &'static GlobalTransform>,
}

impl SkinPose<'_, '_, '_> {
    /// Joint matrices the skin has: Bevy's renderer pairs joints and inverse bind poses.
    pub(crate) fn joint_count(&self) -> usize {
        self.skinned.joints.len().min(self.inverse.len())
    }

    /// Each joint's world transform times its inverse bind pose, as the renderer forms them;
    /// or the first joint that has no transform (despawned), and its entity.
    pub(crate) fn matrices(&self, out: &mut Vec<Affine3A>) -> Result<(), (usize, Entity)> {
        out.clear();
        for (k, (&joint, inverse)) in self.skinned.joints.iter().zip(self.inverse.iter()).enumerate() {
            let transform = self.transforms.get(joint).map_err(|_| (k, joint))?;
            out.push(transform.affine() * Affine3A::from_mat4(*inverse));
        }
        Ok(())
    }

    /// The largest scale the first joint gives the bind-pose mesh (1 without a placed joint).
    pub(crate) fn scale(&self) -> f32 {
        let first = self.skinned.joints.first().zip(self.inverse.first());
        first
            .and_then(|(&joint, inverse)| {
                Some(self.transforms.get(joint).ok()?.affine() * Affine3A::from_mat4(*inverse))
            })
            .map_or(1.0, |transform| largest_scale(&transform))
    }
}
