//! Reading a cloth's GPU buffers back without stalling a frame loop.
//!
//! One frame records a copy of a buffer into a staging buffer; once that frame's commands are
//! submitted, the staging buffer is asked to map; a later frame takes the data, after wgpu has
//! completed the map (it does when the device is polled, and every submit polls). One read per
//! staging buffer is in flight at a time: frames recorded in between copy nothing.
//!
//! | type | what it reads |
//! |---|---|
//! | [`FaultReadback`] | a cloth's count of quarantined particles (and clears it) |
//! | [`ParticleReadback`] | a cloth's whole state: positions and velocities |
//! | [`PassTimer`] | the GPU time of one compute pass, from two timestamp queries |

use core::time::Duration;
use std::sync::Arc;
use std::sync::atomic::{AtomicU8, Ordering};

use crate::layout::GpuParticle;
use wgpu::{Buffer, BufferUsages, CommandEncoder, ComputePassTimestampWrites, Device, MapMode, Queue};

use crate::{ClothBatch, ClothId};

/// Nothing in flight: the next record copies.
const IDLE: u8 = 0;
/// The copy is recorded; waiting for the submit.
const RECORDED: u8 = 1;
/// The map is requested.
const MAPPING: u8 = 2;
/// The data can be read.
const MAPPED: u8 = 3;
/// The map failed (the device was lost, or the buffer destroyed).
const FAILED: u8 = 4;

const COUNTER_BYTES: u64 = size_of::<u32>() as u64;

/// A staging buffer and the phase of its one read in flight.
#[derive(Debug)]
struct Staged {
    buffer: Buffer,
    phase: Arc<AtomicU8>,
}

impl Staged {
    fn new(device: &Device, label: &str, size: u64) -> Self {
        let buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size,
            usage: BufferUsages::MAP_READ | BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Self { buffer, phase: Arc::new(AtomicU8::new(IDLE)) }
    }

    /// Claims the staging buffer for a copy this frame; `false` while a read is in flight.
    fn begin(&self) -> bool {
        self.phase.compare_exchange(IDLE, RECORDED, Ordering::AcqRel, Ordering::Acquire).is_ok()
    }

    fn submitted(&self) {
        if self.phase.compare_exchange(RECORDED, MAPPING, Ordering::AcqRel, Ordering::Acquire).is_ok() {
            let phase = Arc::clone(&self.phase);
            self.buffer.slice(..).map_async(MapMode::Read, move |result| {
                phase.store(if result.is_ok() { MAPPED } else { FAILED }, Ordering::Release);
            });
        }
    }

    fn take<T>(&self, read: impl FnOnce(&[u8]) -> T) -> Option<T> {
        match self.phase.load(Ordering::Acquire) {
            MAPPED => {
                let value = read(&self.buffer.slice(..).get_mapped_range()[..]);
                self.buffer.unmap();
                self.phase.store(IDLE, Ordering::Release);
                Some(value)
            }
            FAILED => {
                self.phase.store(IDLE, Ordering::Release);
                None
            }
            _ => None,
        }
    }
}

/// A non-blocking read of one cloth's count of quarantined particles (see
/// [`ClothBatch::faults`]): [`record`](Self::record) with the frame's commands,
/// [`submitted`](Self::submitted) after they are submitted, [`take`](Self::take) on a later
/// frame. Faults counted while a read is in flight stay in the counter for the next read.
#[derive(Debug)]
pub struct FaultReadback(Staged);

impl FaultReadback {
    /// A readback with its own staging buffer, idle.
    pub fn new(device: &Device) -> Self {
        Self(Staged::new(device, "bvh_cloth_faults_readback", COUNTER_BYTES))
    }

    /// Records into `encoder` a copy of cloth `id`'s counter, then the counter's clearing,
    /// unless a read is already in flight (or `id` is not in `batch`). Returns whether it
    /// recorded.
    pub fn record(&self, encoder: &mut CommandEncoder, batch: &ClothBatch, id: ClothId) -> bool {
        let Some((buffer, offset)) = batch.faults(id) else { return false };
        if !self.0.begin() {
            return false;
        }
        encoder.copy_buffer_to_buffer(buffer, offset, &self.0.buffer, 0, COUNTER_BYTES);
        encoder.clear_buffer(buffer, offset, Some(COUNTER_BYTES));
        true
    }

    /// Asks for the map of a recorded copy. Call it after the encoder given to
    /// [`Self::record`] was submitted; it does nothing otherwise.
    pub fn submitted(&self) {
        self.0.submitted();
    }

    /// The count copied by the last [`Self::record`], once its map has completed; then the
    /// readback is idle again. `None` while the read is in flight, when nothing was recorded,
    /// or when the map failed.
    pub fn take(&self) -> Option<u32> {
        self.0.take(bytemuck::pod_read_unaligned)
    }
}

/// A non-blocking read of one cloth's particles (positions and velocities, in world space), as
/// they are at the end of the frame that recorded it: [`record`](Self::record) with the frame's
/// commands, [`submitted`](Self::submitted) after the submit, [`take`](Self::take) on a later
/// frame (usually the next, or the one after).
#[derive(Debug)]
pub struct ParticleReadback(Staged);

impl ParticleReadback {
    /// A readback sized for `particles` particles, idle.
    pub fn new(device: &Device, particles: usize) -> Self {
        Self(Staged::new(device, "bvh_cloth_particles_readback", (particles.max(1) * size_of::<GpuParticle>()) as u64))
    }

    /// Records into `encoder` a copy of cloth `id`'s particles, unless a read is already in
    /// flight (or `id` is not in `batch`, or has another particle count than this readback
    /// was made for). Returns whether it recorded.
    pub fn record(&self, encoder: &mut CommandEncoder, batch: &ClothBatch, id: ClothId) -> bool {
        let Some((buffer, offset, size)) = batch.particles(id) else { return false };
        if size != self.0.buffer.size() || !self.0.begin() {
            return false;
        }
        encoder.copy_buffer_to_buffer(buffer, offset, &self.0.buffer, 0, size);
        true
    }

    /// Asks for the map of a recorded copy, as [`FaultReadback::submitted`].
    pub fn submitted(&self) {
        self.0.submitted();
    }

    /// The particles copied by the last [`Self::record`], once the map has completed.
    pub fn take(&self) -> Option<Vec<GpuParticle>> {
        self.0.take(bytemuck::pod_collect_to_vec)
    }
}

/// Bytes of two resolved timestamps.
const TIMESTAMP_BYTES: u64 = 2 * size_of::<u64>() as u64;

/// A non-blocking measure of one compute pass's GPU time, from timestamp queries written at its
/// start and end: [`begin`](Self::begin) gives the pass its timestamp writes,
/// [`record`](Self::record) after the pass resolves them into a staging copy,
/// [`submitted`](Self::submitted) after the submit, [`take`](Self::take) on a later frame. One
/// measure is in flight at a time: passes recorded in between run untimed.
#[derive(Debug)]
pub struct PassTimer {
    queries: wgpu::QuerySet,
    resolved: Buffer,
    staged: Staged,
    /// Nanoseconds per timestamp tick ([`Queue::get_timestamp_period`]).
    period: f32,
}

impl PassTimer {
    /// A timer, idle; `None` when `device` was not created with
    /// [`wgpu::Features::TIMESTAMP_QUERY`] (a browser's WebGL2, some mobile GPUs).
    pub fn new(device: &Device, queue: &Queue) -> Option<Self> {
        if !device.features().contains(wgpu::Features::TIMESTAMP_QUERY) {
            return None;
        }
        let queries = device.create_query_set(&wgpu::QuerySetDescriptor {
            label: Some("bvh_cloth_pass_timer"),
            ty: wgpu::QueryType::Timestamp,
            count: 2,
        });
        let resolved = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("bvh_cloth_pass_timer_resolved"),
            size: TIMESTAMP_BYTES,
            usage: BufferUsages::QUERY_RESOLVE | BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let staged = Staged::new(device, "bvh_cloth_pass_timer_readback", TIMESTAMP_BYTES);
        Some(Self { queries, resolved, staged, period: queue.get_timestamp_period() })
    }

    /// Claims the timer for a pass recorded this frame: the timestamp writes to give it, or
    /// `None` while a measure is in flight (the pass then runs untimed).
    pub fn begin(&self) -> Option<ComputePassTimestampWrites<'_>> {
        self.staged.begin().then_some(ComputePassTimestampWrites {
            query_set: &self.queries,
            beginning_of_pass_write_index: Some(0),
            end_of_pass_write_index: Some(1),
        })
    }

    /// Records into `encoder`, after the pass that [`Self::begin`] timed, the resolve of its
    /// timestamps and their copy; does nothing when no pass was claimed this frame.
    pub fn record(&self, encoder: &mut CommandEncoder) {
        if self.staged.phase.load(Ordering::Acquire) != RECORDED {
            return;
        }
        encoder.resolve_query_set(&self.queries, 0..2, &self.resolved, 0);
        encoder.copy_buffer_to_buffer(&self.resolved, 0, &self.staged.buffer, 0, TIMESTAMP_BYTES);
    }

    /// Asks for the map of a recorded measure, as [`FaultReadback::submitted`].
    pub fn submitted(&self) {
        self.staged.submitted();
    }

    /// The timed pass's GPU time, once the map has completed.
    pub fn take(&self) -> Option<Duration> {
        let period = f64::from(self.period);
        self.staged.take(|bytes| {
            let [start, end]: [u64; 2] = bytemuck::pod_read_unaligned(bytes);
            Duration::from_nanos((end.saturating_sub(start) as f64 * period) as u64)
        })
    }
}
