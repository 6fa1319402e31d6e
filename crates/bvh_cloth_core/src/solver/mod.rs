//! How a cloth is stepped: its parameters ([`ClothParams`], paper Table V, with the settings
//! of the air, self-contact and the solver it carries), the spring forces (paper eq. 1–3), and
//! the block-descent integrator (vertex block descent, Chen et al. 2024). The explicit
//! integrators' stages live with the stepper in [`crate::sim`].
//!
//! It uses the cloth, the colliders, the air and self-contact below it.

pub mod block_descent;
pub(crate) mod forces;
pub mod multigrid;
pub(crate) mod params;

pub use params::{ClothParams, Integrator, SpringStiffness};
