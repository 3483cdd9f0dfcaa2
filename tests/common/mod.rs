//! Helpers shared by the integration tests (each test binary uses what it needs).
#![allow(
    dead_code,
    reason = "each test binary includes this module and uses a different part of it"
)]

use bevy::asset::AssetPlugin;
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
