//! Edge against edge: two edges held their thickness apart where they pass close, or put back
//! on the sides they came from when one went through the other during the substep. Between
//! the particles of two layers an edge can cross an edge with no particle near a triangle of
//! the other layer, which point against triangle alone lets through. See the
//! [module docs](super).

use glam::{Vec3, Vec3A};

use super::{Contact, ContactBody, ContactSolver};

impl ContactSolver {
    /// Adds the contacts of the edges triangle `t` stands for with those triangle `u` stands
    /// for to `found`: their boxes over the substep must lie within the largest thickness.
    pub(super) fn edge_contacts(&self, (t, u): (u32, u32), bodies: &[ContactBody<'_>], found: &mut Vec<Contact>) {
        let tree = &self.tree;
        let (i, j) = (tree.place(t), tree.place(u));
        let reach = 2.0 * tree.grow();
        // An edge's box joined from its ends' (none for no edge).
        let boxed = |e: u32| self.edges.get(e as usize).map(|&(_, ends)| (e, tree.edge_box(ends)));
        let theirs = tree.edges[j].map(boxed);
        for (e, e_box) in tree.edges[i].into_iter().filter_map(boxed) {
            let (lo, hi) = (e_box[0] - reach, e_box[1] + reach);
            for &(f, f_box) in theirs.iter().flatten() {
                if lo.cmple(f_box[1]).all() && hi.cmpge(f_box[0]).all() {
                    found.extend(self.edge_contact(bodies, e as usize, f as usize, &e_box, &f_box));
                }
            }
        }
    }

    /// The contact of edge `e` with edge `f` (their boxes over the substep `e_box` and
    /// `f_box`), if they share no particle, lay no closer than the pair's thickness in their
    /// rest shape when they are of one body, and are closer than it now or went through each
    /// other during the substep.
    fn edge_contact(
        &self,
        bodies: &[ContactBody<'_>],
        e: usize,
        f: usize,
        &[e_lo, e_hi]: &[Vec3A; 2],
        &[f_lo, f_hi]: &[Vec3A; 2],
    ) -> Option<Contact> {
        let first = self.triangles.len();
        let ((eb, [a0, a1]), (fb, [b0, b1])) = (self.edges[e], self.edges[f]);
        if a0 == b0 || a0 == b1 || a1 == b0 || a1 == b1 {
            return None;
        }
        let (e_body, f_body) = (&bodies[eb as usize], &bodies[fb as usize]);
        if eb != fb && !e_body.layers.interacts_with(f_body.layers) {
            return None;
        }
        let h = 0.5 * (e_body.contact.thickness + f_body.contact.thickness);
        // Their boxes over the substep within the pair's thickness of each other (the search's
        // test grew them by the largest).
        if !((e_lo - h).cmple(f_hi).all() && (e_hi + h).cmpge(f_lo).all()) {
            return None;
        }
        if eb == fb {
            // Near each other in the rest shape: the cloth's own neighbourhood, not two layers.
            let ([e_lo, e_hi], [f_lo, f_hi]) = (self.tree.rest_boxes[first + e], self.tree.rest_boxes[first + f]);
            if (e_lo - h).cmple(f_hi).all() && (e_hi + h).cmpge(f_lo).all() {
                return None;
            }
        }
        let ids = [a0, a1, b0, b1];
        let [p0, p1, q0, q1] = ids.map(|k| self.x[k as usize]);
        let [r0, r1, s0, s1] = ids.map(|k| self.prev[k as usize]);
        // Farther than the thickness now, and on the side of each other they started on: no
        // contact (below). The normals' lengths leave the sides' signs as they are; farther
        // than the thickness apart along the lines' common normal, they are farther apart.
        let (before, now) = ((r1 - r0).cross(s1 - s0), (p1 - p0).cross(q1 - q0));
        let side_now = (p0 - q0).dot(now);
        let kept = (r0 - s0).dot(before) * if before.dot(now) < 0.0 { -side_now } else { side_now } >= 0.0;
        if kept && side_now * side_now >= h * h * now.length_squared() {
            return None;
        }
        let (s, t) = closest_on_segments(p0, p1, q0, q1);
        let away = p0.lerp(p1, s) - q0.lerp(q1, t);
        let d2 = away.length_squared();
        // A non-finite particle makes no contact.
        if !d2.is_finite() || (kept && d2 >= h * h) {
            return None;
        }
        // The sides of each other's lines the edges were on at the start of the substep and are
        // on now, along the lines' common normal (the one now turned to agree with the one
        // before, so that a turn of the edges is not taken for a crossing). Edges that changed
        // sides went through each other (or round an end, closer than the thickness): they go
        // back to the sides they came from, the thickness apart.
        let normal_before = common_normal(r0, r1, s0, s1);
        let normal_now =
            common_normal(p0, p1, q0, q1).map(|n| if normal_before.is_some_and(|b| b.dot(n) < 0.0) { -n } else { n });
        let side_before = normal_before.map_or(0.0, |n| (r0 - s0).dot(n));
        // An edge with an end on the wrong side of the other's body or sheet, as `untangle`
        // found them: the side to go back to is the other one.
        let inverted = self.inverted(&[a0, a1], &[b0, b1]);
        let side_before = if inverted { -side_before } else { side_before };
        let side_now = normal_now.map_or(0.0, |n| (p0 - q0).dot(n));
        let through = side_before * side_now < 0.0;
        let (n, gap, s, t) = if d2 < h * h {
            let d = d2.sqrt();
            match normal_now {
                Some(normal) if through => (normal * side_before.signum(), -side_now.abs(), s, t),
                _ if d > 1.0e-6 * h => (away / d, d, s, t),
                Some(normal) if side_before != 0.0 => (normal * side_before.signum(), 0.0, s, t),
                // Parallel and touching: the point–triangle contacts of their ends hold them.
                _ => return None,
            }
        } else {
            // Farther than the thickness now: a contact only if they went through each other
            // during the substep (see `crossed`); edges taken back through meet when they come
            // within the thickness.
            if inverted {
                return None;
            }
            let (normal, (s, t)) =
                normal_now.zip(crossed([r0, r1, s0, s1], [p0, p1, q0, q1], side_before, side_now, h))?;
            (normal * side_before.signum(), -side_now.abs(), s, t)
        };
        let [u0, u1, v0, v1] = ids.map(|k| self.v[k as usize]);
        let relative = u0.lerp(u1, s) - v0.lerp(v1, t);
        let friction = 0.5 * (e_body.contact.friction + f_body.contact.friction);
        self.project(ids, [1.0 - s, s, t - 1.0, -t], n, h - gap, relative, friction)
    }
}

/// The unit normal of the lines of the edges `p0 p1` and `q0 q1` (their directions' cross
/// product), or `None` for parallel or degenerate edges.
fn common_normal(p0: Vec3, p1: Vec3, q0: Vec3, q1: Vec3) -> Option<Vec3> {
    let (d, e) = (p1 - p0, q1 - q0);
    let c = d.cross(e);
    let c2 = c.length_squared();
    (c2 > 1.0e-8 * d.length_squared() * e.length_squared() && c2.is_finite()).then(|| c / c2.sqrt())
}

/// Whether edges that went from `before` to `now` (the first edge's ends, then the second's)
/// over a substep went through each other, given the first edge's sides of the second's line
/// at the start and the end: the sides differ, and where the lines met (all four ends moving
/// in straight lines, the lines' turn neglected) the edges were within `h` of each other.
/// Returns where along each edge they met.
fn crossed(before: [Vec3; 4], now: [Vec3; 4], side_before: f32, side_now: f32, h: f32) -> Option<(f32, f32)> {
    // NaN fails too.
    if side_before * side_now >= 0.0 || side_before.is_nan() || side_now.is_nan() {
        return None;
    }
    let at = side_before / (side_before - side_now);
    let [p0, p1, q0, q1]: [Vec3; 4] = core::array::from_fn(|k| before[k].lerp(now[k], at));
    let (s, t) = closest_on_segments(p0, p1, q0, q1);
    let d2 = p0.lerp(p1, s).distance_squared(q0.lerp(q1, t));
    (d2 < h * h).then_some((s, t))
}

/// Where along the segments `p0 p1` and `q0 q1` (0 at the first end, 1 at the second) their
/// closest points lie: the least distance between two segments, with the ends clamped
/// (Ericson 2005, "Real-Time Collision Detection", section 5.1.9). A degenerate segment is a
/// point; parallel segments take the first's first end.
fn closest_on_segments(p0: Vec3, p1: Vec3, q0: Vec3, q1: Vec3) -> (f32, f32) {
    let (d, e, r) = (p1 - p0, q1 - q0, p0 - q0);
    let (a, c, f) = (d.length_squared(), e.length_squared(), e.dot(r));
    let tiny = f32::EPSILON * a.max(c);
    if a <= tiny && c <= tiny {
        return (0.0, 0.0);
    }
    if a <= tiny {
        return (0.0, (f / c).clamp(0.0, 1.0));
    }
    let g = d.dot(r);
    if c <= tiny {
        return ((-g / a).clamp(0.0, 1.0), 0.0);
    }
    let b = d.dot(e);
    let det = a * c - b * b;
    let s = if det > 1.0e-6 * a * c { ((b * f - g * c) / det).clamp(0.0, 1.0) } else { 0.0 };
    let t = (b * s + f) / c;
    if t < 0.0 {
        ((-g / a).clamp(0.0, 1.0), 0.0)
    } else if t > 1.0 {
        (((b - g) / a).clamp(0.0, 1.0), 1.0)
    } else {
        (s, t)
    }
}
