//! The asymmetric reaction to overrunning frames: after a run of consecutive frames past
//! the goal's limit, the next frames' aim is cut at once by the overrun measured, and the
//! cut is handed back as fast as the cost model learns the machine's speed (Unreal's
//! dynamic resolution reacts after 2 consecutive over-budget frames; Unity's samples cut
//! at once and restore slowly). The quantile calibration alone follows such a run only by
//! its small gain, and the learned speed by its time constant.

use bevy::prelude::*;
use serde::{Deserialize, Serialize};

/// How the budget reacts to consecutive frames over the goal's limit
/// ([`FrameBudget::overrun_cut`](super::FrameBudget::overrun_cut)).
///
/// After [`after_frames`](Self::after_frames) consecutive measured frames whose work took
/// longer than the goal's limit (`slack × target` for [`FrameGoal::Tail`](super::FrameGoal::Tail),
/// 1.1 × target for [`FrameGoal::Mean`](super::FrameGoal::Mean)), the aim is divided by
/// the smallest measured-over-predicted ratio of that run, and a still scene's kept
/// selection is handed out anew. The cut then fades with the cost model's speed time
/// constant ([`LearningRates::speed_seconds`](crate::cost::LearningRates::speed_seconds)),
/// as the model learns what the run measured, so a lasting slowdown is not cut twice.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, Reflect)]
#[serde(default)]
pub struct OverrunCut {
    /// Consecutive frames over the limit that cut the aim; `0` never cuts. Default: `0`.
    pub after_frames: u32,
}

impl OverrunCut {
    /// Never cut: the aim follows the goal and the learned costs alone (the default).
    pub const OFF: Self = Self { after_frames: 0 };

    /// Cut after 2 consecutive frames over the limit, as Unreal's dynamic resolution does.
    pub const AFTER_TWO: Self = Self { after_frames: 2 };
}

impl Default for OverrunCut {
    fn default() -> Self {
        Self::OFF
    }
}

/// The reaction's state: the run of frames over the limit and the cut in force.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct OverrunReaction {
    /// Consecutive measured frames over the limit.
    run: u32,
    /// The smallest log of measured over predicted in the run.
    run_ratio: f32,
    /// The cut in force, as a log factor (≥ 0).
    cut: f32,
    /// The cut was raised since [`take_cut`](Self::take_cut) last said so.
    fresh: bool,
}

impl OverrunReaction {
    /// Takes a measured frame: its work `measured` against the `predicted` frame time and
    /// the goal's `limit`, all in seconds, `interval` seconds after the one before; the
    /// cut fades with time constant `fade_seconds`.
    pub(crate) fn observe(
        &mut self,
        settings: OverrunCut,
        measured: f32,
        predicted: f32,
        limit: f32,
        interval: f32,
        fade_seconds: f32,
    ) {
        if interval.is_finite() && interval > 0.0 && fade_seconds > 0.0 {
            self.cut *= (-interval / fade_seconds).exp();
        }
        let ratio = (measured / predicted).ln();
        let over = measured.partial_cmp(&limit) == Some(std::cmp::Ordering::Greater);
        if settings.after_frames == 0 || !ratio.is_finite() || !over {
            self.run = 0;
            return;
        }
        self.run_ratio = if self.run == 0 {
            ratio
        } else {
            self.run_ratio.min(ratio)
        };
        self.run += 1;
        if self.run >= settings.after_frames {
            if self.run_ratio > self.cut {
                self.cut = self.run_ratio;
                self.fresh = true;
            }
            // A new run counts from here: one long run cuts again only after as many
            // more frames over.
            self.run = 0;
        }
    }

    /// The factor on the aim (≤ 1).
    pub(crate) fn factor(&self) -> f32 {
        (-self.cut.max(0.0)).exp()
    }

    /// Whether a frame observed since the last call raised the cut: a still scene's
    /// kept selection is then handed out anew (once).
    pub(crate) fn take_cut(&mut self) -> bool {
        std::mem::take(&mut self.fresh)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const LIMIT: f32 = 0.11;

    fn observe(r: &mut OverrunReaction, settings: OverrunCut, measured: f32) {
        r.observe(settings, measured, 0.09, LIMIT, 0.1, 0.25);
    }

    #[test]
    fn two_frames_over_cut_by_the_smaller_overrun_and_the_cut_fades() {
        let mut r = OverrunReaction::default();
        observe(&mut r, OverrunCut::AFTER_TWO, 0.12);
        assert_eq!(r.factor(), 1.0, "one frame over does not cut");
        observe(&mut r, OverrunCut::AFTER_TWO, 0.135);
        assert!(r.take_cut());
        assert!(!r.take_cut(), "a cut is taken once");
        assert!((r.factor() - 0.09 / 0.12).abs() < 1e-5, "{}", r.factor());
        let first = r.factor();
        observe(&mut r, OverrunCut::AFTER_TWO, 0.08);
        assert!(!r.take_cut());
        assert!(r.factor() > first && r.factor() < 1.0, "{}", r.factor());
        for _ in 0..30 {
            observe(&mut r, OverrunCut::AFTER_TWO, 0.08);
        }
        assert!(r.factor() > 0.999, "{}", r.factor());
    }

    #[test]
    fn frames_over_apart_and_the_setting_off_never_cut() {
        let mut r = OverrunReaction::default();
        for _ in 0..10 {
            observe(&mut r, OverrunCut::AFTER_TWO, 0.13);
            observe(&mut r, OverrunCut::AFTER_TWO, 0.10);
        }
        assert_eq!(r.factor(), 1.0);
        let mut off = OverrunReaction::default();
        for _ in 0..10 {
            observe(&mut off, OverrunCut::OFF, 0.13);
        }
        assert_eq!(off.factor(), 1.0);
    }

    #[test]
    fn nan_and_zero_times_are_ignored() {
        let mut r = OverrunReaction::default();
        for measured in [f32::NAN, 0.0, f32::INFINITY] {
            observe(&mut r, OverrunCut::AFTER_TWO, measured);
            observe(&mut r, OverrunCut::AFTER_TWO, measured);
        }
        r.observe(OverrunCut::AFTER_TWO, 0.2, 0.0, LIMIT, f32::NAN, 0.25);
        r.observe(OverrunCut::AFTER_TWO, 0.2, 0.0, LIMIT, f32::NAN, 0.25);
        assert!(r.factor().is_finite() && r.factor() <= 1.0);
    }
}
