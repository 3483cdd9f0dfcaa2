//! The Value stage: which trees are visible this frame, and a value and a rank per visible
//! object (a tree's trunk, its leaves).

use std::time::Instant;

use bevy::platform::collections::HashMap;
use bevy::prelude::*;

use super::select::{self, PrimitiveCosts, TreeView, VisibleGroup};
use super::{FrameBudget, GroupImpostors, LadderObjects, LodFrame, StrategyKind};
use crate::budget::{ValueInputs, ValueModel};
use crate::cost::CostModel;
use crate::culling::{CullView, ForestCulling, FrustumPlanes, InstanceVisibility};
use crate::draw::{ModelSlot, TreeDrawList};
use crate::instance::{FixedDrawList, ForestInstances, TreeInstance};
use crate::tree::{BoundingSphere, TreeModel, TreeModelsVersion};
use crate::view::LodView;

/// What an object of the hand-out is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(super) enum Part {
    /// A tree's trunk.
    Trunk,
    /// A tree's leaves.
    Leaves,
    /// A mesh entity with a LOD ladder.
    Ladder,
}

/// One visible object: a part of a tree, or a ladder entity.
#[derive(Clone, Copy, Debug)]
pub(super) struct Object {
    /// Index into [`LodFrame::trees`], or for [`Part::Ladder`] into
    /// [`LadderObjects::entries`](super::LadderObjects).
    pub(super) index: u32,
    pub(super) part: Part,
}

/// One visible tree this frame.
pub(super) struct VisibleTree {
    pub(super) entity: Entity,
    /// Its index in the instance table.
    pub(super) instance: u32,
    /// Index into [`LodFrame::infos`].
    pub(super) model: u32,
    pub(super) view: TreeView,
    pub(super) trunk_visible: bool,
    /// The visible leaf groups in [`LodFrame::groups`]; empty when `leaf_depth` is set.
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
pub const UNIFORM_DEPTH_RADII: f32 = 8.0;

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
    /// Index into [`LodFrame::infos`], or [`NO_MODEL`] when its model is not loaded.
    pub(super) model: u32,
    /// Uniform scale.
    pub(super) scale: f32,
    /// World-space centre of its bounding sphere, and of its trunk's area.
    pub(super) center: Vec3,
    pub(super) trunk_center: Vec3,
}

/// [`PlacedTree::model`] of an instance whose model is not loaded.
pub(super) const NO_MODEL: u32 = u32::MAX;

fn place_trees(table: &ForestInstances, infos: &[ModelInfo]) -> Vec<PlacedTree> {
    // (Group impostors add thousands of models: look them up, not search them.)
    let index: HashMap<AssetId<TreeModel>, usize> = infos
        .iter()
        .enumerate()
        .map(|(m, info)| (info.id, m))
        .collect();
    (0..table.len())
        .map(|i| {
            let transform = table.transforms[i];
            let id = table.model_id(i);
            let model = id.and_then(|id| index.get(&id).copied());
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

pub(super) fn value_objects(
    mut frame: ResMut<LodFrame>,
    budget: Res<FrameBudget>,
    cost_model: Res<CostModel>,
    culling: Option<Res<ForestCulling>>,
    views: Query<(&LodView, Option<&CullView>)>,
    table: Res<ForestInstances>,
    models: Res<Assets<TreeModel>>,
    version: Res<TreeModelsVersion>,
    mut ladders: ResMut<LadderObjects>,
    impostors: Res<GroupImpostors>,
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
    let frame = &mut *frame;
    frame.trees.clear();
    frame.groups.clear();
    frame.objects.clear();
    frame.values.clear();
    frame.complexities.clear();
    frame.view = None;
    let Some((view, cull_view)) = views.iter().next() else {
        return;
    };
    frame.viewport_pixels = view.viewport_pixels;
    frame.view = Some(*view);
    if let Some(culling) = culling {
        // The hierarchical strategy values only the trees its cut can reach this frame.
        let boxes = culling.hierarchy.as_ref();
        frame.only_needed = budget.strategy == StrategyKind::Hierarchical && boxes.is_some();
        if let (true, Some(boxes)) = (frame.only_needed, boxes) {
            let has_group = |node: usize| impostors.has_group(Some(&culling), node);
            frame.hierarchical.needed_instances(
                boxes,
                culling.hierarchy_version(),
                culling.result.visibility.len(),
                &has_group,
                &mut frame.needed,
            );
        }
        value_trees(
            frame,
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
        frame,
        budget,
        &cost_model,
        view,
        cull_view.map(|c| &c.0),
        &mut ladders,
    );
    frame.value_ms = start.elapsed().as_secs_f32() * 1000.0;
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
    frame: &mut LodFrame,
    budget: &FrameBudget,
    cost_model: &CostModel,
    culling: &ForestCulling,
    view: &LodView,
    table: &ForestInstances,
    models: &Assets<TreeModel>,
    version: &TreeModelsVersion,
) {
    if frame.ranked_version != Some(version.0) {
        let costs = PrimitiveCosts::from_calibration(cost_model.calibration(), 1.0);
        frame.infos = model_infos(models, &costs);
        frame.ranked_version = Some(version.0);
    }
    // Culling's answer is indexed by the table it was built for (the same, once models
    // have loaded: both are kept in the same frame).
    if culling.layout_version() != Some(table.layout_version()) {
        return;
    }
    let placed_key = (
        table.layout_version(),
        table.transforms_version(),
        version.0,
    );
    if frame.placed_key != Some(placed_key) {
        frame.placed = place_trees(table, &frame.infos);
        frame.placed_key = Some(placed_key);
    }
    let projection = view.projection();
    let value_of =
        |area: f32, at: Vec3, importance: f32| value_seen(budget, view, area, at, importance);
    let area_exponent_one = budget.value.area_exponent() == 1.0;
    // Far trees decided in turn (`FrameBudget::far_refresh`).
    frame.value_frames += 1;
    frame.held.clear();
    frame.held_parts = select::Selected::default();
    frame.held_counts = crate::draw::PrimitiveCounts::default();
    let refresh = u64::from(budget.far_refresh.max(1));
    let holding = refresh > 1
        && budget.strategy == StrategyKind::RobinHood
        && matches!(budget.mode, super::LodMode::Tc | super::LodMode::Tclod);
    let decided_key = (
        table.layout_version(),
        budget.mode,
        budget.line_widths,
        budget.point_sizes,
        budget.far_refresh,
    );
    // Trees planted or felled keep the others' decisions where they now stand.
    let edits = frame
        .decided_key
        .filter(|kept| {
            (kept.1, kept.2, kept.3, kept.4)
                == (decided_key.1, decided_key.2, decided_key.3, decided_key.4)
        })
        .and_then(|kept| table.edits_since(kept.0));
    match edits {
        Some(edits) if holding => edits.apply(&mut frame.decided, |_| None),
        _ if holding && frame.decided_key == Some(decided_key) => {}
        _ => frame.decided.clear(),
    }
    frame.decided_key = holding.then_some(decided_key);
    let turn = frame.value_frames;
    let LodFrame {
        infos,
        placed,
        trees,
        groups,
        keyed,
        only_needed,
        needed,
        decided,
        held,
        held_parts,
        held_counts,
        ..
    } = frame;
    keyed.clear();
    for (i, visibility) in culling.result.visibility.iter().enumerate() {
        if *only_needed && !needed.get(i).copied().unwrap_or(true) {
            continue;
        }
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
        ) = (placed.get(i), table.entities.get(i))
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
        if whole
            && !(i as u64 + turn).is_multiple_of(refresh)
            && let Some((parts, counts)) = decided.get(i).copied().flatten()
        {
            held.push(i as u32);
            *held_parts = select::Selected::both(*held_parts, parts);
            *held_counts += counts;
            continue;
        }
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
        } else if let (Some(model), Some(transform)) =
            (models.get(info.id), table.transforms.get(i))
        {
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
                    index: tree,
                    part: Part::Trunk,
                },
                value_of(area, trunk_center, budget.trunk_importance),
            ));
        }
        if !group_range.is_empty() || leaf_depth.is_some() {
            let (r, c) = info.leaves_rank;
            keyed.push((
                r,
                c,
                Object {
                    index: tree,
                    part: Part::Leaves,
                },
                leaves_value,
            ));
        }
        trees.push(VisibleTree {
            entity,
            instance: i as u32,
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
        index: 0,
        part: Part::Trunk,
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
}

/// The ladder entities in view, valued like the trees and merged into the simple →
/// complex order (their complexity: their best level's calibrated cost).
fn value_ladders(
    frame: &mut LodFrame,
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
    let keyed = &mut frame.ladder_keyed;
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
            part: Part::Ladder,
        };
        keyed.push((costs.mesh(best), object, value));
    }
    if keyed.is_empty() {
        return;
    }
    keyed.sort_by(|a, b| a.0.total_cmp(&b.0));
    // Merge with the trees' objects, already in order: stable, trees first on ties.
    let trees = frame.objects.len();
    let (objects, complexities, values) = (
        core::mem::take(&mut frame.objects),
        core::mem::take(&mut frame.complexities),
        core::mem::take(&mut frame.values),
    );
    frame.objects.reserve(trees + keyed.len());
    let (mut t, mut l) = (0, 0);
    while t < trees || l < keyed.len() {
        let tree_first = l == keyed.len() || (t < trees && complexities[t] <= keyed[l].0);
        if tree_first {
            frame.objects.push(objects[t]);
            frame.complexities.push(complexities[t]);
            frame.values.push(values[t]);
            t += 1;
        } else {
            let (complexity, object, value) = keyed[l];
            frame.objects.push(object);
            frame.complexities.push(complexity);
            frame.values.push(value);
            l += 1;
        }
    }
}
