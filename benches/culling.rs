//! Box-hierarchy culling of 100 000 instances against brute force, at several depths
//! ([`workloads::culling`]). Goal (release, one core): under 1 ms per frame.
//! `cargo bench --bench culling`.

use std::time::Duration;

use bevy_sherwood::testing::workloads;
use criterion::{Criterion, criterion_group, criterion_main};

fn culling(c: &mut Criterion) {
    let mut group = c.benchmark_group("cull_100k");
    group.measurement_time(Duration::from_secs(3));
    for mut workload in workloads::culling() {
        if let Some(note) = &workload.note {
            println!("{note}");
        }
        group.bench_function(workload.name.clone(), |b| b.iter(|| workload.run()));
    }
    group.finish();
}

criterion_group!(benches, culling);
criterion_main!(benches);
