//! Deadlines on a display that waits for its vertical blank (pure).
//!
//! Under FIFO presentation a frame is shown after a whole number of refresh periods: one
//! whose work ends just after a vertical blank waits for the next one. So the frame time a
//! player sees is not the work but the work rounded up to the period grid, and a frame
//! that misses its vertical blank costs a whole period. A frame whose work fits the target
//! is shown at the first vertical blank at or after the target; the budget aims the work
//! at the target, or below that vertical blank by a margin from the measured scatter of
//! the work around its prediction (so that about a chosen share of frames misses it),
//! whichever is earlier.
//!
//! The period is measured, not taken on trust: a display that says it waits may not
//! (Xvfb), an app may pace its frames itself, and an emulated display may run at a rate
//! the monitor does not report. [`vblank_period`] finds it from the intervals of frames
//! that waited.

/// Shares of frames closer to 0 or 1 than this are taken as this.
const SHARE_LIMIT: f64 = 1e-6;

/// How many refresh periods of `period` seconds a frame whose work fits `target` seconds
/// takes on screen: the target rounded up to whole periods, at least one (a target at or
/// below the period is held as "the work fits the target", shown after one period).
pub fn allowed_periods(target: f32, period: f32) -> u32 {
    if !(period > 0.0 && period.is_finite() && target.is_finite()) {
        return 1;
    }
    // A target within a hundredth of a period past k periods (16.7 ms at 60 Hz) is
    // held to the k-th vertical blank.
    ((target / period) - 0.01).ceil().clamp(1.0, 1e6) as u32
}

/// The vertical blank a frame with `target` seconds must make: [`allowed_periods`] ×
/// `period`.
pub(crate) fn vblank_deadline(target: f32, period: f32) -> f32 {
    allowed_periods(target, period) as f32 * period
}

/// How many refresh periods a frame shown after `interval` seconds took (the nearest
/// whole number, at least one).
pub fn periods_taken(interval: f32, period: f32) -> u32 {
    if !(period > 0.0 && period.is_finite() && interval.is_finite()) {
        return 1;
    }
    (interval / period).round().clamp(1.0, 1e6) as u32
}

/// The time a frame's work should be aimed at: `target`, or under vsync (`period` is the
/// refresh period) the [`vblank_deadline`] divided by `spread_factor` (what the work's
/// scatter around its prediction reaches at the share of frames allowed to miss, e.g.
/// [`LogSpread::quantile_factor`](crate::cost::online::LogSpread::quantile_factor)),
/// whichever is less. Never negative; `target` when the inputs are not finite.
///
/// A period that is a fraction of the true one (60 Hz said, 20 Hz shown) gives the same
/// aim wherever the target sits at or below a true vertical blank by more than the
/// margin: the deadline on the finer grid is then the same vertical blank.
pub(crate) fn work_target(target: f32, period: Option<f32>, spread_factor: f32) -> f32 {
    let target = if target.is_finite() {
        target.max(0.0)
    } else {
        0.0
    };
    let Some(period) = period.filter(|p| *p > 0.0 && p.is_finite()) else {
        return target;
    };
    let factor = if spread_factor.is_finite() {
        spread_factor.max(1.0)
    } else {
        1.0
    };
    target.min(vblank_deadline(target, period) / factor)
}

/// The time a frame's work should be aimed at so that only the share of frames whose
/// scatter reaches `spread_factor` (e.g. [`LogSpread::quantile_factor`](crate::cost::online::LogSpread::quantile_factor)
/// at that share) take longer than `slack × target`: `slack × target / spread_factor`.
/// `slack` is taken within 1 to 4 (1 when not finite); a factor that is not finite and
/// positive counts as 1; never negative, 0 for a target that is not finite.
pub(crate) fn tail_target(target: f32, slack: f32, spread_factor: f32) -> f32 {
    if !target.is_finite() {
        return 0.0;
    }
    let slack = if slack.is_finite() {
        slack.clamp(1.0, 4.0)
    } else {
        1.0
    };
    let factor = if spread_factor.is_finite() && spread_factor > 0.0 {
        spread_factor
    } else {
        1.0
    };
    (target.max(0.0) * slack / factor).max(0.0)
}

/// Intervals within this share of a whole number of periods are on the period's grid.
pub(crate) const GRID_TOLERANCE: f32 = 0.03;
/// The share of waited frames that must lie on a period's grid for it to be the display's.
pub(crate) const GRID_AGREEMENT: f32 = 0.8;
/// Fewer waited frames than this say nothing about a period.
pub(crate) const GRID_MIN_FRAMES: usize = 8;

/// The refresh period that paces frames whose intervals (seconds, of frames that waited for
/// the display) are `intervals`: the shortest of them (a frame of one period), snapped to a
/// whole multiple of `hint` (the period the monitor reports) when within
/// [`GRID_TOLERANCE`] of one; `None` when fewer than [`GRID_MIN_FRAMES`] intervals are
/// given or less than [`GRID_AGREEMENT`] of them lie on that period's grid (waits that do
/// not follow a clock: back-pressure from a GPU, not a vertical blank).
pub(crate) fn vblank_period(intervals: &[f32], hint: Option<f32>) -> Option<f32> {
    let valid = || {
        intervals
            .iter()
            .copied()
            .filter(|x| x.is_finite() && *x > 0.0)
    };
    if valid().count() < GRID_MIN_FRAMES {
        return None;
    }
    let shortest = valid().fold(f32::INFINITY, f32::min);
    let candidate = match hint.filter(|h| *h > 0.0 && h.is_finite()) {
        Some(h) => {
            let m = (shortest / h).round().max(1.0);
            if (shortest / (m * h) - 1.0).abs() <= GRID_TOLERANCE {
                m * h
            } else {
                shortest
            }
        }
        None => shortest,
    };
    let on_grid = valid()
        .filter(|x| {
            let k = (x / candidate).round().max(1.0);
            (x / (k * candidate) - 1.0).abs() <= GRID_TOLERANCE
        })
        .count();
    (on_grid as f32 >= GRID_AGREEMENT * valid().count() as f32).then_some(candidate)
}

/// The number of standard deviations above the mean of a normal distribution that a share
/// `share` of it exceeds (the upper quantile `Φ⁻¹(1 − share)`), within 5 × 10⁻⁴
/// (Abramowitz & Stegun 26.2.23). `share` is taken within (10⁻⁶, 1 − 10⁻⁶); NaN gives 0.
pub(crate) fn upper_normal_quantile(share: f32) -> f32 {
    if share.is_nan() {
        return 0.0;
    }
    let q = f64::from(share).clamp(SHARE_LIMIT, 1.0 - SHARE_LIMIT);
    let (p, sign) = if q > 0.5 { (1.0 - q, -1.0) } else { (q, 1.0) };
    let t = (-2.0 * p.ln()).sqrt();
    let z = t
        - (2.515_517 + 0.802_853 * t + 0.010_328 * t * t)
            / (1.0 + 1.432_788 * t + 0.189_269 * t * t + 0.001_308 * t * t * t);
    (sign * z) as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    const P: f32 = 1.0 / 60.0;

    #[test]
    fn the_tail_target_leaves_the_scatter_s_quantile_below_the_slack() {
        // The scatter reaches ×1.2 at the share: aimed so that ×1.2 lands on 1.1 × target.
        assert!((tail_target(0.1, 1.1, 1.2) - 0.1 * 1.1 / 1.2).abs() < 1e-7);
        // A quiet machine (×1.03) is aimed above the target, never past the slack.
        let quiet = tail_target(0.1, 1.1, 1.03);
        assert!(quiet > 0.1 && quiet < 0.11);
        // Out-of-range inputs: slack within 1..4, a bad factor counts as 1.
        assert_eq!(tail_target(0.1, 0.5, 1.0), 0.1);
        assert_eq!(tail_target(0.1, 9.0, 1.0), 0.4);
        assert_eq!(tail_target(0.1, f32::NAN, 1.0), 0.1);
        assert_eq!(tail_target(0.1, 1.1, f32::NAN), tail_target(0.1, 1.1, 1.0));
        assert_eq!(tail_target(0.1, 1.1, 0.0), tail_target(0.1, 1.1, 1.0));
        assert_eq!(tail_target(f32::INFINITY, 1.1, 1.0), 0.0);
        assert_eq!(tail_target(-1.0, 1.1, 1.0), 0.0);
    }

    #[test]
    fn a_frame_that_fits_its_target_shows_at_the_vertical_blank_at_or_after_it() {
        assert_eq!(allowed_periods(0.9 * P, P), 1);
        assert_eq!(allowed_periods(P, P), 1);
        assert_eq!(allowed_periods(0.0167, P), 1);
        assert_eq!(allowed_periods(0.040, P), 3);
        assert_eq!(allowed_periods(2.0 * P, P), 2);
        assert_eq!(allowed_periods(0.0333, P), 2);
        assert_eq!(allowed_periods(0.001, P), 1);
        assert_eq!(allowed_periods(0.04, 0.0), 1);
        assert_eq!(allowed_periods(f32::NAN, P), 1);
        assert!((vblank_deadline(0.040, P) - 3.0 * P).abs() < 1e-6);
    }

    #[test]
    fn periods_taken_rounds_to_the_grid() {
        assert_eq!(periods_taken(P * 1.02, P), 1);
        assert_eq!(periods_taken(P * 1.97, P), 2);
        assert_eq!(periods_taken(0.0, P), 1);
        assert_eq!(periods_taken(3.0 * P, P), 3);
        assert_eq!(periods_taken(0.05, f32::NAN), 1);
    }

    #[test]
    fn the_work_is_aimed_below_the_deadline_by_the_spread() {
        // Without vsync the target itself.
        assert_eq!(work_target(0.05, None, 1.2), 0.05);
        // A target of one period: the deadline less the margin.
        let aim = work_target(0.05, Some(0.05), 1.1);
        assert!((aim - 0.05 / 1.1).abs() < 1e-6);
        // A target well below the period: the target (the work fits it, the frame shows
        // after one period).
        assert_eq!(work_target(0.03, Some(0.05), 1.1), 0.03);
        // Between two and three periods of 60 Hz: the target, well before the third.
        assert_eq!(work_target(0.045, Some(P), 1.05), 0.045);
        // Just before the third: the third less the margin.
        let aim = work_target(0.049, Some(P), 1.05);
        assert!((aim - 3.0 * P / 1.05).abs() < 1e-6, "{aim}");
        // 60 Hz said, 20 Hz shown: the same aims at 0.9 and 1.0 of the true period.
        for t in [0.045, 0.05] {
            let (fine, true_grid) = (
                work_target(t, Some(P), 1.08),
                work_target(t, Some(0.05), 1.08),
            );
            assert!(
                (fine - true_grid).abs() < 1e-6,
                "{t}: {fine} against {true_grid}"
            );
        }
        // A factor below 1 (a biased spread) never aims past the deadline.
        assert_eq!(work_target(0.05, Some(0.05), 0.8), 0.05);
        assert_eq!(work_target(f32::NAN, Some(0.05), 1.1), 0.0);
        assert_eq!(work_target(0.05, Some(0.05), f32::NAN), 0.05);
    }

    #[test]
    fn the_period_is_found_from_the_intervals_of_frames_that_waited() {
        // An emulated 20 Hz display under a monitor that says 60 Hz: the coarsest grid
        // the frames show, on the monitor's.
        let frames = [
            0.05, 0.05, 0.1, 0.05, 0.0501, 0.05, 0.0499, 0.15, 0.05, 0.05,
        ];
        let p = vblank_period(&frames, Some(P)).unwrap();
        assert!((p - 3.0 * P).abs() < 1e-6, "{p}");
        // No monitor rate: the shortest interval.
        assert!((vblank_period(&frames, None).unwrap() - 0.0499).abs() < 1e-6);
        // A monitor rate the frames do not follow (24 Hz shown, 60 Hz said).
        let frames = [0.04167; 10];
        assert!((vblank_period(&frames, Some(P)).unwrap() - 0.04167).abs() < 1e-6);
        // Waits that follow no clock (back-pressure): no period.
        let frames = [
            0.031, 0.034, 0.029, 0.036, 0.033, 0.030, 0.038, 0.032, 0.035, 0.037,
        ];
        assert_eq!(vblank_period(&frames, Some(P)), None);
        assert_eq!(vblank_period(&frames, None), None);
        // Too few frames, or nonsense.
        assert_eq!(vblank_period(&[0.05; 5], Some(P)), None);
        assert_eq!(vblank_period(&[f32::NAN; 20], None), None);
    }

    #[test]
    fn the_normal_quantile_matches_its_table() {
        for (share, z) in [
            (0.5, 0.0),
            (0.1587, 1.0),
            (0.05, 1.6449),
            (0.01, 2.3263),
            (0.001, 3.0902),
        ] {
            let got = upper_normal_quantile(share);
            assert!((got - z).abs() < 1e-3, "{share}: {got} against {z}");
            assert!((upper_normal_quantile(1.0 - share) + z).abs() < 1e-3);
        }
        assert!(upper_normal_quantile(0.0).is_finite());
        assert_eq!(upper_normal_quantile(f32::NAN), 0.0);
    }
}
