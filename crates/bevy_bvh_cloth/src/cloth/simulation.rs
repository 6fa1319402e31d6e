//! A cloth's simulation state, kept in step with its [`Cloth`] component.

use std::sync::atomic::{AtomicU64, Ordering};

use std::sync::Arc;

use bevy::camera::visibility::NoAutoAabb;
use bevy::ecs::entity::{EntityHashMap, EntityHashSet};
use bevy::ecs::system::SystemParam;
use bevy::mesh::skinning::{SkinnedMesh, SkinnedMeshInverseBindposes};
use bevy::prelude::*;
use bvh_cloth_core::{Affine3A, ClothError, ClothGrid, ClothSim, ClothTopology, MeshVertices, Vec3};

use crate::clock::ClothClock;
use crate::cloth::component::{Cloth, ClothPart, ClothShape};
use crate::cloth::mesh::{authored_topology, authored_vertices, new_authored_mesh, new_grid_mesh};
use crate::cloth::skin::{ClothSkin, SkinBinding};
use crate::colliders::auto::{AutoCollider, ColliderStatus};
use crate::messages::{ClothMessage, ResetCloth};
use crate::settings::ClothSettings;

/// The running simulation of a [`Cloth`] entity, added by the plugin.
///
/// Particle positions are in world space. The entity's [`Mesh3d`] shows them in the entity's
/// local frame, each vertex at its particle ([`ClothTopology::vertex_particle`]). On the CPU
/// backend this is the live state. On the GPU backend the live state stays on the GPU: with
/// [`ClothReadback`](crate::ClothReadback) on the entity this is read back two or three frames
/// late, without stalling; without it, this holds the state as of the last rebuild or reset.
///
/// ```
/// # use bevy::prelude::*;
/// # use bevy_bvh_cloth::prelude::*;
/// // How fast each cloth's centre of mass moves, for gameplay (a flag's flapping, a sail's pull).
/// fn report(cloths: Query<(Entity, &ClothSimulation)>) {
///     for (entity, cloth) in &cloths {
///         let sim = cloth.sim();
///         let mean = sim.velocities().iter().sum::<Vec3>() / sim.len().max(1) as f32;
///         info!("{entity}: {} particles, centre of mass moving at {mean}", sim.len());
///     }
/// }
/// ```
///
/// [`ClothTopology::vertex_particle`]: bvh_cloth_core::ClothTopology::vertex_particle
#[derive(Component, Debug)]
pub struct ClothSimulation {
    pub(crate) sim: ClothSim,
    /// The component the grid was built from: a change of shape rebuilds.
    built_from: Cloth,
    /// The entity's rigid pose at the end of the last tick; pins move on from here.
    pub(crate) pose: Affine3A,
    /// The mesh the cloth draws (its own: generated, or a copy of the authored one).
    pub(crate) mesh: Handle<Mesh>,
    /// The authored mesh a [`ClothShape::Mesh`] cloth was built from, kept for rebuilds.
    source: Option<Handle<Mesh>>,
    /// The pinned particles the entity itself holds (those no anchor claims).
    own_pins: Vec<u32>,
    /// The groups other entities hold, one per [`Cloth::anchors`] entry.
    anchors: Vec<AnchorBinding>,
    /// The skin that holds the pins of a skinned mesh (instead of the entity).
    skin: Option<SkinBinding>,
    /// Where the pins go in each tick of this frame (`(particle, world position)` per pin), from
    /// their holders' poses at the end of last frame to this frame's: see [`plan_anchors`].
    pub(crate) anchor_targets: Vec<Vec<(u32, Vec3)>>,
    /// Positions changed since the mesh was last written.
    pub(crate) dirty: bool,
    /// The `(looper, substeps)` the stability guard last warned about: it says so again only
    /// when that changes, not whenever some other parameter (an External Force driven every
    /// frame, say) is edited.
    pub(crate) guard_warned: Option<(u32, u32)>,
    /// Whether a divergence was logged for the current parameters (each one is still sent as a
    /// message): a cloth whose parameters make it diverge every tick logs once, not every frame.
    pub(crate) divergence_warned: bool,
    /// Changes whenever the state is replaced (a new grid, a reset), so that the GPU backend
    /// knows to upload it. Unique across cloths.
    pub(crate) generation: u64,
    /// Changes whenever the pins change on the running cloth, so that the GPU backend changes
    /// them on its state too. Unique across cloths.
    pub(crate) pins_generation: u64,
}

/// A [`ClothAnchor`](crate::ClothAnchor) as built: its particles in its target's frame.
#[derive(Debug)]
struct AnchorBinding {
    target: Entity,
    /// Each held particle and its place in the target's rigid frame, offset not included.
    particles: Vec<(u32, Vec3)>,
    /// The anchor's offset along the target's axes.
    offset: Vec3,
    /// The target's rigid pose at the end of the last tick (its last known one once lost).
    pose: Affine3A,
    /// The target is gone: the particles stay where they were last held.
    lost: bool,
}

/// The source of [`ClothSimulation::generation`].
fn next_generation() -> u64 {
    static NEXT: AtomicU64 = AtomicU64::new(1);
    NEXT.fetch_add(1, Ordering::Relaxed)
}

impl ClothSimulation {
    /// The simulated cloth: positions, velocities, energy, pins.
    pub fn sim(&self) -> &ClothSim {
        &self.sim
    }

    /// The mesh the cloth draws (also in its entity's [`Mesh3d`]).
    pub fn mesh(&self) -> &Handle<Mesh> {
        &self.mesh
    }

    /// The state went non-finite (`particles` of them): back to the rest pose under `pose`,
    /// logged once per parameter set and reported every time.
    pub(crate) fn diverged(
        &mut self,
        entity: Entity,
        particles: u32,
        pose: Affine3A,
        messages: &mut MessageWriter<ClothMessage>,
    ) {
        if !self.divergence_warned {
            warn!(
                "Cloth on {entity}: {particles} particles became NaN or infinite; reset to its rest pose \
                 (logged once until its parameters change, reported as ClothMessage::Diverged each time)"
            );
            self.divergence_warned = true;
        }
        self.reset(pose);
        messages.write(ClothMessage::Diverged { entity, particles });
    }

    /// Gives the running cloth the pins and anchors `cloth` now asks for, keeping its state
    /// ([`ClothSim::set_pins`]): a particle let go starts from rest where it was held, one
    /// newly held goes where its holder puts it (its rest place under the entity's `pose`, or
    /// an anchor's bound as when the cloth is built, to where `target_pose` puts its target
    /// now; a skinned mesh's own pins ride on its skin). Refused, keeping the old holders, when
    /// a selector fails. Returns why the skin could not take the new pins, if it could not (the
    /// entity holds them then).
    fn repin(
        &mut self,
        cloth: &Cloth,
        pose: Affine3A,
        meshes: &Assets<Mesh>,
        skin: Option<Skin<'_>>,
        target_pose: impl Fn(Entity) -> Option<Affine3A>,
    ) -> Result<Option<String>, ClothError> {
        let topology = Arc::clone(self.sim.topology());
        let authored = match &self.source {
            Some(source) => Some(meshes.get(source).ok_or(ClothError::NoTriangleMesh)?),
            None => None,
        };
        let rest: Vec<[f32; 3]>;
        let vertices = match authored {
            Some(mesh) => authored_vertices(mesh),
            None => {
                rest = topology.rest_positions().iter().map(|p| p.to_array()).collect();
                MeshVertices { positions: &rest, colors: None }
            }
        };
        let Holders { mut own_pins, anchors, pins } = holders(cloth, &topology, vertices, pose, target_pose)?;
        let (bound, refused) = match (skin, authored, &self.skin) {
            (Some(skin), Some(mesh), Some(_)) => bind_skin(skin, mesh, &topology, &own_pins),
            _ => (None, None),
        };
        self.sim.set_pins(&pins)?;
        if bound.is_some() {
            own_pins.clear();
        }
        self.skin = bound;
        self.own_pins = own_pins;
        self.anchors = anchors;
        self.pins_generation = next_generation();
        Ok(refused)
    }

    /// Back to the rest pose under `pose`, or for a skinned cloth where its skin was last drawn.
    pub(crate) fn reset(&mut self, pose: Affine3A) {
        self.sim.reset(pose);
        if let Some(skin) = &self.skin {
            place_on_skin(&mut self.sim, skin);
        }
        self.pose = pose;
        self.dirty = true;
        self.generation = next_generation();
    }
}

/// The rotation and translation of a transform: the pose a cloth's pins follow. Scale is left
/// out: a grid cloth is sized by its shape, a mesh cloth by its scale when built.
pub(crate) fn rigid_pose(transform: &GlobalTransform) -> Affine3A {
    let (_, rotation, translation) = transform.to_scale_rotation_translation();
    Affine3A::from_rotation_translation(rotation, translation)
}

/// A cloth built from its component: the simulation, the mesh it draws and the authored mesh
/// it came from.
struct Built {
    sim: ClothSim,
    mesh: Mesh,
    source: Option<Handle<Mesh>>,
    own_pins: Vec<u32>,
    anchors: Vec<AnchorBinding>,
    skin: Option<SkinBinding>,
    /// Why the mesh's skin could not hold the pins (they are held by the entity instead).
    skin_refused: Option<String>,
}

/// A skinned mesh's skin as [`build`] takes it: the `SkinnedMesh`, its inverse bind poses
/// (`None` when they are not loaded), and where its joints are (their whole world transform).
type Skin<'a> = (&'a SkinnedMesh, Option<&'a SkinnedMeshInverseBindposes>, &'a dyn Fn(Entity) -> Option<Affine3A>);

/// Puts every particle of `sim` where `skin` was last drawn, at rest.
fn place_on_skin(sim: &mut ClothSim, skin: &SkinBinding) {
    for (i, p) in skin.placed().enumerate() {
        sim.set_position(i, p);
        sim.set_velocity(i, Vec3::ZERO);
    }
}

/// Builds the simulation of `cloth` at `transform`, its anchors bound to where `target_pose`
/// puts their targets now; an authored mesh with a `skin` starts where the skin draws it, and
/// the skin holds its own pins. `Ok(None)` while its authored mesh is still loading.
fn build(
    cloth: &Cloth,
    transform: &GlobalTransform,
    source: Option<Handle<Mesh>>,
    meshes: &Assets<Mesh>,
    skin: Option<Skin<'_>>,
    target_pose: impl Fn(Entity) -> Option<Affine3A>,
    tick_seconds: Option<f32>,
) -> Result<Option<Built>, ClothError> {
    let params = cloth.to_params()?;
    let pose = rigid_pose(transform);
    // What the cloth is made from: a grid (with its vertices' rest positions for the pins to
    // select from), or an authored mesh.
    enum Made<'a> {
        Grid(ClothGrid, Vec<[f32; 3]>),
        Authored(&'a Mesh, Handle<Mesh>),
    }
    let (topology, from) = match &cloth.shape {
        ClothShape::Grid { size, particles } => {
            let grid = ClothGrid::new(*size, *particles);
            let topology = ClothTopology::grid(grid)?;
            let local = topology.rest_positions().iter().map(|p| p.to_array()).collect();
            (topology, Made::Grid(grid, local))
        }
        ClothShape::Mesh => {
            let source = source.ok_or(ClothError::NoTriangleMesh)?;
            let Some(authored) = meshes.get(&source) else { return Ok(None) };
            (authored_topology(authored, transform.scale())?, Made::Authored(authored, source))
        }
    };
    let vertices = match &from {
        Made::Grid(_, positions) => MeshVertices { positions, colors: None },
        Made::Authored(mesh, _) => authored_vertices(mesh),
    };
    let Holders { mut own_pins, anchors, pins } = holders(cloth, &topology, vertices, pose, target_pose)?;
    if let Some(dt) = tick_seconds {
        params.check_tick(dt, &topology)?;
    }
    // A skinned mesh's own pins ride on its skin.
    let (skin, skin_refused) = match (skin, &from) {
        (Some(skin), Made::Authored(mesh, _)) => bind_skin(skin, mesh, &topology, &own_pins),
        _ => (None, None),
    };
    if skin.is_some() {
        own_pins.clear();
    }
    let mut sim = ClothSim::new(params, Arc::new(topology), pose, &pins)?;
    if let Some(skin) = &skin {
        place_on_skin(&mut sim, skin);
    }
    let (mesh, source) = match from {
        Made::Grid(grid, _) => (new_grid_mesh(&grid, &sim, transform), None),
        Made::Authored(authored, source) => (new_authored_mesh(authored, &sim, transform), Some(source)),
    };
    Ok(Some(Built { sim, mesh, source, own_pins, anchors, skin, skin_refused }))
}

/// Who holds which particles of a cloth: the entity its own pins, each anchor its group.
struct Holders {
    /// The particles the entity itself holds (those no anchor claims).
    own_pins: Vec<u32>,
    anchors: Vec<AnchorBinding>,
    /// Every held particle, sorted.
    pins: Vec<u32>,
}

/// Which particles `cloth`'s pins and anchors choose on `topology` (`vertices` are the mesh's,
/// for selectors by position or colour), each anchor's bound where its target is now
/// (`target_pose`) and the cloth's rest shape lies under `pose`. Each particle goes to the last
/// holder that claims it: the entity, then the anchors.
fn holders(
    cloth: &Cloth,
    topology: &ClothTopology,
    vertices: MeshVertices<'_>,
    pose: Affine3A,
    target_pose: impl Fn(Entity) -> Option<Affine3A>,
) -> Result<Holders, ClothError> {
    let mut holder = vec![None::<usize>; topology.len()];
    let mut held = vec![false; topology.len()];
    for &i in &cloth.pins.particles(topology, vertices)? {
        held[i as usize] = true;
    }
    for (a, anchor) in cloth.anchors.iter().enumerate() {
        for i in anchor.pins.particles(topology, vertices)? {
            holder[i as usize] = Some(a);
        }
    }
    let own_pins = (0..topology.len() as u32).filter(|&i| held[i as usize] && holder[i as usize].is_none()).collect();
    let anchors = cloth
        .anchors
        .iter()
        .enumerate()
        .map(|(a, anchor)| {
            // A target that cannot be found holds its particles where the cloth's rest shape
            // lies (and `plan_anchors` reports it lost).
            let target = target_pose(anchor.target).unwrap_or(pose);
            let to_target = target.inverse() * pose;
            let particles = (0..topology.len() as u32)
                .filter(|&i| holder[i as usize] == Some(a))
                .map(|i| (i, to_target.transform_point3(topology.rest_positions()[i as usize])))
                .collect();
            AnchorBinding { target: anchor.target, particles, offset: anchor.offset, pose: target, lost: false }
        })
        .collect();
    let pins = (0..topology.len() as u32).filter(|&i| held[i as usize] || holder[i as usize].is_some()).collect();
    Ok(Holders { own_pins, anchors, pins })
}

/// The skin that carries a skinned mesh's own pins, or why it cannot (said only where it
/// matters: when there are pins to carry).
fn bind_skin(
    (skinned, inverse, joint_pose): Skin<'_>,
    mesh: &Mesh,
    topology: &ClothTopology,
    own_pins: &[u32],
) -> (Option<SkinBinding>, Option<String>) {
    let binding = inverse
        .ok_or_else(|| "its inverse bind poses are not loaded".to_string())
        .and_then(|inverse| SkinBinding::new(skinned, inverse, mesh, topology, own_pins.to_vec(), joint_pose));
    match binding {
        Ok(binding) => (Some(binding), None),
        Err(reason) => (None, (!own_pins.is_empty()).then_some(reason)),
    }
}

/// Creates, updates, rebuilds and resets the simulation of every [`Cloth`].
#[allow(clippy::type_complexity, clippy::too_many_arguments)]
pub(crate) fn sync_cloths(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut cloths: Query<(
        Entity,
        Ref<Cloth>,
        &GlobalTransform,
        Option<&mut ClothSimulation>,
        Option<&Mesh3d>,
        (Option<&SkinnedMesh>, Option<&ClothSkin>),
        (Option<&ClothPart>, Option<&Name>),
    )>,
    targets: Query<&GlobalTransform>,
    bindposes: Res<Assets<SkinnedMeshInverseBindposes>>,
    mut resets: MessageReader<ResetCloth>,
    mut messages: MessageWriter<ClothMessage>,
    mut loading: Local<EntityHashSet>,
    mut start: ColliderWait,
    settings: Res<ClothSettings>,
    clock: Res<ClothClock>,
) {
    // The tick the clock runs, which the explicit integrators' stability guard depends on.
    let tick_seconds = clock.tick_length(&settings);
    let resets: Vec<ResetCloth> = resets.read().copied().collect();
    // The colliders still being built, found when a new cloth first asks.
    let mut pending: Option<Vec<Entity>> = None;
    for (entity, cloth, transform, state, mesh3d, (skinned, kept_skin), (part, name)) in &mut cloths {
        let pose = rigid_pose(transform);
        let reset = resets.iter().any(|r| *r == ResetCloth::All || *r == ResetCloth::One(entity));
        // A scene's cloth is named with its scene's root, which its user knows.
        let from_scene = match (part, name) {
            (Some(part), Some(name)) => format!(" (\"{name}\" of the ClothHierarchy on {})", part.root),
            (Some(part), None) => format!(" (of the ClothHierarchy on {})", part.root),
            _ => String::new(),
        };
        // A skinned mesh's skin (loaded with its mesh, from the same file; the plugin keeps it
        // as `ClothSkin` once the mesh is cloth), for a build or a change of pins. Joints are
        // placed by their whole transform, anchors by its rigid part.
        let skinned = skinned.or(kept_skin.map(|kept| &kept.0));
        let joint_pose = |joint| targets.get(joint).ok().map(GlobalTransform::affine);
        let skin = skinned
            .map(|s| (s, bindposes.get(&s.inverse_bindposes), &joint_pose as &dyn Fn(Entity) -> Option<Affine3A>));
        let target_pose = |target| targets.get(target).ok().map(rigid_pose);
        let mut reject = |error| {
            error!("Cloth on {entity}{from_scene}: {error}; keeping its last valid state");
            messages.write(ClothMessage::Rejected { entity, error });
        };
        match state {
            Some(mut state) if !state.built_from.shape_differs(&cloth) => {
                if cloth.is_changed() && state.built_from.holders_differ(&cloth) {
                    // Pins and anchors change live: the cloth keeps moving.
                    match state.repin(&cloth, pose, &meshes, skin, target_pose) {
                        Ok(refused) => {
                            if let Some(reason) = refused {
                                warn!(
                                    "Cloth on {entity}: its skin cannot carry its pins ({reason}); the entity holds them"
                                );
                            }
                            state.built_from.pins = cloth.pins.clone();
                            state.built_from.anchors = cloth.anchors.clone();
                        }
                        Err(error) => reject(error),
                    }
                }
                if cloth.is_changed() {
                    let checked = cloth.to_params().and_then(|params| {
                        if let Some(dt) = tick_seconds {
                            params.check_tick(dt, state.sim.topology())?;
                        }
                        state.sim.set_params(params)
                    });
                    match checked {
                        Ok(()) => {
                            // The holders as they now are (the old ones if the change was refused).
                            let (pins, anchors) =
                                (state.built_from.pins.clone(), std::mem::take(&mut state.built_from.anchors));
                            state.built_from = Cloth { pins, anchors, ..Cloth::clone(&cloth) };
                            state.divergence_warned = false;
                            if !state.built_from.holders_differ(&cloth) {
                                for (binding, anchor) in state.anchors.iter_mut().zip(&cloth.anchors) {
                                    binding.offset = anchor.offset;
                                }
                            }
                        }
                        Err(error) => reject(error),
                    }
                }
                if reset {
                    state.reset(pose);
                }
            }
            None if (cloth.is_changed() || reset || loading.contains(&entity))
                && !cloth.start_at_once
                && start.holds(entity, pending.get_or_insert_with(|| start.pending())) =>
            {
                loading.insert(entity);
            }
            state if cloth.is_changed() || reset || loading.contains(&entity) => {
                // An authored cloth is rebuilt from the mesh it was first built from, not from the
                // copy it draws.
                let source = match &state {
                    Some(state) => state.source.clone(),
                    None => mesh3d.map(|m| m.0.clone()),
                };
                let built = match build(&cloth, transform, source, &meshes, skin, target_pose, tick_seconds) {
                    Ok(Some(built)) => built,
                    Ok(None) => {
                        loading.insert(entity);
                        continue;
                    }
                    Err(error) => {
                        loading.remove(&entity);
                        reject(error);
                        continue;
                    }
                };
                loading.remove(&entity);
                if let Some(reason) = &built.skin_refused {
                    warn!("Cloth on {entity}: its skin cannot carry its pins ({reason}); the entity holds them");
                }
                // The renderer must not skin the simulated vertices again: the skin is kept
                // for the pins, off the renderer's sight.
                if let (Some(skinned), Some(_)) = (skinned, &built.source) {
                    commands.entity(entity).try_remove::<SkinnedMesh>().try_insert(ClothSkin(skinned.clone()));
                }
                // A rebuilt cloth keeps its mesh handle, so materials and user references stay.
                let mesh = match state.map(|s| s.mesh.clone()) {
                    Some(handle) if meshes.contains(&handle) => {
                        if let Some(mut old) = meshes.get_mut(&handle) {
                            *old = built.mesh;
                        }
                        handle
                    }
                    _ => meshes.add(built.mesh),
                };
                commands.entity(entity).try_insert((
                    ClothSimulation {
                        sim: built.sim,
                        built_from: Cloth::clone(&cloth),
                        pose,
                        mesh: mesh.clone(),
                        source: built.source,
                        own_pins: built.own_pins,
                        anchors: built.anchors,
                        skin: built.skin,
                        anchor_targets: Vec::new(),
                        dirty: true,
                        guard_warned: None,
                        divergence_warned: false,
                        generation: next_generation(),
                        pins_generation: next_generation(),
                    },
                    Mesh3d(mesh),
                    NoAutoAabb,
                ));
            }
            _ => {}
        }
    }
    loading.retain(|&entity| cloths.contains(entity));
    start.since.retain(|&entity, _| loading.contains(&entity));
}

/// Stops the simulation of an entity whose [`Cloth`] was removed: an authored mesh shows its
/// own mesh again, and a skinned one gets its [`SkinnedMesh`] back, so that it moves with the
/// body as it did before it was cloth. A grid keeps the mesh it last drew.
pub(crate) fn drop_removed_cloths(
    mut commands: Commands,
    mut removed: RemovedComponents<Cloth>,
    stopped: Query<(Option<&ClothSimulation>, Option<&ClothSkin>), Without<Cloth>>,
) {
    for entity in removed.read() {
        let Ok((state, skin)) = stopped.get(entity) else { continue };
        let mut entity = commands.entity(entity);
        entity.try_remove::<(ClothSimulation, NoAutoAabb)>();
        if let Some(source) = state.and_then(|state| state.source.clone()) {
            entity.try_insert(Mesh3d(source));
        }
        if let Some(ClothSkin(skinned)) = skin {
            entity.try_remove::<ClothSkin>().try_insert(skinned.clone());
        }
    }
}

/// What decides whether a new cloth waits for colliders still being built, and since when each
/// waiting cloth has waited.
#[derive(SystemParam)]
pub(crate) struct ColliderWait<'w, 's> {
    colliders: Query<'w, 's, (Entity, &'static ColliderStatus), With<AutoCollider>>,
    settings: Res<'w, ClothSettings>,
    time: Res<'w, Time>,
    /// When each waiting cloth began to wait, and whether it was told it waited too long.
    since: Local<'s, EntityHashMap<(f64, bool)>>,
}

impl ColliderWait<'_, '_> {
    /// The colliders still being built (their mesh loading, or a build running).
    fn pending(&self) -> Vec<Entity> {
        self.colliders
            .iter()
            .filter(|(_, status)| matches!(status, ColliderStatus::Waiting | ColliderStatus::Building))
            .map(|(collider, _)| collider)
            .collect()
    }

    /// Whether the new cloth `entity` waits this frame: some collider is still being built
    /// (`pending`) and the cloth has not waited [`ClothSettings::collider_wait`] yet.
    fn holds(&mut self, entity: Entity, pending: &[Entity]) -> bool {
        if pending.is_empty() {
            return false;
        }
        let now = self.time.elapsed_secs_f64();
        let (since, told) = self.since.entry(entity).or_insert((now, false));
        if now - *since < f64::from(self.settings.collider_wait) {
            return true;
        }
        if !*told {
            warn!(
                "Cloth on {entity}: colliders {pending:?} are still being built after {} s; the cloth starts \
                 without them",
                self.settings.collider_wait
            );
            *told = true;
        }
        false
    }
}

/// Plans this frame's ticks for the pins of every cloth, on either backend: within a frame each
/// holder's pose (the cloth entity's for its own pins, the target's for an anchor) moves
/// smoothly from last frame's to this frame's, one step per tick, and each tick's pins go where
/// that pose puts them. The CPU backend applies them before each tick; the GPU backend uploads
/// them for its `apply_anchors` kernel. An anchor whose target has gone is reported once and
/// holds its particles where they were.
pub(crate) fn plan_anchors(
    clock: Res<ClothClock>,
    mut cloths: Query<(Entity, &mut ClothSimulation, &GlobalTransform)>,
    targets: Query<&GlobalTransform>,
    mut messages: MessageWriter<ClothMessage>,
) {
    for (entity, mut state, transform) in &mut cloths {
        let state = &mut *state;
        state.anchor_targets.clear();
        if clock.ticks == 0 {
            continue;
        }
        let (from, to) = (state.pose, rigid_pose(transform));
        let mut target_poses = Vec::with_capacity(state.anchors.len());
        for binding in &mut state.anchors {
            let now = match targets.get(binding.target) {
                Ok(target) if !binding.lost => rigid_pose(target),
                Ok(_) => binding.pose,
                Err(_) => {
                    if !binding.lost {
                        warn!(
                            "Cloth on {entity}: anchor target {} is gone (despawned, or without a GlobalTransform); \
                             its particles stay where they are",
                            binding.target
                        );
                        messages.write(ClothMessage::AnchorLost { entity, target: binding.target });
                        binding.lost = true;
                    }
                    binding.pose
                }
            };
            target_poses.push((binding.pose, now));
            binding.pose = now;
        }
        let skin_moves = match &mut state.skin {
            Some(skin) => {
                let (moves, gone) = skin.advance(|joint| targets.get(joint).ok().map(GlobalTransform::affine));
                if let Some(joint) = gone {
                    warn!("Cloth on {entity}: joint {joint} of its skin is gone; its pins stay where they are");
                    messages.write(ClothMessage::AnchorLost { entity, target: joint });
                }
                moves
            }
            None => Vec::new(),
        };
        if !state.sim.pins().is_empty() {
            let rest = state.sim.topology().rest_positions();
            for k in 1..=clock.ticks {
                let t = k as f32 / clock.ticks as f32;
                let pose = interpolate(&from, &to, t);
                let mut tick: Vec<(u32, Vec3)> =
                    state.own_pins.iter().map(|&i| (i, pose.transform_point3(rest[i as usize]))).collect();
                for (binding, (was, now)) in state.anchors.iter().zip(&target_poses) {
                    let pose = interpolate(was, now, t);
                    tick.extend(
                        binding.particles.iter().map(|&(i, local)| (i, pose.transform_point3(local + binding.offset))),
                    );
                }
                tick.extend(skin_moves.iter().map(|&(i, was, now)| (i, was.lerp(now, t))));
                state.anchor_targets.push(tick);
            }
        }
        state.pose = to;
    }
}

/// The rigid pose a fraction `t` of the way from `from` to `to`.
fn interpolate(from: &Affine3A, to: &Affine3A, t: f32) -> Affine3A {
    let (_, r0, t0) = from.to_scale_rotation_translation();
    let (_, r1, t1) = to.to_scale_rotation_translation();
    Affine3A::from_rotation_translation(r0.slerp(r1, t), t0.lerp(t1, t))
}

/// Says once per `(looper, substeps)` pair when the stability guard runs a cloth at more
/// substeps per tick than its Looper. Either backend runs the count
/// [`bvh_cloth_core::ClothParams::substeps`] gives, so it is checked here, for both. The count
/// comes from the topology's precomputed bound, so checking it every frame is cheap.
pub(crate) fn warn_stiff_cloths(clock: Res<ClothClock>, mut cloths: Query<(Entity, &mut ClothSimulation)>) {
    if clock.ticks == 0 {
        return;
    }
    for (entity, mut state) in &mut cloths {
        let (looper, substeps) = (state.sim.params().looper, state.sim.substeps(clock.tick_seconds));
        if substeps > looper && state.guard_warned != Some((looper, substeps)) {
            warn!(
                "Cloth on {entity}: spring_k is too stiff for looper = {looper} at this tick rate; \
                 running {substeps} substeps per tick to stay stable"
            );
            state.guard_warned = Some((looper, substeps));
        }
    }
}
