//! A wind source as the integrators and the GPU read it: a fan or a blast, in the cloth's
//! frame, with its strength at this tick.

use glam::Vec3;

/// [`AirSource`]'s kind (in `origin[3]`) of a fan.
pub const SOURCE_FAN: u32 = 0;

/// [`AirSource`]'s kind of a blast.
pub const SOURCE_BLAST: u32 = 1;

/// A [`WindSource`](crate::WindSource) ready to sample, as both backends read it (the GPU's `WindSource`, 48
/// bytes): `origin` (`w`: [`SOURCE_FAN`] or [`SOURCE_BLAST`]), `axis` (the fan's unit axis;
/// `w`: the speed) and `reach` (the range or radius, and the cosine of the fan's spread).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct AirSource {
    /// Origin, and the kind.
    pub origin: [f32; 4],
    /// Unit axis, and the speed.
    pub axis: [f32; 4],
    /// Range, cosine of the spread, and two unused words.
    pub reach: [f32; 4],
}

impl AirSource {
    /// The source's wind at `p`. The GPU's `source_wind` repeats this arithmetic.
    pub fn velocity_at(&self, p: Vec3) -> Vec3 {
        let origin = Vec3::new(self.origin[0], self.origin[1], self.origin[2]);
        let d = p - origin;
        let dist = d.length();
        let range = self.reach[0];
        if !(dist > 0.0 && dist < range) {
            return Vec3::ZERO;
        }
        let inv = 1.0 / dist;
        let mut strength = self.axis[3] * (1.0 - dist * (1.0 / range));
        if self.origin[3] == SOURCE_FAN as f32 {
            let axis = Vec3::new(self.axis[0], self.axis[1], self.axis[2]);
            let cos_spread = self.reach[1];
            let c = d.dot(axis) * inv;
            if c <= cos_spread {
                return Vec3::ZERO;
            }
            let s = (c - cos_spread) / (1.0 - cos_spread);
            strength *= s * s * (3.0 - 2.0 * s);
        }
        d * (strength * inv)
    }
}
