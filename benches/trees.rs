//! Tree analysis and loading: a ~100 000-triangle tree analysed from its meshes, and the
//! same model loaded from the two saved formats.
//!
//! Goals (release, this machine): analysis under 1 s; loading a saved model at least 10×
//! faster than analysing it. `cargo bench --bench trees`.

use std::hint::black_box;
use std::time::Duration;

use bevy_sherwood::tree::*;
use criterion::{Criterion, criterion_group, criterion_main};

/// About 29 000 trunk and 72 000 leaf triangles.
const HUGE: &str = r#"(
    name: "huge",
    seed: 97,
    levels: [
        (length: 14.0, radius: 0.6, taper: 0.3, segments: 30, ring_vertices: 24, children: 12,
         children_start: 0.3, angle: 0.0, angle_jitter: 0.0),
        (length: 0.5, radius: 0.45, segments: 12, ring_vertices: 12, children: 5, angle: 60.0),
        (length: 0.5, radius: 0.5, segments: 8, ring_vertices: 8, children: 6, angle: 45.0),
        (length: 0.5, radius: 0.55, segments: 4, ring_vertices: 5, angle: 40.0),
    ],
    leaves: (per_twig: 100, size: 0.2, shape: Quad, spread: 0.2),
)"#;

fn trees(c: &mut Criterion) {
    let species = SpeciesDesc::from_ron_str(HUGE).unwrap();
    let generated = species.generate();
    let trunk = MeshData {
        positions: &generated.trunk_positions,
        normals: Some(&generated.trunk_normals),
        indices: &generated.trunk_indices,
        color: None,
    };
    let leaves = MeshData {
        positions: &generated.leaf_positions,
        normals: Some(&generated.leaf_normals),
        indices: &generated.leaf_indices,
        color: None,
    };
    let options = AnalysisOptions::default();
    let model = analyze(&trunk, &leaves, &options).unwrap().model;
    println!(
        "huge tree: {} trunk + {} leaf triangles, {} rings, {} leaf groups",
        model.trunk_triangle_count(),
        model.leaf_triangle_count(),
        model.rings.len(),
        model.leaf_groups.len()
    );
    let binary = model.to_binary().unwrap();
    let ron = model.to_ron_string().unwrap();
    println!(
        "saved: {} bytes binary, {} bytes RON",
        binary.len(),
        ron.len()
    );

    let mut group = c.benchmark_group("tree_100k");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(6));
    group.bench_function("analyze", |b| {
        b.iter(|| black_box(analyze(&trunk, &leaves, &options).unwrap()));
    });
    group.bench_function("load_binary", |b| {
        b.iter(|| black_box(TreeModel::from_binary(&binary).unwrap()));
    });
    group.bench_function("load_ron", |b| {
        b.iter(|| black_box(TreeModel::from_ron_str(&ron).unwrap()));
    });
    group.bench_function("generate", |b| b.iter(|| black_box(species.generate())));
    group.finish();
}

criterion_group!(benches, trees);
criterion_main!(benches);
