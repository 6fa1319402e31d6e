//! Collision response between a particle and a collider's spheres (paper section 2.4.4).
//!
//! A particle that ends a substep inside a sphere is moved to the first point where its path
//! (the segment from its previous position) meets the sphere, and only the tangential part of
//! its velocity is kept. The paper leaves some cases open; here is what happens in each:
//!
//! * **Previous position already inside** (the collider moved onto the particle, or the particle
//!   was left inside last time): there is no entry point, so the particle is pushed out along
//!   the sphere's normal through its current position.
//! * **Previous position on the surface** (within [`CONTACT_BAND`] of it: a particle resting or
//!   sliding in contact, which the last response put exactly there): handled like "inside".
//!   The segment's entry point would be the previous position itself, so a particle pressed
//!   against a sphere could never slide along it, while the tangential velocity it keeps would
//!   build up unseen and fling it off when the contact ends. Projecting the end point instead
//!   lets it slide, so its position and velocity agree.
//! * **Several overlapping spheres**: among the spheres that contain the particle, the one the
//!   segment enters first wins. The particle moves to that entry point, and the test repeats
//!   on the shortened segment (at most [`MAX_PASSES`] times), so when that entry point lies
//!   inside another sphere the particle stops where the path entered that one instead. A sphere
//!   the path crosses completely within one substep, without ending inside it, is not seen:
//!   at cloth speeds a substep moves a particle millimetres, so only spheres thinner than that
//!   could be tunnelled through.
//! * **Zero velocity / zero-length segment**: handled as "previous position inside": pushed out
//!   along the normal.
//! * **Exactly on the surface**: not inside (see [`crate::traversal::SURFACE_TOLERANCE`]), so
//!   untouched; a resting particle stays at rest.
//! * **At a sphere's centre**: the normal is undefined; the previous position's direction is
//!   used, then world up.
//!
//! The paper keeps the whole tangential velocity, so its cloth is frictionless and slides off
//! any rounded collider. A collider may add Coulomb friction with coefficient `mu`: each contact
//! takes `mu` times the normal speed it removes off the tangential speed, never past zero, so a
//! resting particle stays put on any slope below `atan(mu)`. With `mu = 0` the response is the
//! paper's.
//!
//! The test runs in the collider's local frame, so a moving collider needs no rebuild.

use glam::{Affine3A, Quat, Vec3};

use crate::collider::Collider;
use crate::lbvh::{Lbvh, Sphere};

/// Relative distance above a sphere's surface within which a previous position counts as in
/// contact (see the module docs). Far above f32 rounding of a projected point (about 1e-7),
/// far below a substep's travel at any speed worth resolving.
pub const CONTACT_BAND: f32 = 1.0e-4;

/// How many times one particle is resolved against one collider per substep.
pub const MAX_PASSES: usize = 4;

/// A collider's frame, prepared once per substep: the world-to-local transform and the margin
/// in local units.
#[derive(Clone, Copy, Debug)]
pub struct ColliderFrame<'a> {
    /// The collider's sphere tree.
    pub lbvh: &'a Lbvh,
    world_to_local: Affine3A,
    local_to_world: Affine3A,
    rotation: Quat,
    /// The margin divided by the collider's scale.
    pub margin_local: f32,
    /// The friction coefficient (0 when the collider's is negative or not finite).
    pub friction: f32,
}

impl<'a> ColliderFrame<'a> {
    /// Prepares `collider`; `None` when its pose is unusable or it has no sphere.
    pub fn new(collider: &'a Collider) -> Option<Self> {
        let pose = collider.pose;
        if !pose.is_valid() || collider.lbvh.spheres.is_empty() {
            return None;
        }
        let local_to_world = pose.to_affine();
        let usable = |v: f32| if v.is_finite() { v.max(0.0) } else { 0.0 };
        Some(Self {
            lbvh: &collider.lbvh,
            world_to_local: local_to_world.inverse(),
            local_to_world,
            rotation: pose.rotation.normalize(),
            margin_local: usable(collider.margin) / pose.scale,
            friction: usable(collider.friction),
        })
    }

    /// A world-space point in the collider's frame.
    #[inline]
    pub fn to_local(&self, p: Vec3) -> Vec3 {
        self.world_to_local.transform_point3(p)
    }

    /// Resolves one particle (world space): moves `position` out of the spheres and removes the
    /// normal part of `velocity`. Returns whether anything was touched.
    #[inline]
    pub fn resolve(&self, prev: Vec3, position: &mut Vec3, velocity: &mut Vec3) -> bool {
        let prev_local = self.to_local(prev);
        let mut p = self.to_local(*position);
        let mut hit = false;
        for _ in 0..MAX_PASSES {
            let Some((moved, normal)) = respond(self.lbvh, prev_local, p, self.margin_local) else {
                break;
            };
            p = moved;
            hit = true;
            *velocity = self.contact_velocity(*velocity, self.rotation * normal);
        }
        if hit {
            *position = self.local_to_world.transform_point3(p);
        }
        hit
    }
}

impl ColliderFrame<'_> {
    /// The velocity after a contact with outward normal `n`: the normal part removed, and the
    /// tangential part slowed by friction when the particle was moving into the surface.
    #[inline]
    fn contact_velocity(&self, velocity: Vec3, n: Vec3) -> Vec3 {
        let vn = velocity.dot(n);
        let tangential = velocity - vn * n;
        if vn >= 0.0 || self.friction == 0.0 {
            return tangential;
        }
        let speed = tangential.length();
        let slowdown = self.friction * -vn;
        if speed > slowdown { tangential * (1.0 - slowdown / speed) } else { Vec3::ZERO }
    }
}

/// The segment parameter `t` in `[0, 1]` where `prev + t (p - prev)` enters the sphere of radius
/// `r` around `c`, given that `prev` is outside and `p` inside.
fn entry_parameter(prev: Vec3, p: Vec3, c: Vec3, r: f32) -> f32 {
    let d = p - prev;
    let f = prev - c;
    let a = d.length_squared();
    let b = f.dot(d);
    let k = f.length_squared() - r * r;
    let disc = (b * b - a * k).max(0.0);
    ((-b - disc.sqrt()) / a).clamp(0.0, 1.0)
}

/// The outward unit normal of a sphere around `c` at `p`, with fallbacks at the centre.
fn outward_normal(p: Vec3, prev: Vec3, c: Vec3) -> Vec3 {
    (p - c).try_normalize().or_else(|| (prev - c).try_normalize()).unwrap_or(Vec3::Y)
}

/// One response pass in the collider's local frame: `None` when `p` is in no sphere, otherwise
/// the corrected position and the contact normal.
pub fn respond(lbvh: &Lbvh, prev: Vec3, p: Vec3, margin: f32) -> Option<(Vec3, Vec3)> {
    // Earliest entry along the segment among spheres `prev` is outside of...
    let mut entry: Option<(f32, Sphere)> = None;
    // ...and, failing that, the deepest penetration among spheres `prev` is inside of (or in
    // contact with).
    let mut deepest: Option<(f32, Sphere)> = None;
    let moving = p.distance_squared(prev) > 0.0;
    lbvh.for_each_containing(p, margin, |_, s| {
        let (c, r) = (s.centre(), s.radius + margin);
        let contact = r * (1.0 + CONTACT_BAND);
        if moving && prev.distance_squared(c) >= contact * contact {
            let t = entry_parameter(prev, p, c, r);
            if entry.is_none_or(|(best, _)| t < best) {
                entry = Some((t, *s));
            }
        } else {
            let depth = r - p.distance(c);
            if deepest.is_none_or(|(best, _)| depth > best) {
                deepest = Some((depth, *s));
            }
        }
    });
    let (target, s) = match (entry, deepest) {
        (Some((t, s)), _) => (prev.lerp(p, t), s),
        (None, Some((_, s))) => (p, s),
        (None, None) => return None,
    };
    let c = s.centre();
    let normal = outward_normal(target, prev, c);
    // Re-project onto the surface so rounding never leaves the point inside.
    Some((c + normal * (s.radius + margin), normal))
}
