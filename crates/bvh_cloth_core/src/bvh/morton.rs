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

/// Bits of a code sorted per pass of [`sort_by_code`]: three passes cover all 32.
const RADIX_BITS: u32 = 11;

/// Below this many codes [`sort_by_code`] sorts by comparison.
const RADIX_MIN: usize = 1024;

/// The pairs `(code, index)` of `codes` sorted by code, equal codes in index order: a stable
/// least-significant-digit radix sort, linear in the count (a comparison sort of the 200,000
/// leaves of a triangle surface takes about twice as long). Fewer than `RADIX_MIN` codes are
/// sorted by comparison, which is quicker than clearing the radix counters.
pub fn sort_by_code(codes: impl ExactSizeIterator<Item = u32>) -> Vec<(u32, u32)> {
    const BUCKETS: usize = 1 << RADIX_BITS;
    // The code in the high half and the index in the low: a pass moves one `u64`.
    let mut keys: Vec<u64> = codes.enumerate().map(|(i, c)| (u64::from(c) << 32) | i as u64).collect();
    if keys.len() < RADIX_MIN {
        keys.sort_unstable();
        return keys.into_iter().map(|k| ((k >> 32) as u32, k as u32)).collect();
    }
    let mut counts = vec![[0u32; BUCKETS]; 3];
    for &k in &keys {
        for (pass, count) in counts.iter_mut().enumerate() {
            count[digit(k, pass)] += 1;
        }
    }
    let mut next = vec![0u64; keys.len()];
    for (pass, count) in counts.iter_mut().enumerate() {
        // A pass whose digit is the same for every key leaves the order as it is.
        if count.iter().any(|&c| c as usize == keys.len()) {
            continue;
        }
        let mut sum = 0u32;
        for c in count.iter_mut() {
            (*c, sum) = (sum, sum + *c);
        }
        for &k in &keys {
            let slot = &mut count[digit(k, pass)];
            next[*slot as usize] = k;
            *slot += 1;
        }
        std::mem::swap(&mut keys, &mut next);
    }
    keys.into_iter().map(|k| ((k >> 32) as u32, k as u32)).collect()
}

/// The radix digit of `key`'s code for `pass`.
#[inline]
fn digit(key: u64, pass: usize) -> usize {
    ((key >> (32 + RADIX_BITS as usize * pass)) & ((1 << RADIX_BITS) - 1)) as usize
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
    fn radix_sort_matches_a_comparison_sort() {
        let mut seed = 99u32;
        for (count, mask) in
            [(0, 0), (1, u32::MAX), (300, u32::MAX), (5000, u32::MAX), (5000, 0x3f), (5000, 0x7ff << 11)]
        {
            let codes: Vec<u32> = (0..count)
                .map(|_| {
                    seed ^= seed << 13;
                    seed ^= seed >> 17;
                    seed ^= seed << 5;
                    seed & mask
                })
                .collect();
            let mut want: Vec<(u32, u32)> = codes.iter().enumerate().map(|(i, &c)| (c, i as u32)).collect();
            want.sort_unstable();
            assert_eq!(sort_by_code(codes.into_iter()), want, "{count} codes masked by {mask:#x}");
        }
    }

    #[test]
    fn flat_axes_and_nan_do_not_panic() {
        let code = morton_code(Vec3::new(f32::NAN, 5.0, 1.0), Vec3::ZERO, Vec3::new(0.0, 10.0, 0.0));
        assert_eq!(code, spread_bits(512) << 1);
    }
}
