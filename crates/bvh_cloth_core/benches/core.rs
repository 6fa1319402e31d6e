//! Micro-benchmarks of the core: cloth steps, aerodynamics, collider builds and particle
//! queries.
//!
//! `cargo bench -p bvh_cloth_core --bench core`

use std::hint::black_box;

use std::sync::Arc;

use bvh_cloth_core::backend::Air;

use bvh_cloth_core::ObjMesh;
use bvh_cloth_core::backend::AirModel;
use bvh_cloth_core::parse_obj;
use bvh_cloth_core::{
    Aerodynamics, Affine3A, ClothGrid, ClothParams, ClothSim, ClothTopology, Collider, Integrator, MeshRef, UVec2,
    Vec2, Vec3, Vec3A, Wind,
};
use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};

fn load(name: &str) -> ObjMesh {
    let path = format!("{}/../../assets/models/{name}", std::env::var("CARGO_MANIFEST_DIR").expect("run by cargo"));
    parse_obj(&std::fs::read_to_string(&path).expect("model file")).expect("valid OBJ")
}

fn grid(size: u32) -> ClothGrid {
    ClothGrid::new(Vec2::splat(2.0), UVec2::splat(size))
}

fn cloth_on(topology: ClothTopology, integrator: Integrator) -> ClothSim {
    let params = ClothParams { integrator, ..Default::default() };
    ClothSim::new(params, Arc::new(topology), Affine3A::from_translation(Vec3::new(0.0, 1.2, 0.0)), &[]).unwrap()
}

fn cloth(size: u32, integrator: Integrator) -> ClothSim {
    cloth_on(ClothTopology::grid(grid(size)).unwrap(), integrator)
}

/// One RK4 substep per particle on the same particle count, three ways: the grid's fast path,
/// the grid's springs through the general per-particle path, and the grid's triangles built as
/// an authored mesh (edges and cross-edge springs, areas for masses).
fn topology(c: &mut Criterion) {
    let mut group = c.benchmark_group("topology");
    for size in [64u32, 128] {
        let g = grid(size);
        let positions: Vec<[f32; 3]> = g.rest_positions(&Affine3A::IDENTITY).iter().map(|p| p.to_array()).collect();
        let indices = g.triangle_indices();
        let authored = ClothTopology::from_mesh(MeshRef { positions: &positions, indices: Some(&indices) }).unwrap();
        let cases = [
            ("grid fast path", ClothTopology::grid(g).unwrap()),
            ("grid general path", ClothTopology::grid_as_mesh(g).unwrap()),
            ("authored mesh", authored),
        ];
        for (name, t) in cases {
            let mut sim = cloth_on(t, Integrator::Rk4);
            group.throughput(Throughput::Elements(u64::from(size * size)));
            group.bench_function(BenchmarkId::new(name, format!("{size}x{size}")), |b| {
                b.iter(|| sim.substep(black_box(1.0e-3), &[]))
            });
        }
    }
    group.finish();
}

fn step(c: &mut Criterion) {
    let mut group = c.benchmark_group("substep");
    for integrator in [Integrator::Rk4, Integrator::SemiImplicitEuler] {
        for size in [64u32, 128, 256] {
            let mut sim = cloth(size, integrator);
            group.throughput(Throughput::Elements(u64::from(size * size)));
            group.bench_function(BenchmarkId::new(format!("{integrator:?}"), format!("{size}x{size}")), |b| {
                b.iter(|| sim.substep(black_box(1.0e-3), &[]))
            });
        }
    }
    // The paper's setup as in the report's Table VII: 64 x 64 on the bunny at n = 5 (1 cm margin,
    // friction 1), landed for a second, collision included.
    let bunny = [Collider::from_mesh(load("bunny.obj").as_mesh_ref(), 5).unwrap().with_margin(0.01).with_friction(1.0)];
    let mut sim = cloth(64, Integrator::Rk4);
    for _ in 0..60 {
        sim.tick(1.0 / 60.0, &bunny); // land on the bunny first, so collisions happen
    }
    group.throughput(Throughput::Elements(64 * 64));
    group.bench_function("Rk4/64x64 on bunny n=5", |b| b.iter(|| sim.substep(black_box(1.0e-3), &bunny)));
    group.finish();
}

/// The parts of aerodynamics at 64 x 64 (the report's `wind` cost scene: hanging from two
/// corners for 1 s in `Wind::gusty` at 8 m/s), against the block-descent substep they are set
/// against: the wind's sampling (once a tick), the kick of drag and lift (once a substep, on the
/// grid's path and on the general one), and a tick without them.
fn aerodynamics(c: &mut Criterion) {
    let mut group = c.benchmark_group("aerodynamics");
    let topology = Arc::new(ClothTopology::grid(ClothGrid::new(Vec2::splat(1.4), UVec2::splat(64))).unwrap());
    let params = ClothParams { aerodynamics: Aerodynamics::FABRIC, ..Default::default() };
    let pose = Affine3A::from_translation(Vec3::new(0.0, 2.0, 0.0)) * Affine3A::from_rotation_x(0.3);
    let wind = Wind::gusty(Vec3::new(8.0, 0.0, 2.0));
    let mut sim = ClothSim::new(params.clone(), topology.clone(), pose, &[0, 63]).unwrap();
    sim.set_wind(wind, &[]).unwrap();
    for _ in 0..60 {
        sim.tick(1.0 / 60.0, &[]);
    }
    let x: Vec<Vec3A> = sim.positions().iter().map(|&p| p.into()).collect();
    let v: Vec<Vec3A> = sim.velocities().iter().map(|&p| p.into()).collect();
    let free = vec![1.0f32; x.len()];
    let model = AirModel::new(params.aerodynamics, params.mass, &wind, 1.0);
    let mut air = Air::default();
    group.throughput(Throughput::Elements(64 * 64));
    group.bench_function("sample/64x64", |b| b.iter(|| air.sample(&model, &[], black_box(&x))));
    let h = 1.0 / (60.0 * params.looper as f32);
    // The kick reads the sampled wind, whether or not the sampling's own benchmark ran.
    air.sample(&model, &[], &x);
    group.bench_function("kick/64x64", |b| {
        let mut v = v.clone();
        b.iter(|| air.kick(&model, &topology, &free, black_box(h), &x, &mut v))
    });
    // The same kick with the same bits on the general path, which gathers each triangle's
    // corners: the path of an authored mesh.
    let general = ClothTopology::grid_as_mesh(*topology.stencil().expect("a generated grid")).unwrap();
    group.bench_function("kick on the general path/64x64", |b| {
        let mut v = v.clone();
        b.iter(|| air.kick(&model, &general, &free, black_box(h), &x, &mut v))
    });
    // A whole tick, whose substeps share one change of layout in and out.
    sim.set_params(ClothParams { aerodynamics: Aerodynamics::NONE, ..params.clone() }).unwrap();
    group.bench_function(format!("block descent tick of {} substeps without aerodynamics/64x64", params.looper), |b| {
        b.iter_batched(|| sim.clone(), |mut sim| sim.tick(black_box(1.0 / 60.0), &[]), criterion::BatchSize::LargeInput)
    });
    group.finish();
}

fn build(c: &mut Criterion) {
    let mut group = c.benchmark_group("collider_build");
    for name in ["bunny.obj", "dragon.obj"] {
        let mesh = load(name);
        for n in [1u32, 3, 5, 16, 32] {
            group.bench_function(BenchmarkId::new(name, format!("n={n}")), |b| {
                b.iter(|| Collider::from_mesh(black_box(mesh.as_mesh_ref()), n).unwrap())
            });
        }
    }
    group.finish();
}

/// 4096 query points spread through the bunny's box and a margin around it.
fn query_points(collider: &Collider) -> Vec<Vec3> {
    let (lo, hi) = collider.lbvh().expect("a mesh collider").bounds().unwrap();
    let mut state = 0x2545_F491_4F6C_DD1Du64;
    let mut unit = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 40) as f32 / (1u64 << 24) as f32
    };
    let pad = (hi - lo) * 0.1;
    (0..4096).map(|_| lo - pad + (hi - lo + 2.0 * pad) * Vec3::new(unit(), unit(), unit())).collect()
}

fn query(c: &mut Criterion) {
    let mesh = load("bunny.obj");
    let mut group = c.benchmark_group("query_bunny");
    group.throughput(Throughput::Elements(4096));
    for n in [5u32, 32] {
        let collider = Collider::from_mesh(mesh.as_mesh_ref(), n).unwrap();
        let points = query_points(&collider);
        group.bench_function(BenchmarkId::new("lbvh", format!("n={n}")), |b| {
            b.iter(|| {
                let mut hits = 0u32;
                for &p in &points {
                    collider.lbvh().expect("a mesh collider").for_each_containing(p, 0.0, |_, _| hits += 1);
                }
                hits
            })
        });
        group.bench_function(BenchmarkId::new("brute_force", format!("n={n}")), |b| {
            b.iter(|| {
                let mut hits = 0u32;
                for &p in &points {
                    collider.lbvh().expect("a mesh collider").brute_force_containing(p, 0.0, |_, _| hits += 1);
                }
                hits
            })
        });
    }
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20).warm_up_time(std::time::Duration::from_millis(500)).measurement_time(std::time::Duration::from_secs(2));
    targets = step, topology, aerodynamics, build, query
}
criterion_main!(benches);
