//! # bevy_bvh_cloth
//!
//! Real-time mass-spring cloth for Bevy, with colliders nobody has to set up by hand: put
//! [`AutoCollider`] on any entity with a [`Mesh3d`] and the mesh is voxelised into spheres
//! arranged in a Morton-code LBVH, after Mei, Fan, Zhang and Liu, *A Collision Detection and
//! Cloth Simulation Method Based on Parallel BVH*. On an entity without a mesh (a glTF scene
//! root, a character) it covers every mesh under it. [`PrimitiveCollider`] adds exact spheres,
//! capsules, boxes and a ground that follow their entity (and so a bone). A cloth with
//! [`Aerodynamics`] catches the air: the [`AmbientWind`], its own [`LocalWind`], and
//! [`WindFan`]s and [`WindBlast`]s that follow their entity. The math lives in
//! [`bvh_cloth_core`], which knows nothing of Bevy.
//!
//! ## Getting started
//!
//! ```no_run
//! use bevy::prelude::*;
//! use bevy_bvh_cloth::prelude::*;
//!
//! fn main() {
//!     App::new()
//!         .add_plugins((DefaultPlugins, BvhClothPlugins::default()))
//!         .add_systems(Startup, setup)
//!         .run();
//! }
//!
//! fn setup(
//!     mut commands: Commands,
//!     mut meshes: ResMut<Assets<Mesh>>,
//!     mut materials: ResMut<Assets<StandardMaterial>>,
//! ) {
//!     // A ball that the cloth falls onto: any mesh works.
//!     commands.spawn((
//!         Mesh3d(meshes.add(Sphere::new(0.5))),
//!         MeshMaterial3d(materials.add(Color::WHITE)),
//!         AutoCollider::new(5),
//!     ));
//!     // A 2 m x 2 m cloth of 64 x 64 particles, one metre above the ball. The plugin gives it
//!     // its mesh. (`Cloth::mesh()` on an entity with a `Mesh3d` simulates that mesh instead.)
//!     commands.spawn((
//!         Cloth::grid(Vec2::splat(2.0), UVec2::splat(64)),
//!         MeshMaterial3d(materials.add(StandardMaterial {
//!             base_color: Color::srgb(0.8, 0.2, 0.2),
//!             double_sided: true,
//!             cull_mode: None,
//!             ..default()
//!         })),
//!         Transform::from_xyz(0.0, 1.5, 0.0),
//!     ));
//!     commands.spawn((Camera3d::default(), Transform::from_xyz(0.0, 2.0, 4.0).looking_at(Vec3::ZERO, Vec3::Y)));
//!     commands.spawn((PointLight::default(), Transform::from_xyz(2.0, 4.0, 2.0)));
//! }
//! ```
//!
//! ## How it runs
//!
//! The main-world systems run in [`PostUpdate`], after transform propagation, in the chained
//! [`ClothSystems`] sets (or in the schedule given to [`BvhClothPlugins::new`], such as
//! `FixedPostUpdate` beside a physics engine). A fixed-rate clock ([`ClothSettings::tick_rate`]) decides how many
//! whole ticks a frame runs, and each tick runs [`ClothParams::looper`] substeps, so a cloth behaves
//! the same at 30 and at 144 frames per second.
//!
//! Who runs the ticks is decided once at start-up ([`ClothBackend`], [`ActiveClothBackend`]):
//! * **GPU** (where the render device runs compute shaders): the render world runs the paper's
//!   kernels from [`bvh_cloth_gpu`] in Bevy's `RenderGraph` schedule, before the camera driver,
//!   for every cloth at once (one batch: shared buffers, one dispatch per integrator stage), and
//!   `normal_shader` writes positions and normals straight into the cloth mesh's vertex
//!   slab. Nothing on the hot path waits for the GPU: each cloth's count of non-finite
//!   particles is read back without waiting for it, and so is its whole state when the cloth
//!   has [`ClothReadback`] (then [`ClothSimulation`] is one or two frames late; without it,
//!   [`ClothSimulation`] holds the state as of the last rebuild or reset).
//!   The kernels are compiled by Bevy's pipeline cache, off the render thread; cloths wait at
//!   rest until they are ready, a few frames after start-up.
//! * **CPU** (no compute shaders, no renderer, or asked for): the core's rayon stepper in
//!   [`ClothSystems::Step`], writing the `Mesh` asset in [`ClothSystems::Writeback`].
//!
//! ## Features
//!
//! | feature | what it adds |
//! |---|---|
//! | `egui` | [`ClothPanelPlugin`](panel::ClothPanelPlugin): a live panel for Looper, SpringK, Damping, External Force, the wind, each cloth's integrator, self-contact and drag and lift, the collider resolution, pause, reset and the debug view |
//!
//! ## When things go wrong
//!
//! Nothing the plugin is fed makes it panic. Invalid [`Cloth`] parameters, meshes that cannot
//! become colliders, and cloths whose state diverges are logged and reported as
//! [`ClothMessage`]s; the rest of the scene keeps running.

#![deny(missing_docs)]

mod backend;
mod clock;
mod cloth;
mod cloth_mesh;
mod collider;
mod collider_hierarchy;
mod collider_mesh;
mod collider_pose;
mod cpu_backend;
mod debug_view;
mod events;
mod gpu_backend;
mod messages;
#[cfg(feature = "egui")]
pub mod panel;
mod primitive_collider;
mod readback;
mod settings;
mod simulation;
mod stats;
mod wind;

use bevy::app::PluginGroupBuilder;
use bevy::camera::visibility::{NoFrustumCulling, VisibilitySystems};
use bevy::ecs::schedule::{InternedScheduleLabel, ScheduleLabel};
use bevy::prelude::*;
use bevy::render::RenderApp;
use bevy::render::mesh::allocator::MeshAllocatorSettings;
use bevy::render::render_resource::{BufferUsages, DownlevelFlags};
use bevy::render::renderer::{RenderAdapter, RenderDevice};
use bevy::shader::Shader;
use bevy::transform::TransformSystems;
use bevy::transform::systems::{mark_dirty_trees, propagate_parent_transforms, sync_simple_transforms};

pub use backend::{ActiveClothBackend, ClothBackend};
pub use bvh_cloth_core;
pub use bvh_cloth_core::{
    Aerodynamics, ClothError, ClothParams, ClothPins, ColliderError, ColorChannel, Integrator, SelfContact,
    SpringStiffness, Tethers, Wind,
};
pub use clock::ClothClock;
pub use cloth::{Cloth, ClothAnchor, ClothShape};
pub use collider::{ASYNC_BUILD_MIN_VERTICES, AutoCollider, ClothCollider, ColliderContact, ColliderStatus};
pub use collider_hierarchy::{ColliderHierarchy, ColliderPart};
pub use collider_mesh::{ColliderFailure, collider_from_mesh};
pub use events::{AnchorLost, ClothDiverged, ClothRejected, ColliderFailed, ColliderReady, WindSourceRejected};
pub use messages::{ClothMessage, ResetCloth};
pub use primitive_collider::{PrimitiveCollider, PrimitiveShape};
pub use readback::ClothReadback;
pub use settings::ClothSettings;
pub use simulation::ClothSimulation;
pub use stats::ClothStats;
pub use wind::{AmbientWind, LocalWind, WindBlast, WindFan};

/// Everything a game needs, in one `use`.
pub mod prelude {
    #[cfg(feature = "egui")]
    pub use crate::panel::ClothPanelPlugin;
    pub use crate::{
        ActiveClothBackend, Aerodynamics, AmbientWind, AnchorLost, AutoCollider, BvhClothPlugin, BvhClothPlugins,
        Cloth, ClothAnchor, ClothBackend, ClothClock, ClothDebugViewPlugin, ClothDiverged, ClothError, ClothMessage,
        ClothParams, ClothPins, ClothReadback, ClothRejected, ClothSettings, ClothShape, ClothSimulation, ClothStats,
        ClothSystems, ColliderContact, ColliderError, ColliderFailed, ColliderHierarchy, ColliderReady, ColliderStatus,
        ColorChannel, Integrator, LocalWind, PrimitiveCollider, PrimitiveShape, ResetCloth, SelfContact,
        SpringStiffness, Tethers, Wind, WindBlast, WindFan, WindSourceRejected,
    };
}

/// The plugins of `bevy_bvh_cloth`: [`BvhClothPlugin`] (the simulation) and
/// [`ClothDebugViewPlugin`] (gizmos; it needs Bevy's gizmo plugin, part of `DefaultPlugins`).
/// The egui panel is added separately, see [`panel`](crate#features).
///
/// `BvhClothPlugins::default()` runs the cloth in [`PostUpdate`];
/// `BvhClothPlugins::new(FixedPostUpdate)` runs it in the schedule given (see
/// [`BvhClothPlugin::new`]).
#[derive(Debug, Clone)]
pub struct BvhClothPlugins {
    schedule: InternedScheduleLabel,
}

impl BvhClothPlugins {
    /// The plugins, with the cloth systems in `schedule`.
    pub fn new(schedule: impl ScheduleLabel) -> Self {
        Self { schedule: schedule.intern() }
    }
}

impl Default for BvhClothPlugins {
    fn default() -> Self {
        Self::new(PostUpdate)
    }
}

impl PluginGroup for BvhClothPlugins {
    fn build(self) -> PluginGroupBuilder {
        PluginGroupBuilder::start::<Self>().add(BvhClothPlugin { schedule: self.schedule }).add(ClothDebugViewPlugin)
    }
}

/// The system sets of the plugin, chained in this order in the schedule the plugin runs in
/// ([`PostUpdate`] by default, after [`TransformSystems::Propagate`]). Order your own systems
/// against them.
#[derive(SystemSet, Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ClothSystems {
    /// [`AutoCollider`]s are built (or their async builds polled) and placed at their
    /// entity's [`GlobalTransform`].
    BuildColliders,
    /// The clock advances; [`Cloth`] changes, [`ResetCloth`] requests and the GPU's divergence
    /// reports are applied.
    Prepare,
    /// Each cloth's pins are planned tick by tick, and the cloths are stepped (on the GPU
    /// backend, in the render world).
    Step,
    /// The results are written into the cloth meshes.
    Writeback,
}

/// The simulation: [`Cloth`] and [`AutoCollider`] components, stepped on the GPU where the
/// render device runs compute shaders and on the CPU otherwise (see [`ClothBackend`]).
///
/// Needs Bevy's asset, mesh and transform plugins (all part of `DefaultPlugins`; with
/// `MinimalPlugins`, add `AssetPlugin`, `MeshPlugin` and `TransformPlugin`, and the CPU backend
/// runs).
///
/// `BvhClothPlugin::default()` runs the cloth systems in [`PostUpdate`], after transform
/// propagation, once per frame. [`BvhClothPlugin::new`] puts them in another schedule.
#[derive(Debug, Clone)]
pub struct BvhClothPlugin {
    schedule: InternedScheduleLabel,
}

impl BvhClothPlugin {
    /// The simulation, with its systems ([`ClothSystems`]) in `schedule`: for example
    /// `FixedPostUpdate`, beside a physics engine stepped there.
    ///
    /// The clock ([`ClothClock`]) advances by that schedule's [`Time`], so in a fixed-timestep
    /// schedule it advances by [`Time<Fixed>`]'s step on each run, and a schedule that runs
    /// twice in a frame runs the ticks of both (on the GPU backend, all in that frame's render
    /// pass, against the colliders' poses of the last run; a cloth reset or rebuilt in the
    /// second run also runs the first run's ticks there). Outside [`PostUpdate`] the plugin
    /// propagates transforms at the start of that schedule (Bevy's own propagation systems, in
    /// [`TransformSystems::Propagate`]), so cloths, colliders, anchors and joints are where
    /// their [`Transform`]s say when the cloth runs.
    pub fn new(schedule: impl ScheduleLabel) -> Self {
        Self { schedule: schedule.intern() }
    }

    /// The schedule the cloth systems run in.
    pub fn schedule(&self) -> InternedScheduleLabel {
        self.schedule
    }
}

impl Default for BvhClothPlugin {
    fn default() -> Self {
        Self::new(PostUpdate)
    }
}

impl Plugin for BvhClothPlugin {
    fn build(&self, app: &mut App) {
        let schedule = self.schedule;
        app.register_type::<Cloth>()
            .register_type::<AutoCollider>()
            .register_type::<ColliderContact>()
            .register_type::<PrimitiveCollider>()
            .register_type::<ColliderHierarchy>()
            .register_type::<ColliderPart>()
            .register_type::<ColliderStatus>()
            .register_type::<ClothSettings>()
            .register_type::<ClothClock>()
            .register_type::<ClothStats>()
            .register_type::<ClothReadback>()
            .register_type::<ClothBackend>()
            .register_type::<ActiveClothBackend>()
            .register_type::<AmbientWind>()
            .register_type::<LocalWind>()
            .register_type::<WindFan>()
            .register_type::<WindBlast>()
            .init_resource::<ClothSettings>()
            .init_resource::<ClothClock>()
            .init_resource::<ClothStats>()
            .init_resource::<AmbientWind>()
            .init_resource::<wind::WindSources>()
            .init_resource::<ClothBackend>()
            .init_resource::<ActiveClothBackend>()
            .init_resource::<gpu_backend::RenderTicks>()
            .add_message::<ClothMessage>()
            .add_message::<ResetCloth>()
            .add_message::<gpu_backend::GpuClothDiverged>()
            .add_message::<readback::GpuClothState>()
            .configure_sets(
                schedule,
                (ClothSystems::BuildColliders, ClothSystems::Prepare, ClothSystems::Step, ClothSystems::Writeback)
                    .chain(),
            )
            .add_systems(First, gpu_backend::start_render_frame.run_if(not(backend::cpu_backend_active)))
            .add_systems(
                schedule,
                (
                    (
                        collider_pose::drop_removed_colliders,
                        collider_hierarchy::spread_colliders,
                        collider::build_colliders,
                        primitive_collider::build_primitive_colliders,
                        collider_pose::update_collider_poses,
                    )
                        .chain()
                        .in_set(ClothSystems::BuildColliders),
                    (
                        clock::advance_clock,
                        simulation::sync_cloths,
                        (gpu_backend::reset_diverged_cloths, readback::apply_gpu_readbacks)
                            .run_if(not(backend::cpu_backend_active)),
                        simulation::warn_stiff_cloths,
                    )
                        .chain()
                        .in_set(ClothSystems::Prepare),
                    (
                        (wind::gather_wind_sources, wind::gather_wind).chain(),
                        simulation::plan_anchors,
                        cpu_backend::step_cloths.run_if(backend::cpu_backend_active),
                        gpu_backend::queue_render_ticks.run_if(not(backend::cpu_backend_active)),
                        stats::update_stats,
                    )
                        .chain()
                        .in_set(ClothSystems::Step),
                    (
                        cpu_backend::write_back_cloths.run_if(backend::cpu_backend_active),
                        gpu_cloths_skip_culling.run_if(not(backend::cpu_backend_active)),
                    )
                        .in_set(ClothSystems::Writeback),
                    events::trigger_message_events.after(ClothSystems::Writeback),
                ),
            );
        if schedule == PostUpdate.intern() {
            app.configure_sets(
                PostUpdate,
                (ClothSystems::BuildColliders, ClothSystems::Writeback)
                    .after(TransformSystems::Propagate)
                    .before(VisibilitySystems::CheckVisibility),
            );
        } else {
            // Elsewhere the transforms are propagated first, as `TransformPlugin` does in
            // `PostUpdate`: a cloth or collider spawned or moved since is where its `Transform`
            // says, not where the last propagation left it.
            app.add_systems(
                schedule,
                (mark_dirty_trees, propagate_parent_transforms, sync_simple_transforms)
                    .chain()
                    .in_set(TransformSystems::Propagate)
                    .before(ClothSystems::BuildColliders),
            );
        }
    }

    fn finish(&self, app: &mut App) {
        let requested = *app.world().resource::<ClothBackend>();
        let active = backend::choose_backend(requested, gpu_capability(app));
        app.insert_resource(active);
        if active != ActiveClothBackend::Gpu {
            return;
        }
        // The kernels' WGSL, as shader assets the render world's pipeline cache compiles.
        let Some(shaders) = app
            .world_mut()
            .get_resource_mut::<Assets<Shader>>()
            .map(|mut shaders| gpu_backend::ClothShaders::add(&mut shaders))
        else {
            return;
        };
        app.insert_resource(shaders.clone());
        if let Some(render_app) = app.get_sub_app_mut(RenderApp) {
            // normal_shader writes into the mesh slabs: they must be storage buffers too.
            render_app.world_mut().resource_mut::<MeshAllocatorSettings>().extra_buffer_usages |= BufferUsages::STORAGE;
            gpu_backend::add_render_systems(render_app, shaders);
        }
    }
}

/// What the render device offers the GPU backend; `None` when the app does not render.
fn gpu_capability(app: &App) -> Option<backend::GpuCapability> {
    let render_world = app.get_sub_app(RenderApp)?.world();
    let adapter = render_world.get_resource::<RenderAdapter>()?;
    let device = render_world.get_resource::<RenderDevice>()?;
    if !adapter.get_downlevel_capabilities().flags.contains(DownlevelFlags::COMPUTE_SHADERS) {
        return Some(Err("the render device does not run compute shaders".into()));
    }
    let storage = device.limits().max_storage_buffers_per_shader_stage;
    let needed = bvh_cloth_gpu::STORAGE_BUFFERS_NEEDED;
    if storage < needed {
        return Some(Err(format!(
            "the render device allows {storage} storage buffers per shader stage, the kernels need {needed}"
        )));
    }
    Some(Ok(()))
}

/// A cloth the GPU moves keeps the bounds of its first pose on the CPU side; it opts out of
/// frustum culling instead, so that it never vanishes while in view.
fn gpu_cloths_skip_culling(
    mut commands: Commands,
    cloths: Query<Entity, (With<ClothSimulation>, Without<NoFrustumCulling>)>,
) {
    for entity in &cloths {
        commands.entity(entity).try_insert(NoFrustumCulling);
    }
}

/// Draws every collider's spheres and boxes with gizmos while
/// [`ClothSettings::debug_view`] is on. Needs Bevy's gizmo plugin.
pub struct ClothDebugViewPlugin;

impl Plugin for ClothDebugViewPlugin {
    fn build(&self, app: &mut App) {
        app.add_systems(PostUpdate, debug_view::draw_colliders.after(ClothSystems::Writeback));
    }
}

/// The README's examples, compiled as doctests.
#[cfg(doctest)]
#[doc = include_str!("../../../README.md")]
pub struct ReadmeDoctests;
