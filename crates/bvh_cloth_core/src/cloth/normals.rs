//! Per-vertex normals of the cloth (paper Algorithm 3, `NormalShader`): the sum of the normals
//! of the triangles around a particle, each weighted by its area, normalised.

use glam::Vec3;

use crate::cloth::topology::ClothTopology;

/// The normal of particle `i` given a position lookup: the cross products of its triangles'
/// edges (twice their areas, pointing the way their corners turn counter-clockwise), summed in
/// the order of [`ClothTopology::triangles_of`] and normalised; `+Y` where they cancel.
pub fn particle_normal(topology: &ClothTopology, i: usize, pos: impl Fn(usize) -> Vec3) -> Vec3 {
    let triangles = topology.triangles();
    let mut n = Vec3::ZERO;
    for &t in topology.triangles_of(i) {
        let [a, b, c] = triangles[t as usize].map(|p| pos(p as usize));
        n += (b - a).cross(c - a);
    }
    n.try_normalize().unwrap_or(Vec3::Y)
}

#[cfg(test)]
mod tests {
    use glam::{Affine3A, Quat, UVec2, Vec2};

    use super::*;

    /// Normals of every particle.
    fn particle_normals(topology: &ClothTopology, positions: &[Vec3]) -> Vec<Vec3> {
        (0..topology.len()).map(|i| particle_normal(topology, i, |p| positions[p])).collect()
    }
    use crate::cloth::grid::ClothGrid;

    fn grid(cols: u32, rows: u32, size: f32) -> (ClothGrid, ClothTopology) {
        let grid = ClothGrid::new(Vec2::splat(size), UVec2::new(cols, rows));
        (grid, ClothTopology::grid(grid).unwrap())
    }

    #[test]
    fn flat_cloth_faces_up_and_follows_rotation() {
        let (grid, topology) = grid(5, 4, 0.4);
        let flat = grid.rest_positions(&Affine3A::IDENTITY);
        assert!(particle_normals(&topology, &flat).iter().all(|n| n.distance(Vec3::Y) < 1e-6));
        let rot = Quat::from_rotation_x(core::f32::consts::FRAC_PI_2);
        let turned = grid.rest_positions(&Affine3A::from_quat(rot));
        let expected = rot * Vec3::Y;
        assert!(particle_normals(&topology, &turned).iter().all(|n| n.distance(expected) < 1e-5));
    }

    #[test]
    fn fold_bends_normals() {
        // A roof: the middle column raised, so normals on each side tilt away from it.
        let (grid, topology) = grid(3, 3, 2.0);
        let mut p = grid.rest_positions(&Affine3A::IDENTITY);
        for r in 0..3 {
            p[grid.index(r, 1)].y = 1.0;
        }
        let n = particle_normals(&topology, &p);
        assert!(n[grid.index(1, 0)].x < -0.1);
        assert!(n[grid.index(1, 2)].x > 0.1);
        // The ridge's own normal points up, tilted only by the one diagonal of each cell.
        assert!(n[grid.index(1, 1)].y > 0.9);
    }
}
