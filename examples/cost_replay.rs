//! Replays a forest record (`--record`) through the cost model offline: each frame's
//! selection (its rendering priced by the calibration, family by family, and its visible
//! trees) is predicted, and what was measured of it is learned two frames later, as with
//! pipelined rendering. Prints the prediction error, so learning rates can be compared on
//! the same recorded frames without rendering them again.
//!
//! ```sh
//! cargo run --release --example cost_replay -- RECORD.csv [--calibration FILE]
//!     [--scale F] [--speed-seconds S] [--costs-seconds S] [--twin UNLIMITED.csv]
//! ```
//!
//! `--twin` names the unlimited run of the same path: the error is then also given on
//! the binding frames (the twin took more than 1.2 × the target).

use std::collections::VecDeque;
use std::path::Path;

use bevy_sherwood::cost::{
    Calibration, CostModel, FamilyTimes, FrameOverlap, FramePrediction, FrameSample, LearningRates,
};
use sherwood_lab::record::Record;

const USAGE: &str = "usage: cost_replay RECORD.csv [--calibration FILE] [--scale F] \
[--speed-seconds S] [--costs-seconds S] [--twin UNLIMITED.csv]";

fn main() {
    if let Err(e) = run() {
        eprintln!("cost_replay: {e}\n{USAGE}");
        std::process::exit(1);
    }
}

fn run() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut it = args.iter();
    let record = it.next().ok_or("no record")?;
    let mut calibration = read_calibration_file(Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/assets/calibration/llvmpipe-llvm-15-0-6-256-bits.calibration.ron"
    )))
    .unwrap_or_else(|_| Calibration::default());
    let (mut scale, mut rates, mut twin) = (1.0_f32, LearningRates::default(), None);
    while let Some(flag) = it.next() {
        let mut value = || it.next().ok_or(format!("{flag} needs a value"));
        let number = |v: &String| v.parse::<f32>().map_err(|e| format!("{flag}: {e}"));
        match flag.as_str() {
            "--calibration" => calibration = read_calibration_file(Path::new(value()?))?,
            "--scale" => scale = number(value()?)?,
            "--speed-seconds" => rates.speed_seconds = number(value()?)?,
            "--costs-seconds" => rates.costs_seconds = number(value()?)?,
            "--twin" => twin = Some(Record::read(Path::new(value()?))?.column("measured_ms")?),
            other => return Err(format!("unknown flag {other}")),
        }
    }
    let r = Record::read(Path::new(record))?;
    let col = |name| r.column(name);
    let (visible, target) = (col("visible")?, col("target_ms")?);
    let (logic, render, interval) = (
        col("measured_logic_ms")?,
        col("measured_render_ms")?,
        col("measured_ms")?,
    );
    let family = [
        col("cal_triangles_ms")?,
        col("cal_triangle_pixels_ms")?,
        col("cal_lines_ms")?,
        col("cal_points_ms")?,
        // Records of scenes without ladder entities have no mesh column.
        col("cal_meshes_ms").unwrap_or_else(|_| vec![0.0; visible.len()]),
        col("cal_mesh_pixels_ms").unwrap_or_else(|_| vec![0.0; visible.len()]),
    ];
    let mut model = CostModel::new(calibration.scaled(scale), FrameOverlap::PIPELINED, rates);
    let mut arriving = VecDeque::new();
    let mut errors = Vec::new();
    for i in 0..visible.len() {
        let calibrated = FamilyTimes {
            triangles: family[0][i] as f32 / 1000.0,
            triangle_pixels: family[1][i] as f32 / 1000.0,
            lines: family[2][i] as f32 / 1000.0,
            points: family[3][i] as f32 / 1000.0,
            meshes: family[4][i] as f32 / 1000.0,
            mesh_pixels: family[5][i] as f32 / 1000.0,
        };
        // A record has no logic measured at the budget: the whole logic is predicted.
        let logic_time = model.logic_after_budget(visible[i] as u32);
        let render_time = model.render_time(&calibrated);
        let frame_time = model.overlap().frame_time(logic_time, render_time);
        model.record(FramePrediction {
            frame: i as u64,
            visible_instances: visible[i] as u32,
            calibrated,
            logic: logic_time,
            logic_so_far: 0.0,
            render: render_time,
            frame_time,
        });
        errors.push((frame_time as f64 * 1000.0 - interval[i]).abs() / interval[i]);
        arriving.push_back(FrameSample {
            frame: i as u64,
            logic: logic[i] as f32 / 1000.0,
            render: render[i] as f32 / 1000.0,
            interval: interval[i] as f32 / 1000.0,
            complete: true,
            ..Default::default()
        });
        if arriving.len() > 2
            && let Some(sample) = arriving.pop_front()
        {
            model.learn(&sample);
        }
    }
    let mean = |which: &[usize]| {
        100.0 * which.iter().map(|&i| errors[i]).sum::<f64>() / which.len().max(1) as f64
    };
    let after: Vec<usize> = (60..errors.len()).collect();
    print!(
        "prediction error {:.2}% over {} frames from 60",
        mean(&after),
        after.len()
    );
    if let Some(twin) = twin {
        let binding: Vec<usize> = after
            .iter()
            .copied()
            .filter(|&i| twin.get(i).is_some_and(|&t| t > 1.2 * target[i]))
            .collect();
        print!(
            ", {:.2}% over {} binding frames",
            mean(&binding),
            binding.len()
        );
    }
    println!();
    println!("learned: {:?}", model.learned());
    Ok(())
}

fn read_calibration_file(path: &Path) -> Result<Calibration, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    Calibration::from_ron_str(&text).map_err(|e| format!("{}: {e}", path.display()))
}
