//! The Value stage: which trees are visible this frame, and a value and a rank per visible
//! object (a tree's trunk, its leaves).

use std::time::Instant;

use bevy::prelude::*;

use super::select::{self, PrimitiveCosts, TreeView, VisibleLeafGroup};
use super::{FrameBudget, LadderObjects, LodMode, StrategyKind};
use crate::budget::{ValueInputs, ValueModel};
use crate::cost::CostModel;
use crate::culling::{CullView, ForestCulling, FrustumPlanes, InstanceVisibility};
use crate::draw::{ModelSlot, PrimitiveCounts, TreeDrawList};
use crate::instance::{FixedDrawList, ForestInstances, TreeInstance};
use crate::tree::{BoundingSphere, FollowedModels, TreeModel, TreeModelsVersion};
use crate::view::LodView;

/// What an object of the hand-out is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(super) enum Part {
    /// A tree's trunk.
    Trunk,
    /// A tree's leaves.
    Leaves,
    /// A mesh entity with a LOD ladder ([`LodLadder`](crate::ladder::LodLadder)).
    Mesh,
}

/// One visible object: a part of a tree, or a mesh-ladder entity.
#[derive(Clone, Copy, Debug)]
pub(super) struct Object {
    /// Index into [`VisibleObjects::trees`], or for [`Part::Mesh`] into
    /// [`LadderObjects::entries`](super::LadderObjects).
    pub(super) index: u32,
    pub(super) part: Part,
}

/// One visible tree this frame.
pub(super) struct VisibleTree {
    pub(super) entity: Entity,
    /// Its index in the instance table.
    pub(super) instance: u32,
    /// Index into [`VisibleObjects::infos`].
    pub(super) model: u32,
    pub(super) view: TreeView,
    /// The visible leaf groups in [`VisibleObjects::leaf_groups`]; empty when `leaf_depth` is set.
    pub(super) groups: core::ops::Range<u32>,
    /// Every leaf group at this depth: the tree is entirely in view and far compared with
    /// its size (see [`UNIFORM_DEPTH_RADII`]).
    pub(super) leaf_depth: Option<f32>,
}

/// A tree entirely in view whose centre is at least this many bounding radii deep has
/// its leaves valued and chosen as one, at the centre's depth
/// ([`select::leaves_at_depth`]): every group's depth is then within an eighth of the
/// centre's, and deciding once instead of group by group is what lets a large forest's
/// LOD stages keep up.
pub(crate) const UNIFORM_DEPTH_RADII: f32 = 8.0;

/// What the stages need of a tree type, derived once when models change.
pub(super) struct ModelInfo {
    pub(super) id: AssetId<TreeModel>,
    /// Rank (simple → complex) and complexity of the trunk as an object.
    pub(super) trunk_rank: (u32, f32),
    /// The same for the leaves.
    pub(super) leaves_rank: (u32, f32),
    /// Centre and radius of the tree's bounding sphere, model space.
    pub(super) center: Vec3,
    pub(super) radius: f32,
    /// Σ over the leaf groups of their leaf counts, and of the counts' square roots: the
    /// value of all groups at one depth is one group's value per leaf times the sum of
    /// counts to the value function's area exponent.
    pub(super) group_leaves: f32,
    pub(super) group_leaves_sqrt: f32,
    /// Area-weighted centre of the trunk's triangles, model space.
    pub(super) trunk_area_center: Vec3,
    /// The whole trunk's area, and one leaf's on average (unscaled).
    pub(super) trunk_area: f32,
    pub(super) leaf_area: f32,
    pub(super) has_trunk: bool,
    pub(super) has_leaves: bool,
    /// What counting a draw list needs.
    pub(super) slot: ModelSlot,
}

/// The Value stage's output: this frame's visible trees and objects, simple → complex,
/// with their values; and what it derives from the forest and the models between frames.
#[derive(Resource, Default)]
pub(super) struct VisibleObjects {
    /// The view's pixel count: the most one primitive can cover.
    pub(super) viewport_pixels: f32,
    /// The camera the objects were valued from.
    pub(super) view: Option<LodView>,
    pub(super) trees: Vec<VisibleTree>,
    pub(super) leaf_groups: Vec<VisibleLeafGroup>,
    /// The objects simple → complex, and per object its value and complexity.
    pub(super) objects: Vec<Object>,
    pub(super) values: Vec<f32>,
    pub(super) complexities: Vec<f32>,
    /// The far trees held this frame (instances, [`FrameBudget::far_refresh`]), and what
    /// they cost and draw together.
    pub(super) held: Vec<u32>,
    pub(super) held_parts: select::Selected,
    pub(super) held_counts: PrimitiveCounts,
    /// Per model, its object types' ranks and the rest the stages derive from it, at the
    /// model's index in `models` ([`refresh_infos`]).
    pub(super) infos: Vec<ModelInfo>,
    models: FollowedModels,
    /// The stage's own time this frame, milliseconds.
    pub(super) value_ms: f32,
    /// Per instance of [`ForestInstances`], its model and placement: derived when the
    /// forest or the models change, not per frame.
    placed: Vec<PlacedTree>,
    /// The layout, transforms, instance models' and infos' versions `placed` was derived
    /// at.
    placed_key: Option<(u64, u64, u64, u64)>,
    /// `(rank, complexity, object, value)` of the visible objects, before ordering.
    keyed: Vec<(u32, f32, Object, f32)>,
    /// Per rank, where its objects start in `objects` (a counting sort's scratch).
    rank_starts: Vec<u32>,
    /// `(complexity, object, value)` of the mesh-ladder entities in view, before merging.
    ladder_keyed: Vec<(f32, Object, f32)>,
    /// Value stages run (which far trees take their turn).
    value_frames: u64,
}

/// Which instances the Value stage values this frame: every visible one, or, when the
/// strategy asks (the hierarchical one: those its last cut can open to), only the marked
/// ones. Written before the Value stage from the strategy's last frame.
#[derive(Resource, Default)]
pub(super) struct NeededInstances {
    /// Only the marked instances are valued.
    pub(super) only_marked: bool,
    /// Per instance of the table, whether it is needed.
    pub(super) marked: Vec<bool>,
}

impl VisibleObjects {
    /// The instances of the table the Value stage last placed.
    pub(super) fn instances(&self) -> usize {
        self.placed.len()
    }

    /// The instances in view this frame: the visible trees and the held far ones.
    pub(super) fn instances_in_view(&self) -> u32 {
        (self.trees.len() + self.held.len()) as u32
    }
}

/// What [`FarDecisions`] is valid for.
#[derive(Clone, Copy, PartialEq)]
struct DecidedKey {
    layout: u64,
    mode: LodMode,
    widths: crate::tree::PixelRange,
    sizes: crate::tree::PixelRange,
    refresh: u32,
}

/// Per instance, the last decision of a far tree (whole tree at one depth): what it costs
/// and draws (`None`: none to keep), for [`FrameBudget::far_refresh`]. Written by the
/// Budget stage, read by the next frame's Value stage (with [`NeededInstances`], the two
/// places the Value stage reads a later stage's result).
#[derive(Resource, Default)]
pub(super) struct FarDecisions {
    pub(super) decided: Vec<Option<(select::Selected, PrimitiveCounts)>>,
    key: Option<DecidedKey>,
}

impl FarDecisions {
    /// Whether far trees are being held this frame (the Budget stage then keeps their
    /// decisions).
    pub(super) fn holding(&self) -> bool {
        self.key.is_some()
    }

    /// Keeps the decisions valid for `key` (re-indexed when trees were only planted or
    /// felled since), or forgets them.
    fn follow(&mut self, key: Option<DecidedKey>, table: &ForestInstances) {
        let same_settings = |kept: &DecidedKey, now: &DecidedKey| {
            DecidedKey {
                layout: now.layout,
                ..*kept
            } == *now
        };
        let edits = match (self.key, key) {
            (Some(kept), Some(now)) if same_settings(&kept, &now) => table.edits_since(kept.layout),
            _ => None,
        };
        match edits {
            Some(edits) if key.is_some() => edits.apply(&mut self.decided, |_| None),
            _ if key.is_some() && self.key == key => {}
            _ => self.decided.clear(),
        }
        self.key = key;
    }
}

pub(super) fn give_draw_lists(
    mut commands: Commands,
    // A tree with `FixedDrawList` and no list is drawn in full, as its docs promise.
    new: Query<
        Entity,
        (
            With<TreeInstance>,
            Without<TreeDrawList>,
            Without<FixedDrawList>,
        ),
    >,
) {
    for entity in &new {
        commands.entity(entity).try_insert(TreeDrawList::default());
    }
}

/// What the value stage needs of one instance that only changes with the forest's layout
/// (the culling hierarchy's transforms) or the models.
#[derive(Clone, Copy)]
pub(super) struct PlacedTree {
    /// Index into [`VisibleObjects::infos`], or [`NO_MODEL`] when its model is not loaded.
    pub(super) model: u32,
    /// Uniform scale.
    pub(super) scale: f32,
    /// World-space centre of its bounding sphere, and of its trunk's area.
    pub(super) center: Vec3,
    pub(super) trunk_center: Vec3,
}

/// [`PlacedTree::model`] of an instance whose model is not loaded.
pub(super) const NO_MODEL: u32 = u32::MAX;

fn place_trees(
    table: &ForestInstances,
    infos: &[ModelInfo],
    models: &FollowedModels,
) -> Vec<PlacedTree> {
    (0..table.len())
        .map(|i| {
            let transform = table.transforms[i];
            let id = table.model_id(i);
            let model = id.and_then(|id| models.index(id)).map(|m| m as usize);
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

/// Brings `visible.infos` up to the models ([`FollowedModels`]): appends the infos of
/// the models added since and ranks them among all. Deriving one orders its leaves
/// (`ModelSlot::of`); group impostors are published and released a few at a time, to
/// thousands of models, and deriving them all at each took the Value stage 14 ms at
/// 1 400 models.
fn refresh_infos(
    visible: &mut VisibleObjects,
    models: &Assets<TreeModel>,
    cost_model: &CostModel,
    version: TreeModelsVersion,
) {
    let Some(change) = visible.models.follow(models, version) else {
        return;
    };
    if change.anew {
        visible.infos.clear();
    }
    let mut costs = None;
    for (id, model) in change.added() {
        let costs = costs
            .get_or_insert_with(|| PrimitiveCosts::from_calibration(cost_model.calibration(), 1.0));
        visible.infos.push(model_info(id, model, costs));
    }
    rank_infos(&mut visible.infos);
}

/// What the stages need of `model`, ranked later ([`rank_infos`]).
fn model_info(id: AssetId<TreeModel>, m: &TreeModel, costs: &PrimitiveCosts) -> ModelInfo {
    // complexity(O): the full-detail time at one constant projected area for everyone.
    const AREA: f32 = 4.0;
    let sizes = m.leaf_groups.iter().map(|g| g.leaves.len() as f32);
    ModelInfo {
        id,
        trunk_rank: (0, costs.triangles(m.trunk_triangle_count() as u32, AREA)),
        leaves_rank: (0, costs.triangles(m.leaf_triangle_count() as u32, AREA)),
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
}

/// Ranks the 2 · models object types (each model's trunk and leaves) simple → complex,
/// `0..2 · models`, by their complexities.
fn rank_infos(infos: &mut [ModelInfo]) {
    let mut types: Vec<(u32, bool, f32)> = infos
        .iter()
        .enumerate()
        .flat_map(|(m, info)| {
            [
                (m as u32, false, info.trunk_rank.1),
                (m as u32, true, info.leaves_rank.1),
            ]
        })
        .collect();
    types.sort_by(|a, b| a.2.total_cmp(&b.2));
    for (rank, (m, leaves, _)) in types.into_iter().enumerate() {
        let info = &mut infos[m as usize];
        let slot = if leaves {
            &mut info.leaves_rank
        } else {
            &mut info.trunk_rank
        };
        slot.0 = rank as u32;
    }
}

pub(super) fn value_objects(
    mut visible: ResMut<VisibleObjects>,
    mut far: ResMut<FarDecisions>,
    needed: Res<NeededInstances>,
    budget: Res<FrameBudget>,
    cost_model: Res<CostModel>,
    culling: Option<Res<ForestCulling>>,
    views: Query<(&LodView, Option<&CullView>)>,
    table: Res<ForestInstances>,
    models: Res<Assets<TreeModel>>,
    version: Res<TreeModelsVersion>,
    mut ladders: ResMut<LadderObjects>,
    mut importances_replaced: Local<bool>,
) {
    let start = Instant::now();
    let ([trunk_importance, leaf_importance], replaced) = budget.importances();
    if replaced && !*importances_replaced {
        warn!(
            "bevy_sherwood: FrameBudget's importances (trunk {}, leaves {}) are not usable \
             (each finite and not negative, not both 0); valuing with trunk \
             {trunk_importance}, leaves {leaf_importance}",
            budget.trunk_importance, budget.leaf_importance
        );
    }
    *importances_replaced = replaced;
    let budget = &FrameBudget {
        trunk_importance,
        leaf_importance,
        ..budget.clone()
    };
    let visible = &mut *visible;
    visible.trees.clear();
    visible.leaf_groups.clear();
    visible.objects.clear();
    visible.values.clear();
    visible.complexities.clear();
    visible.view = None;
    let Some((view, cull_view)) = views.iter().next() else {
        return;
    };
    visible.viewport_pixels = view.viewport_pixels;
    visible.view = Some(*view);
    if let Some(culling) = culling {
        value_trees(
            visible,
            &mut far,
            &needed,
            budget,
            &cost_model,
            &culling,
            view,
            &table,
            &models,
            &version,
        );
    }
    value_ladders(
        visible,
        budget,
        &cost_model,
        view,
        cull_view.map(|c| &c.0),
        &mut ladders,
    );
    visible.value_ms = start.elapsed().as_secs_f32() * 1000.0;
}

/// The configured value function of `area` at `at` seen from `view`, times `importance`.
fn value_seen(budget: &FrameBudget, view: &LodView, area: f32, at: Vec3, importance: f32) -> f32 {
    budget.value.value(&ValueInputs {
        area,
        depth: view.depth(at),
        distance: at.distance(view.position),
        importance,
    })
}

/// The visible trees' objects, simple → complex.
fn value_trees(
    visible: &mut VisibleObjects,
    far: &mut FarDecisions,
    needed: &NeededInstances,
    budget: &FrameBudget,
    cost_model: &CostModel,
    culling: &ForestCulling,
    view: &LodView,
    table: &ForestInstances,
    models: &Assets<TreeModel>,
    version: &TreeModelsVersion,
) {
    refresh_infos(visible, models, cost_model, *version);
    // Culling's answer is indexed by the table it was built for (the same, once models
    // have loaded: both are kept in the same frame).
    if culling.layout_version() != Some(table.layout_version()) {
        return;
    }
    // The infos of models added later are appended: only those the instances use, or a
    // new derivation of them all, move the placements.
    let placed_key = (
        table.layout_version(),
        table.transforms_version(),
        table.models_version(),
        visible.models.generation(),
    );
    if visible.placed_key != Some(placed_key) {
        visible.placed = place_trees(table, &visible.infos, &visible.models);
        visible.placed_key = Some(placed_key);
    }
    // Far trees decided in turn (`FrameBudget::far_refresh`).
    visible.value_frames += 1;
    visible.held.clear();
    visible.held_parts = select::Selected::default();
    visible.held_counts = PrimitiveCounts::default();
    let refresh = u64::from(budget.far_refresh.max(1));
    let holding =
        refresh > 1 && budget.strategy == StrategyKind::RobinHood && budget.mode.is_time_critical();
    far.follow(
        holding.then_some(DecidedKey {
            layout: table.layout_version(),
            mode: budget.mode,
            widths: budget.line_widths,
            sizes: budget.point_sizes,
            refresh: budget.far_refresh,
        }),
        table,
    );
    let valuer = TreeValuer {
        budget,
        view,
        culling,
        table,
        models,
        area_exponent_one: budget.value.area_exponent() == 1.0,
        refresh,
        turn: visible.value_frames,
        decided: &far.decided,
    };
    visible.keyed.clear();
    for (i, visibility) in culling.result.visibility.iter().enumerate() {
        if needed.only_marked && !needed.marked.get(i).copied().unwrap_or(true) {
            continue;
        }
        valuer.value(i, *visibility, visible);
    }
    order_simple_to_complex(visible);
}

/// What valuing one instance reads.
struct TreeValuer<'a> {
    budget: &'a FrameBudget,
    view: &'a LodView,
    culling: &'a ForestCulling,
    table: &'a ForestInstances,
    models: &'a Assets<TreeModel>,
    /// The value function's area exponent is 1 (see [`ModelInfo::group_leaves`]).
    area_exponent_one: bool,
    /// A far tree is decided every `refresh` frames, on its turn.
    refresh: u64,
    turn: u64,
    decided: &'a [Option<(select::Selected, PrimitiveCounts)>],
}

impl TreeValuer<'_> {
    fn value_of(&self, area: f32, at: Vec3, importance: f32) -> f32 {
        value_seen(self.budget, self.view, area, at, importance)
    }

    /// Instance `i` seen as `visibility`: held, or its tree and objects added.
    fn value(&self, i: usize, visibility: InstanceVisibility, out: &mut VisibleObjects) {
        let trunk_visible = match visibility {
            InstanceVisibility::Invisible => return,
            InstanceVisibility::Full => true,
            InstanceVisibility::Partial { trunk, .. } => trunk,
        };
        let (
            Some(&PlacedTree {
                model: model_index,
                scale,
                center,
                trunk_center,
            }),
            Some(&entity),
        ) = (out.placed.get(i), self.table.entities.get(i))
        else {
            return;
        };
        let Some(info) = out.infos.get(model_index as usize) else {
            return;
        };
        let (budget, view) = (self.budget, self.view);
        let tree = out.trees.len() as u32;
        let center_depth = view.depth(center);
        let whole = matches!(visibility, InstanceVisibility::Full)
            && info.has_leaves
            && center_depth >= UNIFORM_DEPTH_RADII * info.radius * scale;
        if whole
            && !(i as u64 + self.turn).is_multiple_of(self.refresh)
            && let Some((parts, counts)) = self.decided.get(i).copied().flatten()
        {
            out.held.push(i as u32);
            out.held_parts = select::Selected::both(out.held_parts, parts);
            out.held_counts += counts;
            return;
        }
        let leaf_area = info.leaf_area * scale * scale;
        let first_group = out.leaf_groups.len() as u32;
        let mut leaves_value = 0.0;
        let mut leaf_depth = None;
        if whole {
            // Every group at the centre's depth and distance: one value per leaf, times
            // the groups' leaf counts to the area's power (see `ModelInfo`).
            let per_leaf = self.value_of(leaf_area, center, budget.leaf_importance);
            let counts = if self.area_exponent_one {
                info.group_leaves
            } else {
                info.group_leaves_sqrt
            };
            leaves_value = crate::budget::finite_value(per_leaf * counts);
            leaf_depth = Some(center_depth.max(crate::budget::MIN_DEPTH));
        } else if let (Some(model), Some(transform)) =
            (self.models.get(info.id), self.table.transforms.get(i))
        {
            for (g, group) in model.leaf_groups.iter().enumerate() {
                if !self.culling.result.group_visible(i, g) {
                    continue;
                }
                let center = transform.transform_point3(group.bounds.center);
                let n = group.leaves.len() as f32;
                leaves_value += self.value_of(n * leaf_area, center, budget.leaf_importance);
                out.leaf_groups.push(VisibleLeafGroup {
                    group: g as u32,
                    depth: view.depth(center).max(crate::budget::MIN_DEPTH),
                });
            }
        }
        let groups = first_group..out.leaf_groups.len() as u32;
        let object = |part| Object { index: tree, part };
        if trunk_visible && info.has_trunk {
            let area = info.trunk_area * scale * scale;
            let (rank, complexity) = info.trunk_rank;
            let value = self.value_of(area, trunk_center, budget.trunk_importance);
            out.keyed
                .push((rank, complexity, object(Part::Trunk), value));
        }
        if !groups.is_empty() || leaf_depth.is_some() {
            let (rank, complexity) = info.leaves_rank;
            out.keyed
                .push((rank, complexity, object(Part::Leaves), leaves_value));
        }
        out.trees.push(VisibleTree {
            entity,
            instance: i as u32,
            model: model_index,
            view: TreeView {
                scale,
                trunk_depth: view.depth(trunk_center).max(crate::budget::MIN_DEPTH),
                projection: view.projection(),
            },
            groups,
            leaf_depth,
        });
    }
}

/// The keyed objects into `objects`, `complexities` and `values`, simple → complex: ranks
/// are few (two per model), so a counting sort by rank is O(n) and stable, and the
/// complexities arrive sorted (Robin Hood then runs in O(n)).
fn order_simple_to_complex(visible: &mut VisibleObjects) {
    let starts = &mut visible.rank_starts;
    starts.clear();
    starts.resize(2 * visible.infos.len() + 1, 0);
    // (`model_infos` ranks the 2 · models object types 0..2 · models.)
    for &(rank, ..) in &visible.keyed {
        starts[rank as usize + 1] += 1;
    }
    for r in 1..starts.len() {
        starts[r] += starts[r - 1];
    }
    let n = visible.keyed.len();
    let placeholder = Object {
        index: 0,
        part: Part::Trunk,
    };
    visible.objects.resize(n, placeholder);
    visible.complexities.resize(n, 0.0);
    visible.values.resize(n, 0.0);
    for &(rank, complexity, object, value) in &visible.keyed {
        let at = &mut starts[rank as usize];
        let i = *at as usize;
        *at += 1;
        visible.objects[i] = object;
        visible.complexities[i] = complexity;
        visible.values[i] = value;
    }
}

/// The mesh-ladder entities in view, valued like the trees and merged into the simple →
/// complex order (their complexity: their best level's calibrated cost).
fn value_ladders(
    visible: &mut VisibleObjects,
    budget: &FrameBudget,
    cost_model: &CostModel,
    view: &LodView,
    frustum: Option<&FrustumPlanes>,
    ladders: &mut LadderObjects,
) {
    ladders.chosen.clear();
    ladders.chosen.resize(ladders.entries.len(), None);
    if ladders.entries.is_empty() {
        return;
    }
    let costs = PrimitiveCosts::from_calibration(cost_model.calibration(), 1.0);
    let keyed = &mut visible.ladder_keyed;
    keyed.clear();
    for (e, entry) in ladders.entries.iter().enumerate() {
        let sphere = BoundingSphere {
            center: entry.center,
            radius: entry.radius,
        };
        if frustum.is_some_and(|planes| !planes.intersects_sphere(&sphere)) {
            continue;
        }
        let Some(&best) = ladders.triangles.get(entry.levels.start as usize) else {
            continue;
        };
        let value = value_seen(budget, view, entry.area, entry.center, entry.importance);
        let object = Object {
            index: e as u32,
            part: Part::Mesh,
        };
        keyed.push((costs.mesh(best), object, value));
    }
    if keyed.is_empty() {
        return;
    }
    keyed.sort_by(|a, b| a.0.total_cmp(&b.0));
    // Merge with the trees' objects, already in order: stable, trees first on ties.
    let trees = visible.objects.len();
    let (objects, complexities, values) = (
        core::mem::take(&mut visible.objects),
        core::mem::take(&mut visible.complexities),
        core::mem::take(&mut visible.values),
    );
    visible.objects.reserve(trees + keyed.len());
    let (mut t, mut l) = (0, 0);
    while t < trees || l < keyed.len() {
        let tree_first = l == keyed.len() || (t < trees && complexities[t] <= keyed[l].0);
        if tree_first {
            visible.objects.push(objects[t]);
            visible.complexities.push(complexities[t]);
            visible.values.push(values[t]);
            t += 1;
        } else {
            let (complexity, object, value) = keyed[l];
            visible.objects.push(object);
            visible.complexities.push(complexity);
            visible.values.push(value);
            l += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::species;
    use bevy::platform::collections::HashMap;

    /// `refresh_infos` after a change of the models (`edited`: the in-place changes).
    fn refreshed(visible: &mut VisibleObjects, models: &Assets<TreeModel>, edited: u64) {
        static CHANGES: core::sync::atomic::AtomicU64 = core::sync::atomic::AtomicU64::new(1);
        let any = CHANGES.fetch_add(1, core::sync::atomic::Ordering::Relaxed);
        let version = TreeModelsVersion { any, edited };
        refresh_infos(visible, models, &CostModel::default(), version);
    }

    /// Each model's index and ranks after `refresh_infos`, by id.
    fn ranks(visible: &VisibleObjects) -> HashMap<AssetId<TreeModel>, (u32, u32, u32)> {
        visible
            .infos
            .iter()
            .enumerate()
            .map(|(m, info)| (info.id, (m as u32, info.trunk_rank.0, info.leaves_rank.0)))
            .collect()
    }

    /// A model added later is appended (every model keeps its index, so the placements
    /// that point at infos stay right) and the object types are ranked among all as a
    /// derivation of every model at once ranks them; a model removed keeps its place
    /// until the removed are as many as the rest, and a model changed derives them all
    /// anew.
    #[test]
    fn models_added_later_are_appended_and_ranked_among_all() {
        let mut models = Assets::<TreeModel>::default();
        let slender = models.add(species("slender")).id();
        let grand = models.add(species("grand")).id();
        let mut visible = VisibleObjects::default();
        refreshed(&mut visible, &models, 0);
        let before = ranks(&visible);
        let generation = visible.models.generation();
        let broad = models.add(species("broad")).id();
        refreshed(&mut visible, &models, 0);
        let after = ranks(&visible);
        assert_eq!(visible.models.generation(), generation, "appended");
        for id in [slender, grand] {
            assert_eq!(
                after[&id].0, before[&id].0,
                "an earlier model kept its index"
            );
        }
        assert_eq!(after[&broad].0, 2);
        let mut at_once = VisibleObjects::default();
        refreshed(&mut at_once, &models, 0);
        let at_once = ranks(&at_once);
        for id in [slender, grand, broad] {
            assert_eq!(
                (after[&id].1, after[&id].2),
                (at_once[&id].1, at_once[&id].2),
                "ranks as if derived at once"
            );
        }
        // A model removed keeps its place until the removed are as many as the rest.
        models.remove(grand);
        refreshed(&mut visible, &models, 0);
        assert_eq!(visible.models.generation(), generation, "kept");
        assert_eq!((visible.infos.len(), visible.models.len()), (3, 2));
        assert_eq!(ranks(&visible)[&broad].0, 2);
        models.remove(slender);
        refreshed(&mut visible, &models, 0);
        assert_ne!(visible.models.generation(), generation, "derived anew");
        assert_eq!((visible.infos.len(), visible.models.len()), (1, 1));
        let (index, trunk, leaves) = ranks(&visible)[&broad];
        assert_eq!((index, trunk.min(leaves), trunk.max(leaves)), (0, 0, 1));
        // A model changed derives them all anew.
        let generation = visible.models.generation();
        refreshed(&mut visible, &models, 1);
        assert_ne!(visible.models.generation(), generation);
    }
}
