//! What every collision response shares, and what it answers: the contact band, the passes of
//! a push out, and the [`Response`] itself. It imports nothing of the crate, so that each
//! shape's response ([`crate::colliders::collision`], [`crate::colliders::primitives`], [`crate::colliders::exact_contact`]) and
//! the solver can use it without importing one another.

use glam::Vec3;

/// Relative distance above a sphere's surface within which a previous position counts as in
/// contact (see [`crate::colliders::collision`]): ten times [`SURFACE_TOLERANCE`](crate::bvh::traversal::SURFACE_TOLERANCE), so that a particle the last
/// response put on a surface is always in contact with it on the next substep.
pub const CONTACT_BAND: f32 = 1.0e-2;

/// How many times a particle that starts a substep inside a sphere is pushed out.
pub const MAX_PASSES: usize = 4;

/// What the response did to a particle, in the collider's local frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Response {
    /// Nothing touched: the particle keeps its integrated position.
    Free,
    /// The particle moves to this point.
    Moved(Vec3),
    /// The particle stays at its previous position (the guard of [`crate::colliders::collision`]).
    Stay,
}
