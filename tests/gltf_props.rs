//! Props from a glTF file with `_LOD` levels, loaded with Bevy's glTF loader as an app
//! does (`WorldAssetRoot` + `LadderFromLodNames`), become ladders in the forest's budget.
//! Run with `cargo test --features gpu-tests`.
#![cfg(feature = "gpu-tests")]

use bevy_sherwood::testing as windowless;

use bevy::log::LogPlugin;
use bevy::prelude::*;
use bevy::world_serialization::WorldAssetRoot;
use bevy_sherwood::prelude::*;

#[test]
fn rocks_named_lod_in_a_gltf_scene_become_ladders_in_the_budget() {
    let mut app = App::new();
    app.add_plugins(
        windowless::windowless_plugins(
            DefaultPlugins.build().disable::<bevy::winit::WinitPlugin>(),
        )
        .disable::<LogPlugin>(),
    )
    .add_plugins(SherwoodPlugins);
    windowless::finish_plugins(&mut app);
    let world = app.world_mut();
    let scene = world
        .resource::<AssetServer>()
        .load(GltfAssetLabel::Scene(0).from_asset("props/rocks.glb"));
    world.spawn((
        WorldAssetRoot(scene),
        LadderFromLodNames,
        Transform::default(),
    ));
    let image = Image::new_target_texture(
        320,
        180,
        bevy::render::render_resource::TextureFormat::Rgba8UnormSrgb,
        None,
    );
    let image = world.resource_mut::<Assets<Image>>().add(image);
    world.spawn((
        Camera3d::default(),
        bevy::camera::RenderTarget::Image(image.into()),
        Msaa::Off,
        Transform::from_xyz(21.0, 12.0, -15.0).looking_at(Vec3::new(21.0, 0.0, 12.0), Vec3::Y),
    ));
    world.spawn(DirectionalLight::default());
    *world.resource_mut::<FrameBudget>() = FrameBudget {
        target_ms: 1_000.0,
        ..default()
    };
    let mut ladders = 0;
    for _ in 0..600 {
        app.update();
        let world = app.world_mut();
        ladders = world.query::<&LodLadder>().iter(world).count();
        if ladders == 40
            && app
                .world()
                .resource::<LadderDiagnostics>()
                .shown_per_level
                .iter()
                .sum::<u32>()
                > 0
        {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    assert_eq!(ladders, 40, "rocks found as ladders");
    let world = app.world_mut();
    for ladder in world.query::<&LodLadder>().iter(world) {
        let triangles: Vec<u32> = ladder.levels().iter().map(|l| l.triangles).collect();
        assert_eq!(triangles, [9000, 1000, 130]);
    }
    // The levels not shown are hidden: one mesh per rock is visible.
    let shown = world
        .query::<(&Name, &Visibility)>()
        .iter(world)
        .filter(|(name, v)| name.as_str().contains("_LOD") && **v != Visibility::Hidden)
        .count();
    assert_eq!(shown, 40, "LOD nodes visible");
    // The budget chose their levels, and priced their pixels.
    let d = app.world().resource::<LodDiagnostics>();
    assert!(
        d.calibrated.meshes > 0.0 && d.calibrated.mesh_pixels > 0.0,
        "{:?}",
        d.calibrated
    );
    let levels = &app.world().resource::<LadderDiagnostics>().shown_per_level;
    assert!(levels.iter().sum::<u32>() > 0, "{levels:?}");
}
