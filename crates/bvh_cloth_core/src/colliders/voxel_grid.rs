//! The voxel grid over a mesh's bounding box, and the part of a triangle that lies in each voxel
//! it passes through.
//!
//! A triangle that spans several voxels is cut by the grid's planes, one axis at a time: into
//! slabs along x, each slab's piece into rows along y, each row's piece into cells along z
//! (Sutherland–Hodgman clipping against two parallel planes per step). Only the slabs, rows and
//! cells a piece actually reaches are visited, so the work follows the voxels the triangle
//! touches, not its bounding box. The corners of each final piece are the points that voxel's
//! sphere must enclose for the sphere to cover that part of the triangle.

use glam::{UVec3, Vec3};

/// Most corners a triangle clipped by six planes can have: each cut adds at most one.
const MAX_CORNERS: usize = 9;

/// A convex polygon with at most [`MAX_CORNERS`] corners.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Piece {
    corners: [Vec3; MAX_CORNERS],
    len: usize,
}

impl Piece {
    fn triangle(a: Vec3, b: Vec3, c: Vec3) -> Self {
        let mut corners = [Vec3::ZERO; MAX_CORNERS];
        corners[..3].copy_from_slice(&[a, b, c]);
        Self { corners, len: 3 }
    }

    /// The corners.
    pub(crate) fn corners(&self) -> &[Vec3] {
        &self.corners[..self.len]
    }

    fn push(&mut self, p: Vec3) {
        if self.len < MAX_CORNERS {
            self.corners[self.len] = p;
            self.len += 1;
        }
    }

    /// The part of the polygon where `sign * (p[axis] - plane) >= 0`.
    fn keep(&self, axis: usize, plane: f32, sign: f32) -> Self {
        let mut out = Self { corners: [Vec3::ZERO; MAX_CORNERS], len: 0 };
        let side = |p: Vec3| sign * (p[axis] - plane);
        for k in 0..self.len {
            let (p, q) = (self.corners[k], self.corners[(k + 1) % self.len]);
            let (sp, sq) = (side(p), side(q));
            if sp >= 0.0 {
                out.push(p);
            }
            if (sp >= 0.0) != (sq >= 0.0) {
                let t = sp / (sp - sq);
                let mut x = p.lerp(q, t);
                // Exactly on the plane, whatever the rounding of the interpolation.
                x[axis] = plane;
                out.push(x);
            }
        }
        out
    }

    /// The smallest and largest coordinate on `axis`.
    fn span(&self, axis: usize) -> (f32, f32) {
        self.corners().iter().fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), p| (lo.min(p[axis]), hi.max(p[axis])))
    }
}

/// The `nx x ny x nz` voxels over a mesh's bounding box: boxes, one layer on a flat axis.
#[derive(Clone, Copy, Debug)]
pub(crate) struct VoxelGrid {
    min: Vec3,
    /// Voxel size on each axis.
    cell: Vec3,
    /// Voxels per unit length on each axis (0 on a flat axis).
    inv_cell: Vec3,
    /// Voxels along each axis, each at least 1.
    n: UVec3,
}

impl VoxelGrid {
    pub(crate) fn new(min: Vec3, max: Vec3, n: UVec3) -> Self {
        let extent = max - min;
        let counts = n.as_vec3();
        let inv_cell = Vec3::select(extent.cmpgt(Vec3::ZERO), counts / extent, Vec3::ZERO);
        Self { min, cell: extent / counts, inv_cell, n }
    }

    /// The cell index along `axis` of coordinate `x`; points on the far face go to the last
    /// layer.
    #[inline]
    fn cell_along(&self, axis: usize, x: f32) -> u32 {
        // `as` truncates, which is `floor` here because the offset is not negative (and it
        // saturates, should rounding push a point a hair outside the box).
        (((x - self.min[axis]) * self.inv_cell[axis]).max(0.0) as u32).min(self.n[axis] - 1)
    }

    /// The box's minimum corner.
    pub(crate) fn min(&self) -> Vec3 {
        self.min
    }

    /// The length of a voxel's diagonal.
    pub(crate) fn cell_diagonal(&self) -> f32 {
        self.cell.length()
    }

    /// Whether the whole grid is one voxel (`n = 1`).
    pub(crate) fn is_single_voxel(&self) -> bool {
        self.n == UVec3::ONE
    }

    /// The key `x + nx (y + ny z)` of cell `(x, y, z)`.
    #[inline]
    fn key(&self, x: u32, y: u32, z: u32) -> u32 {
        x + self.n.x * (y + self.n.y * z)
    }

    /// The voxel holding `p`.
    #[inline]
    pub(crate) fn voxel_of(&self, p: Vec3) -> u32 {
        self.key(self.cell_along(0, p.x), self.cell_along(1, p.y), self.cell_along(2, p.z))
    }

    /// The plane between cells `i - 1` and `i` along `axis`.
    fn plane(&self, axis: usize, i: u32) -> f32 {
        self.min[axis] + i as f32 * self.cell[axis]
    }

    /// The cells along `axis` that `piece` reaches, with its part in each.
    fn split(&self, piece: &Piece, axis: usize, mut visit: impl FnMut(u32, &Piece)) {
        let (lo, hi) = piece.span(axis);
        let (first, last) = (self.cell_along(axis, lo), self.cell_along(axis, hi));
        if first == last {
            visit(first, piece);
            return;
        }
        // Each cut peels the lowest cell off what is left, so each plane is clipped against
        // once from each side.
        let mut rest = *piece;
        for i in first..last {
            let plane = self.plane(axis, i + 1);
            let part = rest.keep(axis, plane, -1.0);
            if part.len > 0 {
                visit(i, &part);
            }
            rest = rest.keep(axis, plane, 1.0);
            if rest.len == 0 {
                return;
            }
        }
        visit(last, &rest);
    }

    /// Calls `visit(voxel, piece)` for every voxel triangle `abc` passes through, with the part of
    /// the triangle in it, when the triangle spans more than one voxel. (A triangle inside one
    /// voxel is covered by any sphere that encloses its corners.)
    pub(crate) fn for_each_piece(&self, [a, b, c]: [Vec3; 3], mut visit: impl FnMut(u32, &Piece)) {
        let key = self.voxel_of(a);
        if key == self.voxel_of(b) && key == self.voxel_of(c) {
            return;
        }
        let triangle = Piece::triangle(a, b, c);
        self.split(&triangle, 0, |x, slab| {
            self.split(slab, 1, |y, row| self.split(row, 2, |z, cell| visit(self.key(x, y, z), cell)));
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_grid(n: u32) -> VoxelGrid {
        VoxelGrid::new(Vec3::ZERO, Vec3::ONE, UVec3::splat(n))
    }

    #[test]
    fn a_triangle_inside_one_voxel_has_no_pieces() {
        let mut count = 0;
        unit_grid(4)
            .for_each_piece([Vec3::splat(0.01), Vec3::splat(0.1), Vec3::new(0.2, 0.05, 0.1)], |_, _| count += 1);
        assert_eq!(count, 0);
    }

    #[test]
    fn a_triangle_across_a_face_is_cut_into_its_voxels() {
        let grid = unit_grid(2);
        let tri = [Vec3::new(0.1, 0.1, 0.1), Vec3::new(0.9, 0.1, 0.1), Vec3::new(0.1, 0.4, 0.1)];
        let mut pieces = Vec::new();
        grid.for_each_piece(tri, |key, piece| pieces.push((key, piece.corners().to_vec())));
        assert_eq!(pieces.iter().map(|p| p.0).collect::<Vec<_>>(), [0, 1]);
        for (key, corners) in &pieces {
            for &p in corners {
                // Every corner lies in (or on the boundary of) its voxel.
                let x = if *key == 0 { 0.0..=0.5 } else { 0.5..=1.0 };
                assert!(x.contains(&p.x), "{key}: {p}");
            }
        }
        // The cut runs along x = 0.5, from the long edge to the slanted one.
        assert!(pieces[0].1.iter().any(|p| p.x == 0.5 && (p.y - 0.1).abs() < 1e-6));
    }

    /// The pieces of a big triangle tile it: their areas sum to its area, and every point of the
    /// triangle lies in the piece of the voxel that holds it.
    #[test]
    fn the_pieces_tile_the_triangle() {
        let grid = unit_grid(7);
        let tri = [Vec3::new(0.02, 0.03, 0.9), Vec3::new(0.97, 0.2, 0.1), Vec3::new(0.3, 0.95, 0.5)];
        let area =
            |c: &[Vec3]| (1..c.len() - 1).map(|k| (c[k] - c[0]).cross(c[k + 1] - c[0]).length() / 2.0).sum::<f32>();
        let mut total = 0.0;
        let mut pieces = Vec::new();
        grid.for_each_piece(tri, |key, piece| {
            total += area(piece.corners());
            pieces.push((key, piece.corners().to_vec()));
        });
        let whole = area(&tri);
        assert!((total - whole).abs() < 1e-5 * whole, "{total} vs {whole}");
        let keys: Vec<u32> = pieces.iter().map(|p| p.0).collect();
        let mut unique = keys.clone();
        unique.sort_unstable();
        unique.dedup();
        assert_eq!(keys.len(), unique.len(), "one piece per voxel");
        for (u, v) in [(0.2, 0.3), (0.5, 0.1), (0.1, 0.8), (0.33, 0.33)] {
            let p = tri[0] + u * (tri[1] - tri[0]) + v * (tri[2] - tri[0]);
            let key = grid.voxel_of(p);
            assert!(keys.contains(&key), "the voxel of {p} has no piece");
        }
    }
}
