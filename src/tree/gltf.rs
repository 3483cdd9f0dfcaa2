//! Trees from glTF: a scene with a trunk mesh and a leaves mesh — as exported from
//! Blender or a tree generator — analysed into a [`TreeModel`].
//!
//! Every triangle primitive of the default scene (node transforms applied) is trunk or
//! leaves: leaves when its node's, mesh's or material's name contains one of
//! [`GltfTreeSettings::leaf_keywords`], trunk otherwise. Loaded as `*.tree.glb` or
//! `*.tree.gltf` (buffers embedded, in the `.glb` container, or in files beside it).

use std::collections::HashMap;

use base64::Engine;
use bevy::asset::io::Reader;
use bevy::asset::{AssetLoader, LoadContext};
use bevy::log::warn;
use bevy::math::{Mat3, Mat4, Vec3};
use bevy::reflect::TypePath;
use serde::{Deserialize, Serialize};

use super::analyze::{AnalysisOptions, MeshData, TreeAnalysis, TreeAnalysisError, analyze};
use super::model::{LinearRgb, TreeModel};

/// How a glTF file is split into trunk and leaves.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct GltfTreeSettings {
    /// A primitive is leaves when its node's, mesh's or material's name contains one of
    /// these (case-insensitive); otherwise it is trunk.
    /// Default: `["leaf", "leaves", "foliage", "needle"]`.
    pub leaf_keywords: Vec<String>,
}

impl Default for GltfTreeSettings {
    fn default() -> Self {
        Self {
            leaf_keywords: ["leaf", "leaves", "foliage", "needle"]
                .map(String::from)
                .to_vec(),
        }
    }
}

/// Why a glTF file could not become a tree.
#[derive(Debug, thiserror::Error)]
pub enum GltfTreeError {
    /// The file is not valid glTF.
    #[error("not valid glTF: {0}")]
    Gltf(#[from] gltf::Error),
    /// A buffer is missing (an external file not found, or an undecodable data URI).
    #[error("buffer {index} ({uri}) could not be read: {reason}")]
    Buffer {
        /// The buffer's index.
        index: usize,
        /// Its URI.
        uri: String,
        /// Why.
        reason: String,
    },
    /// A primitive is not a triangle list.
    #[error("mesh {mesh:?} has a {mode:?} primitive; trees need triangles")]
    NotTriangles {
        /// The mesh's name.
        mesh: String,
        /// Its mode.
        mode: gltf::mesh::Mode,
    },
    /// A primitive has no positions.
    #[error("mesh {mesh:?} has a primitive without positions")]
    NoPositions {
        /// The mesh's name.
        mesh: String,
    },
    /// Nothing was classified as trunk.
    #[error("no trunk: every primitive's name matched a leaf keyword ({keywords:?})")]
    NoTrunk {
        /// The keywords used.
        keywords: Vec<String>,
    },
    /// The meshes do not form a tree.
    #[error("{0}")]
    Analysis(#[from] TreeAnalysisError),
    /// Reading a file failed.
    #[error("could not read: {0}")]
    Io(String),
}

#[derive(Default)]
struct Part {
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    indices: Vec<u32>,
    color_sum: Vec3,
    color_weight: f32,
}

impl Part {
    fn color(&self) -> Option<LinearRgb> {
        (self.color_weight > 0.0).then(|| (self.color_sum / self.color_weight).to_array())
    }
}

/// URIs of the external buffer files `bytes` refers to (not data URIs, not the GLB blob).
pub fn external_buffer_uris(bytes: &[u8]) -> Result<Vec<String>, GltfTreeError> {
    let gltf = gltf::Gltf::from_slice(bytes)?;
    Ok(gltf
        .buffers()
        .filter_map(|b| match b.source() {
            gltf::buffer::Source::Uri(uri) if !uri.starts_with("data:") => Some(uri.to_string()),
            _ => None,
        })
        .collect())
}

/// Splits a glTF document into trunk and leaves and analyses them. `external` holds the
/// bytes of the buffer files named by [`external_buffer_uris`].
pub fn import_gltf(
    bytes: &[u8],
    settings: &GltfTreeSettings,
    external: &HashMap<String, Vec<u8>>,
) -> Result<TreeAnalysis, GltfTreeError> {
    let gltf = gltf::Gltf::from_slice(bytes)?;
    let mut buffers: Vec<Vec<u8>> = Vec::new();
    for buffer in gltf.buffers() {
        let fail = |uri: &str, reason: String| GltfTreeError::Buffer {
            index: buffer.index(),
            uri: uri.to_string(),
            reason,
        };
        let data = match buffer.source() {
            gltf::buffer::Source::Bin => gltf
                .blob
                .clone()
                .ok_or_else(|| fail("BIN chunk", "the file has no binary chunk".into()))?,
            gltf::buffer::Source::Uri(uri) if uri.starts_with("data:") => {
                let payload = uri
                    .split_once(";base64,")
                    .map(|(_, p)| p)
                    .unwrap_or_default();
                base64::engine::general_purpose::STANDARD
                    .decode(payload)
                    .map_err(|e| fail("data URI", e.to_string()))?
            }
            gltf::buffer::Source::Uri(uri) => external
                .get(uri)
                .cloned()
                .ok_or_else(|| fail(uri, "not provided".into()))?,
        };
        if data.len() < buffer.length() {
            return Err(fail(
                "",
                format!("{} bytes, {} expected", data.len(), buffer.length()),
            ));
        }
        buffers.push(data);
    }

    let keywords: Vec<String> = settings
        .leaf_keywords
        .iter()
        .map(|k| k.to_lowercase())
        .collect();
    let is_leaf = |name: Option<&str>| {
        name.is_some_and(|n| {
            let n = n.to_lowercase();
            keywords
                .iter()
                .any(|k| !k.is_empty() && n.contains(k.as_str()))
        })
    };
    let (mut trunk, mut leaves) = (Part::default(), Part::default());
    let mut visit: Vec<(gltf::Node, Mat4)> =
        match gltf.default_scene().or_else(|| gltf.scenes().next()) {
            Some(scene) => scene.nodes().map(|n| (n, Mat4::IDENTITY)).collect(),
            None => gltf.nodes().map(|n| (n, Mat4::IDENTITY)).collect(),
        };
    while let Some((node, parent)) = visit.pop() {
        let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
        visit.extend(node.children().map(|c| (c, world)));
        let Some(mesh) = node.mesh() else { continue };
        let normal_matrix = Mat3::from_mat4(world).inverse().transpose();
        for primitive in mesh.primitives() {
            let mesh_name = mesh.name().unwrap_or("(unnamed)").to_string();
            if primitive.mode() != gltf::mesh::Mode::Triangles {
                return Err(GltfTreeError::NotTriangles {
                    mesh: mesh_name,
                    mode: primitive.mode(),
                });
            }
            let leaf = is_leaf(node.name())
                || is_leaf(mesh.name())
                || is_leaf(primitive.material().name());
            let part = if leaf { &mut leaves } else { &mut trunk };
            let reader = primitive.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
            let positions: Vec<Vec3> = reader
                .read_positions()
                .ok_or(GltfTreeError::NoPositions { mesh: mesh_name })?
                .map(|p| world.transform_point3(Vec3::from(p)))
                .collect();
            let first = part.positions.len() as u32;
            match reader.read_normals() {
                Some(normals) => part.normals.extend(normals.map(|n| {
                    (normal_matrix * Vec3::from(n))
                        .try_normalize()
                        .unwrap_or(Vec3::Y)
                })),
                None => part
                    .normals
                    .extend(core::iter::repeat_n(Vec3::Y, positions.len())),
            }
            match reader.read_indices() {
                Some(indices) => part.indices.extend(indices.into_u32().map(|i| first + i)),
                None => part.indices.extend(first..first + positions.len() as u32),
            }
            let [r, g, b, _] = primitive
                .material()
                .pbr_metallic_roughness()
                .base_color_factor();
            part.color_sum += Vec3::new(r, g, b) * positions.len() as f32;
            part.color_weight += positions.len() as f32;
            part.positions.extend(positions);
        }
    }
    if trunk.indices.is_empty() {
        return Err(GltfTreeError::NoTrunk {
            keywords: settings.leaf_keywords.clone(),
        });
    }
    let options = AnalysisOptions::default();
    let trunk_data = MeshData {
        positions: &trunk.positions,
        normals: Some(&trunk.normals),
        indices: &trunk.indices,
        color: trunk.color(),
    };
    let leaf_data = MeshData {
        positions: &leaves.positions,
        normals: Some(&leaves.normals),
        indices: &leaves.indices,
        color: leaves.color(),
    };
    Ok(analyze(&trunk_data, &leaf_data, &options)?)
}

/// Loads `*.tree.glb` and `*.tree.gltf` files as [`TreeModel`]s.
#[derive(Default, TypePath)]
pub struct GltfTreeLoader;

impl AssetLoader for GltfTreeLoader {
    type Asset = TreeModel;
    type Settings = GltfTreeSettings;
    type Error = GltfTreeError;

    async fn load(
        &self,
        reader: &mut dyn Reader,
        settings: &GltfTreeSettings,
        load_context: &mut LoadContext<'_>,
    ) -> Result<TreeModel, GltfTreeError> {
        let mut bytes = Vec::new();
        reader
            .read_to_end(&mut bytes)
            .await
            .map_err(|e| GltfTreeError::Io(e.to_string()))?;
        let mut external = HashMap::new();
        for uri in external_buffer_uris(&bytes)? {
            let path = load_context
                .path()
                .resolve_embed_str(&uri)
                .map_err(|e| GltfTreeError::Io(e.to_string()))?;
            let data = load_context
                .read_asset_bytes(path)
                .await
                .map_err(|e| GltfTreeError::Io(e.to_string()))?;
            external.insert(uri, data);
        }
        let analysis = import_gltf(&bytes, settings, &external)?;
        for warning in &analysis.warnings {
            warn!("{}: {warning:?}", load_context.path());
        }
        Ok(analysis.model)
    }

    fn extensions(&self) -> &[&str] {
        &["tree.glb", "tree.gltf"]
    }
}
