//! Exact convex primitives: sphere, capsule, box and a half-space ground.
//!
//! A primitive is tested by its exact distance function, not by voxel spheres, so a cloth rests
//! on its true surface and a query costs a few arithmetic operations instead of a tree walk.
//! Each shape is given in its collider's local frame (see [`crate::ColliderPose`]); the margin
//! grows it like it grows the spheres of a mesh collider.
//!
//! # The response
//!
//! It follows the sphere response of [`crate::colliders::collision`], made exact by convexity. For a particle
//! going from `prev` to `p`:
//!
//! 1. **Inside.** When `prev` is inside the grown shape, `p` is pushed out along the normal of
//!    its closest surface point, onto the surface: one push suffices for a convex shape.
//! 2. **Separating plane.** The plane tangent to the grown shape at the point closest to `prev`
//!    bounds the whole shape (it is convex). When `p` lies on `prev`'s side of it, the whole
//!    path does, and nothing is touched.
//! 3. **Contact.** When `prev` is within the contact band of the surface (or the shape is the
//!    half-space, whose tangent plane is its surface), `p` is moved back onto that plane: the
//!    particle slides along the surface, and its whole path stays outside.
//! 4. **Sweep.** Otherwise the path's first entry into the grown shape is found by bisection on
//!    the distance along the path (convex in the path parameter, so its minimum is found first
//!    when the end point is outside), and the particle stops there, on the surface.
//!
//! Every contact removes the normal part of the velocity, with the collider's friction, as for
//! sphere colliders. The guarantee of [`crate::colliders::collision`] holds here too: a particle that starts
//! outside a still primitive ends outside it, and so does its path.

use glam::Vec3;

use crate::bvh::traversal::SURFACE_TOLERANCE;
use crate::colliders::error::ColliderError;
pub use crate::colliders::primitive_shape::Primitive;
use crate::colliders::response::{CONTACT_BAND, Response};

/// Bisection steps of the sweep: the entry is found to `2^-24` of the path length.
pub const SWEEP_STEPS: u32 = 24;

/// Golden-section steps that find where a path that ends outside comes closest to the shape.
pub const CLOSEST_STEPS: u32 = 24;

impl Primitive {
    /// Its number in `GpuCollider::shape` (the GPU crate's `layout`).
    pub fn kind(&self) -> u32 {
        match self {
            Self::Sphere { .. } => 1,
            Self::Capsule { .. } => 2,
            Self::Cuboid { .. } => 3,
            Self::HalfSpace { .. } => 4,
        }
    }

    /// The shape's sizes as the kernels read them (`GpuCollider::size`): the radius, then the
    /// half length, or the half extents, or the normal.
    pub fn size(&self) -> [f32; 4] {
        match *self {
            Self::Sphere { radius } => [radius, 0.0, 0.0, 0.0],
            Self::Capsule { radius, half_length } => [radius, half_length, 0.0, 0.0],
            Self::Cuboid { half_extents } => half_extents.extend(0.0).to_array(),
            Self::HalfSpace { normal } => normal.extend(0.0).to_array(),
        }
    }

    /// Checks the sizes and returns the shape ready for use: finite, positive radii and
    /// extents, a non-negative half length, and a finite non-zero normal (normalised).
    pub fn validate(self) -> Result<Self, ColliderError> {
        let positive = |value: f32| value.is_finite() && value > 0.0;
        let ok = match self {
            Self::Sphere { radius } => positive(radius),
            Self::Capsule { radius, half_length } => positive(radius) && half_length.is_finite() && half_length >= 0.0,
            Self::Cuboid { half_extents } => half_extents.to_array().into_iter().all(positive),
            Self::HalfSpace { normal } => {
                return normal
                    .try_normalize()
                    .map(|normal| Self::HalfSpace { normal })
                    .ok_or(ColliderError::BadPrimitive(self));
            }
        };
        if ok { Ok(self) } else { Err(ColliderError::BadPrimitive(self)) }
    }

    /// The thinnest half-size of the shape: the radius, or the smallest half extent; infinite
    /// for the half-space. Tolerances and the contact band scale with it.
    pub fn thickness(&self) -> f32 {
        match *self {
            Self::Sphere { radius } | Self::Capsule { radius, .. } => radius,
            Self::Cuboid { half_extents } => half_extents.min_element(),
            Self::HalfSpace { .. } => f32::INFINITY,
        }
    }

    /// The signed distance from `p` to the surface (negative inside) and the outward unit normal
    /// of the surface point closest to `p`.
    pub fn distance(&self, p: Vec3) -> (f32, Vec3) {
        match *self {
            Self::Sphere { radius } => round_distance(p, radius),
            Self::Capsule { radius, half_length } => {
                let axis = Vec3::new(0.0, p.y.clamp(-half_length, half_length), 0.0);
                round_distance(p - axis, radius)
            }
            Self::Cuboid { half_extents } => box_distance(p, half_extents),
            Self::HalfSpace { normal } => (p.dot(normal), normal),
        }
    }

    /// Whether `p` is inside the shape grown by `margin`, allowing [`SURFACE_TOLERANCE`] of the
    /// thickness for rounding, as the sphere tree's traversal does for spheres.
    pub fn contains(&self, p: Vec3, margin: f32) -> bool {
        self.distance(p).0 < margin - self.tolerance(margin)
    }

    /// The rounding allowance of [`Self::contains`].
    fn tolerance(&self, margin: f32) -> f32 {
        let thickness = self.thickness();
        SURFACE_TOLERANCE * if thickness.is_finite() { thickness + margin } else { margin }
    }

    /// The response of the module docs, in the collider's local frame, with the shape grown by
    /// `margin`. `touch(normal)` is called with the outward normal of each contact.
    pub fn respond(&self, prev: Vec3, p: Vec3, margin: f32, mut touch: impl FnMut(Vec3)) -> Response {
        let (d_prev, n_prev) = self.distance(prev);
        // 1. Inside: onto the surface along the end point's own normal.
        if d_prev < margin - self.tolerance(margin) {
            let (d, n) = self.distance(p);
            if d >= margin {
                return Response::Free;
            }
            touch(n);
            return Response::Moved(p + (margin - d) * n);
        }
        // 2. The separating plane at `prev`.
        let surface = prev - (d_prev - margin) * n_prev;
        let below = (p - surface).dot(n_prev);
        if below >= 0.0 {
            return Response::Free;
        }
        // 3. Contact: held on the plane.
        let band = CONTACT_BAND * (self.thickness() + margin);
        if d_prev - margin <= band {
            touch(n_prev);
            return Response::Moved(p - below * n_prev);
        }
        // 4. Sweep.
        let gap = |t: f32| self.distance(prev.lerp(p, t)).0 - margin;
        let mut hi = 1.0;
        if gap(1.0) > 0.0 {
            let t = closest_parameter(gap);
            if gap(t) > 0.0 {
                return Response::Free;
            }
            hi = t;
        }
        let mut lo = 0.0;
        for _ in 0..SWEEP_STEPS {
            let mid = 0.5 * (lo + hi);
            if gap(mid) > 0.0 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let entry = prev.lerp(p, lo);
        let (d, n) = self.distance(entry);
        touch(n);
        Response::Moved(entry + (margin - d) * n)
    }
}

/// Where a convex function on `[0, 1]` is smallest, by golden-section search.
fn closest_parameter(f: impl Fn(f32) -> f32) -> f32 {
    const INV_PHI: f32 = 0.618_034;
    let (mut a, mut b) = (0.0f32, 1.0f32);
    let mut c = b - INV_PHI * (b - a);
    let mut d = a + INV_PHI * (b - a);
    let (mut fc, mut fd) = (f(c), f(d));
    for _ in 0..CLOSEST_STEPS {
        if fc < fd {
            b = d;
            d = c;
            fd = fc;
            c = b - INV_PHI * (b - a);
            fc = f(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + INV_PHI * (b - a);
            fd = f(d);
        }
    }
    if fc < fd { c } else { d }
}

/// Distance and normal for the points within `radius` of the origin, from `offset` (the point
/// relative to the closest point of the core: the centre or the axis).
fn round_distance(offset: Vec3, radius: f32) -> (f32, Vec3) {
    let length = offset.length();
    let normal = if length > 0.0 { offset / length } else { Vec3::Y };
    (length - radius, normal)
}

/// Signed distance and normal of an axis-aligned box with half extents `h`. Inside, the normal
/// is that of the nearest face.
fn box_distance(p: Vec3, h: Vec3) -> (f32, Vec3) {
    let q = p.abs() - h;
    if q.max_element() > 0.0 {
        let outside = q.max(Vec3::ZERO);
        let length = outside.length();
        return (length, (outside / length) * p.signum());
    }
    let axis = if q.x >= q.y && q.x >= q.z {
        Vec3::X
    } else if q.y >= q.z {
        Vec3::Y
    } else {
        Vec3::Z
    };
    (q.max_element(), axis * p.signum())
}

#[cfg(test)]
mod tests {
    use super::*;

    const SHAPES: [Primitive; 4] = [
        Primitive::Sphere { radius: 0.5 },
        Primitive::Capsule { radius: 0.25, half_length: 0.5 },
        Primitive::Cuboid { half_extents: Vec3::new(0.5, 0.25, 0.75) },
        Primitive::HalfSpace { normal: Vec3::Y },
    ];

    #[test]
    fn distances_are_exact_on_each_shape() {
        let cases = [
            (SHAPES[0], Vec3::new(0.0, 2.0, 0.0), 1.5, Vec3::Y),
            (SHAPES[1], Vec3::new(1.0, 0.3, 0.0), 0.75, Vec3::X),
            (SHAPES[1], Vec3::new(0.0, -1.0, 0.0), 0.25, Vec3::NEG_Y),
            (SHAPES[2], Vec3::new(0.0, 0.0, 1.0), 0.25, Vec3::Z),
            (SHAPES[2], Vec3::new(0.0, 0.2, 0.0), -0.05, Vec3::Y),
            (SHAPES[2], Vec3::new(1.5, 1.25, 0.0), 2.0f32.sqrt(), Vec3::new(1.0, 1.0, 0.0).normalize()),
            (SHAPES[3], Vec3::new(3.0, -0.5, 7.0), -0.5, Vec3::Y),
        ];
        for (shape, p, distance, normal) in cases {
            let (d, n) = shape.distance(p);
            assert!((d - distance).abs() < 1e-6, "{shape:?} at {p}: {d}, expected {distance}");
            assert!(n.distance(normal) < 1e-6, "{shape:?} at {p}: normal {n}, expected {normal}");
        }
    }

    #[test]
    fn bad_sizes_are_refused_and_normals_normalised() {
        for bad in [
            Primitive::Sphere { radius: 0.0 },
            Primitive::Sphere { radius: f32::NAN },
            Primitive::Capsule { radius: 0.1, half_length: -1.0 },
            Primitive::Cuboid { half_extents: Vec3::new(1.0, -1.0, 1.0) },
            Primitive::HalfSpace { normal: Vec3::ZERO },
        ] {
            assert!(matches!(bad.validate(), Err(ColliderError::BadPrimitive(_))), "{bad:?} is refused");
        }
        let ground = Primitive::HalfSpace { normal: Vec3::new(0.0, 2.0, 0.0) }.validate();
        assert_eq!(ground, Ok(Primitive::HalfSpace { normal: Vec3::Y }));
    }

    /// A deterministic cloud of paths around the shapes: every path that starts outside ends
    /// outside, and so does every point along it.
    #[test]
    fn paths_that_start_outside_stay_outside() {
        let mut seed = 0x2545_f491_u32;
        let mut random = move || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed as f32 / u32::MAX as f32 * 2.0 - 1.0
        };
        let margin = 0.02;
        let mut entering = 0;
        for shape in SHAPES {
            for _ in 0..4000 {
                let prev = Vec3::new(random(), random(), random()) * 1.2;
                let p = prev + Vec3::new(random(), random(), random()) * 0.6;
                if shape.contains(prev, margin) {
                    continue;
                }
                let enters = (1..=64).any(|k| shape.contains(prev.lerp(p, k as f32 / 64.0), margin));
                entering += usize::from(enters);
                let mut touches = 0;
                let end = match shape.respond(prev, p, margin, |_| touches += 1) {
                    Response::Free => {
                        assert!(!enters, "{shape:?}: {prev} -> {p} enters the shape but is left free");
                        p
                    }
                    Response::Moved(end) => end,
                    Response::Stay => prev,
                };
                assert!(!shape.contains(end, margin), "{shape:?}: {prev} -> {p} ends inside at {end}");
                for k in 1..64 {
                    let point = prev.lerp(end, k as f32 / 64.0);
                    assert!(!shape.contains(point, margin), "{shape:?}: {prev} -> {end} passes {point}");
                }
                if shape.distance(p).0 < margin {
                    assert!(touches > 0, "{shape:?}: {prev} -> {p} ends inside but touched nothing");
                }
            }
        }
        assert!(entering > 500, "the cloud must reach the shapes: {entering} paths enter them");
    }

    #[test]
    fn a_particle_inside_is_pushed_onto_the_surface() {
        let shape = SHAPES[2];
        let inside = Vec3::new(0.1, 0.2, 0.0);
        let Response::Moved(out) = shape.respond(inside, inside, 0.0, |n| assert_eq!(n, Vec3::Y)) else {
            panic!("a particle inside the box must move")
        };
        assert!((out - Vec3::new(0.1, 0.25, 0.0)).length() < 1e-6, "{out}");
    }

    #[test]
    fn a_tunnelling_path_stops_at_the_entry() {
        // From well above a thin box to well below it: the end point is outside, the path is not.
        let shape = Primitive::Cuboid { half_extents: Vec3::new(1.0, 0.01, 1.0) };
        let mut normals = Vec::new();
        let response = shape.respond(Vec3::new(0.0, 0.5, 0.0), Vec3::new(0.0, -0.5, 0.0), 0.0, |n| normals.push(n));
        let Response::Moved(entry) = response else { panic!("the path crosses the box: {response:?}") };
        assert!((entry.y - 0.01).abs() < 1e-5, "stops on the top face: {entry}");
        assert_eq!(normals, [Vec3::Y]);
    }
}
