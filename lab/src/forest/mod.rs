//! The forest tool: an ecosystem drawn with time-critical level of detail, a HUD, the
//! paper's camera paths with a frame record and a summary, screenshots, and the
//! machine's calibration run.

use std::time::Duration;

use bevy::app::ScheduleRunnerPlugin;
use bevy::camera_controller::free_camera::FreeCameraPlugin;
use bevy::prelude::*;
use bevy::render::render_resource::PollType;
use bevy::render::renderer::RenderDevice;
use bevy::render::{Render, RenderApp, RenderSystems};
use bevy::window::{ExitCondition, PresentMode, WindowResolution};
use bevy::winit::WinitPlugin;
use bevy_sherwood::cost::{CostSettings, LearningRates};
use bevy_sherwood::lod::BenefitReport;
use bevy_sherwood::prelude::*;
use bevy_sherwood::render::{
    CalibrationProgress, CalibrationRunPlugin, CalibrationRunSystems, CalibrationSettings,
};
use bevy_sherwood::wind::WindSettings;

mod args;
mod camera;
mod measure;
mod scene;

use args::CameraPath;
pub use args::{Args, Mode, positive};
use measure::Run;

/// Runs the forest tool.
pub fn run(mut args: Args) -> AppExit {
    // The record is written at the end: find out now that it cannot be.
    if let Some(file) = &args.record
        && let Err(e) = std::fs::File::create(file)
    {
        eprintln!("forest: --record {}: {e}", file.display());
        return AppExit::error();
    }
    if !args.headless && !has_display() {
        eprintln!(
            "forest: no display (neither DISPLAY nor WAYLAND_DISPLAY is set): rendering headless along the linear path and printing a summary; use xvfb-run for a window"
        );
        args.headless = true;
        args.path.get_or_insert(CameraPath::Linear);
        args.summary = true;
    }
    let mut app = App::new();
    add_bevy(&mut app, &args);
    app.add_plugins((
        SherwoodPlugins,
        ForestHudPlugin,
        bevy::render::diagnostic::RenderDiagnosticsPlugin,
    ))
    .insert_resource(ClearColor(Color::srgb(0.62, 0.76, 0.92)))
    .insert_resource(FrameBudget {
        target_ms: args.target_ms * args.headroom,
        // The pixel-driven LOD until the pass has drawn the forest once (see `measure`):
        // a strategy that drops every object at a tight target would otherwise never
        // draw, and its pipelines would compile in the middle of the measured frames.
        // (Full detail drew every primitive kind too, but its first frames of a
        // 100 000-tree forest took 20 s.)
        mode: LodMode::Static,
        goal: args.goal.frame_goal(),
        strategy: args.strategy.kind(),
        value: args.value.function(),
        far_refresh: args.far_refresh,
        steady: args.steady(),
        overrun_cut: OverrunCut {
            after_frames: args.overrun_cut,
        },
        ..default()
    })
    .insert_resource(BenefitReport {
        enabled: args.benefit,
    })
    .insert_resource(LadderSettings {
        fade_frames: args.fade_frames,
        ..default()
    })
    .insert_resource(WindSettings {
        enabled: !args.no_wind,
        shared_sway_pixels: if args.own_sway {
            0.0
        } else {
            WindSettings::default().shared_sway_pixels
        },
        full_rate_pixels: if args.wind_every_frame {
            0.0
        } else {
            WindSettings::default().full_rate_pixels
        },
        ..default()
    })
    .insert_resource(CostSettings {
        calibration: args.calibration_choice(),
        online: !args.no_correction,
        rates: LearningRates {
            speed_seconds: args
                .speed_seconds
                .unwrap_or(LearningRates::default().speed_seconds),
            ..default()
        },
    })
    .init_resource::<Run>()
    .add_systems(Startup, scene::setup);
    if args.fixed_step {
        app.insert_resource(bevy::time::TimeUpdateStrategy::ManualDuration(
            Duration::from_secs(1) / 60,
        ));
    }
    if let Some(refresh_hz) = args.vsync_hz {
        app.add_plugins(EmulatedVsyncPlugin { refresh_hz });
    }
    if args.id_colors {
        app.insert_resource(ClearColor(Color::BLACK))
            .add_systems(Update, (scene::paint_trees_by_id, scene::hide_terrain));
    }
    if args.path.is_none() {
        app.add_plugins(FreeCameraPlugin);
    }
    if args.calibrate {
        app.add_plugins(CalibrationRunPlugin)
            .insert_resource(CalibrationSettings {
                out: args.out.clone(),
                ..default()
            })
            .add_systems(Update, exit_after_calibration.after(CalibrationRunSystems));
    } else {
        app.add_systems(
            Update,
            (
                scene::stop_when_no_species_loads,
                measure::give_up_when_nothing_is_drawn,
                scene::install_calibration,
                scene::place_boulders,
                camera::follow_path,
                measure::measure,
                app_hitch,
            )
                .chain(),
        )
        .init_resource::<measure::SherwoodSpan>()
        .add_systems(
            PostUpdate,
            (
                measure::start_sherwood_span.before(SherwoodSystems::Instances),
                measure::end_sherwood_span.after(SherwoodSystems::Stats),
            ),
        );
    }
    app.insert_resource(args).run()
}

/// The app's own logic hitching (`--hitch-ms`): busy for that long every
/// `--hitch-every` frames.
fn app_hitch(args: Res<Args>, mut frame: Local<u32>) {
    *frame += 1;
    let Some(ms) = args.hitch_ms else {
        return;
    };
    if (*frame).is_multiple_of(args.hitch_every) {
        busy_for(ms);
    }
}

/// Keeps this thread busy for `ms` milliseconds: the app's own logic, as a game's
/// systems take time (a sleep would leave the core to the render world).
pub fn busy_for(ms: f32) {
    let begun = std::time::Instant::now();
    while begun.elapsed().as_secs_f32() * 1000.0 < ms {
        std::hint::spin_loop();
    }
}

/// Bevy's default plugins: a window (presenting without vsync unless one is emulated:
/// then with Bevy's default), or none and a loop that waits for the GPU each frame.
fn add_bevy(app: &mut App, args: &Args) {
    if args.headless {
        add_headless_bevy(app);
        return;
    }
    let window = WindowPlugin {
        primary_window: Some(Window {
            title: "bevy_sherwood forest".into(),
            resolution: WindowResolution::new(args.width, args.height),
            present_mode: if args.vsync_hz.is_some() {
                PresentMode::AutoVsync
            } else {
                PresentMode::AutoNoVsync
            },
            ..default()
        }),
        exit_condition: ExitCondition::OnAllClosed,
        ..default()
    };
    app.add_plugins(DefaultPlugins.set(window).set(asset_plugin()));
}

/// Bevy's default plugins without a window, and a loop that waits for the GPU each frame
/// (the forest tool's `--headless`, and the `baseline` tool).
pub(crate) fn add_headless_bevy(app: &mut App) {
    let window = WindowPlugin {
        primary_window: None,
        exit_condition: ExitCondition::DontExit,
        ..default()
    };
    let plugins = DefaultPlugins.set(window).set(asset_plugin());
    app.add_plugins(plugins.disable::<WinitPlugin>())
        .add_plugins(ScheduleRunnerPlugin::run_loop(Duration::ZERO));
    // Without a swapchain nothing holds the CPU back while the GPU queue grows: wait
    // for each frame's GPU work so that frame times are real. In the `Render` set, so
    // the wait is measured as the frame's work (which it is: the GPU's).
    app.sub_app_mut(RenderApp).add_systems(
        Render,
        wait_for_gpu
            .in_set(RenderSystems::Render)
            .after(bevy::render::renderer::render_system),
    );
}

/// The crate's assets, wherever the tool runs from.
fn asset_plugin() -> AssetPlugin {
    AssetPlugin {
        file_path: crate::assets::root().to_string_lossy().into_owned(),
        ..default()
    }
}

fn exit_after_calibration(progress: Res<CalibrationProgress>, mut exit: MessageWriter<AppExit>) {
    match &progress.outcome {
        Some(Ok(_)) => {
            exit.write(AppExit::Success);
        }
        Some(Err(e)) => {
            eprintln!("forest: calibration failed: {e}");
            exit.write(AppExit::error());
        }
        None => {}
    }
}

fn wait_for_gpu(device: Res<RenderDevice>) {
    let _ = device.poll(PollType::wait_indefinitely());
}

/// Whether a window can open: on Linux and the BSDs, an X or Wayland display is named.
fn has_display() -> bool {
    if cfg!(any(
        target_os = "linux",
        target_os = "freebsd",
        target_os = "openbsd"
    )) {
        std::env::var_os("DISPLAY").is_some() || std::env::var_os("WAYLAND_DISPLAY").is_some()
    } else {
        true
    }
}
