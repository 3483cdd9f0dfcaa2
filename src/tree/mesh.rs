//! Conversions between Bevy [`Mesh`]es and tree data: analyse a trunk and a leaves mesh
//! you built or imported, or draw a [`TreeModel`] at full detail with Bevy's standard
//! renderer (a reference for the custom pass, and a fallback).

use bevy::asset::RenderAssetUsages;
use bevy::math::Vec3;
use bevy::mesh::{Indices, Mesh, PrimitiveTopology, VertexAttributeValues};

use super::analyze::MeshData;
use super::model::TreeModel;

/// Why a Bevy mesh cannot be read as tree input.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum MeshConversionError {
    /// Only triangle lists describe trees.
    #[error("the mesh's topology is {0:?}; trees need a triangle list")]
    NotTriangleList(PrimitiveTopology),
    /// No `Float32x3` positions.
    #[error("the mesh has no Float32x3 positions")]
    NoPositions,
}

/// Arrays owned on behalf of a [`MeshData`], read from a Bevy [`Mesh`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct OwnedMeshData {
    /// Positions.
    pub positions: Vec<Vec3>,
    /// Normals, when the mesh has them.
    pub normals: Option<Vec<Vec3>>,
    /// Triangle indices (sequential when the mesh has no index buffer).
    pub indices: Vec<u32>,
}

impl OwnedMeshData {
    /// Reads positions, normals and indices from a triangle-list mesh.
    pub fn from_mesh(mesh: &Mesh) -> Result<Self, MeshConversionError> {
        if mesh.primitive_topology() != PrimitiveTopology::TriangleList {
            return Err(MeshConversionError::NotTriangleList(
                mesh.primitive_topology(),
            ));
        }
        let vec3s = |attribute| match mesh.attribute(attribute) {
            Some(VertexAttributeValues::Float32x3(values)) => {
                Some(values.iter().map(|&v| Vec3::from(v)).collect::<Vec<_>>())
            }
            _ => None,
        };
        let positions = vec3s(Mesh::ATTRIBUTE_POSITION).ok_or(MeshConversionError::NoPositions)?;
        let normals = vec3s(Mesh::ATTRIBUTE_NORMAL);
        let indices = match mesh.indices() {
            Some(indices) => indices.iter().map(|i| i as u32).collect(),
            None => (0..positions.len() as u32).collect(),
        };
        Ok(Self {
            positions,
            normals,
            indices,
        })
    }

    /// Borrows the arrays for [`analyze`](super::analyze).
    pub fn as_mesh_data(&self) -> MeshData<'_> {
        MeshData {
            positions: &self.positions,
            normals: self.normals.as_deref(),
            indices: &self.indices,
            color: None,
        }
    }
}

/// A triangle-list Bevy mesh with positions, normals and 32-bit indices.
pub(crate) fn triangle_mesh(positions: &[Vec3], normals: &[Vec3], indices: &[u32]) -> Mesh {
    Mesh::new(
        PrimitiveTopology::TriangleList,
        RenderAssetUsages::default(),
    )
    .with_inserted_attribute(
        Mesh::ATTRIBUTE_POSITION,
        positions.iter().map(Vec3::to_array).collect::<Vec<_>>(),
    )
    .with_inserted_attribute(
        Mesh::ATTRIBUTE_NORMAL,
        normals.iter().map(Vec3::to_array).collect::<Vec<_>>(),
    )
    .with_inserted_indices(Indices::U32(indices.to_vec()))
}

impl TreeModel {
    /// The whole trunk as one Bevy mesh, at full detail.
    pub fn trunk_mesh(&self) -> Mesh {
        triangle_mesh(
            &self.trunk_positions,
            &self.trunk_normals,
            &self.trunk_indices,
        )
    }

    /// All leaves as one Bevy mesh, at full detail (draw it with a double-sided,
    /// cull-less material: leaves are seen from both sides).
    pub fn leaf_mesh(&self) -> Mesh {
        triangle_mesh(&self.leaf_positions, &self.leaf_normals, &self.leaf_indices)
    }
}
