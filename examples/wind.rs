//! Wind: every tree sways on springs driven by a wind with gusts, with its own level of
//! detail (a tree whose rings would move less than a pixel stays still; far trees are
//! updated less often). Wind setups are assets (`wind/default.wind.ron` is the default);
//! `TreeInstance::motion` picks a tree's setup from `WindSettings::sets`.
//!
//! ```sh
//! cargo run --release --example wind
//! ```
//!
//! `Space` switches between the default breeze and a storm made in code; `N` stops and
//! starts the wind. Once a second the log says how many trees moved.

use bevy::camera_controller::free_camera::{FreeCamera, FreeCameraPlugin};
use bevy::prelude::*;
use bevy_sherwood::prelude::*;
use bevy_sherwood::wind::{GustDesc, SpringDesc, SpringSet, WindDesc, WindSettings, WindStats};

fn main() {
    App::new()
        .add_plugins((DefaultPlugins, SherwoodPlugins, FreeCameraPlugin))
        .insert_resource(FrameBudget {
            target_ms: 50.0,
            ..default()
        })
        .add_systems(Startup, setup)
        .add_systems(Update, (switch_weather, report))
        .run();
}

/// The two weathers `Space` switches between.
#[derive(Resource)]
struct Weather {
    breeze: Handle<SpringSet>,
    storm: Handle<SpringSet>,
}

fn setup(mut commands: Commands, server: Res<AssetServer>, mut sets: ResMut<Assets<SpringSet>>) {
    commands.spawn(Forest(server.load("forests/default.ecosystem.ron")));
    commands.insert_resource(Weather {
        breeze: server.load("wind/default.wind.ron"),
        storm: sets.add(storm()),
    });
    commands.spawn((
        Camera3d::default(),
        FreeCamera::default(),
        Transform::from_xyz(-6.0, 8.0, -6.0).looking_at(Vec3::new(30.0, 4.0, 30.0), Vec3::Y),
    ));
    commands.spawn((
        DirectionalLight::default(),
        Transform::from_xyz(1.0, 3.0, 2.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
}

/// Three springs of different stiffness (neighbours do not sway in lockstep), driven by
/// a strong wind whose gusts come often and hard.
fn storm() -> SpringSet {
    let spring = |stiffness: f32, seed: u64| SpringDesc {
        stiffness,
        mass: 1.0,
        damping: 0.995,
        seed,
        wind: WindDesc {
            direction: Vec3::new(1.0, 0.0, 0.2),
            strength: 3.0,
            gusts: GustDesc {
                frequency: 0.8,
                strength: (4.0, 7.0),
                duration: (0.6, 1.5),
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

fn switch_weather(
    input: Res<ButtonInput<KeyCode>>,
    weather: Res<Weather>,
    mut wind: ResMut<WindSettings>,
) {
    if input.just_pressed(KeyCode::Space) {
        // Motion index 0 (every tree of the default forest) takes the other set.
        let stormy = wind.sets.first() == Some(&weather.storm);
        let next = if stormy {
            &weather.breeze
        } else {
            &weather.storm
        };
        wind.sets = vec![next.clone()];
    }
    if input.just_pressed(KeyCode::KeyN) {
        wind.enabled = !wind.enabled;
    }
}

fn report(stats: Res<WindStats>, time: Res<Time>, mut last: Local<f32>) {
    if time.elapsed_secs() - *last >= 1.0 {
        *last = time.elapsed_secs();
        info!(
            "wind: {} trees could move, {} moved, {} updated this frame",
            stats.candidates, stats.moved, stats.updated
        );
    }
}
