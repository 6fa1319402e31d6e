//! The hashed grid contact finds its pairs in (Teschner et al. 2003, "Optimized spatial hashing
//! for collision detection of deformable objects"): each primitive (a triangle or an edge) is
//! entered in the bucket of every cell its box overlaps, and a query looks in the buckets of
//! the cells its own box overlaps. See the [module docs](super) for the layout.

use core::ops::Range;
use core::sync::atomic::{AtomicU32, Ordering};

use glam::{IVec3, Vec3, Vec3A};
use rayon::prelude::*;

use super::{MAX_CANDIDATES, MAX_SPAN};

/// The runs of primitives the grid's counting sort takes in parallel: fixed, so that the
/// buckets do not depend on the thread count.
const SORT_CHUNKS: usize = 4;

/// The grid's buckets, built again each substep.
#[derive(Clone, Debug, Default)]
pub(super) struct HashedGrid {
    /// Bucket `b` holds the primitives `entries[starts[b]..starts[b + 1]]`, in increasing order.
    starts: Vec<u32>,
    entries: Vec<u32>,
    /// The box of each entry's primitive, beside it, so that a scan of a bucket reads them in
    /// a row.
    entry_boxes: Vec<[Vec3A; 2]>,
    /// Each primitive's first grid cell: the one of its box's least corner.
    first_cells: Vec<IVec3>,
    /// Each run of primitives' count of entries in each bucket, then where they go (the
    /// counting sort's scratch).
    counts: Vec<Vec<u32>>,
    /// The cells' inverse width.
    inv: f32,
}

impl HashedGrid {
    /// The counting sort of the primitives whose boxes are `boxes` into the buckets of cells
    /// `cell` wide: each goes into every cell its box overlaps (at most [`MAX_SPAN`] cells
    /// along an axis). Returns how many primitives were wider than that.
    pub(super) fn build(&mut self, boxes: &[[Vec3A; 2]], cell: f32) -> usize {
        let buckets = (2 * boxes.len()).next_power_of_two();
        self.inv = 1.0 / cell;
        let inv = self.inv;
        // The cells of each primitive's box, its span along each axis capped.
        let cells = |&[lo, hi]: &[Vec3A; 2]| cells_of_box(lo, hi, inv, MAX_SPAN);
        let ranges: Vec<Option<((IVec3, IVec3), bool)>> = if boxes.len() >= super::PARALLEL_MIN {
            boxes.par_iter().map(cells).collect()
        } else {
            boxes.iter().map(cells).collect()
        };
        let clamped = ranges.iter().filter(|r| r.is_some_and(|(_, capped)| capped)).count();
        let ranges: Vec<Option<(IVec3, IVec3)>> = ranges.into_iter().map(|r| r.map(|(range, _)| range)).collect();
        self.first_cells.clear();
        self.first_cells.extend(ranges.iter().map(|r| r.map_or(IVec3::ZERO, |(lo, _)| lo)));
        // A counting sort in `SORT_CHUNKS` runs of primitives, counted and scattered in
        // parallel: each run's primitives go after the earlier runs' in every bucket, so the
        // buckets hold their primitives in order, as one pass over all of them would.
        let run = ranges.len().div_ceil(SORT_CHUNKS).max(1);
        let runs = ranges.len().div_ceil(run);
        self.counts.resize_with(runs, Vec::new);
        self.counts.par_iter_mut().zip(ranges.par_chunks(run)).for_each(|(count, part)| {
            count.clear();
            count.resize(buckets, 0);
            for range in part {
                for_each_bucket(*range, buckets, |b| count[b] += 1);
            }
        });
        // Each run's count becomes where its primitives start in the bucket.
        self.starts.clear();
        self.starts.resize(buckets + 1, 0);
        let mut total = 0u32;
        for b in 0..buckets {
            self.starts[b] = total;
            for count in &mut self.counts[..runs] {
                (count[b], total) = (total, total + count[b]);
            }
        }
        self.starts[buckets] = total;
        let entries: Vec<AtomicU32> = (0..total).map(|_| AtomicU32::new(0)).collect();
        ranges.par_chunks(run).zip(self.counts.par_iter_mut()).enumerate().for_each(|(k, (part, next))| {
            for (i, range) in part.iter().enumerate() {
                let t = (k * run + i) as u32;
                for_each_bucket(*range, buckets, |b| {
                    entries[next[b] as usize].store(t, Ordering::Relaxed);
                    next[b] += 1;
                });
            }
        });
        self.entries.clear();
        self.entries.extend(entries.into_iter().map(AtomicU32::into_inner));
        self.refresh(boxes);
        clamped
    }

    /// Copies `boxes` (the primitives' boxes, changed since [`Self::build`]) beside the
    /// entries, where a search's box test reads them. The buckets stay those of the boxes the
    /// grid was built with.
    pub(super) fn refresh(&mut self, boxes: &[[Vec3A; 2]]) {
        self.entry_boxes.clear();
        self.entries.par_iter().map(|&t| boxes[t as usize]).collect_into_vec(&mut self.entry_boxes);
    }

    /// Calls `meet(k)` once for each primitive `k` in `kinds` whose box overlaps the box from
    /// `lo` to `hi`, looking in the buckets of the cells that box overlaps (at most `span`
    /// along an axis) at the first [`MAX_CANDIDATES`] primitives of `kinds` in each, and taking a
    /// primitive only in the first cell both boxes cover (met in another cell's bucket, it is
    /// a hash collision there). Returns whether a bucket held more than [`MAX_CANDIDATES`] of
    /// them, or the box was wider than `span` cells.
    pub(super) fn visit(&self, lo: Vec3A, hi: Vec3A, span: i32, kinds: Range<u32>, mut meet: impl FnMut(u32)) -> bool {
        let Some(((first, last), mut clamped)) = cells_of_box(lo, hi, self.inv, span) else {
            return false;
        };
        let buckets = self.starts.len() - 1;
        for z in first.z..=last.z {
            for y in first.y..=last.y {
                for x in first.x..=last.x {
                    let at = IVec3::new(x, y, z);
                    let b = bucket(at, buckets);
                    let bucket = self.starts[b] as usize..self.starts[b + 1] as usize;
                    // The bucket's entries are in increasing order: those of `kinds` are a run.
                    let entries = &self.entries[bucket.clone()];
                    let from = entries.partition_point(|&k| k < kinds.start);
                    let to = from + entries[from..].partition_point(|&k| k < kinds.end);
                    clamped |= to - from > MAX_CANDIDATES;
                    let boxes = &self.entry_boxes[bucket][from..to];
                    for (&k, &[k_lo, k_hi]) in entries[from..to].iter().zip(boxes).take(MAX_CANDIDATES) {
                        // The boxes first: most candidates are beside the query, not within
                        // the thickness of it.
                        if !(lo.cmple(k_hi).all() && hi.cmpge(k_lo).all()) {
                            continue;
                        }
                        if self.first_cells[k as usize].max(first) != at {
                            continue;
                        }
                        meet(k);
                    }
                }
            }
        }
        clamped
    }
}

/// The cells the box from `lo` to `hi` overlaps (cells `1 / inv` wide), capped at `span` cells
/// along each axis from `lo`'s, and whether it was capped; `None` for a box that is not finite.
#[inline]
fn cells_of_box(lo: Vec3A, hi: Vec3A, inv: f32, span: i32) -> Option<((IVec3, IVec3), bool)> {
    if !(lo.is_finite() && hi.is_finite()) {
        return None;
    }
    let (lo, hi) = (cell_of(lo.into(), inv), cell_of(hi.into(), inv));
    let capped = lo.wrapping_add(IVec3::splat(span - 1)).min(hi);
    Some(((lo, capped), capped != hi))
}

/// The grid cell of `p` (cells `1 / inv` wide). Coordinates beyond `i32` saturate, and a
/// non-finite one gives cell 0 (such a particle is left out of the grid).
#[inline]
fn cell_of(p: Vec3, inv: f32) -> IVec3 {
    let c = p * inv;
    IVec3::new(floor(c.x), floor(c.y), floor(c.z))
}

/// `v.floor() as i32` without a call to the C library's `floorf`, which x86-64's baseline
/// (SSE2, no rounding instruction) makes of `f32::floor`: the truncation, less one where it
/// rounded up. Saturates as `as` does; NaN gives 0.
#[inline]
fn floor(v: f32) -> i32 {
    let t = v as i32;
    t.saturating_sub(i32::from(t as f32 > v))
}

/// Calls `f(bucket)` once for each bucket (of `buckets`) of the cells in `range`: two cells of
/// one primitive may share a bucket.
#[inline]
fn for_each_bucket(range: Option<(IVec3, IVec3)>, buckets: usize, mut f: impl FnMut(usize)) {
    let Some((lo, hi)) = range else { return };
    let mut used = [usize::MAX; (MAX_SPAN * MAX_SPAN * MAX_SPAN) as usize];
    let mut count = 0;
    for z in lo.z..=hi.z {
        for y in lo.y..=hi.y {
            for x in lo.x..=hi.x {
                let b = bucket(IVec3::new(x, y, z), buckets);
                if used[..count].contains(&b) {
                    continue;
                }
                used[count] = b;
                count += 1;
                f(b);
            }
        }
    }
}

/// The bucket of cell `c` in a table of `buckets` (a power of two).
#[inline]
fn bucket(c: IVec3, buckets: usize) -> usize {
    let h = (c.x as u32).wrapping_mul(73_856_093)
        ^ (c.y as u32).wrapping_mul(19_349_663)
        ^ (c.z as u32).wrapping_mul(83_492_791);
    h as usize & (buckets - 1)
}
