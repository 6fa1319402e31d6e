//! The force model: drag and lift on a triangle from its velocity relative to the air, one
//! triangle at a time and four at once, one per SIMD lane, with the same bits.

use glam::{BVec4A, Mat4, Vec3, Vec3A, Vec4};

use super::noise::value_noise_4d;
use super::settings::{Aerodynamics, Wind};
use super::source::AirSource;

/// One tick's air for one cloth: the wind's constants and clock, and the cloth's drag and lift
/// per unit of `A |u|²`, over three times its mass.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AirModel {
    /// The mean wind times the gust factor of this tick.
    pub ambient: Vec3,
    /// Turbulence in m/s.
    pub turbulence: f32,
    /// One over the eddy size, 1/m.
    pub inv_scale: f32,
    /// The turbulence's lattice time this tick, in `[0, NOISE_TIME_PERIOD)`.
    pub lattice_time: f32,
    /// The noise's seed.
    pub seed: u32,
    /// `½ ρ C_d / (3 m)`: a corner's share of drag per unit of `A |u|² |cos θ|`, over the
    /// cloth's mass (a particle's acceleration is this times its inverse mass share).
    pub drag: f32,
    /// `½ ρ C_l / (3 m)`, as `drag`.
    pub lift: f32,
}

impl AirModel {
    /// The air of a cloth of `mass` kg with `aerodynamics`, in `wind`, for the tick that starts
    /// at `time` seconds.
    pub fn new(aerodynamics: Aerodynamics, mass: f32, wind: &Wind, time: f64) -> Self {
        let [gust, lattice_time] = wind.clock(time);
        let per_corner = 0.5 * wind.density / (3.0 * mass);
        Self {
            ambient: wind.velocity * gust,
            turbulence: wind.turbulence,
            inv_scale: 1.0 / wind.turbulence_scale,
            lattice_time,
            seed: wind.seed,
            drag: per_corner * aerodynamics.drag,
            lift: per_corner * aerodynamics.lift,
        }
    }

    /// The wind at `p`: the ambient wind, the turbulence and every source. The GPU's
    /// `air_sample` repeats this arithmetic.
    pub fn wind_at(&self, p: Vec3, sources: &[AirSource]) -> Vec3 {
        self.wind_with(p, sources, |q| value_noise_4d(q, self.lattice_time, self.seed))
    }

    /// [`Self::wind_at`] with the turbulence's noise at `q` (lattice units) from `noise`.
    #[inline]
    pub(super) fn wind_with(&self, p: Vec3, sources: &[AirSource], noise: impl Fn(Vec3) -> Vec3) -> Vec3 {
        let mut w = self.ambient;
        if self.turbulence > 0.0 {
            w += self.turbulence * noise(p * self.inv_scale);
        }
        for source in sources {
            w += source.velocity_at(p);
        }
        w
    }

    /// The aerodynamic force on one triangle (corners `x`, velocities `v`, winds `w`), per
    /// corner and over the cloth's mass: a corner's acceleration is the sum over its triangles
    /// times its inverse mass share. The relative flow is the mean of the corners' relative
    /// velocities, `((w₀ - v₀) + (w₁ - v₁) + (w₂ - v₂)) / 3`. The GPU's `triangle_air` repeats
    /// this arithmetic.
    #[inline]
    pub fn triangle_force(&self, x: [Vec3; 3], v: [Vec3; 3], w: [Vec3; 3]) -> Vec3 {
        let relative = [0, 1, 2].map(|k| Vec3A::from(w[k]) - Vec3A::from(v[k]));
        self.triangle_force_simd(x.map(Vec3A::from), mean_flow(relative)).into()
    }

    /// [`Self::triangle_force`] on SIMD vectors, from the corners and the relative flow `u`.
    ///
    /// With the cross product `m = 2 A n` and `d = m · u` (so `cos θ = d / (|m| |u|)`), the drag
    /// `½ ρ C_d A |u|² |cos θ| û` is `½ ρ C_d |d| u / 2` and the lift
    /// `½ ρ C_l A |u|² cos θ (n - cos θ û)` is `½ ρ C_l d (|u| / |m|) (m - (d / |u|²) u) / 2`:
    /// one square root and two divisions, the factor `½ ρ C / (3 m)` being in `drag` and `lift`.
    #[inline]
    fn triangle_force_simd(&self, x: [Vec3A; 3], u: Vec3A) -> Vec3A {
        let m = (x[1] - x[0]).cross(x[2] - x[0]);
        let m2 = m.dot(m);
        let u2 = u.dot(u);
        if !(m2 > 0.0 && u2 > 0.0) {
            return Vec3A::ZERO;
        }
        let d = m.dot(u);
        let drag = (0.5 * self.drag * d.abs()) * u;
        let lift = (0.5 * self.lift * d * (u2 / m2).sqrt()) * (m - u * (d / u2));
        drag + lift
    }

    /// The arithmetic of [`Self::triangle_force_simd`] on four triangles, one per lane, by
    /// coordinate: edges `[ax, ay, az]` and `b` from each triangle's first corner, and the flow
    /// `u`. Lane by lane it runs the same operations in the same order, so each lane gives the
    /// bits of its triangle alone. A lane not `valid` gives no force.
    #[inline]
    pub(super) fn lane_forces(
        &self,
        [ax, ay, az]: [Vec4; 3],
        [bx, by, bz]: [Vec4; 3],
        u: [Vec4; 3],
        valid: BVec4A,
    ) -> [Vec4; 3] {
        // The cross product, coordinate by coordinate as `Vec3A::cross` forms it.
        let m = [ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx];
        let dot = |p: [Vec4; 3], q: [Vec4; 3]| (p[0] * q[0] + p[1] * q[1]) + p[2] * q[2];
        let (m2, u2, d) = (dot(m, m), dot(u, u), dot(m, u));
        let live = m2.cmpgt(Vec4::ZERO) & u2.cmpgt(Vec4::ZERO) & valid;
        let drag = Vec4::splat(0.5 * self.drag) * d.abs();
        let lift = Vec4::splat(0.5 * self.lift) * d * (u2 / m2).sqrt();
        let along = d / u2;
        let force = |k: usize| Vec4::select(live, drag * u[k] + lift * (m[k] - u[k] * along), Vec4::ZERO);
        [force(0), force(1), force(2)]
    }

    /// [`Self::triangle_force`] for every triangle of `triangles`, bit for bit: `each(k, force)`
    /// for triangle `k` of the slice, in order. Its corners index `corners`, each particle's
    /// position and its wind less its velocity, side by side so that a corner is one read.
    ///
    /// Four triangles at a time, one per SIMD lane: their edges and flows are transposed so
    /// that each vector holds one coordinate of the four, and the arithmetic of
    /// `triangle_force_simd` runs lane-wise, its square root and divisions shared. The
    /// operations and their order are the same, so the lanes give the same bits.
    #[inline]
    pub fn triangle_forces(&self, triangles: &[[u32; 3]], corners: &[[Vec3A; 2]], mut each: impl FnMut(usize, Vec3A)) {
        let mut groups = triangles.chunks_exact(4);
        let mut first = 0;
        for group in &mut groups {
            let mut e1 = [Vec4::ZERO; 4];
            let mut e2 = [Vec4::ZERO; 4];
            let mut flow = [Vec4::ZERO; 4];
            for (lane, t) in group.iter().enumerate() {
                let [[xa, ua], [xb, ub], [xc, uc]] = t.map(|k| corners[k as usize]);
                e1[lane] = wide(xb - xa);
                e2[lane] = wide(xc - xa);
                flow[lane] = wide(mean_flow([ua, ub, uc]));
            }
            // Row k of a transposed matrix is coordinate k of the four triangles.
            let lanes = |v: [Vec4; 4]| {
                let t = Mat4::from_cols(v[0], v[1], v[2], v[3]).transpose();
                [t.x_axis, t.y_axis, t.z_axis]
            };
            let [fx, fy, fz] = self.lane_forces(lanes(e1), lanes(e2), lanes(flow), BVec4A::splat(true));
            let f = Mat4::from_cols(fx, fy, fz, Vec4::ZERO).transpose();
            each(first, Vec3A::from_vec4(f.x_axis));
            each(first + 1, Vec3A::from_vec4(f.y_axis));
            each(first + 2, Vec3A::from_vec4(f.z_axis));
            each(first + 3, Vec3A::from_vec4(f.w_axis));
            first += 4;
        }
        for (k, t) in groups.remainder().iter().enumerate() {
            let [[xa, ua], [xb, ub], [xc, uc]] = t.map(|k| corners[k as usize]);
            each(first + k, self.triangle_force_simd([xa, xb, xc], mean_flow([ua, ub, uc])));
        }
    }
}

/// `v` as a four-vector, for a lane-wise transpose (its fourth coordinate is not read).
#[inline]
pub(super) fn wide(v: Vec3A) -> Vec4 {
    v.extend(0.0)
}

/// The relative flow over a triangle: the mean of its corners' relative velocities.
#[inline]
pub(super) fn mean_flow([a, b, c]: [Vec3A; 3]) -> Vec3A {
    ((a + b) + c) * (1.0 / 3.0)
}

/// [`mean_flow`] of four triangles, one per lane, by coordinate.
#[inline]
pub(super) fn mean_flow_lanes(a: [Vec4; 3], b: [Vec4; 3], c: [Vec4; 3]) -> [Vec4; 3] {
    let third = Vec4::splat(1.0 / 3.0);
    [((a[0] + b[0]) + c[0]) * third, ((a[1] + b[1]) + c[1]) * third, ((a[2] + b[2]) + c[2]) * third]
}
