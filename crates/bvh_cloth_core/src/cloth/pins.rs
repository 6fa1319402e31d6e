//! Which particles of a cloth are held: chosen by grid position, by vertex index, by a pin weight
//! painted into a vertex colour channel, or by a region of the rest shape.
//!
//! A selection names *vertices* of the cloth's mesh as authored (on the generated grid, vertex
//! `row * cols + col` is particle `row * cols + col`). Every vertex that welding merged into
//! one particle ([`ClothTopology::vertex_particle`]) selects that particle, so a pin on one
//! side of a UV seam holds both sides.

#[cfg(feature = "bevy_reflect")]
use bevy_reflect::std_traits::ReflectDefault;
use glam::Vec3;

use crate::cloth::error::ClothError;
use crate::cloth::topology::ClothTopology;

/// Which particles of a cloth are held in place (or, in an anchor, carried by another object).
#[derive(Clone, Debug, Default, PartialEq)]
#[cfg_attr(feature = "bevy_reflect", derive(bevy_reflect::Reflect), reflect(Default, Debug, PartialEq))]
pub enum ClothPins {
    /// Nothing is held: the cloth falls freely.
    #[default]
    None,
    /// The two ends of a generated grid's first row (paper Fig. 5, "two ends fixed").
    TwoEnds,
    /// A generated grid's whole first row, like a curtain.
    FirstRow,
    /// These vertices of the mesh (on the grid, `row * cols + col`).
    Indices(Vec<u32>),
    /// Every vertex whose pin weight, painted into `channel` of the mesh's vertex colours
    /// (`Float32x4`, as Bevy loads glTF `COLOR_0`), is at least `threshold`. Artists paint the
    /// held edge of a cape or a flag in one colour channel, 1 held and 0 free.
    Painted {
        /// The colour channel that holds the weight.
        channel: ColorChannel,
        /// Smallest weight that holds a vertex, in `(0, 1]`.
        threshold: f32,
    },
    /// Every vertex inside an axis-aligned box of the mesh's own coordinates, as authored (the
    /// grid's: centred on the origin in the XZ plane, in metres), bounds included.
    Region {
        /// The box's smallest corner.
        min: Vec3,
        /// The box's largest corner.
        max: Vec3,
    },
}

/// One channel of a vertex colour.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "bevy_reflect", derive(bevy_reflect::Reflect), reflect(Default, Debug, PartialEq))]
pub enum ColorChannel {
    /// The first channel.
    #[default]
    Red,
    /// The second channel.
    Green,
    /// The third channel.
    Blue,
    /// The fourth channel.
    Alpha,
}

impl ColorChannel {
    fn index(self) -> usize {
        match self {
            Self::Red => 0,
            Self::Green => 1,
            Self::Blue => 2,
            Self::Alpha => 3,
        }
    }
}

/// What a selection reads of the cloth's mesh: each vertex's position in the mesh's own
/// coordinates and, when the mesh has them, its colours. Both are indexed like
/// [`ClothTopology::vertex_particle`].
#[derive(Clone, Copy, Debug)]
pub struct MeshVertices<'a> {
    /// Vertex positions as authored.
    pub positions: &'a [[f32; 3]],
    /// Vertex colours, when the mesh has them.
    pub colors: Option<&'a [[f32; 4]]>,
}

impl ClothPins {
    /// The particles of `topology` this selects, sorted and without duplicates. `vertices` is
    /// the mesh the topology was built from (the grid's own rest positions for a generated grid).
    ///
    /// Grid positions on a topology that is not a grid, indices past the mesh, paint on a mesh
    /// without colours, and a NaN threshold or box are errors.
    pub fn particles(&self, topology: &ClothTopology, vertices: MeshVertices<'_>) -> Result<Vec<u32>, ClothError> {
        let map = topology.vertex_particle();
        let count = map.len() as u32;
        let grid_cols = || topology.stencil().map(|grid| grid.cols as u32).ok_or(ClothError::PinsNeedGrid);
        let selected: Vec<u32> = match self {
            ClothPins::None => Vec::new(),
            ClothPins::TwoEnds => vec![0, grid_cols()? - 1],
            ClothPins::FirstRow => (0..grid_cols()?).collect(),
            ClothPins::Indices(indices) => {
                if let Some(&bad) = indices.iter().find(|&&v| v >= count) {
                    return Err(ClothError::PinOutOfRange { index: bad, particles: count });
                }
                indices.clone()
            }
            ClothPins::Painted { channel, threshold } => {
                if !(threshold.is_finite() && *threshold > 0.0 && *threshold <= 1.0) {
                    return Err(ClothError::PinThreshold { value: *threshold });
                }
                let colors = vertices.colors.filter(|c| c.len() == map.len()).ok_or(ClothError::PinsNeedColors)?;
                let c = channel.index();
                (0..count).filter(|&v| colors[v as usize][c] >= *threshold).collect()
            }
            ClothPins::Region { min, max } => {
                if !(min.is_finite() && max.is_finite()) {
                    return Err(ClothError::NotFinite { field: "pins region" });
                }
                if vertices.positions.len() != map.len() {
                    return Err(ClothError::PinsNeedPositions);
                }
                (0..count)
                    .filter(|&v| {
                        let p = Vec3::from(vertices.positions[v as usize]);
                        p.cmpge(*min).all() && p.cmple(*max).all()
                    })
                    .collect()
            }
        };
        let mut particles: Vec<u32> = selected.into_iter().map(|v| map[v as usize]).collect();
        particles.sort_unstable();
        particles.dedup();
        Ok(particles)
    }
}

#[cfg(test)]
mod tests {
    use glam::{UVec2, Vec2};

    use super::*;
    use crate::cloth::grid::ClothGrid;
    use crate::mesh::MeshRef;

    /// Two triangles of a unit square whose diagonal is a seam: vertices 3 and 4 duplicate 0
    /// and 2.
    fn seamed_square() -> (Vec<[f32; 3]>, Vec<u32>) {
        let positions =
            vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 0.0, 1.0], [0.0, 0.0, 0.0], [1.0, 0.0, 1.0], [0.0, 0.0, 1.0]];
        (positions, vec![0, 1, 2, 3, 4, 5])
    }

    #[test]
    fn grid_selections_pick_the_first_row() {
        let grid = ClothGrid::new(Vec2::splat(1.0), UVec2::new(4, 3));
        let topology = ClothTopology::grid(grid).unwrap();
        let positions: Vec<[f32; 3]> = topology.rest_positions().iter().map(|p| p.to_array()).collect();
        let vertices = MeshVertices { positions: &positions, colors: None };
        assert_eq!(ClothPins::TwoEnds.particles(&topology, vertices).unwrap(), vec![0, 3]);
        assert_eq!(ClothPins::FirstRow.particles(&topology, vertices).unwrap(), vec![0, 1, 2, 3]);
        // The first row lies at the smallest z; a region around it finds the same particles.
        let row = ClothPins::Region { min: Vec3::new(-1.0, -0.1, -0.51), max: Vec3::new(1.0, 0.1, -0.49) };
        assert_eq!(row.particles(&topology, vertices).unwrap(), vec![0, 1, 2, 3]);
        assert_eq!(ClothPins::Indices(vec![11, 0, 11]).particles(&topology, vertices).unwrap(), vec![0, 11]);
        assert_eq!(
            ClothPins::Indices(vec![12]).particles(&topology, vertices),
            Err(ClothError::PinOutOfRange { index: 12, particles: 12 })
        );
    }

    #[test]
    fn a_painted_seam_vertex_holds_the_welded_particle() {
        let (positions, indices) = seamed_square();
        let topology = ClothTopology::from_mesh(MeshRef { positions: &positions, indices: Some(&indices) }).unwrap();
        assert_eq!(topology.len(), 4);
        // Paint only vertex 4 (a duplicate of vertex 2) in green, vertex 1 faintly.
        let mut colors = vec![[1.0, 0.0, 0.0, 1.0]; 6];
        colors[4][1] = 1.0;
        colors[1][1] = 0.2;
        let vertices = MeshVertices { positions: &positions, colors: Some(&colors) };
        let held = ClothPins::Painted { channel: ColorChannel::Green, threshold: 0.5 };
        let particles = held.particles(&topology, vertices).unwrap();
        assert_eq!(particles, vec![topology.vertex_particle()[2]]);
        assert_eq!(topology.vertex_particle()[2], topology.vertex_particle()[4]);
        let faint = ClothPins::Painted { channel: ColorChannel::Green, threshold: 0.2 };
        assert_eq!(faint.particles(&topology, vertices).unwrap().len(), 2);
        let all = ClothPins::Painted { channel: ColorChannel::Alpha, threshold: 1.0 };
        assert_eq!(all.particles(&topology, vertices).unwrap(), vec![0, 1, 2, 3]);
    }

    #[test]
    fn selections_that_cannot_apply_are_errors() {
        let (positions, indices) = seamed_square();
        let topology = ClothTopology::from_mesh(MeshRef { positions: &positions, indices: Some(&indices) }).unwrap();
        let bare = MeshVertices { positions: &positions, colors: None };
        let painted = ClothPins::Painted { channel: ColorChannel::Red, threshold: 0.5 };
        assert_eq!(ClothPins::TwoEnds.particles(&topology, bare), Err(ClothError::PinsNeedGrid));
        assert_eq!(painted.particles(&topology, bare), Err(ClothError::PinsNeedColors));
        let short = [[1.0f32; 4]; 5];
        assert_eq!(
            painted.particles(&topology, MeshVertices { colors: Some(&short), ..bare }),
            Err(ClothError::PinsNeedColors)
        );
        for threshold in [0.0, -1.0, 1.5, f32::NAN] {
            let bad = ClothPins::Painted { channel: ColorChannel::Red, threshold };
            assert!(matches!(bad.particles(&topology, bare), Err(ClothError::PinThreshold { .. })), "{threshold}");
        }
        let nan = ClothPins::Region { min: Vec3::NAN, max: Vec3::ONE };
        assert_eq!(nan.particles(&topology, bare), Err(ClothError::NotFinite { field: "pins region" }));
        let inside = ClothPins::Region { min: Vec3::splat(-0.1), max: Vec3::new(0.1, 0.1, 1.1) };
        assert_eq!(inside.particles(&topology, bare).unwrap().len(), 2);
    }
}
