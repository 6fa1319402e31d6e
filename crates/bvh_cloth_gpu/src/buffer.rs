//! The storage buffers the batch, its stages and the colliders create, and the spacing of the
//! dynamic uniforms.

use wgpu::util::DeviceExt;
use wgpu::{Buffer, BufferUsages, Device};

/// Bytes between two dynamic-offset uniforms (the largest alignment wgpu allows a device to
/// ask for).
pub(crate) const UNIFORM_STRIDE: u64 = 256;

/// A storage buffer of at least `bytes` (16 at least) that can be written, copied and read back.
pub(crate) fn storage_buffer(device: &Device, label: &str, bytes: u64) -> Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: bytes.max(16),
        usage: BufferUsages::STORAGE | BufferUsages::COPY_DST | BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    })
}

/// A storage buffer holding `items` (one zeroed item when there is none), that can be written,
/// copied and read back.
pub(crate) fn storage_buffer_with<T: bytemuck::Pod + Default>(device: &Device, label: &str, items: &[T]) -> Buffer {
    // wgpu rejects zero-sized bindings: an empty array is one zeroed element.
    let fallback = [T::default()];
    let contents: &[T] = if items.is_empty() { &fallback } else { items };
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents: bytemuck::cast_slice(contents),
        usage: BufferUsages::STORAGE | BufferUsages::COPY_DST | BufferUsages::COPY_SRC,
    })
}
