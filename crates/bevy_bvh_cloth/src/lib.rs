//! # bevy_bvh_cloth
//!
//! Real-time mass-spring cloth for Bevy, with colliders nobody has to set up by hand: put
//! [`AutoCollider`] on any entity with a [`Mesh3d`] and the mesh is voxelised into spheres
//! arranged in a Morton-code LBVH, after Mei, Fan, Zhang and Liu, *A Collision Detection and
//! Cloth Simulation Method Based on Parallel BVH*. The math lives in [`bvh_cloth_core`], which
//! knows nothing of Bevy.
//!
//! ## Getting started
//!
//! ```no_run
//! use bevy::prelude::*;
//! use bevy_bvh_cloth::prelude::*;
//!
//! fn main() {
//!     App::new()
//!         .add_plugins((DefaultPlugins, BvhClothPlugins))
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
//!     // A 64 x 64 cloth, 2 m wide, one metre above the ball. The plugin gives it its mesh.
//!     commands.spawn((
//!         Cloth::new(64, 64, 2.0),
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
//! Everything runs in [`PostUpdate`], after transform propagation, in the chained
//! [`ClothSystems`] sets. A fixed-rate clock ([`ClothSettings::tick_rate`]) decides how many
//! whole ticks a frame runs, and each tick runs [`Cloth::looper`] substeps, so a cloth behaves
//! the same at 30 and at 144 frames per second.
//!
//! ## Features
//!
//! | feature | what it adds |
//! |---|---|
//! | `egui` | [`ClothPanelPlugin`](panel::ClothPanelPlugin): a live panel for Looper, SpringK, Damping, External Force, the collider resolution, pause, reset and the debug view |
//!
//! ## When things go wrong
//!
//! Nothing the plugin is fed makes it panic. Invalid [`Cloth`] parameters, meshes that cannot
//! become colliders, and cloths whose state diverges are logged and reported as
//! [`ClothMessage`]s; the rest of the scene keeps running.

#![deny(missing_docs)]

mod clock;
mod cloth;
mod cloth_mesh;
mod collider;
mod collider_mesh;
mod cpu_backend;
mod debug_view;
mod messages;
#[cfg(feature = "egui")]
pub mod panel;
mod settings;
mod simulation;
mod stats;

use bevy::app::PluginGroupBuilder;
use bevy::camera::visibility::VisibilitySystems;
use bevy::prelude::*;
use bevy::transform::TransformSystems;

pub use bvh_cloth_core;
pub use clock::ClothClock;
pub use cloth::{Cloth, ClothIntegrator, ClothPins, SpringScales};
pub use collider::{ASYNC_BUILD_MIN_VERTICES, AutoCollider, ClothCollider, ColliderStatus};
pub use collider_mesh::ColliderFailure;
pub use messages::{ClothMessage, ResetCloth};
pub use settings::ClothSettings;
pub use simulation::ClothSimulation;
pub use stats::ClothStats;

/// Everything a game needs, in one `use`.
pub mod prelude {
    #[cfg(feature = "egui")]
    pub use crate::panel::ClothPanelPlugin;
    pub use crate::{
        AutoCollider, BvhClothPlugin, BvhClothPlugins, Cloth, ClothClock, ClothDebugViewPlugin, ClothIntegrator,
        ClothMessage, ClothPins, ClothSettings, ClothSimulation, ClothStats, ClothSystems, ColliderStatus, ResetCloth,
        SpringScales,
    };
}

/// The plugins of `bevy_bvh_cloth`: [`BvhClothPlugin`] (the simulation) and
/// [`ClothDebugViewPlugin`] (gizmos; it needs Bevy's gizmo plugin, part of `DefaultPlugins`).
/// The egui panel is added separately, see [`panel`](crate#features).
pub struct BvhClothPlugins;

impl PluginGroup for BvhClothPlugins {
    fn build(self) -> PluginGroupBuilder {
        PluginGroupBuilder::start::<Self>().add(BvhClothPlugin).add(ClothDebugViewPlugin)
    }
}

/// The system sets of the plugin, all in [`PostUpdate`] after
/// [`TransformSystems::Propagate`], chained in this order. Order your own systems against them.
#[derive(SystemSet, Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ClothSystems {
    /// [`AutoCollider`]s are built (or their async builds polled) and placed at their
    /// entity's [`GlobalTransform`].
    BuildColliders,
    /// The clock advances, and [`Cloth`] changes and [`ResetCloth`] requests are applied.
    Prepare,
    /// The cloths are stepped.
    Step,
    /// The results are written into the cloth meshes.
    Writeback,
}

/// The simulation: [`Cloth`] and [`AutoCollider`] components, stepped on the CPU.
///
/// Needs Bevy's asset, mesh and transform plugins (all part of `DefaultPlugins`; with
/// `MinimalPlugins`, add `AssetPlugin`, `MeshPlugin` and `TransformPlugin`).
pub struct BvhClothPlugin;

impl Plugin for BvhClothPlugin {
    fn build(&self, app: &mut App) {
        app.register_type::<Cloth>()
            .register_type::<AutoCollider>()
            .register_type::<ColliderStatus>()
            .register_type::<ClothSettings>()
            .register_type::<ClothClock>()
            .register_type::<ClothStats>()
            .init_resource::<ClothSettings>()
            .init_resource::<ClothClock>()
            .init_resource::<ClothStats>()
            .add_message::<ClothMessage>()
            .add_message::<ResetCloth>()
            .configure_sets(
                PostUpdate,
                (ClothSystems::BuildColliders, ClothSystems::Prepare, ClothSystems::Step, ClothSystems::Writeback)
                    .chain()
                    .after(TransformSystems::Propagate)
                    .before(VisibilitySystems::CheckVisibility),
            )
            .add_systems(
                PostUpdate,
                (
                    (collider::build_colliders, collider::update_collider_poses)
                        .chain()
                        .in_set(ClothSystems::BuildColliders),
                    (clock::advance_clock, simulation::sync_cloths).in_set(ClothSystems::Prepare),
                    cpu_backend::step_cloths.in_set(ClothSystems::Step),
                    cpu_backend::write_back_cloths.in_set(ClothSystems::Writeback),
                ),
            );
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
