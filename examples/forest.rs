//! The forest: an ecosystem drawn with time-critical level of detail, a HUD, and the
//! paper's camera paths with frame-time statistics.
//!
//! ```sh
//! cargo run --release --example forest                       # fly around (WASD + mouse)
//! cargo run --release --example forest -- --path linear --frames 300 --summary
//! cargo run --release --example forest -- --calibrate     # measure this machine's costs
//! cargo run --release --example forest -- --help
//! ```
//!
//! Keys: `W A S D` move, `Q E` down/up, right mouse button + drag to look, `Shift` faster;
//! `+`/`-` raise/lower the target frame time; `M` cycle the mode; `B` cycle the budget
//! strategy; `N` toggle wind; `C` toggle the culling boxes; `H` toggle the HUD.

#[path = "support/frame_stats.rs"]
mod frame_stats;
#[path = "support/quality.rs"]
mod quality;

use std::io::Write;
use std::time::Duration;

use bevy::app::ScheduleRunnerPlugin;
use bevy::camera::RenderTarget;
use bevy::input::mouse::AccumulatedMouseMotion;
use bevy::prelude::*;
use bevy::render::render_resource::{PollType, TextureFormat, TextureUsages};
use bevy::render::renderer::RenderDevice;
use bevy::render::view::screenshot::{Screenshot, save_to_disk};
use bevy::render::{Render, RenderApp, RenderSystems};
use bevy::window::{ExitCondition, PresentMode, WindowResolution};
use bevy::winit::WinitPlugin;
use bevy_sherwood::cost::{
    CalibrationChoice, CostModel, CostSettings, FrameClock, FrameSample, FrameSamples,
};
use bevy_sherwood::draw::Shading;
use bevy_sherwood::ecosystem::{EcosystemDesc, ForestState, ForestTerrain};
use bevy_sherwood::lod::StrategyKind;
use bevy_sherwood::prelude::*;
use bevy_sherwood::render::{
    CalibrationProgress, CalibrationRunPlugin, CalibrationRunSystems, CalibrationSettings,
};
use bevy_sherwood::wind::WindSettings;
use frame_stats::FrameStats;

const USAGE: &str = "\
usage: forest [OPTIONS]

  --ecosystem PATH       ecosystem file under assets/ (default forests/default.ecosystem.ron)
  --trees N              total trees, split across species in the file's proportions
  --seed S               placement seed
  --path linear|zigzag   walk the paper's camera path instead of flying freely
  --path-frames M        stretch or squeeze the path to M frames (linear 1100, zigzag 1700)
  --hold-frame K         hold the camera at the path's frame K: identical frames, to
                         measure this machine's noise floor
  --frames N             exit after N measured frames (default: the path's length)
  --warmup N             frames excluded from statistics (default 60)
  --target-ms T          target frame time in ms (default 100)
  --mode tclod|tc|static|unlimited
  --strategy robin-hood|funkhouser|funkhouser-incremental|triangle-budget
  --value p8|p9|p10|p11
  --no-wind              no wind
  --no-correction        predict with the calibration alone (no online learning)
  --calibration FILE|default
                         predict with this calibration file, or the built-in default
                         costs (default: the one in assets/calibration/ for this adapter)
  --scale-calibration F  multiply every cost and logic time of the calibration by F (to
                         see the online learning correct a calibration that is off)
  --calibrate            measure this machine's rendering and logic costs over the scene
                         and write a calibration, then exit
  --out PATH             where --calibrate writes (default
                         assets/calibration/<adapter>.calibration.ron)
  --width W --height H   window or image size (default 960x540)
  --record FILE.csv      one row per measured frame
  --summary              print one summary line at exit
  --screenshot FILE.png  save a screenshot of measured frame K (with --at-frame K; with
                         several frames, FILE-K.png for each)
  --at-frame K[,K...]    the measured frames to take (default 0)
  --no-hud               start with the HUD hidden (screenshots that compare images)
  --id-colors            draw each tree in its own flat colour on black, terrain hidden:
                         screenshots whose pixels say which tree covers them (decode with
                         the quality example); implies --no-hud
  --headless             render to an image, without a window
  --help                 this text

The record (--record) has one row per measured frame, times in ms:
  frame                  measured frame (0 = the first after the warm-up)
  visible                visible tree instances
  target_ms              the target frame time
  logic_ms, measured_logic_ms
                         the main world's update, predicted and measured
  render_budget_ms       rendering time handed out to the objects
  render_fixed_ms        predicted fixed part of the rendering
  predicted_render_ms, measured_render_ms
                         the render world's time, predicted and measured
  predicted_ms, measured_ms
                         the frame time, predicted and measured (the interval between
                         this frame's end of rendering and the previous frame's)
  triangles, lines, points
                         primitives selected
  truncated, undrawn     objects drawn below their cheapest, objects not drawn
  wasted_ms              rendering time handed out that nobody used
  overrun_ms             predicted rendering beyond the rendering time
  floor_ms, floor_excess_ms
                         every visible object's cheapest representation together, and
                         how far it exceeds the rendering time
  pass_ms                the forest pass's GPU timestamps, when available
  drawn                  primitives the forest pass drew in the frame rendered last
  cal_triangles_ms, cal_triangle_pixels_ms, cal_lines_ms, cal_points_ms
                         the selection's rendering by family as the calibration alone
                         prices it: what the cost model learns from
  render_speed, logic_speed
                         how much slower than its learned costs the machine runs now
  triangle_us, triangle_pixel_ns, line_us, point_us
                         learned costs (per triangle, per triangle pixel, per 1 px line,
                         per 1 px point)
  logic_fixed_ms, logic_per_instance_us
                         learned logic
  sync_ms, serial        learned overlap: frame = max(logic, render) + serial ·
                         min(logic, render) + sync";

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum CameraPath {
    Linear,
    Zigzag,
}

impl CameraPath {
    fn frames(self) -> u32 {
        match self {
            Self::Linear => 1100,
            Self::Zigzag => 1700,
        }
    }
}

#[derive(Resource, Clone, Debug)]
struct Options {
    ecosystem: String,
    trees: Option<u32>,
    seed: Option<u64>,
    path: Option<CameraPath>,
    path_frames: Option<u32>,
    hold_frame: Option<u32>,
    frames: Option<u32>,
    warmup: u32,
    target_ms: f32,
    mode: LodMode,
    strategy: StrategyKind,
    value: ValueFunction,
    wind: bool,
    correction: bool,
    calibration: CalibrationChoice,
    scale_calibration: Option<f32>,
    calibrate: bool,
    out: Option<String>,
    width: u32,
    height: u32,
    record: Option<String>,
    summary: bool,
    /// The file and the measured frames to take it at.
    screenshot: Option<(String, Vec<u32>)>,
    headless: bool,
    hud: bool,
    id_colors: bool,
}

impl Options {
    /// Frames the camera path takes, when walking one.
    fn path_length(&self) -> Option<u32> {
        self.path.map(|p| self.path_frames.unwrap_or(p.frames()))
    }
}

/// `FILE.png` of measured frame `k`, when several are taken: `FILE-k.png`.
fn screenshot_file(file: &str, k: u32) -> String {
    let path = std::path::Path::new(file);
    let stem = path
        .file_stem()
        .map_or_else(|| file.to_owned(), |s| s.to_string_lossy().into_owned());
    let name = match path.extension() {
        Some(ext) => format!("{stem}-{k}.{}", ext.to_string_lossy()),
        None => format!("{stem}-{k}"),
    };
    path.with_file_name(name).to_string_lossy().into_owned()
}

fn parse(args: &[String]) -> Result<Options, String> {
    let mut o = Options {
        ecosystem: "forests/default.ecosystem.ron".into(),
        trees: None,
        seed: None,
        path: None,
        path_frames: None,
        hold_frame: None,
        frames: None,
        warmup: 60,
        target_ms: 100.0,
        mode: LodMode::Tclod,
        strategy: StrategyKind::RobinHood,
        value: ValueFunction::P11,
        wind: true,
        correction: true,
        calibration: CalibrationChoice::Adapter,
        scale_calibration: None,
        calibrate: false,
        out: None,
        width: 960,
        height: 540,
        record: None,
        summary: false,
        screenshot: None,
        headless: false,
        hud: true,
        id_colors: false,
    };
    let mut at_frame = None;
    let mut screenshot = None;
    let mut it = args.iter();
    fn number<T: std::str::FromStr>(flag: &str, v: Option<&String>) -> Result<T, String> {
        let v = v.ok_or_else(|| format!("{flag} needs a value"))?;
        v.parse()
            .map_err(|_| format!("{flag}: `{v}` is not a valid number"))
    }
    while let Some(flag) = it.next() {
        match flag.as_str() {
            "--ecosystem" => o.ecosystem = it.next().ok_or("--ecosystem needs a path")?.clone(),
            "--trees" => o.trees = Some(number("--trees", it.next())?),
            "--seed" => o.seed = Some(number("--seed", it.next())?),
            "--path" => {
                o.path = Some(match it.next().map(String::as_str) {
                    Some("linear") => CameraPath::Linear,
                    Some("zigzag") => CameraPath::Zigzag,
                    other => {
                        return Err(format!("--path: expected linear or zigzag, got {other:?}"));
                    }
                });
            }
            "--path-frames" => o.path_frames = Some(number("--path-frames", it.next())?),
            "--hold-frame" => o.hold_frame = Some(number("--hold-frame", it.next())?),
            "--frames" => o.frames = Some(number("--frames", it.next())?),
            "--warmup" => o.warmup = number("--warmup", it.next())?,
            "--target-ms" => o.target_ms = number("--target-ms", it.next())?,
            "--mode" => {
                o.mode = match it.next().map(String::as_str) {
                    Some("tclod") => LodMode::Tclod,
                    Some("tc") => LodMode::Tc,
                    Some("static") => LodMode::Static,
                    Some("unlimited") => LodMode::Unlimited,
                    other => return Err(format!("--mode: unknown {other:?}")),
                };
            }
            "--strategy" => {
                o.strategy = match it.next().map(String::as_str) {
                    Some("robin-hood") => StrategyKind::RobinHood,
                    Some("funkhouser") => StrategyKind::FunkhouserSequin,
                    Some("funkhouser-incremental") => StrategyKind::FunkhouserIncremental,
                    Some("triangle-budget") => StrategyKind::TriangleBudget,
                    other => return Err(format!("--strategy: unknown {other:?}")),
                };
            }
            "--value" => {
                o.value = match it.next().map(String::as_str) {
                    Some("p8") => ValueFunction::P8,
                    Some("p9") => ValueFunction::P9,
                    Some("p10") => ValueFunction::P10,
                    Some("p11") => ValueFunction::P11,
                    other => return Err(format!("--value: unknown {other:?}")),
                };
            }
            "--no-wind" => o.wind = false,
            "--no-correction" => o.correction = false,
            "--calibration" => {
                o.calibration = match it.next().map(String::as_str) {
                    Some("default") => CalibrationChoice::Keep,
                    Some(file) => CalibrationChoice::File(file.to_owned()),
                    None => return Err("--calibration needs a file or `default`".into()),
                };
            }
            "--scale-calibration" => {
                o.scale_calibration = Some(number("--scale-calibration", it.next())?);
            }
            "--calibrate" => o.calibrate = true,
            "--out" => o.out = Some(it.next().ok_or("--out needs a path")?.clone()),
            "--width" => o.width = number("--width", it.next())?,
            "--height" => o.height = number("--height", it.next())?,
            "--record" => o.record = Some(it.next().ok_or("--record needs a file")?.clone()),
            "--summary" => o.summary = true,
            "--screenshot" => {
                screenshot = Some(it.next().ok_or("--screenshot needs a file")?.clone());
            }
            "--at-frame" => {
                let list = it.next().ok_or("--at-frame needs a frame")?;
                let frames = list
                    .split(',')
                    .map(|k| {
                        k.trim()
                            .parse()
                            .map_err(|_| format!("--at-frame: `{k}` is not a frame number"))
                    })
                    .collect::<Result<Vec<u32>, String>>()?;
                at_frame = Some(frames);
            }
            "--no-hud" => o.hud = false,
            "--id-colors" => {
                o.id_colors = true;
                o.hud = false;
            }
            "--headless" => o.headless = true,
            "--help" | "-h" => return Err(String::new()),
            other => return Err(format!("unknown flag {other}")),
        }
    }
    if !(o.target_ms.is_finite() && o.target_ms > 0.0) {
        return Err("--target-ms must be a positive number".into());
    }
    if o.width == 0 || o.height == 0 {
        return Err("--width and --height must be positive".into());
    }
    if o.out.is_some() && !o.calibrate {
        return Err("--out needs --calibrate".into());
    }
    if o.scale_calibration
        .is_some_and(|f| !(f.is_finite() && f > 0.0))
    {
        return Err("--scale-calibration must be a positive number".into());
    }
    if o.hold_frame.is_some() && o.path.is_none() {
        return Err("--hold-frame needs --path".into());
    }
    if o.trees == Some(0) {
        return Err("--trees must be positive".into());
    }
    if o.frames == Some(0) {
        return Err("--frames must be positive: a run measures at least one frame".into());
    }
    if o.path_frames == Some(0) {
        return Err("--path-frames must be positive".into());
    }
    o.screenshot = match (screenshot, at_frame) {
        (Some(file), Some(frames)) => Some((file, frames)),
        (Some(file), None) => Some((file, vec![0])),
        (None, Some(_)) => return Err("--at-frame needs --screenshot".into()),
        (None, None) => None,
    };
    Ok(o)
}

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
}

/// The run's state.
#[derive(Resource, Default)]
struct Run {
    /// Frames since the forest was drawn for the first time.
    frame: u32,
    rows: Vec<Row>,
    /// Frames waiting for their measurement: (the cost model's frame number, measured
    /// frame index).
    pending: std::collections::VecDeque<(u64, u32)>,
    /// The LOD stages' figures of recent frames (a frame's arrive in the next frame's
    /// `Update`, its measurement a frame or two later).
    diagnostics: std::collections::VecDeque<LodDiagnostics>,
    image: Option<Handle<Image>>,
}

fn main() -> AppExit {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut options = match parse(&args) {
        Ok(o) => o,
        Err(message) => {
            if message.is_empty() {
                println!("{USAGE}");
                return AppExit::Success;
            }
            eprintln!("forest: {message}\n\n{USAGE}");
            return AppExit::error();
        }
    };
    // The record is written at the end: find out now that it cannot be.
    if let Some(file) = &options.record
        && let Err(e) = std::fs::File::create(file)
    {
        eprintln!("forest: --record {file}: {e}");
        return AppExit::error();
    }
    if !options.headless && !has_display() {
        eprintln!(
            "forest: no display (neither DISPLAY nor WAYLAND_DISPLAY is set): rendering headless along the linear path and printing a summary; use xvfb-run for a window"
        );
        options.headless = true;
        options.path.get_or_insert(CameraPath::Linear);
        options.summary = true;
    }
    let mut app = App::new();
    let window = WindowPlugin {
        primary_window: (!options.headless).then(|| Window {
            title: "bevy_sherwood forest".into(),
            resolution: WindowResolution::new(options.width, options.height),
            present_mode: PresentMode::AutoNoVsync,
            ..default()
        }),
        exit_condition: if options.headless {
            ExitCondition::DontExit
        } else {
            ExitCondition::OnAllClosed
        },
        ..default()
    };
    // The ecosystem file is read from the source tree (see `setup`); the species it names
    // must come from the same place however the binary is started.
    let assets = AssetPlugin {
        file_path: concat!(env!("CARGO_MANIFEST_DIR"), "/assets").into(),
        ..default()
    };
    let plugins = DefaultPlugins.set(window).set(assets);
    if options.headless {
        app.add_plugins(plugins.disable::<WinitPlugin>())
            .add_plugins(ScheduleRunnerPlugin::run_loop(Duration::ZERO));
        // Without a swapchain nothing holds the CPU back while the GPU queue grows: wait
        // for each frame's GPU work so that frame times are real.
        app.sub_app_mut(RenderApp)
            .add_systems(Render, wait_for_gpu.in_set(RenderSystems::Cleanup));
    } else {
        app.add_plugins(plugins);
    }
    app.add_plugins((
        SherwoodPlugins,
        ForestHudPlugin,
        bevy::render::diagnostic::RenderDiagnosticsPlugin,
    ))
    .insert_resource(ClearColor(Color::srgb(0.62, 0.76, 0.92)))
    .insert_resource(FrameBudget {
        target_ms: options.target_ms,
        mode: options.mode,
        strategy: options.strategy,
        value: options.value,
        ..default()
    })
    .insert_resource(WindSettings {
        enabled: options.wind,
        ..default()
    })
    .insert_resource(CostSettings {
        calibration: options.calibration.clone(),
        online: options.correction,
        ..default()
    })
    .init_resource::<Run>()
    .add_systems(Startup, setup);
    if options.id_colors {
        app.insert_resource(ClearColor(Color::BLACK))
            .add_systems(Update, (paint_trees_by_id, hide_terrain));
    }
    if options.calibrate {
        app.add_plugins(CalibrationRunPlugin)
            .insert_resource(CalibrationSettings {
                out: options.out.clone().map(Into::into),
                ..default()
            })
            .add_systems(Update, exit_after_calibration.after(CalibrationRunSystems));
    } else {
        app.add_systems(
            Update,
            (
                stop_when_no_species_loads,
                give_up_when_nothing_is_drawn,
                scale_calibration,
                keys,
                fly,
                follow_path,
                measure,
            )
                .chain(),
        );
    }
    app.insert_resource(options).run()
}

/// `--scale-calibration`: once the calibration is installed, the same scaled.
fn scale_calibration(
    options: Res<Options>,
    mut settings: ResMut<CostSettings>,
    mut model: ResMut<CostModel>,
    adapter: Option<Res<bevy_sherwood::cost::AdapterIdentity>>,
    mut done: Local<bool>,
) {
    let Some(factor) = options.scale_calibration else {
        return;
    };
    // The adapter's calibration is installed in `PreUpdate` once the adapter is known.
    if *done || (settings.calibration == CalibrationChoice::Adapter && adapter.is_none()) {
        return;
    }
    let scaled = model.calibration().scaled(factor);
    info!("cost model: calibration scaled by {factor}");
    model.set_calibration(scaled);
    settings.calibration = CalibrationChoice::Keep;
    *done = true;
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

fn setup(
    mut commands: Commands,
    options: Res<Options>,
    mut ecosystems: ResMut<Assets<Ecosystem>>,
    mut images: ResMut<Assets<Image>>,
    mut run: ResMut<Run>,
    mut hud: ResMut<ForestHud>,
    mut exit: MessageWriter<AppExit>,
) {
    let path = format!(
        "{}/assets/{}",
        env!("CARGO_MANIFEST_DIR"),
        options.ecosystem
    );
    let desc = std::fs::read_to_string(&path)
        .map_err(|e| e.to_string())
        .and_then(|text| EcosystemDesc::from_ron_str(&text).map_err(|e| e.to_string()));
    let mut desc = match desc {
        Ok(desc) => desc,
        Err(e) => {
            eprintln!("forest: {path}: {e}");
            exit.write(AppExit::error());
            return;
        }
    };
    if let Some(total) = options.trees {
        desc.set_total_trees(total);
    }
    if let Some(seed) = options.seed {
        desc.seed = seed;
    }
    // Refused now, rather than by the forest's layout later with nothing drawn.
    if let Err(e) = desc.validate() {
        eprintln!("forest: {path}: {e}");
        exit.write(AppExit::error());
        return;
    }
    if desc.instance_count() == 0 {
        eprintln!("forest: {path}: every species has 0 trees: nothing to draw");
        exit.write(AppExit::error());
        return;
    }
    let size = desc.terrain.size;
    commands.spawn(Forest(ecosystems.add(Ecosystem(desc))));
    commands.spawn((
        DirectionalLight {
            illuminance: 9_000.0,
            ..default()
        },
        Transform::from_xyz(4.0, 10.0, 6.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    let mut camera = commands.spawn((
        Camera3d::default(),
        // Multisampling quadruples the rasteriser's work on a software renderer.
        Msaa::Off,
        Transform::from_xyz(-0.1 * size, 25.0, -0.1 * size)
            .looking_at(Vec3::new(size * 0.5, 0.0, size * 0.5), Vec3::Y),
    ));
    if options.headless {
        let mut image = Image::new_target_texture(
            options.width,
            options.height,
            TextureFormat::Rgba8UnormSrgb,
            None,
        );
        image.texture_descriptor.usage |= TextureUsages::COPY_SRC;
        let image = images.add(image);
        camera.insert(RenderTarget::Image(image.clone().into()));
        run.image = Some(image);
    }
    hud.footer =
        "WASD/QE move, right drag look | +/- target  M mode  B strategy  N wind  C boxes  H hud"
            .into();
    hud.visible = options.hud;
}

/// With every species failed there is nothing to draw, and the frame counter (which starts
/// at the first drawn frame) would wait forever: say why and stop.
fn stop_when_no_species_loads(
    forests: Query<&ForestState>,
    server: Res<AssetServer>,
    mut exit: MessageWriter<AppExit>,
    mut reported: Local<bool>,
) {
    if *reported {
        return;
    }
    for state in &forests {
        let failures: Vec<String> = state
            .species
            .iter()
            .filter_map(|species| match server.load_state(species) {
                bevy::asset::LoadState::Failed(e) => Some(e.to_string()),
                _ => None,
            })
            .collect();
        if !state.species.is_empty() && failures.len() == state.species.len() {
            for failure in failures {
                eprintln!("forest: {failure}");
            }
            eprintln!("forest: no species of the ecosystem loaded; nothing to draw");
            *reported = true;
            exit.write(AppExit::error());
        }
    }
}

fn keys(
    input: Res<ButtonInput<KeyCode>>,
    mut budget: ResMut<FrameBudget>,
    mut wind: ResMut<WindSettings>,
    mut boxes: ResMut<CullingDebug>,
    mut hud: ResMut<ForestHud>,
) {
    if input.just_pressed(KeyCode::Equal) || input.just_pressed(KeyCode::NumpadAdd) {
        budget.target_ms *= 1.25;
    }
    if input.just_pressed(KeyCode::Minus) || input.just_pressed(KeyCode::NumpadSubtract) {
        budget.target_ms /= 1.25;
    }
    if input.just_pressed(KeyCode::KeyM) {
        budget.mode = match budget.mode {
            LodMode::Tclod => LodMode::Tc,
            LodMode::Tc => LodMode::Static,
            LodMode::Static => LodMode::Unlimited,
            LodMode::Unlimited => LodMode::Tclod,
        };
    }
    if input.just_pressed(KeyCode::KeyB) {
        budget.strategy = match budget.strategy {
            StrategyKind::RobinHood => StrategyKind::FunkhouserSequin,
            StrategyKind::FunkhouserSequin => StrategyKind::FunkhouserIncremental,
            StrategyKind::FunkhouserIncremental => StrategyKind::TriangleBudget,
            StrategyKind::TriangleBudget => StrategyKind::RobinHood,
        };
        info!("strategy: {:?}", budget.strategy);
    }
    if input.just_pressed(KeyCode::KeyN) {
        wind.enabled = !wind.enabled;
    }
    if input.just_pressed(KeyCode::KeyC) {
        boxes.enabled = !boxes.enabled;
    }
    if input.just_pressed(KeyCode::KeyH) {
        hud.visible = !hud.visible;
    }
}

fn fly(
    options: Res<Options>,
    time: Res<Time<Real>>,
    input: Res<ButtonInput<KeyCode>>,
    mouse: Res<ButtonInput<MouseButton>>,
    motion: Res<AccumulatedMouseMotion>,
    mut camera: Query<&mut Transform, With<Camera3d>>,
) {
    if options.path.is_some() {
        return;
    }
    let Ok(mut transform) = camera.single_mut() else {
        return;
    };
    // Real time, capped: a slow frame must not throw the camera across the forest.
    let dt = time.delta_secs().min(0.1);
    let speed = if input.pressed(KeyCode::ShiftLeft) {
        60.0
    } else {
        15.0
    };
    let mut step = Vec3::ZERO;
    for (key, direction) in [
        (KeyCode::KeyW, transform.forward().as_vec3()),
        (KeyCode::KeyS, -transform.forward().as_vec3()),
        (KeyCode::KeyA, -transform.right().as_vec3()),
        (KeyCode::KeyD, transform.right().as_vec3()),
        (KeyCode::KeyE, Vec3::Y),
        (KeyCode::KeyQ, -Vec3::Y),
    ] {
        if input.pressed(key) {
            step += direction;
        }
    }
    transform.translation += step.normalize_or_zero() * speed * dt;
    if mouse.pressed(MouseButton::Right) && motion.delta != Vec2::ZERO {
        let (yaw, pitch, _) = transform.rotation.to_euler(EulerRot::YXZ);
        let yaw = yaw - motion.delta.x * 0.003;
        let pitch = (pitch - motion.delta.y * 0.003).clamp(-1.5, 1.5);
        transform.rotation = Quat::from_euler(EulerRot::YXZ, yaw, pitch, 0.0);
    }
}

/// Where the path puts the camera at `t` in [0, 1] over a terrain of `size`: position
/// (x, z) and viewing direction (x, z).
fn path_pose(path: CameraPath, t: f32, size: f32) -> (Vec2, Vec2) {
    let t = t.clamp(0.0, 1.0);
    match path {
        // Along the forest's edge, looking in: the view takes in a growing, then a
        // shrinking part of the forest (peak just before half way, as in the paper).
        CameraPath::Linear => {
            let x = size * (-0.55 + 2.0 * t);
            (Vec2::new(x, -0.12 * size), Vec2::new(0.35, 1.0).normalize())
        }
        // Back and forth through the forest in three legs, turning at the edges (at a
        // third and two thirds of the path): complexity jumps at each turn.
        CameraPath::Zigzag => {
            let leg = (t * 3.0).min(2.999_9);
            let i = leg.floor();
            let s = leg - i;
            let z = size * (0.2 + 0.3 * i);
            let (from, to) = if (i as u32).is_multiple_of(2) {
                (0.08, 0.92)
            } else {
                (0.92, 0.08)
            };
            let x = size * (from + (to - from) * s);
            let heading = Vec2::new((to - from).signum(), 0.25).normalize();
            (Vec2::new(x, z), heading)
        }
    }
}

/// `--id-colors`: every tree in its own flat colour (ambient only, no light), the colour
/// of [`quality::id_color`] of its index in the instance table.
/// A tree painted by [`paint_trees_by_id`].
#[derive(Component)]
struct PaintedById;

fn paint_trees_by_id(
    mut commands: Commands,
    table: Res<ForestInstances>,
    painted: Query<(), With<PaintedById>>,
) {
    for (i, &entity) in table.entities.iter().enumerate() {
        if painted.contains(entity) {
            continue;
        }
        let color = quality::id_color(i as u32);
        let flat = Shading {
            ambient: Vec3::from(quality::linear(color)),
            diffuse: Vec3::ZERO,
            specular: Vec3::ZERO,
            shininess: 1.0,
        };
        commands.entity(entity).insert((
            TreeShading {
                trunk: flat,
                leaves: flat,
            },
            PaintedById,
        ));
    }
}

fn hide_terrain(mut terrain: Query<&mut Visibility, With<ForestTerrain>>) {
    for mut visibility in &mut terrain {
        *visibility = Visibility::Hidden;
    }
}

fn follow_path(
    options: Res<Options>,
    run: Res<Run>,
    terrain: Query<&ForestTerrain>,
    mut camera: Query<&mut Transform, With<Camera3d>>,
) {
    let (Some(path), Ok(mut transform), Ok(terrain)) =
        (options.path, camera.single_mut(), terrain.single())
    else {
        return;
    };
    let size = terrain.terrain.size();
    let frames = options.path_length().unwrap_or(path.frames()).max(2);
    let measured = options
        .hold_frame
        .unwrap_or(run.frame.saturating_sub(options.warmup));
    let t = measured as f32 / (frames - 1) as f32;
    let (at, heading) = path_pose(path, t, size);
    let ground = terrain
        .terrain
        .height_at(at.x.clamp(0.0, size), at.y.clamp(0.0, size));
    let eye = Vec3::new(at.x, ground + 12.0, at.y);
    let target = eye + Vec3::new(heading.x, -0.12, heading.y);
    *transform = Transform::from_translation(eye).looking_at(target, Vec3::Y);
}

fn measure(
    mut commands: Commands,
    options: Res<Options>,
    mut run: ResMut<Run>,
    samples: Res<FrameSamples>,
    clock: Res<FrameClock>,
    stats: Res<ForestRenderStats>,
    lod: Res<LodDiagnostics>,
    mut exit: MessageWriter<AppExit>,
) {
    // Frames count from the first frame the pass really drew the forest (every pipeline
    // ready), whatever the warm-up.
    let drawn = stats.instances > 0 && samples.arrived().iter().any(|s| s.complete);
    if run.frame == 0 && !drawn {
        return;
    }
    let run = &mut *run;
    // Each row pairs a frame's selection (its diagnostics) with what was measured of that
    // same frame.
    if run.diagnostics.len() >= 16 {
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
            run.rows.push(Row {
                frame,
                diagnostics: diagnostics.clone(),
                sample: *sample,
                pass_ms: stats.gpu_time_ms,
                drawn: stats.counts.triangles + stats.counts.lines + stats.counts.points,
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
    let limit = options.frames.or(options.path_length());
    if let Some((file, frames)) = &options.screenshot
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
        // The last frames' measurements are still in the pipeline: wait for them (a
        // few frames at most).
        if run.pending.is_empty() || limit.is_some_and(|n| measured >= n + 8) {
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
fn finish(options: &Options, rows: &[Row]) -> bool {
    let written = match &options.record {
        Some(file) => write_csv(file, rows)
            .map_err(|e| eprintln!("forest: {file}: {e}"))
            .is_ok(),
        None => true,
    };
    if options.summary {
        println!("{}", summary(options.target_ms, rows));
    }
    written
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

/// How long a run with a frame limit waits for its first drawn frame before it gives
/// up, seconds: shaders compile within a few seconds even in a debug build.
const FIRST_FRAME_TIMEOUT_SECS: f32 = 30.0;

/// A run that is to measure frames but never draws the forest (no tree in view, an
/// ecosystem refused, models that failed) would otherwise wait forever: say why and stop.
fn give_up_when_nothing_is_drawn(
    options: Res<Options>,
    run: Res<Run>,
    time: Res<Time<Real>>,
    lod: Res<LodDiagnostics>,
    stats: Res<ForestRenderStats>,
    instances: Query<(), With<TreeInstance>>,
    mut exit: MessageWriter<AppExit>,
    mut reported: Local<bool>,
) {
    let measuring = options.path.is_some() || options.frames.is_some();
    if !measuring || run.frame > 0 || *reported || time.elapsed_secs() < FIRST_FRAME_TIMEOUT_SECS {
        return;
    }
    let trees = instances.iter().count();
    let why = if trees == 0 {
        "no tree was spawned (see the errors above)".to_owned()
    } else if lod.visible_instances == 0 {
        format!("none of the {trees} trees is in view")
    } else {
        format!(
            "{} of the {trees} trees are in view but the pass drew {} (pipelines still compiling?)",
            lod.visible_instances, stats.instances
        )
    };
    eprintln!("forest: nothing was drawn in {FIRST_FRAME_TIMEOUT_SECS} s: {why}");
    *reported = true;
    exit.write(AppExit::error());
}

/// The record's columns: name and how a row writes it.
const COLUMNS: &[(&str, fn(&Row) -> String)] = &[
    ("frame", |r| r.frame.to_string()),
    ("visible", |r| r.diagnostics.visible_instances.to_string()),
    ("target_ms", |r| ms(r.diagnostics.target_ms)),
    ("logic_ms", |r| ms(r.diagnostics.logic_ms)),
    ("measured_logic_ms", |r| ms(r.sample.logic * 1000.0)),
    ("render_budget_ms", |r| ms(r.diagnostics.render_budget_ms)),
    ("render_fixed_ms", |r| ms(r.diagnostics.render_fixed_ms)),
    ("predicted_render_ms", |r| {
        ms(r.diagnostics.predicted_render_ms)
    }),
    ("measured_render_ms", |r| ms(r.sample.render * 1000.0)),
    ("predicted_ms", |r| ms(r.diagnostics.predicted_frame_ms)),
    ("measured_ms", |r| ms(r.sample.interval * 1000.0)),
    ("triangles", |r| r.diagnostics.counts.triangles.to_string()),
    ("lines", |r| r.diagnostics.counts.lines.to_string()),
    ("points", |r| r.diagnostics.counts.points.to_string()),
    ("truncated", |r| r.diagnostics.truncated.to_string()),
    ("undrawn", |r| r.diagnostics.undrawn.to_string()),
    ("wasted_ms", |r| ms(r.diagnostics.wasted_ms)),
    ("overrun_ms", |r| ms(r.diagnostics.overrun_ms)),
    ("floor_ms", |r| ms(r.diagnostics.floor_ms)),
    ("floor_excess_ms", |r| ms(r.diagnostics.floor_excess_ms)),
    ("pass_ms", |r| {
        r.pass_ms.map_or(String::new(), |t| ms(t as f32))
    }),
    ("drawn", |r| r.drawn.to_string()),
    ("cal_triangles_ms", |r| {
        ms(r.diagnostics.calibrated.triangles * 1000.0)
    }),
    ("cal_triangle_pixels_ms", |r| {
        ms(r.diagnostics.calibrated.triangle_pixels * 1000.0)
    }),
    ("cal_lines_ms", |r| {
        ms(r.diagnostics.calibrated.lines * 1000.0)
    }),
    ("cal_points_ms", |r| {
        ms(r.diagnostics.calibrated.points * 1000.0)
    }),
    ("render_speed", |r| {
        ratio(r.diagnostics.learned.render_speed)
    }),
    ("logic_speed", |r| ratio(r.diagnostics.learned.logic_speed)),
    ("triangle_us", |r| ratio(r.diagnostics.learned.triangle_us)),
    ("triangle_pixel_ns", |r| {
        ratio(r.diagnostics.learned.triangle_pixel_ns)
    }),
    ("line_us", |r| ratio(r.diagnostics.learned.line_us)),
    ("point_us", |r| ratio(r.diagnostics.learned.point_us)),
    ("logic_fixed_ms", |r| {
        ms(r.diagnostics.learned.logic_fixed_ms)
    }),
    ("logic_per_instance_us", |r| {
        ratio(r.diagnostics.learned.logic_per_instance_us)
    }),
    ("sync_ms", |r| {
        ms(r.diagnostics.learned.overlap.sync * 1000.0)
    }),
    ("serial", |r| ratio(r.diagnostics.learned.overlap.serial)),
];

fn ms(value: f32) -> String {
    format!("{value:.4}")
}

fn ratio(value: f32) -> String {
    format!("{value:.5}")
}

fn write_csv(file: &str, rows: &[Row]) -> std::io::Result<()> {
    let mut out = std::io::BufWriter::new(std::fs::File::create(file)?);
    let header: Vec<&str> = COLUMNS.iter().map(|c| c.0).collect();
    writeln!(out, "{}", header.join(","))?;
    for r in rows {
        let cells: Vec<String> = COLUMNS.iter().map(|c| (c.1)(r)).collect();
        writeln!(out, "{}", cells.join(","))?;
    }
    out.flush()
}

fn summary(target_ms: f32, rows: &[Row]) -> String {
    let times: Vec<f64> = rows
        .iter()
        .map(|r| f64::from(r.sample.interval * 1000.0))
        .collect();
    let s = FrameStats::of(&times, f64::from(target_ms));
    format!(
        "summary frames={} target_ms={target_ms} mean_ms={:.3} std_ms={:.3} avg_err={:.4} p95_ms={:.3} p99_ms={:.3} over_pct={:.2}",
        s.frames, s.mean, s.std, s.avg_err, s.p95, s.p99, s.over_pct
    )
}
