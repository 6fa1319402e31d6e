//! A skinned mesh as cloth: its pins follow the skin it is painted onto.
//!
//! A mesh with a [`SkinnedMesh`] (a glTF character's cape or skirt, bound to the body's joints)
//! that becomes [`Cloth`](crate::Cloth) is simulated in the world, so the renderer must not skin
//! it again: the plugin takes its `SkinnedMesh` off and keeps it as [`ClothSkin`]. The cloth
//! starts where the skin drew the mesh, and its pins (the cloth's own `pins`, those no anchor
//! claims) go every tick where linear blend skinning puts their vertex, as Bevy's vertex shader
//! does: the sum over the vertex's four joints of its weight times the joint's world transform
//! times the joint's inverse bind pose, applied to the bind-pose position. The free particles
//! are simulated.

use bevy::ecs::entity::EntityHashSet;
use bevy::mesh::VertexAttributeValues;
use bevy::mesh::skinning::{SkinnedMesh, SkinnedMeshInverseBindposes};
use bevy::prelude::*;
use bvh_cloth_core::backend::SkinnedVertices;
use bvh_cloth_core::{Affine3A, ClothTopology, Vec3, Vec3A};

/// The skin of a mesh that became cloth: the [`SkinnedMesh`] the plugin took off it, so that
/// the renderer does not skin the simulated vertices a second time. The cloth's pins follow
/// it; removing the cloth puts the `SkinnedMesh` back.
#[derive(Component, Clone, Debug)]
pub struct ClothSkin(pub SkinnedMesh);

/// A cloth's skin as built: every particle's vertex skin, the joints, and the joint matrices
/// of the end of the last frame, from which the pins move on.
#[derive(Debug)]
pub(crate) struct SkinBinding {
    joints: Vec<Entity>,
    /// Each joint's inverse bind pose.
    inverse: Vec<Affine3A>,
    /// Each particle's vertex: its bind position, four joints and their weights.
    vertices: SkinnedVertices,
    /// The particles the skin holds.
    pub(crate) pins: Vec<u32>,
    /// Each joint's world transform times its inverse bind pose, at the end of the last frame.
    matrices: Vec<Affine3A>,
    /// A joint has gone: the pins stay where they were last held.
    lost: bool,
}

impl SkinBinding {
    /// The skin of `mesh` (its joint indices and weights) under `skin`'s joints, whose inverse
    /// bind poses are `inverse` and whose world transforms `joint_pose` gives, for the
    /// particles of `topology` (each from its first vertex); `pins` follow the skin. The
    /// reason when the skin cannot be used.
    pub(crate) fn new(
        skin: &SkinnedMesh,
        inverse: &SkinnedMeshInverseBindposes,
        mesh: &Mesh,
        topology: &ClothTopology,
        pins: Vec<u32>,
        joint_pose: impl Fn(Entity) -> Option<Affine3A>,
    ) -> Result<Self, String> {
        let joints = match mesh.attribute(Mesh::ATTRIBUTE_JOINT_INDEX) {
            Some(VertexAttributeValues::Uint16x4(joints)) => joints,
            _ => return Err("its mesh has no Uint16x4 joint indices".into()),
        };
        let weights = match mesh.attribute(Mesh::ATTRIBUTE_JOINT_WEIGHT) {
            Some(VertexAttributeValues::Float32x4(weights)) => weights,
            _ => return Err("its mesh has no Float32x4 joint weights".into()),
        };
        let Some(VertexAttributeValues::Float32x3(positions)) = mesh.attribute(Mesh::ATTRIBUTE_POSITION) else {
            return Err("its mesh has no Float32x3 positions".into());
        };
        let count = skin.joints.len().min(inverse.len());
        let map = topology.vertex_particle();
        if joints.len() != map.len() || weights.len() != map.len() || positions.len() != map.len() {
            return Err("its joint attributes do not cover every vertex".into());
        }
        let mut first = vec![None; topology.len()];
        for (v, &particle) in map.iter().enumerate() {
            let slot = &mut first[particle as usize];
            if slot.is_none() {
                let used = joints[v].iter().zip(&weights[v]).filter(|&(_, &w)| w != 0.0);
                if let Some((&joint, _)) = used.clone().find(|&(&j, _)| usize::from(j) >= count) {
                    return Err(format!("vertex {v} names joint {joint}, and the skin has {count}"));
                }
                if !weights[v].iter().all(|w| w.is_finite()) || !Vec3::from(positions[v]).is_finite() {
                    return Err(format!("vertex {v} has a non-finite position or weight"));
                }
                *slot = Some(v);
            }
        }
        let first = first
            .into_iter()
            .map(|v| v.ok_or_else(|| "a particle has no vertex".to_string()))
            .collect::<Result<Vec<_>, _>>()?;
        let vertices = SkinnedVertices {
            positions: first.iter().map(|&v| Vec3A::from_array(positions[v])).collect(),
            joints: first.iter().map(|&v| joints[v]).collect(),
            weights: first.iter().map(|&v| weights[v]).collect(),
        };
        let inverse: Vec<Affine3A> = inverse.iter().take(count).map(|m| Affine3A::from_mat4(*m)).collect();
        let mut binding =
            Self { joints: skin.joints[..count].to_vec(), inverse, vertices, pins, matrices: Vec::new(), lost: false };
        binding.matrices = binding
            .pose(joint_pose)
            .map_err(|(k, joint)| format!("joint {k} ({joint}) has no GlobalTransform (was it despawned?)"))?;
        Ok(binding)
    }

    /// The joint matrices as `joint_pose` places the joints now; or the first joint it cannot
    /// place, and its entity.
    fn pose(&self, joint_pose: impl Fn(Entity) -> Option<Affine3A>) -> Result<Vec<Affine3A>, (usize, Entity)> {
        self.joints
            .iter()
            .zip(&self.inverse)
            .enumerate()
            .map(|(k, (&joint, inverse))| joint_pose(joint).map(|pose| pose * *inverse).ok_or((k, joint)))
            .collect()
    }

    /// Where particle `i` is skinned by `matrices`.
    fn place(&self, matrices: &[Affine3A], i: u32) -> Vec3 {
        self.vertices.skin_vertex(i as usize, matrices).into()
    }

    /// Where every particle is skinned at the end of the last frame: where the cloth starts.
    pub(crate) fn placed(&self) -> impl Iterator<Item = Vec3> + '_ {
        (0..self.vertices.positions.len() as u32).map(|i| self.place(&self.matrices, i))
    }

    /// Moves the skin to this frame's joints and returns each pin's place at the end of the last
    /// frame and now, `(particle, was, now)`. A joint that has gone is reported once (as
    /// `Err(entity)`) and the pins stay where they were.
    pub(crate) fn advance(
        &mut self,
        joint_pose: impl Fn(Entity) -> Option<Affine3A>,
    ) -> (Vec<(u32, Vec3, Vec3)>, Option<Entity>) {
        let mut gone = None;
        let now = match self.pose(joint_pose) {
            Ok(now) if !self.lost => now,
            Ok(_) => self.matrices.clone(),
            Err((_, joint)) => {
                if !self.lost {
                    self.lost = true;
                    gone = Some(joint);
                }
                self.matrices.clone()
            }
        };
        let moves = self.pins.iter().map(|&i| (i, self.place(&self.matrices, i), self.place(&now, i))).collect();
        self.matrices = now;
        (moves, gone)
    }
}

/// Marks the mesh of each cloth that lost its skin as changed, once, a frame or two after:
/// Bevy's renderer read the entity's skin when it first drew the cloth's mesh, in the frame the
/// skin came off, and keeps it until the entity's mesh changes. On the CPU backend the mesh
/// changes every frame anyway; on the GPU backend it would never be drawn.
pub(crate) fn redraw_unskinned(
    mut cloths: Query<(Entity, Ref<ClothSkin>, &mut Mesh3d)>,
    mut redrawn: Local<EntityHashSet>,
) {
    for (entity, skin, mut mesh) in &mut cloths {
        if !skin.is_added() && redrawn.insert(entity) {
            mesh.set_changed();
        }
    }
    redrawn.retain(|&entity| cloths.contains(entity));
}
