//! The real WGSL kernels on a real device: lavapipe in CI (`WGPU_BACKEND=vulkan`), any GPU
//! elsewhere. First each kernel alone on a tiny input with a hand-checked answer, so that a
//! failure points at one kernel; then whole scenes against the CPU reference.
//!
//! Without an adapter these tests pass with a note, unless `BVH_CLOTH_REQUIRE_GPU` is set (as
//! `.ci/run` sets it), where a missing adapter fails them.

use bvh_cloth_core::ObjMesh;
use bvh_cloth_core::backend::crossing_pairs;
use bvh_cloth_core::backend::{ContactSolver, ForceModel, MultigridStepping};
use bvh_cloth_core::parse_obj;
use bvh_cloth_gpu::layout::{GpuCollider, GpuMeshWriteback, GpuParticle, load_gpu_particles};
use std::sync::Arc;

use bvh_cloth_core::{
    Affine3A, ClothGrid, ClothParams, ClothSim, ClothTopology, Collider, ColliderPose, ColliderShape, CollisionLayers,
    Integrator, Lbvh, MeshRef, Primitive, Quat, SkinRef, SkinScratch, Sphere, SpringStiffness, UVec2, UVec3, Vec2,
    Vec3, Voxels,
};
use bvh_cloth_gpu::wgpu::util::DeviceExt;
use bvh_cloth_gpu::wgpu::{self, Device, Queue};
use bvh_cloth_gpu::{
    ClothBatch, ClothId, ClothKernels, FaultReadback, GpuColliders, Kernel, PassTimer, SkinRefit, headless,
};
use core::time::Duration;

struct Rig {
    device: Device,
    queue: Queue,
    kernels: ClothKernels,
}

fn rig() -> Option<Rig> {
    let Some(headless::KernelRig { device, queue, kernels, info }) = headless::kernel_rig() else {
        assert!(
            std::env::var_os("BVH_CLOTH_REQUIRE_GPU").is_none(),
            "no GPU adapter (install mesa-vulkan-drivers for lavapipe and set WGPU_BACKEND=vulkan)"
        );
        eprintln!("no GPU adapter: skipped");
        return None;
    };
    eprintln!("adapter: {:?}", info.name);
    Some(Rig { device, queue, kernels })
}

/// One cloth in a batch of its own: the kernels alone, and single scenes against the CPU.
struct OneCloth {
    batch: ClothBatch,
    id: ClothId,
}

impl OneCloth {
    fn upload_state(&self, queue: &Queue, sim: &ClothSim) {
        self.batch.upload_state(queue, self.id, sim);
    }
}

impl Rig {
    fn cloth(&self, sim: &ClothSim, tick: f32) -> OneCloth {
        let mut batch = ClothBatch::new(&self.device, &self.queue);
        let id = batch.insert(&self.device, &self.queue, sim).unwrap();
        batch.set_params(&self.queue, id, sim.params(), tick);
        OneCloth { batch, id }
    }

    /// A batch of every cloth of `cloths`, each with its parameters for ticks of `tick` seconds,
    /// and their ids in the same order.
    fn batch(&self, cloths: &[(&str, ClothSim)], tick: f32) -> (ClothBatch, Vec<ClothId>) {
        let mut batch = ClothBatch::new(&self.device, &self.queue);
        let ids = cloths
            .iter()
            .map(|(_, sim)| {
                let id = batch.insert(&self.device, &self.queue, sim).unwrap();
                batch.set_params(&self.queue, id, sim.params(), tick);
                id
            })
            .collect();
        (batch, ids)
    }

    /// Runs `ticks` ticks of every cloth of `batch`.
    fn run(&self, batch: &mut ClothBatch, colliders: &GpuColliders, ticks: u32) {
        batch.prepare(&self.device, &self.queue, &self.kernels, colliders);
        let mut encoder = self.device.create_command_encoder(&Default::default());
        batch.encode_ticks(&mut encoder, &self.kernels, ticks);
        self.queue.submit([encoder.finish()]);
    }

    fn ticks(&self, cloth: &mut OneCloth, colliders: &GpuColliders, ticks: u32) {
        self.run(&mut cloth.batch, colliders, ticks);
    }

    /// Runs `normal_shader` for `cloth` into a vertex buffer that starts as `words`, laid out
    /// as `writeback` says, and returns the buffer's words.
    fn write_vertices(&self, cloth: &mut OneCloth, writeback: GpuMeshWriteback, words: Vec<f32>) -> Vec<f32> {
        let vertices = self.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: None,
            contents: bytemuck::cast_slice(&words),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        });
        cloth.batch.set_writeback(cloth.id, writeback, &vertices);
        cloth.batch.prepare(&self.device, &self.queue, &self.kernels, &GpuColliders::new(&self.device, &[]));
        let mut encoder = self.device.create_command_encoder(&Default::default());
        cloth.batch.encode_writebacks(&mut encoder, &self.kernels);
        self.queue.submit([encoder.finish()]);
        headless::read(&self.device, &self.queue, &vertices)
    }

    /// A set of `count` timestamp queries, or `None` when the adapter has none.
    fn timestamp_queries(&self, count: u32) -> Option<wgpu::QuerySet> {
        self.device.features().contains(wgpu::Features::TIMESTAMP_QUERY).then(|| {
            self.device.create_query_set(&wgpu::QuerySetDescriptor {
                label: None,
                ty: wgpu::QueryType::Timestamp,
                count,
            })
        })
    }

    /// Cloth `id`'s particles as the GPU has them.
    fn batch_particles(&self, batch: &ClothBatch, id: ClothId) -> Vec<GpuParticle> {
        batch.read_particles(&self.device, &self.queue, id).expect("the cloth is in the batch")
    }

    /// The positions of each of `ids`'s cloths in `batch`, in order.
    fn batch_positions(&self, batch: &ClothBatch, ids: &[ClothId]) -> Vec<Vec<Vec3>> {
        ids.iter().map(|&id| self.batch_particles(batch, id).iter().map(position).collect()).collect()
    }

    /// One tick of `tick` seconds of every cloth of `batch` on the GPU and of each of `cloths`
    /// (named, with its id in `ids`) on the CPU, the GPU starting from the CPU's state when
    /// `resync`; against `colliders` (CPU and GPU). Returns each cloth's largest CPU–GPU gap.
    fn tick_against_the_cpu(
        &self,
        batch: &mut ClothBatch,
        cloths: &mut [(&str, ClothSim)],
        ids: &[ClothId],
        colliders: (&[Collider], &GpuColliders),
        tick: f32,
        resync: bool,
    ) -> Vec<f32> {
        if resync {
            for ((_, sim), &id) in cloths.iter().zip(ids) {
                batch.upload_state(&self.queue, id, sim);
            }
        }
        for (_, sim) in cloths.iter_mut() {
            sim.tick(tick, colliders.0);
        }
        self.run(batch, colliders.1, 1);
        cloths
            .iter()
            .zip(ids)
            .map(|((_, sim), &id)| {
                let on_gpu: Vec<Vec3> = self.batch_particles(batch, id).iter().map(position).collect();
                largest_gap(&sim.positions(), &on_gpu)
            })
            .collect()
    }

    /// `ticks` ticks of 1/60 s of cloths in the wind, without colliders, each from the CPU's
    /// state and on the CPU's wind clock: each cloth's largest gap after one tick, held to
    /// 1e-5 m.
    fn windy_ticks_against_the_cpu(
        &self,
        batch: &mut ClothBatch,
        cloths: &mut [(&str, ClothSim)],
        ids: &[ClothId],
        ticks: u32,
    ) -> Vec<f32> {
        let none = GpuColliders::new(&self.device, &[]);
        let mut worst = vec![0.0f32; cloths.len()];
        for _ in 0..ticks {
            batch.set_wind_clock(cloths[0].1.wind_time(), 1.0 / 60.0, 1);
            let gaps = self.tick_against_the_cpu(batch, cloths, ids, (&[], &none), 1.0 / 60.0, true);
            for (worst, gap) in worst.iter_mut().zip(gaps) {
                *worst = worst.max(gap);
            }
        }
        for ((name, _), &gap) in cloths.iter().zip(&worst) {
            assert!(gap < 1e-5, "{name}: GPU and CPU differ by {gap} m after one tick");
        }
        worst
    }

    fn particles(&self, cloth: &OneCloth) -> Vec<GpuParticle> {
        self.batch_particles(&cloth.batch, cloth.id)
    }

    /// Cloth `id`'s count of quarantined particles.
    fn faults(&self, cloth: &OneCloth) -> u32 {
        let (buffer, offset) = cloth.batch.faults(cloth.id).expect("the cloth is in the batch");
        let words: Vec<u32> = headless::read(&self.device, &self.queue, buffer);
        words[(offset / 4) as usize]
    }
}

fn position(p: &GpuParticle) -> Vec3 {
    Vec3::from_slice(&p.position[..3])
}

fn velocity(p: &GpuParticle) -> Vec3 {
    Vec3::from_slice(&p.velocity[..3])
}

/// A square grid `size` metres wide of `n x n` particles.
fn square(size: f32, n: u32) -> ClothGrid {
    ClothGrid::new(Vec2::splat(size), UVec2::splat(n))
}

/// A cloth on `grid` with `params`, placed by `pose`, with `pins` held.
fn grid_cloth(grid: ClothGrid, params: ClothParams, pose: Affine3A, pins: &[u32]) -> ClothSim {
    ClothSim::new(params, Arc::new(ClothTopology::grid(grid).unwrap()), pose, pins).unwrap()
}

/// A 2 x 2 cloth, 1 m wide, whose particles weigh 1 kg each, with no damping.
fn small(integrator: Integrator, spring_k: f32, gravity: Vec3, pins: &[u32]) -> ClothSim {
    let params = ClothParams {
        mass: 4.0,
        looper: 1,
        spring_k,
        damping: 0.0,
        gravity,
        stiffness: SpringStiffness { structural: 1.0, shear: 0.0, bending: 0.0 },
        integrator,
        ..Default::default()
    };
    grid_cloth(square(1.0, 2), params, Affine3A::IDENTITY, pins)
}

// ---------------------------------------------------------------------------------------------
// node_update alone (no collider: the last stage only lands the step)
// ---------------------------------------------------------------------------------------------

#[test]
fn node_update_euler_free_fall() {
    let Some(rig) = rig() else { return };
    let sim = small(Integrator::SemiImplicitEuler, 0.0, Vec3::new(0.0, -10.0, 0.0), &[]);
    let none = GpuColliders::new(&rig.device, &[]);
    let mut cloth = rig.cloth(&sim, 0.1);
    rig.ticks(&mut cloth, &none, 1);
    // v = g h = -1; x = x0 + h v = x0 - 0.1.
    for (i, p) in rig.particles(&cloth).iter().enumerate() {
        assert!(velocity(p).distance(Vec3::new(0.0, -1.0, 0.0)) < 1e-6, "{i}: {:?}", p.velocity);
        assert!(position(p).distance(sim.position(i) + Vec3::new(0.0, -0.1, 0.0)) < 1e-6, "{i}: {:?}", p.position);
    }
}

/// A particle whose step overflows keeps its last finite state, at rest, on both integrators;
/// the others step as usual.
#[test]
fn node_update_quarantines_a_particle_that_overflows() {
    let Some(rig) = rig() else { return };
    for integrator in [Integrator::SemiImplicitEuler, Integrator::Rk4] {
        let mut sim = small(integrator, 0.0, Vec3::new(0.0, -10.0, 0.0), &[]);
        let huge = Vec3::new(3.0e38, 0.0, 0.0);
        sim.set_position(0, huge);
        sim.set_velocity(0, huge); // x + h v overflows to infinity with h = 1
        let none = GpuColliders::new(&rig.device, &[]);
        let mut cloth = rig.cloth(&sim, 1.0);
        rig.ticks(&mut cloth, &none, 1);
        let particles = rig.particles(&cloth);
        assert_eq!(position(&particles[0]), huge, "{integrator:?}: the last finite position is kept");
        assert_eq!(velocity(&particles[0]), Vec3::ZERO, "{integrator:?}: the quarantined particle is at rest");
        for (i, p) in particles.iter().enumerate().skip(1) {
            assert!(position(p).is_finite() && velocity(p).is_finite(), "{integrator:?} {i}: {p:?}");
            assert!(velocity(p).y < -9.0, "{integrator:?} {i}: the others fall as usual: {p:?}");
        }
        assert_eq!(rig.faults(&cloth), 1, "{integrator:?}: one particle quarantined in one substep");
    }
}

/// The fault count reaches the host through a `FaultReadback` without a blocking wait: recorded
/// with a frame's commands, mapped after the submit, taken once the device has been polled. The
/// counter is cleared by the read, one read is in flight at a time, and a cloth that stays
/// finite reads zero.
#[test]
fn fault_readback_reports_quarantined_particles_once() {
    let Some(rig) = rig() else { return };
    let mut sim = small(Integrator::SemiImplicitEuler, 0.0, Vec3::new(0.0, -10.0, 0.0), &[]);
    let huge = Vec3::new(3.0e38, 0.0, 0.0);
    sim.set_position(0, huge);
    sim.set_velocity(0, huge);
    let none = GpuColliders::new(&rig.device, &[]);
    let mut cloth = rig.cloth(&sim, 1.0);
    cloth.batch.prepare(&rig.device, &rig.queue, &rig.kernels, &none);
    let readback = FaultReadback::new(&rig.device);
    // A frame that starts from the overflowing state has one fault (after the quarantine the
    // particle rests at 3e38 and steps on finitely); one that goes on from there has none.
    let frame = |overflowing: bool, record: bool| {
        if overflowing {
            cloth.upload_state(&rig.queue, &sim);
        }
        let mut encoder = rig.device.create_command_encoder(&Default::default());
        cloth.batch.encode_ticks(&mut encoder, &rig.kernels, 3);
        let recorded = record && readback.record(&mut encoder, &cloth.batch, cloth.id);
        rig.queue.submit([encoder.finish()]);
        readback.submitted();
        recorded
    };
    assert_eq!(readback.take(), None, "nothing recorded yet");
    assert!(frame(true, true));
    assert!(!frame(true, true), "a second read waits for the first");
    headless::wait(&rig.device);
    assert_eq!(readback.take(), Some(1), "the first frame's fault");
    assert_eq!(readback.take(), None, "taken once");
    assert!(frame(false, true));
    headless::wait(&rig.device);
    assert_eq!(readback.take(), Some(1), "the unread second frame's fault, kept in the counter");
    assert!(frame(false, true));
    headless::wait(&rig.device);
    assert_eq!(readback.take(), Some(0), "cleared by the read, and nothing new");
}

#[test]
fn node_update_rk4_is_exact_under_constant_acceleration() {
    let Some(rig) = rig() else { return };
    let mut sim = small(Integrator::Rk4, 0.0, Vec3::new(0.0, -10.0, 0.0), &[2]);
    for i in 0..4 {
        sim.set_velocity(i, Vec3::X);
    }
    let none = GpuColliders::new(&rig.device, &[]);
    let mut cloth = rig.cloth(&sim, 0.1);
    rig.ticks(&mut cloth, &none, 1);
    let out = rig.particles(&cloth);
    // x = x0 + v0 h + g h^2 / 2, v = v0 + g h: RK4 is exact for a quadratic path.
    for i in [0, 1, 3] {
        let p = &out[i];
        assert!(position(p).distance(sim.position(i) + Vec3::new(0.1, -0.05, 0.0)) < 1e-6, "{i}: {:?}", p.position);
        assert!(velocity(p).distance(Vec3::new(1.0, -1.0, 0.0)) < 1e-6, "{i}: {:?}", p.velocity);
    }
    // The pinned particle has not moved (its velocity is masked).
    assert_eq!(position(&out[2]), sim.position(2));
}

#[test]
fn node_update_hooke_force_of_two_springs() {
    let Some(rig) = rig() else { return };
    // Particles at (-0.5, 0, -0.5), (0.5, 0, -0.5), (-0.5, 0, 0.5), (0.5, 0, 0.5); pin three and
    // pull the last 0.5 m along +x. k / m = 1, rest length 1.
    let mut sim = small(Integrator::SemiImplicitEuler, 1.0, Vec3::ZERO, &[0, 1, 2]);
    sim.set_position(3, Vec3::new(1.0, 0.0, 0.5));
    let none = GpuColliders::new(&rig.device, &[]);
    let mut cloth = rig.cloth(&sim, 0.1);
    rig.ticks(&mut cloth, &none, 1);
    let p = rig.particles(&cloth)[3];
    // To particle 2: d = (-1.5, 0, 0), (1 - 1/1.5) d = (-0.5, 0, 0).
    // To particle 1: d = (-0.5, 0, -1), (1 - 1/sqrt(1.25)) d = (-0.0527864, 0, -0.1055728).
    let a = Vec3::new(-0.5 - 0.052_786_4, 0.0, -0.105_572_8);
    assert!(velocity(&p).distance(0.1 * a) < 1e-6, "{:?}", p.velocity);
    assert!(position(&p).distance(Vec3::new(1.0, 0.0, 0.5) + 0.01 * a) < 1e-6, "{:?}", p.position);
}

// ---------------------------------------------------------------------------------------------
// the collision response alone (a substep without forces: the integrated state is the
// previous one moved by its velocity)
// ---------------------------------------------------------------------------------------------

fn particle(p: Vec3, v: Vec3, free: bool) -> GpuParticle {
    GpuParticle { position: p.extend(if free { 1.0 } else { 0.0 }).to_array(), velocity: v.extend(0.0).to_array() }
}

#[test]
fn collision_response_on_a_posed_ball() {
    let Some(rig) = rig() else { return };
    // A unit ball scaled by 2 and moved to (5, 1, -2), turned about z, with a 0.1 margin: a
    // world radius of 2.1. Four particles, one per case, moving for one substep of 0.1 s with
    // no force (semi-implicit Euler, no springs, no gravity): each lands at x + 0.1 v.
    let pose =
        ColliderPose { translation: Vec3::new(5.0, 1.0, -2.0), rotation: Quat::from_rotation_z(0.7), scale: 2.0 };
    let ball = Collider {
        shape: ColliderShape::Spheres {
            lbvh: Lbvh::build(&[Sphere::new(Vec3::ZERO, 1.0)]).into(),
            counts: UVec3::ONE,
            skin: None,
            surface: None,
        },
        margin: 0.1,
        friction: 0.0,
        pose,
        layers: CollisionLayers::DEFAULT,
    };
    let colliders = GpuColliders::new(&rig.device, std::slice::from_ref(&ball));
    let c = pose.translation;
    let previous = [
        particle(c + Vec3::new(0.0, 5.0, 0.0), Vec3::new(0.0, -40.0, 0.0), true), // flies in from above
        particle(c + Vec3::new(0.2, 0.4, 0.0), Vec3::new(4.0, 4.0, 0.0), true),   // starts inside
        particle(c + Vec3::new(0.0, 3.0, 0.0), Vec3::new(0.0, -5.0, 0.0), true),  // stays outside
        particle(c + Vec3::new(0.0, 1.0, 0.0), Vec3::ZERO, false),                // pinned inside
    ];
    let mut sim = small(Integrator::SemiImplicitEuler, 0.0, Vec3::ZERO, &[3]);
    load_gpu_particles(&mut sim, &previous);
    let mut cloth = rig.cloth(&sim, 0.1);
    rig.ticks(&mut cloth, &colliders, 1);
    let out = rig.particles(&cloth);

    let expect = |i: usize, p: Vec3, v: Vec3| {
        assert!(position(&out[i]).distance(p) < 1e-4, "particle {i} at {:?}, expected {p}", out[i].position);
        assert!(velocity(&out[i]).distance(v) < 1e-4, "particle {i} moving {:?}, expected {v}", out[i].velocity);
    };
    // The path from y = 5 to y = 1 enters at the top: held there, the normal part of its
    // velocity (all of it) gone.
    expect(0, c + Vec3::new(0.0, 2.1, 0.0), Vec3::ZERO);
    // Inside from the start: pushed out along the normal of where it landed, (0.6, 0.8); its
    // velocity (4, 4) points outwards, so only its normal part (5.6) goes.
    let radial = Vec3::new(0.6, 0.8, 0.0);
    expect(1, c + 2.1 * radial, Vec3::new(4.0, 4.0, 0.0) - 5.6 * radial);
    expect(2, c + Vec3::new(0.0, 2.5, 0.0), Vec3::new(0.0, -5.0, 0.0)); // untouched
    expect(3, c + Vec3::new(0.0, 1.0, 0.0), Vec3::ZERO); // pinned particles are never moved
}

// ---------------------------------------------------------------------------------------------
// normal_shader alone
// ---------------------------------------------------------------------------------------------

#[test]
fn normal_shader_writes_an_interleaved_vertex_buffer() {
    let Some(rig) = rig() else { return };
    // A flat 3 x 3 grid stood up by a quarter turn about x (its normals point along +Z in the
    // world), in a mesh whose entity sits at (1, 2, 3) turned the same way: in the mesh's own
    // frame the grid is flat again and faces +Y.
    let turn = Quat::from_rotation_x(core::f32::consts::FRAC_PI_2);
    let pose = Affine3A::from_rotation_translation(turn, Vec3::new(1.0, 2.0, 3.0));
    let sim = grid_cloth(square(1.0, 3), ClothParams::default(), pose, &[]);
    let mut cloth = rig.cloth(&sim, 0.1);
    // Vertices of 8 words: position at 0, normal at 4, sentinels elsewhere; one vertex of
    // padding before the first.
    const STRIDE: u32 = 8;
    let sentinel = -7.0f32;
    let mesh_to_world = Affine3A::from_rotation_translation(turn, Vec3::new(1.0, 2.0, 3.0));
    let writeback = GpuMeshWriteback::new(mesh_to_world, STRIDE, STRIDE, 0, 4);
    let out = rig.write_vertices(&mut cloth, writeback, vec![sentinel; (1 + sim.len()) * STRIDE as usize]);

    assert!(out[..STRIDE as usize].iter().all(|&w| w == sentinel), "the padding vertex was written");
    let grid = square(1.0, 3);
    for r in 0..3 {
        for c in 0..3 {
            let v = &out[((1 + grid.index(r, c)) * STRIDE as usize)..][..STRIDE as usize];
            // In the mesh's own frame the cloth is its flat rest pose, facing +Y.
            let local = Vec3::from_slice(&v[0..3]);
            assert!(local.distance(grid.local_rest_position(r, c)) < 1e-5, "({r},{c}) at {local}");
            assert!(Vec3::from_slice(&v[4..7]).distance(Vec3::Y) < 1e-5, "({r},{c}) normal {:?}", &v[4..7]);
            assert_eq!((v[3], v[7]), (sentinel, sentinel), "({r},{c}): a word outside the attributes was written");
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Whole scenes against the CPU reference
// ---------------------------------------------------------------------------------------------

fn largest_gap(a: &[Vec3], b: &[Vec3]) -> f32 {
    a.iter().zip(b).map(|(p, q)| p.distance(*q)).fold(0.0, f32::max)
}

fn centroid(p: &[Vec3]) -> Vec3 {
    p.iter().copied().sum::<Vec3>() / p.len() as f32
}

fn lowest(p: &[Vec3]) -> f32 {
    p.iter().map(|p| p.y).fold(f32::INFINITY, f32::min)
}

fn gpu_positions(rig: &Rig, cloth: &OneCloth) -> Vec<Vec3> {
    rig.particles(cloth).iter().map(position).collect()
}

/// The two-ends-fixed cloth (paper Fig. 5), 32 x 32, over 2 s, one tick at a time: before each
/// tick the GPU gets the CPU's state, so every tick of the trajectory is checked on its own.
///
/// Tolerance: 1e-5 m per tick. Nothing touches a collider, so the two differ only by f32
/// rounding (the CPU applies each spring once to both ends, the GPU sums every spring per
/// particle; fused multiply-adds and `sqrt`/division rounding on the device), a few ulps per
/// operation over 16 substeps. Over many ticks the folding cloth amplifies such differences
/// (they double about every 5 ticks), which is why the state is resynchronised each tick rather
/// than compared once at the end.
#[test]
fn hanging_cloth_agrees_with_the_cpu() {
    let Some(rig) = rig() else { return };
    let params = ClothParams { damping: 1.0, integrator: Integrator::Rk4, ..Default::default() };
    let grid = square(1.0, 32);
    let mut cpu = grid_cloth(grid, params, Affine3A::from_translation(Vec3::Y), &[0, grid.cols as u32 - 1]);
    let none = GpuColliders::new(&rig.device, &[]);
    let mut gpu = rig.cloth(&cpu, 1.0 / 60.0);
    let mut worst = 0.0f32;
    for _ in 0..120 {
        gpu.upload_state(&rig.queue, &cpu);
        cpu.tick(1.0 / 60.0, &[]);
        rig.ticks(&mut gpu, &none, 1);
        worst = worst.max(largest_gap(&cpu.positions(), &gpu_positions(&rig, &gpu)));
    }
    eprintln!("hanging cloth, 120 ticks: largest CPU-GPU gap after one tick {worst:e} m");
    assert!(worst < 1e-5, "GPU and CPU differ by {worst} m after one tick");
}

/// The bundled low-resolution bunny.
fn bunny_low() -> ObjMesh {
    let path =
        format!("{}/../../assets/models/bunny_low.obj", std::env::var("CARGO_MANIFEST_DIR").expect("run by cargo"));
    parse_obj(&std::fs::read_to_string(path).unwrap()).unwrap()
}

fn bunny(n: u32) -> Collider {
    let obj = bunny_low();
    Collider::from_mesh(MeshRef { positions: &obj.positions, indices: Some(&obj.indices) }, n)
        .unwrap()
        .with_margin(0.01)
        .with_friction(1.0)
}

/// The paper's scene: a 64 x 64 cloth dropped on the (low-resolution) bunny at n = 5, 180 ticks.
///
/// Two tolerances, because contact is chaotic: one-ulp differences at the moment a particle
/// meets a sphere decide which way a fold goes, and from then on single particles may differ by
/// centimetres while the cloth as a whole does the same thing.
/// * Before contact (tick 10, the cloth still falling freely): every particle within 0.1 mm.
/// * After 180 ticks (3 s, draped; a damping of 1/s alone leaves 5 % of a speed after 3 s):
///   centroid within 2 cm, lowest and highest points within 3 cm, and on the GPU too no
///   particle inside any sphere.
#[test]
fn bunny_drop_agrees_with_the_cpu() {
    let Some(rig) = rig() else { return };
    let colliders = [bunny(5)];
    let params = ClothParams { damping: 1.0, integrator: Integrator::Rk4, ..Default::default() };
    let mut cpu = grid_cloth(square(1.2, 64), params, Affine3A::from_translation(Vec3::new(-0.2, 1.2, 0.0)), &[]);
    let gpu_colliders = GpuColliders::new(&rig.device, &colliders);
    let mut gpu = rig.cloth(&cpu, 1.0 / 60.0);

    for _ in 0..10 {
        cpu.tick(1.0 / 60.0, &colliders);
    }
    rig.ticks(&mut gpu, &gpu_colliders, 10);
    let early = largest_gap(&cpu.positions(), &gpu_positions(&rig, &gpu));
    eprintln!("bunny drop, tick 10: largest CPU-GPU gap {early:e} m");
    assert!(early < 1e-4, "before contact GPU and CPU differ by {early} m");

    for _ in 10..180 {
        cpu.tick(1.0 / 60.0, &colliders);
    }
    rig.ticks(&mut gpu, &gpu_colliders, 170);
    let (c, g) = (cpu.positions(), gpu_positions(&rig, &gpu));
    let highest = |p: &[Vec3]| p.iter().map(|p| p.y).fold(f32::NEG_INFINITY, f32::max);
    eprintln!(
        "bunny drop, tick 180: centroid gap {:e} m, lowest {} vs {}, highest {} vs {}, largest particle gap {:e} m",
        centroid(&c).distance(centroid(&g)),
        lowest(&c),
        lowest(&g),
        highest(&c),
        highest(&g),
        largest_gap(&c, &g)
    );
    assert!(centroid(&c).distance(centroid(&g)) < 0.02);
    assert!((lowest(&c) - lowest(&g)).abs() < 0.03);
    assert!((highest(&c) - highest(&g)).abs() < 0.03);
    assert!(g.iter().all(|p| p.is_finite()));
    let inside = g.iter().filter(|&&p| colliders[0].contains(p)).count();
    assert_eq!(inside, 0, "{inside} GPU particles inside the bunny's spheres");
}

/// A ball of radius 0.3 m at `centre`, one sphere, with a 1 cm margin and friction 1.
fn rough_ball(centre: Vec3) -> Collider {
    Collider {
        shape: ColliderShape::Spheres {
            lbvh: Lbvh::build(&[Sphere::new(Vec3::ZERO, 0.3)]).into(),
            counts: UVec3::ONE,
            skin: None,
            surface: None,
        },
        margin: 0.01,
        friction: 1.0,
        pose: ColliderPose { translation: centre, ..Default::default() },
        layers: CollisionLayers::DEFAULT,
    }
}

/// Two colliders in one scene, one of them posed (scaled, turned), and the other sliding
/// 0.2 m under the cloth over one second, its new pose uploaded every tick without a rebuild:
/// the concatenated trees and their offsets, and `GpuColliders::update_frames`, against the
/// CPU. Bit-identical before contact on lavapipe; after it, the bunny drop's tolerances.
#[test]
fn two_colliders_one_moving_agree_with_the_cpu() {
    let Some(rig) = rig() else { return };
    let ball = rough_ball(Vec3::new(-0.5, 0.3, 0.0));
    let small_bunny = bunny(3).with_pose(ColliderPose {
        translation: Vec3::new(0.5, 0.0, 0.0),
        rotation: Quat::from_rotation_y(1.0),
        scale: 0.6,
    });
    let mut colliders = [ball, small_bunny];
    let params = ClothParams { damping: 1.0, integrator: Integrator::Rk4, ..Default::default() };
    let mut cpu = grid_cloth(square(1.8, 48), params, Affine3A::from_translation(Vec3::new(0.0, 1.0, 0.0)), &[]);
    let mut gpu_colliders = GpuColliders::new(&rig.device, &colliders);
    let mut gpu = rig.cloth(&cpu, 1.0 / 60.0);

    for _ in 0..15 {
        cpu.tick(1.0 / 60.0, &colliders);
    }
    rig.ticks(&mut gpu, &gpu_colliders, 15);
    let early = largest_gap(&cpu.positions(), &gpu_positions(&rig, &gpu));
    assert!(early < 1e-4, "before contact GPU and CPU differ by {early} m");
    for tick in 15..180 {
        if tick >= 60 {
            colliders[0].pose.translation.z = 0.2 * ((tick - 59) as f32 / 60.0).min(1.0);
            gpu_colliders.update_frames(&rig.queue, &colliders);
        }
        cpu.tick(1.0 / 60.0, &colliders);
        rig.ticks(&mut gpu, &gpu_colliders, 1);
    }

    let (c, g) = (cpu.positions(), gpu_positions(&rig, &gpu));
    eprintln!(
        "two colliders, tick 180: centroid gap {:e} m, lowest {} vs {}, largest particle gap {:e} m",
        centroid(&c).distance(centroid(&g)),
        lowest(&c),
        lowest(&g),
        largest_gap(&c, &g)
    );
    assert!(centroid(&c).distance(centroid(&g)) < 0.02);
    assert!((lowest(&c) - lowest(&g)).abs() < 0.03);
    for (k, collider) in colliders.iter().enumerate() {
        let inside = g.iter().filter(|&&p| collider.contains(p)).count();
        assert_eq!(inside, 0, "{inside} GPU particles inside collider {k}");
    }
    // The colliders hold the cloth up.
    assert!(centroid(&g).y > 0.1, "the cloth fell past the colliders: centroid {}", centroid(&g));
}

/// The low bunny as a skinned collider: its lower half on joint 0, its upper half on joint 1,
/// blended across the middle 20 cm.
fn skinned_bunny(n: u32) -> Collider {
    let obj = bunny_low();
    let joints = vec![[0u16, 1, 0, 0]; obj.positions.len()];
    let weights: Vec<[f32; 4]> = obj
        .positions
        .iter()
        .map(|p| {
            let upper = ((p[1] - 0.4) / 0.2).clamp(0.0, 1.0);
            [1.0 - upper, upper, 0.0, 0.0]
        })
        .collect();
    let skin = SkinRef { joints: &joints, weights: &weights, joint_count: 2 };
    let mesh = MeshRef { positions: &obj.positions, indices: Some(&obj.indices) };
    Collider::from_skinned_mesh(mesh, skin, Voxels::PerAxis(n)).unwrap().with_margin(0.01).with_friction(1.0)
}

/// A skinned collider whose upper half leans over, refitted every tick on the CPU and written
/// into the GPU's tree buffer in place (`GpuColliders::rewrite_trees`), under a falling cloth:
/// against the CPU with the bunny drop's tolerances, and no GPU particle inside it.
#[test]
fn a_skinned_collider_rewritten_in_place_agrees_with_the_cpu() {
    let Some(rig) = rig() else { return };
    let mut colliders = [skinned_bunny(5)];
    let mut scratch = SkinScratch::default();
    let params = ClothParams { damping: 1.0, integrator: Integrator::Rk4, ..Default::default() };
    let mut cpu = grid_cloth(square(1.4, 40), params, Affine3A::from_translation(Vec3::new(0.0, 1.3, 0.0)), &[]);
    let mut gpu_colliders = GpuColliders::new(&rig.device, &colliders);
    let mut gpu = rig.cloth(&cpu, 1.0 / 60.0);
    for tick in 0..180 {
        // The upper half turns up to 0.3 rad about z, around a point at mid height.
        let angle = 0.3 * (tick as f32 / 120.0).min(1.0);
        let pivot = Vec3::new(0.0, 0.5, 0.0);
        let lean =
            Affine3A::from_translation(pivot) * Affine3A::from_rotation_z(angle) * Affine3A::from_translation(-pivot);
        colliders[0].pose_skin(&[Affine3A::IDENTITY, lean], &mut scratch).unwrap();
        assert!(gpu_colliders.rewrite_trees(&rig.queue, &colliders, &[0]), "a refit keeps the layout");
        cpu.tick(1.0 / 60.0, &colliders);
        rig.ticks(&mut gpu, &gpu_colliders, 1);
    }
    let g = gpu_positions(&rig, &gpu);
    assert_draped_alike("skinned bunny, tick 180", &cpu.positions(), &g, &colliders[0]);
    // A different layout is refused.
    assert!(!gpu_colliders.rewrite_trees(&rig.queue, &[bunny(3)], &[0]));
}

/// A cloth draped on a skinned bunny by the CPU (`c`) and by the GPU (`g`) agrees with the
/// bunny drop's tolerances (centroids within 2 cm, lowest points within 3 cm), no GPU particle
/// is inside `collider`, and the bunny holds the cloth up (centroid above 0.3 m).
fn assert_draped_alike(scene: &str, c: &[Vec3], g: &[Vec3], collider: &Collider) {
    let gap = centroid(c).distance(centroid(g));
    eprintln!("{scene}: centroid gap {gap:e} m, lowest {} vs {}", lowest(c), lowest(g));
    assert!(gap < 0.02 && (lowest(c) - lowest(g)).abs() < 0.03, "{scene}: the GPU's drape is not the CPU's");
    let inside = g.iter().filter(|&&p| collider.contains(p)).count();
    assert_eq!(inside, 0, "{scene}: {inside} GPU particles inside the skinned collider");
    assert!(centroid(g).y > 0.3, "{scene}: the cloth fell past the collider: centroid {}", centroid(g));
}

/// The low bunny's pose `k` of a sway: its upper half turned about z around a point at mid
/// height, by up to 0.4 rad, and the whole lifted and scaled by up to 10%.
fn bunny_sway(t: f32) -> [Affine3A; 2] {
    let pivot = Vec3::new(0.0, 0.5, 0.0);
    let lean = Affine3A::from_translation(pivot)
        * Affine3A::from_rotation_z(0.4 * (2.0 * t).sin())
        * Affine3A::from_translation(-pivot);
    let whole = Affine3A::from_scale_rotation_translation(
        Vec3::splat(1.0 + 0.1 * t.sin().abs()),
        Quat::from_rotation_y(0.5 * t),
        Vec3::new(0.1 * t.sin(), 0.05 * t, 0.0),
    );
    [whole, whole * lean]
}

/// Refits a skinned collider on the GPU (`SkinRefit`: skin, fit, refit level by level, reach),
/// `k`-th of a set after a static bunny so that its tree is not first in the buffer.
fn gpu_refit(rig: &Rig, colliders: &mut [Collider; 2], refit: &SkinRefit, pose: &[Affine3A]) {
    let clearance = colliders[1].accept_skin_pose(pose).unwrap().expect("a skinned collider");
    refit.write_pose(&rig.queue, pose, clearance);
    let mut encoder = rig.device.create_command_encoder(&Default::default());
    {
        let mut pass = encoder.begin_compute_pass(&Default::default());
        refit.encode(&mut pass, &rig.kernels);
    }
    rig.queue.submit([encoder.finish()]);
}

/// A skinned collider refitted on the GPU from its joint matrices alone gives the CPU's refit:
/// at six poses of a sway (bent, turned, lifted and scaled), every sphere's centre and radius
/// and every box's corners within 1e-5 m of the CPU's (`SkinnedSpheres::refit`; the two sum the
/// same points in the same order, so only rounding differs), the contact reach within 1e-6 m,
/// and the static collider before it untouched (bit-equal). Then a cloth falls on the swaying
/// collider refitted on the GPU every tick, against the CPU stepping with the CPU's refit, with
/// the tolerances of the in-place test above and no GPU particle inside.
#[test]
fn a_skinned_collider_refitted_on_the_gpu_matches_the_cpu_refit() {
    let Some(rig) = rig() else { return };
    let mut colliders = [bunny(3), skinned_bunny(5)];
    let ColliderShape::Spheres { lbvh: bind_tree, skin: Some(skin), .. } = &colliders[1].shape else {
        panic!("a skinned collider")
    };
    let mut refit = SkinRefit::new(&rig.device, skin, bind_tree).unwrap();
    let levels = refit.dispatches() - 3;
    colliders[1].accept_skin_pose(&[Affine3A::IDENTITY; 2]).unwrap();
    let gpu = GpuColliders::new(&rig.device, &colliders);
    assert!(refit.bind(&rig.device, &rig.kernels, &gpu, 1), "the skinned tree is on the device");
    let (frames_buffer, tree_buffer) = gpu.buffers();
    let before: Vec<[f32; 4]> = headless::read(&rig.device, &rig.queue, tree_buffer);
    let static_tree = colliders[0].lbvh().unwrap().clone();
    let static_words = 2 * static_tree.nodes.len();
    let (node_offset, sphere_offset) = gpu.tree_offsets(1).unwrap();
    let mut scratch = SkinScratch::default();
    let (mut worst_sphere, mut worst_box, mut worst_reach) = (0.0f32, 0.0f32, 0.0f32);
    for k in 0..6 {
        let pose = bunny_sway(0.4 * k as f32);
        gpu_refit(&rig, &mut colliders, &refit, &pose);
        let mut cpu = colliders[1].clone();
        cpu.pose_skin(&pose, &mut scratch).unwrap();
        let want = cpu.lbvh().unwrap();
        let words: Vec<[f32; 4]> = headless::read(&rig.device, &rig.queue, tree_buffer);
        for (j, s) in want.spheres.iter().enumerate() {
            let got = words[sphere_offset as usize + j];
            let gap = (Vec3::from_slice(&got[..3]) - s.centre()).abs().max_element().max((got[3] - s.radius).abs());
            worst_sphere = worst_sphere.max(gap);
        }
        for (j, node) in want.nodes.iter().enumerate() {
            let (lo, hi) = (words[2 * (node_offset as usize + j)], words[2 * (node_offset as usize + j) + 1]);
            let gap = (Vec3::from_slice(&lo[..3]) - Vec3::from(node.aabb_min))
                .abs()
                .max(Vec3::from_slice(&hi[..3]) - Vec3::from(node.aabb_max))
                .abs()
                .max_element();
            worst_box = worst_box.max(gap);
            assert_eq!((lo[3].to_bits(), hi[3].to_bits()), (node.left, node.right), "node {j}'s children are kept");
        }
        let frames: Vec<GpuCollider> = headless::read(&rig.device, &rig.queue, frames_buffer);
        let reach = bvh_cloth_core::backend::ColliderFrame::new(&cpu).unwrap().contact_reach;
        worst_reach = worst_reach.max((frames[1].contact_reach - reach).abs());
        // The static tree (its nodes first in the buffer, its spheres first after the nodes).
        assert_eq!(&words[..static_words], &before[..static_words], "the static bunny's nodes are untouched");
        let spheres_at = 2 * (static_tree.nodes.len() + want.nodes.len());
        assert_eq!(
            &words[spheres_at..spheres_at + static_tree.spheres.len()],
            &before[spheres_at..spheres_at + static_tree.spheres.len()],
            "the static bunny's spheres are untouched"
        );
    }
    eprintln!(
        "GPU refit ({} spheres, {levels} levels) against the CPU's: spheres {worst_sphere:e} m, boxes {worst_box:e} m, \
         reach {worst_reach:e} m",
        refit_leaves(&colliders[1])
    );
    assert!(worst_sphere < 1e-5 && worst_box < 1e-5, "the GPU refit is not the CPU's");
    assert!(worst_reach < 1e-6, "the contact reach does not follow the refit");

    // A cloth on it, 150 ticks.
    let params = ClothParams { damping: 1.0, integrator: Integrator::Rk4, ..Default::default() };
    let mut cpu = grid_cloth(square(1.4, 40), params, Affine3A::from_translation(Vec3::new(0.0, 1.3, 0.0)), &[]);
    let mut cpu_colliders = colliders.clone();
    let mut cloth = rig.cloth(&cpu, 1.0 / 60.0);
    let mut gpu = gpu;
    for tick in 0..150 {
        let pose = bunny_sway(tick as f32 / 100.0);
        cpu_colliders[1].pose_skin(&pose, &mut scratch).unwrap();
        gpu.update_frames(&rig.queue, &colliders);
        gpu_refit(&rig, &mut colliders, &refit, &pose);
        cpu.tick(1.0 / 60.0, &cpu_colliders);
        rig.ticks(&mut cloth, &gpu, 1);
    }
    let g = gpu_positions(&rig, &cloth);
    assert_draped_alike("swaying skinned bunny refitted on the GPU, tick 150", &cpu.positions(), &g, &cpu_colliders[1]);
    // A tree of another size is not bound.
    let other = GpuColliders::new(&rig.device, &[bunny(3), bunny(4)]);
    assert!(!refit.bind(&rig.device, &rig.kernels, &other, 1) && !refit.is_bound());
}

fn refit_leaves(collider: &Collider) -> usize {
    collider.lbvh().map_or(0, |tree| tree.spheres.len())
}

/// Exact contact on the GPU (`respond_triangles` in collision.wgsl) against the CPU's
/// (`TriangleSurface::respond`): a 40 x 40 cloth falls onto the low bunny with exact contact
/// (thickness 1 cm) beside an exact plate of zero thickness (an open mesh) it overhangs, for
/// 150 ticks. The drapes agree with the bunny drop's tolerances (centroids within 2 cm, lowest
/// points within 3 cm); no GPU particle is closer to a triangle than 90% of the thickness, and
/// none that landed on the plate is below it.
#[test]
fn exact_contact_agrees_with_the_cpu() {
    let Some(rig) = rig() else { return };
    let obj = bunny_low();
    let bunny_mesh = MeshRef { positions: &obj.positions, indices: Some(&obj.indices) };
    let exact_bunny = Collider::from_mesh(bunny_mesh, 3)
        .unwrap()
        .with_exact_contact(bunny_mesh)
        .unwrap()
        .with_margin(0.01)
        .with_friction(1.0);
    let plate_corners = [[-0.4, 0.0, -0.4], [0.4, 0.0, -0.4], [0.4, 0.0, 0.4], [-0.4, 0.0, 0.4]];
    let plate_indices = [0, 2, 1, 0, 3, 2];
    let plate_mesh = MeshRef { positions: &plate_corners, indices: Some(&plate_indices) };
    let mut plate = Collider::from_mesh(plate_mesh, 1)
        .unwrap()
        .with_exact_contact(plate_mesh)
        .unwrap()
        .with_margin(0.01)
        .with_friction(1.0);
    plate.pose.translation = Vec3::new(2.0, 0.5, 0.0);
    let colliders = [exact_bunny, plate];
    let gpu_colliders = GpuColliders::new(&rig.device, &colliders);
    let params = ClothParams { damping: 1.0, integrator: Integrator::Rk4, ..Default::default() };
    for (scene, at) in [("bunny", Vec3::new(0.0, 1.3, 0.0)), ("plate", Vec3::new(2.0, 0.8, 0.0))] {
        let mut cpu = grid_cloth(square(1.0, 40), params.clone(), Affine3A::from_translation(at), &[]);
        let start = cpu.positions();
        let mut gpu = rig.cloth(&cpu, 1.0 / 60.0);
        for _ in 0..150 {
            cpu.tick(1.0 / 60.0, &colliders);
            rig.ticks(&mut gpu, &gpu_colliders, 1);
        }
        let (c, g) = (cpu.positions(), gpu_positions(&rig, &gpu));
        let gap = centroid(&c).distance(centroid(&g));
        eprintln!("exact contact, {scene}, tick 150: centroid gap {gap:e} m, lowest {} vs {}", lowest(&c), lowest(&g));
        assert!(gap < 0.02 && (lowest(&c) - lowest(&g)).abs() < 0.03, "{scene}: the GPU's drape is not the CPU's");
        for collider in &colliders {
            let surface = collider.surface().unwrap();
            let to_local = collider.pose.to_affine().inverse();
            let close = g.iter().filter(|&&p| surface.within(to_local.transform_point3(p), 0.009)).count();
            assert_eq!(close, 0, "{scene}: {close} GPU particles closer than 9 mm to a triangle");
        }
        if scene == "plate" {
            let landed = start.iter().zip(&g).filter(|(s, _)| (s.x - 2.0).abs() < 0.3 && s.z.abs() < 0.3);
            assert!(landed.clone().all(|(_, p)| p.y > 0.5), "a GPU particle that landed on the plate is below it");
            assert!(landed.count() > 100);
        } else {
            assert!(centroid(&g).y > 0.3, "the cloth fell past the bunny: centroid {}", centroid(&g));
        }
    }
}

/// A flag built as an artist exports one: `cols x rows` points over `width x height` metres in
/// the XY plane, split down the middle column at a UV seam (the two halves have their own
/// vertices there), so welding must join them.
fn seamed_flag(cols: u32, rows: u32, width: f32, height: f32) -> (Vec<[f32; 3]>, Vec<u32>) {
    let seam = cols / 2;
    let mut positions = Vec::new();
    let mut indices = Vec::new();
    for (first, last) in [(0, seam), (seam, cols - 1)] {
        let start = positions.len() as u32;
        let span = last - first + 1;
        for r in 0..rows {
            for c in first..=last {
                let x = width * c as f32 / (cols - 1) as f32;
                let y = -height * r as f32 / (rows - 1) as f32;
                positions.push([x, y, 0.0]);
            }
        }
        for r in 0..rows - 1 {
            for c in 0..span - 1 {
                let i = start + r * span + c;
                indices.extend_from_slice(&[i, i + span, i + 1, i + 1, i + span, i + span + 1]);
            }
        }
    }
    (positions, indices)
}

/// An authored mesh (a flag with a UV seam) anchored along its pole edge, whose anchor swings
/// and climbs during every frame of four ticks: the GPU's `apply_anchors` must place the pins
/// tick by tick as the CPU's `move_pins` does, and the general spring path (RK4) and block
/// descent must match.
///
/// Tolerance: 1e-5 m after each frame of 4 ticks, the GPU starting each frame from the CPU's
/// state (no contact, so only rounding differs, as in `hanging_cloth_agrees_with_the_cpu`).
/// The pins themselves are written, not computed: they must be bit-equal to the last tick's
/// targets. Then `normal_shader` writes the render vertices: the two vertices of every seam
/// point must be bit-equal (no crack) and every vertex must show its particle.
#[test]
fn authored_mesh_with_moving_anchors_agrees_with_the_cpu() {
    let Some(rig) = rig() else { return };
    for integrator in [Integrator::Rk4, Integrator::BLOCK_DESCENT] {
        let (positions, indices) = seamed_flag(13, 9, 1.2, 0.8);
        let topology = ClothTopology::from_mesh(MeshRef { positions: &positions, indices: Some(&indices) }).unwrap();
        assert_eq!(topology.len(), 13 * 9, "the seam's 9 duplicated vertices are welded");
        let pole: Vec<u32> =
            (0..topology.len() as u32).filter(|&i| topology.rest_positions()[i as usize].x == 0.0).collect();
        assert_eq!(pole.len(), 9);
        let params = ClothParams { damping: 0.5, integrator, ..Default::default() };
        let start = Affine3A::from_translation(Vec3::new(0.0, 2.0, 0.0));
        let mut cpu = ClothSim::new(params, Arc::new(topology), start, &pole).unwrap();
        let none = GpuColliders::new(&rig.device, &[]);
        let mut gpu = rig.cloth(&cpu, 1.0 / 60.0);
        // The pole's pose at time t: swinging about the vertical and climbing.
        let pose_at = |t: f32| {
            Affine3A::from_rotation_translation(
                Quat::from_rotation_y(1.5 * (3.0 * t).sin()),
                Vec3::new(0.0, 2.0 + t, 0.0),
            )
        };
        const TICKS: u32 = 4;
        let (mut worst, mut pin_gap) = (0.0f32, 0.0f32);
        for frame in 0..30 {
            gpu.upload_state(&rig.queue, &cpu);
            let targets: Vec<Vec<(u32, Vec3)>> = (0..TICKS)
                .map(|k| {
                    let pose = pose_at((frame * TICKS + k) as f32 / 60.0);
                    cpu.pin_targets(&pose).collect()
                })
                .collect();
            for tick in &targets {
                cpu.move_pins(tick);
                cpu.tick(1.0 / 60.0, &[]);
            }
            gpu.batch.set_anchor_targets(gpu.id, &targets);
            rig.ticks(&mut gpu, &none, TICKS);
            let on_gpu = gpu_positions(&rig, &gpu);
            worst = worst.max(largest_gap(&cpu.positions(), &on_gpu));
            for &(i, target) in targets.last().unwrap() {
                pin_gap = pin_gap.max(on_gpu[i as usize].distance(target));
            }
        }
        eprintln!(
            "anchored flag, {integrator:?}, 30 frames of {TICKS} ticks: largest CPU-GPU gap after a frame {worst:e} m"
        );
        assert_eq!(pin_gap, 0.0, "the pins sit exactly on their last targets");
        assert!(worst < 1e-5, "{integrator:?}: GPU and CPU differ by {worst} m after a frame");
        let travelled = cpu.positions().iter().map(|p| p.y).fold(f32::INFINITY, f32::min);
        assert!(travelled > 1.3, "the flag was carried up with its pole (lowest point {travelled})");

        // The render vertices, straight from normal_shader, in world space: 8 words each, the
        // position at word 0 and the normal at word 4.
        const STRIDE: u32 = 8;
        let writeback = GpuMeshWriteback::new(Affine3A::IDENTITY, 0, STRIDE, 0, 4);
        let out = rig.write_vertices(&mut gpu, writeback, vec![0.0; positions.len() * STRIDE as usize]);
        let on_gpu = gpu_positions(&rig, &gpu);
        let vertex = |v: usize| &out[v * STRIDE as usize..][..STRIDE as usize];
        let topology = cpu.topology();
        for (v, &p) in topology.vertex_particle().iter().enumerate() {
            assert_eq!(Vec3::from_slice(&vertex(v)[0..3]), on_gpu[p as usize], "vertex {v} shows particle {p}");
            let n = Vec3::from_slice(&vertex(v)[4..7]);
            assert!((n.length() - 1.0).abs() < 1e-5, "vertex {v} has a unit normal, not {n}");
            for (w, &q) in topology.vertex_particle().iter().enumerate().skip(v + 1) {
                if q == p {
                    assert_eq!(vertex(v)[..7], vertex(w)[..7], "seam vertices {v} and {w} split apart");
                }
            }
        }
    }
}

/// Four cloths of different sizes, integrators, parameters and substep counts in one batch,
/// above a ball that one of them lands on; one is removed and another added while the others
/// run. Each is compared with the same cloth stepped alone by the CPU after every tick.
///
/// Tolerance: 1e-5 m per tick, as in `hanging_cloth_agrees_with_the_cpu` (the two differ by
/// rounding only; on lavapipe the largest gap is about 3e-6 m). The GPU starts each tick from
/// the CPU's state, except at the removal and the addition, where it must carry on from the
/// state it kept (moved by the batch's rebuild at the addition).
#[test]
fn a_batch_of_cloths_agrees_with_each_alone_on_the_cpu_as_cloths_come_and_go() {
    let Some(rig) = rig() else { return };
    let ball = rough_ball(Vec3::new(3.0, 0.6, 0.0));
    let colliders = [ball];
    let gpu_colliders = GpuColliders::new(&rig.device, &colliders);
    let hanging = ClothParams { damping: 1.0, integrator: Integrator::Rk4, ..Default::default() };
    let euler = ClothParams {
        damping: 0.5,
        spring_k: 300.0,
        looper: 8,
        integrator: Integrator::SemiImplicitEuler,
        ..Default::default()
    };
    let stiff = ClothParams { spring_k: 20_000.0, looper: 4, integrator: Integrator::Rk4, ..Default::default() };
    let grid = |w: f32, h: f32, cols: u32, rows: u32| ClothGrid::new(Vec2::new(w, h), UVec2::new(cols, rows));
    let at = |x: f32, y: f32| Affine3A::from_translation(Vec3::new(x, y, 0.0));
    let mut cloths: Vec<(&str, ClothSim)> = vec![
        ("hanging 16x16", grid_cloth(grid(1.0, 1.0, 16, 16), hanging, at(0.0, 1.0), &[0, 15])),
        ("euler 24x20 onto the ball", grid_cloth(grid(1.2, 1.0, 24, 20), euler, at(3.0, 1.0), &[])),
        ("stiff 12x12", grid_cloth(grid(0.6, 0.6, 12, 12), stiff, at(-3.0, 1.0), &(0..12).collect::<Vec<_>>())),
    ];
    let tick = 1.0 / 60.0;
    let (mut batch, mut ids) = rig.batch(&cloths, tick);
    assert!(
        batch.substeps(ids[2]) > batch.substeps(ids[0]),
        "the stiff cloth needs more substeps than the others, and sits out none of its own"
    );
    let mut worst = vec![0.0f32; 4];
    for t in 0..60 {
        let carry_on = t == 20 || t == 30;
        if t == 20 {
            batch.remove(&rig.queue, ids.remove(0));
            cloths.remove(0);
            worst.remove(0);
        }
        if t == 30 {
            let before = batch.particles(ids[0]).unwrap().1;
            // Larger than the room left: the batch is rebuilt, the others' state moved.
            let rk4 = ClothParams { integrator: Integrator::Rk4, ..Default::default() };
            let sim = grid_cloth(grid(1.4, 1.4, 32, 32), rk4, at(0.0, 2.0), &[]);
            let id = batch.insert(&rig.device, &rig.queue, &sim).unwrap();
            batch.set_params(&rig.queue, id, sim.params(), tick);
            ids.push(id);
            cloths.push(("added 32x32", sim));
            assert_ne!(batch.particles(ids[0]).unwrap().1, before, "the rebuild packed the cloths");
        }
        let gaps =
            rig.tick_against_the_cpu(&mut batch, &mut cloths, &ids, (&colliders, &gpu_colliders), tick, !carry_on);
        for (k, (gap, (name, _))) in gaps.into_iter().zip(&cloths).enumerate() {
            worst[k] = worst[k].max(gap);
            assert!(gap < 1e-5, "{name}, tick {t}: GPU and CPU differ by {gap} m");
        }
    }
    eprintln!("largest CPU-GPU gaps after one tick: {:?}", cloths.iter().map(|c| c.0).zip(&worst).collect::<Vec<_>>());
    let landed = cloths.iter().find(|c| c.0.starts_with("euler")).unwrap();
    assert!(
        landed.1.positions().iter().any(|p| colliders[0].contains(*p + Vec3::new(0.0, -0.02, 0.0))),
        "the Euler cloth reached the ball"
    );
}

/// Profiling splits a tick into one compute pass per dispatch, timed: the same dispatches in
/// the same order, so the same state as an untimed tick, bit for bit, and one kernel reported per
/// dispatch (four per substep without pins). Too small a query set records nothing.
#[test]
fn timed_ticks_step_as_untimed_ones_and_name_each_dispatch() {
    let Some(rig) = rig() else { return };
    let params = ClothParams { damping: 1.0, looper: 3, integrator: Integrator::Rk4, ..Default::default() };
    let sim = grid_cloth(square(1.0, 12), params, Affine3A::from_translation(Vec3::Y), &[]);
    let none = GpuColliders::new(&rig.device, &[]);
    let (mut plain, mut timed) = (rig.cloth(&sim, 1.0 / 60.0), rig.cloth(&sim, 1.0 / 60.0));
    rig.ticks(&mut plain, &none, 2);
    timed.batch.prepare(&rig.device, &rig.queue, &rig.kernels, &none);
    let Some(queries) = rig.timestamp_queries(64) else {
        eprintln!("the adapter has no timestamp queries: only the untimed path ran");
        return;
    };
    let mut encoder = rig.device.create_command_encoder(&Default::default());
    assert_eq!(
        timed.batch.encode_ticks_timed(&mut encoder, &rig.kernels, 2, &queries, 8),
        None,
        "8 queries are too few"
    );
    let kernels = timed.batch.encode_ticks_timed(&mut encoder, &rig.kernels, 2, &queries, 64).expect("64 queries fit");
    rig.queue.submit([encoder.finish()]);
    let substep = [Kernel::NodeUpdate, Kernel::NodeUpdate, Kernel::NodeUpdate, Kernel::NodeUpdateFinal];
    assert_eq!(kernels, substep.repeat(6), "2 ticks of 3 substeps");
    assert_eq!(rig.particles(&timed), rig.particles(&plain));
}

/// A `PassTimer` around a batch's ticks: the ticks step as untimed ones, bit for bit; a second
/// claim while a measure is in flight runs untimed; the measure arrives once the device is
/// polled, and 16 ticks take longer than one (on lavapipe, about 16 times as long).
#[test]
fn a_pass_timer_measures_the_ticks_without_changing_them() {
    let Some(rig) = rig() else { return };
    let Some(timer) = PassTimer::new(&rig.device, &rig.queue) else {
        assert!(
            rig.device.features().contains(wgpu::Features::TIMESTAMP_QUERY),
            "the device has timestamp queries and no timer was made"
        );
        eprintln!("the adapter has no timestamp queries: no timer");
        return;
    };
    let sim = grid_cloth(square(1.0, 32), ClothParams::default(), Affine3A::from_translation(Vec3::Y), &[0, 31]);
    let none = GpuColliders::new(&rig.device, &[]);
    let (mut plain, mut timed) = (rig.cloth(&sim, 1.0 / 60.0), rig.cloth(&sim, 1.0 / 60.0));
    rig.ticks(&mut plain, &none, 1);
    timed.batch.prepare(&rig.device, &rig.queue, &rig.kernels, &none);
    let measure = |ticks: u32| {
        let mut encoder = rig.device.create_command_encoder(&Default::default());
        let writes = timer.begin();
        assert!(writes.is_some(), "the timer is idle");
        timed.batch.encode_ticks_with(&mut encoder, &rig.kernels, ticks, writes);
        timer.record(&mut encoder);
        assert!(timer.begin().is_none(), "a second claim while the first is in flight");
        rig.queue.submit([encoder.finish()]);
        timer.submitted();
        assert_eq!(timer.take(), None, "the measure is there before the device was polled");
        let _ = rig.particles(&timed);
        timer.take().expect("the measure after a poll")
    };
    let one = measure(1);
    assert_eq!(rig.particles(&timed), rig.particles(&plain), "the timed tick stepped otherwise");
    let sixteen = measure(16);
    eprintln!("pass timer: one tick {one:?}, sixteen ticks {sixteen:?}");
    assert!(one > Duration::ZERO && sixteen > 2 * one, "one tick {one:?}, sixteen {sixteen:?}");
}

/// `normal_shader` writes every cloth of a vertex buffer in one dispatch: two cloths of
/// different sizes share one buffer (the second after a vertex of padding), a third has a
/// buffer of its own; each vertex shows its own cloth's particle, and the padding is untouched.
#[test]
fn one_writeback_dispatch_per_vertex_buffer_writes_every_cloth_in_it() {
    let Some(rig) = rig() else { return };
    const STRIDE: u32 = 8;
    let sentinel = -7.0f32;
    let sims = [
        grid_cloth(square(1.0, 3), ClothParams::default(), Affine3A::from_translation(Vec3::Y), &[]),
        grid_cloth(square(0.5, 5), ClothParams::default(), Affine3A::from_translation(Vec3::X), &[]),
        grid_cloth(square(2.0, 4), ClothParams::default(), Affine3A::from_translation(Vec3::Z), &[]),
    ];
    let mut batch = ClothBatch::new(&rig.device, &rig.queue);
    let ids: Vec<ClothId> = sims.iter().map(|sim| batch.insert(&rig.device, &rig.queue, sim).unwrap()).collect();
    let buffer = |words: usize| {
        rig.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: None,
            contents: bytemuck::cast_slice(&vec![sentinel; words]),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        })
    };
    let (n0, n1, n2) = (sims[0].len() as u32, sims[1].len() as u32, sims[2].len() as u32);
    let shared = buffer(((n0 + 1 + n1) * STRIDE) as usize);
    let own = buffer((n2 * STRIDE) as usize);
    let at = |first_vertex: u32| GpuMeshWriteback::new(Affine3A::IDENTITY, first_vertex * STRIDE, STRIDE, 0, 4);
    batch.set_writeback(ids[0], at(0), &shared);
    batch.set_writeback(ids[1], at(n0 + 1), &shared);
    batch.set_writeback(ids[2], at(0), &own);
    batch.prepare(&rig.device, &rig.queue, &rig.kernels, &GpuColliders::new(&rig.device, &[]));
    let mut encoder = rig.device.create_command_encoder(&Default::default());
    batch.encode_writebacks(&mut encoder, &rig.kernels);
    rig.queue.submit([encoder.finish()]);
    let shared: Vec<f32> = headless::read(&rig.device, &rig.queue, &shared);
    let own: Vec<f32> = headless::read(&rig.device, &rig.queue, &own);
    let shows = |words: &[f32], first: u32, sim: &ClothSim, name: &str| {
        for i in 0..sim.len() {
            let w = ((first + i as u32) * STRIDE) as usize;
            assert_eq!(Vec3::from_slice(&words[w..w + 3]), sim.position(i), "{name}: vertex {i}");
            assert!((Vec3::from_slice(&words[w + 4..w + 7]).length() - 1.0).abs() < 1e-5, "{name}: normal {i}");
        }
    };
    shows(&shared, 0, &sims[0], "first cloth of the shared buffer");
    shows(&shared, n0 + 1, &sims[1], "second cloth of the shared buffer");
    shows(&own, 0, &sims[2], "the cloth with a buffer of its own");
    let padding = &shared[(n0 * STRIDE) as usize..((n0 + 1) * STRIDE) as usize];
    assert!(padding.iter().all(|&w| w == sentinel), "the padding vertex was written");
}

/// Block descent on the GPU against the CPU, in one batch with an RK4 cloth: a 32x32 grid
/// hanging from two corners (5 colours, one sweep per substep), and an authored flag with a
/// seam (greedy colours, 3 sweeps) dropped onto a rough ball. At tick 20 the RK4 cloth is
/// removed and at tick 30 a third block-descent cloth is added, larger than the room left, so
/// the batch is rebuilt and the colour list written again for cloths that moved.
///
/// Tolerance: 1e-5 m per tick, the GPU starting each tick from the CPU's state (except at the
/// removal and the addition). Colours are visited in the same order on both, and within a
/// colour no particle reads another's result, so the two differ only by f32 rounding (fused
/// multiply-adds, `sqrt` and division on the device) through the 3x3 solves. Measured on
/// lavapipe: 5.4e-7 m on the grids, 1.9e-6 m on the flag, which touches the ball.
#[test]
fn block_descent_agrees_with_the_cpu_in_a_mixed_batch() {
    let Some(rig) = rig() else { return };
    let colliders = [rough_ball(Vec3::new(3.6, 0.3, 0.4))];
    let gpu_colliders = GpuColliders::new(&rig.device, &colliders);
    let descent = |iterations: u32, looper: u32| ClothParams {
        damping: 1.0,
        looper,
        integrator: Integrator::BlockDescent { iterations },
        ..Default::default()
    };
    let (positions, indices) = seamed_flag(13, 9, 1.2, 0.8);
    let flag = ClothTopology::from_mesh(MeshRef { positions: &positions, indices: Some(&indices) }).unwrap();
    let colours = flag.colouring().unwrap().len();
    assert_ne!(colours, 5, "the flag's greedy colouring has another colour count than the grid's");
    let flat = Affine3A::from_rotation_translation(
        Quat::from_rotation_x(-core::f32::consts::FRAC_PI_2),
        Vec3::new(3.0, 1.0, 0.0),
    );
    let at = |x: f32, y: f32| Affine3A::from_translation(Vec3::new(x, y, 0.0));
    let mut cloths: Vec<(&str, ClothSim)> = vec![
        (
            "rk4 16x16",
            grid_cloth(
                square(1.0, 16),
                ClothParams { damping: 1.0, integrator: Integrator::Rk4, ..Default::default() },
                at(-3.0, 1.0),
                &[0, 15],
            ),
        ),
        ("descent 32x32", grid_cloth(square(1.0, 32), descent(1, 8), at(0.0, 1.0), &[0, 31])),
        ("descent flag onto the ball", ClothSim::new(descent(3, 6), Arc::new(flag), flat, &[]).unwrap()),
    ];
    let tick = 1.0 / 60.0;
    let (mut batch, mut ids) = rig.batch(&cloths, tick);
    let mut worst = vec![0.0f32; 3];
    for t in 0..60 {
        let carry_on = t == 20 || t == 30;
        if t == 20 {
            batch.remove(&rig.queue, ids.remove(0));
            cloths.remove(0);
            worst.remove(0);
        }
        if t == 30 {
            let before = batch.particles(ids[0]).unwrap().1;
            let sim = grid_cloth(square(1.4, 40), descent(2, 4), at(-3.0, 2.0), &[0, 39]);
            let id = batch.insert(&rig.device, &rig.queue, &sim).unwrap();
            batch.set_params(&rig.queue, id, sim.params(), tick);
            ids.push(id);
            cloths.push(("added descent 40x40", sim));
            worst.push(0.0);
            assert_ne!(batch.particles(ids[0]).unwrap().1, before, "the rebuild packed the cloths");
        }
        let gaps =
            rig.tick_against_the_cpu(&mut batch, &mut cloths, &ids, (&colliders, &gpu_colliders), tick, !carry_on);
        for (k, (gap, (name, _))) in gaps.into_iter().zip(&cloths).enumerate() {
            worst[k] = worst[k].max(gap);
            assert!(gap < 1e-5, "{name}, tick {t}: GPU and CPU differ by {gap} m");
        }
    }
    eprintln!(
        "block descent, largest CPU-GPU gaps after one tick: {:?}",
        cloths.iter().map(|c| c.0).zip(&worst).collect::<Vec<_>>()
    );
    let flag = &cloths.iter().find(|c| c.0.starts_with("descent flag")).unwrap().1;
    assert!(
        flag.positions().iter().any(|p| colliders[0].contains(*p + Vec3::new(0.0, -0.02, 0.0))),
        "the flag reached the ball"
    );
}

/// The multigrid integrator on the GPU against the CPU, in one batch with a block-descent
/// cloth: a 32 x 32 grid hanging from two corners, the same grid with springs stiff enough for
/// the blend of BDF2 and implicit Euler and the first level's W-cycle, and an authored flag
/// with a seam dropped onto a rough ball (its particles held by the ball are left out of the
/// correction, and each touch starts BDF2 again from implicit Euler). BDF2 builds on the last two substeps, so the
/// GPU cannot start each tick from the CPU's state as the other comparisons do: it starts
/// from it at 0 and 0.5 s and otherwise runs on its own. At 0.25 s a block-descent cloth
/// joins, larger than the room left: the buffers are rebuilt, and the multigrid cloths' BDF2
/// history comes through (their gap that tick within 1e-5 m).
///
/// Tolerance: 1e-5 m one tick after 0.5 s (both sides then start from implicit Euler), as
/// block descent's; measured on lavapipe, 3.6e-7 m on both multigrid cloths. The blended
/// cloth's springs are about a thousand times stiffer, and its two sides part by 1.7e-4 m in
/// that tick (springs stiff enough for implicit Euler in every substep part them by 5.4e-4 m):
/// it is held to 1e-3 m there, and to 2e-6 m after its first tick, which it starts from rest
/// (measured 5.0e-7 m; with BDF2's weight of the last substep in the blend's place on the GPU,
/// 1.2e-4 m, and 7.7e-3 m one tick after 0.5 s). At 1 s, after
/// 30 ticks on its own, the centroid within 0.1 % of the cloth's fall and the lowest point
/// within 1 % (measured 2.4e-4 % and 0.009 %): the correction decides when to assemble its
/// levels again by comparing two curvatures, and where rounding tips that decision the other
/// way the two sides part by millimetres (from 0 s, the 32 x 32 cloth's lowest points ended
/// 9 mm, 0.9 %, apart).
#[test]
fn the_multigrid_integrator_agrees_with_the_cpu() {
    let Some(rig) = rig() else { return };
    let colliders = [rough_ball(Vec3::new(3.6, 0.3, 0.4))];
    let gpu_colliders = GpuColliders::new(&rig.device, &colliders);
    let multigrid = ClothParams { integrator: Integrator::Multigrid, ..Default::default() };
    let (positions, indices) = seamed_flag(13, 9, 1.2, 0.8);
    let flag = ClothTopology::from_mesh(MeshRef { positions: &positions, indices: Some(&indices) }).unwrap();
    let flat = Affine3A::from_rotation_translation(
        Quat::from_rotation_x(-core::f32::consts::FRAC_PI_2),
        Vec3::new(3.0, 1.0, 0.0),
    );
    let at = |x: f32, y: f32| Affine3A::from_translation(Vec3::new(x, y, 0.0));
    let descent = ClothParams { integrator: Integrator::BlockDescent { iterations: 1 }, ..Default::default() };
    let tick = 1.0 / 60.0;
    // Springs stiff enough that the substeps blend BDF2 with implicit Euler and the correction
    // runs the first level's W-cycle.
    let blended = ClothParams { spring_k: 1.7e5, ..multigrid.clone() };
    let blended = grid_cloth(square(1.0, 32), blended, at(6.0, 1.0), &[0, 31]);
    let h = tick / blended.params().substeps(tick, blended.topology()) as f32;
    let stepping = MultigridStepping::of(&ForceModel::new(blended.params()), blended.topology(), h);
    assert_eq!(stepping, MultigridStepping::Blend);
    let mut cloths: Vec<(&str, ClothSim)> = vec![
        ("multigrid 32x32", grid_cloth(square(1.0, 32), multigrid.clone(), at(0.0, 1.0), &[0, 31])),
        ("multigrid flag onto the ball", ClothSim::new(multigrid, Arc::new(flag), flat, &[]).unwrap()),
        ("descent 16x16", grid_cloth(square(1.0, 16), descent.clone(), at(-3.0, 1.0), &[0, 15])),
        ("multigrid 32x32 blended", blended),
    ];
    let (mut batch, mut ids) = rig.batch(&cloths, tick);
    let mut start: Vec<Vec<Vec3>> = cloths.iter().map(|(_, sim)| sim.positions()).collect();
    let mut first = vec![0.0f32; cloths.len()];
    let mut opening = Vec::new();
    for t in 0..60 {
        // At tick 15 a cloth larger than the room left joins: the buffers are rebuilt, and the
        // multigrid cloths' BDF2 history must come through.
        if t == 15 {
            let before = batch.particles(ids[0]).unwrap().0.clone();
            let added = grid_cloth(square(1.4, 64), descent.clone(), at(-3.0, 3.0), &[0, 63]);
            let id = batch.insert(&rig.device, &rig.queue, &added).unwrap();
            batch.set_params(&rig.queue, id, added.params(), tick);
            start.push(added.positions());
            ids.push(id);
            cloths.push(("added descent 64x64", added));
            first.push(0.0);
            assert_ne!(*batch.particles(ids[0]).unwrap().0, before, "the buffers were rebuilt");
        }
        // At tick 30 both start again from one state: a nudge the CPU sees as a change, so that
        // its BDF2 starts again from implicit Euler as the GPU's does after the upload.
        if t == 30 {
            for (_, sim) in &mut cloths {
                let last = sim.len() - 1;
                sim.set_velocity(last, sim.velocity(last) + Vec3::new(0.0, 0.0, 1.0e-3));
            }
        }
        let gaps = rig.tick_against_the_cpu(&mut batch, &mut cloths, &ids, (&colliders, &gpu_colliders), tick, t == 30);
        // The blended cloth is left out: over 15 ticks on its own its stiff springs part the two
        // sides by 1e-4 m (measured on lavapipe; 5e-4 m with springs stiff enough for implicit
        // Euler in every substep), rebuild or not.
        if t == 15 {
            for ((name, _), gap) in cloths.iter().zip(&gaps).take(2) {
                assert!(*gap < 1e-5, "{name}: GPU and CPU differ by {gap} m after the rebuild");
            }
        }
        if t == 0 {
            opening = gaps.clone();
        }
        if t == 30 {
            first = gaps;
        }
    }
    // The cloth that joined at tick 15 had no first tick with the others.
    opening.push(0.0);
    for ((((name, sim), before), (&id, first)), opening) in
        cloths.iter().zip(&start).zip(ids.iter().zip(&first)).zip(&opening)
    {
        let on_gpu: Vec<Vec3> = rig.batch_particles(&batch, id).iter().map(position).collect();
        let (cpu, gpu) = (sim.positions(), on_gpu);
        let fall = (centroid(before) - centroid(&cpu)).length();
        let centre = (centroid(&cpu) - centroid(&gpu)).length();
        let lowest = (lowest(&cpu) - lowest(&gpu)).abs();
        let gap = largest_gap(&cpu, &gpu);
        eprintln!(
            "{name}: the first tick {opening:.2e} m, one tick from 0.5 s {first:.2e} m; at 1 s, centroid {centre:.2e} m, \
             lowest point {lowest:.2e} m, largest gap {gap:.2e} m (fall {fall:.3} m)"
        );
        if name.ends_with("blended") {
            assert!(*opening < 2e-6, "{name}: GPU and CPU differ by {opening} m after the first tick");
            assert!(*first < 1e-3, "{name}: GPU and CPU differ by {first} m one tick after 0.5 s");
        } else {
            assert!(*first < 1e-5, "{name}: GPU and CPU differ by {first} m one tick after 0.5 s");
        }
        assert!(centre < 1e-3 * fall && lowest < 0.01 * fall, "{name}: centroid {centre} m, lowest {lowest} m apart");
    }
    let flag = &cloths[1].1;
    assert!(
        flag.positions().iter().any(|p| colliders[0].contains(*p + Vec3::new(0.0, -0.02, 0.0))),
        "the flag reached the ball"
    );
}

/// Tethers on the GPU as on the CPU: a 64 x 64 cloth hanging from two corners, stepped by block
/// descent with one sweep and the default tethers (a slack of 3 %), and the same cloth without
/// tethers fall for 1 s in
/// one batch, each tick from the CPU's state. Tolerance 2e-5 m per tick, twice block descent's
/// elsewhere: 16 substeps of a 64 x 64 cloth stretching while it swings carry the f32 rounding
/// of its 3x3 solves further (measured on lavapipe: 1.0e-5 m with tethers, where a tether takes
/// a particle's outward speed from the substep its distance crosses the reach, and 9.8e-6 m
/// without). On the GPU, too, the tethers hold the cloth: its sag at 1 s is at least 5 cm less
/// than without (measured on the CPU: 0.476 against 0.593 m).
#[test]
fn tethers_hold_a_hanging_cloth_on_the_gpu_as_on_the_cpu() {
    let Some(rig) = rig() else { return };
    let at = |x: f32| Affine3A::from_translation(Vec3::new(x, 2.0, 0.0));
    let tethered = ClothParams { integrator: Integrator::BLOCK_DESCENT, ..Default::default() };
    let untethered = ClothParams { tethers: None, ..tethered.clone() };
    let mut cloths: Vec<(&str, ClothSim)> = vec![
        ("tethered", grid_cloth(square(1.0, 64), tethered, at(0.0), &[0, 63])),
        ("untethered", grid_cloth(square(1.0, 64), untethered, at(3.0), &[0, 63])),
    ];
    let (mut batch, ids) = rig.batch(&cloths, 1.0 / 60.0);
    let none = GpuColliders::new(&rig.device, &[]);
    let mut worst = [0.0f32; 2];
    for t in 0..60 {
        let gaps = rig.tick_against_the_cpu(&mut batch, &mut cloths, &ids, (&[], &none), 1.0 / 60.0, true);
        for (k, (gap, (name, _))) in gaps.into_iter().zip(&cloths).enumerate() {
            worst[k] = worst[k].max(gap);
            assert!(gap < 2e-5, "{name}, tick {t}: GPU and CPU differ by {gap} m");
        }
    }
    let sag = |id: ClothId| {
        let particles = rig.batch_particles(&batch, id);
        2.0 - position(&particles[63 * 64 + 32]).y
    };
    let (held, loose) = (sag(ids[0]), sag(ids[1]));
    eprintln!(
        "largest CPU-GPU gap after one tick, with and without tethers: {worst:?} m; sag at 1 s {held:.3} m, without {loose:.3} m"
    );
    assert!(held + 0.05 < loose, "the tethers hold the cloth on the GPU: sag {held} m against {loose} m without");
}

/// The bundled low-resolution bunny as authored cloth, half a metre across, around `centre`.
fn bunny_cloth(centre: Vec3) -> ClothTopology {
    let obj = bunny_low();
    let (lo, hi) =
        obj.positions.iter().fold((Vec3::MAX, Vec3::MIN), |(lo, hi), &p| (lo.min(p.into()), hi.max(p.into())));
    let scale = 0.5 / (hi - lo).max_element();
    let positions: Vec<[f32; 3]> =
        obj.positions.iter().map(|&p| (centre + (Vec3::from(p) - 0.5 * (lo + hi)) * scale).to_array()).collect();
    ClothTopology::from_mesh(MeshRef { positions: &positions, indices: Some(&obj.indices) }).unwrap()
}

/// The default solver (the multigrid integrator: BDF2 after the first substep, and the
/// correction) on the GPU, against the analytic answer and the CPU: in one batch, a 16 x 16
/// grid hanging from two corners (held, so its drift is not summed), a 30 x 30 grid turned
/// upright, the bunny as authored cloth and a 3 x 3 grid, which start inside 64-slot blocks
/// that another cloth leads (the 3 x 3 grid wholly inside one), and a 16 x 16 grid 1 km out on
/// every axis, fall for 1 s (solving for positions, the last one did not move).
///
/// Every free cloth's centre of mass drops `g/c (t - (1 - e^{-ct})/c)` = 4.180 m within 1 %
/// and moves less than 1 mm sideways, and the CPU's is within 1 mm of the GPU's (measured on
/// lavapipe: 4.1802 m, the CPU within 7e-5 m, 2.4e-4 m 1 km out). The batch is rebuilt as its
/// cloths are added, so this also checks that BDF2's history comes through a rebuild.
#[test]
fn the_default_solver_falls_and_keeps_momentum_on_the_gpu() {
    assert_eq!(ClothParams::default().integrator, Integrator::Multigrid);
    falls_and_keeps_momentum_on_the_gpu(ClothParams::default());
}

/// As `the_default_solver_falls_and_keeps_momentum_on_the_gpu`, with block descent's one sweep
/// (measured on lavapipe: 4.1834 m). The drift sums' per-tick agreement with the CPU, where
/// contact makes the drift large, is `block_descent_agrees_with_the_cpu_in_a_mixed_batch`'s
/// flag.
#[test]
fn block_descent_falls_and_keeps_momentum_on_the_gpu() {
    falls_and_keeps_momentum_on_the_gpu(ClothParams { integrator: Integrator::BLOCK_DESCENT, ..Default::default() });
}

fn falls_and_keeps_momentum_on_the_gpu(params: ClothParams) {
    let Some(rig) = rig() else { return };
    let upright = |x: f32| {
        Affine3A::from_rotation_translation(Quat::from_rotation_x(core::f32::consts::FRAC_PI_2), Vec3::new(x, 2.0, 0.0))
    };
    let mut cloths: Vec<(&str, ClothSim)> = vec![
        (
            "hanging 16x16",
            grid_cloth(
                square(1.0, 16),
                params.clone(),
                Affine3A::from_translation(Vec3::new(-3.0, 3.0, 0.0)),
                &[0, 15],
            ),
        ),
        ("upright 30x30", grid_cloth(square(1.0, 30), params.clone(), upright(-1.0), &[])),
        (
            "bunny cloth",
            ClothSim::new(params.clone(), Arc::new(bunny_cloth(Vec3::new(1.0, 2.0, 0.0))), Affine3A::IDENTITY, &[])
                .unwrap(),
        ),
        ("3x3", grid_cloth(square(0.2, 3), params.clone(), upright(2.5), &[])),
        // Where f32 keeps a position to 61 µm: the sweeps solve for displacements.
        (
            "16x16 1 km out",
            grid_cloth(square(1.0, 16), params.clone(), Affine3A::from_translation(Vec3::splat(1000.0)), &[]),
        ),
    ];
    let starts: Vec<u32> = [0u32, 256, 1156, 1156 + 1839, 1156 + 1839 + 9].to_vec();
    let tick = 1.0 / 60.0;
    let (mut batch, ids) = rig.batch(&cloths, tick);
    for (&id, &start) in ids.iter().zip(&starts) {
        let (_, offset, _) = batch.particles(id).unwrap();
        assert_eq!(offset / size_of::<GpuParticle>() as u64, u64::from(start), "the batch packs the cloths in order");
    }
    let at_start: Vec<Vec3> = cloths.iter().map(|(_, sim)| sim.centre_of_mass()).collect();
    let (g, c) = (f64::from(params.gravity.length()), f64::from(params.damping));
    let expected = g / c * (1.0 - (1.0 - (-c).exp()) / c);
    let none = GpuColliders::new(&rig.device, &[]);
    rig.run(&mut batch, &none, 60);
    for (((name, sim), &id), &start) in cloths.iter_mut().zip(&ids).zip(&at_start) {
        for _ in 0..60 {
            sim.tick(tick, &[]);
        }
        if !sim.is_free_body() {
            continue;
        }
        let mut on_gpu = sim.clone();
        load_gpu_particles(&mut on_gpu, &rig.batch_particles(&batch, id));
        let (gpu, cpu) = (on_gpu.centre_of_mass(), sim.centre_of_mass());
        let moved = gpu - start;
        let fell = f64::from(-moved.y);
        eprintln!("{name}: fell {fell:.4} m on the GPU, CPU-GPU gap {:e} m", gpu.distance(cpu));
        assert!((fell - expected).abs() <= 0.01 * expected, "{name}: fell {fell} m, not {expected} m");
        assert!(moved.with_y(0.0).length() < 1.0e-3, "{name}: drifted {} m sideways", moved.with_y(0.0).length());
        assert!(gpu.distance(cpu) < 1.0e-3, "{name}: GPU and CPU centres of mass {} m apart", gpu.distance(cpu));
    }
}

// ---------------------------------------------------------------------------------------------
// Exact primitives
// ---------------------------------------------------------------------------------------------

/// A sphere, a capsule, a box and the ground, each posed (turned, scaled, moved), with a margin
/// and friction.
fn primitives() -> Vec<Collider> {
    let turn = Quat::from_rotation_x(0.3) * Quat::from_rotation_y(-0.5) * Quat::from_rotation_z(0.8);
    let shapes = [
        (Primitive::Sphere { radius: 0.3 }, Vec3::new(-1.0, 0.5, 0.0), 1.0),
        (Primitive::Capsule { radius: 0.2, half_length: 0.25 }, Vec3::new(1.0, 0.5, 0.0), 1.5),
        (Primitive::Cuboid { half_extents: Vec3::new(0.4, 0.1, 0.3) }, Vec3::new(0.0, 0.5, 1.0), 1.0),
        (Primitive::HalfSpace { normal: Vec3::Y }, Vec3::new(0.0, -0.2, 0.0), 1.0),
    ];
    shapes
        .into_iter()
        .enumerate()
        .map(|(k, (shape, translation, scale))| {
            let rotation = if k == 3 { Quat::from_rotation_x(0.1) } else { turn };
            Collider::primitive(shape).unwrap().with_margin(0.01).with_friction(0.5).with_pose(ColliderPose {
                translation,
                rotation,
                scale,
            })
        })
        .collect()
}

/// One substep of 1,024 free particles with no springs and no gravity, scattered around the four
/// primitives with random velocities (some start inside, some pass through, some miss): every
/// particle's position and velocity on the GPU within 1e-4 of the CPU's `ColliderFrame::resolve`.
#[test]
fn primitive_responses_agree_with_the_cpu() {
    let Some(rig) = rig() else { return };
    let colliders = primitives();
    let gpu_colliders = GpuColliders::new(&rig.device, &colliders);
    assert_eq!(gpu_colliders.len(), 4);
    let params = ClothParams {
        looper: 1,
        spring_k: 0.0,
        damping: 0.0,
        gravity: Vec3::ZERO,
        integrator: Integrator::SemiImplicitEuler,
        ..Default::default()
    };
    let mut sim = grid_cloth(square(1.0, 32), params, Affine3A::IDENTITY, &[]);
    let mut seed = 0x9e37_79b9_u32;
    let mut random = move || {
        seed ^= seed << 13;
        seed ^= seed >> 17;
        seed ^= seed << 5;
        seed as f32 / u32::MAX as f32 * 2.0 - 1.0
    };
    let centres = [Vec3::new(-1.0, 0.5, 0.0), Vec3::new(1.0, 0.5, 0.0), Vec3::new(0.0, 0.5, 1.0), Vec3::ZERO];
    let start: Vec<GpuParticle> = (0..sim.len())
        .map(|i| {
            let near = centres[i % 4] + Vec3::new(random(), random(), random()) * 0.6;
            particle(near, Vec3::new(random(), random(), random()) * 4.0, true)
        })
        .collect();
    load_gpu_particles(&mut sim, &start);
    let mut cloth = rig.cloth(&sim, 0.1);
    sim.tick(0.1, &colliders);
    rig.ticks(&mut cloth, &gpu_colliders, 1);
    let out = rig.particles(&cloth);
    let (cpu_p, cpu_v) = (sim.positions(), sim.velocities());
    let mut touched = 0;
    for (i, gpu) in out.iter().enumerate() {
        let free_end = position(&start[i]) + 0.1 * velocity(&start[i]);
        touched += usize::from(cpu_p[i].distance(free_end) > 1e-6);
        assert!(position(gpu).distance(cpu_p[i]) < 1e-4, "particle {i}: GPU {:?}, CPU {}", gpu.position, cpu_p[i]);
        assert!(velocity(gpu).distance(cpu_v[i]) < 1e-4, "particle {i}: GPU {:?}, CPU {}", gpu.velocity, cpu_v[i]);
    }
    eprintln!("primitive responses: {touched} of {} particles touched a primitive", out.len());
    assert!(touched > 150, "the scatter must reach the primitives: {touched} touched");
}

/// A 48 x 48 cloth dropped over the sphere, the capsule and the box onto the ground, the
/// default solver (multigrid), 240 ticks: the cloths agree in the large (centroid within 2 cm, lowest point within
/// 3 cm), and no GPU particle ends inside a primitive.
#[test]
fn a_cloth_dropped_on_primitives_agrees_with_the_cpu() {
    let Some(rig) = rig() else { return };
    let colliders = primitives();
    let gpu_colliders = GpuColliders::new(&rig.device, &colliders);
    let params = ClothParams { damping: 1.0, ..Default::default() };
    let pose = Affine3A::from_translation(Vec3::new(0.0, 1.2, 0.3));
    let mut cpu = grid_cloth(square(3.0, 48), params, pose, &[]);
    let mut gpu = rig.cloth(&cpu, 1.0 / 60.0);
    for _ in 0..240 {
        cpu.tick(1.0 / 60.0, &colliders);
    }
    rig.ticks(&mut gpu, &gpu_colliders, 240);
    let (c, g) = (cpu.positions(), gpu_positions(&rig, &gpu));
    eprintln!(
        "primitive drop, tick 240: centroid gap {:e} m, lowest {} vs {}",
        centroid(&c).distance(centroid(&g)),
        lowest(&c),
        lowest(&g)
    );
    assert!(centroid(&c).distance(centroid(&g)) < 0.02);
    assert!((lowest(&c) - lowest(&g)).abs() < 0.03);
    // On the ground: the lowest particle rests on it (its plane is tilted by 0.1 rad).
    assert!(lowest(&g) > -0.2 - 0.2 && lowest(&g) < 0.1, "lowest GPU particle at {}", lowest(&g));
    for collider in &colliders {
        let inside = g.iter().filter(|&&p| collider.contains(p)).count();
        assert_eq!(inside, 0, "{inside} GPU particles inside {:?}", collider.shape);
    }
}

// ---------------------------------------------------------------------------------------------
// Self-contact
// ---------------------------------------------------------------------------------------------

/// The self-contact scene: a 24 x 24 cloth of 0.8 m stepped by block descent and, 0.1 m above
/// it and turned, one stepped by RK4, both with self-contact (8 mm, friction 0.3), dropped on a
/// ball; beside them a hanging cloth without self-contact, which must not take part.
fn contact_scene() -> (Vec<(&'static str, ClothSim)>, [Collider; 1]) {
    let contact = Some(bvh_cloth_core::SelfContact { thickness: 0.008, friction: 0.3 });
    let place = |y: f32, turn: f32| Affine3A::from_rotation_translation(Quat::from_rotation_y(turn), Vec3::Y * y);
    let lower = ClothParams { self_contact: contact, integrator: Integrator::BLOCK_DESCENT, ..Default::default() };
    let upper = ClothParams { self_contact: contact, integrator: Integrator::Rk4, damping: 1.0, ..Default::default() };
    let hanging = ClothParams { integrator: Integrator::Rk4, damping: 1.0, ..Default::default() };
    let cloths = vec![
        ("lower, block descent", grid_cloth(square(0.8, 24), lower, place(0.35, 0.0), &[])),
        ("upper, RK4", grid_cloth(square(0.8, 24), upper, place(0.45, 0.4), &[])),
        (
            "hanging, no contact",
            grid_cloth(square(0.8, 16), hanging, Affine3A::from_translation(Vec3::X * 2.0), &[0, 15]),
        ),
    ];
    (cloths, [rough_ball(Vec3::ZERO)])
}

/// One tick of the contact scene on the CPU: the two contact cloths together (as the plugin's
/// CPU backend steps them), the hanging one alone. Returns the contacts of the last substep.
fn contact_tick_on_the_cpu(
    cloths: &mut [(&str, ClothSim)],
    colliders: &[Collider],
    solver: &mut ContactSolver,
) -> usize {
    let (pair, rest) = cloths.split_at_mut(2);
    let [(_, lower), (_, upper)] = pair else { unreachable!() };
    let (_, stats) = ClothSim::tick_together(&mut [lower, upper], 1.0 / 60.0, colliders, solver);
    rest[0].1.tick(1.0 / 60.0, colliders);
    stats.contacts
}

/// Self-contact on the GPU against the CPU, one tick at a time: before each tick the GPU gets
/// the CPU's state, then both step the scene one tick, for 45 ticks (the upper cloth lands on
/// the lower from about tick 10). The contact cloths take one substep count on both.
///
/// Tolerances, per tick: at most half of each cloth's particles more than 1e-5 m from the CPU's,
/// and none more than 7 mm. On lavapipe: at worst 34.5% and 1.4 mm with the CPU's pairs from a
/// hashed grid as the GPU's; with the CPU's pairs from its tree, summed in the pairs' order and
/// the cloths' flat parts skipped, at worst 34.5% and 2.8 mm (the block-descent cloth at tick
/// 21) with leaves of one triangle, 4.0 mm (tick 19) with those leaves and the tests' early
/// exits, and 6.5 mm (tick 19, 60 particles off; 5.3 mm for the RK4 cloth) with leaves of two,
/// whose walk takes the pairs of the same rules in another order and sums their contacts in
/// it. The largest gap follows the order of the sums, through the response's discontinuity
/// (below). Without contact the scene
/// agrees to 4e-6 m per tick. Contact's response is not continuous: a point that comes within
/// the thickness of a triangle, or an edge within the thickness of an edge, loses its approach
/// speed at once, and a particle a collider touches weighs as pinned, so particles a few ulps
/// from either threshold, on one side of it on the CPU and on the other on the GPU, end the
/// substep up to their approach speed times the substep apart (about 1 m/s x 2 ms), and drag
/// their neighbours. The CPU against itself shows it: the scene's two contact cloths moved by
/// 2 µm before a tick end it with up to 19% of their particles more than 1e-5 m (and 1 mm)
/// from where they end unmoved. A wrong response moves more, and further: on the GPU without
/// friction, without the corners' share, without the side a point came from, or with a touched
/// particle weighing as a free one, up to 100%, 100%, 13% and 100% of a cloth's particles
/// differ, by up to 6.4, 7.1, 8.1 and 6.6 mm: the three that move every particle fail the share,
/// the fourth (13%) the 7 mm. (Those two sets of figures come from variants of this test run on
/// lavapipe and not kept: the CPU's state nudged before each tick, and each part of the GPU's
/// response taken out in turn.)
#[test]
fn self_contact_agrees_with_the_cpu() {
    let Some(rig) = rig() else { return };
    let (mut cloths, colliders) = contact_scene();
    let gpu_colliders = GpuColliders::new(&rig.device, &colliders);
    let (mut batch, ids) = rig.batch(&cloths, 1.0 / 60.0);
    let mut solver = ContactSolver::default();
    let (mut worst, mut most_off, mut cpu_contacts, mut gpu_contacts) = (vec![0.0f32; 3], vec![0; 3], 0, 0);
    for t in 0..45 {
        for ((_, sim), &id) in cloths.iter().zip(&ids) {
            batch.upload_state(&rig.queue, id, sim);
        }
        cpu_contacts += contact_tick_on_the_cpu(&mut cloths, &colliders, &mut solver);
        rig.run(&mut batch, &gpu_colliders, 1);
        let stats: Vec<u32> = headless::read(&rig.device, &rig.queue, batch.contact_stats().expect("contact buffers"));
        assert_eq!(stats[1], 0, "tick {t}: the GPU grid met a bound");
        gpu_contacts += stats[0];
        for (k, ((name, sim), &id)) in cloths.iter().zip(&ids).enumerate() {
            let on_gpu: Vec<Vec3> = rig.batch_particles(&batch, id).iter().map(position).collect();
            let gap = largest_gap(&sim.positions(), &on_gpu);
            let off = sim.positions().iter().zip(&on_gpu).filter(|(a, b)| a.distance(**b) > 1e-5).count();
            worst[k] = worst[k].max(gap);
            most_off[k] = most_off[k].max(off);
            assert!(gap < 7e-3, "{name}, tick {t}: GPU and CPU differ by {gap} m");
            assert!(off * 2 <= on_gpu.len(), "{name}, tick {t}: {off} particles differ by more than 1e-5 m");
        }
    }
    eprintln!(
        "self-contact, largest CPU-GPU gaps after one tick: {:?}, most particles off by > 1e-5 m: {most_off:?}; \
         contacts in the last substeps on the CPU {cpu_contacts}, in all substeps on the GPU {gpu_contacts}",
        cloths.iter().map(|c| c.0).zip(&worst).collect::<Vec<_>>()
    );
    assert_eq!(batch.substeps(ids[0]), batch.substeps(ids[1]), "the contact cloths share one substep count");
    assert!(cpu_contacts > 0 && gpu_contacts > 0, "the cloths never touched: the scene tests nothing");
}

/// The contact scene `cloths` on the GPU alone for `ticks` 60 Hz ticks: every cloth's
/// positions, and how many triangles of the first two cloths cross each other's.
fn contact_scene_on_the_gpu(
    rig: &Rig,
    cloths: &[(&str, ClothSim)],
    colliders: &[Collider],
    ticks: u32,
) -> (Vec<Vec<Vec3>>, usize) {
    let gpu_colliders = GpuColliders::new(&rig.device, colliders);
    let (mut batch, ids) = rig.batch(cloths, 1.0 / 60.0);
    rig.run(&mut batch, &gpu_colliders, ticks);
    let x = rig.batch_positions(&batch, &ids);
    let tris = cloths[0].1.topology().triangles();
    let crossing = crossing_pairs(tris, &x[0], Some((tris, &x[1])));
    (x, crossing)
}

/// The contact scene on the GPU alone for 1 s: the upper cloth lands on the lower from about tick
/// 10 and rests on it; at the end no triangle of one crosses the other's and no particle is
/// closer than half the thickness to one of the other cloth. The control, the same scene
/// without self-contact, crosses within 1 s.
#[test]
fn self_contact_on_the_gpu_keeps_two_cloths_apart() {
    let Some(rig) = rig() else { return };
    let mut results = Vec::new();
    for contact in [true, false] {
        let (mut cloths, colliders) = contact_scene();
        for (_, sim) in cloths.iter_mut().filter(|_| !contact) {
            sim.set_params(ClothParams { self_contact: None, ..sim.params().clone() }).unwrap();
        }
        let (x, crossing) = contact_scene_on_the_gpu(&rig, &cloths, &colliders, 60);
        let close: usize = x[0].iter().map(|p| x[1].iter().filter(|q| p.distance(**q) < 0.004).count()).sum();
        assert!(x.iter().flatten().all(|p| p.is_finite()));
        eprintln!("GPU, contact {contact}: {crossing} crossing triangles, {close} close pairs between the cloths");
        results.push((crossing, close, centroid(&x[1]).y - centroid(&x[0]).y));
    }
    let [(crossing, close, above), (control, _, _)] = results[..] else { unreachable!() };
    assert!(control > 100, "without contact only {control} triangles cross: the cloths never met");
    assert_eq!(crossing, 0, "triangles of the two cloths intersect");
    assert_eq!(close, 0, "particles of the two cloths closer than half the thickness");
    assert!(above > 0.0, "the upper cloth is not above the lower one");
}

/// Two 32 x 32 cloths of 0.8 m that start crossed along a line (one flat, the other turned 10
/// degrees about the line across both middles) fall onto a ball together on the GPU, as the
/// core's `two_cloths_started_crossed_come_apart` on the CPU (184, 0 and 0 pairs of their
/// triangles intersecting at 0, 0.5 and 1 s there): within 1 s no triangle of one intersects
/// one of the other, and no particle of one lies within half the thickness of the other's.
/// The untangling kernels found the crossing pairs in the first half second (the grid's
/// statistics word).
#[test]
fn two_cloths_started_crossed_come_apart_on_the_gpu() {
    let Some(rig) = rig() else { return };
    let thickness = 0.01;
    let ball = Collider::primitive(Primitive::Sphere { radius: 0.25 }).unwrap().with_friction(0.5);
    let colliders = [ball];
    let params = ClothParams {
        self_contact: Some(bvh_cloth_core::SelfContact { thickness, friction: 0.3 }),
        ..ClothParams::default()
    };
    let middle = Vec3::Y * 0.45;
    let turned = Affine3A::from_rotation_translation(Quat::from_rotation_z(10f32.to_radians()), middle);
    let cloths = [
        ("flat", grid_cloth(square(0.8, 32), params.clone(), Affine3A::from_translation(middle), &[])),
        ("turned", grid_cloth(square(0.8, 32), params, turned, &[])),
    ];
    let tris = cloths[0].1.topology().triangles();
    let between = |x: &[Vec<Vec3>]| crossing_pairs(tris, &x[0], Some((tris, &x[1])));
    let start = between(&[cloths[0].1.positions(), cloths[1].1.positions()]);
    assert!(start > 50, "the cloths start crossed at only {start} pairs of triangles");
    let gpu_colliders = GpuColliders::new(&rig.device, &colliders);
    let (mut batch, ids) = rig.batch(&cloths, 1.0 / 60.0);
    let (mut pairs, mut found) = (vec![start], 0);
    for half in 0..2 {
        rig.run(&mut batch, &gpu_colliders, 30);
        if half == 0 {
            found = headless::read::<u32>(&rig.device, &rig.queue, batch.contact_stats().expect("contact buffers"))[3];
        }
        pairs.push(between(&rig.batch_positions(&batch, &ids)));
    }
    let x = rig.batch_positions(&batch, &ids);
    let close: usize = x[0].iter().map(|p| x[1].iter().filter(|q| p.distance(**q) < 0.5 * thickness).count()).sum();
    eprintln!(
        "GPU, two cloths started crossed: {pairs:?} intersecting pairs at 0, 0.5 and 1 s; {close} close pairs at 1 s; \
         {found} crossing pairs found by the substeps' analyses in the first 0.5 s"
    );
    assert!(x.iter().flatten().all(|p| p.is_finite()));
    assert!(found > 0, "the untangling kernels found no crossing pair");
    assert_eq!(pairs[2], 0, "triangles of the two cloths still intersect at 1 s");
    assert_eq!(close, 0, "particles of the two cloths closer than half the thickness at 1 s");
}

/// The core's `a_cloth_poked_through_itself_comes_apart` on the GPU: a cloth folded over itself
/// on the ground (32 x 66 particles, 0.8 m wide, its halves 5 cm apart, joined by a round fold),
/// a bump of its lower half poked up through its upper half (a closed curve of intersection on
/// each half; 103, 0 and 0 pairs of its triangles intersecting at 0, 0.5 and 1 s on the CPU).
/// Within 1 s no two of its triangles intersect, and no two particles that share no spring and
/// lie farther apart than the thickness at rest are closer than half of it.
#[test]
fn a_cloth_poked_through_itself_comes_apart_on_the_gpu() {
    let Some(rig) = rig() else { return };
    let thickness = 0.01;
    let params = ClothParams {
        self_contact: Some(bvh_cloth_core::SelfContact { thickness, friction: 0.3 }),
        ..ClothParams::default()
    };
    let (cols, rows) = (32u32, 66u32);
    let spacing = 0.8 / (cols - 1) as f32;
    let grid = ClothGrid::new(Vec2::new(0.8, spacing * (rows - 1) as f32), UVec2::new(cols, rows));
    let mut cloth = grid_cloth(grid, params, Affine3A::IDENTITY, &[]);
    let (floor, radius, width, bump) = (0.02, 3.0 * spacing / core::f32::consts::PI, 0.06, 0.15);
    for r in 0..rows {
        for c in 0..cols {
            let x = -0.4 + c as f32 * spacing;
            let position = match r {
                0..=31 => {
                    let z = -0.4 + r as f32 * spacing;
                    Vec3::new(x, floor + bump * (-(x * x + z * z) / (2.0 * width * width)).exp(), z)
                }
                32..=33 => {
                    let angle = (r - 31) as f32 * core::f32::consts::PI / 3.0;
                    Vec3::new(x, floor + radius * (1.0 - angle.cos()), 0.4 + radius * angle.sin())
                }
                _ => Vec3::new(x, floor + 2.0 * radius, 0.4 - (r - 34) as f32 * spacing),
            };
            cloth.set_position((r * cols + c) as usize, position);
        }
    }
    let topology = Arc::clone(cloth.topology());
    let start = crossing_pairs(topology.triangles(), &cloth.positions(), None);
    assert!(start > 20, "the bump crosses the upper half at only {start} pairs of triangles");
    let ground = [Collider::primitive(Primitive::HalfSpace { normal: Vec3::Y }).unwrap().with_friction(0.5)];
    let gpu_colliders = GpuColliders::new(&rig.device, &ground);
    let (mut batch, ids) = rig.batch(&[("folded", cloth)], 1.0 / 60.0);
    let mut pairs = vec![start];
    for _ in 0..2 {
        rig.run(&mut batch, &gpu_colliders, 30);
        pairs.push(crossing_pairs(topology.triangles(), &rig.batch_positions(&batch, &ids)[0], None));
    }
    let x = rig.batch_positions(&batch, &ids).remove(0);
    let rest = topology.rest_positions();
    let close = (0..x.len())
        .flat_map(|i| (i + 1..x.len()).map(move |j| (i, j)))
        .filter(|&(i, j)| {
            x[i].distance(x[j]) < 0.5 * thickness
                && rest[i].distance(rest[j]) >= thickness
                && !topology.springs_of(i).iter().any(|e| e.other as usize == j)
        })
        .count();
    eprintln!(
        "GPU, a cloth poked through itself: {pairs:?} intersecting pairs at 0, 0.5 and 1 s; {close} close pairs at 1 s"
    );
    assert!(x.iter().all(|p| p.is_finite()));
    assert_eq!(pairs[2], 0, "triangles of the cloth still intersect each other at 1 s");
    assert_eq!(close, 0, "particles of the cloth closer than half the thickness at 1 s");
}

/// Collision layers on the GPU as on the CPU: two cloths in one batch over a table on its own
/// layer, one that filters for the table (block descent) and one that does not (RK4), each tick
/// from the CPU's state. The first comes to rest on the table, the second falls past it as if it
/// were not there; each agrees with the CPU to 1e-4 m per tick (on lavapipe: 0 and 1.9e-9 m).
/// Negative control, by hand: with the collision kernel's layer test removed, the table stops the
/// second cloth on the GPU, 0.12 m from the CPU's after one tick.
#[test]
fn collision_layers_choose_each_cloths_colliders_on_the_gpu_as_on_the_cpu() {
    let Some(rig) = rig() else { return };
    const CLOTH: u32 = 1 << 1;
    const TABLE: u32 = 1 << 2;
    let table = Collider::primitive(Primitive::Cuboid { half_extents: Vec3::new(0.5, 0.1, 0.5) })
        .unwrap()
        .with_pose(ColliderPose { translation: Vec3::new(0.0, 0.5, 0.0), ..Default::default() })
        .with_layers(CollisionLayers::new(TABLE, CollisionLayers::ALL));
    let colliders = [table];
    let gpu_colliders = GpuColliders::new(&rig.device, &colliders);
    let meets = ClothParams { layers: CollisionLayers::new(CLOTH, TABLE), damping: 1.0, ..Default::default() };
    let passes =
        ClothParams { layers: CollisionLayers::new(CLOTH, CLOTH), integrator: Integrator::Rk4, ..meets.clone() };
    let pose = Affine3A::from_translation(Vec3::new(0.0, 0.8, 0.0));
    let mut cloths = vec![
        ("meets the table", grid_cloth(square(0.6, 16), meets, pose, &[])),
        ("passes", grid_cloth(square(0.6, 16), passes, pose, &[])),
    ];
    let (mut batch, ids) = rig.batch(&cloths, 1.0 / 60.0);
    let mut worst = [0.0f32; 2];
    for _ in 0..60 {
        let gaps =
            rig.tick_against_the_cpu(&mut batch, &mut cloths, &ids, (&colliders, &gpu_colliders), 1.0 / 60.0, true);
        for (worst, gap) in worst.iter_mut().zip(gaps) {
            *worst = worst.max(gap);
        }
    }
    let on_gpu = rig.batch_positions(&batch, &ids);
    eprintln!(
        "layers: largest CPU-GPU gap after one tick {worst:?}; lowest on the GPU {} and {}",
        lowest(&on_gpu[0]),
        lowest(&on_gpu[1])
    );
    for ((name, _), gap) in cloths.iter().zip(worst) {
        assert!(gap < 1e-4, "{name}: GPU and CPU differ by {gap} m after one tick");
    }
    assert!(lowest(&on_gpu[0]) > 0.59, "the table let through the cloth that meets it");
    assert!(lowest(&on_gpu[1]) < 0.3, "the table held the cloth that does not meet it");
}

/// The self-contact scene with the two contact cloths on layers that do not meet: on the GPU
/// they pass through each other within 1 s (as without self-contact in the test above), while
/// each still lands on the ball, whose default layers both meet.
#[test]
fn cloths_whose_layers_do_not_meet_pass_through_each_other_on_the_gpu() {
    let Some(rig) = rig() else { return };
    let (mut cloths, colliders) = contact_scene();
    for (k, (_, sim)) in cloths.iter_mut().take(2).enumerate() {
        let own = 1 << (k + 1);
        let layers = CollisionLayers::new(own, own | CollisionLayers::DEFAULT.memberships);
        sim.set_params(ClothParams { layers, ..sim.params().clone() }).unwrap();
    }
    let (x, crossing) = contact_scene_on_the_gpu(&rig, &cloths, &colliders, 60);
    let inside = x.iter().take(2).flatten().filter(|&&p| colliders[0].contains(p)).count();
    eprintln!("GPU, contact cloths on layers apart: {crossing} crossing triangles, {inside} particles in the ball");
    assert!(crossing > 100, "only {crossing} triangles cross: the cloths kept off each other");
    assert_eq!(inside, 0, "the ball let particles in");
}

/// The flags' settings when the GPU is held to the CPU in wind: the defaults without tethers.
/// A particle that reaches its tether's length loses its outward speed at once, a jump that
/// f32 rounding can move by a substep, and a flag whipping in gusts meets it often. On the CPU
/// alone, nudging the particles of `block_descent_takes_its_air_kick_in_its_prediction`'s flag
/// by 1e-7 m moves its eighth tick by 8.6e-5 m with tethers and by at most 4.5e-7 m without, and
/// an NVIDIA H200 differed from the CPU there by the same 8.6e-5 m. The tethers' agreement has
/// its own test (`tethers_hold_a_hanging_cloth_on_the_gpu_as_on_the_cpu`).
fn windy() -> ClothParams {
    ClothParams { tethers: None, ..Default::default() }
}

/// Three flags, 24 x 16 each, held along one edge, in a gusty, turbulent wind square to them
/// with a fan behind them: one stepped by RK4, one by block descent, and one without
/// aerodynamics. Each tick the GPU starts from the CPU's state, and both sample the wind at the
/// same clock time.
///
/// Tolerance: 1e-5 m per tick, as for the hanging cloth: the wind is smooth in space and time
/// (the noise and the fan's edges blend with smoothstep), so the two differ by f32 rounding
/// only. The flags have no tethers ([`windy`]). Measured on lavapipe: 4e-7 m (RK4) and 1.5e-6 m
/// (block descent). Negative controls,
/// each by hand: with the GPU's wind clock held at zero the RK4 flag differs by 26 mm after one
/// tick, and without the GPU's fan by 33 mm.
#[test]
fn flags_in_gusty_wind_agree_with_the_cpu() {
    use bvh_cloth_core::{Aerodynamics, Wind, WindSource};
    let Some(rig) = rig() else { return };
    let wind = Wind { seed: 11, ..Wind::gusty(Vec3::new(1.0, 0.0, 8.0)) };
    let fan = WindSource::Fan {
        origin: Vec3::new(-1.0, 1.0, -1.0),
        direction: Vec3::new(0.5, 0.0, 1.0),
        speed: 6.0,
        range: 5.0,
        spread: 0.7,
    };
    let grid = ClothGrid::new(Vec2::new(1.5, 1.0), UVec2::new(24, 16));
    let pole: Vec<u32> = (0..16).map(|r| r * 24).collect();
    let flags = [
        ("rk4", Integrator::Rk4, Aerodynamics::FABRIC),
        ("block descent", Integrator::BLOCK_DESCENT, Aerodynamics::FABRIC),
        ("no aerodynamics", Integrator::Rk4, Aerodynamics::NONE),
    ];
    let mut cloths: Vec<(&str, ClothSim)> = flags
        .iter()
        .enumerate()
        .map(|(k, &(name, integrator, aerodynamics))| {
            let params = ClothParams { mass: 0.3, integrator, aerodynamics, ..windy() };
            let pose = Affine3A::from_translation(Vec3::new(0.0, 1.5, k as f32 * 0.8))
                * Affine3A::from_rotation_x(core::f32::consts::FRAC_PI_2);
            let mut sim = grid_cloth(grid, params, pose, &pole);
            sim.set_wind(wind, &[fan]).unwrap();
            sim.set_wind_time(100.0);
            (name, sim)
        })
        .collect();
    let (mut batch, ids) = rig.batch(&cloths, 1.0 / 60.0);
    batch.set_wind_sources(&[fan]).unwrap();
    // How far each flag's free edge has gone downwind, along +Z.
    let far_z = |(k, sim): (usize, &ClothSim)| {
        (0..16).map(|r| sim.position(r * 24 + 23).z).sum::<f32>() / 16.0 - k as f32 * 0.8
    };
    let worst = rig.windy_ticks_against_the_cpu(&mut batch, &mut cloths, &ids, 90);
    eprintln!("flags in gusty wind, 90 ticks: largest CPU-GPU gaps after one tick {worst:?} m");
    // The wind matters in this scene: it swings the flags with aerodynamics round their pole,
    // while the flag without them hangs in its plane.
    let downwind: Vec<f32> = cloths.iter().map(|(_, sim)| sim).enumerate().map(far_z).collect();
    assert!(downwind[0] > 0.3 && downwind[1] > 0.3 && downwind[2].abs() < 0.01, "free edges downwind: {downwind:?} m");
}

/// A batch whose only cloth in the wind runs block descent gives it its kick in its
/// prediction: per substep `air_forces` and `vbd_predict_air`, no `air_kick` and no plain
/// `vbd_predict`; and it agrees with the CPU (to 1e-5 m after each tick, 30 ticks of gusty
/// wind), as a still cloth beside it does.
#[test]
fn block_descent_takes_its_air_kick_in_its_prediction() {
    use bvh_cloth_core::{Aerodynamics, Wind};
    let Some(rig) = rig() else { return };
    let wind = Wind { seed: 3, ..Wind::gusty(Vec3::new(0.0, 0.0, 8.0)) };
    let grid = ClothGrid::new(Vec2::new(1.5, 1.0), UVec2::new(24, 16));
    let pole: Vec<u32> = (0..16).map(|r| r * 24).collect();
    let mut cloths: Vec<(&str, ClothSim)> = [("in the wind", Aerodynamics::FABRIC), ("still", Aerodynamics::NONE)]
        .into_iter()
        .enumerate()
        .map(|(k, (name, aerodynamics))| {
            let params = ClothParams { mass: 0.3, integrator: Integrator::BLOCK_DESCENT, aerodynamics, ..windy() };
            let pose = Affine3A::from_translation(Vec3::new(0.0, 1.5, k as f32 * 0.8))
                * Affine3A::from_rotation_x(core::f32::consts::FRAC_PI_2);
            let mut sim = grid_cloth(grid, params, pose, &pole);
            sim.set_wind(wind, &[]).unwrap();
            sim.set_wind_time(10.0);
            (name, sim)
        })
        .collect();
    let (mut batch, ids) = rig.batch(&cloths, 1.0 / 60.0);
    let worst = rig.windy_ticks_against_the_cpu(&mut batch, &mut cloths, &ids, 30);
    eprintln!("block descent alone in gusty wind, 30 ticks: largest CPU-GPU gaps after one tick {worst:?} m");
    assert!(cloths[0].1.velocities().iter().any(|v| v.z > 0.5), "the wind blows the flag downwind");
    let Some(queries) = rig.timestamp_queries(512) else {
        eprintln!("the adapter has no timestamp queries: the dispatches were not listed");
        return;
    };
    let mut encoder = rig.device.create_command_encoder(&Default::default());
    let kernels = batch.encode_ticks_timed(&mut encoder, &rig.kernels, 1, &queries, 512).expect("512 queries fit");
    rig.queue.submit([encoder.finish()]);
    let count = |kernel: Kernel| kernels.iter().filter(|&&k| k == kernel).count();
    let substeps = cloths[0].1.params().looper as usize;
    assert_eq!(count(Kernel::AirSample), 1);
    assert_eq!(count(Kernel::AirForces), substeps);
    assert_eq!(count(Kernel::VbdPredictAir), substeps);
    assert_eq!((count(Kernel::AirKick), count(Kernel::VbdPredict)), (0, 0), "{kernels:?}");
}

/// Pins changed live on the GPU as on the CPU (`ClothBatch::set_pins` against
/// `ClothSim::set_pins`), in one batch: a 16 x 16 cloth on RK4 and one on block descent, each
/// hanging from two corners, let go of one corner after 20 ticks; a 12 x 12 cloth falling
/// free, caught by a corner (it had no tethers, so the buffers are rebuilt); and a cloth left
/// alone. Each tick starts from the CPU's state but the first after the change, which checks
/// that the state stayed on the GPU with the new free flags and velocities; the 30 after it
/// check that the tethers and the constants follow the new pins. 2e-5 m per tick, as the
/// tethers' test (measured on lavapipe: 4.7e-6 m at most in the first tick, 1.1e-5 m after).
#[test]
fn pins_change_live_on_the_gpu_as_on_the_cpu() {
    let Some(rig) = rig() else { return };
    let at = |x: f32| Affine3A::from_translation(Vec3::new(x, 2.0, 0.0));
    let rk4 = ClothParams { integrator: Integrator::Rk4, ..Default::default() };
    let descent = ClothParams { integrator: Integrator::BLOCK_DESCENT, ..Default::default() };
    let mut cloths: Vec<(&str, ClothSim)> = vec![
        ("RK4, let go", grid_cloth(square(1.0, 16), rk4, at(0.0), &[0, 15])),
        ("block descent, let go", grid_cloth(square(1.0, 16), descent.clone(), at(2.0), &[0, 15])),
        ("falling, caught", grid_cloth(square(0.5, 12), descent.clone(), at(4.0), &[])),
        ("left alone", grid_cloth(square(1.0, 16), descent, at(6.0), &[0, 15])),
    ];
    let tick = 1.0 / 60.0;
    let (mut batch, ids) = rig.batch(&cloths, tick);
    let none = GpuColliders::new(&rig.device, &[]);
    for _ in 0..20 {
        rig.tick_against_the_cpu(&mut batch, &mut cloths, &ids, (&[], &none), tick, true);
    }
    for (k, pins) in [(0, vec![0]), (1, vec![0]), (2, vec![0])] {
        let sim = &mut cloths[k].1;
        sim.set_pins(&pins).unwrap();
        batch.set_pins(&rig.device, &rig.queue, ids[k], sim.pins(), sim.tethers().clone()).unwrap();
        batch.set_params(&rig.queue, ids[k], &sim.params().clone(), tick);
    }
    let caught_at = cloths[2].1.position(0);
    let released_at = cloths[1].1.position(15);
    let gaps = rig.tick_against_the_cpu(&mut batch, &mut cloths, &ids, (&[], &none), tick, false);
    eprintln!("first tick after the pins changed, GPU against CPU: {gaps:?} m");
    for (gap, (name, _)) in gaps.iter().zip(&cloths) {
        assert!(*gap < 2e-5, "{name}: GPU and CPU differ by {gap} m in the first tick after the change");
    }
    let mut worst = vec![0.0f32; cloths.len()];
    for _ in 0..30 {
        let gaps = rig.tick_against_the_cpu(&mut batch, &mut cloths, &ids, (&[], &none), tick, true);
        for (worst, gap) in worst.iter_mut().zip(gaps) {
            *worst = worst.max(gap);
        }
    }
    eprintln!("largest gap after one tick over the 30 ticks after it: {worst:?} m");
    for (gap, (name, _)) in worst.iter().zip(&cloths) {
        assert!(*gap < 2e-5, "{name}: GPU and CPU differ by {gap} m after a tick");
    }
    let on_gpu = |k: usize| rig.batch_particles(&batch, ids[k]).iter().map(position).collect::<Vec<_>>();
    assert_eq!(on_gpu(2)[0], caught_at, "the caught corner moved on the GPU");
    let fell = released_at.y - on_gpu(1)[15].y;
    assert!(fell > 0.2, "the released corner fell {fell} m on the GPU in 0.5 s");
}
