//! Any Bevy mesh in the same frame budget as the trees: a dense mesh is simplified into a
//! ladder of levels (meshoptimizer), and each entity with a `LodLadder` shows the level
//! its share of the frame buys. The material is the app's own.
//!
//! ```sh
//! cargo run --release --example ladders
//! ```
//!
//! Boulders of 20 480 triangles, each with levels at 35, 12, 4 and 1.2% of its
//! triangles, scattered through the default forest; once a second the log says how many
//! boulders show each level.

use bevy::camera_controller::free_camera::{FreeCamera, FreeCameraPlugin};
use bevy::mesh::VertexAttributeValues;
use bevy::prelude::*;
use bevy_sherwood::prelude::*;

fn main() {
    App::new()
        .add_plugins((DefaultPlugins, SherwoodPlugins, FreeCameraPlugin))
        .insert_resource(FrameBudget {
            target_ms: 50.0,
            ..default()
        })
        .add_systems(Startup, setup)
        .add_systems(Update, report_levels)
        .run();
}

fn setup(
    mut commands: Commands,
    server: Res<AssetServer>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) {
    commands.spawn(Forest(server.load("forests/default.ecosystem.ron")));
    let levels = generate_ladder(&boulder(), &[0.35, 0.12, 0.04, 0.012])
        .expect("an icosphere is a valid triangle mesh");
    let ladder = LodLadder::from_generated(&mut meshes, levels).expect("each level is cheaper");
    let material = materials.add(StandardMaterial {
        base_color: Color::srgb(0.62, 0.58, 0.54),
        perceptual_roughness: 0.9,
        ..default()
    });
    for i in 0..120 {
        let (x, z) = ((i % 12) as f32 * 10.0, (i / 12) as f32 * 10.0);
        let scale = 0.8 + 0.6 * (i as f32 * 0.7).sin().abs();
        commands.spawn((
            ladder.clone(),
            // The best level until the ladder has chosen.
            Mesh3d(ladder.levels()[0].mesh.clone()),
            MeshMaterial3d(material.clone()),
            Transform::from_xyz(x + 3.0, 0.5 * scale, z + 3.0)
                .with_scale(Vec3::new(1.3, 0.8, 1.0) * scale),
        ));
    }
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

/// An icosphere (20 480 triangles) pushed in and out by a few waves.
fn boulder() -> Mesh {
    let mut mesh = Sphere::new(1.0)
        .mesh()
        .ico(5)
        .expect("ico 5 is small enough");
    if let Some(VertexAttributeValues::Float32x3(positions)) =
        mesh.attribute_mut(Mesh::ATTRIBUTE_POSITION)
    {
        for p in positions.iter_mut() {
            let v = Vec3::from(*p);
            let bump = 0.12 * (3.0 * v.x).sin() * (2.0 * v.z).cos() + 0.06 * (7.0 * v.y).sin();
            *p = (v * (1.0 + bump)).to_array();
        }
    }
    mesh.compute_smooth_normals();
    mesh
}

/// Once a second, how many boulders in view show each level, best first.
fn report_levels(ladders: Res<LadderDiagnostics>, time: Res<Time>, mut last: Local<f32>) {
    if time.elapsed_secs() - *last >= 1.0 {
        *last = time.elapsed_secs();
        info!("boulders showing each level: {:?}", ladders.shown_per_level);
    }
}
