//! The optional stages of a batch's substep, each with its own buffers, bind groups and
//! dispatches: the air (`air.wgsl`) for the cloths with drag or lift, self-contact
//! (`self_contact.wgsl`) for the cloths with a contact thickness, and the multigrid correction
//! (`multigrid.wgsl`) of block descent's sweep. The batch allocates them when
//! a cloth needs one and schedules them in its tick.
//!
//! Uses the kernels, the buffers and the layouts below it; the batch above uses these.

pub(crate) mod air;
pub(crate) mod multigrid;
pub(crate) mod self_contact;
