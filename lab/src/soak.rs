//! A measurement harness: a long headless run of what an app does over hours — a moving
//! camera, wind, trees spawned and despawned every 100 frames, the strategy changed every
//! 5 000 frames — printing every 1 000 frames the process's resident memory and what the
//! cost model has learned, to show that neither drifts. `scripts/soak.sh` runs it.
//!
//! ```sh
//! cargo run --release -p sherwood-lab -- soak --frames 100000 --trees 100 --target-ms 10
//! ```
//!
//! `--spawn-every 0` plants nothing (to tell what the spawn cycles cost from the rest).
//!
//! Prints `soak frame=… rss_mb=… …` lines and a last `soak done …` line.

use bevy::camera::RenderTarget;
use bevy::prelude::*;
use bevy::render::render_resource::{PollType, TextureFormat};
use bevy::render::renderer::RenderDevice;
use bevy::render::{Render, RenderApp, RenderSystems};
use bevy_sherwood::cost::CostModel;
use bevy_sherwood::ecosystem::EcosystemDesc;
use bevy_sherwood::prelude::*;
use bevy_sherwood::testing as windowless;

/// Frames between spawning a few trees and despawning the ones spawned before, by
/// default (`--spawn-every`).
const SPAWN_EVERY: u64 = 100;
/// Frames between strategy changes.
const STRATEGY_EVERY: u64 = 5_000;
/// Frames between report lines.
const REPORT_EVERY: u64 = 1_000;
/// The strategies (and modes) taken in turn.
const STRATEGIES: [(LodMode, StrategyKind); 5] = [
    (LodMode::Tclod, StrategyKind::RobinHood),
    (LodMode::Tclod, StrategyKind::FunkhouserSequin),
    (LodMode::Tc, StrategyKind::RobinHood),
    (LodMode::Tclod, StrategyKind::Hierarchical),
    (LodMode::Tclod, StrategyKind::TriangleBudget),
];

/// The soak run's command line.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Frames to run.
    #[arg(long, default_value_t = 100_000)]
    frames: u64,
    /// Trees of the default ecosystem.
    #[arg(long, default_value_t = 100, value_parser = clap::value_parser!(u32).range(1..))]
    trees: u32,
    /// Target frame time, ms.
    #[arg(long, default_value_t = 10.0)]
    target_ms: f32,
    /// Frames between plantings; 0: never (to tell what the spawn cycles cost).
    #[arg(long, default_value_t = SPAWN_EVERY)]
    spawn_every: u64,
}

/// The hand-planted trees of the last spawn, and the camera.
#[derive(Resource, Default)]
struct Soak {
    planted: Vec<Entity>,
    size: f32,
    spawn_every: u64,
}

/// Runs the soak.
pub fn run(options: Args) -> AppExit {
    let mut app = App::new();
    app.add_plugins((
        windowless::windowless_plugins(
            DefaultPlugins.build().disable::<bevy::winit::WinitPlugin>(),
        ),
        SherwoodPlugins,
    ))
    .insert_resource(FrameBudget {
        target_ms: options.target_ms,
        ..default()
    })
    .init_resource::<Soak>();
    // Nothing else holds the CPU back while the GPU's queue grows: wait for each frame.
    app.sub_app_mut(RenderApp).add_systems(
        Render,
        wait_for_gpu
            .in_set(RenderSystems::Render)
            .after(bevy::render::renderer::render_system),
    );
    windowless::finish_plugins(&mut app);
    app.world_mut().resource_mut::<Soak>().spawn_every = options.spawn_every;
    if let Err(e) = setup(app.world_mut(), options.trees) {
        eprintln!("soak: {e}");
        return AppExit::error();
    }
    let start = std::time::Instant::now();
    for frame in 1..=options.frames {
        step(app.world_mut(), frame);
        app.update();
        if frame.is_multiple_of(REPORT_EVERY) {
            report(app.world(), frame, start.elapsed().as_secs_f32());
        }
    }
    println!(
        "soak done frames={} seconds={:.0}",
        options.frames,
        start.elapsed().as_secs_f32()
    );
    AppExit::Success
}

fn wait_for_gpu(device: Res<RenderDevice>) {
    let _ = device.poll(PollType::wait_indefinitely());
}

fn setup(world: &mut World, trees: u32) -> Result<(), String> {
    let path = crate::assets::root().join("forests/default.ecosystem.ron");
    let path = path.display();
    let text = std::fs::read_to_string(path.to_string()).map_err(|e| format!("{path}: {e}"))?;
    let mut desc = EcosystemDesc::from_ron_str(&text).map_err(|e| format!("{path}: {e}"))?;
    let species = desc.species.len() as u32;
    let all: u32 = desc.species.iter().map(|s| s.count).sum();
    for s in &mut desc.species {
        s.count = trees.div_ceil(species);
    }
    desc.terrain.size *= (trees as f32 / all.max(1) as f32).sqrt();
    world.resource_mut::<Soak>().size = desc.terrain.size;
    let ecosystem = world
        .resource_mut::<Assets<Ecosystem>>()
        .add(Ecosystem(desc));
    world.spawn(Forest(ecosystem));
    let image = Image::new_target_texture(480, 270, TextureFormat::Rgba8UnormSrgb, None);
    let image = world.resource_mut::<Assets<Image>>().add(image);
    world.spawn((
        Camera3d::default(),
        RenderTarget::Image(image.into()),
        Msaa::Off,
        Transform::default(),
    ));
    world.spawn((
        DirectionalLight::default(),
        Transform::from_xyz(1.0, 3.0, 2.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    Ok(())
}

/// What the app does before frame `frame`: the camera circles the forest; every
/// `--spawn-every` frames the trees planted last time go and five new ones come; every
/// [`STRATEGY_EVERY`] frames the next strategy.
fn step(world: &mut World, frame: u64) {
    let (size, spawn_every) = {
        let soak = world.resource::<Soak>();
        (soak.size, soak.spawn_every)
    };
    let center = Vec3::new(0.5 * size, 0.0, 0.5 * size);
    let angle = frame as f32 * 0.002;
    let eye = center + Vec3::new(angle.cos(), 0.0, angle.sin()) * 0.7 * size + 20.0 * Vec3::Y;
    let mut cameras = world.query_filtered::<&mut Transform, With<Camera3d>>();
    for mut transform in cameras.iter_mut(world) {
        *transform = Transform::from_translation(eye).looking_at(center, Vec3::Y);
    }
    if spawn_every > 0 && frame.is_multiple_of(spawn_every) {
        let planted = std::mem::take(&mut world.resource_mut::<Soak>().planted);
        for tree in planted {
            world.despawn(tree);
        }
        let model = world
            .resource::<AssetServer>()
            .load("species/broad.species.ron");
        let mut planted = Vec::new();
        for k in 0..5u64 {
            let t = ((frame / spawn_every) * 5 + k) as f32 * 0.618_034;
            let at = Vec3::new(t.fract() * size, 0.0, (t * 1.7).fract() * size);
            planted.push(
                world
                    .spawn((
                        TreeInstance::new(model.clone()),
                        Transform::from_translation(at),
                    ))
                    .id(),
            );
        }
        world.resource_mut::<Soak>().planted = planted;
    }
    if frame.is_multiple_of(STRATEGY_EVERY) {
        let (mode, strategy) = STRATEGIES[(frame / STRATEGY_EVERY) as usize % STRATEGIES.len()];
        let mut budget = world.resource_mut::<FrameBudget>();
        budget.mode = mode;
        budget.strategy = strategy;
    }
}

/// The resident set size, MiB (Linux; NaN elsewhere).
fn resident_mib() -> f32 {
    let pages = std::fs::read_to_string("/proc/self/statm")
        .ok()
        .and_then(|s| s.split_whitespace().nth(1)?.parse::<f32>().ok());
    pages.map_or(f32::NAN, |p| p * 4096.0 / (1024.0 * 1024.0))
}

fn report(world: &World, frame: u64, seconds: f32) {
    let learned = world.resource::<CostModel>().learned();
    let lod = world.resource::<LodDiagnostics>();
    let s = learned.scales;
    println!(
        "soak frame={frame} seconds={seconds:.0} rss_mb={:.1} trees={} visible={} frame_ms={:.2} fixed_ms={:.3} triangles={:.3} triangle_pixels={:.3} lines={:.3} points={:.3} render_speed={:.3} logic_fixed_ms={:.3} frames_learned={}",
        resident_mib(),
        world.resource::<ForestInstances>().len(),
        lod.visible_instances,
        lod.measured_frame_ms,
        learned.render_fixed_ms,
        s.triangles,
        s.triangle_pixels,
        s.lines,
        s.points,
        learned.render_speed,
        learned.logic_fixed_ms,
        learned.frames_learned,
    );
}
