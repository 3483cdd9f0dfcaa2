//! Steady selections: while the scene stays as it was (the same camera, the same objects
//! of nearly the same values, the same settings), last frame's hand-out is kept as long
//! as it still fits the rendering time at this frame's learned costs. The learned costs
//! move a few percent a frame with the machine's noise; handing out again every frame
//! would move every object's share with them and flip choices across their thresholds
//! all over a still picture.

use bevy::prelude::*;
use serde::{Deserialize, Serialize};

use super::select::Selected;
use crate::cost::{FamilyScales, FamilyTimes};

/// How a still scene keeps its selection ([`FrameBudget::steady`](super::FrameBudget::steady)).
///
/// A fresh hand-out fills some share of the render world's time (its *fit*: the render
/// world's predicted time with the hand-out's price in place of the rendering time handed
/// out, over the time it has; about 1, less when everything fits). Each following frame
/// of the same scene, the kept selection is priced at that frame's learned costs and its
/// fit, smoothed over [`smoothing_frames`](Self::smoothing_frames), is compared with the
/// fresh one: the selection is kept while the smoothed fit stays within
/// `[(1 − below) × fresh, (1 + above) × max(fresh, 1)]`; otherwise the time is handed
/// out anew. The band follows the aim (the rendering time is this frame's), so a machine
/// that slows or speeds up by more than the band, or a tail goal that moves its aim, gets
/// a new hand-out within a few frames and the target is still held.
///
/// The band is a share of the render world's time, not of the trees': where the app's
/// own rendering (its meshes, the fixed part) takes most of the frame, the noise in what
/// is learned of it moves the trees' rendering time by several times as much as it moves
/// the frame, and a band on the trees' time alone would hand out anew every few frames.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, Reflect)]
#[serde(default)]
pub struct SteadySelection {
    /// How far below the fresh fit the smoothed fit may fall (time left unused) before
    /// the time is handed out again, as a share of the render world's time. Wider than
    /// [`above`](Self::above): a still picture gains little from the last few percent of
    /// detail and every hand-out that adds it redraws part of the picture, where an
    /// overrun has to be cut at once. Default: `0.08`.
    pub below: f32,
    /// How far above the fresh fit (or the rendering time, when the fresh hand-out fitted
    /// it) the smoothed fit may rise (a predicted overrun) before the time is handed out
    /// again, as a share of the render world's time. Default: `0.03`.
    pub above: f32,
    /// How much an object's value may change (a share of it) with the scene still
    /// counting as the same: trees swaying in the wind move their bounds a little.
    /// Default: `0.02`.
    pub value_change: f32,
    /// Over how many frames the kept selection's fit is smoothed (an exponential
    /// average): the learned costs move a few percent a frame with the machine's noise,
    /// a change of its speed lasts (a lasting 15% change leaves the default band in 2
    /// frames). Default: `8`.
    pub smoothing_frames: f32,
    /// When a still scene's kept selection leaves its band, whether the new hand-out
    /// changes only the trees the price needs: every tree keeps what it drew but for the
    /// fewest whose fresh drawing moves the price back within half the band of the
    /// rendering time (those that move it most for how large they are on screen
    /// first). Otherwise every tree takes its fresh share (a drift of a few percent then
    /// flips choices all over the picture at once). Default: `true`.
    pub gradual: bool,
}

impl SteadySelection {
    /// Hand out anew every frame (the paper's behaviour).
    pub const OFF: Self = Self {
        below: 0.0,
        above: 0.0,
        value_change: 0.0,
        smoothing_frames: 1.0,
        gradual: false,
    };

    /// Keep a still scene's selection while its smoothed fit stays within 8% below and
    /// 3% above (the default). A wider band keeps more frames but lets a kept selection
    /// sit further below the aim (time unused: the tail goal then leaves fewer frames
    /// over than it promises); a narrower one below follows every rise of the aim, and
    /// the aim rises for seconds after the camera stops, as the learned scatter of frame
    /// times narrows (`sherwood-lab forest --steady-band`, `scripts/shimmer.sh`).
    pub const KEEP_WHILE_STILL: Self = Self {
        below: 0.08,
        above: 0.03,
        value_change: 0.02,
        smoothing_frames: 8.0,
        gradual: true,
    };

    /// The fit of a fresh hand-out that costs `price` in `room`; `None` when there is
    /// nothing to keep (steadiness off, or no time or price to compare).
    pub(crate) fn fit(&self, price: f32, room: Room) -> Option<Fit> {
        let ratio = room.fill(price)?;
        self.is_on().then_some(Fit {
            fresh: ratio,
            smoothed: ratio,
        })
    }

    /// Whether a selection of `fit` that costs `price` in this frame's `room` is kept;
    /// its smoothed fit moves to this frame's.
    pub(crate) fn keeps(&self, fit: &mut Fit, price: f32, room: Room) -> bool {
        let Some(ratio) = room.fill(price).filter(|_| self.is_on()) else {
            return false;
        };
        let frames = if self.smoothing_frames.is_finite() {
            self.smoothing_frames.max(1.0)
        } else {
            1.0
        };
        fit.smoothed += (ratio - fit.smoothed) / frames;
        let (below, above) = (share(self.below), share(self.above));
        fit.smoothed >= (1.0 - below) * fit.fresh
            && fit.smoothed <= (1.0 + above) * fit.fresh.max(1.0)
    }

    /// Where a blend of a fresh hand-out with a kept one keeps its price: within half
    /// the band around the rendering time of `room`, so that the blend is kept
    /// afterwards.
    pub(crate) fn blend_band(&self, room: Room) -> (f32, f32) {
        let whole = room.whole();
        (
            room.rendering - 0.5 * share(self.below) * whole,
            room.rendering + 0.5 * share(self.above) * whole,
        )
    }

    fn is_on(&self) -> bool {
        share(self.below) + share(self.above) > 0.0
    }

    /// Whether `now` is the same value as `then`, within [`value_change`](Self::value_change).
    pub(crate) fn same_value(&self, then: f32, now: f32) -> bool {
        (now - then).abs() <= share(self.value_change) * then.abs().max(now.abs())
    }
}

/// A share in `[0, 1]`; one that is not finite counts as 0.
fn share(s: f32) -> f32 {
    if s.is_finite() {
        s.clamp(0.0, 1.0)
    } else {
        0.0
    }
}

impl Default for SteadySelection {
    fn default() -> Self {
        Self::KEEP_WHILE_STILL
    }
}

/// The time a hand-out's price is measured against: the rendering time handed out to the
/// trees and ladders, and the render world's whole time in the aim, of which it is a part
/// (with the fixed part, the app's own meshes and the trees held from earlier frames).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Room {
    pub(crate) rendering: f32,
    pub(crate) render_world: f32,
}

impl Room {
    /// The render world's time; never less than the rendering time in it.
    fn whole(&self) -> f32 {
        self.render_world.max(self.rendering)
    }

    /// The render world's time with `price` in place of the rendering time, as a share
    /// of its time (1: the price uses the rendering time exactly); `None` without a time
    /// or a price to compare.
    fn fill(&self, price: f32) -> Option<f32> {
        let whole = self.whole();
        let fill = (whole - self.rendering + price) / whole;
        (fill.is_finite() && whole > 0.0 && self.rendering >= 0.0).then_some(fill)
    }
}

/// A kept selection's fit (its [`Room::fill`]): when it was handed out, and smoothed
/// since.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Fit {
    fresh: f32,
    smoothed: f32,
}

/// How a still scene's fresh hand-out is blended with the selection it replaces (when the
/// kept one left its band): starting from what the kept selection drew, only trees whose
/// fresh drawing moves the price the way it has to go (up when time is left unused, down
/// when the frame would overrun) change, those that move it most for what they show
/// first, until the price is within `[low, high]`; a tree whose change would carry the
/// price past the far end of the band is passed over. A drift of a few percent then
/// changes a few trees that take it up, not every tree whose share moved across a
/// threshold (the fresh hand-out moves shares both ways: changing all the trees it
/// changed would redraw much of the picture for a small net change of price).
///
/// `changes` holds per tree the kept drawing's cost at this frame's costs and the fresh
/// one's, `shown` per tree what changing it shows (its value: the larger on screen, the
/// more a change shows). `keep` is set per tree (a kept cost that is not finite is never
/// kept); returns the blended price.
pub(crate) fn change_fewest(
    changes: &[(f32, f32)],
    shown: &[f32],
    (low, high): (f32, f32),
    order: &mut Vec<u32>,
    keep: &mut Vec<bool>,
) -> f32 {
    keep.clear();
    keep.extend(changes.iter().map(|(kept, _)| kept.is_finite()));
    let mut price: f32 = changes
        .iter()
        .map(|&(kept, fresh)| if kept.is_finite() { kept } else { fresh })
        .sum();
    let up = price < low;
    if !up && price <= high {
        return price;
    }
    // How much a tree's change moves the price the way it has to go.
    let gain = |t: usize| {
        let (kept, fresh) = changes[t];
        if up { fresh - kept } else { kept - fresh }
    };
    order.clear();
    order.extend((0..changes.len() as u32).filter(|&t| {
        let gain = gain(t as usize);
        keep[t as usize] && gain.is_finite() && gain > 0.0
    }));
    // Per unit shown, most first; a change that shows nothing comes first.
    let per_shown =
        |t: &u32| gain(*t as usize) / shown.get(*t as usize).map_or(0.0, |s| s.max(0.0));
    order.sort_by(|a, b| per_shown(b).total_cmp(&per_shown(a)));
    for &t in order.iter() {
        let t = t as usize;
        let (kept, fresh) = changes[t];
        let candidate = price - kept + fresh;
        let reached = if up { price >= low } else { price <= high };
        if reached {
            break;
        }
        let past = if up {
            candidate > high
        } else {
            candidate < low
        };
        if !past {
            price = candidate;
            keep[t] = false;
        }
    }
    price
}

/// `selected` with every time multiplied by `ratio`.
pub(crate) fn scaled(selected: Selected, ratio: f32) -> Selected {
    Selected {
        cost: selected.cost * ratio,
        lines: selected.lines * ratio,
        points: selected.points * ratio,
        meshes: selected.meshes * ratio,
        mesh_pixels: selected.mesh_pixels * ratio,
        ..selected
    }
}

/// `total` with `from` replaced by `to`.
pub(crate) fn shifted(total: Selected, from: Selected, to: Selected) -> Selected {
    Selected {
        cost: total.cost - from.cost + to.cost,
        lines: total.lines - from.lines + to.lines,
        points: total.points - from.points + to.points,
        meshes: total.meshes - from.meshes + to.meshes,
        mesh_pixels: total.mesh_pixels - from.mesh_pixels + to.mesh_pixels,
        ..total
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

    /// A render world that is the rendering time alone.
    fn alone(rendering: f32) -> Room {
        Room {
            rendering,
            render_world: rendering,
        }
    }

    #[test]
    fn a_selection_is_kept_while_its_smoothed_fit_stays_in_the_band() {
        let steady = SteadySelection {
            smoothing_frames: 1.0,
            ..SteadySelection::KEEP_WHILE_STILL
        };
        let kept = |fresh: f32, now: f32| {
            let mut fit = steady.fit(fresh, alone(1.0)).unwrap();
            steady.keeps(&mut fit, now, alone(1.0))
        };
        assert!(kept(1.0, 1.0) && kept(1.0, 0.93) && kept(1.0, 1.025));
        assert!(!kept(1.0, 0.91), "too much time left unused");
        assert!(!kept(1.0, 1.04), "a predicted overrun");
        assert!(
            kept(0.5, 0.49),
            "a hand-out that could not use the time keeps"
        );
        assert!(!kept(0.5, 0.45));
        assert!(kept(1.0, 0.96), "the band is wider below than above");
        assert!(kept(1.2, 1.22), "nor could one whose cheapest overran");
        assert!(!kept(1.0, f32::NAN));
        assert!(
            steady.fit(1.0, alone(0.0)).is_none()
                && SteadySelection::OFF.fit(1.0, alone(1.0)).is_none()
        );
        let odd = SteadySelection {
            below: f32::NAN,
            above: -1.0,
            ..steady
        };
        assert!(
            odd.fit(1.0, alone(1.0)).is_none(),
            "shares that are not finite or negative are 0"
        );
    }

    #[test]
    fn noise_is_smoothed_and_a_lasting_change_leaves_the_band_within_a_few_frames() {
        let steady = SteadySelection::KEEP_WHILE_STILL;
        let mut fit = steady.fit(1.0, alone(1.0)).unwrap();
        // Alternating ±8%: each frame alone would leave the band.
        for k in 0..40 {
            let price = if k % 2 == 0 { 1.08 } else { 0.92 };
            assert!(steady.keeps(&mut fit, price, alone(1.0)), "frame {k}");
        }
        // The machine 15% slower from now on.
        let left = (1..=20).find(|_| !steady.keeps(&mut fit, 1.15, alone(1.0)));
        assert!(left.is_some_and(|k| k <= 3), "{left:?}");
    }

    #[test]
    fn the_band_is_a_share_of_the_render_worlds_time() {
        let steady = SteadySelection {
            smoothing_frames: 1.0,
            ..SteadySelection::KEEP_WHILE_STILL
        };
        // The trees have 1 of a render world of 5.
        let room = |rendering: f32| Room {
            rendering,
            render_world: 5.0,
        };
        let kept = |rendering: f32, price: f32| {
            let mut fit = steady.fit(1.0, room(1.0)).unwrap();
            steady.keeps(&mut fit, price, room(rendering))
        };
        assert!(
            kept(1.3, 1.0),
            "30% more rendering time is 6% of the render world: within the band below"
        );
        assert!(kept(0.9, 1.0) && kept(1.0, 1.1));
        assert!(!kept(1.5, 1.0), "10% of the render world left unused");
        assert!(!kept(1.0, 1.2), "an overrun of 4% of the render world");
        let (low, high) = steady.blend_band(room(1.0));
        assert!(
            (low - 0.8).abs() < 1e-6 && (high - 1.075).abs() < 1e-6,
            "{low} {high}"
        );
        // No time left for the trees: their floors are kept while the render world's
        // time holds.
        let mut fit = steady.fit(0.5, room(0.0)).unwrap();
        assert!(steady.keeps(&mut fit, 0.5, room(0.0)));
        assert!(
            steady
                .fit(
                    1.0,
                    Room {
                        rendering: 0.0,
                        render_world: 0.0
                    }
                )
                .is_none()
        );
    }

    #[test]
    fn values_count_as_the_same_within_their_tolerance() {
        let steady = SteadySelection::KEEP_WHILE_STILL;
        assert!(steady.same_value(10.0, 10.15));
        assert!(!steady.same_value(10.0, 10.3));
        assert!(SteadySelection::OFF.same_value(3.0, 3.0));
        assert!(!SteadySelection::OFF.same_value(3.0, 3.0001));
        assert_eq!(SteadySelection::default(), steady);
    }

    #[test]
    fn a_blend_changes_the_trees_that_move_the_price_most_for_what_they_show() {
        let (mut order, mut keep) = (Vec::new(), Vec::new());
        // Kept costs 5.0; the fresh hand-out (5.05) moved every tree, both ways.
        let changes = [(1.0, 1.2), (1.0, 0.8), (1.0, 1.3), (2.0, 1.75)];
        let shown = [1.0, 1.0, 3.0, 1.0];
        // Time left unused: only trees that raise the price change, tree 0 (0.2 for 1
        // shown) before tree 2 (0.3 for 3 shown).
        let price = change_fewest(&changes, &shown, (5.15, 5.3), &mut order, &mut keep);
        assert_eq!(keep, [false, true, true, true]);
        assert!((price - 5.2).abs() < 1e-5, "{price}");
        let price = change_fewest(&changes, &shown, (5.25, 5.6), &mut order, &mut keep);
        assert_eq!(keep, [false, true, false, true], "{price}");
        // A change past the far end of the band is passed over.
        change_fewest(&changes, &shown, (5.1, 5.15), &mut order, &mut keep);
        assert_eq!(keep, [true; 4], "tree 0 alone would carry the price to 5.2");
        // An overrun: only trees that lower it; tree 3 (0.25 for 1) before tree 1 (0.2).
        let price = change_fewest(&changes, &shown, (4.5, 4.7), &mut order, &mut keep);
        assert_eq!(keep, [true, false, true, false]);
        assert!((price - 4.55).abs() < 1e-5, "{price}");
        // Within the band, nothing changes.
        change_fewest(&changes, &shown, (4.9, 5.1), &mut order, &mut keep);
        assert_eq!(keep, [true; 4]);
        // A kept cost that is not finite is never kept, and prices the fresh one.
        let odd = [(f32::NAN, 1.0), (1.0, 1.0)];
        let price = change_fewest(&odd, &[1.0, 1.0], (0.0, 10.0), &mut order, &mut keep);
        assert_eq!((keep.as_slice(), price), ([false, true].as_slice(), 2.0));
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
