//! The time-critical LOD stages in a headless app: the default forest, culled and
//! budgeted against a fixed view.

use crate::testing as common;

use crate::cost::{CostModel, CostSettings};
use crate::culling::ForestCulling;
use crate::draw::TreeDrawList;
use crate::lod::StrategyKind;
use crate::prelude::*;
use bevy::prelude::*;

const EYE: Vec3 = Vec3::new(60.0, 14.0, 40.0);
const LOOK_AT: Vec3 = Vec3::new(140.0, 4.0, 120.0);

fn app() -> App {
    common::default_forest_view(EYE, LOOK_AT, |_| {})
}

fn frame(app: &mut App, budget: FrameBudget) -> LodDiagnostics {
    *app.world_mut().resource_mut::<FrameBudget>() = budget;
    app.update();
    app.world().resource::<LodDiagnostics>().clone()
}

fn with(mode: LodMode, target_ms: f32) -> FrameBudget {
    FrameBudget {
        mode,
        target_ms,
        ..Default::default()
    }
}

/// Draw lists of the instances culling found visible, and of the rest.
fn lists(app: &mut App) -> (Vec<TreeDrawList>, Vec<TreeDrawList>) {
    let world = app.world_mut();
    let culling = world.resource::<ForestCulling>();
    let entities = world.resource::<ForestInstances>().entities.clone();
    let visible: Vec<bool> = (0..entities.len())
        .map(|i| culling.result.visibility[i] != Default::default())
        .collect();
    let mut seen = Vec::new();
    let mut unseen = Vec::new();
    for (e, v) in entities.into_iter().zip(visible) {
        let list = world.get::<TreeDrawList>(e).cloned().unwrap_or_default();
        if v {
            seen.push(list);
        } else {
            unseen.push(list);
        }
    }
    (seen, unseen)
}

fn total(d: &LodDiagnostics) -> u64 {
    d.counts.triangles + d.counts.lines + d.counts.points
}

#[test]
fn more_time_never_draws_fewer_primitives() {
    let mut app = app();
    for mode in [LodMode::Tc, LodMode::Tclod] {
        // Ordered by the rendering time each frame was given: the target less the logic
        // measured so far in that frame, which the machine's load moves (a test binary
        // beside this one can take a frame's logic past a low target's difference).
        let mut frames: Vec<(f32, u64, f32)> = [5.0, 20.0, 40.0, 80.0, 160.0, 320.0, 640.0, 5000.0]
            .into_iter()
            .map(|target| {
                let d = frame(&mut app, with(mode, target));
                assert!(d.visible_instances > 20, "{d:?}");
                (d.render_budget_ms, total(&d), target)
            })
            .collect();
        frames.sort_by(|a, b| a.0.total_cmp(&b.0));
        for pair in frames.windows(2) {
            let ((less_ms, fewer, at), (more_ms, more, then)) = (pair[0], pair[1]);
            assert!(
                more >= fewer,
                "{mode:?}: {more_ms} ms of rendering (target {then} ms) draw {more} primitives, \
                 fewer than {fewer} with {less_ms} ms (target {at} ms)"
            );
        }
    }
}

#[test]
fn with_no_time_every_visible_object_is_still_drawn() {
    let mut app = app();
    for mode in [LodMode::Tc, LodMode::Tclod] {
        let d = frame(&mut app, with(mode, 0.0));
        assert_eq!(d.render_budget_ms, 0.0);
        assert_eq!(d.undrawn, 0);
        // Every object at its cheapest: the floors, all beyond the (zero) rendering time.
        let selection = d.predicted_render_ms - d.render_fixed_ms;
        assert!(d.floor_ms > 0.0, "{mode:?}: {d:?}");
        assert!(
            (selection - d.floor_ms).abs() <= 1e-3 * d.floor_ms,
            "{mode:?}: {d:?}"
        );
        assert_eq!(d.floor_excess_ms, d.floor_ms, "{mode:?}: {d:?}");
        let (seen, unseen) = lists(&mut app);
        assert!(!seen.is_empty());
        assert!(
            seen.iter().all(|l| !l.is_empty()),
            "{mode:?}: a visible tree is undrawn"
        );
        assert!(
            unseen.iter().all(TreeDrawList::is_empty),
            "{mode:?}: an invisible tree is drawn"
        );
    }
}

#[test]
fn the_prediction_stays_within_the_rendering_time() {
    let _measuring = common::measuring();
    let mut app = app();
    for mode in [LodMode::Tc, LodMode::Tclod] {
        for target in [30.0, 60.0, 120.0, 250.0, 1000.0] {
            let d = frame(&mut app, with(mode, target));
            assert!(d.predicted_render_ms.is_finite() && d.predicted_frame_ms.is_finite());
            if d.truncated == 0 {
                assert!(
                    d.predicted_render_ms
                        <= (d.render_fixed_ms + d.render_budget_ms) * 1.0001 + 1e-6,
                    "{mode:?} at {target} ms: {d:?}"
                );
            } else {
                assert!(d.predicted_render_ms > 0.0);
            }
            assert_eq!(d.undrawn, 0);
        }
    }
}

#[test]
fn modes_and_targets_switch_at_run_time_without_respawning() {
    let mut app = app();
    let instances = app.world().resource::<ForestInstances>().entities.clone();
    let unlimited = frame(&mut app, with(LodMode::Unlimited, 50.0));
    let static_lod = frame(&mut app, with(LodMode::Static, 50.0));
    let tight = frame(&mut app, with(LodMode::Tclod, 50.0));
    let loose = frame(&mut app, with(LodMode::Tclod, 2000.0));
    let tc = frame(&mut app, with(LodMode::Tc, 50.0));
    assert_eq!(
        app.world().resource::<ForestInstances>().entities,
        instances
    );

    assert_eq!(unlimited.counts.lines + unlimited.counts.points, 0);
    assert!(
        static_lod.counts.lines + static_lod.counts.points > 0,
        "{static_lod:?}"
    );
    assert!(static_lod.counts.triangles < unlimited.counts.triangles);
    assert_eq!(tc.counts.lines + tc.counts.points, 0);
    assert!(tc.counts.triangles < unlimited.counts.triangles);
    assert!(tight.counts.triangles < loose.counts.triangles);
    // A target the same again gives the same selection: nothing drifts between frames.
    let again = frame(&mut app, with(LodMode::Tclod, 50.0));
    assert_eq!(again.counts, tight.counts);
}

#[test]
fn a_target_below_the_logic_time_is_clamped_not_negative() {
    let mut app = app();
    let d = frame(&mut app, with(LodMode::Tclod, -5.0));
    assert_eq!(d.render_budget_ms, 0.0);
    assert!(d.logic_ms > 0.0);
    assert!(d.target_below_logic, "reported in the diagnostics at once");
    let d = frame(&mut app, with(LodMode::Tclod, f32::NAN));
    assert_eq!(d.render_budget_ms, 0.0);
    assert_eq!(d.undrawn, 0);
    assert!(d.target_below_logic);
    // A reachable target, or a mode without a budget, is not below anything.
    assert!(!frame(&mut app, with(LodMode::Tclod, 10_000.0)).target_below_logic);
    assert!(!frame(&mut app, with(LodMode::Unlimited, -5.0)).target_below_logic);
}

/// A target that stays unreachable is announced once, after a few seconds, to the app's
/// observers; a reachable one in between announces the next failure again.
#[test]
fn an_unreachable_target_is_announced_once() {
    use crate::lod::{TargetUnreachable, Unreachable};
    #[derive(Resource, Default)]
    struct Alerts(Vec<Unreachable>);
    let mut app = app();
    app.init_resource::<Alerts>().add_observer(
        |alert: On<TargetUnreachable>, mut alerts: ResMut<Alerts>| {
            alerts.0.push(alert.cause);
        },
    );
    let until = |app: &mut App, budget: FrameBudget, seconds: f32| {
        let start = std::time::Instant::now();
        while start.elapsed().as_secs_f32() < seconds {
            frame(app, budget.clone());
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
    };
    until(&mut app, with(LodMode::Tclod, -5.0), 1.0);
    assert!(app.world().resource::<Alerts>().0.is_empty(), "not at once");
    until(&mut app, with(LodMode::Tclod, -5.0), 3.0);
    assert_eq!(
        app.world().resource::<Alerts>().0,
        [Unreachable::BelowLogic]
    );
    until(&mut app, with(LodMode::Tclod, 10_000.0), 0.2);
    until(&mut app, with(LodMode::Tclod, -5.0), 3.5);
    assert_eq!(
        app.world().resource::<Alerts>().0,
        [Unreachable::BelowLogic, Unreachable::BelowLogic]
    );
}

#[test]
fn ladder_strategies_may_drop_objects_and_say_so() {
    let mut app = app();
    let strategies = [
        StrategyKind::FunkhouserSequin,
        StrategyKind::FunkhouserIncremental,
        StrategyKind::TriangleBudget,
    ];
    for strategy in strategies {
        for target in [5.0, 40.0, 200.0, 2000.0] {
            let budget = FrameBudget {
                strategy,
                target_ms: target,
                ..Default::default()
            };
            let d = frame(&mut app, budget.clone());
            // The incremental strategy starts from last frame: give it a second frame.
            let d = if strategy == StrategyKind::FunkhouserIncremental {
                frame(&mut app, budget)
            } else {
                d
            };
            assert!(d.predicted_render_ms.is_finite());
            // The greedy drops what does not fit; the triangle budget never goes below
            // every object's cheapest level and reports the overrun.
            if strategy == StrategyKind::TriangleBudget {
                // It never drops an object; what its cheapest levels cost beyond the
                // rendering time is reported as the overrun.
                assert_eq!(d.undrawn, 0, "{strategy:?} at {target} ms: {d:?}");
                let selection = d.predicted_render_ms - d.render_fixed_ms;
                assert!(
                    selection <= d.render_budget_ms * 1.0001 + d.overrun_ms + 1e-4,
                    "{strategy:?} at {target} ms: {d:?}"
                );
            } else {
                assert!(
                    d.predicted_render_ms
                        <= (d.render_fixed_ms + d.render_budget_ms) * 1.0001 + 1e-6,
                    "{strategy:?} at {target} ms overspends: {d:?}"
                );
            }
            let (seen, _) = lists(&mut app);
            let empty = seen.iter().filter(|l| l.is_empty()).count() as u32;
            // A tree is empty only when both its parts were dropped.
            assert!(
                empty <= d.undrawn,
                "{strategy:?} at {target} ms: {empty} empty trees, {} dropped objects",
                d.undrawn
            );
            if target == 5.0 && strategy == StrategyKind::FunkhouserSequin {
                assert!(
                    d.undrawn > 0,
                    "with 1 ms for {} objects something must go",
                    d.visible_objects
                );
            }
            if target == 2000.0 {
                assert_eq!(
                    d.undrawn, 0,
                    "{strategy:?} drops objects with time to spare"
                );
            }
        }
    }
    // Back to Robin Hood: nothing dropped.
    let d = frame(&mut app, with(LodMode::Tclod, 5.0));
    assert_eq!(d.undrawn, 0);
}

#[test]
fn the_diagnostics_plugin_publishes_the_frame() {
    use bevy::diagnostic::{DiagnosticPath, DiagnosticsStore};
    let mut app = app();
    app.add_plugins(LodDiagnosticsPlugin);
    frame(&mut app, with(LodMode::Tclod, 100.0));
    let d = frame(&mut app, with(LodMode::Tclod, 100.0));
    let store = app.world().resource::<DiagnosticsStore>();
    let read = |path: &'static str| {
        store
            .get(&DiagnosticPath::const_new(path))
            .and_then(bevy::diagnostic::Diagnostic::value)
            .unwrap_or_else(|| panic!("{path} not published"))
    };
    assert_eq!(
        read("sherwood/visible_objects"),
        f64::from(d.visible_objects)
    );
    assert_eq!(read("sherwood/triangles"), d.counts.triangles as f64);
    assert!(read("sherwood/render_budget") > 0.0);
}

#[test]
fn the_budget_chooses_the_calibration_file_and_a_bad_one_falls_back() {
    use crate::cost::Calibration;
    use crate::cost::CalibrationChoice;
    let dir = std::env::temp_dir().join(format!("sherwood-lod-calibration-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut app = common::app_reading(&dir, CostPlugin);
    let mut measured = Calibration {
        adapter: "test adapter".into(),
        ..Default::default()
    };
    measured.triangles.per_primitive = 7e-6;
    std::fs::write(
        dir.join("good.calibration.ron"),
        measured.to_ron_string().unwrap(),
    )
    .unwrap();
    std::fs::write(dir.join("bad.calibration.ron"), "(triangles: (fixed: -1))").unwrap();
    // Loading takes a few frames: until the model's calibration is `until` (bounded).
    let choose = |app: &mut App, choice: CalibrationChoice, until: &Calibration| {
        app.world_mut().resource_mut::<CostSettings>().calibration = choice;
        for _ in 0..2000 {
            app.update();
            if app.world().resource::<CostModel>().calibration() == until {
                break;
            }
            std::thread::sleep(std::time::Duration::from_millis(2));
        }
        app.world().resource::<CostModel>().calibration().clone()
    };
    assert_eq!(
        choose(
            &mut app,
            CalibrationChoice::File("good.calibration.ron".into()),
            &measured
        ),
        measured
    );
    assert_eq!(
        choose(
            &mut app,
            CalibrationChoice::File("bad.calibration.ron".into()),
            &Calibration::default()
        ),
        Calibration::default()
    );
    // Keep: what code put there stays.
    app.world_mut()
        .resource_mut::<CostModel>()
        .set_calibration(measured.clone());
    assert_eq!(
        choose(&mut app, CalibrationChoice::Keep, &measured),
        measured
    );
    app.update();
    assert_eq!(*app.world().resource::<CostModel>().calibration(), measured);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Thesis §6.5 and the floors: the selection's predicted cost stays within the rendering
/// time except by the reported excess of the floors, grows with the target, and reaches
/// full detail once the target pays for it.
#[test]
fn the_selection_spends_its_time_up_to_full_detail() {
    let mut app = app();
    app.update();
    let unlimited = frame(&mut app, with(LodMode::Unlimited, 100.0));
    for mode in [LodMode::Tclod, LodMode::Tc] {
        // (rendering time given, selection): ordered by the time given, since the logic
        // measured so far in a frame (real time, moved by the machine's load) comes off
        // each target.
        let mut spent = Vec::new();
        let mut full_at = None;
        let mut target = 0.5;
        while target < 200_000.0 {
            let d = frame(&mut app, with(mode, target));
            let selection = d.predicted_render_ms - d.render_fixed_ms;
            assert!(
                selection <= d.render_budget_ms * 1.0001 + d.floor_excess_ms + 1e-4,
                "{mode:?} at {target} ms: {d:?}"
            );
            spent.push((d.render_budget_ms, selection, target));
            assert_eq!(d.undrawn, 0);
            if full_at.is_none() && d.counts == unlimited.counts {
                full_at = Some(target);
            }
            target *= 1.5;
        }
        spent.sort_by(|a, b| a.0.total_cmp(&b.0));
        for pair in spent.windows(2) {
            let ((_, previous, at), (_, selection, then)) = (pair[0], pair[1]);
            assert!(
                selection >= previous * 0.9999,
                "{mode:?} at {then} ms: {selection} ms after {previous} ms at {at} ms"
            );
        }
        let full_at = full_at.unwrap_or_else(|| panic!("{mode:?} never reaches full detail"));
        // Full detail as soon as the target covers it (the sweep's next step).
        assert!(
            full_at <= 1.5 * unlimited.predicted_frame_ms,
            "{mode:?}: full detail only at {full_at} ms, unlimited predicts {} ms",
            unlimited.predicted_frame_ms
        );
    }
    // With a target below what the floors cost, the excess is reported.
    let d = frame(&mut app, with(LodMode::Tclod, 0.5));
    assert!(
        d.floor_excess_ms > 0.0 && d.floor_ms > d.render_budget_ms,
        "{d:?}"
    );
}

#[test]
fn far_trees_decided_in_turn_keep_their_lists_and_their_time() {
    // From high above, most trees are far and entirely in view: decided as a whole.
    let mut app = common::default_forest_view(
        Vec3::new(-60.0, 120.0, -60.0),
        Vec3::new(120.0, 0.0, 120.0),
        |_| {},
    );
    let budget = |far_refresh| FrameBudget {
        target_ms: 60.0,
        far_refresh,
        ..Default::default()
    };
    let d = frame(&mut app, budget(1));
    assert_eq!(d.held_trees, 0, "every tree decided every frame by default");
    let mut held = 0;
    for _ in 0..4 {
        let d = frame(&mut app, budget(2));
        held = held.max(d.held_trees);
        // Held trees are still visible and drawn; their time is taken off the rest's.
        assert_eq!(d.undrawn, 0);
        let (seen, unseen) = lists(&mut app);
        assert!(
            seen.iter().all(|l| !l.is_empty()),
            "a visible tree draws nothing"
        );
        assert!(unseen.iter().all(TreeDrawList::is_empty));
        let selection = d.predicted_render_ms - d.render_fixed_ms;
        assert!(
            selection <= d.render_budget_ms * 1.0001 + d.floor_excess_ms + 1e-4,
            "{d:?}"
        );
    }
    assert!(held > 10, "far trees take turns ({held} held)");
    // A tree planted a frame (and the last one felled) does not make every tree decide
    // anew.
    let model = app
        .world()
        .resource::<AssetServer>()
        .load("species/broad.species.ron");
    let mut planted = None;
    for k in 0..4 {
        let at = Vec3::new(60.0 + 10.0 * k as f32, 0.0, 60.0);
        common::replant(&mut app, &mut planted, &model, at);
        let d = frame(&mut app, budget(2));
        assert!(
            d.held_trees > 10,
            "planting {k}: only {} held",
            d.held_trees
        );
    }
    // Back to every frame.
    assert_eq!(frame(&mut app, budget(1)).held_trees, 0);
}

/// What the cost model learns from (the selection by family, as the calibration prices
/// it) is what was drawn: repriced with the model's factors it is the predicted rendering
/// less the fixed part, at every target and mode. Robin Hood's residue passes offer an
/// object more time and replace its first choice; only the last may be counted.
#[test]
fn the_selection_learned_from_is_the_selection_drawn() {
    // From outside the forest, far: most trees drawn as points and lines, few triangles,
    // and time left for residue passes at the middle targets.
    let mut app = common::default_forest_view(
        Vec3::new(-160.0, 40.0, -160.0),
        Vec3::new(100.0, 0.0, 100.0),
        |_| {},
    );
    let mut checked = 0;
    for mode in [LodMode::Tclod, LodMode::Tc] {
        for target_ms in [2.0, 4.0, 8.0, 20.0, 40.0, 80.0, 160.0] {
            let d = frame(&mut app, with(mode, target_ms));
            let (c, k) = (d.calibrated, d.learned.scales);
            let repriced = 1000.0
                * (c.triangles * k.triangles
                    + c.triangle_pixels * k.triangle_pixels
                    + c.lines * k.lines
                    + c.points * k.points
                    + c.meshes * k.meshes);
            let predicted = d.predicted_render_ms - d.render_fixed_ms;
            assert!(
                (repriced - predicted).abs() <= 0.01 * predicted + 1e-3,
                "{mode:?} at {target_ms} ms: the recorded selection costs {repriced} ms, the \
                 hand-out's {predicted} ms ({c:?})"
            );
            checked += 1;
        }
    }
    assert_eq!(checked, 14);
}

/// The app's game logic, busy this frame.
#[derive(Resource, Default)]
struct BusyLogic(std::time::Duration);

fn busy_logic(busy: Res<BusyLogic>) {
    let start = std::time::Instant::now();
    while start.elapsed() < busy.0 {
        std::hint::spin_loop();
    }
}

/// A step in the app's own logic (a busy system in `Update`) has already run when the
/// Budget stage hands out the frame's time: it is in this frame's prediction, not learned
/// frames later.
#[test]
fn a_step_in_the_app_s_logic_is_in_the_same_frame_s_budget() {
    let _measuring = common::measuring();
    let mut app = app();
    app.init_resource::<BusyLogic>()
        .add_systems(Update, busy_logic);
    let before = frame(&mut app, with(LodMode::Tclod, 200.0));
    let step = std::time::Duration::from_millis(60);
    app.world_mut().resource_mut::<BusyLogic>().0 = step;
    let after = frame(&mut app, with(LodMode::Tclod, 200.0));
    // The learned logic cannot reach the step in one frame: a prediction of at least the
    // step is the step measured. (Not compared with the frame before's, whose logic other
    // tests running beside this one can lengthen.)
    assert!(
        after.logic_so_far_ms >= 60.0 && after.logic_ms >= 60.0,
        "the step's frame predicted {} ms of logic ({} ms so far), the frame before {} ms",
        after.logic_ms,
        after.logic_so_far_ms,
        before.logic_ms
    );
    // (How much rendering time it leaves depends on how logic and rendering overlap: with
    // pipelined rendering, nothing until the logic is the longer of the two.)
}

#[test]
fn the_benefit_report_scores_every_strategy_below_its_bound_and_at_it_with_time_to_spare() {
    use crate::lod::BenefitReport;
    let mut app = app();
    let strategies = [
        StrategyKind::RobinHood,
        StrategyKind::FunkhouserSequin,
        StrategyKind::TriangleBudget,
        StrategyKind::Hierarchical,
    ];
    // Off by default: nothing is scored.
    let d = frame(&mut app, with(LodMode::Tclod, 40.0));
    assert_eq!((d.benefit, d.benefit_bound), (0.0, 0.0), "{d:?}");
    app.world_mut().resource_mut::<BenefitReport>().enabled = true;
    for strategy in strategies {
        for target in [200.0, 1000.0] {
            let budget = FrameBudget {
                strategy,
                target_ms: target,
                ..Default::default()
            };
            // The hierarchical cut refines from last frame's over a few frames.
            for _ in 0..30 {
                frame(&mut app, budget.clone());
            }
            let d = frame(&mut app, budget);
            assert!(d.benefit > 0.0, "{strategy:?} at {target} ms: {d:?}");
            // Cheapest representations beyond the rendering time (a loaded machine's debug
            // frame can leave none) are the one way past the bound.
            if d.overrun_ms == 0.0 {
                assert!(
                    d.benefit <= d.benefit_bound * 1.001,
                    "{strategy:?} at {target} ms: benefit {} of bound {}: {d:?}",
                    d.benefit,
                    d.benefit_bound
                );
            }
        }
    }
    // With time for everything at full detail, the bound is every object's whole value
    // and Robin Hood reaches it.
    frame(&mut app, with(LodMode::Tclod, 1.0e6));
    let d = frame(&mut app, with(LodMode::Tclod, 1.0e6));
    assert!(d.benefit_bound > 0.0);
    assert!(
        (d.benefit - d.benefit_bound).abs() <= 1e-3 * d.benefit_bound,
        "benefit {} of bound {} with unlimited time",
        d.benefit,
        d.benefit_bound
    );
}

/// The draw lists the trees were given, priced apart from the search that chose them:
/// their primitives at the calibration's per-primitive costs (width by width, size by
/// size; no pixels, so a lower bound of what they cost) fit in the rendering time.
#[test]
fn the_draw_lists_written_are_priced_within_the_rendering_time() {
    use crate::draw::ModelSlot;
    use crate::tree::TreeModel;
    let mut app = app();
    for mode in [LodMode::Tc, LodMode::Tclod] {
        for target in [40.0, 120.0, 400.0] {
            frame(&mut app, with(mode, target));
            let d = frame(&mut app, with(mode, target));
            let world = app.world_mut();
            let calibration = world.resource::<CostModel>().calibration().clone();
            let sized = |costs: &[crate::cost::LinearCost], px: u32| {
                costs[(px.max(1) as usize - 1).min(costs.len() - 1)].per_primitive
            };
            let mut query = world.query::<(&TreeInstance, &TreeDrawList)>();
            let models = world.resource::<Assets<TreeModel>>();
            let mut price = 0.0_f64;
            let mut trees = 0;
            for (tree, list) in query.iter(world) {
                let Some(model) = models.get(&tree.model) else {
                    continue;
                };
                if list.is_empty() {
                    continue;
                }
                trees += 1;
                let slot = ModelSlot::of(model);
                let counts = slot.counts(list);
                price += counts.triangles as f64 * f64::from(calibration.triangles.per_primitive);
                for run in &list.trunk_lines {
                    let n = run.segments.len().min(model.segments.len()) as f64;
                    price += n * f64::from(sized(&calibration.lines, run.width));
                }
                for run in &list.leaf_points {
                    let n = run.leaves.len().min(model.leaves.len()) as f64;
                    price += n * f64::from(sized(&calibration.points, run.size));
                }
            }
            assert!(trees > 20, "{mode:?} at {target} ms: {trees} trees drawn");
            if d.truncated == 0 && d.overrun_ms == 0.0 {
                let price_ms = price * 1000.0;
                assert!(
                    price_ms <= f64::from(d.render_budget_ms) * 1.001 + 1e-3,
                    "{mode:?} at {target} ms: the lists cost at least {price_ms:.3} ms of {} ms: {d:?}",
                    d.render_budget_ms
                );
            }
        }
    }
}
