//! The section `far_from_origin`: how far from the origin a stiff cloth still steps finitely.

use super::*;

/// Particle positions are world-space `f32`: far from the origin their spacing (one ulp) grows
/// towards the springs' rest length. The soak's stiff case (a free 26 x 24 cloth, 1.4 m wide,
/// SpringK 1,390 N/m, semi-implicit Euler, under its swept force) is started at growing
/// distances and run for 10 s.
pub(crate) fn far_from_origin() {
    println!("\n## Precision far from the origin: a free 26 x 24 cloth (5.6 cm springs), SpringK 1,390, 10 s\n");
    println!("| distance from the origin | f32 spacing of each coordinate | first non-finite tick (of 600) |");
    println!("|---|---|---|");
    for distance in [0.0f32, 100.0, 1_000.0, 3_000.0, 10_000.0, 100_000.0] {
        let params = ClothParams {
            looper: 22,
            spring_k: 1_390.0,
            damping: 0.1,
            external_force: Vec3::new(3.9, 17.8, -0.3),
            integrator: Integrator::SemiImplicitEuler,
            ..Default::default()
        };
        let coordinate = distance / 3f32.sqrt();
        let start = Affine3A::from_translation(Vec3::splat(coordinate));
        let grid = ClothGrid::new(Vec2::new(1.4, 1.4 * 25.0 / 23.0), UVec2::new(24, 26));
        let topology = Arc::new(ClothTopology::grid(grid).expect("a valid grid"));
        let mut sim = ClothSim::new(params, topology, start, &[]).expect("valid parameters");
        let first_bad = (1..=600).find(|_| {
            sim.tick(TICK, &[]);
            !sim.is_finite()
        });
        let spacing = f32::from_bits(coordinate.max(1.0).to_bits() + 1) - coordinate.max(1.0);
        let outcome = first_bad.map_or("none: finite throughout".to_string(), |t| t.to_string());
        println!("| {distance} m | {spacing:.1e} m | {outcome} |");
    }
}
