//! Tree assets: species descriptions generated and analysed at load time
//! (`*.species.ron`), and analysed models saved to disk so large trees are analysed once
//! (`*.tree.ron`, readable, or `*.tree.bin`, compact and fast).

use bevy::app::{App, Plugin, PostUpdate};
use bevy::asset::AssetEvent;
use bevy::asset::io::Reader;
use bevy::asset::{AssetApp, AssetId, AssetLoader, Assets, LoadContext};
use bevy::ecs::message::MessageReader;
use bevy::ecs::prelude::{IntoScheduleConfigs, ResMut, Resource};
use bevy::log::warn;
use bevy::platform::collections::HashMap;
use bevy::reflect::TypePath;

use super::NO_RING;
use super::model::TreeModel;
use super::species::{SpeciesDesc, SpeciesError};

/// First bytes of a `*.tree.bin` file.
pub(crate) const BINARY_MAGIC: &[u8; 8] = b"SHWDTREE";
/// Version of the binary layout; files of another version are refused with a clear error.
pub(crate) const BINARY_VERSION: u32 = 2;

/// Why a tree file could not be loaded.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum TreeFileError {
    /// Reading failed.
    #[error("could not read the file: {0}")]
    Io(#[from] std::io::Error),
    /// The text is not UTF-8.
    #[error("the file is not UTF-8 text: {0}")]
    Utf8(#[from] core::str::Utf8Error),
    /// A species description is malformed or out of range.
    #[error("{0}")]
    Species(#[from] SpeciesError),
    /// A saved model's RON does not parse (the message names line, column and field).
    #[error("{0}")]
    Ron(#[from] ron::error::SpannedError),
    /// A saved binary model is not one, or of another version.
    #[error("not a bevy_sherwood tree file of version {BINARY_VERSION}: {0}")]
    Header(String),
    /// A saved binary model does not decode.
    #[error("the binary model does not decode: {0}")]
    Binary(#[from] postcard::Error),
    /// A saved model decodes but is inconsistent.
    #[error("inconsistent model: {field}: {detail}")]
    Inconsistent {
        /// The field at fault.
        field: &'static str,
        /// What is wrong.
        detail: String,
    },
}

fn inconsistent(field: &'static str, detail: impl Into<String>) -> TreeFileError {
    TreeFileError::Inconsistent {
        field,
        detail: detail.into(),
    }
}

/// An error naming `field` when one of `values` is not below `len`.
fn check_in_range(field: &'static str, values: &[u32], len: usize) -> Result<(), TreeFileError> {
    match values.iter().find(|&&v| v as usize >= len) {
        Some(v) => Err(inconsistent(
            field,
            format!("index {v} is out of range (length {len})"),
        )),
        None => Ok(()),
    }
}

/// An error naming `field` when one of `values` is not finite.
fn check_finite(field: &'static str, values: &[bevy::math::Vec3]) -> Result<(), TreeFileError> {
    match values.iter().position(|v| !v.is_finite()) {
        Some(i) => Err(inconsistent(field, format!("element {i} is not finite"))),
        None => Ok(()),
    }
}

/// Not a finite, non-negative number.
fn is_bad_number(x: &f32) -> bool {
    !x.is_finite() || *x < 0.0
}

impl TreeModel {
    /// Checks that every index and range points inside its array and every number is
    /// finite, so that a hand-edited or corrupted file cannot make the renderer or the
    /// LOD read out of bounds later.
    pub fn validate(&self) -> Result<(), TreeFileError> {
        self.validate_vertices()?;
        self.validate_rings()?;
        self.validate_segments()?;
        self.validate_scalars()?;
        self.validate_leaves()
    }

    /// The vertex and index arrays: finite, parallel, in range.
    fn validate_vertices(&self) -> Result<(), TreeFileError> {
        let rings = self.rings.len();
        let trunk_vertices = self.trunk_positions.len();
        let leaf_vertices = self.leaf_positions.len();
        check_finite("trunk_positions", &self.trunk_positions)?;
        check_finite("trunk_normals", &self.trunk_normals)?;
        check_finite("leaf_positions", &self.leaf_positions)?;
        check_finite("leaf_normals", &self.leaf_normals)?;
        check_finite("ring_vectors", &self.ring_vectors)?;
        if self.trunk_normals.len() != trunk_vertices
            || self.trunk_vertex_ring.len() != trunk_vertices
        {
            return Err(inconsistent(
                "trunk_normals",
                "trunk vertex arrays differ in length",
            ));
        }
        if self.leaf_normals.len() != leaf_vertices || self.leaf_vertex_leaf.len() != leaf_vertices
        {
            return Err(inconsistent(
                "leaf_normals",
                "leaf vertex arrays differ in length",
            ));
        }
        if self.ring_vectors.len() != self.ring_vertices.len() {
            return Err(inconsistent("ring_vectors", "must parallel ring_vertices"));
        }
        if !self.trunk_indices.len().is_multiple_of(3) || !self.leaf_indices.len().is_multiple_of(3)
        {
            return Err(inconsistent(
                "trunk_indices",
                "index counts must be multiples of 3",
            ));
        }
        check_in_range("trunk_indices", &self.trunk_indices, trunk_vertices)?;
        check_in_range("leaf_indices", &self.leaf_indices, leaf_vertices)?;
        check_in_range("ring_vertices", &self.ring_vertices, trunk_vertices)?;
        check_in_range("trunk_vertex_ring", &self.trunk_vertex_ring, rings)?;
        check_in_range(
            "leaf_vertex_leaf",
            &self.leaf_vertex_leaf,
            self.leaves.len().max(1),
        )?;
        Ok(())
    }

    /// The rings: each after its parent, pointing inside the model.
    fn validate_rings(&self) -> Result<(), TreeFileError> {
        let rings = self.rings.len();
        for (i, r) in self.rings.iter().enumerate() {
            // Parents come first: the wind walks rings in order, each after its parent, and
            // this also rules out cycles.
            if r.parent != NO_RING && r.parent as usize >= i {
                return Err(inconsistent(
                    "rings",
                    format!("ring {i} comes before its parent {}", r.parent),
                ));
            }
            if (r.parent != NO_RING && r.parent as usize >= rings)
                || r.children.iter().any(|&c| c as usize >= rings)
                || r.vertices.start > r.vertices.end
                || r.vertices.end as usize > self.ring_vertices.len()
                || r.leaf_group
                    .is_some_and(|g| g as usize >= self.leaf_groups.len())
                || !r.center.is_finite()
                || !r.diameter.is_finite()
            {
                return Err(inconsistent(
                    "rings",
                    format!("ring {i} points outside the model"),
                ));
            }
        }
        Ok(())
    }

    /// The trunk's segments: parallel, finite, sorted thin → thick, tiling the triangles.
    fn validate_segments(&self) -> Result<(), TreeFileError> {
        let rings = self.rings.len();
        let s = &self.segments;
        let n = s.ring.len();
        if s.triangle_offsets.len() != n + 1
            || s.line.len() != n
            || s.diameter.len() != n
            || s.cumulative_length.len() != n
        {
            return Err(inconsistent("segments", "parallel arrays differ in length"));
        }
        check_in_range("segments.ring", &s.ring, rings)?;
        if let Some(i) = s
            .line
            .iter()
            .position(|l| !l[0].is_finite() || !l[1].is_finite())
        {
            return Err(inconsistent(
                "segments.line",
                format!("segment {i} is not finite"),
            ));
        }
        if let Some(i) = s.diameter.iter().position(is_bad_number) {
            return Err(inconsistent(
                "segments.diameter",
                format!("segment {i} is negative or not finite"),
            ));
        }
        if s.diameter.windows(2).any(|w| w[0] > w[1]) {
            return Err(inconsistent(
                "segments.diameter",
                "segments must be sorted thin → thick",
            ));
        }
        if s.cumulative_length.iter().any(is_bad_number)
            || s.cumulative_length.windows(2).any(|w| w[0] > w[1])
        {
            return Err(inconsistent(
                "segments.cumulative_length",
                "must be finite and never fall",
            ));
        }
        if s.triangle_offsets.windows(2).any(|w| w[0] > w[1])
            || s.triangle_offsets.first().is_some_and(|&o| o != 0)
            || s.triangle_offsets
                .last()
                .is_some_and(|&o| o as usize * 3 != self.trunk_indices.len())
        {
            return Err(inconsistent(
                "segments.triangle_offsets",
                "must rise from 0 to the trunk's triangle count",
            ));
        }
        Ok(())
    }

    /// The bounds, areas and colours.
    fn validate_scalars(&self) -> Result<(), TreeFileError> {
        for (field, bounds) in [
            ("bounds", &self.bounds),
            ("trunk_bounds", &self.trunk_bounds),
        ] {
            if !bounds.min.is_finite()
                || !bounds.max.is_finite()
                || bounds.min.cmpgt(bounds.max).any()
            {
                return Err(inconsistent(field, "must be a finite box, min ≤ max"));
            }
        }
        for (field, value) in [
            ("mean_leaf_triangle_area", self.mean_leaf_triangle_area),
            ("mean_trunk_triangle_area", self.mean_trunk_triangle_area),
        ] {
            if is_bad_number(&value) {
                return Err(inconsistent(field, "must be finite and not negative"));
            }
        }
        if !self.trunk_area_center.is_finite() {
            return Err(inconsistent("trunk_area_center", "must be finite"));
        }
        for (field, color) in [
            ("bark_color", self.bark_color),
            ("leaf_color", self.leaf_color),
        ] {
            if color.iter().any(is_bad_number) {
                return Err(inconsistent(field, "must be finite and not negative"));
            }
        }
        if let Some(crown) = &self.crown {
            if !crown.center.is_finite() || !crown.normal.is_finite() || is_bad_number(&crown.area)
            {
                return Err(inconsistent(
                    "crown",
                    "must be finite, its area not negative",
                ));
            }
            if crown.ring as usize >= self.rings.len() {
                return Err(inconsistent("crown", "ring out of range"));
            }
        }
        Ok(())
    }

    /// The leaves and their groups, which tile them in order.
    fn validate_leaves(&self) -> Result<(), TreeFileError> {
        let rings = self.rings.len();
        let leaf_triangles = (self.leaf_indices.len() / 3) as u32;
        for (i, leaf) in self.leaves.iter().enumerate() {
            if leaf.triangles.start > leaf.triangles.end
                || leaf.triangles.end > leaf_triangles
                || leaf.group as usize >= self.leaf_groups.len()
                || !leaf.center.is_finite()
                || !leaf.normal.is_finite()
            {
                return Err(inconsistent(
                    "leaves",
                    format!("leaf {i} points outside leaf_indices"),
                ));
            }
        }
        for (i, g) in self.leaf_groups.iter().enumerate() {
            if g.ring as usize >= rings
                || g.leaves.start > g.leaves.end
                || g.leaves.end as usize > self.leaves.len()
                || !g.bounds.center.is_finite()
                || is_bad_number(&g.bounds.radius)
            {
                return Err(inconsistent(
                    "leaf_groups",
                    format!("group {i} points outside the model"),
                ));
            }
        }
        // The groups tile the leaves in order: the far-first order and the LOD's group
        // ranges rely on it.
        let mut next = 0;
        for (i, g) in self.leaf_groups.iter().enumerate() {
            if g.leaves.is_empty() {
                return Err(inconsistent(
                    "leaf_groups",
                    format!("group {i} has no leaves"),
                ));
            }
            if g.leaves.start != next {
                return Err(inconsistent(
                    "leaf_groups",
                    format!("group {i} does not start where the previous group ends"),
                ));
            }
            next = g.leaves.end;
        }
        if next as usize != self.leaves.len() {
            return Err(inconsistent(
                "leaf_groups",
                "the groups must cover every leaf",
            ));
        }
        Ok(())
    }

    /// The model as RON text (readable, diffable; slower to load than binary).
    pub fn to_ron_string(&self) -> Result<String, ron::Error> {
        ron::ser::to_string_pretty(self, ron::ser::PrettyConfig::default().compact_arrays(true))
    }

    /// Parses and validates a model saved with [`TreeModel::to_ron_string`].
    pub fn from_ron_str(text: &str) -> Result<Self, TreeFileError> {
        let model: Self = crate::ron_file::ron_options().from_str(text)?;
        model.validate()?;
        Ok(model)
    }

    /// The model in the compact binary format of `*.tree.bin`.
    pub fn to_binary(&self) -> Result<Vec<u8>, postcard::Error> {
        let mut out = Vec::with_capacity(BINARY_MAGIC.len() + 4);
        out.extend_from_slice(BINARY_MAGIC);
        out.extend_from_slice(&BINARY_VERSION.to_le_bytes());
        postcard::to_extend(self, out)
    }

    /// Decodes and validates a model saved with [`TreeModel::to_binary`].
    pub fn from_binary(bytes: &[u8]) -> Result<Self, TreeFileError> {
        let header = BINARY_MAGIC.len() + 4;
        if bytes.len() < header || &bytes[..BINARY_MAGIC.len()] != BINARY_MAGIC {
            return Err(TreeFileError::Header("missing magic bytes".into()));
        }
        let version = u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]);
        if version != BINARY_VERSION {
            return Err(TreeFileError::Header(format!("file is version {version}")));
        }
        let (model, rest): (Self, _) = postcard::take_from_bytes(&bytes[header..])?;
        if !rest.is_empty() {
            return Err(TreeFileError::Header(format!(
                "{} bytes after the model: the file is damaged or not one model",
                rest.len()
            )));
        }
        model.validate()?;
        Ok(model)
    }
}

/// Loads `*.species.ron`: generates the species' meshes and analyses them into a
/// [`TreeModel`].
#[derive(Default, TypePath)]
pub(crate) struct SpeciesLoader;

impl AssetLoader for SpeciesLoader {
    type Asset = TreeModel;
    type Settings = ();
    type Error = TreeFileError;

    async fn load(
        &self,
        reader: &mut dyn Reader,
        _settings: &(),
        load_context: &mut LoadContext<'_>,
    ) -> Result<TreeModel, TreeFileError> {
        let text: String = crate::ron_file::read_text::<TreeFileError>(reader).await?;
        let species = SpeciesDesc::from_ron_str(&text)?;
        let analysis = species.generate_and_analyze()?;
        for warning in &analysis.warnings {
            warn!("{}: {warning:?}", load_context.path());
        }
        Ok(analysis.model)
    }

    fn extensions(&self) -> &[&str] {
        &["species.ron"]
    }
}

/// Loads analysed models saved with [`TreeModel::to_ron_string`] (`*.tree.ron`) or
/// [`TreeModel::to_binary`] (`*.tree.bin`).
#[derive(Default, TypePath)]
pub(crate) struct TreeModelLoader;

impl AssetLoader for TreeModelLoader {
    type Asset = TreeModel;
    type Settings = ();
    type Error = TreeFileError;

    async fn load(
        &self,
        reader: &mut dyn Reader,
        _settings: &(),
        load_context: &mut LoadContext<'_>,
    ) -> Result<TreeModel, TreeFileError> {
        let mut bytes = Vec::new();
        reader.read_to_end(&mut bytes).await?;
        // By the file's extension, so that a damaged binary file says what is wrong
        // with it rather than that it is not text.
        let binary = load_context
            .path()
            .path()
            .to_string_lossy()
            .ends_with(".tree.bin");
        if binary || bytes.starts_with(BINARY_MAGIC) {
            TreeModel::from_binary(&bytes)
        } else {
            TreeModel::from_ron_str(core::str::from_utf8(&bytes)?)
        }
    }

    fn extensions(&self) -> &[&str] {
        &["tree.ron", "tree.bin"]
    }
}

/// Registers [`TreeModel`] assets and their loaders.
#[derive(Default)]
pub struct TreePlugin;

/// Which tree models changed, so that whatever is derived from them (packed geometry,
/// object-type ranks) follows: `any` is bumped whenever a model is added, changed or
/// removed, `edited` only when one is changed in place. What is derived model by model
/// can then append the models added and pass over those removed (group impostors are
/// published and released a few at a time, to thousands of models), and derive
/// everything anew only when `edited` moved.
#[derive(Resource, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct TreeModelsVersion {
    /// Bumped when a model is added, changed or removed.
    pub(crate) any: u64,
    /// Bumped when a model is changed in place.
    pub(crate) edited: u64,
}

fn bump_models_version(
    mut events: MessageReader<AssetEvent<TreeModel>>,
    mut version: ResMut<TreeModelsVersion>,
) {
    let (mut any, mut edited) = (false, false);
    for event in events.read() {
        any |= !matches!(event, AssetEvent::Unused { .. });
        edited |= matches!(event, AssetEvent::Modified { .. });
    }
    if any {
        version.any += 1;
    }
    if edited {
        version.edited += 1;
    }
}

/// Keeps what is derived from the tree models one by one (packed geometry, per-model
/// infos) in step with them, as [`TreeModelsVersion`] tells their changes: every model
/// gets an index in the order it came, and what is derived from it is appended at that
/// index. A model removed keeps its index, unused, until the removed are as many as the
/// rest; then, or when a model changed in place, everything is derived anew.
#[derive(Default)]
pub(crate) struct FollowedModels {
    /// The versions followed.
    any: Option<u64>,
    edited: Option<u64>,
    /// Each model's index.
    index: HashMap<AssetId<TreeModel>, u32>,
    /// Indices handed out since everything was last derived anew (the removed' included).
    next: u32,
    /// How many times everything was derived anew.
    generation: u64,
}

impl FollowedModels {
    /// Brings the indices up to `models` at `version`: `None` when nothing changed;
    /// otherwise the change, whose [`added`](ModelsChange::added) models are to be derived
    /// and appended, in order, after what was derived before (or, when it is
    /// [`anew`](ModelsChange::anew), after nothing).
    pub(crate) fn follow<'a>(
        &'a mut self,
        models: &'a Assets<TreeModel>,
        version: TreeModelsVersion,
    ) -> Option<ModelsChange<'a>> {
        if self.any == Some(version.any) {
            return None;
        }
        self.any = Some(version.any);
        self.index.retain(|&id, _| models.contains(id));
        let removed = self.next as usize - self.index.len();
        let anew = self.edited != Some(version.edited) || removed > self.index.len();
        if anew {
            self.edited = Some(version.edited);
            self.index.clear();
            self.next = 0;
            self.generation += 1;
        }
        Some(ModelsChange {
            followed: self,
            models,
            anew,
        })
    }

    /// Model `id`'s index, if it is loaded.
    pub(crate) fn index(&self, id: AssetId<TreeModel>) -> Option<u32> {
        self.index.get(&id).copied()
    }

    /// How many models are loaded.
    #[cfg(test)]
    pub(crate) fn len(&self) -> usize {
        self.index.len()
    }

    /// How many times everything was derived anew: the indices handed out before are
    /// void.
    pub(crate) fn generation(&self) -> u64 {
        self.generation
    }
}

/// A change of the models [`FollowedModels::follow`] found.
pub(crate) struct ModelsChange<'a> {
    followed: &'a mut FollowedModels,
    models: &'a Assets<TreeModel>,
    /// Everything is to be derived anew: what was derived before is void.
    pub(crate) anew: bool,
}

impl<'a> ModelsChange<'a> {
    /// The models without an index yet (every model, when [`anew`](Self::anew)), each
    /// given the next index as it is yielded.
    pub(crate) fn added(self) -> impl Iterator<Item = (AssetId<TreeModel>, &'a TreeModel)> {
        let Self {
            followed, models, ..
        } = self;
        models.iter().filter(move |&(id, _)| {
            let new = !followed.index.contains_key(&id);
            if new {
                followed.index.insert(id, followed.next);
                followed.next += 1;
            }
            new
        })
    }
}

impl Plugin for TreePlugin {
    fn build(&self, app: &mut App) {
        crate::schedule::require_plugin::<bevy::asset::AssetPlugin>(
            app,
            "TreePlugin",
            "Bevy's AssetPlugin",
        );
        app.init_asset::<TreeModel>()
            .init_resource::<TreeModelsVersion>()
            .add_systems(
                PostUpdate,
                bump_models_version.before(crate::schedule::SherwoodSystems::Instances),
            )
            .register_asset_loader(SpeciesLoader)
            .register_asset_loader(TreeModelLoader);
        #[cfg(feature = "gltf")]
        app.register_asset_loader(super::GltfTreeLoader);
    }
}
