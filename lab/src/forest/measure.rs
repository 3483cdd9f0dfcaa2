//! The measurement: each frame's selection paired with what was measured of it, the
//! record and the summary line.

use std::path::{Path, PathBuf};

use bevy::prelude::*;
use bevy::render::view::screenshot::{Screenshot, save_to_disk};
use bevy_sherwood::cost::{FrameBound, FrameClock, FrameSample, FrameSamples};
use bevy_sherwood::display as deadline;
use bevy_sherwood::lod::StrategyKind;
use bevy_sherwood::prelude::*;
use bevy_sherwood::wind::WindStats;

use super::args::{Args, Mode, Strategy};
use crate::frame_stats::FrameStats;
use crate::record::{Bound, FrameRecord, Record};

/// One measured frame.
#[derive(Clone, Debug)]
struct Row {
    frame: u32,
    diagnostics: LodDiagnostics,
    /// What was measured of the frame the diagnostics were made for.
    sample: FrameSample,
    /// The forest pass's GPU time, when timestamps are available (arrives a frame or two
    /// late).
    pass_ms: Option<f64>,
    /// What the forest pass drew in the frame rendered last when the measurement arrived.
    drawn: u64,
    /// The ladders' levels shown and switches in the frame.
    ladders: LadderDiagnostics,
    /// With `--vsync-hz`: refresh periods the frame took (0 without), and whether that is
    /// more than its target allows.
    periods: u32,
    missed_vblank: bool,
    /// The mode and strategy when the row was taken.
    mode: LodMode,
    strategy: StrategyKind,
    /// The plugin's CPU times when the row was taken.
    plugin: PluginTimes,
}

/// The plugin's CPU times in the latest frame, milliseconds (the render world's of the
/// frame rendered last).
#[derive(Clone, Copy, Debug, Default)]
struct PluginTimes {
    sherwood: f32,
    wind: f32,
    extract: f32,
    prepare: f32,
}

/// When the Sherwood sets started this frame, and their span last frame.
#[derive(Resource, Default)]
pub struct SherwoodSpan {
    start: Option<std::time::Instant>,
    ms: f32,
}

/// Before the Sherwood sets: the span starts.
pub fn start_sherwood_span(mut span: ResMut<SherwoodSpan>) {
    span.start = Some(std::time::Instant::now());
}

/// After the Sherwood sets: the span ends.
pub fn end_sherwood_span(mut span: ResMut<SherwoodSpan>) {
    if let Some(start) = span.start.take() {
        span.ms = start.elapsed().as_secs_f32() * 1000.0;
    }
}

impl Row {
    /// The row as the record has it.
    fn record(&self) -> FrameRecord {
        let (d, s) = (&self.diagnostics, &self.sample);
        let (learned, calibrated) = (&d.learned, &d.calibrated);
        let ms = |seconds: f32| seconds * 1000.0;
        FrameRecord {
            frame: self.frame,
            visible: d.visible_instances,
            target_ms: d.target_ms,
            logic_ms: d.logic_ms,
            measured_logic_ms: ms(s.logic),
            render_budget_ms: d.render_budget_ms,
            render_fixed_ms: d.render_fixed_ms,
            predicted_render_ms: d.predicted_render_ms,
            measured_render_ms: ms(s.render),
            predicted_ms: d.predicted_frame_ms,
            measured_ms: ms(s.interval),
            work_ms: ms(s.work_interval()),
            gpu_ms: s.gpu.map(ms),
            waited_ms: ms(s.waited),
            bound: match s.bound() {
                FrameBound::Logic => Bound::Logic,
                FrameBound::RenderCpu => Bound::RenderCpu,
                FrameBound::Gpu => Bound::Gpu,
                FrameBound::Unknown => Bound::Unknown,
            },
            work_target_ms: d.work_target_ms,
            frame_spread: d.frame_spread,
            tail_offset: d.tail_offsets[0],
            rare_offset: d.tail_offsets[1],
            overrun_factor: d.overrun_factor,
            frames_over_share: d.frames_over_share,
            periods: self.periods,
            missed_vblank: u8::from(self.missed_vblank),
            triangles: d.counts.triangles,
            lines: d.counts.lines,
            points: d.counts.points,
            truncated: d.truncated,
            undrawn: d.undrawn,
            held_trees: d.held_trees,
            selection_kept: u8::from(d.selection_kept),
            impostors_drawn: d.impostors_drawn,
            trees_drawn: d.trees_drawn,
            wasted_ms: d.wasted_ms,
            overrun_ms: d.overrun_ms,
            floor_ms: d.floor_ms,
            floor_excess_ms: d.floor_excess_ms,
            pass_ms: self.pass_ms.map(|t| t as f32),
            drawn: self.drawn,
            cal_triangles_ms: ms(calibrated.triangles),
            cal_triangle_pixels_ms: ms(calibrated.triangle_pixels),
            cal_lines_ms: ms(calibrated.lines),
            cal_points_ms: ms(calibrated.points),
            render_speed: learned.render_speed,
            logic_speed: learned.logic_speed,
            triangle_us: learned.triangle_us,
            triangle_pixel_ns: learned.triangle_pixel_ns,
            line_us: learned.line_us,
            point_us: learned.point_us,
            logic_fixed_ms: learned.logic_fixed_ms,
            logic_per_instance_us: learned.logic_per_instance_us,
            sync_ms: ms(learned.overlap.sync),
            serial: learned.overlap.serial,
            cal_meshes_ms: ms(calibrated.meshes),
            mesh_draw_us: learned.mesh_draw_us,
            cal_mesh_pixels_ms: ms(calibrated.mesh_pixels),
            mesh_pixel_ns: learned.mesh_pixel_ns,
            mesh_triangle_ns: learned.mesh_triangle_ns,
            ladder_switches: self.ladders.switches,
            ladder_levels: levels_field(&self.ladders.shown_per_level),
            mode: Mode::name_of(self.mode),
            strategy: Strategy::name_of(self.strategy),
            benefit: d.benefit,
            benefit_bound: d.benefit_bound,
            value_stage_ms: d.value_stage_ms,
            budget_stage_ms: d.budget_stage_ms,
            draw_lists_stage_ms: d.draw_lists_stage_ms,
            sherwood_ms: self.plugin.sherwood,
            wind_ms: self.plugin.wind,
            extract_ms: self.plugin.extract,
            prepare_ms: self.plugin.prepare,
        }
    }
}

/// The run's state.
#[derive(Resource, Default)]
pub struct Run {
    /// Frames since the forest was drawn for the first time.
    pub frame: u32,
    rows: Vec<Row>,
    /// Frames waiting for their measurement: (the cost model's frame number, measured
    /// frame index).
    pending: std::collections::VecDeque<(u64, u32)>,
    /// The LOD stages' figures of recent frames (a frame's arrive in the next frame's
    /// `Update`, its measurement a frame or two later).
    diagnostics: std::collections::VecDeque<LodDiagnostics>,
    pub image: Option<Handle<Image>>,
}

/// `FILE.png` of measured frame `k`, when several are taken: `FILE-k.png`.
fn screenshot_file(file: &Path, k: u32) -> PathBuf {
    let stem = file
        .file_stem()
        .unwrap_or(file.as_os_str())
        .to_string_lossy();
    let name = match file.extension() {
        Some(ext) => format!("{stem}-{k}.{}", ext.to_string_lossy()),
        None => format!("{stem}-{k}"),
    };
    file.with_file_name(name)
}

pub fn measure(
    mut commands: Commands,
    options: Res<Args>,
    mut run: ResMut<Run>,
    samples: Res<FrameSamples>,
    clock: Res<FrameClock>,
    stats: Res<ForestRenderStats>,
    lod: Res<LodDiagnostics>,
    ladders: Res<LadderDiagnostics>,
    (span, wind): (Res<SherwoodSpan>, Res<WindStats>),
    mut budget: ResMut<FrameBudget>,
    mut exit: MessageWriter<AppExit>,
) {
    // Frames count from the first frame the pass really drew the forest (every pipeline
    // ready), whatever the warm-up; until then the forest is drawn by the pixel-driven
    // LOD, and the mode asked for starts with the warm-up.
    let drawn = stats.instances > 0 && samples.arrived().iter().any(|s| s.complete);
    if run.frame == 0 && !drawn {
        return;
    }
    if run.frame == 0 {
        budget.mode = options.mode.lod();
    }
    let run = &mut *run;
    // Each row pairs a frame's selection (its diagnostics) with what was measured of that
    // same frame.
    if run.diagnostics.len() >= 32 {
        run.diagnostics.pop_front();
    }
    run.diagnostics.push_back(lod.clone());
    for sample in samples.arrived() {
        while run.pending.front().is_some_and(|p| p.0 < sample.frame) {
            run.pending.pop_front();
        }
        let diagnostics = run.diagnostics.iter().find(|d| d.frame == sample.frame);
        if let (Some(&(_, frame)), Some(diagnostics)) = (
            run.pending.front().filter(|p| p.0 == sample.frame),
            diagnostics,
        ) {
            let period = options.vsync_hz.map(|hz| 1.0 / hz);
            let periods = period.map_or(0, |p| deadline::periods_taken(sample.interval, p));
            let allowed = period.map_or(u32::MAX, |p| {
                deadline::allowed_periods(diagnostics.target_ms / 1000.0, p)
            });
            run.rows.push(Row {
                frame,
                periods,
                missed_vblank: periods > allowed,
                diagnostics: diagnostics.clone(),
                sample: *sample,
                pass_ms: stats.gpu_time_ms,
                drawn: stats.counts.triangles + stats.counts.lines + stats.counts.points,
                ladders: ladders.clone(),
                mode: budget.mode,
                strategy: budget.strategy,
                plugin: PluginTimes {
                    sherwood: span.ms,
                    wind: wind.update_ms,
                    extract: stats.extract_ms,
                    prepare: stats.prepare_ms,
                },
            });
            run.pending.pop_front();
        }
    }
    let index = run.frame;
    run.frame += 1;
    if index < options.warmup {
        return;
    }
    let measured = index - options.warmup;
    let limit = options.frame_limit();
    let frames = &options.at_frame;
    if let Some(file) = &options.screenshot
        && frames.contains(&measured)
    {
        let target = match &run.image {
            Some(image) => Screenshot::image(image.clone()),
            None => Screenshot::primary_window(),
        };
        let file = if frames.len() > 1 {
            screenshot_file(file, measured)
        } else {
            file.clone()
        };
        commands.spawn(target).observe(save_to_disk(file));
    }
    if limit.is_some_and(|n| measured >= n) {
        // The last frames' measurements are still in the pipeline (and their GPU times
        // behind them): wait for them, a few frames at most.
        if run.pending.is_empty() || limit.is_some_and(|n| measured >= n + 16) {
            exit.write(if finish(&options, &run.rows) {
                AppExit::Success
            } else {
                AppExit::error()
            });
        }
        return;
    }
    run.pending.push_back((clock.frame, measured));
}

/// Writes the record and the summary; false when the record could not be written.
fn finish(options: &Args, rows: &[Row]) -> bool {
    let written = match &options.record {
        Some(file) => {
            let frames: Vec<FrameRecord> = rows.iter().map(Row::record).collect();
            Record::write(file, &frames)
                .map_err(|e| eprintln!("forest: {e}"))
                .is_ok()
        }
        None => true,
    };
    if options.summary {
        let mut line = summary(options.target_ms, rows, options.vsync_hz.is_some());
        if options.meshes > 0 {
            line.push_str(&format!(" levels={}", mean_levels(rows)));
        }
        println!("{line}");
    }
    written
}

/// How long a run with a frame limit waits for its first drawn frame before it gives
/// up, seconds: shaders compile within a few seconds even in a debug build.
const FIRST_FRAME_TIMEOUT_SECS: f32 = 30.0;

/// A run that is to measure frames but never draws the forest (no tree in view, an
/// ecosystem refused, models that failed) would otherwise wait forever: say why and stop.
pub fn give_up_when_nothing_is_drawn(
    options: Res<Args>,
    run: Res<Run>,
    time: Res<Time<Real>>,
    lod: Res<LodDiagnostics>,
    stats: Res<ForestRenderStats>,
    instances: Query<(), With<TreeInstance>>,
    mut exit: MessageWriter<AppExit>,
    mut reported: Local<bool>,
) {
    let measuring = options.path.is_some() || options.frames.is_some();
    // A forest the pass is drawing may take long to its first complete frame (millions
    // of trees in view): it gets ten times as long before the run gives up on it.
    let waited = time.elapsed_secs();
    let patience = if stats.instances > 0 { 10.0 } else { 1.0 } * FIRST_FRAME_TIMEOUT_SECS;
    if !measuring || run.frame > 0 || *reported || waited < patience {
        return;
    }
    let trees = instances.iter().count();
    if stats.instances > 0 {
        eprintln!(
            "forest: no frame completed in {patience} s: the pass draws {} of the {trees} trees, {} in view",
            stats.instances, lod.visible_instances
        );
        *reported = true;
        exit.write(AppExit::error());
        return;
    }
    let why = if trees == 0 {
        "no tree was spawned (see the errors above)".to_owned()
    } else if lod.visible_instances == 0 {
        format!("none of the {trees} trees is in view")
    } else {
        format!(
            "{} of the {trees} trees are in view but the pass drew none (pipelines still compiling?)",
            lod.visible_instances
        )
    };
    eprintln!("forest: nothing was drawn in {FIRST_FRAME_TIMEOUT_SECS} s: {why}");
    *reported = true;
    exit.write(AppExit::error());
}

/// Counts per level as `a/b/c`.
fn levels_field(counts: &[u32]) -> String {
    counts
        .iter()
        .map(u32::to_string)
        .collect::<Vec<_>>()
        .join("/")
}

/// The mean over `rows` of the ladder entities in view showing each level, `a/b/..`.
fn mean_levels(rows: &[Row]) -> String {
    let levels = rows
        .iter()
        .map(|r| r.ladders.shown_per_level.len())
        .max()
        .unwrap_or(0);
    let mut sums = vec![0_u64; levels];
    for r in rows {
        for (sum, &count) in sums.iter_mut().zip(&r.ladders.shown_per_level) {
            *sum += u64::from(count);
        }
    }
    let n = rows.len().max(1) as u64;
    let means: Vec<u32> = sums.iter().map(|&s| ((s + n / 2) / n) as u32).collect();
    levels_field(&means)
}

fn summary(target_ms: f32, rows: &[Row], vsync: bool) -> String {
    let times: Vec<f64> = rows
        .iter()
        .map(|r| f64::from(r.sample.interval * 1000.0))
        .collect();
    let s = FrameStats::of(&times, f64::from(target_ms));
    let line = format!(
        "summary frames={} target_ms={target_ms} mean_ms={:.3} std_ms={:.3} avg_err={:.4} p95_ms={:.3} p99_ms={:.3} over_pct={:.2}",
        s.frames, s.mean, s.std, s.avg_err, s.p95, s.p99, s.over_pct
    );
    if vsync {
        let missed = rows.iter().filter(|r| r.missed_vblank).count();
        let primitives: f64 = rows
            .iter()
            .map(|r| {
                let c = &r.diagnostics.counts;
                (c.triangles + c.lines + c.points) as f64
            })
            .sum();
        let n = rows.len().max(1) as f64;
        format!(
            "{line} missed_vblank_pct={:.2} primitives={:.0}",
            100.0 * missed as f64 / n,
            primitives / n
        )
    } else {
        line
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn several_screenshots_are_numbered_beside_the_file_named() {
        let file = Path::new("/tmp/out dir/shot.png");
        assert_eq!(
            screenshot_file(file, 7),
            Path::new("/tmp/out dir/shot-7.png")
        );
        assert_eq!(screenshot_file(Path::new("shot"), 0), Path::new("shot-0"));
    }

    #[test]
    fn levels_are_written_best_first() {
        assert_eq!(levels_field(&[3, 0, 12]), "3/0/12");
        assert_eq!(levels_field(&[]), "");
    }
}
