//! A headless app: a forest spawned from the default ecosystem file, culled against a
//! view, respawned on change.

use crate::testing as common;

use crate::culling::CullView;
use crate::culling::ForestCulling;
use crate::culling::{CullResult, FrustumPlanes, MovedShapes, cull_brute_force};
use crate::ecosystem::{ForestState, ForestTerrain};
use crate::prelude::*;
use bevy::prelude::*;

fn app() -> App {
    common::headless_app()
}

/// Updates until the culling hierarchy exists (bounded).
fn until_culled(app: &mut App) {
    for _ in 0..3000 {
        app.update();
        let culling = app.world().resource::<ForestCulling>();
        if culling.hierarchy.is_some() && culling.models_loading() == 0 {
            return;
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    panic!("the forest never finished loading");
}

/// Where the wind tests look from: across the forest from just outside a corner, so trees
/// are from ~10 m to a forest side away.
const CORNER_EYE: Vec3 = Vec3::new(-5.0, 20.0, -5.0);

/// A forest of `trees` seen from [`CORNER_EYE`], visible, with 1/20 s per update.
fn forest_in_wind(trees: u32) -> App {
    let (mut app, size) = common::forest_of(trees);
    app.insert_resource(bevy::time::TimeUpdateStrategy::ManualDuration(
        std::time::Duration::from_millis(50),
    ));
    common::look_from(&mut app, CORNER_EYE, Vec3::new(size / 2.0, 0.0, size / 2.0));
    common::until_visible(&mut app);
    app
}

/// Two seconds of wind.
fn blow(app: &mut App) {
    for _ in 0..40 {
        app.update();
    }
}

/// Edits the default spring set in place.
fn edit_spring_set(app: &mut App, edit: impl FnOnce(&mut crate::wind::SpringSet)) {
    let set = app.world().resource::<WindSettings>().sets[0].clone();
    edit(
        &mut app
            .world_mut()
            .resource_mut::<Assets<crate::wind::SpringSet>>()
            .get_mut(&set)
            .unwrap(),
    );
}

fn count<C: Component>(app: &mut App) -> usize {
    app.world_mut().query::<&C>().iter(app.world()).count()
}

#[test]
fn forest_spawns_culls_and_respawns() {
    let mut app = app();
    let handle = app
        .world()
        .resource::<AssetServer>()
        .load("forests/default.ecosystem.ron");
    let forest = app.world_mut().spawn(Forest(handle.clone())).id();
    let view = Mat4::perspective_infinite_reverse_rh(1.0, 16.0 / 9.0, 0.1)
        * Mat4::look_at_rh(
            Vec3::new(100.0, 10.0, 100.0),
            Vec3::new(200.0, 5.0, 100.0),
            Vec3::Y,
        );
    let planes = FrustumPlanes::from_clip_from_world(view);
    app.world_mut().spawn(CullView(planes));
    until_culled(&mut app);
    app.update();

    assert_eq!(count::<TreeInstance>(&mut app), 600);
    assert_eq!(count::<ForestTerrain>(&mut app), 1);
    let culling = app.world().resource::<ForestCulling>();
    assert_eq!(culling.result.visibility.len(), 600);
    let mut reference = CullResult::default();
    cull_brute_force(
        &planes,
        &culling.instances,
        &culling.shapes,
        &MovedShapes::default(),
        &mut reference,
    );
    let visible = |r: &CullResult| (0..600).filter(|&i| r.trunk_visible(i)).count();
    assert_eq!(visible(&culling.result), visible(&reference));
    assert!(
        visible(&reference) > 50 && visible(&reference) < 600,
        "{}",
        visible(&reference)
    );

    // An edit respawns the forest with nothing stale left behind.
    let generation = app.world().get::<ForestState>(forest).unwrap().generation;
    app.world_mut()
        .resource_mut::<Assets<Ecosystem>>()
        .get_mut(&handle)
        .unwrap()
        .0
        .species[0]
        .count = 100;
    until_culled(&mut app);
    for _ in 0..3 {
        app.update();
    }
    assert_eq!(count::<TreeInstance>(&mut app), 500);
    assert_eq!(count::<ForestTerrain>(&mut app), 1);
    assert_eq!(
        app.world().get::<ForestState>(forest).unwrap().generation,
        generation + 1
    );
    assert_eq!(app.world().resource::<ForestInstances>().len(), 500);

    // An edit that cannot be laid out leaves the previous forest standing.
    app.world_mut()
        .resource_mut::<Assets<Ecosystem>>()
        .get_mut(&handle)
        .unwrap()
        .0
        .species[1]
        .scale = (2.0, 1.0);
    for _ in 0..3 {
        app.update();
    }
    assert_eq!(count::<TreeInstance>(&mut app), 500);
}

#[test]
fn a_species_that_fails_to_load_does_not_hold_the_forest_back() {
    let mut app = app();
    let mut desc = common::default_ecosystem();
    desc.species[1].tree = "species/missing.species.ron".into();
    common::spawn_forest(&mut app, desc);
    let view = Mat4::perspective_infinite_reverse_rh(1.2, 1.0, 0.1)
        * Mat4::look_at_rh(
            Vec3::new(100.0, 400.0, 100.01),
            Vec3::new(100.0, 0.0, 100.0),
            Vec3::Y,
        );
    app.world_mut()
        .spawn(CullView(FrustumPlanes::from_clip_from_world(view)));
    until_culled(&mut app);
    app.update();
    let culling = app.world().resource::<ForestCulling>();
    let visible = culling
        .result
        .visibility
        .iter()
        .filter(|v| **v != crate::culling::InstanceVisibility::Invisible)
        .count();
    assert_eq!(
        visible, 400,
        "the two species that loaded are seen from above; the missing one is not"
    );
}

#[test]
fn wind_moves_visible_trees_only_and_can_be_turned_off() {
    use crate::wind::{RingOffsetTable, WindSettings, WindStats};
    use bevy::time::TimeUpdateStrategy;

    let mut app = app();
    app.insert_resource(TimeUpdateStrategy::ManualDuration(
        std::time::Duration::from_millis(50),
    ));
    let handle = app
        .world()
        .resource::<AssetServer>()
        .load("forests/default.ecosystem.ron");
    app.world_mut().spawn(Forest(handle));
    let view = Mat4::perspective_infinite_reverse_rh(1.0, 16.0 / 9.0, 0.1)
        * Mat4::look_at_rh(
            Vec3::new(100.0, 10.0, 100.0),
            Vec3::new(200.0, 5.0, 100.0),
            Vec3::Y,
        );
    app.world_mut()
        .spawn(CullView(FrustumPlanes::from_clip_from_world(view)));
    until_culled(&mut app);
    for _ in 0..40 {
        app.update(); // two seconds of wind
    }
    let culling = app.world().resource::<ForestCulling>();
    let table = app.world().resource::<RingOffsetTable>();
    assert_eq!(table.len(), 600);
    let moves = |i: usize| {
        table
            .get(i)
            .is_some_and(|o| o.iter().any(|o| o.length() > 1e-4))
    };
    let visible: Vec<bool> = (0..600)
        .map(|i| culling.result.visibility[i] != crate::culling::InstanceVisibility::Invisible)
        .collect();
    assert!(table.moving() > 0);
    for (i, _) in visible.iter().enumerate().filter(|(_, v)| !**v) {
        assert!(!moves(i), "invisible instance {i} moved");
    }
    assert!((0..600).any(moves));
    // Every moved instance is culled with its moved shape.
    assert_eq!(
        app.world().resource::<MovedShapes>().len(),
        table.moving() as usize
    );
    let stats = *app.world().resource::<WindStats>();
    assert_eq!(stats.moved, table.moving());
    assert_eq!(stats.moved + stats.skipped, stats.candidates);

    app.world_mut().resource_mut::<WindSettings>().enabled = false;
    app.update();
    let table = app.world().resource::<RingOffsetTable>();
    assert_eq!(table.moving(), 0);
    assert!((0..table.len()).all(|i| table.get(i).is_none()));
    assert!(app.world().resource::<MovedShapes>().is_empty());
}

#[test]
fn motion_lod_moves_near_trees_and_leaves_far_ones_still() {
    use crate::wind::{RingOffsetTable, WindStats};

    let mut app = forest_in_wind(600);
    let eye = CORNER_EYE;
    // With the shipped half-pixel threshold every tip of this forest moves a visible
    // amount; a coarser threshold puts the boundary inside it.
    edit_spring_set(&mut app, |set| set.pixel_threshold = 6.0);
    blow(&mut app);
    let stats = *app.world().resource::<WindStats>();
    assert!(stats.moved > 0 && stats.skipped > 0, "{stats:?}");
    let table = app.world().resource::<RingOffsetTable>().clone();
    assert_eq!(table.moving(), stats.moved);
    let state = app
        .world_mut()
        .query::<&ForestState>()
        .single(app.world())
        .unwrap()
        .clone();
    let (mut moved, mut still) = (Vec::new(), Vec::new());
    let culling = app.world().resource::<ForestCulling>();
    for (i, entity) in state.instances.iter().enumerate() {
        if culling.result.visibility[i] == crate::culling::InstanceVisibility::Invisible {
            continue;
        }
        let distance = app
            .world()
            .get::<GlobalTransform>(*entity)
            .unwrap()
            .translation()
            .distance(eye);
        let offsets = table.get(i).unwrap_or_default();
        if app.world().resource::<MovedShapes>().get(i).is_some() {
            moved.push(distance);
        } else {
            assert!(
                offsets.iter().all(|o| *o == Vec3A::ZERO),
                "still tree {i} moved"
            );
            still.push(distance);
        }
    }
    let mean = |v: &[f32]| v.iter().sum::<f32>() / v.len() as f32;
    assert_eq!(moved.len(), stats.moved as usize);
    assert!(
        mean(&moved) < 0.5 * mean(&still),
        "moved trees are {} m away on average, still ones {} m",
        mean(&moved),
        mean(&still)
    );
}

#[test]
fn edited_association_rules_take_effect_on_the_next_frame() {
    use crate::wind::RingOffsetTable;

    let mut app = forest_in_wind(60);
    blow(&mut app);
    let moves = |app: &App| {
        let table = app.world().resource::<RingOffsetTable>();
        (0..table.len()).any(|i| {
            table
                .get(i)
                .is_some_and(|o| o.iter().any(|o| *o != Vec3A::ZERO))
        })
    };
    assert!(moves(&app));
    // Rings follow 0% of their spring from now on.
    edit_spring_set(&mut app, |set| {
        for rule in &mut set.rules {
            rule.influence = 0.0;
        }
    });
    app.update();
    assert!(!moves(&app), "the rings still follow the old rules");
}

#[test]
fn slowly_moving_trees_are_updated_less_often_and_hold_their_bend_in_between() {
    use crate::wind::{RingOffsetTable, WindSettings, WindStats};

    let mut app = forest_in_wind(600);
    // Every moving tree computes its own offsets here (no borrowed sway).
    app.world_mut()
        .resource_mut::<WindSettings>()
        .shared_sway_pixels = 0.0;
    blow(&mut app);
    let slices = |app: &App| {
        let table = app.world().resource::<RingOffsetTable>();
        (0..table.len())
            .map(|i| table.get(i).unwrap_or_default().to_vec())
            .collect::<Vec<_>>()
    };
    let moving = |app: &App| {
        let moved = app.world().resource::<MovedShapes>();
        (0..app.world().resource::<ForestInstances>().len())
            .map(|i| moved.get(i).is_some())
            .collect::<Vec<_>>()
    };
    let interval = app.world().resource::<WindSettings>().max_update_interval as usize;
    let mut before = slices(&app);
    let mut moving_throughout = moving(&app);
    let mut changed_ever = vec![false; before.len()];
    for _ in 0..interval {
        app.update();
        let stats = *app.world().resource::<WindStats>();
        let now = slices(&app);
        let changed: Vec<bool> = now.iter().zip(&before).map(|(a, b)| a != b).collect();
        // An instance's offsets change exactly when it is updated (the wind never stops
        // here), and the rest hold theirs.
        assert_eq!(
            changed.iter().filter(|c| **c).count(),
            stats.updated as usize,
            "{stats:?}"
        );
        assert_eq!(stats.updated + stats.held, stats.moved);
        assert!(stats.held > 0 && stats.updated > 0, "{stats:?}");
        // Staggered: no frame updates every moving tree.
        assert!(stats.updated < stats.moved, "{stats:?}");
        for (i, m) in moving(&app).into_iter().enumerate() {
            moving_throughout[i] &= m;
            changed_ever[i] |= changed[i];
        }
        before = now;
    }
    // Over the longest interval, every tree that kept moving was updated at least once.
    for (i, _) in moving_throughout.iter().enumerate().filter(|(_, m)| **m) {
        assert!(changed_ever[i], "moving instance {i} was never updated");
    }

    // Turned off, every moving tree is updated every frame.
    app.world_mut()
        .resource_mut::<WindSettings>()
        .full_rate_pixels = 0.0;
    for _ in 0..3 {
        app.update();
        let stats = *app.world().resource::<WindStats>();
        assert!(stats.moved > 0);
        assert_eq!((stats.updated, stats.held), (stats.moved, 0), "{stats:?}");
    }
}

#[test]
fn far_trees_borrow_a_representative_s_sway_and_near_ones_compute_their_own() {
    use crate::wind::{RingOffsetTable, WindSettings, WindStats};

    let mut app = forest_in_wind(600);
    blow(&mut app);
    let distance_of = |app: &mut App, i: usize| {
        let state = app
            .world_mut()
            .query::<&ForestState>()
            .single(app.world())
            .unwrap();
        let entity = state.instances[i];
        app.world()
            .get::<GlobalTransform>(entity)
            .unwrap()
            .translation()
            .distance(CORNER_EYE)
    };
    let mut offsets_before: Vec<Option<Vec<Vec3A>>> = Vec::new();
    let mut changed = Vec::new();
    for frame in 0..=8 {
        app.update();
        let stats = *app.world().resource::<WindStats>();
        assert!(stats.shared > 0 && stats.updated > 0, "{stats:?}");
        assert_eq!(stats.updated + stats.held + stats.shared, stats.moved);
        // Fewer blocks computed than trees swaying with them.
        assert!(stats.shared_updated < stats.shared, "{stats:?}");
        let table = app.world().resource::<RingOffsetTable>().clone();
        let n = app.world().resource::<ForestInstances>().len();
        let shared: Vec<usize> = (0..n).filter(|&i| table.is_shared(i)).collect();
        assert_eq!(shared.len(), stats.shared as usize);
        let blocks: std::collections::HashSet<u32> = shared
            .iter()
            .map(|&i| table.block(i, table.get(i).unwrap().len() as u32).unwrap())
            .collect();
        assert!(blocks.len() < shared.len(), "{} blocks", blocks.len());
        // Every moving tree is culled with a moved shape, its own or its block's.
        let moved = app.world().resource::<MovedShapes>().clone();
        assert_eq!(
            (0..n).filter(|&i| moved.get(i).is_some()).count(),
            table.moving() as usize
        );
        let now: Vec<Option<Vec<Vec3A>>> =
            (0..n).map(|i| table.get(i).map(<[_]>::to_vec)).collect();
        if frame == 0 {
            let own: Vec<usize> = (0..n)
                .filter(|&i| table.get(i).is_some() && !table.is_shared(i))
                .collect();
            let mean = |app: &mut App, v: &[usize]| {
                v.iter().map(|&i| distance_of(app, i)).sum::<f32>() / v.len() as f32
            };
            let (near, far) = (mean(&mut app, &own), mean(&mut app, &shared));
            assert!(
                near < far,
                "own-sway trees {near} m away, borrowing ones {far} m"
            );
            changed = vec![false; n];
        } else {
            for i in shared {
                changed[i] |= now[i] != offsets_before[i];
            }
        }
        offsets_before = now;
    }
    // A borrowed sway is not frozen: over the longest update interval it moved.
    let table = app.world().resource::<RingOffsetTable>();
    let still_shared = (0..changed.len()).filter(|&i| table.is_shared(i));
    for i in still_shared {
        assert!(changed[i], "borrowing instance {i} never moved");
    }

    // Off: every moving tree computes its own again.
    app.world_mut()
        .resource_mut::<WindSettings>()
        .shared_sway_pixels = 0.0;
    app.update();
    let stats = *app.world().resource::<WindStats>();
    let table = app.world().resource::<RingOffsetTable>();
    assert_eq!(stats.shared, 0);
    assert!((0..table.len()).all(|i| !table.is_shared(i)));
    assert_eq!(
        app.world().resource::<MovedShapes>().len(),
        table.moving() as usize
    );
}
