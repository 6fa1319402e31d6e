//! The cloth's grid mesh: built once per grid, then rewritten from the simulation.

use bevy::asset::RenderAssetUsages;
use bevy::camera::primitives::Aabb;
use bevy::mesh::{Indices, PrimitiveTopology, VertexAttributeValues};
use bevy::prelude::*;
use bvh_cloth_core::ClothSim;
use bvh_cloth_core::normals::vertex_normal;

/// A new mesh for `sim`: positions and normals in the frame of `transform`, UVs over the grid,
/// two triangles per cell.
pub(crate) fn new_cloth_mesh(sim: &ClothSim, transform: &GlobalTransform) -> Mesh {
    let n = sim.len();
    let mut mesh = Mesh::new(PrimitiveTopology::TriangleList, RenderAssetUsages::default())
        .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, vec![[0.0f32; 3]; n])
        .with_inserted_attribute(Mesh::ATTRIBUTE_NORMAL, vec![[0.0f32, 1.0, 0.0]; n])
        .with_inserted_attribute(Mesh::ATTRIBUTE_UV_0, sim.grid().uvs())
        .with_inserted_indices(Indices::U32(sim.grid().triangle_indices()));
    write_cloth_mesh(&mut mesh, sim, transform);
    mesh
}

/// Writes the simulated positions and normals into `mesh`, in the local frame of `transform`,
/// and returns their bounds. `None` (and nothing written) when the transform cannot be
/// inverted or the mesh is not the cloth's.
pub(crate) fn write_cloth_mesh(mesh: &mut Mesh, sim: &ClothSim, transform: &GlobalTransform) -> Option<Aabb> {
    let local_to_world = transform.affine();
    if !local_to_world.is_finite() || local_to_world.matrix3.determinant().abs() < f32::MIN_POSITIVE {
        return None;
    }
    let world_to_local = local_to_world.inverse();
    // Normals go world -> local by the transpose of the local -> world linear part (the inverse
    // transpose of world -> local), which is right for any scale.
    let normal_to_local = local_to_world.matrix3.transpose();
    let grid = *sim.grid();
    let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
    {
        let Some(VertexAttributeValues::Float32x3(positions)) = mesh.attribute_mut(Mesh::ATTRIBUTE_POSITION) else {
            return None;
        };
        if positions.len() != sim.len() {
            return None;
        }
        for (i, out) in positions.iter_mut().enumerate() {
            let local = world_to_local.transform_point3(sim.position(i));
            (lo, hi) = (lo.min(local), hi.max(local));
            *out = local.to_array();
        }
    }
    let Some(VertexAttributeValues::Float32x3(normals)) = mesh.attribute_mut(Mesh::ATTRIBUTE_NORMAL) else {
        return None;
    };
    for r in 0..grid.rows {
        for c in 0..grid.cols {
            let world = vertex_normal(&grid, r, c, |i| sim.position(i));
            let local = (normal_to_local * world).normalize_or(Vec3::Y);
            normals[grid.index(r, c)] = local.to_array();
        }
    }
    Some(Aabb::from_min_max(lo, hi))
}
