//! The batch of every cloth on the GPU: [`ClothBatch`].

use std::sync::Arc;

use bvh_cloth_core::backend::AirModel;

use crate::layout::GpuAirCloth;
use crate::layout::{
    GpuBatchCloth, GpuBatchFrame, GpuBatchStep, GpuBatchWriteback, GpuColourPass, GpuMeshWriteback, GpuParticle,
    GpuWritebackGroup, INTEGRATOR_BLOCK_DESCENT, NO_CLOTH, gpu_particle_info, gpu_particles, gpu_surface_words,
    gpu_tether_ends,
};
use bvh_cloth_core::backend::AirSource;
use bvh_cloth_core::backend::MAX_COLOURS;
use bvh_cloth_core::backend::MAX_ITERATIONS;
use bvh_cloth_core::backend::ParticleColouring;
use bvh_cloth_core::backend::TetherSet;
use bvh_cloth_core::{
    Aerodynamics, ClothError, ClothParams, ClothSim, ClothTopology, Integrator, Vec3, Wind, WindSource,
};
use wgpu::util::DeviceExt;
use wgpu::{BindGroup, Buffer, BufferUsages, CommandEncoder, Device, Queue};

use crate::air::{AirFrame, AirPlan};
use crate::buffer::{UNIFORM_STRIDE, storage_buffer};
use crate::colliders::GpuColliders;
use crate::contact::{ContactCloth, ContactPlan, SharedBuffers};
use crate::kernels::{ClothKernels, Kernel, KernelError, WORKGROUP_SIZE, storage_binding_limit};

/// A cloth in a [`ClothBatch`], valid until it is removed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ClothId(u32);

/// Most substeps one tick may run ([`bvh_cloth_core::backend::MAX_SUBSTEPS_PER_TICK`]).
const MAX_SUBSTEPS: u32 = bvh_cloth_core::backend::MAX_SUBSTEPS_PER_TICK;

/// One cloth of the batch.
#[derive(Debug)]
struct Slot {
    topology: Arc<ClothTopology>,
    particle_start: u32,
    ends_start: u32,
    surface_start: u32,
    constants: GpuBatchCloth,
    /// Pinned particles: `apply_anchors` targets per tick at most.
    pins: u32,
    /// This frame's anchor targets per tick, particle indices relative to the cloth.
    targets: Vec<Vec<(u32, Vec3)>>,
    /// The cloth's state, waiting for the next rebuild or first upload.
    pending_state: Option<Vec<GpuParticle>>,
    /// Where `normal_shader` writes the cloth this frame: the layout, and the vertex buffer.
    writeback: Option<(GpuMeshWriteback, Buffer)>,
    /// The substeps its own parameters ask for, and the tick they were given for: a cloth with
    /// self-contact takes the largest count among the contact cloths instead.
    own_substeps: u32,
    tick_seconds: f32,
    /// How it catches the air, its mass, and its ambient wind.
    aerodynamics: Aerodynamics,
    mass: f32,
    wind: Wind,
    /// Whether no particle with mass is pinned ([`ClothSim::is_free_body`]).
    free_body: bool,
    /// Each particle's nearest pin and rest distance ([`ClothSim::tethers`]).
    tethers: Arc<TetherSet>,
}

impl Slot {
    fn surface_len(&self) -> u32 {
        surface_len(&self.topology)
    }

    /// Entries of the spring-end buffer the cloth takes: its springs, then its tethers.
    fn ends_len(&self) -> u32 {
        (self.topology.spring_ends().len() + self.tethers.pin.len()) as u32
    }

    /// Where the cloth's tethers start in the spring-end buffer.
    fn tether_start(&self) -> u32 {
        self.ends_start + self.topology.spring_ends().len() as u32
    }
}

fn surface_len(topology: &ClothTopology) -> u32 {
    (topology.vertex_particle().len()
        + topology.len()
        + 1
        + topology.triangle_list().len()
        + 3 * topology.triangles().len()) as u32
}

/// The shared buffers, sized in elements.
#[derive(Debug)]
struct Buffers {
    particles: u32,
    ends: u32,
    surface: u32,
    cloths: u32,
    base: Buffer,
    stage_a: Buffer,
    stage_b: Buffer,
    slope_sum: Buffer,
    info: Buffer,
    colour_list: Buffer,
    /// Block descent's drift sums, one per 64 particle slots.
    drift_blocks: Buffer,
    spring_ends: Buffer,
    surface_words: Buffer,
    cloth_constants: Buffer,
    writebacks: Buffer,
}

impl Buffers {
    fn new(device: &Device, particles: u32, ends: u32, surface: u32, cloths: u32) -> Self {
        let storage = |label: &str, bytes: u64| storage_buffer(device, label, bytes);
        let particle_bytes = u64::from(particles) * size_of::<GpuParticle>() as u64;
        Self {
            particles,
            ends,
            surface,
            cloths,
            base: storage("bvh_cloth_particles", particle_bytes),
            stage_a: storage("bvh_cloth_stage_a", particle_bytes),
            stage_b: storage("bvh_cloth_stage_b", particle_bytes),
            slope_sum: storage("bvh_cloth_slope_sum", particle_bytes),
            info: storage("bvh_cloth_particle_info", u64::from(particles) * 16),
            colour_list: storage("bvh_cloth_colour_list", u64::from(particles) * 4),
            drift_blocks: storage("bvh_cloth_drift_blocks", u64::from(particles.div_ceil(64)) * 16),
            spring_ends: storage("bvh_cloth_spring_ends", u64::from(ends) * 16),
            surface_words: storage("bvh_cloth_surface", u64::from(surface) * 4),
            cloth_constants: storage("bvh_cloth_cloths", u64::from(cloths) * size_of::<GpuBatchCloth>() as u64),
            writebacks: storage("bvh_cloth_mesh_writebacks", u64::from(cloths) * size_of::<GpuBatchWriteback>() as u64),
        }
    }
}

/// This frame's anchor targets: tick `k`'s start at `k * stride` bytes.
#[derive(Debug)]
struct AnchorTargets {
    buffer: Buffer,
    stride: u64,
    /// Ticks the buffer has room for.
    ticks: u32,
}

/// One `normal_shader` dispatch: the cloths written into one vertex buffer.
#[derive(Debug)]
struct WritebackGroup {
    vertices: Buffer,
    /// The cloths, in the order their vertices follow one another among the threads.
    cloths: Vec<u32>,
    bind_group: BindGroup,
    workgroups: (u32, u32),
}

/// The writeback dispatches. Their bind groups hold what they share: the owner of each thread
/// (its cloth) and each group's constants.
#[derive(Debug)]
struct Writebacks {
    groups: Vec<WritebackGroup>,
}

/// Bind groups that stay valid until the buffers (or the colliders') are replaced.
#[derive(Debug)]
struct Groups {
    /// The collider buffers they were made with.
    colliders: (Buffer, Buffer),
    /// The anchor buffer they were made with.
    anchors: Option<Buffer>,
    stages: [BindGroup; 3],
    last: BindGroup,
    predict: BindGroup,
    solve: BindGroup,
    finish: BindGroup,
    /// The two levels of the drift sums.
    drift: [BindGroup; 2],
    apply_anchors: Option<BindGroup>,
    /// Self-contact's kernels, when a cloth has it.
    contact: Option<[BindGroup; 8]>,
    /// Aerodynamics' kernels, when a cloth has drag or lift.
    air: Option<[BindGroup; 4]>,
}

/// One colour of the colour list: where it starts, how many particles it has, and the
/// workgroups of its dispatch.
#[derive(Debug, PartialEq)]
struct ColourRange {
    start: u32,
    count: u32,
    workgroups: (u32, u32),
}

/// The block-descent dispatches of the batch, and what they were written for.
#[derive(Debug, Default)]
struct DescentPlan {
    /// The block-descent cloths: slot, first particle and the address of its shape.
    cloths: Vec<(u32, u32, usize)>,
    colours: Vec<ColourRange>,
    /// Most iterations and substeps of any block-descent cloth.
    iterations: u32,
    substeps: u32,
    /// Whether a block-descent cloth is held by nothing, so that its drift is summed.
    free_bodies: bool,
}

/// Every cloth on the GPU in one batch: shared, packed buffers, and one dispatch per integrator
/// stage for all of them.
///
/// A cloth's particles are a range of the shared particle buffers, its spring ends a range of
/// the spring-end buffer, its surface a range of the surface buffer, and its constants one
/// [`GpuBatchCloth`]; every index stored inside those ranges is relative to the cloth's own
/// start, so a range can move without rewriting it. A tick is one `apply_anchors` dispatch,
/// then for each substep RK4's three `node_update` stages and `node_update_final` (the last
/// stage fused with the collision response), each one dispatch over every particle slot.
///
/// A block-descent cloth takes, per substep, `vbd_predict` over every slot, one `vbd_solve`
/// dispatch per iteration and colour, and `vbd_finish` (with the collision response). Its
/// particles are listed colour by colour in the colour list: colour `k` of every block-descent
/// cloth, then colour `k + 1`, so one dispatch updates one colour of all of them. The list is
/// written again when the set of block-descent cloths, or where they lie, changes.
///
/// The substeps run in step: substep `k` of the explicit cloths, then of the block-descent
/// cloths, then self-contact for the cloths that have it (`contact_begin` before the
/// integrators; see the `contact` module), so that contact sees every integrator's result.
/// The cloths with self-contact all take the largest substep count among them.
///
/// Cloths that need different substep counts share the tick: the batch runs the largest count,
/// and a cloth sits out the substeps past its own (each cloth keeps its own substep length, so
/// its trajectory is the one it would have alone, and the CPU stepper's). A semi-implicit Euler
/// cloth integrates in the first stage and lands in the last; the other two skip it. Every
/// cloth collides with every collider the batch is prepared with ([`ClothBatch::prepare`]), as
/// every cloth of a scene does on the CPU.
///
/// Adding a cloth writes its ranges at the end of the used space. When that is full, the
/// buffers are rebuilt, larger where needed and with the live cloths packed together: their
/// state is copied on the GPU (a submitted copy, which the CPU never waits for) and their
/// shapes uploaded again. Removing a cloth marks its particles as no cloth's; the space comes
/// back at the next rebuild. Other cloths' state is never touched.
#[derive(Debug)]
pub struct ClothBatch {
    slots: Vec<Option<Slot>>,
    /// Used extents of the particle, spring-end and surface buffers.
    used: (u32, u32, u32),
    buffers: Buffers,
    frame: Buffer,
    steps: Buffer,
    anchors: Option<AnchorTargets>,
    groups: Option<Groups>,
    /// The writeback dispatches, kept while the cloths write into the same vertex buffers.
    writebacks: Option<Writebacks>,
    /// One uniform entry per block-descent iteration and colour: entry
    /// `iteration * MAX_COLOURS + colour`.
    colour_passes: Buffer,
    /// The block-descent dispatches, `None` until written for the current buffers.
    descent: Option<DescentPlan>,
    /// Self-contact's buffers, `None` while no cloth has self-contact (or they did not fit
    /// the device: [`Self::contact_error`]).
    contact: Option<ContactPlan>,
    contact_error: Option<KernelError>,
    /// Why the cloths with drag or lift run without them, if they do (their buffer would not
    /// fit the device: [`Self::air_error`]).
    air_error: Option<KernelError>,
    /// Aerodynamics' buffers, `None` while no cloth has drag or lift; the wind sources; and
    /// the wind clock of the coming frame: the first tick's time, the tick length, the ticks.
    air: Option<AirPlan>,
    wind_sources: Vec<AirSource>,
    wind_clock: (f64, f64, u32),
    /// Workgroups of the integrator dispatches, and the batch's substeps per tick for the
    /// explicit integrators.
    workgroups: (u32, u32),
    substeps: u32,
    /// Anchor targets per tick this frame.
    anchor_count: u32,
}

impl ClothBatch {
    /// An empty batch.
    pub fn new(device: &Device, queue: &Queue) -> Self {
        let frame = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("bvh_cloth_frame"),
            size: size_of::<GpuBatchFrame>() as u64,
            usage: BufferUsages::UNIFORM | BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        // One entry per substep and stage: entry 3k + s is substep k's stage s.
        let entries = u64::from(MAX_SUBSTEPS) * 3;
        let steps = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("bvh_cloth_steps"),
            size: entries * UNIFORM_STRIDE,
            usage: BufferUsages::UNIFORM | BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut bytes = vec![0u8; (entries * UNIFORM_STRIDE) as usize];
        for k in 0..MAX_SUBSTEPS {
            for stage in 0..3 {
                let step = GpuBatchStep { substep: k, stage, _pad: [0; 2] };
                let at = (u64::from(3 * k + stage) * UNIFORM_STRIDE) as usize;
                bytes[at..at + size_of::<GpuBatchStep>()].copy_from_slice(bytemuck::bytes_of(&step));
            }
        }
        queue.write_buffer(&steps, 0, &bytes);
        let colour_passes = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("bvh_cloth_colour_passes"),
            size: u64::from(MAX_ITERATIONS * MAX_COLOURS) * UNIFORM_STRIDE,
            usage: BufferUsages::UNIFORM | BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Self {
            slots: Vec::new(),
            used: (0, 0, 0),
            buffers: Buffers::new(device, 64, 64, 64, 4),
            frame,
            steps,
            anchors: None,
            groups: None,
            writebacks: None,
            colour_passes,
            descent: None,
            contact: None,
            contact_error: None,
            air_error: None,
            air: None,
            wind_sources: Vec::new(),
            wind_clock: (0.0, 0.0, 1),
            workgroups: (1, 1),
            substeps: 0,
            anchor_count: 0,
        }
    }

    /// Adds `sim` (its shape, pins and current state) to the batch. It runs once
    /// [`Self::set_params`] has given it its constants. Refused, leaving the batch as it was,
    /// when the batch would outgrow the device.
    pub fn insert(&mut self, device: &Device, queue: &Queue, sim: &ClothSim) -> Result<ClothId, KernelError> {
        let topology = Arc::clone(sim.topology());
        let (n, s) = (topology.len() as u32, surface_len(&topology));
        ClothKernels::workgroups(device, topology.vertex_particle().len() as u32)?;
        ClothKernels::workgroups(device, self.used.0.saturating_add(n))?;
        let slot = Slot {
            topology,
            particle_start: 0,
            ends_start: 0,
            surface_start: 0,
            constants: GpuBatchCloth::default(),
            pins: sim.pins().len() as u32,
            targets: Vec::new(),
            pending_state: Some(gpu_particles(sim)),
            writeback: None,
            own_substeps: 0,
            tick_seconds: 0.0,
            aerodynamics: sim.params().aerodynamics,
            mass: sim.params().mass,
            wind: *sim.wind(),
            free_body: sim.is_free_body(),
            tethers: Arc::clone(sim.tethers()),
        };
        let e = slot.ends_len();
        let index = match self.slots.iter().position(Option::is_none) {
            Some(free) => free,
            None => self.slots.len(),
        };
        let fits = self.used.0.checked_add(n).is_some_and(|p| p <= self.buffers.particles)
            && self.used.1 + e <= self.buffers.ends
            && self.used.2 + s <= self.buffers.surface
            && (index as u32) < self.buffers.cloths;
        if index == self.slots.len() {
            self.slots.push(None);
        }
        self.slots[index] = Some(slot);
        if fits {
            let (p, e0, s0) = self.used;
            self.place(queue, index, p, e0, s0);
            self.used = (p + n, e0 + e, s0 + s);
        } else if let Err(error) = self.rebuild(device, queue) {
            self.slots[index] = None;
            return Err(error);
        }
        self.refresh_workgroups(device)?;
        Ok(ClothId(index as u32))
    }

    /// Writes slot `index`'s shape, constants and pending state at the given starts.
    fn place(&mut self, queue: &Queue, index: usize, particle_start: u32, ends_start: u32, surface_start: u32) {
        let Some(slot) = self.slots[index].as_mut() else { return };
        slot.particle_start = particle_start;
        slot.ends_start = ends_start;
        slot.surface_start = surface_start;
        slot.constants.particle_start = particle_start;
        slot.constants.ends_start = ends_start;
        slot.constants.tether_start = slot.tether_start();
        let b = &self.buffers;
        queue.write_buffer(
            &b.info,
            u64::from(particle_start) * 16,
            bytemuck::cast_slice(&gpu_particle_info(&slot.topology, index as u32)),
        );
        queue.write_buffer(
            &b.spring_ends,
            u64::from(ends_start) * 16,
            bytemuck::cast_slice(slot.topology.spring_ends()),
        );
        queue.write_buffer(
            &b.spring_ends,
            u64::from(slot.tether_start()) * 16,
            bytemuck::cast_slice(&gpu_tether_ends(&slot.tethers)),
        );
        queue.write_buffer(
            &b.surface_words,
            u64::from(surface_start) * 4,
            bytemuck::cast_slice(&gpu_surface_words(&slot.topology)),
        );
        queue.write_buffer(
            &b.cloth_constants,
            index as u64 * size_of::<GpuBatchCloth>() as u64,
            &bytemuck::bytes_of(&slot.constants)[..GpuBatchCloth::HOST_BYTES as usize],
        );
        if let Some(state) = slot.pending_state.take() {
            queue.write_buffer(
                &b.base,
                u64::from(particle_start) * size_of::<GpuParticle>() as u64,
                bytemuck::cast_slice(&state),
            );
        }
    }

    /// New buffers with the live cloths packed from the start, each about twice what they
    /// use; the live cloths' state copied over on the GPU. The fault counts start again from
    /// zero.
    fn rebuild(&mut self, device: &Device, queue: &Queue) -> Result<(), KernelError> {
        let (n, e, s) = self.slots.iter().flatten().fold((0u64, 0u64, 0u64), |(n, e, s), slot| {
            (n + slot.topology.len() as u64, e + u64::from(slot.ends_len()), s + u64::from(slot.surface_len()))
        });
        let max = storage_binding_limit(device);
        let particle_size = size_of::<GpuParticle>() as u64;
        for (count, size) in [(n, particle_size), (e, 16), (s, 4)] {
            if count * size > max {
                return Err(KernelError::BufferTooLarge { bytes: count * size, max });
            }
        }
        // Twice the need where that fits a binding, the need where only that does.
        let room = |needed: u64, size: u64| {
            u32::try_from((2 * needed).max(64).min(max / size).max(needed)).unwrap_or(u32::MAX)
        };
        let particles = room(n, particle_size);
        let cloths = (self.slots.len() as u32).saturating_mul(2).max(4);
        let old =
            std::mem::replace(&mut self.buffers, Buffers::new(device, particles, room(e, 16), room(s, 4), cloths));
        // Every particle slot is no cloth's until a cloth is placed on it.
        queue.write_buffer(&self.buffers.info, 0, bytemuck::cast_slice(&vec![[NO_CLOTH; 4]; particles as usize]));
        let mut encoder =
            device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("bvh_cloth_rebuild") });
        let mut used = (0u32, 0u32, 0u32);
        for index in 0..self.slots.len() {
            let Some(slot) = self.slots[index].as_ref() else { continue };
            let (len, ends, surface) = (slot.topology.len() as u32, slot.ends_len(), slot.surface_len());
            if slot.pending_state.is_none() {
                // The state, and block descent's acceleration estimates (kept in the inertial
                // target's buffer between substeps).
                for (from, to) in [(&old.base, &self.buffers.base), (&old.stage_b, &self.buffers.stage_b)] {
                    encoder.copy_buffer_to_buffer(
                        from,
                        u64::from(slot.particle_start) * particle_size,
                        to,
                        u64::from(used.0) * particle_size,
                        u64::from(len) * particle_size,
                    );
                }
            }
            self.place(queue, index, used.0, used.1, used.2);
            used = (used.0 + len, used.1 + ends, used.2 + surface);
        }
        // The writes above run before this submit's copies, which touch only the ranges of
        // cloths that had a state on the GPU (the writes fill the others').
        queue.submit([encoder.finish()]);
        self.used = used;
        self.groups = None;
        self.writebacks = None;
        self.descent = None;
        self.contact = None;
        self.air = None;
        Ok(())
    }

    fn refresh_workgroups(&mut self, device: &Device) -> Result<(), KernelError> {
        self.workgroups = ClothKernels::workgroups(device, self.used.0)?;
        Ok(())
    }

    /// Takes a cloth out of the batch. The other cloths are not touched; its space is reused
    /// at the next rebuild (or at once when it was the last placed).
    pub fn remove(&mut self, queue: &Queue, id: ClothId) {
        let Some(slot) = self.slots.get_mut(id.0 as usize).and_then(Option::take) else { return };
        let len = slot.topology.len() as u32;
        queue.write_buffer(
            &self.buffers.info,
            u64::from(slot.particle_start) * 16,
            bytemuck::cast_slice(&vec![[NO_CLOTH; 4]; len as usize]),
        );
        let inactive = GpuBatchCloth::default();
        queue.write_buffer(
            &self.buffers.cloth_constants,
            u64::from(id.0) * size_of::<GpuBatchCloth>() as u64,
            &bytemuck::bytes_of(&inactive)[..GpuBatchCloth::HOST_BYTES as usize],
        );
        if slot.particle_start + len == self.used.0
            && slot.ends_start + slot.ends_len() == self.used.1
            && slot.surface_start + slot.surface_len() == self.used.2
        {
            self.used = (slot.particle_start, slot.ends_start, slot.surface_start);
        }
        while matches!(self.slots.last(), Some(None)) {
            self.slots.pop();
        }
    }

    /// Whether `id` names a cloth of the batch.
    pub fn contains(&self, id: ClothId) -> bool {
        self.slot(id).is_some()
    }

    /// Number of cloths.
    pub fn len(&self) -> usize {
        self.slots.iter().flatten().count()
    }

    /// Whether the batch has no cloth.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    fn slot(&self, id: ClothId) -> Option<&Slot> {
        self.slots.get(id.0 as usize).and_then(Option::as_ref)
    }

    /// The shape `id` was added with.
    pub fn topology(&self, id: ClothId) -> Option<&Arc<ClothTopology>> {
        self.slot(id).map(|slot| &slot.topology)
    }

    /// Gives `id` its constants for ticks of `tick_seconds`: the substep count and length the
    /// CPU stepper would use (stability guard included). Parameters that fail
    /// [`ClothParams::validate_for`] on the cloth's shape are ignored: it keeps its last ones.
    pub fn set_params(&mut self, queue: &Queue, id: ClothId, params: &ClothParams, tick_seconds: f32) {
        let Some(slot) = self.slots.get_mut(id.0 as usize).and_then(Option::as_mut) else { return };
        if params.validate_for(&slot.topology).is_err() {
            return;
        }
        let substeps = params.substeps(tick_seconds, &slot.topology).min(MAX_SUBSTEPS);
        let h = tick_seconds / substeps as f32;
        slot.constants = GpuBatchCloth::new(params, &slot.topology, slot.particle_start, slot.ends_start, substeps, h);
        slot.constants.free_body = u32::from(slot.free_body);
        slot.constants.tether_start = slot.tether_start();
        slot.constants.tether_scale = match (params.integrator, params.tethers) {
            (Integrator::BlockDescent { .. }, Some(tethers)) if !slot.tethers.is_empty() => 1.0 + tethers.slack,
            _ => 0.0,
        };
        slot.own_substeps = substeps;
        slot.tick_seconds = tick_seconds;
        slot.aerodynamics = params.aerodynamics;
        slot.mass = params.mass;
        queue.write_buffer(
            &self.buffers.cloth_constants,
            u64::from(id.0) * size_of::<GpuBatchCloth>() as u64,
            &bytemuck::bytes_of(&slot.constants)[..GpuBatchCloth::HOST_BYTES as usize],
        );
    }

    /// Sets `id`'s ambient wind (see [`bvh_cloth_core::air`]); only a cloth with drag
    /// or lift feels it. Refused, keeping the last one, when it is invalid.
    pub fn set_wind(&mut self, id: ClothId, wind: Wind) -> Result<(), ClothError> {
        wind.validate()?;
        if let Some(slot) = self.slots.get_mut(id.0 as usize).and_then(Option::as_mut) {
            slot.wind = wind;
        }
        Ok(())
    }

    /// Sets the wind sources every cloth of the batch is in. Refused, keeping the last ones,
    /// when one is invalid.
    pub fn set_wind_sources(&mut self, sources: &[WindSource]) -> Result<(), ClothError> {
        for source in sources {
            source.validate()?;
        }
        self.wind_sources.clear();
        self.wind_sources.extend(sources.iter().map(WindSource::prepare));
        Ok(())
    }

    /// Sets the wind clock of the coming frame, as [`ClothSim::set_wind_time`] does on the
    /// CPU: its `ticks` ticks of `tick_seconds` start at `start` seconds, and each samples the
    /// wind at its own start. Ticks past `ticks` sample it as the last one does. Call it once
    /// per frame, before [`Self::prepare`].
    pub fn set_wind_clock(&mut self, start: f64, tick_seconds: f32, ticks: u32) {
        if start.is_finite() && tick_seconds.is_finite() {
            self.wind_clock = (start, f64::from(tick_seconds), ticks.max(1));
        }
    }

    /// Substeps per tick `id` runs under its last parameters (for a cloth with self-contact,
    /// the most any such cloth of the batch needs, once [`Self::prepare`] has run).
    pub fn substeps(&self, id: ClothId) -> u32 {
        self.slot(id).map_or(0, |slot| slot.constants.substeps)
    }

    /// Where `id`'s pinned particles go in each tick of the coming frame: `ticks[k]` holds tick
    /// `k`'s `(index, world position)` pairs, indices into the cloth, at most one per pin (as
    /// [`ClothSim::pin_targets`] gives them), applied at the start of that tick, as the CPU
    /// stepper's [`ClothSim::move_pins`]. Pins, and ticks, without targets stay where they are.
    pub fn set_anchor_targets(&mut self, id: ClothId, ticks: &[Vec<(u32, Vec3)>]) {
        if let Some(slot) = self.slots.get_mut(id.0 as usize).and_then(Option::as_mut) {
            slot.targets.clear();
            slot.targets.extend(ticks.iter().map(|tick| tick.iter().copied().take(slot.pins as usize).collect()));
        }
    }

    /// Replaces `id`'s GPU state with `sim`'s (a reset, or pins moved by the caller), and
    /// clears its fault count.
    pub fn upload_state(&self, queue: &Queue, id: ClothId, sim: &ClothSim) {
        let Some(slot) = self.slot(id) else { return };
        let particles = gpu_particles(sim);
        let count = particles.len().min(slot.topology.len());
        queue.write_buffer(
            &self.buffers.base,
            u64::from(slot.particle_start) * size_of::<GpuParticle>() as u64,
            bytemuck::cast_slice(&particles[..count]),
        );
        queue.write_buffer(&self.buffers.cloth_constants, self.faults_offset(id), bytemuck::bytes_of(&0u32));
    }

    /// Uploads what the coming frame's ticks need: the frame constants, every cloth's anchor
    /// targets, and the bind groups where buffers changed. Call it once per frame, after the
    /// cloths' [`Self::set_params`] and [`Self::set_anchor_targets`] and before
    /// [`Self::encode_ticks`].
    pub fn prepare(&mut self, device: &Device, queue: &Queue, kernels: &ClothKernels, colliders: &GpuColliders) {
        self.prepare_contact(device, queue);
        self.prepare_air(device, queue);
        let explicit = |slot: &&Slot| slot.constants.integrator != INTEGRATOR_BLOCK_DESCENT;
        self.substeps =
            self.slots.iter().flatten().filter(explicit).map(|slot| slot.constants.substeps).max().unwrap_or(0);
        self.prepare_descent(device, queue);
        self.write_anchor_targets(device, queue);
        let width = self.workgroups.0 * WORKGROUP_SIZE;
        let frame = GpuBatchFrame {
            particle_slots: self.used.0,
            anchor_count: self.anchor_count,
            collider_count: colliders.len(),
            dispatch_width: width,
        };
        queue.write_buffer(&self.frame, 0, bytemuck::bytes_of(&frame));
        self.prepare_writebacks(device, queue, kernels);
        let key = (colliders.frames.clone(), colliders.tree.clone());
        let anchors = self.anchors.as_ref().map(|a| a.buffer.clone());
        if self.groups.as_ref().is_none_or(|g| g.colliders != key || g.anchors != anchors) {
            self.groups = Some(self.bind_groups(device, kernels, key, anchors));
        }
    }

    /// Gives every cloth with self-contact the largest substep count among them, as
    /// [`ClothSim::tick_together`] does, and writes the contact buffers when the contact cloths,
    /// or where they lie, changed; the contact constants every frame.
    fn prepare_contact(&mut self, device: &Device, queue: &Queue) {
        let in_contact = |slot: &Slot| slot.constants.contact_thickness > 0.0;
        let substeps = self.slots.iter().flatten().filter(|s| in_contact(s)).map(|s| s.own_substeps).max().unwrap_or(0);
        let mut thickest = 0.0f32;
        for (index, slot) in self.slots.iter_mut().enumerate() {
            let Some(slot) = slot.as_mut().filter(|slot| in_contact(slot)) else { continue };
            thickest = thickest.max(slot.constants.contact_thickness);
            if slot.constants.substeps != substeps {
                slot.constants.substeps = substeps;
                slot.constants.h = slot.tick_seconds / substeps as f32;
                queue.write_buffer(
                    &self.buffers.cloth_constants,
                    index as u64 * size_of::<GpuBatchCloth>() as u64,
                    &bytemuck::bytes_of(&slot.constants)[..GpuBatchCloth::HOST_BYTES as usize],
                );
            }
        }
        let cloths: Vec<(ContactCloth, &ClothTopology)> = self
            .slots
            .iter()
            .enumerate()
            .filter_map(|(index, slot)| Some((index as u32, slot.as_ref().filter(|slot| in_contact(slot))?)))
            .map(|(index, slot)| ((index, slot.particle_start, Arc::as_ptr(&slot.topology) as usize), &*slot.topology))
            .collect();
        if cloths.is_empty() {
            if self.contact.take().is_some() {
                self.groups = None;
            }
            self.contact_error = None;
            return;
        }
        let same = self.contact.as_ref().is_some_and(|plan| {
            plan.particle_capacity == self.buffers.particles
                && plan.cloths.len() == cloths.len()
                && plan.cloths.iter().zip(&cloths).all(|(a, (b, _))| a == b)
        });
        if !same {
            self.groups = None;
            match ContactPlan::new(device, queue, &cloths, self.buffers.particles) {
                Ok(plan) => {
                    self.contact = Some(plan);
                    self.contact_error = None;
                }
                Err(error) => {
                    self.contact = None;
                    self.contact_error = Some(error);
                }
            }
        }
        if let Some(plan) = self.contact.as_mut() {
            plan.substeps = substeps;
            plan.write_frame(device, queue, self.used.0, thickest);
        }
    }

    /// Writes the air of the coming frame's ticks for the cloths with drag or lift, making the
    /// air buffers when there are none or they no longer fit.
    fn prepare_air(&mut self, device: &Device, queue: &Queue) {
        let active = |slot: &Slot| slot.aerodynamics.is_active();
        if !self.slots.iter().flatten().any(active) {
            if self.air.take().is_some() {
                self.groups = None;
            }
            self.air_error = None;
            return;
        }
        let capacity = self.buffers.cloths as usize;
        let (start, tick_seconds, ticks) = self.wind_clock;
        let mut frame = AirFrame {
            cloths: vec![GpuAirCloth::default(); capacity],
            triangles: 0,
            sources: self.wind_sources.clone(),
            ticks: vec![vec![[0.0; 4]; capacity]; ticks as usize],
            substeps: 0,
            explicit: false,
        };
        // The triangles' forces lie after the wind at every particle slot, in one buffer.
        let first_triangle = self.buffers.particles;
        for (index, slot) in self.slots.iter().enumerate() {
            let Some(slot) = slot.as_ref().filter(|slot| active(slot)) else { continue };
            frame.substeps = frame.substeps.max(slot.constants.substeps);
            frame.explicit |= slot.constants.integrator != INTEGRATOR_BLOCK_DESCENT;
            for (k, words) in frame.ticks.iter_mut().enumerate() {
                let time = start + k as f64 * tick_seconds;
                let model = AirModel::new(slot.aerodynamics, slot.mass, &slot.wind, time);
                if k == 0 {
                    let sources = self.wind_sources.len() as u32;
                    let triangle_start = first_triangle + frame.triangles;
                    frame.cloths[index] =
                        GpuAirCloth::new(&model, &slot.topology, slot.surface_start, triangle_start, sources);
                }
                words[index] = GpuAirCloth::tick_word(&model);
            }
            frame.triangles += slot.topology.triangles().len() as u32;
        }
        if let Err(error) = crate::air::check_state(device, self.buffers.particles, frame.triangles) {
            // The cloths run without drag and lift until their air fits again.
            if self.air.take().is_some() {
                self.groups = None;
            }
            self.air_error = Some(error);
            return;
        }
        self.air_error = None;
        if self.air.as_ref().is_none_or(|plan| !plan.fits(self.buffers.particles, self.buffers.cloths)) {
            self.air = Some(AirPlan::new(device, self.buffers.particles, self.buffers.cloths));
            self.groups = None;
        }
        if let Some(plan) = self.air.as_mut()
            && plan.write(device, queue, &frame)
        {
            self.groups = None;
        }
    }

    /// Why the batch's cloths with drag or lift run without them, if they do: the buffer of
    /// their wind and their triangles' forces would not fit one storage binding of the device.
    pub fn air_error(&self) -> Option<&KernelError> {
        self.air_error.as_ref()
    }

    /// Why the batch's cloths with self-contact run without it, if they do: its buffers would
    /// not fit the device.
    pub fn contact_error(&self) -> Option<&KernelError> {
        self.contact_error.as_ref()
    }

    /// The self-contact statistics buffer (`COPY_SRC`) when a cloth has self-contact: its first
    /// two `u32` words count the contacts (one per free particle taking part in one) and the
    /// bounds met ([`bvh_cloth_core::backend::MAX_CANDIDATES`] and the grid's room) over
    /// the ticks encoded since the last [`Self::prepare`].
    pub fn contact_stats(&self) -> Option<&Buffer> {
        self.contact.as_ref().map(ContactPlan::stats)
    }

    /// Writes the colour list and the colour passes when the block-descent cloths, or where
    /// they lie, changed; updates the plan's iteration and substep counts every frame.
    fn prepare_descent(&mut self, device: &Device, queue: &Queue) {
        let descent: Vec<(u32, &Slot, &ParticleColouring)> = self
            .slots
            .iter()
            .enumerate()
            .filter_map(|(index, slot)| Some((index as u32, slot.as_ref()?)))
            .filter(|(_, slot)| slot.constants.integrator == INTEGRATOR_BLOCK_DESCENT)
            .filter_map(|(index, slot)| Some((index, slot, slot.topology.colouring().ok()?)))
            .collect();
        let cloths: Vec<(u32, u32, usize)> = descent
            .iter()
            .map(|(index, slot, _)| (*index, slot.particle_start, Arc::as_ptr(&slot.topology) as usize))
            .collect();
        let iterations =
            descent.iter().map(|(_, slot, _)| slot.constants.iterations).max().unwrap_or(0).min(MAX_ITERATIONS);
        let substeps = descent.iter().map(|(_, slot, _)| slot.constants.substeps).max().unwrap_or(0);
        let free_bodies = descent.iter().any(|(_, slot, _)| slot.free_body);
        if let Some(plan) = self.descent.as_mut()
            && plan.cloths == cloths
        {
            plan.iterations = iterations;
            plan.substeps = substeps;
            plan.free_bodies = free_bodies;
            return;
        }
        let colours = descent.iter().map(|(_, _, colouring)| colouring.len()).max().unwrap_or(0);
        let mut list = Vec::with_capacity(descent.iter().map(|(_, slot, _)| slot.topology.len()).sum());
        let mut ranges = Vec::with_capacity(colours);
        for k in 0..colours {
            let start = list.len() as u32;
            for (_, slot, colouring) in &descent {
                if k < colouring.len() {
                    list.extend(colouring.colour(k).iter().map(|&i| slot.particle_start + i));
                }
            }
            let count = list.len() as u32 - start;
            // The batch's particles already fit one dispatch, so each colour does too.
            let workgroups = ClothKernels::workgroups(device, count).unwrap_or((1, 1));
            ranges.push(ColourRange { start, count, workgroups });
        }
        queue.write_buffer(&self.buffers.colour_list, 0, bytemuck::cast_slice(&list));
        let mut bytes = vec![0u8; (u64::from(MAX_ITERATIONS) * u64::from(MAX_COLOURS) * UNIFORM_STRIDE) as usize];
        for iteration in 0..MAX_ITERATIONS {
            for (k, range) in ranges.iter().enumerate() {
                let entry = GpuColourPass {
                    start: range.start,
                    count: range.count,
                    iteration,
                    dispatch_width: range.workgroups.0 * WORKGROUP_SIZE,
                };
                let at = ((u64::from(iteration * MAX_COLOURS) + k as u64) * UNIFORM_STRIDE) as usize;
                bytes[at..at + size_of::<GpuColourPass>()].copy_from_slice(bytemuck::bytes_of(&entry));
            }
        }
        queue.write_buffer(&self.colour_passes, 0, &bytes);
        self.descent = Some(DescentPlan { cloths, colours: ranges, iterations, substeps, free_bodies });
    }

    fn write_anchor_targets(&mut self, device: &Device, queue: &Queue) {
        let ticks = self.slots.iter().flatten().map(|slot| slot.targets.len()).max().unwrap_or(0) as u32;
        let per_tick: u32 =
            self.slots.iter().flatten().filter(|slot| !slot.targets.is_empty()).map(|slot| slot.pins).sum();
        self.anchor_count = if ticks == 0 { 0 } else { per_tick };
        if self.anchor_count == 0 {
            return;
        }
        let align = u64::from(device.limits().min_storage_buffer_offset_alignment);
        let stride = (u64::from(per_tick) * 16).div_ceil(align) * align;
        if self.anchors.as_ref().is_none_or(|a| a.ticks < ticks || a.stride < stride) {
            let capacity = ticks.max(4);
            let buffer = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("bvh_cloth_anchor_targets"),
                size: stride * u64::from(capacity),
                usage: BufferUsages::STORAGE | BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            self.anchors = Some(AnchorTargets { buffer, stride, ticks: capacity });
        }
        let Some(anchors) = self.anchors.as_ref() else { return };
        // A pin without a target this tick keeps its slot, naming no particle.
        let unused = [0.0, 0.0, 0.0, f32::from_bits(u32::MAX)];
        let mut words: Vec<[f32; 4]> = vec![unused; (anchors.stride / 16 * u64::from(ticks)) as usize];
        for k in 0..ticks as usize {
            let mut at = k * (anchors.stride / 16) as usize;
            for slot in self.slots.iter().flatten().filter(|slot| !slot.targets.is_empty()) {
                if let Some(targets) = slot.targets.get(k) {
                    for (j, &(i, p)) in targets.iter().enumerate() {
                        words[at + j] = [p.x, p.y, p.z, f32::from_bits(slot.particle_start + i)];
                    }
                }
                at += slot.pins as usize;
            }
        }
        queue.write_buffer(&anchors.buffer, 0, bytemuck::cast_slice(&words));
    }

    fn bind_groups(
        &self,
        device: &Device,
        kernels: &ClothKernels,
        colliders: (Buffer, Buffer),
        anchors: Option<Buffer>,
    ) -> Groups {
        let b = &self.buffers;
        let step = wgpu::BindGroupEntry {
            binding: 1,
            resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                buffer: &self.steps,
                offset: 0,
                size: wgpu::BufferSize::new(size_of::<GpuBatchStep>() as u64),
            }),
        };
        let frame = wgpu::BindGroupEntry { binding: 0, resource: self.frame.as_entire_binding() };
        let stage = |source: &Buffer, target: &Buffer| {
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("bvh_cloth_node_update"),
                layout: &kernels.node_update_layout,
                entries: &[
                    frame.clone(),
                    step.clone(),
                    wgpu::BindGroupEntry { binding: 2, resource: b.base.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 3, resource: source.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 4, resource: b.slope_sum.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 5, resource: target.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 6, resource: b.info.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 7, resource: b.spring_ends.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 8, resource: b.cloth_constants.as_entire_binding() },
                ],
            })
        };
        // y -> a -> b -> a, then the last stage reads a and lands on y, as the CPU stepper.
        let stages = [stage(&b.base, &b.stage_a), stage(&b.stage_a, &b.stage_b), stage(&b.stage_b, &b.stage_a)];
        let last = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("bvh_cloth_node_update_final"),
            layout: &kernels.final_layout,
            entries: &[
                frame.clone(),
                step.clone(),
                wgpu::BindGroupEntry { binding: 3, resource: b.stage_a.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 6, resource: b.info.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 7, resource: b.spring_ends.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 8, resource: b.cloth_constants.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 9, resource: b.base.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 10, resource: b.slope_sum.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 11, resource: colliders.0.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 12, resource: colliders.1.as_entire_binding() },
            ],
        });
        let apply_anchors = self.anchors.as_ref().map(|anchors| {
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("bvh_cloth_anchors"),
                layout: &kernels.anchors_layout,
                entries: &[
                    frame.clone(),
                    wgpu::BindGroupEntry { binding: 13, resource: b.base.as_entire_binding() },
                    wgpu::BindGroupEntry {
                        binding: 14,
                        resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                            buffer: &anchors.buffer,
                            offset: 0,
                            size: wgpu::BufferSize::new(anchors.stride),
                        }),
                    },
                ],
            })
        });
        let colour_pass = wgpu::BindGroupEntry {
            binding: 25,
            resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                buffer: &self.colour_passes,
                offset: 0,
                size: wgpu::BufferSize::new(size_of::<GpuColourPass>() as u64),
            }),
        };
        fn buffer(binding: u32, buffer: &Buffer) -> wgpu::BindGroupEntry<'_> {
            wgpu::BindGroupEntry { binding, resource: buffer.as_entire_binding() }
        }
        let predict_entries = [
            frame.clone(),
            step.clone(),
            buffer(6, &b.info),
            buffer(8, &b.cloth_constants),
            buffer(19, &b.base),
            buffer(20, &b.stage_a),
            buffer(21, &b.stage_b),
        ];
        let predict = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("bvh_cloth_vbd_predict"),
            layout: &kernels.vbd_predict_layout,
            entries: &predict_entries,
        });
        let solve = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("bvh_cloth_vbd_solve"),
            layout: &kernels.vbd_solve_layout,
            entries: &[
                frame.clone(),
                step.clone(),
                buffer(6, &b.info),
                buffer(7, &b.spring_ends),
                buffer(8, &b.cloth_constants),
                buffer(19, &b.base),
                buffer(20, &b.stage_a),
                buffer(21, &b.stage_b),
                buffer(22, &b.colour_list),
                colour_pass,
            ],
        });
        let finish = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("bvh_cloth_vbd_finish"),
            layout: &kernels.vbd_finish_layout,
            entries: &[
                frame.clone(),
                step.clone(),
                buffer(6, &b.info),
                buffer(7, &b.spring_ends),
                buffer(8, &b.cloth_constants),
                buffer(11, &colliders.0),
                buffer(12, &colliders.1),
                buffer(19, &b.base),
                buffer(20, &b.stage_a),
                buffer(21, &b.stage_b),
            ],
        });
        // The prediction's bindings but the inertial target, and the per-block sums (as the
        // kernels' layouts say).
        let drift_entries = [&predict_entries[..6], &[buffer(48, &b.drift_blocks)]].concat();
        let drift = [0, 1].map(|level| {
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("bvh_cloth_vbd_drift"),
                layout: &kernels.vbd_drift_layouts[level],
                entries: &drift_entries,
            })
        });
        let contact = self.contact.as_ref().map(|plan| {
            let shared = SharedBuffers {
                frame: &self.frame,
                particles: &b.base,
                info: &b.info,
                cloths: &b.cloth_constants,
                colliders: (&colliders.0, &colliders.1),
            };
            plan.bind_groups(device, kernels, &shared)
        });
        let air = self.air.as_ref().map(|plan| {
            let shared = crate::air::SharedBuffers {
                frame: &self.frame,
                steps: &self.steps,
                particles: &b.base,
                info: &b.info,
                cloths: &b.cloth_constants,
                surface: &b.surface_words,
                substep_start: &b.stage_a,
                inertial: &b.stage_b,
            };
            plan.bind_groups(device, kernels, &shared)
        });
        Groups { colliders, anchors, stages, last, predict, solve, finish, drift, apply_anchors, contact, air }
    }

    /// Records `ticks` ticks of every cloth: per tick the anchors, then per substep the
    /// integrator stages, the last fused with the collision response, all in one compute pass.
    /// Needs [`Self::prepare`] this frame.
    pub fn encode_ticks(&self, encoder: &mut CommandEncoder, kernels: &ClothKernels, ticks: u32) {
        let mut pass = encoder
            .begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("bvh_cloth_step"), timestamp_writes: None });
        self.dispatch_ticks(kernels, ticks, |_, run| run(&mut pass));
    }

    /// As [`Self::encode_ticks`], with each dispatch in a compute pass of its own whose start
    /// and end are written to `queries` (entries `2k` and `2k + 1` for the `k`th pass): GPU time
    /// per kernel, for profiling on a device with [`wgpu::Features::TIMESTAMP_QUERY`]. Returns
    /// the kernel of each pass in order, or `None` (and records nothing) when `queries` has
    /// fewer than `capacity` entries than that needs.
    pub fn encode_ticks_timed(
        &self,
        encoder: &mut CommandEncoder,
        kernels: &ClothKernels,
        ticks: u32,
        queries: &wgpu::QuerySet,
        capacity: u32,
    ) -> Option<Vec<Kernel>> {
        let mut passes = Vec::new();
        self.dispatch_ticks(kernels, ticks, |kernel, _| passes.push(kernel));
        if 2 * passes.len() as u64 > u64::from(capacity) {
            return None;
        }
        let mut k = 0u32;
        self.dispatch_ticks(kernels, ticks, |_, run| {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("bvh_cloth_timed"),
                timestamp_writes: Some(wgpu::ComputePassTimestampWrites {
                    query_set: queries,
                    beginning_of_pass_write_index: Some(2 * k),
                    end_of_pass_write_index: Some(2 * k + 1),
                }),
            });
            run(&mut pass);
            k += 1;
        });
        Some(passes)
    }

    /// Calls `each` once per dispatch of `ticks` ticks, in order, with the kernel and a function
    /// that records the dispatch into a pass.
    fn dispatch_ticks(
        &self,
        kernels: &ClothKernels,
        ticks: u32,
        mut each: impl FnMut(Kernel, &dyn Fn(&mut wgpu::ComputePass<'_>)),
    ) {
        let Some(groups) = &self.groups else { return };
        let descent = self.descent.as_ref().filter(|plan| plan.substeps > 0 && plan.iterations > 0);
        if ticks == 0 || self.used.0 == 0 || (self.substeps == 0 && descent.is_none()) {
            return;
        }
        let contact = self.contact.as_ref().zip(groups.contact.as_ref()).filter(|(plan, _)| plan.substeps > 0);
        let air = self.air.as_ref().zip(groups.air.as_ref());
        let substeps = self.substeps.max(descent.map_or(0, |plan| plan.substeps));
        let x = self.workgroups.0;
        let written = self.slots.iter().flatten().map(|s| s.targets.len()).max().unwrap_or(0) as u32;
        for tick in 0..ticks {
            if let (Some(group), Some(anchors)) = (&groups.apply_anchors, &self.anchors)
                && tick < written
                && self.anchor_count > 0
            {
                // As wide as every other dispatch, since threads find their index by that width.
                let rows = self.anchor_count.div_ceil(x * WORKGROUP_SIZE * WORKGROUP_SIZE);
                let offset = [(u64::from(tick) * anchors.stride) as u32];
                each(Kernel::ApplyAnchors, &|pass| {
                    pass.set_pipeline(&kernels.anchors);
                    pass.set_bind_group(0, group, &offset);
                    pass.dispatch_workgroups(x, rows, 1);
                });
            }
            if let Some((plan, air_groups)) = air {
                plan.sample(kernels, air_groups, self.workgroups, tick, &mut each);
            }
            // Substep by substep, every integrator in turn, so that contact sees all of them.
            for k in 0..substeps {
                if let Some((plan, air_groups)) = air {
                    plan.kick(kernels, air_groups, self.workgroups, k, &mut each);
                }
                let contact = contact.filter(|(plan, _)| k < plan.substeps);
                if let Some((plan, contact_groups)) = contact {
                    plan.begin(kernels, contact_groups, &mut each);
                }
                self.dispatch_explicit(kernels, groups, k, &mut each);
                if let Some(plan) = descent.filter(|plan| k < plan.substeps) {
                    self.dispatch_descent(kernels, groups, plan, air, k, &mut each);
                }
                if let Some((plan, contact_groups)) = contact {
                    plan.resolve(kernels, contact_groups, &mut each);
                }
            }
        }
    }

    /// Calls `each` with substep `k` of the explicit integrators: RK4's three stages, then the
    /// last one with the collision response.
    fn dispatch_explicit(
        &self,
        kernels: &ClothKernels,
        groups: &Groups,
        k: u32,
        each: &mut impl FnMut(Kernel, &dyn Fn(&mut wgpu::ComputePass<'_>)),
    ) {
        if k >= self.substeps {
            return;
        }
        let (x, y) = self.workgroups;
        let step = |stage: u32| [(u64::from(3 * k + stage) * UNIFORM_STRIDE) as u32];
        for (stage, group) in groups.stages.iter().enumerate() {
            let offset = step(stage as u32);
            each(Kernel::NodeUpdate, &|pass| {
                pass.set_pipeline(&kernels.node_update);
                pass.set_bind_group(0, group, &offset);
                pass.dispatch_workgroups(x, y, 1);
            });
        }
        let offset = step(0);
        each(Kernel::NodeUpdateFinal, &|pass| {
            pass.set_pipeline(&kernels.node_update_final);
            pass.set_bind_group(0, &groups.last, &offset);
            pass.dispatch_workgroups(x, y, 1);
        });
    }

    /// Calls `each` with substep `k` of block descent: the prediction (after the air kick in a
    /// batch with aerodynamics), the sweeps colour by colour, and the finish with the collision
    /// response.
    fn dispatch_descent(
        &self,
        kernels: &ClothKernels,
        groups: &Groups,
        plan: &DescentPlan,
        air: Option<(&AirPlan, &[BindGroup; 4])>,
        k: u32,
        each: &mut impl FnMut(Kernel, &dyn Fn(&mut wgpu::ComputePass<'_>)),
    ) {
        let (x, y) = self.workgroups;
        let offset = [(u64::from(3 * k) * UNIFORM_STRIDE) as u32];
        match air {
            Some((air, air_groups)) => air.predict(kernels, air_groups, self.workgroups, k, each),
            None => each(Kernel::VbdPredict, &|pass| {
                pass.set_pipeline(&kernels.vbd_predict);
                pass.set_bind_group(0, &groups.predict, &offset);
                pass.dispatch_workgroups(x, y, 1);
            }),
        }
        for iteration in 0..plan.iterations {
            for (colour, range) in plan.colours.iter().enumerate() {
                let entry = u64::from(iteration * MAX_COLOURS) + colour as u64;
                let offsets = [offset[0], (entry * UNIFORM_STRIDE) as u32];
                each(Kernel::VbdSolve, &|pass| {
                    pass.set_pipeline(&kernels.vbd_solve);
                    pass.set_bind_group(0, &groups.solve, &offsets);
                    pass.dispatch_workgroups(range.workgroups.0, range.workgroups.1, 1);
                });
            }
        }
        if plan.free_bodies {
            let cloths = self.slots.len() as u32;
            for (level, (pipeline, group)) in kernels.vbd_drift.iter().zip(&groups.drift).enumerate() {
                let (gx, gy) = if level == 0 { (x, y) } else { (cloths, 1) };
                each(Kernel::VbdDrift, &|pass| {
                    pass.set_pipeline(pipeline);
                    pass.set_bind_group(0, group, &offset);
                    pass.dispatch_workgroups(gx, gy, 1);
                });
            }
        }
        each(Kernel::VbdFinish, &|pass| {
            pass.set_pipeline(&kernels.vbd_finish);
            pass.set_bind_group(0, &groups.finish, &offset);
            pass.dispatch_workgroups(x, y, 1);
        });
    }

    /// Sets where [`Self::encode_writebacks`] writes `id` (until it is set again or cleared):
    /// into `vertices` (a storage buffer of `f32` words, such as a mesh's vertex slab), laid out
    /// by `mesh`. All cloths written into one vertex buffer share one dispatch.
    pub fn set_writeback(&mut self, id: ClothId, mesh: GpuMeshWriteback, vertices: &Buffer) {
        if let Some(slot) = self.slots.get_mut(id.0 as usize).and_then(Option::as_mut) {
            slot.writeback = Some((mesh, vertices.clone()));
        }
    }

    /// Stops writing `id` into a vertex buffer (its mesh is not allocated this frame, say).
    pub fn clear_writeback(&mut self, id: ClothId) {
        if let Some(slot) = self.slots.get_mut(id.0 as usize).and_then(Option::as_mut) {
            slot.writeback = None;
        }
    }

    /// Uploads every cloth's writeback and, when the cloths or their vertex buffers changed,
    /// the owner table, the group constants and the bind groups.
    fn prepare_writebacks(&mut self, device: &Device, queue: &Queue, kernels: &ClothKernels) {
        let mut groups: Vec<(Buffer, Vec<u32>)> = Vec::new();
        for (index, slot) in self.slots.iter().enumerate() {
            let Some((_, vertices)) = slot.as_ref().and_then(|slot| slot.writeback.as_ref()) else { continue };
            match groups.iter_mut().find(|(buffer, _)| buffer == vertices) {
                Some((_, cloths)) => cloths.push(index as u32),
                None => groups.push((vertices.clone(), vec![index as u32])),
            }
        }
        let vertex_count =
            |index: u32| self.slots[index as usize].as_ref().map_or(0, |s| s.topology.vertex_particle().len() as u32);
        // Every cloth's writeback, each cloth's first thread counted within its group.
        let mut constants = vec![GpuBatchWriteback::default(); self.slots.len()];
        for (_, cloths) in &groups {
            let mut first = 0;
            for &index in cloths {
                let Some(slot) = self.slots[index as usize].as_ref() else { continue };
                let Some((mesh, _)) = slot.writeback else { continue };
                constants[index as usize] = GpuBatchWriteback {
                    mesh,
                    particle_start: slot.particle_start,
                    surface_start: slot.surface_start,
                    vertex_count: vertex_count(index),
                    particle_count: slot.topology.len() as u32,
                    group_first: first,
                    _pad: [0; 3],
                };
                first += vertex_count(index);
            }
        }
        if !constants.is_empty() {
            queue.write_buffer(&self.buffers.writebacks, 0, bytemuck::cast_slice(&constants));
        }
        let same = self.writebacks.as_ref().is_some_and(|w| {
            w.groups.len() == groups.len()
                && w.groups
                    .iter()
                    .zip(&groups)
                    .all(|(g, (vertices, cloths))| g.vertices == *vertices && g.cloths == *cloths)
        });
        if same {
            return;
        }
        if groups.is_empty() {
            self.writebacks = None;
            return;
        }
        let mut owners = Vec::new();
        let mut infos = vec![0u8; groups.len() * UNIFORM_STRIDE as usize];
        let mut sizes = Vec::with_capacity(groups.len());
        for (k, (_, cloths)) in groups.iter().enumerate() {
            let first_owner = owners.len() as u32;
            for &index in cloths {
                owners.extend(std::iter::repeat_n(index, vertex_count(index) as usize));
            }
            let count = owners.len() as u32 - first_owner;
            let workgroups = ClothKernels::workgroups(device, count).unwrap_or((0, 0));
            let info = GpuWritebackGroup {
                first_owner,
                vertex_count: count,
                dispatch_width: workgroups.0 * WORKGROUP_SIZE,
                pad: 0,
            };
            let at = k * UNIFORM_STRIDE as usize;
            infos[at..at + size_of::<GpuWritebackGroup>()].copy_from_slice(bytemuck::bytes_of(&info));
            sizes.push(workgroups);
        }
        let owners = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("bvh_cloth_writeback_owners"),
            contents: bytemuck::cast_slice(&owners),
            usage: BufferUsages::STORAGE,
        });
        let group_constants = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("bvh_cloth_writeback_groups"),
            contents: &infos,
            usage: BufferUsages::UNIFORM,
        });
        let b = &self.buffers;
        let groups = groups
            .into_iter()
            .zip(sizes)
            .map(|((vertices, cloths), workgroups)| {
                let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("bvh_cloth_normal_shader"),
                    layout: &kernels.normal_layout,
                    entries: &[
                        wgpu::BindGroupEntry { binding: 15, resource: b.writebacks.as_entire_binding() },
                        wgpu::BindGroupEntry { binding: 16, resource: b.base.as_entire_binding() },
                        wgpu::BindGroupEntry { binding: 17, resource: b.surface_words.as_entire_binding() },
                        wgpu::BindGroupEntry { binding: 18, resource: vertices.as_entire_binding() },
                        wgpu::BindGroupEntry { binding: 23, resource: owners.as_entire_binding() },
                        wgpu::BindGroupEntry {
                            binding: 24,
                            resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                                buffer: &group_constants,
                                offset: 0,
                                size: wgpu::BufferSize::new(size_of::<GpuWritebackGroup>() as u64),
                            }),
                        },
                    ],
                });
                WritebackGroup { vertices, cloths, bind_group, workgroups }
            })
            .collect();
        self.writebacks = Some(Writebacks { groups });
    }

    /// Records `normal_shader` for every cloth with a writeback: positions and normals into
    /// their vertex buffers, one dispatch per vertex buffer. Needs [`Self::prepare`] this frame.
    pub fn encode_writebacks(&self, encoder: &mut CommandEncoder, kernels: &ClothKernels) {
        let Some(writebacks) = &self.writebacks else { return };
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("bvh_cloth_writeback"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&kernels.normal);
        for (k, group) in writebacks.groups.iter().enumerate() {
            if group.workgroups.0 == 0 {
                continue;
            }
            pass.set_bind_group(0, &group.bind_group, &[(k as u64 * UNIFORM_STRIDE) as u32]);
            pass.dispatch_workgroups(group.workgroups.0, group.workgroups.1, 1);
        }
    }

    /// The particle buffer (`GpuParticle`s, `COPY_SRC`) and where `id`'s particles lie in it,
    /// in bytes: `(offset, size)`.
    pub fn particles(&self, id: ClothId) -> Option<(&Buffer, u64, u64)> {
        let slot = self.slot(id)?;
        let size = size_of::<GpuParticle>() as u64;
        Some((&self.buffers.base, u64::from(slot.particle_start) * size, slot.topology.len() as u64 * size))
    }

    /// The buffer holding every cloth's count of quarantined particles (`COPY_SRC | COPY_DST`),
    /// and the byte offset of `id`'s: one `u32`, one per particle and substep whose new state
    /// was not finite, since it was last cleared.
    pub fn faults(&self, id: ClothId) -> Option<(&Buffer, u64)> {
        self.slot(id)?;
        Some((&self.buffers.cloth_constants, self.faults_offset(id)))
    }

    fn faults_offset(&self, id: ClothId) -> u64 {
        u64::from(id.0) * size_of::<GpuBatchCloth>() as u64 + GpuBatchCloth::HOST_BYTES
    }
}
