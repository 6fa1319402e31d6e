//! The particle grid: indexing, rest pose, the spring stencil and pin sets (paper section 2.1).

use bytemuck::{Pod, Zeroable};
use glam::{Affine3A, UVec2, Vec2, Vec3};

use crate::cloth::error::ClothError;

/// The three kinds of spring of the mass-spring model.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
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

/// Largest particle count a single cloth may have (4096 x 4096).
pub const MAX_PARTICLES: u32 = 1 << 24;

/// The shape of a `rows x cols` particle grid spanning `size` metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClothGrid {
    /// Number of rows (along local +Z).
    pub rows: usize,
    /// Number of columns (along local +X).
    pub cols: usize,
    /// Extent in metres from the first to the last column (`x`) and row (`y`).
    pub size: Vec2,
}

impl ClothGrid {
    /// A grid of `particles.x` columns by `particles.y` rows spanning `size` metres (`x` along
    /// the columns, `y` along the rows).
    pub fn new(size: Vec2, particles: UVec2) -> Self {
        Self { rows: particles.y as usize, cols: particles.x as usize, size }
    }

    /// Checks that the grid can be simulated: at least 2 x 2 particles, at most
    /// [`MAX_PARTICLES`], and a finite positive size on both axes.
    pub fn validate(&self) -> Result<(), ClothError> {
        let (rows, cols) = (u32::try_from(self.rows).unwrap_or(u32::MAX), u32::try_from(self.cols).unwrap_or(u32::MAX));
        if rows < 2 || cols < 2 {
            return Err(ClothError::GridTooSmall { rows, cols });
        }
        if u64::from(rows) * u64::from(cols) > u64::from(MAX_PARTICLES) {
            return Err(ClothError::GridTooLarge { rows, cols, max_particles: MAX_PARTICLES });
        }
        for (field, value) in [("size.x", self.size.x), ("size.y", self.size.y)] {
            if !(value.is_finite() && value > 0.0) {
                return Err(ClothError::NotPositive { field, value });
            }
        }
        Ok(())
    }

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

    /// Rest distance between neighbouring columns (`x`) and rows (`y`), in metres.
    pub fn spacing(&self) -> Vec2 {
        Vec2::new(self.size.x / (self.cols.max(2) - 1) as f32, self.size.y / (self.rows.max(2) - 1) as f32)
    }

    /// Rest length of the spring to the particle `dr` rows and `dc` columns away.
    pub fn rest_length(&self, dr: i32, dc: i32) -> f32 {
        let s = self.spacing();
        Vec2::new(dc as f32 * s.x, dr as f32 * s.y).length()
    }

    /// The stiffness weight `A / L²` of the spring to the particle `dr` rows and `dc` columns
    /// away (see [`crate::cloth::topology`]): the area of `dr² + dc²` cells over the squared rest
    /// length. It is 1 for every spring of a grid with square cells, so a square grid's springs
    /// all have the stiffness [`crate::ClothParams::spring_k`] times their kind's scale.
    pub fn weight(&self, dr: i32, dc: i32) -> f32 {
        let s = self.spacing();
        let length = self.rest_length(dr, dc);
        (dr * dr + dc * dc) as f32 * s.x * s.y / (length * length)
    }

    /// Rest position of `(row, col)` in the cloth's local frame: a flat sheet in the XZ plane,
    /// centred on the origin, facing +Y.
    pub fn local_rest_position(&self, row: usize, col: usize) -> Vec3 {
        let s = self.spacing();
        Vec3::new(col as f32 * s.x - 0.5 * self.size.x, 0.0, row as f32 * s.y - 0.5 * self.size.y)
    }

    /// Triangle indices of the grid, two counter-clockwise (seen from local +Y) triangles per
    /// cell.
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

/// One spring as seen from one of its ends: the other end, its kind, rest length and weight.
/// Uploaded unchanged to the GPU. 16 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct SpringEnd {
    /// The particle at the other end.
    pub other: u32,
    /// The spring's kind as a number (0 structural, 1 shear, 2 bending).
    pub kind: u32,
    /// Rest length in metres.
    pub rest: f32,
    /// Stiffness weight `A / L²` (see [`crate::cloth::topology`]).
    pub weight: f32,
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
    fn square_cells_weigh_one_and_rectangles_stay_isotropic() {
        let square = ClothGrid::new(Vec2::splat(2.0), UVec2::splat(5));
        for s in STENCIL {
            assert!((square.weight(s.dr, s.dc) - 1.0).abs() < 1e-6, "{s:?}");
        }
        // Cells twice as long along x as along z: a spring along x must be half as stiff as one
        // along z, so that the sheet resists a strain the same way along both axes (tension
        // per metre of cut = weight * strain * length / spacing across).
        let rect = ClothGrid::new(Vec2::new(4.0, 2.0), UVec2::splat(5));
        assert!((rect.weight(0, 1) - 0.5).abs() < 1e-6);
        assert!((rect.weight(1, 0) - 2.0).abs() < 1e-6);
        let s = rect.spacing();
        let tension_x = rect.weight(0, 1) * s.x / s.y;
        let tension_z = rect.weight(1, 0) * s.y / s.x;
        assert!((tension_x - tension_z).abs() < 1e-6);
        assert!((rect.rest_length(1, 1) - (1.0f32 + 0.25).sqrt()).abs() < 1e-6);
    }

    #[test]
    fn triangles_face_up_at_rest() {
        let grid = ClothGrid::new(Vec2::new(1.5, 1.0), UVec2::new(4, 3));
        let p = grid.rest_positions(&Affine3A::IDENTITY);
        for tri in grid.triangle_indices().chunks(3) {
            let [a, b, c] = [p[tri[0] as usize], p[tri[1] as usize], p[tri[2] as usize]];
            assert!((b - a).cross(c - a).y > 0.0);
        }
    }
}
