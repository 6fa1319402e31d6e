//! The order of a tick's dispatches: the anchors, then for each substep the air, the
//! integrator's stages or block descent's sweeps, and self-contact, every cloth in one pass.

use bvh_cloth_core::backend::MAX_COLOURS;
use wgpu::{BindGroup, CommandEncoder};

use crate::buffer::UNIFORM_STRIDE;
use crate::kernels::{ClothKernels, EntryPoint, Kernel, WORKGROUP_SIZE};
use crate::stages::air::AirPlan;

use super::ClothBatch;
use super::bind_groups::{DescentPlan, Groups};

impl ClothBatch {
    /// Records `ticks` ticks of every cloth: per tick the anchors, then per substep the
    /// integrator stages, the last fused with the collision response, all in one compute pass.
    /// Needs [`Self::prepare`] this frame.
    pub fn encode_ticks(&self, encoder: &mut CommandEncoder, kernels: &ClothKernels, ticks: u32) {
        self.encode_ticks_with(encoder, kernels, ticks, None);
    }

    /// As [`Self::encode_ticks`], the pass writing `timestamp_writes` at its start and end (a
    /// [`PassTimer`](crate::PassTimer)'s, to measure the ticks' GPU time).
    pub fn encode_ticks_with(
        &self,
        encoder: &mut CommandEncoder,
        kernels: &ClothKernels,
        ticks: u32,
        timestamp_writes: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) {
        let mut pass = encoder
            .begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("bvh_cloth_step"), timestamp_writes });
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
    pub(super) fn dispatch_ticks(
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
                    pass.set_pipeline(kernels.pipeline(EntryPoint::ApplyAnchors));
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
    pub(super) fn dispatch_explicit(
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
                pass.set_pipeline(kernels.pipeline(EntryPoint::NodeUpdate));
                pass.set_bind_group(0, group, &offset);
                pass.dispatch_workgroups(x, y, 1);
            });
        }
        let offset = step(0);
        each(Kernel::NodeUpdateFinal, &|pass| {
            pass.set_pipeline(kernels.pipeline(EntryPoint::NodeUpdateFinal));
            pass.set_bind_group(0, &groups.last, &offset);
            pass.dispatch_workgroups(x, y, 1);
        });
    }

    /// Calls `each` with substep `k` of block descent: the multigrid cloths' choice of step,
    /// the prediction (after the air kick in a batch with aerodynamics), the sweeps colour by
    /// colour, the multigrid correction, and the finish with the collision response.
    pub(super) fn dispatch_descent(
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
        let multigrid = self.multigrid.as_ref().and_then(|stage| stage.plan.as_ref()).zip(groups.multigrid.as_ref());
        if let Some((plan, group)) = multigrid {
            plan.begin(kernels, group, k, each);
        }
        match air {
            Some((air, air_groups)) => air.predict(kernels, air_groups, self.workgroups, k, each),
            None => each(Kernel::VbdPredict, &|pass| {
                pass.set_pipeline(kernels.pipeline(EntryPoint::VbdPredict));
                pass.set_bind_group(0, &groups.predict, &offset);
                pass.dispatch_workgroups(x, y, 1);
            }),
        }
        for iteration in 0..plan.iterations {
            for (colour, range) in plan.colours.iter().enumerate() {
                let entry = u64::from(iteration * MAX_COLOURS) + colour as u64;
                let offsets = [offset[0], (entry * UNIFORM_STRIDE) as u32];
                each(Kernel::VbdSolve, &|pass| {
                    pass.set_pipeline(kernels.pipeline(EntryPoint::VbdSolve));
                    pass.set_bind_group(0, &groups.solve, &offsets);
                    pass.dispatch_workgroups(range.workgroups.0, range.workgroups.1, 1);
                });
            }
        }
        if let Some((plan, group)) = multigrid {
            plan.correct(kernels, group, k, self.workgroups, each);
        }
        if plan.free_bodies {
            let cloths = self.slots.len() as u32;
            for (level, (entry, group)) in
                [EntryPoint::VbdDriftBlocks, EntryPoint::VbdDrift].into_iter().zip(&groups.drift).enumerate()
            {
                let pipeline = kernels.pipeline(entry);
                let (gx, gy) = if level == 0 { (x, y) } else { (cloths, 1) };
                each(Kernel::VbdDrift, &|pass| {
                    pass.set_pipeline(pipeline);
                    pass.set_bind_group(0, group, &offset);
                    pass.dispatch_workgroups(gx, gy, 1);
                });
            }
        }
        each(Kernel::VbdFinish, &|pass| {
            pass.set_pipeline(kernels.pipeline(EntryPoint::VbdFinish));
            pass.set_bind_group(0, &groups.finish, &offset);
            pass.dispatch_workgroups(x, y, 1);
        });
    }
}
