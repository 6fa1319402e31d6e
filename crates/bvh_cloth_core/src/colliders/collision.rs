//! Collision response between a particle and a collider's spheres (paper section 2.4.4); the
//! exact primitives answer in [`crate::colliders::primitives`], with the same guarantee.
//!
//! The paper moves a particle that ends a substep inside a sphere back to where its path entered
//! the sphere and keeps only the tangential part of its velocity. Its spheres only cover the
//! surface: at high `n` they form a thin shell around a hollow inside. So the response here
//! looks at the whole path, not only its end, and works in three steps (in the collider's local
//! frame, so a moving collider needs no rebuild):
//!
//! 1. **Contacts.** Every sphere whose surface the previous position touches (within
//!    [`CONTACT_BAND`] of its radius) holds the particle on its outer side: the end point is
//!    moved back onto the plane tangent to the sphere below the previous position, when it went
//!    past it. A tangent plane meets its sphere in one point, so a particle pressed against a
//!    sphere slides along it, and its whole path stays outside. Each contact that held the end
//!    point takes the normal part, along the normal at the previous position, off the velocity.
//! 2. **Sweep.** The path from the previous position to the (held) end point is tested against
//!    every sphere near it, the ones it passes straight through included. If it enters one, the
//!    particle stops where it enters the first, on that sphere's surface, and that contact
//!    takes the normal part off the velocity.
//! 3. **Guard.** If rounding leaves that entry point inside a sphere, the particle stays at its
//!    previous position.
//!
//! # The guarantee
//!
//! For a collider that does not move during the substep and a particle that starts the substep
//! outside every sphere, the particle ends the substep outside every sphere, and the straight
//! path between its two positions passes through no sphere. It cannot cross the shell: a cloth
//! that starts outside a collider stays outside, at any `n`, however thin the spheres.
//! "Outside" is `sphere_contains`'s test, which allows
//! [`SURFACE_TOLERANCE`](crate::bvh::traversal::SURFACE_TOLERANCE) of the radius for rounding.
//!
//! A particle that starts the substep inside a sphere (the collider moved onto it, or it was
//! placed there) has no outside path to keep to. It is pushed out along the normal of the sphere
//! it is deepest in, at most [`MAX_PASSES`] times: the paper's response to a penetration.
//!
//! # Friction
//!
//! The paper keeps the whole tangential velocity, so its cloth is frictionless and slides off
//! any rounded collider. A collider may add Coulomb friction with coefficient `mu`: each contact
//! takes `mu` times the normal speed it removes off the tangential speed, never past zero, so a
//! resting particle stays put on any slope below `atan(mu)`. With `mu = 0` the response is the
//! paper's.

use glam::{Affine3A, Quat, Vec3};

use crate::bvh::lbvh::{Lbvh, Sphere};
use crate::bvh::traversal::sphere_contains;
use crate::colliders::collider::{Collider, ColliderShape};
use crate::colliders::exact_contact::TriangleSurface;
use crate::colliders::layers::CollisionLayers;
use crate::colliders::primitives::Primitive;

pub use crate::colliders::response::{CONTACT_BAND, MAX_PASSES, Response};

/// What a [`ColliderFrame`] tests against.
#[derive(Clone, Copy, Debug)]
pub enum FrameShape<'a> {
    /// A mesh collider's sphere tree.
    Spheres(&'a Lbvh),
    /// A mesh collider's own triangles (exact contact, see [`crate::colliders::exact_contact`]).
    Triangles(&'a TriangleSurface),
    /// An exact primitive (see [`crate::colliders::primitives`]).
    Primitive(Primitive),
}

/// A collider's frame, prepared once per substep: the world-to-local transform and the margin
/// in local units.
#[derive(Clone, Copy, Debug)]
pub struct ColliderFrame<'a> {
    /// The collider's shape.
    pub shape: FrameShape<'a>,
    world_to_local: Affine3A,
    local_to_world: Affine3A,
    rotation: Quat,
    /// The margin divided by the collider's scale; for exact contact at least the surface's
    /// [least thickness](TriangleSurface::least_thickness) at the pose.
    pub margin_local: f32,
    /// The friction coefficient (0 when the collider's is negative or not finite).
    pub friction: f32,
    /// How far beyond a node's box (grown by the margin) a contact can be: the contact band of
    /// the largest sphere (0 for a primitive).
    pub contact_reach: f32,
    /// The collider's collision layers: the cloths it meets.
    pub layers: CollisionLayers,
}

impl<'a> ColliderFrame<'a> {
    /// Prepares `collider`; `None` when its pose is unusable or it has no sphere.
    pub fn new(collider: &'a Collider) -> Option<Self> {
        let pose = collider.pose;
        if !pose.is_valid() {
            return None;
        }
        let local_to_world = pose.to_affine();
        let usable = |v: f32| if v.is_finite() { v.max(0.0) } else { 0.0 };
        let mut margin_local = usable(collider.margin) / pose.scale;
        let (shape, contact_reach) = match &collider.shape {
            ColliderShape::Spheres { lbvh, .. } if lbvh.spheres.is_empty() => return None,
            ColliderShape::Spheres { surface: Some(surface), .. } => {
                margin_local = margin_local.max(surface.least_thickness(&pose));
                (FrameShape::Triangles(surface), 0.0)
            }
            ColliderShape::Spheres { lbvh, .. } => {
                (FrameShape::Spheres(lbvh), contact_reach(lbvh.max_radius, margin_local))
            }
            ColliderShape::Primitive(primitive) => (FrameShape::Primitive(*primitive), 0.0),
        };
        Some(Self {
            shape,
            world_to_local: local_to_world.inverse(),
            local_to_world,
            rotation: pose.rotation.normalize(),
            margin_local,
            friction: usable(collider.friction),
            contact_reach,
            layers: collider.layers,
        })
    }

    /// A world-space point in the collider's frame.
    #[inline]
    pub fn to_local(&self, p: Vec3) -> Vec3 {
        self.world_to_local.transform_point3(p)
    }

    /// Whether the world-space point `p` is inside the shape grown by the margin (for exact
    /// contact: closer to a triangle than the margin, less the contact band).
    pub fn contains(&self, p: Vec3) -> bool {
        let local = self.to_local(p);
        match self.shape {
            FrameShape::Spheres(lbvh) => lbvh.any_containing(local, self.margin_local),
            // The response holds a particle at the margin, and lets it rest within the contact
            // band below it where a neighbouring triangle's plane put it (see
            // `exact_contact`): closer than that is inside.
            FrameShape::Triangles(surface) => surface.within(local, self.margin_local * (1.0 - CONTACT_BAND)),
            FrameShape::Primitive(primitive) => primitive.contains(local, self.margin_local),
        }
    }

    /// Resolves one particle (world space): moves `position` out of the shape and removes the
    /// normal part of `velocity` at each contact. `prev` is where the particle started the
    /// substep. Returns whether anything was touched.
    #[inline]
    pub fn resolve(&self, prev: Vec3, position: &mut Vec3, velocity: &mut Vec3) -> bool {
        let prev_local = self.to_local(prev);
        let p = self.to_local(*position);
        let touch = |normal: Vec3| {
            *velocity = self.contact_velocity(*velocity, self.rotation * normal);
        };
        let response = match self.shape {
            FrameShape::Spheres(lbvh) => respond(lbvh, prev_local, p, self.margin_local, self.contact_reach, touch),
            FrameShape::Triangles(surface) => surface.respond(prev_local, p, self.margin_local, touch),
            FrameShape::Primitive(primitive) => primitive.respond(prev_local, p, self.margin_local, touch),
        };
        match response {
            Response::Free => return false,
            Response::Moved(local) => *position = self.local_to_world.transform_point3(local),
            Response::Stay => *position = prev,
        }
        true
    }
}

impl Collider {
    /// Whether the world-space point `p` lies inside the shape grown by the margin.
    pub fn contains(&self, p: Vec3) -> bool {
        ColliderFrame::new(self).is_some_and(|frame| frame.contains(p))
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

/// How far beyond a node's box (grown by `margin`) a sphere's contact band can reach, for a
/// tree whose largest radius is `max_radius`.
pub fn contact_reach(max_radius: f32, margin: f32) -> f32 {
    CONTACT_BAND * (max_radius + margin)
}

/// The segment parameter `t` in `[0, 1]` where `prev + t (p - prev)` first meets the sphere of
/// radius `r` around `c` (0 when `prev` is already inside it).
fn entry_parameter(prev: Vec3, p: Vec3, c: Vec3, r: f32) -> f32 {
    let d = p - prev;
    let f = prev - c;
    let a = d.length_squared();
    let b = f.dot(d);
    let k = f.length_squared() - r * r;
    let disc = (b * b - a * k).max(0.0);
    ((-b - disc.sqrt()) / a).clamp(0.0, 1.0)
}

/// Whether the segment from `prev` (outside the sphere) to `p` enters `sphere` grown by
/// `margin`, with [`sphere_contains`]'s tolerance: its end point is inside, or its closest
/// point to the centre is.
fn segment_enters(sphere: &Sphere, prev: Vec3, p: Vec3, margin: f32) -> bool {
    if sphere_contains(sphere, p, margin) {
        return true;
    }
    let c = sphere.centre();
    let d = p - prev;
    let a = d.length_squared();
    if a == 0.0 {
        return false;
    }
    let t = ((c - prev).dot(d) / a).clamp(0.0, 1.0);
    sphere_contains(sphere, prev + t * d, margin)
}

/// The outward unit normal of a sphere around `c` at `p`, with fallbacks at the centre.
fn outward_normal(p: Vec3, prev: Vec3, c: Vec3) -> Vec3 {
    (p - c).try_normalize().or_else(|| (prev - c).try_normalize()).unwrap_or(Vec3::Y)
}

/// The response of the module docs for a particle going from `prev` to `p` (the collider's
/// local frame). `touch(normal)` is called for each contact, in order, with the outward normal.
pub fn respond(
    lbvh: &Lbvh,
    prev: Vec3,
    p: Vec3,
    margin: f32,
    contact_reach: f32,
    mut touch: impl FnMut(Vec3),
) -> Response {
    // 1. Contacts: the spheres whose surface `prev` touches hold the end point on their side.
    let mut target = p;
    let mut touched = false;
    let mut inside = false;
    let reach = Vec3::splat(contact_reach);
    lbvh.for_each_overlapping(prev - reach, prev + reach, margin, |_, s| {
        let (c, r) = (s.centre(), s.radius + margin);
        let band = r * (1.0 + CONTACT_BAND);
        if prev.distance_squared(c) >= band * band {
            return;
        }
        if sphere_contains(s, prev, margin) {
            inside = true;
            return;
        }
        let n = outward_normal(prev, prev, c);
        let below = (target - (c + n * r)).dot(n);
        if below < 0.0 {
            target -= below * n;
            touched = true;
            touch(n);
        }
    });
    if inside {
        return push_out(lbvh, prev, p, margin, touch);
    }

    // 2. Sweep: the first sphere the path to the held end point enters.
    let mut first: Option<(f32, Sphere)> = None;
    lbvh.for_each_overlapping(prev.min(target), prev.max(target), margin, |_, s| {
        if segment_enters(s, prev, target, margin) {
            let t = entry_parameter(prev, target, s.centre(), s.radius + margin);
            if first.is_none_or(|(best, _)| t < best) {
                first = Some((t, *s));
            }
        }
    });
    let Some((t, s)) = first else {
        return if touched { Response::Moved(target) } else { Response::Free };
    };
    let c = s.centre();
    let normal = outward_normal(prev.lerp(target, t), prev, c);
    // On the surface, whatever the rounding of the interpolation.
    let entry = c + normal * (s.radius + margin);
    touch(normal);

    // 3. Guard.
    if lbvh.any_containing(entry, margin) { Response::Stay } else { Response::Moved(entry) }
}

/// The paper's response for a particle that starts inside a sphere: `p` is pushed out along the
/// normal of the sphere it is deepest in, at most [`MAX_PASSES`] times.
fn push_out(lbvh: &Lbvh, prev: Vec3, mut p: Vec3, margin: f32, mut touch: impl FnMut(Vec3)) -> Response {
    let mut moved = false;
    for _ in 0..MAX_PASSES {
        let mut deepest: Option<(f32, Sphere)> = None;
        lbvh.for_each_containing(p, margin, |_, s| {
            let depth = s.radius + margin - p.distance(s.centre());
            if deepest.is_none_or(|(best, _)| depth > best) {
                deepest = Some((depth, *s));
            }
        });
        let Some((_, s)) = deepest else { break };
        let c = s.centre();
        let normal = outward_normal(p, prev, c);
        p = c + normal * (s.radius + margin);
        moved = true;
        touch(normal);
    }
    if moved { Response::Moved(p) } else { Response::Free }
}
