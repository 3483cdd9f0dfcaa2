//! What one object of the hand-out draws with a given time: a tree's trunk or leaves by
//! the mode's methods ([`select`]), a mesh ladder's level; the cheapest representation
//! each costs, and the rungs the strategies that see an object as a list of
//! representations price it by.

use bevy::prelude::*;

use super::select::{self, LeafMethod, PrimitiveCosts, TreeView, VisibleLeafGroup};
use super::value::{Object, Part, VisibleTree};
use super::{FrameBudget, LadderEntry, LodMode, RUNG_FRACTIONS};
use crate::budget::{Level, oracle};
use crate::draw::TreeDrawList;
use crate::tree::{PixelRange, TreeModel};
use crate::view::LodView;

/// Time given to a search that is to find an object's full detail, seconds: more than
/// any object's full detail costs.
pub(super) const FULL_DETAIL_TIME: f32 = 1.0e6;

/// An object's rungs: each representation's cost and benefit at [`RUNG_FRACTIONS`] of its
/// full detail, best → cheapest.
pub(super) type Rungs = [Level; RUNG_FRACTIONS.len()];

/// The rungs of an object worth `value` whose full detail costs `full` (already
/// searched: the top rung): `cost_at(fraction)` is what its search draws with a smaller
/// fraction of its full detail's time (a rung never costs more than the one above it),
/// each judged against `judged_full` (its own full detail's cost, or for a group impostor
/// its trees').
pub(super) fn rungs(
    value: f32,
    judged_full: f32,
    full: f32,
    mut cost_at: impl FnMut(f32) -> f32,
) -> Rungs {
    let mut rungs = [Level::new(0.0, 0.0); RUNG_FRACTIONS.len()];
    let mut previous_cost = f32::INFINITY;
    for (rung, &fraction) in rungs.iter_mut().zip(&RUNG_FRACTIONS) {
        let searched = if fraction >= 1.0 {
            full
        } else {
            cost_at(fraction)
        };
        let cost = searched.min(previous_cost);
        previous_cost = cost;
        *rung = Level::new(cost, oracle::sqrt_benefit(value, judged_full, cost) as f32);
    }
    rungs
}

/// How a trunk is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum TrunkMethod {
    /// Triangles only, from the thickest segment down ([`select::trunk_tc`]).
    Tc,
    /// Lines of these widths and triangles ([`select::trunk_tclod`]).
    Tclod(PixelRange),
    /// The static points-and-lines LOD at these widths ([`select::trunk_static`]).
    Static(PixelRange),
}

/// The trunk and leaf methods of the budget's mode; in [`LodMode::Unlimited`] a search
/// given [`FULL_DETAIL_TIME`] or more draws everything.
pub(super) fn methods(budget: &FrameBudget) -> (TrunkMethod, LeafMethod) {
    match budget.mode {
        LodMode::Tclod => (
            TrunkMethod::Tclod(budget.line_widths),
            LeafMethod::Tclod(budget.point_sizes),
        ),
        LodMode::Tc => (TrunkMethod::Tc, LeafMethod::Tc),
        LodMode::Static => (
            TrunkMethod::Static(budget.line_widths),
            LeafMethod::Static(budget.point_sizes.sanitized().min),
        ),
        LodMode::Unlimited => (TrunkMethod::Tc, LeafMethod::Full),
    }
}

/// A trunk by `method` with `time`, written into `list`.
pub(super) fn trunk(
    model: &TreeModel,
    view: &TreeView,
    costs: &PrimitiveCosts,
    method: TrunkMethod,
    time: f32,
    list: &mut TreeDrawList,
) -> select::Selected {
    match method {
        TrunkMethod::Tc => select::trunk_tc(model, view, costs, time, list),
        TrunkMethod::Tclod(widths) => select::trunk_tclod(model, view, costs, widths, time, list),
        TrunkMethod::Static(widths) => select::trunk_static(model, view, costs, widths, list),
    }
}

/// Every object of this frame's hand-out as its search sees it.
pub(super) struct ObjectSearch<'a> {
    /// The visible objects, simple → complex.
    pub(super) objects: &'a [Object],
    pub(super) trees: &'a [VisibleTree],
    pub(super) leaf_groups: &'a [VisibleLeafGroup],
    /// The models by [`VisibleTree::model`] (`None`: not loaded).
    pub(super) models: Vec<Option<&'a TreeModel>>,
    /// This frame's learned per-primitive costs.
    pub(super) costs: &'a PrimitiveCosts,
    pub(super) trunk: TrunkMethod,
    pub(super) leaves: LeafMethod,
    /// The mesh-ladder entities ([`LadderObjects`](super::LadderObjects)) and their
    /// levels' triangle counts.
    pub(super) ladders: &'a [LadderEntry],
    pub(super) ladder_triangles: &'a [u32],
    /// The camera the Value stage saw.
    pub(super) view: Option<LodView>,
    /// Whether a mesh ladder keeps the level it shows while that fits (Robin Hood's
    /// choice; the strategies that price rungs keep their own previous choice).
    pub(super) keep_shown: bool,
}

impl ObjectSearch<'_> {
    fn model(&self, tree: &VisibleTree) -> Option<&TreeModel> {
        self.models.get(tree.model as usize).copied().flatten()
    }

    /// The entity object `object` belongs to.
    pub(super) fn entity(&self, object: Object) -> Entity {
        match object.part {
            Part::Mesh => self.ladders[object.index as usize].entity,
            _ => self.trees[object.index as usize].entity,
        }
    }

    /// What object `i` draws with `time`, written into `list` (a mesh ladder's level is
    /// [`mesh_level`](Self::mesh_level)'s and writes no list).
    pub(super) fn search(&self, i: usize, time: f32, list: &mut TreeDrawList) -> select::Selected {
        let object = self.objects[i];
        if object.part == Part::Mesh {
            return self.mesh_level(object, time).1;
        }
        let tree = &self.trees[object.index as usize];
        let Some(model) = self.model(tree) else {
            return select::Selected::default();
        };
        if object.part == Part::Leaves {
            self.tree_leaves(model, tree, time, list)
        } else {
            trunk(model, &tree.view, self.costs, self.trunk, time, list)
        }
    }

    /// What object `i` costs at full detail.
    pub(super) fn full_cost(&self, i: usize, scratch: &mut TreeDrawList) -> f32 {
        self.search(i, FULL_DETAIL_TIME, scratch).cost
    }

    /// Object `i`'s rungs worth `value`, and the time each rung's search is given.
    pub(super) fn rungs(
        &self,
        i: usize,
        value: f32,
        scratch: &mut TreeDrawList,
    ) -> (Rungs, [f32; RUNG_FRACTIONS.len()]) {
        let full = self.full_cost(i, scratch);
        let rungs = rungs(value, full, full, |fraction| {
            self.search(i, full * fraction, scratch).cost
        });
        (rungs, RUNG_FRACTIONS.map(|fraction| full * fraction))
    }

    /// What object `i` draws with no time: its cheapest representation's cost, found
    /// without searching.
    pub(super) fn floor(&self, i: usize) -> f32 {
        let object = self.objects[i];
        if object.part == Part::Mesh {
            let pixels = self.mesh_pixels(object.index);
            let levels = self.mesh_levels(object.index);
            return select::ladder_level(self.costs, levels, pixels, 0.0, None)
                .1
                .cost;
        }
        let tree = &self.trees[object.index as usize];
        let Some(model) = self.model(tree) else {
            return 0.0;
        };
        if object.part == Part::Leaves {
            return match tree.leaf_depth {
                Some(depth) => {
                    select::leaves_at_depth_floor(model, &tree.view, self.costs, self.leaves, depth)
                }
                None => {
                    let groups = self.leaf_groups_of(tree);
                    select::leaves_floor(model, &tree.view, self.costs, self.leaves, groups)
                }
            };
        }
        let widths = match self.trunk {
            TrunkMethod::Tc => None,
            TrunkMethod::Tclod(widths) | TrunkMethod::Static(widths) => Some(widths),
        };
        select::trunk_floor(model, &tree.view, self.costs, widths)
    }

    /// The level a mesh-ladder object wants with `time`, and the cost of what it will
    /// show: the hysteresis may hold the level shown, and then that is what is paid.
    pub(super) fn mesh_level(&self, object: Object, time: f32) -> (u32, select::Selected) {
        let hold = self
            .ladders
            .get(object.index as usize)
            .map_or(select::LadderHold::default(), |entry| entry.hold);
        let levels = self.mesh_levels(object.index);
        let pixels = self.mesh_pixels(object.index);
        let (wanted, chosen) = select::ladder_level(
            self.costs,
            levels,
            pixels,
            time,
            self.keep_shown.then_some(hold.shown),
        );
        let shown = hold.shown_for(wanted);
        let paid = if shown == wanted {
            chosen
        } else {
            select::ladder_cost(self.costs, levels, pixels, shown)
        };
        let Some(fading) = hold.fading_for(wanted) else {
            return (wanted, paid);
        };
        // Both levels are drawn while a fade runs; the level shown still says what more
        // time would change.
        let ghost = select::ladder_cost(self.costs, levels, pixels, fading);
        (
            wanted,
            select::Selected {
                full: paid.full,
                truncated: paid.truncated,
                ..select::Selected::both(paid, ghost)
            },
        )
    }

    /// A mesh-ladder entity's levels' triangle counts, best first.
    fn mesh_levels(&self, entry: u32) -> &[u32] {
        self.ladders
            .get(entry as usize)
            .and_then(|entry| {
                self.ladder_triangles
                    .get(entry.levels.start as usize..entry.levels.end as usize)
            })
            .unwrap_or(&[])
    }

    /// The pixels a mesh-ladder entity covers, whatever its level.
    fn mesh_pixels(&self, entry: u32) -> f32 {
        match (self.ladders.get(entry as usize), self.view) {
            (Some(entry), Some(view)) => view.sphere_pixels(entry.center, entry.radius),
            _ => 0.0,
        }
    }

    fn leaf_groups_of(&self, tree: &VisibleTree) -> &[VisibleLeafGroup] {
        &self.leaf_groups[tree.groups.start as usize..tree.groups.end as usize]
    }

    /// A tree's leaves with `time`: group by group, or all at one depth.
    fn tree_leaves(
        &self,
        model: &TreeModel,
        tree: &VisibleTree,
        time: f32,
        list: &mut TreeDrawList,
    ) -> select::Selected {
        let (view, costs, method) = (&tree.view, self.costs, self.leaves);
        match tree.leaf_depth {
            Some(depth) => select::leaves_at_depth(model, view, costs, method, depth, time, list),
            None => {
                let groups = self.leaf_groups_of(tree);
                select::leaves(model, view, costs, method, groups, time, list)
            }
        }
    }
}

/// Where the hand-out's choices go: each tree's list and each mesh ladder's level.
pub(super) struct Choices<'a> {
    /// Per visible tree, the list being chosen.
    pub(super) lists: &'a mut [TreeDrawList],
    /// Per mesh-ladder entity, the level chosen (`None`: out of view).
    pub(super) mesh_levels: &'a mut [Option<u32>],
    /// Per object, what its last search drew (a strategy that offers an object more
    /// time replaces its earlier choice).
    pub(super) drawn: &'a mut [select::Selected],
}

impl Choices<'_> {
    /// Draws object `i` with `time`: a tree part into its tree's list, a mesh ladder's
    /// level into `mesh_levels` (returned too); what it costs.
    pub(super) fn draw(
        &mut self,
        search: &ObjectSearch,
        i: usize,
        time: f32,
    ) -> (select::Selected, Option<u32>) {
        let object = search.objects[i];
        let (chosen, level) = if object.part == Part::Mesh {
            let (level, chosen) = search.mesh_level(object, time);
            self.mesh_levels[object.index as usize] = Some(level);
            (chosen, Some(level))
        } else {
            let list = &mut self.lists[object.index as usize];
            (search.search(i, time, list), None)
        };
        if let Some(slot) = self.drawn.get_mut(i) {
            *slot = chosen;
        }
        (chosen, level)
    }
}
