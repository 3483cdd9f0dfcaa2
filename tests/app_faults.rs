//! What an app does through the ECS to the plugin — despawns in the middle of a frame, a
//! forest despawned, trees sent to NaN or to infinity, settings typed into an inspector —
//! in a headless app: each is survived with the forest drawn and the model learning.

mod common;

use bevy::prelude::*;
use bevy_sherwood::cost::{CostModel, CostSettings, FrameSamples, LearningRates};
use bevy_sherwood::prelude::*;

/// A headless forest of `trees` trees, seen from its corner, its trees in view.
fn forest_in_view(trees: u32) -> (App, Entity, f32) {
    let (mut app, size) = common::forest_of(trees);
    let forest = app
        .world_mut()
        .query_filtered::<Entity, With<Forest>>()
        .single(app.world())
        .unwrap();
    common::look_from(
        &mut app,
        Vec3::new(-0.1 * size, 20.0, -0.1 * size),
        Vec3::new(0.5 * size, 0.0, 0.5 * size),
    );
    common::until_visible(&mut app);
    (app, forest, size)
}

fn trees_in(app: &mut App) -> usize {
    app.world_mut()
        .query::<&TreeInstance>()
        .iter(app.world())
        .count()
}

/// Despawns every tree the frame it is spawned, queued before the Value stage gives it its
/// draw list (as a game despawning what it just spawned does): the list's insertion must
/// not panic on a tree that is gone.
#[test]
fn a_tree_despawned_in_the_frame_it_was_spawned_does_not_panic() {
    #[derive(Component)]
    struct Doomed;
    fn despawn_new_trees(
        mut commands: Commands,
        new: Query<Entity, (Added<TreeInstance>, With<Doomed>)>,
    ) {
        for tree in &new {
            commands.entity(tree).despawn();
        }
    }
    let (mut app, _, size) = forest_in_view(60);
    let before = trees_in(&mut app);
    app.add_systems(
        PostUpdate,
        despawn_new_trees
            .after(SherwoodSystems::Cull)
            .before_ignore_deferred(SherwoodSystems::Value),
    );
    for k in 0..3 {
        let tree = common::plant(
            &mut app,
            "broad",
            Vec3::new(0.3 * size, 0.0, 0.3 * size + k as f32),
        );
        app.world_mut().entity_mut(tree).insert(Doomed);
        app.update();
    }
    assert_eq!(trees_in(&mut app), before);
    assert!(app.world().resource::<LodDiagnostics>().visible_instances > 0);
}

/// Despawning a `Forest` despawns its trees and its terrain; a forest spawned again is
/// drawn.
#[test]
fn despawning_a_forest_despawns_its_trees() {
    let (mut app, forest, _) = forest_in_view(60);
    assert!(trees_in(&mut app) > 0);
    app.world_mut().entity_mut(forest).despawn();
    app.update();
    app.update();
    assert_eq!(trees_in(&mut app), 0, "the forest's trees outlived it");
    let terrains = app
        .world_mut()
        .query::<&bevy_sherwood::ecosystem::ForestTerrain>()
        .iter(app.world())
        .count();
    assert_eq!(terrains, 0, "the forest's terrain outlived it");
    assert!(app.world().resource::<ForestInstances>().is_empty());
    assert_eq!(
        app.world().resource::<LodDiagnostics>().visible_instances,
        0
    );
}

/// One tree at NaN and one at infinity beside the forest (a physics step gone wrong):
/// both are left out of the instance table, every other tree is culled, valued and drawn
/// as before, and a tree moved back to a real place comes back.
#[test]
fn trees_at_nan_and_at_infinity_leave_the_forest_drawn() {
    let (mut app, _, size) = forest_in_view(120);
    for _ in 0..5 {
        app.update();
    }
    let visible = app.world().resource::<LodDiagnostics>().visible_instances;
    let in_table = app.world().resource::<ForestInstances>().len();
    let nan = common::plant(&mut app, "broad", Vec3::NAN);
    let far = common::plant(&mut app, "broad", Vec3::new(f32::INFINITY, 0.0, 0.0));
    let huge = common::plant(&mut app, "broad", Vec3::new(0.0, 0.0, 1e30));
    for _ in 0..5 {
        app.update();
    }
    let table = app.world().resource::<ForestInstances>();
    assert_eq!(
        table.len(),
        in_table,
        "a tree that cannot be placed is in the table"
    );
    for tree in [nan, far, huge] {
        assert!(table.index_of(tree).is_none());
    }
    let diagnostics = app.world().resource::<LodDiagnostics>();
    assert_eq!(diagnostics.visible_instances, visible);
    assert!(diagnostics.predicted_frame_ms.is_finite());
    // Back in the forest, in view: in the table again.
    app.world_mut()
        .entity_mut(nan)
        .insert(Transform::from_translation(Vec3::new(
            0.4 * size,
            0.0,
            0.4 * size,
        )));
    for _ in 0..3 {
        app.update();
    }
    let table = app.world().resource::<ForestInstances>();
    assert_eq!(table.len(), in_table + 1);
    assert!(table.index_of(nan).is_some());
    // And out again when it moves to NaN.
    app.world_mut()
        .entity_mut(nan)
        .insert(Transform::from_translation(Vec3::NAN));
    app.update();
    assert!(
        app.world()
            .resource::<ForestInstances>()
            .index_of(nan)
            .is_none()
    );
}

/// Learning rates of NaN or 0 typed into an inspector: the model keeps learning (it is
/// not reset every frame) with usable rates.
#[test]
fn unusable_learning_rates_do_not_stop_the_learning() {
    for bad in [f32::NAN, 0.0, f32::INFINITY, -1.0] {
        let (mut app, _, _) = forest_in_view(60);
        app.world_mut().resource_mut::<CostSettings>().rates = LearningRates {
            costs_seconds: bad,
            speed_seconds: bad,
        };
        app.update();
        for _ in 0..30 {
            let p = common::predicted_frame(&mut app);
            // A machine twice as slow as the calibration says.
            let render = 2.0 * p.render;
            let sample = bevy_sherwood::cost::FrameSample {
                frame: p.frame,
                logic: 0.005,
                render,
                interval: render + 0.006,
                complete: true,
                ..Default::default()
            };
            app.world_mut().resource_mut::<FrameSamples>().push(sample);
        }
        app.update();
        let learned = app.world().resource::<CostModel>().learned();
        assert!(
            learned.frames_learned >= 20,
            "rates {bad}: {} frames learned",
            learned.frames_learned
        );
        assert!(learned.scales.triangles.is_finite(), "rates {bad}");
    }
}

/// Both importances 0 would leave every tree at its cheapest whatever the time; they are
/// taken as the defaults, and the selection is the default's (within what the measured
/// logic time, which the budget takes off, moves it from frame to frame).
#[test]
fn importances_that_value_nothing_fall_back_to_the_defaults() {
    let (mut app, _, _) = forest_in_view(60);
    app.world_mut().resource_mut::<CostSettings>().online = false;
    app.world_mut().resource_mut::<WindSettings>().enabled = false;
    app.world_mut().resource_mut::<FrameBudget>().target_ms = 60.0;
    for _ in 0..3 {
        app.update();
    }
    let triangles = |app: &App| app.world().resource::<LodDiagnostics>().counts.triangles;
    let defaults = triangles(&app);
    for [trunk, leaves] in [[0.0, 0.0], [f32::NAN, f32::NAN], [-1.0, -1.0]] {
        {
            let mut budget = app.world_mut().resource_mut::<FrameBudget>();
            budget.trunk_importance = trunk;
            budget.leaf_importance = leaves;
        }
        for _ in 0..3 {
            app.update();
        }
        let got = triangles(&app);
        assert!(
            got.abs_diff(defaults) * 20 <= defaults,
            "importances {trunk}, {leaves}: {got} triangles, the defaults {defaults}"
        );
    }
}

/// A tree whose model never loads (a handle nothing will ever fill) is named once it has
/// been loading for `LOADING_WARNING_SECS`, and the forest beside it is drawn.
#[test]
fn a_model_that_never_loads_is_reported() {
    use bevy::time::TimeUpdateStrategy;
    use bevy_sherwood::culling::{ForestCulling, LOADING_WARNING_SECS};
    let (mut app, _, size) = forest_in_view(60);
    app.insert_resource(TimeUpdateStrategy::ManualDuration(
        std::time::Duration::from_millis(500),
    ));
    let never = app.world().resource::<Assets<TreeModel>>().reserve_handle();
    app.world_mut().spawn((
        TreeInstance::new(never),
        Transform::from_xyz(0.5 * size, 0.0, 0.5 * size),
    ));
    let stuck = |app: &App| {
        app.world()
            .resource::<ForestCulling>()
            .models_stuck_loading()
    };
    let updates = (LOADING_WARNING_SECS / 0.5) as usize;
    for _ in 0..updates / 2 {
        app.update();
    }
    assert_eq!(stuck(&app), 0, "reported before its time");
    for _ in 0..updates {
        app.update();
    }
    assert_eq!(stuck(&app), 1);
    assert!(app.world().resource::<LodDiagnostics>().visible_instances > 0);
}
