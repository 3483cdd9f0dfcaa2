//! Time-critical level of detail in the ECS: a value per visible object, the frame's
//! rendering time handed out by Robin Hood, and per object the representation that fits,
//! written into each instance's [`TreeDrawList`].
//!
//! Each tree is two objects — its trunk and its leaves — with their own values and
//! complexities. Per frame, in [`SherwoodSystems`] order:
//!
//! * **Value**: for each visible instance ([`ForestCulling`]) the configured value
//!   function of its trunk (at the trunk's area-density centre) and of its leaves (the sum
//!   over its visible leaf groups, each at its own depth), times the part's importance.
//! * **Budget**: the logic time the cost model predicts for this many visible trees, the
//!   rendering time that leaves in the target (the learned overlap of logic and
//!   rendering, [`FrameOverlap`](crate::cost::FrameOverlap), replaces the paper's
//!   P-5..P-7), less the rendering's fixed part; every object's cheapest representation
//!   is paid first, then Robin Hood walks the objects simple → complex (object types are
//!   ranked once when models change) and each object's search (see [`select`]) picks what
//!   fits its floor plus its share, the remainder passing on; a residue left at the end is
//!   handed out again to objects below full detail. The search runs inside the hand-out
//!   because a remainder is only known once the object has chosen.
//! * **Select**: the chosen draw lists are copied into the instances' components;
//!   invisible instances get empty lists. In `Static` and `Unlimited` mode no time is
//!   handed out and this stage does all the work.
//!
//! The budget predicts with the [`CostModel`]: a measured calibration as the prior and
//! what the running app learned of its own frames (see [`crate::cost`]). The logic time
//! and the rendering time left in the target come from it, the rendering time is handed
//! out in its learned per-primitive costs, and each frame's prediction is recorded with
//! it ([`CostModel::record`]) so that it learns from what that frame then measured.

mod diagnostics;
pub mod select;

pub use diagnostics::LodDiagnosticsPlugin;

use std::time::Instant;

use bevy::platform::collections::HashMap;
use bevy::prelude::*;
use serde::{Deserialize, Serialize};

use crate::SherwoodSystems;
use crate::budget::{
    Allocation, BudgetProblem, BudgetStrategy, Fit, FunkhouserIncremental, FunkhouserSequin, Level,
    ObjectDesc, PreviousSelection, RobinHood, TriangleBudget, ValueFunction, ValueInputs,
    ValueModel,
};
use crate::cost::{CostModel, FamilyTimes, FrameClock, FramePrediction, LearnedCosts};
use crate::culling::{ForestCulling, InstanceVisibility};
use crate::draw::{ModelSlot, PrimitiveCounts, TreeDrawList};
use crate::ecosystem::TreeInstance;
use crate::tree::{PixelRange, TreeModel, TreeModelsVersion};
use crate::view::LodView;

use select::{LeafMethod, PrimitiveCosts, TreeView, VisibleGroup};

/// How objects are drawn.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize, Reflect)]
pub enum LodMode {
    /// Time-critical with points-and-lines LOD (thesis §6.5): thin trunk segments as lines
    /// of several widths, leaves as points of several sizes, as many triangles as fit.
    #[default]
    Tclod,
    /// Time-critical with triangles only (thesis §6.4): as many as fit, trunk from the
    /// thickest segment down, leaf groups from their far leaves in.
    Tc,
    /// The pixel-driven points-and-lines LOD (thesis §4.4) with no budget: a baseline.
    Static,
    /// Everything at full detail: the reference.
    Unlimited,
}

/// Which strategy hands out the rendering time in the time-critical modes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize, Reflect)]
pub enum StrategyKind {
    /// Robin Hood: every visible object gets time in proportion to its value, remainders
    /// pass on; nothing visible is dropped.
    #[default]
    RobinHood,
    /// Funkhouser–Séquin's greedy over each object's ladder; may drop objects.
    FunkhouserSequin,
    /// Funkhouser–Séquin's incremental variant, starting from last frame's choice.
    FunkhouserIncremental,
    /// The triangle-budget greedy.
    TriangleBudget,
}

/// The frame's budget and how it is spent. Changing it takes effect on the next frame.
#[derive(Resource, Clone, Debug, PartialEq, Serialize, Deserialize, Reflect)]
#[reflect(Resource)]
#[serde(default)]
pub struct FrameBudget {
    /// Target frame time in milliseconds (default 100: this crate's reference machine
    /// renders in software). A target at or below the logic time leaves no rendering time:
    /// everything is drawn at its cheapest ([`LodDiagnostics::target_below_logic`]), and a
    /// warning is logged once it has lasted [`TARGET_WARNING_SECS`] (not for the slow
    /// frames of start-up, while shaders compile and the measured logic time settles).
    pub target_ms: f32,
    /// How objects are drawn (default TCLOD).
    pub mode: LodMode,
    /// Who hands out the time in the time-critical modes (default Robin Hood). The
    /// ladder strategies see each object as a ladder of its representations at
    /// [`LADDER_FRACTIONS`] of its full cost, with benefit `value · √(cost / full cost)`.
    pub strategy: StrategyKind,
    /// Value function (default P-11).
    pub value: ValueFunction,
    /// Importance of trunks (default 1).
    pub trunk_importance: f32,
    /// Importance of leaves (default 1/16, as in the paper).
    pub leaf_importance: f32,
    /// Line widths in pixels (default 1–20).
    pub line_widths: PixelRange,
    /// Point sizes in pixels (default 1–20). Static mode uses the smallest.
    pub point_sizes: PixelRange,
}

impl Default for FrameBudget {
    fn default() -> Self {
        Self {
            target_ms: 100.0,
            mode: LodMode::Tclod,
            strategy: StrategyKind::RobinHood,
            value: ValueFunction::P11,
            trunk_importance: 1.0,
            leaf_importance: 1.0 / 16.0,
            line_widths: PixelRange::default(),
            point_sizes: PixelRange::default(),
        }
    }
}

/// The fractions of an object's full-detail time at which its ladder's rungs are searched
/// for the ladder strategies (best → cheapest; 0 gives the cheapest representation).
pub const LADDER_FRACTIONS: [f32; 7] = [1.0, 0.5, 0.25, 0.125, 1.0 / 16.0, 1.0 / 64.0, 0.0];

/// What the LOD stages did in the last frame.
#[derive(Resource, Clone, Debug, Default, PartialEq, Reflect)]
#[reflect(Resource)]
pub struct LodDiagnostics {
    /// The frame these figures are of ([`FrameClock::frame`](crate::cost::FrameClock)).
    pub frame: u64,
    /// The target frame time, ms.
    pub target_ms: f32,
    /// Visible objects (a tree's trunk and leaves count separately).
    pub visible_objects: u32,
    /// Visible tree instances.
    pub visible_instances: u32,
    /// Predicted logic time (the main world's update), ms.
    pub logic_ms: f32,
    /// Rendering time handed out to the objects, ms (the fixed part excluded).
    pub render_budget_ms: f32,
    /// Predicted fixed part of the rendering, ms.
    pub render_fixed_ms: f32,
    /// Predicted rendering time: the fixed part and the selection, ms.
    pub predicted_render_ms: f32,
    /// Predicted frame time, ms: logic and rendering as they overlap
    /// ([`FrameOverlap`](crate::cost::FrameOverlap)).
    pub predicted_frame_ms: f32,
    /// The most recent measured frame (a frame or two before this one: the render world
    /// reports late): its number, or 0 before any.
    pub measured_frame: u64,
    /// Its frame time, ms.
    pub measured_frame_ms: f32,
    /// Its logic time, ms.
    pub measured_logic_ms: f32,
    /// Its rendering time, ms.
    pub measured_render_ms: f32,
    /// What had been predicted for its frame time, ms.
    pub measured_frame_predicted_ms: f32,
    /// Rendering time handed out but not used by anyone, ms.
    pub wasted_ms: f32,
    /// What the cost model has learned.
    pub learned: LearnedCosts,
    /// The selection's rendering time by primitive family as the calibration alone prices
    /// it, seconds: what the cost model learns from (with the measured times) once the
    /// frame is measured.
    pub calibrated: FamilyTimes,
    /// Predicted rendering time beyond the rendering time, ms: cheapest representations
    /// that did not fit (Robin Hood draws every visible object at least at its cheapest;
    /// the triangle budget never goes below them).
    pub overrun_ms: f32,
    /// Robin Hood: every visible object's cheapest representation together, ms, paid
    /// before the rest of the rendering time is handed out by value.
    pub floor_ms: f32,
    /// How far those cheapest representations alone exceed the rendering time, ms: the
    /// overrun no choice could avoid with every visible object drawn. Positive means the
    /// target cannot be held with this many objects in view (see [`LodDiagnostics::visible_objects`]).
    pub floor_excess_ms: f32,
    /// Primitives selected.
    pub counts: PrimitiveCounts,
    /// Objects drawn at their cheapest representation although it did not fit.
    pub truncated: u32,
    /// Visible objects drawn with nothing (always 0 with Robin Hood).
    pub undrawn: u32,
    /// Time of the Value stage, ms.
    pub value_stage_ms: f32,
    /// Time of the Budget stage, ms.
    pub budget_stage_ms: f32,
    /// Time of the Select stage, ms.
    pub select_stage_ms: f32,
    /// The target frame time is at or below the logic time this frame, so there was no
    /// rendering time to hand out and everything was drawn at its cheapest.
    pub target_below_logic: bool,
}

/// How long, in seconds, the target must stay at or below the logic time before a
/// warning is logged: longer than the start-up's slow frames take to leave the learned
/// logic time.
pub const TARGET_WARNING_SECS: f32 = 3.0;

/// Adds the Value, Budget and Select stages, [`FrameBudget`] and [`LodDiagnostics`].
/// Part of [`SherwoodPlugins`](crate::SherwoodPlugins); needs the culling plugin and
/// the [`CostPlugin`](crate::cost::CostPlugin).
#[derive(Default)]
pub struct LodPlugin;

impl Plugin for LodPlugin {
    fn build(&self, app: &mut App) {
        app.register_type::<FrameBudget>()
            .register_type::<LodDiagnostics>()
            .init_resource::<FrameBudget>()
            .init_resource::<TreeModelsVersion>()
            .init_resource::<LodDiagnostics>()
            .init_resource::<LodFrame>()
            .add_systems(
                PostUpdate,
                (
                    (give_draw_lists, value_objects)
                        .chain()
                        .in_set(SherwoodSystems::Value),
                    hand_out_time.in_set(SherwoodSystems::Budget),
                    write_draw_lists.in_set(SherwoodSystems::Select),
                ),
            );
    }
}

/// One visible part of a tree.
#[derive(Clone, Copy, Debug)]
struct Object {
    /// Index into [`LodFrame::trees`].
    tree: u32,
    leaves: bool,
}

/// One visible tree this frame.
struct VisibleTree {
    entity: Entity,
    /// Index into [`LodFrame::infos`].
    model: u32,
    view: TreeView,
    trunk_visible: bool,
    /// The visible leaf groups in [`LodFrame::groups`]; empty when `leaf_depth` is set.
    groups: core::ops::Range<u32>,
    /// Every leaf group at this depth: the tree is entirely in view and far compared with
    /// its size (see [`UNIFORM_DEPTH_RADII`]).
    leaf_depth: Option<f32>,
}

/// A tree entirely in view whose centre is at least this many bounding radii deep has
/// its leaves valued and chosen as one, at the centre's depth
/// ([`select::leaves_at_depth`]): every group's depth is then within an eighth of the
/// centre's, and deciding once instead of group by group is what lets a large forest's
/// LOD stages keep up.
pub const UNIFORM_DEPTH_RADII: f32 = 8.0;

/// What the stages need of a tree type, derived once when models change.
struct ModelInfo {
    id: AssetId<TreeModel>,
    /// Rank (simple → complex) and complexity of the trunk as an object.
    trunk_rank: (u32, f32),
    /// The same for the leaves.
    leaves_rank: (u32, f32),
    /// Centre and radius of the tree's bounding sphere, model space.
    center: Vec3,
    radius: f32,
    /// Σ over the leaf groups of their leaf counts, and of the counts' square roots: the
    /// value of all groups at one depth is one group's value per leaf times the sum of
    /// counts to the value function's area exponent.
    group_leaves: f32,
    group_leaves_sqrt: f32,
    /// Area-weighted centre of the trunk's triangles, model space.
    trunk_area_center: Vec3,
    /// The whole trunk's area, and one leaf's on average (unscaled).
    trunk_area: f32,
    leaf_area: f32,
    has_trunk: bool,
    has_leaves: bool,
    /// What counting a draw list needs.
    slot: ModelSlot,
}

/// The frame's working state, kept between frames to reuse its allocations.
#[derive(Resource, Default)]
struct LodFrame {
    /// The view's pixel count: the most one primitive can cover.
    viewport_pixels: f32,
    trees: Vec<VisibleTree>,
    groups: Vec<VisibleGroup>,
    objects: Vec<Object>,
    /// `(rank, complexity, object, value)` of the visible objects, before ordering.
    keyed: Vec<(u32, f32, Object, f32)>,
    /// Per rank, where its objects start in `objects` (a counting sort's scratch).
    rank_starts: Vec<u32>,
    values: Vec<f32>,
    complexities: Vec<f32>,
    /// Per object, the cost of its cheapest representation.
    floors: Vec<f32>,
    /// Per tree, the list being chosen.
    lists: Vec<TreeDrawList>,
    allocations: Vec<Allocation>,
    robin_hood: RobinHood,
    funkhouser: FunkhouserSequin,
    incremental: FunkhouserIncremental,
    triangle_budget: TriangleBudget,
    problem: BudgetProblem,
    /// Per object, the time of each ladder rung (ladder strategies).
    rung_times: Vec<[f32; LADDER_FRACTIONS.len()]>,
    /// Last frame's rung per (instance, leaves), for the incremental strategies.
    previous: HashMap<(Entity, bool), u32>,
    next_previous: HashMap<(Entity, bool), u32>,
    scratch: TreeDrawList,
    /// Per model, its object types' ranks and the rest the stages derive from it; rebuilt
    /// when models change.
    infos: Vec<ModelInfo>,
    /// Per instance of [`ForestCulling::entities`], its model and placement: derived when
    /// the forest or the models change, not per frame.
    placed: Vec<PlacedTree>,
    /// The models' version `infos` was derived at, and the culling layout and models'
    /// version `placed` was.
    ranked_version: Option<u64>,
    placed_key: Option<(u64, u64)>,
    value_ms: f32,
    /// Since when (real seconds since start-up) the target has been at or below the
    /// logic time, and whether that was reported.
    target_below_logic_since: Option<f32>,
    warned_target: bool,
}

fn give_draw_lists(
    mut commands: Commands,
    new: Query<Entity, (With<TreeInstance>, Without<TreeDrawList>)>,
) {
    for entity in &new {
        commands.entity(entity).insert(TreeDrawList::default());
    }
}

/// What the value stage needs of one instance that only changes with the forest's layout
/// (the culling hierarchy's transforms) or the models.
#[derive(Clone, Copy)]
struct PlacedTree {
    /// Index into [`LodFrame::infos`], or [`NO_MODEL`] when its model is not loaded.
    model: u32,
    /// Uniform scale.
    scale: f32,
    /// World-space centre of its bounding sphere, and of its trunk's area.
    center: Vec3,
    trunk_center: Vec3,
}

/// [`PlacedTree::model`] of an instance whose model is not loaded.
const NO_MODEL: u32 = u32::MAX;

fn place_trees(
    culling: &ForestCulling,
    instances: &Query<&TreeInstance>,
    infos: &[ModelInfo],
) -> Vec<PlacedTree> {
    culling
        .entities
        .iter()
        .zip(&culling.instances)
        .map(|(&entity, cull)| {
            let transform = cull.transform;
            let id = instances.get(entity).ok().map(|i| i.model.id());
            let model = id.and_then(|id| infos.iter().position(|info| info.id == id));
            let (center, trunk_center) = model.map_or((Vec3::ZERO, Vec3::ZERO), |m| {
                (
                    transform.transform_point3(infos[m].center),
                    transform.transform_point3(infos[m].trunk_area_center),
                )
            });
            PlacedTree {
                model: model.map_or(NO_MODEL, |m| m as u32),
                scale: transform.matrix3.x_axis.length(),
                center,
                trunk_center,
            }
        })
        .collect()
}

fn model_infos(models: &Assets<TreeModel>, costs: &PrimitiveCosts) -> Vec<ModelInfo> {
    // complexity(O): the full-detail time at one constant projected area for everyone.
    const AREA: f32 = 4.0;
    let mut types: Vec<((AssetId<TreeModel>, bool), f32)> = models
        .iter()
        .flat_map(|(id, m)| {
            [
                (
                    (id, false),
                    costs.triangles(m.trunk_triangle_count() as u32, AREA),
                ),
                (
                    (id, true),
                    costs.triangles(m.leaf_triangle_count() as u32, AREA),
                ),
            ]
        })
        .collect();
    types.sort_by(|a, b| a.1.total_cmp(&b.1));
    let ranks: HashMap<(AssetId<TreeModel>, bool), (u32, f32)> = types
        .into_iter()
        .enumerate()
        .map(|(rank, (key, complexity))| (key, (rank as u32, complexity)))
        .collect();
    models
        .iter()
        .map(|(id, m)| {
            let rank = |leaves| ranks.get(&(id, leaves)).copied().unwrap_or((0, 0.0));
            let sizes = m.leaf_groups.iter().map(|g| g.leaves.len() as f32);
            ModelInfo {
                id,
                trunk_rank: rank(false),
                leaves_rank: rank(true),
                center: m.bounds.center(),
                radius: m.bounds.half_extents().length(),
                group_leaves: sizes.clone().sum(),
                group_leaves_sqrt: sizes.map(f32::sqrt).sum(),
                trunk_area_center: m.trunk_area_center,
                trunk_area: m.mean_trunk_triangle_area * m.trunk_triangle_count() as f32,
                leaf_area: select::mean_leaf_area(m),
                has_trunk: m.trunk_triangle_count() > 0,
                has_leaves: !m.leaf_groups.is_empty(),
                slot: ModelSlot::of(m),
            }
        })
        .collect()
}

fn value_objects(
    mut frame: ResMut<LodFrame>,
    budget: Res<FrameBudget>,
    cost_model: Res<CostModel>,
    culling: Option<Res<ForestCulling>>,
    views: Query<&LodView>,
    instances: Query<&TreeInstance>,
    models: Res<Assets<TreeModel>>,
    version: Res<TreeModelsVersion>,
) {
    let start = Instant::now();
    let frame = &mut *frame;
    frame.trees.clear();
    frame.groups.clear();
    frame.objects.clear();
    frame.values.clear();
    frame.complexities.clear();
    let (Some(culling), Some(view)) = (culling, views.iter().next()) else {
        return;
    };
    if frame.ranked_version != Some(version.0) {
        let costs = PrimitiveCosts::from_calibration(cost_model.calibration(), 1.0);
        frame.infos = model_infos(&models, &costs);
        frame.ranked_version = Some(version.0);
    }
    let placed_key = (culling.layout_version(), version.0);
    if frame.placed_key != Some(placed_key) {
        frame.placed = place_trees(&culling, &instances, &frame.infos);
        frame.placed_key = Some(placed_key);
    }
    let projection = view.projection();
    frame.viewport_pixels = view.viewport_pixels;
    let value_of = |area: f32, at: Vec3, importance: f32| {
        budget.value.value(&ValueInputs {
            area,
            depth: view.depth(at),
            distance: at.distance(view.position),
            importance,
        })
    };
    let area_exponent_one = budget.value.area_exponent() == 1.0;
    let LodFrame {
        infos,
        placed,
        trees,
        groups,
        keyed,
        ..
    } = frame;
    keyed.clear();
    for (i, visibility) in culling.result.visibility.iter().enumerate() {
        let trunk_visible = match visibility {
            InstanceVisibility::Invisible => continue,
            InstanceVisibility::Full => true,
            InstanceVisibility::Partial { trunk, .. } => *trunk,
        };
        let (
            Some(&PlacedTree {
                model: model_index,
                scale,
                center,
                trunk_center,
            }),
            Some(&entity),
        ) = (placed.get(i), culling.entities.get(i))
        else {
            continue;
        };
        let Some(info) = infos.get(model_index as usize) else {
            continue;
        };
        let tree = trees.len() as u32;
        let first_group = groups.len() as u32;
        let leaf_area = info.leaf_area * scale * scale;
        let center_depth = view.depth(center);
        let whole = matches!(visibility, InstanceVisibility::Full)
            && info.has_leaves
            && center_depth >= UNIFORM_DEPTH_RADII * info.radius * scale;
        let mut leaves_value = 0.0;
        let mut leaf_depth = None;
        if whole {
            // Every group at the centre's depth and distance: one value per leaf, times
            // the groups' leaf counts to the area's power (see `ModelInfo`).
            let per_leaf = value_of(leaf_area, center, budget.leaf_importance);
            let counts = if area_exponent_one {
                info.group_leaves
            } else {
                info.group_leaves_sqrt
            };
            leaves_value = crate::budget::finite_value(per_leaf * counts);
            leaf_depth = Some(center_depth.max(crate::budget::MIN_DEPTH));
        } else if let (Some(model), Some(cull)) = (models.get(info.id), culling.instances.get(i)) {
            let transform = cull.transform;
            for (g, group) in model.leaf_groups.iter().enumerate() {
                if !culling.result.group_visible(i, g) {
                    continue;
                }
                let center = transform.transform_point3(group.bounds.center);
                let n = group.leaves.len() as f32;
                leaves_value += value_of(n * leaf_area, center, budget.leaf_importance);
                groups.push(VisibleGroup {
                    group: g as u32,
                    depth: view.depth(center).max(crate::budget::MIN_DEPTH),
                });
            }
        }
        let group_range = first_group..groups.len() as u32;
        if trunk_visible && info.has_trunk {
            let area = info.trunk_area * scale * scale;
            let (r, c) = info.trunk_rank;
            keyed.push((
                r,
                c,
                Object {
                    tree,
                    leaves: false,
                },
                value_of(area, trunk_center, budget.trunk_importance),
            ));
        }
        if !group_range.is_empty() || leaf_depth.is_some() {
            let (r, c) = info.leaves_rank;
            keyed.push((r, c, Object { tree, leaves: true }, leaves_value));
        }
        trees.push(VisibleTree {
            entity,
            model: model_index,
            view: TreeView {
                scale,
                trunk_depth: view.depth(trunk_center).max(crate::budget::MIN_DEPTH),
                projection,
            },
            trunk_visible,
            groups: group_range,
            leaf_depth,
        });
    }
    // Simple → complex: ranks are few (two per model), so a counting sort by rank is O(n)
    // and stable, and the complexities arrive sorted (Robin Hood then runs in O(n)).
    let starts = &mut frame.rank_starts;
    starts.clear();
    starts.resize(2 * frame.infos.len() + 1, 0);
    // (`model_infos` ranks the 2 · models object types 0..2 · models.)
    for &(rank, ..) in &frame.keyed {
        starts[rank as usize + 1] += 1;
    }
    for r in 1..starts.len() {
        starts[r] += starts[r - 1];
    }
    let n = frame.keyed.len();
    let placeholder = Object {
        tree: 0,
        leaves: false,
    };
    frame.objects.resize(n, placeholder);
    frame.complexities.resize(n, 0.0);
    frame.values.resize(n, 0.0);
    for &(rank, complexity, object, value) in &frame.keyed {
        let at = &mut starts[rank as usize];
        let i = *at as usize;
        *at += 1;
        frame.objects[i] = object;
        frame.complexities[i] = complexity;
        frame.values[i] = value;
    }
    frame.value_ms = start.elapsed().as_secs_f32() * 1000.0;
}

fn hand_out_time(
    mut frame: ResMut<LodFrame>,
    budget: Res<FrameBudget>,
    mut cost_model: ResMut<CostModel>,
    clock: Res<FrameClock>,
    models: Res<Assets<TreeModel>>,
    time: Res<Time<Real>>,
    mut diagnostics: ResMut<LodDiagnostics>,
) {
    let start = Instant::now();
    let frame = &mut *frame;
    let scales = cost_model.family_scales();
    let costs = cost_model
        .primitive_costs()
        .within_viewport(frame.viewport_pixels);
    let visible_instances = frame.trees.len() as u32;
    let logic = cost_model.logic_time(visible_instances);
    let overlap = cost_model.overlap();
    let fixed = cost_model.render_fixed();
    let target = (budget.target_ms.max(0.0)) / 1000.0;
    let available = overlap.rendering_time(logic, target);
    let target_below_logic =
        available <= 0.0 && budget.mode != LodMode::Unlimited && budget.mode != LodMode::Static;
    if target_below_logic {
        let now = time.elapsed_secs();
        let since = *frame.target_below_logic_since.get_or_insert(now);
        if !frame.warned_target && now - since >= TARGET_WARNING_SECS {
            warn!(
                "FrameBudget: target {:.1} ms has been at or below the logic time ({:.1} ms now) for {TARGET_WARNING_SECS} s; every object is drawn at its cheapest",
                budget.target_ms,
                logic * 1000.0
            );
            frame.warned_target = true;
        }
    } else {
        frame.target_below_logic_since = None;
        frame.warned_target = false;
    }
    let rendering = (available - fixed).max(0.0);

    // The models by `VisibleTree::model`, looked up once a frame.
    let tree_models: Vec<Option<&TreeModel>> =
        frame.infos.iter().map(|info| models.get(info.id)).collect();
    let model_of = |tree: &VisibleTree| tree_models.get(tree.model as usize).copied().flatten();

    // Per tree, a fresh list.
    frame
        .lists
        .resize_with(frame.trees.len(), TreeDrawList::default);
    for list in &mut frame.lists[..frame.trees.len()] {
        list.clear();
    }

    let mut predicted = 0.0f32;
    // What of it went to lines and to points (the rest to triangles).
    let mut parts = select::Selected::default();
    let mut take = |chosen: select::Selected| {
        parts.lines += chosen.lines;
        parts.points += chosen.points;
        chosen
    };
    let mut truncated = 0;
    let mut wasted = 0.0;
    let mut undrawn = 0;
    let mut floor = 0.0;
    let mut floor_excess = 0.0;
    match budget.mode {
        LodMode::Unlimited | LodMode::Static => {
            for (tree, list) in frame.trees.iter().zip(&mut frame.lists) {
                let Some(m) = model_of(tree) else {
                    continue;
                };
                let unlimited = budget.mode == LodMode::Unlimited;
                if tree.trunk_visible {
                    predicted += take(if unlimited {
                        select::trunk_tc(m, &tree.view, &costs, f32::INFINITY, list)
                    } else {
                        select::trunk_static(m, &tree.view, &costs, budget.line_widths, list)
                    })
                    .cost;
                }
                let method = if unlimited {
                    LeafMethod::Full
                } else {
                    LeafMethod::Static(budget.point_sizes.sanitized().min)
                };
                predicted += take(tree_leaves(
                    m,
                    tree,
                    &frame.groups,
                    &costs,
                    method,
                    0.0,
                    list,
                ))
                .cost;
            }
        }
        LodMode::Tc | LodMode::Tclod => {
            let tclod = budget.mode == LodMode::Tclod;
            let (trees, groups, objects, lists) = (
                &frame.trees,
                &frame.groups,
                &frame.objects,
                &mut frame.lists,
            );
            let leaf_method = if tclod {
                LeafMethod::Tclod(budget.point_sizes)
            } else {
                LeafMethod::Tc
            };
            // What object `i` draws with `given` seconds, written into `list`.
            let search = |i: usize, given: f32, list: &mut TreeDrawList| {
                let object = objects[i];
                let tree = &trees[object.tree as usize];
                let Some(m) = model_of(tree) else {
                    return select::Selected::default();
                };
                if object.leaves {
                    tree_leaves(m, tree, groups, &costs, leaf_method, given, list)
                } else if tclod {
                    select::trunk_tclod(m, &tree.view, &costs, budget.line_widths, given, list)
                } else {
                    select::trunk_tc(m, &tree.view, &costs, given, list)
                }
            };
            let stats = if budget.strategy == StrategyKind::RobinHood {
                // Every object's cheapest representation, paid before the hand-out.
                let floors = &mut frame.floors;
                floors.clear();
                floors.extend(objects.iter().map(|object| {
                    let tree = &trees[object.tree as usize];
                    let Some(m) = model_of(tree) else {
                        return 0.0;
                    };
                    if object.leaves {
                        tree_leaves_floor(m, tree, groups, &costs, leaf_method)
                    } else {
                        select::trunk_floor(
                            m,
                            &tree.view,
                            &costs,
                            tclod.then_some(budget.line_widths),
                        )
                    }
                }));
                frame.robin_hood.distribute_with(
                    &frame.values,
                    &frame.complexities,
                    &frame.floors,
                    rendering,
                    |i, given| {
                        let chosen = take(search(i, given, &mut lists[objects[i].tree as usize]));
                        Fit {
                            used: chosen.cost,
                            // 0: full detail, nothing more to buy.
                            level: u32::from(!chosen.full),
                            truncated: chosen.truncated,
                        }
                    },
                    &mut frame.allocations,
                )
            } else {
                // Ladders: each object's representations at fractions of its full cost.
                frame.problem.clear();
                frame.rung_times.clear();
                frame.next_previous.clear();
                let scratch = &mut frame.scratch;
                for (i, object) in objects.iter().enumerate() {
                    let full = search(i, 1.0e6, scratch).cost;
                    let mut ladder = [Level::new(0.0, 0.0); LADDER_FRACTIONS.len()];
                    let mut times = [0.0; LADDER_FRACTIONS.len()];
                    let mut previous_cost = f32::INFINITY;
                    for (j, fraction) in LADDER_FRACTIONS.iter().enumerate() {
                        times[j] = full * fraction;
                        let cost = search(i, times[j], scratch).cost.min(previous_cost);
                        previous_cost = cost;
                        let accuracy = if full > 0.0 {
                            (cost / full).sqrt()
                        } else {
                            1.0
                        };
                        ladder[j] = Level::new(cost, frame.values[i] * accuracy);
                    }
                    let key = (trees[object.tree as usize].entity, object.leaves);
                    let previous = frame
                        .previous
                        .get(&key)
                        .map_or(PreviousSelection::New, |&l| PreviousSelection::Level(l));
                    let desc = ObjectDesc {
                        value: frame.values[i],
                        complexity: frame.complexities[i],
                        previous,
                    };
                    if frame.problem.push_object(desc, &ladder).is_err() {
                        // Not expected: values and costs are finite by construction. Keep
                        // the indices aligned with a free, worthless object.
                        let _ = frame
                            .problem
                            .push_object(ObjectDesc::default(), &[Level::new(0.0, 0.0)]);
                    }
                    frame.rung_times.push(times);
                }
                let strategy: &mut dyn BudgetStrategy = match budget.strategy {
                    StrategyKind::FunkhouserSequin => &mut frame.funkhouser,
                    StrategyKind::FunkhouserIncremental => &mut frame.incremental,
                    _ => &mut frame.triangle_budget,
                };
                let stats = strategy.distribute(&frame.problem, rendering, &mut frame.allocations);
                for (i, allocation) in frame.allocations.iter().enumerate() {
                    let object = objects[i];
                    if let Some(level) = allocation.level {
                        let time = frame.rung_times[i][level as usize];
                        take(search(i, time, &mut lists[object.tree as usize]));
                        let key = (trees[object.tree as usize].entity, object.leaves);
                        frame.next_previous.insert(key, level);
                    }
                }
                core::mem::swap(&mut frame.previous, &mut frame.next_previous);
                stats
            };
            predicted = stats.used;
            truncated = stats.truncated;
            undrawn = stats.dropped;
            wasted = stats.wasted;
            floor = stats.floor;
            floor_excess = stats.floor_excess;
        }
    }

    let mut counts = PrimitiveCounts::default();
    for (tree, list) in frame.trees.iter().zip(&frame.lists) {
        if let Some(info) = frame.infos.get(tree.model as usize) {
            counts += info.slot.counts(list);
        }
    }
    // The selection by family, priced as the calibration alone would: what the cost
    // model learns from once the frame is measured.
    let triangles = (predicted - parts.lines - parts.points).max(0.0);
    let triangle_vertices = (counts.triangles as f32 * costs.triangle).min(triangles);
    let priced = FamilyTimes {
        triangles: triangle_vertices,
        triangle_pixels: triangles - triangle_vertices,
        lines: parts.lines,
        points: parts.points,
    };
    let render = fixed + predicted;
    let frame_time = overlap.frame_time(logic, render);
    let calibrated = priced.unscaled(scales);
    cost_model.record(FramePrediction {
        frame: clock.frame,
        visible_instances,
        calibrated,
        logic,
        render,
        frame_time,
    });
    let measured = cost_model.last_learned().copied().unwrap_or_default();
    *diagnostics = LodDiagnostics {
        frame: clock.frame,
        target_ms: budget.target_ms,
        visible_objects: frame.objects.len() as u32,
        visible_instances,
        logic_ms: logic * 1000.0,
        render_budget_ms: rendering * 1000.0,
        render_fixed_ms: fixed * 1000.0,
        predicted_render_ms: render * 1000.0,
        predicted_frame_ms: frame_time * 1000.0,
        measured_frame: measured.measured.frame,
        measured_frame_ms: measured.measured.interval * 1000.0,
        measured_logic_ms: measured.measured.logic * 1000.0,
        measured_render_ms: measured.measured.render * 1000.0,
        measured_frame_predicted_ms: measured.predicted.frame_time * 1000.0,
        wasted_ms: wasted * 1000.0,
        overrun_ms: (predicted - rendering).max(0.0) * 1000.0,
        floor_ms: floor * 1000.0,
        floor_excess_ms: floor_excess * 1000.0,
        learned: cost_model.learned(),
        calibrated,
        counts,
        truncated,
        undrawn,
        value_stage_ms: frame.value_ms,
        budget_stage_ms: start.elapsed().as_secs_f32() * 1000.0,
        select_stage_ms: 0.0,
        target_below_logic,
    };
}

/// What [`tree_leaves`] draws with no time: the cost of the leaves' cheapest
/// representation.
fn tree_leaves_floor(
    model: &TreeModel,
    tree: &VisibleTree,
    groups: &[VisibleGroup],
    costs: &PrimitiveCosts,
    method: LeafMethod,
) -> f32 {
    match tree.leaf_depth {
        Some(depth) => select::leaves_at_depth_floor(model, &tree.view, costs, method, depth),
        None => {
            let groups = &groups[tree.groups.start as usize..tree.groups.end as usize];
            select::leaves_floor(model, &tree.view, costs, method, groups)
        }
    }
}

/// A tree's leaves by `method` with `time`: group by group, or all at one depth.
fn tree_leaves(
    model: &TreeModel,
    tree: &VisibleTree,
    groups: &[VisibleGroup],
    costs: &PrimitiveCosts,
    method: LeafMethod,
    time: f32,
    list: &mut TreeDrawList,
) -> select::Selected {
    match tree.leaf_depth {
        Some(depth) => select::leaves_at_depth(model, &tree.view, costs, method, depth, time, list),
        None => {
            let groups = &groups[tree.groups.start as usize..tree.groups.end as usize];
            select::leaves(model, &tree.view, costs, method, groups, time, list)
        }
    }
}

fn write_draw_lists(
    mut frame: ResMut<LodFrame>,
    culling: Option<Res<ForestCulling>>,
    mut lists: Query<&mut TreeDrawList>,
    mut diagnostics: ResMut<LodDiagnostics>,
) {
    let start = Instant::now();
    let frame = &mut *frame;
    let Some(culling) = culling else {
        return;
    };
    // Invisible instances draw nothing; visible ones get their chosen list.
    let mut next = 0;
    for &entity in &culling.entities {
        let Ok(mut list) = lists.get_mut(entity) else {
            continue;
        };
        if next < frame.trees.len() && frame.trees[next].entity == entity {
            // Swapped, not compared and copied: the frame's list gets the old one's
            // allocations to fill next frame.
            core::mem::swap(&mut *list, &mut frame.lists[next]);
            next += 1;
        } else if !list.is_empty() {
            list.clear();
        }
    }
    diagnostics.select_stage_ms = start.elapsed().as_secs_f32() * 1000.0;
}
