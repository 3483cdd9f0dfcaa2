//! The wind stage (`SherwoodSystems::Animate`: ring offsets and moved bounds of every
//! moving tree) in a headless app, timed by the stage's own clock (`WindStats::update_ms`),
//! with simulated time advancing 1/60 s per frame.
//!
//! - `wind/2000_visible/every_tree_moves`: 2 000 trees in view, motion level of detail off
//!   (pixel threshold 0). Goal (release, one core — the stage is one system): < 2 ms.
//! - `wind/2000_visible/shipped_threshold`: the same with the shipped set's threshold.
//!
//! Then two tables, the shapes of thesis figures 5.8 and 5.9: the stage's cost as the
//! camera recedes from the forest, and as the springs come to rest after the wind drops.
//! `cargo bench --no-default-features --bench wind`.

use std::time::Duration;

use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use bevy_sherwood::wind::{SpringSet, WindSettings, WindStats};
use criterion::{Criterion, criterion_group, criterion_main};

#[path = "../tests/common/mod.rs"]
mod common;

const TREES: u32 = 2_000;

/// Edits the default spring set in place (its springs keep their motion).
fn edit_springs(app: &mut App, edit: impl Fn(&mut SpringSet)) {
    let handle = app.world().resource::<WindSettings>().sets[0].clone();
    let mut sets = app.world_mut().resource_mut::<Assets<SpringSet>>();
    let mut set = sets
        .get_mut(&handle)
        .expect("the default spring set is loaded");
    edit(&mut set);
}

/// Mean stage time (ms) and the last frame's stats over `frames` frames.
fn run(app: &mut App, frames: u32) -> (f32, WindStats) {
    let mut total = 0.0;
    for _ in 0..frames {
        app.update();
        total += app.world().resource::<WindStats>().update_ms;
    }
    (total / frames as f32, *app.world().resource::<WindStats>())
}

fn wind(c: &mut Criterion) {
    let (mut app, size) = common::forest_of(TREES);
    app.insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_secs_f64(
        1.0 / 60.0,
    )));
    let centre = Vec3::new(size / 2.0, 0.0, size / 2.0);
    let overhead = |height: f32| centre + Vec3::new(0.0, height, 1.0);
    common::look_from(&mut app, overhead(size * 0.9), centre);
    common::until_visible(&mut app);
    // Three seconds of wind, so the springs are moving.
    run(&mut app, 180);

    let mut group = c.benchmark_group("wind/2000_visible");
    group.sample_size(20);
    group.measurement_time(Duration::from_secs(5));
    for (name, threshold) in [("every_tree_moves", 0.0), ("shipped_threshold", 0.5)] {
        edit_springs(&mut app, |set| set.pixel_threshold = threshold);
        run(&mut app, 2);
        let stats = *app.world().resource::<WindStats>();
        println!(
            "{name}: {} candidates, {} moved, {} skipped",
            stats.candidates, stats.moved, stats.skipped
        );
        group.bench_function(name, |b| {
            b.iter_custom(|iterations| {
                let mut total = Duration::ZERO;
                for _ in 0..iterations {
                    app.update();
                    let ms = app.world().resource::<WindStats>().update_ms;
                    total += Duration::from_secs_f32(ms / 1000.0);
                }
                total
            });
        });
    }
    group.finish();

    // Figure 5.8's shape: the camera rises above the centre, trees shrink on screen and
    // the motion level of detail leaves more of them still.
    edit_springs(&mut app, |set| set.pixel_threshold = 0.5);
    println!("\n| camera height / forest side | visible | moved | skipped | stage ms |");
    println!("|---:|---:|---:|---:|---:|");
    for factor in [0.15, 0.3, 0.6, 1.2, 2.4, 4.8] {
        common::look_from(&mut app, overhead(size * factor), centre);
        run(&mut app, 10);
        let (ms, stats) = run(&mut app, 60);
        println!(
            "| {factor} | {} | {} | {} | {ms:.3} |",
            stats.candidates, stats.moved, stats.skipped
        );
    }

    // Figure 5.9's shape: the wind drops; damped springs come to rest and tree after tree
    // falls below the threshold.
    common::look_from(&mut app, overhead(size * 0.9), centre);
    run(&mut app, 60);
    edit_springs(&mut app, |set| {
        for spring in &mut set.springs {
            spring.wind.strength = 0.0;
            spring.wind.gusts.strength = (0.0, 0.0);
        }
    });
    println!("\n| seconds after the wind dropped | moved | skipped | stage ms |");
    println!("|---:|---:|---:|---:|");
    for second in 1..=12 {
        let (ms, stats) = run(&mut app, 60);
        println!(
            "| {second} | {} | {} | {ms:.3} |",
            stats.moved, stats.skipped
        );
    }
}

criterion_group!(benches, wind);
criterion_main!(benches);
