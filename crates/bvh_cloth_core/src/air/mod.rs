//! Aerodynamics: drag and lift on every triangle of a cloth from its velocity relative to the
//! air, and the air itself: a wind with gusts and turbulence, and local sources (a fan, a
//! blast).
//!
//! ## The force on a triangle
//! A triangle of area `A` and unit normal `n`, whose corners move on average at `v` in air whose
//! velocity averaged over the corners is `w`, meets the relative flow `u = w - v`. With
//! `cos θ = n · û` (θ the angle between the normal and the flow):
//! - drag, along the flow: `½ ρ C_d A |u|² |cos θ| û`. A triangle square to the flow catches
//!   all of it, one edge-on catches none.
//! - lift, across the flow: `½ ρ C_l A |u|² cos θ (n - cos θ û)`, of size
//!   `½ ρ C_l A |u|² cos θ sin θ`: zero square to the flow and edge-on, largest at 45°, and
//!   pushing the triangle away from the side the air strikes.
//!
//! Both are unchanged when the normal flips, so the mesh's winding does not matter. Each corner
//! takes a third of its triangle's force. This split into a drag and a lift coefficient is the
//! one game cloth solvers expose (NvCloth's `setDragCoefficient` and `setLiftCoefficient`).
//!
//! ## How it is stepped
//! The wind is sampled at every particle once per tick, at the tick's start. The forces are
//! evaluated once per substep from the substep's start state and applied as a change of
//! velocity before the integrator runs, `v += h a`: the same splitting for every integrator
//! and on both backends. A particle's change of velocity is capped at its speed relative to the
//! wind, so drag can bring a particle up to the wind's speed but never past it, and a light
//! cloth in a gale stays stable at any substep length.
//!
//! On the CPU the triangles' forces are found four at a time, one triangle per SIMD lane
//! ([`AirModel::triangle_forces`]); on a generated grid four cells of a row are read straight
//! into the lanes, with no gather, and four particles sum their forces at once. A tick's
//! sampling hashes each corner of the noise's lattice round the cloth and blends it in time
//! once, not once per particle in its cells (the noise blends each corner in time first, then
//! in space). All of these give the bits of the one-at-a-time arithmetic that the GPU repeats.
//!
//! ## The wind
//! At a point `p` and time `t`, the air moves at
//! `velocity (1 + gust_strength g(t / gust_period)) + turbulence N(p / turbulence_scale, t / turbulence_period)`
//! plus every source's velocity there. `g` is a value noise in time and `N` a vector value
//! noise in space and time, each component in `[-1, 1]`: lattice values from an integer hash,
//! blended with smoothstep weights, so the same integers give the same values on every device.
//! The time lattice repeats every [`NOISE_TIME_PERIOD`] steps, which keeps the lattice time in
//! `f32` precise however long a game runs, with no seam.

mod grid_kick;
mod kick;
mod model;
mod noise;
mod settings;
mod source;

pub use kick::{Air, capped_kick};
pub use model::AirModel;
pub use noise::{NOISE_TIME_PERIOD, hash, value_noise_1d, value_noise_4d};
pub use settings::{Aerodynamics, MAX_AIR_DENSITY, MAX_COEFFICIENT, MAX_WIND_SPEED, Wind, WindSource};
pub use source::{AirSource, SOURCE_BLAST, SOURCE_FAN};

/// Particles (or triangles) one rayon task handles at least: below that a pass is not split,
/// since a fork and join costs more than the work it would share (a 64x64 cloth's 7,938
/// triangles are not split).
const MIN_TASK: usize = 8192;

#[cfg(test)]
mod tests {
    use glam::{Vec3, Vec3A};

    use super::kick::*;
    use super::model::*;
    use super::noise::*;
    use super::*;
    use crate::cloth::error::ClothError;
    use crate::cloth::topology::ClothTopology;

    fn model(aerodynamics: Aerodynamics, wind: &Wind) -> AirModel {
        AirModel::new(aerodynamics, 3.0, wind, 0.0)
    }

    /// A unit right triangle in the XZ plane (area 0.5, normal ±Y), at rest.
    fn plate() -> [Vec3; 3] {
        [Vec3::ZERO, Vec3::X, Vec3::Z]
    }

    #[test]
    fn drag_square_to_the_flow_is_half_rho_cd_a_u_squared() {
        let wind = Wind::steady(Vec3::new(0.0, -10.0, 0.0));
        let m = model(Aerodynamics { drag: 1.2, lift: 0.7 }, &wind);
        let w = [wind.velocity; 3];
        let f = m.triangle_force(plate(), [Vec3::ZERO; 3], w);
        // Per corner over the mass: ½ 1.225 1.2 0.5 100 / (3 * 3), all along the flow; no lift
        // square to it.
        let want = 0.5 * 1.225 * 1.2 * 0.5 * 100.0 / 9.0;
        assert!((f - Vec3::new(0.0, -want, 0.0)).length() < 1e-5 * want, "{f}");
        // Edge-on: neither drag nor lift.
        let edge_on = m.triangle_force(plate(), [Vec3::ZERO; 3], [Vec3::new(10.0, 0.0, 0.0); 3]);
        assert!(edge_on.length() < 1e-6, "{edge_on}");
    }

    #[test]
    fn lift_at_45_degrees_pushes_away_from_the_struck_side() {
        // Air from above and behind at 45°: cos θ = sin θ = √½.
        let u = Vec3::new(1.0, -1.0, 0.0).normalize() * 10.0;
        let m = model(Aerodynamics { drag: 0.0, lift: 1.0 }, &Wind::steady(u));
        let f = m.triangle_force(plate(), [Vec3::ZERO; 3], [u; 3]);
        let q = 0.5 * 100.0;
        let want = 0.5 * 1.225 / 9.0 * q * 0.5;
        assert!((f.length() - want).abs() < 1e-4 * want, "{} vs {want}", f.length());
        assert!(f.dot(u).abs() < 1e-4 * want, "lift is across the flow");
        assert!(f.y < 0.0, "air striking the top pushes the plate down: {f}");
        // The winding does not matter.
        let [a, b, c] = plate();
        let flipped = m.triangle_force([a, c, b], [Vec3::ZERO; 3], [u; 3]);
        assert!((flipped - f).length() < 1e-6 * want);
    }

    /// The three-lane pass gives every triangle's force bit for bit as one triangle at a time
    /// does, for every remainder of three, with triangles of no area, corners moving with the
    /// air, and corners that are not finite among them.
    #[test]
    fn lanes_give_the_bits_of_one_triangle_at_a_time() {
        let m = model(Aerodynamics::FABRIC, &Wind::steady(Vec3::new(6.0, -1.0, 2.0)));
        let mut seed = 17u32;
        let mut next = || {
            seed = hash(seed);
            unit(seed) * 2.0
        };
        let count = 40;
        let x: Vec<Vec3A> = (0..count).map(|_| Vec3A::new(next(), next(), next())).collect();
        let mut v: Vec<Vec3A> = (0..count).map(|_| Vec3A::new(next(), next(), next())).collect();
        let w: Vec<Vec3A> = (0..count).map(|_| Vec3A::new(next(), next(), next()) * 5.0).collect();
        // Particles 0 to 2 move with their air, and 3 is not finite.
        v[..3].copy_from_slice(&w[..3]);
        v[3] = Vec3A::NAN;
        let mut triangles: Vec<[u32; 3]> =
            (0..count as u32 - 2).map(|i| [i, (i * 7 + 1) % 40, (i * 13 + 2) % 40]).collect();
        // No area: a corner twice, and three corners in a line.
        triangles.extend([[5, 5, 9], [0, 1, 2], [0, 1, 3]]);
        let x = {
            let mut x = x;
            x[11] = x[10] * 2.0 - x[9];
            x
        };
        triangles.push([9, 10, 11]);
        let corners: Vec<[Vec3A; 2]> = (0..count).map(|i| [x[i], w[i] - v[i]]).collect();
        // Four lengths in a row: every remainder of four, after whole groups and alone.
        let n = triangles.len();
        for len in [n, n - 1, n - 2, n - 3, 3, 2, 1, 0] {
            let mut lanes = vec![Vec3A::splat(7.0); len];
            m.triangle_forces(&triangles[..len], &corners, |t, f| lanes[t] = f);
            for (t, (corners, got)) in triangles.iter().zip(&lanes).enumerate() {
                let [a, b, c] = corners.map(|k| k as usize);
                let one = m.triangle_force(
                    [x[a], x[b], x[c]].map(Vec3::from),
                    [v[a], v[b], v[c]].map(Vec3::from),
                    [w[a], w[b], w[c]].map(Vec3::from),
                );
                let got = Vec3::from(*got);
                assert!(
                    got.to_array().map(f32::to_bits) == one.to_array().map(f32::to_bits),
                    "triangle {t} of {len}: {got} in lanes, {one} alone"
                );
            }
        }
    }

    /// A tick's sampling, which hashes and blends each lattice corner once, gives every particle
    /// the bits of [`AirModel::wind_at`]: in eddies larger than the cloth, in eddies so small
    /// that the corners are hashed point by point, and with a point that is not finite among
    /// them.
    #[test]
    fn sampling_gives_the_bits_of_the_wind_at_each_point() {
        let mut seed = 5u32;
        let mut next = || {
            seed = hash(seed);
            unit(seed)
        };
        let mut x: Vec<Vec3A> = (0..3000).map(|_| Vec3A::new(next(), next() + 3.0, next()) * 1.5).collect();
        x[17] = Vec3A::new(f32::NAN, 0.0, 0.0);
        let sources = [WindSource::Blast { center: Vec3::ZERO, speed: 4.0, radius: 3.0 }.prepare()];
        for (scale, corners) in [(2.0, true), (0.3, true), (0.001, false)] {
            let wind = Wind { turbulence_scale: scale, ..Wind::gusty(Vec3::new(7.0, 0.0, 3.0)) };
            let model = AirModel::new(Aerodynamics::FABRIC, 0.3, &wind, 1234.5);
            let q = x.iter().map(|&p| p * model.inv_scale);
            let lattice = NoiseLattice::around(q, model.lattice_time, model.seed, x.len());
            assert_eq!(lattice.is_some(), corners, "eddies of {scale} m");
            let mut air = Air::default();
            air.sample(&model, &sources, &x);
            for (i, (&p, &got)) in x.iter().zip(&air.wind).enumerate() {
                let want = model.wind_at(p.into(), &sources);
                let same = Vec3::from(got).to_array().map(f32::to_bits) == want.to_array().map(f32::to_bits);
                assert!(
                    same || (got.is_nan() && want.is_nan()),
                    "eddies of {scale} m, particle {i}: {got} sampled, {want} at the point"
                );
            }
        }
    }

    #[test]
    fn a_triangle_moving_with_the_air_feels_nothing() {
        let wind = Wind::steady(Vec3::new(3.0, 1.0, -2.0));
        let m = model(Aerodynamics::FABRIC, &wind);
        assert_eq!(m.triangle_force(plate(), [wind.velocity; 3], [wind.velocity; 3]), Vec3::ZERO);
        // A degenerate triangle neither.
        let line = [Vec3::ZERO, Vec3::X, 2.0 * Vec3::X];
        assert_eq!(m.triangle_force(line, [Vec3::ZERO; 3], [wind.velocity; 3]), Vec3::ZERO);
    }

    /// A kick gives each particle the bits of its triangles' forces found one at a time and
    /// summed in the order of its list, on every path: a generated grid's rows of lanes (on one
    /// thread and on the pool, with rows and columns that leave partial groups of four), and
    /// the same grid as a general mesh, small enough for one thread (each force copied under
    /// its corners) and large enough for the pool (gathered per particle). A long substep caps
    /// some particles' kicks and not others', so that both sides of the cap are held too.
    #[test]
    fn kicks_sum_each_particles_triangles_in_the_order_of_its_list() {
        use crate::cloth::grid::ClothGrid;
        use glam::{UVec2, Vec2};
        let wind = Wind::gusty(Vec3::new(6.0, 1.0, -2.0));
        let m = model(Aerodynamics::FABRIC, &wind);
        let mut seed = 11u32;
        let mut next = || {
            seed = hash(seed);
            unit(seed)
        };
        let cases = [
            (UVec2::splat(24), 1.0 / 960.0, false),
            (UVec2::splat(100), 1.0 / 960.0, false),
            (UVec2::new(6, 9), 8.0, true),
            (UVec2::new(13, 5), 8.0, true),
            (UVec2::new(2, 2), 8.0, false),
        ];
        // Substeps this long cap some kicks, and not others.
        for (shape, h, both_sides_of_the_cap) in cases {
            let grid = ClothGrid::new(Vec2::splat(1.0), shape);
            for topology in [ClothTopology::grid(grid).unwrap(), ClothTopology::grid_as_mesh(grid).unwrap()] {
                let n = topology.len();
                let x: Vec<Vec3A> = topology
                    .rest_positions()
                    .iter()
                    .map(|&p| Vec3A::from(p) + 0.01 * Vec3A::new(next(), next(), next()))
                    .collect();
                let v0: Vec<Vec3A> = (0..n).map(|_| 3.0 * Vec3A::new(next(), next(), next())).collect();
                let free: Vec<f32> = (0..n).map(|i| if i % 7 == 0 { 0.0 } else { 1.0 }).collect();
                let mut air = Air::default();
                air.sample(&m, &[], &x);
                let mut v = v0.clone();
                air.kick(&m, &topology, &free, h, &x, &mut v);
                let corners = |t: [u32; 3], a: &[Vec3A]| t.map(|k| Vec3::from(a[k as usize]));
                let mut capped = [0; 2];
                for i in 0..n {
                    let mut f = Vec3::ZERO;
                    for &t in topology.triangles_of(i) {
                        let tri = topology.triangles()[t as usize];
                        f += m.triangle_force(corners(tri, &x), corners(tri, &v0), corners(tri, &air.wind));
                    }
                    let mut want = Vec3::from(v0[i]);
                    if free[i] != 0.0 {
                        let (dv, relative) = (f * (h * topology.inv_mass_share()[i]), Vec3::from(air.wind[i] - v0[i]));
                        capped[usize::from(dv.length_squared() > relative.length_squared())] += 1;
                        want += capped_kick(dv, relative);
                    }
                    assert_eq!(
                        Vec3::from(v[i]).to_array().map(f32::to_bits),
                        want.to_array().map(f32::to_bits),
                        "{shape} particles, grid path {}, particle {i}: {} kicked, {want} one at a time",
                        topology.stencil().is_some(),
                        v[i]
                    );
                }
                if both_sides_of_the_cap {
                    assert!(capped[0] > 0 && capped[1] > 0, "{shape} particles: {capped:?} kicks whole and capped");
                }
            }
        }
    }

    #[test]
    fn a_kick_never_takes_a_particle_past_the_wind() {
        let dv = capped_kick(Vec3::new(50.0, 0.0, 0.0), Vec3::new(2.0, 0.0, 0.0));
        assert!((dv - Vec3::new(2.0, 0.0, 0.0)).length() < 1e-6, "{dv}");
        assert_eq!(capped_kick(Vec3::new(0.5, 0.0, 0.0), Vec3::new(2.0, 0.0, 0.0)), Vec3::new(0.5, 0.0, 0.0));
    }

    #[test]
    fn noise_is_smooth_bounded_and_repeats_in_time() {
        let mut max = 0.0f32;
        let mut mean = Vec3::ZERO;
        let n = 4000;
        for i in 0..n {
            let q = Vec3::new(i as f32 * 0.173, i as f32 * 0.071 - 30.0, (i % 97) as f32 * 0.31);
            let t = i as f32 * 0.013;
            let v = value_noise_4d(q, t, 7);
            max = max.max(v.abs().max_element());
            mean += v;
            // A small step moves the value a little: the noise is continuous.
            let near = value_noise_4d(q + Vec3::splat(1e-3), t + 1e-3, 7);
            assert!((near - v).abs().max_element() < 0.02, "{q} {t}: {v} -> {near}");
        }
        assert!(max <= 1.0 && max > 0.5, "{max}");
        assert!((mean / n as f32).abs().max_element() < 0.1, "{mean}");
        // The lattice time repeats with no seam.
        let q = Vec3::new(0.3, 1.7, -2.2);
        let a = value_noise_4d(q, 0.25, 3);
        let b = value_noise_4d(q, NOISE_TIME_PERIOD as f32 + 0.25, 3);
        assert!((a - b).length() < 1e-3, "{a} vs {b}");
        assert!((value_noise_1d(0.5, 9) - value_noise_1d(NOISE_TIME_PERIOD as f32 + 0.5, 9)).abs() < 1e-3);
        // Another seed, another field.
        assert_ne!(value_noise_4d(q, 0.25, 4), a);
    }

    #[test]
    fn a_fan_blows_inside_its_cone_and_reach_only() {
        let fan = WindSource::Fan {
            origin: Vec3::ZERO,
            direction: Vec3::new(0.0, 0.0, 2.0),
            speed: 10.0,
            range: 5.0,
            spread: 0.5,
        }
        .prepare();
        let on_axis = fan.velocity_at(Vec3::new(0.0, 0.0, 1.0));
        assert!((on_axis - Vec3::new(0.0, 0.0, 8.0)).length() < 1e-5, "{on_axis}");
        assert_eq!(fan.velocity_at(Vec3::new(0.0, 0.0, 6.0)), Vec3::ZERO, "past its range");
        assert_eq!(fan.velocity_at(Vec3::new(1.0, 0.0, 1.0)), Vec3::ZERO, "outside its cone");
        assert_eq!(fan.velocity_at(Vec3::new(0.0, 0.0, -1.0)), Vec3::ZERO, "behind it");
        let blast = WindSource::Blast { center: Vec3::ONE, speed: 20.0, radius: 4.0 }.prepare();
        let v = blast.velocity_at(Vec3::new(1.0, 3.0, 1.0));
        assert!((v - Vec3::new(0.0, 10.0, 0.0)).length() < 1e-5, "{v}");
    }

    #[test]
    fn absurd_air_is_refused_naming_the_field() {
        let field = |e: ClothError| match e {
            ClothError::OutOfRange { field, .. }
            | ClothError::NotFinite { field }
            | ClothError::NotPositive { field, .. } => field,
            other => panic!("{other}"),
        };
        let wind = Wind::STILL;
        let cases = [
            (Wind { velocity: Vec3::new(f32::NAN, 0.0, 0.0), ..wind }, "wind.velocity"),
            (Wind { velocity: Vec3::new(400.0, 0.0, 0.0), ..wind }, "wind.velocity"),
            (Wind { density: -1.0, ..wind }, "wind.density"),
            (Wind { gust_strength: 2.0, ..wind }, "wind.gust_strength"),
            (Wind { gust_period: 0.0, ..wind }, "wind.gust_period"),
            (Wind { turbulence: f32::INFINITY, ..wind }, "wind.turbulence"),
            (Wind { turbulence_scale: f32::NAN, ..wind }, "wind.turbulence_scale"),
        ];
        for (wind, name) in cases {
            assert_eq!(field(wind.validate().unwrap_err()), name);
        }
        Wind::gusty(Vec3::new(8.0, 0.0, 0.0)).validate().unwrap();
        assert_eq!(field(Aerodynamics { drag: f32::NAN, lift: 0.0 }.validate().unwrap_err()), "aerodynamics.drag");
        assert_eq!(field(Aerodynamics { drag: 1.0, lift: 50.0 }.validate().unwrap_err()), "aerodynamics.lift");
        let fan = |speed, spread| WindSource::Fan { origin: Vec3::ZERO, direction: Vec3::X, speed, range: 1.0, spread };
        assert_eq!(field(fan(1e6, 0.5).validate().unwrap_err()), "fan.speed");
        assert_eq!(field(fan(5.0, 0.0).validate().unwrap_err()), "fan.spread");
        let zero_axis =
            WindSource::Fan { origin: Vec3::ZERO, direction: Vec3::ZERO, speed: 1.0, range: 1.0, spread: 1.0 };
        assert_eq!(field(zero_axis.validate().unwrap_err()), "fan.direction");
        let blast = WindSource::Blast { center: Vec3::ZERO, speed: 1.0, radius: -2.0 };
        assert_eq!(field(blast.validate().unwrap_err()), "blast.radius");
    }
}
