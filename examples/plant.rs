//! Trees planted by hand, without an ecosystem: any entity with a `TreeInstance` and a
//! `Transform` is culled, given its share of the frame, moved by the wind and drawn,
//! whoever spawned it, and follows its `Transform` when you move it.
//!
//! ```sh
//! cargo run --release --example plant
//! ```
//!
//! A grove of the four shipped species on a lawn; one tree walks in a circle. `Space`
//! plants a tree in front of the camera, `Backspace` removes the last one planted.

use bevy::camera_controller::free_camera::{FreeCamera, FreeCameraPlugin};
use bevy::prelude::*;
use bevy_sherwood::prelude::*;

const SPECIES: [&str; 4] = ["slender", "broad", "grand", "dense"];

fn main() {
    App::new()
        .add_plugins((DefaultPlugins, SherwoodPlugins, FreeCameraPlugin))
        .insert_resource(FrameBudget {
            target_ms: 50.0,
            ..default()
        })
        .init_resource::<Planted>()
        .add_systems(Startup, setup)
        .add_systems(Update, (walk, plant))
        .run();
}

/// The species' models, and the trees planted with `Space`.
#[derive(Resource, Default)]
struct Planted {
    models: Vec<Handle<TreeModel>>,
    trees: Vec<Entity>,
}

/// The tree that walks.
#[derive(Component)]
struct Walker;

fn setup(
    mut commands: Commands,
    server: Res<AssetServer>,
    mut planted: ResMut<Planted>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) {
    planted.models = SPECIES
        .iter()
        .map(|name| server.load(format!("species/{name}.species.ron")))
        .collect();
    for i in 0..64 {
        let (x, z) = ((i % 8) as f32 * 9.0, (i / 8) as f32 * 9.0);
        // A little disorder, the same every run.
        let jitter = Vec3::new((i as f32 * 2.3).sin(), 0.0, (i as f32 * 1.7).cos()) * 2.5;
        let model = planted.models[i % SPECIES.len()].clone();
        commands.spawn((
            TreeInstance::new(model),
            Transform::from_translation(Vec3::new(x, 0.0, z) + jitter),
        ));
    }
    commands.spawn((
        TreeInstance::new(planted.models[2].clone()),
        Transform::from_xyz(30.0, 0.0, -12.0),
        Walker,
    ));
    commands.spawn((
        Mesh3d(meshes.add(Plane3d::default().mesh().size(200.0, 200.0))),
        MeshMaterial3d(materials.add(Color::srgb(0.33, 0.45, 0.22))),
        Transform::from_xyz(30.0, 0.0, 30.0),
    ));
    commands.spawn((
        Camera3d::default(),
        FreeCamera::default(),
        Transform::from_xyz(-20.0, 14.0, -20.0).looking_at(Vec3::new(30.0, 0.0, 30.0), Vec3::Y),
    ));
    commands.spawn((
        DirectionalLight::default(),
        Transform::from_xyz(1.0, 3.0, 2.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
}

/// Moving a tree is moving its `Transform`: its culling box and shares follow.
fn walk(time: Res<Time>, mut walker: Query<&mut Transform, With<Walker>>) {
    let angle = 0.3 * time.elapsed_secs();
    for mut transform in &mut walker {
        transform.translation =
            Vec3::new(30.0 + 40.0 * angle.cos(), 0.0, 30.0 + 40.0 * angle.sin());
    }
}

fn plant(
    mut commands: Commands,
    input: Res<ButtonInput<KeyCode>>,
    camera: Query<&Transform, With<Camera3d>>,
    mut planted: ResMut<Planted>,
) {
    if input.just_pressed(KeyCode::Space)
        && let Ok(eye) = camera.single()
    {
        let ahead = eye.translation + eye.forward().as_vec3() * 15.0;
        let model = planted.models[planted.trees.len() % SPECIES.len()].clone();
        let tree = commands
            .spawn((
                TreeInstance::new(model),
                Transform::from_xyz(ahead.x, 0.0, ahead.z),
            ))
            .id();
        planted.trees.push(tree);
    }
    if input.just_pressed(KeyCode::Backspace)
        && let Some(tree) = planted.trees.pop()
    {
        commands.entity(tree).despawn();
    }
}
