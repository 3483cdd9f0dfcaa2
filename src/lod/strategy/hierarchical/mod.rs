//! [`StrategyKind::Hierarchical`](crate::lod::StrategyKind::Hierarchical): the culling
//! boxes in view solved as a Mason–Blake hierarchy from last frame's cut ([`cut`]), a box
//! drawn as its group impostor or as its trees, each tree part priced by its rungs.

mod cut;

use bevy::prelude::*;

pub(crate) use cut::HierarchicalCut;
use cut::{Drawn, HierarchicalFrame, HierarchyInputs, SearchedRungs};

use super::{HandOut, Outcome, Strategy};
use crate::budget::{Allocation, BudgetStats, MIN_DEPTH};
use crate::culling::ForestCulling;
use crate::draw::TreeDrawList;
use crate::lod::RUNG_FRACTIONS;
use crate::lod::group_impostors::{GroupImpostors, ImpostorStatus};
use crate::lod::search::{self, FULL_DETAIL_TIME, ObjectSearch};
use crate::lod::select::{self, Selected};
use crate::tree::TreeModel;

/// The hierarchical strategy's state, kept between frames.
#[derive(Default)]
pub(super) struct Hierarchical {
    frame: HierarchicalFrame,
    /// A list for the group impostors' rung searches.
    scratch: TreeDrawList,
}

impl Strategy for Hierarchical {
    fn needed_instances(
        &mut self,
        culling: &ForestCulling,
        impostors: &GroupImpostors,
        needed: &mut Vec<bool>,
    ) -> bool {
        let Some(boxes) = culling.hierarchy.as_ref() else {
            return false;
        };
        let status = |node: usize| impostors.status(Some(culling), node);
        self.frame.needed_instances(
            boxes,
            culling.hierarchy_version(),
            culling.result.visibility.len(),
            &status,
            needed,
        );
        true
    }

    fn hand_out(&mut self, hand_out: &mut HandOut) -> Outcome {
        let HandOut {
            search,
            choices,
            values,
            rendering,
            allocations,
            scratch,
            scene,
            ..
        } = hand_out;
        let (search, values, rendering) = (*search, *values, *rendering);
        let culling = scene.culling;
        let impostors = ImpostorSearch {
            impostors: scene.impostors,
            models: scene.models,
            search,
        };
        let status = |node: usize| scene.impostors.status(culling, node);
        let inputs = HierarchyInputs {
            boxes: culling.and_then(|c| c.hierarchy.as_ref()),
            instances: culling.map_or(0, |c| c.result.visibility.len()),
            trees: search.trees,
            objects: search.objects,
            values,
            ladders: search.ladders,
            rendering,
            layout: culling.and_then(ForestCulling::hierarchy_version),
            status: &status,
        };
        let group_scratch = &mut self.scratch;
        let solved = self.frame.solve(
            &inputs,
            &mut |i| search.rungs(i, values[i], scratch),
            &mut |node, value, members_full| {
                if status(node) != ImpostorStatus::Built {
                    return None;
                }
                Some(impostors.rungs(node, value, members_full, group_scratch))
            },
            scene.cut,
        );
        allocations.clear();
        allocations.resize(search.objects.len(), Allocation::DROPPED);
        let mut outcome = Outcome::default();
        let mut truncated = 0;
        let lists = &mut *scene.impostor_lists;
        for drawn in &self.frame.drawn {
            let chosen = match *drawn {
                Drawn::Object {
                    object,
                    level,
                    time,
                } => {
                    let chosen = choices.draw(search, object as usize, time).0;
                    allocations[object as usize] = Allocation::drawn(chosen.cost, level);
                    chosen
                }
                Drawn::Impostor { node, fraction, .. } => {
                    let Some(g) = scene
                        .impostors
                        .nodes
                        .get(node as usize)
                        .and_then(Option::as_ref)
                    else {
                        continue;
                    };
                    let list = lists.push(g.entity);
                    let chosen = impostors.search(node as usize, fraction, None, list).0;
                    outcome.impostor_counts += g.slot.counts(list);
                    chosen
                }
            };
            outcome.count(chosen);
            truncated += u32::from(chosen.truncated);
        }
        let used = outcome.drawn.cost;
        outcome.impostors_drawn = solved.impostors_drawn;
        outcome.benefit = Some(solved.solved.benefit as f32);
        // The cut moves a box level a frame from where last frame's left it, and refines
        // once the group impostors it waits for are built.
        outcome.settling = scene.cut.selection != scene.cut.seed || solved.waiting;
        // Not even the coarsest cut fitted: it is the floor, and its overrun the one no
        // choice could avoid.
        let floor = if solved.scene_dropped { used } else { 0.0 };
        outcome.stats = BudgetStats {
            rendering_time: rendering,
            given: used,
            used,
            wasted: (rendering - used).max(0.0),
            overrun: (used - rendering).max(0.0),
            drawn: self.frame.drawn.len() as u32,
            dropped: 0,
            truncated,
            floor,
            floor_excess: (floor - rendering).max(0.0),
        };
        outcome
    }
}

/// A group impostor's search: its trunk and leaves by the objects' methods.
struct ImpostorSearch<'a> {
    impostors: &'a GroupImpostors,
    models: &'a Assets<TreeModel>,
    search: &'a ObjectSearch<'a>,
}

impl ImpostorSearch<'_> {
    /// What box `node`'s group impostor draws with its trunk and leaves each given
    /// `fraction` of their full detail's time (`fulls`, searched when not given), and
    /// those full details' times.
    fn search(
        &self,
        node: usize,
        fraction: f32,
        fulls: Option<(f32, f32)>,
        list: &mut TreeDrawList,
    ) -> (Selected, (f32, f32)) {
        let (Some(g), Some(view)) = (
            self.impostors.nodes.get(node).and_then(Option::as_ref),
            self.search.view,
        ) else {
            return Default::default();
        };
        let Some(m) = self.models.get(&g.model) else {
            return Default::default();
        };
        let depth = |at: Vec3| view.depth(g.origin + at).max(MIN_DEPTH);
        let tree_view = select::TreeView {
            scale: 1.0,
            trunk_depth: depth(m.trunk_area_center),
            projection: view.projection(),
        };
        let costs = self.search.costs;
        let trunk = |time: f32, list: &mut TreeDrawList| {
            search::trunk(m, &tree_view, costs, self.search.trunk, time, list)
        };
        let leaf_depth = depth(m.bounds.center());
        let leaves = |time: f32, list: &mut TreeDrawList| {
            let method = self.search.leaves;
            select::leaves_at_depth(m, &tree_view, costs, method, leaf_depth, time, list)
        };
        let (full_trunk, full_leaves) = fulls.unwrap_or_else(|| {
            (
                trunk(FULL_DETAIL_TIME, list).cost,
                leaves(FULL_DETAIL_TIME, list).cost,
            )
        });
        let chosen = Selected::both(
            trunk(full_trunk * fraction, list),
            leaves(full_leaves * fraction, list),
        );
        (chosen, (full_trunk, full_leaves))
    }

    /// Box `node`'s group impostor's rungs worth `value`, judged against its trees' full
    /// detail (`members_full`) when that is more than its own; each rung's search is given
    /// its fraction.
    fn rungs(
        &self,
        node: usize,
        value: f32,
        members_full: f32,
        scratch: &mut TreeDrawList,
    ) -> SearchedRungs {
        let (best, fulls) = self.search(node, 1.0, None, scratch);
        let judged_full = members_full.max(best.cost);
        let rungs = search::rungs(value, judged_full, best.cost, |fraction| {
            self.search(node, fraction, Some(fulls), scratch).0.cost
        });
        (rungs, RUNG_FRACTIONS)
    }
}
