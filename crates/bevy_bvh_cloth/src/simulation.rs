//! A cloth's simulation state, kept in step with its [`Cloth`] component.

use std::sync::atomic::{AtomicU64, Ordering};

use bevy::camera::visibility::NoAutoAabb;
use bevy::prelude::*;
use bvh_cloth_core::{Affine3A, ClothSim};

use crate::clock::ClothClock;
use crate::cloth::Cloth;
use crate::cloth_mesh::new_cloth_mesh;
use crate::messages::{ClothMessage, ResetCloth};
use crate::settings::ClothSettings;

/// The running simulation of a [`Cloth`] entity, added by the plugin.
///
/// Particle positions are in world space. The entity's [`Mesh3d`] shows them in the entity's
/// local frame. On the CPU backend this is the live state; on the GPU backend the live state
/// stays on the GPU, and this holds the state as of the last rebuild or reset.
#[derive(Component, Debug)]
pub struct ClothSimulation {
    pub(crate) sim: ClothSim,
    /// The component the grid was built from: a change of shape rebuilds.
    built_from: Cloth,
    /// The entity's rigid pose at the end of the last tick; pins move on from here.
    pub(crate) pose: Affine3A,
    /// The cloth's own grid mesh.
    pub(crate) mesh: Handle<Mesh>,
    /// Positions changed since the mesh was last written.
    pub(crate) dirty: bool,
    /// Whether the stability guard's warning was given for the current parameters.
    pub(crate) guard_warned: bool,
    /// Whether a divergence was logged for the current parameters (each one is still sent as a
    /// message): a cloth whose parameters make it diverge every tick logs once, not every frame.
    pub(crate) divergence_warned: bool,
    /// Changes whenever the state is replaced (a new grid, a reset), so that the GPU backend
    /// knows to upload it. Unique across cloths.
    pub(crate) generation: u64,
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

    /// The grid mesh the plugin made for this cloth.
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

    /// Back to the rest pose under `pose`.
    pub(crate) fn reset(&mut self, pose: Affine3A) {
        self.sim.reset(pose);
        self.pose = pose;
        self.dirty = true;
        self.generation = next_generation();
    }
}

/// The rotation and translation of a transform: the pose a cloth's pins follow. Scale is left
/// out, because the cloth's size is set by [`Cloth::size`].
pub(crate) fn rigid_pose(transform: &GlobalTransform) -> Affine3A {
    let (_, rotation, translation) = transform.to_scale_rotation_translation();
    Affine3A::from_rotation_translation(rotation, translation)
}

/// Creates, updates, rebuilds and resets the simulation of every [`Cloth`].
#[allow(clippy::type_complexity)]
pub(crate) fn sync_cloths(
    mut commands: Commands,
    settings: Res<ClothSettings>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut cloths: Query<(Entity, Ref<Cloth>, &GlobalTransform, Option<&mut ClothSimulation>)>,
    mut resets: MessageReader<ResetCloth>,
    mut messages: MessageWriter<ClothMessage>,
) {
    let resets: Vec<ResetCloth> = resets.read().copied().collect();
    let settings_changed = settings.is_changed();
    for (entity, cloth, transform, state) in &mut cloths {
        let pose = rigid_pose(transform);
        let reset = resets.iter().any(|r| *r == ResetCloth::All || *r == ResetCloth::One(entity));
        let mut reject = |error| {
            error!("Cloth on {entity}: {error}; keeping its last valid state");
            messages.write(ClothMessage::Rejected { entity, error });
        };
        match state {
            Some(mut state) if !state.built_from.shape_differs(&cloth) => {
                if cloth.is_changed() || settings_changed {
                    match cloth.to_params(settings.gravity).and_then(|params| state.sim.set_params(params)) {
                        Ok(()) => {
                            state.built_from = Cloth::clone(&cloth);
                            state.guard_warned = false;
                            state.divergence_warned = false;
                        }
                        Err(error) => reject(error),
                    }
                }
                if reset {
                    state.reset(pose);
                }
            }
            state if cloth.is_changed() || reset => {
                let pins = cloth.pins.indices(cloth.rows, cloth.cols);
                let sim = match cloth.to_params(settings.gravity).and_then(|params| ClothSim::new(params, pose, &pins))
                {
                    Ok(sim) => sim,
                    Err(error) => {
                        reject(error);
                        continue;
                    }
                };
                let new_mesh = new_cloth_mesh(&sim, transform);
                // A rebuilt cloth keeps its mesh handle, so materials and user references stay.
                let mesh = match state.map(|s| s.mesh.clone()) {
                    Some(handle) if meshes.contains(&handle) => {
                        if let Some(mut old) = meshes.get_mut(&handle) {
                            *old = new_mesh;
                        }
                        handle
                    }
                    _ => meshes.add(new_mesh),
                };
                commands.entity(entity).try_insert((
                    ClothSimulation {
                        sim,
                        built_from: Cloth::clone(&cloth),
                        pose,
                        mesh: mesh.clone(),
                        dirty: true,
                        guard_warned: false,
                        divergence_warned: false,
                        generation: next_generation(),
                    },
                    Mesh3d(mesh),
                    NoAutoAabb,
                ));
            }
            _ => {}
        }
    }
}

/// Says once per parameter set when the stability guard runs a cloth at more substeps per tick
/// than its Looper. Either backend runs the count [`bvh_cloth_core::ClothParams::substeps`]
/// gives, so it is checked here, for both.
pub(crate) fn warn_stiff_cloths(clock: Res<ClothClock>, mut cloths: Query<(Entity, &mut ClothSimulation)>) {
    if clock.ticks == 0 {
        return;
    }
    for (entity, mut state) in &mut cloths {
        if state.guard_warned {
            continue;
        }
        let params = state.sim.params();
        let (looper, substeps) = (params.looper, params.substeps(clock.tick_seconds));
        if substeps > looper {
            warn!(
                "Cloth on {entity}: spring_k is too stiff for looper = {looper} at this tick rate; \
                 running {substeps} substeps per tick to stay stable"
            );
            state.guard_warned = true;
        }
    }
}
