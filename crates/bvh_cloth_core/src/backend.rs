//! What a backend reads beyond the public API: the structures a GPU backend uploads, the
//! constants its kernels share with the CPU reference, and the reference's own queries, which
//! the GPU crate's tests and the benchmarks compare against.
//!
//! This module is for `bvh_cloth_gpu` and the workspace's tests and benchmarks. A game names
//! the types at the crate's root instead; what is here follows the kernels and may change with
//! them in any release.

pub use crate::air::{Air, AirModel, AirSource, NOISE_TIME_PERIOD, SOURCE_BLAST, SOURCE_FAN};
pub use crate::bvh::lbvh::LEAF_BIT;
pub use crate::bvh::traversal::{STACK_SIZE, SURFACE_TOLERANCE};
pub use crate::bvh::wide::WideBvh;
pub use crate::cloth::colouring::{MAX_COLOURS, ParticleColouring};
pub use crate::cloth::normals::particle_normal;
pub use crate::cloth::tethers::{TetherSet, UNTETHERED};
pub use crate::colliders::collision::ColliderFrame;
pub use crate::colliders::exact_contact::{LOOKOUT_ROUNDING, TriangleSurface};
pub use crate::colliders::primitives::{CLOSEST_STEPS, SWEEP_STEPS};
pub use crate::colliders::response::{CONTACT_BAND, MAX_PASSES};
pub use crate::colliders::skinning::{SkinPoint, SkinnedVertices, largest_scale};
pub use crate::colliders::voxel_spheres::{MAX_RESOLUTION, SURFACE_CLEARANCE, voxel_spheres};
pub use crate::mesh::triangles::{
    EDGE_SLACK, PLANE_ROUNDING, closest_point, crossing_pairs, face_normal, intersecting_pairs, segment_hit,
};
pub use crate::self_contact::{
    ContactBody, ContactSolver, MAX_CANDIDATES, MAX_HELD_SCALE, MAX_PATH_SPAN, MAX_SPAN, MAX_TESTS_PER_TRIANGLE,
    UNTANGLE_EVERY, particle_spacing, shared_substeps,
};
pub use crate::solver::block_descent::{BLEND_LAG, BLEND_STEP, MultigridStepping};
pub use crate::solver::forces::ForceModel;
pub use crate::solver::multigrid::{
    COARSEST_SMOOTHING, Cycle, DENSE_NODES, JACOBI_WEIGHT, LayoutSpring, LevelLayout, MultigridCorrection,
    MultigridLayout, NO_NODE, REASSEMBLE_EVERY, STALE_CURVATURE,
};
pub use crate::solver::params::{MAX_ITERATIONS, MAX_SUBSTEPS_PER_TICK};
