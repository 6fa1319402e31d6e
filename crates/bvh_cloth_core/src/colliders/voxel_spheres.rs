//! Voxel sphere fitting (paper section 2.4.1): the mesh's AABB is cut into `n x n x n` voxels
//! (or, given a voxel size, into as many near-cubic voxels along each axis as that size needs;
//! see [`Voxels`]) and every voxel the surface passes through gets a sphere enclosing the
//! surface in it.
//!
//! # Which points a sphere encloses
//!
//! The paper fits each sphere to the vertices in its voxel. That covers the surface only while
//! triangles are small next to voxels: once a triangle spans several voxels, the part of it near
//! a voxel boundary may lie in no sphere (on the bunny at n = 64 a draped cloth fell straight
//! through such gaps), and a voxel the triangle crosses without holding a vertex gets no sphere
//! at all. So each voxel's points are its vertices plus, for every triangle that spans more than
//! one voxel, the corners of the triangle's part in that voxel (found by clipping the triangle
//! against the grid's planes).
//! A sphere encloses the convex hull of its points, hence that whole part, and the union of the
//! spheres covers every triangle. Where no triangle crosses a voxel boundary (low `n`, fine
//! meshes) the spheres are exactly the paper's.
//!
//! # How a sphere is fitted
//!
//! For the vertices `V` of one voxel two candidate centres are tried: the centre of `V`'s own
//! bounding box and `V`'s centroid. Each candidate's radius is the largest distance from it to a
//! vertex of `V`, so both spheres enclose every vertex by construction; the smaller one is kept.
//! The box centre is optimal for a single long cluster (its radius is at most half the box
//! diagonal, within `sqrt(3)` of the minimum enclosing sphere); the centroid wins when most
//! vertices crowd one side of the voxel, as on a curved surface patch. Both cost two linear
//! passes, which keeps the build far below a millisecond per thousand vertices, whereas an exact
//! minimum enclosing sphere (Welzl) would add an expected-linear but much slower randomised step.
//! The radius is then grown by [`SURFACE_CLEARANCE`] of the voxel's diagonal.
//!
//! # Why the spheres reach past the surface
//!
//! A sphere fitted exactly has its farthest points on its surface, and on a flat face those are
//! the corners of the voxel's piece, which the neighbouring voxels' spheres also only touch. So
//! where four pieces meet, the exactly fitted spheres leave a pinhole of zero width straight
//! through the shell, and a cloth resting in the dip at that corner slides through it. Grown
//! by `δ`, every sphere holds the points of its piece at least `δ` inside, so the spheres
//! together contain every point within `δ` of the surface: the shell is at least `2δ` thick
//! everywhere, and a path that crosses the mesh's surface must enter a sphere (which is what
//! the collision response tests, see [`crate::colliders::collision`]).
//!
//! The voxels are the mesh's AABB divided evenly per axis, so cells are boxes, not cubes, on a
//! mesh that is longer on one axis. A flat axis (a planar mesh) has a single layer of voxels.
//!
//! # Memory
//!
//! The points are never stored. Two parallel passes over the vertices and the clipped pieces
//! keep running figures per voxel instead: the first its box, point count and coordinate sum
//! (so both candidate centres), the second each candidate's largest distance. Memory is then
//! bounded by the voxel count (52 bytes a voxel, about 104 MiB at `n = 128`) plus 5 bytes a
//! vertex, however many triangles cross however many voxels. Every large allocation is tried
//! first, and one that fails is [`ColliderError::OutOfMemory`], never an abort.
//!
//! The running sums are fixed-point integers, so the passes give the same spheres whatever the
//! order the threads add their points in.

use std::sync::atomic::{AtomicI64, AtomicU32, Ordering::Relaxed};

use glam::{UVec3, Vec3};
use rayon::prelude::*;

use crate::bvh::lbvh::Sphere;
use crate::colliders::error::ColliderError;
use crate::colliders::voxel_grid::VoxelGrid;
use crate::mesh::MeshRef;

/// Largest voxel resolution accepted: 128³ voxels; beyond that the spheres are smaller than
/// any sensible cloth spacing and the voxel table grows past 8 MiB.
pub const MAX_RESOLUTION: u32 = 128;

/// Most voxels a grid may have, whichever way it is given: `MAX_RESOLUTION³`.
pub const MAX_VOXELS: u64 = (MAX_RESOLUTION as u64).pow(3);

/// How a mesh's bounding box is cut into voxels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Voxels {
    /// `n` voxels along every axis of the box, whatever its shape: the paper's `n x n x n`.
    PerAxis(u32),
    /// Cubes of this side (the mesh's units) as near as whole counts allow: each axis of the box
    /// gets `ceil(extent / size)` voxels (at least one), so that the meshes of one scene built
    /// with one size have voxels of one size, whatever their extents.
    Size(f32),
}

impl Voxels {
    /// The voxels along each axis of a box of `extent`, checked.
    pub fn counts(self, extent: Vec3) -> Result<UVec3, ColliderError> {
        match self {
            Self::PerAxis(0) => Err(ColliderError::ZeroResolution),
            Self::PerAxis(n) if n > MAX_RESOLUTION => Err(ColliderError::ResolutionTooHigh { n, max: MAX_RESOLUTION }),
            Self::PerAxis(n) => Ok(UVec3::splat(n)),
            Self::Size(size) if !(size.is_finite() && size > 0.0) => Err(ColliderError::BadVoxelSize(size)),
            Self::Size(size) => {
                let counts = (extent / size).ceil().max(Vec3::ONE);
                let voxels = f64::from(counts.x) * f64::from(counts.y) * f64::from(counts.z);
                if voxels > MAX_VOXELS as f64 {
                    return Err(ColliderError::TooManyVoxels { size, voxels: voxels as u64, max: MAX_VOXELS });
                }
                Ok(counts.as_uvec3())
            }
        }
    }
}

/// How far every sphere reaches beyond the part of the surface it encloses, as a fraction of
/// the voxel's diagonal (see the module docs): 0.27 mm on a 1 m mesh at `n = 64`.
pub const SURFACE_CLEARANCE: f32 = 0.01;

/// Checks a mesh and returns which vertices its triangles use (`None`: all of them).
fn used_vertices(mesh: MeshRef<'_>) -> Result<Option<Vec<bool>>, ColliderError> {
    mesh.check()?;
    let Some(indices) = mesh.indices else { return Ok(None) };
    let mut used = filled(mesh.positions.len(), false)?;
    for &index in indices {
        used[index as usize] = true;
    }
    Ok(Some(used))
}

/// The spheres of a voxelised mesh, in voxel order (x fastest, then y, then z).
#[derive(Clone, Debug)]
pub struct VoxelSpheres {
    /// One sphere per non-empty voxel.
    pub spheres: Vec<Sphere>,
    /// The voxel of each sphere, as `x + nx (y + ny z)`, ascending.
    pub voxels: Vec<u32>,
    /// The mesh's bounding box minimum corner.
    pub mesh_min: Vec3,
    /// The mesh's bounding box maximum corner.
    pub mesh_max: Vec3,
    /// The voxels along each axis.
    pub counts: UVec3,
}

/// Voxelises `mesh` at resolution `n` (`n x n x n` voxels) and fits one sphere per non-empty
/// voxel.
pub fn voxel_spheres(mesh: MeshRef<'_>, n: u32) -> Result<VoxelSpheres, ColliderError> {
    voxel_spheres_in(mesh, Voxels::PerAxis(n))
}

/// Voxelises `mesh` into the voxels `voxels` gives and fits one sphere per non-empty voxel.
pub fn voxel_spheres_in(mesh: MeshRef<'_>, voxels: Voxels) -> Result<VoxelSpheres, ColliderError> {
    if let Voxels::PerAxis(_) = voxels {
        // A bad resolution is reported before anything about the mesh.
        voxels.counts(Vec3::ONE)?;
    }
    let used = used_vertices(mesh)?;
    let is_used = |i: usize| used.as_ref().is_none_or(|u| u[i]);
    let positions = mesh.positions;
    let empty = (Vec3::INFINITY, Vec3::NEG_INFINITY);
    let (min, max) = positions
        .par_chunks(CHUNK)
        .enumerate()
        .map(|(c, chunk)| {
            let used = chunk.iter().enumerate().filter(|&(j, _)| is_used(c * CHUNK + j));
            used.fold(empty, |(lo, hi), (_, &p)| (lo.min(Vec3::from(p)), hi.max(Vec3::from(p))))
        })
        .reduce(|| empty, |(a, b), (c, d)| (a.min(c), b.max(d)));
    let extent = max - min;
    if extent.max_element() <= 0.0 {
        return Err(ColliderError::ZeroExtent);
    }

    let n = voxels.counts(extent)?;
    let grid = VoxelGrid::new(min, max, n);
    let mut keys = filled(positions.len(), UNUSED)?;
    keys.par_chunks_mut(CHUNK).zip(positions.par_chunks(CHUNK)).enumerate().for_each(|(c, (keys, chunk))| {
        for (j, (key, &p)) in keys.iter_mut().zip(chunk).enumerate() {
            if is_used(c * CHUNK + j) {
                *key = grid.voxel_of(Vec3::from(p));
            }
        }
    });
    let points = Points { mesh, grid: &grid, keys: &keys };

    // First pass: each voxel's box, point count and coordinate sum.
    let cells = n.x as usize * n.y as usize * n.z as usize;
    let fixed = FixedPoint::new(min, extent);
    let boxes = VoxelBoxes::new(cells)?;
    points.for_each(|key, run| boxes.add(key as usize, run, &fixed));
    let VoxelBoxes { lo, hi, count, sum } = boxes;

    // Each occupied voxel's two candidate centres take the place of its box (as plain `f32`
    // bits), and its sums are cleared to hold each centre's largest squared distance.
    let load =
        |a: &[AtomicU32; 3], decode: fn(u32) -> f32| Vec3::from_array(a.each_ref().map(|x| decode(x.load(Relaxed))));
    let store =
        |a: &[AtomicU32; 3], v: Vec3| a.iter().zip(v.to_array()).for_each(|(x, c)| x.store(c.to_bits(), Relaxed));
    lo.par_iter().zip(&hi).zip(&count).zip(&sum).for_each(|(((lo, hi), count), sum)| {
        let points = count.load(Relaxed);
        if points == 0 {
            return;
        }
        let box_centre = 0.5 * (load(lo, from_ordered) + load(hi, from_ordered));
        let centroid = fixed.mean(sum.each_ref().map(|x| x.load(Relaxed)), points);
        store(lo, box_centre);
        store(hi, centroid);
        sum.iter().for_each(|x| x.store(0, Relaxed));
    });

    // Second pass: the largest squared distance from each candidate centre.
    points.for_each(|key, run| {
        let key = key as usize;
        let centres = [load(&lo[key], f32::from_bits), load(&hi[key], f32::from_bits)];
        for (far, centre) in sum[key].iter().zip(centres) {
            let d2 = run.iter().fold(0.0f32, |d2, &p| d2.max(p.distance_squared(centre)));
            // Non-negative floats order like their bits.
            far.fetch_max(i64::from(d2.to_bits()), Relaxed);
        }
    });

    // The smaller candidate of each occupied voxel, in key order.
    let clearance = SURFACE_CLEARANCE * grid.cell_diagonal();
    let occupied = count.par_iter().filter(|c| c.load(Relaxed) > 0).count();
    let mut spheres = Vec::new();
    spheres.try_reserve_exact(occupied).map_err(|_| out_of_memory::<Sphere>(occupied))?;
    let mut voxels = Vec::new();
    voxels.try_reserve_exact(occupied).map_err(|_| out_of_memory::<u32>(occupied))?;
    for key in (0..cells).filter(|&key| count[key].load(Relaxed) > 0) {
        let [r_box, r_centroid, _] = sum[key].each_ref().map(|far| f32::from_bits(far.load(Relaxed) as u32).sqrt());
        let (centre, radius) = if r_centroid < r_box {
            (load(&hi[key], f32::from_bits), r_centroid)
        } else {
            (load(&lo[key], f32::from_bits), r_box)
        };
        spheres.push(Sphere::new(centre, radius + clearance));
        voxels.push(key as u32);
    }
    Ok(VoxelSpheres { spheres, voxels, mesh_min: min, mesh_max: max, counts: n })
}

/// Where a mesh's points are: its used vertices, and for every triangle that spans more than
/// one voxel the corners of its part in each voxel it passes through.
struct Points<'a> {
    mesh: MeshRef<'a>,
    grid: &'a VoxelGrid,
    /// Each vertex's voxel ([`UNUSED`] for a vertex no triangle uses).
    keys: &'a [u32],
}

impl Points<'_> {
    /// Calls `visit(voxel, points)` for every point, a few points of one voxel at a time, on the
    /// rayon pool, in no fixed order.
    fn for_each(&self, visit: impl Fn(u32, &[Vec3]) + Sync) {
        let positions = self.mesh.positions;
        self.keys.par_chunks(CHUNK).zip(positions.par_chunks(CHUNK)).for_each(|(keys, chunk)| {
            // Runs of neighbouring vertices in one voxel are handed over together.
            let mut run = [Vec3::ZERO; RUN];
            let (mut run_key, mut len) = (UNUSED, 0);
            for (&key, &p) in keys.iter().zip(chunk) {
                if key == UNUSED {
                    continue;
                }
                if key != run_key || len == RUN {
                    if len > 0 {
                        visit(run_key, &run[..len]);
                    }
                    (run_key, len) = (key, 0);
                }
                run[len] = Vec3::from(p);
                len += 1;
            }
            if len > 0 {
                visit(run_key, &run[..len]);
            }
        });
        if self.grid.is_single_voxel() {
            return;
        }
        match self.mesh.indices {
            Some(indices) => {
                self.for_each_crossing(indices.len() / 3, |t| [0, 1, 2].map(|k| indices[3 * t + k] as usize), &visit)
            }
            None => self.for_each_crossing(positions.len() / 3, |t| [0, 1, 2].map(|k| 3 * t + k), &visit),
        }
    }

    /// The corners of the pieces of `count` triangles whose vertex indices `corners` gives, one
    /// piece at a time. A triangle whose corners share one voxel is skipped without reading
    /// positions.
    fn for_each_crossing(
        &self,
        count: usize,
        corners: impl Fn(usize) -> [usize; 3] + Sync,
        visit: &(impl Fn(u32, &[Vec3]) + Sync),
    ) {
        let (positions, keys) = (self.mesh.positions, self.keys);
        (0..count).into_par_iter().with_min_len(CHUNK / 64).for_each(|t| {
            let vertices = corners(t);
            let [a, b, c] = vertices.map(|i| keys[i]);
            if a == b && a == c {
                return;
            }
            let triangle = vertices.map(|i| Vec3::from(positions[i]));
            self.grid.for_each_piece(triangle, |key, piece| {
                // A corner that is one of the triangle's vertices, in that vertex's own voxel,
                // is among the voxel's points already.
                let known = |p: Vec3| (0..3).any(|k| triangle[k] == p && keys[vertices[k]] == key);
                let mut new = [Vec3::ZERO; RUN];
                let mut len = 0;
                for &p in piece.corners().iter().filter(|&&p| !known(p)) {
                    new[len] = p;
                    len += 1;
                }
                if len > 0 {
                    visit(key, &new[..len]);
                }
            });
        });
    }
}

/// Most points handed over at once: at least the corners of a clipped piece.
const RUN: usize = 16;

/// Per-voxel running figures of the first pass: the box (as ordered bits, see [`ordered`]),
/// the point count and the fixed-point coordinate sum. The second pass reuses them.
struct VoxelBoxes {
    lo: Vec<[AtomicU32; 3]>,
    hi: Vec<[AtomicU32; 3]>,
    count: Vec<AtomicU32>,
    sum: Vec<[AtomicI64; 3]>,
}

impl VoxelBoxes {
    fn new(cells: usize) -> Result<Self, ColliderError> {
        let atomics = |init: u32| -> Result<Vec<[AtomicU32; 3]>, ColliderError> {
            let mut v = Vec::new();
            v.try_reserve_exact(cells).map_err(|_| out_of_memory::<[AtomicU32; 3]>(cells))?;
            v.resize_with(cells, || [AtomicU32::new(init), AtomicU32::new(init), AtomicU32::new(init)]);
            Ok(v)
        };
        let (lo, hi) = (atomics(u32::MAX)?, atomics(0)?);
        let mut count = Vec::new();
        count.try_reserve_exact(cells).map_err(|_| out_of_memory::<AtomicU32>(cells))?;
        count.resize_with(cells, || AtomicU32::new(0));
        let mut sum = Vec::new();
        sum.try_reserve_exact(cells).map_err(|_| out_of_memory::<[AtomicI64; 3]>(cells))?;
        sum.resize_with(cells, || [AtomicI64::new(0), AtomicI64::new(0), AtomicI64::new(0)]);
        Ok(Self { lo, hi, count, sum })
    }

    /// Adds `points`, all in voxel `key`.
    fn add(&self, key: usize, points: &[Vec3], fixed: &FixedPoint) {
        let (lo, hi) = points.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &p| (lo.min(p), hi.max(p)));
        for axis in 0..3 {
            self.lo[key][axis].fetch_min(ordered(lo[axis]), Relaxed);
            self.hi[key][axis].fetch_max(ordered(hi[axis]), Relaxed);
            self.sum[key][axis].fetch_add(points.iter().map(|&p| fixed.to_fixed(p, axis)).sum(), Relaxed);
        }
        self.count[key].fetch_add(points.len() as u32, Relaxed);
    }
}

/// Coordinates as integers: `2^24` steps across the mesh's box on each axis, so that sums are
/// exact and do not depend on the order of the additions.
struct FixedPoint {
    min: Vec3,
    to_steps: Vec3,
    to_length: Vec3,
}

impl FixedPoint {
    const STEPS: f32 = (1u32 << 24) as f32;

    fn new(min: Vec3, extent: Vec3) -> Self {
        // An axis too thin for its steps to be finite (an extent of 1e-34 m) counts as flat.
        let steps = Self::STEPS / extent;
        let to_steps = Vec3::select(extent.cmpgt(Vec3::ZERO) & steps.is_finite_mask(), steps, Vec3::ZERO);
        Self { min, to_steps, to_length: extent / Self::STEPS }
    }

    /// The coordinate in steps from the box's corner, held within the box (twice its steps,
    /// for rounding), so that no sum of a voxel's points can overflow.
    fn to_fixed(&self, p: Vec3, axis: usize) -> i64 {
        ((p[axis] - self.min[axis]) * self.to_steps[axis]).round().clamp(0.0, 2.0 * Self::STEPS) as i64
    }

    /// The mean of `count` points whose fixed-point coordinates sum to `sum`.
    fn mean(&self, sum: [i64; 3], count: u32) -> Vec3 {
        let steps = Vec3::from_array(sum.map(|s| (s as f64 / count as f64) as f32));
        self.min + steps * self.to_length
    }
}

/// `f32` bits mapped so that unsigned order is float order (for finite values).
fn ordered(x: f32) -> u32 {
    let bits = x.to_bits();
    if bits & 0x8000_0000 != 0 { !bits } else { bits | 0x8000_0000 }
}

/// The inverse of [`ordered`].
fn from_ordered(bits: u32) -> f32 {
    f32::from_bits(if bits & 0x8000_0000 != 0 { bits & 0x7fff_ffff } else { !bits })
}

/// A vector of `len` copies of `value`, or [`ColliderError::OutOfMemory`].
fn filled<T: Clone>(len: usize, value: T) -> Result<Vec<T>, ColliderError> {
    let mut v = Vec::new();
    v.try_reserve_exact(len).map_err(|_| out_of_memory::<T>(len))?;
    v.resize(len, value);
    Ok(v)
}

fn out_of_memory<T>(len: usize) -> ColliderError {
    ColliderError::OutOfMemory { bytes: len.saturating_mul(size_of::<T>()) }
}

/// Vertices per parallel task in the passes over the whole mesh.
const CHUNK: usize = 1 << 14;

/// The voxel key of a vertex no triangle uses.
const UNUSED: u32 = u32::MAX;

impl VoxelSpheres {
    /// The voxel a point of the mesh falls in, in the numbering of [`Self::voxels`].
    pub fn voxel_of(&self, p: Vec3) -> u32 {
        VoxelGrid::new(self.mesh_min, self.mesh_max, self.counts).voxel_of(p)
    }

    /// The sphere of the voxel holding `p`, if that voxel is not empty.
    pub fn sphere_of(&self, p: Vec3) -> Option<&Sphere> {
        let key = self.voxel_of(p);
        self.voxels.binary_search(&key).ok().map(|i| &self.spheres[i])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cube() -> (Vec<[f32; 3]>, Vec<u32>) {
        let mut p = Vec::new();
        for i in 0..8u32 {
            p.push([(i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32]);
        }
        // Twelve triangles; their exact winding does not matter for voxelisation.
        let idx = vec![
            0, 1, 3, 0, 3, 2, 4, 6, 7, 4, 7, 5, 0, 4, 5, 0, 5, 1, 2, 3, 7, 2, 7, 6, 0, 2, 6, 0, 6, 4, 1, 5, 7, 1, 7, 3,
        ];
        (p, idx)
    }

    #[test]
    fn one_voxel_encloses_the_cube() {
        let (p, idx) = cube();
        let v = voxel_spheres(MeshRef { positions: &p, indices: Some(&idx) }, 1).unwrap();
        assert_eq!(v.spheres.len(), 1);
        let s = v.spheres[0];
        assert!((s.centre() - Vec3::splat(0.5)).length() < 1e-6);
        assert!((s.radius - 0.75f32.sqrt() * (1.0 + 2.0 * SURFACE_CLEARANCE)).abs() < 1e-5, "{s:?}");
    }

    /// How far inside its sphere every point of the surface must be.
    fn clearance(v: &VoxelSpheres) -> f32 {
        SURFACE_CLEARANCE * ((v.mesh_max - v.mesh_min) / v.counts.as_vec3()).length()
    }

    /// Every point of a triangle lies in the sphere of the voxel that holds it, with the
    /// clearance to spare (up to rounding).
    fn assert_covered(v: &VoxelSpheres, triangles: &[[Vec3; 3]]) {
        let clearance = clearance(v);
        for (t, [a, b, c]) in triangles.iter().enumerate() {
            for i in 0..=12 {
                for j in 0..=12 - i {
                    let p = *a + (i as f32 / 12.0) * (*b - *a) + (j as f32 / 12.0) * (*c - *a);
                    let s = v.sphere_of(p).unwrap_or_else(|| panic!("triangle {t}: the voxel of {p} has no sphere"));
                    let depth = s.radius - p.distance(s.centre());
                    assert!(depth >= clearance - 1e-6, "triangle {t}: {p} only {depth} inside its voxel's sphere");
                }
            }
        }
    }

    #[test]
    fn the_cube_surface_gives_every_boundary_voxel_a_sphere_that_covers_it() {
        let (p, idx) = cube();
        let v = voxel_spheres(MeshRef { positions: &p, indices: Some(&idx) }, 3).unwrap();
        // Every voxel but the middle one holds part of a face.
        assert_eq!(v.spheres.len(), 26);
        assert!(v.voxels.binary_search(&13).is_err());
        let triangles: Vec<[Vec3; 3]> =
            idx.chunks(3).map(|t| [0, 1, 2].map(|k| Vec3::from(p[t[k] as usize]))).collect();
        assert_covered(&v, &triangles);
        // A face voxel's sphere is about its face patch (a third of the face on a side), not the
        // whole voxel.
        let corner = v.sphere_of(Vec3::ZERO).unwrap();
        assert!(corner.radius < 0.5 * (3.0f32 / 9.0).sqrt() + clearance(&v) + 1e-5, "{corner:?}");
    }

    #[test]
    fn bad_meshes_are_typed_errors() {
        let (p, idx) = cube();
        let ok = MeshRef { positions: &p, indices: Some(&idx) };
        assert_eq!(voxel_spheres(ok, 0).unwrap_err(), ColliderError::ZeroResolution);
        assert!(matches!(voxel_spheres(ok, 1000), Err(ColliderError::ResolutionTooHigh { .. })));
        let empty = MeshRef { positions: &[], indices: None };
        assert_eq!(voxel_spheres(empty, 3).unwrap_err(), ColliderError::EmptyMesh);
        let mut nan = p.clone();
        nan[5][1] = f32::NAN;
        let m = MeshRef { positions: &nan, indices: Some(&idx) };
        assert_eq!(voxel_spheres(m, 3).unwrap_err(), ColliderError::NonFiniteVertex { vertex: 5 });
        let m = MeshRef { positions: &p, indices: Some(&[0, 1, 99]) };
        assert_eq!(
            voxel_spheres(m, 3).unwrap_err(),
            ColliderError::IndexOutOfRange { position: 2, index: 99, vertices: 8 }
        );
        let m = MeshRef { positions: &p, indices: Some(&[0, 1]) };
        assert_eq!(voxel_spheres(m, 3).unwrap_err(), ColliderError::IndicesNotTriangles { len: 2 });
        let m = MeshRef { positions: &p, indices: Some(&[0, 0, 0]) };
        assert_eq!(voxel_spheres(m, 3).unwrap_err(), ColliderError::ZeroExtent);
        let far = [[2.0e18f32, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let m = MeshRef { positions: &far, indices: None };
        assert!(matches!(voxel_spheres(m, 3), Err(ColliderError::VertexTooFar { vertex: 0, .. })));
    }

    #[test]
    fn planar_mesh_is_accepted() {
        let quad = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 0.0, 1.0], [0.0, 0.0, 1.0]];
        let m = MeshRef { positions: &quad, indices: Some(&[0, 1, 2, 0, 2, 3]) };
        let v = voxel_spheres(m, 4).unwrap();
        // One layer of 4 x 4 cells, all crossed by the quad.
        assert_eq!(v.spheres.len(), 16);
        let corners = quad.map(Vec3::from);
        assert_covered(&v, &[[corners[0], corners[1], corners[2]], [corners[0], corners[2], corners[3]]]);
    }

    /// A voxel size cuts each axis of the box into its own count: a 2 x 1 x 0.5 box at 0.25
    /// has 8 x 4 x 2 voxels, every one of them on the surface, each face covered.
    #[test]
    fn a_voxel_size_gives_each_axis_its_own_count() {
        let (p, idx) = cube();
        let stretched: Vec<[f32; 3]> = p.iter().map(|&[x, y, z]| [2.0 * x, y, 0.5 * z]).collect();
        let v = voxel_spheres_in(MeshRef { positions: &stretched, indices: Some(&idx) }, Voxels::Size(0.25)).unwrap();
        assert_eq!(v.counts, UVec3::new(8, 4, 2));
        assert_eq!(v.spheres.len(), 64);
        let triangles: Vec<[Vec3; 3]> =
            idx.chunks(3).map(|t| [0, 1, 2].map(|k| Vec3::from(stretched[t[k] as usize]))).collect();
        assert_covered(&v, &triangles);
        // A size that does not divide the extent rounds the count up: voxels never grow past it.
        assert_eq!(Voxels::Size(0.3).counts(Vec3::new(2.0, 1.0, 0.5)), Ok(UVec3::new(7, 4, 2)));
    }

    #[test]
    fn bad_voxel_sizes_are_typed_errors() {
        let (p, idx) = cube();
        let mesh = MeshRef { positions: &p, indices: Some(&idx) };
        for size in [0.0, -1.0, f32::NAN, f32::INFINITY] {
            assert!(matches!(voxel_spheres_in(mesh, Voxels::Size(size)), Err(ColliderError::BadVoxelSize(_))));
        }
        // A tenth of a millimetre on a 1 m mesh: 10^12 voxels, refused before any allocation.
        let Err(ColliderError::TooManyVoxels { voxels, max, .. }) = voxel_spheres_in(mesh, Voxels::Size(1e-4)) else {
            panic!("a 0.1 mm voxel on a 1 m mesh must be refused")
        };
        assert!(voxels > 999_000_000_000 && max == MAX_VOXELS, "{voxels} voxels, {max} accepted");
    }
}
