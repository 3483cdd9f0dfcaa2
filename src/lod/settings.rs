//! What a user configures: the frame's target, the mode and the strategy.

use bevy::prelude::*;
use serde::{Deserialize, Serialize};

use super::{OverrunCut, SteadySelection};
use crate::budget::ValueFunction;
use crate::tree::PixelRange;

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

impl LodMode {
    /// Whether the mode hands out a rendering time ([`Tclod`](Self::Tclod),
    /// [`Tc`](Self::Tc)); the others draw every object by a fixed rule.
    pub(crate) fn is_time_critical(self) -> bool {
        matches!(self, Self::Tclod | Self::Tc)
    }
}

/// Which strategy hands out the rendering time in the time-critical modes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize, Reflect)]
pub enum StrategyKind {
    /// Robin Hood: every visible object gets time in proportion to its value, remainders
    /// pass on; nothing visible is dropped.
    #[default]
    RobinHood,
    /// Funkhouser–Séquin's greedy over each object's rungs; may drop objects.
    FunkhouserSequin,
    /// Funkhouser–Séquin's incremental variant, starting from last frame's choice.
    FunkhouserIncremental,
    /// The triangle-budget greedy.
    TriangleBudget,
    /// Mason & Blake's hierarchical optimisation over the culling boxes: a box in view
    /// may be drawn as one group impostor of all its trees ([`GroupImpostorSettings`]) instead of
    /// its trees, so a view too large for every tree's cheapest representation stays
    /// complete and on time. Each tree part is priced by its rungs as with
    /// [`FunkhouserSequin`](Self::FunkhouserSequin); the choice starts from last frame's.
    Hierarchical,
}

/// What a [`FrameBudget`]'s target promises.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, Reflect)]
pub enum FrameGoal {
    /// The paper's goal: frames predicted at the target. Frame times scatter around their
    /// prediction (6–11% on a shared machine), so about half the frames are longer.
    Mean,
    /// At most `share` of the frames longer than `slack × target`, and at most
    /// `rare_share` longer than `rare_slack × target`: the work is aimed at `slack ×
    /// target` divided by what the learned scatter of frame times around their prediction
    /// (`CostModel::frame_spread`) reaches at `share` (and likewise for the rare bound,
    /// whichever aim is lower). Where that scatter is reached is calibrated by how often
    /// frames actually pass it (adaptive conformal inference), so frame times with a
    /// longer tail than a log-normal one still keep their shares; the calibration aims at
    /// four fifths of each share, so that a run keeps its share rather than landing on
    /// either side of it. A noisy machine is
    /// aimed below the target, a quiet one a little above it (σ = 2%: 1.06 × target);
    /// under vsync never past the last vertical blank the target allows.
    Tail {
        /// Share of frames allowed over `slack × target`, in (0, 1). Default: `0.05`.
        share: f32,
        /// How far past the target a frame counts as over, as a factor (1 to 4).
        /// Default: `1.1`.
        slack: f32,
        /// Share of frames allowed over `rare_slack × target`: the bound on the rare
        /// long frames (the 99th percentile, by default). Default: `0.01`.
        #[serde(default = "default_rare_share")]
        rare_share: f32,
        /// How far past the target a rare frame may go, as a factor (1 to 4; 4 lifts
        /// the rare bound in practice). Default: `1.25`.
        #[serde(default = "default_rare_slack")]
        rare_slack: f32,
    },
}

/// The default rare bound: at most 1% of frames over 1.25 × target.
const RARE_SHARE: f32 = 0.01;
const RARE_SLACK: f32 = 1.25;

fn default_rare_share() -> f32 {
    RARE_SHARE
}

fn default_rare_slack() -> f32 {
    RARE_SLACK
}

impl FrameGoal {
    /// [`FrameGoal::Tail`]: at most `share` of the frames longer than `slack × target`,
    /// with the default rare bound (at most 1% longer than 1.25 × target).
    pub const fn tail(share: f32, slack: f32) -> Self {
        Self::Tail {
            share,
            slack,
            rare_share: RARE_SHARE,
            rare_slack: RARE_SLACK,
        }
    }

    /// The frame time past which a frame of `target` counts as over, in the target's
    /// unit: `slack × target` for [`FrameGoal::Tail`] (the slack taken within 1 to 4, as
    /// the budget does), and for [`FrameGoal::Mean`], which has no slack, 1.1 × target
    /// (the default tail's), so both goals are counted alike.
    pub(crate) fn over_limit(&self, target: f32) -> f32 {
        let slack = match *self {
            Self::Tail { slack, .. } => slack,
            Self::Mean => 1.1,
        };
        crate::budget::deadline::tail_target(target, slack, 1.0)
    }
}

impl Default for FrameGoal {
    fn default() -> Self {
        Self::tail(0.05, 1.1)
    }
}

/// The frame's budget and how it is spent. Changing it takes effect on the next frame.
#[derive(Resource, Clone, Debug, PartialEq, Serialize, Deserialize, Reflect)]
#[reflect(Resource)]
#[serde(default)]
pub struct FrameBudget {
    /// Target frame time in milliseconds; 100 because this crate's reference machine
    /// renders in software. Default: `100.0`. A target at or below the logic time leaves no rendering time:
    /// everything is drawn at its cheapest ([`LodDiagnostics::target_below_logic`](super::LodDiagnostics::target_below_logic)), and a
    /// warning is logged and [`TargetUnreachable`](super::TargetUnreachable) raised once
    /// it has lasted `TARGET_WARNING_SECS` (not for the slow frames of start-up, while
    /// shaders compile and the measured logic time settles).
    pub target_ms: f32,
    /// What the target promises. Default: [`FrameGoal::Tail`], at most 5% of frames over
    /// 1.1 × target and 1% over 1.25 × target; [`FrameGoal::Mean`] is the paper's (its tables use it).
    pub goal: FrameGoal,
    /// How objects are drawn. Default: [`LodMode::Tclod`].
    pub mode: LodMode,
    /// Who hands out the time in the time-critical modes. Default:
    /// [`StrategyKind::RobinHood`]. The
    /// other strategies see each object as rungs of its representations at
    /// `RUNG_FRACTIONS` of its full cost, with benefit `value · √(cost / full cost)`.
    pub strategy: StrategyKind,
    /// Value function. Default: [`ValueFunction::P11`].
    pub value: ValueFunction,
    /// Importance of trunks. Default: `1.0`. A value that is not finite or is negative
    /// is taken as the default, and both 0 as both defaults, with a warning
    /// (`importances`).
    pub trunk_importance: f32,
    /// Importance of leaves, as in the paper. Default: `0.0625` (1/16). See
    /// `trunk_importance`.
    pub leaf_importance: f32,
    /// Line widths in pixels. Default: `PixelRange { min: 1, max: 20 }`.
    pub line_widths: PixelRange,
    /// Point sizes in pixels; static mode uses the smallest. Default: `PixelRange { min: 1, max: 20 }`.
    pub point_sizes: PixelRange,
    /// With Robin Hood: a far tree (entirely in view and chosen as a whole, see
    /// `UNIFORM_DEPTH_RADII`) is decided again only every
    /// this many frames, the far trees taking turns; in between it keeps its
    /// representation, whose predicted time is taken off the rendering time before the
    /// hand-out. Trades how fast a far tree follows the camera for the LOD stages' time
    /// (at 20 000 far trees, 2 halves the Budget stage's work on them);
    /// [`LodDiagnostics::held_trees`](super::LodDiagnostics::held_trees) counts the trees
    /// held each frame. Default: `1` (every tree decided every frame, as in the paper).
    pub far_refresh: u32,
    /// How a still scene keeps its selection while the learned costs wander with the
    /// machine's noise (a still camera sees no shimmer). Default:
    /// [`SteadySelection::KEEP_WHILE_STILL`]; [`SteadySelection::OFF`] hands out anew
    /// every frame, as the paper does. Applies to
    /// the time-critical modes with `far_refresh` 1;
    /// [`LodDiagnostics::selection_kept`](super::LodDiagnostics::selection_kept) says when
    /// it did.
    pub steady: SteadySelection,
    /// How the aim reacts to consecutive frames over the goal's limit. Default:
    /// [`OverrunCut::OFF`]: beside the tail goal's calibrated margin, cutting after 2
    /// frames over left as many frames over and gave up 3.6 points of the target's
    /// detail (`docs/goals-calibrated.md`); it shortens a sudden slowdown's run of long
    /// frames (a test: 4 frames over instead of 7).
    pub overrun_cut: OverrunCut,
}

impl Default for FrameBudget {
    fn default() -> Self {
        Self {
            target_ms: 100.0,
            goal: FrameGoal::default(),
            mode: LodMode::Tclod,
            strategy: StrategyKind::RobinHood,
            value: ValueFunction::P11,
            trunk_importance: 1.0,
            leaf_importance: 1.0 / 16.0,
            line_widths: PixelRange::default(),
            point_sizes: PixelRange::default(),
            far_refresh: 1,
            steady: SteadySelection::default(),
            overrun_cut: OverrunCut::default(),
        }
    }
}

impl FrameBudget {
    /// The trunk and leaf importances the Value stage uses, and whether they differ from
    /// the ones set: each as set when finite and not negative, else its default; both at
    /// their defaults when both are 0 (no tree would be worth any time, and every one
    /// would stay at its cheapest however much time there is).
    pub(crate) fn importances(&self) -> ([f32; 2], bool) {
        let defaults = Self::default();
        let valid = |v: f32, default: f32| {
            if v.is_finite() && v >= 0.0 {
                v
            } else {
                default
            }
        };
        let mut used = [
            valid(self.trunk_importance, defaults.trunk_importance),
            valid(self.leaf_importance, defaults.leaf_importance),
        ];
        if used == [0.0, 0.0] {
            used = [defaults.trunk_importance, defaults.leaf_importance];
        }
        let replaced = used != [self.trunk_importance, self.leaf_importance];
        (used, replaced)
    }
}

/// Whether the Budget stage also scores its hand-out each frame, into
/// [`LodDiagnostics::benefit`](super::LodDiagnostics::benefit) and
/// [`benefit_bound`](super::LodDiagnostics::benefit_bound): how much of the best possible
/// benefit the strategy reached. For evaluation (the lab forest's `--record`); it
/// searches every visible object once more at full detail, which takes about as long as
/// the hand-out itself, and is left out of `budget_stage_ms`. Default: off.
///
/// The benefit is the ladders' model, `value · √(cost / full cost)` per object
/// (`sqrt_benefit`); the bound is its best total
/// within the rendering time (`sqrt_benefit_bound`),
/// which no strategy can exceed except where Robin Hood's cheapest representations alone
/// exceed the rendering time. With [`StrategyKind::Hierarchical`] the bound is over the
/// trees its cut reached: for the first frames after switching to it, while the cut is
/// still a few group impostors and reaches no tree, its benefit is above a bound of 0.
#[derive(Resource, Clone, Copy, Debug, Default, PartialEq, Eq, Reflect)]
#[reflect(Resource)]
pub struct BenefitReport {
    /// Score the hand-out. Default: `false`.
    pub enabled: bool,
}

/// The group impostors of the [`StrategyKind::Hierarchical`] strategy: one per box of the
/// culling hierarchy holding enough trees, built from its trees
/// (`group_impostor_model`) when the cut first reaches the box, and rebuilt when its trees
/// are planted or felled (not when they only move or sway: a group keeps its trees'
/// places at build time, and does not sway). Built lazily: only boxes last frame's cut
/// reached (and the children of those it drew as groups) get one, coarsest first, a few
/// a frame; those the cut has not reached for [`idle_secs`](Self::idle_secs) are
/// released. Until a box has one, the cut draws its trees on their own. Changing
/// `min_trees`, `leaves`, `trunks` or `max_vertices` releases them all (they are rebuilt
/// as wanted).
#[derive(Resource, Clone, Copy, Debug, PartialEq, Serialize, Deserialize, Reflect)]
#[reflect(Resource)]
#[serde(default)]
pub struct GroupImpostorSettings {
    /// A box gets a group impostor when it holds at least this many trees. Default: `16`.
    pub min_trees: u32,
    /// Leaves a group keeps (one triangle each, enlarged to its trees' leaf area).
    /// Default: `256`.
    pub leaves: u32,
    /// Trees whose stem and leaves a group keeps, at most. Default: `32`.
    pub trunks: u32,
    /// Vertices all the groups may have together: when the boxes in view want more, the
    /// coarsest are built first and the finer go without, so that the packed geometry
    /// stays within what a GPU binds at once (wgpu's default limit is 128 MiB, 4 Mi
    /// vertices of the pass's 32 bytes, and the trees need their share). Default:
    /// `2_000_000` (~1 600 groups at the other defaults).
    pub max_vertices: u32,
    /// CPU time a frame may spend building group impostors, milliseconds (at least one is
    /// built a frame while any is wanted; at the defaults one takes ~1 ms on a 2 GHz
    /// core). Default: `2.0`.
    pub build_ms_per_frame: f32,
    /// A group impostor the cut has not reached for this long (seconds of real time) is
    /// released, its memory with it. Default: `10.0`.
    pub idle_secs: f32,
}

impl Default for GroupImpostorSettings {
    fn default() -> Self {
        Self {
            min_trees: 16,
            leaves: 256,
            trunks: 32,
            max_vertices: 2_000_000,
            build_ms_per_frame: 2.0,
            idle_secs: 10.0,
        }
    }
}

impl GroupImpostorSettings {
    /// The group-model options these settings ask for.
    pub(crate) fn model_options(&self) -> crate::tree::GroupImpostorOptions {
        crate::tree::GroupImpostorOptions {
            leaves: self.leaves,
            trunks: self.trunks,
        }
    }

    /// The settings whose change releases every group impostor: what shapes a group and
    /// which boxes may have one.
    pub(crate) fn shape(&self) -> (u32, u32, u32, u32) {
        (self.min_trees, self.leaves, self.trunks, self.max_vertices)
    }
}

/// The fractions of an object's full-detail time at which its rungs are searched for the
/// strategies that price representations as rungs (Funkhouser–Séquin, its incremental
/// variant, the triangle budget, the hierarchical strategy; best → cheapest, 0 gives the
/// cheapest representation).
pub(crate) const RUNG_FRACTIONS: [f32; 7] = [1.0, 0.5, 0.25, 0.125, 1.0 / 16.0, 1.0 / 64.0, 0.0];

/// How long, in seconds, the target must stay at or below the logic time before a
/// warning is logged: longer than the start-up's slow frames take to leave the learned
/// logic time.
pub(crate) const TARGET_WARNING_SECS: f32 = 3.0;
