//! Fitting benchmark samples: linear costs per primitive family (thesis §6.2).

use serde::{Deserialize, Serialize};

/// A primitive family's cost: `fixed + per_primitive · primitives + per_pixel · pixels`,
/// in seconds.
#[derive(Clone, Copy, Debug, PartialEq, Default, Serialize, Deserialize)]
pub(crate) struct LinearCost {
    /// Cost of drawing any of this family at all (state changes, the draw call).
    pub fixed: f32,
    /// Cost per primitive (vertex work, setup).
    pub per_primitive: f32,
    /// Cost per covered pixel (fill).
    pub per_pixel: f32,
}

impl LinearCost {
    /// Predicted time of `primitives` primitives covering `pixels` pixels (0 for none).
    #[cfg(any(test, feature = "render"))]
    pub(crate) fn time(&self, primitives: f32, pixels: f32) -> f32 {
        if primitives <= 0.0 {
            return 0.0;
        }
        (self.fixed + self.per_primitive * primitives + self.per_pixel * pixels.max(0.0)).max(0.0)
    }
}

/// One benchmark sample: how many primitives, how many pixels they covered, how long it took.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg(any(test, feature = "render"))]
pub(crate) struct CostSample {
    /// Primitives drawn.
    pub primitives: f32,
    /// Pixels covered.
    pub pixels: f32,
    /// Measured time, seconds.
    pub time: f32,
}

/// Why a fit failed.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
#[cfg(any(test, feature = "render"))]
pub(crate) enum FitError {
    /// Fewer than three finite samples.
    #[error("need at least 3 finite samples to fit 3 parameters, got {0}")]
    TooFewSamples(usize),
    /// The samples do not vary enough to tell the parts apart.
    #[error("the samples are degenerate: primitive and pixel counts must vary independently")]
    Degenerate,
}

/// Least-squares fit of a [`LinearCost`] to samples (normal equations, solved in `f64`).
#[cfg(test)]
pub(crate) fn fit_linear_cost(samples: &[CostSample]) -> Result<LinearCost, FitError> {
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
#[cfg(any(test, feature = "render"))]
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
#[cfg(any(test, feature = "render"))]
pub(crate) fn fit_nonnegative_cost(samples: &[CostSample]) -> Result<LinearCost, FitError> {
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
#[cfg(any(test, feature = "render"))]
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
#[cfg(any(test, feature = "render"))]
pub(crate) fn fit_sized_costs(
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
#[cfg(any(test, feature = "render"))]
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
