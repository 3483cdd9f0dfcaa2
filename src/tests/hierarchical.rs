//! The hierarchical strategy (Mason–Blake over the culling boxes, with group impostors)
//! in a headless app: the default forest against a fixed view.

use crate::testing as common;

use crate::budget::{HierarchicalLod, NodeSelection};
use crate::culling::ForestCulling;
use crate::draw::TreeDrawList;
use crate::lod::{
    GroupImpostorOf, GroupImpostorSettings, GroupImpostors, HierarchicalCut, ImpostorStatus,
    StrategyKind,
};
use crate::prelude::*;
use bevy::prelude::*;

const EYE: Vec3 = Vec3::new(60.0, 14.0, 40.0);
const LOOK_AT: Vec3 = Vec3::new(140.0, 4.0, 120.0);

fn hierarchical(target_ms: f32) -> FrameBudget {
    FrameBudget {
        strategy: StrategyKind::Hierarchical,
        target_ms,
        ..Default::default()
    }
}

fn frame(app: &mut App, budget: FrameBudget) -> LodDiagnostics {
    *app.world_mut().resource_mut::<FrameBudget>() = budget;
    app.update();
    app.world().resource::<LodDiagnostics>().clone()
}

/// The app with its group impostors built and drawn once.
fn app() -> App {
    let mut app = common::default_forest_view(EYE, LOOK_AT, |_| {});
    for _ in 0..3 {
        frame(&mut app, hierarchical(100.0));
    }
    assert!(
        !app.world().resource::<GroupImpostors>().is_empty(),
        "the default forest's upper boxes hold enough trees for groups"
    );
    app
}

/// Per instance of the table: culled visible, drawn on its own, drawn by a group.
fn coverage(app: &mut App) -> Vec<(bool, bool, bool)> {
    let world = app.world_mut();
    let table = world.resource::<ForestInstances>().entities.clone();
    let mut by_group = vec![false; table.len()];
    let mut groups = world.query::<(&GroupImpostorOf, &TreeDrawList)>();
    let drawn_groups: Vec<u32> = groups
        .iter(world)
        .filter(|(_, list)| !list.is_empty())
        .map(|(g, _)| g.node)
        .collect();
    let culling = world.resource::<ForestCulling>();
    let boxes = culling.hierarchy.as_ref().unwrap();
    for node in drawn_groups {
        for &i in boxes.node_instances(node as usize) {
            by_group[i as usize] = true;
        }
    }
    let visible: Vec<bool> = (0..table.len())
        .map(|i| culling.result.visibility[i] != Default::default())
        .collect();
    table
        .iter()
        .enumerate()
        .map(|(i, &e)| {
            let own = world.get::<TreeDrawList>(e).is_some_and(|l| !l.is_empty());
            (visible[i], own, by_group[i])
        })
        .collect()
}

#[test]
fn no_visible_tree_is_left_unrepresented() {
    let mut app = app();
    let mut saw_groups = false;
    // Down and back up again: the cut starts from last frame's either way.
    for target in [5000.0, 200.0, 40.0, 10.0, 2.0, 0.5, 2.0, 10.0, 40.0, 5000.0] {
        // A cut refines by one box level a frame, once the boxes it opens have their
        // children's groups: give a rising target a few frames after they are built.
        let frames = if target >= 5000.0 { 6 } else { 2 };
        let mut d = LodDiagnostics::default();
        let mut in_view = 0;
        let mut settled = 0;
        for _ in 0..300 {
            if settled == frames {
                break;
            }
            d = frame(&mut app, hierarchical(target));
            if !app.world().resource::<GroupImpostors>().building() {
                settled += 1;
            }
            assert_eq!(d.undrawn, 0, "at {target} ms: {d:?}");
            assert!(
                d.trees_drawn + d.impostors_drawn > 0,
                "nothing drawn at {target} ms"
            );
            let seen = coverage(&mut app);
            in_view = seen.iter().filter(|c| c.0).count();
            assert!(in_view > 20);
            for (i, (visible, own, by_group)) in seen.into_iter().enumerate() {
                if visible {
                    assert!(
                        own || by_group,
                        "at {target} ms visible instance {i} is drawn neither on its own nor by a group"
                    );
                }
                // Exactly one representation: never a tree and a group over it.
                assert!(
                    !(own && by_group),
                    "at {target} ms instance {i} is drawn twice"
                );
            }
            saw_groups |= d.impostors_drawn > 0;
        }
        if target >= 5000.0 {
            assert_eq!(
                d.impostors_drawn, 0,
                "time to spare opens every group: {d:?}"
            );
            assert_eq!(d.trees_drawn as usize, in_view);
        }
    }
    assert!(saw_groups, "tight targets draw group impostors");
}

#[test]
fn leaving_the_hierarchical_strategy_draws_every_tree_on_its_own() {
    let others = [
        FrameBudget {
            strategy: StrategyKind::RobinHood,
            target_ms: 2.0,
            ..Default::default()
        },
        // A fixed mode with the strategy still set draws every visible tree too.
        FrameBudget {
            mode: LodMode::Unlimited,
            ..hierarchical(2.0)
        },
    ];
    for other in others {
        let mut app = app();
        let mut d = LodDiagnostics::default();
        for _ in 0..3 {
            d = frame(&mut app, hierarchical(2.0));
        }
        assert!(d.impostors_drawn > 0, "a tight target draws groups: {d:?}");
        for _ in 0..2 {
            d = frame(&mut app, other.clone());
        }
        assert_eq!(d.impostors_drawn, 0, "{other:?}: {d:?}");
        for (i, (visible, own, by_group)) in coverage(&mut app).into_iter().enumerate() {
            assert!(!by_group, "{other:?}: instance {i} still drawn by a group");
            assert_eq!(
                visible, own,
                "{other:?}: visible instance {i} drawn on its own"
            );
        }
    }
}

#[test]
fn the_cut_fits_whenever_the_coarsest_cut_fits() {
    let mut app = app();
    for target in [5000.0, 100.0, 30.0, 10.0, 3.0, 1.0, 0.3] {
        let d = frame(&mut app, hierarchical(target));
        let selection = d.predicted_render_ms - d.render_fixed_ms;
        let cut = app.world().resource::<HierarchicalCut>();
        if cut.coarsest_forced {
            // Only when even the coarsest cut (here the root box's cheapest group
            // impostor: the whole forest as one object) does not fit; last frame's cut is
            // then drawn a box level coarser, at its cheapest.
            assert!(d.floor_excess_ms > 0.0, "at {target} ms: {d:?}");
            assert!(selection > d.render_budget_ms, "at {target} ms: {d:?}");
        } else {
            assert!(
                selection <= d.render_budget_ms * 1.0001 + 1e-6,
                "at {target} ms the cut overspends: {d:?}"
            );
            assert_eq!(d.floor_excess_ms, 0.0);
        }
    }
}

/// A frame with no time at all after a fine cut draws that cut a box level coarser and
/// at its cheapest, not the whole forest as the root box's one group impostor; only a
/// lasting starvation comes down to that.
#[test]
fn a_starved_frame_coarsens_last_frame_s_cut_by_one_box_level() {
    let mut app = app();
    let mut fine = LodDiagnostics::default();
    // Until every box the cut reaches has its group impostor (a few are built a frame,
    // by the clock): a box without one has no group to coarsen to.
    for _ in 0..300 {
        fine = frame(&mut app, hierarchical(5000.0));
        if !app.world().resource::<GroupImpostors>().building() {
            break;
        }
    }
    assert!(
        !app.world().resource::<GroupImpostors>().building(),
        "the groups are built"
    );
    assert!(fine.trees_drawn > 20, "{fine:?}");
    let starved = frame(&mut app, hierarchical(0.001));
    assert!(
        app.world().resource::<HierarchicalCut>().coarsest_forced,
        "nothing fits: {starved:?}"
    );
    assert!(
        starved.impostors_drawn > 0 && starved.trees_drawn + starved.impostors_drawn > 1,
        "one box level coarser, not the root alone: {starved:?} after {fine:?}"
    );
    assert!(
        starved.predicted_render_ms < fine.predicted_render_ms,
        "at its cheapest: {starved:?} after {fine:?}"
    );
    let mut lasting = starved;
    for _ in 0..20 {
        lasting = frame(&mut app, hierarchical(0.001));
    }
    assert_eq!(
        (lasting.impostors_drawn, lasting.trees_drawn),
        (1, 0),
        "{lasting:?}"
    );
}

#[test]
fn the_app_draws_what_the_pure_solver_chooses() {
    let mut app = app();
    for target in [200.0, 40.0, 8.0, 40.0] {
        let d = frame(&mut app, hierarchical(target));
        let cut = app.world().resource::<HierarchicalCut>();
        if cut.coarsest_forced {
            continue;
        }
        // The same hierarchy from the same start, solved by the pure optimiser.
        let mut solver = HierarchicalLod::new();
        solver.solve_from(&cut.hierarchy, cut.rendering, &cut.seed);
        let mut predicted = 0.0f64;
        let mut groups = 0;
        let mut objects = 0;
        for node in 0..cut.hierarchy.len() as u32 {
            let selection = solver.selection(node);
            assert_eq!(
                selection, cut.selection[node as usize],
                "node {node} at {target} ms"
            );
            if let NodeSelection::Impostor(level) = selection {
                predicted += f64::from(cut.hierarchy.impostors(node)[level as usize].cost);
                if cut.boxes[node as usize].is_some() {
                    groups += 1;
                } else {
                    objects += 1;
                }
            }
        }
        assert_eq!(groups, d.impostors_drawn, "at {target} ms");
        assert!(objects >= d.trees_drawn, "at {target} ms");
        // What was drawn is what the solver priced (searches are deterministic).
        let selection = f64::from(d.predicted_render_ms - d.render_fixed_ms) / 1000.0;
        assert!(
            (selection - predicted).abs() <= 1e-3 * predicted.max(1e-6),
            "at {target} ms drawn {selection} s, solver's cut {predicted} s"
        );
    }
}

#[test]
fn group_geometry_stays_within_its_vertex_budget_coarsest_first() {
    let mut app = common::default_forest_view(EYE, LOOK_AT, |app| {
        app.insert_resource(GroupImpostorSettings {
            max_vertices: 4000,
            ..Default::default()
        });
    });
    for _ in 0..3 {
        frame(&mut app, hierarchical(2.0));
    }
    let groups = app.world().resource::<GroupImpostors>();
    let count = groups.len();
    assert!(count >= 1, "the root's group fits");
    let world = app.world_mut();
    let mut query = world.query::<(&GroupImpostorOf, &TreeInstance)>();
    let mut vertices = 0;
    let mut nodes = Vec::new();
    for (of, tree) in query.iter(world) {
        let model = world
            .resource::<Assets<TreeModel>>()
            .get(&tree.model)
            .unwrap();
        vertices += model.trunk_positions.len() + model.leaf_positions.len();
        nodes.push(of.node);
    }
    assert_eq!(nodes.len(), count);
    assert!(vertices <= 4000, "{vertices} vertices");
    // Coarsest first: the root (box 0) has one, and every box with one has a parent with
    // one (boxes are numbered level by level, four children each: box c's parent is
    // (c - 1) / 4).
    assert!(nodes.contains(&0));
    for &node in &nodes {
        assert!(node == 0 || nodes.contains(&((node - 1) / 4)), "box {node}");
    }
    // And the picture is still complete with fewer groups.
    assert_every_visible_tree_represented(&mut app);
    // A still view stops building: a box whose model found no room is not built again
    // (to be thrown away) every frame while no room could be made.
    let builds = |app: &App| app.world().resource::<GroupImpostors>().builds();
    let (mut last, mut quiet) = (builds(&app), 0);
    for _ in 0..100 {
        frame(&mut app, hierarchical(2.0));
        let now = builds(&app);
        quiet = if now == last { quiet + 1 } else { 0 };
        last = now;
        if quiet == 10 {
            break;
        }
    }
    assert_eq!(
        quiet, 10,
        "still building at the vertex budget after 100 frames ({last} models built)"
    );
}

/// Every instance culling sees is drawn on its own or by a group.
fn assert_every_visible_tree_represented(app: &mut App) {
    for (i, (visible, own, by_group)) in coverage(app).into_iter().enumerate() {
        assert!(!visible || own || by_group, "instance {i} unrepresented");
    }
}

/// The boxes last frame's cut reached, with how it drew them.
fn reached_boxes(app: &App) -> Vec<(u32, NodeSelection)> {
    let cut = app.world().resource::<HierarchicalCut>();
    cut.boxes
        .iter()
        .zip(&cut.selection)
        .filter_map(|(node, selection)| node.map(|n| (n, *selection)))
        .collect()
}

/// Whether box `node` was wanted by last frame's cut: reached by it, or a child of a box it
/// drew as its group impostor (where it refines next; boxes are numbered level by level,
/// four children each).
fn wanted_by_the_cut(reached: &[(u32, NodeSelection)], node: u32) -> bool {
    let selection = |n: u32| reached.iter().find(|(b, _)| *b == n).map(|(_, s)| *s);
    selection(node).is_some()
        || (node > 0 && matches!(selection((node - 1) / 4), Some(NodeSelection::Impostor(_))))
}

#[test]
fn group_impostors_are_built_for_the_boxes_in_view_and_released_when_left() {
    let mut app = common::default_forest_view(EYE, LOOK_AT, |app| {
        app.insert_resource(GroupImpostorSettings {
            // One build a frame, and a box the cut leaves is released at once.
            build_ms_per_frame: 0.0,
            idle_secs: 0.0,
            ..Default::default()
        });
    });
    let mut builds = 0;
    let mut frames = 0;
    loop {
        frame(&mut app, hierarchical(4.0));
        frames += 1;
        let groups = app.world().resource::<GroupImpostors>();
        assert!(
            groups.builds() <= builds + 1,
            "{} built in one frame",
            groups.builds() - builds
        );
        builds = groups.builds();
        // Until it has them, the cut draws every tree of a box on its own.
        assert_every_visible_tree_represented(&mut app);
        if !app.world().resource::<GroupImpostors>().building() {
            break;
        }
        assert!(frames < 400, "still building after {frames} frames");
    }
    let in_view = app.world().resource::<GroupImpostors>().len();
    let vertices = app.world().resource::<GroupImpostors>().vertices();
    assert!(in_view >= 2, "{in_view} group impostors");
    for _ in 0..4 {
        frame(&mut app, hierarchical(4.0));
    }
    let impostor_boxes = |app: &mut App| {
        let world = app.world_mut();
        let mut query = world.query::<&GroupImpostorOf>();
        query.iter(world).map(|g| g.node).collect::<Vec<_>>()
    };
    let reached = reached_boxes(&app);
    for node in impostor_boxes(&mut app) {
        assert!(
            wanted_by_the_cut(&reached, node),
            "box {node} kept, not in view"
        );
    }
    // Turned away from the forest: the boxes behind are let go, their memory with them.
    common::look_from(
        &mut app,
        EYE,
        EYE + (EYE - LOOK_AT) * Vec3::new(1.0, -1.0, 1.0),
    );
    for _ in 0..4 {
        frame(&mut app, hierarchical(4.0));
    }
    let groups = app.world().resource::<GroupImpostors>();
    assert!(
        groups.len() < in_view && groups.vertices() < vertices,
        "{} of {in_view} group impostors, {} of {vertices} vertices kept after turning away",
        groups.len(),
        groups.vertices()
    );
    let reached = reached_boxes(&app);
    for node in impostor_boxes(&mut app) {
        assert!(
            wanted_by_the_cut(&reached, node),
            "box {node} kept behind the camera"
        );
    }
}

/// A box the cut drew as its group impostor opens only once its children in view have
/// theirs (or cannot have one): opened earlier, it would open through a child without one
/// down to every tree beneath it, thousands at 100 000 trees, priced in one frame. The
/// cut still reaches the near trees on their own, a box level as their groups are built.
#[test]
fn a_box_drawn_as_its_group_opens_once_its_children_have_theirs() {
    let mut app = common::default_forest_view(EYE, LOOK_AT, |app| {
        app.insert_resource(GroupImpostorSettings {
            // One build a frame: children wait for theirs over several frames.
            build_ms_per_frame: 0.0,
            ..Default::default()
        });
    });
    // A tight target until the cut draws its first groups, their children's groups
    // still to come; then time for every tree.
    for _ in 0..200 {
        if frame(&mut app, hierarchical(1.0)).impostors_drawn > 0 {
            break;
        }
    }
    let mut last = reached_boxes(&app);
    assert!(
        last.iter()
            .any(|(_, s)| matches!(s, NodeSelection::Impostor(_))),
        "the cut draws groups: {last:?}"
    );
    let mut opened_after_group = 0;
    let mut trees_drawn = 0;
    for frames in 0..400 {
        let d = frame(&mut app, hierarchical(5000.0));
        let reached = reached_boxes(&app);
        let world = app.world();
        let (groups, culling) = (
            world.resource::<GroupImpostors>(),
            world.resource::<ForestCulling>(),
        );
        for &(node, selection) in &reached {
            let was_group = last
                .iter()
                .any(|&(b, s)| b == node && matches!(s, NodeSelection::Impostor(_)));
            if !(was_group && selection == NodeSelection::Children) {
                continue;
            }
            opened_after_group += 1;
            let children = culling.hierarchy.as_ref().unwrap().children(node as usize);
            let children = children.unwrap_or_default();
            for &(child, _) in reached
                .iter()
                .filter(|(c, _)| children.contains(&(*c as usize)))
            {
                assert_ne!(
                    groups.status(Some(culling), child as usize),
                    ImpostorStatus::Coming,
                    "frame {frames}: box {node} opened before its child {child} had its group"
                );
            }
        }
        assert_every_visible_tree_represented(&mut app);
        last = reached;
        trees_drawn = d.trees_drawn;
        if opened_after_group > 0 && trees_drawn > 20 {
            break;
        }
    }
    assert!(opened_after_group > 0, "no box drawn as its group opened");
    assert!(
        trees_drawn > 20,
        "the cut never reached the trees: {trees_drawn}"
    );
}
