//! Reading a Bevy [`Mesh`] as the triangle list the collider builder takes.

use bevy::asset::RenderAssetUsages;
use bevy::mesh::{Indices, PrimitiveTopology, VertexAttributeValues};
use bevy::prelude::*;
use bvh_cloth_core::{Collider, MeshRef, SkinRef, Voxels};

use crate::messages::ColliderFailure;

/// A copy of a mesh's triangle list (and skin, for a skinned collider), ready to hand to a
/// build task.
#[derive(Clone, Debug, Default)]
pub(crate) struct TriangleList {
    pub positions: Vec<[f32; 3]>,
    pub indices: Option<Vec<u32>>,
    pub skin: Option<TriangleSkin>,
}

/// A copy of a mesh's skin: four joints and weights per vertex, and the skin's joint count.
#[derive(Clone, Debug, Default)]
pub(crate) struct TriangleSkin {
    joints: Vec<[u16; 4]>,
    weights: Vec<[f32; 4]>,
    joint_count: usize,
}

impl TriangleList {
    /// Copies the positions and indices out of `mesh`.
    pub fn from_mesh(mesh: &Mesh) -> Result<Self, ColliderFailure> {
        if !mesh.asset_usage.contains(RenderAssetUsages::MAIN_WORLD) {
            return Err(ColliderFailure::NotInMainWorld);
        }
        if mesh.primitive_topology() != PrimitiveTopology::TriangleList {
            return Err(ColliderFailure::NotTriangles(mesh.primitive_topology()));
        }
        let positions = match mesh.attribute(Mesh::ATTRIBUTE_POSITION) {
            None => return Err(ColliderFailure::NoPositions),
            Some(VertexAttributeValues::Float32x3(p)) => p.clone(),
            Some(_) => return Err(ColliderFailure::PositionsNotFloat3),
        };
        let indices = mesh.indices().map(|indices| match indices {
            Indices::U16(i) => i.iter().map(|&i| u32::from(i)).collect(),
            Indices::U32(i) => i.clone(),
        });
        Ok(Self { positions, indices, skin: None })
    }

    /// Also copies the mesh's joint indices and weights, for a skin of `joint_count` joints.
    pub fn with_skin(mut self, mesh: &Mesh, joint_count: usize) -> Result<Self, ColliderFailure> {
        let joints = match mesh.attribute(Mesh::ATTRIBUTE_JOINT_INDEX) {
            Some(VertexAttributeValues::Uint16x4(joints)) => joints.clone(),
            _ => return Err(ColliderFailure::NoSkin),
        };
        let weights = match mesh.attribute(Mesh::ATTRIBUTE_JOINT_WEIGHT) {
            Some(VertexAttributeValues::Float32x4(weights)) => weights.clone(),
            _ => return Err(ColliderFailure::NoSkin),
        };
        self.skin = Some(TriangleSkin { joints, weights, joint_count });
        Ok(self)
    }

    /// Number of vertices.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// The borrowed view the core takes.
    pub fn as_mesh_ref(&self) -> MeshRef<'_> {
        MeshRef { positions: &self.positions, indices: self.indices.as_deref() }
    }

    /// Voxelises the triangles into `voxels` and builds a collider: a skinned one when the list
    /// has a skin; otherwise, when `exact`, with exact contact against the triangles.
    pub fn build(&self, voxels: Voxels, exact: bool) -> Result<Collider, ColliderFailure> {
        let built = match &self.skin {
            None if exact => Collider::from_mesh_in_exact(self.as_mesh_ref(), voxels),
            None => Collider::from_mesh_in(self.as_mesh_ref(), voxels),
            Some(skin) => {
                let skin = SkinRef { joints: &skin.joints, weights: &skin.weights, joint_count: skin.joint_count };
                Collider::from_skinned_mesh(self.as_mesh_ref(), skin, voxels)
            }
        };
        built.map_err(ColliderFailure::Rejected)
    }
}

/// Builds a collider from a Bevy mesh at resolution `n` with exact contact, the way a default
/// [`AutoCollider`] does: for tools, tests, or colliders a game builds itself. Never panics; a
/// mesh that cannot become a collider gives the reason.
///
/// [`AutoCollider`]: crate::AutoCollider
pub fn collider_from_mesh(mesh: &Mesh, n: u32) -> Result<Collider, ColliderFailure> {
    TriangleList::from_mesh(mesh)?.build(Voxels::PerAxis(n), true)
}
