//! `sherwood-lab`: `bevy_sherwood`'s measurement harness, one binary with a subcommand per
//! tool. The examples in `examples/` are what an app author copies; this is what measures
//! them: the forest along the paper's camera paths with its frame record, the machine's
//! calibration, screenshots, image quality, the results and cost reports, the render
//! pass's benchmark, long soak runs and the user's app under an emulated vsync.
//!
//! ```sh
//! cargo run --release -p sherwood-lab -- forest --path linear --summary
//! cargo run --release -p sherwood-lab -- forest --calibrate
//! cargo run --release -p sherwood-lab -- help
//! ```
//!
//! Paths on the command line are ordinary file paths (relative to the working directory,
//! or absolute); where a tool also reads the crate's assets (`--ecosystem`,
//! `--calibration`), a path that names no file is looked up under `assets/`.

use std::process::ExitCode;

use bevy::app::AppExit;
use clap::{Parser, Subcommand};

mod assets;
mod baseline;
mod cost_replay;
mod cost_report;
mod forest;
mod frame_stats;
mod gallery;
mod goals;
mod id_colors;
mod large_forest;
mod pass_benchmark;
mod quality;
mod record;
mod results;
mod soak;
mod tree_info;
mod user_app;
mod wind_gust;

/// `bevy_sherwood`'s measurement harness.
#[derive(Parser, Debug)]
#[command(name = "sherwood-lab", version, about)]
struct Cli {
    #[command(subcommand)]
    tool: Tool,
}

#[derive(Subcommand, Debug)]
enum Tool {
    /// The forest with time-critical LOD: the paper's camera paths, a frame record,
    /// screenshots, the machine's calibration.
    Forest(Box<forest::Args>),
    /// `docs/results.md` and its plots from the runs of `scripts/reproduce.sh` (or the
    /// large-forest report with `--large`).
    Results(results::Args),
    /// `docs/goals.md` from the runs of `scripts/goals.sh`: the tail goal beside the mean
    /// goal and fixed headrooms.
    Goals(goals::Args),
    /// `docs/cost-model.md` from the runs of `scripts/learning.sh`.
    CostReport(cost_report::Args),
    /// Replays a frame record through the cost model offline.
    CostReplay(cost_replay::Args),
    /// Image quality of a LOD frame against the full-detail one (SSIM, per-tree
    /// coverage), contact sheets and SSIM maps.
    Quality(quality::Args),
    /// The forest render pass against Bevy's mesh path, and the cost per primitive.
    PassBenchmark(pass_benchmark::Args),
    /// What the analysis makes of a tree file.
    TreeInfo(tree_info::Args),
    /// A long headless run: memory and learned costs over hours of spawning and moving.
    Soak(soak::Args),
    /// The forest tool's headless Bevy app without Sherwood: the memory figures' baseline.
    Baseline(baseline::Args),
    /// The app of `examples/minimal.rs` as a user writes it, measured as the player sees
    /// it (the main loop's period, missed vertical blanks).
    UserApp(user_app::Args),
    /// A gust through the forest as a contact sheet (`docs/wind-gust.png`).
    WindGust(wind_gust::Args),
    /// Every shipped species at full detail, one PNG each (the docs' pictures).
    Gallery(gallery::Args),
}

fn main() -> ExitCode {
    match Cli::parse().tool {
        Tool::Forest(args) => exit_code(forest::run(*args)),
        Tool::Results(args) => results::run(args),
        Tool::Goals(args) => goals::run(args),
        Tool::CostReport(args) => cost_report::run(args),
        Tool::CostReplay(args) => cost_replay::run(args),
        Tool::Quality(args) => quality::run(args),
        Tool::PassBenchmark(args) => pass_benchmark::run(args),
        Tool::TreeInfo(args) => tree_info::run(args),
        Tool::Soak(args) => exit_code(soak::run(args)),
        Tool::Baseline(args) => exit_code(baseline::run(args)),
        Tool::UserApp(args) => exit_code(user_app::run(args)),
        Tool::WindGust(args) => exit_code(wind_gust::run(args)),
        Tool::Gallery(args) => exit_code(gallery::run(args)),
    }
}

/// A Bevy app's exit as the process's.
fn exit_code(exit: AppExit) -> ExitCode {
    match exit {
        AppExit::Success => ExitCode::SUCCESS,
        AppExit::Error(code) => ExitCode::from(code.get()),
    }
}

/// A tool's error as the process's: the message on stderr, status 1.
fn report(tool: &str, result: Result<(), String>) -> ExitCode {
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("{tool}: {e}");
            ExitCode::FAILURE
        }
    }
}

#[cfg(test)]
mod tests {
    use clap::CommandFactory;

    use super::*;

    #[test]
    fn the_command_line_is_consistent() {
        // Clap's own checks: no two flags share a name, every `requires` names a flag.
        Cli::command().debug_assert();
    }

    #[test]
    fn an_unknown_tool_is_refused() {
        let e = Cli::try_parse_from(["sherwood-lab", "forests"]).unwrap_err();
        assert_eq!(e.kind(), clap::error::ErrorKind::InvalidSubcommand);
    }
}
