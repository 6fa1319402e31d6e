//! Graph colouring of a cloth's particles: no two particles that share a spring get the same
//! colour, so every particle of one colour can be updated at once, in parallel, by a solver
//! that moves each particle against its neighbours' current positions (Gauss–Seidel by
//! colour, as [`crate::solver::block_descent`] does).
//!
//! - **The grid** is coloured in closed form: particle `(r, c)` gets `(r + 2c) mod 5`. The
//!   stencil's offsets `(0, ±1)`, `(±1, 0)`, `(±1, ±1)`, `(0, ±2)` and `(±2, 0)` change
//!   `r + 2c` by 2, 1, 3 or -1, 4 or -4, and 2 or 1, never by a multiple of 5, so the five colours
//!   are proper. A 2x2 block is a clique of four, so no colouring of the stencil has fewer
//!   than four colours.
//! - **An authored mesh** is coloured greedily at build, particles in index order, each taking
//!   the smallest colour none of its spring neighbours has. Greedy needs at most one colour
//!   more than the largest number of springs at a particle; a cloth mesh with bending springs
//!   typically needs 6–10. A mesh that would need more than [`MAX_COLOURS`] (a particle with
//!   dozens of springs: a fan or a degenerate weld) is refused.
//!
//! The colouring is part of the topology, so the CPU and GPU solvers visit the same colours in
//! the same order, and a particle's update reads the same neighbour positions on both.

use crate::cloth::error::ClothError;
use crate::cloth::grid::ClothGrid;
use crate::cloth::grid::SpringEnd;

/// Most colours a cloth may need. Each colour is one dispatch per solver iteration.
pub const MAX_COLOURS: u32 = 32;

/// The particles grouped by colour: colour `k` is `order[offsets[k]..offsets[k + 1]]`, in
/// increasing particle order.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ParticleColouring {
    order: Vec<u32>,
    offsets: Vec<u32>,
}

impl ParticleColouring {
    /// The closed-form colouring of the grid's stencil.
    pub fn grid(grid: &ClothGrid) -> Self {
        let colours = (0..grid.rows).flat_map(|r| (0..grid.cols).map(move |c| ((r + 2 * c) % 5) as u32));
        Self::from_colours(colours.collect())
    }

    /// A greedy colouring of `n` particles joined by the springs of a CSR list
    /// (`spring_offsets`, `spring_ends`), or [`ClothError::TooManyColours`].
    pub fn greedy(n: usize, spring_offsets: &[u32], spring_ends: &[SpringEnd]) -> Result<Self, ClothError> {
        const UNCOLOURED: u32 = u32::MAX;
        let mut colour = vec![UNCOLOURED; n];
        for i in 0..n {
            let mut taken = 0u64;
            for end in &spring_ends[spring_offsets[i] as usize..spring_offsets[i + 1] as usize] {
                let other = colour[end.other as usize];
                if other != UNCOLOURED {
                    taken |= 1 << other;
                }
            }
            let first_free = (!taken).trailing_zeros();
            if first_free >= MAX_COLOURS {
                return Err(ClothError::TooManyColours { particle: i as u32, limit: MAX_COLOURS });
            }
            colour[i] = first_free;
        }
        Ok(Self::from_colours(colour))
    }

    fn from_colours(colour: Vec<u32>) -> Self {
        let count = colour.iter().max().map_or(0, |&c| c as usize + 1);
        let mut offsets = vec![0u32; count + 1];
        for &c in &colour {
            offsets[c as usize + 1] += 1;
        }
        for k in 0..count {
            offsets[k + 1] += offsets[k];
        }
        let mut fill = offsets.clone();
        let mut order = vec![0u32; colour.len()];
        for (i, &c) in colour.iter().enumerate() {
            order[fill[c as usize] as usize] = i as u32;
            fill[c as usize] += 1;
        }
        Self { order, offsets }
    }

    /// Number of colours.
    pub fn len(&self) -> usize {
        self.offsets.len() - 1
    }

    /// Whether there is no colour (never true for a built topology).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The particles of colour `k`, in increasing order.
    pub fn colour(&self, k: usize) -> &[u32] {
        &self.order[self.offsets[k] as usize..self.offsets[k + 1] as usize]
    }

    /// Every particle, colour after colour (what the GPU's colour list holds).
    pub fn order(&self) -> &[u32] {
        &self.order
    }

    /// Where each colour starts in [`Self::order`], and its end: `len() + 1` entries.
    pub fn offsets(&self) -> &[u32] {
        &self.offsets
    }
}

#[cfg(test)]
mod tests {
    use glam::{UVec2, Vec2};

    use super::*;
    use crate::cloth::topology::ClothTopology;

    /// Whether no spring joins two particles of one colour, and every particle has a colour.
    fn is_proper(topology: &ClothTopology, colouring: &ParticleColouring) -> bool {
        let mut colour = vec![u32::MAX; topology.len()];
        for k in 0..colouring.len() {
            for &i in colouring.colour(k) {
                colour[i as usize] = k as u32;
            }
        }
        colour.iter().all(|&c| c != u32::MAX)
            && (0..topology.len()).all(|i| topology.springs_of(i).iter().all(|e| colour[e.other as usize] != colour[i]))
    }

    #[test]
    fn the_grid_takes_five_proper_colours() {
        for (cols, rows) in [(2, 2), (7, 3), (32, 32), (65, 9)] {
            let grid = ClothGrid::new(Vec2::ONE, UVec2::new(cols, rows));
            let topology = ClothTopology::grid(grid).unwrap();
            let colouring = topology.colouring().unwrap();
            assert_eq!(colouring.len(), if cols * rows >= 5 { 5 } else { (cols * rows) as usize }, "{cols}x{rows}");
            assert!(is_proper(&topology, colouring), "{cols}x{rows}");
            assert_eq!(colouring.order().len(), topology.len());
        }
    }

    #[test]
    fn greedy_colours_an_irregular_mesh_properly() {
        // A fan of triangles around one hub plus a strip: uneven degrees.
        let mut positions = vec![[0.0f32, 0.0, 0.0]];
        let spokes = 12;
        for k in 0..spokes {
            let a = k as f32 / spokes as f32 * core::f32::consts::TAU;
            positions.push([a.cos(), 0.0, a.sin()]);
        }
        let mut indices = Vec::new();
        for k in 0..spokes {
            indices.extend_from_slice(&[0, 1 + k, 1 + (k + 1) % spokes]);
        }
        let topology =
            ClothTopology::from_mesh(crate::MeshRef { positions: &positions, indices: Some(&indices) }).unwrap();
        let colouring = topology.colouring().unwrap();
        assert!(is_proper(&topology, colouring));
        assert!(colouring.len() <= 13, "{}", colouring.len());
    }

    /// `n` particles, each joined to every other.
    fn clique(n: usize) -> (Vec<u32>, Vec<SpringEnd>) {
        let mut offsets = vec![0u32];
        let mut ends = Vec::new();
        for i in 0..n {
            for j in (0..n).filter(|&j| j != i) {
                ends.push(SpringEnd { other: j as u32, kind: 0, rest: 1.0, weight: 1.0 });
            }
            offsets.push(ends.len() as u32);
        }
        (offsets, ends)
    }

    #[test]
    fn a_mesh_that_needs_more_colours_than_the_limit_is_refused() {
        let (offsets, ends) = clique(MAX_COLOURS as usize);
        assert_eq!(ParticleColouring::greedy(MAX_COLOURS as usize, &offsets, &ends).map(|c| c.len()), Ok(32));
        let (offsets, ends) = clique(MAX_COLOURS as usize + 1);
        assert_eq!(
            ParticleColouring::greedy(MAX_COLOURS as usize + 1, &offsets, &ends),
            Err(ClothError::TooManyColours { particle: MAX_COLOURS, limit: MAX_COLOURS })
        );
    }
}
