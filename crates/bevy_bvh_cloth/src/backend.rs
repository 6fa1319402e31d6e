//! Which backend steps the cloths: the GPU kernels where the device runs compute shaders,
//! otherwise the CPU stepper.

use bevy::prelude::*;

/// The backend a game asks for. Read once, when the app starts (insert it before
/// `App::run`); later changes have no effect.
///
/// ```no_run
/// # use bevy::prelude::*;
/// # use bevy_bvh_cloth::prelude::*;
/// // The CPU stepper whatever the device: every cloth's state is live in the main world.
/// App::new()
///     .insert_resource(ClothBackend::Cpu)
///     .add_plugins((DefaultPlugins, BvhClothPlugins::default()))
///     .run();
/// ```
#[derive(Resource, Clone, Copy, Debug, Default, PartialEq, Eq, Reflect)]
#[reflect(Resource, Default, Debug)]
pub enum ClothBackend {
    /// The GPU where the render device runs compute shaders, otherwise the CPU (with one
    /// warning saying why).
    #[default]
    Auto,
    /// The GPU; falls back to the CPU with an error when the device cannot run the kernels.
    Gpu,
    /// The CPU stepper, always.
    Cpu,
}

/// The backend actually in use, decided at start-up from [`ClothBackend`] and the device.
#[derive(Resource, Clone, Copy, Debug, Default, PartialEq, Eq, Reflect)]
#[reflect(Resource, Default, Debug)]
pub enum ActiveClothBackend {
    /// The core's rayon stepper in the main world, writing the `Mesh` asset.
    #[default]
    Cpu,
    /// The WGSL kernels in the render world, writing the mesh's vertex buffer directly.
    Gpu,
}

impl ActiveClothBackend {
    /// Its name, as the panel and [`crate::ClothStats`] show it.
    pub fn name(self) -> &'static str {
        match self {
            Self::Cpu => "CPU",
            Self::Gpu => "GPU",
        }
    }

    /// The backend the plugin runs for `requested` on a renderer that offers `gpu`: `Ok` where
    /// the device runs the kernels, the reason where it does not, `None` for an app without a
    /// renderer. A fallback to the CPU is logged once, as a warning for
    /// [`ClothBackend::Auto`] and as an error for an explicit [`ClothBackend::Gpu`]; without a
    /// renderer `Auto` takes the CPU silently.
    pub fn choose(requested: ClothBackend, gpu: Option<Result<(), String>>) -> Self {
        match (requested, gpu) {
            (ClothBackend::Cpu, _) => Self::Cpu,
            (_, Some(Ok(()))) => Self::Gpu,
            (ClothBackend::Auto, None) => Self::Cpu,
            (ClothBackend::Auto, Some(Err(reason))) => {
                warn!("bevy_bvh_cloth: {reason}; simulating cloth on the CPU");
                Self::Cpu
            }
            (ClothBackend::Gpu, gpu) => {
                let reason = gpu.and_then(Result::err).unwrap_or_else(|| "the app has no renderer".into());
                error!("bevy_bvh_cloth: the GPU backend was asked for, but {reason}; simulating cloth on the CPU");
                Self::Cpu
            }
        }
    }
}

pub(crate) fn cpu_backend_active(active: Res<ActiveClothBackend>) -> bool {
    *active == ActiveClothBackend::Cpu
}
