//! The default ecosystem with every tree at full detail through the forest render pass
//! (no level of detail), with the culling boxes shown: dashed boxes are fully visible,
//! solid ones partly.
//!
//! ```sh
//! cargo run --release --example ecosystem_preview -- [ECOSYSTEM] [SCREENSHOT.png]
//! ```

use bevy::prelude::*;
use bevy::render::view::screenshot::{Screenshot, save_to_disk};
use bevy::window::{PresentMode, WindowResolution};
use bevy_sherwood::culling::ForestCulling;
use bevy_sherwood::ecosystem::ForestState;
use bevy_sherwood::prelude::*;

#[derive(Resource)]
struct Preview {
    screenshot: Option<String>,
    frames: u32,
}

fn main() -> AppExit {
    let mut args = std::env::args().skip(1);
    let ecosystem = args
        .next()
        .unwrap_or_else(|| "forests/default.ecosystem.ron".into());
    let screenshot = args.next();
    App::new()
        .add_plugins(DefaultPlugins.set(WindowPlugin {
            primary_window: Some(Window {
                title: "bevy_sherwood ecosystem preview".into(),
                resolution: WindowResolution::new(960, 540),
                present_mode: PresentMode::AutoNoVsync,
                ..default()
            }),
            ..default()
        }))
        .add_plugins(SherwoodPlugins)
        .insert_resource(ClearColor(Color::srgb(0.62, 0.76, 0.92)))
        .insert_resource(CullingDebug { enabled: true })
        .insert_resource(Preview {
            screenshot,
            frames: 0,
        })
        .add_systems(
            Startup,
            move |mut commands: Commands, server: Res<AssetServer>| {
                commands.spawn(Forest(server.load(ecosystem.clone())));
                // A narrow view from the forest's edge, so some boxes are culled.
                commands.spawn((
                    Camera3d::default(),
                    Projection::Perspective(PerspectiveProjection {
                        fov: 0.6,
                        ..default()
                    }),
                    Transform::from_xyz(-40.0, 45.0, -40.0)
                        .looking_at(Vec3::new(110.0, 0.0, 90.0), Vec3::Y),
                ));
                commands.spawn((
                    DirectionalLight {
                        illuminance: 9_000.0,
                        ..default()
                    },
                    Transform::from_xyz(4.0, 10.0, 6.0).looking_at(Vec3::ZERO, Vec3::Y),
                ));
            },
        )
        .add_systems(Update, capture)
        .run()
}

fn capture(
    mut commands: Commands,
    mut preview: ResMut<Preview>,
    forests: Query<&ForestState>,
    drawn: Res<ForestRenderStats>,
    culling: Res<ForestCulling>,
    mut exit: MessageWriter<AppExit>,
) {
    let Some(path) = preview.screenshot.clone() else {
        return;
    };
    let ready = forests
        .iter()
        .any(|f| !f.instances.is_empty() && drawn.instances as usize == f.instances.len());
    if !ready || !culling.is_built() || culling.models_loading() > 0 {
        return;
    }
    preview.frames += 1;
    if preview.frames == 40 {
        commands
            .spawn(Screenshot::primary_window())
            .observe(save_to_disk(path));
    } else if preview.frames == 46 {
        exit.write(AppExit::Success);
    }
}
