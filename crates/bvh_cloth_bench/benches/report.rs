//! The benchmark report: prints markdown tables, and writes the data of the plot as CSV.
//!
//! 1. The paper's Table VII: a 64 x 64 cloth on the bunny and the dragon at n = 1, 3, 5, per
//!    frame, on the CPU backend (1 thread and all threads) and the GPU kernels.
//! 2. Particle queries head to head: our LBVH, brute force over the same spheres, and parry3d's
//!    exact triangle-mesh projection, on the same draped particle positions.
//! 3. Collider fidelity: cloths resting on the spheres, measured against the true mesh.
//! 4. Scaling: step time against cloth size; the cost of any topology (an authored mesh against
//!    the grid at the same particle count); collider build time against n.
//! 5. The GPU profile: GPU ms per tick by kernel (timestamp queries), and many cloths: one
//!    GPU batch against a batch per cloth, 1 to 512 cloths.
//! 6. Precision far from the origin: how far from it a stiff cloth still steps finitely.
//! 7. The solvers: block descent against RK4 for the same sag, across stiffness, and big cloth
//!    on the GPU.
//! 8. Exact primitives against voxelised meshes: collision cost per particle.
//! 9. Skinned colliders: one frame's refit against skinning the mesh's vertices.
//! 10. Exact contact against sphere contact: the resting air gap; its point query against
//!     parry3d's bounded projection, on a draped cloth and on points near the surface, and its
//!     build and memory up to 2 million triangles ([`exact_queries`], `exact_contact_queries`,
//!     `exact_contact_build`).
//! 11. Self-contact: a cloth folding over a bar and two cloths on the bunny, checked with an
//!     exact triangle–triangle test, and its cost; and how a fast fold's layers get through
//!     each other ([`crossing_events`], `self_contact_events`).
//! 12. Wind: a flag's flutter in steady wind (the free edge's spectral peak) and its energy on
//!     both backends, GPU against CPU in gusty wind, and what drag and lift cost.
//! 13. Motion ([`motion`]): each solver setting's free fall and drift against the analytic
//!     answer, a hanging cloth's sag and strain in motion against RK4 from 32 x 32 to 256 x 256,
//!     and the flag's flutter; and what the tethers cost block descent a tick, and the default
//!     (the multigrid integrator) against block descent (`motion_cost`); the default's swing at
//!     512 x 512 and 1024 x 1024 against RK4 at the same resolution (`fine_swing`).
//! 14. Several cloths on the CPU ([`cpu_cloths`]): stepped one after another against side by
//!     side.
//!
//! `WGPU_BACKEND=vulkan cargo bench -p bvh_cloth_bench --bench report`
//! (without a GPU adapter the GPU columns say so and the rest still runs). Append `-- NAME...`
//! to run only the sections whose name contains one of the NAMEs: `table_vii`, `queries`,
//! `fidelity`, `step_scaling`, `topology`, `gpu_profile`, `many_cloths`, `build_scaling`,
//! `far_from_origin`, `solver`, `solver_gpu`, `primitives`, `skinned_refit`, `exact_contact`,
//! `exact_contact_queries`, `exact_contact_build`, `exact_contact_gpu`, `self_contact`,
//! `self_contact_events`, `self_contact_crossed_gpu`, `self_contact_gpu`, `wind`, `wind_gpu`,
//! `motion`, `motion_cost`, `fine_swing`, `cpu_cloths`. The GPU halves of the solver, exact-contact, self-contact and
//! wind tables are sections of their own, so `-- gpu` runs every GPU-only table without their
//! CPU simulations.

#[path = "report/cpu_cloths.rs"]
mod cpu_cloths;
#[path = "report/crossing_events.rs"]
mod crossing_events;
#[path = "report/exact_contact.rs"]
mod exact_contact;
#[path = "report/exact_queries.rs"]
mod exact_queries;
#[path = "report/fidelity.rs"]
mod fidelity;
#[path = "report/gpu.rs"]
mod gpu;
#[path = "report/gpu_profile.rs"]
mod gpu_profile;
#[path = "report/motion.rs"]
mod motion;
#[path = "report/precision.rs"]
mod precision;
#[path = "report/primitives.rs"]
mod primitives;
#[path = "report/queries.rs"]
mod queries;
#[path = "report/scaling.rs"]
mod scaling;
#[path = "report/self_contact.rs"]
mod self_contact;
#[path = "report/skinned.rs"]
mod skinned;
#[path = "report/solver.rs"]
mod solver;
#[path = "report/table_vii.rs"]
mod table_vii;
#[path = "report/wind.rs"]
mod wind;

// Each section's entry point, and the helpers the sections share, by name in `main` and in the
// sections (which `use super::*`).
use self::{
    exact_contact::*, fidelity::*, gpu::*, gpu_profile::*, precision::*, primitives::*, queries::*, scaling::*,
    self_contact::*, skinned::*, solver::*, table_vii::*, wind::*,
};
use std::fmt::Write as _;
use std::sync::Arc;

use bvh_cloth_bench::{
    MODELS, TICK, authored_grid, best_of, cloth_above, collider, drape, median, model, square_grid, time,
    topology_above,
};
use bvh_cloth_core::ObjMesh;

use bvh_cloth_core::SelfContact;
use bvh_cloth_core::SkinRef;
use bvh_cloth_core::SkinScratch;
use bvh_cloth_core::backend::ColliderFrame;
use bvh_cloth_core::backend::ContactSolver;
use bvh_cloth_core::backend::SkinnedVertices;
use bvh_cloth_core::backend::crossing_pairs;
use bvh_cloth_core::backend::intersecting_pairs;
use bvh_cloth_core::{
    Aerodynamics, Affine3A, ClothGrid, ClothParams, ClothSim, ClothTopology, Collider, ColliderPose, Integrator,
    Primitive, Quat, UVec2, Vec2, Vec3, Wind,
};
use bvh_cloth_gpu::layout::{GpuParticle, load_gpu_particles};
use bvh_cloth_gpu::{ClothBatch, GpuColliders, Kernel, SkinRefit, headless, wgpu};
use parry3d::math::Vector;
use parry3d::query::{PointQuery, Ray, RayCast};
use parry3d::shape::{TriMesh, TriMeshFlags};
use rayon::prelude::*;

/// Voxel resolutions of the query table.
const RESOLUTIONS: [u32; 7] = [1, 3, 5, 8, 16, 32, 64];
/// Frames timed per Table VII case, after one simulated second of falling and landing.
const FRAMES: usize = 30;

fn main() {
    let threads = rayon::current_num_threads();
    let single = rayon::ThreadPoolBuilder::new().num_threads(1).build().expect("a one-thread pool");
    let gpu = headless::kernel_rig();
    if let Some(gpu) = &gpu {
        let info = &gpu.info;
        println!("GPU adapter: {} ({:?}, driver {} {})", info.name, info.device_type, info.driver, info.driver_info);
    }
    if gpu.is_none() {
        println!("GPU adapter: none (set WGPU_BACKEND, e.g. vulkan for lavapipe); GPU columns are skipped");
    }
    println!("CPU: {}, {threads} threads", cpu_name());
    let meshes: Vec<ObjMesh> = MODELS.iter().map(|m| model(m)).collect();
    let csv_dir = format!("{}/../../docs/benchmarks", std::env::var("CARGO_MANIFEST_DIR").expect("run by cargo"));
    std::fs::create_dir_all(&csv_dir).expect("docs/benchmarks is writable");

    // `cargo bench ... -- NAME...` runs only the sections whose name contains one of the NAMEs.
    let filters: Vec<String> = std::env::args().skip(1).filter(|a| !a.starts_with("--")).collect();
    let run = |section: &str| filters.is_empty() || filters.iter().any(|f| section.contains(f.as_str()));
    if run("table_vii") {
        table_vii(&meshes, gpu.as_ref(), &single, threads);
    }
    let parry: Vec<TriMesh> = meshes.iter().map(exact_mesh).collect();
    if run("queries") {
        std::fs::write(format!("{csv_dir}/queries.csv"), queries(&meshes, &parry)).expect("write queries.csv");
    }
    if run("fidelity") {
        std::fs::write(format!("{csv_dir}/fidelity.csv"), fidelity(&meshes, &parry)).expect("write fidelity.csv");
    }
    if run("step_scaling") {
        step_scaling(gpu.as_ref(), &single, threads);
    }
    if run("topology") {
        topology(gpu.as_ref(), &single, threads);
    }
    if run("gpu_profile") {
        gpu_profile(&meshes, gpu.as_ref());
    }
    if run("many_cloths") {
        many_cloths(gpu.as_ref());
    }
    if run("build_scaling") {
        build_scaling(&meshes);
    }
    if run("far_from_origin") {
        far_from_origin();
    }
    if run("solver") {
        solver(&single, threads);
    }
    if run("solver_gpu") {
        solver_on_gpu(&meshes, gpu.as_ref());
    }
    if run("primitives") {
        primitives(&meshes[0], gpu.as_ref());
    }
    if run("skinned_refit") {
        skinned_refit(&meshes, &single, gpu.as_ref());
    }
    if run("exact_contact") {
        exact_contact(&meshes, &parry);
    }
    if run("exact_contact_queries") {
        exact_queries::exact_queries(&meshes, &single);
    }
    if run("exact_contact_build") {
        exact_queries::exact_build(&meshes);
    }
    if run("exact_contact_gpu") {
        exact_contact_on_gpu(&meshes, gpu.as_ref());
    }
    if run("self_contact") {
        self_contact(&meshes[0], &single, threads);
    }
    if run("self_contact_events") {
        crossing_events::self_contact_events(&meshes[0]);
    }
    if run("self_contact_crossed_gpu") {
        started_crossed_on_gpu(&meshes[0], gpu.as_ref());
    }
    if run("self_contact_gpu") {
        self_contact_on_gpu(&meshes[0], gpu.as_ref());
    }
    if run("wind") {
        wind(&single, threads);
    }
    if run("wind_gpu") {
        wind_on_gpu(&meshes[0], gpu.as_ref());
    }
    if run("motion") {
        motion::motion();
    }
    if run("motion_cost") {
        motion::motion_cost();
    }
    if run("fine_swing") {
        motion::fine_swing();
    }
    if run("cpu_cloths") {
        cpu_cloths::cpu_cloths(threads);
    }
    println!("\nCSV written to docs/benchmarks/ (plot: python3 scripts/plot_benchmarks.py)");
}

/// Writes one byte in every 64-byte line of `bytes`: evicts the caches, and its loop's branches
/// are few and always taken.
fn write_every_line(bytes: &mut [u8]) {
    for b in bytes.iter_mut().step_by(64) {
        *b = b.wrapping_add(1);
    }
    std::hint::black_box(bytes);
}

/// Three million steps of a loop over 16 KiB whose branches follow a pseudo-random sequence
/// (xorshift): trains the branch predictors on other code, and evicts little from the caches.
fn train_other_branches(words: &mut [u32; 4096]) {
    let mut state = words[0] | 1;
    for _ in 0..3_000_000 {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        let w = &mut words[(state & 4095) as usize];
        if *w & 1 == 0 {
            *w = w.wrapping_add(state);
        } else if state & 2 == 0 {
            *w ^= 7;
        } else {
            *w = w.rotate_left(3);
        }
    }
    std::hint::black_box(words);
}

/// The exact mesh as parry3d sees it, oriented so that its pseudo-normals tell inside from outside.
fn exact_mesh(mesh: &ObjMesh) -> TriMesh {
    let vertices = mesh.positions.iter().map(|&p| Vector::from(p)).collect();
    let triangles = mesh.indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
    let flags =
        TriMeshFlags::ORIENTED | TriMeshFlags::MERGE_DUPLICATE_VERTICES | TriMeshFlags::DELETE_DEGENERATE_TRIANGLES;
    TriMesh::with_flags(vertices, triangles, flags).expect("the bundled models are valid triangle meshes")
}

/// The CPU's model name, from /proc/cpuinfo where there is one.
fn cpu_name() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|s| s.trim().to_owned())
        })
        .unwrap_or_else(|| "unknown".into())
}
