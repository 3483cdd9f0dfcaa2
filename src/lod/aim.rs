//! What the Budget stage aims a frame's work at: the target, or under vsync the last
//! vertical blank within it less a margin from the measured scatter of frame times
//! (see [`budget::deadline`](crate::budget::deadline)); and what the display made of the
//! last measured frame, for the diagnostics.

use super::FrameGoal;
use crate::budget::deadline::{
    allowed_periods, periods_taken, tail_target, upper_normal_quantile, work_target,
};
use crate::cost::{CostModel, FrameBound, LearnedFrame, MeasuredPacing};
use crate::display::{DisplayTiming, VsyncMode, VsyncSettings};

/// The frame's aim.
#[derive(Clone, Copy, Debug)]
pub(super) struct Aim {
    /// What the work is aimed at, seconds.
    pub(super) work: f32,
    /// The refresh period under vsync, seconds.
    pub(super) period: Option<f32>,
}

/// Aims a frame of `target` seconds at `goal`.
pub(super) fn aim(
    target: f32,
    goal: FrameGoal,
    display: Option<&DisplayTiming>,
    pacing: Option<&MeasuredPacing>,
    vsync: Option<&VsyncSettings>,
    model: &CostModel,
) -> Aim {
    let settings = vsync.copied().unwrap_or_default();
    let period = match settings.mode {
        VsyncMode::Off => None,
        VsyncMode::On { .. } => display.and_then(DisplayTiming::refresh_period),
        VsyncMode::FromWindow => {
            pacing.and_then(|p| p.period(display.and_then(DisplayTiming::refresh_period)))
        }
    };
    let spread = model.frame_spread();
    let vblank_factor = spread.quantile_factor(upper_normal_quantile(settings.missed_vblank_share));
    let tail = match goal {
        FrameGoal::Mean => target,
        FrameGoal::Tail { share, slack } => tail_target(
            target,
            slack,
            spread.quantile_factor(upper_normal_quantile(share)),
        ),
    };
    // Under vsync, never past the last vertical blank the target allows.
    let work = match period {
        Some(_) => work_target(target, period, vblank_factor).min(tail),
        None => tail,
    };
    Aim { work, period }
}

/// What the display made of a measured frame.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Shown {
    /// Its work, ms ([`FrameSample::work_interval`](crate::cost::FrameSample::work_interval)).
    pub(super) work_ms: f32,
    /// Its GPU time, ms (0 without timestamps).
    pub(super) gpu_ms: f32,
    /// The render world's waits, ms.
    pub(super) waited_ms: f32,
    /// What paced it.
    pub(super) bound: FrameBound,
    /// Refresh periods it took (0 without vsync).
    pub(super) periods: u32,
    /// It took more periods than `target` allows.
    pub(super) missed_vblank: bool,
}

pub(super) fn shown(measured: Option<&LearnedFrame>, target: f32, period: Option<f32>) -> Shown {
    let Some(frame) = measured else {
        return Shown::default();
    };
    let sample = &frame.measured;
    let periods = period.map_or(0, |p| periods_taken(sample.interval, p));
    Shown {
        work_ms: sample.work_interval() * 1000.0,
        gpu_ms: sample.gpu.unwrap_or(0.0) * 1000.0,
        waited_ms: sample.waited * 1000.0,
        bound: sample.bound(),
        periods,
        missed_vblank: period.is_some_and(|p| periods > allowed_periods(target, p)),
    }
}
