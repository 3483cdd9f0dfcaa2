//! LOD ladders for any mesh: generated levels, the hysteresis, and ladder entities in the
//! same Robin Hood hand-out as the trees.
#![cfg(feature = "render")]

use crate::testing as common;

use crate::ladder::{LadderError, LadderState, generate_ladder};
use crate::prelude::*;
use bevy::asset::RenderAssetUsages;
use bevy::camera::primitives::MeshAabb;
use bevy::mesh::{Indices, PrimitiveTopology, VertexAttributeValues};
use bevy::prelude::*;

fn sphere() -> Mesh {
    Sphere::new(1.0).mesh().ico(5).unwrap()
}

fn triangles(mesh: &Mesh) -> usize {
    mesh.indices().map_or(0, |i| i.len() / 3)
}

/// The bounds of the vertices a mesh's triangles use.
fn used_bounds(mesh: &Mesh) -> (Vec3, Vec3) {
    let Some(VertexAttributeValues::Float32x3(p)) = mesh.attribute(Mesh::ATTRIBUTE_POSITION) else {
        panic!("no positions");
    };
    let mut lo = Vec3::splat(f32::INFINITY);
    let mut hi = Vec3::splat(f32::NEG_INFINITY);
    for i in mesh.indices().unwrap().iter() {
        lo = lo.min(Vec3::from(p[i]));
        hi = hi.max(Vec3::from(p[i]));
    }
    (lo, hi)
}

#[test]
fn generated_levels_get_cheaper_keep_attributes_and_bounds() {
    let mesh = sphere();
    let full = triangles(&mesh);
    let levels = generate_ladder(&mesh, &[0.5, 0.25, 0.1, 0.02]).unwrap();
    assert_eq!(levels[0].triangles as usize, full);
    assert_eq!(levels[0].error, 0.0);
    assert!(levels.len() >= 4, "{}", levels.len());
    let (lo, hi) = used_bounds(&mesh);
    for pair in levels.windows(2) {
        assert!(pair[1].triangles < pair[0].triangles);
        assert!(pair[1].error >= 0.0 && pair[1].error.is_finite());
    }
    for (level, ratio) in levels[1..].iter().zip([0.5_f32, 0.25, 0.1]) {
        let aim = full as f32 * ratio;
        assert!(
            (level.triangles as f32) < 1.5 * aim && (level.triangles as f32) > 0.5 * aim,
            "aimed at {aim}, got {}",
            level.triangles
        );
    }
    for level in &levels {
        assert_eq!(triangles(&level.mesh), level.triangles as usize);
        for attribute in [Mesh::ATTRIBUTE_NORMAL, Mesh::ATTRIBUTE_UV_0] {
            assert_eq!(
                level
                    .mesh
                    .attribute(attribute)
                    .map(VertexAttributeValues::len),
                mesh.attribute(attribute).map(VertexAttributeValues::len)
            );
        }
        // Within the full level's bounds, and the mesh's box is the full level's (Bevy's
        // frustum culling and the budget see the same object at every level).
        let (l, h) = used_bounds(&level.mesh);
        assert!(l.cmpge(lo - 1e-6).all() && h.cmple(hi + 1e-6).all());
        assert_eq!(level.mesh.compute_aabb(), mesh.compute_aabb());
    }
    // A sphere at 2% still has a shape: its used vertices span most of the box.
    let (l, h) = used_bounds(&levels.last().unwrap().mesh);
    assert!((h - l).min_element() > 1.5, "{l} {h}");
}

#[test]
fn bad_meshes_and_ratios_are_errors() {
    let mesh = sphere();
    for ratios in [&[1.0][..], &[0.0], &[0.5, 0.6], &[f32::NAN]] {
        assert!(
            matches!(
                generate_ladder(&mesh, ratios),
                Err(LadderError::BadRatio { .. })
            ),
            "{ratios:?}"
        );
    }
    let lines = Mesh::new(PrimitiveTopology::LineList, RenderAssetUsages::default())
        .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, vec![[0.0_f32; 3]; 2]);
    assert!(matches!(
        generate_ladder(&lines, &[0.5]),
        Err(LadderError::NotTriangles(_))
    ));
    let no_positions = Mesh::new(
        PrimitiveTopology::TriangleList,
        RenderAssetUsages::default(),
    );
    assert_eq!(
        generate_ladder(&no_positions, &[0.5]).unwrap_err(),
        LadderError::NoPositions
    );
    let mut bad_index = sphere();
    bad_index.insert_indices(Indices::U32(vec![0, 1, 1_000_000]));
    assert!(matches!(
        generate_ladder(&bad_index, &[0.5]),
        Err(LadderError::BadIndices { .. })
    ));
    let mut nan = sphere();
    if let Some(VertexAttributeValues::Float32x3(p)) = nan.attribute_mut(Mesh::ATTRIBUTE_POSITION) {
        p[3] = [f32::NAN, 0.0, 0.0];
    }
    assert_eq!(
        generate_ladder(&nan, &[0.5]).unwrap_err(),
        LadderError::NonFinitePosition { vertex: 3 }
    );
}

#[test]
fn hysteresis_holds_one_level_changes_either_way_and_lets_jumps_through() {
    let mut state = LadderState::showing(2);
    // One frame wanting one level better: held.
    assert!(state.holds(1, 3));
    assert!(!state.settle(1, 3));
    assert_eq!(state.shown, 2);
    assert!(!state.settle(2, 3));
    // Three frames in a row: shown; `holds` says so beforehand.
    assert!(!state.settle(1, 3));
    assert!(!state.settle(1, 3));
    assert!(!state.holds(1, 3));
    assert!(state.settle(1, 3));
    assert_eq!(state.shown, 1);
    // One level cheaper: held as well, then shown.
    assert!(!state.settle(2, 3));
    assert!(!state.settle(2, 3));
    assert_eq!(state.shown, 1);
    assert!(state.settle(2, 3));
    assert_eq!(state.shown, 2);
    // Two levels away: at once, either way.
    assert!(!state.holds(0, 3));
    assert!(state.settle(0, 3));
    assert_eq!(state.shown, 0);
    assert!(state.settle(2, 3));
    assert_eq!(state.shown, 2);
    // An interrupted streak starts again.
    let mut state = LadderState::showing(3);
    state.settle(2, 3);
    state.settle(2, 3);
    state.settle(3, 3);
    assert!(!state.settle(2, 3));
    assert_eq!(state.shown, 3);
    // One frame of hysteresis (or none): no holding.
    assert!(!LadderState::showing(3).holds(2, 1));
    assert!(!LadderState::showing(3).holds(4, 0));
}

#[test]
fn the_budget_pays_for_the_level_the_hysteresis_holds() {
    use crate::lod::select::LadderHold;
    let hold = LadderHold {
        shown: 2,
        better: true,
        cheaper: false,
        ..LadderHold::default()
    };
    assert_eq!(hold.shown_for(1), 2);
    assert_eq!(hold.shown_for(3), 3);
    assert_eq!(hold.shown_for(0), 0);
    assert_eq!(hold.shown_for(2), 2);
    let hold = LadderHold {
        cheaper: true,
        better: false,
        ..hold
    };
    assert_eq!(hold.shown_for(3), 2);
    assert_eq!(hold.shown_for(1), 1);
    assert_eq!(hold.shown_for(4), 4);
}

#[test]
fn the_budget_pays_for_both_levels_while_a_fade_runs() {
    use crate::lod::select::LadderHold;
    let hold = LadderHold {
        shown: 2,
        better: true,
        fades: true,
        ..LadderHold::default()
    };
    // A change fades from the level shown until now; a held or unchanged choice draws
    // no second level.
    assert_eq!(hold.fading_for(0), Some(2));
    assert_eq!(hold.fading_for(3), Some(2));
    assert_eq!(hold.fading_for(1), None);
    assert_eq!(hold.fading_for(2), None);
    let running = LadderHold {
        fading: Some(1),
        ..hold
    };
    assert_eq!(running.fading_for(2), Some(1));
    assert_eq!(running.fading_for(0), Some(2));
    let unfaded = LadderHold {
        fades: false,
        ..running
    };
    assert_eq!(unfaded.fading_for(0), None);
    assert_eq!(unfaded.fading_for(2), Some(1));
}

const EYE: Vec3 = Vec3::new(60.0, 14.0, 40.0);
const LOOK_AT: Vec3 = Vec3::new(140.0, 4.0, 120.0);

/// The default forest and `n` ladder spheres (five levels) in front of the camera.
fn app(n: usize) -> (App, Vec<Entity>) {
    let mut spheres = Vec::new();
    let app = common::default_forest_view(EYE, LOOK_AT, |app| {
        app.init_asset::<Mesh>();
        let levels = generate_ladder(&sphere(), &[0.4, 0.15, 0.05, 0.01]).unwrap();
        let aabb = levels[0].mesh.compute_aabb().unwrap();
        let ladder = {
            let mut meshes = app.world_mut().resource_mut::<Assets<Mesh>>();
            LodLadder::from_generated(&mut meshes, levels).unwrap()
        };
        for k in 0..n {
            let along = EYE + (LOOK_AT - EYE).normalize() * (8.0 + 4.0 * k as f32);
            let side = Vec3::new(((k % 5) as f32 - 2.0) * 3.0, 0.0, 0.0);
            spheres.push(
                app.world_mut()
                    .spawn((
                        ladder.clone(),
                        Mesh3d(ladder.levels()[0].mesh.clone()),
                        aabb,
                        Transform::from_translation(along + side).with_scale(Vec3::splat(1.5)),
                    ))
                    .id(),
            );
        }
    });
    (app, spheres)
}

fn frame(app: &mut App, mode: LodMode, strategy: StrategyKind, target_ms: f32) -> LodDiagnostics {
    *app.world_mut().resource_mut::<FrameBudget>() = FrameBudget {
        mode,
        strategy,
        target_ms,
        ..Default::default()
    };
    app.update();
    app.world().resource::<LodDiagnostics>().clone()
}

fn shown(app: &App, spheres: &[Entity]) -> Vec<u32> {
    spheres
        .iter()
        .map(|&e| app.world().get::<LadderState>(e).unwrap().shown)
        .collect()
}

#[test]
fn ladders_share_the_hand_out_with_the_trees() {
    let (mut app, spheres) = app(20);
    app.world_mut()
        .resource_mut::<LadderSettings>()
        .hysteresis_frames = 1;
    // Generous: every sphere at its best level.
    frame(&mut app, LodMode::Tclod, StrategyKind::RobinHood, 100_000.0);
    let d = frame(&mut app, LodMode::Tclod, StrategyKind::RobinHood, 100_000.0);
    assert!(
        shown(&app, &spheres).iter().all(|&l| l == 0),
        "{:?}",
        shown(&app, &spheres)
    );
    let ladders = app.world().resource::<LadderDiagnostics>().clone();
    assert_eq!(ladders.entities, 20);
    assert_eq!(ladders.shown_per_level.iter().sum::<u32>(), 20);
    assert!(d.learned.scales.meshes > 0.0);
    // Each sphere's mesh is its shown level's.
    for &e in &spheres {
        let ladder = app.world().get::<LodLadder>(e).unwrap();
        let state = app.world().get::<LadderState>(e).unwrap();
        let mesh = app.world().get::<Mesh3d>(e).unwrap();
        assert_eq!(mesh.0, ladder.levels()[state.shown as usize].mesh);
    }
    // Tighter targets: cheaper levels, never more detail with less time, nothing dropped,
    // and the selection within the rendering time but for the floors' reported excess.
    let mut previous = vec![0_u32; spheres.len()];
    for target in [400.0, 120.0, 60.0, 30.0, 10.0] {
        let d = frame(&mut app, LodMode::Tclod, StrategyKind::RobinHood, target);
        let selection = d.predicted_render_ms - d.render_fixed_ms;
        assert!(
            selection <= d.render_budget_ms * 1.0001 + d.floor_excess_ms + 1e-4,
            "at {target} ms: {d:?}"
        );
        assert_eq!(d.undrawn, 0);
        let now = shown(&app, &spheres);
        let total: u32 = now.iter().sum();
        assert!(
            total >= previous.iter().sum::<u32>(),
            "at {target} ms: {now:?} after {previous:?}"
        );
        previous = now;
    }
    assert!(
        previous.iter().any(|&l| l > 0),
        "a tight target picks cheaper levels: {previous:?}"
    );
    // The ladder strategies take ladder entities too.
    for strategy in [StrategyKind::FunkhouserSequin, StrategyKind::TriangleBudget] {
        let d = frame(&mut app, LodMode::Tclod, strategy, 100_000.0);
        assert_eq!(d.undrawn, 0, "{strategy:?}");
        assert!(
            shown(&app, &spheres).iter().all(|&l| l == 0),
            "{strategy:?}"
        );
    }
}

#[test]
fn the_budget_keeps_the_shown_level_while_it_fits_and_upgrades_with_a_margin() {
    use crate::cost::{Calibration, MeshPathCost, PrimitiveCosts};
    use crate::lod::select::ladder_level;
    let calibration = Calibration {
        meshes: MeshPathCost {
            per_draw: 0.0,
            per_triangle: 1.0,
            per_pixel: 0.0,
        },
        ..Default::default()
    };
    let costs = PrimitiveCosts::from_calibration(&calibration, 1.0);
    let levels = [100, 50, 10];
    let level = |time: f32, shown: Option<u32>| ladder_level(&costs, &levels, 0.0, time, shown).0;
    // Nothing shown yet: the best that fits.
    assert_eq!(level(60.0, None), 1);
    assert_eq!(level(100.0, None), 0);
    // Showing level 1: kept while it fits, level 0 only with a margin.
    assert_eq!(level(60.0, Some(1)), 1);
    assert_eq!(level(110.0, Some(1)), 1);
    assert_eq!(level(120.0, Some(1)), 0);
    // No longer fitting: the best that fits, else the cheapest, never nothing.
    assert_eq!(level(40.0, Some(1)), 2);
    let (cheapest, chosen) = ladder_level(&costs, &levels, 0.0, 1.0, Some(0));
    assert_eq!(cheapest, 2);
    assert!(chosen.truncated && chosen.cost == 10.0 && chosen.meshes == 10.0);
}

/// A node as a glTF scene spawns it: a named entity with one child per primitive (each
/// with the bounds Bevy's visibility plugin would give it).
fn spawn_node(app: &mut App, parent: Entity, name: &str, primitives: &[Handle<Mesh>]) -> Entity {
    let aabb = sphere().compute_aabb().unwrap();
    let node = app
        .world_mut()
        .spawn((
            Name::new(name.to_owned()),
            Transform::default(),
            ChildOf(parent),
        ))
        .id();
    for mesh in primitives {
        app.world_mut().spawn((
            Mesh3d(mesh.clone()),
            aabb,
            Transform::default(),
            ChildOf(node),
        ));
    }
    node
}

#[test]
fn lod_named_siblings_become_ladders_and_broken_groups_stay_as_spawned() {
    let mut app = common::default_forest_view(EYE, LOOK_AT, |app| {
        app.init_asset::<Mesh>();
    });
    let levels = generate_ladder(&sphere(), &[0.3, 0.05]).unwrap();
    let handles: Vec<Handle<Mesh>> = {
        let mut meshes = app.world_mut().resource_mut::<Assets<Mesh>>();
        levels.iter().map(|l| meshes.add(l.mesh.clone())).collect()
    };
    let root = app
        .world_mut()
        .spawn((
            LadderFromLodNames,
            Transform::from_translation(EYE + (LOOK_AT - EYE).normalize() * 10.0),
        ))
        .id();
    let group = app
        .world_mut()
        .spawn((Name::new("Props"), Transform::default(), ChildOf(root)))
        .id();
    // Out of order, two primitives per level (the second primitive is the same ladder).
    let lod2 = spawn_node(
        &mut app,
        group,
        "Rock_LOD2",
        &[handles[2].clone(), handles[2].clone()],
    );
    let lod0 = spawn_node(
        &mut app,
        group,
        "Rock_lod0",
        &[handles[0].clone(), handles[1].clone()],
    );
    let lod1 = spawn_node(
        &mut app,
        group,
        "Rock_LOD1",
        &[handles[1].clone(), handles[2].clone()],
    );
    // Broken: level 1 has more triangles than level 0.
    let bad0 = spawn_node(&mut app, group, "Bad_LOD0", &[handles[2].clone()]);
    let bad1 = spawn_node(&mut app, group, "Bad_LOD1", &[handles[0].clone()]);
    app.update();
    app.update();

    let primitives = |node: Entity| -> Vec<Entity> {
        app.world().get::<Children>(node).unwrap().iter().collect()
    };
    let expected = [
        [
            levels[0].triangles,
            levels[1].triangles,
            levels[2].triangles,
        ],
        [
            levels[1].triangles,
            levels[2].triangles,
            levels[2].triangles,
        ],
    ];
    for (primitive, triangles) in primitives(lod0).into_iter().zip(expected) {
        let ladder = app.world().get::<LodLadder>(primitive).expect("a ladder");
        let counts: Vec<u32> = ladder.levels().iter().map(|l| l.triangles).collect();
        assert_eq!(counts, triangles);
    }
    for node in [lod1, lod2] {
        assert_eq!(
            app.world().get::<Visibility>(node),
            Some(&Visibility::Hidden)
        );
    }
    assert_ne!(
        app.world().get::<Visibility>(lod0),
        Some(&Visibility::Hidden)
    );
    // The broken group: no ladder, nothing hidden.
    for node in [bad0, bad1] {
        assert_ne!(
            app.world().get::<Visibility>(node),
            Some(&Visibility::Hidden)
        );
        for primitive in primitives(node) {
            assert!(app.world().get::<LodLadder>(primitive).is_none());
        }
    }
    assert!(app.world().get::<LadderFromLodNames>(root).is_none());
    // The ladders are in the hand-out.
    let ladders = app.world().resource::<LadderDiagnostics>().clone();
    assert_eq!(ladders.entities, 2, "{ladders:?}");
}

#[test]
fn lod_named_siblings_wait_for_their_meshes() {
    let mut app = common::default_forest_view(EYE, LOOK_AT, |app| {
        app.init_asset::<Mesh>();
    });
    let levels = generate_ladder(&sphere(), &[0.3]).unwrap();
    let root = app
        .world_mut()
        .spawn((LadderFromLodNames, Transform::default()))
        .id();
    // Handles reserved but not yet filled: a glTF still loading.
    let reserved: Vec<Handle<Mesh>> = {
        let meshes = app.world().resource::<Assets<Mesh>>();
        levels.iter().map(|_| meshes.reserve_handle()).collect()
    };
    let lod0 = spawn_node(&mut app, root, "Tower_LOD0", &reserved[..1]);
    spawn_node(&mut app, root, "Tower_LOD1", &reserved[1..]);
    app.update();
    let primitive = app.world().get::<Children>(lod0).unwrap()[0];
    assert!(app.world().get::<LodLadder>(primitive).is_none());
    assert!(app.world().get::<LadderFromLodNames>(root).is_some());
    {
        let mut meshes = app.world_mut().resource_mut::<Assets<Mesh>>();
        for (handle, level) in reserved.iter().zip(&levels) {
            meshes.insert(handle.id(), level.mesh.clone()).unwrap();
        }
    }
    app.update();
    app.update();
    assert!(app.world().get::<LodLadder>(primitive).is_some());
    assert!(app.world().get::<LadderFromLodNames>(root).is_none());
}

#[test]
fn the_hand_out_pays_for_the_levels_shown_while_the_hysteresis_holds() {
    use crate::cost::{CostModel, PrimitiveCosts};
    let (mut app, spheres) = app(20);
    app.world_mut()
        .resource_mut::<LadderSettings>()
        .hysteresis_frames = 4;
    let (mut held, mut switched) = (0, 0);
    // Each change of a shown level is announced once, as it happens.
    #[derive(Resource, Default)]
    struct Announced(Vec<(Entity, u32, u32)>);
    app.init_resource::<Announced>().add_observer(
        |change: On<LadderLevelChanged>, mut seen: ResMut<Announced>| {
            seen.0.push((change.entity, change.from, change.to));
        },
    );
    let mut before = shown(&app, &spheres);
    // Generous, then tighter and tighter for a while each, a one-frame dip, generous again.
    let targets = [
        (100_000.0, 2),
        (90.0, 6),
        (60.0, 6),
        (30.0, 6),
        (400.0, 1),
        (30.0, 2),
        (400.0, 8),
    ];
    for target in targets
        .into_iter()
        .flat_map(|(t, n)| std::iter::repeat_n(t, n))
    {
        let d = frame(&mut app, LodMode::Tclod, StrategyKind::RobinHood, target);
        let now = shown(&app, &spheres);
        let mut changed: Vec<(Entity, u32, u32)> = spheres
            .iter()
            .zip(before.iter().zip(&now))
            .filter(|(_, (a, b))| a != b)
            .map(|(&e, (&a, &b))| (e, a, b))
            .collect();
        let mut announced = std::mem::take(&mut app.world_mut().resource_mut::<Announced>().0);
        changed.sort();
        announced.sort();
        assert_eq!(announced, changed, "at {target} ms");
        before = now.clone();
        let ladders = app.world().resource::<LadderDiagnostics>().clone();
        assert_eq!(
            ladders.shown_per_level.iter().sum::<u32>(),
            20,
            "all in view"
        );
        let calibration = app.world().resource::<CostModel>().calibration().clone();
        let prices = PrimitiveCosts::from_calibration(&calibration, 1.0);
        let paid: f32 = spheres
            .iter()
            .zip(&now)
            .map(|(&e, &level)| {
                let ladder = app.world().get::<LodLadder>(e).unwrap();
                prices.mesh(ladder.levels()[level as usize].triangles)
            })
            .sum();
        assert!(
            (d.calibrated.meshes - paid).abs() <= 1e-3 * paid.max(1e-9),
            "at {target} ms the budget paid {} for meshes showing {:?} that cost {paid}",
            d.calibrated.meshes,
            now
        );
        held += spheres
            .iter()
            .filter(|&&e| {
                app.world()
                    .get::<LadderState>(e)
                    .unwrap()
                    .pending()
                    .is_some()
            })
            .count();
        switched += ladders.switches;
    }
    assert!(
        held > 0,
        "no level was ever held: the test saw no hysteresis"
    );
    assert!(switched > 0, "no level ever changed");
}

/// With a `StandardMaterial`, every change of a shown level cross-fades: a ghost draws the
/// old level for `fade_frames` frames, both entities carry the dither's ranges, the budget
/// pays for both levels while the fade runs, and nothing of it is left afterwards.
#[test]
fn a_level_change_fades_for_its_frames_and_the_hand_out_pays_for_both_levels() {
    use crate::cost::{CostModel, PrimitiveCosts};
    use crate::ladder::LadderGhost;
    use bevy::camera::visibility::VisibilityRange;
    const FADE: u32 = 3;
    let (mut app, spheres) = app(20);
    for &sphere in &spheres {
        app.world_mut()
            .entity_mut(sphere)
            .insert(MeshMaterial3d::<StandardMaterial>::default());
    }
    *app.world_mut().resource_mut::<LadderSettings>() = LadderSettings {
        hysteresis_frames: 1,
        fade_frames: FADE,
    };
    let targets = [
        (100_000.0, 2),
        (60.0, 6),
        (30.0, 6),
        (400.0, 1),
        (100_000.0, 8),
    ];
    let mut faded_since: Vec<Option<u32>> = vec![None; spheres.len()];
    let (mut fades, mut lengths) = (0, Vec::new());
    let mut before = shown(&app, &spheres);
    for target in targets
        .into_iter()
        .flat_map(|(t, n)| std::iter::repeat_n(t, n))
    {
        let d = frame(&mut app, LodMode::Tclod, StrategyKind::RobinHood, target);
        let now = shown(&app, &spheres);
        let world = app.world_mut();
        let ghosts: Vec<(Entity, Handle<Mesh>)> = world
            .query::<(&LadderGhost, &Mesh3d)>()
            .iter(world)
            .map(|(g, m)| (g.owner, m.0.clone()))
            .collect();
        let world = app.world();
        let calibration = world.resource::<CostModel>().calibration().clone();
        let prices = PrimitiveCosts::from_calibration(&calibration, 1.0);
        let mut paid = 0.0;
        for (k, (&sphere, &level)) in spheres.iter().zip(&now).enumerate() {
            let ladder = world.get::<LodLadder>(sphere).unwrap();
            let levels = ladder.levels();
            paid += prices.mesh(levels[level as usize].triangles);
            let ghost: Vec<_> = ghosts.iter().filter(|(o, _)| *o == sphere).collect();
            assert!(ghost.len() <= 1, "one ghost per ladder");
            let range = world.get::<VisibilityRange>(sphere).is_some();
            if let Some((_, mesh)) = ghost.first() {
                let old = levels.iter().position(|l| l.mesh == *mesh).unwrap();
                assert_ne!(old as u32, level, "the ghost draws the level faded out");
                paid += prices.mesh(levels[old].triangles);
                assert!(range, "a fading ladder dithers");
            } else {
                assert!(!range, "the dither's range outlived the fade");
            }
            if before[k] != level {
                faded_since[k] = Some(0);
                assert!(!ghost.is_empty(), "a change of level did not fade");
            }
            match (&mut faded_since[k], ghost.is_empty()) {
                (Some(n), false) => *n += 1,
                (since @ Some(_), true) => {
                    lengths.push(since.take().unwrap());
                }
                (None, false) => panic!("a ghost without a change of level"),
                (None, true) => {}
            }
        }
        fades += ghosts.len();
        assert_eq!(
            world.resource::<LadderDiagnostics>().fades as usize,
            ghosts.len()
        );
        assert_eq!(d.app_mesh_draws, 0, "a ghost counted as an app mesh");
        assert!(
            (d.calibrated.meshes - paid).abs() <= 1e-3 * paid.max(1e-9),
            "at {target} ms the budget paid {} for meshes and fades that cost {paid}",
            d.calibrated.meshes,
        );
        before = now;
    }
    assert!(fades > 0, "no level ever faded");
    assert!(
        lengths.iter().all(|&n| n == FADE),
        "fades lasted {lengths:?} frames, not {FADE}"
    );
    assert!(
        faded_since.iter().all(Option::is_none),
        "a fade never ended"
    );
}

/// The app's own meshes (no ladder) are not budgeted but predicted: spawning them takes
/// their time from the trees in the same frame; hidden ones and ones behind the camera
/// count for nothing.
#[test]
fn the_app_s_own_meshes_move_the_prediction_in_the_frame_they_appear() {
    let (mut app, _) = app(0);
    let before = frame(&mut app, LodMode::Tclod, StrategyKind::RobinHood, 150.0);
    assert_eq!(before.app_mesh_draws, 0);
    let mesh = app
        .world_mut()
        .resource_mut::<Assets<Mesh>>()
        .add(Sphere::new(1.0).mesh().uv(64, 32));
    let aabb = Sphere::new(1.0).mesh().uv(64, 32).compute_aabb().unwrap();
    let ahead = (LOOK_AT - EYE).normalize();
    let world = app.world_mut();
    for k in 0..20 {
        let at = EYE + ahead * (6.0 + 2.0 * k as f32) + Vec3::Y * ((k % 3) as f32 - 1.0);
        world.spawn((
            Mesh3d(mesh.clone()),
            aabb,
            InheritedVisibility::VISIBLE,
            Transform::from_translation(at).with_scale(Vec3::splat(1.5)),
        ));
    }
    // Hidden, and behind the camera.
    world.spawn((
        Mesh3d(mesh.clone()),
        aabb,
        InheritedVisibility::HIDDEN,
        Transform::from_translation(EYE + ahead * 10.0),
    ));
    world.spawn((
        Mesh3d(mesh.clone()),
        aabb,
        InheritedVisibility::VISIBLE,
        Transform::from_translation(EYE - ahead * 10.0),
    ));
    let after = frame(&mut app, LodMode::Tclod, StrategyKind::RobinHood, 150.0);
    assert_eq!(after.app_mesh_draws, 20, "{after:?}");
    assert!(after.app_meshes_ms > 0.0);
    // Their time is taken before the hand-out, in this very frame.
    assert!(
        after.render_budget_ms <= before.render_budget_ms - after.app_meshes_ms + 0.01,
        "{} ms handed out with the meshes ({} ms), {} ms before",
        after.render_budget_ms,
        after.app_meshes_ms,
        before.render_budget_ms
    );
    let c = after.calibrated;
    assert!(c.meshes > 0.0 && c.mesh_pixels > 0.0, "{c:?}");
}
