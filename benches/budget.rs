//! Each budget strategy at 1k, 10k, 100k and 1M objects with 8-level ladders
//! ([`workloads::budget_strategies`]).
//!
//! `cargo bench --bench budget`; criterion reports time per iteration and objects/s.

use std::time::Duration;

use bevy_sherwood::testing::workloads;
use criterion::{Criterion, Throughput, criterion_group, criterion_main};

fn strategies(c: &mut Criterion) {
    let mut group = c.benchmark_group("strategy");
    group.warm_up_time(Duration::from_secs(1));
    group.measurement_time(Duration::from_secs(4));
    group.sample_size(10);
    for n in [1_000, 10_000, 100_000, 1_000_000] {
        for mut workload in workloads::budget_strategies(n) {
            group.throughput(Throughput::Elements(workload.elements));
            group.bench_function(workload.name.clone(), |b| b.iter(|| workload.run()));
        }
    }
    group.finish();
}

criterion_group!(benches, strategies);
criterion_main!(benches);
