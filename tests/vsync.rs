//! The frame-time promise under vsync, on the real render schedule: a renderer whose work
//! is synthetic and known (the render world spins for a time set by the frame's own
//! selection), once with frames free-running, once with every frame held to a vertical
//! blank (`EmulatedVsyncPlugin`), the same target below the period, and once with the app
//! idling between updates. The cost model must learn the work, not the waits, and neither
//! the vsync run nor the idling one may cut the forest. Run with
//! `cargo test --features gpu-tests`.
#![cfg(feature = "gpu-tests")]

use bevy_sherwood::testing as common;
use bevy_sherwood::testing as windowless;

use std::time::{Duration, Instant};

use bevy::log::LogPlugin;
use bevy::prelude::*;
use bevy::render::{Extract, ExtractSchedule, Render, RenderApp, RenderSystems};
use bevy_sherwood::cost::{
    CalibrationChoice, CostModel, CostSettings, FrameClock, FrameSample, FrameSamples,
};
use bevy_sherwood::prelude::*;

/// The emulated display's refresh period, seconds.
const PERIOD: f32 = 0.15;
/// The target, below the period.
const TARGET_MS: f32 = 120.0;
/// The synthetic renderer: a fixed part and a factor on the selection's calibrated time,
/// large enough that the real rendering (a small image) and its noise are a small part.
const SYNTHETIC_FIXED: f32 = 0.02;
const SYNTHETIC_SCALE: f32 = 6.0;
const FRAMES: usize = 140;
/// Frames at the end whose figures are compared.
const SETTLED: usize = 50;

/// This frame's synthetic rendering work, handed to the render world.
#[derive(Resource, Default)]
struct SyntheticWork(Duration);

fn extract_work(
    mut work: ResMut<SyntheticWork>,
    model: Extract<Res<CostModel>>,
    clock: Extract<Res<FrameClock>>,
) {
    let selection = model
        .prediction(clock.frame)
        .map_or(0.0, |p| p.calibrated.total());
    work.0 = Duration::from_secs_f32(SYNTHETIC_FIXED + SYNTHETIC_SCALE * selection);
}

/// Spins for the frame's synthetic work, in the render world's `Prepare` set (work, not a
/// wait).
fn render_work(work: Res<SyntheticWork>) {
    let start = Instant::now();
    while start.elapsed() < work.0 {
        std::hint::spin_loop();
    }
}

struct Run {
    /// The measured samples of the settled frames.
    samples: Vec<FrameSample>,
    /// The selections' calibrated rendering time of the settled frames, seconds.
    selections: Vec<f32>,
    /// The last frames' floors and what they spent beyond the fixed part, ms.
    floors: Vec<f32>,
    spent: Vec<f32>,
    /// The rendering predicted for them, seconds.
    predicted: Vec<f32>,
}

/// How the frames of a run are paced.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Pacing {
    /// As fast as they go.
    Free,
    /// Held to an emulated vertical blank.
    Vsync,
    /// The app idles [`IDLE`] between updates by choice (as winit's reactive modes do).
    Idle,
}

const IDLE: Duration = Duration::from_millis(40);

fn run(pacing: Pacing) -> Run {
    let mut app = App::new();
    app.add_plugins(
        windowless::windowless_plugins(
            DefaultPlugins.build().disable::<bevy::winit::WinitPlugin>(),
        )
        .disable::<LogPlugin>(),
    )
    .add_plugins(SherwoodPlugins);
    if pacing == Pacing::Vsync {
        app.add_plugins(EmulatedVsyncPlugin {
            refresh_hz: 1.0 / PERIOD,
        });
    }
    app.sub_app_mut(RenderApp)
        .init_resource::<SyntheticWork>()
        .add_systems(ExtractSchedule, extract_work)
        .add_systems(Render, render_work.in_set(RenderSystems::Prepare));
    windowless::finish_plugins(&mut app);
    {
        let world = app.world_mut();
        world.resource_mut::<CostSettings>().calibration = CalibrationChoice::Keep;
        world.resource_mut::<WindSettings>().enabled = false;
        *world.resource_mut::<FrameBudget>() = FrameBudget {
            target_ms: TARGET_MS,
            ..default()
        };
    }
    let mut desc = common::default_ecosystem();
    for s in &mut desc.species {
        s.count = 40;
    }
    let size = desc.terrain.size;
    common::spawn_forest(&mut app, desc);
    small_camera(
        &mut app,
        Vec3::new(0.1 * size, 15.0, 0.1 * size),
        Vec3::new(0.6 * size, 0.0, 0.6 * size),
    );

    let mut samples = Vec::new();
    let mut selections = Vec::new();
    let mut floors = Vec::new();
    let mut spent = Vec::new();
    let mut predicted = Vec::new();
    let mut updates = 0;
    while samples.len() < FRAMES {
        if pacing == Pacing::Idle {
            std::thread::sleep(IDLE);
        }
        app.update();
        updates += 1;
        assert!(updates < 20 * FRAMES, "too few frames were measured");
        let world = app.world();
        let model = world.resource::<CostModel>();
        for sample in world.resource::<FrameSamples>().arrived() {
            let Some(learned) = model.last_learned() else {
                continue;
            };
            if learned.measured.frame != sample.frame || !sample.is_usable() {
                continue;
            }
            samples.push(*sample);
            selections.push(learned.predicted.calibrated.total());
            predicted.push(learned.predicted.render);
        }
        let d = world.resource::<LodDiagnostics>();
        floors.push(d.floor_ms);
        spent.push(d.predicted_render_ms - d.render_fixed_ms);
    }
    let start = samples.len() - SETTLED;
    Run {
        samples: samples.split_off(start),
        selections: selections.split_off(start),
        floors: floors.split_off(floors.len() - SETTLED),
        spent: spent.split_off(spent.len() - SETTLED),
        predicted: predicted.split_off(start),
    }
}

/// A camera rendering into a 96×54 image, so that the real rendering stays small beside
/// the synthetic work, and a sun.
fn small_camera(app: &mut App, eye: Vec3, target: Vec3) {
    use bevy::camera::RenderTarget;
    use bevy::render::render_resource::TextureFormat;
    let world = app.world_mut();
    let image = Image::new_target_texture(96, 54, TextureFormat::Rgba8UnormSrgb, None);
    let image = world.resource_mut::<Assets<Image>>().add(image);
    world.spawn((
        Camera3d::default(),
        RenderTarget::Image(image.into()),
        Msaa::Off,
        Transform::from_translation(eye).looking_at(target, Vec3::Y),
    ));
    world.spawn(DirectionalLight::default());
}

fn mean(values: impl Iterator<Item = f32>) -> f32 {
    let (sum, n) = values.fold((0.0, 0), |(s, n), v| (s + v, n + 1));
    sum / n.max(1) as f32
}

#[test]
fn under_vsync_or_idling_the_model_learns_the_work_and_keeps_the_detail() {
    let free = run(Pacing::Free);
    let held = run(Pacing::Vsync);
    let idling = run(Pacing::Idle);
    let figures = |name: &str, run: &Run| {
        eprintln!(
            "{name}: render {:.4} predicted {:.4} interval {:.4} waited {:.4} selection {:.4} floor {:.4} gpu {}/{} {:.4} logic {:.4}",
            mean(run.samples.iter().map(|s| s.render)),
            mean(run.predicted.iter().copied()),
            mean(run.samples.iter().map(|s| s.interval)),
            mean(run.samples.iter().map(|s| s.waited)),
            mean(run.selections.iter().copied()),
            mean(run.floors.iter().copied()) / 1000.0,
            run.samples.iter().filter(|s| s.gpu.is_some()).count(),
            run.samples.len(),
            mean(run.samples.iter().filter_map(|s| s.gpu)),
            mean(run.samples.iter().map(|s| s.logic)),
        );
    };
    figures("free", &free);
    figures("held", &held);
    figures("idling", &idling);

    // The emulated display really held every frame to its vertical blanks.
    let on_grid = held
        .samples
        .iter()
        .filter(|s| {
            let k = (s.interval / PERIOD).round();
            k >= 1.0 && (s.interval - k * PERIOD).abs() < 0.003
        })
        .count();
    assert!(
        on_grid >= held.samples.len() * 9 / 10,
        "only {on_grid} of {} frames on the vblank grid: {:?}",
        held.samples.len(),
        held.samples.iter().map(|s| s.interval).collect::<Vec<_>>()
    );
    // (A frame whose work ends within `WAIT_THRESHOLD` of a blank hardly waits.)
    let waited = held
        .samples
        .iter()
        .filter(|s| s.waited_for_display())
        .count();
    assert!(
        waited >= held.samples.len() * 9 / 10,
        "only {waited} of {} held frames waited",
        held.samples.len()
    );
    // Free-running frames are not on it: they end when their work does.
    assert!(free.samples.iter().any(|s| !s.waited_for_display()));

    // What the render world measures beyond the synthetic work (Bevy's own rendering of
    // a small image) is the same with and without vsync: the wait is not in it.
    let beyond = |run: &Run| {
        mean(
            run.samples
                .iter()
                .zip(&run.selections)
                .map(|(s, &selection)| s.render - (SYNTHETIC_FIXED + SYNTHETIC_SCALE * selection)),
        )
    };
    let (beyond_held, beyond_free) = (beyond(&held), beyond(&free));
    assert!(
        (beyond_held - beyond_free).abs() < 0.1 * PERIOD,
        "render work beyond the synthetic: {beyond_held} s with vsync, {beyond_free} s without"
    );
    // The rendering the model predicts with vsync is the truth: the synthetic work of
    // each frame's selection and Bevy's own rendering (measured without vsync).
    let error = mean(
        held.predicted
            .iter()
            .zip(&held.selections)
            .map(|(&p, &selection)| {
                let truth = SYNTHETIC_FIXED + SYNTHETIC_SCALE * selection + beyond_free;
                (p / truth - 1.0).abs()
            }),
    );
    assert!(
        error < 0.10,
        "with vsync the predicted rendering is {error:.3} off the truth on average"
    );

    // A target below the period keeps the detail it has without vsync.
    let detail_free = mean(free.selections.iter().copied());
    let detail_held = mean(held.selections.iter().copied());
    let floor = mean(held.floors.iter().copied());
    let spent = mean(held.spent.iter().copied());
    assert!(
        detail_held >= 0.8 * detail_free,
        "with vsync the selection's rendering is {detail_held} s against {detail_free} s without"
    );
    assert!(
        spent > 1.5 * floor,
        "with vsync the selection ({spent} ms) sits at its floor ({floor} ms)"
    );

    // An app idling between updates: the idling is measured apart, not charged.
    assert!(
        idling
            .samples
            .iter()
            .all(|s| s.idle >= 0.9 * IDLE.as_secs_f32() && s.waited_for_display()),
        "idling not measured: {:?}",
        idling.samples.iter().map(|s| s.idle).collect::<Vec<_>>()
    );
    let detail_idling = mean(idling.selections.iter().copied());
    assert!(
        detail_idling >= 0.8 * detail_free,
        "idling between updates, the selection's rendering is {detail_idling} s against {detail_free} s"
    );
}
