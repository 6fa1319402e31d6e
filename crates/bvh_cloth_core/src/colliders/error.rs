//! Why a collider could not be built: the typed error of every collider constructor.

use core::fmt;

use crate::mesh::{MAX_COORDINATE, MeshDefect};

/// Why a collider could not be built from a triangle mesh or a primitive.
#[derive(Clone, Debug, PartialEq)]
pub enum ColliderError {
    /// The mesh has no vertex positions.
    EmptyMesh,
    /// The mesh has no triangle that references a vertex.
    NoTriangles,
    /// The index list is not a whole number of triangles.
    IndicesNotTriangles {
        /// Length of the index list.
        len: usize,
    },
    /// A mesh without indices (every three vertices a triangle) whose vertex count is not a
    /// multiple of three.
    VerticesNotTriangles {
        /// Number of vertices.
        vertices: usize,
    },
    /// A vertex position is NaN or infinite.
    NonFiniteVertex {
        /// Index of the first such vertex.
        vertex: usize,
    },
    /// A vertex coordinate is so large that squared distances would overflow `f32`.
    VertexTooFar {
        /// Index of the first such vertex.
        vertex: usize,
        /// The largest coordinate magnitude accepted.
        limit: f32,
    },
    /// A triangle references a vertex that does not exist.
    IndexOutOfRange {
        /// Position of the bad entry in the index list.
        position: usize,
        /// The index found there.
        index: u32,
        /// Number of vertices in the mesh.
        vertices: usize,
    },
    /// Every referenced vertex sits at the same point: there is no volume or area to voxelise.
    ZeroExtent,
    /// The voxel resolution `n` must be at least 1.
    ZeroResolution,
    /// The mesh given for exact contact is not the one the collider's spheres were built from:
    /// its triangles' box does not fit the spheres' box.
    ExactMeshMismatch,
    /// The voxel resolution is larger than the core accepts.
    ResolutionTooHigh {
        /// The requested resolution.
        n: u32,
        /// The largest accepted resolution.
        max: u32,
    },
    /// The memory the voxelisation needs could not be allocated.
    OutOfMemory {
        /// The size of the allocation that failed, in bytes.
        bytes: usize,
    },
    /// A voxel size that is zero, negative or not finite.
    BadVoxelSize(f32),
    /// A voxel size so small against the mesh that the grid would have more voxels than the
    /// core accepts.
    TooManyVoxels {
        /// The voxel size asked for (the mesh's units).
        size: f32,
        /// The voxels it would make.
        voxels: u64,
        /// The most accepted.
        max: u64,
    },
    /// A primitive with a zero, negative or non-finite size, or a zero normal.
    BadPrimitive(crate::colliders::primitive_shape::Primitive),
    /// A skin whose joint or weight list does not have one entry per vertex.
    SkinLength {
        /// Vertices of the mesh.
        vertices: usize,
        /// Entries of the joint list.
        joints: usize,
        /// Entries of the weight list.
        weights: usize,
    },
    /// A vertex whose skin weights are negative, not finite, or all zero.
    BadSkinWeights {
        /// The first such vertex.
        vertex: usize,
        /// Its weights.
        weights: [f32; 4],
    },
    /// A vertex weighted to a joint the skin does not have.
    JointOutOfRange {
        /// The first such vertex.
        vertex: usize,
        /// The joint index it names.
        joint: u16,
        /// Joints of the skin.
        joints: usize,
    },
    /// A skinned collider posed with fewer joint matrices than its skin has joints.
    MissingJoints {
        /// Matrices given.
        joints: usize,
        /// Matrices needed.
        needed: usize,
    },
    /// A joint matrix with a NaN or infinite entry.
    NonFiniteJoint {
        /// The joint.
        joint: usize,
    },
    /// No triangle of the mesh has an area: exact contact has no surface to hold the cloth off.
    NoArea,
    /// More triangles with an area than exact contact's tree holds.
    TooManyTriangles {
        /// The mesh's triangles with an area.
        triangles: usize,
        /// The most accepted.
        max: usize,
    },
    /// A skinned collider's refit data and tree do not belong together.
    SkinTreeMismatch {
        /// Leaves of the tree.
        leaves: usize,
        /// Leaves the refit data has.
        expected: usize,
    },
}

impl fmt::Display for ColliderError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::EmptyMesh => write!(f, "collider mesh has no vertex positions"),
            Self::NoTriangles => write!(f, "collider mesh has no triangles"),
            Self::IndicesNotTriangles { len } => {
                write!(f, "collider mesh has {len} indices, which is not a whole number of triangles")
            }
            Self::VerticesNotTriangles { vertices } => write!(
                f,
                "collider mesh has no indices and {vertices} vertices, which is not a whole number of triangles"
            ),
            Self::NonFiniteVertex { vertex } => {
                write!(f, "collider mesh vertex {vertex} has a NaN or infinite coordinate")
            }
            Self::VertexTooFar { vertex, limit } => {
                write!(f, "collider mesh vertex {vertex} lies further than {limit:e} from the origin")
            }
            Self::IndexOutOfRange { position, index, vertices } => write!(
                f,
                "collider mesh index {position} points at vertex {index}, but the mesh has {vertices} vertices"
            ),
            Self::ZeroExtent => write!(f, "collider mesh has zero extent: all of its vertices are at one point"),
            Self::ZeroResolution => write!(f, "collider voxel resolution `n` must be at least 1"),
            Self::ExactMeshMismatch => write!(
                f,
                "the mesh given for exact contact is not the one the collider's spheres were built from (their bounds \
                 differ); build both from one mesh with `Collider::from_mesh_exact`"
            ),
            Self::ResolutionTooHigh { n, max } => {
                write!(f, "collider voxel resolution n = {n} is above the maximum of {max}")
            }
            Self::OutOfMemory { bytes } => {
                write!(f, "collider voxelisation could not allocate {bytes} bytes")
            }
            Self::BadVoxelSize(size) => write!(f, "collider voxel size {size} is not a positive finite length"),
            Self::TooManyVoxels { size, voxels, max } => write!(
                f,
                "collider voxel size {size} would cut the mesh into {voxels} voxels; at most {max} are accepted"
            ),
            Self::BadPrimitive(shape) => {
                write!(f, "collider primitive {shape:?} needs finite positive sizes and a non-zero normal")
            }
            Self::SkinLength { vertices, joints, weights } => write!(
                f,
                "skinned collider mesh has {vertices} vertices but {joints} joint indices and {weights} joint weights"
            ),
            Self::BadSkinWeights { vertex, weights } => write!(
                f,
                "skinned collider mesh vertex {vertex} has joint weights {weights:?}: they must be finite, not \
                 negative, and not all zero"
            ),
            Self::JointOutOfRange { vertex, joint, joints } => write!(
                f,
                "skinned collider mesh vertex {vertex} is weighted to joint {joint}, but the skin has {joints} joints"
            ),
            Self::MissingJoints { joints, needed } => {
                write!(f, "skinned collider posed with {joints} joint matrices, but its skin has {needed} joints")
            }
            Self::NonFiniteJoint { joint } => {
                write!(f, "skinned collider joint {joint} has a NaN or infinite transform")
            }
            Self::NoArea => write!(
                f,
                "collider mesh has no triangle with an area, so exact contact has no surface (sphere contact \
                 collides with its voxel spheres)"
            ),
            Self::TooManyTriangles { triangles, max } => write!(
                f,
                "collider mesh has {triangles} triangles with an area, more than exact contact holds ({max}); \
                 build it with sphere contact, or split the mesh"
            ),
            Self::SkinTreeMismatch { leaves, expected } => {
                write!(f, "skinned collider refit data holds {expected} spheres but its tree has {leaves}")
            }
        }
    }
}

impl std::error::Error for ColliderError {}

impl From<MeshDefect> for ColliderError {
    fn from(defect: MeshDefect) -> Self {
        match defect {
            MeshDefect::Empty => Self::EmptyMesh,
            MeshDefect::NonFiniteVertex { vertex } => Self::NonFiniteVertex { vertex },
            MeshDefect::VertexTooFar { vertex } => Self::VertexTooFar { vertex, limit: MAX_COORDINATE },
            MeshDefect::VerticesNotTriangles { vertices } => Self::VerticesNotTriangles { vertices },
            MeshDefect::NoTriangles => Self::NoTriangles,
            MeshDefect::IndicesNotTriangles { len } => Self::IndicesNotTriangles { len },
            MeshDefect::IndexOutOfRange { position, index, vertices } => {
                Self::IndexOutOfRange { position, index, vertices }
            }
        }
    }
}
