//! Time-critical level of detail in the ECS: a value per visible object, the frame's
//! rendering time handed out by Robin Hood, and per object the representation that fits,
//! written into each instance's [`TreeDrawList`](crate::draw::TreeDrawList).
//!
//! Each tree is two objects — its trunk and its leaves — with their own values and
//! complexities. Per frame, in [`SherwoodSystems`] order:
//!
//! * **Value**: for each visible instance ([`ForestCulling`](crate::culling::ForestCulling))
//!   the configured value
//!   function of its trunk (at the trunk's area-density centre) and of its leaves (the sum
//!   over its visible leaf groups, each at its own depth), times the part's importance.
//! * **Budget**: the logic time the cost model predicts for this many visible trees, the
//!   rendering time that leaves in the target (the learned overlap of logic and
//!   rendering, [`FrameOverlap`](crate::cost::FrameOverlap), replaces the paper's
//!   P-5..P-7), less the rendering's fixed part; every object's cheapest representation
//!   is paid first, then Robin Hood walks the objects simple → complex (object types are
//!   ranked once when models change) and each object's search (see `select`) picks what
//!   fits its floor plus its share, the remainder passing on; a residue left at the end is
//!   handed out again to objects below full detail. The search runs inside the hand-out
//!   because a remainder is only known once the object has chosen.
//!   With [`StrategyKind::Hierarchical`] the Budget stage instead solves the culling boxes
//!   in view as a Mason–Blake hierarchy (boxes with group impostors over trees over their
//!   trunk and leaves, see [`GroupImpostorSettings`] and `HierarchicalCut`) from last frame's
//!   cut; the Value stage then values only the trees that cut can reach. Each strategy
//!   is a file of its own behind one interface (`src/lod/strategy/`). In `Static` and
//!   `Unlimited` mode no time is handed out: every object draws what its mode draws.
//! * **Draw lists**: the chosen draw lists are copied into the instances' components;
//!   instances no longer chosen get empty lists.
//!
//! The Value stage reads the Budget stage's result of the frame before in two places (see
//! [`SherwoodSystems`]): far trees held by [`FrameBudget::far_refresh`] keep their last
//! decision, and with the hierarchical strategy only the trees its last cut can reach are
//! valued.
//!
//! The budget predicts with the [`CostModel`](crate::cost::CostModel): a measured calibration as the prior and
//! what the running app learned of its own frames (see [`crate::cost`]). The logic time
//! and the rendering time left in the target come from it, the rendering time is handed
//! out in its learned per-primitive costs, and each frame's prediction is recorded with
//! it ([`CostModel::record`](crate::cost::CostModel::record)) so that it learns from what that frame then measured.

mod aim;
mod alerts;
mod diagnostics;
mod draw_lists;
mod group_impostors;
mod hand_out;
mod logic_hitch;
mod overrun;
mod parallel;
mod search;
pub(crate) mod select;
mod settings;
mod steady;
mod strategy;
mod value;

pub use crate::budget::ValueFunction;
pub use alerts::{TargetUnreachable, Unreachable};
pub use diagnostics::{LodDiagnostics, LodDiagnosticsPlugin};
pub use group_impostors::GroupImpostors;
#[cfg(test)]
pub(crate) use group_impostors::{GROUP_REBUILD_SECS, GroupImpostorOf, ImpostorStatus};
pub use overrun::OverrunCut;
pub use settings::{
    BenefitReport, FrameBudget, FrameGoal, GroupImpostorSettings, LodMode, StrategyKind,
};
pub(crate) use settings::{RUNG_FRACTIONS, TARGET_WARNING_SECS};
pub use steady::SteadySelection;
pub(crate) use strategy::HierarchicalCut;

use bevy::prelude::*;

use crate::schedule::SherwoodSystems;
use crate::tree::TreeModelsVersion;

use draw_lists::{ChosenLists, write_draw_lists};
use group_impostors::build_group_impostors;
use hand_out::hand_out_time;
use strategy::{Strategies, mark_needed_instances};
use value::{FarDecisions, NeededInstances, VisibleObjects, give_draw_lists, value_objects};

/// Adds the Value, Budget and `DrawLists` stages, [`FrameBudget`] and [`LodDiagnostics`].
/// Part of [`SherwoodPlugins`](crate::SherwoodPlugins); needs the culling plugin and
/// the [`CostPlugin`](crate::cost::CostPlugin).
#[derive(Default)]
pub struct LodPlugin;

impl Plugin for LodPlugin {
    fn finish(&self, app: &mut App) {
        crate::core_plugin::warn_without_core(app, "LodPlugin");
        crate::schedule::require_plugin::<crate::tree::TreePlugin>(app, "LodPlugin", "TreePlugin");
        crate::schedule::require_plugin::<crate::cost::CostPlugin>(app, "LodPlugin", "CostPlugin");
    }

    fn build(&self, app: &mut App) {
        crate::core_plugin::use_instance_table(app);
        app.register_type::<FrameBudget>()
            .register_type::<LodDiagnostics>()
            .register_type::<BenefitReport>()
            .register_type::<GroupImpostorSettings>()
            .init_resource::<GroupImpostorSettings>()
            .init_resource::<GroupImpostors>()
            .init_resource::<HierarchicalCut>()
            .init_resource::<FrameBudget>()
            .init_resource::<BenefitReport>()
            .init_resource::<TreeModelsVersion>()
            .init_resource::<LodDiagnostics>()
            .init_resource::<VisibleObjects>()
            .init_resource::<FarDecisions>()
            .init_resource::<NeededInstances>()
            .init_resource::<Strategies>()
            .init_resource::<ChosenLists>()
            .init_resource::<LadderObjects>()
            .add_systems(
                PostUpdate,
                (
                    (
                        give_draw_lists,
                        build_group_impostors,
                        mark_needed_instances,
                        value_objects,
                    )
                        .chain()
                        .in_set(SherwoodSystems::Value),
                    hand_out_time.in_set(SherwoodSystems::Budget),
                    (write_draw_lists, diagnostics::count_frames_over)
                        .in_set(SherwoodSystems::DrawLists),
                ),
            );
    }
}

/// The mesh entities with LOD ladders in the hand-out beside the trees: written before
/// the Value stage by the ladder plugin ([`crate::ladder`], feature `render`), their
/// levels chosen by the Budget stage.
#[derive(Resource, Default, Debug)]
pub(crate) struct LadderObjects {
    /// One per ladder entity.
    pub(crate) entries: Vec<LadderEntry>,
    /// Every entry's levels' triangle counts, best first ([`LadderEntry::levels`]).
    pub(crate) triangles: Vec<u32>,
    /// Per entry, the level the Budget stage chose (0 = best); `None` out of view.
    pub(crate) chosen: Vec<Option<u32>>,
    /// The app's own visible meshes (not ladder entities) this frame.
    pub(crate) app_meshes: AppMeshLoad,
}

/// The app's own visible meshes in the budget's view: not budgeted, but predicted, so the
/// trees get the time they leave.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct AppMeshLoad {
    pub(crate) draws: u32,
    pub(crate) triangles: u64,
    /// The pixels their bounds cover (each at most the viewport).
    pub(crate) pixels: f32,
}

/// A ladder entity as the stages see it: a bounding sphere, an area for the value
/// function, an importance and its levels' triangle counts.
#[derive(Clone, Debug)]
pub(crate) struct LadderEntry {
    pub(crate) entity: Entity,
    /// Its bounding sphere, world space.
    pub(crate) center: Vec3,
    pub(crate) radius: f32,
    /// Its world-space surface area (of its bounding box): what the value function
    /// weighs, as a tree part's triangle area.
    pub(crate) area: f32,
    pub(crate) importance: f32,
    /// The level it shows now (0 = best), and what the hysteresis holds this frame.
    pub(crate) hold: select::LadderHold,
    /// Its levels in [`LadderObjects::triangles`].
    pub(crate) levels: core::ops::Range<u32>,
}
