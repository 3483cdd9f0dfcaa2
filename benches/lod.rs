//! The Sherwood stages of a whole frame (`app.update()` of a headless app: animate, cull,
//! value, budget, select) for forests of 2 000, 20 000 and 100 000 trees, every tree in
//! view, in TCLOD mode at a 100 ms target. Goal (release): under 2 ms for 20 000 visible
//! trees. `cargo bench --no-default-features --bench lod`.
//!
//! After the timings it prints the per-stage times of the last frame from
//! `LodDiagnostics`.

use std::time::Duration;

use bevy::prelude::*;
use bevy_sherwood::prelude::*;
use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};

#[path = "../tests/common/mod.rs"]
mod common;

fn forest_app(trees: u32) -> App {
    let (mut app, size) = common::forest_of(trees);
    // High above the centre, looking down: every tree in view.
    common::look_from(
        &mut app,
        Vec3::new(size / 2.0, size * 0.9, size / 2.0 + 1.0),
        Vec3::new(size / 2.0, 0.0, size / 2.0),
    );
    common::until_visible(&mut app);
    app
}

fn stages(c: &mut Criterion) {
    let mut group = c.benchmark_group("sherwood_frame");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(10));
    let mut reports = Vec::new();
    for trees in [2_000, 20_000, 100_000] {
        let mut app = forest_app(trees);
        group.bench_with_input(BenchmarkId::from_parameter(trees), &trees, |b, _| {
            b.iter(|| app.update());
        });
        reports.push((trees, app.world().resource::<LodDiagnostics>().clone()));
    }
    group.finish();
    for (trees, d) in reports {
        println!(
            "{trees} trees: {} visible, stages value {:.2} ms, budget {:.2} ms, select {:.2} ms; {} triangles, {} lines, {} points",
            d.visible_instances,
            d.value_stage_ms,
            d.budget_stage_ms,
            d.select_stage_ms,
            d.counts.triangles,
            d.counts.lines,
            d.counts.points
        );
    }
}

criterion_group!(benches, stages);
criterion_main!(benches);
