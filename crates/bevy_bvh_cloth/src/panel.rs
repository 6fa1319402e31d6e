//! The live parameter panel (feature `egui`): the paper's Looper, SpringK, Damping and
//! External Force, plus pause, reset, the wind, each cloth's integrator, self-contact and
//! aerodynamics, the collider resolution (or voxel size) and contact, the debug view and live
//! figures.

use core::ops::DerefMut;

use bevy::prelude::*;
use bevy_egui::{EguiContexts, EguiPlugin, EguiPrimaryContextPass, egui};
use bvh_cloth_core::backend::MAX_ITERATIONS;
use bvh_cloth_core::backend::particle_spacing;

use crate::{
    Aerodynamics, AmbientWind, AutoCollider, Cloth, ClothSettings, ClothShape, ClothSimulation, ClothStats,
    ColliderContact, ColliderStatus, Integrator, ResetCloth, SelfContact,
};

/// Adds the panel (and [`EguiPlugin`] if the app has none).
pub struct ClothPanelPlugin;

impl Plugin for ClothPanelPlugin {
    fn build(&self, app: &mut App) {
        if !app.is_plugin_added::<EguiPlugin>() {
            app.add_plugins(EguiPlugin::default());
        }
        app.add_systems(EguiPrimaryContextPass, cloth_panel);
    }
}

/// Shows `edit` on a copy of `value` and writes it back only when it changed, so that an idle
/// panel does not trigger change detection every frame.
fn edit_in_place<T: Clone + PartialEq>(value: &mut impl DerefMut<Target = T>, edit: impl FnOnce(&mut T)) {
    let mut copy = (**value).clone();
    edit(&mut copy);
    if copy != **value {
        **value = copy;
    }
}

fn cloth_panel(
    mut contexts: EguiContexts,
    mut settings: ResMut<ClothSettings>,
    mut wind: ResMut<AmbientWind>,
    stats: Res<ClothStats>,
    mut cloths: Query<(Entity, &mut Cloth, Option<&ClothSimulation>)>,
    mut colliders: Query<(Entity, &mut AutoCollider, &ColliderStatus)>,
    mut resets: MessageWriter<ResetCloth>,
) -> Result {
    egui::Window::new("Cloth").default_width(280.0).show(contexts.ctx_mut()?, |ui| {
        ui.label(format!("Backend: {}", stats.backend));
        ui.label(format!(
            "{} particles in {} cloth(s), {} spheres in {} collider(s)",
            stats.particles, stats.cloths, stats.spheres, stats.colliders
        ));
        if let Some((time, ticks)) = stats.gpu_time {
            ui.label(format!("Simulation: {:.2} ms on the GPU for {ticks} ticks", time.as_secs_f64() * 1e3));
        } else if stats.step_time.is_zero() {
            ui.label(format!("Simulation: {} ticks this frame", stats.ticks));
        } else {
            ui.label(format!(
                "Simulation: {:.2} ms this frame ({} ticks)",
                stats.step_time.as_secs_f64() * 1e3,
                stats.ticks
            ));
        }
        ui.separator();

        edit_in_place(&mut settings, |s| {
            ui.horizontal(|ui| {
                ui.checkbox(&mut s.paused, "Pause");
                ui.checkbox(&mut s.debug_view, "Show BVH");
            });
        });
        if ui.button("Reset cloth (R)").clicked() {
            resets.write(ResetCloth::All);
        }
        ui.separator();
        edit_in_place(&mut wind, |w| {
            let wind = &mut w.0;
            // Speed and heading in the horizontal plane; the vertical part is kept.
            // The velocity is rewritten only when a slider moves, so that the round trip through
            // the angle does not change an idle wind every frame.
            let horizontal = Vec2::new(wind.velocity.x, wind.velocity.z);
            let mut speed = horizontal.length();
            let mut heading = horizontal.y.atan2(horizontal.x).to_degrees();
            let moved = ui.add(egui::Slider::new(&mut speed, 0.0..=30.0).text("Wind (m/s)")).changed()
                | ui.add(egui::Slider::new(&mut heading, -180.0..=180.0).text("Wind heading (°)")).changed();
            if moved {
                let (sin, cos) = heading.to_radians().sin_cos();
                wind.velocity = Vec3::new(speed * cos, wind.velocity.y, speed * sin);
            }
            ui.add(egui::Slider::new(&mut wind.gust_strength, 0.0..=1.0).text("Gusts"));
            ui.add(egui::Slider::new(&mut wind.turbulence, 0.0..=10.0).text("Turbulence (m/s)"));
        });

        for (entity, mut cloth, simulation) in &mut cloths {
            // The thickest self-contact the cloth accepts: its particle spacing (5 cm until the
            // cloth is built).
            let spacing = simulation.map_or(0.05, |s| particle_spacing(s.sim().topology()));
            // The cloth's rest area, to show its weight per square metre (none until built).
            let area = simulation.map(|s| s.sim().topology().rest_area()).filter(|&a| a > 0.0);
            ui.separator();
            let shape = match &cloth.shape {
                ClothShape::Grid { size, particles } => {
                    format!("{} x {} particles, {:.2} x {:.2} m", particles.x, particles.y, size.x, size.y)
                }
                ClothShape::Mesh => "its mesh".into(),
            };
            ui.label(format!("Cloth {entity}: {shape}"));
            edit_in_place(&mut cloth, |c| {
                ui.add(egui::Slider::new(&mut c.params.looper, 1..=64).text("Looper"));
                ui.add(egui::Slider::new(&mut c.params.spring_k, 10.0..=400.0).logarithmic(true).text("SpringK (N/m)"));
                ui.add(egui::Slider::new(&mut c.params.damping, 0.0..=10.0).text("Damping (1/s)"));
                // The fabric's weight: moving it sets the density, which keeps the fabric when
                // the cloth is resized.
                if let Some(area) = area {
                    let mut density = c.params.density.unwrap_or(c.params.mass / area);
                    let slider = egui::Slider::new(&mut density, 0.01..=2.0).logarithmic(true).text("Fabric (kg/m²)");
                    if ui.add(slider).changed() {
                        c.params.density = Some(density);
                    }
                }
                ui.label("External Force (N)");
                ui.horizontal(|ui| {
                    for (axis, value) in ["x", "y", "z"].into_iter().zip(c.params.external_force.as_mut()) {
                        ui.add(egui::DragValue::new(value).speed(0.05).range(-20.0..=20.0).prefix(format!("{axis} ")));
                    }
                });
                ui.horizontal(|ui| {
                    ui.radio_value(&mut c.params.integrator, Integrator::Rk4, "RK4");
                    ui.radio_value(&mut c.params.integrator, Integrator::SemiImplicitEuler, "Semi-implicit Euler");
                    let descent = matches!(c.params.integrator, Integrator::BlockDescent { .. });
                    if ui.radio(descent, "Block descent").clicked() && !descent {
                        c.params.integrator = Integrator::BLOCK_DESCENT;
                    }
                    ui.radio_value(&mut c.params.integrator, Integrator::Multigrid, "Multigrid");
                });
                if let Integrator::BlockDescent { iterations } = &mut c.params.integrator {
                    ui.add(egui::Slider::new(iterations, 1..=MAX_ITERATIONS).text("Iterations per substep"));
                }
                let mut air = c.params.aerodynamics.is_active();
                if ui.checkbox(&mut air, "Aerodynamics (feels the wind)").changed() {
                    c.params.aerodynamics = if air { Aerodynamics::FABRIC } else { Aerodynamics::NONE };
                }
                if air {
                    ui.add(egui::Slider::new(&mut c.params.aerodynamics.drag, 0.0..=3.0).text("Drag coefficient"));
                    ui.add(egui::Slider::new(&mut c.params.aerodynamics.lift, 0.0..=3.0).text("Lift coefficient"));
                }
                let mut contact = c.params.self_contact.is_some();
                if ui.checkbox(&mut contact, "Self-contact").changed() {
                    c.params.self_contact = contact.then(SelfContact::default);
                }
                if let Some(contact) = &mut c.params.self_contact {
                    // 0 is the cloth's own: half its particle spacing.
                    ui.add(
                        egui::Slider::new(&mut contact.thickness, 0.0..=spacing.max(0.002))
                            .text("Thickness (m, 0: half the spacing)"),
                    );
                    ui.add(egui::Slider::new(&mut contact.friction, 0.0..=1.0).text("Friction between layers"));
                }
            });
        }

        for (entity, mut collider, status) in &mut colliders {
            ui.separator();
            let state = match status {
                ColliderStatus::Ready { spheres, inner_nodes } => format!("{spheres} spheres, {inner_nodes} boxes"),
                ColliderStatus::Failed(reason) => format!("failed: {reason}"),
                other => format!("{other:?}"),
            };
            ui.label(format!("Collider {entity}: {state}"));
            edit_in_place(&mut collider, |c| {
                match &mut c.voxel_size {
                    Some(size) => ui.add(egui::Slider::new(size, 0.01..=0.2).text("Voxel size (m)")),
                    None => ui.add(egui::Slider::new(&mut c.resolution, 1..=32).text("Voxels per axis (n)")),
                };
                let mut exact = c.contact == ColliderContact::Exact;
                if ui.checkbox(&mut exact, "Exact contact (triangles, not spheres)").changed() {
                    c.contact = if exact { ColliderContact::Exact } else { ColliderContact::Spheres };
                }
                ui.add(egui::Slider::new(&mut c.friction, 0.0..=1.5).text("Friction"));
            });
        }
    });
    Ok(())
}
