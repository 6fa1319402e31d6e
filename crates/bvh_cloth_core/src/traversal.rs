//! Stack traversal of the LBVH (paper section 2.4.3, Algorithm 2): depth-first, without
//! recursion, on a fixed-size stack; a child is pushed only when its box overlaps the query.

use glam::Vec3;

use crate::lbvh::{BvhNode, LEAF_BIT, Lbvh, Sphere};

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
pub const SURFACE_TOLERANCE: f32 = 1.0e-5;

#[inline]
fn box_contains(node: &BvhNode, p: Vec3, margin: f32) -> bool {
    let lo = Vec3::from(node.aabb_min) - margin;
    let hi = Vec3::from(node.aabb_max) + margin;
    p.cmpge(lo).all() && p.cmple(hi).all()
}

impl Lbvh {
    /// Calls `visit(sphere_index, sphere)` for every leaf sphere (grown by `margin`) that
    /// contains `p`, in depth-first order.
    #[inline]
    pub fn for_each_containing(&self, p: Vec3, margin: f32, mut visit: impl FnMut(u32, &Sphere)) {
        if self.nodes.is_empty() {
            if let Some(s) = self.spheres.first()
                && sphere_contains(s, p, margin)
            {
                visit(0, s);
            }
            return;
        }
        if !box_contains(&self.nodes[0], p, margin) {
            return;
        }
        let mut stack = [0u32; STACK_SIZE];
        let mut top = 1usize;
        while top > 0 {
            top -= 1;
            let node = &self.nodes[stack[top] as usize];
            // Right first, so that the left subtree is popped first, as in Algorithm 2.
            for child in [node.right, node.left] {
                if child & LEAF_BIT != 0 {
                    let index = child & !LEAF_BIT;
                    let sphere = &self.spheres[index as usize];
                    if sphere_contains(sphere, p, margin) {
                        visit(index, sphere);
                    }
                } else if box_contains(&self.nodes[child as usize], p, margin) {
                    stack[top] = child;
                    top += 1;
                }
            }
        }
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
