//! The particle grid: indexing, rest pose, the spring stencil and pin sets (paper section 2.1).

use glam::{Affine3A, Vec3};

/// The three kinds of spring of the mass-spring model.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SpringKind {
    /// To the 4-neighbourhood.
    Structural = 0,
    /// To the diagonal neighbours.
    Shear = 1,
    /// To the neighbours two steps away along a row or column.
    Bending = 2,
}

/// One entry of the spring stencil: the neighbour at `(row + dr, col + dc)`.
#[derive(Clone, Copy, Debug)]
pub struct StencilSpring {
    /// Row offset.
    pub dr: i32,
    /// Column offset.
    pub dc: i32,
    /// Kind of spring, which sets its stiffness scale.
    pub kind: SpringKind,
}

const fn spring(dr: i32, dc: i32, kind: SpringKind) -> StencilSpring {
    StencilSpring { dr, dc, kind }
}

/// Every spring a particle can have, as grid offsets. The topology is implicit: a particle's
/// springs are the stencil entries whose neighbour lies inside the grid. Keeping the topology
/// implicit (rather than a spring list) lets the force loop run over contiguous rows.
pub const STENCIL: [StencilSpring; 12] = [
    spring(0, -1, SpringKind::Structural),
    spring(0, 1, SpringKind::Structural),
    spring(-1, 0, SpringKind::Structural),
    spring(1, 0, SpringKind::Structural),
    spring(-1, -1, SpringKind::Shear),
    spring(-1, 1, SpringKind::Shear),
    spring(1, -1, SpringKind::Shear),
    spring(1, 1, SpringKind::Shear),
    spring(0, -2, SpringKind::Bending),
    spring(0, 2, SpringKind::Bending),
    spring(-2, 0, SpringKind::Bending),
    spring(2, 0, SpringKind::Bending),
];

/// The shape of a `rows x cols` particle grid with square cells.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClothGrid {
    /// Number of rows (along local +Z).
    pub rows: usize,
    /// Number of columns (along local +X).
    pub cols: usize,
    /// Rest distance between neighbouring particles.
    pub spacing: f32,
}

impl ClothGrid {
    /// Number of particles.
    pub fn len(&self) -> usize {
        self.rows * self.cols
    }

    /// Whether the grid has no particle (never true for a validated grid).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Row-major particle index of `(row, col)`.
    pub fn index(&self, row: usize, col: usize) -> usize {
        row * self.cols + col
    }

    /// Rest length of a spring of the given kind.
    pub fn rest_length(&self, kind: SpringKind) -> f32 {
        match kind {
            SpringKind::Structural => self.spacing,
            SpringKind::Shear => self.spacing * core::f32::consts::SQRT_2,
            SpringKind::Bending => self.spacing * 2.0,
        }
    }

    /// Rest position of `(row, col)` in the cloth's local frame: a flat sheet in the XZ plane,
    /// centred on the origin, facing +Y.
    pub fn local_rest_position(&self, row: usize, col: usize) -> Vec3 {
        let half_w = 0.5 * self.spacing * (self.cols - 1) as f32;
        let half_d = 0.5 * self.spacing * (self.rows - 1) as f32;
        Vec3::new(col as f32 * self.spacing - half_w, 0.0, row as f32 * self.spacing - half_d)
    }

    /// Triangle indices of the grid, two counter-clockwise (seen from local +Y) triangles per
    /// cell, matching the normals of [`crate::normals`].
    pub fn triangle_indices(&self) -> Vec<u32> {
        let mut out = Vec::with_capacity((self.rows - 1) * (self.cols - 1) * 6);
        for r in 0..self.rows - 1 {
            for c in 0..self.cols - 1 {
                let i = self.index(r, c) as u32;
                let right = i + 1;
                let down = i + self.cols as u32;
                let diag = down + 1;
                out.extend_from_slice(&[i, down, right, right, down, diag]);
            }
        }
        out
    }

    /// Texture coordinates: u along the columns, v along the rows, both in `[0, 1]`.
    pub fn uvs(&self) -> Vec<[f32; 2]> {
        let mut out = Vec::with_capacity(self.len());
        for r in 0..self.rows {
            for c in 0..self.cols {
                out.push([c as f32 / (self.cols - 1) as f32, r as f32 / (self.rows - 1) as f32]);
            }
        }
        out
    }

    /// Rest positions of every particle, placed in the world by `pose`.
    pub fn rest_positions(&self, pose: &Affine3A) -> Vec<Vec3> {
        let mut out = Vec::with_capacity(self.len());
        for r in 0..self.rows {
            for c in 0..self.cols {
                out.push(pose.transform_point3(self.local_rest_position(r, c)));
            }
        }
        out
    }
}

/// Which particles are held in place.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub enum Pins {
    /// Nothing is pinned: the cloth falls freely.
    #[default]
    None,
    /// The two ends of the first row (paper Fig. 5: "two ends fixed").
    TwoEnds,
    /// The whole first row.
    FirstRow,
    /// Explicit row-major particle indices.
    Indices(Vec<u32>),
}

impl Pins {
    /// The pinned particle indices for a grid, sorted and without duplicates.
    pub fn indices(&self, grid: &ClothGrid) -> Vec<u32> {
        let mut out: Vec<u32> = match self {
            Pins::None => Vec::new(),
            Pins::TwoEnds => vec![0, grid.cols as u32 - 1],
            Pins::FirstRow => (0..grid.cols as u32).collect(),
            Pins::Indices(indices) => indices.clone(),
        };
        out.sort_unstable();
        out.dedup();
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stencil_is_symmetric() {
        for s in STENCIL {
            assert!(STENCIL.iter().any(|t| t.dr == -s.dr && t.dc == -s.dc && t.kind == s.kind));
        }
    }

    #[test]
    fn triangles_face_up_at_rest() {
        let grid = ClothGrid { rows: 3, cols: 4, spacing: 0.5 };
        let p = grid.rest_positions(&Affine3A::IDENTITY);
        for tri in grid.triangle_indices().chunks(3) {
            let [a, b, c] = [p[tri[0] as usize], p[tri[1] as usize], p[tri[2] as usize]];
            assert!((b - a).cross(c - a).y > 0.0);
        }
    }
}
