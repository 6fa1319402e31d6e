//! Exact contact: the cloth collides with a mesh's own triangles, held at a thickness above
//! them, instead of with the voxel spheres around them.
//!
//! A collider gets it from [`Collider::from_mesh_exact`](crate::Collider::from_mesh_exact),
//! which builds the spheres and the triangles from one mesh, and says the thickness it keeps
//! with [`Collider::contact_thickness`](crate::Collider::contact_thickness).
//!
//! # Broad phase
//!
//! The triangles are arranged in the same Morton-code LBVH as the voxel spheres ([`Lbvh`]), one
//! leaf per triangle, each leaf the triangle's bounding sphere; the inner boxes are fitted to
//! the triangles themselves. A voxel would hold hundreds of
//! triangles at the paper's `n = 5` (about 900 on the 70,000-triangle bunny), so a tree whose
//! leaves are single triangles keeps the narrow phase to the few triangles within a thickness
//! of the particle whatever `n` the voxel spheres were built with, and the same traversal
//! serves both. The CPU walks a four-wide copy of it ([`WideBvh`]), whose nodes test four of the
//! binary tree's boxes at once, kept in 8 bits a bound; the GPU walks the binary tree, built
//! again from the triangles when it is uploaded ([`TriangleSurface::binary_tree`]), which meets
//! the triangles in the same order.
//!
//! # Response
//!
//! With thickness `h` (the collider's margin), a particle going from `prev` to `p` in a
//! substep, in the collider's frame:
//!
//! 1. **Contacts.** Every triangle within `h` (and the [`CONTACT_BAND`] beyond it) of `prev`
//!    holds the end point on `prev`'s side: at least `h` above the plane through the
//!    triangle's closest point to `prev`, normal to the direction from that point to `prev`.
//!    That direction is the surface's distance gradient, so on a face it is the face normal
//!    and round an edge or a corner it turns smoothly. Each contact that held the end point
//!    takes the normal part off the velocity, with friction, as the sphere response does.
//! 2. **Sweep.** If the path from `prev` to the held end point crosses a triangle, the
//!    particle stops `h` off the first one it crosses, on `prev`'s side.
//! 3. **Clearance.** If the end point is still within `h` of a triangle (one that was not
//!    within reach of `prev`), it is pushed out along the direction from that triangle, at
//!    most [`MAX_PASSES`] times.
//! 4. **Guard.** If the path from `prev` to the final point crosses any triangle, the particle
//!    stays at `prev`. When neither the sweep nor the clearance moved the end point, the sweep
//!    has just tested this very path, so the guard is not run again.
//!
//! A particle whose path is no longer than the band, with no triangle within the band plus
//! the path's length of `prev` (step 1 looks that far), is free at once: no triangle is near
//! enough to its path or its end for steps 2 to 4 to find. Such particles (most of a hanging
//! cloth) pay for one traversal of the tree instead of three.
//!
//! # The guarantee
//!
//! For a collider that does not move during the substep, the straight path between a
//! particle's two positions crosses no triangle, at any margin, zero included.
//!
//! Two things make that hold in `f32`. The thickness is never less than the surface's
//! [least thickness](TriangleSurface::least_thickness): a millionth of its diagonal, and
//! [`ROUNDING_THICKNESS`] of the coordinates' magnitude, hundreds of times the rounding of a
//! position there, so a particle held at the thickness is clearly on its side. And the
//! crossing test ([`segment_hit`]) counts a path that ends on a plane, or past it by less than
//! the rounding of its distance to it, as reaching it, and decides which side of an edge a
//! path passes from the edge alone, so two triangles that share an edge cannot both miss a
//! path through it. So a particle never passes through the
//! surface, whatever its thickness or speed: not through a thin plate, not through an open
//! mesh, and not into a closed one. A particle that starts inside a closed mesh (the collider
//! was placed over it) stays inside; nothing here can tell the inside of an open mesh.
//!
//! At an open border a particle slides round the border's edge, held `h` from it, onto the
//! other side: the border is a rounded rim, not a wall.
//!
//! Degenerate triangles (no area, or a non-finite corner) are left out when the surface is
//! built; duplicated, sliver, inverted and intersecting triangles are used as they are, since
//! the response needs neither a winding nor a closed mesh.

use glam::{Vec3, Vec4};
use rayon::prelude::*;

use crate::bvh::lbvh::{Lbvh, Sphere};
use crate::bvh::wide::{MAX_LEAVES, WideBvh};
use crate::colliders::error::ColliderError;
use crate::colliders::pose::ColliderPose;
use crate::colliders::response::{CONTACT_BAND, MAX_PASSES, Response};
use crate::mesh::MeshRef;
use crate::mesh::triangles::{
    EDGE_SLACK, closest_point, face_normal, has_area, lane_bound, segment_hit, squared_distances_4,
};

/// The triangles of a mesh in an LBVH, for exact contact.
///
/// It keeps the triangles and the four-wide tree the CPU's queries walk, about 52 bytes a
/// triangle; the binary tree the GPU walks is built again from the triangles when it is
/// uploaded ([`Self::binary_tree`]).
#[derive(Clone, Debug)]
pub struct TriangleSurface {
    /// The LBVH over the triangles' bounding spheres folded four wide, each leaf's box the
    /// triangle's: leaf `k` is `triangles[k]`. The CPU's queries walk it.
    pub wide: WideBvh,
    /// The triangles in leaf order, in the mesh's coordinates.
    pub triangles: Vec<[Vec3; 3]>,
    /// Triangles of the mesh left out because they have no area (or a non-finite corner).
    pub dropped: usize,
    /// The least thickness a response uses, in the mesh's units: a millionth of the surface's
    /// bounding box diagonal, and at least [`ROUNDING_THICKNESS`] of its largest coordinate, so
    /// that a zero margin keeps a particle off the plane it rests on by far more than `f32` can
    /// round a position there. [`Self::least_thickness`] adds the collider's placement.
    pub min_thickness: f32,
    /// The largest of the triangles' bounding radii.
    pub max_radius: f32,
}

/// The least thickness of exact contact relative to the coordinates' magnitude: 256 times
/// `f32::EPSILON`, so 256 steps of `f32` at that magnitude (15 µm for a mesh reaching 0.5 m
/// from its origin), far above the rounding of a position, of a distance to a plane
/// ([`PLANE_ROUNDING`](crate::mesh::triangles::PLANE_ROUNDING)) and of the move between the world and the collider's frame.
pub const ROUNDING_THICKNESS: f32 = 256.0 * f32::EPSILON;

/// The rounding of a distance at a point, relative to the point's largest coordinate, ten
/// times over: the lookout of [`TriangleSurface::respond`] is widened by it.
pub const LOOKOUT_ROUNDING: f32 = 10.0 * f32::EPSILON;

/// Above this many triangles the surface is built on the rayon pool.
const PARALLEL_MIN: usize = 16_384;

impl TriangleSurface {
    /// The triangles of `mesh` with an area, in an LBVH of their bounding spheres. Fails with
    /// [`ColliderError::NoArea`] when none has an area, and with
    /// [`ColliderError::TooManyTriangles`] above 2^29 of them; indices out of range are skipped (a
    /// collider's mesh is checked before it gets here).
    pub fn build(mesh: MeshRef<'_>) -> Result<Self, ColliderError> {
        let corner = |i: u32| mesh.positions.get(i as usize).map(|&p| Vec3::from(p));
        let count = mesh.indices.map_or(mesh.positions.len() / 3, |i| i.len() / 3);
        let corners = |t: u32| -> Option<[Vec3; 3]> {
            let t = t as usize;
            let ids = match mesh.indices {
                Some(indices) => [indices[3 * t], indices[3 * t + 1], indices[3 * t + 2]],
                None => [3 * t as u32, 3 * t as u32 + 1, 3 * t as u32 + 2],
            };
            Some([corner(ids[0])?, corner(ids[1])?, corner(ids[2])?])
        };
        // Every triangle's bounding sphere in one pass over the mesh, a negative radius for one
        // without an area; then the kept triangles by index, read from the mesh again where
        // needed: the mesh's triangles are copied once, in leaf order (a build's memory is
        // mostly fresh pages). When every triangle has an area (most meshes), the kept ones
        // are all of them, in order, and the spheres are kept as they are.
        let sphere_of = |t: u32| match corners(t) {
            Some(c) if has_area(c) => bounding_sphere(&c),
            _ => Sphere { center: [0.0; 3], radius: -1.0 },
        };
        let parallel = count >= PARALLEL_MIN;
        let all: Vec<Sphere> = if parallel {
            (0..count as u32).into_par_iter().map(sphere_of).collect()
        } else {
            (0..count as u32).map(sphere_of).collect()
        };
        let (kept, spheres): (Vec<u32>, Vec<Sphere>) = if all.iter().all(|s| s.radius >= 0.0) {
            ((0..count as u32).collect(), all)
        } else {
            (0..count as u32).zip(all).filter(|(_, s)| s.radius >= 0.0).unzip()
        };
        if kept.is_empty() {
            return Err(ColliderError::NoArea);
        }
        if kept.len() > MAX_LEAVES {
            return Err(ColliderError::TooManyTriangles { triangles: kept.len(), max: MAX_LEAVES });
        }
        // Every kept triangle has its corners.
        let kept_triangle = |t: u32| corners(t).unwrap_or_default();
        let parallel = kept.len() >= PARALLEL_MIN;
        // The spheres give the Morton codes and the largest radius; the boxes are the
        // triangles' own, not their spheres' (up to twice as wide), so that a query descends
        // only where a triangle may be.
        let max_radius = spheres.iter().fold(0.0f32, |r, s| r.max(s.radius));
        let (keys, order) = Lbvh::sorted_keys(&spheres);
        drop(spheres);
        let triangles: Vec<[Vec3; 3]> = if parallel {
            order.par_iter().map(|&k| kept_triangle(kept[k as usize])).collect()
        } else {
            order.iter().map(|&k| kept_triangle(kept[k as usize])).collect()
        };
        // The wide tree is folded straight from the sorted keys, its boxes found on the way up:
        // the binary tree is never built (the GPU's is built, fitted, when it is uploaded).
        let leaf_box = |k: u32| triangle_box(&triangles[k as usize]);
        let (wide, (lo, hi)) = WideBvh::from_keys(&keys, leaf_box);
        drop(keys);
        let magnitude = lo.abs().max(hi.abs()).max_element();
        let min_thickness = (1.0e-6 * lo.distance(hi)).max(ROUNDING_THICKNESS * magnitude);
        Ok(Self { wide, triangles, dropped: count - kept.len(), min_thickness, max_radius })
    }

    /// The bytes the surface keeps on the heap: its triangles and its wide tree.
    pub fn heap_bytes(&self) -> usize {
        self.triangles.capacity() * size_of::<[Vec3; 3]>() + self.wide.bytes()
    }

    /// The point of the surface closest to `p` within `reach`, if any is.
    ///
    /// A nearest-first descent of the wide tree: the reach shrinks to the closest triangle
    /// found so far, the nearer children are visited first, and a child is skipped when its box
    /// lies farther than that. A node's leaves are measured four at a time, side by side in
    /// SIMD lanes without a branch, and only a triangle that may be nearer than the closest so
    /// far is measured again exactly ([`closest_point`]), which gives the answer.
    pub fn closest_within(&self, p: Vec3, reach: f32) -> Option<Vec3> {
        let mut point = None;
        // A triangle nearer than `best` has its corners within `best` and its width of `p`.
        let bound = |best: f32| lane_bound(best, best.sqrt() + 2.0 * self.max_radius);
        self.wide.nearest(p, reach * reach, &self.triangles, |leaves, mut best| {
            let mut within = bound(best);
            for leaves in leaves.chunks(4) {
                // The lanes past the leaves repeat the first.
                let tris: [&[Vec3; 3]; 4] =
                    std::array::from_fn(|lane| &self.triangles[leaves[lane.min(leaves.len() - 1)] as usize]);
                let lanes = squared_distances_4(p, tris);
                // The bound only shrinks, so a lane above it now stays above it: most batches
                // end here.
                let mut candidates = lanes.cmple(Vec4::splat(within)).bitmask() & ((1 << leaves.len()) - 1);
                if candidates == 0 {
                    continue;
                }
                // The nearest lane first, so that the others meet the least `best`; then the
                // other candidates in lane order.
                let lanes = lanes.to_array();
                let first = (1..leaves.len()).fold(0, |m, lane| if lanes[lane] < lanes[m] { lane } else { m });
                let mut lane = first;
                loop {
                    if lanes[lane] <= within {
                        let q = closest_point(p, *tris[lane]);
                        let d2 = q.distance_squared(p);
                        if d2 < best {
                            (point, best, within) = (Some(q), d2, bound(d2));
                        }
                    }
                    candidates &= !(1 << first) & !(1 << lane);
                    if candidates == 0 {
                        break;
                    }
                    lane = candidates.trailing_zeros() as usize;
                }
            }
            best
        });
        point
    }

    /// The farthest off a triangle the sweep may find a crossing, ten times over: the slack
    /// [`segment_hit`] allows at the edges is [`EDGE_SLACK`] of edges at most twice the largest
    /// bounding radius. [`Self::first_crossing`] grows the triangles' boxes by it, and
    /// [`Self::respond`] looks that much farther round `prev` (and [`LOOKOUT_ROUNDING`] of
    /// `prev`'s size) before it calls a short path free.
    pub fn sweep_slack(&self) -> f32 {
        20.0 * EDGE_SLACK * self.max_radius
    }

    /// The binary LBVH the wide tree was folded from, built again from the triangles: leaf `k`
    /// is `triangles[k]` (the triangles are in its leaves' Morton order, which a stable sort
    /// keeps), each leaf the triangle's bounding sphere, the inner boxes fitted to the
    /// triangles. The GPU walks it; a box query meets the triangles in the order the wide tree
    /// does.
    pub fn binary_tree(&self) -> Lbvh {
        let spheres: Vec<Sphere> = if self.triangles.len() >= PARALLEL_MIN {
            self.triangles.par_iter().map(bounding_sphere).collect()
        } else {
            self.triangles.iter().map(bounding_sphere).collect()
        };
        let (mut tree, order) = Lbvh::build_unfitted(&spheres);
        debug_assert!(order.iter().enumerate().all(|(k, &o)| k as u32 == o), "the triangles are in leaf order");
        tree.fit_boxes_by(|k| triangle_box(&self.triangles[k as usize]));
        tree
    }

    /// The least thickness of a response at `pose`, in the mesh's units: [`Self::min_thickness`],
    /// and [`ROUNDING_THICKNESS`] of the pose's distance from the world's origin, since a
    /// particle's position is rounded there too.
    pub fn least_thickness(&self, pose: &ColliderPose) -> f32 {
        let placed = ROUNDING_THICKNESS * pose.translation.abs().max_element() / pose.scale;
        if placed.is_finite() { self.min_thickness.max(placed) } else { self.min_thickness }
    }

    /// Whether `p` is closer than `thickness` to the surface.
    pub fn within(&self, p: Vec3, thickness: f32) -> bool {
        self.closest_within(p, thickness).is_some()
    }

    /// The first triangle the segment from `p` to `q` crosses: its parameter along the segment
    /// and the triangle.
    pub fn first_crossing(&self, p: Vec3, q: Vec3) -> Option<(f32, [Vec3; 3])> {
        let mut first: Option<(f32, [Vec3; 3])> = None;
        // Grown by the slack: a crossing within it of an edge may lie just off the triangle's
        // box.
        self.wide.for_each_overlapping(p.min(q), p.max(q), self.sweep_slack(), |k| {
            let tri = self.triangles[k as usize];
            if let Some(t) = segment_hit(p, q, tri)
                && first.is_none_or(|(best, _)| t < best)
            {
                first = Some((t, tri));
            }
        });
        first
    }

    /// The response of the module docs for a particle going from `prev` to `p` (the surface's
    /// frame), held `thickness` off the triangles. `touch(normal)` is called for each contact,
    /// in order, with the unit normal pointing to the particle's side.
    pub fn respond(&self, prev: Vec3, p: Vec3, thickness: f32, mut touch: impl FnMut(Vec3)) -> Response {
        let h = thickness.max(self.min_thickness);
        let band = h * (1.0 + CONTACT_BAND);
        let mut target = p;
        let mut touched = false;

        // 1. Contacts at the previous position. A short path is looked along too: with no
        // triangle within the band plus the path's length of `prev`, none is within reach of
        // the path or of its end, so steps 2 to 4 could only find nothing.
        let path = prev.distance(p);
        let short = path <= band;
        let lookout =
            if short { band + path + self.sweep_slack() + LOOKOUT_ROUNDING * prev.abs().max_element() } else { band };
        let mut near = false;
        self.wide.for_each_overlapping(prev, prev, lookout, |k| {
            let tri = self.triangles[k as usize];
            let q = closest_point(prev, tri);
            let away = prev - q;
            let distance = away.length();
            if distance >= lookout {
                return;
            }
            near = true;
            if distance >= band {
                return;
            }
            let n = if distance > 1.0e-3 * h { away / distance } else { facing(tri, prev - p) };
            let below = (target - q).dot(n) - h;
            if below < 0.0 {
                target -= below * n;
                touched = true;
                touch(n);
            }
        });
        if short && !near {
            return Response::Free;
        }

        // 2. Sweep: stop off the first triangle the path crosses. `clear` while the path to
        // `target` is known to cross nothing.
        let mut clear = true;
        if let Some((t, tri)) = self.first_crossing(prev, target) {
            let hit = prev.lerp(target, t);
            let n = facing(tri, prev - hit);
            target = hit + n * h;
            touched = true;
            clear = false;
            touch(n);
        }

        // 3. Clearance from triangles the end point came near.
        for _ in 0..MAX_PASSES {
            let Some(q) = self.closest_within(target, h * (1.0 - CONTACT_BAND)) else { break };
            let away = target - q;
            let n = away.try_normalize().unwrap_or_else(|| (prev - target).normalize_or(Vec3::Y));
            target = q + n * h;
            touched = true;
            clear = false;
            touch(n);
        }

        // 4. Guard, unless the sweep has just found this very path clear.
        if !touched {
            return Response::Free;
        }
        if !clear && self.first_crossing(prev, target).is_some() { Response::Stay } else { Response::Moved(target) }
    }
}

/// The triangle's unit normal turned to the side `towards` points to (the face normal by
/// winding when `towards` lies in the plane; +Y for a triangle without one).
fn facing(tri: [Vec3; 3], towards: Vec3) -> Vec3 {
    let n = face_normal(tri).unwrap_or(Vec3::Y);
    if n.dot(towards) < 0.0 { -n } else { n }
}

/// The triangle's box.
fn triangle_box([a, b, c]: &[Vec3; 3]) -> (Vec3, Vec3) {
    (a.min(*b).min(*c), a.max(*b).max(*c))
}

/// A sphere around the triangle: centred on its box, through its farthest corner.
fn bounding_sphere(tri: &[Vec3; 3]) -> Sphere {
    let centre = 0.5 * (tri[0].min(tri[1]).min(tri[2]) + tri[0].max(tri[1]).max(tri[2]));
    let radius = tri.iter().map(|p| p.distance(centre)).fold(0.0f32, f32::max);
    Sphere::new(centre, radius)
}
