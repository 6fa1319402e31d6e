//! Voxel sphere fitting (paper section 2.4.1): the mesh's AABB is cut into `n x n x n` voxels
//! and every voxel that holds at least one vertex gets a sphere enclosing all of its vertices.
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
//! The radius is then grown by one part in a million so that rounding never leaves a vertex a
//! hair outside its sphere.
//!
//! The voxels are the mesh's AABB divided evenly per axis, so cells are boxes, not cubes, on a
//! mesh that is longer on one axis. A flat axis (a planar mesh) has a single layer of voxels.

use glam::Vec3;
use rayon::prelude::*;

use crate::error::ColliderError;
use crate::lbvh::Sphere;

/// Largest voxel resolution accepted: 128³ voxels; beyond that the spheres are smaller than
/// any sensible cloth spacing and the voxel table grows past 8 MiB.
pub const MAX_RESOLUTION: u32 = 128;

/// Largest coordinate magnitude accepted, so that squared distances stay finite in `f32`.
pub const MAX_COORDINATE: f32 = 1.0e18;

/// A triangle mesh borrowed from the caller: positions, and an optional triangle-list index
/// buffer (without one, every three consecutive positions form a triangle).
#[derive(Clone, Copy, Debug)]
pub struct MeshRef<'a> {
    /// Vertex positions.
    pub positions: &'a [[f32; 3]],
    /// Triangle-list indices into `positions`.
    pub indices: Option<&'a [u32]>,
}

/// Checks a mesh and returns which vertices its triangles use (`None`: all of them).
fn used_vertices(mesh: MeshRef<'_>) -> Result<Option<Vec<bool>>, ColliderError> {
    if mesh.positions.is_empty() {
        return Err(ColliderError::EmptyMesh);
    }
    let bad = |p: &[f32; 3]| !p.iter().all(|c| c.is_finite() && c.abs() <= MAX_COORDINATE);
    let first_bad = mesh
        .positions
        .par_chunks(CHUNK)
        .enumerate()
        .find_map_first(|(c, chunk)| chunk.iter().position(bad).map(|i| c * CHUNK + i));
    if let Some(vertex) = first_bad {
        let p = mesh.positions[vertex];
        return Err(if p.iter().all(|c| c.is_finite()) {
            ColliderError::VertexTooFar { vertex, limit: MAX_COORDINATE }
        } else {
            ColliderError::NonFiniteVertex { vertex }
        });
    }
    let vertices = mesh.positions.len();
    let Some(indices) = mesh.indices else {
        if !vertices.is_multiple_of(3) {
            return Err(ColliderError::IndicesNotTriangles { len: vertices });
        }
        return Ok(None);
    };
    if indices.is_empty() {
        return Err(ColliderError::NoTriangles);
    }
    if !indices.len().is_multiple_of(3) {
        return Err(ColliderError::IndicesNotTriangles { len: indices.len() });
    }
    let mut used = vec![false; vertices];
    for (position, &index) in indices.iter().enumerate() {
        let Some(flag) = used.get_mut(index as usize) else {
            return Err(ColliderError::IndexOutOfRange { position, index, vertices });
        };
        *flag = true;
    }
    Ok(Some(used))
}

/// The spheres of a voxelised mesh, in voxel order (x fastest, then y, then z).
#[derive(Clone, Debug)]
pub struct VoxelSpheres {
    /// One sphere per non-empty voxel.
    pub spheres: Vec<Sphere>,
    /// The voxel of each sphere, as `x + n (y + n z)`, ascending.
    pub voxels: Vec<u32>,
    /// The mesh's bounding box minimum corner.
    pub mesh_min: Vec3,
    /// The mesh's bounding box maximum corner.
    pub mesh_max: Vec3,
    /// The resolution `n` used.
    pub resolution: u32,
}

/// Voxelises `mesh` at resolution `n` and fits one sphere per non-empty voxel.
pub fn voxel_spheres(mesh: MeshRef<'_>, n: u32) -> Result<VoxelSpheres, ColliderError> {
    if n == 0 {
        return Err(ColliderError::ZeroResolution);
    }
    if n > MAX_RESOLUTION {
        return Err(ColliderError::ResolutionTooHigh { n, max: MAX_RESOLUTION });
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

    let grid = VoxelGrid::new(min, max, n);
    // Counting sort of the used vertices by voxel: keys, counts, prefix sums, scatter.
    let cells = (n as usize).pow(3);
    let mut keys = vec![UNUSED; positions.len()];
    keys.par_chunks_mut(CHUNK).zip(positions.par_chunks(CHUNK)).enumerate().for_each(|(c, (keys, chunk))| {
        for (j, (key, &p)) in keys.iter_mut().zip(chunk).enumerate() {
            if is_used(c * CHUNK + j) {
                *key = grid.voxel_of(Vec3::from(p));
            }
        }
    });
    let mut start = vec![0u32; cells + 1];
    for &k in keys.iter().filter(|&&k| k != UNUSED) {
        start[k as usize + 1] += 1;
    }
    for i in 0..cells {
        start[i + 1] += start[i];
    }
    let mut cursor = start.clone();
    let mut grouped = vec![Vec3::ZERO; start[cells] as usize];
    for (&k, &p) in keys.iter().zip(positions).filter(|&(&k, _)| k != UNUSED) {
        let slot = &mut cursor[k as usize];
        grouped[*slot as usize] = Vec3::from(p);
        *slot += 1;
    }

    let occupied: Vec<(u32, u32, u32)> =
        start.windows(2).enumerate().filter(|(_, w)| w[1] > w[0]).map(|(key, w)| (key as u32, w[0], w[1])).collect();
    let spheres =
        occupied.par_iter().map(|&(_, lo, hi)| enclosing_sphere(&grouped[lo as usize..hi as usize])).collect();
    let voxels = occupied.into_iter().map(|(key, _, _)| key).collect();
    Ok(VoxelSpheres { spheres, voxels, mesh_min: min, mesh_max: max, resolution: n })
}

/// Vertices per parallel task in the passes over the whole mesh.
const CHUNK: usize = 1 << 14;

/// The voxel key of a vertex no triangle uses.
const UNUSED: u32 = u32::MAX;

/// The voxel grid over a mesh's AABB.
#[derive(Clone, Copy, Debug)]
struct VoxelGrid {
    min: Vec3,
    /// Voxels per unit length on each axis (0 on a flat axis).
    inv_cell: Vec3,
    n: u32,
}

impl VoxelGrid {
    fn new(min: Vec3, max: Vec3, n: u32) -> Self {
        let extent = max - min;
        let inv_cell = Vec3::select(extent.cmpgt(Vec3::ZERO), Vec3::splat(n as f32) / extent, Vec3::ZERO);
        Self { min, inv_cell, n }
    }

    /// The voxel holding `p`, as `x + n (y + n z)`; points on the far faces go to the last layer.
    fn voxel_of(&self, p: Vec3) -> u32 {
        // `as` truncates, which is `floor` here because the offset is not negative (and it
        // saturates, should rounding push a point a hair outside the box).
        let q = ((p - self.min) * self.inv_cell).max(Vec3::ZERO);
        let cell = |x: f32| (x as u32).min(self.n - 1);
        cell(q.x) + self.n * (cell(q.y) + self.n * cell(q.z))
    }
}

impl VoxelSpheres {
    /// The voxel a point of the mesh falls in, in the numbering of [`Self::voxels`].
    pub fn voxel_of(&self, p: Vec3) -> u32 {
        VoxelGrid::new(self.mesh_min, self.mesh_max, self.resolution).voxel_of(p)
    }

    /// The sphere of the voxel holding `p`, if that voxel is not empty.
    pub fn sphere_of(&self, p: Vec3) -> Option<&Sphere> {
        let key = self.voxel_of(p);
        self.voxels.binary_search(&key).ok().map(|i| &self.spheres[i])
    }
}

/// The smaller of the box-centre and centroid spheres around `points` (see the module docs).
pub fn enclosing_sphere(points: &[Vec3]) -> Sphere {
    debug_assert!(!points.is_empty());
    let (lo, hi) = points.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &p| (lo.min(p), hi.max(p)));
    let box_centre = 0.5 * (lo + hi);
    let centroid = points.iter().copied().sum::<Vec3>() / points.len() as f32;
    let radius_around = |c: Vec3| points.iter().map(|&p| p.distance(c)).fold(0.0f32, f32::max);
    let (r_box, r_centroid) = (radius_around(box_centre), radius_around(centroid));
    let (centre, radius) = if r_centroid < r_box { (centroid, r_centroid) } else { (box_centre, r_box) };
    Sphere::new(centre, radius * (1.0 + 1.0e-6))
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
        assert!((s.radius - 0.75f32.sqrt()).abs() < 1e-5);
    }

    #[test]
    fn corners_fall_in_corner_voxels() {
        let (p, idx) = cube();
        let v = voxel_spheres(MeshRef { positions: &p, indices: Some(&idx) }, 3).unwrap();
        assert_eq!(v.spheres.len(), 8);
        assert!(v.spheres.iter().all(|s| s.radius < 1e-5));
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
        assert_eq!(v.spheres.len(), 4);
    }
}
