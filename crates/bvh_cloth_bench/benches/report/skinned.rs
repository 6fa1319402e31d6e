//! The section `skinned_refit`: one frame's refit of a skinned collider against skinning the
//! mesh's vertices, on the CPU and the GPU.

use super::*;

/// Skinned colliders: each model given a skeleton of [`BONES`] bones stacked up its height,
/// every vertex weighted to the two bones nearest its height, posed with every bone bent. One
/// frame's collider update (skin the vertices the points use, fit every sphere to its points,
/// refit the tree) against skinning every vertex of the mesh alone (what a renderer or a CPU
/// skinning pass does), both on one thread, best of 15.
pub(crate) fn skinned_refit(meshes: &[ObjMesh], single: &rayon::ThreadPool, gpu: Option<&Gpu>) {
    println!(
        "\n## Skinned colliders: one frame's refit against skinning the vertices, one thread; and the refit on the \
         GPU (median of 15, timestamp queries around its pass)\n"
    );
    println!(
        "| model | vertices | n | spheres | points | skin vertices ms | refit ms | refit / skin | build ms | GPU refit ms | GPU dispatches |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    for (name, mesh) in MODELS.iter().zip(meshes) {
        let (joints, weights) = bone_weights(mesh);
        let skin = SkinRef { joints: &joints, weights: &weights, joint_count: BONES };
        let pose = bent_pose();
        let vertices = SkinnedVertices {
            positions: mesh.positions.iter().map(|&p| p.into()).collect(),
            joints: joints.clone(),
            weights: weights.clone(),
        };
        for n in [5u32, 16] {
            let mut build_s = 0.0;
            let collider = single.install(|| {
                let mut built = None;
                build_s = best_of(3, || {
                    built = Some(
                        Collider::from_skinned_mesh(mesh.as_mesh_ref(), skin, bvh_cloth_core::Voxels::PerAxis(n))
                            .expect("a valid skin"),
                    );
                });
                built.expect("built")
            });
            let skinned = collider.skin().expect("a skinned collider").clone();
            // Skinning and refit alternate, so that both meet the same moments of a shared
            // machine's load; the best of 50 of each.
            let (skin_s, refit_s) = single.install(|| {
                let mut out = Vec::new();
                let mut posed = collider.clone();
                let mut scratch = SkinScratch::default();
                (0..50).fold((f64::INFINITY, f64::INFINITY), |(skin_s, refit_s), _| {
                    let skin = best_of(1, || vertices.skin_into(&pose, &mut out));
                    let refit = best_of(1, || posed.pose_skin(&pose, &mut scratch).expect("a valid pose"));
                    (skin_s.min(skin), refit_s.min(refit))
                })
            });
            let (gpu_ms, dispatches) = gpu
                .and_then(|gpu| gpu_refit_ms(gpu, &collider, &pose))
                .map_or(("—".to_string(), "—".to_string()), |(ms, d)| (format!("{ms:.4}"), d.to_string()));
            println!(
                "| {name} | {} | {n} | {} | {} | {:.3} | {:.3} | {:.2}x | {:.1} | {gpu_ms} | {dispatches} |",
                mesh.positions.len(),
                collider.sphere_count(),
                skinned.points.len(),
                skin_s * 1e3,
                refit_s * 1e3,
                refit_s / skin_s,
                build_s * 1e3,
            );
        }
    }
    if gpu.is_some_and(|g| g.is_software()) {
        println!("\nThe GPU here is a software adapter on the same CPU cores: its column is not a GPU figure.");
    }
}

/// GPU ms of one refit of `collider` (skinned) to `pose` on the GPU (`SkinRefit`): the median of
/// 15, each timed with timestamp queries at the start and end of the refit's compute pass; and
/// the dispatches a refit records. `None` without timestamp queries.
pub(crate) fn gpu_refit_ms(gpu: &Gpu, collider: &Collider, pose: &[Affine3A]) -> Option<(f64, usize)> {
    if !gpu.device.features().contains(wgpu::Features::TIMESTAMP_QUERY) {
        return None;
    }
    let mut collider = collider.clone();
    let clearance = collider.accept_skin_pose(pose).ok()??;
    let colliders = GpuColliders::new(&gpu.device, std::slice::from_ref(&collider));
    let mut refit = SkinRefit::new(&gpu.device, collider.skin()?, collider.lbvh()?).ok()?;
    if !refit.bind(&gpu.device, &gpu.kernels, &colliders, 0) {
        return None;
    }
    refit.write_pose(&gpu.queue, pose, clearance);
    let queries = gpu.device.create_query_set(&wgpu::QuerySetDescriptor {
        label: None,
        ty: wgpu::QueryType::Timestamp,
        count: 2,
    });
    let resolved = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size: 16,
        usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    let period_ns = f64::from(gpu.queue.get_timestamp_period());
    let samples = (0..16)
        .map(|_| {
            let mut encoder = gpu.device.create_command_encoder(&Default::default());
            {
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("bvh_cloth_skin_refit_timed"),
                    timestamp_writes: Some(wgpu::ComputePassTimestampWrites {
                        query_set: &queries,
                        beginning_of_pass_write_index: Some(0),
                        end_of_pass_write_index: Some(1),
                    }),
                });
                refit.encode(&mut pass, &gpu.kernels);
            }
            encoder.resolve_query_set(&queries, 0..2, &resolved, 0);
            gpu.queue.submit([encoder.finish()]);
            let stamps: Vec<u64> = headless::read(&gpu.device, &gpu.queue, &resolved);
            stamps[1].saturating_sub(stamps[0]) as f64 * period_ns * 1e-6
        })
        // The first refit warms the pipelines' caches.
        .skip(1)
        .collect();
    Some((median(samples), refit.dispatches()))
}

/// Bones of the skinned-collider scenes.
pub(crate) const BONES: usize = 8;

/// Every vertex weighted to the two bones whose centres are nearest its height, linearly.
pub(crate) fn bone_weights(mesh: &ObjMesh) -> (Vec<[u16; 4]>, Vec<[f32; 4]>) {
    let (lo, hi) =
        mesh.positions.iter().fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), p| (lo.min(p[1]), hi.max(p[1])));
    mesh.positions
        .iter()
        .map(|p| {
            let t = ((p[1] - lo) / (hi - lo) * BONES as f32 - 0.5).clamp(0.0, (BONES - 1) as f32);
            let below = (t.floor() as usize).min(BONES - 2);
            let w = t - below as f32;
            ([below as u16, below as u16 + 1, 0, 0], [1.0 - w, w, 0.0, 0.0])
        })
        .unzip()
}

/// Each bone turned 0.15 rad more than the one below it about a horizontal axis through its
/// base, the bones chained: the model bends like a spine.
pub(crate) fn bent_pose() -> Vec<Affine3A> {
    let mut matrices = Vec::with_capacity(BONES);
    let mut parent = Affine3A::IDENTITY;
    for bone in 0..BONES {
        let base = Vec3::new(0.0, bone as f32 / BONES as f32, 0.0);
        let turn =
            Affine3A::from_translation(base) * Affine3A::from_rotation_z(0.15) * Affine3A::from_translation(-base);
        parent *= turn;
        matrices.push(parent);
    }
    matrices
}
