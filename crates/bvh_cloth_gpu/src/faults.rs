//! Reading a cloth's fault counter back without stalling a frame loop.
//!
//! One frame records a copy of the counter into a small staging buffer and clears the counter;
//! once that frame's commands are submitted, the staging buffer is asked to map; a later frame
//! takes the count, after wgpu has completed the map (it does when the device is polled, and
//! every submit polls). One read is in flight at a time: frames recorded in between copy
//! nothing, and their faults stay in the counter for the next read.

use std::sync::Arc;
use std::sync::atomic::{AtomicU8, Ordering};

use wgpu::{Buffer, BufferUsages, CommandEncoder, Device, MapMode};

use crate::GpuCloth;

/// Nothing in flight: the next [`FaultReadback::record`] copies.
const IDLE: u8 = 0;
/// The copy is recorded; waiting for the submit.
const RECORDED: u8 = 1;
/// The map is requested.
const MAPPING: u8 = 2;
/// The count can be read.
const MAPPED: u8 = 3;
/// The map failed (the device was lost, or the buffer destroyed).
const FAILED: u8 = 4;

const COUNTER_BYTES: u64 = size_of::<u32>() as u64;

/// A non-blocking read of one cloth's count of quarantined particles (see
/// [`GpuCloth::faults`]): [`record`](Self::record) with the frame's commands,
/// [`submitted`](Self::submitted) after they are submitted, [`take`](Self::take) on a later
/// frame.
#[derive(Debug)]
pub struct FaultReadback {
    staging: Buffer,
    phase: Arc<AtomicU8>,
}

impl FaultReadback {
    /// A readback with its own staging buffer, idle.
    pub fn new(device: &Device) -> Self {
        let staging = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("bvh_cloth_faults_readback"),
            size: COUNTER_BYTES,
            usage: BufferUsages::MAP_READ | BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Self { staging, phase: Arc::new(AtomicU8::new(IDLE)) }
    }

    /// Records into `encoder` a copy of `cloth`'s counter, then the counter's clearing, unless a
    /// read is already in flight. Returns whether it recorded.
    pub fn record(&self, encoder: &mut CommandEncoder, cloth: &GpuCloth) -> bool {
        if self.phase.compare_exchange(IDLE, RECORDED, Ordering::AcqRel, Ordering::Acquire).is_err() {
            return false;
        }
        encoder.copy_buffer_to_buffer(cloth.faults(), 0, &self.staging, 0, COUNTER_BYTES);
        encoder.clear_buffer(cloth.faults(), 0, None);
        true
    }

    /// Asks for the map of a recorded copy. Call it after the encoder given to
    /// [`Self::record`] was submitted; it does nothing otherwise.
    pub fn submitted(&self) {
        if self.phase.compare_exchange(RECORDED, MAPPING, Ordering::AcqRel, Ordering::Acquire).is_ok() {
            let phase = Arc::clone(&self.phase);
            self.staging.slice(..).map_async(MapMode::Read, move |result| {
                phase.store(if result.is_ok() { MAPPED } else { FAILED }, Ordering::Release);
            });
        }
    }

    /// The count copied by the last [`Self::record`], once its map has completed; then the
    /// readback is idle again. `None` while the read is in flight, when nothing was recorded,
    /// or when the map failed.
    pub fn take(&self) -> Option<u32> {
        match self.phase.load(Ordering::Acquire) {
            MAPPED => {
                let count = bytemuck::pod_read_unaligned(&self.staging.slice(..).get_mapped_range()[..]);
                self.staging.unmap();
                self.phase.store(IDLE, Ordering::Release);
                Some(count)
            }
            FAILED => {
                self.phase.store(IDLE, Ordering::Release);
                None
            }
            _ => None,
        }
    }
}
