//! Frame-time statistics of a run in the paper's terms: shared by the forest tool's
//! `--summary` line and the `results` tables, so both report the same numbers.

/// Statistics of a run's measured frame times against its target.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FrameStats {
    /// Frames.
    pub frames: usize,
    /// Mean frame time, ms.
    pub mean: f64,
    /// Standard deviation (of the population), ms.
    pub std: f64,
    /// Mean of |t − target| / target.
    pub avg_err: f64,
    /// 95th percentile (nearest rank), ms.
    pub p95: f64,
    /// 99th percentile (nearest rank), ms.
    pub p99: f64,
    /// Percentage of frames slower than 1.1 × target.
    pub over_pct: f64,
    /// Slowest frame, ms.
    pub peak: f64,
}

impl FrameStats {
    /// The statistics of `times` (ms) against `target` (ms); all zero for no frames.
    pub fn of(times: &[f64], target: f64) -> Self {
        let n = times.len().max(1) as f64;
        let mean = times.iter().sum::<f64>() / n;
        let mut sorted = times.to_vec();
        sorted.sort_by(f64::total_cmp);
        let percentile = |p: f64| {
            sorted
                .get((p * (sorted.len().max(1) - 1) as f64).round() as usize)
                .copied()
                .unwrap_or(0.0)
        };
        Self {
            frames: times.len(),
            mean,
            std: (times.iter().map(|t| (t - mean).powi(2)).sum::<f64>() / n).sqrt(),
            avg_err: times
                .iter()
                .map(|t| (t - target).abs() / target)
                .sum::<f64>()
                / n,
            p95: percentile(0.95),
            p99: percentile(0.99),
            over_pct: times.iter().filter(|&&t| t > 1.1 * target).count() as f64 / n * 100.0,
            peak: sorted.last().copied().unwrap_or(0.0),
        }
    }
}

/// Frames per window of the within-regime noise (the machine's speed changes every
/// 5–10 s; a window of 25 frames stays inside one regime at these frame rates).
pub const NOISE_WINDOW: usize = 25;

/// How much frame times vary, percent: the coefficient of variation over all of `times`,
/// and its median within windows of [`NOISE_WINDOW`] frames.
pub fn variation(times: &[f64]) -> (f64, f64) {
    let cv = |v: &[f64]| {
        let s = FrameStats::of(v, 1.0);
        if s.mean > 0.0 {
            100.0 * s.std / s.mean
        } else {
            0.0
        }
    };
    let mut windows: Vec<f64> = times.chunks_exact(NOISE_WINDOW).map(cv).collect();
    windows.sort_by(f64::total_cmp);
    (
        cv(times),
        windows.get(windows.len() / 2).copied().unwrap_or(0.0),
    )
}
