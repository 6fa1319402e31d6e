//! The storage buffers the batch and its stages create, and the spacing of their dynamic
//! uniforms.

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
