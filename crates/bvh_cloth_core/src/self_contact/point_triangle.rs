//! Point against triangle: a particle held its thickness off a triangle it is near, or put
//! back on the side it came from when its path went through one. See the
//! [module docs](super).

use glam::{Vec3, Vec3A};

use super::{Contact, ContactBody, ContactSolver};
use crate::mesh::triangles::closest_point;

impl ContactSolver {
    /// Adds the contacts of the points each of the triangles `t` and `u` stands for with the
    /// other triangle to `found`: each point's path over the substep, grown by the thickness,
    /// must meet the other's box.
    pub(super) fn point_contacts(&self, (t, u): (u32, u32), bodies: &[ContactBody<'_>], found: &mut Vec<Contact>) {
        let tree = &self.tree;
        let (i, j) = (tree.place(t), tree.place(u));
        for (from, to) in [(i, j), (j, i)] {
            let [lo, hi] = tree.reach_box(to);
            for &p in tree.points[from].iter().take_while(|&&p| p != u32::MAX) {
                let (x, prev) = (Vec3A::from(self.x[p as usize]), Vec3A::from(self.prev[p as usize]));
                if x.min(prev).cmple(hi).all() && x.max(prev).cmpge(lo).all() {
                    found.extend(self.contact(bodies, p as usize, to));
                }
            }
        }
    }

    /// The contact of point `p` (flat index) with the triangle at `place` in the tree's order,
    /// whose grown box its path meets, if the point is closer than the pair's thickness, is not
    /// one of its corners, and lay no closer than that in their rest shape when they are of one
    /// body.
    fn contact(&self, bodies: &[ContactBody<'_>], p: usize, place: usize) -> Option<Contact> {
        let t = self.tree.triangle_at(place);
        let (tb, corners) = self.triangles[t as usize];
        if corners.contains(&(p as u32)) {
            return None;
        }
        let xp = self.x[p];
        let (pb, pl) = self.owner[p];
        let (point_body, tri_body) = (&bodies[pb as usize], &bodies[tb as usize]);
        if pb != tb && !point_body.layers.interacts_with(tri_body.layers) {
            return None;
        }
        let h = 0.5 * (point_body.contact.thickness + tri_body.contact.thickness);
        if pb == tb {
            // Near it in the rest shape: the cloth's own neighbourhood, not another layer.
            let [lo, hi] = self.tree.rest_boxes[t as usize];
            let rest = Vec3A::from(point_body.topology.rest_positions()[pl as usize]);
            if rest.cmpge(lo - h).all() && rest.cmple(hi + h).all() {
                return None;
            }
        }
        let at = corners.map(|c| self.x[c as usize]);
        let before = corners.map(|c| self.prev[c as usize]);
        // The side of the triangle's plane the point was on at the start of the substep, and is
        // on now (0 for a triangle without area then). A point that changed sides went through
        // the triangle (or round its edge, closer than the thickness): it goes back to the side
        // it came from, the thickness off the plane.
        let [normal_before, normal_now] = self.tree.faces[place];
        let side_before = (self.prev[p] - before[0]).dot(normal_before);
        let side_now = (xp - at[0]).dot(normal_now);
        // Farther than the thickness now, and on the side of the plane it started on: no
        // contact (below). Farther than that from the plane, it is from the triangle too.
        let kept = side_before * side_now >= 0.0;
        if kept && side_now * side_now >= h * h {
            return None;
        }
        let q = closest_point(xp, at);
        let away = xp - q;
        let d2 = away.length_squared();
        // A non-finite particle makes no contact.
        if !d2.is_finite() || (kept && d2 >= h * h) {
            return None;
        }
        let face = (normal_now != Vec3::ZERO).then_some(normal_now);
        // A point on the wrong side of the triangle's body or sheet, or a triangle of the wrong
        // side of the point's, as `untangle` found them: the side to go back to is the other.
        let inverted = self.inverted(&[p as u32], &corners);
        let side_before = if inverted { -side_before } else { side_before };
        let through = side_before * side_now < 0.0;
        let (n, gap, q) = if d2 < h * h {
            let d = d2.sqrt();
            let (n, gap) = match face {
                Some(face) if through => (face * side_before.signum(), -side_now.abs()),
                _ if d > 1.0e-6 * h => (away / d, d),
                Some(face) if side_before != 0.0 => (face * side_before.signum(), 0.0),
                _ => (face.unwrap_or(Vec3::Y), 0.0),
            };
            (n, gap, q)
        } else {
            // Farther than the thickness now: a contact only if the point's path went through
            // the triangle during the substep (see `crossed`); a point taken back through
            // meets it when it comes within the thickness.
            if inverted {
                return None;
            }
            let (face, q) = face.zip(crossed(self.prev[p], xp, before, at, side_before, side_now, h))?;
            (face * side_before.signum(), -side_now.abs(), q)
        };
        let b = barycentric(q, at);
        let v = corners.map(|c| self.v[c as usize]);
        let relative = self.v[p] - (b[0] * v[0] + b[1] * v[1] + b[2] * v[2]);
        let friction = 0.5 * (point_body.contact.friction + tri_body.contact.friction);
        let ids = [p as u32, corners[0], corners[1], corners[2]];
        self.project(ids, [1.0, -b[0], -b[1], -b[2]], n, h - gap, relative, friction)
    }
}

/// Whether a point that went from `p0` to `p1` over a substep went through the triangle that
/// went from `before` to `now`, given the point's sides of the triangle's plane at the start and
/// the end: the sides differ, and where the point crossed the plane (all four moving in straight
/// lines, the plane's turn neglected) it was within `h` of the triangle, which was then as far
/// along its own path. Returns the point of the triangle as it stands now at the crossing's
/// barycentric weights. Against the triangle's end position alone, a fold whose two sides both
/// move a thickness or more in a substep passes through unseen.
fn crossed(
    p0: Vec3,
    p1: Vec3,
    before: [Vec3; 3],
    now: [Vec3; 3],
    side_before: f32,
    side_now: f32,
    h: f32,
) -> Option<Vec3> {
    // NaN fails too.
    if side_before * side_now >= 0.0 || side_before.is_nan() || side_now.is_nan() {
        return None;
    }
    let s = side_before / (side_before - side_now);
    let then: [Vec3; 3] = core::array::from_fn(|k| before[k].lerp(now[k], s));
    let at = p0.lerp(p1, s);
    let q = closest_point(at, then);
    let d2 = q.distance_squared(at);
    if d2 >= h * h || d2.is_nan() {
        return None;
    }
    let b = barycentric(q, then);
    Some(b[0] * now[0] + b[1] * now[1] + b[2] * now[2])
}

/// The barycentric weights of `q` (a point of the triangle) on the triangle; equal weights for
/// a triangle without area.
fn barycentric(q: Vec3, [a, b, c]: [Vec3; 3]) -> [f32; 3] {
    let (e1, e2, r) = (b - a, c - a, q - a);
    let (d11, d12, d22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let (r1, r2) = (r.dot(e1), r.dot(e2));
    let det = d11 * d22 - d12 * d12;
    let scale = d11.max(d22);
    if det.is_nan() || det <= 1.0e-12 * scale * scale {
        return [1.0 / 3.0; 3];
    }
    let u = ((d22 * r1 - d12 * r2) / det).clamp(0.0, 1.0);
    let w = ((d11 * r2 - d12 * r1) / det).clamp(0.0, 1.0 - u);
    [1.0 - u - w, u, w]
}
