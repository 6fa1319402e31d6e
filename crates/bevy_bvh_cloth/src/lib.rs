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
//!   has [`ClothReadback`] (then [`ClothSimulation`] is two or three frames late; without it,
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
mod colliders;
mod cpu_backend;
mod debug_view;
mod events;
mod messages;
#[cfg(feature = "egui")]
pub mod panel;
mod render;
mod schedule;
mod settings;
mod wind;

use bevy::app::PluginGroupBuilder;
use bevy::ecs::schedule::{InternedScheduleLabel, ScheduleLabel};
use bevy::prelude::*;

pub use backend::{ActiveClothBackend, ClothBackend};
pub use bvh_cloth_core;
pub use bvh_cloth_core::{
    Aerodynamics, ClothError, ClothParams, ClothPins, ColliderError, CollisionLayers, ColorChannel, Integrator,
    SelfContact, SpringStiffness, Tethers, Wind,
};
pub use clock::ClothClock;
pub use cloth::ClothPlugin;
pub use cloth::component::{Cloth, ClothAnchor, ClothPart, ClothShape};
pub use cloth::hierarchy::{ClothHierarchy, JointAnchor, SceneCloth};
pub use cloth::simulation::ClothSimulation;
pub use cloth::skin::ClothSkin;
pub use cloth::stats::ClothStats;
pub use colliders::ColliderPlugin;
pub use colliders::auto::{ASYNC_BUILD_MIN_VERTICES, AutoCollider, ClothCollider, ColliderContact, ColliderStatus};
pub use colliders::hierarchy::{ColliderHierarchy, ColliderPart, ExcludeFromColliders};
pub use colliders::mesh::collider_from_mesh;
pub use colliders::primitive::{PrimitiveCollider, PrimitiveShape};
pub use cpu_backend::CpuBackendPlugin;
pub use events::{
    AnchorLost, ClothDiverged, ClothHierarchyReady, ClothRejected, ColliderFailed, ColliderHierarchyReady,
    ColliderReady, NameNotFound, SceneNotSpawned, WindNotFelt, WindSourceRejected,
};
pub use messages::{ClothMessage, ColliderFailure, ResetCloth};
pub use render::GpuBackendPlugin;
pub use render::readback::ClothReadback;
pub use schedule::{ClothSchedulePlugin, ClothSystems};
pub use settings::ClothSettings;
pub use wind::{AmbientWind, LocalWind, WindBlast, WindFan, WindPlugin};

/// Everything a game needs, in one `use`.
pub mod prelude {
    #[cfg(feature = "egui")]
    pub use crate::panel::ClothPanelPlugin;
    pub use crate::{
        ActiveClothBackend, Aerodynamics, AmbientWind, AnchorLost, AutoCollider, BvhClothPlugin, BvhClothPlugins,
        Cloth, ClothAnchor, ClothBackend, ClothClock, ClothCollider, ClothDebugViewPlugin, ClothDiverged, ClothError,
        ClothHierarchy, ClothHierarchyReady, ClothMessage, ClothParams, ClothPart, ClothPins, ClothReadback,
        ClothRejected, ClothSettings, ClothShape, ClothSimulation, ClothSkin, ClothStats, ClothSystems,
        ColliderContact, ColliderError, ColliderFailed, ColliderHierarchy, ColliderHierarchyReady, ColliderPart,
        ColliderReady, ColliderStatus, CollisionLayers, ColorChannel, ExcludeFromColliders, Integrator, JointAnchor,
        LocalWind, NameNotFound, PrimitiveCollider, PrimitiveShape, ResetCloth, SceneCloth, SceneNotSpawned,
        SelfContact, SpringStiffness, Tethers, Wind, WindBlast, WindFan, WindNotFelt, WindSourceRejected,
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
        PluginGroupBuilder::start::<Self>().add_group(BvhClothPlugin::new(self.schedule)).add(ClothDebugViewPlugin)
    }
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
///
/// It is a group of one plugin per concern, each adding its own systems to the schedule:
/// [`ClothSchedulePlugin`] (the system sets, the clock, settings and messages),
/// [`ColliderPlugin`], [`ClothPlugin`], [`WindPlugin`], [`CpuBackendPlugin`] and
/// [`GpuBackendPlugin`] (the render world). They work together; a game adds the group.
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

impl PluginGroup for BvhClothPlugin {
    fn build(self) -> PluginGroupBuilder {
        let schedule = self.schedule;
        PluginGroupBuilder::start::<Self>()
            .add(ClothSchedulePlugin::new(schedule))
            .add(ColliderPlugin::new(schedule))
            .add(ClothPlugin::new(schedule))
            .add(WindPlugin::new(schedule))
            .add(CpuBackendPlugin::new(schedule))
            .add(GpuBackendPlugin::new(schedule))
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
