//! Voxelisation memory is bounded by the voxel count, not by how many voxels the triangles
//! cross: thousands of 1 m squares stacked in a 1 m cube, voxelised at n = 128, where every
//! triangle crosses 8,000 voxels. This binary counts every allocation, so it holds one test.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};

use bvh_cloth_core::MeshRef;

use bvh_cloth_core::backend::voxel_spheres;
use bvh_cloth_core::{ColliderError, Vec3};

/// The system allocator, counting the bytes live and the most ever live, and refusing any
/// single allocation above `FAIL_ABOVE` bytes (to stage an allocation failure).
struct Counting;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);
static FAIL_ABOVE: AtomicUsize = AtomicUsize::new(usize::MAX);

#[allow(unsafe_code)]
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if layout.size() > FAIL_ABOVE.load(Relaxed) {
            return std::ptr::null_mut();
        }
        // SAFETY: forwarded unchanged to the system allocator.
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            let live = LIVE.fetch_add(layout.size(), Relaxed) + layout.size();
            PEAK.fetch_max(live, Relaxed);
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { System.dealloc(ptr, layout) };
        LIVE.fetch_sub(layout.size(), Relaxed);
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// `k` squares of 1 m (two triangles each) stacked evenly from y = 0 to y = 1.
fn stacked_squares(k: usize) -> (Vec<[f32; 3]>, Vec<u32>) {
    let mut positions = Vec::with_capacity(4 * k);
    let mut indices = Vec::with_capacity(6 * k);
    for i in 0..k {
        let y = i as f32 / (k - 1) as f32;
        let base = positions.len() as u32;
        positions.extend([[0.0, y, 0.0], [1.0, y, 0.0], [1.0, y, 1.0], [0.0, y, 1.0]]);
        indices.extend([0, 1, 2, 0, 2, 3].map(|v| base + v));
    }
    (positions, indices)
}

/// Peak bytes allocated above what was live before `f` ran, and its result.
fn peak_during<T>(f: impl FnOnce() -> T) -> (usize, T) {
    let before = LIVE.load(Relaxed);
    PEAK.store(before, Relaxed);
    let out = f();
    (PEAK.load(Relaxed) - before, out)
}

const MIB: usize = 1 << 20;

#[test]
fn stacked_squares_voxelise_in_memory_bounded_by_the_voxel_count() {
    // 52 bytes a voxel for the running figures (about 104 MiB at n = 128), plus the output and
    // per-vertex keys. Without the bound, 1,000 squares peaked at 2 GiB and 3,000 aborted.
    const BOUND: usize = 160 * MIB;
    for k in [1_000, 3_000] {
        let (positions, indices) = stacked_squares(k);
        let mesh = MeshRef { positions: &positions, indices: Some(&indices) };
        let (peak, voxels) = peak_during(|| voxel_spheres(mesh, 128));
        let voxels = voxels.unwrap_or_else(|e| panic!("{k} squares: {e}"));
        println!("{k} squares at n = 128: {} spheres, peak {:.1} MiB", voxels.spheres.len(), peak as f64 / MIB as f64);
        assert!(peak < BOUND, "{k} squares: peak {} MiB", peak / MIB);
        // Every square crosses one layer of 128 x 128 voxels, and the 128 layers are all full.
        assert_eq!(voxels.spheres.len(), 128 * 128 * 128);
        // The squares are covered: points on them lie in their voxel's sphere.
        for (i, p) in [(0, Vec3::new(0.3, 0.0, 0.7)), (k / 2, Vec3::new(0.9, 0.0, 0.05))] {
            let p = p + Vec3::Y * (i as f32 / (k - 1) as f32);
            let s = voxels.sphere_of(p).expect("a voxel on a square has a sphere");
            assert!(p.distance(s.centre()) < s.radius, "square {i}: {p} outside {s:?}");
        }
    }

    // A failed allocation is an error, not an abort: with every allocation over 16 MiB refused,
    // the n = 128 voxel tables cannot be had, and the build says which size failed.
    let (positions, indices) = stacked_squares(10);
    let mesh = MeshRef { positions: &positions, indices: Some(&indices) };
    FAIL_ABOVE.store(16 * MIB, Relaxed);
    let refused = voxel_spheres(mesh, 128);
    FAIL_ABOVE.store(usize::MAX, Relaxed);
    match refused {
        Err(ColliderError::OutOfMemory { bytes }) => assert!(bytes > 16 * MIB, "{bytes}"),
        other => panic!("expected OutOfMemory, got {other:?}"),
    }
    // The same mesh builds at a resolution whose tables fit.
    FAIL_ABOVE.store(16 * MIB, Relaxed);
    let small = voxel_spheres(mesh, 32);
    FAIL_ABOVE.store(usize::MAX, Relaxed);
    assert!(small.is_ok(), "{small:?}");
}
