//! Helpers shared by the integration tests (each test binary uses what it needs).
#![allow(
    dead_code,
    reason = "each test binary includes this module and uses a different part of it"
)]

use bevy::asset::{AssetPlugin, LoadState};
use bevy::prelude::*;
use bevy_sherwood::prelude::*;

/// A shipped species (`assets/species/NAME.species.ron`), generated and analysed.
pub fn species(name: &str) -> TreeModel {
    let path = format!(
        "{}/assets/species/{name}.species.ron",
        env!("CARGO_MANIFEST_DIR")
    );
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    SpeciesDesc::from_ron_str(&text)
        .unwrap()
        .generate_and_analyze()
        .unwrap()
        .model
}

/// A headless app with every Sherwood plugin, reading the crate's assets.
pub fn headless_app() -> App {
    let mut app = App::new();
    app.add_plugins((
        MinimalPlugins,
        AssetPlugin {
            file_path: concat!(env!("CARGO_MANIFEST_DIR"), "/assets").into(),
            ..Default::default()
        },
        TransformPlugin,
        SherwoodPlugins,
    ));
    app
}

/// A headless app that loads tree models from `dir`.
pub fn tree_app(dir: &std::path::Path) -> App {
    let mut app = App::new();
    app.add_plugins((
        MinimalPlugins,
        AssetPlugin {
            file_path: dir.to_string_lossy().into_owned(),
            ..Default::default()
        },
        TreePlugin,
    ));
    app
}

/// Updates until the asset has loaded or failed (bounded).
pub fn settle(app: &mut App, handle: &Handle<TreeModel>) -> LoadState {
    for _ in 0..2000 {
        app.update();
        let state = app
            .world()
            .resource::<AssetServer>()
            .load_state(handle.id());
        if matches!(state, LoadState::Loaded | LoadState::Failed(_)) {
            return state;
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    panic!("asset neither loaded nor failed");
}
