//! A device without a window, and blocking readback: for tests and benchmarks, never for a
//! frame loop.

use bytemuck::Pod;
use wgpu::{Buffer, BufferUsages, Device, Queue};

use crate::kernels::ClothKernels;

/// A device without a window, with the instance and adapter it came from.
#[derive(Debug)]
pub struct HeadlessGpu {
    /// The instance; its [`wgpu::Instance::generate_report`] counts live GPU resources.
    pub instance: wgpu::Instance,
    /// The adapter.
    pub adapter: wgpu::Adapter,
    /// The device.
    pub device: Device,
    /// Its queue.
    pub queue: Queue,
}

/// A device on the first adapter `WGPU_BACKEND` (or the platform default) offers, with all of
/// the adapter's limits and its timestamp queries where it has them, or `None` when there is
/// none.
pub fn device() -> Option<HeadlessGpu> {
    device_with_limits(|limits| limits)
}

/// As [`device`], with the limits `limit` makes of the adapter's: lower ones stand in for a
/// smaller device.
pub fn device_with_limits(limit: impl FnOnce(wgpu::Limits) -> wgpu::Limits) -> Option<HeadlessGpu> {
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
    let adapter =
        futures_lite::future::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions::default())).ok()?;
    let (device, queue) = futures_lite::future::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        label: Some("bvh_cloth_headless"),
        required_limits: limit(adapter.limits()),
        required_features: adapter.features() & wgpu::Features::TIMESTAMP_QUERY,
        ..Default::default()
    }))
    .ok()?;
    Some(HeadlessGpu { instance, adapter, device, queue })
}

/// A device with the kernels compiled on it: what the GPU tests and the benchmark report drive.
#[derive(Debug)]
pub struct KernelRig {
    /// The device.
    pub device: Device,
    /// Its queue.
    pub queue: Queue,
    /// The kernels, compiled on the device.
    pub kernels: ClothKernels,
    /// The adapter's name, type and driver.
    pub info: wgpu::AdapterInfo,
}

impl KernelRig {
    /// Whether the adapter is a software rasteriser such as lavapipe, which runs on the CPU's
    /// cores: a correctness device, never a timing one.
    pub fn is_software(&self) -> bool {
        self.info.device_type == wgpu::DeviceType::Cpu
    }
}

/// [`device`] with the kernels compiled on it, or `None` without an adapter. Panics when the
/// kernels do not fit the adapter's device.
pub fn kernel_rig() -> Option<KernelRig> {
    let HeadlessGpu { adapter, device, queue, .. } = device()?;
    let kernels = ClothKernels::new(&device).expect("the kernels fit the device");
    Some(KernelRig { device, queue, kernels, info: adapter.get_info() })
}

/// Copies `buffer` (which needs `COPY_SRC`) into memory, waiting for the GPU.
pub fn read<T: Pod>(device: &Device, queue: &Queue, buffer: &Buffer) -> Vec<T> {
    read_range(device, queue, buffer, 0, buffer.size())
}

/// Copies `size` bytes of `buffer` (which needs `COPY_SRC`) from `offset` into memory, waiting
/// for the GPU; both are multiples of [`wgpu::COPY_BUFFER_ALIGNMENT`].
pub fn read_range<T: Pod>(device: &Device, queue: &Queue, buffer: &Buffer, offset: u64, size: u64) -> Vec<T> {
    let staging = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("bvh_cloth_readback"),
        size,
        usage: BufferUsages::MAP_READ | BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut encoder = device.create_command_encoder(&Default::default());
    encoder.copy_buffer_to_buffer(buffer, offset, &staging, 0, size);
    queue.submit([encoder.finish()]);
    staging.slice(..).map_async(wgpu::MapMode::Read, |result| result.expect("mapping a readback buffer"));
    device.poll(wgpu::PollType::Wait { submission_index: None, timeout: None }).expect("waiting for the GPU");
    let out = bytemuck::cast_slice(&staging.slice(..).get_mapped_range()).to_vec();
    staging.unmap();
    out
}

/// Waits until the GPU has finished everything submitted so far.
pub fn wait(device: &Device) {
    device.poll(wgpu::PollType::Wait { submission_index: None, timeout: None }).expect("waiting for the GPU");
}
