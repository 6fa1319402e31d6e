//! Every collider of a scene on the GPU: frames (a primitive's whole shape), and the mesh
//! colliders' trees concatenated.
//!
//! Here too is a skinned collider's refit on the device ([`skin_refit`]), which writes into
//! these trees. Uses the kernels, the buffers and the layouts below it.

pub(crate) mod skin_refit;

use crate::layout::{GpuCollider, gpu_sphere_region, gpu_tree, gpu_tree_size};
use bvh_cloth_core::{BvhNode, Collider};
use wgpu::{Buffer, Device, Queue};

use crate::buffer::storage_buffer_with;
use crate::kernels::storage_binding_limit;

/// The colliders' frames and trees. Trees are uploaded once; [`Self::update_frames`] moves the
/// colliders without touching them, and [`Self::rewrite_trees`] writes refitted trees (a
/// skinned collider's, every frame) in place.
///
/// The trees are concatenated into one buffer, nodes first and spheres after, which must fit
/// one storage binding of the device: colliders that would overflow it are left out (see
/// [`Self::left_out`]) rather than failing the rest.
#[derive(Debug)]
pub struct GpuColliders {
    pub(crate) frames: Buffer,
    /// Every tree's nodes, then every tree's spheres (`vec4`s: a node is two).
    pub(crate) tree: Buffer,
    /// Nodes of all trees: the spheres start at `2 * nodes` `vec4`s.
    nodes: u32,
    /// Colliders usable on the GPU (a collider with an invalid pose is left out).
    pub(crate) count: u32,
    /// Offsets of each input collider's tree, in input order; `None` for one left out.
    offsets: Vec<Option<(u32, u32)>>,
    /// Node and sphere counts of each input collider's tree (zero for a primitive).
    sizes: Vec<(usize, usize)>,
    /// Each input collider's index in the frame buffer, as last written.
    frame_indices: Vec<Option<u32>>,
    /// Input indices of the colliders whose trees did not fit.
    left_out: Vec<usize>,
}

impl GpuColliders {
    /// Uploads `colliders`: trees and frames. Colliders are taken in order while their trees
    /// fit the device's storage bindings; the others are left out.
    pub fn new(device: &Device, colliders: &[Collider]) -> Self {
        let max = storage_binding_limit(device);
        let fits = |nodes: usize, words: usize| (nodes * size_of::<BvhNode>() + words * 16) as u64 <= max;
        let mut nodes: Vec<BvhNode> = Vec::new();
        let mut spheres: Vec<[f32; 4]> = Vec::new();
        let mut offsets = Vec::with_capacity(colliders.len());
        let mut left_out = Vec::new();
        let sizes = colliders.iter().map(gpu_tree_size).collect();
        for (k, collider) in colliders.iter().enumerate() {
            let Some(tree) = gpu_tree(collider) else {
                // A primitive has no tree: its frame holds its whole shape.
                offsets.push(Some((nodes.len() as u32, spheres.len() as u32)));
                continue;
            };
            if !fits(nodes.len() + tree.nodes.len(), spheres.len() + gpu_tree_size(collider).1) {
                offsets.push(None);
                left_out.push(k);
                continue;
            }
            offsets.push(Some((nodes.len() as u32, spheres.len() as u32)));
            nodes.extend_from_slice(&tree.nodes);
            spheres.extend(gpu_sphere_region(collider, &tree));
        }
        let node_count = nodes.len() as u32;
        let (frames, frame_indices) = Self::frames_of(colliders, &offsets, node_count);
        let mut tree: Vec<[f32; 4]> = Vec::with_capacity(2 * nodes.len() + spheres.len());
        tree.extend_from_slice(bytemuck::cast_slice(&nodes));
        tree.extend_from_slice(&spheres);
        Self {
            count: frames.len() as u32,
            frames: storage_buffer_with(device, "bvh_cloth_collider_frames", &pad_frames(frames, colliders.len())),
            tree: storage_buffer_with(device, "bvh_cloth_bvh_trees", &tree),
            nodes: node_count,
            offsets,
            sizes,
            frame_indices,
            left_out,
        }
    }

    /// Writes the trees of the colliders `changed` (indices into `colliders`) in place, and the
    /// frames of all, when `colliders` has the layout [`Self::new`] was given: the same number
    /// of colliders, each tree with as many nodes and spheres as before (a refit keeps them).
    /// Returns `false`, writing nothing, when the layout differs: then a new [`Self::new`] is
    /// needed.
    pub fn rewrite_trees(&mut self, queue: &Queue, colliders: &[Collider], changed: &[usize]) -> bool {
        if colliders.len() != self.sizes.len() || colliders.iter().zip(&self.sizes).any(|(c, &s)| gpu_tree_size(c) != s)
        {
            return false;
        }
        for &k in changed {
            let (Some((node, sphere)), Some(tree)) = (self.offsets[k], gpu_tree(&colliders[k])) else {
                continue;
            };
            let node_bytes = u64::from(node) * size_of::<BvhNode>() as u64;
            let sphere_bytes = u64::from(self.nodes) * size_of::<BvhNode>() as u64 + u64::from(sphere) * 16;
            if !tree.nodes.is_empty() {
                queue.write_buffer(&self.tree, node_bytes, bytemuck::cast_slice(&tree.nodes));
            }
            let region = gpu_sphere_region(&colliders[k], &tree);
            if !region.is_empty() {
                queue.write_buffer(&self.tree, sphere_bytes, bytemuck::cast_slice(&region));
            }
        }
        self.update_frames(queue, colliders);
        true
    }

    /// The frames of the colliders whose trees were uploaded; `sphere_offset` counts `vec4`s of
    /// the tree buffer, past the `nodes` nodes.
    fn frames_of(
        colliders: &[Collider],
        offsets: &[Option<(u32, u32)>],
        nodes: u32,
    ) -> (Vec<GpuCollider>, Vec<Option<u32>>) {
        let mut frames = Vec::with_capacity(colliders.len());
        let indices = colliders
            .iter()
            .zip(offsets)
            .map(|(collider, offset)| {
                let frame = offset.and_then(|(node, sphere)| GpuCollider::new(collider, node, 2 * nodes + sphere))?;
                frames.push(frame);
                Some(frames.len() as u32 - 1)
            })
            .collect();
        (frames, indices)
    }

    /// Uploads new poses, margins and frictions for the same colliders, in the same order, as
    /// [`Self::new`] was given.
    pub fn update_frames(&mut self, queue: &Queue, colliders: &[Collider]) {
        let (frames, frame_indices) = Self::frames_of(colliders, &self.offsets, self.nodes);
        self.frame_indices = frame_indices;
        self.count = frames.len() as u32;
        if !frames.is_empty() {
            queue.write_buffer(&self.frames, 0, bytemuck::cast_slice(&frames));
        }
    }

    /// Where input collider `k`'s tree lies in the tree buffer: its first node (in nodes) and
    /// its first sphere (in `vec4`s); `None` for one left out.
    pub fn tree_offsets(&self, k: usize) -> Option<(u32, u32)> {
        let (node, sphere) = (*self.offsets.get(k)?)?;
        Some((node, 2 * self.nodes + sphere))
    }

    /// Input collider `k`'s index in the frame buffer as last written; `None` for one left out
    /// or with an invalid pose.
    pub fn frame_index(&self, k: usize) -> Option<u32> {
        *self.frame_indices.get(k)?
    }

    /// `vec4`s of input collider `k`'s sphere region: its spheres (and for exact contact its
    /// triangles after them).
    pub fn spheres_of(&self, k: usize) -> u32 {
        self.sizes.get(k).map_or(0, |&(_, spheres)| spheres as u32)
    }

    /// The frame buffer (an array of [`GpuCollider`]) and the tree buffer (every tree's nodes,
    /// two `vec4`s each, then every sphere), for reading back.
    pub fn buffers(&self) -> (&Buffer, &Buffer) {
        (&self.frames, &self.tree)
    }

    /// Colliders the kernels test against.
    pub fn len(&self) -> u32 {
        self.count
    }

    /// Whether there is none.
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// Indices, into the slice given to [`Self::new`], of the colliders left out because their
    /// trees did not fit the device's storage bindings.
    pub fn left_out(&self) -> &[usize] {
        &self.left_out
    }
}

/// The frame buffer is sized for every input collider, so that a collider whose pose becomes
/// valid later fits without a new buffer.
fn pad_frames(mut frames: Vec<GpuCollider>, capacity: usize) -> Vec<GpuCollider> {
    frames.resize(capacity.max(frames.len()), GpuCollider::default());
    frames
}
