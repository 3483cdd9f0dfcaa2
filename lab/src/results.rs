//! Turns the forest runs of `scripts/reproduce.sh` into `docs/results.md` — tables in the
//! paper's form next to the paper's numbers, binding-frame statistics, the noise floor
//! measured in the same session, each strategy's benefit as a share of the best possible —
//! and plots like the paper's figures 3, 4 and 7, plus the strategies side by side.
//!
//! ```sh
//! cargo run --release -p sherwood-lab -- results results/raw docs
//! ```
//!
//! Each run is `RAW/<trees>_<path>_<label>.csv` (the forest tool's `--record`), where
//! the label is `unlimited`, `hold_<fraction>` (identical frames: the noise floor) or
//! `<mode>_<strategy>_<fraction>[_nocorr]`; `RAW/GRID` says which grid produced them.
//!
//! `results --large results/large docs` turns the runs of `scripts/large-forest.sh`
//! into `docs/large-forest.md` instead.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use std::path::PathBuf;
use std::process::ExitCode;

use plotters::prelude::*;

use crate::frame_stats::{FrameStats, NOISE_WINDOW, variation};
use crate::record::{self, Record};

/// A frame counts as *binding* when its unlimited twin (the same frame of the path at full
/// detail) took more than this many times the target: no budget could be idle there.
const BINDING: f64 = 1.2;

/// One recorded frame.
#[derive(Clone, Debug)]
struct Frame {
    frame: u32,
    visible: f64,
    predicted_ms: f64,
    measured_ms: f64,
    benefit: f64,
    benefit_bound: f64,
    /// Value, budget and draw-lists stages together.
    stages_ms: f64,
    /// Visible objects drawn with nothing.
    undrawn: f64,
}

#[derive(Clone, Debug, PartialEq)]
enum Kind {
    Unlimited,
    /// Identical frames: the noise floor.
    Hold,
    Timed {
        corrected: bool,
    },
}

/// One run: its name's parts, target and frames.
#[derive(Clone, Debug)]
struct Run {
    trees: u32,
    path: String,
    kind: Kind,
    mode: String,
    strategy: String,
    /// Fraction of the unlimited peak the target was set to (none for unlimited).
    fraction: Option<f64>,
    target_ms: f64,
    frames: Vec<Frame>,
}

/// Statistics of a set of frames against a target.
#[derive(Clone, Copy, Debug, Default)]
struct Stats {
    frames: FrameStats,
    /// Mean |predicted − measured| / measured.
    prediction_err: f64,
    /// Mean of benefit / bound over the frames with a bound, percent (None without).
    benefit_pct: Option<f64>,
    stages_ms: f64,
    /// Mean visible objects drawn with nothing per frame.
    undrawn: f64,
}

impl Stats {
    fn of(frames: &[&Frame], target: f64) -> Self {
        let times: Vec<f64> = frames.iter().map(|f| f.measured_ms).collect();
        let n = frames.len().max(1) as f64;
        let scored: Vec<f64> = frames
            .iter()
            .filter(|f| f.benefit_bound > 0.0)
            .map(|f| 100.0 * f.benefit / f.benefit_bound)
            .collect();
        Self {
            frames: FrameStats::of(&times, target),
            prediction_err: frames
                .iter()
                .map(|f| (f.predicted_ms - f.measured_ms).abs() / f.measured_ms.max(1e-6))
                .sum::<f64>()
                / n,
            benefit_pct: (!scored.is_empty())
                .then(|| scored.iter().sum::<f64>() / scored.len() as f64),
            stages_ms: frames.iter().map(|f| f.stages_ms).sum::<f64>() / n,
            undrawn: frames.iter().map(|f| f.undrawn).sum::<f64>() / n,
        }
    }
}

impl Run {
    fn all(&self) -> Vec<&Frame> {
        self.frames.iter().collect()
    }

    /// The frames whose unlimited twin took more than [`BINDING`] × the target.
    fn binding(&self, unlimited: &Run) -> Vec<&Frame> {
        let full: BTreeMap<u32, f64> = unlimited
            .frames
            .iter()
            .map(|f| (f.frame, f.measured_ms))
            .collect();
        self.frames
            .iter()
            .filter(|f| {
                full.get(&f.frame)
                    .is_some_and(|&t| t > BINDING * self.target_ms)
            })
            .collect()
    }

    /// The run's label in tables and legends.
    fn label(&self) -> String {
        match self.kind {
            Kind::Timed { corrected: false } => {
                format!("{} {} (no correction)", self.mode, self.strategy)
            }
            _ => format!("{} {}", self.mode, self.strategy),
        }
    }
}

/// `(trees, path, kind, mode, strategy, fraction)` from a run's file stem.
fn parse_name(stem: &str) -> Option<(u32, String, Kind, String, String, Option<f64>)> {
    let parts: Vec<&str> = stem.split('_').collect();
    let trees = parts.first()?.parse().ok()?;
    let path = (*parts.get(1)?).to_owned();
    let fraction = |s: &str| s.parse::<f64>().ok().filter(|f| *f > 0.0);
    let timed = |mode: &str, strategy: &str, f: &str, corrected: bool| {
        Some((
            trees,
            path.clone(),
            Kind::Timed { corrected },
            mode.to_owned(),
            strategy.to_owned(),
            Some(fraction(f)?),
        ))
    };
    match parts[2..] {
        ["unlimited"] => Some((
            trees,
            path.clone(),
            Kind::Unlimited,
            "unlimited".into(),
            String::new(),
            None,
        )),
        ["hold", f] => Some((
            trees,
            path.clone(),
            Kind::Hold,
            "tclod".into(),
            "robin-hood".into(),
            Some(fraction(f)?),
        )),
        [mode, strategy, f] => timed(mode, strategy, f, true),
        [mode, strategy, f, "nocorr"] => timed(mode, strategy, f, false),
        _ => None,
    }
}

fn read_run(csv: &Path) -> Result<Option<Run>, String> {
    let stem = csv.file_stem().and_then(|s| s.to_str()).unwrap_or_default();
    let Some((trees, path, kind, mode, strategy, fraction)) = parse_name(stem) else {
        return Ok(None);
    };
    let record = Record::read(csv)?;
    let target = record.column(|r| r.target_ms);
    let frames = record
        .frames
        .iter()
        .map(|r| Frame {
            frame: r.frame,
            visible: f64::from(r.visible),
            predicted_ms: f64::from(r.predicted_ms),
            measured_ms: f64::from(r.measured_ms),
            benefit: f64::from(r.benefit),
            benefit_bound: f64::from(r.benefit_bound),
            stages_ms: f64::from(r.value_stage_ms + r.budget_stage_ms + r.draw_lists_stage_ms),
            undrawn: f64::from(r.undrawn),
        })
        .collect();
    let target_ms = target
        .first()
        .copied()
        .filter(|t| *t > 0.0)
        .ok_or_else(|| format!("{}: no frames with a target", csv.display()))?;
    Ok(Some(Run {
        trees,
        path,
        kind,
        mode,
        strategy,
        fraction,
        target_ms,
        frames,
    }))
}

/// The noise floor of a hold run: coefficient of variation over the whole run and the
/// median within windows of [`NOISE_WINDOW`] frames, percent; and its statistics.
struct Floor {
    whole_cv: f64,
    window_cv: f64,
    stats: Stats,
}

fn noise_floor(hold: &Run) -> Floor {
    let times: Vec<f64> = hold.frames.iter().map(|f| f.measured_ms).collect();
    let (whole_cv, window_cv) = variation(&times);
    Floor {
        whole_cv,
        window_cv,
        stats: Stats::of(&hold.all(), hold.target_ms),
    }
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

/// One line of a plot: its label, colour index and points.
struct Series {
    label: String,
    points: Vec<(u32, f64)>,
    /// A dashed horizontal line at this value (the target), in the series' colour.
    level: Option<f64>,
}

fn plot(
    file: &Path,
    title: &str,
    y_desc: &str,
    background: Option<&Series>,
    series: &[Series],
) -> Result<(), Box<dyn std::error::Error>> {
    let root = BitMapBackend::new(file, (1100, 520)).into_drawing_area();
    root.fill(&WHITE)?;
    let all = || series.iter().chain(background);
    let frames = all()
        .flat_map(|s| s.points.last().map(|p| p.0))
        .max()
        .unwrap_or(1)
        .max(1);
    let top = all()
        .flat_map(|s| s.points.iter().map(|p| p.1).chain(s.level))
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
        .y_desc(y_desc)
        .light_line_style(WHITE)
        .draw()?;
    if let Some(b) = background {
        let grey = RGBColor(150, 150, 150);
        chart
            .draw_series(LineSeries::new(
                b.points.iter().copied(),
                grey.stroke_width(1),
            ))?
            .label(b.label.clone())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], grey));
    }
    for (i, s) in series.iter().enumerate() {
        let color = Palette99::pick(i).to_rgba();
        chart
            .draw_series(LineSeries::new(
                s.points.iter().copied(),
                color.stroke_width(1),
            ))?
            .label(s.label.clone())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color));
        if let Some(level) = s.level {
            chart.draw_series(DashedLineSeries::new(
                [(0, level), (frames, level)],
                6,
                4,
                color.stroke_width(1),
            ))?;
        }
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

fn frame_times(run: &Run, label: String) -> Series {
    Series {
        label,
        points: run
            .frames
            .iter()
            .map(|f| (f.frame, f.measured_ms))
            .collect(),
        level: Some(run.target_ms),
    }
}

/// The results tool's command line.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The runs' records (`<trees>_<path>_<label>.csv`) and their `GRID`.
    raw: PathBuf,
    /// Where `results.md` (or `large-forest.md`) and the plots go.
    docs: PathBuf,
    /// The large-forest report (`scripts/large-forest.sh`'s runs) instead.
    #[arg(long)]
    large: bool,
}

/// Runs the results tool.
pub fn run(args: Args) -> ExitCode {
    let result = if args.large {
        crate::large_forest::report(&args.raw, &args.docs).map_err(|e| e.to_string())
    } else {
        report(&args.raw, &args.docs).map_err(|e| e.to_string())
    };
    crate::report("results", result)
}

/// A target fraction as a map key (fractions are short decimals from the file names).
fn fraction_key(fraction: Option<f64>) -> u64 {
    (fraction.unwrap_or(0.0) * 1e6).round() as u64
}

fn pct(x: f64) -> String {
    format!("{:.1}", 100.0 * x)
}

fn report(raw: &Path, docs: &Path) -> Result<(), Box<dyn std::error::Error>> {
    plotters::style::register_font(
        "sans-serif",
        FontStyle::Normal,
        bevy::text::DEFAULT_FONT_DATA,
    )
    .map_err(|_| "the embedded font did not load")?;
    let mut runs = Vec::new();
    for p in &record::csv_files(raw)? {
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
        "Generated by `scripts/reproduce.sh` (then `cargo run --release -p sherwood-lab -- results results/raw docs`) \
         on a 2-core machine rendering with Mesa lavapipe (software Vulkan), release build, 960×540, \
         no window (`--headless`). The grid that produced these tables:\n\n```\n{}\n```\n",
        grid.trim()
    )?;
    writeln!(
        md,
        "Targets are fractions of the unlimited run's peak frame time on the same path and forest, as the paper \
         chose 1/16 to 1/2 of its unconstrained peak. **Whole path**: every measured frame, in the paper's form \
         (mean, std, avg error = mean |t − target| / target). **Binding frames**: the frames whose unlimited twin \
         took more than {BINDING} × the target, where the budget must bind (elsewhere no method can reach the target \
         and the whole-path mean blames the budget for it); *mean* is their mean against the target, *over* the \
         share slower than 1.1 × target, *pred err* the mean |predicted − measured| / measured frame time. \
         **Benefit**: each frame's benefit (value × √(cost / full cost) per object, the ladders' model) as a \
         share of the best any selection could reach within the same rendering time (`budget::oracle::sqrt_benefit_bound`), \
         mean over binding frames; above 100% only where Robin Hood's cheapest representations alone overran; \
         *dropped*: visible objects drawn with nothing, mean per binding frame (Robin Hood never drops one). \
         *stages*: the value, budget and draw-lists stages per frame. **Goals** (binding frames; for TC and TCLOD): mean \
         within ±3% of the target, avg error ≤ 5%, over ≤ 5%, pred err ≤ 5% or 1.5 × the noise floor's.\n"
    )?;
    let mut groups: BTreeMap<(u32, String), Vec<&Run>> = BTreeMap::new();
    for run in &runs {
        groups
            .entry((run.trees, run.path.clone()))
            .or_default()
            .push(run);
    }
    // The noise floor is per forest and target fraction (taken on one path): its
    // prediction error sets the bar of every path of that forest at that fraction.
    let floors: BTreeMap<(u32, u64), (&Run, Floor)> = runs
        .iter()
        .filter(|r| r.kind == Kind::Hold)
        .map(|r| ((r.trees, fraction_key(r.fraction)), (r, noise_floor(r))))
        .collect();
    for ((trees, path), group) in &groups {
        writeln!(md, "## {trees} trees, {path} path\n")?;
        let Some(unlimited) = group.iter().copied().find(|r| r.kind == Kind::Unlimited) else {
            writeln!(md, "No unlimited run: no binding frames and no targets.\n")?;
            continue;
        };
        let s = FrameStats::of(
            &unlimited
                .frames
                .iter()
                .map(|f| f.measured_ms)
                .collect::<Vec<_>>(),
            1.0,
        );
        writeln!(
            md,
            "Unlimited: {} frames, mean {:.1} ms, std {:.1}, peak {:.1} ms, mean visible {:.0}.\n",
            s.frames,
            s.mean,
            s.std,
            s.peak,
            unlimited.frames.iter().map(|f| f.visible).sum::<f64>()
                / unlimited.frames.len().max(1) as f64
        )?;
        let held: Vec<&(&Run, Floor)> = floors
            .range((*trees, 0)..=(*trees, u64::MAX))
            .map(|(_, f)| f)
            .collect();
        if held.first().is_some_and(|(hold, _)| &hold.path == path) {
            writeln!(
                md,
                "Noise floor: identical frames, the camera held at the unlimited peak's frame, TCLOD Robin Hood at each target \
                 (*variation*: the frame time's std / mean over the run, and its median within {NOISE_WINDOW}-frame windows).\n"
            )?;
            writeln!(
                md,
                "| target ms | frames | variation % (run / windows) | mean vs target | avg err % | over % | pred err % |"
            )?;
            writeln!(md, "|---|---|---|---|---|---|---|")?;
            for (hold, floor) in &held {
                writeln!(
                    md,
                    "| {:.1} | {} | {:.1} / {:.1} | {:+.1}% | {} | {:.1} | {} |",
                    hold.target_ms,
                    floor.stats.frames.frames,
                    floor.whole_cv,
                    floor.window_cv,
                    100.0 * (floor.stats.frames.mean / hold.target_ms - 1.0),
                    pct(floor.stats.frames.avg_err),
                    floor.stats.frames.over_pct,
                    pct(floor.stats.prediction_err),
                )?;
            }
            writeln!(md)?;
        }
        writeln!(
            md,
            "| target ms | mode | strategy | whole: mean ms | std | avg err % | binding frames | mean vs target | avg err % | p95 ms | p99 ms | over % | pred err % | benefit % of bound | dropped | stages ms | goals |"
        )?;
        writeln!(
            md,
            "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
        )?;
        let mut timed: Vec<&Run> = group
            .iter()
            .copied()
            .filter(|r| matches!(r.kind, Kind::Timed { .. }))
            .collect();
        timed.sort_by(|a, b| {
            (
                a.fraction.unwrap_or(0.0),
                a.mode.as_str(),
                a.strategy.as_str(),
                a.kind != (Kind::Timed { corrected: true }),
            )
                .partial_cmp(&(
                    b.fraction.unwrap_or(0.0),
                    b.mode.as_str(),
                    b.strategy.as_str(),
                    b.kind != (Kind::Timed { corrected: true }),
                ))
                .unwrap_or(core::cmp::Ordering::Equal)
        });
        for run in &timed {
            let whole = Stats::of(&run.all(), run.target_ms);
            let binding = run.binding(unlimited);
            let bind = Stats::of(&binding, run.target_ms);
            let floor_pred = floors
                .get(&(*trees, fraction_key(run.fraction)))
                .map(|f| f.1.stats.prediction_err);
            let pred_bar = floor_pred.map_or(0.05, |f| (1.5 * f).max(0.05));
            let goals = if binding.is_empty() {
                "no binding frames".to_owned()
            } else {
                let missed: Vec<&str> = [
                    (
                        (bind.frames.mean - run.target_ms).abs() > 0.03 * run.target_ms,
                        "mean",
                    ),
                    (bind.frames.avg_err > 0.05, "avg err"),
                    (bind.frames.over_pct > 5.0, "over"),
                    (bind.prediction_err > pred_bar, "pred err"),
                ]
                .into_iter()
                .filter_map(|(miss, name)| miss.then_some(name))
                .collect();
                if missed.is_empty() {
                    "met".to_owned()
                } else {
                    format!("**missed**: {}", missed.join(", "))
                }
            };
            writeln!(
                md,
                "| {:.1} | {} | {}{} | {:.1} | {:.1} | {} | {} | {:+.1}% | {} | {:.1} | {:.1} | {:.1} | {} | {} | {:.1} | {:.2} | {goals} |",
                run.target_ms,
                run.mode,
                run.strategy,
                if run.kind == (Kind::Timed { corrected: false }) {
                    " (no correction)"
                } else {
                    ""
                },
                whole.frames.mean,
                whole.frames.std,
                pct(whole.frames.avg_err),
                binding.len(),
                100.0 * (bind.frames.mean / run.target_ms - 1.0),
                pct(bind.frames.avg_err),
                bind.frames.p95,
                bind.frames.p99,
                bind.frames.over_pct,
                pct(bind.prediction_err),
                bind.benefit_pct.map_or("—".into(), |b| format!("{b:.1}")),
                bind.undrawn,
                whole.stages_ms,
            )?;
        }
        writeln!(md)?;
        // Figures 3, 4 and 7: one mode with Robin Hood at every target.
        for mode in ["tc", "tclod"] {
            let of_mode: Vec<Series> = timed
                .iter()
                .filter(|r| {
                    r.mode == mode
                        && r.strategy == "robin-hood"
                        && r.kind == (Kind::Timed { corrected: true })
                })
                .map(|r| frame_times(r, format!("target {:.1} ms", r.target_ms)))
                .collect();
            if of_mode.is_empty() {
                continue;
            }
            let name = format!("{trees}-{path}-{mode}.png");
            plot(
                &plots.join(&name),
                &format!(
                    "{trees} trees, {path} path, {}, Robin Hood",
                    mode.to_uppercase()
                ),
                "frame time (ms)",
                Some(&frame_times(unlimited, "unlimited".into())),
                &of_mode,
            )?;
            writeln!(md, "![{mode}, {trees} trees, {path}](results/{name})\n")?;
        }
        // The strategies side by side at one target (the one nearest 1/4 of the peak).
        let Some(fraction) = timed
            .iter()
            .filter_map(|r| r.fraction)
            .min_by(|a, b| (a - 0.25).abs().total_cmp(&(b - 0.25).abs()))
        else {
            continue;
        };
        let side: Vec<&Run> = timed
            .iter()
            .copied()
            .filter(|r| {
                r.mode == "tclod"
                    && r.fraction == Some(fraction)
                    && r.kind == (Kind::Timed { corrected: true })
            })
            .collect();
        if side.len() > 1 {
            let name = format!("{trees}-{path}-strategies.png");
            let series: Vec<Series> = side.iter().map(|r| frame_times(r, r.label())).collect();
            plot(
                &plots.join(&name),
                &format!(
                    "{trees} trees, {path} path, TCLOD at {:.1} ms: the strategies",
                    side[0].target_ms
                ),
                "frame time (ms)",
                Some(&frame_times(unlimited, "unlimited".into())),
                &series,
            )?;
            writeln!(md, "![strategies, {trees} trees, {path}](results/{name})\n")?;
            let scored: Vec<Series> = side
                .iter()
                .map(|r| Series {
                    label: r.label(),
                    points: r
                        .frames
                        .iter()
                        .filter(|f| f.benefit_bound > 0.0)
                        .map(|f| (f.frame, 100.0 * f.benefit / f.benefit_bound))
                        .collect(),
                    level: None,
                })
                .filter(|s| !s.points.is_empty())
                .collect();
            if !scored.is_empty() {
                let name = format!("{trees}-{path}-benefit.png");
                plot(
                    &plots.join(&name),
                    &format!(
                        "{trees} trees, {path} path, TCLOD at {:.1} ms: benefit as % of the bound",
                        side[0].target_ms
                    ),
                    "benefit (% of bound)",
                    None,
                    &scored,
                )?;
                writeln!(md, "![benefit, {trees} trees, {path}](results/{name})\n")?;
            }
        }
    }
    writeln!(md, "## The paper's numbers\n")?;
    writeln!(
        md,
        "From `ALGORITHMS.md` (paper table 2 = thesis tables 6.2/6.3: 600 trees, TC without LOD; thesis table 6.6: \
         TCLOD with P-11, std not given). Their machine had a GPU; the targets are theirs; their statistics are \
         whole-path ones.\n"
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
