//! Turns the runs of `scripts/learning.sh` into `docs/cost-model.md`: this machine's
//! noise floor, and how well the budget predicts and holds its target on the frames where
//! it must (the *binding* frames: those whose unlimited twin, the same frame of the same
//! path drawn at full detail, took more than 1.2 × the target), with the shipped
//! calibration and with one 3× too dear or too cheap.
//!
//! ```sh
//! cargo run --release --example cost_report -- results/learning docs
//! ```
//!
//! Runs are `RAW/<trees>-<path>-unlimited.csv`, `RAW/<trees>-<path>-<mode>-hold<K>.csv`
//! (the camera held at the path's frame K: identical frames) and
//! `RAW/<trees>-<path>-<mode>-<fraction>-x<scale>.csv` (target = fraction × the unlimited
//! peak, calibration × scale), each the forest example's `--record` with `--warmup 0`, so
//! that frame 0 is the first frame drawn and the learning is seen from its start.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use sherwood_lab::frame_stats::FrameStats;
use sherwood_lab::record::{self, Record};

/// Frames a learning run is given before its prediction error counts.
const LEARNING_FRAMES: usize = 60;

/// Frames of a window within which the machine's speed is taken as constant (a regime
/// lasts 5–10 s, a few tens of frames here).
const REGIME_FRAMES: usize = 20;

/// A frame binds when its unlimited twin took more than this × the target.
const BINDING: f64 = 1.2;

/// A run's recorded frames.
struct Frames {
    measured: Vec<f64>,
    predicted: Vec<f64>,
    target: Vec<f64>,
}

impl Frames {
    fn read(csv: &Path) -> Result<Self, String> {
        let record = Record::read(csv)?;
        let column = |name| {
            record
                .column(name)
                .map_err(|e| format!("{}: {e}", csv.display()))
        };
        Ok(Self {
            measured: column("measured_ms")?,
            predicted: column("predicted_ms")?,
            target: column("target_ms")?,
        })
    }
}

/// Mean |t − mean| / mean of `times`, %.
fn spread(times: &[f64]) -> f64 {
    let mean = times.iter().sum::<f64>() / times.len().max(1) as f64;
    100.0 * times.iter().map(|t| (t - mean).abs()).sum::<f64>()
        / times.len().max(1) as f64
        / mean.max(1e-9)
}

/// This run's own frame-to-frame jitter over `which`, %: mean |t − the mean of its two
/// neighbours on either side| / t. A predictor that knew the frames around each frame
/// would still be off by about this much: the noise floor of the same sitting, at this
/// load.
fn jitter(frames: &Frames, which: &[usize]) -> f64 {
    let t = &frames.measured;
    let inner: Vec<usize> = which
        .iter()
        .copied()
        .filter(|&i| i >= 2 && i + 2 < t.len())
        .collect();
    100.0
        * inner
            .iter()
            .map(|&i| {
                let around = (t[i - 2] + t[i - 1] + t[i + 1] + t[i + 2]) / 4.0;
                (t[i] - around).abs() / t[i]
            })
            .sum::<f64>()
        / inner.len().max(1) as f64
}

/// Seconds of frames from the start until the prediction error over the next
/// `LEARNING_FRAMES / 6` frames is within `bound` % (the learning of a calibration that
/// is off), or `None` if never.
fn settled_after(frames: &Frames, bound: f64) -> Option<f64> {
    let window = LEARNING_FRAMES / 6;
    let n = frames.measured.len();
    (0..n.saturating_sub(window)).find_map(|start| {
        let which: Vec<usize> = (start..start + window).collect();
        (prediction_error(frames, &which) <= bound)
            .then(|| (frames.measured[..start].iter().sum::<f64>() / 1000.0).max(0.0))
    })
}

/// Mean |predicted − measured| / measured over `frames`, %.
fn prediction_error(frames: &Frames, which: &[usize]) -> f64 {
    100.0
        * which
            .iter()
            .map(|&i| (frames.predicted[i] - frames.measured[i]).abs() / frames.measured[i])
            .sum::<f64>()
        / which.len().max(1) as f64
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [raw, docs] = args.as_slice() else {
        eprintln!("usage: cost_report RAW_DIR DOCS_DIR");
        std::process::exit(2);
    };
    if let Err(e) = run(Path::new(raw), Path::new(docs)) {
        eprintln!("cost_report: {e}");
        std::process::exit(1);
    }
}

fn run(raw: &Path, docs: &Path) -> Result<(), String> {
    let paths = record::csv_files(raw)?;
    let stem = |p: &Path| {
        p.file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or_default()
            .to_owned()
    };
    let mut out = String::new();
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|info| {
            info.lines().find_map(|l| {
                l.strip_prefix("model name")
                    .map(|v| v.trim_start_matches([' ', '\t', ':']).to_owned())
            })
        })
        .unwrap_or_else(|| "unknown".into());
    let _ = writeln!(
        out,
        "# The cost model on this machine\n\n\
         Generated by `scripts/learning.sh` (`examples/cost_report.rs`) on a {} with {} \
         cores, rendering with Mesa lavapipe, headless at 960×540, without wind. Times in ms.\n",
        cpu,
        std::thread::available_parallelism().map_or(0, std::num::NonZero::get)
    );

    // The noise floor: identical frames.
    let _ = writeln!(
        out,
        "## Noise floor: identical frames\n\n\
         The camera held at the linear path's busiest frame. *Whole run*: mean |t − mean| / \
         mean over every frame. *Within regimes*: the same within windows of {REGIME_FRAMES} \
         frames, averaged (the machine's speed switches between regimes lasting seconds). \
         *Regimes*: the slowest window's mean over the fastest's.\n\n\
         | run | frames | mean | whole run | within regimes | regimes |\n|---|---|---|---|---|---|"
    );
    let mut floor = None::<f64>;
    for p in paths.iter().filter(|p| stem(p).contains("-hold")) {
        let frames = Frames::read(p)?;
        let t = &frames.measured;
        let windows: Vec<&[f64]> = t.chunks_exact(REGIME_FRAMES).collect();
        let within = windows.iter().map(|w| spread(w)).sum::<f64>() / windows.len().max(1) as f64;
        let means: Vec<f64> = windows
            .iter()
            .map(|w| w.iter().sum::<f64>() / w.len() as f64)
            .collect();
        let regimes = means.iter().copied().fold(0.0, f64::max)
            / means.iter().copied().fold(f64::INFINITY, f64::min);
        let mean = t.iter().sum::<f64>() / t.len().max(1) as f64;
        floor = Some(floor.map_or(within, |f: f64| f.max(within)));
        let _ = writeln!(
            out,
            "| {} | {} | {mean:.1} | {:.1}% | {within:.1}% | ×{regimes:.2} |",
            stem(p),
            t.len(),
            spread(t)
        );
    }
    let floor = floor.unwrap_or(0.0);
    let allowed = if floor > 3.5 { 1.5 * floor } else { 5.0 };
    let _ = writeln!(
        out,
        "\nGoal for the prediction error: 5%, or 1.5 × the within-regime floor where that is \
         above 3.5%: **{allowed:.1}%** here.\n"
    );

    // The unlimited twins.
    let mut unlimited = BTreeMap::new();
    for p in paths.iter().filter(|p| stem(p).ends_with("-unlimited")) {
        let name = stem(p);
        let path = name.split('-').nth(1).unwrap_or_default().to_owned();
        unlimited.insert(path, Frames::read(p)?);
    }

    let _ = writeln!(
        out,
        "## Binding frames\n\n\
         Frames from {LEARNING_FRAMES} on whose unlimited twin took more than {BINDING} × the \
         target. *Mean*: their mean frame time and its difference from the target (goal: \
         within 3%). *Avg err*: mean |t − target| / target. *Over*: frames slower than 1.1 × \
         target (goal: 5%). *Pred err*: mean |predicted − measured| / measured (goal above); \
         *jitter*: the same run's frame-to-frame noise on those frames (mean |t − the mean of \
         the two frames either side| / t), the floor of this sitting at this load; *all*: the \
         prediction error over every frame from {LEARNING_FRAMES} on; *settled*: seconds from \
         the first frame until the prediction error over {} frames is within 1.5 × the \
         jitter (how long a calibration that is off takes to learn).\n\n\
         | path | mode | target | calibration | binding | mean | avg err | over | p95 | pred err | jitter | all | settled |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|---|",
        LEARNING_FRAMES / 6
    );
    let mut rows = Vec::new();
    for p in &paths {
        let name = stem(p);
        let parts: Vec<&str> = name.split('-').collect();
        let [_, path, mode, fraction, scale] = parts.as_slice() else {
            continue;
        };
        let (Some(scale), Ok(fraction)) = (scale.strip_prefix('x'), fraction.parse::<f64>()) else {
            continue;
        };
        let Some(twin) = unlimited.get(*path) else {
            return Err(format!("{name}: no unlimited run of the {path} path"));
        };
        let frames = Frames::read(p)?;
        let target = frames.target.first().copied().unwrap_or(f64::NAN);
        let n = frames.measured.len().min(twin.measured.len());
        let after: Vec<usize> = (LEARNING_FRAMES..n).collect();
        let binding: Vec<usize> = after
            .iter()
            .copied()
            .filter(|&i| twin.measured[i] > BINDING * target)
            .collect();
        let times: Vec<f64> = binding.iter().map(|&i| frames.measured[i]).collect();
        let s = FrameStats::of(&times, target);
        let floor = jitter(&frames, &after);
        let settled = settled_after(&frames, 1.5 * floor)
            .map_or("never".to_owned(), |t| format!("{:.1} s", t + 0.0));
        let binding_columns = if binding.is_empty() {
            "0 | — | — | — | — | — | —".to_owned()
        } else {
            format!(
                "{} | {:.1} ({:+.1}%) | {:.3} | {:.1}% | {:.1} | {:.1}% | {:.1}%",
                binding.len(),
                s.mean,
                100.0 * (s.mean / target - 1.0),
                s.avg_err,
                s.over_pct,
                s.p95,
                prediction_error(&frames, &binding),
                jitter(&frames, &binding),
            )
        };
        rows.push((
            path.to_string(),
            mode.to_string(),
            fraction,
            scale.parse::<f64>().unwrap_or(1.0),
            format!(
                "| {path} | {mode} | {target:.1} ({fraction}) | ×{scale} | {binding_columns} | {:.1}% | {settled} |",
                prediction_error(&frames, &after),
            ),
        ));
    }
    rows.sort_by(|a, b| {
        (&a.0, &a.1)
            .cmp(&(&b.0, &b.1))
            .then(a.2.total_cmp(&b.2))
            .then(b.3.total_cmp(&a.3))
    });
    for row in rows {
        let _ = writeln!(out, "{}", row.4);
    }
    let file = docs.join("cost-model.md");
    std::fs::write(&file, out).map_err(|e| format!("{}: {e}", file.display()))?;
    println!("wrote {}", file.display());
    Ok(())
}
