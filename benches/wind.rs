//! The wind stage (`SherwoodSystems::Animate`: ring offsets and moved bounds of every
//! moving tree) in a headless app, timed by the stage's own clock (`WindStats::update_ms`),
//! with simulated time advancing 1/60 s per frame.
//!
//! - `wind/per_tree/SPECIES/ring_offsets`, `.../ring_offsets_thresholded` and
//!   `.../moved_bounds`: the pure per-instance work for one tree of each shipped species
//!   (the stage's floor), with every movement applied and with sub-centimetre movements
//!   accumulated (the stage's half-pixel threshold at about 50 m).
//! - `wind/2000_visible/every_tree_moves_every_frame`: 2 000 trees in view across the
//!   forest from a corner, both levels of detail off (pixel threshold 0, every moving
//!   tree updated every frame): the worst case.
//! - `wind/2000_visible/every_tree_moves`: the same, with the shipped update-rate level
//!   of detail (`WindSettings::full_rate_pixels`). Goal (release, one core — the stage is
//!   one system): < 2 ms.
//! - `wind/2000_visible/shipped_threshold_own_sway`: the same view with the shipped
//!   settings except that every moving tree computes its own offsets
//!   (`WindSettings::shared_sway_pixels` 0).
//! - `wind/2000_visible/shipped_threshold`: the same view with the shipped settings (far
//!   trees borrow a representative's sway).
//!
//! Then two tables, the shapes of thesis figures 5.8 and 5.9: the stage's cost as the
//! camera backs away from the forest, and as the springs come to rest after the wind drops.
//! `cargo bench --no-default-features --bench wind`.

use std::time::Duration;

use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use bevy_sherwood::testing::{self as common, workloads};
use bevy_sherwood::wind::{SpringSet, WindSettings, WindStats};
use criterion::{Criterion, criterion_group, criterion_main};

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

/// The pure per-instance work, one shipped species at a time: the stage's floor.
fn per_tree(c: &mut Criterion) {
    let set_text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/assets/wind/default.wind.ron"
    ))
    .unwrap();
    let set = SpringSet::from_ron_str(&set_text).unwrap();
    let mut group = c.benchmark_group("wind/per_tree");
    for name in ["slender", "broad", "grand"] {
        let model = common::species(name);
        println!("{name}: {} rings", model.rings.len());
        for mut workload in workloads::wind_per_tree(&model, &set.rules) {
            group.bench_function(format!("{name}/{}", workload.name), |b| {
                b.iter(|| workload.run());
            });
        }
    }
    group.finish();
}

fn wind(c: &mut Criterion) {
    let (mut app, size) = common::forest_of(TREES);
    app.insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_secs_f64(
        1.0 / 60.0,
    )));
    let centre = Vec3::new(size / 2.0, 0.0, size / 2.0);
    // Looking across the forest from outside a corner, 20 m up, `back` × the forest's
    // side away from it: a walker's view, near trees large and far ones small. From a
    // quarter of the side back, the whole forest is in view.
    let corner = |back: f32| Vec3::new(-back * size, 20.0, -back * size);
    common::look_from(&mut app, corner(0.25), centre);
    common::until_visible(&mut app);
    // Three seconds of wind, so the springs are moving.
    run(&mut app, 180);

    let mut group = c.benchmark_group("wind/2000_visible");
    group.sample_size(20);
    group.measurement_time(Duration::from_secs(5));
    let shipped = app.world().resource::<WindSettings>().clone();
    let (rate, shared) = (shipped.full_rate_pixels, shipped.shared_sway_pixels);
    for (name, threshold, full_rate_pixels, shared_sway_pixels) in [
        ("every_tree_moves_every_frame", 0.0, 0.0, 0.0),
        ("every_tree_moves", 0.0, rate, 0.0),
        ("shipped_threshold_own_sway", 0.5, rate, 0.0),
        ("shipped_threshold", 0.5, rate, shared),
    ] {
        edit_springs(&mut app, |set| set.pixel_threshold = threshold);
        let mut settings = app.world_mut().resource_mut::<WindSettings>();
        settings.full_rate_pixels = full_rate_pixels;
        settings.shared_sway_pixels = shared_sway_pixels;
        // Long enough for every update interval to come round.
        let (_, stats) = run(&mut app, 16);
        // The stage's cost per updated tree, over 64 frames: unlike the stage's time, it
        // does not swing with the gusts (stronger wind, more trees updated every frame).
        let (mut updated, mut ms) = (0, 0.0);
        for _ in 0..64 {
            app.update();
            let frame = *app.world().resource::<WindStats>();
            updated += frame.updated;
            ms += frame.update_ms;
        }
        let rings = app.world().resource::<WindStats>().rings_held;
        println!(
            "{name}: {} candidates, {} moved ({} updated, {} held, {} borrowing {} blocks computed), \
             {} skipped; {rings} rings held; {:.2} µs per updated tree, {} updated per frame on average",
            stats.candidates,
            stats.moved,
            stats.updated,
            stats.held,
            stats.shared,
            stats.shared_updated,
            stats.skipped,
            ms * 1000.0 / updated.max(1) as f32,
            updated / 64,
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

    // Figure 5.8's shape: the camera backs away from the forest, trees shrink on screen
    // and the motion level of detail leaves more of them still.
    edit_springs(&mut app, |set| set.pixel_threshold = 0.5);
    println!("\n| camera back / forest side | visible | moved | updated | skipped | stage ms |");
    println!("|---:|---:|---:|---:|---:|---:|");
    for back in [0.0, 0.25, 0.5, 1.0, 2.0, 4.0] {
        common::look_from(&mut app, corner(back), centre);
        run(&mut app, 10);
        let (ms, stats) = run(&mut app, 60);
        println!(
            "| {back} | {} | {} | {} | {} | {ms:.3} |",
            stats.candidates, stats.moved, stats.updated, stats.skipped
        );
    }

    // Figure 5.9's shape: the wind drops; damped springs come to rest and tree after tree
    // falls below the threshold.
    common::look_from(&mut app, corner(0.25), centre);
    run(&mut app, 60);
    edit_springs(&mut app, |set| {
        for spring in &mut set.springs {
            spring.wind.strength = 0.0;
            spring.wind.gusts.strength = (0.0, 0.0);
        }
    });
    println!("\n| seconds after the wind dropped | moved | updated | skipped | stage ms |");
    println!("|---:|---:|---:|---:|---:|");
    for second in 1..=12 {
        let (ms, stats) = run(&mut app, 60);
        println!(
            "| {second} | {} | {} | {} | {ms:.3} |",
            stats.moved, stats.updated, stats.skipped
        );
    }
}

criterion_group!(benches, per_tree, wind);
criterion_main!(benches);
