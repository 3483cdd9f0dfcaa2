//! A hitch in the app's own update before the Budget stage (a slow system, a stall) makes
//! the frame late whatever is drawn. Handing the trees only what this frame's logic
//! leaves in the aim would drop every tree to its cheapest representation for that one
//! frame and restore it the next: a flash over the whole forest, for a frame that
//! rendering less makes little shorter (rendering shorter than the logic adds only its
//! serial share to the frame, [`FrameOverlap`]). So the rendering time is never less than
//! what a frame of the usual logic gets, as far as this frame's logic is long: such a
//! frame is late by at most the hitch itself.

use crate::cost::FrameOverlap;

/// The main world's usual logic before the Budget stage, learned from its frames: an
/// exponential average that follows a fall at once and a rise by at most a fifth of
/// itself a frame, so that one hitch moves it by a fifth for one frame (the next usual
/// frame brings it back) and a lasting rise, even tenfold, is followed within about 25
/// frames.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct UsualLogic {
    seconds: Option<f32>,
}

impl UsualLogic {
    /// How much of a frame's difference the average takes.
    const RATE: f32 = 0.2;
    /// The most a frame counts for, as a multiple of the usual.
    const MOST_RISE: f32 = 2.0;

    /// Learns a frame whose logic before the Budget stage took `so_far` seconds; returns
    /// the usual logic before this frame (this frame's own when there is none yet).
    pub(super) fn observe(&mut self, so_far: f32) -> f32 {
        if !(so_far.is_finite() && so_far >= 0.0) {
            return self.seconds.unwrap_or(0.0);
        }
        let usual = self.seconds.unwrap_or(so_far);
        let counted = so_far.min(Self::MOST_RISE * usual);
        let next = if counted < usual {
            counted
        } else {
            usual + Self::RATE * (counted - usual)
        };
        self.seconds = Some(next);
        usual
    }
}

/// The longest rendering time for a frame whose logic takes `logic` seconds, aimed at
/// `aim`: what the logic leaves ([`FrameOverlap::rendering_time`]), but never less than
/// what a frame of the `usual` logic gets, up to `logic` (rendering that the longer
/// logic hides).
pub(super) fn rendering_time(overlap: FrameOverlap, logic: f32, usual: f32, aim: f32) -> f32 {
    let now = overlap.rendering_time(logic, aim);
    if !(usual.is_finite() && usual < logic) {
        return now;
    }
    now.max(overlap.rendering_time(usual, aim).min(logic))
}

#[cfg(test)]
mod tests {
    use super::*;

    const PIPELINED: FrameOverlap = FrameOverlap {
        sync: 0.001,
        serial: 0.1,
    };

    #[test]
    fn a_hitch_keeps_the_usual_rendering_time_and_is_late_by_at_most_itself() {
        let aim = 0.03;
        let usual = rendering_time(PIPELINED, 0.004, 0.004, aim);
        assert!(usual > 0.02, "{usual}");
        // 35 ms of logic: nothing is left in the aim, and the usual rendering hides
        // behind the logic.
        let hitch = rendering_time(PIPELINED, 0.035, 0.004, aim);
        assert_eq!(hitch, usual);
        assert_eq!(
            PIPELINED.rendering_time(0.035, aim),
            0.0,
            "what is left alone"
        );
        for overlap in [PIPELINED, FrameOverlap::SERIAL] {
            for logic in [0.01, 0.026, 0.035, 0.05] {
                let r = rendering_time(overlap, logic, 0.004, aim);
                let usual_frame =
                    overlap.frame_time(0.004, rendering_time(overlap, 0.004, 0.004, aim));
                let late = overlap.frame_time(logic, r) - usual_frame;
                assert!(
                    late <= logic - 0.004 + 1e-6,
                    "{overlap:?} {logic}: late by {late}"
                );
            }
        }
        // Rendering longer than this frame's logic is not kept: it would not hide.
        let short = rendering_time(FrameOverlap::SERIAL, 0.031, 0.004, 0.03);
        assert!(short <= 0.031, "{short}");
        // Logic as usual or shorter: what it leaves.
        assert_eq!(
            rendering_time(PIPELINED, 0.003, 0.004, aim),
            PIPELINED.rendering_time(0.003, aim)
        );
        assert_eq!(rendering_time(PIPELINED, 0.035, f32::NAN, aim), 0.0);
    }

    #[test]
    fn the_usual_logic_follows_a_fall_at_once_and_a_rise_slowly() {
        let mut usual = UsualLogic::default();
        assert_eq!(
            usual.observe(0.004),
            0.004,
            "the first frame is its own usual"
        );
        assert_eq!(usual.observe(0.004), 0.004);
        // One hitch moves it by a fifth at most.
        usual.observe(0.1);
        let after = usual.observe(0.004);
        assert!(after > 0.004 && after <= 0.004 * 1.2 + 1e-7, "{after}");
        assert!(usual.observe(0.002) > 0.002);
        assert_eq!(usual.observe(0.002), 0.002, "a fall is followed at once");
        // A lasting rise, tenfold, is followed within about 25 frames.
        let risen = (0..30).map(|_| usual.observe(0.02)).last().unwrap();
        assert!(risen > 0.019, "{risen}");
        assert_eq!(
            usual.observe(f32::NAN),
            usual.observe(0.02),
            "a NaN is not learned"
        );
    }
}
