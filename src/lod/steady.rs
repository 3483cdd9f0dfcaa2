//! Steady selections: while the scene stays as it was (the same camera, the same objects
//! of nearly the same values, the same settings), last frame's hand-out is kept as long
//! as it still fits the rendering time at this frame's learned costs. The learned costs
//! move a few percent a frame with the machine's noise; handing out again every frame
//! would move every object's share with them and flip choices across their thresholds
//! all over a still picture.

use bevy::prelude::*;
use serde::{Deserialize, Serialize};

use crate::cost::{FamilyScales, FamilyTimes};

/// How a still scene keeps its selection ([`FrameBudget::steady`](super::FrameBudget::steady)).
///
/// Last frame's selection, priced at this frame's learned costs, is kept while the price
/// is within `[(1 − below), (1 + above)] ×` the rendering time and the scene has not
/// changed; otherwise the time is handed out anew. A machine that slows or speeds up by
/// more than the band gets a new hand-out at once, so the target is still held.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, Reflect)]
#[serde(default)]
pub struct SteadySelection {
    /// How far below the rendering time the kept selection's price may fall (time left
    /// unused) before the time is handed out again, as a share. Default: `0` (see
    /// [`OFF`](Self::OFF)).
    pub below: f32,
    /// How far above the rendering time it may rise (a predicted overrun) before the
    /// time is handed out again, as a share. Default: `0`.
    pub above: f32,
    /// How much an object's value may change (a share of it) with the scene still
    /// counting as the same: trees swaying in the wind move their bounds a little.
    /// Default: `0`.
    pub value_change: f32,
}

impl SteadySelection {
    /// Hand out anew every frame (the paper's behaviour, and the default for now: a
    /// kept selection below the aim leaves fewer frames over than the tail goal
    /// promises, and the mesh ladders' own hysteresis is not yet reconciled with it).
    pub const OFF: Self = Self {
        below: 0.0,
        above: 0.0,
        value_change: 0.0,
    };

    /// Keep a still scene's selection within −10% / +3% of the rendering time, values
    /// within 2%.
    pub const KEEP_WHILE_STILL: Self = Self {
        below: 0.1,
        above: 0.03,
        value_change: 0.02,
    };

    /// Whether a selection that costs `price` fits `rendering` closely enough to keep.
    /// Shares that are not finite or negative count as 0 (no keeping on that side).
    pub(crate) fn keeps(&self, price: f32, rendering: f32) -> bool {
        let share = |s: f32| {
            if s.is_finite() {
                s.clamp(0.0, 1.0)
            } else {
                0.0
            }
        };
        let (below, above) = (share(self.below), share(self.above));
        below + above > 0.0
            && price.is_finite()
            && rendering > 0.0
            && price >= (1.0 - below) * rendering
            && price <= (1.0 + above) * rendering
    }

    /// Whether `now` is the same value as `then`, within [`value_change`](Self::value_change).
    pub(crate) fn same_value(&self, then: f32, now: f32) -> bool {
        let tolerance = if self.value_change.is_finite() {
            self.value_change.clamp(0.0, 1.0)
        } else {
            0.0
        };
        (now - then).abs() <= tolerance * then.abs().max(now.abs())
    }
}

impl Default for SteadySelection {
    fn default() -> Self {
        Self::OFF
    }
}

/// Each family's calibrated time multiplied by its learned factor: what a selection
/// priced by the calibration costs at this frame's learned costs (the inverse of
/// [`FamilyTimes::unscaled`]).
pub(crate) fn rescaled(calibrated: FamilyTimes, scales: FamilyScales) -> FamilyTimes {
    let times = |t: f32, s: f32| if s.is_finite() && s > 0.0 { t * s } else { t };
    FamilyTimes {
        triangles: times(calibrated.triangles, scales.triangles),
        triangle_pixels: times(calibrated.triangle_pixels, scales.triangle_pixels),
        lines: times(calibrated.lines, scales.lines),
        points: times(calibrated.points, scales.points),
        meshes: times(calibrated.meshes, scales.meshes),
        mesh_pixels: times(calibrated.mesh_pixels, scales.mesh_pixels),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_selection_is_kept_inside_the_band_only() {
        let steady = SteadySelection::KEEP_WHILE_STILL;
        assert!(steady.keeps(1.0, 1.0));
        assert!(steady.keeps(0.91, 1.0) && steady.keeps(1.029, 1.0));
        assert!(!steady.keeps(0.89, 1.0), "too much time left unused");
        assert!(!steady.keeps(1.04, 1.0), "a predicted overrun");
        assert!(!steady.keeps(f32::NAN, 1.0) && !steady.keeps(0.0, 0.0));
        assert!(!SteadySelection::OFF.keeps(1.0, 1.0));
        let odd = SteadySelection {
            below: f32::NAN,
            above: -1.0,
            value_change: 0.0,
        };
        assert!(
            !odd.keeps(1.0, 1.0),
            "shares that are not finite or negative are 0"
        );
    }

    #[test]
    fn values_count_as_the_same_within_their_tolerance() {
        let steady = SteadySelection::KEEP_WHILE_STILL;
        assert!(steady.same_value(10.0, 10.15));
        assert!(!steady.same_value(10.0, 10.3));
        assert!(SteadySelection::OFF.same_value(3.0, 3.0));
        assert!(!SteadySelection::OFF.same_value(3.0, 3.0001));
    }

    #[test]
    fn rescaling_undoes_unscaling() {
        let scales = FamilyScales {
            triangles: 2.0,
            triangle_pixels: 0.5,
            lines: 3.0,
            points: 4.0,
            meshes: 1.5,
            mesh_pixels: 0.25,
        };
        let times = FamilyTimes {
            triangles: 1.0,
            triangle_pixels: 2.0,
            lines: 3.0,
            points: 4.0,
            meshes: 5.0,
            mesh_pixels: 6.0,
        };
        let back = rescaled(times.unscaled(scales), scales);
        assert!((back.total() - times.total()).abs() < 1e-5, "{back:?}");
    }
}
