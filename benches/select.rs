//! The per-object searches of the Budget stage alone, outside any app: each tree's TCLOD
//! trunk and its leaves chosen as one, for 20 000 trees of the four shipped species
//! ([`workloads::tree_searches`]).
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

use std::time::Duration;

use bevy_sherwood::testing::{self as common, workloads};
use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};

const TREES: usize = 20_000;

fn searches(c: &mut Criterion) {
    let models = ["broad", "dense", "grand", "slender"]
        .into_iter()
        .map(common::species)
        .collect();
    let mut group = c.benchmark_group("tree_search");
    group.measurement_time(Duration::from_secs(5));
    for mut workload in workloads::tree_searches(models, TREES) {
        group.throughput(Throughput::Elements(workload.elements));
        group.bench_function(BenchmarkId::from_parameter(&workload.name), |b| {
            b.iter(|| workload.run());
        });
    }
    group.finish();
}

criterion_group!(benches, searches);
criterion_main!(benches);
