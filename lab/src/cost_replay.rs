//! Replays a forest record (`--record`) through the cost model offline: each frame's
//! selection (its rendering priced by the calibration, family by family, and its visible
//! trees) is predicted, and what was measured of it is learned two frames later, as with
//! pipelined rendering. Prints the prediction error, so learning rates can be compared on
//! the same recorded frames without rendering them again.
//!
//! ```sh
//! cargo run --release -p sherwood-lab -- cost-replay RECORD.csv [--calibration FILE]
//!     [--scale F] [--speed-seconds S] [--costs-seconds S] [--twin UNLIMITED.csv]
//! ```
//!
//! `--twin` names the unlimited run of the same path: the error is then also given on
//! the binding frames (the twin took more than 1.2 × the target).

use std::collections::VecDeque;
use std::path::PathBuf;
use std::process::ExitCode;

use bevy_sherwood::cost::{
    Calibration, CostModel, FamilyTimes, FrameOverlap, FramePrediction, FrameSample, LearningRates,
};

use crate::record::Record;

/// The cost replay's command line.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The forest tool's record to replay.
    record: PathBuf,
    /// The calibration to start from (a path, or one under `assets/`; default: the
    /// shipped lavapipe calibration, or the built-in costs when it is missing).
    #[arg(long)]
    calibration: Option<PathBuf>,
    /// Multiply the calibration by F.
    #[arg(long, default_value_t = 1.0)]
    scale: f32,
    /// The learning's speed time constant, s.
    #[arg(long)]
    speed_seconds: Option<f32>,
    /// The learning's costs time constant, s.
    #[arg(long)]
    costs_seconds: Option<f32>,
    /// The unlimited run of the same path: the error is also given on its binding frames.
    #[arg(long)]
    twin: Option<PathBuf>,
}

/// Runs the cost replay.
pub fn run(args: Args) -> ExitCode {
    crate::report("cost-replay", replay(args))
}

fn replay(args: Args) -> Result<(), String> {
    let calibration = match &args.calibration {
        Some(file) => crate::assets::read_calibration(file)?,
        None => crate::assets::read_calibration(
            "calibration/llvmpipe-llvm-15-0-6-256-bits.calibration.ron".as_ref(),
        )
        .unwrap_or_else(|_| Calibration::default()),
    };
    let scale = args.scale;
    let mut rates = LearningRates::default();
    if let Some(s) = args.speed_seconds {
        rates.speed_seconds = s;
    }
    if let Some(s) = args.costs_seconds {
        rates.costs_seconds = s;
    }
    let twin = match &args.twin {
        Some(file) => Some(Record::read(file)?.column(|r| r.measured_ms)),
        None => None,
    };
    let r = Record::read(&args.record)?;
    let col = |field: fn(&crate::record::FrameRecord) -> f32| r.column(field);
    let (visible, target) = (col(|r| r.visible as f32), col(|r| r.target_ms));
    let (logic, render, interval) = (
        col(|r| r.measured_logic_ms),
        col(|r| r.measured_render_ms),
        col(|r| r.measured_ms),
    );
    let family = [
        col(|r| r.cal_triangles_ms),
        col(|r| r.cal_triangle_pixels_ms),
        col(|r| r.cal_lines_ms),
        col(|r| r.cal_points_ms),
        col(|r| r.cal_meshes_ms),
        col(|r| r.cal_mesh_pixels_ms),
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
