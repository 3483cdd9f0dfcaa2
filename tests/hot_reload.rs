//! Editing an ecosystem file while the app runs (Bevy's file watcher, `hot-reload`
//! feature): a valid edit respawns the forest, a malformed one leaves it standing.
//! `cargo test --features hot-reload --test hot_reload`
#![cfg(feature = "hot-reload")]

use std::time::{Duration, Instant};

use bevy::asset::{AssetLoadFailedEvent, AssetPlugin};
use bevy::prelude::*;
use bevy_sherwood::ecosystem::{Ecosystem, ForestState};
use bevy_sherwood::prelude::*;

const FOREST: &str = r#"(
    materials: { "bark": (), "leaf": (), "ground": () },
    species: [(tree: "small.species.ron", count: COUNT)],
    terrain: (size: 50.0, resolution: 9, degree: 1, control_heights: [[0.0, 0.0], [0.0, 0.0]]),
)"#;

fn run_until(app: &mut App, seconds: u64, done: impl Fn(&mut App) -> bool) -> bool {
    let start = Instant::now();
    while start.elapsed() < Duration::from_secs(seconds) {
        app.update();
        if done(app) {
            return true;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    false
}

/// Failed (re)loads of ecosystem files so far.
#[derive(Resource, Default)]
struct Failures(u32);

fn count_failures(
    mut failures: ResMut<Failures>,
    mut read: MessageReader<AssetLoadFailedEvent<Ecosystem>>,
) {
    failures.0 += read.read().count() as u32;
}

fn instances(app: &mut App) -> usize {
    app.world_mut()
        .query::<&TreeInstance>()
        .iter(app.world())
        .count()
}

#[test]
fn edits_respawn_and_malformed_edits_keep_the_forest() {
    let dir = std::env::temp_dir().join(format!("sherwood-reload-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let species = std::fs::read(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/assets/species/slender.species.ron"
    ))
    .unwrap();
    std::fs::write(dir.join("small.species.ron"), species).unwrap();
    let file = dir.join("test.ecosystem.ron");
    std::fs::write(&file, FOREST.replace("COUNT", "10")).unwrap();

    let mut app = App::new();
    app.add_plugins((
        MinimalPlugins,
        AssetPlugin {
            file_path: dir.to_string_lossy().into_owned(),
            watch_for_changes_override: Some(true),
            ..Default::default()
        },
        TransformPlugin,
        SherwoodPlugins,
    ))
    .init_resource::<Failures>()
    .add_systems(Update, count_failures);
    let handle = app
        .world()
        .resource::<AssetServer>()
        .load("test.ecosystem.ron");
    let forest = app.world_mut().spawn(Forest(handle)).id();
    assert!(run_until(&mut app, 20, |app| instances(app) == 10));

    std::fs::write(&file, FOREST.replace("COUNT", "25")).unwrap();
    assert!(
        run_until(&mut app, 20, |app| instances(app) == 25),
        "a valid edit respawns"
    );
    let generation = app.world().get::<ForestState>(forest).unwrap().generation;

    std::fs::write(&file, FOREST.replace("COUNT", "25,,")).unwrap();
    assert!(
        // (The watcher may report one write as two changes: two failed loads.)
        run_until(&mut app, 20, |app| app.world().resource::<Failures>().0
            >= 1),
        "the malformed edit is reported as a failed load"
    );
    // A forest respawned from it would be in place by now.
    for _ in 0..5 {
        app.update();
    }
    assert_eq!(
        instances(&mut app),
        25,
        "a malformed edit leaves the forest standing"
    );
    assert_eq!(
        app.world().get::<ForestState>(forest).unwrap().generation,
        generation
    );

    std::fs::write(&file, FOREST.replace("COUNT", "7")).unwrap();
    assert!(
        run_until(&mut app, 20, |app| instances(app) == 7),
        "and a fixed edit respawns again"
    );
    let _ = std::fs::remove_dir_all(dir);
}
