//! A gust through the forest, as a contact sheet: renders a few trees without a window
//! while a strong gust passes (simulated time advances 1/30 s per frame, so the pictures
//! do not depend on how fast this machine renders) and writes the frames side by side.
//!
//! ```sh
//! cargo run --release -p sherwood-lab -- wind-gust docs/wind-gust.png
//! ```

use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use bevy::camera::RenderTarget;
use bevy::prelude::*;
use bevy::render::render_resource::{Extent3d, TextureDimension, TextureFormat, TextureUsages};
use bevy::render::view::screenshot::{Screenshot, ScreenshotCaptured};
use bevy::time::TimeUpdateStrategy;
use bevy_sherwood::ecosystem::{EcosystemDesc, ForestTerrain};
use bevy_sherwood::prelude::*;
use bevy_sherwood::testing as windowless;
use bevy_sherwood::wind::{GustDesc, SpringDesc, SpringSet, WindDesc, WindSettings};

const WIDTH: u32 = 480;
const HEIGHT: u32 = 360;
const COLUMNS: u32 = 3;
/// Frames on the sheet, and simulated seconds between them.
const FRAMES: u32 = 6;
const STEP_SECONDS: f32 = 0.3;
const FRAME_SECONDS: f32 = 1.0 / 30.0;

/// The gust sheet's command line.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The contact sheet to write.
    #[arg(default_value = "wind-gust.png")]
    out: PathBuf,
}

/// Renders the gust and writes the sheet.
pub fn run(args: Args) -> AppExit {
    let out = args.out.display().to_string();
    let mut app = App::new();
    app.add_plugins((
        windowless::windowless_plugins(
            DefaultPlugins.build().disable::<bevy::winit::WinitPlugin>(),
        ),
        SherwoodPlugins,
    ))
    .insert_resource(ClearColor(Color::srgb(0.62, 0.76, 0.92)))
    .insert_resource(FrameBudget {
        mode: LodMode::Unlimited,
        ..default()
    })
    .insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_secs_f32(
        FRAME_SECONDS,
    )));
    windowless::finish_plugins(&mut app);

    let image = setup(app.world_mut());
    // Let the forest load, the pipelines compile and the calm wind settle.
    let Some(tree) = settle(&mut app) else {
        eprintln!("wind_gust: the forest never appeared");
        return AppExit::error();
    };
    // Across the wind (it blows along +x), from above the ground wherever the eye lands
    // and a little above the crowns, so the bending shows and nothing sways into the lens.
    let world = app.world_mut();
    let mut eye = tree + Vec3::new(0.0, 0.0, -28.0);
    let ground = world
        .query::<&ForestTerrain>()
        .iter(world)
        .next()
        .map_or(tree.y, |t| t.terrain.height_at(eye.x, eye.z));
    eye.y = ground.max(tree.y) + 9.0;
    let target = tree + Vec3::new(0.0, 4.5, 0.0);
    let mut cameras = world.query_filtered::<&mut Transform, With<Camera3d>>();
    for mut transform in cameras.iter_mut(world) {
        *transform = Transform::from_translation(eye).looking_at(target, Vec3::Y);
    }
    // The gust: one spring set whose gusts come often and hard.
    let gusty = app
        .world_mut()
        .resource_mut::<Assets<SpringSet>>()
        .add(gusty_set());
    app.world_mut().resource_mut::<WindSettings>().sets = vec![gusty];

    let mut frames = Vec::new();
    let every = (STEP_SECONDS / FRAME_SECONDS).round() as u32;
    for _ in 0..FRAMES {
        for _ in 0..every {
            app.update();
        }
        match capture(&mut app, &image) {
            Some(frame) => frames.push(frame),
            None => {
                eprintln!("wind_gust: a screenshot never arrived");
                return AppExit::error();
            }
        }
    }
    match save_sheet(&frames, &out) {
        Ok(()) => {
            println!("wind_gust: wrote {out}");
            AppExit::Success
        }
        Err(e) => {
            eprintln!("wind_gust: {out}: {e}");
            AppExit::error()
        }
    }
}

fn setup(world: &mut World) -> Handle<Image> {
    let text = std::fs::read_to_string(crate::assets::root().join("forests/default.ecosystem.ron"))
        .expect("the default forest ships with the crate");
    let mut desc = EcosystemDesc::from_ron_str(&text).expect("the default forest parses");
    desc.set_total_trees(60)
        .expect("the default forest has trees to scale");
    let forest = world
        .resource_mut::<Assets<Ecosystem>>()
        .add(Ecosystem(desc));
    world.spawn(Forest(forest));
    world.spawn((
        DirectionalLight {
            illuminance: 9_000.0,
            ..default()
        },
        Transform::from_xyz(4.0, 10.0, 6.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    let mut image = Image::new_target_texture(WIDTH, HEIGHT, TextureFormat::Rgba8UnormSrgb, None);
    image.texture_descriptor.usage |= TextureUsages::COPY_SRC;
    let image = world.resource_mut::<Assets<Image>>().add(image);
    world.spawn((
        Camera3d::default(),
        Msaa::Off,
        RenderTarget::Image(image.clone().into()),
        Transform::from_xyz(0.0, 10.0, 0.0).looking_at(Vec3::X, Vec3::Y),
    ));
    image
}

/// Updates until the forest has spawned and a few seconds have passed; returns the base
/// of the tree nearest the forest's centre.
fn settle(app: &mut App) -> Option<Vec3> {
    for _ in 0..2_000 {
        app.update();
        let world = app.world_mut();
        let mut trees = world.query::<(&TreeInstance, &GlobalTransform)>();
        let positions: Vec<Vec3> = trees.iter(world).map(|(_, t)| t.translation()).collect();
        if positions.is_empty() {
            std::thread::sleep(Duration::from_millis(2));
            continue;
        }
        let centre = positions.iter().sum::<Vec3>() / positions.len() as f32;
        for _ in 0..90 {
            app.update();
        }
        return positions
            .into_iter()
            .min_by(|a, b| a.distance(centre).total_cmp(&b.distance(centre)));
    }
    None
}

fn gusty_set() -> SpringSet {
    let spring = |stiffness: f32, seed: u64| SpringDesc {
        stiffness,
        mass: 1.0,
        damping: 0.995,
        seed,
        wind: WindDesc {
            direction: Vec3::new(1.0, 0.0, 0.2),
            strength: 0.5,
            gusts: GustDesc {
                frequency: 2.0,
                strength: (5.0, 7.0),
                duration: (0.6, 1.0),
                rise: 0.3,
                fall: 0.6,
            },
        },
    };
    SpringSet {
        springs: vec![spring(18.0, 1), spring(22.0, 2), spring(30.0, 3)],
        ..default()
    }
}

fn capture(app: &mut App, image: &Handle<Image>) -> Option<Image> {
    let captured: Arc<Mutex<Option<Image>>> = Arc::default();
    let sink = captured.clone();
    app.world_mut()
        .spawn(Screenshot::image(image.clone()))
        .observe(move |event: On<ScreenshotCaptured>| {
            if let Ok(mut slot) = sink.lock() {
                *slot = Some(event.image.clone());
            }
        });
    // The capture arrives within a few frames; simulated time is paused meanwhile so the
    // sheet's spacing stays exact.
    app.insert_resource(TimeUpdateStrategy::ManualDuration(Duration::ZERO));
    let mut frame = None;
    for _ in 0..30 {
        app.update();
        frame = captured.lock().ok().and_then(|mut c| c.take());
        if frame.is_some() {
            break;
        }
    }
    app.insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_secs_f32(
        FRAME_SECONDS,
    )));
    frame
}

fn save_sheet(frames: &[Image], out: &str) -> Result<(), String> {
    let rows = frames.len().div_ceil(COLUMNS as usize) as u32;
    let (width, height) = (WIDTH * COLUMNS, HEIGHT * rows);
    let mut sheet = vec![255u8; (width * height * 4) as usize];
    for (k, frame) in frames.iter().enumerate() {
        let data = frame.data.as_ref().ok_or("a screenshot without pixels")?;
        let (fw, fh) = (frame.width().min(WIDTH), frame.height().min(HEIGHT));
        let (x0, y0) = ((k as u32 % COLUMNS) * WIDTH, (k as u32 / COLUMNS) * HEIGHT);
        for y in 0..fh {
            let from = (y * frame.width() * 4) as usize;
            let to = (((y0 + y) * width + x0) * 4) as usize;
            sheet[to..to + (fw * 4) as usize]
                .copy_from_slice(&data[from..from + (fw * 4) as usize]);
        }
    }
    let sheet = Image::new(
        Extent3d {
            width,
            height,
            depth_or_array_layers: 1,
        },
        TextureDimension::D2,
        sheet,
        TextureFormat::Rgba8UnormSrgb,
        default(),
    );
    sheet
        .try_into_dynamic()
        .map_err(|e| e.to_string())?
        .to_rgba8()
        .save(out)
        .map_err(|e| e.to_string())
}
