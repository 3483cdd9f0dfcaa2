//! The forest: the default ecosystem with time-critical level of detail, the HUD that
//! shows what each frame was given and took, and keys to change the budget as you fly.
//!
//! ```sh
//! cargo run --release --example forest
//! ```
//!
//! Fly with Bevy's `FreeCamera` (WASD, Q/E down and up, hold the right mouse button to
//! look). `+`/`-` raise or lower the target frame time, `M` cycles the mode (TCLOD, TC,
//! static, unlimited), `B` the budget strategy, `N` toggles the wind, `C` the culling
//! boxes, `H` the HUD. The measurement harness (camera paths, records, calibration) is
//! `cargo run --release -p sherwood-lab -- forest --help`.

use bevy::camera_controller::free_camera::{FreeCamera, FreeCameraPlugin};
use bevy::prelude::*;
use bevy_sherwood::lod::StrategyKind;
use bevy_sherwood::prelude::*;
use bevy_sherwood::wind::WindSettings;

fn main() {
    App::new()
        .add_plugins((
            DefaultPlugins,
            SherwoodPlugins,
            ForestHudPlugin,
            FreeCameraPlugin,
        ))
        .insert_resource(ClearColor(Color::srgb(0.62, 0.76, 0.92)))
        .insert_resource(FrameBudget {
            target_ms: 100.0,
            ..default()
        })
        .add_systems(Startup, setup)
        .add_systems(Update, keys)
        .run();
}

fn setup(mut commands: Commands, server: Res<AssetServer>, mut hud: ResMut<ForestHud>) {
    commands.spawn(Forest(server.load("forests/default.ecosystem.ron")));
    commands.spawn((
        DirectionalLight {
            illuminance: 9_000.0,
            ..default()
        },
        Transform::from_xyz(4.0, 10.0, 6.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    commands.spawn((
        Camera3d::default(),
        // Multisampling quadruples the rasteriser's work on a software renderer.
        Msaa::Off,
        FreeCamera {
            // `M` is the mode here.
            keyboard_key_toggle_cursor_grab: KeyCode::KeyG,
            ..default()
        },
        Transform::from_xyz(-12.0, 25.0, -12.0).looking_at(Vec3::new(60.0, 0.0, 60.0), Vec3::Y),
    ));
    hud.footer = "+/- target  M mode  B strategy  N wind  C boxes  H hud".into();
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
            StrategyKind::TriangleBudget => StrategyKind::Hierarchical,
            StrategyKind::Hierarchical => StrategyKind::RobinHood,
        };
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
