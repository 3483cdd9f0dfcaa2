//! The cost model the budget predicts with: a calibration as the prior, and what the
//! running app measured of its own frames.
//!
//! A frame is three measured times ([`FrameSample`]): the main world's update (the
//! *logic* `L`), the render world's rendering of the frame (`R`), and the interval the
//! frame took (`F`). The model predicts each from what the frame contains:
//!
//! * `R = speed_R · (θ₀ + θ₁·T + θ₂·P + θ₃·Λ + θ₄·Π + θ₅·M + θ₆·Q)`: a fixed part
//!   (Bevy's own passes, the upload, the present), the selection's triangles (`T`: per
//!   triangle, `P`: per covered pixel), lines `Λ` and points `Π`, and the meshes on Bevy's
//!   own path — ladder levels and the app's own visible meshes — per draw and triangle
//!   (`M`) and per covered pixel (`Q`), each priced by the calibration; so the
//!   `θ` are factors on the calibration, which keeps its measured shape across line
//!   widths and point sizes.
//! * `L = L₀ + speed_L · (φ₀ + φ₁·n)`: the logic `L₀` that already ran when the Budget
//!   stage hands out the frame's time (measured, this frame: the app's `Update` systems,
//!   culling, the values), and the rest of the update after it (the hand-out itself, the
//!   draw lists, whatever the app runs later), learned, with `n` the visible instances. A
//!   step in the app's logic is so in the same frame's budget. On two cores a busy main
//!   world also takes a core from a software rasteriser; that contention shows as the
//!   overlap's serial share `s` below, which is learned.
//! * `F = max(L, R) + s·min(L, R) + c` ([`FrameOverlap`]): with Bevy's pipelined
//!   rendering the main world updates the next frame while the render world draws this
//!   one, so the frame is the longer of the two plus a synchronisation `c` (extraction)
//!   and the share `s` of the shorter one that does not overlap (0 when they overlap
//!   perfectly, 1 when they run one after the other). Both are learned; measured on
//!   lavapipe with pipelined rendering, `F − max(L, R)` was 1.1–1.2 ms with a spread of
//!   0.3 ms whatever the load, which is why the overlap is modelled explicitly instead of
//!   through the paper's machine constant `C` (P-7), which assumes a fixed share.
//!
//! The `θ` and `φ` relax toward the calibration over [`LearningRates::costs_seconds`]
//! and are estimated with the speeds by a [`CostFilter`] each, which follows a change of
//! speed within [`LearningRates::speed_seconds`]; `c` and `s` are a [`PriorRegression`].
//! See [`crate::cost::online`].
//!
//! Learning pairs each frame's prediction ([`CostModel::record`]) with what was measured
//! of that same frame ([`FrameSample::frame`]), so it never feeds back into the frame it
//! learns from, and a jump in the scene moves the next prediction at once through the
//! counts.

use std::collections::VecDeque;

use bevy::prelude::*;
use serde::{Deserialize, Serialize};

use super::online::{
    CostFilter, LogSpread, MEASURED_PRIOR_SPREAD, PRIOR_SPREAD, PriorRegression, RobustGate,
};
use super::{Calibration, FamilyScales, FamilyTimes, FrameSample, PrimitiveCosts};

/// How the main world's logic `L` and the render world's rendering `R` make a frame:
/// `max(L, R) + serial · min(L, R) + sync`.
#[derive(Clone, Copy, Debug, PartialEq, Reflect, Serialize, Deserialize)]
pub struct FrameOverlap {
    /// Time added to every frame (handing the frame to the render world), seconds.
    pub sync: f32,
    /// The share of the shorter of `L` and `R` that does not overlap the longer: 0 with
    /// pipelined rendering on enough cores, 1 without.
    pub serial: f32,
}

impl Default for FrameOverlap {
    fn default() -> Self {
        Self::PIPELINED
    }
}

impl FrameOverlap {
    /// Pipelined rendering: the worlds overlap.
    pub const PIPELINED: Self = Self {
        sync: 1e-3,
        serial: 0.0,
    };
    /// The render world runs after the main world.
    pub const SERIAL: Self = Self {
        sync: 1e-3,
        serial: 1.0,
    };

    /// The frame time of `logic` and `render` seconds. Negative or NaN inputs count as 0.
    pub fn frame_time(&self, logic: f32, render: f32) -> f32 {
        let clean = |x: f32| if x.is_nan() { 0.0 } else { x.max(0.0) };
        let (l, r) = (clean(logic), clean(render));
        l.max(r) + self.serial.clamp(0.0, 1.0) * l.min(r) + self.sync.max(0.0)
    }

    /// The longest rendering time that keeps a frame with `logic` seconds of logic within
    /// `target` seconds: the inverse of [`FrameOverlap::frame_time`] in `render`. Zero
    /// (never negative or NaN) when even no rendering would not fit.
    pub(crate) fn rendering_time(&self, logic: f32, target: f32) -> f32 {
        if !(target.is_finite() && target > 0.0) || logic.is_nan() {
            return 0.0;
        }
        let logic = logic.max(0.0);
        let serial = self.serial.clamp(0.0, 1.0);
        let room = target - self.sync.max(0.0);
        if room <= logic {
            return 0.0;
        }
        // Rendering shorter than the logic adds only its serial share.
        if serial > 0.0 {
            let shorter = (room - logic) / serial;
            if shorter <= logic {
                return shorter;
            }
        }
        (room - serial * logic).max(0.0)
    }
}

/// What the cost model has learned, as numbers to show (HUD, diagnostics, records).
#[derive(Clone, Copy, Debug, Default, PartialEq, Reflect, Serialize, Deserialize)]
pub struct LearnedCosts {
    /// The render world's fixed time per frame, ms.
    pub render_fixed_ms: f32,
    /// Per triangle, µs.
    pub triangle_us: f32,
    /// Per covered pixel of triangles, ns.
    pub triangle_pixel_ns: f32,
    /// Per thinnest line (1 px, as calibrated), µs.
    pub line_us: f32,
    /// Per smallest point (1 px, as calibrated), µs.
    pub point_us: f32,
    /// Per mesh drawn on Bevy's own path (a ladder entity), µs.
    pub mesh_draw_us: f32,
    /// Per triangle of such a mesh, ns.
    pub mesh_triangle_ns: f32,
    /// Per pixel such a mesh covers, ns.
    pub mesh_pixel_ns: f32,
    /// Factors on the calibration (speed included), per family.
    pub scales: FamilyScales,
    /// The main world's logic after the Budget stage with nothing visible, ms.
    pub logic_fixed_ms: f32,
    /// Logic after the Budget stage per visible instance, µs.
    pub logic_per_instance_us: f32,
    /// How much slower the machine renders now than the learned costs say (1: as learned).
    pub render_speed: f32,
    /// The same for the logic.
    pub logic_speed: f32,
    /// How logic and rendering make a frame.
    pub overlap: FrameOverlap,
    /// Frames learned from since the calibration was installed.
    pub frames_learned: u32,
}

/// One frame's prediction, kept until the frame's measurement arrives.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FramePrediction {
    /// The frame ([`FrameClock::frame`](super::FrameClock::frame)).
    pub frame: u64,
    /// Visible tree instances.
    pub visible_instances: u32,
    /// The selection's rendering time by family, priced by the calibration alone.
    pub calibrated: FamilyTimes,
    /// Predicted logic, seconds: what had run when the budget was handed out
    /// ([`FramePrediction::logic_so_far`]) and the learned rest.
    pub logic: f32,
    /// The main world's logic measured when the Budget stage ran, seconds.
    pub logic_so_far: f32,
    /// Predicted rendering (fixed part included), seconds.
    pub render: f32,
    /// Predicted frame time, seconds.
    pub frame_time: f32,
}

/// A prediction and what was measured of its frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LearnedFrame {
    /// What was predicted.
    pub predicted: FramePrediction,
    /// What was measured.
    pub measured: FrameSample,
}

/// How many predictions wait for their measurement (the render world reports a frame or
/// two late).
const KEPT_PREDICTIONS: usize = 32;

/// The render model's parameters: fixed, triangles, triangle pixels, lines, points,
/// meshes, mesh pixels.
const RENDER_PARAMETERS: usize = 7;
/// The logic model's: fixed, per visible instance.
const LOGIC_PARAMETERS: usize = 2;
/// The overlap's: sync, serial share.
const OVERLAP_PARAMETERS: usize = 2;

/// Time constants of the learning, seconds.
#[derive(Clone, Copy, Debug, PartialEq, Reflect, Serialize, Deserialize)]
pub struct LearningRates {
    /// What things cost relative to each other: a regression over this many seconds.
    /// Default: `30.0` (a property of the renderer, which changes rarely; the speed
    /// follows the machine).
    pub costs_seconds: f32,
    /// How fast the machine is now. Default: `0.25` (a step change is followed within
    /// about a second).
    pub speed_seconds: f32,
}

impl LearningRates {
    /// The shortest time constant used, seconds: a shorter one would chase each frame's
    /// noise.
    pub(crate) const MIN_SECONDS: f32 = 0.1;
    /// The longest time constant used, seconds (an hour).
    pub(crate) const MAX_SECONDS: f32 = 3600.0;

    /// These rates as the model uses them: a time constant that is not finite is its
    /// default, the others are kept within [`MIN_SECONDS`](Self::MIN_SECONDS)..=
    /// [`MAX_SECONDS`](Self::MAX_SECONDS).
    pub(crate) fn usable(self) -> Self {
        let defaults = Self::default();
        let usable = |v: f32, default: f32| {
            if v.is_finite() {
                v.clamp(Self::MIN_SECONDS, Self::MAX_SECONDS)
            } else {
                default
            }
        };
        Self {
            costs_seconds: usable(self.costs_seconds, defaults.costs_seconds),
            speed_seconds: usable(self.speed_seconds, defaults.speed_seconds),
        }
    }
}

impl Default for LearningRates {
    fn default() -> Self {
        Self {
            costs_seconds: 30.0,
            speed_seconds: 0.25,
        }
    }
}

/// The costs the budget predicts with: a [`Calibration`] (the prior) and what was learned
/// from measured frames (see the module docs). Kept by [`CostPlugin`](super::CostPlugin).
#[derive(Resource, Clone, Debug)]
pub struct CostModel {
    calibration: Calibration,
    prior_overlap: FrameOverlap,
    rates: LearningRates,
    render: CostFilter<RENDER_PARAMETERS>,
    logic: CostFilter<LOGIC_PARAMETERS>,
    overlap: PriorRegression<OVERLAP_PARAMETERS>,
    overlap_gate: RobustGate,
    frame_spread: LogSpread,
    predictions: VecDeque<FramePrediction>,
    frames_learned: u32,
    last: Option<LearnedFrame>,
}

impl Default for CostModel {
    fn default() -> Self {
        Self::new(
            Calibration::default(),
            FrameOverlap::PIPELINED,
            LearningRates::default(),
        )
    }
}

impl CostModel {
    /// A model predicting with `calibration` and `overlap` until it learns better.
    pub fn new(calibration: Calibration, overlap: FrameOverlap, rates: LearningRates) -> Self {
        let rates = rates.usable();
        let fixed = f64::from(calibration.render_fixed_time());
        // Factors within ×100 of the calibration; the fixed part up to 10 s.
        let mut render = CostFilter::new(
            [fixed.max(1e-4), 1.0, 1.0, 1.0, 1.0, 1.0, 1.0],
            [0.0, 0.01, 0.01, 0.01, 0.01, 0.01, 0.01],
            [10.0, 100.0, 100.0, 100.0, 100.0, 100.0, 100.0],
            rates.speed_seconds,
            rates.costs_seconds,
        );
        if calibration.is_measured() {
            // The families' shape is the renderer's; the fixed part is the app's.
            let family = MEASURED_PRIOR_SPREAD;
            render = render.with_prior_spreads([
                PRIOR_SPREAD,
                family,
                family,
                family,
                family,
                family,
                family,
            ]);
        }
        let (logic_fixed, logic_slope) = calibration.logic_line();
        let (logic_fixed, logic_slope) = (f64::from(logic_fixed), f64::from(logic_slope));
        let logic = CostFilter::new(
            [logic_fixed.max(1e-4), logic_slope.max(1e-7)],
            [1e-5, 0.0],
            [10.0, 0.1],
            rates.speed_seconds,
            rates.costs_seconds,
        );
        let overlap_regression = PriorRegression::new(
            [f64::from(overlap.sync), f64::from(overlap.serial)],
            [0.0, 0.0],
            [1.0, 1.0],
            f64::from(rates.costs_seconds),
        );
        Self {
            calibration,
            prior_overlap: overlap,
            rates,
            render,
            logic,
            overlap: overlap_regression,
            overlap_gate: RobustGate::new(1e-3, 2e-4),
            frame_spread: LogSpread::new(
                FRAME_SPREAD_PRIOR,
                FRAME_SPREAD_FLOOR,
                FRAME_SPREAD_SECONDS,
            ),
            predictions: VecDeque::new(),
            frames_learned: 0,
            last: None,
        }
    }

    /// The calibration predictions start from.
    pub fn calibration(&self) -> &Calibration {
        &self.calibration
    }

    /// Installs a calibration and forgets what was learned.
    pub fn set_calibration(&mut self, calibration: Calibration) {
        *self = Self::new(calibration, self.prior_overlap, self.rates);
    }

    /// Forgets what was learned (the calibration stays).
    pub(crate) fn reset(&mut self) {
        self.set_calibration(self.calibration.clone());
    }

    /// The overlap assumed before anything is learned.
    pub(crate) fn set_prior_overlap(&mut self, overlap: FrameOverlap) {
        self.prior_overlap = overlap;
        self.reset();
    }

    /// The learning's time constants, as used.
    pub(crate) fn rates(&self) -> LearningRates {
        self.rates
    }

    /// The learning's time constants; changing them forgets what was learned.
    pub(crate) fn set_rates(&mut self, rates: LearningRates) {
        self.rates = rates.usable();
        self.reset();
    }

    /// The factors on the calibration's per-primitive costs the budget prices with now
    /// (learned costs and current speed).
    pub(crate) fn family_scales(&self) -> FamilyScales {
        let t = self.render.costs();
        let speed = f64::from(self.render.speed());
        let s = |j: usize| (t[j] * speed) as f32;
        FamilyScales {
            triangles: s(1),
            triangle_pixels: s(2),
            lines: s(3),
            points: s(4),
            meshes: s(5),
            mesh_pixels: s(6),
        }
    }

    /// Per-primitive costs as the budget prices them now.
    pub(crate) fn primitive_costs(&self) -> PrimitiveCosts {
        PrimitiveCosts::scaled(&self.calibration, self.family_scales())
    }

    /// The render world's predicted fixed time per frame, seconds.
    pub(crate) fn render_fixed(&self) -> f32 {
        (self.render.costs()[0] * f64::from(self.render.speed())) as f32
    }

    /// Predicted rendering time of a selection whose families cost `calibrated` by the
    /// calibration alone, fixed part included, seconds.
    pub fn render_time(&self, calibrated: &FamilyTimes) -> f32 {
        self.render.predict(&render_regressors(calibrated))
    }

    /// Predicted logic time after the Budget stage (the rest of the main world's update)
    /// with `visible_instances` instances in view, seconds.
    pub fn logic_after_budget(&self, visible_instances: u32) -> f32 {
        self.logic.predict(&[1.0, f64::from(visible_instances)])
    }

    /// How logic and rendering make a frame, as learned.
    pub fn overlap(&self) -> FrameOverlap {
        let [sync, serial] = self.overlap.parameters();
        FrameOverlap {
            sync: sync as f32,
            serial: serial as f32,
        }
    }

    /// Keeps a frame's prediction until its measurement arrives.
    pub fn record(&mut self, prediction: FramePrediction) {
        if self.predictions.len() >= KEPT_PREDICTIONS {
            self.predictions.pop_front();
        }
        self.predictions.push_back(prediction);
    }

    /// The prediction recorded for `frame`, while it waits for its measurement.
    pub fn prediction(&self, frame: u64) -> Option<&FramePrediction> {
        self.predictions.iter().find(|p| p.frame == frame)
    }

    /// The latest frame learned from: its prediction and what was measured.
    pub fn last_learned(&self) -> Option<&LearnedFrame> {
        self.last.as_ref()
    }

    /// Learns from a measured frame, if its prediction is still kept. Returns whether it
    /// was learned from: a frame that was not complete, whose times are not finite and
    /// positive, that was predicted to draw nothing, or that stalled (`is_stall`) is
    /// not.
    pub fn learn(&mut self, sample: &FrameSample) -> bool {
        while self
            .predictions
            .front()
            .is_some_and(|p| p.frame < sample.frame)
        {
            self.predictions.pop_front();
        }
        let Some(predicted) = self
            .predictions
            .front()
            .copied()
            .filter(|p| p.frame == sample.frame)
        else {
            return false;
        };
        self.predictions.pop_front();
        // A frame that drew nothing (a minimised window, no view) says nothing of what
        // drawing costs, and a stall (a debugger, a blocking load) nothing of the machine.
        if !sample.is_usable()
            || predicted.calibrated.total() <= 0.0
            || is_stall(sample.interval, predicted.frame_time)
        {
            return false;
        }
        let dt = sample.interval;
        // The rendering side is whichever of the render world's CPU work and the GPU took
        // longer: with frames in flight they overlap, and the longer one paces the frame.
        let rendering = sample.rendering();
        self.render
            .learn(&render_regressors(&predicted.calibrated), rendering, dt);
        // What ran after the hand-out (never taken below a microsecond: a logarithm is
        // learned).
        self.logic.learn(
            &[1.0, f64::from(predicted.visible_instances)],
            (sample.logic - predicted.logic_so_far).max(1e-6),
            dt,
        );
        // How the worlds overlap is learned from frames that did not wait for the display:
        // in those that did, the interval is the display's, not the work's.
        if !sample.waited_for_display() {
            let longer = sample.logic.max(rendering);
            let shorter = sample.logic.min(rendering);
            let beyond = sample.interval - longer;
            let error = beyond - self.overlap.predict(&[1.0, f64::from(shorter)]) as f32;
            self.overlap.update(
                &[1.0, f64::from(shorter)],
                f64::from(beyond),
                f64::from(self.overlap_gate.weight(error)),
                f64::from(dt),
            );
            self.overlap_gate.observe(error, dt);
        }
        self.frame_spread
            .observe(predicted.frame_time, sample.work_interval(), dt);
        self.frames_learned = self.frames_learned.saturating_add(1);
        self.last = Some(LearnedFrame {
            predicted,
            measured: *sample,
        });
        true
    }

    /// Learns from the GPU time of the pass that drew the budgeted primitives (every
    /// family but the meshes, which Bevy's own passes draw), paired with the latest frame
    /// learned from: the rendering minus the pass is the fixed part, so the fixed part and
    /// the primitives' costs stop trading places when the scene's mix hardly changes.
    /// Returns whether it was learned from: not before a frame was, nor when that frame's
    /// primitives were predicted below [`MIN_PASS_PART`] of the pass (the pass's own
    /// overhead would then pass for their cost), nor for a time that is not finite and
    /// positive.
    pub(crate) fn learn_pass(&mut self, seconds: f32) -> bool {
        let Some(last) = &self.last else {
            return false;
        };
        if !(seconds.is_finite() && seconds > 0.0) {
            return false;
        }
        let x = pass_regressors(&last.predicted.calibrated);
        let predicted = self.render.predict(&x);
        if predicted.is_nan() || predicted < MIN_PASS_PART * seconds {
            return false;
        }
        self.render.learn_part(&x, seconds);
        true
    }

    /// How the frames' work scatters around its prediction (`ln(measured / predicted)`
    /// of [`FrameSample::work_interval`] against [`FramePrediction::frame_time`]): what a
    /// deadline needs as its margin.
    pub(crate) fn frame_spread(&self) -> &LogSpread {
        &self.frame_spread
    }

    /// What has been learned, as numbers to show.
    pub fn learned(&self) -> LearnedCosts {
        let scales = self.family_scales();
        let logic = self.logic.costs();
        let logic_speed = f64::from(self.logic.speed());
        let c = &self.calibration;
        let first = |costs: &[super::LinearCost]| costs.first().map_or(0.0, |c| c.per_primitive);
        LearnedCosts {
            render_fixed_ms: self.render_fixed() * 1000.0,
            triangle_us: c.triangles.per_primitive * scales.triangles * 1e6,
            triangle_pixel_ns: c.triangles.per_pixel * scales.triangle_pixels * 1e9,
            line_us: first(&c.lines) * scales.lines * 1e6,
            point_us: first(&c.points) * scales.points * 1e6,
            mesh_draw_us: c.meshes.per_draw * scales.meshes * 1e6,
            mesh_triangle_ns: c.meshes.per_triangle * scales.meshes * 1e9,
            mesh_pixel_ns: c.meshes.per_pixel * scales.mesh_pixels * 1e9,
            scales,
            logic_fixed_ms: (logic[0] * logic_speed * 1000.0) as f32,
            logic_per_instance_us: (logic[1] * logic_speed * 1e6) as f32,
            render_speed: self.render.speed(),
            logic_speed: self.logic.speed(),
            overlap: self.overlap(),
            frames_learned: self.frames_learned,
        }
    }
}

/// The frame spread before anything is measured: 5% (identical frames vary by 3–11% on
/// the machines this was measured on).
pub(crate) const FRAME_SPREAD_PRIOR: f32 = 0.05;
/// The smallest frame spread the model assumes: 1%.
pub(crate) const FRAME_SPREAD_FLOOR: f32 = 0.01;
/// The frame spread follows about this many seconds of frames: a change of the machine's
/// noise (measured here as regimes of 5–10 s) is followed within a few seconds, while at
/// 10 frames a second the deviation is taken over some twenty frames, not a noisy handful
/// (with one second, 1% of frames were let miss and 2–3% did).
pub(crate) const FRAME_SPREAD_SECONDS: f32 = 2.0;

/// A frame whose interval is over this many times its prediction, and over
/// [`STALL_SECONDS`], stalled.
pub(crate) const STALL_FACTOR: f32 = 4.0;
/// The shortest interval that counts as a stall, seconds.
pub(crate) const STALL_SECONDS: f32 = 1.0;

/// Whether a frame of `interval` seconds, predicted to take `predicted`, stalled (a
/// debugger, a blocking load, a window dragged): its interval is over
/// max([`STALL_FACTOR`] × predicted, [`STALL_SECONDS`]). A stall is not learned from.
pub(crate) fn is_stall(interval: f32, predicted: f32) -> bool {
    let predicted = if predicted.is_finite() {
        predicted
    } else {
        0.0
    };
    interval > (STALL_FACTOR * predicted).max(STALL_SECONDS)
}

/// A pass time is learned from only when the primitives it drew were predicted to take at
/// least this share of it.
pub(crate) const MIN_PASS_PART: f32 = 0.25;

/// [`render_regressors`] of what the forest pass draws: no fixed part, no meshes.
fn pass_regressors(calibrated: &FamilyTimes) -> [f64; RENDER_PARAMETERS] {
    let [_, triangles, pixels, lines, points, _, _] = render_regressors(calibrated);
    [0.0, triangles, pixels, lines, points, 0.0, 0.0]
}

fn render_regressors(calibrated: &FamilyTimes) -> [f64; RENDER_PARAMETERS] {
    [
        1.0,
        f64::from(calibrated.triangles),
        f64::from(calibrated.triangle_pixels),
        f64::from(calibrated.lines),
        f64::from(calibrated.points),
        f64::from(calibrated.meshes),
        f64::from(calibrated.mesh_pixels),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn learning_rates_are_used_within_bounds_and_a_stall_is_told_apart() {
        let defaults = LearningRates::default();
        let used = |v: f32| {
            LearningRates {
                costs_seconds: v,
                speed_seconds: v,
            }
            .usable()
        };
        assert_eq!(used(f32::NAN), defaults);
        assert_eq!(used(f32::NEG_INFINITY), defaults);
        assert_eq!(used(0.0).speed_seconds, LearningRates::MIN_SECONDS);
        assert_eq!(used(-3.0).costs_seconds, LearningRates::MIN_SECONDS);
        assert_eq!(used(1e9).costs_seconds, LearningRates::MAX_SECONDS);
        assert_eq!(defaults.usable(), defaults);
        // A stall: over four times the prediction and over a second.
        assert!(!is_stall(0.9, 0.1));
        assert!(is_stall(1.1, 0.1));
        assert!(!is_stall(3.0, 1.0));
        assert!(is_stall(4.1, 1.0));
        assert!(is_stall(2.0, f32::NAN));
    }

    #[test]
    fn rendering_time_inverts_frame_time() {
        for overlap in [
            FrameOverlap::PIPELINED,
            FrameOverlap::SERIAL,
            FrameOverlap {
                sync: 0.002,
                serial: 0.3,
            },
        ] {
            for logic in [0.0, 0.005, 0.02, 0.06] {
                for target in [0.01, 0.03, 0.05, 0.1] {
                    let r = overlap.rendering_time(logic, target);
                    assert!(r >= 0.0 && r.is_finite());
                    if r > 0.0 {
                        let f = overlap.frame_time(logic, r);
                        assert!(
                            (f - target).abs() < 1e-5,
                            "{overlap:?} {logic} {target}: {f}"
                        );
                    } else {
                        assert!(overlap.frame_time(logic, 0.0) >= target - 1e-6);
                    }
                }
            }
        }
        assert_eq!(FrameOverlap::PIPELINED.rendering_time(0.01, f32::NAN), 0.0);
        assert_eq!(FrameOverlap::PIPELINED.rendering_time(f32::NAN, 0.1), 0.0);
    }
}
