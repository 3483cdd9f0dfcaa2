//! Renders every shipped species at full detail with Bevy's standard renderer and saves
//! one PNG per species, for the docs and for looking at what the generator makes.
//!
//! ```sh
//! cargo run --release -p sherwood-lab -- gallery docs
//! # without a display: xvfb-run -a -s "-screen 0 1280x1024x24" cargo run ...
//! ```

use std::path::PathBuf;

use bevy::prelude::*;
use bevy::render::view::screenshot::{Capturing, Screenshot, save_to_disk};
use bevy::window::{PresentMode, WindowResolution};
use bevy_sherwood::prelude::*;

const SPECIES: [&str; 4] = ["slender", "broad", "grand", "dense"];
/// Frames to wait after spawning a tree before capturing (pipelines compile
/// asynchronously; a software renderer needs a while).
const SETTLE_FRAMES: u32 = 90;

#[derive(Resource)]
struct Gallery {
    out_dir: String,
    index: usize,
    handle: Option<Handle<TreeModel>>,
    frames: u32,
    captured: bool,
}

#[derive(Component)]
struct Shown;

/// The gallery's command line.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The folder the pictures go to (`species-<name>.png`).
    #[arg(default_value = "docs")]
    out_dir: PathBuf,
}

/// Renders the species and saves their pictures.
pub fn run(args: Args) -> AppExit {
    let out_dir = args.out_dir.display().to_string();
    if let Err(e) = std::fs::create_dir_all(&out_dir) {
        eprintln!("gallery: cannot create {out_dir}: {e}");
        return AppExit::error();
    }
    App::new()
        .add_plugins(
            DefaultPlugins
                .set(WindowPlugin {
                    primary_window: Some(Window {
                        title: "bevy_sherwood species".into(),
                        resolution: WindowResolution::new(640, 800),
                        present_mode: PresentMode::AutoNoVsync,
                        ..default()
                    }),
                    ..default()
                })
                .set(AssetPlugin {
                    file_path: crate::assets::root().to_string_lossy().into_owned(),
                    ..default()
                }),
        )
        .add_plugins(SherwoodPlugins)
        .insert_resource(ClearColor(Color::srgb(0.62, 0.76, 0.92)))
        .insert_resource(Gallery {
            out_dir,
            index: 0,
            handle: None,
            frames: 0,
            captured: false,
        })
        .add_systems(Startup, setup)
        .add_systems(Update, step)
        .run()
}

fn setup(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) {
    commands.spawn((Camera3d::default(), Transform::default()));
    commands.spawn((
        DirectionalLight {
            illuminance: 9_000.0,
            shadow_maps_enabled: false,
            ..default()
        },
        Transform::from_xyz(4.0, 10.0, 6.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    commands.insert_resource(GlobalAmbientLight {
        brightness: 400.0,
        ..default()
    });
    commands.spawn((
        Mesh3d(meshes.add(Plane3d::default().mesh().size(40.0, 40.0))),
        MeshMaterial3d(materials.add(Color::srgb(0.30, 0.42, 0.22))),
    ));
}

#[expect(clippy::too_many_arguments, reason = "a small example's only system")]
fn step(
    mut commands: Commands,
    mut gallery: ResMut<Gallery>,
    server: Res<AssetServer>,
    models: Res<Assets<TreeModel>>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    shown: Query<Entity, With<Shown>>,
    capturing: Query<(), With<Capturing>>,
    mut camera: Single<&mut Transform, With<Camera3d>>,
    mut exit: MessageWriter<AppExit>,
) {
    let Some(name) = SPECIES.get(gallery.index).copied() else {
        exit.write(AppExit::Success);
        return;
    };
    let Some(handle) = gallery.handle.clone() else {
        gallery.handle = Some(server.load(format!("species/{name}.species.ron")));
        return;
    };
    if shown.is_empty() {
        let Some(model) = models.get(&handle) else {
            if server.load_state(&handle).is_failed() {
                error!("species {name} failed to load");
                exit.write(AppExit::error());
            }
            return;
        };
        let bark = model.bark_color;
        let leaf = model.leaf_color;
        commands.spawn((
            Shown,
            Mesh3d(meshes.add(model.trunk_mesh())),
            MeshMaterial3d(materials.add(StandardMaterial {
                base_color: Color::linear_rgb(bark[0], bark[1], bark[2]),
                perceptual_roughness: 0.9,
                ..default()
            })),
        ));
        commands.spawn((
            Shown,
            Mesh3d(meshes.add(model.leaf_mesh())),
            MeshMaterial3d(materials.add(StandardMaterial {
                base_color: Color::linear_rgb(leaf[0], leaf[1], leaf[2]),
                double_sided: true,
                cull_mode: None,
                perceptual_roughness: 0.8,
                ..default()
            })),
        ));
        let center = model.bounds.center();
        let radius = model.bounds.half_extents().length();
        **camera = Transform::from_translation(
            center + Vec3::new(1.0, 0.15, 1.0).normalize() * radius * 2.4,
        )
        .looking_at(center, Vec3::Y);
        gallery.frames = 0;
        gallery.captured = false;
        info!(
            "{name}: {} trunk + {} leaf triangles",
            model.trunk_triangle_count(),
            model.leaf_triangle_count()
        );
        return;
    }
    gallery.frames += 1;
    if gallery.frames == SETTLE_FRAMES {
        let path = format!("{}/species-{name}.png", gallery.out_dir);
        commands
            .spawn(Screenshot::primary_window())
            .observe(save_to_disk(path));
        gallery.captured = true;
    } else if gallery.captured && gallery.frames > SETTLE_FRAMES + 2 && capturing.is_empty() {
        for entity in &shown {
            commands.entity(entity).despawn();
        }
        gallery.index += 1;
        gallery.handle = None;
    }
}
