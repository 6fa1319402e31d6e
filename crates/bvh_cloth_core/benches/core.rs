//! Micro-benchmarks of the core: cloth steps, collider builds and particle queries.
//!
//! `cargo bench -p bvh_cloth_core --bench core`

use std::hint::black_box;

use bvh_cloth_core::obj::{ObjMesh, parse_obj};
use bvh_cloth_core::{Affine3A, ClothParams, ClothSim, Collider, Integrator, Vec3};
use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};

fn load(name: &str) -> ObjMesh {
    let path = format!("{}/../../assets/models/{name}", std::env::var("CARGO_MANIFEST_DIR").expect("run by cargo"));
    parse_obj(&std::fs::read_to_string(&path).expect("model file")).expect("valid OBJ")
}

fn cloth(size: u32, integrator: Integrator) -> ClothSim {
    let params = ClothParams { rows: size, cols: size, integrator, ..Default::default() };
    ClothSim::new(params, Affine3A::from_translation(Vec3::new(0.0, 1.2, 0.0)), &[]).unwrap()
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
    let (lo, hi) = collider.lbvh.bounds().unwrap();
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
                    collider.lbvh.for_each_containing(p, 0.0, |_, _| hits += 1);
                }
                hits
            })
        });
        group.bench_function(BenchmarkId::new("brute_force", format!("n={n}")), |b| {
            b.iter(|| {
                let mut hits = 0u32;
                for &p in &points {
                    collider.lbvh.brute_force_containing(p, 0.0, |_, _| hits += 1);
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
    targets = step, build, query
}
criterion_main!(benches);
