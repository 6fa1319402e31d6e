//! Point and segment queries against one triangle, the narrow phase of exact contact (see
//! [`crate::colliders::exact_contact`]). Every query is total: a degenerate triangle (a sliver, a segment,
//! a point) answers as the segment or point it is, never with a NaN.

use glam::{Vec3, Vec4};

/// The point of the triangle `[a, b, c]` closest to `p`.
///
/// The plane's Voronoi regions are tested in turn (the three vertices, the three edges, the
/// face), each from the same six dot products, so the answer is exact up to rounding and the
/// function has no division by a vanishing quantity: a degenerate triangle falls into a vertex
/// or edge region.
pub fn closest_point(p: Vec3, [a, b, c]: [Vec3; 3]) -> Vec3 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    // Edge regions: the signed areas of the sub-triangles say which side of an edge `p` is.
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let sum = va + vb + vc;
    if sum.is_nan() || sum <= 0.0 {
        // Only a degenerate triangle gets here (all three areas vanish): its closest point is
        // on its longest edge.
        return closest_on_longest_edge(p, [a, b, c]);
    }
    a + ab * (vb / sum) + ac * (vc / sum)
}

/// The point of the triangle's longest edge closest to `p`.
fn closest_on_longest_edge(p: Vec3, [a, b, c]: [Vec3; 3]) -> Vec3 {
    let edges = [(a, b), (b, c), (c, a)];
    let (s, e) = edges
        .into_iter()
        .max_by(|(s0, e0), (s1, e1)| s0.distance_squared(*e0).total_cmp(&s1.distance_squared(*e1)))
        .unwrap_or((a, b));
    let d = e - s;
    let len = d.length_squared();
    if len == 0.0 {
        return s;
    }
    s + d * ((p - s).dot(d) / len).clamp(0.0, 1.0)
}

/// Four triangles' squared distances from `p` at once, one SIMD lane each, as a filter for
/// [`closest_point`]: no lane exceeds [`lane_bound`] of its triangle's squared distance (its
/// rounding), and each lane is that distance to its rounding unless the triangle is nearly
/// degenerate, whose lane is 0 (its distance left to the exact test).
///
/// Where `p`'s foot on the plane lies within the triangle, the lane is the distance to the
/// plane; elsewhere the least distance to the three edges, which is the distance to the
/// triangle when the foot lies outside it. Within rounding of an edge the foot may land on
/// either side, and either answer is the distance to the triangle to that rounding. The foot's
/// barycentric coordinates are solved in the basis of the edges from the first corner, whose
/// rounding grows as the square of that corner's sine shrinks: a triangle counts as nearly
/// degenerate when the squared sine is below [`WELL_SHAPED_SINE_SQUARED`]. No branch: a walk
/// that meets up to four leaves at once tests them together, read where they lie (the four
/// need not be copied side by side first).
#[inline]
pub fn squared_distances_4(p: Vec3, tris: [&[Vec3; 3]; 4]) -> Vec4 {
    let axis = |corner: usize, axis: usize| Vec4::from_array(std::array::from_fn(|lane| tris[lane][corner][axis]));
    let corner = |corner: usize| [axis(corner, 0), axis(corner, 1), axis(corner, 2)];
    let (a, b, c) = (corner(0), corner(1), corner(2));
    let sub = |x: [Vec4; 3], y: [Vec4; 3]| [x[0] - y[0], x[1] - y[1], x[2] - y[2]];
    let dot = |x: [Vec4; 3], y: [Vec4; 3]| x[0] * y[0] + x[1] * y[1] + x[2] * y[2];
    let p = [Vec4::splat(p.x), Vec4::splat(p.y), Vec4::splat(p.z)];
    let (ab, ac, bc, ap, bp) = (sub(b, a), sub(c, a), sub(c, b), sub(p, a), sub(p, b));
    let (d00, d01, d11, d20, d21) = (dot(ab, ab), dot(ab, ac), dot(ac, ac), dot(ap, ab), dot(ap, ac));
    // The squared distance to an edge's closest point.
    let edge = |from: [Vec4; 3], e: [Vec4; 3], along: Vec4, length2: Vec4| {
        let t = (along / length2).clamp(Vec4::ZERO, Vec4::ONE);
        let off = [from[0] - t * e[0], from[1] - t * e[1], from[2] - t * e[2]];
        dot(off, off)
    };
    let edges = edge(ap, ab, d20, d00).min(edge(ap, ac, d21, d11)).min(edge(bp, bc, dot(bp, bc), dot(bc, bc)));
    // The foot's barycentric coordinates along `ab` and `ac`; `area2` is |ab x ac|^2.
    let area2 = d00 * d11 - d01 * d01;
    let (v, w) = ((d11 * d20 - d01 * d21) / area2, (d00 * d21 - d01 * d20) / area2);
    let inside = v.cmpge(Vec4::ZERO) & w.cmpge(Vec4::ZERO) & (v + w).cmple(Vec4::ONE);
    let n = [ab[1] * ac[2] - ab[2] * ac[1], ab[2] * ac[0] - ab[0] * ac[2], ab[0] * ac[1] - ab[1] * ac[0]];
    let height = dot(ap, n);
    let plane = height * height / dot(n, n);
    let well_shaped = area2.cmpge(Vec4::splat(WELL_SHAPED_SINE_SQUARED) * d00 * d11);
    Vec4::select(well_shaped, Vec4::select(inside, plane.min(edges), edges), Vec4::ZERO)
}

/// The least squared sine of a triangle's first angle for which [`squared_distances_4`] solves
/// the foot of a point on its plane.
pub const WELL_SHAPED_SINE_SQUARED: f32 = 0.01;

/// The largest lane [`squared_distances_4`] gives a triangle whose squared distance from `p` is
/// `squared`, when `p` lies within `span` of the triangle's first corner: the distance grown by
/// its relative rounding and by [`LANE_ROUNDING`] of `span` (a distance measured across a
/// long way is rounded at that length). A caller that measures exactly every triangle whose
/// lane is at most `lane_bound(best, span)` measures every triangle nearer than `best`.
#[inline]
pub fn lane_bound(squared: f32, span: f32) -> f32 {
    let reach = squared.sqrt() * (1.0 + LANE_ROUNDING) + LANE_ROUNDING * span;
    reach * reach
}

/// The rounding [`lane_bound`] allows: 16 times `f32::EPSILON`, several times the rounding of
/// a lane's dot products and of the exact test's own.
pub const LANE_ROUNDING: f32 = 16.0 * f32::EPSILON;

/// Barycentric slack allowed at a triangle's edges by [`segment_hit`], relative to the
/// triangle.
pub const EDGE_SLACK: f32 = 1.0e-5;

/// The rounding [`segment_hit`] allows in a signed distance to a triangle's plane, as a
/// multiple of `f32::EPSILON` times the distance from the triangle's corner and over the sine
/// of the corner's angle: four times a bound on the rounding of the distance itself.
pub const PLANE_ROUNDING: f32 = 4.0 * f32::EPSILON;

/// Where the segment from `p` to `q` first meets the triangle `[a, b, c]` (either side), as
/// the parameter `t` in `[0, 1]` along it; `None` if it misses, runs in the triangle's plane,
/// or the triangle has no area.
///
/// The test is robust to `f32` rounding where a miss would let a particle through:
/// - An end point on the plane, or past it by less than the rounding of its distance to it,
///   counts as reaching it. Only a start point clearly off the plane can go through it; one
///   on the plane hits at `t = 0` when the segment leaves the plane within the triangle.
/// - Which side of each edge the segment passes is one signed volume per edge, computed from
///   the edge's corners in a fixed order, so two triangles that share an edge answer it
///   with the same number: a segment through the edge hits at least one of them.
pub fn segment_hit(p: Vec3, q: Vec3, [a, b, c]: [Vec3; 3]) -> Option<f32> {
    let n = (b - a).cross(c - a);
    let (sp, sq) = ((p - a).dot(n), (q - a).dot(n));
    // The rounding of each signed distance (scaled by |n|), squared.
    let corner = PLANE_ROUNDING * PLANE_ROUNDING * (b - a).length_squared() * (c - a).length_squared();
    let (on_p, on_q) = (sp * sp <= corner * (p - a).length_squared(), sq * sq <= corner * (q - a).length_squared());
    if !(sp.is_finite() && sq.is_finite()) || n == Vec3::ZERO {
        return None;
    }
    let t = if on_p {
        // From the plane: out of it through the triangle, at its start.
        if on_q {
            return None;
        }
        0.0
    } else if on_q || (sp > 0.0) != (sq > 0.0) {
        (sp / (sp - sq)).clamp(0.0, 1.0)
    } else {
        return None;
    };
    // Barycentric coordinates of the line through `p` and `q` from the three edges' volumes,
    // whose sum is (q - p) . n; the line is taken along the normal where it starts on the plane.
    let (from, dir) = if on_p { (p, n) } else { (p, q - p) };
    let edge = |s: Vec3, e: Vec3| {
        let (lo, hi, sign) = if (s.x, s.y, s.z) <= (e.x, e.y, e.z) { (s, e, 1.0) } else { (e, s, -1.0) };
        sign * dir.cross(lo - from).dot(hi - from)
    };
    let volumes = [edge(b, c), edge(c, a), edge(a, b)];
    let sum = volumes[0] + volumes[1] + volumes[2];
    if sum == 0.0 || sum.is_nan() {
        return None;
    }
    volumes.iter().all(|&v| v / sum >= -EDGE_SLACK).then_some(t)
}

/// Whether two triangles intersect: an edge of either crosses the other ([`segment_hit`], so
/// with its slack at the edges). Coplanar overlapping triangles do not count.
pub fn triangles_intersect(a: [Vec3; 3], b: [Vec3; 3]) -> bool {
    let crosses = |s: [Vec3; 3], t: [Vec3; 3]| {
        [(s[0], s[1]), (s[1], s[2]), (s[2], s[0])].into_iter().any(|(p, q)| segment_hit(p, q, t).is_some())
    };
    crosses(a, b) || crosses(b, a)
}

/// How many pairs of triangles intersect ([`intersecting_pairs`]).
pub fn crossing_pairs(tris: &[[u32; 3]], x: &[Vec3], other: Option<(&[[u32; 3]], &[Vec3])>) -> usize {
    intersecting_pairs(tris, x, other).len()
}

/// The pairs `(i, j)` of intersecting triangles (`triangles_intersect`), in order: among `tris`
/// (corners indexing `x`, `i < j`), skipping pairs that share a corner, or, with `other`,
/// between `tris[i]` and `other`'s triangle `j` (indexing its own positions). Every pair whose
/// boxes overlap is tested: a measure for tests and reports, not for a solver.
pub fn intersecting_pairs(tris: &[[u32; 3]], x: &[Vec3], other: Option<(&[[u32; 3]], &[Vec3])>) -> Vec<(usize, usize)> {
    use rayon::prelude::*;
    let corners = |t: &[u32; 3], x: &[Vec3]| t.map(|k| x[k as usize]);
    let bounds = |t: [Vec3; 3]| (t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2]));
    let overlap = |a: (Vec3, Vec3), b: (Vec3, Vec3)| a.1.cmpge(b.0).all() && b.1.cmpge(a.0).all();
    let (theirs, y) = other.unwrap_or((tris, x));
    (0..tris.len())
        .into_par_iter()
        .flat_map_iter(|i| {
            let a = corners(&tris[i], x);
            let first = if other.is_some() { 0 } else { i + 1 };
            (first..theirs.len())
                .filter(move |&j| other.is_some() || !share_a_corner(tris[i], theirs[j]))
                .filter(move |&j| {
                    let b = corners(&theirs[j], y);
                    overlap(bounds(a), bounds(b)) && triangles_intersect(a, b)
                })
                .map(move |j| (i, j))
        })
        .collect()
}

/// Whether the triangles with corners `a` and `b` (indices into one list of positions) share a
/// corner.
pub fn share_a_corner(a: [u32; 3], b: [u32; 3]) -> bool {
    a.iter().any(|k| b.contains(k))
}

/// The triangle's unit normal by its winding (`(b - a) x (c - a)`), or `None` when it has no
/// area.
pub fn face_normal([a, b, c]: [Vec3; 3]) -> Option<Vec3> {
    (b - a).cross(c - a).try_normalize()
}

/// Whether the triangle has an area worth colliding with: finite corners, and a cross product
/// not lost to rounding against its edges.
pub fn has_area([a, b, c]: [Vec3; 3]) -> bool {
    if !(a.is_finite() && b.is_finite() && c.is_finite()) {
        return false;
    }
    let (e1, e2) = (b - a, c - a);
    let cross = e1.cross(e2).length();
    cross > 1.0e-12 * e1.length_squared().max(e2.length_squared()) && cross > 0.0
}

#[cfg(test)]
mod tests {
    use super::*;

    const T: [Vec3; 3] = [Vec3::ZERO, Vec3::X, Vec3::Y];

    /// Seeded xorshift numbers in `[0, 1]`.
    fn unit_numbers(mut seed: u32) -> impl FnMut() -> f32 {
        move || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed as f32 / u32::MAX as f32
        }
    }

    #[test]
    fn closest_points_in_every_region() {
        let cases = [
            // Face: straight down onto the plane.
            (Vec3::new(0.2, 0.3, 0.7), Vec3::new(0.2, 0.3, 0.0)),
            (Vec3::new(0.2, 0.3, -2.0), Vec3::new(0.2, 0.3, 0.0)),
            // Vertices.
            (Vec3::new(-1.0, -1.0, 0.5), Vec3::ZERO),
            (Vec3::new(2.0, -0.5, 0.0), Vec3::X),
            (Vec3::new(-0.5, 3.0, 1.0), Vec3::Y),
            // Edges.
            (Vec3::new(0.5, -1.0, 0.3), Vec3::new(0.5, 0.0, 0.0)),
            (Vec3::new(-1.0, 0.25, -0.3), Vec3::new(0.0, 0.25, 0.0)),
            (Vec3::new(1.0, 1.0, 0.0), Vec3::new(0.5, 0.5, 0.0)),
        ];
        for (p, want) in cases {
            let got = closest_point(p, T);
            assert!(got.distance(want) < 1e-6, "closest to {p}: {got}, not {want}");
        }
    }

    /// Against brute force: the closest of a dense sample of the triangle is never closer than
    /// the answer, for random triangles and points.
    #[test]
    fn closest_point_beats_sampling() {
        let mut unit = unit_numbers(17);
        let mut next = || unit() * 4.0 - 2.0;
        for _ in 0..300 {
            let tri = [0; 3].map(|_| Vec3::new(next(), next(), next()));
            let p = Vec3::new(next(), next(), next());
            let got = closest_point(p, tri).distance(p);
            let mut best = f32::INFINITY;
            for i in 0..=40 {
                for j in 0..=40 - i {
                    let (u, v) = (i as f32 / 40.0, j as f32 / 40.0);
                    let q = tri[0] + u * (tri[1] - tri[0]) + v * (tri[2] - tri[0]);
                    best = best.min(q.distance(p));
                }
            }
            assert!(got <= best + 1e-5, "answer {got} farther than a sample {best}");
            assert!(got >= best - 0.2, "answer {got} far closer than any sample {best}");
        }
    }

    /// The four-lane filter against the exact distance: never above it (to its rounding), 0
    /// for a nearly degenerate triangle, and equal to it for nearly every well-shaped one, on
    /// triangles from a millimetre to a metre wide, slivers and sharp corners among them, and
    /// points from a millionth of a width off the plane (over an edge or the middle) to ten
    /// widths away.
    #[test]
    fn four_distances_never_exceed_the_exact_one() {
        let mut unit = unit_numbers(29);
        let (mut well_shaped, mut equal) = (0, 0);
        for _ in 0..20000 {
            let tris: [[Vec3; 3]; 4] = std::array::from_fn(|_| {
                let size = 10f32.powf(-3.0 * unit());
                let origin = Vec3::new(unit(), unit(), unit()) * 4.0 - 2.0;
                let corner = |unit: &mut dyn FnMut() -> f32| Vec3::new(unit(), unit(), unit()) * 2.0 - 1.0;
                let (b, c) = (corner(&mut unit), corner(&mut unit));
                // A quarter are slivers (the third corner squashed onto the line of the other
                // two) and a quarter have a sharp first angle, a sine of 0.1 to 0.25.
                let c = match unit() {
                    x if x < 0.25 => b * unit() + (c - b * unit()) * 10f32.powf(-2.0 - 4.0 * unit()),
                    x if x < 0.5 => {
                        let (along, across) = (b.normalize(), b.any_orthonormal_vector());
                        let sine = 0.1 + 0.15 * unit();
                        (along * (1.0 - sine * sine).sqrt() + across * sine) * (0.2 + unit())
                    }
                    _ => c,
                };
                [origin, origin + b * size, origin + c * size]
            });
            let (centre, size) = (tris[0][0], (tris[0][1] - tris[0][0]).length().max(1.0e-3));
            let reach = size * 10f32.powf(2.0 * unit() - 1.0);
            let [a, b, c] = tris[0];
            let p = match unit() {
                x if x < 0.5 => centre + (Vec3::new(unit(), unit(), unit()) * 2.0 - 1.0) * reach,
                // Just off the first triangle's plane over a point near an edge, or over its
                // middle, where the foot's rounding decides between the plane and the edges.
                x => {
                    let on = if x < 0.75 {
                        a + (b - a) * (1.0 + unit()) * 0.5
                            + (c - a) * (10f32.powf(-3.0 - 4.0 * unit()) * (unit() - 0.5))
                    } else {
                        (a + b + c) / 3.0
                    };
                    on + face_normal(tris[0]).unwrap_or(Vec3::Z) * size * 10f32.powf(-6.0 * unit())
                }
            };
            let lanes = squared_distances_4(p, tris.each_ref()).to_array();
            for (tri, lane) in tris.iter().zip(lanes) {
                // Measured from the first corner, as the lanes are: an answer in the world's
                // coordinates is rounded at their magnitude, far above a short distance's.
                let (a, local) = (tri[0], tri.map(|corner| corner - tri[0]));
                let exact = closest_point(p - a, local).distance_squared(p - a);
                let span = (p - a).length();
                assert!(lane <= lane_bound(exact, span), "{p} to {tri:?}: {lane} above the exact {exact}");
                let (ab, ac) = (tri[1] - tri[0], tri[2] - tri[0]);
                let sine2 = ab.cross(ac).length_squared() / (ab.length_squared() * ac.length_squared());
                if sine2 < WELL_SHAPED_SINE_SQUARED * 0.99 {
                    assert_eq!(lane, 0.0, "a sliver's lane is left to the exact test");
                } else if sine2 > WELL_SHAPED_SINE_SQUARED * 1.01 {
                    well_shaped += 1;
                    equal += usize::from(lane_bound(lane, span) >= exact);
                }
            }
        }
        assert!(well_shaped > 10_000, "{well_shaped} well-shaped triangles");
        assert!(equal as f32 > 0.97 * well_shaped as f32, "{equal} of {well_shaped} lanes at the exact distance");
    }

    #[test]
    fn degenerate_triangles_answer_as_segments_and_points() {
        let line = [Vec3::ZERO, Vec3::X, Vec3::new(2.0, 0.0, 0.0)];
        let got = closest_point(Vec3::new(1.5, 1.0, 0.0), line);
        assert!(got.distance(Vec3::new(1.5, 0.0, 0.0)) < 1e-6, "{got}");
        let point = [Vec3::ONE; 3];
        assert_eq!(closest_point(Vec3::ZERO, point), Vec3::ONE);
        assert!(!has_area(line) && !has_area(point));
        assert!(face_normal(point).is_none());
        assert!(segment_hit(Vec3::new(1.0, 0.0, -1.0), Vec3::new(1.0, 0.0, 1.0), line).is_none());
        let sliver = [Vec3::ZERO, Vec3::X, Vec3::new(0.5, 1.0e-4, 0.0)];
        assert!(has_area(sliver));
        assert!(closest_point(Vec3::new(0.5, 0.5, 0.5), sliver).is_finite());
    }

    #[test]
    fn segments_hit_from_either_side_and_miss_outside() {
        let down = segment_hit(Vec3::new(0.25, 0.25, 1.0), Vec3::new(0.25, 0.25, -1.0), T);
        assert!((down.unwrap() - 0.5).abs() < 1e-6);
        let up = segment_hit(Vec3::new(0.25, 0.25, -1.0), Vec3::new(0.25, 0.25, 3.0), T);
        assert!((up.unwrap() - 0.25).abs() < 1e-6);
        // Short of the plane, past the hypotenuse, in the plane.
        assert!(segment_hit(Vec3::new(0.25, 0.25, 1.0), Vec3::new(0.25, 0.25, 0.5), T).is_none());
        assert!(segment_hit(Vec3::new(0.6, 0.6, 1.0), Vec3::new(0.6, 0.6, -1.0), T).is_none());
        assert!(segment_hit(Vec3::new(-1.0, 0.2, 0.0), Vec3::new(2.0, 0.2, 0.0), T).is_none());
        // Through a shared edge: at least one of the two triangles is hit.
        let other = [Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y];
        let (p, q) = (Vec3::new(0.5, 0.5, 1.0), Vec3::new(0.5, 0.5, -1.0));
        assert!(segment_hit(p, q, T).is_some() || segment_hit(p, q, other).is_some());
        assert_eq!(face_normal(T), Some(Vec3::Z));
    }

    /// An end point on the plane, or a rounding past it, reaches it; a start on the plane hits
    /// at its start when it leaves through the triangle; a grazing path that dips a micrometre
    /// through it over 23 mm is found.
    #[test]
    fn paths_ending_on_the_plane_hit_and_paths_in_it_do_not() {
        let on = segment_hit(Vec3::new(0.25, 0.25, 1.0), Vec3::new(0.25, 0.25, 0.0), T);
        assert_eq!(on, Some(1.0));
        let past = segment_hit(Vec3::new(0.25, 0.25, 1.0e-6), Vec3::new(0.25, 0.25, -1.0e-12), T);
        assert!(past.is_some_and(|t| t > 0.99), "{past:?}");
        // Short of the plane by more than the rounding at 0.35 m from the corner (4e-8 m).
        let short = segment_hit(Vec3::new(0.25, 0.25, 1.0e-5), Vec3::new(0.25, 0.25, 1.0e-6), T);
        assert_eq!(short, None);
        assert_eq!(segment_hit(Vec3::new(0.25, 0.25, 0.0), Vec3::new(0.25, 0.25, 1.0), T), Some(0.0));
        assert_eq!(segment_hit(Vec3::new(0.25, 0.25, 0.0), Vec3::new(0.3, 0.25, 0.0), T), None);
        assert_eq!(segment_hit(Vec3::new(2.0, 2.0, 0.0), Vec3::new(2.0, 2.0, 1.0), T), None);
        let graze = segment_hit(Vec3::new(0.1, 0.3, 1.0e-6), Vec3::new(0.123, 0.3, -1.0e-8), T);
        assert!(graze.is_some_and(|t| t > 0.98), "{graze:?}");
    }

    #[test]
    fn triangles_intersect_when_one_pierces_the_other() {
        // Standing through the middle of T, touching it along no edge of T.
        let through = [Vec3::new(0.2, 0.2, -1.0), Vec3::new(0.3, 0.2, 1.0), Vec3::new(0.2, 0.3, 1.0)];
        assert!(triangles_intersect(T, through) && triangles_intersect(through, T));
        // The same lifted clear of T's plane, and beside it.
        let above = through.map(|p| p + Vec3::Z * 1.5);
        let beside = through.map(|p| p + Vec3::X * 2.0);
        assert!(!triangles_intersect(T, above) && !triangles_intersect(T, beside));
        // A large triangle through which a small one's edge passes, neither edge of the large
        // one touching the small one.
        let big = [Vec3::new(-5.0, -5.0, 0.5), Vec3::new(5.0, -5.0, 0.5), Vec3::new(0.0, 5.0, 0.5)];
        let small = [Vec3::new(0.0, 0.0, 0.0), Vec3::new(0.1, 0.0, 1.0), Vec3::new(0.0, 0.1, 0.0)];
        assert!(triangles_intersect(big, small) && triangles_intersect(small, big));
    }
}
