//! A measurement harness: the app of `minimal.rs` as a user writes it (Bevy's default
//! plugins and present mode, the default forest through the asset server), with the camera
//! held still, measured as the player sees it: the main loop's period (`Time<Real>`), the
//! primitives drawn, and with `--vsync-hz` the vertical blanks missed. A window needs a
//! display: run it under `xvfb-run -a`, which has no vertical blank (hence the emulation).
//!
//! ```sh
//! xvfb-run -a cargo run --release --example user_app -- --vsync-hz 20 --target-ms 45
//! ```
//!
//! Started without cargo, it needs `BEVY_ASSET_ROOT` set to the crate's directory (Bevy
//! looks for `assets/` there).
//!
//! Flags: `--vsync-hz H` (emulate a display refreshing H times a second; default none),
//! `--target-ms T` (default 50), `--mode tclod|tc|static|unlimited` (default tclod),
//! `--frames N` measured frames (default 300), `--warmup N` (default 100), `--width W`
//! `--height H` (default 960×540), `--msaa 1|2|4|8` (default 4, Bevy's). Prints one
//! `user_app ...` line.

use bevy::prelude::*;
use bevy::window::WindowResolution;
use bevy_sherwood::budget::deadline;
use bevy_sherwood::prelude::*;

#[derive(Resource, Clone, Debug)]
struct Options {
    vsync_hz: Option<f32>,
    target_ms: f32,
    mode: LodMode,
    frames: usize,
    warmup: usize,
    width: u32,
    height: u32,
    /// `--msaa N`: the camera's multisampling (Bevy's default: 4).
    msaa: u32,
}

fn parse(args: &[String]) -> Result<Options, String> {
    let mut o = Options {
        vsync_hz: None,
        target_ms: 50.0,
        mode: LodMode::Tclod,
        frames: 300,
        warmup: 100,
        width: 960,
        height: 540,
        msaa: 4,
    };
    let mut it = args.iter();
    while let Some(flag) = it.next() {
        let mut value = || it.next().ok_or(format!("{flag} needs a value"));
        let number = |v: &String| v.parse::<f32>().map_err(|_| format!("{flag}: `{v}`"));
        match flag.as_str() {
            "--vsync-hz" => o.vsync_hz = Some(number(value()?)?),
            "--target-ms" => o.target_ms = number(value()?)?,
            "--frames" => o.frames = number(value()?)? as usize,
            "--warmup" => o.warmup = number(value()?)? as usize,
            "--width" => o.width = number(value()?)? as u32,
            "--height" => o.height = number(value()?)? as u32,
            "--msaa" => o.msaa = number(value()?)? as u32,
            "--mode" => {
                o.mode = match value()?.as_str() {
                    "tclod" => LodMode::Tclod,
                    "tc" => LodMode::Tc,
                    "static" => LodMode::Static,
                    "unlimited" => LodMode::Unlimited,
                    other => return Err(format!("--mode: unknown {other}")),
                }
            }
            other => return Err(format!("unknown flag {other}")),
        }
    }
    if o.vsync_hz.is_some_and(|hz| !(hz > 0.0 && hz.is_finite())) || o.target_ms <= 0.0 {
        return Err("--vsync-hz and --target-ms must be positive".into());
    }
    Ok(o)
}

/// What each measured frame looked like to the player.
#[derive(Resource, Default)]
struct Measured {
    updates: usize,
    periods: Vec<f32>,
    primitives: Vec<u64>,
    /// Sums of the measured logic, render work and floor, ms.
    logic: f32,
    render: f32,
    floor: f32,
    missed: usize,
}

fn main() -> AppExit {
    let options = match parse(&std::env::args().skip(1).collect::<Vec<_>>()) {
        Ok(o) => o,
        Err(e) => {
            eprintln!("user_app: {e}");
            return AppExit::error();
        }
    };
    let window = Window {
        resolution: WindowResolution::new(options.width, options.height),
        ..default()
    };
    let mut app = App::new();
    app.add_plugins((
        DefaultPlugins.set(WindowPlugin {
            primary_window: Some(window),
            ..default()
        }),
        SherwoodPlugins,
    ))
    .insert_resource(FrameBudget {
        target_ms: options.target_ms,
        mode: options.mode,
        ..default()
    })
    .insert_resource(WindSettings {
        enabled: false,
        ..default()
    })
    .init_resource::<Measured>()
    .add_systems(Startup, setup)
    .add_systems(Last, measure);
    if let Some(refresh_hz) = options.vsync_hz {
        app.add_plugins(EmulatedVsyncPlugin { refresh_hz });
    }
    app.insert_resource(options).run()
}

fn setup(mut commands: Commands, server: Res<AssetServer>, options: Res<Options>) {
    commands.spawn(Forest(server.load("forests/default.ecosystem.ron")));
    let msaa = match options.msaa {
        1 => Msaa::Off,
        2 => Msaa::Sample2,
        8 => Msaa::Sample8,
        _ => Msaa::Sample4,
    };
    commands.spawn((
        Camera3d::default(),
        msaa,
        Transform::from_xyz(-10.0, 12.0, -10.0).looking_at(Vec3::new(60.0, 0.0, 60.0), Vec3::Y),
    ));
    commands.spawn((
        DirectionalLight::default(),
        Transform::from_xyz(1.0, 3.0, 2.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
}

fn measure(
    options: Res<Options>,
    time: Res<Time<Real>>,
    lod: Res<LodDiagnostics>,
    stats: Res<ForestRenderStats>,
    mut measured: ResMut<Measured>,
    mut exit: MessageWriter<AppExit>,
) {
    // Frames count once the pass draws the forest (pipelines compiled, trees loaded).
    if stats.instances == 0 && measured.updates == 0 {
        if time.elapsed_secs() > 60.0 {
            eprintln!("user_app: nothing drawn in 60 s (are the assets found? BEVY_ASSET_ROOT)");
            exit.write(AppExit::error());
        }
        return;
    }
    measured.updates += 1;
    if measured.updates <= options.warmup {
        return;
    }
    let period = time.delta_secs();
    let c = lod.counts;
    measured.periods.push(period);
    measured.primitives.push(c.triangles + c.lines + c.points);
    measured.logic += lod.measured_logic_ms;
    measured.render += lod.measured_render_ms;
    measured.floor += lod.floor_ms;
    if let Some(hz) = options.vsync_hz {
        let p = 1.0 / hz;
        let allowed = deadline::allowed_periods(options.target_ms / 1000.0, p);
        if deadline::periods_taken(period, p) > allowed {
            measured.missed += 1;
        }
    }
    if measured.periods.len() < options.frames {
        return;
    }
    let n = measured.periods.len() as f64;
    let ms: Vec<f64> = measured
        .periods
        .iter()
        .map(|&p| f64::from(p) * 1000.0)
        .collect();
    let mean = ms.iter().sum::<f64>() / n;
    let std = (ms.iter().map(|t| (t - mean).powi(2)).sum::<f64>() / n).sqrt();
    let over = ms
        .iter()
        .filter(|&&t| t > 1.1 * f64::from(options.target_ms))
        .count();
    let primitives = measured.primitives.iter().sum::<u64>() as f64 / n;
    println!(
        "user_app vsync_hz={} target_ms={} frames={} mean_ms={mean:.2} std_over_mean={:.4} over_1.1_pct={:.2} missed_vblank_pct={:.2} primitives={primitives:.0} spread={:.4} work_target_ms={:.2} logic_ms={:.2} render_ms={:.2} floor_ms={:.2}",
        options.vsync_hz.unwrap_or(0.0),
        options.target_ms,
        ms.len(),
        std / mean,
        100.0 * over as f64 / n,
        100.0 * measured.missed as f64 / n,
        lod.frame_spread,
        lod.work_target_ms,
        measured.logic / n as f32,
        measured.render / n as f32,
        measured.floor / n as f32,
    );
    exit.write(AppExit::Success);
}
