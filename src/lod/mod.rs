//! Time-critical level of detail in the ECS: a value per visible object, the frame's
//! rendering time handed out by Robin Hood, and per object the representation that fits,
//! written into each instance's [`TreeDrawList`].
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
//!   ranked once when models change) and each object's search (see [`select`]) picks what
//!   fits its floor plus its share, the remainder passing on; a residue left at the end is
//!   handed out again to objects below full detail. The search runs inside the hand-out
//!   because a remainder is only known once the object has chosen.
//!   With [`StrategyKind::Hierarchical`] the Budget stage instead solves the culling boxes
//!   in view as a Mason–Blake hierarchy (boxes with group impostors over trees over their
//!   trunk and leaves, see [`GroupSettings`] and [`HierarchicalCut`]) from last frame's
//!   cut; the Value stage then values only the trees that cut can reach.
//! * **Draw lists**: the chosen draw lists are copied into the instances' components;
//!   invisible instances get empty lists. In `Static` and `Unlimited` mode no time is
//!   handed out and this stage does all the work.
//!
//! The budget predicts with the [`CostModel`](crate::cost::CostModel): a measured calibration as the prior and
//! what the running app learned of its own frames (see [`crate::cost`]). The logic time
//! and the rendering time left in the target come from it, the rendering time is handed
//! out in its learned per-primitive costs, and each frame's prediction is recorded with
//! it ([`CostModel::record`](crate::cost::CostModel::record)) so that it learns from what that frame then measured.

mod aim;
mod diagnostics;
mod groups;
mod hand_out;
mod hierarchical;
pub mod select;
mod settings;
mod value;

pub use diagnostics::{LodDiagnostics, LodDiagnosticsPlugin};
pub use groups::{GROUP_REBUILD_SECS, GroupImpostorOf, GroupImpostors};
pub use hierarchical::HierarchicalCut;
pub use settings::{
    BenefitReport, FrameBudget, FrameGoal, GroupSettings, LADDER_FRACTIONS, LodMode, StrategyKind,
    TARGET_WARNING_SECS,
};
pub use value::UNIFORM_DEPTH_RADII;

use bevy::platform::collections::HashMap;
use bevy::prelude::*;

use crate::budget::{
    Allocation, BudgetProblem, FunkhouserIncremental, FunkhouserSequin, RobinHood, TriangleBudget,
};
use crate::draw::TreeDrawList;
use crate::schedule::SherwoodSystems;
use crate::tree::TreeModelsVersion;

use groups::build_group_impostors;
use hand_out::{hand_out_time, write_draw_lists};
use select::VisibleGroup;
use value::{ModelInfo, Object, PlacedTree, VisibleTree, give_draw_lists, value_objects};

/// Adds the Value, Budget and Select stages, [`FrameBudget`] and [`LodDiagnostics`].
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
            .register_type::<GroupSettings>()
            .init_resource::<GroupSettings>()
            .init_resource::<GroupImpostors>()
            .init_resource::<HierarchicalCut>()
            .init_resource::<FrameBudget>()
            .init_resource::<BenefitReport>()
            .init_resource::<TreeModelsVersion>()
            .init_resource::<LodDiagnostics>()
            .init_resource::<LodFrame>()
            .init_resource::<LadderObjects>()
            .add_systems(
                PostUpdate,
                (
                    (give_draw_lists, build_group_impostors, value_objects)
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

/// The frame's working state, kept between frames to reuse its allocations.
#[derive(Resource, Default)]
pub(super) struct LodFrame {
    /// The view's pixel count: the most one primitive can cover.
    viewport_pixels: f32,
    trees: Vec<VisibleTree>,
    groups: Vec<VisibleGroup>,
    objects: Vec<Object>,
    /// `(complexity, object, value)` of the ladder entities in view, before merging.
    ladder_keyed: Vec<(f32, Object, f32)>,
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
    /// Last frame's rung per (entity, part), for the incremental strategies.
    previous: HashMap<(Entity, value::Part), u32>,
    next_previous: HashMap<(Entity, value::Part), u32>,
    scratch: TreeDrawList,
    /// The view of this frame (the Value stage's), for the group impostors' searches.
    view: Option<crate::view::LodView>,
    /// The hierarchical strategy's state and this frame's group impostor lists.
    hierarchical: hierarchical::HierarchicalFrame,
    group_lists: Vec<(Entity, TreeDrawList)>,
    /// The group impostors whose lists were written last frame.
    groups_shown: Vec<Entity>,
    /// The trees whose lists were written non-empty last frame.
    trees_shown: Vec<Entity>,
    /// Per instance, the frame stamp it was last chosen at (`stamp`: this frame's).
    stamps: Vec<u32>,
    stamp: u32,
    /// Per instance, the last decision of a far tree (whole tree at one depth): what it
    /// costs and draws (`None`: none to keep), for `FrameBudget::far_refresh`.
    decided: Vec<Option<(select::Selected, crate::draw::PrimitiveCounts)>>,
    /// What `decided` is valid for: layout, mode, widths and sizes, refresh.
    decided_key: Option<(
        u64,
        LodMode,
        crate::tree::PixelRange,
        crate::tree::PixelRange,
        u32,
    )>,
    /// The far trees held this frame (instances), and what they cost and draw together.
    held: Vec<u32>,
    held_parts: select::Selected,
    held_counts: crate::draw::PrimitiveCounts,
    /// Per visible tree, what its parts drew this frame (while far trees are held).
    tree_parts: Vec<select::Selected>,
    /// What each object chose in this frame's hand-out, by object (Robin Hood's residue
    /// passes offer an object more time and replace its earlier choice).
    object_choices: Vec<select::Selected>,
    /// Value stages run (which far trees take their turn).
    value_frames: u64,
    /// Whether the Value stage took only the `needed` instances (hierarchical strategy),
    /// and which those are, per instance.
    only_needed: bool,
    needed: Vec<bool>,
    /// Per model, its object types' ranks and the rest the stages derive from it; rebuilt
    /// when models change.
    infos: Vec<ModelInfo>,
    /// Per instance of [`ForestInstances`](crate::instance::ForestInstances), its model and placement: derived when
    /// the forest or the models change, not per frame.
    placed: Vec<PlacedTree>,
    /// The models' version `infos` was derived at, and the culling layout and models'
    /// version `placed` was.
    ranked_version: Option<u64>,
    placed_key: Option<(u64, u64, u64)>,
    value_ms: f32,
    /// Since when (real seconds since start-up) the target has been at or below the
    /// logic time, and whether that was reported.
    target_below_logic_since: Option<f32>,
    warned_target: bool,
}
