//! A tree from a glTF file (`*.tree.glb`), as generators and modelling tools write them:
//! the loader analyses the trunk into rings and the leaves into groups, and the tree is
//! planted like any other. Here the five EZ-Tree presets shipped in `assets/trees/eztree`,
//! one with the loader's settings changed in code (a `.meta` file beside the tree does the
//! same); once loaded, the log says what the analysis found in each.
//!
//! ```sh
//! cargo run --release --example gltf_tree
//! ```

use bevy::camera_controller::free_camera::{FreeCamera, FreeCameraPlugin};
use bevy::prelude::*;
use bevy_sherwood::prelude::*;
use bevy_sherwood::tree::GltfTreeSettings;

const TREES: [&str; 5] = [
    "ash_small",
    "aspen_small",
    "oak_small",
    "pine_small",
    "bush_2",
];
/// EZ-Tree's units are about four to the metre.
const SCALE: f32 = 0.28;

fn main() {
    App::new()
        .add_plugins((DefaultPlugins, SherwoodPlugins, FreeCameraPlugin))
        .insert_resource(FrameBudget {
            target_ms: 50.0,
            ..default()
        })
        .add_systems(Startup, setup)
        .add_systems(Update, report_analysis)
        .run();
}

fn setup(
    mut commands: Commands,
    server: Res<AssetServer>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) {
    for (i, name) in TREES.iter().enumerate() {
        let path = format!("trees/eztree/{name}.tree.glb");
        let model: Handle<TreeModel> = if *name == "bush_2" {
            // A bush's branches dip below the ground: attach them rather than root them.
            server
                .load_builder()
                .with_settings(|s: &mut GltfTreeSettings| s.analysis.ground = -1.0)
                .load(path)
        } else {
            server.load(path)
        };
        let tree = TreeInstance {
            scale: SCALE,
            ..TreeInstance::new(model)
        };
        commands.spawn((
            tree,
            Transform::from_xyz(i as f32 * 6.0, 0.0, 0.0).with_scale(Vec3::splat(SCALE)),
        ));
    }
    commands.spawn((
        Mesh3d(meshes.add(Plane3d::default().mesh().size(80.0, 80.0))),
        MeshMaterial3d(materials.add(Color::srgb(0.33, 0.45, 0.22))),
        Transform::from_xyz(12.0, 0.0, 0.0),
    ));
    commands.spawn((
        Camera3d::default(),
        FreeCamera::default(),
        Transform::from_xyz(12.0, 5.0, -18.0).looking_at(Vec3::new(12.0, 3.0, 0.0), Vec3::Y),
    ));
    commands.spawn((
        DirectionalLight::default(),
        Transform::from_xyz(1.0, 3.0, -2.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
}

/// Each model's rings, segments and leaves, once, when it has loaded.
fn report_analysis(
    mut events: MessageReader<AssetEvent<TreeModel>>,
    models: Res<Assets<TreeModel>>,
    server: Res<AssetServer>,
) {
    for event in events.read() {
        if let AssetEvent::LoadedWithDependencies { id } = event
            && let Some(model) = models.get(*id)
        {
            let path = server.get_path(*id).map(|p| p.to_string());
            info!(
                "{}: {} rings, {} segments, {} leaves in {} groups",
                path.unwrap_or_default(),
                model.rings.len(),
                model.segments.len(),
                model.leaves.len(),
                model.leaf_groups.len()
            );
        }
    }
}
