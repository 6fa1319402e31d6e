//! Self-contact and contact between cloths: every particle is held a thickness away from every
//! triangle of its own cloth it is not a corner of, and from every triangle of the other cloths
//! stepped with it whose collision layers its own meet ([`ContactBody::layers`]).
//!
//! Point against triangle, not point against point: with a thickness below the particle
//! spacing, a particle of one layer passes between the particles of another through the middle
//! of a triangle, so pairs of particles alone let two cloths cross each other. Held off the
//! triangles, a layer's particles meet the other layer's surface wherever they cross it.
//!
//! # Finding the pairs
//!
//! A hashed grid of the triangles, rebuilt each substep (Teschner et al. 2003, "Optimized
//! spatial hashing for collision detection of deformable objects"): cells twice as wide as the
//! largest thickness plus the mean edge, and every triangle entered in each cell its box over
//! the substep (where its corners were at the start and are now), grown by the thickness,
//! overlaps (one to eight cells for most). A point whose path over the substep came within the
//! thickness of a triangle, or went through it, met that box, so the triangle is in the bucket
//! of a cell the point's path overlaps: a point looks in the buckets of those cells (one for
//! most, at most [`MAX_PATH_SPAN`] along an axis), and takes a triangle only in the first cell
//! that both cover, so that it meets each triangle once. Each
//! cell is hashed into a table of about twice as many buckets as triangles, and a counting sort
//! lays the entries out bucket by bucket: one pass to count, a prefix sum, one pass to place.
//! The same layout is what a GPU builds with atomics; it needs no pointers and no allocation
//! per cell. Two cells that hash to one bucket only add candidates, which the box test drops.
//! On the CPU the sort takes the triangles in four runs (`SORT_CHUNKS`), counted and placed in
//! parallel, each run after the earlier ones in every bucket, so the buckets are the same
//! whatever the threads; each entry's box is copied beside it, so that a point's scan of a
//! bucket, most of the cost, reads the boxes in a row; and each triangle's first cell is kept
//! from the sort for the scan's once-per-triangle test.
//!
//! Within a cloth a point and a triangle are skipped when the point is a corner of the
//! triangle, or lies within the thickness of the triangle's box in the rest shape (the
//! triangle is its neighbour on the cloth, not another layer): the cloth's own shape never
//! fights the contact.
//!
//! # Bounds
//!
//! A point examines at most [`MAX_CANDIDATES`] triangles of a bucket, its path at most
//! [`MAX_PATH_SPAN`] cells and a triangle at most [`MAX_SPAN`] cells along an axis. Everything at one point (a cloth collapsed by an absurd
//! force) costs a bounded amount per particle, not the square of the count; what met a bound is
//! counted in [`ContactStats::clamped`], never silently.
//!
//! # Response
//!
//! A point `p` closer than the pair's thickness `h` (the mean of the two cloths') to a triangle,
//! at distance `d` from its closest point `q = Σ b_c x_c` (barycentric weights `b`), along the
//! unit direction `n` from `q` to `p`: the constraint `(x_p - q)·n >= h` is projected with the
//! particles' weights (1 free, 0 pinned), so `p` moves `w_p λ n` and each corner `-w_c b_c λ n`,
//! with `λ = (h - d) / (w_p + Σ w_c b_c²)`. A particle a collider touched in the substep's
//! collision response ([`ContactBody::held`]) takes no part either, unless every particle of
//! the contact is held: where a model presses one layer into another, the layer on the model
//! cannot give way (the collider puts it back), so the other side takes the held particles'
//! share too (`λ` scaled by the ratio of the two denominators, at most [`MAX_HELD_SCALE`]),
//! and the layers do not cross.
//! A point that changed sides of the triangle's plane during the substep (from the positions
//! at its start, [`ContactBody::prev`]) went through it if, where it crossed the plane, it was
//! within the thickness of the triangle as far along its own path (all four particles moving in
//! straight lines over the substep): `n` is then the face normal on the side it came from, and
//! `d` its depth below the plane, so it goes back the thickness above the side it left, however
//! far past the triangle it ended. If they approach, the normal part of their relative velocity is taken off
//! the same way, and the tangential part slowed by Coulomb friction. The
//! contacts are found in parallel, point by point, and summed in point order; a particle in
//! several contacts moves by the mean of its corrections (Jacobi with averaging), so the result
//! depends neither on the thread count nor on the order. A particle that moved is then checked
//! against the colliders from where it was, so that contact never pushes cloth through a
//! collider.
//!
//! # Limits
//!
//! A point is caught going through a triangle at any speed up to a path of
//! [`MAX_PATH_SPAN`] cells a substep (the bar fold of the core's tests, thrown at 15 m/s, ends
//! with no crossing pair; tested at the end of the substep alone, 20). The crossing is found
//! with the triangle's plane taken as it turns linearly, not by the exact cubic of continuous
//! collision detection. Edges are not tested against edges: two edges can pass through each
//! other between the particles of both layers. Nothing undoes an intersection that exists:
//! the same cloth thrown onto the bunny at 15 m/s ends with 16 crossing pairs. Over that fold,
//! of the 1,326 times a pair of its triangles came to intersect, 1,003 were an edge going
//! through an edge alone, 303 a corner through a face this contact tests and 20 a corner
//! through a neighbouring face it skips (at 7 m/s: 171, 4 and 20 of 195; the report's
//! `self_contact_events` section).

use core::sync::atomic::{AtomicU32, Ordering};

#[cfg(feature = "bevy_reflect")]
use bevy_reflect::std_traits::ReflectDefault;
use glam::{IVec3, Vec3, Vec3A};
use rayon::prelude::*;

use crate::cloth::error::ClothError;
use crate::cloth::grid::SpringKind;
use crate::cloth::topology::ClothTopology;
use crate::colliders::collision::ColliderFrame;
use crate::colliders::layers::CollisionLayers;
use crate::mesh::triangles::{closest_point, face_normal};

/// Most triangles one particle examines in one grid cell's bucket for contact in a substep.
pub const MAX_CANDIDATES: usize = 256;

/// Most grid cells a triangle covers along an axis; a wider one (stretched far beyond the
/// others) is entered in the first `MAX_SPAN³` of its cells and counted as clamped.
pub const MAX_SPAN: i32 = 4;

/// Most grid cells a particle's path over a substep is looked along, along an axis: a path
/// longer than a cell (twice the thickness and the mean edge: 48 mm, 46 m/s at Looper 16 for
/// the 64 x 64 cloth of 1 m at 8 mm) is looked along for its first two cells and counted as
/// clamped.
pub const MAX_PATH_SPAN: i32 = 2;

/// Most a contact's correction is scaled up when held particles take no part of it: the free
/// side takes the held side's share, up to this many times its own (a triangle whose only free
/// corner has a small weight at the contact would otherwise be levered far).
pub const MAX_HELD_SCALE: f32 = 16.0;

/// Above this many particles the contacts are found on the rayon pool.
const PARALLEL_MIN: usize = 2048;

/// The runs of triangles the grid's counting sort takes in parallel: fixed, so that the
/// buckets do not depend on the thread count.
const SORT_CHUNKS: usize = 4;

/// How a cloth keeps off itself and other cloths.
///
/// `SelfContact::default()` fits any cloth: its thickness is taken from the cloth's own
/// particle spacing when the cloth is built ([`Self::AUTO_THICKNESS`]), and its friction is 0.3.
///
/// ```
/// # use bvh_cloth_core::{ClothParams, SelfContact};
/// let params = ClothParams { self_contact: Some(SelfContact::default()), ..Default::default() };
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "bevy_reflect", derive(bevy_reflect::Reflect), reflect(Default, Debug, PartialEq))]
pub struct SelfContact {
    /// The least distance between a particle and a triangle it is not a corner of, in metres.
    /// At most the cloth's particle spacing (the mean rest length of its structural springs):
    /// thicker, and the cloth's own neighbouring triangles would push its particles. 0 (the
    /// default) is half that spacing, whatever the cloth's size and resolution.
    pub thickness: f32,
    /// Coulomb friction between layers (0 slides freely).
    pub friction: f32,
}

impl Default for SelfContact {
    fn default() -> Self {
        Self { thickness: 0.0, friction: 0.3 }
    }
}

impl SelfContact {
    /// The share of the cloth's particle spacing a thickness of 0 stands for: half, thick
    /// enough that a particle crossing a layer at up to half the spacing per substep is caught,
    /// and thin enough that the cloth's own triangles never push their neighbours.
    pub const AUTO_THICKNESS: f32 = 0.5;

    /// Checks the fields alone: a finite thickness, positive or 0 (see [`Self::thickness`]),
    /// and a non-negative, finite friction.
    pub fn validate(&self) -> Result<(), ClothError> {
        if self.thickness != 0.0 {
            ClothError::check_positive("self_contact.thickness", self.thickness)?;
        }
        ClothError::check_non_negative("self_contact.friction", self.friction)
    }

    /// The same contact with a thickness of 0 replaced by [`Self::AUTO_THICKNESS`] of
    /// `topology`'s particle spacing; any other thickness is kept.
    pub fn resolved_for(self, topology: &ClothTopology) -> Self {
        if self.thickness == 0.0 {
            Self { thickness: Self::AUTO_THICKNESS * particle_spacing(topology), ..self }
        } else {
            self
        }
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
        .filter(|e| e.kind == SpringKind::Structural as u32)
        .fold((0.0f64, 0usize), |(sum, count), e| (sum + f64::from(e.rest), count + 1));
    if count == 0 { 0.0 } else { (sum / count as f64) as f32 }
}

/// One cloth's particles as contact sees them.
#[derive(Debug)]
pub struct ContactBody<'a> {
    /// The cloth's shape: its triangles, and its rest shape, which says which of its own
    /// triangles a point skips.
    pub topology: &'a ClothTopology,
    /// Its thickness and friction.
    pub contact: SelfContact,
    /// Its collision layers: the colliders its particles are checked against after contact,
    /// and the other bodies it keeps off (a body always keeps off itself).
    pub layers: CollisionLayers,
    /// 1 for a free particle, 0 for a pinned one.
    pub free: &'a [f32],
    /// 1 for a particle a collider touched in this substep's collision response, else 0 (or
    /// an empty slice for none): contact weighs it as pinned.
    pub held: &'a [f32],
    /// Positions at the start of the substep: a point that went through a triangle during it
    /// is put back on the side it came from.
    pub prev: &'a [Vec3],
    /// Positions, in the world.
    pub x: &'a mut [Vec3],
    /// Velocities.
    pub v: &'a mut [Vec3],
}

/// What one resolution found.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ContactStats {
    /// Point–triangle contacts, counted once by each free particle taking part (the point and
    /// the triangle's corners). A pinned particle is never moved by contact.
    pub contacts: usize,
    /// Points that had more than [`MAX_CANDIDATES`] candidate triangles (some left
    /// unexamined), and triangles wider than [`MAX_SPAN`] cells.
    pub clamped: usize,
}

/// The grid and the scratch of contact resolution, kept between substeps.
#[derive(Clone, Debug, Default)]
pub struct ContactSolver {
    prev: Vec<Vec3>,
    x: Vec<Vec3>,
    v: Vec<Vec3>,
    free: Vec<f32>,
    /// 1 for a particle a collider touched in the substep.
    held: Vec<f32>,
    /// For each particle, its body and its index in it.
    owner: Vec<(u32, u32)>,
    /// Every body's triangles: its body and its corners' flat indices.
    triangles: Vec<(u32, [u32; 3])>,
    /// Each triangle's box as the particles stand, grown by the largest thickness, and its box
    /// in the rest shape.
    boxes: Vec<[Vec3A; 2]>,
    /// Each triangle's first grid cell: the one of its grown box's least corner.
    first_cells: Vec<IVec3>,
    rest_boxes: Vec<[Vec3A; 2]>,
    /// Bucket `b` holds the triangles `entries[starts[b]..starts[b + 1]]`.
    starts: Vec<u32>,
    entries: Vec<u32>,
    /// The box of each entry's triangle, `boxes[entries[k]]`.
    entry_boxes: Vec<[Vec3A; 2]>,
    /// Each run of triangles' count of entries in each bucket, then where they go (the
    /// counting sort's scratch).
    counts: Vec<Vec<u32>>,
    /// Each particle's summed corrections and the number of contacts it took part in.
    dx: Vec<Vec3>,
    dv: Vec<Vec3>,
    count: Vec<u32>,
}

/// One point–triangle contact: the correction each takes part in, per unit of its weight.
#[derive(Clone, Copy, Debug)]
struct Contact {
    /// The point (flat index) and the triangle.
    point: u32,
    triangle: u32,
    /// Unit normal, from the triangle to the point.
    n: Vec3,
    /// The point's barycentric weights on the triangle.
    b: [f32; 3],
    /// Position correction along `n` per unit weight.
    lambda: f32,
    /// Velocity correction per unit weight (normal and friction).
    impulse: Vec3,
    /// The weights the corrections are taken with: the point's, then the corners'.
    w: [f32; 4],
}

impl ContactSolver {
    /// Holds every particle of `bodies` its thickness off every triangle (within a body and
    /// across bodies), as the [module docs](self) say, then checks the particles that moved
    /// against `frames` from where they were. `bodies` are written in place.
    pub fn resolve(&mut self, bodies: &mut [ContactBody<'_>], frames: &[ColliderFrame<'_>]) -> ContactStats {
        let mean_edge = self.gather(bodies);
        let n = self.x.len();
        let thickest = bodies.iter().map(|b| b.contact.thickness).fold(0.0f32, f32::max);
        // Twice a grown triangle's typical width: most triangles fall in one to eight cells.
        let cell = 2.0 * (thickest + mean_edge);
        if n < 2 || self.triangles.is_empty() || !(cell.is_finite() && thickest > 0.0) {
            return ContactStats::default();
        }
        let mut stats = ContactStats { clamped: self.sort_triangles(cell, thickest), ..Default::default() };

        // Every point's contacts, in point order whatever the threads.
        let this = &*self;
        let bodies_ref: &[ContactBody<'_>] = bodies;
        let find = |(mut found, mut clamped): (Vec<Contact>, usize), p: usize| {
            clamped += usize::from(this.contacts_of(p, bodies_ref, cell, &mut found));
            (found, clamped)
        };
        let found: Vec<(Vec<Contact>, usize)> = if n >= PARALLEL_MIN {
            (0..n).into_par_iter().fold(|| (Vec::new(), 0), find).collect()
        } else {
            vec![(0..n).fold((Vec::new(), 0), find)]
        };

        self.dx.clear();
        self.dx.resize(n, Vec3::ZERO);
        self.dv.clear();
        self.dv.resize(n, Vec3::ZERO);
        self.count.clear();
        self.count.resize(n, 0);
        for (contacts, clamped) in &found {
            stats.clamped += clamped;
            for c in contacts {
                let p = c.point as usize;
                if c.w[0] > 0.0 {
                    self.dx[p] += c.w[0] * c.lambda * c.n;
                    self.dv[p] += c.w[0] * c.impulse;
                    self.count[p] += 1;
                }
                for ((corner, &b), &w) in self.triangles[c.triangle as usize].1.iter().zip(&c.b).zip(&c.w[1..]) {
                    let k = *corner as usize;
                    if w > 0.0 {
                        self.dx[k] -= w * b * c.lambda * c.n;
                        self.dv[k] -= w * b * c.impulse;
                        self.count[k] += 1;
                    }
                }
            }
        }
        for k in 0..n {
            let count = self.count[k];
            if count == 0 {
                continue;
            }
            stats.contacts += count as usize;
            let mean = 1.0 / count as f32;
            let (mut p, mut vel) = (self.x[k] + self.dx[k] * mean, self.v[k] + self.dv[k] * mean);
            let (body, local) = self.owner[k];
            let body = &mut bodies[body as usize];
            for frame in frames.iter().filter(|f| body.layers.interacts_with(f.layers)) {
                frame.resolve(self.x[k], &mut p, &mut vel);
            }
            body.x[local as usize] = p;
            body.v[local as usize] = vel;
        }

        stats
    }

    /// Copies every body's particles and triangles into the flat arrays; returns the mean edge
    /// length of the triangles as the particles stand.
    fn gather(&mut self, bodies: &[ContactBody<'_>]) -> f32 {
        self.prev.clear();
        self.x.clear();
        self.v.clear();
        self.free.clear();
        self.held.clear();
        self.owner.clear();
        self.triangles.clear();
        self.rest_boxes.clear();
        let (mut sum, mut edges) = (0.0f64, 0usize);
        for (b, body) in bodies.iter().enumerate() {
            let n = body.topology.len();
            assert!(
                body.x.len() >= n && body.v.len() >= n && body.free.len() >= n && body.prev.len() >= n,
                "a contact body holds fewer particles than its topology"
            );
            let first = self.x.len() as u32;
            self.prev.extend_from_slice(&body.prev[..n]);
            self.x.extend_from_slice(&body.x[..n]);
            self.v.extend_from_slice(&body.v[..n]);
            self.free.extend_from_slice(&body.free[..n]);
            self.held.extend((0..n).map(|i| body.held.get(i).copied().unwrap_or(0.0)));
            self.owner.extend((0..n as u32).map(|i| (b as u32, i)));
            for t in body.topology.triangles() {
                let [a, b2, c] = t.map(|k| body.x[k as usize]);
                let perimeter = a.distance(b2) + b2.distance(c) + c.distance(a);
                if perimeter.is_finite() {
                    sum += f64::from(perimeter);
                    edges += 3;
                }
                self.triangles.push((b as u32, t.map(|k| first + k)));
                let [ra, rb, rc] = t.map(|k| body.topology.rest_positions()[k as usize]);
                self.rest_boxes.push([ra.min(rb).min(rc).into(), ra.max(rb).max(rc).into()]);
            }
        }
        if edges == 0 { 0.0 } else { (sum / edges as f64) as f32 }
    }

    /// The counting sort of the triangles into the hashed grid's buckets: each goes into
    /// every cell its box, grown by `grow`, overlaps (at most [`MAX_SPAN`] cells along an
    /// axis). Returns how many triangles were wider than that.
    fn sort_triangles(&mut self, cell: f32, grow: f32) -> usize {
        let buckets = (2 * self.triangles.len()).next_power_of_two();
        let inv = 1.0 / cell;
        let (x, prev) = (&self.x, &self.prev);
        let grown_box = |(_, corners): &(u32, [u32; 3])| {
            // Where the triangle was at the start of the substep, and is now.
            let ([a, b, c], [d, e, f]) = (corners.map(|k| x[k as usize]), corners.map(|k| prev[k as usize]));
            let (lo, hi) = (a.min(b).min(c).min(d.min(e).min(f)), a.max(b).max(c).max(d.max(e).max(f)));
            [Vec3A::from(lo - grow), Vec3A::from(hi + grow)]
        };
        self.boxes.clear();
        if self.triangles.len() >= PARALLEL_MIN {
            self.triangles.par_iter().map(grown_box).collect_into_vec(&mut self.boxes);
        } else {
            self.boxes.extend(self.triangles.iter().map(grown_box));
        }
        // The cells of each triangle's grown box, its span along each axis capped.
        let cells = |&[lo, hi]: &[Vec3A; 2]| cells_of_box(lo, hi, inv, MAX_SPAN);
        let ranges: Vec<Option<((IVec3, IVec3), bool)>> = if self.boxes.len() >= PARALLEL_MIN {
            self.boxes.par_iter().map(cells).collect()
        } else {
            self.boxes.iter().map(cells).collect()
        };
        let clamped = ranges.iter().filter(|r| r.is_some_and(|(_, capped)| capped)).count();
        let ranges: Vec<Option<(IVec3, IVec3)>> = ranges.into_iter().map(|r| r.map(|(range, _)| range)).collect();
        self.first_cells.clear();
        self.first_cells.extend(ranges.iter().map(|r| r.map_or(IVec3::ZERO, |(lo, _)| lo)));
        // A counting sort in `SORT_CHUNKS` runs of triangles, counted and scattered in
        // parallel: each run's triangles go after the earlier runs' in every bucket, so the
        // buckets hold their triangles in order, as one pass over all of them would.
        let run = ranges.len().div_ceil(SORT_CHUNKS).max(1);
        let runs = ranges.len().div_ceil(run);
        self.counts.resize_with(runs, Vec::new);
        self.counts.par_iter_mut().zip(ranges.par_chunks(run)).for_each(|(count, part)| {
            count.clear();
            count.resize(buckets, 0);
            for range in part {
                for_each_bucket(*range, buckets, |b| count[b] += 1);
            }
        });
        // Each run's count becomes where its triangles start in the bucket.
        self.starts.clear();
        self.starts.resize(buckets + 1, 0);
        let mut total = 0u32;
        for b in 0..buckets {
            self.starts[b] = total;
            for count in &mut self.counts[..runs] {
                (count[b], total) = (total, total + count[b]);
            }
        }
        self.starts[buckets] = total;
        let entries: Vec<AtomicU32> = (0..total).map(|_| AtomicU32::new(0)).collect();
        ranges.par_chunks(run).zip(self.counts.par_iter_mut()).enumerate().for_each(|(k, (part, next))| {
            for (i, range) in part.iter().enumerate() {
                let t = (k * run + i) as u32;
                for_each_bucket(*range, buckets, |b| {
                    entries[next[b] as usize].store(t, Ordering::Relaxed);
                    next[b] += 1;
                });
            }
        });
        self.entries.clear();
        self.entries.extend(entries.into_iter().map(AtomicU32::into_inner));
        // Each entry's box beside it, so that a point's scan of a bucket reads them in a row.
        let boxes = &self.boxes;
        self.entries.par_iter().map(|&t| boxes[t as usize]).collect_into_vec(&mut self.entry_boxes);
        clamped
    }

    /// Adds the contacts of point `p` with the triangles in the buckets of the cells its path
    /// over the substep overlaps to `found`, each triangle once; returns whether a bucket held
    /// more than [`MAX_CANDIDATES`] of them, or the path was wider than [`MAX_PATH_SPAN`]
    /// cells.
    fn contacts_of(&self, p: usize, bodies: &[ContactBody<'_>], cell: f32, found: &mut Vec<Contact>) -> bool {
        let (x, prev) = (Vec3A::from(self.x[p]), Vec3A::from(self.prev[p]));
        let inv = 1.0 / cell;
        let Some(((lo, hi), mut clamped)) = cells_of_box(x.min(prev), x.max(prev), inv, MAX_PATH_SPAN) else {
            return false;
        };
        let (path_lo, path_hi) = (x.min(prev), x.max(prev));
        let buckets = self.starts.len() - 1;
        for z in lo.z..=hi.z {
            for y in lo.y..=hi.y {
                for x in lo.x..=hi.x {
                    let at = IVec3::new(x, y, z);
                    let b = bucket(at, buckets);
                    let bucket = self.starts[b] as usize..self.starts[b + 1] as usize;
                    clamped |= bucket.len() > MAX_CANDIDATES;
                    let candidates = self.entries[bucket.clone()].iter().zip(&self.entry_boxes[bucket]);
                    for (&t, &[t_lo, t_hi]) in candidates.take(MAX_CANDIDATES) {
                        // The grown boxes first, here in the scan: most candidates are beside
                        // the path, not within the thickness of it.
                        if !(path_lo.cmple(t_hi).all() && path_hi.cmpge(t_lo).all()) {
                            continue;
                        }
                        // Once per triangle: in the first cell both it and the path cover (a
                        // triangle met in another cell's bucket is a hash collision there).
                        if self.first_cells[t as usize].max(lo) != at {
                            continue;
                        }
                        found.extend(self.contact(bodies, p, t));
                    }
                }
            }
        }
        clamped
    }

    /// The contact of point `p` (flat index) with triangle `t`, whose grown box holds it, if
    /// the point is closer than the pair's thickness, is not one of its corners, and lay no
    /// closer than that in their rest shape when they are of one body.
    fn contact(&self, bodies: &[ContactBody<'_>], p: usize, t: u32) -> Option<Contact> {
        let (tb, corners) = self.triangles[t as usize];
        if corners.contains(&(p as u32)) {
            return None;
        }
        let xp = self.x[p];
        let (pb, pl) = self.owner[p];
        let (point_body, tri_body) = (&bodies[pb as usize], &bodies[tb as usize]);
        if pb != tb && !point_body.layers.interacts_with(tri_body.layers) {
            return None;
        }
        let h = 0.5 * (point_body.contact.thickness + tri_body.contact.thickness);
        if pb == tb {
            // Near it in the rest shape: the cloth's own neighbourhood, not another layer.
            let [lo, hi] = self.rest_boxes[t as usize];
            let rest = Vec3A::from(point_body.topology.rest_positions()[pl as usize]);
            if rest.cmpge(lo - h).all() && rest.cmple(hi + h).all() {
                return None;
            }
        }
        let at = corners.map(|c| self.x[c as usize]);
        let q = closest_point(xp, at);
        let away = xp - q;
        let d2 = away.length_squared();
        // A non-finite particle makes no contact.
        if !d2.is_finite() {
            return None;
        }
        // The side of the triangle's plane the point was on at the start of the substep, and is
        // on now. A point that changed sides went through the triangle (or round its edge,
        // closer than the thickness): it goes back to the side it came from, the thickness off
        // the plane.
        let face = face_normal(at);
        let before = corners.map(|c| self.prev[c as usize]);
        let side_before = face_normal(before).map_or(0.0, |n| (self.prev[p] - before[0]).dot(n));
        let side_now = face.map_or(0.0, |n| (xp - at[0]).dot(n));
        let through = side_before * side_now < 0.0;
        let (n, gap, q) = if d2 < h * h {
            let d = d2.sqrt();
            let (n, gap) = match face {
                Some(face) if through => (face * side_before.signum(), -side_now.abs()),
                _ if d > 1.0e-6 * h => (away / d, d),
                Some(face) if side_before != 0.0 => (face * side_before.signum(), 0.0),
                _ => (face.unwrap_or(Vec3::Y), 0.0),
            };
            (n, gap, q)
        } else {
            // Farther than the thickness now: a contact only if the point's path went through
            // the triangle during the substep (see `crossed`).
            let (face, q) = face.zip(crossed(self.prev[p], xp, before, at, side_before, side_now, h))?;
            (face * side_before.signum(), -side_now.abs(), q)
        };
        let b = barycentric(q, at);
        let weigh = |w: [f32; 4]| w[0] + w[1] * b[0] * b[0] + w[2] * b[1] * b[1] + w[3] * b[2] * b[2];
        let ids = [p as u32, corners[0], corners[1], corners[2]];
        let free = ids.map(|k| self.free[k as usize]);
        let denom = weigh(free);
        if denom <= 0.0 {
            return None;
        }
        // The held particles' share goes to the others, when there are others: the correction
        // is scaled so that the free side alone makes the whole of it, at most MAX_HELD_SCALE
        // times its own share.
        let unheld = ids.map(|k| self.free[k as usize] * (1.0 - self.held[k as usize]));
        let unheld_denom = weigh(unheld);
        let (w, scale) =
            if unheld_denom > 0.0 { (unheld, (denom / unheld_denom).min(MAX_HELD_SCALE)) } else { (free, 1.0) };
        let v = corners.map(|c| self.v[c as usize]);
        let relative = self.v[p] - (b[0] * v[0] + b[1] * v[1] + b[2] * v[2]);
        let vn = relative.dot(n);
        let impulse = if vn < 0.0 {
            let tangential = relative - vn * n;
            let friction = 0.5 * (point_body.contact.friction + tri_body.contact.friction);
            let speed = tangential.length();
            let slow = if speed > 0.0 { (friction * -vn / speed).min(1.0) } else { 0.0 };
            -(vn * n + slow * tangential) / denom * scale
        } else {
            Vec3::ZERO
        };
        Some(Contact { point: p as u32, triangle: t, n, b, lambda: (h - gap) / denom * scale, impulse, w })
    }
}

/// Whether a point that went from `p0` to `p1` over a substep went through the triangle that
/// went from `before` to `now`, given the point's sides of the triangle's plane at the start and
/// the end: the sides differ, and where the point crossed the plane (all four moving in straight
/// lines, the plane's turn neglected) it was within `h` of the triangle, which was then as far
/// along its own path. Returns the point of the triangle as it stands now at the crossing's
/// barycentric weights. Against the triangle's end position alone, a fold whose two sides both
/// move a thickness or more in a substep passes through unseen.
fn crossed(
    p0: Vec3,
    p1: Vec3,
    before: [Vec3; 3],
    now: [Vec3; 3],
    side_before: f32,
    side_now: f32,
    h: f32,
) -> Option<Vec3> {
    // NaN fails too.
    if side_before * side_now >= 0.0 || side_before.is_nan() || side_now.is_nan() {
        return None;
    }
    let s = side_before / (side_before - side_now);
    let then: [Vec3; 3] = core::array::from_fn(|k| before[k].lerp(now[k], s));
    let at = p0.lerp(p1, s);
    let q = closest_point(at, then);
    let d2 = q.distance_squared(at);
    if d2 >= h * h || d2.is_nan() {
        return None;
    }
    let b = barycentric(q, then);
    Some(b[0] * now[0] + b[1] * now[1] + b[2] * now[2])
}

/// The cells the box from `lo` to `hi` overlaps (cells `1 / inv` wide), capped at `span` cells
/// along each axis from `lo`'s, and whether it was capped; `None` for a box that is not finite.
#[inline]
fn cells_of_box(lo: Vec3A, hi: Vec3A, inv: f32, span: i32) -> Option<((IVec3, IVec3), bool)> {
    if !(lo.is_finite() && hi.is_finite()) {
        return None;
    }
    let (lo, hi) = (cell_of(lo.into(), inv), cell_of(hi.into(), inv));
    let capped = lo.wrapping_add(IVec3::splat(span - 1)).min(hi);
    Some(((lo, capped), capped != hi))
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

/// The grid cell of `p` (cells `1 / inv` wide). Coordinates beyond `i32` saturate, and a
/// non-finite one gives cell 0 (such a particle is left out of the grid).
#[inline]
fn cell_of(p: Vec3, inv: f32) -> IVec3 {
    let c = p * inv;
    IVec3::new(floor(c.x), floor(c.y), floor(c.z))
}

/// `v.floor() as i32` without a call to the C library's `floorf`, which x86-64's baseline
/// (SSE2, no rounding instruction) makes of `f32::floor`: the truncation, less one where it
/// rounded up. Saturates as `as` does; NaN gives 0.
#[inline]
fn floor(v: f32) -> i32 {
    let t = v as i32;
    t.saturating_sub(i32::from(t as f32 > v))
}

/// Calls `f(bucket)` once for each bucket (of `buckets`) of the cells in `range`: two cells of
/// one triangle may share a bucket.
#[inline]
fn for_each_bucket(range: Option<(IVec3, IVec3)>, buckets: usize, mut f: impl FnMut(usize)) {
    let Some((lo, hi)) = range else { return };
    let mut used = [usize::MAX; (MAX_SPAN * MAX_SPAN * MAX_SPAN) as usize];
    let mut count = 0;
    for z in lo.z..=hi.z {
        for y in lo.y..=hi.y {
            for x in lo.x..=hi.x {
                let b = bucket(IVec3::new(x, y, z), buckets);
                if used[..count].contains(&b) {
                    continue;
                }
                used[count] = b;
                count += 1;
                f(b);
            }
        }
    }
}

/// The bucket of cell `c` in a table of `buckets` (a power of two).
#[inline]
fn bucket(c: IVec3, buckets: usize) -> usize {
    let h = (c.x as u32).wrapping_mul(73_856_093)
        ^ (c.y as u32).wrapping_mul(19_349_663)
        ^ (c.z as u32).wrapping_mul(83_492_791);
    h as usize & (buckets - 1)
}
/// The substeps of a tick of cloths stepped together with self-contact: the most any of them
/// asks for alone (`own`), so that each keeps its own stability and contact is resolved after
/// every substep of each. Both backends take this rule; `None` for no cloth.
pub fn shared_substeps(own: impl IntoIterator<Item = u32>) -> Option<u32> {
    own.into_iter().max()
}
