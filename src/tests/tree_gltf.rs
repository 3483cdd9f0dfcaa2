//! Trees from glTF: a binary glTF with a trunk mesh and a leaves mesh, built here byte by
//! byte, imported and analysed.
#![cfg(feature = "gltf")]

use crate::testing as common;

use std::collections::HashMap;

use crate::tree::*;
use bevy::math::Vec3;

/// `bytes` imported with the default settings and no external buffers.
fn import(bytes: &[u8]) -> Result<TreeAnalysis, GltfTreeError> {
    import_gltf(bytes, &GltfTreeSettings::default(), &HashMap::new())
}

/// A trunk of three 4-vertex rings (two cylinders, base below ground) and one quad leaf,
/// in a `.glb` whose trunk node is moved by `offset` and whose leaf material is named
/// `leaf_material`.
fn glb(offset: Vec3, leaf_material: &str) -> Vec<u8> {
    edited_glb(offset, leaf_material, |json| json)
}

/// [`glb`] with its JSON chunk passed through `edit` first.
fn edited_glb(offset: Vec3, leaf_material: &str, edit: impl FnOnce(String) -> String) -> Vec<u8> {
    let mut trunk_positions = Vec::new();
    for (y, r) in [(-0.5_f32, 0.3_f32), (1.0, 0.2), (2.0, 0.1)] {
        for j in 0..4 {
            let a = core::f32::consts::TAU * j as f32 / 4.0;
            trunk_positions.push([r * a.cos(), y, r * a.sin()]);
        }
    }
    let mut trunk_indices: Vec<u16> = Vec::new();
    for ring in 0..2_u16 {
        for j in 0..4_u16 {
            let (a0, a1) = (ring * 4 + j, ring * 4 + (j + 1) % 4);
            let (b0, b1) = (a0 + 4, a1 + 4);
            trunk_indices.extend([a0, a1, b1, a0, b1, b0]);
        }
    }
    let leaf_positions = [
        [0.5_f32, 2.5, 0.0],
        [0.8, 2.5, 0.0],
        [0.8, 2.8, 0.0],
        [0.5, 2.8, 0.0],
    ];
    let leaf_indices: [u16; 6] = [0, 1, 2, 0, 2, 3];

    let mut bin = Vec::new();
    let mut views = Vec::new();
    let mut push = |bytes: &[u8], bin: &mut Vec<u8>| {
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        views.push((bin.len(), bytes.len()));
        bin.extend_from_slice(bytes);
    };
    let floats = |v: &[[f32; 3]]| {
        v.iter()
            .flatten()
            .flat_map(|f| f.to_le_bytes())
            .collect::<Vec<u8>>()
    };
    let shorts = |v: &[u16]| v.iter().flat_map(|i| i.to_le_bytes()).collect::<Vec<u8>>();
    push(&floats(&trunk_positions), &mut bin);
    push(&shorts(&trunk_indices), &mut bin);
    push(&floats(&leaf_positions), &mut bin);
    push(&shorts(&leaf_indices), &mut bin);
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let view_json: Vec<String> = views
        .iter()
        .map(|(o, l)| format!(r#"{{"buffer":0,"byteOffset":{o},"byteLength":{l}}}"#))
        .collect();
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0,1]}}],
"nodes":[{{"name":"Tree","mesh":0,"translation":[{},{},{}]}},{{"name":"Crown","mesh":1}}],
"meshes":[{{"name":"Bark","primitives":[{{"attributes":{{"POSITION":0}},"indices":1,"material":0}}]}},
{{"name":"Crown","primitives":[{{"attributes":{{"POSITION":2}},"indices":3,"material":1}}]}}],
"materials":[{{"name":"bark","pbrMetallicRoughness":{{"baseColorFactor":[0.3,0.2,0.1,1]}}}},
{{"name":"{leaf_material}","pbrMetallicRoughness":{{"baseColorFactor":[0.1,0.5,0.1,1]}}}}],
"accessors":[
{{"bufferView":0,"componentType":5126,"count":12,"type":"VEC3","min":[-0.3,-0.5,-0.3],"max":[0.3,2.0,0.3]}},
{{"bufferView":1,"componentType":5123,"count":48,"type":"SCALAR"}},
{{"bufferView":2,"componentType":5126,"count":4,"type":"VEC3","min":[0.5,2.5,0.0],"max":[0.8,2.8,0.0]}},
{{"bufferView":3,"componentType":5123,"count":6,"type":"SCALAR"}}],
"bufferViews":[{}],"buffers":[{{"byteLength":{}}}]}}"#,
        offset.x,
        offset.y,
        offset.z,
        view_json.join(","),
        bin.len()
    );
    let mut json = edit(json).into_bytes();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = Vec::new();
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2_u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    out
}

#[test]
fn trunk_and_leaves_are_told_apart_by_material_name() {
    let analysis = import(&glb(Vec3::ZERO, "Leaves")).unwrap();
    let m = &analysis.model;
    assert_eq!(m.rings.len(), 3);
    assert_eq!(m.segments.len(), 2);
    assert_eq!(m.trunk_triangle_count(), 16);
    assert_eq!(m.leaves.len(), 1);
    assert_eq!(m.leaf_triangle_count(), 2);
    assert_eq!(m.bark_color, [0.3, 0.2, 0.1]);
    assert_eq!(m.leaf_color, [0.1, 0.5, 0.1]);
}

/// [`glb`] with a "Ground" node: the leaf quad re-used under a bark material, laid flat
/// at the trunk's foot (y = -0.5) and scaled `scale` times (0.3 m × `scale` wide).
fn glb_with_ground(scale: f32) -> Vec<u8> {
    edited_glb(Vec3::ZERO, "Leaves", |json| {
        let ground = format!(
            r#"{{"name":"Crown","mesh":1}},{{"name":"Ground","mesh":2,"translation":[{},-0.5,{}],"rotation":[-0.7071068,0,0,0.7071068],"scale":[{scale},{scale},{scale}]}}]"#,
            -0.65 * scale,
            2.65 * scale
        );
        let replaced = json
            .replace(r#""nodes":[0,1]"#, r#""nodes":[0,1,2]"#)
            .replace(r#"{"name":"Crown","mesh":1}]"#, &ground)
            .replace(
                r#""material":1}]}],"#,
                r#""material":1}]},{"name":"Plane","primitives":[{"attributes":{"POSITION":2},"indices":3,"material":0}]}],"#,
            );
        assert_eq!(replaced.matches("Plane").count(), 1, "{replaced}");
        assert_eq!(replaced.matches("Ground").count(), 1, "{replaced}");
        replaced
    })
}

#[test]
fn a_ground_plane_exported_with_the_tree_is_left_out_with_a_warning() {
    let plain = import(&glb(Vec3::ZERO, "Leaves")).unwrap();
    let with_ground = import(&glb_with_ground(20.0)).unwrap();
    assert_eq!(with_ground.model, plain.model, "the plane changed the tree");
    let ground: Vec<_> = with_ground
        .warnings
        .iter()
        .filter_map(|w| match w {
            AnalysisWarning::GroundPlaneLeftOut { mesh, width } => Some((mesh.as_str(), *width)),
            _ => None,
        })
        .collect();
    assert_eq!(ground.len(), 1, "{:?}", with_ground.warnings);
    assert_eq!(ground[0].0, "Plane");
    assert!((ground[0].1 - 6.0).abs() < 1e-3, "{ground:?}");

    // Named as skipped, it is left out without a word.
    let settings = GltfTreeSettings {
        skip_keywords: vec!["plane".into()],
        ..Default::default()
    };
    let skipped = import_gltf(&glb_with_ground(20.0), &settings, &HashMap::new()).unwrap();
    assert_eq!(skipped.model, plain.model);
    assert_eq!(skipped.warnings, plain.warnings);

    // A flat quad a tenth of the tree's height wide is not a ground plane: it stays.
    let small = import(&glb_with_ground(1.0));
    if let Ok(small) = small {
        assert_ne!(
            small.model, plain.model,
            "a small flat primitive was dropped"
        );
        assert!(
            !small
                .warnings
                .iter()
                .any(|w| matches!(w, AnalysisWarning::GroundPlaneLeftOut { .. }))
        );
    }
}

#[test]
fn node_transforms_are_applied() {
    let m = import_gltf(
        &glb(Vec3::new(5.0, 0.0, 0.0), "Leaves"),
        &GltfTreeSettings::default(),
        &HashMap::new(),
    )
    .unwrap()
    .model;
    let root = m.roots().next().unwrap();
    assert!((m.rings[root as usize].center - Vec3::new(5.0, -0.5, 0.0)).length() < 1e-5);
}

#[test]
fn keywords_are_configurable_and_a_missing_trunk_is_an_error() {
    // "Greens" is not a default leaf keyword: the quad is read as trunk (a flat branch
    // attached to the nearest ring), so the tree has no leaves.
    let bytes = glb(Vec3::ZERO, "Greens");
    let as_trunk = import(&bytes).unwrap();
    assert_eq!(as_trunk.model.leaves.len(), 0);
    assert_eq!(as_trunk.model.trunk_triangle_count(), 18);
    let settings = GltfTreeSettings {
        leaf_keywords: vec!["green".into()],
        ..Default::default()
    };
    assert_eq!(
        import_gltf(&bytes, &settings, &HashMap::new())
            .unwrap()
            .model
            .leaves
            .len(),
        1
    );
    let everything = GltfTreeSettings {
        leaf_keywords: vec!["".into(), "e".into()],
        ..Default::default()
    };
    assert!(matches!(
        import_gltf(&bytes, &everything, &HashMap::new()),
        Err(GltfTreeError::NoTrunk { .. })
    ));
}

#[test]
fn broken_files_are_refused() {
    assert!(matches!(
        import(b"not gltf at all"),
        Err(GltfTreeError::Gltf(_))
    ));
    let mut truncated = glb(Vec3::ZERO, "Leaves");
    truncated.truncate(truncated.len() - 40);
    assert!(import(&truncated).is_err());
}

#[test]
fn tree_glb_files_load_through_the_asset_server() {
    use bevy::asset::LoadState;
    use bevy::prelude::*;

    let dir = std::env::temp_dir().join(format!("sherwood-gltf-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("oak.tree.glb"), glb(Vec3::ZERO, "Leaves")).unwrap();
    let mut app = common::tree_app(&dir);
    let handle: Handle<TreeModel> = app.world().resource::<AssetServer>().load("oak.tree.glb");
    match common::settle(&mut app, &handle) {
        LoadState::Loaded => {}
        state => panic!("{state:?}"),
    }
    let model = app
        .world()
        .resource::<Assets<TreeModel>>()
        .get(&handle)
        .unwrap();
    assert_eq!(model.rings.len(), 3);
    let _ = std::fs::remove_dir_all(dir);
}

/// The loader's settings, analysis options included, come from a `.meta` file beside the
/// tree, as `GltfTreeSettings`' documentation shows.
#[test]
fn meta_files_set_the_keywords_and_the_analysis_options() {
    use bevy::asset::LoadState;
    use bevy::prelude::*;

    let dir = std::env::temp_dir().join(format!("sherwood-gltf-meta-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let meta = |settings: &str| {
        format!(
            "(meta_format_version: \"1.0\", asset: Load(loader: \"bevy_sherwood::tree::gltf::GltfTreeLoader\", settings: {settings}))"
        )
    };
    // "Greens" is no default leaf keyword: only the meta file makes the quad a leaf.
    for name in ["plain", "green", "sunk"] {
        std::fs::write(
            dir.join(format!("{name}.tree.glb")),
            glb(Vec3::ZERO, "Greens"),
        )
        .unwrap();
    }
    std::fs::write(
        dir.join("green.tree.glb.meta"),
        meta("(leaf_keywords: [\"green\"])"),
    )
    .unwrap();
    // The trunk's lowest ring is at y = -0.5: with the ground below it there is no root.
    std::fs::write(
        dir.join("sunk.tree.glb.meta"),
        meta("(analysis: (ground: -1.0))"),
    )
    .unwrap();
    let mut app = common::tree_app(&dir);
    let load = |app: &mut App, name: &str| {
        let handle: Handle<TreeModel> = app
            .world()
            .resource::<AssetServer>()
            .load(format!("{name}.tree.glb"));
        let state = common::settle(app, &handle);
        (
            state,
            app.world()
                .resource::<Assets<TreeModel>>()
                .get(&handle)
                .map(|m| m.leaves.len()),
        )
    };
    assert!(matches!(
        load(&mut app, "plain"),
        (LoadState::Loaded, Some(0))
    ));
    assert!(matches!(
        load(&mut app, "green"),
        (LoadState::Loaded, Some(1))
    ));
    match load(&mut app, "sunk") {
        (LoadState::Failed(e), None) => assert!(e.to_string().contains("no root ring"), "{e}"),
        other => panic!("{other:?}"),
    }
    let _ = std::fs::remove_dir_all(dir);
}

/// Files that break what glTF promises get an error naming the mesh and accessor, never
/// a panic inside the `gltf` crate (whose readers assume a valid file).
#[test]
fn malformed_accessors_are_errors_not_panics() {
    let import_edited =
        |edit: &dyn Fn(String) -> String| import(&edited_glb(Vec3::ZERO, "leaf", edit));
    let cases: [(&str, &dyn Fn(String) -> String); 6] = [
        // Float indices: the gltf crate's index reader hits `unreachable!` on them.
        ("float indices", &|j| {
            j.replacen(
                r#""componentType":5123,"count":48"#,
                r#""componentType":5126,"count":48"#,
                1,
            )
        }),
        // No vertices: its readers compute `count - 1`.
        ("no vertices", &|j| {
            j.replacen(r#""count":12"#, r#""count":0"#, 1)
        }),
        // Fewer vertices than the indices name.
        ("indices past the vertices", &|j| {
            j.replacen(r#""count":12"#, r#""count":8"#, 1)
        }),
        // An accessor running past its buffer view.
        ("past the view", &|j| {
            j.replacen(
                r#"{"bufferView":0,"#,
                r#"{"bufferView":0,"byteOffset":120,"#,
                1,
            )
        }),
        // Positions of the wrong type.
        ("integer positions", &|j| {
            j.replacen(
                r#""componentType":5126,"count":12"#,
                r#""componentType":5123,"count":12"#,
                1,
            )
        }),
        // A scene with nothing in it.
        ("empty scene", &|j| {
            j.replacen(
                r#""scenes":[{"nodes":[0,1]}]"#,
                r#""scenes":[{"nodes":[]}]"#,
                1,
            )
        }),
    ];
    for (case, edit) in cases {
        let probe = edited_glb(Vec3::ZERO, "leaf", edit);
        assert_ne!(
            probe,
            glb(Vec3::ZERO, "leaf"),
            "{case}: the edit changed nothing"
        );
        let error = import_edited(edit)
            .err()
            .unwrap_or_else(|| panic!("{case}: imported"));
        let message = error.to_string();
        match case {
            "indices past the vertices" => {
                assert!(
                    matches!(error, GltfTreeError::IndexOutOfRange { .. }),
                    "{case}: {message}"
                );
            }
            "empty scene" => assert!(
                matches!(error, GltfTreeError::NoMeshes),
                "{case}: {message}"
            ),
            // The gltf crate's own validation may catch some first; either way an error.
            _ => match error {
                GltfTreeError::Accessor { .. } => {
                    assert!(message.contains("Bark"), "{case}: {message}");
                }
                GltfTreeError::Gltf(_) => {}
                other => panic!("{case}: {other}"),
            },
        }
    }
}

/// A buffer URI that leaves the file's folder would read any file on the machine as
/// geometry: refused before anything is read.
#[test]
fn buffer_uris_outside_the_folder_are_refused() {
    let gltf = |uri: &str| {
        format!(r#"{{"asset":{{"version":"2.0"}},"buffers":[{{"byteLength":12,"uri":"{uri}"}}]}}"#)
            .into_bytes()
    };
    for uri in [
        "../secret.bin",
        "%2E%2E%5Csecret.bin",
        "trees/../../secret.bin",
        "%2e%2e/secret.bin",
        "/etc/passwd",
        "file:///etc/passwd",
        "C:/Windows/win.ini",
        r"..\\secret.bin",
    ] {
        assert!(
            matches!(
                external_buffers(&gltf(uri)),
                Err(GltfTreeError::UnsafeUri { .. })
            ),
            "{uri} was accepted"
        );
    }
    for (uri, path) in [
        ("tree.bin", "tree.bin"),
        ("buffers/tree.bin", "buffers/tree.bin"),
        ("a%20b.bin", "a b.bin"),
        ("%C3%A9t%C3%A9.bin", "été.bin"),
    ] {
        assert_eq!(
            external_buffers(&gltf(uri)).unwrap(),
            vec![BufferFile {
                uri: uri.to_owned(),
                path: path.to_owned()
            }]
        );
    }
}

/// The JSON and the binary chunk of a GLB.
fn split_glb(glb: &[u8]) -> (String, Vec<u8>) {
    let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    let json = String::from_utf8(glb[20..20 + json_len].to_vec()).unwrap();
    let bin = glb[20 + json_len + 8..].to_vec();
    (json, bin)
}

/// A `.gltf` names its buffer file by URI: `my%20oak.bin` is the file `my oak.bin`.
#[test]
fn a_buffer_file_named_with_percent_escapes_loads_through_the_asset_server() {
    use bevy::asset::LoadState;
    use bevy::prelude::*;

    let dir = std::env::temp_dir().join(format!("sherwood-gltf-uri-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (json, bin) = split_glb(&glb(Vec3::ZERO, "Leaves"));
    let byte_length = format!(r#""buffers":[{{"byteLength":{}}}]"#, bin.len());
    assert!(json.contains(&byte_length));
    let json = json.replace(
        &byte_length,
        &format!(
            r#""buffers":[{{"byteLength":{},"uri":"my%20oak.bin"}}]"#,
            bin.len()
        ),
    );
    std::fs::write(dir.join("oak.tree.gltf"), json).unwrap();
    std::fs::write(dir.join("my oak.bin"), bin).unwrap();
    let mut app = common::tree_app(&dir);
    let handle: Handle<TreeModel> = app.world().resource::<AssetServer>().load("oak.tree.gltf");
    let state = common::settle(&mut app, &handle);
    let _ = std::fs::remove_dir_all(&dir);
    assert!(matches!(state, LoadState::Loaded), "{state:?}");
    let model = app
        .world()
        .resource::<Assets<TreeModel>>()
        .get(&handle)
        .unwrap();
    assert_eq!((model.rings.len(), model.leaves.len()), (3, 1));
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(super::fuzz::cases()))]

    /// A damaged `.glb` (bytes changed, JSON numbers replaced by extreme values) is an
    /// error or a valid model, never a panic.
    #[test]
    fn mutated_glb_files_import_valid_or_fail(
        m in proptest::collection::vec(super::fuzz::mutation(), 1..6)
    ) {
        let bytes = super::fuzz::mutate(&glb(Vec3::ZERO, "leaf"), &m);
        if let Ok(analysis) = import(&bytes) {
            let valid = analysis.model.validate();
            proptest::prop_assert!(valid.is_ok(), "{:?}", valid.err());
        }
    }
}
