//! The instance table: every `TreeInstance`, whoever spawned it, is culled, budgeted and
//! drawn; moved trees are culled where they are; removed ones leave the table.

use crate::testing as common;

use crate::culling::{ForestCulling, InstanceVisibility};
use crate::draw::TreeDrawList;
use crate::prelude::*;
use bevy::prelude::*;

const EYE: Vec3 = Vec3::new(-5.0, 20.0, -5.0);

/// The default ecosystem with `trees` trees, its seed moved by `seed_offset`.
fn other_forest(trees: u32, seed_offset: u64) -> crate::ecosystem::EcosystemDesc {
    let mut desc = common::default_ecosystem();
    desc.set_total_trees(trees)
        .expect("the default forest has trees to scale");
    desc.seed = desc.seed.wrapping_add(seed_offset);
    desc
}

struct Scene {
    app: App,
    /// The second ecosystem's forest entity.
    second: Entity,
    /// The tree placed by hand.
    hand: Entity,
    /// Where the hand-placed tree stands, near where the view looks.
    target: Vec3,
}

/// The default forest, a second (smaller, other seed) ecosystem over the same ground, and
/// one tree placed by hand where the view looks.
fn scene() -> Scene {
    let (mut app, size) = common::forest_of(600);
    let second = common::spawn_forest(&mut app, other_forest(40, 1));
    let look_at = Vec3::new(size / 2.0, 0.0, size / 2.0);
    // Off the middle, which is a boundary of the hierarchy's cells.
    let target = look_at + Vec3::new(3.1, 0.0, 2.3);
    let hand = common::plant(&mut app, "broad", target);
    common::look_from(&mut app, EYE, look_at);
    common::until_visible(&mut app);
    // Both forests spawned and every model loaded.
    for _ in 0..2_000 {
        let table = app.world().resource::<ForestInstances>();
        let culling = app.world().resource::<ForestCulling>();
        if table.len() > 600 + 1 && culling.models_loading() == 0 {
            break;
        }
        app.update();
    }
    app.update();
    Scene {
        app,
        second,
        hand,
        target,
    }
}

fn visibility(app: &App, entity: Entity) -> InstanceVisibility {
    let i = app
        .world()
        .resource::<ForestInstances>()
        .index_of(entity)
        .expect("in the instance table") as usize;
    app.world().resource::<ForestCulling>().result.visibility[i]
}

fn draws(app: &App, entity: Entity) -> bool {
    app.world()
        .get::<TreeDrawList>(entity)
        .is_some_and(|list| !list.is_empty())
}

#[test]
fn trees_of_a_second_ecosystem_and_a_hand_placed_tree_are_culled_budgeted_and_drawn() {
    let Scene {
        mut app,
        second,
        hand,
        ..
    } = scene();
    let mut query = app.world_mut().query::<(Entity, &TreeInstance)>();
    let second_trees: Vec<Entity> = query
        .iter(app.world())
        .filter(|(_, tree)| tree.forest == second)
        .map(|(entity, _)| entity)
        .collect();
    assert_eq!(second_trees.len(), 40);
    let table = app.world().resource::<ForestInstances>();
    assert_eq!(table.len(), 600 + 40 + 1);
    assert!(second_trees.iter().all(|&e| table.index_of(e).is_some()));
    assert!(table.index_of(hand).is_some());

    assert_ne!(visibility(&app, hand), InstanceVisibility::Invisible);
    assert!(draws(&app, hand), "the hand-placed tree is not drawn");
    let seen: Vec<Entity> = second_trees
        .iter()
        .copied()
        .filter(|&e| visibility(&app, e) != InstanceVisibility::Invisible)
        .collect();
    assert!(!seen.is_empty(), "no tree of the second forest is in view");
    assert!(
        seen.iter().all(|&e| draws(&app, e)),
        "a visible tree of the second forest is not drawn"
    );
    // Both have a share of the frame: the budget saw them as objects like the others.
    let diagnostics = app.world().resource::<LodDiagnostics>();
    assert_eq!(diagnostics.undrawn, 0, "{diagnostics:?}");
    assert!(diagnostics.visible_instances as usize > seen.len());
}

#[test]
fn a_moved_tree_is_culled_where_it_now_stands() {
    let Scene {
        mut app,
        hand,
        target,
        ..
    } = scene();
    let (rebuilds, refits) = app
        .world()
        .resource::<ForestCulling>()
        .rebuilds_and_refits();
    // Behind the camera: out of view, and out of its leaf box.
    let behind = EYE + (EYE - target).normalize() * 30.0;
    app.world_mut()
        .get_mut::<Transform>(hand)
        .unwrap()
        .translation = behind;
    app.update();
    assert_eq!(visibility(&app, hand), InstanceVisibility::Invisible);
    assert!(!draws(&app, hand), "a tree out of view still draws");
    let index = app
        .world()
        .resource::<ForestInstances>()
        .index_of(hand)
        .unwrap() as usize;
    let culled_at = app.world().resource::<ForestCulling>().instances[index]
        .transform
        .translation;
    assert_eq!(Vec3::from(culled_at), behind);
    // Back, and a small step within its box: refitted, not rebuilt.
    app.world_mut()
        .get_mut::<Transform>(hand)
        .unwrap()
        .translation = target;
    app.update();
    assert_ne!(visibility(&app, hand), InstanceVisibility::Invisible);
    assert!(draws(&app, hand));
    let after_return = app
        .world()
        .resource::<ForestCulling>()
        .rebuilds_and_refits();
    app.world_mut()
        .get_mut::<Transform>(hand)
        .unwrap()
        .translation = target + Vec3::X * 0.01;
    app.update();
    let after_step = app
        .world()
        .resource::<ForestCulling>()
        .rebuilds_and_refits();
    assert_eq!(
        after_step.0, after_return.0,
        "a small step rebuilt the hierarchy"
    );
    assert_eq!(
        after_step.1,
        after_return.1 + 1,
        "a small step was not refitted"
    );
    assert!(after_return.0 + after_return.1 > rebuilds + refits);
    // The layout (every other index) did not change for a move.
    assert_eq!(
        app.world()
            .resource::<ForestInstances>()
            .index_of(hand)
            .unwrap() as usize,
        index
    );
}

#[test]
fn a_removed_tree_leaves_the_table() {
    let Scene { mut app, hand, .. } = scene();
    let before = app.world().resource::<ForestInstances>().len();
    let layout = app.world().resource::<ForestInstances>().layout_version();
    app.world_mut().despawn(hand);
    app.update();
    let table = app.world().resource::<ForestInstances>();
    assert_eq!(table.len(), before - 1);
    assert_eq!(table.index_of(hand), None);
    assert_ne!(table.layout_version(), layout);
    assert!(!table.entities.contains(&hand));
    let culling = app.world().resource::<ForestCulling>();
    assert_eq!(culling.result.visibility.len(), before - 1);
    assert_eq!(culling.layout_version(), Some(table.layout_version()));
    assert_eq!(app.world().resource::<LodDiagnostics>().undrawn, 0);
}

#[test]
fn a_tree_with_a_fixed_draw_list_is_left_alone() {
    let Scene {
        mut app, target, ..
    } = scene();
    let model = app
        .world()
        .resource::<AssetServer>()
        .load("species/broad.species.ron");
    let list = TreeDrawList {
        trunk_triangles: 0..3,
        ..Default::default()
    };
    // Far outside the view: culling would make it draw nothing.
    let fixed = app
        .world_mut()
        .spawn((
            TreeInstance::standalone(model),
            FixedDrawList,
            list.clone(),
            Transform::from_translation(target + Vec3::Y * 10_000.0),
        ))
        .id();
    // Without a list of its own it is drawn in full: nothing gives it an empty one.
    let listless = common::plant(&mut app, "broad", target);
    app.world_mut().entity_mut(listless).insert(FixedDrawList);
    app.update();
    app.update();
    assert_eq!(
        app.world().resource::<ForestInstances>().index_of(fixed),
        None
    );
    assert_eq!(app.world().get::<TreeDrawList>(fixed), Some(&list));
    assert_eq!(app.world().get::<TreeDrawList>(listless), None);
}

/// On a real adapter: a hand-placed tree and the trees of two ecosystems reach the forest
/// pass, each drawn from the list the budget gave it.
#[cfg(feature = "gpu-tests")]
#[test]
fn the_forest_pass_draws_every_producers_trees() {
    use crate::testing as windowless;
    use bevy::log::LogPlugin;

    let mut app = App::new();
    app.add_plugins(
        windowless::windowless_plugins(
            DefaultPlugins.build().disable::<bevy::winit::WinitPlugin>(),
        )
        .disable::<LogPlugin>(),
    )
    .add_plugins(SherwoodPlugins);
    windowless::finish_plugins(&mut app);
    let forests: Vec<Entity> = (0..2)
        .map(|seed_offset| common::spawn_forest(&mut app, other_forest(30, seed_offset)))
        .collect();
    let look_at = Vec3::new(100.0, 0.0, 100.0);
    let hand = common::plant(&mut app, "broad", look_at);
    common::image_camera(&mut app, Vec3::new(-20.0, 40.0, -20.0), look_at);

    let drawing = |app: &mut App| {
        let mut query = app
            .world_mut()
            .query::<(Entity, &TreeInstance, &TreeDrawList)>();
        query
            .iter(app.world())
            .filter(|(_, _, list)| !list.is_empty())
            .map(|(entity, tree, _)| (entity, tree.forest))
            .collect::<Vec<_>>()
    };
    let mut drawn = Vec::new();
    for _ in 0..3_000 {
        app.update();
        let loading = app.world().resource::<ForestCulling>().models_loading();
        drawn = drawing(&mut app);
        let stats = app.world().resource::<ForestRenderStats>();
        if loading == 0 && !drawn.is_empty() && stats.instances as usize == drawn.len() {
            break;
        }
    }
    let stats = app.world().resource::<ForestRenderStats>().clone();
    assert_eq!(stats.instances as usize, drawn.len(), "{stats:?}");
    assert!(
        drawn.iter().any(|&(e, _)| e == hand),
        "the hand-placed tree is not drawn"
    );
    for &forest in &forests {
        assert!(
            drawn.iter().any(|&(_, f)| f == forest),
            "no tree of forest {forest:?} is drawn"
        );
    }
    // And on screen: taking each producer's trees away (not its terrain) changes the
    // picture.
    let mut before = common::screenshot(&mut app);
    for (what, producer) in [
        ("the hand-placed tree", None),
        ("the first forest's trees", Some(forests[0])),
        ("the second forest's trees", Some(forests[1])),
    ] {
        let trees: Vec<Entity> = match producer {
            None => vec![hand],
            Some(forest) => drawn
                .iter()
                .filter(|&&(e, f)| f == forest && e != hand)
                .map(|&(e, _)| e)
                .collect(),
        };
        for tree in trees {
            app.world_mut().entity_mut(tree).despawn();
        }
        for _ in 0..4 {
            app.update();
        }
        let after = common::screenshot(&mut app);
        let changed = before
            .chunks(4)
            .zip(after.chunks(4))
            .filter(|(a, b)| a != b)
            .count();
        assert!(changed > 20, "{changed} pixels changed without {what}");
        before = after;
    }
}
