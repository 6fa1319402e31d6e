//! Self-contact on the GPU: the buffers, bind groups and dispatches of `self_contact.wgsl` for
//! the cloths of a batch that have a contact thickness.
//!
//! Every such cloth keeps off its own triangles and edges and off every other such cloth's, as
//! [`bvh_cloth_core::ClothSim::tick_together`] does on the CPU: they share one hashed grid of
//! triangles and edges, rebuilt each substep with a counting sort (counts by atomics, a prefix
//! sum, a scatter), and take the largest substep count among them. Per substep
//! `contact_begin` runs before the integrator and the others after it: the grid's build,
//! untangling's analysis (`untangle.wgsl`: which particles lie through another cloth or
//! another sheet of their own), the
//! points' contacts found and applied, then the edges' found and applied.
//!
//! The buffers are written when the set of contact cloths, or where they lie, changes: the
//! particles' rest positions, each primitive's corners and rest box (every cloth's triangles,
//! then every cloth's edges), and a grid sized for them (a table of about twice as many buckets
//! as primitives, room for eight entries per primitive), followed by untangling's words (each
//! triangle's neighbours across its edges among them, written here).
//! Everything else is per frame: the thickness the boxes grow by and the cell width.

use crate::layout::{
    CONTACT_TRIANGLE_WORDS, GpuContactFrame, gpu_contact_edges, gpu_contact_triangles, gpu_triangle_neighbours,
};
use bvh_cloth_core::ClothTopology;
use wgpu::{BindGroup, Buffer, BufferUsages, ComputePass, Device, Queue};

use crate::buffer::storage_buffer;
use crate::kernels::{ClothKernels, EntryPoint, Kernel, KernelError, WORKGROUP_SIZE, storage_binding_limit};

/// Buckets per prefix-sum block (`SCAN_BLOCK` in the WGSL).
const SCAN_BLOCK: u32 = 256;

/// Most buckets of the grid: the prefix sum's blocks must fit one dispatch dimension.
const MAX_BUCKETS: u32 = 1 << 23;

/// Grid entries per primitive there is room for. A triangle or an edge whose grown box is
/// narrower than a cell (the usual case: cells are twice a grown triangle's width) covers at
/// most eight.
const ENTRIES_PER_PRIMITIVE: u32 = 8;

/// Words of the grid before the counts: contacts, points clamped, edges clamped, one unused.
const GRID_HEADER: u32 = 4;

/// Words per particle of the sums.
const SUM_WORDS: u64 = 8;

/// Untangling's words after the grid's entries (`untangle.wgsl`): two, then five per cloth slot,
/// eleven per triangle (its three neighbours, then the analysis's eight), and five per particle
/// slot (`TANGLE_*_WORDS` in `self_contact.wgsl`).
const TANGLE_HEADER: u64 = 2;
const TANGLE_CLOTH_WORDS: u64 = 5;
const TANGLE_TRIANGLE_WORDS: u64 = 11;
const TANGLE_PARTICLE_WORDS: u64 = 5;

/// One cloth with self-contact: its slot, its first particle and the address of its shape.
pub(crate) type ContactCloth = (u32, u32, usize);

/// What the bind groups of the contact kernels bind besides the plan's own buffers.
pub(crate) struct SharedBuffers<'a> {
    pub frame: &'a Buffer,
    pub particles: &'a Buffer,
    pub info: &'a Buffer,
    pub cloths: &'a Buffer,
    pub colliders: (&'a Buffer, &'a Buffer),
    /// Block descent's inertial targets, where a multigrid cloth's particle is marked as moved.
    pub inertial: &'a Buffer,
}

/// The contact buffers of a batch, written for one set of contact cloths.
#[derive(Debug)]
pub(crate) struct ContactPlan {
    /// The cloths, and the particle-buffer capacity, the buffers were written for.
    pub cloths: Vec<ContactCloth>,
    pub particle_capacity: u32,
    /// Substeps every contact cloth takes per tick.
    pub substeps: u32,
    triangles: u32,
    edges: u32,
    buckets: u32,
    blocks: u32,
    entry_capacity: u32,
    /// One more than the highest slot of a contact cloth.
    cloth_slots: u32,
    /// Mean rest edge of the contact cloths' triangles, in metres.
    mean_edge: f32,
    uniform: Buffer,
    points: Buffer,
    triangle_words: Buffer,
    grid: Buffer,
    sums: Buffer,
    /// Workgroups along `x` of every dispatch but the prefix sum's, and the particle slots
    /// and buckets the begin dispatch covers (set each frame).
    width_groups: u32,
    slots: u32,
}

impl ContactPlan {
    /// The buffers for `cloths` (each with its shape), in a batch whose particle buffers hold
    /// `particle_capacity` slots. Refused when a buffer would exceed a storage binding.
    pub fn new(
        device: &Device,
        queue: &Queue,
        cloths: &[(ContactCloth, &ClothTopology)],
        particle_capacity: u32,
    ) -> Result<Self, KernelError> {
        let triangles: u32 = cloths.iter().map(|(_, t)| t.triangles().len() as u32).sum();
        let edges: u32 = cloths.iter().map(|(_, t)| t.edges().len() as u32).sum();
        let primitives = triangles + edges;
        let buckets = (2 * primitives).next_power_of_two().clamp(SCAN_BLOCK, MAX_BUCKETS);
        let blocks = buckets / SCAN_BLOCK;
        let entry_capacity = primitives.saturating_mul(ENTRIES_PER_PRIMITIVE).max(1);
        let cloth_slots = cloths.iter().map(|&((slot, _, _), _)| slot + 1).max().unwrap_or(0);
        let entries_end =
            u64::from(GRID_HEADER) + 3 * u64::from(buckets) + 1 + u64::from(blocks) + u64::from(entry_capacity);
        let neighbours_at = entries_end + TANGLE_HEADER + TANGLE_CLOTH_WORDS * u64::from(cloth_slots);
        let grid_words = neighbours_at
            + TANGLE_TRIANGLE_WORDS * u64::from(triangles)
            + TANGLE_PARTICLE_WORDS * u64::from(particle_capacity);
        let sizes = [
            u64::from(particle_capacity) * 32,
            u64::from(primitives) * CONTACT_TRIANGLE_WORDS as u64 * 16,
            grid_words * 4,
            u64::from(particle_capacity) * SUM_WORDS * 4,
        ];
        let max = storage_binding_limit(device);
        if let Some(&bytes) = sizes.iter().find(|&&bytes| bytes > max) {
            return Err(KernelError::BufferTooLarge { bytes, max });
        }
        let storage = |label: &str, bytes: u64| storage_buffer(device, label, bytes);
        let points = storage("bvh_cloth_contact_points", sizes[0]);
        let triangle_words = storage("bvh_cloth_contact_triangles", sizes[1]);
        let grid = storage("bvh_cloth_contact_grid", sizes[2]);
        let sums = storage("bvh_cloth_contact_sums", sizes[3]);
        let uniform = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("bvh_cloth_contact_frame"),
            size: size_of::<GpuContactFrame>() as u64,
            usage: BufferUsages::UNIFORM | BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let (mut perimeters, mut sides) = (0.0f64, 0u64);
        let mut words = Vec::with_capacity(primitives as usize * CONTACT_TRIANGLE_WORDS);
        for &((slot, start, _), topology) in cloths {
            // Each particle's rest position, beside the start-of-substep position the kernels keep.
            let rest: Vec<[f32; 8]> =
                topology.rest_positions().iter().map(|p| [0.0, 0.0, 0.0, 0.0, p.x, p.y, p.z, 0.0]).collect();
            queue.write_buffer(&points, u64::from(start) * 32, bytemuck::cast_slice(&rest));
            words.extend(gpu_contact_triangles(topology, start, slot));
            let r = topology.rest_positions();
            for t in topology.triangles() {
                let [a, b, c] = t.map(|k| r[k as usize]);
                perimeters += f64::from(a.distance(b) + b.distance(c) + c.distance(a));
                sides += 3;
            }
        }
        for &((slot, start, _), topology) in cloths {
            words.extend(gpu_contact_edges(topology, start, slot));
        }
        queue.write_buffer(&triangle_words, 0, bytemuck::cast_slice(&words));
        let mut neighbours = Vec::with_capacity(triangles as usize);
        for &(_, topology) in cloths {
            neighbours.extend(gpu_triangle_neighbours(topology, neighbours.len() as u32));
        }
        queue.write_buffer(&grid, neighbours_at * 4, bytemuck::cast_slice(&neighbours));
        let mean_edge = if sides == 0 { 0.0 } else { (perimeters / sides as f64) as f32 };
        let cover = primitives.max(buckets).max(cloth_slots);
        let width_groups = ClothKernels::workgroups(device, cover)?.0;
        Ok(Self {
            cloths: cloths.iter().map(|(cloth, _)| *cloth).collect(),
            particle_capacity,
            substeps: 0,
            triangles,
            edges,
            buckets,
            blocks,
            entry_capacity,
            cloth_slots,
            mean_edge,
            uniform,
            points,
            triangle_words,
            grid,
            sums,
            width_groups,
            slots: 0,
        })
    }

    /// Writes this frame's constants: the batch's used particle slots and the largest
    /// thickness among the contact cloths. The cell is twice a grown triangle's typical width,
    /// as on the CPU (which measures the edges as the particles stand, not at rest: the cell
    /// decides only which triangles a point examines, not which touch it). Clears the
    /// statistics.
    pub fn write_frame(&mut self, device: &Device, queue: &Queue, particle_slots: u32, thickest: f32) {
        let cover = particle_slots.max(self.triangles + self.edges).max(self.buckets).max(self.cloth_slots);
        self.width_groups = ClothKernels::workgroups(device, cover).map_or(self.width_groups, |(x, _)| x);
        self.slots = particle_slots;
        let cell = 2.0 * (thickest + self.mean_edge);
        let frame = GpuContactFrame {
            triangle_count: self.triangles,
            buckets: self.buckets,
            blocks: self.blocks,
            entry_capacity: self.entry_capacity,
            inv_cell: 1.0 / cell,
            grow: thickest,
            dispatch_width: self.width_groups * WORKGROUP_SIZE,
            particle_slots,
            edge_count: self.edges,
            cloth_slots: self.cloth_slots,
            pad_a: 0,
            pad_b: 0,
        };
        queue.write_buffer(&self.uniform, 0, bytemuck::bytes_of(&frame));
        queue.write_buffer(&self.grid, 0, bytemuck::cast_slice(&[0u32; GRID_HEADER as usize]));
    }

    /// The grid's statistics words (`COPY_SRC`): the contacts (one per free particle taking
    /// part in one, summed over the substeps), the bounds the points and the triangles met,
    /// those the edges met, and the pairs of triangles the untangling found crossing, since the
    /// last [`Self::write_frame`].
    pub fn stats(&self) -> &Buffer {
        &self.grid
    }

    /// The bind groups of the kernels, in [`EntryPoint::CONTACT`] order.
    pub fn bind_groups(
        &self,
        device: &Device,
        kernels: &ClothKernels,
        shared: &SharedBuffers<'_>,
    ) -> [BindGroup; EntryPoint::CONTACT.len()] {
        let resource = |binding: u32| -> &Buffer {
            match binding {
                0 => shared.frame,
                6 => shared.info,
                8 => shared.cloths,
                11 => shared.colliders.0,
                12 => shared.colliders.1,
                35 => &self.uniform,
                36 => &self.points,
                37 => &self.triangle_words,
                38 => &self.grid,
                39 => &self.sums,
                21 => shared.inertial,
                40 => shared.particles,
                other => unreachable!("no contact kernel binds {other}"),
            }
        };
        let descriptors = ClothKernels::descriptors();
        let contact = EntryPoint::CONTACT.map(|entry| descriptors.iter().find(|d| d.entry == entry));
        core::array::from_fn(|k| {
            let entries: Vec<wgpu::BindGroupEntry<'_>> = contact[k]
                .expect("every entry point has a descriptor")
                .layout
                .iter()
                .map(|e| wgpu::BindGroupEntry { binding: e.binding, resource: resource(e.binding).as_entire_binding() })
                .collect();
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("bvh_cloth_self_contact"),
                layout: kernels.layout(EntryPoint::CONTACT[k]),
                entries: &entries,
            })
        })
    }

    fn rows(&self, count: u32) -> u32 {
        count.div_ceil(self.width_groups * WORKGROUP_SIZE * WORKGROUP_SIZE).max(1)
    }

    /// Calls `each` with the dispatch that opens a substep: `contact_begin`.
    pub fn begin(
        &self,
        kernels: &ClothKernels,
        groups: &[BindGroup; EntryPoint::CONTACT.len()],
        each: &mut impl FnMut(Kernel, &dyn Fn(&mut ComputePass<'_>)),
    ) {
        let size = (self.width_groups, self.rows(self.slots.max(self.buckets).max(self.cloth_slots)));
        each(Kernel::ContactBegin, &|pass| {
            pass.set_pipeline(kernels.pipeline(EntryPoint::ContactBegin));
            pass.set_bind_group(0, &groups[0], &[]);
            pass.dispatch_workgroups(size.0, size.1, 1);
        });
    }

    /// Calls `each` with the dispatches that close a substep, after the integrator: the grid's
    /// build, the points' contacts found and applied, then the edges'.
    pub fn resolve(
        &self,
        kernels: &ClothKernels,
        groups: &[BindGroup; EntryPoint::CONTACT.len()],
        each: &mut impl FnMut(Kernel, &dyn Fn(&mut ComputePass<'_>)),
    ) {
        let primitives = (self.width_groups, self.rows(self.triangles + self.edges));
        let particles = (self.width_groups, self.rows(self.slots));
        let edges = (self.width_groups, self.rows(self.edges));
        let triangles = (self.width_groups, self.rows(self.triangles));
        // Each dispatch: its kernel's place in EntryPoint::CONTACT, its size and its name.
        let dispatches = [
            (1, primitives, Kernel::ContactCount),
            (2, (self.blocks, 1), Kernel::ContactScan),
            (3, (1, 1), Kernel::ContactScan),
            (4, (self.blocks, 1), Kernel::ContactScan),
            (5, primitives, Kernel::ContactScatter),
            (9, triangles, Kernel::Untangle),
            (10, triangles, Kernel::Untangle),
            (11, triangles, Kernel::Untangle),
            (12, triangles, Kernel::Untangle),
            (13, triangles, Kernel::Untangle),
            (14, triangles, Kernel::Untangle),
            (15, triangles, Kernel::Untangle),
            (16, triangles, Kernel::Untangle),
            (17, particles, Kernel::Untangle),
            (18, triangles, Kernel::Untangle),
            (19, particles, Kernel::Untangle),
            (20, triangles, Kernel::Untangle),
            (6, particles, Kernel::ContactFind),
            (7, particles, Kernel::ContactApply),
            (8, edges, Kernel::ContactFindEdges),
            (7, particles, Kernel::ContactApply),
        ];
        for (k, size, name) in dispatches {
            let (pipeline, group) = (kernels.pipeline(EntryPoint::CONTACT[k]), &groups[k]);
            each(name, &|pass| {
                pass.set_pipeline(pipeline);
                pass.set_bind_group(0, group, &[]);
                pass.dispatch_workgroups(size.0, size.1, 1);
            });
        }
    }
}
