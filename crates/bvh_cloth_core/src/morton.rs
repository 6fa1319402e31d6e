//! 30-bit Morton codes (10 bits per axis), the sort key of the LBVH (paper section 2.4.2).

use glam::Vec3;

/// Spreads the low 10 bits of `v` so that two zero bits separate each of them.
fn spread_bits(v: u32) -> u32 {
    let mut x = v & 0x3ff;
    x = (x | (x << 16)) & 0x0300_00ff;
    x = (x | (x << 8)) & 0x0300_f00f;
    x = (x | (x << 4)) & 0x030c_30c3;
    x = (x | (x << 2)) & 0x0924_9249;
    x
}

/// Morton code of `p` inside the box `[min, max]`: each axis is normalised to `[0, 1]`,
/// quantised to 10 bits and interleaved as `...z1y1x1z0y0x0`. A flat axis maps to 0.
pub fn morton_code(p: Vec3, min: Vec3, max: Vec3) -> u32 {
    let extent = max - min;
    let quantise = |v: f32, lo: f32, ext: f32| -> u32 {
        if ext > 0.0 {
            // `as` saturates, and NaN becomes 0.
            (((v - lo) / ext) * 1024.0).clamp(0.0, 1023.0) as u32
        } else {
            0
        }
    };
    let x = quantise(p.x, min.x, extent.x);
    let y = quantise(p.y, min.y, extent.y);
    let z = quantise(p.z, min.z, extent.z);
    spread_bits(x) | (spread_bits(y) << 1) | (spread_bits(z) << 2)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interleaves_axes() {
        let (lo, hi) = (Vec3::ZERO, Vec3::splat(1024.0));
        assert_eq!(morton_code(Vec3::ZERO, lo, hi), 0);
        assert_eq!(morton_code(Vec3::new(1.0, 0.0, 0.0), lo, hi), 0b001);
        assert_eq!(morton_code(Vec3::new(0.0, 1.0, 0.0), lo, hi), 0b010);
        assert_eq!(morton_code(Vec3::new(0.0, 0.0, 1.0), lo, hi), 0b100);
        assert_eq!(morton_code(Vec3::new(3.0, 0.0, 0.0), lo, hi), 0b1001);
        assert_eq!(morton_code(hi, lo, hi), (1 << 30) - 1);
    }

    #[test]
    fn flat_axes_and_nan_do_not_panic() {
        let code = morton_code(Vec3::new(f32::NAN, 5.0, 1.0), Vec3::ZERO, Vec3::new(0.0, 10.0, 0.0));
        assert_eq!(code, spread_bits(512) << 1);
    }
}
