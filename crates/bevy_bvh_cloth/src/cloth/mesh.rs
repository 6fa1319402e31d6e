//! The cloth's render mesh: the generated grid's, or a copy of the authored one, rewritten from
//! the simulation through the vertex-to-particle map, so that split vertices move together.

use bevy::asset::RenderAssetUsages;
use bevy::camera::primitives::Aabb;
use bevy::mesh::{Indices, PrimitiveTopology, VertexAttributeValues};
use bevy::prelude::*;
use bvh_cloth_core::backend::particle_normal;
use bvh_cloth_core::{ClothError, ClothGrid, ClothSim, ClothTopology, MeshVertices};

use crate::colliders::mesh::TriangleList;

/// The topology of an authored mesh, its positions scaled by `scale` (the entity's scale when
/// the cloth is built). The mesh is read as colliders read theirs ([`TriangleList`]); a mesh
/// that is not a main-world triangle list with `Float32x3` positions is
/// [`ClothError::NoTriangleMesh`].
pub(crate) fn authored_topology(mesh: &Mesh, scale: Vec3) -> Result<ClothTopology, ClothError> {
    let mut triangles = TriangleList::from_mesh(mesh).map_err(|_| ClothError::NoTriangleMesh)?;
    for p in &mut triangles.positions {
        *p = (Vec3::from(*p) * scale).to_array();
    }
    ClothTopology::from_mesh(triangles.as_mesh_ref())
}

/// What pins select from in an authored mesh: its positions as authored and its `Float32x4`
/// vertex colours, where it has them. (Positions that are not `Float32x3` read as none; such a
/// mesh never gets this far, [`authored_topology`] refuses it.)
pub(crate) fn authored_vertices(mesh: &Mesh) -> MeshVertices<'_> {
    let positions = match mesh.attribute(Mesh::ATTRIBUTE_POSITION) {
        Some(VertexAttributeValues::Float32x3(p)) => p.as_slice(),
        _ => &[],
    };
    let colors = match mesh.attribute(Mesh::ATTRIBUTE_COLOR) {
        Some(VertexAttributeValues::Float32x4(c)) => Some(c.as_slice()),
        _ => None,
    };
    MeshVertices { positions, colors }
}

/// A new mesh for a grid cloth: positions and normals in the frame of `transform`, UVs over the
/// grid, two triangles per cell.
pub(crate) fn new_grid_mesh(grid: &ClothGrid, sim: &ClothSim, transform: &GlobalTransform) -> Mesh {
    let n = sim.len();
    let mut mesh = Mesh::new(PrimitiveTopology::TriangleList, RenderAssetUsages::default())
        .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, vec![[0.0f32; 3]; n])
        .with_inserted_attribute(Mesh::ATTRIBUTE_NORMAL, vec![[0.0f32, 1.0, 0.0]; n])
        .with_inserted_attribute(Mesh::ATTRIBUTE_UV_0, grid.uvs())
        .with_inserted_indices(Indices::U32(grid.triangle_indices()));
    write_cloth_mesh(&mut mesh, sim, transform);
    mesh
}

/// The mesh a cloth built from `source` draws: a copy of it (UVs, colours and any other
/// attribute kept) that both worlds hold, with normals, written from `sim`. A skinned source's
/// joint indices and weights are left out: the cloth's vertices are never skinned, and a mesh
/// with them but no `SkinnedMesh` would be drawn by Bevy's skinned pipeline without a skin.
pub(crate) fn new_authored_mesh(source: &Mesh, sim: &ClothSim, transform: &GlobalTransform) -> Mesh {
    let mut mesh = source.clone();
    mesh.asset_usage = RenderAssetUsages::default();
    mesh.remove_attribute(Mesh::ATTRIBUTE_JOINT_INDEX);
    mesh.remove_attribute(Mesh::ATTRIBUTE_JOINT_WEIGHT);
    let vertices = sim.topology().vertex_particle().len();
    if !matches!(mesh.attribute(Mesh::ATTRIBUTE_NORMAL), Some(VertexAttributeValues::Float32x3(n)) if n.len() == vertices)
    {
        mesh.insert_attribute(Mesh::ATTRIBUTE_NORMAL, vec![[0.0f32, 1.0, 0.0]; vertices]);
    }
    write_cloth_mesh(&mut mesh, sim, transform);
    mesh
}

/// Writes the simulated positions and normals into `mesh`, in the local frame of `transform`,
/// each vertex from its particle, and returns their bounds. `None` (and nothing written) when
/// the transform cannot be inverted or the mesh is not the cloth's.
pub(crate) fn write_cloth_mesh(mesh: &mut Mesh, sim: &ClothSim, transform: &GlobalTransform) -> Option<Aabb> {
    let local_to_world = transform.affine();
    if !local_to_world.is_finite() || local_to_world.matrix3.determinant().abs() < f32::MIN_POSITIVE {
        return None;
    }
    let world_to_local = local_to_world.inverse();
    // Normals go world -> local by the transpose of the local -> world linear part (the inverse
    // transpose of world -> local), which is right for any scale.
    let normal_to_local = local_to_world.matrix3.transpose();
    let topology = sim.topology();
    let map = topology.vertex_particle();
    let local: Vec<Vec3> = (0..sim.len()).map(|i| world_to_local.transform_point3(sim.position(i))).collect();
    let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
    {
        let Some(VertexAttributeValues::Float32x3(positions)) = mesh.attribute_mut(Mesh::ATTRIBUTE_POSITION) else {
            return None;
        };
        if positions.len() != map.len() {
            return None;
        }
        for (out, &p) in positions.iter_mut().zip(map) {
            let p = local[p as usize];
            (lo, hi) = (lo.min(p), hi.max(p));
            *out = p.to_array();
        }
    }
    let normals: Vec<Vec3> = (0..sim.len())
        .map(|i| (normal_to_local * particle_normal(topology, i, |p| sim.position(p))).normalize_or(Vec3::Y))
        .collect();
    let Some(VertexAttributeValues::Float32x3(out)) = mesh.attribute_mut(Mesh::ATTRIBUTE_NORMAL) else {
        return None;
    };
    for (out, &p) in out.iter_mut().zip(map) {
        *out = normals[p as usize].to_array();
    }
    Some(Aabb::from_min_max(lo, hi))
}
