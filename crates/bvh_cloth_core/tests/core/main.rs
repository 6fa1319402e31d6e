//! The core's integration tests, in one binary so that the crate and its generic code are
//! compiled and linked once for all of them (`voxel_memory` counts every allocation of its
//! binary, so it keeps its own). Each module is one concern.

mod common;

mod aerodynamics;
mod block_descent;
mod cloth;
mod collider_fuzz;
mod collision;
mod exact_contact;
mod free_fall;
mod house;
mod integrators;
mod layers;
mod lbvh;
mod motion;
mod self_contact;
mod shell;
mod thin_contact;
mod wide_bvh;
