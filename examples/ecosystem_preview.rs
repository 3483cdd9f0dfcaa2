//! The default ecosystem drawn with Bevy's standard renderer (every tree at full detail),
//! with the culling boxes shown: dashed boxes are fully visible, solid ones partly.
//! A reference view until the forest render pass and the forest example arrive.
//!
//! ```sh
//! cargo run --release --example ecosystem_preview -- [ECOSYSTEM] [SCREENSHOT.png]
//! ```

use bevy::prelude::*;
use bevy::render::view::screenshot::{Screenshot, save_to_disk};
use bevy::window::{PresentMode, WindowResolution};
use bevy_sherwood::ecosystem::ForestState;
use bevy_sherwood::prelude::*;

#[derive(Resource)]
struct Preview {
    screenshot: Option<String>,
    frames: u32,
}

#[derive(Component)]
struct Drawn;

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
        .add_systems(Update, (draw_trees, capture))
        .run()
}

/// Gives every tree instance the standard renderer's meshes, once its model has loaded.
fn draw_trees(
    mut commands: Commands,
    instances: Query<(Entity, &TreeInstance), Without<Drawn>>,
    models: Res<Assets<TreeModel>>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    mut cache: Local<
        Vec<
            Option<(
                Handle<Mesh>,
                Handle<Mesh>,
                Handle<StandardMaterial>,
                Handle<StandardMaterial>,
            )>,
        >,
    >,
) {
    for (entity, instance) in &instances {
        let Some(model) = models.get(&instance.model) else {
            continue;
        };
        if cache.len() <= instance.species {
            cache.resize(instance.species + 1, None);
        }
        let (trunk, leaves, bark, leaf) = cache[instance.species]
            .get_or_insert_with(|| {
                let [br, bg, bb] = model.bark_color;
                let [lr, lg, lb] = model.leaf_color;
                (
                    meshes.add(model.trunk_mesh()),
                    meshes.add(model.leaf_mesh()),
                    materials.add(Color::linear_rgb(br, bg, bb)),
                    materials.add(StandardMaterial {
                        base_color: Color::linear_rgb(lr, lg, lb),
                        double_sided: true,
                        cull_mode: None,
                        ..default()
                    }),
                )
            })
            .clone();
        commands
            .entity(entity)
            .insert((Drawn, Visibility::default()))
            .with_children(|parent| {
                parent.spawn((Mesh3d(trunk), MeshMaterial3d(bark)));
                parent.spawn((Mesh3d(leaves), MeshMaterial3d(leaf)));
            });
    }
}

fn capture(
    mut commands: Commands,
    mut preview: ResMut<Preview>,
    forests: Query<&ForestState>,
    drawn: Query<(), With<Drawn>>,
    culling: Res<ForestCulling>,
    mut exit: MessageWriter<AppExit>,
) {
    let Some(path) = preview.screenshot.clone() else {
        return;
    };
    let ready = forests
        .iter()
        .any(|f| !f.instances.is_empty() && drawn.iter().count() == f.instances.len());
    if !ready || culling.hierarchy.is_none() {
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
