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

use super::analyze::{
    AnalysisOptions, AnalysisWarning, MeshData, TreeAnalysis, TreeAnalysisError, analyze,
};
use super::model::{Bounds, LinearRgb, TreeModel};

/// How a glTF file is split into trunk and leaves and analysed: the glTF tree loader's
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
/// or in code with `AssetServer::load_builder().with_settings(…)`. Fields left out keep their
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

/// One triangle primitive of the scene, in world space.
struct Primitive {
    /// Its mesh's name, for errors and warnings.
    mesh: String,
    /// Classified as leaves by [`GltfTreeSettings::leaf_keywords`].
    leaf: bool,
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    /// Into `positions`.
    indices: Vec<u32>,
    /// Its material's base colour when untextured.
    color: Option<Vec3>,
}

impl Primitive {
    fn bounds(&self) -> Bounds {
        Bounds::from_points(self.positions.iter().copied())
    }
}

/// A trunk or the leaves: the primitives classified so, merged.
#[derive(Default)]
struct Part {
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    indices: Vec<u32>,
    color_sum: Vec3,
    color_weight: f32,
}

impl Part {
    fn add(&mut self, primitive: &Primitive) {
        let first = self.positions.len() as u32;
        self.indices
            .extend(primitive.indices.iter().map(|i| first + i));
        self.positions.extend_from_slice(&primitive.positions);
        self.normals.extend_from_slice(&primitive.normals);
        if let Some(color) = primitive.color {
            let weight = primitive.positions.len() as f32;
            self.color_sum += color * weight;
            self.color_weight += weight;
        }
    }

    fn color(&self) -> Option<LinearRgb> {
        (self.color_weight > 0.0).then(|| (self.color_sum / self.color_weight).to_array())
    }

    fn mesh_data(&self) -> MeshData<'_> {
        MeshData {
            positions: &self.positions,
            normals: Some(&self.normals),
            indices: &self.indices,
            color: self.color(),
        }
    }
}

/// How flat a primitive must be to be taken for a ground plane: its height at most this
/// share of its width.
const GROUND_FLATNESS: f32 = 0.01;
/// How wide, as a share of the rest of the tree's height: a trunk's flat base cap is far
/// narrower.
const GROUND_MIN_WIDTH: f32 = 0.25;

/// Takes out the ground planes exported with a tree (a modelling tool's default scene
/// has one): trunk primitives that are flat and horizontal, lie at or below the foot of
/// the rest of the tree, and are wider than [`GROUND_MIN_WIDTH`] of its height. Analysed
/// as trunk, a plane would widen the tree's bounds to the plane's and make it a ring of
/// its own. Returns each plane's mesh name and width; nothing is taken when no other
/// trunk primitive would be left.
fn take_ground_planes(primitives: &mut Vec<Primitive>) -> Vec<(String, f32)> {
    // Per primitive: its bounds, its horizontal width, and whether it is a flat
    // non-leaf (a ground plane candidate).
    let shapes: Vec<(Bounds, f32, bool)> = primitives
        .iter()
        .map(|p| {
            let b = p.bounds();
            let size = b.max - b.min;
            let width = size.x.max(size.z);
            let flat = !p.leaf && width > 0.0 && size.y <= GROUND_FLATNESS * width;
            (b, width, flat)
        })
        .collect();
    let rest = shapes
        .iter()
        .filter(|s| !s.2)
        .fold(Bounds::EMPTY, |all, s| all.union(s.0));
    let other_trunk = primitives.iter().zip(&shapes).any(|(p, s)| !p.leaf && !s.2);
    let height = rest.max.y - rest.min.y;
    if !other_trunk || height.is_nan() || height <= 0.0 {
        return Vec::new();
    }
    let is_ground = |&(b, width, flat): &(Bounds, f32, bool)| {
        flat && b.max.y <= rest.min.y + 2.0 * GROUND_FLATNESS * height
            && width >= GROUND_MIN_WIDTH * height
    };
    let (ground, kept): (Vec<_>, Vec<_>) = core::mem::take(primitives)
        .into_iter()
        .zip(&shapes)
        .partition(|(_, shape)| is_ground(shape));
    *primitives = kept.into_iter().map(|(p, _)| p).collect();
    ground.into_iter().map(|(p, s)| (p.mesh, s.1)).collect()
}

/// An external buffer file a glTF document refers to.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BufferFile {
    /// The URI as the document writes it: the key of the buffer's bytes for
    /// [`import_gltf`].
    pub uri: String,
    /// The file to read, relative to the document's folder: the URI percent-decoded
    /// (`my%20tree.bin` is the file `my tree.bin`).
    pub path: String,
}

/// The external buffer files `bytes` refers to (not data URIs, not the GLB blob). A URI
/// that would read outside the file's folder (a `..` segment, an absolute path, a drive
/// or another scheme, percent-encoded or not) is refused: a tree file must not be able to
/// read the rest of the machine.
pub fn external_buffers(bytes: &[u8]) -> Result<Vec<BufferFile>, GltfTreeError> {
    let gltf = parse(bytes)?;
    let mut files = Vec::new();
    for buffer in gltf.buffers() {
        if let gltf::buffer::Source::Uri(uri) = buffer.source()
            && !uri.starts_with("data:")
        {
            let unsafe_uri = || GltfTreeError::UnsafeUri {
                uri: uri.to_owned(),
            };
            let path = percent_decoded(uri).ok_or_else(unsafe_uri)?;
            if !is_confined(&path) {
                return Err(unsafe_uri());
            }
            files.push(BufferFile {
                uri: uri.to_owned(),
                path,
            });
        }
    }
    Ok(files)
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

/// `uri` with its `%XX` escapes decoded, or `None` when that is not UTF-8.
fn percent_decoded(uri: &str) -> Option<String> {
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
    String::from_utf8(decoded).ok()
}

/// Whether a relative (decoded) path stays in its folder or below: no scheme or drive, no
/// root, no `..` segment.
fn is_confined(path: &str) -> bool {
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
/// bytes of the buffer files named by [`external_buffers`]. A ground plane exported
/// with the tree is left out with a warning ([`AnalysisWarning::GroundPlaneLeftOut`]).
pub fn import_gltf(
    bytes: &[u8],
    settings: &GltfTreeSettings,
    external: &HashMap<String, Vec<u8>>,
) -> Result<TreeAnalysis, GltfTreeError> {
    let gltf = parse(bytes)?;
    let buffers = read_buffers(&gltf, external)?;
    let mut primitives = scene_primitives(&gltf, &buffers, settings)?;
    if primitives.is_empty() {
        return Err(GltfTreeError::NoMeshes);
    }
    let ground_planes = take_ground_planes(&mut primitives);
    let (mut trunk, mut leaves) = (Part::default(), Part::default());
    for primitive in &primitives {
        if primitive.leaf {
            leaves.add(primitive);
        } else {
            trunk.add(primitive);
        }
    }
    if trunk.indices.is_empty() {
        return Err(GltfTreeError::NoTrunk {
            keywords: settings.leaf_keywords.clone(),
        });
    }
    let mut analysis = analyze(&trunk.mesh_data(), &leaves.mesh_data(), &settings.analysis)?;
    analysis.warnings.extend(
        ground_planes
            .into_iter()
            .map(|(mesh, width)| AnalysisWarning::GroundPlaneLeftOut { mesh, width }),
    );
    Ok(analysis)
}

/// The bytes of every buffer: the GLB blob, data URIs, or `external` files.
fn read_buffers(
    gltf: &gltf::Gltf,
    external: &HashMap<String, Vec<u8>>,
) -> Result<Vec<Vec<u8>>, GltfTreeError> {
    let mut buffers = Vec::new();
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
    Ok(buffers)
}

/// Every triangle primitive of the default scene (or the first, or every node when there
/// is no scene) not skipped by [`GltfTreeSettings::skip_keywords`], node transforms
/// applied, classified as trunk or leaves.
fn scene_primitives(
    gltf: &gltf::Gltf,
    buffers: &[Vec<u8>],
    settings: &GltfTreeSettings,
) -> Result<Vec<Primitive>, GltfTreeError> {
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
    let mut primitives = Vec::new();
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
        for primitive in mesh.primitives() {
            if matches(&skip_keywords, primitive.material().name()) {
                continue;
            }
            let mesh_name = mesh.name().unwrap_or("(unnamed)").to_string();
            let leaf = matches(&leaf_keywords, node.name())
                || matches(&leaf_keywords, mesh.name())
                || matches(&leaf_keywords, primitive.material().name());
            primitives.push(read_primitive(&primitive, buffers, world, mesh_name, leaf)?);
        }
    }
    Ok(primitives)
}

/// One primitive's triangles in world space, its accessors checked first.
fn read_primitive(
    primitive: &gltf::Primitive,
    buffers: &[Vec<u8>],
    world: Mat4,
    mesh: String,
    leaf: bool,
) -> Result<Primitive, GltfTreeError> {
    use gltf::accessor::{DataType, Dimensions};
    if primitive.mode() != gltf::mesh::Mode::Triangles {
        return Err(GltfTreeError::NotTriangles {
            mesh,
            mode: primitive.mode(),
        });
    }
    let Some(position_accessor) = primitive.get(&gltf::Semantic::Positions) else {
        return Err(GltfTreeError::NoPositions { mesh });
    };
    let check = |accessor: &gltf::Accessor, attribute, dimensions, types: &[DataType]| {
        check_accessor(accessor, buffers, &mesh, attribute, dimensions, types)
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
    let Some(positions) = reader.read_positions() else {
        return Err(GltfTreeError::NoPositions { mesh });
    };
    let positions: Vec<Vec3> = positions
        .map(|p| world.transform_point3(Vec3::from(p)))
        .collect();
    let vertices = positions.len();
    let normal_matrix = Mat3::from_mat4(world).inverse().transpose();
    let normals = match reader.read_normals().filter(|_| normals_valid) {
        Some(normals) => normals
            .map(|n| {
                (normal_matrix * Vec3::from(n))
                    .try_normalize()
                    .unwrap_or(Vec3::Y)
            })
            .collect(),
        None => vec![Vec3::Y; vertices],
    };
    let indices = match reader.read_indices() {
        Some(indices) => {
            let indices: Vec<u32> = indices.into_u32().collect();
            if let Some(&value) = indices.iter().find(|&&i| i as usize >= vertices) {
                return Err(GltfTreeError::IndexOutOfRange {
                    mesh,
                    value,
                    vertices,
                });
            }
            indices
        }
        None => (0..vertices as u32).collect(),
    };
    // A textured material's factor only tints its texture (EZ-Tree's leaves are white
    // times a leaf picture), so it says nothing of the colour: such primitives leave the
    // part to the untextured ones or the default colour. glTF keeps colours within 0–1;
    // the `gltf` crate does not check.
    let pbr = primitive.material().pbr_metallic_roughness();
    let color = pbr.base_color_texture().is_none().then(|| {
        let [r, g, b, _] = pbr.base_color_factor().map(|c| {
            if c.is_finite() {
                c.clamp(0.0, 1.0)
            } else {
                1.0
            }
        });
        Vec3::new(r, g, b)
    });
    Ok(Primitive {
        mesh,
        leaf,
        positions,
        normals,
        indices,
        color,
    })
}

/// Loads `*.tree.glb` and `*.tree.gltf` files as [`TreeModel`]s.
#[derive(Default, TypePath)]
pub(crate) struct GltfTreeLoader;

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
        for file in external_buffers(&bytes)? {
            let path = load_context
                .path()
                .resolve_embed_str(&file.path)
                .map_err(|e| GltfTreeError::Io(e.to_string()))?;
            let data = load_context
                .read_asset_bytes(path)
                .await
                .map_err(|e| GltfTreeError::Io(e.to_string()))?;
            external.insert(file.uri, data);
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
