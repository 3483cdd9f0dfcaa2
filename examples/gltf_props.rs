//! Props from a glTF file whose levels of detail are named the way modelling tools export
//! them (`RockN_LOD0`, `RockN_LOD1`, …), in the same frame budget as the forest: spawned
//! with Bevy's glTF loader, marked `LadderFromLodNames`, each rock becomes a `LodLadder`
//! and shows the level its share of the frame buys. The rocks and their file come from
//! `scripts/make_rocks.py` (40 rocks, 9 000 / 1 000 / 130 triangles, one PBR material).
//!
//! ```sh
//! cargo run --release --example gltf_props
//! ```

use bevy::camera_controller::free_camera::{FreeCamera, FreeCameraPlugin};
use bevy::prelude::*;
use bevy::world_serialization::WorldAssetRoot;
use bevy_sherwood::prelude::*;

fn main() {
    App::new()
        .add_plugins((DefaultPlugins, SherwoodPlugins, FreeCameraPlugin))
        .insert_resource(FrameBudget {
            target_ms: 100.0,
            ..default()
        })
        .add_systems(Startup, setup)
        .add_systems(Update, report_levels)
        .run();
}

fn setup(mut commands: Commands, server: Res<AssetServer>) {
    commands.spawn(Forest(server.load("forests/default.ecosystem.ron")));
    commands.spawn((
        WorldAssetRoot(server.load(GltfAssetLabel::Scene(0).from_asset("props/rocks.glb"))),
        LadderFromLodNames,
        Transform::from_xyz(8.0, 0.5, 8.0),
    ));
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

/// Once a second, how many rocks show each level.
fn report_levels(ladders: Res<LadderDiagnostics>, time: Res<Time>, mut last: Local<f32>) {
    if time.elapsed_secs() - *last >= 1.0 {
        *last = time.elapsed_secs();
        info!(
            "rocks showing each level, best first: {:?}",
            ladders.shown_per_level
        );
    }
}
