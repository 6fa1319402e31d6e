//! The batch of every cloth on the GPU: [`ClothBatch`].

mod allocation;
mod bind_groups;
mod schedule;
mod writeback;

use allocation::{Buffers, surface_len};
use bind_groups::{AnchorTargets, DescentPlan, Groups};
use writeback::Writebacks;

use std::sync::Arc;

use crate::layout::{
    GpuBatchCloth, GpuBatchFrame, GpuBatchStep, GpuMeshWriteback, GpuParticle, NO_CLOTH, gpu_particles, gpu_tether_ends,
};
use bvh_cloth_core::backend::AirSource;
use bvh_cloth_core::backend::MAX_COLOURS;
use bvh_cloth_core::backend::MAX_ITERATIONS;
use bvh_cloth_core::backend::TetherSet;
use bvh_cloth_core::backend::{ForceModel, MultigridCorrection, MultigridStepping};
use bvh_cloth_core::{
    Aerodynamics, ClothError, ClothParams, ClothSim, ClothTopology, Integrator, Vec3, Vec3A, Wind, WindSource,
};
use wgpu::{Buffer, BufferUsages, Device, Queue};

use crate::buffer::UNIFORM_STRIDE;
use crate::headless;
use crate::kernels::{ClothKernels, KernelError};
use crate::stages::air::AirPlan;
use crate::stages::multigrid::MultigridPlan;
use crate::stages::self_contact::ContactPlan;

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
    /// Pinned particles, sorted: `apply_anchors` takes as many targets per tick at most.
    pins: Vec<u32>,
    /// This frame's anchor targets per tick, particle indices relative to the cloth.
    targets: Vec<Vec<(u32, Vec3)>>,
    /// The state the cloth was added with ([`gpu_particles`]): uploaded at its first placing
    /// (while `pending` says so), and where a multigrid cloth's hierarchy is grouped from.
    added: Arc<[GpuParticle]>,
    pending: bool,
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
    /// The multigrid correction's hierarchy for the current pins, once a multigrid cloth needs it.
    multigrid: Option<Arc<MultigridCorrection>>,
    /// How the multigrid integrator steps it at its substep length (multigrid only).
    stepping: MultigridStepping,
    /// Its forces under its last parameters.
    model: ForceModel,
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

    /// The multigrid hierarchy for the current pins and springs, built on first need as the
    /// CPU builds it in the cloth's first multigrid substep, from the state it was added with.
    fn multigrid(&mut self) -> Arc<MultigridCorrection> {
        let Self { topology, pins, added, model, constants, multigrid, .. } = self;
        Arc::clone(multigrid.get_or_insert_with(|| {
            let mut free = vec![1.0; topology.len()];
            for &p in pins.iter() {
                free[p as usize] = 0.0;
            }
            let x: Vec<Vec3A> = added.iter().map(|p| Vec3A::from_slice(&p.position[..3])).collect();
            let v: Vec<Vec3A> = added.iter().map(|p| Vec3A::from_slice(&p.velocity[..3])).collect();
            let held: Vec<f32> = added.iter().map(|p| p.velocity[3]).collect();
            Arc::new(MultigridCorrection::for_first_substep(topology, model, &free, &held, constants.h, &x, &v))
        }))
    }
}

/// The multigrid correction's plan and what it was built for: per multigrid cloth its slot,
/// first particle, hierarchy and stepping.
#[derive(Debug)]
struct MultigridStage {
    key: Vec<(u32, u32, usize, MultigridStepping)>,
    /// `None` when the plan would not fit the device ([`ClothBatch::multigrid_error`]).
    plan: Option<MultigridPlan>,
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
    /// The multigrid correction of the multigrid cloths, `None` while there is none; and why
    /// they run as block descent instead, if they do.
    multigrid: Option<MultigridStage>,
    multigrid_error: Option<KernelError>,
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
            multigrid: None,
            multigrid_error: None,
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
            pins: sim.pins().to_vec(),
            targets: Vec::new(),
            added: gpu_particles(sim).into(),
            pending: true,
            writeback: None,
            own_substeps: 0,
            tick_seconds: 0.0,
            aerodynamics: sim.params().aerodynamics,
            mass: sim.params().mass,
            wind: *sim.wind(),
            free_body: sim.is_free_body(),
            tethers: Arc::clone(sim.tethers()),
            multigrid: None,
            stepping: MultigridStepping::Bdf2,
            model: ForceModel::new(sim.params()),
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
        // A self-contact thickness of 0 is this cloth's own, as the core resolves it.
        let resolved = params.clone().resolved_for(&slot.topology);
        let params = &resolved;
        let substeps = params.substeps(tick_seconds, &slot.topology).min(MAX_SUBSTEPS);
        let h = tick_seconds / substeps as f32;
        let before = (slot.constants.h, slot.constants.integrator, slot.constants.k_over_mass);
        slot.constants = GpuBatchCloth::new(params, &slot.topology, slot.particle_start, slot.ends_start, substeps, h);
        slot.model = ForceModel::new(params);
        slot.stepping = MultigridStepping::of(&slot.model, &slot.topology, h);
        // New springs need a new hierarchy, and BDF2 no history from another substep length.
        if before.2 != slot.constants.k_over_mass {
            slot.multigrid = None;
        }
        let broken = before.0 != h || before.1 != slot.constants.integrator;
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
        if broken {
            self.break_history(queue, id);
        }
    }

    /// Starts a multigrid cloth's BDF2 again from implicit Euler: its state or substep changed.
    fn break_history(&self, queue: &Queue, id: ClothId) {
        let at = u64::from(id.0) * size_of::<GpuBatchCloth>() as u64 + GpuBatchCloth::BROKEN_OFFSET;
        queue.write_buffer(&self.buffers.cloth_constants, at, bytemuck::bytes_of(&1u32));
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
            slot.targets.extend(ticks.iter().map(|tick| tick.iter().copied().take(slot.pins.len()).collect()));
        }
    }

    /// Changes which of `id`'s particles are pinned, keeping its state on the GPU, as
    /// [`ClothSim::set_pins`] does on the CPU: a particle let go starts from rest where it was
    /// held, one newly pinned stays where it is until its targets move it. `tethers` are the
    /// ones the core found for `pins` ([`ClothSim::tethers`]). A cloth that had no tethers and
    /// now has them needs room in the spring-end buffer, so the buffers are rebuilt (the
    /// states copied on the GPU), which can fail as [`Self::insert`] can; the cloth then
    /// keeps its old pins.
    pub fn set_pins(
        &mut self,
        device: &Device,
        queue: &Queue,
        id: ClothId,
        pins: &[u32],
        tethers: Arc<TetherSet>,
    ) -> Result<(), KernelError> {
        let Some(slot) = self.slots.get_mut(id.0 as usize).and_then(Option::as_mut) else { return Ok(()) };
        let n = slot.topology.len();
        let mut pins: Vec<u32> = pins.iter().copied().filter(|&i| (i as usize) < n).collect();
        pins.sort_unstable();
        pins.dedup();
        if pins == slot.pins {
            return Ok(());
        }
        let grows = tethers.pin.len() > slot.tethers.pin.len();
        let old = (std::mem::replace(&mut slot.pins, pins), std::mem::replace(&mut slot.tethers, tethers));
        if grows && let Err(error) = self.rebuild(device, queue) {
            let slot = self.slots[id.0 as usize].as_mut().expect("the slot was just changed");
            (slot.pins, slot.tethers) = old;
            return Err(error);
        }
        self.break_history(queue, id);
        let slot = self.slots[id.0 as usize].as_mut().expect("the slot is there");
        slot.multigrid = None;
        let share = slot.topology.mass_share();
        slot.free_body = slot.pins.iter().all(|&i| share[i as usize] == 0.0);
        let particle = |i: u32| u64::from(slot.particle_start + i) * size_of::<GpuParticle>() as u64;
        // `position.w` is the free flag; a particle let go also loses its velocity.
        for &i in old.0.iter().filter(|&&i| slot.pins.binary_search(&i).is_err() && share[i as usize] > 0.0) {
            queue.write_buffer(&self.buffers.base, particle(i) + 12, bytemuck::bytes_of(&[1.0f32, 0.0, 0.0, 0.0, 0.0]));
        }
        for &i in slot.pins.iter().filter(|&&i| old.0.binary_search(&i).is_err()) {
            queue.write_buffer(&self.buffers.base, particle(i) + 12, bytemuck::bytes_of(&0.0f32));
        }
        if !grows {
            queue.write_buffer(
                &self.buffers.spring_ends,
                u64::from(slot.tether_start()) * 16,
                bytemuck::cast_slice(&gpu_tether_ends(&slot.tethers)),
            );
        }
        Ok(())
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
        self.break_history(queue, id);
    }

    /// Why the batch's multigrid cloths run as block descent with one sweep, if they do: the
    /// correction's buffers would not fit the device.
    pub fn multigrid_error(&self) -> Option<&KernelError> {
        self.multigrid_error.as_ref()
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
    /// bounds met ([`bvh_cloth_core::backend::MAX_CANDIDATES`] and the grid's room), its
    /// fourth the pairs of triangles the untangling found crossing, over the ticks encoded
    /// since the last [`Self::prepare`].
    pub fn contact_stats(&self) -> Option<&Buffer> {
        self.contact.as_ref().map(ContactPlan::stats)
    }

    /// The particle buffer (`GpuParticle`s, `COPY_SRC`) and where `id`'s particles lie in it,
    /// in bytes: `(offset, size)`.
    pub fn particles(&self, id: ClothId) -> Option<(&Buffer, u64, u64)> {
        let slot = self.slot(id)?;
        let size = size_of::<GpuParticle>() as u64;
        Some((&self.buffers.base, u64::from(slot.particle_start) * size, slot.topology.len() as u64 * size))
    }

    /// Cloth `id`'s particles as the GPU has them (its part of the particle buffer, read with
    /// [`headless::read_range`], waiting for the GPU: for tests and benchmarks, never for a
    /// frame loop), or `None` for a cloth not in the batch.
    pub fn read_particles(&self, device: &Device, queue: &Queue, id: ClothId) -> Option<Vec<GpuParticle>> {
        let (buffer, offset, size) = self.particles(id)?;
        Some(headless::read_range(device, queue, buffer, offset, size))
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
