//! Whether the display (or a pacer) holds frames to a vertical blank, as measured: the
//! share of recent frames whose render world waited, and the period their intervals
//! follow ([`vblank_period`]). A window that says it waits may not (Xvfb does not), and an
//! app may pace its frames itself: the budget believes what the frames show.

use std::collections::VecDeque;

use bevy::prelude::*;

use super::{FrameSample, FrameSamples};
use crate::budget::deadline::vblank_period;

/// Recent frames this many long are looked at.
const RECENT_FRAMES: usize = 32;

/// How recent frames were paced, as measured. Kept by [`CostPlugin`](super::CostPlugin).
#[derive(Resource, Clone, Debug, Default)]
pub(crate) struct MeasuredPacing {
    /// (waited for the display, interval) of recent usable frames, oldest first.
    recent: VecDeque<(bool, f32)>,
}

impl MeasuredPacing {
    /// Takes a measured frame (unusable ones are ignored).
    pub(crate) fn observe(&mut self, sample: &FrameSample) {
        if !sample.is_usable() {
            return;
        }
        if self.recent.len() >= RECENT_FRAMES {
            self.recent.pop_front();
        }
        self.recent
            .push_back((sample.waited > super::WAIT_THRESHOLD, sample.interval));
    }

    /// The share of recent frames that waited for the display.
    pub(crate) fn waited_share(&self) -> f32 {
        let waited = self.recent.iter().filter(|(w, _)| *w).count();
        waited as f32 / self.recent.len().max(1) as f32
    }

    /// The refresh period that paces the frames, seconds: when most recent frames waited
    /// and their intervals follow one period's grid (snapped to `hint`, the monitor's
    /// period, when it fits). `None` when frames are not paced.
    pub(crate) fn period(&self, hint: Option<f32>) -> Option<f32> {
        if self.waited_share() <= 0.5 {
            return None;
        }
        let intervals: Vec<f32> = self
            .recent
            .iter()
            .filter(|(w, _)| *w)
            .map(|(_, i)| *i)
            .collect();
        vblank_period(&intervals, hint)
    }
}

pub(super) fn observe_pacing(samples: Res<FrameSamples>, mut pacing: ResMut<MeasuredPacing>) {
    for sample in samples.arrived() {
        pacing.observe(sample);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(waited: f32, interval: f32) -> FrameSample {
        FrameSample {
            logic: 0.01,
            render: 0.02,
            waited,
            interval,
            complete: true,
            ..Default::default()
        }
    }

    #[test]
    fn frames_held_to_a_grid_give_its_period_and_free_frames_none() {
        let mut pacing = MeasuredPacing::default();
        for _ in 0..40 {
            pacing.observe(&frame(0.0, 0.031));
        }
        assert_eq!(pacing.period(Some(1.0 / 60.0)), None);
        for k in 0..40 {
            pacing.observe(&frame(0.02, if k % 9 == 0 { 0.1 } else { 0.05 }));
        }
        let p = pacing.period(None).unwrap();
        assert!((p - 0.05).abs() < 1e-6, "{p}");
        // Unusable frames change nothing.
        let before = pacing.recent.clone();
        pacing.observe(&FrameSample {
            complete: false,
            ..frame(0.0, 0.01)
        });
        assert_eq!(pacing.recent, before);
    }
}
