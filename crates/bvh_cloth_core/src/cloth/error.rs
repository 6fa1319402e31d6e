//! Why a cloth could not be built or retuned: the typed error of every cloth constructor and setter.

use core::fmt;

use crate::mesh::{MAX_COORDINATE, MeshDefect};

/// Why a cloth could not be built from its parameters.
#[derive(Clone, Debug, PartialEq)]
pub enum ClothError {
    /// The particle grid needs at least 2 rows and 2 columns.
    GridTooSmall {
        /// Requested rows.
        rows: u32,
        /// Requested columns.
        cols: u32,
    },
    /// The particle grid is larger than the core accepts.
    GridTooLarge {
        /// Requested rows.
        rows: u32,
        /// Requested columns.
        cols: u32,
        /// Largest particle count accepted.
        max_particles: u32,
    },
    /// A parameter must be finite and strictly positive.
    NotPositive {
        /// Name of the offending field.
        field: &'static str,
        /// The value that was given.
        value: f32,
    },
    /// A parameter must be finite and not negative.
    Negative {
        /// Name of the offending field.
        field: &'static str,
        /// The value that was given.
        value: f32,
    },
    /// A vector parameter has a NaN or infinite component.
    NotFinite {
        /// Name of the offending field.
        field: &'static str,
    },
    /// `looper` (substeps per tick) must be at least 1.
    ZeroLooper,
    /// A pinned particle index lies outside the cloth.
    PinOutOfRange {
        /// The offending index.
        index: u32,
        /// Number of particles in the cloth.
        particles: u32,
    },
    /// The cloth has no mesh to simulate, or its mesh is not a list of triangles with `f32`
    /// positions that the simulation can read.
    NoTriangleMesh,
    /// The cloth mesh has no vertex positions.
    MeshWithoutVertices,
    /// The cloth mesh's index list is not a whole number of triangles.
    MeshIndicesNotTriangles {
        /// Length of the index list.
        len: usize,
    },
    /// The cloth mesh has no indices and its vertex count is not a whole number of triangles.
    MeshVerticesNotTriangles {
        /// Number of vertices.
        vertices: usize,
    },
    /// A cloth mesh vertex position is NaN or infinite.
    MeshVertexNotFinite {
        /// Index of the first such vertex.
        vertex: usize,
    },
    /// A cloth mesh triangle references a vertex that does not exist.
    MeshIndexOutOfRange {
        /// Position of the bad entry in the index list.
        position: usize,
        /// The index found there.
        index: u32,
        /// Number of vertices in the mesh.
        vertices: usize,
    },
    /// No triangle of the cloth mesh has any area, so there is no surface to carry mass.
    MeshWithoutArea,
    /// A vertex of the cloth mesh lies further than [`crate::mesh::MAX_COORDINATE`] from the
    /// origin along an axis.
    MeshVertexTooFar {
        /// The vertex.
        vertex: usize,
        /// The largest coordinate accepted.
        limit: f32,
    },
    /// Pins chosen by grid position (the two ends, the first row) on a cloth that is not a
    /// generated grid.
    PinsNeedGrid,
    /// Pins chosen by painted weight on a mesh without a `Float32x4` colour per vertex.
    PinsNeedColors,
    /// Pins chosen by region without a position per vertex of the mesh.
    PinsNeedPositions,
    /// A painted pin weight threshold outside `(0, 1]`.
    PinThreshold {
        /// The threshold given.
        value: f32,
    },
    /// The cloth mesh cannot be coloured for the block-descent solver within the limit: some
    /// particle's spring neighbours already use every colour.
    TooManyColours {
        /// The first particle that found no free colour.
        particle: u32,
        /// Most colours allowed ([`crate::cloth::colouring::MAX_COLOURS`]).
        limit: u32,
    },
    /// A count parameter lies outside the range the solver accepts.
    CountOutOfRange {
        /// Name of the offending field.
        field: &'static str,
        /// The value that was given.
        value: u32,
        /// Smallest value accepted.
        min: u32,
        /// Largest value accepted.
        max: u32,
    },
    /// The cloth has more particles than the core accepts.
    TooManyParticles {
        /// Particles after welding.
        particles: usize,
        /// Largest particle count accepted.
        max: u32,
    },
    /// An explicit integrator would need more substeps a tick than the stability guard allows
    /// ([`crate::solver::params::MAX_SUBSTEPS_PER_TICK`]) to stay stable: stepped anyway, the cloth
    /// would go non-finite.
    BeyondStabilityGuard {
        /// Substeps a tick the integrator would need.
        needed: u32,
        /// Most substeps a tick the guard takes.
        max: u32,
    },
    /// A parameter lies outside the range the model accepts (a wind speed no air reaches, a
    /// coefficient no fabric has).
    OutOfRange {
        /// Name of the offending field.
        field: &'static str,
        /// The value that was given (for a vector, its length).
        value: f32,
        /// Smallest value accepted.
        min: f32,
        /// Largest value accepted.
        max: f32,
    },
    /// The self-contact thickness is larger than the cloth's particle spacing.
    ThicknessAboveSpacing {
        /// The thickness given, in metres.
        thickness: f32,
        /// The cloth's particle spacing (the mean rest length of its structural springs).
        spacing: f32,
    },
}

impl ClothError {
    /// `Ok` for a finite `value` above zero, else [`Self::NotPositive`] naming `field`.
    pub fn check_positive(field: &'static str, value: f32) -> Result<(), Self> {
        if value.is_finite() && value > 0.0 { Ok(()) } else { Err(Self::NotPositive { field, value }) }
    }

    /// `Ok` for a finite `value` of at least zero, else [`Self::Negative`] naming `field`.
    pub fn check_non_negative(field: &'static str, value: f32) -> Result<(), Self> {
        if value.is_finite() && value >= 0.0 { Ok(()) } else { Err(Self::Negative { field, value }) }
    }
}

impl fmt::Display for ClothError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::GridTooSmall { rows, cols } => {
                write!(f, "cloth grid of {rows}x{cols} is too small: it needs at least 2 rows and 2 columns")
            }
            Self::GridTooLarge { rows, cols, max_particles } => {
                write!(f, "cloth grid of {rows}x{cols} is too large: at most {max_particles} particles are supported")
            }
            Self::NotPositive { field, value } => {
                write!(f, "cloth parameter `{field}` must be finite and > 0, got {value}")
            }
            Self::Negative { field, value } => {
                write!(f, "cloth parameter `{field}` must be finite and >= 0, got {value}")
            }
            Self::NotFinite { field } => {
                write!(f, "cloth parameter `{field}` has a NaN or infinite component")
            }
            Self::ZeroLooper => write!(f, "cloth parameter `looper` must be at least 1"),
            Self::PinOutOfRange { index, particles } => {
                write!(f, "pinned particle {index} is outside the cloth of {particles} particles")
            }
            Self::NoTriangleMesh => {
                write!(f, "cloth has no readable triangle-list mesh with Float32x3 positions to simulate")
            }
            Self::MeshWithoutVertices => write!(f, "cloth mesh has no vertex positions"),
            Self::MeshIndicesNotTriangles { len } => {
                write!(f, "cloth mesh has {len} indices, which is not a whole number of triangles")
            }
            Self::MeshVerticesNotTriangles { vertices } => {
                write!(f, "cloth mesh has no indices and {vertices} vertices, which is not a whole number of triangles")
            }
            Self::MeshVertexNotFinite { vertex } => {
                write!(f, "cloth mesh vertex {vertex} has a NaN or infinite coordinate")
            }
            Self::MeshIndexOutOfRange { position, index, vertices } => {
                write!(f, "cloth mesh index {position} points at vertex {index}, but the mesh has {vertices} vertices")
            }
            Self::MeshWithoutArea => write!(f, "cloth mesh has no triangle with any area"),
            Self::MeshVertexTooFar { vertex, limit } => {
                write!(f, "cloth mesh vertex {vertex} lies further than {limit:e} from the origin")
            }
            Self::PinsNeedGrid => {
                write!(f, "cloth pins by grid position (two ends, first row) need a generated grid; pin vertex indices")
            }
            Self::PinsNeedColors => {
                write!(f, "cloth pins by painted weight need a Float32x4 vertex colour on every vertex of the mesh")
            }
            Self::PinsNeedPositions => write!(f, "cloth pins by region need a position for every vertex of the mesh"),
            Self::PinThreshold { value } => {
                write!(f, "cloth pin weight threshold must be in (0, 1], got {value}")
            }
            Self::TooManyColours { particle, limit } => write!(
                f,
                "cloth mesh needs more than {limit} colours for the block-descent solver (particle {particle} has \
                 springs to every colour); use another integrator or a mesh with fewer springs per vertex"
            ),
            Self::CountOutOfRange { field, value, min, max } => {
                write!(f, "cloth parameter `{field}` must be in {min}..={max}, got {value}")
            }
            Self::TooManyParticles { particles, max } => {
                write!(f, "cloth has {particles} particles; at most {max} are supported")
            }
            Self::BeyondStabilityGuard { needed, max } => write!(
                f,
                "the explicit integrator would need {needed} substeps a tick to stay stable, more than the {max} \
                 the stability guard takes: lower `spring_k`, raise `mass`, coarsen the cloth, or use \
                 `Integrator::BlockDescent`, which is stable at every stiffness"
            ),
            Self::OutOfRange { field, value, min, max } => {
                write!(f, "cloth parameter `{field}` must be in [{min}, {max}], got {value}")
            }
            Self::ThicknessAboveSpacing { thickness, spacing } => write!(
                f,
                "cloth parameter `self_contact.thickness` is {thickness} m, more than the cloth's particle spacing of \
                 {spacing} m: particles a few edges apart on the flat cloth would push each other"
            ),
        }
    }
}

impl std::error::Error for ClothError {}

impl From<MeshDefect> for ClothError {
    fn from(defect: MeshDefect) -> Self {
        match defect {
            MeshDefect::Empty => Self::MeshWithoutVertices,
            MeshDefect::NonFiniteVertex { vertex } => Self::MeshVertexNotFinite { vertex },
            MeshDefect::VertexTooFar { vertex } => Self::MeshVertexTooFar { vertex, limit: MAX_COORDINATE },
            MeshDefect::VerticesNotTriangles { vertices } => Self::MeshVerticesNotTriangles { vertices },
            // An empty index list is a mesh of no triangle, so of no area.
            MeshDefect::NoTriangles => Self::MeshWithoutArea,
            MeshDefect::IndicesNotTriangles { len } => Self::MeshIndicesNotTriangles { len },
            MeshDefect::IndexOutOfRange { position, index, vertices } => {
                Self::MeshIndexOutOfRange { position, index, vertices }
            }
        }
    }
}
