//! The frame record: one row per measured frame, written by `forest --record` and read
//! back by every tool that reports on runs (results, cost report, cost replay, the large
//! forest). One type, serialised with serde through the `csv` crate, so a column a writer
//! adds is a field every reader sees, and a record that does not match is refused with
//! its file and line.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

/// What paced a frame (the cost model's [`FrameBound`](bevy_sherwood::cost::FrameBound)).
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum Bound {
    /// The main world's logic.
    Logic,
    /// The render world's CPU work.
    RenderCpu,
    /// The GPU.
    Gpu,
    /// Not known (no GPU timestamps).
    #[serde(rename = "")]
    Unknown,
}

/// One measured frame. Times in milliseconds.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
pub struct FrameRecord {
    /// Measured frame (0 = the first after the warm-up).
    pub frame: u32,
    /// Visible tree instances.
    pub visible: u32,
    /// The target frame time.
    pub target_ms: f32,
    /// The main world's update, predicted.
    pub logic_ms: f32,
    /// The main world's update, measured.
    pub measured_logic_ms: f32,
    /// Rendering time handed out to the objects.
    pub render_budget_ms: f32,
    /// Predicted fixed part of the rendering.
    pub render_fixed_ms: f32,
    /// The render world's time, predicted.
    pub predicted_render_ms: f32,
    /// The render world's time, measured.
    pub measured_render_ms: f32,
    /// The frame time, predicted.
    pub predicted_ms: f32,
    /// The frame time, measured: the interval between this frame's end of rendering and
    /// the previous frame's (what the player sees, waits for the display included).
    pub measured_ms: f32,
    /// The frame's work: its frame time less the render world's waits for the display.
    pub work_ms: f32,
    /// The whole frame's GPU time from timestamps, when available.
    pub gpu_ms: Option<f32>,
    /// The render world's waits (next swapchain image, vsync, pacer).
    pub waited_ms: f32,
    /// What paced the frame.
    pub bound: Bound,
    /// What the frame's work was aimed at (under vsync the last vertical blank within
    /// the target, less the learned margin).
    pub work_target_ms: f32,
    /// The learned scatter of frame times (std of the log ratio).
    pub frame_spread: f32,
    /// How far the tail goal's quantile was calibrated, as a log factor.
    pub tail_offset: f32,
    /// How far the rare bound's quantile was calibrated, as a log factor.
    pub rare_offset: f32,
    /// The factor the overrun cut put on the aim (1: none; `--overrun-cut`).
    #[serde(default = "no_cut")]
    pub overrun_factor: f32,
    /// Share of the last second's measured frames over the goal's limit.
    pub frames_over_share: f32,
    /// With `--vsync-hz`: refresh periods the frame took (0 without).
    pub periods: u32,
    /// 1 when the frame took more periods than its target allows.
    pub missed_vblank: u8,
    /// Triangles selected.
    pub triangles: u64,
    /// Lines selected.
    pub lines: u64,
    /// Points selected.
    pub points: u64,
    /// Objects drawn below their cheapest representation.
    pub truncated: u32,
    /// Objects not drawn.
    pub undrawn: u32,
    /// Far trees keeping their last decision (`--far-refresh`).
    pub held_trees: u32,
    /// 1 when the frame kept last frame's selection (a still scene,
    /// `FrameBudget::steady`).
    pub selection_kept: u8,
    /// Group impostors drawn (hierarchical strategy).
    pub impostors_drawn: u32,
    /// Visible trees drawn on their own (not by a group).
    pub trees_drawn: u32,
    /// Rendering time handed out that nobody used.
    pub wasted_ms: f32,
    /// Predicted rendering beyond the rendering time.
    pub overrun_ms: f32,
    /// Every visible object's cheapest representation together.
    pub floor_ms: f32,
    /// How far the floor exceeds the rendering time.
    pub floor_excess_ms: f32,
    /// The forest pass's GPU timestamps, when available.
    pub pass_ms: Option<f32>,
    /// Primitives the forest pass drew in the frame rendered last.
    pub drawn: u64,
    /// The selection's triangles as the calibration alone prices them.
    pub cal_triangles_ms: f32,
    /// The selection's triangle pixels as the calibration alone prices them.
    pub cal_triangle_pixels_ms: f32,
    /// The selection's lines as the calibration alone prices them.
    pub cal_lines_ms: f32,
    /// The selection's points as the calibration alone prices them.
    pub cal_points_ms: f32,
    /// How much slower than its learned costs the machine renders now.
    pub render_speed: f32,
    /// How much slower than its learned costs the machine runs the logic now.
    pub logic_speed: f32,
    /// Learned cost per triangle, µs.
    pub triangle_us: f32,
    /// Learned cost per triangle pixel, ns.
    pub triangle_pixel_ns: f32,
    /// Learned cost per 1 px line, µs.
    pub line_us: f32,
    /// Learned cost per 1 px point, µs.
    pub point_us: f32,
    /// Learned fixed logic.
    pub logic_fixed_ms: f32,
    /// Learned logic per instance, µs.
    pub logic_per_instance_us: f32,
    /// Learned overlap: frame = max(logic, render) + serial · min(logic, render) + sync.
    pub sync_ms: f32,
    /// Learned overlap's serial share.
    pub serial: f32,
    /// The meshes on Bevy's path as the calibration prices them, per draw and triangle.
    pub cal_meshes_ms: f32,
    /// Learned cost of a draw on Bevy's mesh path, µs.
    pub mesh_draw_us: f32,
    /// The meshes' pixels as the calibration prices them.
    pub cal_mesh_pixels_ms: f32,
    /// Learned cost of a mesh pixel, ns.
    pub mesh_pixel_ns: f32,
    /// Learned cost of a mesh triangle, ns.
    pub mesh_triangle_ns: f32,
    /// Ladder entities whose shown level changed in the frame.
    pub ladder_switches: u32,
    /// Ladder entities in view showing each level, best first, as `a/b/..`.
    pub ladder_levels: String,
    /// The frame's mode, as on the command line.
    pub mode: String,
    /// The frame's strategy, as on the command line.
    pub strategy: String,
    /// With `--benefit`: the selection's benefit (0 without).
    pub benefit: f32,
    /// With `--benefit`: the best any selection could reach within the rendering time.
    pub benefit_bound: f32,
    /// The value stage's time.
    pub value_stage_ms: f32,
    /// The budget stage's time.
    pub budget_stage_ms: f32,
    /// The draw-list stage's time.
    pub draw_lists_stage_ms: f32,
    /// The Sherwood sets' span in `PostUpdate` (from the instance table to the stats;
    /// whatever the executor ran in between counts too), milliseconds.
    #[serde(default)]
    pub sherwood_ms: f32,
    /// The wind's per-instance work (`WindStats::update_ms`).
    #[serde(default)]
    pub wind_ms: f32,
    /// The forest's extraction into the render world (`ForestRenderStats::extract_ms`).
    #[serde(default)]
    pub extract_ms: f32,
    /// Preparing the forest's GPU buffers (`ForestRenderStats::prepare_ms`).
    #[serde(default)]
    pub prepare_ms: f32,
}

/// A record read back: its frames in order.
pub struct Record {
    /// One per measured frame.
    pub frames: Vec<FrameRecord>,
}

impl Record {
    /// Reads `csv`; a row that does not parse is an error naming the file, its line and
    /// the field.
    pub fn read(csv: &Path) -> Result<Self, String> {
        let mut reader =
            csv::Reader::from_path(csv).map_err(|e| format!("{}: {e}", csv.display()))?;
        let frames = reader
            .deserialize()
            .collect::<Result<Vec<FrameRecord>, _>>()
            .map_err(|e| format!("{}: {e}", csv.display()))?;
        Ok(Self { frames })
    }

    /// Writes `frames` to `csv`, a header first.
    pub fn write(csv: &Path, frames: &[FrameRecord]) -> Result<(), String> {
        let fail = |e: csv::Error| format!("{}: {e}", csv.display());
        let mut writer = csv::Writer::from_path(csv).map_err(fail)?;
        for frame in frames {
            writer.serialize(frame).map_err(fail)?;
        }
        writer
            .flush()
            .map_err(|e| format!("{}: {e}", csv.display()))
    }

    /// One value per frame, as `f64` (the statistics' type).
    pub fn column(&self, field: impl Fn(&FrameRecord) -> f32) -> Vec<f64> {
        self.frames.iter().map(|r| f64::from(field(r))).collect()
    }
}

/// The `*.csv` files of `dir`, sorted.
pub fn csv_files(dir: &Path) -> Result<Vec<PathBuf>, String> {
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| format!("{}: {e}", dir.display()))?
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == "csv"))
        .collect();
    paths.sort();
    Ok(paths)
}

/// Records written before the overrun cut had none.
fn no_cut() -> f32 {
    1.0
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A record of `n` frames whose measured time is `10 + frame` ms.
    pub(crate) fn frames(n: u32) -> Vec<FrameRecord> {
        (0..n)
            .map(|frame| FrameRecord {
                frame,
                visible: 100,
                target_ms: 50.0,
                logic_ms: 5.0,
                measured_logic_ms: 5.5,
                render_budget_ms: 40.0,
                render_fixed_ms: 1.0,
                predicted_render_ms: 39.0,
                measured_render_ms: 41.0,
                predicted_ms: 48.0,
                measured_ms: 10.0 + frame as f32,
                work_ms: 47.0,
                gpu_ms: None,
                waited_ms: 0.0,
                bound: Bound::Unknown,
                work_target_ms: 50.0,
                frame_spread: 0.05,
                tail_offset: 0.0,
                rare_offset: 0.0,
                overrun_factor: 1.0,
                frames_over_share: 0.0,
                periods: 0,
                missed_vblank: 0,
                triangles: 1000,
                lines: 10,
                points: 20,
                truncated: 0,
                undrawn: 0,
                held_trees: 0,
                selection_kept: 0,
                impostors_drawn: 0,
                trees_drawn: 100,
                wasted_ms: 0.1,
                overrun_ms: 0.0,
                floor_ms: 2.0,
                floor_excess_ms: 0.0,
                pass_ms: Some(3.25),
                drawn: 1030,
                cal_triangles_ms: 1.0,
                cal_triangle_pixels_ms: 2.0,
                cal_lines_ms: 3.0,
                cal_points_ms: 4.0,
                render_speed: 1.0,
                logic_speed: 1.0,
                triangle_us: 0.16,
                triangle_pixel_ns: 1.5,
                line_us: 0.3,
                point_us: 0.68,
                logic_fixed_ms: 1.0,
                logic_per_instance_us: 2.0,
                sync_ms: 0.5,
                serial: 0.1,
                cal_meshes_ms: 0.0,
                mesh_draw_us: 10.0,
                cal_mesh_pixels_ms: 0.0,
                mesh_pixel_ns: 1.0,
                mesh_triangle_ns: 1.0,
                ladder_switches: 0,
                ladder_levels: "3/1".into(),
                mode: "tclod".into(),
                strategy: "robin-hood".into(),
                benefit: 0.0,
                benefit_bound: 0.0,
                value_stage_ms: 0.2,
                budget_stage_ms: 0.3,
                draw_lists_stage_ms: 0.1,
                sherwood_ms: 1.0,
                wind_ms: 0.1,
                extract_ms: 0.2,
                prepare_ms: 0.1,
            })
            .collect()
    }

    fn temp(name: &str) -> PathBuf {
        std::env::temp_dir().join(format!("sherwood-lab-{}-{name}", std::process::id()))
    }

    #[test]
    fn a_record_reads_back_what_was_written() {
        let file = temp("round-trip.csv");
        let written = frames(3);
        Record::write(&file, &written).unwrap();
        let read = Record::read(&file).unwrap();
        assert_eq!(read.frames, written);
        assert_eq!(read.column(|r| r.measured_ms), vec![10.0, 11.0, 12.0]);
        // A missing GPU time is an empty cell, an unknown bound too.
        let text = std::fs::read_to_string(&file).unwrap();
        assert!(
            text.lines()
                .next()
                .unwrap()
                .starts_with("frame,visible,target_ms,")
        );
        std::fs::remove_file(file).unwrap();
    }

    #[test]
    fn a_malformed_record_names_its_file_and_line() {
        let file = temp("malformed.csv");
        Record::write(&file, &frames(2)).unwrap();
        let text = std::fs::read_to_string(&file).unwrap();
        let broken = text.replacen("\n1,100,", "\n1,many,", 1);
        assert_ne!(broken, text);
        std::fs::write(&file, broken).unwrap();
        let e = Record::read(&file).err().unwrap();
        assert!(e.contains("malformed.csv"), "{e}");
        assert!(e.contains("line: 3") || e.contains("line 3"), "{e}");
        std::fs::remove_file(file).unwrap();
    }
}
