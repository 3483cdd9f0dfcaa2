//! The Sherwood stages of a whole frame (`app.update()` of a headless app: animate, cull,
//! value, budget, draw lists) for forests of 2 000, 20 000 and 100 000 trees, every tree in
//! view, in TCLOD mode at a 100 ms target, with Robin Hood and with the hierarchical
//! strategy (group impostors over the culling boxes). Goals (release): under 2 ms for
//! 20 000 visible trees with Robin Hood, under 3 ms for 100 000 with hierarchical. Robin
//! Hood also runs with far trees decided every other frame (`FrameBudget::far_refresh`).
//! `cargo bench --no-default-features --bench lod` (`-- robin-hood` or `-- hierarchical`
//! for one strategy).
//!
//! After the timings it prints, per forest and strategy, the mean time of the LOD stages
//! (value, budget, draw lists, from `LodDiagnostics`) over 64 more frames, and the cut.

use std::time::Duration;

use bevy::prelude::*;
use bevy_sherwood::lod::{GroupImpostors, StrategyKind};
use bevy_sherwood::prelude::*;
use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};

use bevy_sherwood::testing as common;

fn forest_app(trees: u32, strategy: StrategyKind, far_refresh: u32) -> (App, f32) {
    let (mut app, size) = common::forest_of(trees);
    let mut budget = app.world_mut().resource_mut::<FrameBudget>();
    budget.strategy = strategy;
    budget.far_refresh = far_refresh;
    // High above the centre, looking down: every tree in view.
    common::look_from(
        &mut app,
        Vec3::new(size / 2.0, size * 0.9, size / 2.0 + 1.0),
        Vec3::new(size / 2.0, 0.0, size / 2.0),
    );
    common::until_visible(&mut app);
    if strategy == StrategyKind::Hierarchical {
        // The group impostors are built once the strategy is chosen; then the cut refines
        // one box level a frame.
        for _ in 0..600 {
            app.update();
            if !app.world().resource::<GroupImpostors>().is_empty() {
                break;
            }
        }
        for _ in 0..32 {
            app.update();
        }
    }
    (app, size)
}

/// Plants one tree a frame at a new place in the forest and fells the last one planted.
struct Planter {
    model: Handle<TreeModel>,
    size: f32,
    step: u32,
    last: Option<Entity>,
}

impl Planter {
    fn new(app: &mut App, size: f32) -> Self {
        let model = app
            .world_mut()
            .query_filtered::<&TreeInstance, Without<FixedDrawList>>()
            .iter(app.world())
            .next()
            .expect("a forest")
            .model
            .clone();
        Self {
            model,
            size,
            step: 0,
            last: None,
        }
    }

    fn plant_one(&mut self, app: &mut App) {
        // A low-discrepancy walk over the forest's square.
        self.step += 1;
        let (u, v) = (
            (self.step as f32 * 0.618_034).fract(),
            (self.step as f32 * 0.754_878).fract(),
        );
        let at = Vec3::new(u * self.size, 0.0, v * self.size);
        common::replant(app, &mut self.last, &self.model, at);
        app.update();
    }
}

/// Frames averaged for the per-stage report.
const REPORT_FRAMES: u32 = 64;

fn stages(c: &mut Criterion) {
    let mut group = c.benchmark_group("sherwood_frame");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(10));
    let mut reports = Vec::new();
    // The `-planting` runs plant one tree a frame and fell the one planted the frame
    // before: the instance table changes every frame.
    for (name, strategy, far_refresh, planting) in [
        ("robin-hood", StrategyKind::RobinHood, 1, false),
        // Far trees decided every other frame (`FrameBudget::far_refresh`, off by default).
        (
            "robin-hood-far-refresh-2",
            StrategyKind::RobinHood,
            2,
            false,
        ),
        ("hierarchical", StrategyKind::Hierarchical, 1, false),
        ("robin-hood-planting", StrategyKind::RobinHood, 1, true),
        ("hierarchical-planting", StrategyKind::Hierarchical, 1, true),
    ] {
        for trees in [2_000, 20_000, 100_000] {
            // Built on first use, so that a filtered-out size costs no setup (criterion
            // calls the routine once per sample).
            let mut app = None;
            group.bench_with_input(BenchmarkId::new(name, trees), &trees, |b, &trees| {
                let (app, size) =
                    app.get_or_insert_with(|| forest_app(trees, strategy, far_refresh));
                if planting {
                    let mut planter = Planter::new(app, *size);
                    b.iter(|| planter.plant_one(app));
                } else {
                    b.iter(|| app.update());
                }
            });
            if let Some((app, _)) = &mut app {
                reports.push((name, trees, stage_means(app)));
            }
        }
    }
    group.finish();
    for (name, trees, (d, [value, budget, draw_lists])) in reports {
        println!(
            "{name}, {trees} trees: {} visible; LOD stages {:.2} ms (value {value:.2}, budget {budget:.2}, draw lists {draw_lists:.2}; mean of {REPORT_FRAMES} frames); {} held, {} groups and {} trees drawn; {} triangles, {} lines, {} points",
            d.visible_instances,
            value + budget + draw_lists,
            d.held_trees,
            d.impostors_drawn,
            d.trees_drawn,
            d.counts.triangles,
            d.counts.lines,
            d.counts.points
        );
    }
}

/// The last frame's diagnostics, and the value, budget and draw-lists stages' mean times
/// over [`REPORT_FRAMES`] more frames.
fn stage_means(app: &mut App) -> (LodDiagnostics, [f32; 3]) {
    let mut sums = [0.0; 3];
    for _ in 0..REPORT_FRAMES {
        app.update();
        let d = app.world().resource::<LodDiagnostics>();
        for (sum, ms) in
            sums.iter_mut()
                .zip([d.value_stage_ms, d.budget_stage_ms, d.draw_lists_stage_ms])
        {
            *sum += ms / REPORT_FRAMES as f32;
        }
    }
    (app.world().resource::<LodDiagnostics>().clone(), sums)
}

criterion_group!(benches, stages);
criterion_main!(benches);
