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

/// How a glTF file is split into trunk and leaves and analysed: the [`GltfTreeLoader`]'s
/// settings.
///
/// Set them per file in a `.meta` file beside it (`bark.tree.glb.meta`):
///
/// ```ron
/// (
///     meta_format_version: "1.0",
///     asset: Load(
///         loader: "bevy_sherwood::tree::gltf::GltfTreeLoader",
///         settings: (
///             leaf_keywords: ["leaf", "frond"],
///             analysis: (ground: -0.05, weld_tolerance: 1e-4),
///         ),
///     ),
/// )
/// ```
///
/// or in code with `AssetServer::load_with_settings`. Fields left out keep their
/// defaults.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct GltfTreeSettings {
    /// A primitive is leaves when its node's, mesh's or material's name contains one of
    /// these (case-insensitive); otherwise it is trunk.
    /// Default: `["leaf", "leaves", "foliage", "needle"]`.
    pub leaf_keywords: Vec<String>,
    /// A primitive is not part of the tree at all when its node's (or an ancestor
    /// node's), mesh's or material's name contains one of these (case-insensitive):
    /// supports and props exported with it, such as EZ-Tree's trellis.
    /// Default: `["trellis"]`.
    pub skip_keywords: Vec<String>,
    /// The analysis' options: ground level, weld tolerance, default colours.
    /// Default: [`AnalysisOptions::default`].
    pub analysis: AnalysisOptions,
}

impl Default for GltfTreeSettings {
    fn default() -> Self {
        Self {
            leaf_keywords: ["leaf", "leaves", "foliage", "needle"]
                .map(String::from)
                .to_vec(),
            skip_keywords: vec!["trellis".into()],
            analysis: AnalysisOptions::default(),
        }
    }
}

/// Why a glTF file could not become a tree.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum GltfTreeError {
    /// The file is not valid glTF.
    #[error("not valid glTF: {0}")]
    Gltf(#[from] gltf::Error),
    /// The file is so malformed that the `gltf` crate gave up on it (an index into an
    /// array that is not there).
    #[error("not valid glTF: {0}")]
    Malformed(String),
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
    /// An accessor the importer reads is not what glTF allows there, or lies outside its
    /// buffer.
    #[error("mesh {mesh:?}: the {attribute} accessor {index} {reason}")]
    Accessor {
        /// The mesh's name.
        mesh: String,
        /// What it holds: `POSITION`, `NORMAL` or `indices`.
        attribute: &'static str,
        /// The accessor's index in the file.
        index: usize,
        /// What is wrong with it.
        reason: String,
    },
    /// An index names a vertex the primitive does not have.
    #[error("mesh {mesh:?}: index {value} is past the primitive's {vertices} vertices")]
    IndexOutOfRange {
        /// The mesh's name.
        mesh: String,
        /// The index.
        value: u32,
        /// The primitive's vertex count.
        vertices: usize,
    },
    /// The scene has no triangle primitive at all.
    #[error("the scene has no mesh: nothing to make a tree of")]
    NoMeshes,
    /// Nothing was classified as trunk.
    #[error("no trunk: every primitive's name matched a leaf keyword ({keywords:?})")]
    NoTrunk {
        /// The keywords used.
        keywords: Vec<String>,
    },
    /// An external buffer's URI leaves the folder the file is in (`..`), is absolute, or
    /// names another scheme: only files beside the glTF file (or below it) are read.
    #[error(
        "buffer URI {uri:?} points outside the asset's folder; only relative paths below it are read"
    )]
    UnsafeUri {
        /// The URI.
        uri: String,
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
/// A URI that would read outside the file's folder (a `..` segment, an absolute path, a
/// drive or another scheme, percent-encoded or not) is refused: a tree file must not be
/// able to read the rest of the machine.
pub fn external_buffer_uris(bytes: &[u8]) -> Result<Vec<String>, GltfTreeError> {
    let gltf = parse(bytes)?;
    let mut uris = Vec::new();
    for buffer in gltf.buffers() {
        if let gltf::buffer::Source::Uri(uri) = buffer.source()
            && !uri.starts_with("data:")
        {
            if !is_confined(uri) {
                return Err(GltfTreeError::UnsafeUri {
                    uri: uri.to_owned(),
                });
            }
            uris.push(uri.to_owned());
        }
    }
    Ok(uris)
}

/// Parses a glTF document. The `gltf` crate's validation indexes arrays with indices it
/// has not checked yet (a POSITION accessor past the accessors panics inside it), so a
/// panic there is caught and reported as a malformed file.
fn parse(bytes: &[u8]) -> Result<gltf::Gltf, GltfTreeError> {
    match std::panic::catch_unwind(|| gltf::Gltf::from_slice(bytes)) {
        Ok(parsed) => Ok(parsed?),
        Err(panic) => {
            let reason = panic
                .downcast_ref::<&str>()
                .map(|s| (*s).to_owned())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "an index out of range".into());
            Err(GltfTreeError::Malformed(reason))
        }
    }
}

/// Whether a relative URI stays in its folder or below: no scheme or drive, no root, no
/// `..` segment, after percent-decoding.
fn is_confined(uri: &str) -> bool {
    let bytes = uri.as_bytes();
    let mut decoded = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        let hex = |b: u8| (b as char).to_digit(16);
        match (
            bytes[i],
            bytes.get(i + 1).copied().and_then(hex),
            bytes.get(i + 2).copied().and_then(hex),
        ) {
            (b'%', Some(hi), Some(lo)) => {
                decoded.push((hi * 16 + lo) as u8);
                i += 3;
            }
            (b, ..) => {
                decoded.push(b);
                i += 1;
            }
        }
    }
    let Ok(path) = String::from_utf8(decoded) else {
        return false;
    };
    !path.is_empty()
        && !path.contains(':')
        && !path.starts_with(['/', '\\'])
        && path.split(['/', '\\']).all(|segment| segment != "..")
        && !path.contains('\0')
}

/// Checks an accessor before the `gltf` crate reads it (its readers assume valid files:
/// a float index accessor reaches an `unreachable!`, an empty one underflows): its type,
/// that it has elements, and that they lie within its buffer view and the view within
/// its buffer.
fn check_accessor(
    accessor: &gltf::Accessor,
    buffers: &[Vec<u8>],
    mesh: &str,
    attribute: &'static str,
    dimensions: gltf::accessor::Dimensions,
    types: &[gltf::accessor::DataType],
) -> Result<(), GltfTreeError> {
    let bad = |reason: String| GltfTreeError::Accessor {
        mesh: mesh.to_owned(),
        attribute,
        index: accessor.index(),
        reason,
    };
    if accessor.sparse().is_some() {
        return Err(bad("is sparse, which tree files do not support".into()));
    }
    if accessor.dimensions() != dimensions || !types.contains(&accessor.data_type()) {
        return Err(bad(format!(
            "holds {:?} {:?}; expected {dimensions:?} of {types:?}",
            accessor.data_type(),
            accessor.dimensions()
        )));
    }
    if accessor.count() == 0 {
        return Err(bad("has no elements".into()));
    }
    let Some(view) = accessor.view() else {
        return Err(bad("has no buffer view".into()));
    };
    let size = accessor.size();
    let stride = view.stride().unwrap_or(size);
    if stride < size {
        return Err(bad(format!(
            "has a stride of {stride} bytes, less than its {size}-byte elements"
        )));
    }
    let end = (accessor.count() - 1)
        .checked_mul(stride)
        .and_then(|n| n.checked_add(size))
        .and_then(|n| n.checked_add(accessor.offset()));
    if end.is_none_or(|end| end > view.length()) {
        return Err(bad(format!(
            "extends past its buffer view ({} elements of {stride} bytes from byte {} of a {}-byte view)",
            accessor.count(),
            accessor.offset(),
            view.length()
        )));
    }
    let buffer_length = buffers.get(view.buffer().index()).map_or(0, Vec::len);
    if view
        .offset()
        .checked_add(view.length())
        .is_none_or(|end| end > buffer_length)
    {
        return Err(bad(format!(
            "lies in a buffer view past the end of buffer {} ({buffer_length} bytes)",
            view.buffer().index()
        )));
    }
    Ok(())
}

/// Splits a glTF document into trunk and leaves and analyses them. `external` holds the
/// bytes of the buffer files named by [`external_buffer_uris`].
pub fn import_gltf(
    bytes: &[u8],
    settings: &GltfTreeSettings,
    external: &HashMap<String, Vec<u8>>,
) -> Result<TreeAnalysis, GltfTreeError> {
    let gltf = parse(bytes)?;
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

    let lower = |keywords: &[String]| -> Vec<String> {
        keywords
            .iter()
            .map(|k| k.to_lowercase())
            .filter(|k| !k.is_empty())
            .collect()
    };
    let (leaf_keywords, skip_keywords) = (
        lower(&settings.leaf_keywords),
        lower(&settings.skip_keywords),
    );
    let matches = |keywords: &[String], name: Option<&str>| {
        name.is_some_and(|n| {
            let n = n.to_lowercase();
            keywords.iter().any(|k| n.contains(k.as_str()))
        })
    };
    let (mut trunk, mut leaves) = (Part::default(), Part::default());
    let mut primitives = 0;
    // Each node with its world transform and whether an ancestor is skipped.
    let mut visit: Vec<(gltf::Node, Mat4, bool)> =
        match gltf.default_scene().or_else(|| gltf.scenes().next()) {
            Some(scene) => scene.nodes().map(|n| (n, Mat4::IDENTITY, false)).collect(),
            None => gltf.nodes().map(|n| (n, Mat4::IDENTITY, false)).collect(),
        };
    while let Some((node, parent, skipped_above)) = visit.pop() {
        let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
        let skipped = skipped_above || matches(&skip_keywords, node.name());
        visit.extend(node.children().map(|c| (c, world, skipped)));
        let Some(mesh) = node.mesh() else { continue };
        if skipped || matches(&skip_keywords, mesh.name()) {
            continue;
        }
        let normal_matrix = Mat3::from_mat4(world).inverse().transpose();
        for primitive in mesh.primitives() {
            if matches(&skip_keywords, primitive.material().name()) {
                continue;
            }
            let mesh_name = mesh.name().unwrap_or("(unnamed)").to_string();
            if primitive.mode() != gltf::mesh::Mode::Triangles {
                return Err(GltfTreeError::NotTriangles {
                    mesh: mesh_name,
                    mode: primitive.mode(),
                });
            }
            primitives += 1;
            let leaf = matches(&leaf_keywords, node.name())
                || matches(&leaf_keywords, mesh.name())
                || matches(&leaf_keywords, primitive.material().name());
            let part = if leaf { &mut leaves } else { &mut trunk };
            use gltf::accessor::{DataType, Dimensions};
            let Some(position_accessor) = primitive.get(&gltf::Semantic::Positions) else {
                return Err(GltfTreeError::NoPositions { mesh: mesh_name });
            };
            let check = |accessor: &gltf::Accessor, attribute, dimensions, types: &[DataType]| {
                check_accessor(accessor, &buffers, &mesh_name, attribute, dimensions, types)
            };
            check(
                &position_accessor,
                "POSITION",
                Dimensions::Vec3,
                &[DataType::F32],
            )?;
            // Normals are optional: any other kind is read as none.
            let normals_valid = primitive.get(&gltf::Semantic::Normals).is_some_and(|a| {
                check(&a, "NORMAL", Dimensions::Vec3, &[DataType::F32]).is_ok()
                    && a.count() == position_accessor.count()
            });
            if let Some(indices) = primitive.indices() {
                check(
                    &indices,
                    "indices",
                    Dimensions::Scalar,
                    &[DataType::U8, DataType::U16, DataType::U32],
                )?;
            }
            let reader = primitive.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
            let positions: Vec<Vec3> = reader
                .read_positions()
                .ok_or(GltfTreeError::NoPositions {
                    mesh: mesh_name.clone(),
                })?
                .map(|p| world.transform_point3(Vec3::from(p)))
                .collect();
            let vertices = positions.len();
            let first = part.positions.len() as u32;
            match reader.read_normals().filter(|_| normals_valid) {
                Some(normals) => part.normals.extend(normals.map(|n| {
                    (normal_matrix * Vec3::from(n))
                        .try_normalize()
                        .unwrap_or(Vec3::Y)
                })),
                None => part.normals.extend(core::iter::repeat_n(Vec3::Y, vertices)),
            }
            match reader.read_indices() {
                Some(indices) => {
                    for i in indices.into_u32() {
                        if i as usize >= vertices {
                            return Err(GltfTreeError::IndexOutOfRange {
                                mesh: mesh_name,
                                value: i,
                                vertices,
                            });
                        }
                        part.indices.push(first + i);
                    }
                }
                None => part.indices.extend(first..first + vertices as u32),
            }
            // A textured material's factor only tints its texture (EZ-Tree's leaves are
            // white times a leaf picture), so it says nothing of the colour: such
            // primitives leave the part to the untextured ones or the default colour.
            // glTF keeps colours within 0–1; the `gltf` crate does not check.
            let pbr = primitive.material().pbr_metallic_roughness();
            if pbr.base_color_texture().is_none() {
                let [r, g, b, _] = pbr.base_color_factor().map(|c| {
                    if c.is_finite() {
                        c.clamp(0.0, 1.0)
                    } else {
                        1.0
                    }
                });
                part.color_sum += Vec3::new(r, g, b) * positions.len() as f32;
                part.color_weight += positions.len() as f32;
            }
            part.positions.extend(positions);
        }
    }
    if primitives == 0 {
        return Err(GltfTreeError::NoMeshes);
    }
    if trunk.indices.is_empty() {
        return Err(GltfTreeError::NoTrunk {
            keywords: settings.leaf_keywords.clone(),
        });
    }
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
    Ok(analyze(&trunk_data, &leaf_data, &settings.analysis)?)
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
