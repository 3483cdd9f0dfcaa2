//! The Budget stage's strategies: who hands out the rendering time, one file each behind
//! [`Strategy`]. A new strategy is a file here implementing it, a variant of
//! [`StrategyKind`] and a line in [`new_strategy`].

mod fixed;
mod hierarchical;
mod robin_hood;
mod rungs;

use bevy::platform::collections::HashMap;
use bevy::prelude::*;

use super::draw_lists::ImpostorLists;
use super::group_impostors::GroupImpostors;
use super::search::{Choices, ObjectSearch};
use super::select::Selected;
use super::value::NeededInstances;
use super::{FrameBudget, StrategyKind};
use crate::budget::{
    Allocation, BudgetStats, FunkhouserIncremental, FunkhouserSequin, TriangleBudget,
};
use crate::culling::ForestCulling;
use crate::draw::{PrimitiveCounts, TreeDrawList};
use crate::tree::TreeModel;

pub(super) use fixed::draw_everything;
pub(crate) use hierarchical::HierarchicalCut;

/// The strategy of each kind, made when first chosen and kept (with what it remembers
/// of its last frame) while others run.
#[derive(Resource, Default)]
pub(super) struct Strategies {
    states: HashMap<StrategyKind, Box<dyn Strategy>>,
}

impl Strategies {
    /// The strategy of `kind`.
    pub(super) fn get(&mut self, kind: StrategyKind) -> &mut dyn Strategy {
        self.states
            .entry(kind)
            .or_insert_with(|| new_strategy(kind))
            .as_mut()
    }
}

/// Before the Value stage: which instances the strategy needs valued this frame, from
/// its last frame (the fixed modes draw, so value, every visible tree).
pub(super) fn mark_needed_instances(
    budget: Res<FrameBudget>,
    culling: Option<Res<ForestCulling>>,
    impostors: Res<GroupImpostors>,
    mut strategies: ResMut<Strategies>,
    mut needed: ResMut<NeededInstances>,
) {
    let needed = &mut *needed;
    needed.only_marked = budget.mode.is_time_critical()
        && culling.is_some_and(|culling| {
            strategies.get(budget.strategy).needed_instances(
                &culling,
                &impostors,
                &mut needed.marked,
            )
        });
}

/// The registry: one line per [`StrategyKind`].
fn new_strategy(kind: StrategyKind) -> Box<dyn Strategy> {
    match kind {
        StrategyKind::RobinHood => Box::<robin_hood::RobinHoodStrategy>::default(),
        StrategyKind::FunkhouserSequin => Box::<rungs::RungGreedy<FunkhouserSequin>>::default(),
        StrategyKind::FunkhouserIncremental => {
            Box::<rungs::RungGreedy<FunkhouserIncremental>>::default()
        }
        StrategyKind::TriangleBudget => Box::<rungs::RungGreedy<TriangleBudget>>::default(),
        StrategyKind::Hierarchical => Box::<hierarchical::Hierarchical>::default(),
    }
}

/// Who hands out the rendering time among the visible objects.
pub(super) trait Strategy: Send + Sync + 'static {
    /// Hands out `hand_out.rendering` among the objects: draws each chosen one through
    /// `hand_out.choices` and writes one allocation per object.
    fn hand_out(&mut self, hand_out: &mut HandOut) -> Outcome;

    /// Before the Value stage: whether only some instances are to be valued this frame
    /// (then `needed` says which, per instance). Default: every visible one is.
    fn needed_instances(
        &mut self,
        _culling: &ForestCulling,
        _impostors: &GroupImpostors,
        _needed: &mut Vec<bool>,
    ) -> bool {
        false
    }
}

/// A frame's hand-out as a strategy sees it.
pub(super) struct HandOut<'a> {
    /// Every object's search.
    pub(super) search: &'a ObjectSearch<'a>,
    /// Where what is drawn goes.
    pub(super) choices: Choices<'a>,
    /// Per object, its value and complexity (simple → complex).
    pub(super) values: &'a [f32],
    pub(super) complexities: &'a [f32],
    /// The rendering time to hand out, seconds (held far trees' already taken off).
    pub(super) rendering: f32,
    /// Per object, what it was given and used: written by the strategy.
    pub(super) allocations: &'a mut Vec<Allocation>,
    /// A list for searches whose drawing is not kept.
    pub(super) scratch: &'a mut TreeDrawList,
    /// When far trees are being held ([`FrameBudget::far_refresh`](super::FrameBudget::far_refresh)):
    /// per visible tree, what its two parts drew, for the frames it will be held.
    pub(super) tree_parts: Option<&'a mut Vec<Selected>>,
    /// What a strategy over the culling boxes reads beside the objects.
    pub(super) scene: Scene<'a>,
}

/// The culling boxes, their group impostors and the cut over them.
pub(super) struct Scene<'a> {
    pub(super) culling: Option<&'a ForestCulling>,
    pub(super) impostors: &'a GroupImpostors,
    pub(super) models: &'a Assets<TreeModel>,
    pub(super) cut: &'a mut HierarchicalCut,
    /// The group impostors drawn this frame and their lists: empty before the hand-out
    /// (an impostor not listed draws nothing).
    pub(super) impostor_lists: &'a mut ImpostorLists,
}

/// What a hand-out drew.
#[derive(Clone, Default)]
pub(super) struct Outcome {
    pub(super) stats: BudgetStats,
    /// What the drawn choices together cost, by family.
    pub(super) drawn: Selected,
    /// Group impostors drawn, and their primitives.
    pub(super) impostors_drawn: u32,
    pub(super) impostor_counts: PrimitiveCounts,
    /// The benefit of what was drawn, when the strategy knows it better than the
    /// allocations' sum (a cut's group impostors).
    pub(super) benefit: Option<f32>,
    /// The strategy would choose otherwise next frame for the same scene (its own state
    /// is still moving, as a hierarchical cut refining from last frame's): a still scene
    /// does not keep this hand-out ([`FrameBudget::steady`](super::FrameBudget::steady)).
    pub(super) settling: bool,
}

impl Outcome {
    /// The outcome of `stats`, before anything drawn is counted.
    fn of(stats: BudgetStats) -> Self {
        Self {
            stats,
            ..Self::default()
        }
    }

    /// Counts `chosen` among what was drawn.
    fn count(&mut self, chosen: Selected) {
        self.drawn = Selected::both(self.drawn, chosen);
    }
}
