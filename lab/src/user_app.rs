//! A measurement harness: the app of `minimal.rs` as a user writes it (Bevy's default
//! plugins and present mode, the default forest through the asset server), with the camera
//! held still, measured as the player sees it: the main loop's period (`Time<Real>`), the
//! primitives drawn, and with `--vsync-hz` the vertical blanks missed. A window needs a
//! display: run it under `xvfb-run -a`, which has no vertical blank (hence the emulation).
//!
//! ```sh
//! xvfb-run -a cargo run --release -p sherwood-lab -- user-app --vsync-hz 20 --target-ms 45
//! ```
//!
//! Its assets are the crate's (`assets/`), however the binary is started. Prints one
//! `user_app ...` line; it reports the frames over 1.1 × target among the 20 after each
//! event (`--step-ms`, `--spawn-spheres`).

use bevy::prelude::*;
use bevy::window::WindowResolution;
use bevy_sherwood::cost::CostModel;
use bevy_sherwood::display as deadline;
use bevy_sherwood::prelude::*;

use crate::forest::{Mode, busy_for, positive};

/// The user-app harness's command line.
#[derive(clap::Args, Resource, Clone, Debug)]
pub struct Args {
    /// Emulate a display refreshing H times a second (default: none).
    #[arg(long, value_name = "H", value_parser = positive, allow_negative_numbers = true)]
    vsync_hz: Option<f32>,
    /// Target frame time, ms.
    #[arg(long, default_value_t = 50.0, value_parser = positive, allow_negative_numbers = true)]
    target_ms: f32,
    /// The level-of-detail mode.
    #[arg(long, value_enum, default_value_t = Mode::Tclod)]
    mode: Mode,
    /// Measured frames.
    #[arg(long, default_value_t = 300, value_parser = at_least_one)]
    frames: usize,
    /// Frames before the measurement.
    #[arg(long, default_value_t = 100)]
    warmup: usize,
    /// Window width.
    #[arg(long, default_value_t = 960, value_parser = clap::value_parser!(u32).range(1..))]
    width: u32,
    /// Window height.
    #[arg(long, default_value_t = 540, value_parser = clap::value_parser!(u32).range(1..))]
    height: u32,
    /// The camera's multisampling: 1, 2, 4 or 8 samples (Bevy's default: 4).
    #[arg(long, default_value_t = 4, value_parser = msaa_samples)]
    msaa: u32,
    /// The 40 glTF rocks with `_LOD` levels of the `gltf_props` example in front of the
    /// forest.
    #[arg(long)]
    props: bool,
    /// Game logic (a busy `Update` system) of S ms from a third of the measured frames to
    /// two thirds.
    #[arg(long, default_value_t = 0.0)]
    step_ms: f32,
    /// N PBR spheres spawned in front of the camera a third of the way through.
    #[arg(long, default_value_t = 0)]
    spawn_spheres: u32,
    /// A line per frame around each event (the period, this frame's prediction, the
    /// latest measured frame's logic, render and prediction).
    #[arg(long)]
    trace: bool,
}

fn at_least_one(text: &str) -> Result<usize, String> {
    match text.parse::<usize>() {
        Ok(n) if n > 0 => Ok(n),
        _ => Err(format!("{text:?} is not a positive whole number")),
    }
}

fn msaa_samples(text: &str) -> Result<u32, String> {
    match text.parse::<u32>() {
        Ok(n @ (1 | 2 | 4 | 8)) => Ok(n),
        _ => Err(format!("{text:?}: the samples are 1, 2, 4 or 8")),
    }
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
    /// Sums of the predicted frame and of the app's own meshes' predicted rendering, ms.
    predicted: f32,
    app_meshes: f32,
    missed: usize,
}

/// Runs the user-app harness.
pub fn run(options: Args) -> AppExit {
    let window = Window {
        resolution: WindowResolution::new(options.width, options.height),
        ..default()
    };
    let mut app = App::new();
    app.add_plugins((
        DefaultPlugins
            .set(WindowPlugin {
                primary_window: Some(window),
                ..default()
            })
            .set(AssetPlugin {
                file_path: crate::assets::root().to_string_lossy().into_owned(),
                ..default()
            }),
        SherwoodPlugins,
    ))
    .insert_resource(FrameBudget {
        target_ms: options.target_ms,
        mode: options.mode.lod(),
        ..default()
    })
    .insert_resource(WindSettings {
        enabled: false,
        ..default()
    })
    .init_resource::<Measured>()
    .add_systems(Startup, setup)
    .add_systems(Update, (game_logic, spawn_spheres))
    .add_systems(Last, measure);
    if let Some(refresh_hz) = options.vsync_hz {
        app.add_plugins(EmulatedVsyncPlugin { refresh_hz });
    }
    app.insert_resource(options).run()
}

fn setup(mut commands: Commands, server: Res<AssetServer>, options: Res<Args>) {
    commands.spawn(Forest(server.load("forests/default.ecosystem.ron")));
    if options.props {
        commands.spawn((
            WorldAssetRoot(server.load(GltfAssetLabel::Scene(0).from_asset("props/rocks.glb"))),
            LadderFromLodNames,
            Transform::from_xyz(8.0, 0.5, 8.0),
        ));
    }
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

/// The measured frames at which the events start and (the logic step) end.
fn events(options: &Args) -> (usize, usize) {
    (options.frames / 3, 2 * options.frames / 3)
}

fn game_logic(options: Res<Args>, measured: Res<Measured>) {
    let (start, end) = events(&options);
    let frame = measured.periods.len();
    if options.step_ms > 0.0 && (start..end).contains(&frame) {
        busy_for(options.step_ms);
    }
}

fn spawn_spheres(
    mut commands: Commands,
    options: Res<Args>,
    measured: Res<Measured>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    mut done: Local<bool>,
) {
    if *done || options.spawn_spheres == 0 || measured.periods.len() != events(&options).0 {
        return;
    }
    *done = true;
    let mesh = meshes.add(Sphere::new(0.5).mesh().uv(64, 32));
    let material = materials.add(Color::srgb(0.8, 0.3, 0.2));
    for k in 0..options.spawn_spheres {
        let at = Vec3::new(
            -2.0 + 2.5 * (k % 5) as f32,
            8.0 + 2.5 * (k / 5 % 4) as f32,
            4.0 + 3.0 * (k / 20) as f32,
        );
        commands.spawn((
            Mesh3d(mesh.clone()),
            MeshMaterial3d(material.clone()),
            Transform::from_translation(at),
        ));
    }
}

fn measure(
    options: Res<Args>,
    time: Res<Time<Real>>,
    lod: Res<LodDiagnostics>,
    model: Res<CostModel>,
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
    let k = measured.periods.len();
    let (start, end) = events(&options);
    if options.trace
        && (start.saturating_sub(3)..start + 20)
            .chain(end.saturating_sub(3)..end + 20)
            .any(|e| e + 1 == k)
    {
        println!(
            "trace frame={} period_ms={:.1} predicted_ms={:.1} logic_so_far_ms={:.1} app_meshes_ms={:.1} measured_frame={} measured_ms={:.1} measured_logic_ms={:.1} measured_render_ms={:.1} measured_predicted_ms={:.1}",
            k - 1,
            period * 1000.0,
            lod.predicted_frame_ms,
            lod.logic_so_far_ms,
            lod.app_meshes_ms,
            lod.measured_frame,
            lod.measured_frame_ms,
            lod.measured_logic_ms,
            lod.measured_render_ms,
            lod.measured_frame_predicted_ms,
        );
    }
    measured.primitives.push(c.triangles + c.lines + c.points);
    measured.logic += lod.measured_logic_ms;
    measured.render += lod.measured_render_ms;
    measured.floor += lod.floor_ms;
    measured.predicted += lod.predicted_frame_ms;
    measured.app_meshes += lod.app_meshes_ms;
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
    let swing = {
        let sd = measured
            .primitives
            .iter()
            .map(|&p| (p as f64 - primitives).powi(2))
            .sum::<f64>()
            / n;
        sd.sqrt() / primitives.max(1.0)
    };
    let (start, end) = events(&options);
    let over_after = |from: usize| {
        ms.iter()
            .skip(from)
            .take(20)
            .filter(|&&t| t > 1.1 * f64::from(options.target_ms))
            .count()
    };
    println!(
        "user_app vsync_hz={} target_ms={} frames={} mean_ms={mean:.2} std_over_mean={:.4} over_1.1_pct={:.2} missed_vblank_pct={:.2} primitives={primitives:.0} spread={:.4} work_target_ms={:.2} logic_ms={:.2} render_ms={:.2} floor_ms={:.2} primitives_swing={swing:.4} over_after_start={} over_after_end={} predicted_ms={:.2} app_meshes_ms={:.2} mesh_pixel_ns={:.1}",
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
        over_after(start),
        over_after(end),
        measured.predicted / n as f32,
        measured.app_meshes / n as f32,
        model.learned().mesh_pixel_ns,
    );
    exit.write(AppExit::Success);
}
