//! How much of a target frame time is left for rendering, given the logic time
//! (paper equations 5–7, thesis T-6.14), and the thesis' combined frame-time
//! estimate for overlapping CPU and GPU work (T-6.1).

use bevy::reflect::Reflect;
use serde::{Deserialize, Serialize};

/// The paper's frame-time model: `ℓ = (t_l/t_f)²`, `ρ = 1 − ℓ`, `t_r = ρ²·t_f / C`.
///
/// The square terms model CPU (logic) and GPU (rendering) work overlapping: when the
/// logic takes a small share of the frame, nearly the whole frame is left for
/// rendering; as the logic approaches the target, rendering time falls smoothly to 0.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, Reflect)]
pub struct FrameTimeModel {
    /// The per-machine constant `C` (> 0). Larger values leave less time for rendering.
    /// A NaN, infinite, zero or negative constant is treated as `1.0`.
    ///
    /// Default: `1.0`.
    pub machine_constant: f32,
}

impl Default for FrameTimeModel {
    fn default() -> Self {
        Self {
            machine_constant: 1.0,
        }
    }
}

impl FrameTimeModel {
    /// A model with machine constant `C`.
    pub const fn new(machine_constant: f32) -> Self {
        Self { machine_constant }
    }

    /// The constant actually used: [`FrameTimeModel::machine_constant`], or `1.0`
    /// when that is not a finite positive number.
    pub fn effective_constant(&self) -> f32 {
        let c = self.machine_constant;
        if c.is_finite() && c > 0.0 { c } else { 1.0 }
    }

    /// Rendering time `t_r` available in a frame of `target` seconds whose logic takes
    /// `logic` seconds (P-5..P-7).
    ///
    /// Returns 0 — never a negative or NaN time — when the target is at or below the
    /// logic time, or when either input is NaN or not positive.
    pub fn rendering_time(&self, logic: f32, target: f32) -> f32 {
        if !(target.is_finite() && target > 0.0) || logic.is_nan() || logic >= target {
            return 0.0;
        }
        let logic = logic.max(0.0);
        let ell = (logic / target) * (logic / target);
        let rho = 1.0 - ell;
        let t_r = rho * rho * target / self.effective_constant();
        if t_r.is_finite() { t_r.max(0.0) } else { 0.0 }
    }

    /// The residual of the thesis' single-equation form T-6.14,
    /// `u⁴t_l⁴ − 2u²t_l² − C·u·t_r + 1` with `u = 1/t_f`: zero when `t_r` is the
    /// rendering time this model gives.
    pub fn t614_residual(&self, logic: f32, target: f32, rendering: f32) -> f64 {
        let u = 1.0 / f64::from(target);
        let tl = f64::from(logic);
        let c = f64::from(self.effective_constant());
        (u * tl).powi(4) - 2.0 * (u * tl).powi(2) - c * u * f64::from(rendering) + 1.0
    }
}

/// The thesis' estimate T-6.1 of a frame's time when logic (`t_l`) and rendering
/// (`t_r`) overlap: the larger of the two plus the smaller scaled by the square of
/// their ratio. Negative or NaN inputs count as 0.
pub fn combined_frame_time(logic: f32, rendering: f32) -> f32 {
    let clean = |x: f32| if x.is_nan() { 0.0 } else { x.max(0.0) };
    let (logic, rendering) = (clean(logic), clean(rendering));
    let (small, large) = if rendering < logic {
        (rendering, logic)
    } else {
        (logic, rendering)
    };
    if large == 0.0 {
        return 0.0;
    }
    (small / large) * (small / large) * small + large
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn paper_equations_by_hand() {
        // t_l = 0.01, t_f = 0.04: ℓ = 1/16, ρ = 15/16, t_r = (15/16)²·0.04 / 2.
        let model = FrameTimeModel::new(2.0);
        let expected = (15.0_f32 / 16.0).powi(2) * 0.04 / 2.0;
        assert_relative_eq!(
            model.rendering_time(0.01, 0.04),
            expected,
            max_relative = 1e-6
        );
    }

    #[test]
    fn satisfies_t614() {
        for c in [0.5, 1.0, 1.7] {
            let model = FrameTimeModel::new(c);
            for (tl, tf) in [(0.001, 0.0125), (0.02, 0.05), (0.15, 0.2), (0.0, 0.1)] {
                let tr = model.rendering_time(tl, tf);
                assert!(
                    model.t614_residual(tl, tf, tr).abs() < 1e-5,
                    "{c} {tl} {tf}"
                );
            }
        }
    }

    #[test]
    fn no_logic_leaves_the_whole_frame_over_c() {
        assert_relative_eq!(FrameTimeModel::new(1.25).rendering_time(0.0, 0.1), 0.08);
    }

    #[test]
    fn target_at_or_below_logic_gives_zero() {
        let model = FrameTimeModel::default();
        assert_eq!(model.rendering_time(0.05, 0.05), 0.0);
        assert_eq!(model.rendering_time(0.08, 0.05), 0.0);
        assert_eq!(model.rendering_time(0.01, 0.0), 0.0);
        assert_eq!(model.rendering_time(0.01, -1.0), 0.0);
        assert_eq!(model.rendering_time(f32::NAN, 0.05), 0.0);
        assert_eq!(model.rendering_time(0.01, f32::NAN), 0.0);
        assert_eq!(model.rendering_time(0.01, f32::INFINITY), 0.0);
    }

    #[test]
    fn rendering_time_falls_as_logic_grows() {
        let model = FrameTimeModel::default();
        let mut last = f32::INFINITY;
        for i in 0..=100 {
            let t = model.rendering_time(i as f32 * 0.001, 0.1);
            assert!(t <= last && t >= 0.0);
            last = t;
        }
        assert_eq!(last, 0.0);
    }

    #[test]
    fn invalid_constant_falls_back_to_one() {
        for c in [0.0, -2.0, f32::NAN, f32::INFINITY] {
            let model = FrameTimeModel::new(c);
            assert_eq!(model.effective_constant(), 1.0);
            assert_relative_eq!(model.rendering_time(0.0, 0.1), 0.1);
        }
    }

    #[test]
    fn combined_estimate_t61() {
        // Rendering dominates: (t_l/t_r)²·t_l + t_r.
        assert_relative_eq!(combined_frame_time(0.01, 0.04), 0.0625 * 0.01 + 0.04);
        // Logic dominates: (t_r/t_l)²·t_r + t_l.
        assert_relative_eq!(combined_frame_time(0.04, 0.01), 0.0625 * 0.01 + 0.04);
        // One dominating term: the frame is that term.
        assert_relative_eq!(combined_frame_time(0.0, 0.05), 0.05);
        assert_eq!(combined_frame_time(0.0, 0.0), 0.0);
        assert_eq!(combined_frame_time(f32::NAN, -1.0), 0.0);
    }
}
