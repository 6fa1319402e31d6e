//! Triangle meshes as the core reads them: a borrowed mesh ([`MeshRef`]) and the one check
//! every mesh passes before a cloth or a collider is built from it, a minimal OBJ reader, and
//! the point and segment queries against one triangle that contact is built on.
//!
//! The floor of the crate beside [`crate::bvh`]: it imports nothing from the crate.

pub mod obj;
pub(crate) mod triangles;

use rayon::prelude::*;

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

/// What makes a mesh unreadable: the first defect [`MeshRef::check`] meets. The cloth and the
/// collider errors each name it in their own words ([`crate::ClothError`],
/// [`crate::ColliderError`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum MeshDefect {
    /// No vertex positions.
    Empty,
    /// A vertex with a NaN or infinite coordinate.
    NonFiniteVertex { vertex: usize },
    /// A vertex further than [`MAX_COORDINATE`] from the origin along an axis.
    VertexTooFar { vertex: usize },
    /// No indices, and a vertex count that is not a whole number of triangles.
    VerticesNotTriangles { vertices: usize },
    /// An empty index list.
    NoTriangles,
    /// An index list that is not a whole number of triangles.
    IndicesNotTriangles { len: usize },
    /// An index past the last vertex.
    IndexOutOfRange { position: usize, index: u32, vertices: usize },
}

/// Vertices checked by one task.
const CHUNK: usize = 1 << 14;

impl MeshRef<'_> {
    /// The mesh's first defect, checked in this order: vertices, then the triangle list.
    /// Vertices are checked in parallel, and the first bad one is the one named.
    pub(crate) fn check(self) -> Result<(), MeshDefect> {
        let positions = self.positions;
        if positions.is_empty() {
            return Err(MeshDefect::Empty);
        }
        let bad = |p: &[f32; 3]| !p.iter().all(|c| c.is_finite() && c.abs() <= MAX_COORDINATE);
        let first_bad = positions
            .par_chunks(CHUNK)
            .enumerate()
            .find_map_first(|(c, chunk)| chunk.iter().position(bad).map(|i| c * CHUNK + i));
        if let Some(vertex) = first_bad {
            return Err(if positions[vertex].iter().all(|c| c.is_finite()) {
                MeshDefect::VertexTooFar { vertex }
            } else {
                MeshDefect::NonFiniteVertex { vertex }
            });
        }
        let vertices = positions.len();
        let Some(indices) = self.indices else {
            return if vertices.is_multiple_of(3) {
                Ok(())
            } else {
                Err(MeshDefect::VerticesNotTriangles { vertices })
            };
        };
        if indices.is_empty() {
            return Err(MeshDefect::NoTriangles);
        }
        if !indices.len().is_multiple_of(3) {
            return Err(MeshDefect::IndicesNotTriangles { len: indices.len() });
        }
        match indices.iter().position(|&i| i as usize >= vertices) {
            Some(position) => Err(MeshDefect::IndexOutOfRange { position, index: indices[position], vertices }),
            None => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check(positions: &[[f32; 3]], indices: Option<&[u32]>) -> Result<(), MeshDefect> {
        MeshRef { positions, indices }.check()
    }

    #[test]
    fn names_the_first_defect() {
        let tri = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        assert_eq!(check(&tri, None), Ok(()));
        assert_eq!(check(&tri, Some(&[0, 1, 2])), Ok(()));
        assert_eq!(check(&[], None), Err(MeshDefect::Empty));
        let mut nan = tri;
        nan[1][2] = f32::NAN;
        assert_eq!(check(&nan, None), Err(MeshDefect::NonFiniteVertex { vertex: 1 }));
        let mut far = tri;
        far[2][0] = 2.0 * MAX_COORDINATE;
        assert_eq!(check(&far, None), Err(MeshDefect::VertexTooFar { vertex: 2 }));
        assert_eq!(check(&tri[..2], None), Err(MeshDefect::VerticesNotTriangles { vertices: 2 }));
        assert_eq!(check(&tri, Some(&[])), Err(MeshDefect::NoTriangles));
        assert_eq!(check(&tri, Some(&[0, 1])), Err(MeshDefect::IndicesNotTriangles { len: 2 }));
        assert_eq!(
            check(&tri, Some(&[0, 1, 3])),
            Err(MeshDefect::IndexOutOfRange { position: 2, index: 3, vertices: 3 })
        );
    }

    #[test]
    fn finds_the_first_bad_vertex_across_tasks() {
        let mut positions = vec![[0.0f32; 3]; 3 * CHUNK];
        positions[2 * CHUNK + 5][0] = f32::INFINITY;
        positions[CHUNK + 7][1] = f32::NAN;
        assert_eq!(check(&positions, None), Err(MeshDefect::NonFiniteVertex { vertex: CHUNK + 7 }));
    }
}
