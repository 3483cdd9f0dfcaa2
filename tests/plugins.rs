//! Headless app tests of the plugin wiring.

use std::sync::{Arc, Mutex};

use bevy::prelude::*;
use bevy_sherwood::prelude::*;

type Log = Arc<Mutex<Vec<SherwoodSystems>>>;

fn recorder(log: Log, stage: SherwoodSystems) -> impl FnMut() {
    move || log.lock().unwrap().push(stage)
}

#[test]
fn stages_run_in_order_every_frame() {
    let stages = [
        SherwoodSystems::Instances,
        SherwoodSystems::Animate,
        SherwoodSystems::Cull,
        SherwoodSystems::Value,
        SherwoodSystems::Budget,
        SherwoodSystems::DrawLists,
        SherwoodSystems::Stats,
    ];
    let log: Log = Arc::default();
    let mut app = App::new();
    app.add_plugins((MinimalPlugins, AssetPlugin::default(), SherwoodPlugins));
    // Registered in reverse so that only the set ordering can put them right.
    for stage in stages.iter().rev() {
        app.add_systems(PostUpdate, recorder(log.clone(), *stage).in_set(*stage));
    }
    app.update();
    app.update();
    let seen = log.lock().unwrap().clone();
    let expected: Vec<_> = stages.iter().chain(stages.iter()).copied().collect();
    assert_eq!(seen, expected);
}

#[test]
fn stages_follow_transform_propagation() {
    #[derive(Component)]
    struct Probe;
    #[derive(Resource, Default)]
    struct Seen(Option<Vec3>);

    let mut app = App::new();
    app.add_plugins((
        MinimalPlugins,
        AssetPlugin::default(),
        TransformPlugin,
        SherwoodPlugins,
    ))
    .init_resource::<Seen>()
    .add_systems(
        PostUpdate,
        (|q: Query<&GlobalTransform, With<Probe>>, mut seen: ResMut<Seen>| {
            seen.0 = q.iter().next().map(GlobalTransform::translation);
        })
        .in_set(SherwoodSystems::Value),
    );
    app.world_mut()
        .spawn((Probe, Transform::from_xyz(1.0, 2.0, 3.0)));
    app.update();
    assert_eq!(
        app.world().resource::<Seen>().0,
        Some(Vec3::new(1.0, 2.0, 3.0))
    );
}

#[test]
fn plugin_group_can_leave_a_plugin_out() {
    let mut app = App::new();
    app.add_plugins((
        MinimalPlugins,
        AssetPlugin::default(),
        SherwoodPlugins.build().disable::<SherwoodCorePlugin>(),
    ));
    app.update();
    assert!(!app.is_plugin_added::<SherwoodCorePlugin>());
}

#[test]
#[should_panic(expected = "LodPlugin needs CostPlugin")]
fn a_missing_prerequisite_is_named_at_start_up() {
    let mut app = App::new();
    app.add_plugins((
        MinimalPlugins,
        AssetPlugin::default(),
        SherwoodPlugins.build().disable::<CostPlugin>(),
    ));
    app.finish();
}

#[test]
#[should_panic(expected = "TreePlugin needs Bevy's AssetPlugin")]
fn a_missing_asset_plugin_is_named() {
    App::new().add_plugins((MinimalPlugins, SherwoodPlugins));
}

#[test]
fn calibrations_are_looked_for_in_the_apps_asset_folder() {
    use bevy_sherwood::cost::CalibrationDir;
    let folder = std::env::temp_dir().join("sherwood-assets-elsewhere");
    let mut app = App::new();
    app.add_plugins((
        MinimalPlugins,
        AssetPlugin {
            file_path: folder.to_string_lossy().into_owned(),
            ..default()
        },
        SherwoodPlugins,
    ));
    assert_eq!(
        app.world().resource::<CalibrationDir>().0,
        folder.join("calibration")
    );
    // One inserted first is kept.
    let mine = CalibrationDir(std::env::temp_dir().join("mine"));
    let mut app = App::new();
    app.insert_resource(mine.clone()).add_plugins((
        MinimalPlugins,
        AssetPlugin::default(),
        SherwoodPlugins,
    ));
    assert_eq!(*app.world().resource::<CalibrationDir>(), mine);
}
