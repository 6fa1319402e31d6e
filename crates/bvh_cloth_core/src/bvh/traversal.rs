//! Stack traversal of the LBVH (paper section 2.4.3, Algorithm 2): depth-first, without
//! recursion, on a fixed-size stack; a child is pushed only when its box overlaps the query.

use glam::Vec3;

use crate::bvh::lbvh::{BvhNode, LEAF_BIT, Lbvh, Sphere};

/// Size of the fixed traversal stack, shared with the WGSL kernel.
///
/// Depth-first traversal holds at most one entry per level. A Karras tree splits on the first
/// differing bit of the 30-bit Morton code extended by the leaf index, so its depth is at most
/// `30 + log2(N)`; with at most `128³` leaves that is below 52, well under this bound.
pub const STACK_SIZE: usize = 64;

/// Whether `p` lies inside `sphere` grown by `margin`, with a relative tolerance so that a point
/// placed on the surface by the collision response counts as outside.
#[inline]
pub fn sphere_contains(sphere: &Sphere, p: Vec3, margin: f32) -> bool {
    let r = sphere.radius + margin;
    let shrunk = r * (1.0 - SURFACE_TOLERANCE);
    p.distance_squared(sphere.centre()) < shrunk * shrunk
}

/// Relative distance below the surface that still counts as "on" it.
///
/// A point the response put on a sphere's surface is turned from the collider's frame into the
/// world and back before the next test, which moves it by a few `f32` steps of its coordinates.
/// At `n = 128` a sphere's radius is about 1/200 of the mesh, so one step of a coordinate the
/// size of the mesh is about `2.4e-5` of the radius; this tolerance leaves room for forty.
pub const SURFACE_TOLERANCE: f32 = 1.0e-3;

/// Whether the box `[lo, hi]` overlaps the node's box grown by `margin`.
#[inline]
fn boxes_overlap(node: &BvhNode, lo: Vec3, hi: Vec3, margin: f32) -> bool {
    let node_lo = Vec3::from(node.aabb_min) - margin;
    let node_hi = Vec3::from(node.aabb_max) + margin;
    hi.cmpge(node_lo).all() && lo.cmple(node_hi).all()
}

/// Whether the box `[lo, hi]` overlaps the box of `sphere` grown by `margin`.
#[inline]
fn sphere_box_overlaps(sphere: &Sphere, lo: Vec3, hi: Vec3, margin: f32) -> bool {
    let r = sphere.radius + margin;
    let c = sphere.centre();
    hi.cmpge(c - r).all() && lo.cmple(c + r).all()
}

impl Lbvh {
    /// Calls `visit(sphere_index, sphere)` for every leaf sphere whose bounding box, grown by
    /// `margin`, overlaps the box `[lo, hi]`, in depth-first order (the left subtree first, as
    /// in Algorithm 2). A point query is the box `[p, p]`; a swept query is the box around a
    /// segment. The caller makes the exact test.
    #[inline]
    pub fn for_each_overlapping(&self, lo: Vec3, hi: Vec3, margin: f32, mut visit: impl FnMut(u32, &Sphere)) {
        if self.nodes.is_empty() {
            if let Some(s) = self.spheres.first()
                && sphere_box_overlaps(s, lo, hi, margin)
            {
                visit(0, s);
            }
            return;
        }
        if !boxes_overlap(&self.nodes[0], lo, hi, margin) {
            return;
        }
        let mut stack = [0u32; STACK_SIZE];
        let mut top = 1usize;
        while top > 0 {
            top -= 1;
            let node = &self.nodes[stack[top] as usize];
            // Right first, so that the left subtree is popped first.
            for child in [node.right, node.left] {
                if child & LEAF_BIT != 0 {
                    let index = child & !LEAF_BIT;
                    let sphere = &self.spheres[index as usize];
                    if sphere_box_overlaps(sphere, lo, hi, margin) {
                        visit(index, sphere);
                    }
                } else if boxes_overlap(&self.nodes[child as usize], lo, hi, margin) {
                    stack[top] = child;
                    top += 1;
                }
            }
        }
    }

    /// Calls `visit(sphere_index, sphere)` for every leaf sphere (grown by `margin`) that
    /// contains `p`, in depth-first order.
    #[inline]
    pub fn for_each_containing(&self, p: Vec3, margin: f32, mut visit: impl FnMut(u32, &Sphere)) {
        self.for_each_overlapping(p, p, margin, |i, s| {
            if sphere_contains(s, p, margin) {
                visit(i, s);
            }
        });
    }

    /// Whether any sphere (grown by `margin`) contains `p`.
    pub fn any_containing(&self, p: Vec3, margin: f32) -> bool {
        let mut inside = false;
        self.for_each_containing(p, margin, |_, _| inside = true);
        inside
    }

    /// Brute force reference for [`Self::for_each_containing`]: tests every sphere.
    pub fn brute_force_containing(&self, p: Vec3, margin: f32, mut visit: impl FnMut(u32, &Sphere)) {
        for (i, s) in self.spheres.iter().enumerate() {
            if sphere_contains(s, p, margin) {
                visit(i as u32, s);
            }
        }
    }
}
