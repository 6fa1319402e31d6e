//! Per-vertex normals of the cloth grid (paper Algorithm 3, `NormalShader`): the sum of the
//! normals of the (up to four) grid cells around a particle, normalised.

use glam::Vec3;

use crate::grid::ClothGrid;

/// The normal of particle `(r, c)` given a position lookup. Each adjacent cell contributes the
/// cross product of its two edges at the particle, ordered so a flat cloth at rest faces +Y.
pub fn vertex_normal(grid: &ClothGrid, r: usize, c: usize, pos: impl Fn(usize) -> Vec3) -> Vec3 {
    let p = pos(grid.index(r, c));
    let edge = |rr: usize, cc: usize| pos(grid.index(rr, cc)) - p;
    let (has_up, has_down) = (r > 0, r + 1 < grid.rows);
    let (has_left, has_right) = (c > 0, c + 1 < grid.cols);
    let mut n = Vec3::ZERO;
    if has_down && has_right {
        n += edge(r + 1, c).cross(edge(r, c + 1));
    }
    if has_right && has_up {
        n += edge(r, c + 1).cross(edge(r - 1, c));
    }
    if has_up && has_left {
        n += edge(r - 1, c).cross(edge(r, c - 1));
    }
    if has_left && has_down {
        n += edge(r, c - 1).cross(edge(r + 1, c));
    }
    n.try_normalize().unwrap_or(Vec3::Y)
}

/// Normals of every particle, row-major.
pub fn grid_normals(grid: &ClothGrid, positions: &[Vec3]) -> Vec<Vec3> {
    let mut out = Vec::with_capacity(grid.len());
    for r in 0..grid.rows {
        for c in 0..grid.cols {
            out.push(vertex_normal(grid, r, c, |i| positions[i]));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use glam::{Affine3A, Quat};

    use super::*;

    #[test]
    fn flat_cloth_faces_up_and_follows_rotation() {
        let grid = ClothGrid { rows: 4, cols: 5, spacing: 0.1 };
        let flat = grid.rest_positions(&Affine3A::IDENTITY);
        assert!(grid_normals(&grid, &flat).iter().all(|n| n.distance(Vec3::Y) < 1e-6));
        let rot = Quat::from_rotation_x(core::f32::consts::FRAC_PI_2);
        let turned = grid.rest_positions(&Affine3A::from_quat(rot));
        let expected = rot * Vec3::Y;
        assert!(grid_normals(&grid, &turned).iter().all(|n| n.distance(expected) < 1e-5));
    }

    #[test]
    fn fold_bends_normals() {
        // A roof: the middle column raised, so normals on each side tilt away from it.
        let grid = ClothGrid { rows: 3, cols: 3, spacing: 1.0 };
        let mut p = grid.rest_positions(&Affine3A::IDENTITY);
        for r in 0..3 {
            p[grid.index(r, 1)].y = 1.0;
        }
        let n = grid_normals(&grid, &p);
        assert!(n[grid.index(1, 0)].x < -0.1);
        assert!(n[grid.index(1, 2)].x > 0.1);
        assert!(n[grid.index(1, 1)].x.abs() < 1e-6);
    }
}
