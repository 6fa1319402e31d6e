//! Scenes and timers shared by the benchmark report (`benches/report.rs`).
//!
//! Every scene is the paper's Table VII setup or a variation of it: a square cloth dropped onto
//! one of the two models in `assets/models` (each normalised to a 1 m box standing on y = 0).

use std::sync::Arc;
use std::time::Instant;

use bvh_cloth_core::ObjMesh;

use bvh_cloth_core::parse_obj;
use bvh_cloth_core::{
    Affine3A, ClothGrid, ClothParams, ClothSim, ClothTopology, Collider, Integrator, MeshRef, Primitive, UVec2, Vec2,
    Vec3,
};

/// The simulation tick: one frame at 60 Hz.
pub const TICK: f32 = 1.0 / 60.0;

/// The two models of the paper's Table VII.
pub const MODELS: [&str; 2] = ["bunny", "dragon"];

/// Loads `assets/models/{name}.obj`.
pub fn model(name: &str) -> ObjMesh {
    let path = format!("{}/../../assets/models/{name}.obj", std::env::var("CARGO_MANIFEST_DIR").expect("run by cargo"));
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    parse_obj(&text).unwrap_or_else(|e| panic!("{path}: {e:?}"))
}

/// The collider of the Table VII scenes: `n`³ voxels, a 1 cm margin and a rough surface.
pub fn collider(mesh: &ObjMesh, n: u32) -> Collider {
    Collider::from_mesh(mesh.as_mesh_ref(), n)
        .expect("the bundled models are valid")
        .with_margin(0.01)
        .with_friction(1.0)
}

/// The Table VII cloth's grid: `size x size` particles over 1.4 m x 1.4 m.
pub fn square_grid(size: u32) -> ClothGrid {
    ClothGrid::new(Vec2::splat(1.4), UVec2::splat(size))
}

/// The same grid's triangles built as an authored mesh would be ([`ClothTopology::from_mesh`]:
/// edges and cross-edge springs, masses by area).
pub fn authored_grid(size: u32) -> ClothTopology {
    let grid = square_grid(size);
    let positions: Vec<[f32; 3]> = grid.rest_positions(&Affine3A::IDENTITY).iter().map(|p| p.to_array()).collect();
    let indices = grid.triangle_indices();
    ClothTopology::from_mesh(MeshRef { positions: &positions, indices: Some(&indices) }).expect("a valid mesh")
}

/// A cloth of `topology` (Looper 16, the paper's other parameters) held flat 0.3 m above
/// `collider`, a little off its centre so that it slides off one side.
pub fn topology_above(collider: &Collider, topology: ClothTopology, integrator: Integrator) -> ClothSim {
    let top = top_of(collider);
    let params = ClothParams { damping: 1.0, integrator, ..Default::default() };
    let pose = Affine3A::from_translation(Vec3::new(-0.2, top + 0.3, 0.0));
    ClothSim::new(params, Arc::new(topology), pose, &[]).expect("valid cloth")
}

/// The height of `collider`'s highest point (its plane's height for a half-space).
pub fn top_of(collider: &Collider) -> f32 {
    let pose = collider.pose;
    let Some(primitive) = collider.as_primitive() else {
        let local_top = collider.lbvh().expect("a mesh collider").bounds().expect("a collider has spheres").1.y;
        return pose.translation.y + pose.scale * local_top;
    };
    // The top of the shape's bounding sphere (exact for the sphere and the plane).
    let reach = match *primitive {
        Primitive::Sphere { radius } => radius,
        Primitive::Capsule { radius, half_length } => radius + half_length,
        Primitive::Cuboid { half_extents } => half_extents.length(),
        Primitive::HalfSpace { .. } => 0.0,
    };
    pose.translation.y + pose.scale * reach
}

/// A `size x size` grid cloth (1.4 m wide) above `collider`, as [`topology_above`].
pub fn cloth_above(collider: &Collider, size: u32, integrator: Integrator) -> ClothSim {
    topology_above(collider, ClothTopology::grid(square_grid(size)).expect("a valid grid"), integrator)
}

/// A 64 x 64 cloth dropped on `collider` and simulated for `seconds`.
pub fn drape(collider: &Collider, seconds: f32) -> ClothSim {
    let mut sim = cloth_above(collider, 64, Integrator::Rk4);
    let colliders = std::slice::from_ref(collider);
    for _ in 0..(seconds / TICK).round() as u32 {
        sim.tick(TICK, colliders);
    }
    sim
}

/// Seconds taken by `f`.
pub fn time(f: impl FnOnce()) -> f64 {
    let start = Instant::now();
    f();
    start.elapsed().as_secs_f64()
}

/// The fastest of `reps` runs of `f`, in seconds. On a shared machine the minimum is the run
/// least disturbed by other work, so it is the figure that compares best within one report.
pub fn best_of(reps: u32, mut f: impl FnMut()) -> f64 {
    (0..reps).map(|_| time(&mut f)).fold(f64::INFINITY, f64::min)
}

/// The median of `samples`.
pub fn median(mut samples: Vec<f64>) -> f64 {
    samples.sort_by(f64::total_cmp);
    samples[samples.len() / 2]
}
