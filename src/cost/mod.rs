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
//! a few time constants (by default about one second). Each frame's ratio is first
//! limited to within [`MAX_FRAME_RATIO`] of the current factor, so one wild frame moves
//! the factor little while a steady error of any size is still learned.

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
    let rows = finite_rows(samples);
    if rows.len() < 3 {
        return Err(FitError::TooFewSamples(rows.len()));
    }
    let solution = least_squares(&rows, &[0, 1, 2]).ok_or(FitError::Degenerate)?;
    Ok(LinearCost {
        fixed: solution[0] as f32,
        per_primitive: solution[1] as f32,
        per_pixel: solution[2] as f32,
    })
}

/// `[1, primitives, pixels, time]` per finite sample.
fn finite_rows(samples: &[CostSample]) -> Vec<[f64; 4]> {
    samples
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
        .collect()
}

/// Fits a cost with no negative part (non-negative least squares, exactly: every subset
/// of the three parts is fitted and the best fit whose parts are all non-negative wins).
/// Noise makes an unmeasurably small part come out negative in the plain fit; dropping it
/// is better than clamping it. When pixels follow the primitive count (points of one
/// size) the per-pixel part cannot be told apart and is left at 0.
pub fn fit_nonnegative_cost(samples: &[CostSample]) -> Result<LinearCost, FitError> {
    let rows = finite_rows(samples);
    if rows.is_empty() {
        return Err(FitError::TooFewSamples(0));
    }
    let pixels_follow_primitives = {
        let ratios: Vec<f64> = rows
            .iter()
            .filter(|r| r[1] > 0.0)
            .map(|r| r[2] / r[1])
            .collect();
        let first = ratios.first().copied().unwrap_or(0.0);
        ratios
            .iter()
            .all(|r| (r - first).abs() <= 1e-4 * first.abs().max(1e-12))
    };
    // Column subsets: {fixed, primitive, pixel} as bits 0, 1, 2.
    let mut best: Option<(f64, LinearCost)> = None;
    for subset in 1u8..8 {
        if pixels_follow_primitives && subset & 4 != 0 {
            continue;
        }
        let columns: Vec<usize> = (0..3).filter(|c| subset & (1 << c) != 0).collect();
        let Some(solution) = least_squares(&rows, &columns) else {
            continue;
        };
        if solution.iter().any(|x| *x < 0.0 || !x.is_finite()) {
            continue;
        }
        let mut parts = [0.0_f64; 3];
        for (&c, &x) in columns.iter().zip(&solution) {
            parts[c] = x;
        }
        let error: f64 = rows
            .iter()
            .map(|r| (parts[0] + parts[1] * r[1] + parts[2] * r[2] - r[3]).powi(2))
            .sum();
        if best.as_ref().is_none_or(|b| error < b.0 * (1.0 - 1e-9)) {
            best = Some((
                error,
                LinearCost {
                    fixed: parts[0] as f32,
                    per_primitive: parts[1] as f32,
                    per_pixel: parts[2] as f32,
                },
            ));
        }
    }
    best.map(|b| b.1).ok_or(FitError::Degenerate)
}

/// Least squares of `rows[..][3]` on the given columns of `rows` (normal equations with
/// scaled columns, solved in `f64`); `None` when singular or with too few rows.
fn least_squares(rows: &[[f64; 4]], columns: &[usize]) -> Option<Vec<f64>> {
    let k = columns.len();
    if rows.len() < k {
        return None;
    }
    let scale: Vec<f64> = columns
        .iter()
        .map(|&c| {
            rows.iter()
                .map(|r| r[c].abs())
                .fold(0.0, f64::max)
                .max(1e-30)
        })
        .collect();
    let mut a = [[0.0_f64; 3]; 3];
    let mut b = [0.0_f64; 3];
    for r in rows {
        let x: Vec<f64> = columns.iter().zip(&scale).map(|(&c, s)| r[c] / s).collect();
        for i in 0..k {
            b[i] += x[i] * r[3];
            for j in 0..k {
                a[i][j] += x[i] * x[j];
            }
        }
    }
    // Pad to 3×3 with identity rows so one solver serves every size.
    for (i, row) in a.iter_mut().enumerate().skip(k) {
        row[i] = 1.0;
    }
    let solution = solve3(a, b)?;
    Some((0..k).map(|i| solution[i] / scale[i]).collect())
}

/// Costs for sizes (line widths or point sizes) `1..=max_size` from samples measured at
/// some sizes: each measured size is fitted on its own ([`fit_nonnegative_cost`]); a size
/// between two measured ones gets the linear interpolation of their parts; a size
/// outside the measured ones, the nearest.
pub fn fit_sized_costs(
    samples: &[(u32, CostSample)],
    max_size: u32,
) -> Result<Vec<LinearCost>, FitError> {
    let mut sizes: Vec<u32> = samples.iter().map(|s| s.0).collect();
    sizes.sort_unstable();
    sizes.dedup();
    let mut fitted: Vec<(u32, LinearCost)> = Vec::with_capacity(sizes.len());
    for size in sizes {
        let of_size: Vec<CostSample> = samples
            .iter()
            .filter(|s| s.0 == size)
            .map(|s| s.1)
            .collect();
        fitted.push((size, fit_nonnegative_cost(&of_size)?));
    }
    if fitted.is_empty() {
        return Err(FitError::TooFewSamples(0));
    }
    let lerp = |a: &LinearCost, b: &LinearCost, t: f32| LinearCost {
        fixed: a.fixed + t * (b.fixed - a.fixed),
        per_primitive: a.per_primitive + t * (b.per_primitive - a.per_primitive),
        per_pixel: a.per_pixel + t * (b.per_pixel - a.per_pixel),
    };
    Ok((1..=max_size.max(1))
        .map(|size| {
            let i = fitted.partition_point(|f| f.0 <= size);
            match (i.checked_sub(1).map(|j| &fitted[j]), fitted.get(i)) {
                (Some(a), Some(b)) => lerp(&a.1, &b.1, (size - a.0) as f32 / (b.0 - a.0) as f32),
                (Some(only), None) | (None, Some(only)) => only.1,
                (None, None) => LinearCost::default(),
            }
        })
        .collect())
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

/// Logic time against the number of visible instances at one target frame time, from
/// the logic benchmark; interpolated between the nearest samples at run time.
#[derive(Clone, Debug, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LogicTable {
    /// The target frame time the samples were measured at, ms (the LOD's search, and so
    /// the logic time, depends on it when LOD is view-dependent).
    pub target_ms: f32,
    /// `(visible instances, seconds)`, sorted by visible count.
    pub samples: Vec<(u32, f32)>,
}

impl LogicTable {
    /// A table from samples in any order: non-finite or negative times are dropped, and
    /// samples whose visible counts lie within [`LogicTable::merge_gap`] of a run's first
    /// count are averaged into one (count and time). Frame times on a shared machine vary
    /// by tens of percent, so two samples one instance apart would otherwise make a
    /// segment whose slope is noise (the lavapipe calibration had 533 → 0 ms and
    /// 534 → 20 ms).
    pub fn new(target_ms: f32, mut samples: Vec<(u32, f32)>) -> Self {
        samples.retain(|s| s.1.is_finite() && s.1 >= 0.0);
        samples.sort_by_key(|s| s.0);
        let gap = Self::merge_gap(samples.last().map_or(0, |s| s.0));
        // (first count of the run, sum of counts, sum of times, samples)
        let mut runs: Vec<(u32, f64, f64, u32)> = Vec::new();
        for (n, t) in samples {
            match runs.last_mut() {
                Some(run) if n - run.0 <= gap => {
                    run.1 += f64::from(n);
                    run.2 += f64::from(t);
                    run.3 += 1;
                }
                _ => runs.push((n, f64::from(n), f64::from(t), 1)),
            }
        }
        Self {
            target_ms,
            samples: runs
                .into_iter()
                .map(|(_, n, t, k)| {
                    let k = f64::from(k);
                    ((n / k).round() as u32, (t / k) as f32)
                })
                .collect(),
        }
    }

    /// Samples whose visible counts differ by at most this much are one sample: 2% of the
    /// largest count, at least 2.
    pub fn merge_gap(largest_count: u32) -> u32 {
        (largest_count / 50).max(2)
    }

    /// Logic time with `visible` instances: linear between the two nearest samples;
    /// outside the sampled range, the nearest end sample extended with the table's
    /// overall slope (first to last sample, so one noisy end segment cannot send the
    /// estimate to seconds), never below zero; a single sample is a constant; an empty
    /// table is 0.
    pub fn time(&self, visible: u32) -> f32 {
        let s = &self.samples;
        let (Some(&first), Some(&last)) = (s.first(), s.last()) else {
            return 0.0;
        };
        if s.len() == 1 {
            return first.1;
        }
        let span = last.0.saturating_sub(first.0);
        let overall_slope = if span == 0 {
            0.0
        } else {
            (last.1 - first.1) / span as f32
        };
        let time = if visible <= first.0 {
            first.1 - overall_slope * (first.0 - visible) as f32
        } else if visible >= last.0 {
            last.1 + overall_slope * (visible - last.0) as f32
        } else {
            let i = s.partition_point(|p| p.0 <= visible).clamp(1, s.len() - 1);
            let (a, b) = (s[i - 1], s[i]);
            // `max(1)`: the fields are public, so a hand-built table may repeat a count.
            let t = visible.saturating_sub(a.0) as f32 / b.0.saturating_sub(a.0).max(1) as f32;
            a.1 + t.min(1.0) * (b.1 - a.1)
        };
        time.max(0.0)
    }
}

/// Logic time with `visible` instances at target `target_ms` from tables measured at
/// several targets: each table interpolated in the visible count, then linearly between
/// the two tables whose targets bracket `target_ms` (the nearest table outside their
/// range: logic time is not extrapolated in the target). No tables: 0.
pub fn logic_time(tables: &[LogicTable], visible: u32, target_ms: f32) -> f32 {
    let mut below: Option<&LogicTable> = None;
    let mut above: Option<&LogicTable> = None;
    for table in tables.iter().filter(|t| t.target_ms.is_finite()) {
        if table.target_ms <= target_ms {
            if below.is_none_or(|b| table.target_ms > b.target_ms) {
                below = Some(table);
            }
        } else if above.is_none_or(|a| table.target_ms < a.target_ms) {
            above = Some(table);
        }
    }
    match (below, above) {
        (Some(b), Some(a)) => {
            let t = (target_ms - b.target_ms) / (a.target_ms - b.target_ms);
            let (tb, ta) = (b.time(visible), a.time(visible));
            tb + t.clamp(0.0, 1.0) * (ta - tb)
        }
        (Some(only), None) | (None, Some(only)) => only.time(visible),
        (None, None) => 0.0,
    }
}

/// The most one frame's measured/predicted ratio may differ from the current factor, as
/// a ratio, before it is smoothed in. A single frame whose prediction was far off (a
/// stall, a tree at the camera) would otherwise drag the factor for a second of frames;
/// a steady error of any size is still learned, at most this ratio per time constant.
pub const MAX_FRAME_RATIO: f32 = 2.0;

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
    /// Forgets what was learned (factor 1), keeping the time constant.
    pub fn reset(&mut self) {
        self.log_factor = 0.0;
    }

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
        let step = MAX_FRAME_RATIO.ln();
        let target = (measured / predicted)
            .ln()
            .clamp(self.log_factor - step, self.log_factor + step);
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
    /// Logic time against visible instances, one table per target frame time measured
    /// (see [`logic_time`]).
    pub logic: Vec<LogicTable>,
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
            lines: vec![
                LinearCost {
                    fixed: 2e-4,
                    per_primitive: 2.6e-6,
                    per_pixel: 5e-9,
                };
                20
            ],
            points: vec![
                LinearCost {
                    fixed: 2e-4,
                    per_primitive: 1.5e-6,
                    per_pixel: 1.2e-8,
                };
                20
            ],
            logic: vec![LogicTable::new(100.0, vec![(0, 2e-3), (1000, 6e-3)])],
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
        let mut calibration: Self = crate::ron_options().from_str(text)?;
        // Files written before near-equal counts were merged, or edited by hand.
        for table in &mut calibration.logic {
            *table = LogicTable::new(table.target_ms, core::mem::take(&mut table.samples));
        }
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

    /// The fixed per-frame part of the pass: one draw of each family (the fixed part of
    /// triangles, of the thinnest lines and of the smallest points), seconds.
    pub fn fixed_time(&self) -> f32 {
        (self.triangles.fixed
            + self.lines.first().map_or(0.0, |c| c.fixed)
            + self.points.first().map_or(0.0, |c| c.fixed))
        .max(0.0)
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

/// The adapter the app renders with, as a calibration names it. The render plugin inserts
/// it once the renderer is up; calibrations are matched against it.
#[derive(bevy::prelude::Resource, Clone, Debug, PartialEq, Eq, Default)]
pub struct AdapterIdentity {
    /// wgpu's adapter name, e.g. `llvmpipe (LLVM 15.0.6, 256 bits)`.
    pub name: String,
    /// wgpu's driver and driver info, e.g. `llvmpipe Mesa 22.3.6 (LLVM 15.0.6)`.
    pub driver: String,
    /// A software rasteriser (wgpu's `DeviceType::Cpu`, e.g. lavapipe). Its GPU timestamps
    /// are taken when the draws are handed to the rasteriser threads, before the pixels
    /// are filled, so they miss most of a pass's cost: the cost model and the calibration
    /// then measure frame times instead.
    pub cpu: bool,
}

/// The file name a calibration of `adapter` is saved under: the adapter name in lower
/// case, runs of anything but letters and digits as one `-`, then `.calibration.ron`.
pub fn calibration_file_name(adapter: &str) -> String {
    let mut name = String::new();
    for c in adapter.chars() {
        if c.is_ascii_alphanumeric() {
            name.push(c.to_ascii_lowercase());
        } else if !name.ends_with('-') && !name.is_empty() {
            name.push('-');
        }
    }
    let name = name.trim_end_matches('-');
    format!(
        "{}.calibration.ron",
        if name.is_empty() { "adapter" } else { name }
    )
}

/// What [`find_calibration`] found in a directory.
#[derive(Debug, Default)]
pub struct CalibrationSearch {
    /// The calibration for the adapter: one naming the same adapter and driver, else one
    /// naming the same adapter.
    pub found: Option<(std::path::PathBuf, Calibration)>,
    /// Calibration files that could not be read or parsed, with the reason.
    pub refused: Vec<(std::path::PathBuf, String)>,
}

/// Reads the calibration file at `path`.
pub fn read_calibration(path: &std::path::Path) -> Result<Calibration, String> {
    let text = std::fs::read_to_string(path).map_err(|e| e.to_string())?;
    Calibration::from_ron_str(&text).map_err(|e| e.to_string())
}

/// Looks through the `*.calibration.ron` files of `dir` for one measured on `adapter`.
/// A missing directory finds nothing; unreadable or malformed files are listed in
/// [`CalibrationSearch::refused`] and skipped.
pub fn find_calibration(dir: &std::path::Path, adapter: &AdapterIdentity) -> CalibrationSearch {
    let mut search = CalibrationSearch::default();
    let Ok(entries) = std::fs::read_dir(dir) else {
        return search;
    };
    let mut paths: Vec<std::path::PathBuf> = entries
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.ends_with(".calibration.ron"))
        })
        .collect();
    paths.sort();
    let mut same_adapter = None;
    for path in paths {
        match read_calibration(&path) {
            Ok(c) if c.adapter == adapter.name && c.driver == adapter.driver => {
                search.found = Some((path, c));
                return search;
            }
            Ok(c) if c.adapter == adapter.name => {
                same_adapter.get_or_insert((path, c));
            }
            Ok(_) => {}
            Err(e) => search.refused.push((path, e)),
        }
    }
    search.found = same_adapter;
    search
}
