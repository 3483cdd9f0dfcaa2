//! Turns the forest runs of `scripts/reproduce.sh` into `docs/results.md` (tables in the
//! paper's form, next to the paper's numbers) and frame-time plots like the paper's
//! figures 3, 4 and 7.
//!
//! ```sh
//! cargo run --release --example results -- results/raw docs
//! ```
//!
//! Each run is `RAW/<trees>-<path>-<mode>[-<fraction>][-nocorr].csv` (the forest example's
//! `--record`) with its `--summary` line in the `.summary` file of the same name.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use frame_stats::FrameStats;
use plotters::prelude::*;
use record::Record;

#[path = "support/frame_stats.rs"]
mod frame_stats;
#[path = "support/record.rs"]
mod record;

/// One recorded frame.
#[derive(Clone, Debug)]
struct Frame {
    frame: u32,
    visible: f64,
    logic_ms: f64,
    predicted_ms: f64,
    measured_ms: f64,
}

/// One run: its name's parts, target and frames.
#[derive(Clone, Debug)]
struct Run {
    trees: u32,
    path: String,
    mode: String,
    /// Fraction of the unlimited peak the target was set to (none for unlimited).
    fraction: Option<f64>,
    corrected: bool,
    target_ms: f64,
    frames: Vec<Frame>,
}

/// The statistics of a run: its frame times', and the model's.
struct Stats {
    frames: FrameStats,
    logic: f64,
    prediction_err: f64,
}

impl Run {
    fn stats(&self) -> Stats {
        let times: Vec<f64> = self.frames.iter().map(|f| f.measured_ms).collect();
        let n = times.len().max(1) as f64;
        Stats {
            frames: FrameStats::of(&times, self.target_ms),
            logic: self.frames.iter().map(|f| f.logic_ms).sum::<f64>() / n,
            prediction_err: self
                .frames
                .iter()
                .map(|f| (f.predicted_ms - f.measured_ms).abs() / f.measured_ms.max(1e-6))
                .sum::<f64>()
                / n,
        }
    }
}

fn parse_name(stem: &str) -> Option<(u32, String, String, Option<f64>, bool)> {
    let mut parts: Vec<&str> = stem.split('-').collect();
    let corrected = parts.last() != Some(&"nocorr");
    if !corrected {
        parts.pop();
    }
    match parts.as_slice() {
        [trees, path, mode] => Some((
            trees.parse().ok()?,
            (*path).into(),
            (*mode).into(),
            None,
            corrected,
        )),
        [trees, path, mode, fraction] => Some((
            trees.parse().ok()?,
            (*path).into(),
            (*mode).into(),
            Some(fraction.parse().ok()?),
            corrected,
        )),
        _ => None,
    }
}

fn read_run(csv: &Path) -> Result<Option<Run>, String> {
    let stem = csv.file_stem().and_then(|s| s.to_str()).unwrap_or_default();
    let Some((trees, path, mode, fraction, corrected)) = parse_name(stem) else {
        return Ok(None);
    };
    let record = Record::read(csv)?;
    let column = |name| {
        record
            .column(name)
            .map_err(|e| format!("{}: {e}", csv.display()))
    };
    let (frame, visible, logic, predicted, measured) = (
        column("frame")?,
        column("visible")?,
        column("logic_ms")?,
        column("predicted_ms")?,
        column("measured_ms")?,
    );
    let frames = (0..frame.len())
        .map(|i| Frame {
            frame: frame[i] as u32,
            visible: visible[i],
            logic_ms: logic[i],
            predicted_ms: predicted[i],
            measured_ms: measured[i],
        })
        .collect();
    let summary_path = csv.with_extension("summary");
    let summary = std::fs::read_to_string(&summary_path).unwrap_or_default();
    let target_ms = summary
        .split_whitespace()
        .find_map(|w| w.strip_prefix("target_ms="))
        .and_then(|v| v.parse().ok())
        .ok_or_else(|| format!("{}: no summary line with target_ms", summary_path.display()))?;
    Ok(Some(Run {
        trees,
        path,
        mode,
        fraction,
        corrected,
        target_ms,
        frames,
    }))
}

/// The paper's own numbers (ALGORITHMS.md: paper table 2 = thesis 6.2/6.3, TC without LOD,
/// 600 trees; thesis table 6.6, TCLOD with P-11, path not stated): (mode, path, `t_f` ms,
/// mean ms, std ms, avg error).
const PAPER: &[(&str, &str, f64, f64, Option<f64>, f64)] = &[
    ("tc", "linear", 12.5, 11.791, Some(0.606), 0.065),
    ("tc", "linear", 50.0, 47.253, Some(1.121), 0.055),
    ("tc", "linear", 200.0, 198.541, Some(1.742), 0.009),
    ("tc", "zigzag", 12.5, 11.606, Some(0.391), 0.073),
    ("tc", "zigzag", 50.0, 47.577, Some(1.012), 0.049),
    ("tc", "zigzag", 200.0, 198.201, Some(1.725), 0.011),
    ("tclod", "—", 20.0, 20.0, None, 0.107),
    ("tclod", "—", 40.0, 36.8, None, 0.089),
    ("tclod", "—", 80.0, 74.9, None, 0.070),
    ("tclod", "—", 160.0, 158.3, None, 0.029),
];

fn plot(
    file: &Path,
    title: &str,
    unlimited: Option<&Run>,
    runs: &[&Run],
) -> Result<(), Box<dyn std::error::Error>> {
    let root = BitMapBackend::new(file, (1100, 520)).into_drawing_area();
    root.fill(&WHITE)?;
    let frames = runs
        .iter()
        .chain(unlimited.as_ref())
        .flat_map(|r| r.frames.last().map(|f| f.frame))
        .max()
        .unwrap_or(1);
    let top = runs
        .iter()
        .chain(unlimited.as_ref())
        .flat_map(|r| r.frames.iter().map(|f| f.measured_ms))
        .fold(1.0_f64, f64::max)
        * 1.05;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(0u32..frames, 0.0..top)?;
    chart
        .configure_mesh()
        .x_desc("frame")
        .y_desc("frame time (ms)")
        .light_line_style(WHITE)
        .draw()?;
    if let Some(u) = unlimited {
        chart
            .draw_series(LineSeries::new(
                u.frames.iter().map(|f| (f.frame, f.measured_ms)),
                RGBColor(150, 150, 150).stroke_width(1),
            ))?
            .label("unlimited")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], RGBColor(150, 150, 150)));
    }
    for (i, run) in runs.iter().enumerate() {
        let color = Palette99::pick(i).to_rgba();
        chart
            .draw_series(LineSeries::new(
                run.frames.iter().map(|f| (f.frame, f.measured_ms)),
                color.stroke_width(1),
            ))?
            .label(format!("target {:.1} ms", run.target_ms))
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color));
        chart.draw_series(DashedLineSeries::new(
            [(0, run.target_ms), (frames, run.target_ms)],
            6,
            4,
            color.stroke_width(1),
        ))?;
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()?;
    root.present()?;
    Ok(())
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [raw, docs] = args.as_slice() else {
        eprintln!("usage: results RAW_DIR DOCS_DIR");
        std::process::exit(2);
    };
    if let Err(e) = run(Path::new(raw), Path::new(docs)) {
        eprintln!("results: {e}");
        std::process::exit(1);
    }
}

fn run(raw: &Path, docs: &Path) -> Result<(), Box<dyn std::error::Error>> {
    plotters::style::register_font(
        "sans-serif",
        FontStyle::Normal,
        bevy::text::DEFAULT_FONT_DATA,
    )
    .map_err(|_| "the embedded font did not load")?;
    let paths = record::csv_files(raw)?;
    let mut runs = Vec::new();
    for p in &paths {
        if let Some(run) = read_run(p)? {
            runs.push(run);
        }
    }
    if runs.is_empty() {
        return Err(format!("no runs in {}", raw.display()).into());
    }
    let plots = docs.join("results");
    std::fs::create_dir_all(&plots)?;
    let grid = std::fs::read_to_string(raw.join("GRID")).unwrap_or_else(|_| "(unknown)".into());

    let mut md = String::new();
    writeln!(
        md,
        "# Results: frame times along the paper's camera paths\n"
    )?;
    writeln!(
        md,
        "Generated by `scripts/reproduce.sh` (then `cargo run --release --example results -- results/raw docs`) \
         on a 2-core machine rendering with Mesa lavapipe (software Vulkan), release build, 960×540, \
         no window (`--headless`). Grid of these tables:\n\n```\n{}\n```\n",
        grid.trim()
    )?;
    writeln!(
        md,
        "Targets are fractions of the unlimited run's peak frame time on the same path and forest, as the paper \
         chose 1/16 to 1/2 of its unconstrained peak. *logic* is the cost model's estimate of everything but the \
         forest pass (mean over the run); the goals (mean within ±3% of the target, avg error ≤ 5%, over_pct ≤ 5%) \
         apply to targets at least twice the logic time. *pred err* is the mean |predicted − measured| / measured \
         frame time.\n"
    )?;
    let mut groups: BTreeMap<(u32, String), Vec<&Run>> = BTreeMap::new();
    for run in &runs {
        groups
            .entry((run.trees, run.path.clone()))
            .or_default()
            .push(run);
    }
    for ((trees, path), group) in &groups {
        let unlimited = group.iter().copied().find(|r| r.mode == "unlimited");
        writeln!(md, "## {trees} trees, {path} path\n")?;
        if let Some(u) = unlimited {
            let s = u.stats().frames;
            writeln!(
                md,
                "Unlimited: {} frames, mean {:.1} ms, std {:.1}, peak {:.1} ms, mean visible {:.0}.\n",
                s.frames,
                s.mean,
                s.std,
                s.peak,
                u.frames.iter().map(|f| f.visible).sum::<f64>() / u.frames.len().max(1) as f64
            )?;
        }
        writeln!(
            md,
            "| mode | correction | target ms | mean ms | std ms | avg error | p95 ms | p99 ms | over_pct | logic ms | pred err | goals |"
        )?;
        writeln!(md, "|---|---|---|---|---|---|---|---|---|---|---|---|")?;
        let mut timed: Vec<&Run> = group
            .iter()
            .copied()
            .filter(|r| r.mode != "unlimited")
            .collect();
        timed.sort_by(|a, b| {
            (a.mode.as_str(), !a.corrected, a.fraction.unwrap_or(0.0))
                .partial_cmp(&(b.mode.as_str(), !b.corrected, b.fraction.unwrap_or(0.0)))
                .unwrap_or(core::cmp::Ordering::Equal)
        });
        for run in &timed {
            let Stats {
                frames: s,
                logic,
                prediction_err,
            } = run.stats();
            let applies = run.target_ms >= 2.0 * logic;
            let met = (s.mean - run.target_ms).abs() <= 0.03 * run.target_ms
                && s.avg_err <= 0.05
                && s.over_pct <= 5.0;
            let goals = match (applies, met) {
                (false, _) => "n/a (target < 2× logic)",
                (true, true) => "met",
                (true, false) => "**missed**",
            };
            writeln!(
                md,
                "| {} | {} | {:.1} | {:.1} | {:.1} | {:.3} | {:.1} | {:.1} | {:.1} | {:.1} | {:.3} | {goals} |",
                run.mode,
                if run.corrected { "on" } else { "off" },
                run.target_ms,
                s.mean,
                s.std,
                s.avg_err,
                s.p95,
                s.p99,
                s.over_pct,
                logic,
                prediction_err,
            )?;
        }
        writeln!(md)?;
        for mode in ["tc", "tclod"] {
            let of_mode: Vec<&Run> = timed
                .iter()
                .copied()
                .filter(|r| r.mode == mode && r.corrected)
                .collect();
            if of_mode.is_empty() {
                continue;
            }
            let name = format!("{trees}-{path}-{mode}.png");
            plot(
                &plots.join(&name),
                &format!("{trees} trees, {path} path, {}", mode.to_uppercase()),
                unlimited,
                &of_mode,
            )?;
            writeln!(md, "![{mode}, {trees} trees, {path}](results/{name})\n")?;
        }
    }
    writeln!(md, "## The paper's numbers\n")?;
    writeln!(
        md,
        "From `ALGORITHMS.md` (paper table 2 = thesis tables 6.2/6.3: 600 trees, TC without LOD; thesis table 6.6: \
         TCLOD with P-11, std not given). Their machine had a GPU; the targets are theirs.\n"
    )?;
    writeln!(
        md,
        "| mode | path | target ms | mean ms | std ms | avg error |"
    )?;
    writeln!(md, "|---|---|---|---|---|---|")?;
    for (mode, path, target, mean, std, err) in PAPER {
        writeln!(
            md,
            "| {mode} | {path} | {target} | {mean} | {} | {err} |",
            std.map_or("—".into(), |s| format!("{s}"))
        )?;
    }
    std::fs::write(docs.join("results.md"), md)?;
    println!(
        "wrote {} and {} plots",
        docs.join("results.md").display(),
        plots.display()
    );
    Ok(())
}
