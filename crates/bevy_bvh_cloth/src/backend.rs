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
}

/// What the device offers the GPU backend: `Ok`, or why it cannot run the kernels.
pub(crate) type GpuCapability = Result<(), String>;

/// Decides the backend, logging a fallback: once, as a warning for `Auto` and an error for an
/// explicit `Gpu`. With no renderer at all there is nothing to warn about.
pub(crate) fn choose_backend(requested: ClothBackend, gpu: Option<GpuCapability>) -> ActiveClothBackend {
    match (requested, gpu) {
        (ClothBackend::Cpu, _) => ActiveClothBackend::Cpu,
        (_, Some(Ok(()))) => ActiveClothBackend::Gpu,
        (ClothBackend::Auto, None) => ActiveClothBackend::Cpu,
        (ClothBackend::Auto, Some(Err(reason))) => {
            warn!("bevy_bvh_cloth: {reason}; simulating cloth on the CPU");
            ActiveClothBackend::Cpu
        }
        (ClothBackend::Gpu, gpu) => {
            let reason = gpu.and_then(Result::err).unwrap_or_else(|| "the app has no renderer".into());
            error!("bevy_bvh_cloth: the GPU backend was asked for, but {reason}; simulating cloth on the CPU");
            ActiveClothBackend::Cpu
        }
    }
}

pub(crate) fn cpu_backend_active(active: Res<ActiveClothBackend>) -> bool {
    *active == ActiveClothBackend::Cpu
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn falls_back_to_the_cpu_without_compute_shaders() {
        let no_compute = || Some(Err("the device does not run compute shaders".to_string()));
        assert_eq!(choose_backend(ClothBackend::Auto, Some(Ok(()))), ActiveClothBackend::Gpu);
        assert_eq!(choose_backend(ClothBackend::Auto, no_compute()), ActiveClothBackend::Cpu);
        assert_eq!(choose_backend(ClothBackend::Auto, None), ActiveClothBackend::Cpu);
        assert_eq!(choose_backend(ClothBackend::Gpu, no_compute()), ActiveClothBackend::Cpu);
        assert_eq!(choose_backend(ClothBackend::Gpu, None), ActiveClothBackend::Cpu);
        assert_eq!(choose_backend(ClothBackend::Cpu, Some(Ok(()))), ActiveClothBackend::Cpu);
    }
}
