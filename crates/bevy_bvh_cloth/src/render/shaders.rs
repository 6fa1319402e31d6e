//! The kernels' WGSL as shader assets, and their pipelines queued on Bevy's pipeline cache
//! (compiled off the render thread) until all of them are ready.

use bevy::prelude::*;
use bevy::render::render_resource::{
    BindGroupLayoutDescriptor, CachedComputePipelineId, CachedPipelineState, ComputePipelineDescriptor, PipelineCache,
};
use bevy::shader::Shader;
use bvh_cloth_gpu::{CONSTANTS_FILE, ClothKernels, SHADER_FILES, shared_constants};

/// The kernels' WGSL files as shader assets, one per [`SHADER_FILES`] entry, then the module of
/// the constants they share with the core, held for the app's lifetime: the pipeline cache
/// compiles the kernels from them, resolving their imports.
#[derive(Resource, Clone)]
pub(crate) struct ClothShaders(Vec<Handle<Shader>>);

impl ClothShaders {
    /// Adds the files to `shaders`.
    pub(crate) fn add(shaders: &mut Assets<Shader>) -> Self {
        let constants = Shader::from_wgsl(shared_constants(), format!("bvh_cloth_gpu/{CONSTANTS_FILE}"));
        let files = SHADER_FILES.iter().map(|(name, text)| Shader::from_wgsl(*text, format!("bvh_cloth_gpu/{name}")));
        Self(files.chain([constants]).map(|shader| shaders.add(shader)).collect())
    }

    fn file(&self, name: &str) -> Option<Handle<Shader>> {
        SHADER_FILES.iter().position(|(file, _)| *file == name).map(|k| self.0[k].clone())
    }
}

/// The kernels' pipelines, queued on Bevy's pipeline cache (compiled off the render thread),
/// and their bind group layouts.
pub(super) struct QueuedKernels {
    pub(super) pipelines: Vec<CachedComputePipelineId>,
    pub(super) layouts: Vec<BindGroupLayoutDescriptor>,
}

impl QueuedKernels {
    pub(super) fn queue(cache: &PipelineCache, shaders: &ClothShaders) -> Option<Self> {
        let descriptors = ClothKernels::descriptors();
        let layouts: Vec<_> = descriptors
            .iter()
            .map(|kernel| BindGroupLayoutDescriptor::new(format!("bvh_cloth_{}", kernel.entry.name()), &kernel.layout))
            .collect();
        let mut pipelines = Vec::with_capacity(descriptors.len());
        for (kernel, layout) in descriptors.iter().zip(&layouts) {
            pipelines.push(cache.queue_compute_pipeline(ComputePipelineDescriptor {
                label: Some(format!("bvh_cloth_{}", kernel.entry.name()).into()),
                layout: vec![layout.clone()],
                immediate_size: 0,
                shader: shaders.file(kernel.file)?,
                shader_defs: Vec::new(),
                entry_point: Some(kernel.entry.name().into()),
                zero_initialize_workgroup_memory: false,
            }));
        }
        Some(Self { pipelines, layouts })
    }

    /// The kernels once every pipeline is compiled; `Err` with the reason if one failed.
    pub(super) fn ready(&self, cache: &PipelineCache) -> Result<Option<ClothKernels>, String> {
        for &id in &self.pipelines {
            if let CachedPipelineState::Err(error) = cache.get_compute_pipeline_state(id) {
                return Err(error.to_string());
            }
        }
        // Queued in `EntryPoint::ALL`'s order, so an entry point's number is its index here.
        Ok(ClothKernels::from_parts(|entry| {
            let pipeline = cache.get_compute_pipeline(self.pipelines[entry as usize])?;
            let layout = cache.get_bind_group_layout(&self.layouts[entry as usize]);
            Some(((**pipeline).clone(), (*layout).clone()))
        }))
    }
}
