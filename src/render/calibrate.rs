//! Measures what this adapter's primitives and this app's logic cost, through the real
//! forest pass and over the user's own scene, and writes a `*.calibration.ron`
//! (thesis §6.2).
//!
//! [`CalibrationRunPlugin`] takes over the first 3D camera while it runs:
//!
//! 1. **Rendering**: the camera looks at the empty sky; benchmark trees of the scene's
//!    most complex model are spawned in front of it with draw lists of one primitive
//!    family only — triangles (full detail), lines of one width, points of one size —
//!    at several total primitive counts and, for triangles and lines, two distances (so
//!    covered pixels vary apart from the count). Each configuration's time is the median
//!    of the render world's time ([`FrameSample::render`](crate::cost::FrameSample::render)) less that of an empty frame,
//!    which is kept as [`Calibration::render_fixed`]. Pixels are the LOD's
//!    own estimates ([`crate::lod::select`]), so the fitted per-pixel parts are in the
//!    units the budget predicts with. Each family, and each width and size, is fitted
//!    with [`fit_nonnegative_cost`]: points' pixels follow their count at one size, so
//!    points get a fixed and a per-point part per size; widths and sizes between the
//!    measured ones are interpolated ([`fit_sized_costs`]).
//! 2. **Logic**: the scene's forest comes back, and the camera walks two sampling paths
//!    at a corner of it — turning from looking away to looking at its centre (visible
//!    count rising from none to most of the forest), and back (falling) — at a few
//!    targets in TCLOD mode. Each position's logic time is the median of the main world's
//!    update ([`FrameSample::logic`](crate::cost::FrameSample::logic)): app logic, the Sherwood stages and their search,
//!    everything but the wait for the render world.
//!
//! At the end the calibration is written (by default to
//! `assets/calibration/<adapter>.calibration.ron`, where [`CalibrationChoice::Adapter`]
//! finds it), installed in the [`CostModel`], and [`CalibrationProgress::outcome`] is set;
//! the camera, budget, cost and wind settings are restored. A progress bar is printed on
//! the terminal and a progress line shown on screen. Frames are only measured when every
//! pipeline was ready ([`FrameSample::complete`](crate::cost::FrameSample::complete)).
//!
//! [`CalibrationChoice::Adapter`]: crate::cost::CalibrationChoice::Adapter

use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

use bevy::prelude::*;

use crate::cost::{
    AdapterIdentity, Calibration, CalibrationDir, CostModel, CostSample, CostSettings,
    FrameSamples, LinearCost, LogicTable, MeshPathCost, add_to_index, calibration_file_name,
    fit_nonnegative_cost, fit_sized_costs,
};
use crate::culling::ForestCulling;
use crate::draw::{LineRun, PointRun, TreeDrawList};
use crate::instance::{FixedDrawList, ForestInstances, TreeInstance};
use crate::lod::select::{PROJECTED_LENGTH_FACTOR, TreeView, group_area, trunk_triangle_area};
use crate::lod::{FrameBudget, LodDiagnostics, LodMode};
use crate::tree::{Projection, TreeModel};
use crate::wind::WindSettings;

/// What the calibration run measures. The defaults took about 25 minutes on a 2-core
/// machine rendering with lavapipe (137 configurations, frames of up to a second).
#[derive(Resource, Clone, Debug, PartialEq, Reflect)]
#[reflect(Resource)]
pub struct CalibrationSettings {
    /// Where to write the calibration; `None`: the [`CalibrationDir`] under the adapter's
    /// `calibration_file_name`.
    pub out: Option<PathBuf>,
    /// Frames after each change before measuring (pipelines, late timestamps).
    pub settle_frames: u32,
    /// Frames measured per configuration (the median is kept).
    pub frames_per_sample: u32,
    /// Total primitives per frame of each rendering configuration.
    pub primitive_counts: Vec<u32>,
    /// Line widths and point sizes measured, pixels.
    pub sizes: Vec<u32>,
    /// Targets (ms) the logic benchmark runs at.
    pub logic_targets_ms: Vec<f32>,
    /// Camera positions along each logic sampling path.
    pub logic_positions: u32,
}

impl Default for CalibrationSettings {
    fn default() -> Self {
        Self {
            out: None,
            settle_frames: 4,
            frames_per_sample: 7,
            primitive_counts: vec![15_000, 45_000, 120_000],
            sizes: vec![1, 2, 3, 4, 6, 8, 12, 16, 20],
            logic_targets_ms: vec![50.0, 100.0, 200.0],
            logic_positions: 8,
        }
    }
}

/// How far the calibration run is.
#[derive(Resource, Clone, Debug, Default, PartialEq)]
pub struct CalibrationProgress {
    /// Configurations measured.
    pub done: u32,
    /// Configurations in all (0 until the scene is ready).
    pub total: u32,
    /// What is being measured.
    pub label: String,
    /// Set once at the end: the file written, or why nothing was.
    pub outcome: Option<Result<PathBuf, String>>,
}

/// Runs the calibration benchmarks once the scene's forest has loaded; see the
/// module docs. Configure it with a [`CalibrationSettings`] resource.
#[derive(Default)]
pub struct CalibrationRunPlugin;

impl Plugin for CalibrationRunPlugin {
    fn build(&self, app: &mut App) {
        app.register_type::<CalibrationSettings>()
            .init_resource::<CalibrationSettings>()
            .init_resource::<CalibrationProgress>()
            .init_resource::<RunState>()
            .add_systems(
                Update,
                (run_calibration, show_progress)
                    .chain()
                    .in_set(CalibrationRunSystems),
            );
    }
}

/// The calibration run's systems (in `Update`): order camera controllers before them.
#[derive(SystemSet, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct CalibrationRunSystems;

/// A primitive family of the rendering benchmark.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Family {
    Triangles,
    Lines,
    Points,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Step {
    /// Every primitive kind drawn until the pipelines have compiled; not measured.
    WarmUp,
    /// Nothing drawn: the baseline frame.
    Empty,
    Render {
        family: Family,
        size: u32,
        primitives: u32,
        /// Fraction of the view's height a tree covers.
        tree_fraction: f32,
    },
    Logic {
        target_ms: f32,
        /// 0 = looking away from the forest, 1 = at its centre.
        turn: f32,
    },
}

impl Step {
    fn label(&self) -> String {
        match *self {
            Step::WarmUp => "compiling pipelines".into(),
            Step::Empty => "empty frame".into(),
            Step::Render {
                family,
                size,
                primitives,
                tree_fraction,
            } => {
                let what = match family {
                    Family::Triangles => "triangles".to_owned(),
                    Family::Lines => format!("lines {size} px"),
                    Family::Points => format!("points {size} px"),
                };
                format!(
                    "rendering: {primitives} {what}, trees {:.0}% of the view",
                    tree_fraction * 100.0
                )
            }
            Step::Logic { target_ms, turn } => {
                format!("logic: target {target_ms} ms, turn {:.0}%", turn * 100.0)
            }
        }
    }
}

/// Frame measurements of one step.
#[derive(Default)]
struct Measured {
    render_ms: Vec<f32>,
    logic_ms: Vec<f32>,
    visible: Vec<u32>,
}

struct Saved {
    camera: Transform,
    budget: FrameBudget,
    wind: bool,
    cost: CostSettings,
}

#[derive(Resource, Default)]
struct RunState {
    plan: Vec<Step>,
    step: usize,
    frame_in_step: u32,
    measured: Measured,
    model: Option<Handle<TreeModel>>,
    bench: Vec<Entity>,
    saved: Option<Saved>,
    /// The forest's instances: bounds of their positions.
    forest_min: Vec3,
    forest_max: Vec3,
    /// The render world's time with nothing drawn, ms.
    empty_render_ms: f32,
    render_samples: Vec<(Family, u32, CostSample)>,
    logic_samples: Vec<(f32, u32, f32)>,
    step_started: Option<Instant>,
    finished: bool,
}

/// The median of the finite values.
fn median(values: impl IntoIterator<Item = f32>) -> Option<f32> {
    let mut values: Vec<f32> = values.into_iter().filter(|v| v.is_finite()).collect();
    if values.is_empty() {
        return None;
    }
    values.sort_by(f32::total_cmp);
    Some(values[values.len() / 2])
}

fn plan(settings: &CalibrationSettings) -> Vec<Step> {
    let mut plan = vec![Step::WarmUp, Step::Empty];
    let fractions = [0.5, 0.12];
    for &primitives in &settings.primitive_counts {
        for &tree_fraction in &fractions {
            plan.push(Step::Render {
                family: Family::Triangles,
                size: 1,
                primitives,
                tree_fraction,
            });
        }
    }
    for &size in &settings.sizes {
        for &primitives in &settings.primitive_counts {
            for &tree_fraction in &fractions {
                plan.push(Step::Render {
                    family: Family::Lines,
                    size,
                    primitives,
                    tree_fraction,
                });
            }
            plan.push(Step::Render {
                family: Family::Points,
                size,
                primitives,
                tree_fraction: fractions[1],
            });
        }
    }
    let n = settings.logic_positions.max(2);
    for &target_ms in &settings.logic_targets_ms {
        // Rising, then falling.
        for i in (0..n).chain((0..n).rev()) {
            plan.push(Step::Logic {
                target_ms,
                turn: i as f32 / (n - 1) as f32,
            });
        }
    }
    plan
}

fn run_calibration(
    mut commands: Commands,
    // One parameter: a system takes at most 16.
    (settings, calibration_dir): (Res<CalibrationSettings>, Res<CalibrationDir>),
    mut state: ResMut<RunState>,
    mut progress: ResMut<CalibrationProgress>,
    (culling, table): (Res<ForestCulling>, Res<ForestInstances>),
    instances: Query<&TreeInstance>,
    models: Res<Assets<TreeModel>>,
    adapter: Option<Res<AdapterIdentity>>,
    mut cameras: Query<(&mut Transform, &Camera, Option<&crate::view::LodView>), With<Camera3d>>,
    mut budget: ResMut<FrameBudget>,
    mut wind: ResMut<WindSettings>,
    (mut cost_model, mut cost_settings): (ResMut<CostModel>, ResMut<CostSettings>),
    samples: Res<FrameSamples>,
    diagnostics: Res<LodDiagnostics>,
) {
    let state = &mut *state;
    if state.finished {
        return;
    }
    let Ok((mut camera_transform, camera, lod_view)) = cameras.single_mut() else {
        return;
    };
    if state.plan.is_empty() {
        // Wait for the forest, its models and the adapter.
        let loaded = culling.hierarchy.is_some() && culling.models_loading() == 0;
        if !loaded || adapter.is_none() || lod_view.is_none() {
            return;
        }
        let Some(model) = largest_model(&table, &instances, &models) else {
            return;
        };
        (state.forest_min, state.forest_max) = forest_bounds(&culling);
        state.model = Some(model);
        state.plan = plan(&settings);
        state.saved = Some(Saved {
            camera: *camera_transform,
            budget: budget.clone(),
            wind: wind.enabled,
            cost: cost_settings.clone(),
        });
        // The benchmark measures the calibration's own costs: nothing is learned meanwhile.
        cost_settings.online = false;
        progress.total = state.plan.len() as u32;
    }
    let Some(model_handle) = state.model.clone() else {
        return;
    };
    let Some(model) = models.get(&model_handle) else {
        return;
    };
    let step = state.plan[state.step];
    let viewport = camera
        .physical_viewport_size()
        .unwrap_or(UVec2::new(960, 540));
    let focal = lod_view.map_or(1.0, |v| v.focal_pixels);

    if state.frame_in_step == 0 {
        for e in state.bench.drain(..) {
            commands.entity(e).despawn();
        }
        progress.label = step.label();
        state.step_started = Some(Instant::now());
        begin_step(
            step,
            state,
            &mut commands,
            &model_handle,
            model,
            &mut camera_transform,
            (&mut budget, &mut wind),
            (focal, viewport),
        );
    } else if state.frame_in_step > settings.settle_frames {
        // (Samples arrive a frame or two late: the settling frames cover that.)
        let m = &mut state.measured;
        for sample in samples.arrived().iter().filter(|s| s.is_usable()) {
            m.render_ms.push(sample.render * 1000.0);
            m.logic_ms.push(sample.logic * 1000.0);
        }
        m.visible.push(diagnostics.visible_instances);
    }
    state.frame_in_step += 1;
    let measuring_done =
        state.frame_in_step > settings.settle_frames + settings.frames_per_sample.max(1);
    let done = if step == Step::WarmUp {
        // Pipelines compile asynchronously (seconds on a software renderer).
        state.frame_in_step >= 30
            && state
                .step_started
                .is_some_and(|t| t.elapsed().as_secs_f32() >= 8.0)
    } else {
        measuring_done
    };
    if !done {
        return;
    }

    record_step(step, state, model, focal, viewport);
    state.step += 1;
    state.frame_in_step = 0;
    progress.done = state.step as u32;
    if state.step < state.plan.len() {
        return;
    }

    finish(
        state,
        &mut commands,
        &settings,
        &calibration_dir,
        adapter.map(|a| a.clone()).unwrap_or_default(),
        &mut camera_transform,
        (&mut budget, &mut wind),
        (&mut cost_model, &mut cost_settings),
        &mut progress,
    );
}

/// The model of the forest's trees with the most triangles: the benchmark's tree.
fn largest_model(
    table: &ForestInstances,
    instances: &Query<&TreeInstance>,
    models: &Assets<TreeModel>,
) -> Option<Handle<TreeModel>> {
    table
        .entities
        .iter()
        .filter_map(|&e| instances.get(e).ok())
        .max_by_key(|i| {
            models
                .get(&i.model)
                .map_or(0, |m| m.trunk_triangle_count() + m.leaf_triangle_count())
        })
        .map(|i| i.model.clone())
}

/// The bounds of the forest's trees' positions.
fn forest_bounds(culling: &ForestCulling) -> (Vec3, Vec3) {
    culling
        .instances
        .iter()
        .map(|i| Vec3::from(i.transform.translation))
        .fold(
            (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
            |(lo, hi), p| (lo.min(p), hi.max(p)),
        )
}

/// Sets the scene up for `step`: the camera, the benchmark trees, the wind and budget.
fn begin_step(
    step: Step,
    state: &mut RunState,
    commands: &mut Commands,
    model_handle: &Handle<TreeModel>,
    model: &TreeModel,
    camera_transform: &mut Transform,
    (budget, wind): (&mut FrameBudget, &mut WindSettings),
    (focal, viewport): (f32, UVec2),
) {
    match step {
        Step::WarmUp | Step::Empty | Step::Render { .. } => {
            wind.enabled = false;
            // Straight up from the forest, high enough that the ground is out of
            // view, looking at the horizon: nothing but the benchmark is drawn.
            let above = Vec3::new(
                state.forest_min.x,
                state.forest_max.y + 5_000.0,
                state.forest_min.z,
            );
            *camera_transform = Transform::from_translation(above).looking_to(Vec3::X, Vec3::Y);
            if step == Step::WarmUp {
                let list = warm_up_list(model);
                for offset in bench_layout(model, Family::Triangles, 1, 0.3, focal, viewport) {
                    let at = *camera_transform * offset;
                    state.bench.push(
                        commands
                            .spawn(bench_tree(model_handle, list.clone(), at))
                            .id(),
                    );
                }
            }
            if let Step::Render {
                family,
                size,
                primitives,
                tree_fraction,
            } = step
            {
                let layout =
                    bench_layout(model, family, primitives, tree_fraction, focal, viewport);
                let list = bench_list(model, family, size);
                for offset in layout {
                    let at = *camera_transform * offset;
                    state.bench.push(
                        commands
                            .spawn(bench_tree(model_handle, list.clone(), at))
                            .id(),
                    );
                }
            }
        }
        Step::Logic { target_ms, turn } => {
            if let Some(saved) = &state.saved {
                wind.enabled = saved.wind;
                *budget = FrameBudget {
                    target_ms,
                    mode: LodMode::Tclod,
                    ..saved.budget.clone()
                };
            }
            *camera_transform = logic_pose(state.forest_min, state.forest_max, turn);
        }
    }
}

/// Keeps what the frames of the measured `step` showed.
fn record_step(step: Step, state: &mut RunState, model: &TreeModel, focal: f32, viewport: UVec2) {
    // The step is measured.
    let m = std::mem::take(&mut state.measured);
    let render_ms = median(m.render_ms.iter().copied());
    match step {
        Step::WarmUp => {}
        Step::Empty => state.empty_render_ms = render_ms.unwrap_or(0.0),
        Step::Render {
            family,
            size,
            primitives: _,
            tree_fraction,
        } => {
            let n = state.bench.len() as f32;
            let depth = bench_depth(model, tree_fraction, focal, viewport.y as f32);
            let (per_tree_primitives, per_tree_pixels) =
                bench_amounts(model, family, size, depth, focal);
            if let Some(render_ms) = render_ms {
                state.render_samples.push((
                    family,
                    size,
                    CostSample {
                        primitives: n * per_tree_primitives,
                        pixels: n * per_tree_pixels,
                        time: (render_ms - state.empty_render_ms).max(0.0) / 1000.0,
                    },
                ));
            }
        }
        Step::Logic { target_ms, .. } => {
            let mut visible = m.visible.clone();
            visible.sort_unstable();
            let visible = visible.get(visible.len() / 2).copied().unwrap_or(0);
            if let Some(ms) = median(m.logic_ms.iter().copied()) {
                state.logic_samples.push((target_ms, visible, ms / 1000.0));
            }
        }
    }
}

/// Every step measured: the calibration fitted, written and installed, the app restored.
fn finish(
    state: &mut RunState,
    commands: &mut Commands,
    settings: &CalibrationSettings,
    calibration_dir: &CalibrationDir,
    adapter: AdapterIdentity,
    camera_transform: &mut Transform,
    (budget, wind): (&mut FrameBudget, &mut WindSettings),
    (cost_model, cost_settings): (&mut CostModel, &mut CostSettings),
    progress: &mut CalibrationProgress,
) {
    // Every step measured: fit, write, install, restore.
    state.finished = true;
    for e in state.bench.drain(..) {
        commands.entity(e).despawn();
    }
    if let Some(saved) = state.saved.take() {
        *camera_transform = saved.camera;
        *budget = saved.budget;
        wind.enabled = saved.wind;
        *cost_settings = saved.cost;
    }
    let fitted = fit(
        &state.render_samples,
        &state.logic_samples,
        state.empty_render_ms / 1000.0,
        &adapter,
    );
    let outcome = fitted.and_then(|calibration| {
        let file_name = calibration_file_name(&adapter.name);
        let path = settings
            .out
            .clone()
            .unwrap_or_else(|| calibration_dir.0.join(&file_name));
        write(&path, &calibration)?;
        if settings.out.is_none() {
            add_to_index(&calibration_dir.0, &file_name)?;
        }
        print_report(&calibration, &state.render_samples);
        cost_model.set_calibration(calibration);
        Ok(path)
    });
    progress.label = match &outcome {
        Ok(path) => format!("wrote {}", path.display()),
        Err(e) => format!("calibration failed: {e}"),
    };
    progress.outcome = Some(outcome);
}

/// Marks the calibration's benchmark trees.
#[derive(Component)]
struct CalibrationTree;

/// A benchmark tree (outside the instance table: culling and LOD leave it alone, the pass
/// draws its list).
fn bench_tree(
    model: &Handle<TreeModel>,
    list: TreeDrawList,
    at: Vec3,
) -> (
    CalibrationTree,
    TreeInstance,
    FixedDrawList,
    TreeDrawList,
    Transform,
) {
    (
        CalibrationTree,
        TreeInstance::standalone(model.clone()),
        FixedDrawList,
        list,
        Transform::from_translation(at),
    )
}

/// Every primitive kind at once: trunk triangles and lines, leaf triangles and points.
fn warm_up_list(model: &TreeModel) -> TreeDrawList {
    let segments = model.segments.len() as u32;
    let leaves = model.leaves.len() as u32;
    TreeDrawList {
        trunk_triangles: model.segments.triangle_offsets[(segments / 2) as usize]
            ..model.trunk_triangle_count() as u32,
        trunk_lines: vec![LineRun {
            segments: 0..segments / 2,
            width: 3,
        }],
        leaf_triangles: core::iter::once(0..leaves / 2).collect(),
        leaf_points: vec![PointRun {
            leaves: leaves / 2..leaves,
            size: 3,
        }],
    }
}

/// Depth at which the model covers `fraction` of a view `height_px` tall.
fn bench_depth(model: &TreeModel, fraction: f32, focal: f32, height_px: f32) -> f32 {
    let height = (model.bounds.max.y - model.bounds.min.y).max(1e-3);
    height * focal / (fraction * height_px).max(1.0)
}

/// Per tree of the benchmark: primitives of the family and their estimated pixels.
fn bench_amounts(
    model: &TreeModel,
    family: Family,
    size: u32,
    depth: f32,
    focal: f32,
) -> (f32, f32) {
    let view = TreeView {
        scale: 1.0,
        trunk_depth: depth,
        projection: Projection {
            focal_pixels: focal,
        },
    };
    match family {
        Family::Triangles => {
            let trunk = model.trunk_triangle_count() as f32;
            let leaves = model.leaf_triangle_count() as f32;
            let leaf_pixels: f32 = model
                .leaf_groups
                .iter()
                .map(|g| group_area(model, &view, g.leaves.len() as u32, depth))
                .sum();
            (
                trunk + leaves,
                trunk * trunk_triangle_area(model, &view) + leaf_pixels,
            )
        }
        Family::Lines => {
            let length = model
                .segments
                .cumulative_length
                .last()
                .copied()
                .unwrap_or(0.0);
            let px = view.projection.pixels(1.0, depth);
            (
                model.segments.len() as f32,
                length * px * PROJECTED_LENGTH_FACTOR * size as f32,
            )
        }
        Family::Points => {
            let n = model.leaves.len() as f32;
            (n, n * (size * size) as f32)
        }
    }
}

/// The draw list of one family at one size.
fn bench_list(model: &TreeModel, family: Family, size: u32) -> TreeDrawList {
    match family {
        Family::Triangles => TreeDrawList::full(model),
        Family::Lines => TreeDrawList {
            trunk_lines: vec![LineRun {
                segments: 0..model.segments.len() as u32,
                width: size,
            }],
            ..default()
        },
        Family::Points => TreeDrawList {
            leaf_points: vec![PointRun {
                leaves: 0..model.leaves.len() as u32,
                size,
            }],
            ..default()
        },
    }
}

/// Positions of the benchmark trees relative to the camera (camera space: −Z ahead),
/// enough of them for `primitives` primitives, spread over the view at the depth where a
/// tree covers `fraction` of its height.
fn bench_layout(
    model: &TreeModel,
    family: Family,
    primitives: u32,
    fraction: f32,
    focal: f32,
    viewport: UVec2,
) -> Vec<Vec3> {
    let per_tree = match family {
        Family::Triangles => model.trunk_triangle_count() + model.leaf_triangle_count(),
        Family::Lines => model.segments.len(),
        Family::Points => model.leaves.len(),
    }
    .max(1) as u32;
    let trees = primitives.div_ceil(per_tree).clamp(1, 4_000);
    let depth = bench_depth(model, fraction, focal, viewport.y as f32);
    let half_width = depth * viewport.x as f32 * 0.5 / focal;
    let half_height = depth * viewport.y as f32 * 0.5 / focal;
    let tree_height = model.bounds.max.y - model.bounds.min.y;
    let centre_y = (model.bounds.max.y + model.bounds.min.y) * 0.5;
    // Tree centres within the view, on a grid as square as the view allows.
    let columns = ((trees as f32 * viewport.x as f32 / viewport.y as f32)
        .sqrt()
        .ceil() as u32)
        .max(1);
    let rows = trees.div_ceil(columns);
    let span_x = (half_width * 1.8 - tree_height * 0.5).max(0.0);
    let span_y = (half_height * 2.0 - tree_height).max(0.0);
    (0..trees)
        .map(|i| {
            let (c, r) = (i % columns, i / columns);
            let u = if columns > 1 {
                c as f32 / (columns - 1) as f32 - 0.5
            } else {
                0.0
            };
            let v = if rows > 1 {
                r as f32 / (rows - 1) as f32 - 0.5
            } else {
                0.0
            };
            // Slightly staggered in depth so that coplanar trees do not z-fight.
            Vec3::new(
                u * span_x,
                v * span_y - centre_y,
                -depth * (1.0 + 0.002 * (i % 7) as f32),
            )
        })
        .collect()
}

/// The logic benchmark's camera at `turn` ∈ [0, 1]: at the forest's corner, a little
/// above the trees, turning from looking away (0) to looking at the centre (1).
fn logic_pose(min: Vec3, max: Vec3, turn: f32) -> Transform {
    let centre = (min + max) * 0.5;
    let eye = Vec3::new(min.x, max.y.max(min.y) + 12.0, min.z);
    let towards = Vec2::new(centre.x - eye.x, centre.z - eye.z).normalize_or(Vec2::X);
    let angle = core::f32::consts::PI * (1.0 - turn.clamp(0.0, 1.0));
    let heading = Vec2::from_angle(angle).rotate(towards);
    Transform::from_translation(eye).looking_to(Vec3::new(heading.x, -0.15, heading.y), Vec3::Y)
}

/// The calibration from the samples.
fn fit(
    render: &[(Family, u32, CostSample)],
    logic: &[(f32, u32, f32)],
    render_fixed: f32,
    adapter: &AdapterIdentity,
) -> Result<Calibration, String> {
    let of = |family: Family| -> Vec<(u32, CostSample)> {
        render
            .iter()
            .filter(|s| s.0 == family)
            .map(|s| (s.1, s.2))
            .collect()
    };
    let triangles: Vec<CostSample> = of(Family::Triangles).into_iter().map(|s| s.1).collect();
    let triangles = fit_nonnegative_cost(&triangles).map_err(|e| format!("triangles: {e}"))?;
    let lines = fit_sized_costs(&of(Family::Lines), 20).map_err(|e| format!("lines: {e}"))?;
    let points = fit_sized_costs(&of(Family::Points), 20).map_err(|e| format!("points: {e}"))?;
    let mut targets: Vec<f32> = logic.iter().map(|s| s.0).collect();
    targets.sort_by(f32::total_cmp);
    targets.dedup();
    let logic = targets
        .into_iter()
        .map(|target| {
            LogicTable::new(
                target,
                logic
                    .iter()
                    .filter(|s| s.0 == target)
                    .map(|s| (s.1, s.2))
                    .collect(),
            )
        })
        .collect();
    Ok(Calibration {
        adapter: adapter.name.clone(),
        driver: adapter.driver.clone(),
        triangles,
        lines,
        points,
        logic,
        render_fixed,
        // Bevy's mesh path is not measured by this run: its prior, which the running app
        // corrects from its frames.
        meshes: MeshPathCost::default(),
    })
}

fn write(path: &std::path::Path, calibration: &Calibration) -> Result<(), String> {
    let text = calibration.to_ron_string().map_err(|e| e.to_string())?;
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    }
    std::fs::write(path, text).map_err(|e| format!("{}: {e}", path.display()))
}

/// The fit's residuals per family, and the logic tables, on stdout.
fn print_report(calibration: &Calibration, render: &[(Family, u32, CostSample)]) {
    let predicted = |family: Family, size: u32, s: &CostSample| {
        let pick = |costs: &[LinearCost]| {
            costs
                .get(size.max(1) as usize - 1)
                .or(costs.last())
                .copied()
                .unwrap_or_default()
        };
        let cost = match family {
            Family::Triangles => calibration.triangles,
            Family::Lines => pick(&calibration.lines),
            Family::Points => pick(&calibration.points),
        };
        cost.time(s.primitives, s.pixels)
    };
    println!(
        "calibration for {} ({})",
        calibration.adapter, calibration.driver
    );
    println!("  family      size  primitives      pixels  measured ms  fitted ms  error");
    for family in [Family::Triangles, Family::Lines, Family::Points] {
        let mut errors = Vec::new();
        for (f, size, s) in render.iter().filter(|s| s.0 == family) {
            let p = predicted(*f, *size, s);
            let error = (p - s.time) / s.time.max(1e-9);
            errors.push(error * error);
            println!(
                "  {:<10} {size:>5} {:>11.0} {:>11.0} {:>12.2} {:>10.2} {:>+6.1}%",
                format!("{family:?}"),
                s.primitives,
                s.pixels,
                s.time * 1000.0,
                p * 1000.0,
                error * 100.0
            );
        }
        let rms = (errors.iter().sum::<f32>() / errors.len().max(1) as f32).sqrt();
        println!(
            "  {family:?}: RMS relative error of the fit {:.1}%",
            rms * 100.0
        );
    }
    println!(
        "  render world with nothing drawn: {:.2} ms",
        calibration.render_fixed * 1000.0
    );
    println!("  logic (visible instances → ms, per target):");
    for table in &calibration.logic {
        let row: Vec<String> = table
            .samples
            .iter()
            .map(|(n, t)| format!("{n}→{:.1}", t * 1000.0))
            .collect();
        println!("    {:>6} ms: {}", table.target_ms, row.join("  "));
    }
}

/// Terminal progress bar and an on-screen line.
fn show_progress(
    progress: Res<CalibrationProgress>,
    mut last: Local<Option<(u32, String)>>,
    #[cfg(feature = "hud")] mut commands: Commands,
    #[cfg(feature = "hud")] mut text: Query<&mut Text, With<ProgressText>>,
) {
    if progress.total == 0 {
        return;
    }
    let key = (progress.done, progress.label.clone());
    if last.as_ref() == Some(&key) {
        return;
    }
    *last = Some(key);
    let width = 30;
    let filled = (progress.done as usize * width) / progress.total.max(1) as usize;
    let line = format!(
        "calibrating [{}{}] {}/{} {}",
        "#".repeat(filled),
        " ".repeat(width - filled.min(width)),
        progress.done,
        progress.total,
        progress.label
    );
    let mut stderr = std::io::stderr();
    let _ = write!(stderr, "\r\x1b[2K{line}");
    if progress.outcome.is_some() {
        let _ = writeln!(stderr);
    }
    let _ = stderr.flush();
    #[cfg(feature = "hud")]
    match text.single_mut() {
        Ok(mut text) => text.0 = line,
        Err(_) => {
            commands.spawn((
                ProgressText,
                Text::new(line),
                TextFont {
                    font_size: FontSize::Px(20.0),
                    ..default()
                },
                Node {
                    position_type: PositionType::Absolute,
                    bottom: Val::Px(12.0),
                    left: Val::Px(12.0),
                    ..default()
                },
            ));
        }
    }
}

/// The on-screen progress line.
#[cfg(feature = "hud")]
#[derive(Component)]
struct ProgressText;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cost::logic_time;

    #[test]
    fn the_median_is_the_middle_finite_value() {
        assert_eq!(median([3.0, f32::NAN, 1.0, 2.0]), Some(2.0));
        // Of an even count, the upper of the two middle values.
        assert_eq!(median([4.0, 1.0, 3.0, 2.0]), Some(3.0));
        assert_eq!(median([f32::INFINITY, 5.0]), Some(5.0));
        assert_eq!(median([f32::NAN]), None);
        assert_eq!(median([]), None);
    }

    /// A synthetic adapter: each family's (and size's) cost, in seconds.
    fn truth(family: Family, size: u32) -> LinearCost {
        let s = size as f32;
        match family {
            Family::Triangles => LinearCost {
                fixed: 2e-4,
                per_primitive: 3e-8,
                per_pixel: 4e-9,
            },
            Family::Lines => LinearCost {
                fixed: 1e-4,
                per_primitive: 1e-8 * (1.0 + 0.1 * s),
                per_pixel: 2e-9,
            },
            Family::Points => LinearCost {
                fixed: 1e-4,
                per_primitive: 4e-9 * s * s + 2e-8,
                per_pixel: 0.0,
            },
        }
    }

    /// Pixels a step's primitives cover: trees nearer the camera (a larger fraction of
    /// the view) cover more per triangle and per line; a point covers its square.
    fn pixels(family: Family, size: u32, primitives: u32, tree_fraction: f32) -> f32 {
        let nearness = tree_fraction / 0.12;
        primitives as f32
            * match family {
                Family::Triangles => 6.0 * nearness,
                Family::Lines => size as f32 * 3.0 * nearness,
                Family::Points => (size * size) as f32,
            }
    }

    /// What a run of `plan` would measure on the synthetic adapter: one sample per step.
    fn measure(plan: &[Step]) -> (Vec<(Family, u32, CostSample)>, Vec<(f32, u32, f32)>) {
        let mut render = Vec::new();
        let mut logic = Vec::new();
        for step in plan {
            match *step {
                Step::Render {
                    family,
                    size,
                    primitives,
                    tree_fraction,
                } => {
                    let pixels = pixels(family, size, primitives, tree_fraction);
                    render.push((
                        family,
                        size,
                        CostSample {
                            primitives: primitives as f32,
                            pixels,
                            time: truth(family, size).time(primitives as f32, pixels),
                        },
                    ));
                }
                Step::Logic { target_ms, turn } => {
                    let visible = (turn * 500.0) as u32;
                    logic.push((target_ms, visible, 1e-3 + 2e-6 * visible as f32));
                }
                Step::WarmUp | Step::Empty => {}
            }
        }
        (render, logic)
    }

    fn adapter() -> AdapterIdentity {
        AdapterIdentity {
            name: "synthetic".into(),
            driver: "test".into(),
            cpu: false,
        }
    }

    #[test]
    fn a_run_of_the_plan_fits_back_the_adapter_it_measured() {
        let settings = CalibrationSettings {
            sizes: vec![1, 3, 8, 20],
            ..default()
        };
        let plan = plan(&settings);
        assert_eq!(plan[..2], [Step::WarmUp, Step::Empty]);
        let (render, logic) = measure(&plan);
        let calibration = fit(&render, &logic, 0.004, &adapter()).unwrap();
        assert_eq!(calibration.render_fixed, 0.004);
        assert_eq!(calibration.lines.len(), 20);
        assert_eq!(calibration.points.len(), 20);
        // Predictions at a distance the plan did not measure, so a per-pixel part the
        // plan cannot tell from the per-primitive one shows.
        let close = |a: f32, b: f32| (a - b).abs() <= 0.02 * b.abs().max(1e-6);
        for (family, costs) in [
            (Family::Triangles, vec![calibration.triangles; 20]),
            (Family::Lines, calibration.lines.clone()),
            (Family::Points, calibration.points.clone()),
        ] {
            for &size in &settings.sizes {
                let cost = costs[size as usize - 1];
                let size = if family == Family::Triangles { 1 } else { size };
                for primitives in [1_000, 60_000, 300_000] {
                    let px = pixels(family, size, primitives, 0.3);
                    let (fitted, truth) = (
                        cost.time(primitives as f32, px),
                        truth(family, size).time(primitives as f32, px),
                    );
                    assert!(
                        close(fitted, truth),
                        "{family:?} {size} px, {primitives}: fitted {fitted}, truth {truth}"
                    );
                }
            }
        }
        // A size between two measured ones is between their costs.
        let between = calibration.points[4].time(10_000.0, 0.0);
        assert!(
            calibration.points[2].time(10_000.0, 0.0) < between
                && between < calibration.points[7].time(10_000.0, 0.0)
        );
        // One logic table per target, each from its rising and falling walk.
        let targets: Vec<f32> = calibration.logic.iter().map(|t| t.target_ms).collect();
        assert_eq!(targets, settings.logic_targets_ms);
        for table in &calibration.logic {
            let time = logic_time(std::slice::from_ref(table), 250, table.target_ms);
            assert!(close(time, 1e-3 + 2e-6 * 250.0), "{time}");
        }
    }

    #[test]
    fn the_logic_walk_turns_towards_the_forest_and_back() {
        let settings = CalibrationSettings {
            logic_targets_ms: vec![40.0],
            logic_positions: 4,
            ..default()
        };
        let turns: Vec<f32> = plan(&settings)
            .into_iter()
            .filter_map(|s| match s {
                Step::Logic { turn, .. } => Some(turn),
                _ => None,
            })
            .collect();
        let third = 1.0 / 3.0;
        assert_eq!(
            turns,
            [0.0, third, 2.0 * third, 1.0, 1.0, 2.0 * third, third, 0.0]
        );
    }

    #[test]
    fn a_family_the_run_did_not_measure_is_named_in_the_error() {
        let (mut render, logic) = measure(&plan(&CalibrationSettings::default()));
        render.retain(|s| s.0 != Family::Lines);
        let error = fit(&render, &logic, 0.0, &adapter()).unwrap_err();
        assert!(error.starts_with("lines: "), "{error}");
    }
}
