//! The multigrid correction on the GPU: the buffers, bind group and dispatches of
//! `multigrid.wgsl` for the multigrid cloths of a batch
//! ([`bvh_cloth_core::solver::multigrid`]).
//!
//! The hierarchy's structure is built on the CPU
//! ([`MultigridCorrection::for_first_substep`]) and uploaded
//! once: every cloth's nodes level by level, level `l` of every cloth together, so that one
//! dispatch runs one pass of the V-cycle on that level of all of them. Indices in the buffers
//! are global (nodes, blocks, springs and particle slots of the batch): the plan is built again
//! when a cloth joins, leaves or moves. The numbers (the levels' matrices, their factors, the
//! right-hand sides and solutions) live on the GPU only, and the kernels decide when to
//! assemble and factor them, as the CPU does.
//!
//! A substep's correction is `mg_begin` before the prediction ([`MultigridPlan::begin`]: the
//! step: BDF2's, the blend's or implicit Euler's) and the rest after the sweep
//! ([`MultigridPlan::correct`]): `9 + 4 (L - 1)` dispatches for the deepest cloth's `L` levels,
//! and `2 L` more in a batch where a cloth runs [`Cycle::TopW`]. The line search sums in two
//! levels (chunks of 64 level-1 nodes, then each cloth's chunks), so that a big cloth's sums
//! spread over many workgroups.
//!
//! [`MultigridCorrection::for_first_substep`]: bvh_cloth_core::backend::MultigridCorrection::for_first_substep

#[cfg(test)]
mod tests;

use bvh_cloth_core::backend::{Cycle, DENSE_NODES, MultigridLayout, MultigridStepping, NO_NODE, REASSEMBLE_EVERY};
use wgpu::util::DeviceExt;
use wgpu::{BindGroup, Buffer, Device};

use crate::buffer::{UNIFORM_STRIDE, storage_buffer, storage_buffer_with};
use crate::kernels::{ClothKernels, EntryPoint, Kernel, KernelError, WORKGROUP_SIZE, storage_binding_limit};
use crate::layout::{
    GpuBatchStep, GpuMultigridCloth, GpuMultigridPass, MULTIGRID_NODE_VALUES, MULTIGRID_NODE_WORDS,
    MULTIGRID_SPRING_VALUES,
};

/// One cloth's correction as the plan takes it.
pub(crate) struct MultigridCloth<'a> {
    /// The cloth's index in the batch's cloth array.
    pub slot: u32,
    /// Its first particle slot.
    pub particle_start: u32,
    /// Its hierarchy.
    pub layout: &'a MultigridLayout,
    /// How it steps: whether its levels are assembled in every substep, whether it blends
    /// BDF2 with implicit Euler, and its cycle.
    pub stepping: MultigridStepping,
}

/// What the bind group binds besides the plan's own buffers.
pub(crate) struct SharedBuffers<'a> {
    pub frame: &'a Buffer,
    /// The batch's substep uniforms ([`crate::layout::GpuBatchStep`], three per substep).
    pub steps: &'a Buffer,
    pub info: &'a Buffer,
    pub cloths: &'a Buffer,
    pub iterate: &'a Buffer,
    pub substep_start: &'a Buffer,
    pub inertial: &'a Buffer,
}

/// The multigrid buffers of a batch and the dispatches of one substep's correction.
#[derive(Debug)]
pub(crate) struct MultigridPlan {
    index: Buffer,
    values: Buffer,
    cloths: Buffer,
    passes: Buffer,
    /// Levels of the deepest cloth.
    levels: u32,
    /// [`Cycle::TopW`] when any cloth runs it (the others' second visits compute their first
    /// answers again), else [`Cycle::V`].
    cycle: Cycle,
    /// Entries of the cloth array (workgroups of the per-cloth kernels).
    cloth_slots: u32,
    /// Per pass entry, its workgroups.
    workgroups: Vec<(u32, u32)>,
}

/// The pass entries before the levels': the cloths, the crossing springs, every node, the
/// chunks of level-1 nodes.
const CLOTHS: u32 = 0;
const SPRINGS: u32 = 1;
const NODES: u32 = 2;
const CHUNKS: u32 = 3;
const FIRST_LEVEL: u32 = 4;

/// Level-1 nodes per chunk: one workgroup of the line search's first level.
const CHUNK: u32 = 64;

impl MultigridPlan {
    /// The buffers for `cloths` in a batch of `cloth_slots` cloth entries.
    pub(crate) fn new(device: &Device, cloths: &[MultigridCloth<'_>], cloth_slots: u32) -> Result<Self, KernelError> {
        let levels = cloths.iter().map(|c| c.layout.levels.len()).max().unwrap_or(0);
        let node_count =
            |c: &MultigridCloth<'_>, l: usize| c.layout.levels.get(l).map_or(0, |level| level.offsets.len() - 1);
        let block_count = |c: &MultigridCloth<'_>, l: usize| c.layout.levels.get(l).map_or(0, |level| level.cols.len());
        // Global numbering: level by level, cloth by cloth within a level.
        let mut node_base = vec![vec![0u32; levels]; cloths.len()];
        let mut block_base = vec![vec![0u32; levels]; cloths.len()];
        let mut level_ranges = Vec::with_capacity(levels);
        let (mut nodes, mut blocks) = (0u32, 0u32);
        for l in 0..levels {
            let first = nodes;
            for (k, cloth) in cloths.iter().enumerate() {
                (node_base[k][l], block_base[k][l]) = (nodes, blocks);
                nodes += node_count(cloth, l) as u32;
                blocks += block_count(cloth, l) as u32;
            }
            level_ranges.push((first, nodes - first));
        }
        let mut crossing_base = Vec::with_capacity(cloths.len());
        let mut crossing_total = 0u32;
        for cloth in cloths {
            crossing_base.push(crossing_total);
            crossing_total += cloth.layout.crossing_count as u32;
        }
        let mut inner_base = Vec::with_capacity(cloths.len());
        let mut springs_total = crossing_total;
        for cloth in cloths {
            inner_base.push(springs_total);
            springs_total += (cloth.layout.springs.len() - cloth.layout.crossing_count) as u32;
        }
        let share_total: u32 = cloths.iter().map(|c| c.layout.shares.len() as u32).sum();
        // The index buffer: node words, block words, share words, spring words, then the
        // children lists and the particles' aggregates.
        let block_words = nodes * MULTIGRID_NODE_WORDS;
        let share_words = block_words + 2 * blocks;
        let spring_words = share_words + 4 * share_total;
        let mut index = vec![0u32; (spring_words + 4 * springs_total) as usize];
        let mut share_base = 0u32;
        let mut headers = vec![GpuMultigridCloth::default(); cloth_slots as usize];
        // The values: nodes, blocks, crossing springs, then each cloth's dense factor.
        let node_values = 0u32;
        let block_values = nodes * MULTIGRID_NODE_VALUES;
        let spring_values = block_values + 2 * blocks;
        let mut dense_end = spring_values + crossing_total * MULTIGRID_SPRING_VALUES;
        for (k, cloth) in cloths.iter().enumerate() {
            let layout = cloth.layout;
            let last = layout.levels.len() - 1;
            let global_particle = |i: u32| cloth.particle_start + i;
            for (l, level) in layout.levels.iter().enumerate() {
                for a in 0..node_count(cloth, l) {
                    let w = ((node_base[k][l] + a as u32) * MULTIGRID_NODE_WORDS) as usize;
                    let child_start = index.len() as u32;
                    let children =
                        &level.children[level.child_offsets[a] as usize..level.child_offsets[a + 1] as usize];
                    if l == 0 {
                        index.extend(children.iter().map(|&i| global_particle(i)));
                    } else {
                        index.extend(children.iter().map(|&b| node_base[k][l - 1] + b));
                    }
                    let child_end = index.len() as u32;
                    let parent = if l < last { node_base[k][l + 1] + level.parent[a] } else { NO_NODE };
                    let (shares, inner) = if l == 0 {
                        let inner = |o: u32| inner_base[k] + o - layout.crossing_count as u32;
                        (
                            [share_base + layout.share_offsets[a], share_base + layout.share_offsets[a + 1]],
                            [inner(layout.inner_offsets[a]), inner(layout.inner_offsets[a + 1])],
                        )
                    } else {
                        ([0, 0], [0, 0])
                    };
                    index[w..w + MULTIGRID_NODE_WORDS as usize].copy_from_slice(&[
                        block_base[k][l] + level.offsets[a],
                        block_base[k][l] + level.offsets[a + 1],
                        child_start,
                        child_end,
                        parent,
                        cloth.slot,
                        shares[0],
                        shares[1],
                        inner[0],
                        inner[1],
                        l as u32,
                        0,
                    ]);
                }
                for (b, &col) in level.cols.iter().enumerate() {
                    let w = (block_words + 2 * (block_base[k][l] + b as u32)) as usize;
                    let slot = match level.slot.get(b) {
                        Some(&slot) if slot != NO_NODE => block_base[k][l + 1] + slot,
                        _ => NO_NODE,
                    };
                    index[w..w + 2].copy_from_slice(&[node_base[k][l] + col, slot]);
                }
            }
            for (s, &[spring, side, slot]) in layout.shares.iter().enumerate() {
                let w = (share_words + 4 * (share_base + s as u32)) as usize;
                let slot = if slot == NO_NODE { NO_NODE } else { block_base[k][0] + slot };
                index[w..w + 4].copy_from_slice(&[crossing_base[k] + spring, side, slot, 0]);
            }
            share_base += layout.shares.len() as u32;
            for (s, spring) in layout.springs.iter().enumerate() {
                let global = if s < layout.crossing_count {
                    crossing_base[k] + s as u32
                } else {
                    inner_base[k] + (s - layout.crossing_count) as u32
                };
                let w = (spring_words + 4 * global) as usize;
                index[w..w + 4].copy_from_slice(&[
                    global_particle(spring.ends[0]),
                    global_particle(spring.ends[1]),
                    spring.stiffness.to_bits(),
                    spring.rest.to_bits(),
                ]);
            }
            let aggregate_start = index.len() as u32;
            index.extend(layout.aggregate.iter().map(|&a| if a == NO_NODE { NO_NODE } else { node_base[k][0] + a }));
            let coarsest_count = node_count(cloth, last) as u32;
            let dense_order = if coarsest_count as usize <= DENSE_NODES { 3 * coarsest_count } else { 0 };
            headers[cloth.slot as usize] = GpuMultigridCloth {
                levels: layout.levels.len() as u32,
                node_start: node_base[k][0],
                node_count: node_count(cloth, 0) as u32,
                coarsest_start: node_base[k][last],
                coarsest_count,
                crossing_start: crossing_base[k],
                crossing_count: layout.crossing_count as u32,
                aggregate_start,
                dense_start: dense_end,
                dense_order,
                stiff: u32::from(cloth.stepping == MultigridStepping::Stiff),
                blend: u32::from(cloth.stepping == MultigridStepping::Blend),
                age: REASSEMBLE_EVERY,
                ..Default::default()
            };
            dense_end += (dense_order * dense_order).div_ceil(4);
        }
        // The chunk table: each cloth's level-1 nodes in runs of up to 64, one workgroup each in
        // the line search's first level.
        let chunk_words = index.len() as u32;
        let mut chunks = 0u32;
        for (k, cloth) in cloths.iter().enumerate() {
            let count = node_count(cloth, 0) as u32;
            let header = &mut headers[cloth.slot as usize];
            header.chunk_start = chunks;
            for first in (0..count).step_by(CHUNK as usize) {
                index.extend([node_base[k][0] + first, CHUNK.min(count - first)]);
                header.chunk_count += 1;
                chunks += 1;
            }
        }
        let chunk_values = dense_end;
        let value_count = chunk_values + chunks;
        let max = storage_binding_limit(device);
        for bytes in [4 * index.len() as u64, 16 * u64::from(value_count)] {
            if bytes > max {
                return Err(KernelError::BufferTooLarge { bytes, max });
            }
        }
        let mut entries = vec![(0, cloth_slots, 0), (0, crossing_total, 0), (0, nodes, 0), (0, chunks, 0)];
        entries.extend(level_ranges.iter().enumerate().map(|(l, &(start, count))| (start, count, l as u32)));
        let mut workgroups = Vec::with_capacity(entries.len());
        let mut bytes = vec![0u8; entries.len() * UNIFORM_STRIDE as usize];
        for (e, &(start, count, level)) in entries.iter().enumerate() {
            // A chunk is one workgroup of 64 threads: a dispatch of as many threads as its nodes.
            let threads = if e as u32 == CHUNKS { count.saturating_mul(CHUNK) } else { count };
            let groups = ClothKernels::workgroups(device, threads)?;
            workgroups.push(groups);
            let pass = GpuMultigridPass {
                start,
                count,
                width: groups.0 * WORKGROUP_SIZE,
                level,
                block_words,
                share_words,
                spring_words,
                chunk_words,
                node_values,
                block_values,
                spring_values,
                chunk_values,
            };
            let at = e * UNIFORM_STRIDE as usize;
            bytes[at..at + size_of::<GpuMultigridPass>()].copy_from_slice(bytemuck::bytes_of(&pass));
        }
        let passes = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("bvh_cloth_multigrid_passes"),
            contents: &bytes,
            usage: wgpu::BufferUsages::UNIFORM,
        });
        Ok(Self {
            index: storage_buffer_with(device, "bvh_cloth_multigrid_index", &index),
            values: storage_buffer(device, "bvh_cloth_multigrid_values", 16 * u64::from(value_count)),
            cloths: storage_buffer_with(device, "bvh_cloth_multigrid_cloths", &headers),
            passes,
            levels: levels as u32,
            cycle: if cloths.iter().any(|c| c.stepping.cycle() == Cycle::TopW) { Cycle::TopW } else { Cycle::V },
            cloth_slots,
            workgroups,
        })
    }

    /// The bind group every multigrid kernel takes.
    pub(crate) fn bind_group(&self, device: &Device, kernels: &ClothKernels, shared: &SharedBuffers<'_>) -> BindGroup {
        fn whole(binding: u32, buffer: &Buffer) -> wgpu::BindGroupEntry<'_> {
            wgpu::BindGroupEntry { binding, resource: buffer.as_entire_binding() }
        }
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("bvh_cloth_multigrid"),
            layout: kernels.layout(EntryPoint::MgBegin),
            entries: &[
                whole(0, shared.frame),
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                        buffer: shared.steps,
                        offset: 0,
                        size: wgpu::BufferSize::new(size_of::<GpuBatchStep>() as u64),
                    }),
                },
                whole(6, shared.info),
                whole(8, shared.cloths),
                whole(19, shared.iterate),
                whole(20, shared.substep_start),
                whole(21, shared.inertial),
                whole(49, &self.index),
                whole(50, &self.values),
                whole(51, &self.cloths),
                wgpu::BindGroupEntry {
                    binding: 52,
                    resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                        buffer: &self.passes,
                        offset: 0,
                        size: wgpu::BufferSize::new(size_of::<GpuMultigridPass>() as u64),
                    }),
                },
            ],
        })
    }

    /// Calls `each` with `mg_begin` of substep `k`, which goes before the substep's prediction.
    pub(crate) fn begin(
        &self,
        kernels: &ClothKernels,
        group: &BindGroup,
        k: u32,
        each: &mut impl FnMut(Kernel, &dyn Fn(&mut wgpu::ComputePass<'_>)),
    ) {
        if self.levels > 0 {
            self.run(kernels, group, k, EntryPoint::MgBegin, CLOTHS, self.workgroups[CLOTHS as usize], each);
        }
    }

    /// Calls `each` with every dispatch of substep `k`'s correction, in order, after the
    /// sweep; `particles` is the batch's particle dispatch.
    pub(crate) fn correct(
        &self,
        kernels: &ClothKernels,
        group: &BindGroup,
        k: u32,
        particles: (u32, u32),
        each: &mut impl FnMut(Kernel, &dyn Fn(&mut wgpu::ComputePass<'_>)),
    ) {
        if self.levels == 0 {
            return;
        }
        let per_cloth = (self.cloth_slots, 1);
        let level = |l: u32| FIRST_LEVEL + l;
        let groups = |entry: u32| self.workgroups[entry as usize];
        let mut run = |entry: EntryPoint, pass: u32, workgroups: (u32, u32)| {
            self.run(kernels, group, k, entry, pass, workgroups, each);
        };
        run(EntryPoint::MgSprings, SPRINGS, groups(SPRINGS));
        run(EntryPoint::MgResidual, level(0), groups(level(0)));
        for l in 1..self.levels {
            run(EntryPoint::MgGalerkin, level(l), groups(level(l)));
        }
        run(EntryPoint::MgFactor, NODES, groups(NODES));
        run(EntryPoint::MgDenseFactor, CLOTHS, per_cloth);
        self.cycle(0, &mut |entry, l| match entry {
            EntryPoint::MgCoarsest => run(entry, CLOTHS, per_cloth),
            _ => run(entry, level(l), groups(level(l))),
        });
        run(EntryPoint::MgLineChunks, CHUNKS, groups(CHUNKS));
        run(EntryPoint::MgLineSearch, CHUNKS, per_cloth);
        run(EntryPoint::MgApply, CLOTHS, particles);
    }

    /// Calls `run` with the passes of the cycle from level `l` (and the level each runs on), in
    /// order, as `bvh_cloth_core::solver::multigrid` runs it: the smoothing from zero, then one
    /// visit of the next level (two from the first level in [`Cycle::TopW`]), each the
    /// residual's restriction, the next level's cycle and the smoothing on the way up.
    fn cycle(&self, l: u32, run: &mut impl FnMut(EntryPoint, u32)) {
        if l + 1 >= self.levels {
            run(EntryPoint::MgCoarsest, l);
            return;
        }
        run(EntryPoint::MgSmoothDown, l);
        let visits = if self.cycle == Cycle::TopW && l == 0 { 2 } else { 1 };
        for visit in 0..visits {
            if visit > 0 {
                run(EntryPoint::MgKeep, l);
            }
            run(EntryPoint::MgRestrict, l + 1);
            self.cycle(l + 1, run);
            run(EntryPoint::MgSmoothUp, l);
        }
    }

    /// One dispatch of `entry` in substep `k` with pass entry `pass`.
    #[allow(clippy::too_many_arguments)]
    fn run(
        &self,
        kernels: &ClothKernels,
        group: &BindGroup,
        k: u32,
        entry: EntryPoint,
        pass: u32,
        workgroups: (u32, u32),
        each: &mut impl FnMut(Kernel, &dyn Fn(&mut wgpu::ComputePass<'_>)),
    ) {
        let offsets = [(u64::from(3 * k) * UNIFORM_STRIDE) as u32, (u64::from(pass) * UNIFORM_STRIDE) as u32];
        each(Kernel::Multigrid, &|compute| {
            compute.set_pipeline(kernels.pipeline(entry));
            compute.set_bind_group(0, group, &offsets);
            compute.dispatch_workgroups(workgroups.0, workgroups.1, 1);
        });
    }
}
