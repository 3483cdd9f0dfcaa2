//! Cost models: what primitives and logic cost on this machine (paper §4, thesis §6.2),
//! fitted from benchmark samples, saved per adapter, and corrected online.
//!
//! # How the online correction works
//! The calibrated model predicts each frame's rendering and logic time *before* the
//! frame, so a sudden jump in scene complexity is handled by prediction. After the frame,
//! the measured time is compared with what the calibrated model alone predicted, and a
//! smoothed correction factor per family is updated: `log f ← log f + α (log(measured /
//! predicted) − log f)`, with `α = 1 − exp(−dt / time_constant)`. Because the factor
//! tracks the ratio to the *uncorrected* prediction, it is a first-order low-pass filter
//! of a measurement, not a feedback loop through the budget: it converges monotonically
//! (no overshoot, no oscillation) and a stale or foreign calibration is corrected within
//! a few time constants (by default about one second).

use serde::{Deserialize, Serialize};

/// A primitive family's cost: `fixed + per_primitive · primitives + per_pixel · pixels`,
/// in seconds.
#[derive(Clone, Copy, Debug, PartialEq, Default, Serialize, Deserialize)]
pub struct LinearCost {
    /// Cost of drawing any of this family at all (state changes, the draw call).
    pub fixed: f32,
    /// Cost per primitive (vertex work, setup).
    pub per_primitive: f32,
    /// Cost per covered pixel (fill).
    pub per_pixel: f32,
}

impl LinearCost {
    /// Predicted time of `primitives` primitives covering `pixels` pixels (0 for none).
    pub fn time(&self, primitives: f32, pixels: f32) -> f32 {
        if primitives <= 0.0 {
            return 0.0;
        }
        (self.fixed + self.per_primitive * primitives + self.per_pixel * pixels.max(0.0)).max(0.0)
    }
}

/// One benchmark sample: how many primitives, how many pixels they covered, how long it took.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CostSample {
    /// Primitives drawn.
    pub primitives: f32,
    /// Pixels covered.
    pub pixels: f32,
    /// Measured time, seconds.
    pub time: f32,
}

/// Why a fit failed.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum FitError {
    /// Fewer than three finite samples.
    #[error("need at least 3 finite samples to fit 3 parameters, got {0}")]
    TooFewSamples(usize),
    /// The samples do not vary enough to tell the parts apart.
    #[error("the samples are degenerate: primitive and pixel counts must vary independently")]
    Degenerate,
}

/// Least-squares fit of a [`LinearCost`] to samples (normal equations, solved in `f64`).
pub fn fit_linear_cost(samples: &[CostSample]) -> Result<LinearCost, FitError> {
    let rows: Vec<[f64; 4]> = samples
        .iter()
        .filter(|s| s.primitives.is_finite() && s.pixels.is_finite() && s.time.is_finite())
        .map(|s| {
            [
                1.0,
                f64::from(s.primitives),
                f64::from(s.pixels),
                f64::from(s.time),
            ]
        })
        .collect();
    if rows.len() < 3 {
        return Err(FitError::TooFewSamples(rows.len()));
    }
    // Scale columns so the normal matrix is well conditioned.
    let mut scale = [1.0_f64; 3];
    for c in 1..3 {
        scale[c] = rows
            .iter()
            .map(|r| r[c].abs())
            .fold(0.0, f64::max)
            .max(1e-30);
    }
    let mut a = [[0.0_f64; 3]; 3];
    let mut b = [0.0_f64; 3];
    for r in &rows {
        let x = [r[0] / scale[0], r[1] / scale[1], r[2] / scale[2]];
        for i in 0..3 {
            b[i] += x[i] * r[3];
            for j in 0..3 {
                a[i][j] += x[i] * x[j];
            }
        }
    }
    let solution = solve3(a, b).ok_or(FitError::Degenerate)?;
    Ok(LinearCost {
        fixed: (solution[0] / scale[0]) as f32,
        per_primitive: (solution[1] / scale[1]) as f32,
        per_pixel: (solution[2] / scale[2]) as f32,
    })
}

/// Gaussian elimination with partial pivoting; `None` when singular.
fn solve3(mut a: [[f64; 3]; 3], mut b: [f64; 3]) -> Option<[f64; 3]> {
    let norm = a.iter().flatten().fold(0.0_f64, |m, x| m.max(x.abs()));
    for col in 0..3 {
        let pivot = (col..3).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))?;
        if a[pivot][col].abs() <= 1e-12 * norm.max(f64::MIN_POSITIVE) {
            return None;
        }
        a.swap(col, pivot);
        b.swap(col, pivot);
        let pivot_row = a[col];
        for row in col + 1..3 {
            let f = a[row][col] / pivot_row[col];
            for (value, p) in a[row].iter_mut().zip(pivot_row).skip(col) {
                *value -= f * p;
            }
            b[row] -= f * b[col];
        }
    }
    let mut x = [0.0; 3];
    for row in (0..3).rev() {
        let rest: f64 = (row + 1..3).map(|k| a[row][k] * x[k]).sum();
        x[row] = (b[row] - rest) / a[row][row];
    }
    Some(x)
}

/// Logic time against the number of visible instances, from the logic benchmark;
/// interpolated between the nearest samples at run time.
#[derive(Clone, Debug, PartialEq, Default, Serialize, Deserialize)]
pub struct LogicTable {
    /// `(visible instances, seconds)`, sorted by visible count.
    pub samples: Vec<(u32, f32)>,
}

impl LogicTable {
    /// A table from samples in any order (non-finite or negative times dropped; equal
    /// counts averaged).
    pub fn new(mut samples: Vec<(u32, f32)>) -> Self {
        samples.retain(|s| s.1.is_finite() && s.1 >= 0.0);
        samples.sort_by_key(|s| s.0);
        let mut merged: Vec<(u32, f32, u32)> = Vec::new();
        for (n, t) in samples {
            match merged.last_mut() {
                Some(last) if last.0 == n => {
                    last.1 += t;
                    last.2 += 1;
                }
                _ => merged.push((n, t, 1)),
            }
        }
        Self {
            samples: merged
                .into_iter()
                .map(|(n, t, k)| (n, t / k as f32))
                .collect(),
        }
    }

    /// Logic time with `visible` instances: linear between the two nearest samples;
    /// outside the sampled range, the nearest segment extended (never below zero); a
    /// single sample is a constant; an empty table is 0.
    pub fn time(&self, visible: u32) -> f32 {
        let s = &self.samples;
        match s.len() {
            0 => 0.0,
            1 => s[0].1,
            _ => {
                let i = s.partition_point(|p| p.0 <= visible).clamp(1, s.len() - 1);
                let (a, b) = (s[i - 1], s[i]);
                let t = (visible as f32 - a.0 as f32) / (b.0 as f32 - a.0 as f32);
                (a.1 + t * (b.1 - a.1)).max(0.0)
            }
        }
    }
}

/// A smoothed multiplicative correction of one family's predictions.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct OnlineCorrection {
    /// Time constant of the smoothing, seconds. Default: `0.25` (≈ 1 s to settle).
    pub time_constant: f32,
    log_factor: f32,
}

impl Default for OnlineCorrection {
    fn default() -> Self {
        Self {
            time_constant: 0.25,
            log_factor: 0.0,
        }
    }
}

impl OnlineCorrection {
    /// The current factor to multiply calibrated predictions by.
    pub fn factor(&self) -> f32 {
        self.log_factor.exp()
    }

    /// Feeds one frame: what the calibrated model alone predicted, what was measured, and
    /// the frame's duration. Non-positive or non-finite inputs are ignored.
    pub fn update(&mut self, predicted: f32, measured: f32, dt: f32) {
        if ![predicted, measured, dt]
            .iter()
            .all(|x| x.is_finite() && *x > 0.0)
        {
            return;
        }
        let tau = if self.time_constant > 0.0 {
            self.time_constant
        } else {
            1e-6
        };
        let alpha = 1.0 - (-dt / tau).exp();
        let target = (measured / predicted).ln();
        self.log_factor += alpha * (target - self.log_factor);
    }
}

/// A saved calibration (`*.calibration.ron`): what this adapter's primitives and logic cost.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Calibration {
    /// The adapter it was measured on (wgpu's adapter name).
    pub adapter: String,
    /// The driver (wgpu's driver and driver info).
    pub driver: String,
    /// Triangles.
    pub triangles: LinearCost,
    /// Lines, per width in pixels from 1 (index 0) up.
    pub lines: Vec<LinearCost>,
    /// Points, per size in pixels from 1 (index 0) up.
    pub points: Vec<LinearCost>,
    /// Logic time against visible instances.
    pub logic: LogicTable,
}

impl Default for Calibration {
    /// A rough default, used with a warning until a calibration is measured: per-primitive
    /// costs of this crate's render pass on Mesa lavapipe (a software rasteriser), as
    /// `pass_benchmark` measured them on a 2-core machine — about 1.1 µs per small
    /// triangle, 2.6 µs per line and 1.5 µs per point, plus a few ns per covered pixel.
    /// `pixels` are covered pixels: a line's length × width, a point's size².
    fn default() -> Self {
        Self {
            adapter: "unknown".into(),
            driver: "unknown".into(),
            triangles: LinearCost {
                fixed: 2e-4,
                per_primitive: 1.1e-6,
                per_pixel: 5e-9,
            },
            lines: (1..=20)
                .map(|_| LinearCost {
                    fixed: 2e-4,
                    per_primitive: 2.6e-6,
                    per_pixel: 5e-9,
                })
                .collect(),
            points: (1..=20)
                .map(|_| LinearCost {
                    fixed: 2e-4,
                    per_primitive: 1.5e-6,
                    per_pixel: 1.2e-8,
                })
                .collect(),
            logic: LogicTable::new(vec![(0, 2e-3), (1000, 6e-3)]),
        }
    }
}

/// Why a calibration file was refused.
#[derive(Debug, thiserror::Error)]
pub enum CalibrationError {
    /// The RON does not parse (the message names line, column and field).
    #[error("{0}")]
    Ron(#[from] ron::error::SpannedError),
    /// A value is out of range.
    #[error("{0}")]
    Invalid(String),
}

impl Calibration {
    /// Parses and validates a calibration.
    pub fn from_ron_str(text: &str) -> Result<Self, CalibrationError> {
        let calibration: Self = crate::ron_options().from_str(text)?;
        let costs = core::iter::once(&calibration.triangles)
            .chain(&calibration.lines)
            .chain(&calibration.points);
        for (i, c) in costs.enumerate() {
            let values = [c.fixed, c.per_primitive, c.per_pixel];
            if values.iter().any(|v| !v.is_finite() || *v < 0.0) {
                return Err(CalibrationError::Invalid(format!(
                    "cost {i} (triangles, then lines, then points) has a negative or non-finite part"
                )));
            }
        }
        Ok(calibration)
    }

    /// The calibration as RON.
    pub fn to_ron_string(&self) -> Result<String, ron::Error> {
        ron::ser::to_string_pretty(self, ron::ser::PrettyConfig::default())
    }

    /// Parses `text`, or falls back to [`Calibration::default`] with the reason.
    pub fn from_ron_str_or_default(text: &str) -> (Self, Option<CalibrationError>) {
        match Self::from_ron_str(text) {
            Ok(c) => (c, None),
            Err(e) => (Self::default(), Some(e)),
        }
    }
}
