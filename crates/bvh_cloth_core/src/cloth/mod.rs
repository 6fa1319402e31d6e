//! The cloth as a shape: its particle grid or authored mesh ([`ClothTopology`]), the springs
//! between its particles (paper 2.1), which particles are held ([`ClothPins`]), the tethers
//! that keep a held cloth from stretching ([`Tethers`]), the colouring the block-descent solver
//! sweeps by, per-particle normals (paper Algorithm 3), and the error of every cloth
//! constructor and setter ([`ClothError`]).
//!
//! It uses [`crate::mesh`] only: nothing here knows how a cloth is stepped or what it collides
//! with.

pub(crate) mod colouring;
pub(crate) mod error;
pub(crate) mod grid;
pub(crate) mod normals;
pub(crate) mod pins;
pub mod tethers;
pub mod topology;

pub use error::ClothError;
pub use grid::{ClothGrid, MAX_PARTICLES};
pub use pins::{ClothPins, ColorChannel, MeshVertices};
pub use tethers::Tethers;
pub use topology::{ClothTopology, SpringEnd};
