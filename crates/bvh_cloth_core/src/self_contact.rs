//! Self-contact and contact between cloths: every particle is held a thickness away from every
//! triangle of its own cloth it is not a corner of, and from every triangle of the other cloths
//! stepped with it.
//!
//! Point against triangle, not point against point: with a thickness below the particle
//! spacing, a particle of one layer passes between the particles of another through the middle
//! of a triangle, so pairs of particles alone let two cloths cross each other. Held off the
//! triangles, a layer's particles meet the other layer's surface wherever they cross it.
//!
//! # Finding the pairs
//!
//! A hashed grid, rebuilt each substep, of cells as wide as the reach: the largest thickness
//! plus the longest edge of any triangle as the particles stand, so that every corner of a
//! triangle within the thickness of a particle lies within the reach of it, in its cell or the
//! 26 around it. Each particle's cell is hashed into a table of about twice as many buckets as
//! particles, and a counting sort lays the particles out bucket by bucket: one pass to count, a
//! prefix sum, one pass to place. The same layout is what a GPU builds with atomics; it needs
//! no pointers and no allocation per cell. Two cells that hash to one bucket only add
//! candidates, which the distance test drops.
//!
//! Each particle `k` then gathers, from every particle `j` within the reach: its contacts as a
//! point with the triangles `j` is the first corner of (so each triangle once), and as a corner
//! of its own triangles with the point `j`. Within a cloth a point and a triangle are skipped
//! when the point is a corner of the triangle or lies closer to it than the thickness in the
//! rest shape: the cloth's own shape never fights the contact.
//!
//! # Bounds
//!
//! A particle examines at most [`MAX_CANDIDATES`] others. Everything at one point (a cloth
//! collapsed by an absurd force) costs a bounded amount per particle, not the square of the
//! count; the particles that met the bound are counted in [`ContactStats::clamped`], never
//! silently.
//!
//! # Response
//!
//! A point `p` closer than the pair's thickness `h` (the mean of the two cloths') to a triangle,
//! at distance `d` from its closest point `q = Σ b_c x_c` (barycentric weights `b`), along the
//! unit direction `n` from `q` to `p`: the constraint `(x_p - q)·n >= h` is projected with the
//! particles' weights (1 free, 0 pinned), so `p` moves `w_p λ n` and each corner `-w_c b_c λ n`,
//! with `λ = (h - d) / (w_p + Σ w_c b_c²)`. If they approach, the normal part of their relative
//! velocity is taken off the same way, and the tangential part slowed by Coulomb friction. A
//! particle in several contacts moves by the mean of its corrections (Jacobi with averaging),
//! so the result depends neither on the order nor on the thread count. A particle that moved
//! is then checked against the colliders from where it was, so that contact never pushes
//! cloth through a collider.
//!
//! # Limits
//!
//! The contact is discrete: a layer that crosses another within one substep (a relative speed
//! above the thickness per substep, 10 mm in 1 ms is 10 m/s at Looper 16) is not caught, and
//! layers that already cross are not untangled.

use glam::{IVec3, Vec3};
use rayon::prelude::*;

use crate::collision::ColliderFrame;
use crate::error::ClothError;
use crate::topology::ClothTopology;
use crate::triangles::{closest_point, face_normal};

/// Most particles one particle examines for contact in a substep.
pub const MAX_CANDIDATES: usize = 256;

/// Above this many particles the pairs are found and resolved on the rayon pool.
const PARALLEL_MIN: usize = 2048;

/// How a cloth keeps off itself and other cloths.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "bevy_reflect", derive(bevy_reflect::Reflect), reflect(Debug, PartialEq))]
pub struct SelfContact {
    /// The least distance between a particle and a triangle it is not a corner of, in metres.
    /// At most the cloth's particle spacing (the mean rest length of its structural springs):
    /// thicker, and the cloth's own neighbouring triangles would push its particles.
    pub thickness: f32,
    /// Coulomb friction between layers (0 slides freely).
    pub friction: f32,
}

impl SelfContact {
    /// Checks the fields alone: a positive, finite thickness and a non-negative, finite
    /// friction.
    pub fn validate(&self) -> Result<(), ClothError> {
        if !(self.thickness.is_finite() && self.thickness > 0.0) {
            return Err(ClothError::NotPositive { field: "self_contact.thickness", value: self.thickness });
        }
        if !(self.friction.is_finite() && self.friction >= 0.0) {
            return Err(ClothError::Negative { field: "self_contact.friction", value: self.friction });
        }
        Ok(())
    }

    /// [`Self::validate`], and a thickness no larger than `topology`'s particle spacing.
    pub fn validate_for(&self, topology: &ClothTopology) -> Result<(), ClothError> {
        self.validate()?;
        let spacing = particle_spacing(topology);
        if self.thickness > spacing {
            return Err(ClothError::ThicknessAboveSpacing { thickness: self.thickness, spacing });
        }
        Ok(())
    }
}

/// The mean rest length of `topology`'s structural springs: its particle spacing.
pub fn particle_spacing(topology: &ClothTopology) -> f32 {
    let (sum, count) = topology
        .spring_ends()
        .iter()
        .filter(|e| e.kind == 0)
        .fold((0.0f64, 0usize), |(sum, count), e| (sum + f64::from(e.rest), count + 1));
    if count == 0 { 0.0 } else { (sum / count as f64) as f32 }
}

/// One cloth's particles as contact sees them.
#[derive(Debug)]
pub struct ContactBody<'a> {
    /// The cloth's shape: its springs and rest positions say which pairs are skipped.
    pub topology: &'a ClothTopology,
    /// Its thickness and friction.
    pub contact: SelfContact,
    /// 1 for a free particle, 0 for a pinned one.
    pub free: &'a [f32],
    /// Positions, in the world.
    pub x: &'a mut [Vec3],
    /// Velocities.
    pub v: &'a mut [Vec3],
}

/// What one resolution found.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ContactStats {
    /// Point–triangle contacts, counted once by each particle taking part (the point and each
    /// free corner).
    pub contacts: usize,
    /// Particles that had more than [`MAX_CANDIDATES`] candidates, some left unexamined.
    pub clamped: usize,
}

/// The grid and the scratch of contact resolution, kept between substeps.
#[derive(Clone, Debug, Default)]
pub struct ContactSolver {
    x: Vec<Vec3>,
    v: Vec<Vec3>,
    free: Vec<f32>,
    /// For each particle, its body and its index in it.
    owner: Vec<(u32, u32)>,
    /// Each body's first particle in the flat arrays.
    first: Vec<u32>,
    cell: Vec<IVec3>,
    /// Bucket `b` holds `order[starts[b]..starts[b + 1]]`.
    starts: Vec<u32>,
    order: Vec<u32>,
    /// Each particle's new position and velocity, and what it met.
    out: Vec<Moved>,
}

/// One particle's result of a pass.
#[derive(Clone, Copy, Debug)]
struct Moved {
    x: Vec3,
    v: Vec3,
    contacts: u32,
    clamped: bool,
}

/// One point–triangle contact: the correction each takes part in, per unit of its weight.
struct Contact {
    /// Unit normal, from the triangle to the point.
    n: Vec3,
    /// The point's barycentric weights on the triangle.
    b: [f32; 3],
    /// Position correction along `n` per unit weight.
    lambda: f32,
    /// Velocity correction per unit weight (normal and friction).
    impulse: Vec3,
}

impl ContactSolver {
    /// Holds every particle of `bodies` its thickness off every triangle (within a body and
    /// across bodies), as the [module docs](self) say, then checks the particles that moved
    /// against `frames` from where they were. `bodies` are written in place.
    pub fn resolve(&mut self, bodies: &mut [ContactBody<'_>], frames: &[ColliderFrame<'_>]) -> ContactStats {
        let longest_edge = self.gather(bodies);
        let n = self.x.len();
        let thickest = bodies.iter().map(|b| b.contact.thickness).fold(0.0f32, f32::max);
        // A triangle within the thickness of a point has every corner within this of it.
        let reach = thickest + longest_edge;
        if n < 2 || !(reach.is_finite() && thickest > 0.0) {
            return ContactStats::default();
        }
        self.sort_into_buckets(reach);

        let this = &*self;
        let bodies_ref: &[ContactBody<'_>] = bodies;
        let respond = |k: usize| this.respond(k, bodies_ref, reach);
        let out: Vec<Moved> = if n >= PARALLEL_MIN {
            (0..n).into_par_iter().map(respond).collect()
        } else {
            (0..n).map(respond).collect()
        };
        self.out = out;

        let mut stats = ContactStats::default();
        for (k, moved) in self.out.iter().enumerate() {
            stats.contacts += moved.contacts as usize;
            stats.clamped += usize::from(moved.clamped);
            if moved.contacts == 0 {
                continue;
            }
            let (body, local) = self.owner[k];
            let body = &mut bodies[body as usize];
            let (mut p, mut vel) = (moved.x, moved.v);
            for frame in frames {
                frame.resolve(self.x[k], &mut p, &mut vel);
            }
            body.x[local as usize] = p;
            body.v[local as usize] = vel;
        }
        stats
    }

    /// Copies every body's particles into the flat arrays; returns the longest edge of any
    /// triangle as the particles stand.
    fn gather(&mut self, bodies: &[ContactBody<'_>]) -> f32 {
        self.x.clear();
        self.v.clear();
        self.free.clear();
        self.owner.clear();
        self.first.clear();
        let mut longest = 0.0f32;
        for (b, body) in bodies.iter().enumerate() {
            let n = body.topology.len();
            assert!(
                body.x.len() >= n && body.v.len() >= n && body.free.len() >= n,
                "a contact body holds fewer particles than its topology"
            );
            self.first.push(self.x.len() as u32);
            self.x.extend_from_slice(&body.x[..n]);
            self.v.extend_from_slice(&body.v[..n]);
            self.free.extend_from_slice(&body.free[..n]);
            self.owner.extend((0..n as u32).map(|i| (b as u32, i)));
            for t in body.topology.triangles() {
                let [a, b, c] = t.map(|k| body.x[k as usize]);
                let edge = a.distance_squared(b).max(b.distance_squared(c)).max(c.distance_squared(a));
                if edge.is_finite() {
                    longest = longest.max(edge);
                }
            }
        }
        longest.sqrt()
    }

    /// The counting sort of the particles into the hashed grid's buckets.
    fn sort_into_buckets(&mut self, cell_size: f32) {
        let n = self.x.len();
        let buckets = (2 * n).next_power_of_two();
        let inv = 1.0 / cell_size;
        self.cell.clear();
        self.cell.extend(self.x.iter().map(|&p| cell_of(p, inv)));
        self.starts.clear();
        self.starts.resize(buckets + 1, 0);
        for (k, &c) in self.cell.iter().enumerate() {
            if self.x[k].is_finite() {
                self.starts[bucket(c, buckets) + 1] += 1;
            }
        }
        for b in 0..buckets {
            self.starts[b + 1] += self.starts[b];
        }
        let mut next: Vec<u32> = self.starts[..buckets].to_vec();
        self.order.clear();
        self.order.resize(self.starts[buckets] as usize, 0);
        for (k, &c) in self.cell.iter().enumerate() {
            if self.x[k].is_finite() {
                let slot = &mut next[bucket(c, buckets)];
                self.order[*slot as usize] = k as u32;
                *slot += 1;
            }
        }
    }

    /// Particle `k`'s new position and velocity: the mean of its corrections as a point
    /// against the triangles near it, and as a corner of its own triangles against the points
    /// near them. Every candidate is a particle within `reach` of `k`.
    fn respond(&self, k: usize, bodies: &[ContactBody<'_>], reach: f32) -> Moved {
        let (x, v) = (self.x[k], self.v[k]);
        let unmoved = Moved { x, v, contacts: 0, clamped: false };
        if self.free[k] == 0.0 || !x.is_finite() {
            return unmoved;
        }
        let (body, local) = self.owner[k];
        let me = bodies[body as usize].topology;
        let buckets = self.starts.len() - 1;
        let centre = self.cell[k];
        let mut seen = [u32::MAX; 27];
        let (mut dx, mut dv, mut contacts, mut examined) = (Vec3::ZERO, Vec3::ZERO, 0u32, 0usize);
        let mut clamped = false;
        'cells: for (c, offset) in NEIGHBOUR_CELLS.iter().enumerate() {
            let b = bucket(centre.wrapping_add(*offset), buckets) as u32;
            // Two neighbour cells may share a bucket: read it once.
            if seen[..c].contains(&b) {
                continue;
            }
            seen[c] = b;
            for &j in &self.order[self.starts[b as usize] as usize..self.starts[b as usize + 1] as usize] {
                let j = j as usize;
                if j == k || self.x[j].distance_squared(x) >= reach * reach {
                    continue;
                }
                if examined == MAX_CANDIDATES {
                    clamped = true;
                    break 'cells;
                }
                examined += 1;
                let (other_body, other_local) = self.owner[j];
                let other = bodies[other_body as usize].topology;
                // As a point: the triangles `j` is the first corner of (so each triangle once).
                for &t in other.triangles_of(other_local as usize) {
                    let tri = other.triangles()[t as usize];
                    if tri[0] != other_local {
                        continue;
                    }
                    if let Some(c) = self.contact(bodies, k, other_body, tri) {
                        dx += self.free[k] * c.lambda * c.n;
                        dv += self.free[k] * c.impulse;
                        contacts += 1;
                    }
                }
                // As a corner: `k`'s own triangles against the point `j`.
                for &t in me.triangles_of(local as usize) {
                    let tri = me.triangles()[t as usize];
                    if let Some(c) = self.contact(bodies, j, body, tri) {
                        let corner = tri.iter().position(|&q| q == local).unwrap_or(0);
                        let share = -self.free[k] * c.b[corner];
                        dx += share * c.lambda * c.n;
                        dv += share * c.impulse;
                        contacts += 1;
                    }
                }
            }
        }
        if contacts == 0 {
            return Moved { clamped, ..unmoved };
        }
        let mean = 1.0 / contacts as f32;
        Moved { x: x + dx * mean, v: v + dv * mean, contacts, clamped }
    }

    /// The contact of point `p` (flat index) with triangle `tri` of body `tb`, if the point is
    /// closer than the pair's thickness, is not one of its corners, and lay no closer than
    /// that in their rest shape when they are of one body.
    fn contact(&self, bodies: &[ContactBody<'_>], p: usize, tb: u32, tri: [u32; 3]) -> Option<Contact> {
        let (pb, pl) = self.owner[p];
        if pb == tb && tri.contains(&pl) {
            return None;
        }
        let (point_body, tri_body) = (&bodies[pb as usize], &bodies[tb as usize]);
        let h = 0.5 * (point_body.contact.thickness + tri_body.contact.thickness);
        let first = self.first[tb as usize] as usize;
        let corners = tri.map(|c| first + c as usize);
        let at = corners.map(|c| self.x[c]);
        let xp = self.x[p];
        let q = closest_point(xp, at);
        let away = xp - q;
        let d2 = away.length_squared();
        // NaN too: a non-finite particle makes no contact.
        if d2.is_nan() || d2 >= h * h {
            return None;
        }
        if pb == tb {
            let rest = tri_body.topology.rest_positions();
            let rp = rest[pl as usize];
            if closest_point(rp, tri.map(|c| rest[c as usize])).distance_squared(rp) < h * h {
                return None;
            }
        }
        let d = d2.sqrt();
        let n = if d > 1.0e-6 * h { away / d } else { face_normal(at).unwrap_or(Vec3::Y) };
        let b = barycentric(q, at);
        let w = corners.map(|c| self.free[c]);
        let denom = self.free[p] + w[0] * b[0] * b[0] + w[1] * b[1] * b[1] + w[2] * b[2] * b[2];
        if denom <= 0.0 {
            return None;
        }
        let relative = self.v[p] - (b[0] * self.v[corners[0]] + b[1] * self.v[corners[1]] + b[2] * self.v[corners[2]]);
        let vn = relative.dot(n);
        let impulse = if vn < 0.0 {
            let tangential = relative - vn * n;
            let friction = 0.5 * (point_body.contact.friction + tri_body.contact.friction);
            let speed = tangential.length();
            let slow = if speed > 0.0 { (friction * -vn / speed).min(1.0) } else { 0.0 };
            -(vn * n + slow * tangential) / denom
        } else {
            Vec3::ZERO
        };
        Some(Contact { n, b, lambda: (h - d) / denom, impulse })
    }
}

/// The barycentric weights of `q` (a point of the triangle) on the triangle; equal weights for
/// a triangle without area.
fn barycentric(q: Vec3, [a, b, c]: [Vec3; 3]) -> [f32; 3] {
    let (e1, e2, r) = (b - a, c - a, q - a);
    let (d11, d12, d22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let (r1, r2) = (r.dot(e1), r.dot(e2));
    let det = d11 * d22 - d12 * d12;
    let scale = d11.max(d22);
    if det.is_nan() || det <= 1.0e-12 * scale * scale {
        return [1.0 / 3.0; 3];
    }
    let u = ((d22 * r1 - d12 * r2) / det).clamp(0.0, 1.0);
    let w = ((d11 * r2 - d12 * r1) / det).clamp(0.0, 1.0 - u);
    [1.0 - u - w, u, w]
}

/// The 27 cells round a cell, itself first.
const NEIGHBOUR_CELLS: [IVec3; 27] = {
    let mut cells = [IVec3::ZERO; 27];
    let mut k = 1;
    let mut i = 0;
    while i < 27 {
        let offset = IVec3::new(i % 3 - 1, (i / 3) % 3 - 1, i / 9 - 1);
        if !(offset.x == 0 && offset.y == 0 && offset.z == 0) {
            cells[k] = offset;
            k += 1;
        }
        i += 1;
    }
    cells
};

/// The grid cell of `p` (cells `1 / inv` wide). Coordinates beyond `i32` saturate, and a
/// non-finite one gives cell 0 (such a particle is left out of the grid).
#[inline]
fn cell_of(p: Vec3, inv: f32) -> IVec3 {
    let c = (p * inv).floor();
    IVec3::new(c.x as i32, c.y as i32, c.z as i32)
}

/// The bucket of cell `c` in a table of `buckets` (a power of two).
#[inline]
fn bucket(c: IVec3, buckets: usize) -> usize {
    let h = (c.x as u32).wrapping_mul(73_856_093)
        ^ (c.y as u32).wrapping_mul(19_349_663)
        ^ (c.z as u32).wrapping_mul(83_492_791);
    h as usize & (buckets - 1)
}
