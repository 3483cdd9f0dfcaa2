//! Calibrations as assets: `*.calibration.ron` files load through Bevy's asset server
//! (any asset source: the app's folder, `embedded://`, the web), and the calibrations an
//! app ships are listed in an index, `calibration/index.calibrations.ron`, because
//! directories cannot be listed everywhere (the web, Android). The calibrations this
//! crate ships are embedded in it, so an app whose asset folder has none still finds them.

use bevy::asset::io::Reader;
use bevy::asset::io::embedded::EmbeddedAssetRegistry;
use bevy::asset::{AssetLoader, AssetPath, LoadContext, LoadState};
use bevy::prelude::*;
use bevy::tasks::{IoTaskPool, Task, block_on, futures_lite::future};
use serde::Deserialize;

use super::calibration::{AdapterIdentity, Calibration, CalibrationError};
use crate::ron_file::read_text;

/// The index of an app's own calibrations, in its default asset source.
pub(crate) const APP_INDEX: &str = "calibration/index.calibrations.ron";
/// The index of the calibrations this crate ships, embedded in it.
pub(crate) const SHIPPED_INDEX: &str =
    "embedded://bevy_sherwood/calibration/index.calibrations.ron";

/// The shipped index and the files it lists, as embedded.
const SHIPPED: [(&str, &[u8]); 2] = [
    (
        "index.calibrations.ron",
        include_bytes!("../../assets/calibration/index.calibrations.ron"),
    ),
    (
        "llvmpipe-llvm-15-0-6-256-bits.calibration.ron",
        include_bytes!("../../assets/calibration/llvmpipe-llvm-15-0-6-256-bits.calibration.ron"),
    ),
];

/// A list of `*.calibration.ron` files, as paths relative to the index (a RON list of
/// strings): what [`CalibrationChoice::Adapter`](super::CalibrationChoice::Adapter) looks
/// through.
#[derive(Asset, TypePath, Clone, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(transparent)]
pub(crate) struct CalibrationIndex(pub Vec<String>);

/// Loads `*.calibration.ron` as a [`Calibration`].
#[derive(Default, TypePath)]
pub(crate) struct CalibrationLoader;

impl AssetLoader for CalibrationLoader {
    type Asset = Calibration;
    type Settings = ();
    type Error = CalibrationError;

    async fn load(
        &self,
        reader: &mut dyn Reader,
        _settings: &(),
        _context: &mut LoadContext<'_>,
    ) -> Result<Calibration, CalibrationError> {
        Calibration::from_ron_str(&read_text::<CalibrationError>(reader).await?)
    }

    fn extensions(&self) -> &[&str] {
        &["calibration.ron"]
    }
}

/// Loads `*.calibrations.ron` as a [`CalibrationIndex`].
#[derive(Default, TypePath)]
pub(crate) struct CalibrationIndexLoader;

impl AssetLoader for CalibrationIndexLoader {
    type Asset = CalibrationIndex;
    type Settings = ();
    type Error = CalibrationError;

    async fn load(
        &self,
        reader: &mut dyn Reader,
        _settings: &(),
        _context: &mut LoadContext<'_>,
    ) -> Result<CalibrationIndex, CalibrationError> {
        let text = read_text::<CalibrationError>(reader).await?;
        Ok(crate::ron_file::ron_options().from_str(&text)?)
    }

    fn extensions(&self) -> &[&str] {
        &["calibrations.ron"]
    }
}

/// Registers the loaders and embeds the shipped calibrations (needs `AssetPlugin`).
pub(crate) fn register(app: &mut App) {
    app.init_asset::<Calibration>()
        .init_asset::<CalibrationIndex>()
        .register_asset_loader(CalibrationLoader)
        .register_asset_loader(CalibrationIndexLoader);
    let registry = app.world().resource::<EmbeddedAssetRegistry>();
    for (name, bytes) in SHIPPED {
        let path = std::path::Path::new("bevy_sherwood/calibration").join(name);
        registry.insert_asset(path.clone(), &path, bytes);
    }
}

/// The calibration of `candidates` measured on `adapter`: the first naming the same
/// adapter and driver, else the first naming the same adapter.
pub(crate) fn choose_calibration<'a>(
    candidates: impl IntoIterator<Item = &'a Calibration>,
    adapter: &AdapterIdentity,
) -> Option<&'a Calibration> {
    let mut same_adapter = None;
    for c in candidates {
        if c.adapter == adapter.name && c.driver == adapter.driver {
            return Some(c);
        }
        if c.adapter == adapter.name {
            same_adapter.get_or_insert(c);
        }
    }
    same_adapter
}

/// A search for a calibration under way, one step a frame.
#[derive(Default)]
pub(crate) enum CalibrationLookup {
    /// Nothing to look for.
    #[default]
    Idle,
    /// One file, as [`CalibrationChoice::File`](super::CalibrationChoice::File) names it.
    File(Handle<Calibration>),
    /// Whether the app has an index of its own (a missing one is no error), with the
    /// shipped index loading meanwhile.
    Probing(
        Task<Option<Handle<CalibrationIndex>>>,
        Handle<CalibrationIndex>,
    ),
    /// The indexes, the app's first.
    Indexes(Vec<Handle<CalibrationIndex>>),
    /// The files they list, in order.
    Files(Vec<Handle<Calibration>>),
}

/// What a step of the lookup came to.
pub(crate) enum LookupStep {
    /// Still loading.
    Pending,
    /// Done: the calibration found, if any (`None`: no index listed one for the adapter,
    /// or the file failed).
    Done(Option<Calibration>),
}

impl CalibrationLookup {
    /// Starts looking for the file at asset path `path`.
    pub(crate) fn file(server: &AssetServer, path: &str) -> Self {
        Self::File(server.load(path.to_owned()))
    }

    /// Starts looking through the app's index (if it has one) and the shipped one.
    pub(crate) fn adapter(server: &AssetServer) -> Self {
        let probe = server.clone();
        let task = IoTaskPool::get().spawn(async move {
            // Loaded quietly: an app without calibrations of its own is no error.
            let handle = probe
                .load_builder()
                .load_untyped_async(APP_INDEX)
                .await
                .ok()?;
            handle.try_typed::<CalibrationIndex>().ok()
        });
        Self::Probing(task, server.load(SHIPPED_INDEX))
    }

    /// Takes the lookup one step on.
    pub(crate) fn step(
        &mut self,
        server: &AssetServer,
        calibrations: &Assets<Calibration>,
        indexes: &Assets<CalibrationIndex>,
        adapter: &AdapterIdentity,
    ) -> LookupStep {
        match self {
            Self::Idle => LookupStep::Done(None),
            Self::File(handle) => match server.load_state(handle.id()) {
                LoadState::Loaded => LookupStep::Done(calibrations.get(handle.id()).cloned()),
                LoadState::Failed(_) => LookupStep::Done(None),
                _ => LookupStep::Pending,
            },
            Self::Probing(task, shipped) => {
                let Some(app_index) = block_on(future::poll_once(task)) else {
                    return LookupStep::Pending;
                };
                *self = Self::Indexes(app_index.into_iter().chain([shipped.clone()]).collect());
                LookupStep::Pending
            }
            Self::Indexes(handles) => {
                if handles.iter().any(|h| is_loading(server, h.id())) {
                    return LookupStep::Pending;
                }
                let files = handles
                    .iter()
                    .filter_map(|h| Some((server.get_path(h.id())?, indexes.get(h.id())?)))
                    .flat_map(|(path, index)| {
                        index
                            .0
                            .iter()
                            .filter_map(move |name| path.resolve_embed_str(name).ok())
                            .collect::<Vec<AssetPath>>()
                    })
                    .map(|path| server.load::<Calibration>(path))
                    .collect();
                *self = Self::Files(files);
                LookupStep::Pending
            }
            Self::Files(handles) => {
                if handles.iter().any(|h| is_loading(server, h.id())) {
                    return LookupStep::Pending;
                }
                let loaded = handles.iter().filter_map(|h| calibrations.get(h.id()));
                LookupStep::Done(choose_calibration(loaded, adapter).cloned())
            }
        }
    }
}

fn is_loading(server: &AssetServer, id: impl Into<bevy::asset::UntypedAssetId>) -> bool {
    !matches!(
        server.load_state(id),
        LoadState::Loaded | LoadState::Failed(_)
    )
}

/// Adds `file_name` to the index in `dir` (`index.calibrations.ron`), creating it: what a
/// calibration run does after writing a calibration there, so that
/// [`CalibrationChoice::Adapter`](super::CalibrationChoice::Adapter) finds it.
#[cfg(any(test, feature = "render"))]
pub(crate) fn add_to_index(dir: &std::path::Path, file_name: &str) -> Result<(), String> {
    let path = dir.join("index.calibrations.ron");
    let mut index = match std::fs::read_to_string(&path) {
        Ok(text) => crate::ron_file::ron_options()
            .from_str::<Vec<String>>(&text)
            .map_err(|e| format!("{}: {e}", path.display()))?,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Vec::new(),
        Err(e) => return Err(format!("{}: {e}", path.display())),
    };
    if index.iter().any(|name| name == file_name) {
        return Ok(());
    }
    index.push(file_name.to_owned());
    let text = ron::ser::to_string_pretty(&index, ron::ser::PrettyConfig::default())
        .map_err(|e| e.to_string())?;
    std::fs::write(&path, text + "\n").map_err(|e| format!("{}: {e}", path.display()))
}
