//! What a user writes: Bevy's default plugins (a window presenting with vsync), the
//! Sherwood plugins, the default forest through the asset server, and a camera to fly
//! (Bevy's `FreeCamera`: WASD to move, Q/E down and up, hold the right mouse button to
//! look around, the wheel to change speed).
//!
//! ```sh
//! cargo run --release --example minimal
//! ```

use bevy::camera_controller::free_camera::{FreeCamera, FreeCameraPlugin};
use bevy::prelude::*;
use bevy_sherwood::prelude::*;

fn main() {
    App::new()
        .add_plugins((DefaultPlugins, SherwoodPlugins, FreeCameraPlugin))
        // Under vsync a frame is shown after whole refresh periods: ask for a multiple of
        // the period. 50 ms is three periods at 60 Hz (what a software renderer holds); a
        // game on a GPU would ask for 16.7 ms.
        .insert_resource(FrameBudget {
            target_ms: 50.0,
            ..default()
        })
        .add_systems(Startup, setup)
        .run();
}

fn setup(mut commands: Commands, server: Res<AssetServer>) {
    commands.spawn(Forest(server.load("forests/default.ecosystem.ron")));
    commands.spawn((
        Camera3d::default(),
        FreeCamera::default(),
        Transform::from_xyz(-10.0, 12.0, -10.0).looking_at(Vec3::new(60.0, 0.0, 60.0), Vec3::Y),
    ));
    commands.spawn((
        DirectionalLight::default(),
        Transform::from_xyz(1.0, 3.0, 2.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
}
