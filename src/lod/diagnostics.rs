//! Bevy diagnostics for the LOD stages: every field of [`LodDiagnostics`] as a
//! `sherwood/...` diagnostic, for `LogDiagnosticsPlugin`, the `DiagnosticsStore` or any
//! tool that reads Bevy diagnostics.

use bevy::diagnostic::{Diagnostic, DiagnosticPath, Diagnostics, RegisterDiagnostic};
use bevy::prelude::*;

use crate::cost::{FamilyTimes, FrameBound, LearnedCosts};
use crate::draw::PrimitiveCounts;
use crate::schedule::SherwoodSystems;

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
    /// Visible tree instances: those culling found in view, or with the hierarchical
    /// strategy those its cut reached (the others are drawn by group impostors).
    pub visible_instances: u32,
    /// Predicted logic time (the main world's update), ms: what had run when the budget
    /// was handed out ([`LodDiagnostics::logic_so_far_ms`]) and the learned rest.
    pub logic_ms: f32,
    /// The main world's logic measured when the budget was handed out, ms.
    pub logic_so_far_ms: f32,
    /// The app's own visible meshes (not ladder entities): their predicted rendering, ms,
    /// taken from the time before it is handed out.
    pub app_meshes_ms: f32,
    /// How many of them were drawn in the budget's view.
    pub app_mesh_draws: u32,
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
    /// What this frame's work was aimed at, ms: for [`FrameGoal::Tail`](super::FrameGoal::Tail)
    /// `slack × target` less the margin the measured scatter of frame times asks for at
    /// its share, for [`FrameGoal::Mean`](super::FrameGoal::Mean) the target; under vsync
    /// at most the last vertical blank within the target less the margin for
    /// [`VsyncSettings::missed_vblank_share`](crate::display::VsyncSettings).
    pub work_target_ms: f32,
    /// The display's refresh period under vsync, ms (0 without vsync).
    pub vsync_period_ms: f32,
    /// How the frames' work scatters around its prediction: the standard deviation of
    /// the log ratio (0.05 is about 5%).
    pub frame_spread: f32,
    /// How far the tail goal's quantile of that scatter, then its rare bound's, were
    /// moved by how often measured frames passed them, as log factors (0.05 is about
    /// 5%): positive where frame times have a longer tail than a log-normal scatter (0
    /// for the mean goal).
    pub tail_offsets: [f32; 2],
    /// The factor the overrun cut put on this frame's aim
    /// ([`FrameBudget::overrun_cut`](super::FrameBudget::overrun_cut); 1: no cut).
    pub overrun_factor: f32,
    /// The measured frame's work, ms: its frame time less the render world's waits for
    /// the display (at least the longer of its logic and its rendering).
    pub measured_work_ms: f32,
    /// The measured frame's GPU time, ms (0 when the adapter has no timestamp queries).
    pub measured_gpu_ms: f32,
    /// What the render world waited for in the measured frame (the next swapchain image,
    /// a frame pacer), ms.
    pub measured_waited_ms: f32,
    /// What paced the measured frame: the logic, the render world's CPU or the GPU.
    pub measured_bound: FrameBound,
    /// Refresh periods the measured frame took on screen (0 without vsync).
    pub measured_periods: u32,
    /// The measured frame took more refresh periods than the target allows: a missed
    /// vertical blank.
    pub missed_vblank: bool,
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
    /// Visible objects drawn with nothing (always 0 with Robin Hood and with the
    /// hierarchical strategy, whose group impostors stand for the trees they cover).
    pub undrawn: u32,
    /// Far trees that kept last decision's representation this frame
    /// ([`FrameBudget::far_refresh`](super::FrameBudget::far_refresh); 0 by default).
    pub held_trees: u32,
    /// The frame kept last frame's selection: the scene was still and it still fitted
    /// ([`FrameBudget::steady`](super::FrameBudget::steady)).
    pub selection_kept: bool,
    /// Group impostors drawn ([`StrategyKind::Hierarchical`](super::StrategyKind::Hierarchical);
    /// 0 otherwise).
    pub impostors_drawn: u32,
    /// Visible trees drawn on their own rather than by a group impostor (with the
    /// hierarchical strategy; every visible tree otherwise).
    pub trees_drawn: u32,
    /// The selection's benefit ([`BenefitReport`](super::BenefitReport); 0 when it is
    /// off or the mode has no budget).
    pub benefit: f32,
    /// The best benefit any selection could reach within the rendering time (same
    /// conditions). `benefit / benefit_bound` is the strategy's share of the optimum.
    pub benefit_bound: f32,
    /// Time of the Value stage, ms.
    pub value_stage_ms: f32,
    /// Time of the Budget stage, ms.
    pub budget_stage_ms: f32,
    /// Time of the `DrawLists` stage (the chosen lists written into the components), ms.
    pub draw_lists_stage_ms: f32,
    /// The target frame time is at or below the logic time this frame, so there was no
    /// rendering time to hand out and everything was drawn at its cheapest.
    pub target_below_logic: bool,
    /// Of the frames measured in the last second, the share longer than the goal's limit
    /// (`FrameGoal::over_limit`: `slack × target` for the
    /// default tail goal); the default goal holds it at about 5%.
    pub frames_over_share: f32,
}

/// The measured frames of the last second, each longer than the goal's limit or not.
#[derive(Default)]
pub(super) struct RecentFrames {
    /// `(frame number, frame time in seconds, over)`, oldest first.
    frames: std::collections::VecDeque<(u64, f32, bool)>,
    /// Their frame times together, seconds.
    span: f32,
}

impl RecentFrames {
    /// The window's length, seconds.
    const SPAN: f32 = 1.0;

    /// Adds measured frame `frame` (once: a frame already counted is left alone).
    fn push(&mut self, frame: u64, interval: f32, over: bool) {
        if frame == 0
            || !interval.is_finite()
            || self.frames.back().is_some_and(|&(last, ..)| last >= frame)
        {
            return;
        }
        self.frames.push_back((frame, interval, over));
        self.span += interval;
        // The fewest newest frames that still cover the window.
        while let Some(&(_, oldest, _)) = self.frames.front()
            && self.span - oldest >= Self::SPAN
        {
            self.frames.pop_front();
            self.span -= oldest;
        }
    }

    /// The share of the window's frames that were over (0 without frames).
    fn share_over(&self) -> f32 {
        let over = self.frames.iter().filter(|&&(.., over)| over).count();
        over as f32 / self.frames.len().max(1) as f32
    }
}

/// Counts the newest measured frame against the goal's limit into
/// [`LodDiagnostics::frames_over_share`].
pub(super) fn count_frames_over(
    budget: Res<super::FrameBudget>,
    mut diagnostics: ResMut<LodDiagnostics>,
    mut recent: Local<RecentFrames>,
) {
    let interval = diagnostics.measured_frame_ms / 1000.0;
    let limit = budget.goal.over_limit(budget.target_ms / 1000.0);
    recent.push(diagnostics.measured_frame, interval, interval > limit);
    diagnostics.frames_over_share = recent.share_over();
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The window holds a second of frames: a burst of long frames counts while it is in
    /// it and is forgotten once a second of short ones has passed.
    #[test]
    fn the_share_over_is_of_the_last_second_of_frames() {
        let mut recent = RecentFrames::default();
        for frame in 1..=20 {
            recent.push(frame, 0.05, frame > 18);
        }
        assert!(
            (recent.share_over() - 0.1).abs() < 1e-6,
            "{}",
            recent.share_over()
        );
        // The same frame reported again (the model reports the latest measured one
        // every frame) is counted once.
        recent.push(20, 0.05, true);
        assert!((recent.share_over() - 0.1).abs() < 1e-6);
        for frame in 21..=40 {
            recent.push(frame, 0.05, false);
        }
        assert_eq!(recent.share_over(), 0.0);
        // One frame longer than the window is the window.
        recent.push(41, 3.0, true);
        assert_eq!(recent.share_over(), 1.0);
    }
}

/// Publishes [`LodDiagnostics`] as Bevy diagnostics each frame. Without it the resource
/// is still kept (it is a few numbers) and nothing else is done.
#[derive(Default)]
pub struct LodDiagnosticsPlugin;

/// The published diagnostics, with how each is read off [`LodDiagnostics`].
const PATHS: [(DiagnosticPath, &str, fn(&LodDiagnostics) -> f64); 31] = [
    (
        DiagnosticPath::const_new("sherwood/visible_objects"),
        "",
        |d| f64::from(d.visible_objects),
    ),
    (
        DiagnosticPath::const_new("sherwood/visible_instances"),
        "",
        |d| f64::from(d.visible_instances),
    ),
    (DiagnosticPath::const_new("sherwood/logic"), "ms", |d| {
        f64::from(d.logic_ms)
    }),
    (
        DiagnosticPath::const_new("sherwood/render_budget"),
        "ms",
        |d| f64::from(d.render_budget_ms),
    ),
    (
        DiagnosticPath::const_new("sherwood/predicted_render"),
        "ms",
        |d| f64::from(d.predicted_render_ms),
    ),
    (
        DiagnosticPath::const_new("sherwood/predicted_frame"),
        "ms",
        |d| f64::from(d.predicted_frame_ms),
    ),
    (
        DiagnosticPath::const_new("sherwood/measured_frame"),
        "ms",
        |d| f64::from(d.measured_frame_ms),
    ),
    (DiagnosticPath::const_new("sherwood/wasted"), "ms", |d| {
        f64::from(d.wasted_ms)
    }),
    (DiagnosticPath::const_new("sherwood/triangles"), "", |d| {
        d.counts.triangles as f64
    }),
    (DiagnosticPath::const_new("sherwood/lines"), "", |d| {
        d.counts.lines as f64
    }),
    (DiagnosticPath::const_new("sherwood/points"), "", |d| {
        d.counts.points as f64
    }),
    (DiagnosticPath::const_new("sherwood/truncated"), "", |d| {
        f64::from(d.truncated)
    }),
    (DiagnosticPath::const_new("sherwood/undrawn"), "", |d| {
        f64::from(d.undrawn)
    }),
    (
        DiagnosticPath::const_new("sherwood/stage_time"),
        "ms",
        |d| f64::from(d.value_stage_ms + d.budget_stage_ms + d.draw_lists_stage_ms),
    ),
    (DiagnosticPath::const_new("sherwood/overrun"), "ms", |d| {
        f64::from(d.overrun_ms)
    }),
    (
        DiagnosticPath::const_new("sherwood/floor_excess"),
        "ms",
        |d| f64::from(d.floor_excess_ms),
    ),
    (
        DiagnosticPath::const_new("sherwood/measured_logic"),
        "ms",
        |d| f64::from(d.measured_logic_ms),
    ),
    (
        DiagnosticPath::const_new("sherwood/measured_render"),
        "ms",
        |d| f64::from(d.measured_render_ms),
    ),
    (
        DiagnosticPath::const_new("sherwood/measured_frame_predicted"),
        "ms",
        |d| f64::from(d.measured_frame_predicted_ms),
    ),
    (
        DiagnosticPath::const_new("sherwood/learned_render_fixed"),
        "ms",
        |d| f64::from(d.learned.render_fixed_ms),
    ),
    (
        DiagnosticPath::const_new("sherwood/learned_render_speed"),
        "",
        |d| f64::from(d.learned.render_speed),
    ),
    (
        DiagnosticPath::const_new("sherwood/measured_work"),
        "ms",
        |d| f64::from(d.measured_work_ms),
    ),
    (
        DiagnosticPath::const_new("sherwood/measured_gpu"),
        "ms",
        |d| f64::from(d.measured_gpu_ms),
    ),
    (
        DiagnosticPath::const_new("sherwood/work_target"),
        "ms",
        |d| f64::from(d.work_target_ms),
    ),
    (
        DiagnosticPath::const_new("sherwood/missed_vblank"),
        "",
        |d| f64::from(u8::from(d.missed_vblank)),
    ),
    (
        DiagnosticPath::const_new("sherwood/frame_spread"),
        "",
        |d| f64::from(d.frame_spread),
    ),
    (DiagnosticPath::const_new("sherwood/tail_offset"), "", |d| {
        f64::from(d.tail_offsets[0])
    }),
    (DiagnosticPath::const_new("sherwood/rare_offset"), "", |d| {
        f64::from(d.tail_offsets[1])
    }),
    (
        DiagnosticPath::const_new("sherwood/overrun_factor"),
        "",
        |d| f64::from(d.overrun_factor),
    ),
    (
        DiagnosticPath::const_new("sherwood/frames_over_share"),
        "",
        |d| f64::from(d.frames_over_share),
    ),
    (
        DiagnosticPath::const_new("sherwood/learned_logic_fixed"),
        "ms",
        |d| f64::from(d.learned.logic_fixed_ms),
    ),
];

impl Plugin for LodDiagnosticsPlugin {
    fn finish(&self, app: &mut App) {
        crate::schedule::require_plugin::<super::LodPlugin>(
            app,
            "LodDiagnosticsPlugin",
            "LodPlugin",
        );
    }

    fn build(&self, app: &mut App) {
        for (path, suffix, _) in PATHS {
            app.register_diagnostic(Diagnostic::new(path).with_suffix(suffix));
        }
        app.add_systems(PostUpdate, publish.in_set(SherwoodSystems::Stats));
    }
}

fn publish(lod: Res<LodDiagnostics>, mut diagnostics: Diagnostics) {
    for (path, _, read) in &PATHS {
        diagnostics.add_measurement(path, || read(&lod));
    }
}
