//! Tree assets: loading species and saved models through Bevy's asset server, and the
//! saved formats' round trips and errors.

use bevy_sherwood::testing as common;

use std::path::PathBuf;

use bevy::asset::LoadState;
use bevy::prelude::*;
use bevy_sherwood::tree::*;

fn slender() -> TreeModel {
    common::species("slender")
}

/// A scratch asset folder holding `files`.
fn asset_dir(name: &str, files: &[(&str, &[u8])]) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("sherwood-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    for (file, bytes) in files {
        let path = dir.join(file);
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(path, bytes).unwrap();
    }
    dir
}

#[test]
fn species_saved_and_broken_files_load_through_the_asset_server() {
    let model = slender();
    let species = std::fs::read(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/assets/species/slender.species.ron"
    ))
    .unwrap();
    let ron = model.to_ron_string().unwrap();
    let bin = model.to_binary().unwrap();
    let dir = asset_dir(
        "load",
        &[
            ("slender.species.ron", &species),
            ("slender.tree.ron", ron.as_bytes()),
            ("slender.tree.bin", &bin),
            (
                "broken.species.ron",
                b"(levels: [(length: 2.0, segmnts: 3)])",
            ),
        ],
    );
    let mut app = common::tree_app(&dir);
    let server = app.world().resource::<AssetServer>().clone();
    let handles = [
        server.load::<TreeModel>("slender.species.ron"),
        server.load::<TreeModel>("slender.tree.ron"),
        server.load::<TreeModel>("slender.tree.bin"),
    ];
    for handle in &handles {
        assert!(matches!(
            common::settle(&mut app, handle),
            LoadState::Loaded
        ));
        let loaded = app
            .world()
            .resource::<Assets<TreeModel>>()
            .get(handle)
            .unwrap();
        assert_eq!(loaded, &model);
    }
    let broken = server.load::<TreeModel>("broken.species.ron");
    let LoadState::Failed(error) = common::settle(&mut app, &broken) else {
        panic!("a malformed species file must fail to load");
    };
    let message = error.to_string();
    assert!(
        message.contains("broken.species.ron") && message.contains("segmnts"),
        "{message}"
    );
    // The app keeps running, and the good assets stay.
    app.update();
    assert!(
        app.world()
            .resource::<Assets<TreeModel>>()
            .get(&handles[0])
            .is_some()
    );
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn saved_models_round_trip() {
    let model = slender();
    assert_eq!(
        TreeModel::from_ron_str(&model.to_ron_string().unwrap()).unwrap(),
        model
    );
    assert_eq!(
        TreeModel::from_binary(&model.to_binary().unwrap()).unwrap(),
        model
    );
}

#[test]
fn corrupt_or_foreign_binaries_are_refused() {
    let bin = slender().to_binary().unwrap();
    assert!(matches!(
        TreeModel::from_binary(b"nonsense"),
        Err(TreeFileError::Header(_))
    ));
    let mut other_version = bin.clone();
    other_version[8] = 9;
    let e = TreeModel::from_binary(&other_version).unwrap_err();
    assert!(e.to_string().contains("version 9"), "{e}");
    let truncated = &bin[..bin.len() / 2];
    assert!(matches!(
        TreeModel::from_binary(truncated),
        Err(TreeFileError::Binary(_))
    ));
}

#[test]
fn inconsistent_models_are_refused_not_trusted() {
    let mut model = slender();
    model.trunk_indices[4] = model.trunk_positions.len() as u32 + 7;
    let e = TreeModel::from_binary(&model.to_binary().unwrap()).unwrap_err();
    assert!(
        e.to_string()
            .starts_with("inconsistent model: trunk_indices"),
        "{e}"
    );

    let mut model = slender();
    model.segments.diameter.pop();
    assert!(matches!(
        model.validate(),
        Err(TreeFileError::Inconsistent {
            field: "segments",
            ..
        })
    ));

    // Groups out of range, overlapping, leaving leaves out, or empty.
    let cases: [fn(&mut TreeModel); 4] = [
        |m| m.leaf_groups[0].leaves.end = m.leaves.len() as u32 + 1,
        |m| m.leaf_groups[1].leaves.start -= 1,
        |m| m.leaf_groups.last_mut().unwrap().leaves.end -= 1,
        |m| {
            let end = m.leaf_groups[0].leaves.end;
            m.leaf_groups[0].leaves.start = end;
            m.leaf_groups[0].leaves.end = end;
        },
    ];
    for (i, break_groups) in cases.into_iter().enumerate() {
        let mut model = slender();
        assert_eq!(model.validate().ok(), Some(()));
        break_groups(&mut model);
        let e = model.validate();
        assert!(
            matches!(
                e,
                Err(TreeFileError::Inconsistent {
                    field: "leaf_groups",
                    ..
                })
            ),
            "case {i}: {e:?}"
        );
    }
}

#[test]
fn malformed_saved_ron_names_line_and_field() {
    let text = slender()
        .to_ron_string()
        .unwrap()
        .replacen("diameter", "diametre", 1);
    let e = TreeModel::from_ron_str(&text).unwrap_err();
    let message = e.to_string();
    assert!(
        message.contains("diametre") || message.contains("diameter"),
        "{message}"
    );
    assert!(
        message.chars().next().unwrap().is_ascii_digit(),
        "line:column first: {message}"
    );
}
