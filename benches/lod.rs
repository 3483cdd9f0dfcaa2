//! The Sherwood stages of a whole frame (`app.update()` of a headless app: animate, cull,
//! value, budget, draw lists) for forests of 2 000, 20 000 and 100 000 trees, in TCLOD mode
//! at a 100 ms target, with Robin Hood and with the hierarchical strategy (group impostors
//! over the culling boxes), from two views on a 960 × 540 screen: `above` (high over the
//! centre, every tree in view) and `ground` (the forest example's default view, 25 m up
//! outside a corner, looking in). The camera moves a little every frame, so every frame
//! is a fresh hand-out (a still camera keeps last frame's, `FrameBudget::steady`). Goals
//! (release): under 2 ms for 20 000 trees in view with Robin Hood, under 2 ms for 100 000
//! with hierarchical.
//! Robin Hood also runs with far trees decided every other frame
//! (`FrameBudget::far_refresh`). `cargo bench --no-default-features --bench lod`
//! (`-- robin-hood` or `-- hierarchical` for one strategy, `-- ground` for one view).
//!
//! After the timings it prints, per forest, view and strategy, the mean time of the LOD
//! stages (value, budget, draw lists, from `LodDiagnostics`), of the wind (and the
//! trees it swayed and updated) and of building group impostors (and the models built)
//! over 64 more frames, how many of them kept last frame's hand-out (0 here), and the
//! cut.

use std::time::Duration;

use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use bevy_sherwood::lod::{GroupImpostors, StrategyKind};
use bevy_sherwood::prelude::*;
use bevy_sherwood::wind::WindStats;
use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};

use bevy_sherwood::testing as common;

/// Where the bench's camera stands.
#[derive(Clone, Copy)]
enum View {
    /// High above the centre, looking down: every tree in view.
    Above,
    /// The forest example's default view: 25 m up, outside a corner, looking at the
    /// centre; most trees in view are near enough to be drawn alone.
    Ground,
}

impl View {
    fn name(self) -> &'static str {
        match self {
            View::Above => "above",
            View::Ground => "ground",
        }
    }

    /// Places the camera for frame `frame`: it sways a few metres back and forth (a
    /// 64-frame period), so that no two consecutive frames see the same view.
    fn look(self, app: &mut App, size: f32, frame: u32) {
        let sway = (frame as f32 * std::f32::consts::TAU / 64.0).sin();
        let centre = Vec3::new(size / 2.0, 0.0, size / 2.0);
        let (eye, target) = match self {
            View::Above => (
                Vec3::new(size / 2.0 + sway * 2.0, size * 0.9, size / 2.0 + 1.0),
                centre,
            ),
            View::Ground => {
                let back = (0.1 * size).min(320.0) + sway * 2.0;
                (Vec3::new(-back, 25.0, -back), centre)
            }
        };
        // The forest example's screen: 960 × 540.
        common::look_from_screen(app, eye, target, 960.0, 540.0);
    }
}

/// A headless app drawing `trees` trees from `view`, and the view's frame counter.
struct Bench {
    app: App,
    size: f32,
    view: View,
    frame: u32,
}

impl Bench {
    /// One frame, the camera a step further.
    fn update(&mut self) {
        self.frame += 1;
        self.view.look(&mut self.app, self.size, self.frame);
        self.app.update();
    }
}

fn forest_app(trees: u32, view: View, strategy: StrategyKind, far_refresh: u32) -> Bench {
    let (mut app, size) = common::forest_of(trees);
    // The same 60 Hz step every frame, so the wind sways the same way in every run.
    app.insert_resource(TimeUpdateStrategy::ManualDuration(
        Duration::from_secs(1) / 60,
    ));
    let mut budget = app.world_mut().resource_mut::<FrameBudget>();
    budget.strategy = strategy;
    budget.far_refresh = far_refresh;
    view.look(&mut app, size, 0);
    common::until_visible(&mut app);
    if strategy == StrategyKind::Hierarchical {
        // The group impostors of the boxes the cut reaches are built a few a frame; then
        // the cut refines one box level a frame.
        for _ in 0..2000 {
            app.update();
            let groups = app.world().resource::<GroupImpostors>();
            if !groups.is_empty() && !groups.building() {
                break;
            }
        }
        for _ in 0..32 {
            app.update();
        }
    }
    Bench {
        app,
        size,
        view,
        frame: 0,
    }
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

    fn plant_one(&mut self, bench: &mut Bench) {
        // A low-discrepancy walk over the forest's square.
        self.step += 1;
        let (u, v) = (
            (self.step as f32 * 0.618_034).fract(),
            (self.step as f32 * 0.754_878).fract(),
        );
        let at = Vec3::new(u * self.size, 0.0, v * self.size);
        common::replant(&mut bench.app, &mut self.last, &self.model, at);
        bench.update();
    }
}

/// Frames averaged for the per-stage report.
const REPORT_FRAMES: u32 = 64;

fn stages(c: &mut Criterion) {
    // `SHERWOOD_COMPUTE_THREADS=n`: the compute task pool with `n` threads (Bevy's
    // default leaves it one on a 2-core machine), to measure what the stages' parallel
    // per-object work buys with more cores. Set before any app makes its own pool.
    if let Some(threads) = std::env::var("SHERWOOD_COMPUTE_THREADS")
        .ok()
        .and_then(|n| n.parse().ok())
    {
        bevy::tasks::ComputeTaskPool::get_or_init(|| {
            bevy::tasks::TaskPoolBuilder::new()
                .num_threads(threads)
                .build()
        });
    }
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
        for view in [View::Above, View::Ground] {
            for trees in [2_000, 20_000, 100_000] {
                let id = format!("{name}/{}", view.name());
                // Built on first use, so that a filtered-out size costs no setup
                // (criterion calls the routine once per sample).
                let mut bench = None;
                group.bench_with_input(BenchmarkId::new(&id, trees), &trees, |b, &trees| {
                    let bench =
                        bench.get_or_insert_with(|| forest_app(trees, view, strategy, far_refresh));
                    if planting {
                        let mut planter = Planter::new(&mut bench.app, bench.size);
                        b.iter(|| planter.plant_one(bench));
                    } else {
                        b.iter(|| bench.update());
                    }
                });
                if let Some(bench) = &mut bench {
                    let means = stage_means(bench);
                    let groups = bench.app.world().get_resource::<GroupImpostors>();
                    let held = groups.map_or((0, 0), |g| (g.len(), g.vertices()));
                    reports.push((id, trees, means, held));
                }
            }
        }
    }
    group.finish();
    // The stages' per-object work is spread over this pool (`lod::parallel`).
    let threads = bevy::tasks::ComputeTaskPool::try_get().map_or(0, |pool| pool.thread_num());
    println!("compute task pool: {threads} threads");
    for (
        name,
        trees,
        (
            d,
            [
                value,
                budget,
                draw_lists,
                wind,
                updated,
                moved,
                still,
                rings,
                shared,
                blocks,
                build,
                built,
            ],
            kept,
        ),
        (held, vertices),
    ) in reports
    {
        println!(
            "{name}, {trees} trees: {} visible; LOD stages {:.2} ms (value {value:.2}, budget {budget:.2}, draw lists {draw_lists:.2}), wind {wind:.2} ms ({updated:.0} trees updated and {shared:.0} borrowing {blocks:.0} blocks computed, of {moved:.0} moving; {still:.0} left still, {rings:.0} ring offsets held), group impostors built {build:.2} ms ({built:.2} models a frame; {held} held, {vertices} vertices); mean of {REPORT_FRAMES} frames, {kept} kept last frame's hand-out; {} held, {} groups and {} trees drawn; {} triangles, {} lines, {} points",
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

/// The last frame's diagnostics; the value, budget and draw-lists stages' and the wind's
/// mean times, the trees the wind updated, moved and left still (motion level of
/// detail), and the group impostors' building time and models built, over
/// [`REPORT_FRAMES`] more frames; how many of them kept the hand-out.
fn stage_means(bench: &mut Bench) -> (LodDiagnostics, [f32; 12], u32) {
    let mut sums = [0.0; 12];
    let mut kept = 0;
    for _ in 0..REPORT_FRAMES {
        let builds = |bench: &Bench| {
            bench
                .app
                .world()
                .get_resource::<GroupImpostors>()
                .map_or((0.0, 0), |g| (g.build_ms(), g.builds()))
        };
        let (_, built_before) = builds(bench);
        bench.update();
        let (build_ms, built_after) = builds(bench);
        let world = bench.app.world();
        let d = world.resource::<LodDiagnostics>();
        let wind = world.resource::<WindStats>();
        kept += u32::from(d.selection_kept);
        for (sum, ms) in sums.iter_mut().zip([
            d.value_stage_ms,
            d.budget_stage_ms,
            d.draw_lists_stage_ms,
            wind.update_ms,
            wind.updated as f32,
            wind.moved as f32,
            wind.skipped as f32,
            wind.rings_held as f32,
            wind.shared as f32,
            wind.shared_updated as f32,
            build_ms,
            (built_after - built_before) as f32,
        ]) {
            *sum += ms / REPORT_FRAMES as f32;
        }
    }
    let world = bench.app.world();
    (world.resource::<LodDiagnostics>().clone(), sums, kept)
}

criterion_group!(benches, stages);
criterion_main!(benches);
