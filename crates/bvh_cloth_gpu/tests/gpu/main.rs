//! The GPU crate's integration tests, in one binary so that the crate and wgpu are linked
//! once for all of them: the WGSL against the Rust layouts (`layout`, no GPU needed), the real
//! kernels against the CPU reference (`on_device`) and devices smaller than the work
//! (`device_limits`).

mod device_limits;
mod layout;
mod on_device;
