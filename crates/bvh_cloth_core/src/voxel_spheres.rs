//! Voxel sphere fitting (paper section 2.4.1): the mesh's AABB is cut into `n x n x n` voxels
//! and every voxel the surface passes through gets a sphere enclosing the surface in it.
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
//! The radius is then grown by one part in a million so that rounding never leaves a vertex a
//! hair outside its sphere.
//!
//! The voxels are the mesh's AABB divided evenly per axis, so cells are boxes, not cubes, on a
//! mesh that is longer on one axis. A flat axis (a planar mesh) has a single layer of voxels.

use glam::Vec3;
use rayon::prelude::*;

use crate::error::ColliderError;
use crate::lbvh::Sphere;
use crate::voxel_grid::VoxelGrid;

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
    let mut keys = vec![UNUSED; positions.len()];
    keys.par_chunks_mut(CHUNK).zip(positions.par_chunks(CHUNK)).enumerate().for_each(|(c, (keys, chunk))| {
        for (j, (key, &p)) in keys.iter_mut().zip(chunk).enumerate() {
            if is_used(c * CHUNK + j) {
                *key = grid.voxel_of(Vec3::from(p));
            }
        }
    });
    let crossings = crossing_points(mesh, &grid, &keys);
    // Counting sort of the used vertices and the crossing points by voxel: counts, prefix sums,
    // scatter.
    let cells = (n as usize).pow(3);
    let mut start = vec![0u32; cells + 1];
    for &k in keys.iter().filter(|&&k| k != UNUSED).chain(crossings.iter().map(|(k, _)| k)) {
        start[k as usize + 1] += 1;
    }
    for i in 0..cells {
        start[i + 1] += start[i];
    }
    let mut cursor = start.clone();
    let mut grouped = vec![Vec3::ZERO; start[cells] as usize];
    let vertices = keys.iter().zip(positions).filter(|&(&k, _)| k != UNUSED).map(|(&k, &p)| (k, Vec3::from(p)));
    for (k, p) in vertices.chain(crossings) {
        let slot = &mut cursor[k as usize];
        grouped[*slot as usize] = p;
        *slot += 1;
    }

    let occupied: Vec<(u32, u32, u32)> =
        start.windows(2).enumerate().filter(|(_, w)| w[1] > w[0]).map(|(key, w)| (key as u32, w[0], w[1])).collect();
    let spheres =
        occupied.par_iter().map(|&(_, lo, hi)| enclosing_sphere(&grouped[lo as usize..hi as usize])).collect();
    let voxels = occupied.into_iter().map(|(key, _, _)| key).collect();
    Ok(VoxelSpheres { spheres, voxels, mesh_min: min, mesh_max: max, resolution: n })
}

/// For every triangle that spans more than one voxel, the corners of its part in each voxel it
/// passes through, keyed by voxel; in triangle order, whatever the thread count. `keys` are the
/// vertices' voxels: a triangle whose corners share one is skipped without reading positions.
fn crossing_points(mesh: MeshRef<'_>, grid: &VoxelGrid, keys: &[u32]) -> Vec<(u32, Vec3)> {
    if grid.is_single_voxel() {
        return Vec::new();
    }
    match mesh.indices {
        Some(indices) => crossings_of(mesh.positions, indices.len() / 3, grid, keys, |t| {
            [0, 1, 2].map(|k| indices[3 * t + k] as usize)
        }),
        None => crossings_of(mesh.positions, mesh.positions.len() / 3, grid, keys, |t| [0, 1, 2].map(|k| 3 * t + k)),
    }
}

/// [`crossing_points`] over `count` triangles whose vertex indices `corners` gives.
fn crossings_of(
    positions: &[[f32; 3]],
    count: usize,
    grid: &VoxelGrid,
    keys: &[u32],
    corners: impl Fn(usize) -> [usize; 3] + Sync,
) -> Vec<(u32, Vec3)> {
    (0..count)
        .into_par_iter()
        .with_min_len(CHUNK / 4)
        .fold(Vec::new, |mut out, t| {
            let vertices = corners(t);
            let [a, b, c] = vertices.map(|i| keys[i]);
            if a != b || a != c {
                let triangle = vertices.map(|i| Vec3::from(positions[i]));
                grid.for_each_piece(triangle, |key, piece| {
                    // A corner that is one of the triangle's vertices, in that vertex's own
                    // voxel, is among the voxel's points already.
                    let known = |p: Vec3| (0..3).any(|k| triangle[k] == p && keys[vertices[k]] == key);
                    out.extend(piece.corners().iter().filter(|&&p| !known(p)).map(|&p| (key, p)));
                });
            }
            out
        })
        .reduce(Vec::new, |mut a, mut b| {
            a.append(&mut b);
            a
        })
}

/// Vertices per parallel task in the passes over the whole mesh.
const CHUNK: usize = 1 << 14;

/// The voxel key of a vertex no triangle uses.
const UNUSED: u32 = u32::MAX;

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

    /// Every point of a triangle lies in the sphere of the voxel that holds it (up to rounding).
    fn assert_covered(v: &VoxelSpheres, triangles: &[[Vec3; 3]]) {
        for (t, [a, b, c]) in triangles.iter().enumerate() {
            for i in 0..=12 {
                for j in 0..=12 - i {
                    let p = *a + (i as f32 / 12.0) * (*b - *a) + (j as f32 / 12.0) * (*c - *a);
                    let s = v.sphere_of(p).unwrap_or_else(|| panic!("triangle {t}: the voxel of {p} has no sphere"));
                    assert!(p.distance(s.centre()) <= s.radius + 1e-6, "triangle {t}: {p} outside its voxel's sphere");
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
        assert!(corner.radius < 0.5 * (3.0f32 / 9.0).sqrt() + 1e-5, "{corner:?}");
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
}
