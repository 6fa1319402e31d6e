//! The wind's noise: an integer hash, value noise in time (the gusts) and vector value noise
//! in space and time (the turbulence), with the lattice shared by a tick's particles sampled
//! once.

use glam::{Vec3, Vec3A};

/// Lattice steps after which the noise's time axis repeats.
pub const NOISE_TIME_PERIOD: u32 = 4096;

/// The integer hash behind the noise (Wellons' `lowbias32`): every input bit flips about half
/// of the output bits.
#[inline]
pub fn hash(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^= x >> 16;
    x
}

/// One lattice value in `[-1, 1]` from 10 bits of a hash.
#[inline]
pub(super) fn unit(bits: u32) -> f32 {
    ((bits & 0x3ff) as f32 - 511.5) * (1.0 / 511.5)
}

/// Smoothstep weight of a fraction in `[0, 1)`.
#[inline]
pub(super) fn smooth(f: f32) -> f32 {
    f * f * (3.0 - 2.0 * f)
}

/// A one-dimensional value noise in `[-1, 1]` at lattice time `t` (`0 <= t`), repeating every
/// [`NOISE_TIME_PERIOD`] steps.
pub fn value_noise_1d(t: f32, seed: u32) -> f32 {
    let cell = t.floor();
    let i = cell as u32;
    let s = smooth(t - cell);
    let key = |k: u32| hash((k % NOISE_TIME_PERIOD) ^ seed.wrapping_mul(0x9e37_79b9));
    let (a, b) = (unit(key(i)), unit(key(i.wrapping_add(1))));
    a + (b - a) * s
}

/// One coordinate's key in a lattice corner's hash: the coordinate times its own odd constant.
/// A corner's hash is that of its four keys and the seed, XORed.
#[inline]
pub(super) fn lattice_key(coordinate: i32, prime: u32) -> u32 {
    (coordinate as u32).wrapping_mul(prime)
}

#[inline]
pub(super) fn time_key(t: u32) -> u32 {
    (t % NOISE_TIME_PERIOD).wrapping_mul(0x1656_67b1)
}

/// The lattice cell of `q`: `Vec3::floor` on SIMD lanes, inline where `f32::floor` is a call.
#[inline]
pub(super) fn floor(q: Vec3) -> Vec3 {
    Vec3A::from(q).floor().into()
}

/// A corner's vector: three lattice values from one hash.
#[inline]
pub(super) fn corner_vector(h: u32) -> Vec3A {
    Vec3A::new(unit(h), unit(h >> 10), unit(h >> 20))
}

/// A vector value noise in space and time, each component in `[-1, 1]`: at `q` (lattice
/// units) and lattice time `t` (`0 <= t`), smoothstep-blended over the 16 corners of its cell.
/// The GPU's `value_noise_4d` repeats this arithmetic.
pub fn value_noise_4d(q: Vec3, t: f32, seed: u32) -> Vec3 {
    let cell = floor(q);
    let tc = t.floor();
    let [x, y, z] = [cell.x as i32, cell.y as i32, cell.z as i32];
    let ti = tc as u32;
    // The corners' hashes XOR one key per coordinate (as `corner` does): each key is found once.
    let xs = [lattice_key(x, X_KEY), lattice_key(x.wrapping_add(1), X_KEY)];
    let ys = [lattice_key(y, Y_KEY), lattice_key(y.wrapping_add(1), Y_KEY)];
    let zs = [lattice_key(z, Z_KEY), lattice_key(z.wrapping_add(1), Z_KEY)];
    let ts = [time_key(ti) ^ seed, time_key(ti.wrapping_add(1)) ^ seed];
    let st = smooth(t - tc);
    blend_cell(q - cell, |[i, j, k]| {
        let key = xs[i] ^ ys[j] ^ zs[k];
        corner_at(key, ts, st)
    })
}

/// The odd constants of the lattice's x, y and z keys.
pub(super) const X_KEY: u32 = 0x8da6_b343;

pub(super) const Y_KEY: u32 = 0xd816_3841;

pub(super) const Z_KEY: u32 = 0xcb1a_b31f;

/// The vector of the lattice corner whose spatial keys XOR to `key`, at a time between two
/// lattice times (keys `ts`, seed included): its vectors at the two blended by the time's
/// smoothstep weight `st`. Time is blended first, so that one tick's corners are blended once,
/// whatever the number of points in their cells.
#[inline(always)]
pub(super) fn corner_at(key: u32, ts: [u32; 2], st: f32) -> Vec3A {
    lerp(corner_vector(hash(key ^ ts[0])), corner_vector(hash(key ^ ts[1])), st)
}

/// `a` blended towards `b` by the weight `s`.
#[inline(always)]
pub(super) fn lerp(a: Vec3A, b: Vec3A, s: f32) -> Vec3A {
    a + (b - a) * s
}

/// The smoothstep blend of a cell's 8 corner vectors (already blended in time), `corner([x, y,
/// z])` with each index 0 or 1, at the fractions `f`: along x, then y, then z.
#[inline(always)]
pub(super) fn blend_cell(f: Vec3, corner: impl Fn([usize; 3]) -> Vec3A) -> Vec3 {
    let (sx, sy, sz) = (smooth(f.x), smooth(f.y), smooth(f.z));
    let mut by_z = [Vec3A::ZERO; 2];
    for (k, plane) in by_z.iter_mut().enumerate() {
        let mut by_y = [Vec3A::ZERO; 2];
        for (j, row) in by_y.iter_mut().enumerate() {
            *row = lerp(corner([0, j, k]), corner([1, j, k]), sx);
        }
        *plane = lerp(by_y[0], by_y[1], sy);
    }
    lerp(by_z[0], by_z[1], sz).into()
}

/// The most corner vectors a [`NoiseLattice`] holds per particle it serves (and 4,096 at
/// least): eddies far smaller than the cloth are sampled corner by corner instead.
pub(super) const LATTICE_PER_PARTICLE: usize = 2;

/// The turbulence's corner vectors over the cells a cloth's particles lie in, at one lattice
/// time: one tick's [`value_noise_4d`] for every particle, each of the cells' corners hashed
/// and blended in time once instead of once for each particle in them. The same corners and
/// the same blend give the same bits.
pub(super) struct NoiseLattice {
    /// The first corner, in lattice coordinates.
    lo: [i32; 3],
    /// Corners along x, y and z.
    dims: [usize; 3],
    /// The vectors at the lattice time, x fastest, then y and z.
    vectors: Vec<Vec3A>,
}

impl NoiseLattice {
    /// The corners round the cells of every finite `q` (lattice units) at lattice time `t`;
    /// `None` when there is no finite point or the lattice would be too large.
    pub(super) fn around(q: impl Iterator<Item = Vec3A>, t: f32, seed: u32, particles: usize) -> Option<Self> {
        // The cells' bounds are those of the points, floored (floor does not decrease).
        let (lo, hi) = q
            .filter(|q| q.is_finite())
            .fold((Vec3A::INFINITY, Vec3A::NEG_INFINITY), |(lo, hi), q| (lo.min(q), hi.max(q)));
        let (lo, hi) = (Vec3::from(lo.floor()), Vec3::from(hi.floor()));
        if !(lo.is_finite() && hi.is_finite())
            || lo.min_element() < i32::MIN as f32 / 2.0
            || hi.max_element() > i32::MAX as f32 / 2.0
        {
            return None;
        }
        let span = hi - lo + 2.0;
        let count = f64::from(span.x) * f64::from(span.y) * f64::from(span.z);
        if count > (LATTICE_PER_PARTICLE * particles).max(4096) as f64 {
            return None;
        }
        let lo = [lo.x as i32, lo.y as i32, lo.z as i32];
        let dims = [span.x as usize, span.y as usize, span.z as usize];
        let tc = t.floor();
        let st = smooth(t - tc);
        let ti = tc as u32;
        let ts = [time_key(ti) ^ seed, time_key(ti.wrapping_add(1)) ^ seed];
        let mut vectors = Vec::with_capacity(count as usize);
        for z in 0..dims[2] as i32 {
            let zk = lattice_key(lo[2].wrapping_add(z), Z_KEY);
            for y in 0..dims[1] as i32 {
                let yk = lattice_key(lo[1].wrapping_add(y), Y_KEY);
                for x in 0..dims[0] as i32 {
                    let key = lattice_key(lo[0].wrapping_add(x), X_KEY) ^ yk ^ zk;
                    vectors.push(corner_at(key, ts, st));
                }
            }
        }
        Some(Self { lo, dims, vectors })
    }

    /// [`value_noise_4d`] at `q` and the lattice's time `t`: from the stored corners when `q`'s
    /// cell is among them, else hashed.
    #[inline]
    pub(super) fn noise(&self, q: Vec3, t: f32, seed: u32) -> Vec3 {
        let cell = floor(q);
        let c = [cell.x as i32, cell.y as i32, cell.z as i32];
        let mut base = [0usize; 3];
        for axis in 0..3 {
            let offset = c[axis].wrapping_sub(self.lo[axis]);
            if !(0..self.dims[axis] as i32 - 1).contains(&offset) {
                return value_noise_4d(q, t, seed);
            }
            base[axis] = offset as usize;
        }
        let [dx, dy, _] = self.dims;
        let first = (base[2] * dy + base[1]) * dx + base[0];
        let (y_stride, z_stride) = (dx, dx * dy);
        blend_cell(q - cell, |[i, j, k]| self.vectors[first + i + j * y_stride + k * z_stride])
    }
}
