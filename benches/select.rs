//! The per-object searches of the Budget stage alone, outside any app: each tree's TCLOD
//! trunk ([`select::trunk_tclod`]) and its leaves chosen as one
//! ([`select::leaves_at_depth`]), for 20 000 trees of the four shipped species.
//!
//! Two views: `far` puts every tree 1 000–1 050 units deep, where the `lod` bench's
//! 20 000-tree forest stands (every trunk below half a pixel), and `middle` 400–450
//! units deep, where about half the trunks are lines of a pixel or two and take the
//! general search. Each object gets a few microseconds, the shares a 100 ms frame gives
//! a forest of this size. Free of the app's scheduling and of the other stages, this
//! bench resolves changes of a few nanoseconds per object that the `lod` bench's
//! run-to-run noise hides.
//!
//! `cargo bench --no-default-features --bench select`; criterion reports time per
//! 20 000 trees (40 000 objects).

use std::hint::black_box;
use std::time::Duration;

use bevy_sherwood::lod::select::{self, LeafMethod, PrimitiveCosts, TreeView};
use bevy_sherwood::prelude::*;
use bevy_sherwood::tree::{PixelRange, Projection};
use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};

#[path = "../tests/common/mod.rs"]
mod common;

const TREES: usize = 20_000;

/// One tree: its species, view, leaves' depth and the times its trunk and leaves get.
type Tree = (usize, TreeView, f32, f32, f32);

fn trees(depth: f32) -> Vec<Tree> {
    // The lod bench's view: 540 px high, 1.2 rad vertical field of view.
    let projection = Projection::perspective(1.2, 540.0);
    let mut next = common::unit_noise();
    (0..TREES)
        .map(|i| {
            let depth = depth + 50.0 * next();
            let view = TreeView {
                scale: 0.8 + 0.4 * next(),
                trunk_depth: depth,
                projection,
            };
            (i % 4, view, depth, 4.0e-6 * next(), 4.0e-6 * next())
        })
        .collect()
}

fn searches(c: &mut Criterion) {
    let models: Vec<TreeModel> = ["broad", "dense", "grand", "slender"]
        .into_iter()
        .map(common::species)
        .collect();
    let costs = PrimitiveCosts::from_calibration(&bevy_sherwood::cost::Calibration::default(), 1.0)
        .within_viewport(540.0 * 540.0);
    let sizes = PixelRange::default();
    let mut lists: Vec<TreeDrawList> = (0..TREES).map(|_| TreeDrawList::default()).collect();
    let mut group = c.benchmark_group("tree_search");
    group.throughput(Throughput::Elements(2 * TREES as u64));
    group.measurement_time(Duration::from_secs(5));
    for (name, depth) in [("far", 1000.0), ("middle", 400.0)] {
        let trees = trees(depth);
        group.bench_function(BenchmarkId::from_parameter(name), |b| {
            b.iter(|| {
                let mut total = 0.0;
                for ((model, view, depth, trunk_time, leaf_time), list) in
                    trees.iter().zip(&mut lists)
                {
                    let model = &models[*model];
                    total +=
                        select::trunk_tclod(model, view, &costs, sizes, *trunk_time, list).cost;
                    total += select::leaves_at_depth(
                        model,
                        view,
                        &costs,
                        LeafMethod::Tclod(sizes),
                        *depth,
                        *leaf_time,
                        list,
                    )
                    .cost;
                }
                black_box(total)
            });
        });
    }
    group.finish();
}

criterion_group!(benches, searches);
criterion_main!(benches);
