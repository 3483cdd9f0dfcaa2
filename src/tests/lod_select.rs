//! The per-object searches of the time-critical modes, on a shipped species.

use crate::testing as common;

use crate::cost::Calibration;
use crate::draw::{PointRun, TreeDrawList};
use crate::lod::select::*;
use crate::tree::{PixelRange, Projection, TreeModel};
use bevy::math::Vec3;

fn model() -> TreeModel {
    common::species("grand")
}

fn view(depth: f32) -> TreeView {
    TreeView {
        scale: 1.0,
        trunk_depth: depth,
        projection: Projection::perspective(0.8, 540.0),
    }
}

fn groups(model: &TreeModel, depth: f32) -> Vec<VisibleLeafGroup> {
    (0..model.leaf_groups.len() as u32)
        .map(|group| VisibleLeafGroup { group, depth })
        .collect()
}

const TIMES: [f32; 9] = [0.0, 1e-6, 1e-5, 5e-5, 1e-4, 5e-4, 1e-3, 1e-2, 1.0];

#[test]
fn a_trunk_never_costs_more_than_its_time_unless_truncated_and_grows_with_it() {
    let model = model();
    let costs = PrimitiveCosts::from_calibration(&Calibration::default(), 1.0);
    let total = model.trunk_triangle_count() as u32;
    for depth in [3.0, 15.0, 60.0, 250.0] {
        let v = view(depth);
        let mut previous = 0.0;
        for time in TIMES {
            for tclod in [false, true] {
                let mut list = TreeDrawList::default();
                let s = if tclod {
                    trunk_tclod(&model, &v, &costs, PixelRange::default(), time, &mut list)
                } else {
                    trunk_tc(&model, &v, &costs, time, &mut list)
                };
                assert!(s.cost.is_finite());
                assert!(
                    !list.is_empty(),
                    "an undrawn trunk at depth {depth}, time {time}"
                );
                assert!(
                    s.cost <= time * 1.0001 || s.truncated,
                    "depth {depth} time {time}: {s:?}"
                );
                assert_eq!(
                    list.trunk_triangles.end.min(total),
                    list.trunk_triangles.end
                );
                if tclod {
                    assert!(
                        s.cost >= previous * 0.9999,
                        "depth {depth}: less at {time} than before"
                    );
                    previous = s.cost;
                }
            }
        }
        // With a second to spare, full detail: every segment as triangles, the sub-pixel
        // twigs the static LOD drops included (thesis §6.5).
        let mut list = TreeDrawList::default();
        trunk_tclod(&model, &v, &costs, PixelRange::default(), 1.0, &mut list);
        assert_eq!(list.trunk_triangles, 0..total, "depth {depth}");
        // Just short of that, every segment the static LOD does not drop is triangles.
        let full = trunk_tc(&model, &v, &costs, f32::INFINITY, &mut list).cost;
        let dropped =
            crate::tree::trunk_lod(&model, 1.0, depth, &v.projection, PixelRange::default())
                .dropped
                .end;
        let first = model.segments.triangle_offsets[dropped as usize];
        let enough = costs.triangles(total - first, trunk_triangle_area(&model, &v));
        if enough < full {
            trunk_tclod(
                &model,
                &v,
                &costs,
                PixelRange::default(),
                enough.max(0.999 * full),
                &mut list,
            );
            assert!(list.trunk_triangles.start <= first, "depth {depth}");
        }
        assert!(list.trunk_lines.is_empty());
    }
}

#[test]
fn far_trunks_become_lines_and_near_ones_triangles() {
    let model = model();
    let costs = PrimitiveCosts::from_calibration(&Calibration::default(), 1.0);
    let mut far = TreeDrawList::default();
    trunk_tclod(
        &model,
        &view(400.0),
        &costs,
        PixelRange::default(),
        1e-5,
        &mut far,
    );
    assert!(!far.trunk_lines.is_empty());
    assert!(far.trunk_lines.iter().all(|r| (1..=20).contains(&r.width)));
    let mut near = TreeDrawList::default();
    trunk_tclod(
        &model,
        &view(1.0),
        &costs,
        PixelRange::default(),
        1e-5,
        &mut near,
    );
    assert!(
        near.trunk_lines.is_empty(),
        "a trunk filling the view is not a line"
    );
}

#[test]
fn leaves_fit_their_time_and_use_it_as_it_grows() {
    let model = model();
    let costs = PrimitiveCosts::from_calibration(&Calibration::default(), 1.0);
    for depth in [5.0, 30.0, 200.0] {
        let v = view(depth);
        let g = groups(&model, depth);
        for method in [LeafMethod::Tc, LeafMethod::Tclod(PixelRange::default())] {
            let mut previous = 0.0;
            for time in TIMES {
                let mut list = TreeDrawList::default();
                let s = leaves(&model, &v, &costs, method, &g, time, &mut list);
                assert!(s.cost.is_finite());
                assert!(
                    s.cost <= time * 1.0001 || s.truncated,
                    "{method:?} {depth} {time}: {s:?}"
                );
                assert!(
                    s.cost >= previous * 0.9999,
                    "{method:?} at {depth}: less with more time"
                );
                previous = s.cost;
                // Every group draws something, and no leaf twice.
                let mut drawn = vec![0u8; model.leaves.len()];
                for r in &list.leaf_triangles {
                    r.clone().for_each(|l| drawn[l as usize] += 1);
                }
                for r in &list.leaf_points {
                    r.leaves.clone().for_each(|l| drawn[l as usize] += 1);
                }
                assert!(drawn.iter().all(|&d| d <= 1));
                for group in &model.leaf_groups {
                    assert!(group.leaves.clone().any(|l| drawn[l as usize] == 1));
                }
            }
        }
    }
    // Points are the far leaves of a group, never its near ones, when the group is small
    // (and the time short of full detail).
    let mut list = TreeDrawList::default();
    let g = groups(&model, 300.0);
    let full = leaves(
        &model,
        &view(300.0),
        &costs,
        LeafMethod::Full,
        &g,
        0.0,
        &mut list,
    )
    .cost;
    leaves(
        &model,
        &view(300.0),
        &costs,
        LeafMethod::Tclod(PixelRange::default()),
        &g,
        0.5 * full,
        &mut list,
    );
    assert!(!list.leaf_points.is_empty());
    for run in &list.leaf_points {
        let group = &model.leaf_groups[model.leaves[run.leaves.start as usize].group as usize];
        assert_eq!(run.leaves.end, group.leaves.end);
    }
    let _ = Vec3::ZERO;
}

#[test]
fn a_trunk_too_far_to_see_is_still_one_thin_line() {
    let model = model();
    let costs = PrimitiveCosts::from_calibration(&Calibration::default(), 1.0);
    let mut list = TreeDrawList::default();
    trunk_tclod(
        &model,
        &view(50_000.0),
        &costs,
        PixelRange::default(),
        0.0,
        &mut list,
    );
    assert!(list.trunk_triangles.is_empty());
    assert_eq!(list.trunk_lines.len(), 1);
    assert_eq!(list.trunk_lines[0].width, 1);
    assert_eq!(list.trunk_lines[0].segments.len(), 1);
    // With time for it but short of the whole trunk, the thickest segment's triangles
    // instead of its line.
    let n = model.segments.len() as u32;
    let full = trunk_tc(&model, &view(50_000.0), &costs, f32::INFINITY, &mut list).cost;
    let generous = trunk_tclod(
        &model,
        &view(50_000.0),
        &costs,
        PixelRange::default(),
        0.5 * full,
        &mut list,
    );
    assert!(list.trunk_lines.is_empty());
    let thickest = model.segments.triangles(n as usize - 1);
    assert_eq!(list.trunk_triangles, thickest);
    assert!(!generous.truncated);
    // A thickest segment that owns no triangles (joined to its parent by proximity) stays
    // a line: the trunk is never drawn as nothing.
    let mut joined = model.clone();
    let offsets = &mut joined.segments.triangle_offsets;
    offsets[n as usize - 1] = offsets[n as usize];
    assert!(joined.validate().is_ok());
    let full = trunk_tc(&joined, &view(50_000.0), &costs, f32::INFINITY, &mut list).cost;
    trunk_tclod(
        &joined,
        &view(50_000.0),
        &costs,
        PixelRange::default(),
        0.5 * full,
        &mut list,
    );
    assert_eq!(list.trunk_lines.len(), 1, "{list:?}");
    assert!(list.trunk_triangles.is_empty());
}

#[test]
fn a_tree_at_the_camera_fills_the_screen_once() {
    // Seen from inside (depth at the clamp), a leaf triangle projects to billions of
    // pixels; the tree's triangles together fill the screen, not more.
    let model = model();
    let viewport = 960.0 * 540.0;
    let unbounded = PrimitiveCosts::from_calibration(&Calibration::default(), 1.0);
    let costs = unbounded.clone().within_viewport(viewport);
    let at_camera = crate::budget::MIN_DEPTH;
    let v = view(at_camera);
    let g = groups(&model, at_camera);
    let mut list = TreeDrawList::default();
    let full = leaves(&model, &v, &costs, LeafMethod::Full, &g, 0.0, &mut list);
    let trunk = trunk_tc(&model, &v, &costs, f32::INFINITY, &mut list);
    assert!(full.cost.is_finite() && trunk.cost.is_finite());
    // The fill: the same trees priced with fill free, subtracted.
    let mut no_fill = Calibration::default();
    no_fill.triangles.per_pixel = 0.0;
    let vertices_only = PrimitiveCosts::from_calibration(&no_fill, 1.0).within_viewport(viewport);
    let leaf_fill = full.cost
        - leaves(
            &model,
            &v,
            &vertices_only,
            LeafMethod::Full,
            &g,
            0.0,
            &mut list,
        )
        .cost;
    let trunk_fill =
        trunk.cost - trunk_tc(&model, &v, &vertices_only, f32::INFINITY, &mut list).cost;
    // Together, a trunk's triangles fill the screen once, as do the tree's leaves: the
    // fill is one screen's, not the triangle count's worth of screens.
    let screen = Calibration::default().triangles.per_pixel * viewport;
    for (part, fill) in [("leaves", leaf_fill), ("trunk", trunk_fill)] {
        assert!(
            fill <= screen * 1.001,
            "{part}: {fill} s of fill, a screen is {screen} s"
        );
        assert!(
            fill >= screen * 0.5,
            "{part}: {fill} s of fill, a screen is {screen} s"
        );
    }
    let uncapped = leaves(&model, &v, &unbounded, LeafMethod::Full, &g, 0.0, &mut list);
    assert!(
        uncapped.cost > 100.0 * full.cost,
        "the cap matters here: {} vs {}",
        uncapped.cost,
        full.cost
    );
    // Far away, the cap changes nothing.
    let far = view(80.0);
    let g = groups(&model, 80.0);
    let capped = leaves(&model, &far, &costs, LeafMethod::Full, &g, 0.0, &mut list);
    let plain = leaves(
        &model,
        &far,
        &unbounded,
        LeafMethod::Full,
        &g,
        0.0,
        &mut list,
    );
    assert_eq!(capped, plain);
}

/// (triangle leaves, points) a list draws, and whether every group draws a leaf and no
/// leaf is drawn twice.
/// Leaves drawn as triangles and as points (the crown disc counts as one point), and
/// whether the drawing is sound: no leaf drawn twice, every group drawn — by a leaf of
/// its own, or by the crown disc alone.
fn drawn(model: &TreeModel, list: &TreeDrawList) -> (u32, u32, bool) {
    let n = model.leaves.len();
    let far_first = model.far_first_leaves();
    let crown = model.crown_leaf();
    let leaf = |l: u32| match l as usize {
        l if l < n => l,
        l => far_first[l - n] as usize,
    };
    let mut drawn = vec![0u8; n];
    for r in &list.leaf_triangles {
        r.clone().for_each(|l| drawn[leaf(l)] += 1);
    }
    let triangles = drawn.iter().map(|&d| d as u32).sum();
    let crowns = list
        .leaf_points
        .iter()
        .filter(|r| r.leaves.contains(&crown))
        .count() as u32;
    for r in &list.leaf_points {
        r.leaves
            .clone()
            .filter(|&l| l != crown)
            .for_each(|l| drawn[leaf(l)] += 1);
    }
    let points = drawn.iter().map(|&d| d as u32).sum::<u32>() - triangles + crowns;
    let every_group = model
        .leaf_groups
        .iter()
        .all(|g| g.leaves.clone().any(|l| drawn[l as usize] == 1));
    let sound = if crowns > 0 {
        crowns == 1 && model.crown.is_some() && drawn.iter().all(|&d| d == 0)
    } else {
        drawn.iter().all(|&d| d <= 1) && every_group
    };
    (triangles, points, sound)
}

#[test]
fn a_far_tree_chosen_whole_matches_its_groups_chosen_one_by_one() {
    let model = model();
    let costs = PrimitiveCosts::from_calibration(&Calibration::default(), 1.0);
    let groups_count = model.leaf_groups.len() as u32;
    let (mut single_size_checks, mut far_points_checks, mut crown_checks) = (0, 0, 0);
    for depth in [40.0, 150.0, 300.0, 600.0] {
        let v = view(depth);
        let g = groups(&model, depth);
        for method in [
            LeafMethod::Tc,
            LeafMethod::Tclod(PixelRange::default()),
            LeafMethod::Static(1),
            LeafMethod::Static(3),
            LeafMethod::Full,
        ] {
            let timed = matches!(method, LeafMethod::Tc | LeafMethod::Tclod(_));
            let mut previous = 0.0;
            for time in TIMES {
                let (mut one_by_one, mut at_once) =
                    (TreeDrawList::default(), TreeDrawList::default());
                let by_group = leaves(&model, &v, &costs, method, &g, time, &mut one_by_one);
                let whole = leaves_at_depth(&model, &v, &costs, method, depth, time, &mut at_once);
                let case = format!("{method:?} at {depth} with {time}: {by_group:?} vs {whole:?}");
                eprintln!(
                    "{case} {:?} {:?}",
                    drawn(&model, &one_by_one),
                    drawn(&model, &at_once)
                );
                assert!(whole.cost.is_finite(), "{case}");
                assert!(
                    !timed || whole.cost <= time * 1.0001 || whole.truncated,
                    "{case}"
                );
                assert!(
                    whole.cost >= previous * 0.9999,
                    "less with more time: {case}"
                );
                previous = whole.cost;
                let (a, b) = (drawn(&model, &one_by_one), drawn(&model, &at_once));
                assert!(b.2, "a group undrawn or a leaf twice: {case}");
                // The predicted cost is what is drawn.
                let triangle_leaf = costs.triangles(1, 0.0) * model.leaf_triangle_count() as f32
                    / model.leaves.len() as f32;
                let drawn_cost_floor = b.0 as f32 * triangle_leaf;
                assert!(whole.cost >= drawn_cost_floor * 0.9999, "{case}");
                match method {
                    // Triangles alone: the same count, up to a leaf per group.
                    LeafMethod::Tc | LeafMethod::Full | LeafMethod::Static(1) => {
                        assert!(a.0.abs_diff(b.0) <= groups_count, "{case}: {a:?} vs {b:?}");
                    }
                    // One point size for the whole tree: the smallest whose static split
                    // fits (group by group, remainders passed on mix two sizes); or, when
                    // no split fits, only the far points that fit, at the largest size.
                    // The crown disc: only when a far point of every group does not fit
                    // (the tree without a crown overruns), and cheaper than those.
                    LeafMethod::Tclod(_)
                        if at_once.leaf_points.len() == 1
                            && at_once.leaf_points[0].leaves.start == model.crown_leaf() =>
                    {
                        crown_checks += 1;
                        let bare = TreeModel {
                            crown: None,
                            ..model.clone()
                        };
                        let mut list = TreeDrawList::default();
                        let points =
                            leaves_at_depth(&bare, &v, &costs, method, depth, time, &mut list);
                        assert!(points.truncated, "{case}: {points:?}");
                        assert!(whole.cost < points.cost, "{case}: {points:?}");
                    }
                    LeafMethod::Tclod(sizes) if b.1 > 0 => {
                        assert_eq!(at_once.leaf_points.len(), 1, "{case}");
                        let size = at_once.leaf_points[0].size;
                        let split = |size| {
                            let method = LeafMethod::Static(size);
                            let mut list = TreeDrawList::default();
                            leaves_at_depth(&model, &v, &costs, method, depth, time, &mut list)
                        };
                        if split(size).cost == whole.cost {
                            single_size_checks += 1;
                            assert!(size == sizes.min || split(size - 1).cost > time, "{case}");
                        } else {
                            far_points_checks += 1;
                            assert!(split(size).cost > time, "{case}");
                            assert_eq!(b.0, 0, "{case}");
                        }
                    }
                    _ => {}
                }
            }
        }
    }
    assert!(single_size_checks > 3, "{single_size_checks}");
    assert!(far_points_checks > 0, "{far_points_checks}");
    assert!(crown_checks > 0, "{crown_checks}");
}

/// A floor is what the budget pays an object before the hand-out: given it, the object
/// draws within it (never truncated), with nothing it draws no more than it, and the
/// floor is that cheapest drawing, or near it (a group's cheapest may be its few leaves
/// as triangles rather than the far point the floor prices).
fn assert_floor(case: &str, floor: f32, mut search: impl FnMut(f32) -> Selected) {
    assert!(floor.is_finite() && floor >= 0.0, "{case}: floor {floor}");
    let none = search(0.0);
    let at = search(floor);
    assert!(
        none.cost <= floor * 1.00001,
        "{case}: {} with no time, floor {floor}",
        none.cost
    );
    assert!(
        !at.truncated && at.cost <= floor * 1.00001,
        "{case}: {at:?} at floor {floor}"
    );
    assert!(
        floor <= 1.25 * none.cost,
        "{case}: floor {floor} for a cheapest of {}",
        none.cost
    );
}

/// Every shipped species, seen at many depths and scales.
fn sightings() -> Vec<(String, TreeModel, TreeView, f32)> {
    let mut out = Vec::new();
    for name in ["slender", "broad", "grand", "dense"] {
        let model = common::species(name);
        for depth in [1.5, 6.0, 25.0, 100.0, 400.0, 3000.0] {
            for scale in [0.5, 1.0, 2.5] {
                let v = TreeView {
                    scale,
                    trunk_depth: depth,
                    projection: Projection::perspective(0.8, 540.0),
                };
                out.push((
                    format!("{name} at {depth} ×{scale}"),
                    model.clone(),
                    v,
                    depth,
                ));
            }
        }
    }
    out
}

/// Thesis §6.5: the time-critical search runs only when an object's time is below its
/// full cost. At its full cost an object draws full detail; a little less draws the best
/// that fits; nothing draws its floor, which the floor functions give without a search.
#[test]
fn full_detail_whenever_the_time_pays_for_it_and_the_floor_with_none() {
    let costs = PrimitiveCosts::from_calibration(&Calibration::default(), 1.0)
        .within_viewport(960.0 * 540.0);
    let widths = PixelRange::default();
    let close = |a: f32, b: f32| (a - b).abs() <= 1e-5 * a.abs().max(b.abs()).max(1e-12);
    for (case, model, v, depth) in sightings() {
        let total = model.trunk_triangle_count() as u32;
        let mut list = TreeDrawList::default();
        // Full detail, as the unlimited mode draws it.
        let trunk_full = trunk_tc(&model, &v, &costs, f32::INFINITY, &mut list).cost;
        for tclod in [false, true] {
            let search = |time: f32, list: &mut TreeDrawList| {
                if tclod {
                    trunk_tclod(&model, &v, &costs, widths, time, list)
                } else {
                    trunk_tc(&model, &v, &costs, time, list)
                }
            };
            let at = search(trunk_full, &mut list);
            assert_eq!(list.trunk_triangles, 0..total, "{case} tclod {tclod}");
            assert!(list.trunk_lines.is_empty(), "{case}");
            assert!(close(at.cost, trunk_full), "{case}");
            let below = search(0.95 * trunk_full, &mut list);
            assert!(
                below.cost <= 0.95 * trunk_full * 1.00001 || below.truncated,
                "{case}"
            );
            let floor = trunk_floor(&model, &v, &costs, tclod.then_some(widths));
            assert_floor(&case, floor, |time| search(time, &mut list));
        }
        let g = groups(&model, depth);
        for method in [LeafMethod::Tc, LeafMethod::Tclod(PixelRange::default())] {
            for at_depth in [false, true] {
                let search = |method: LeafMethod, time: f32, list: &mut TreeDrawList| {
                    if at_depth {
                        leaves_at_depth(&model, &v, &costs, method, depth, time, list)
                    } else {
                        leaves(&model, &v, &costs, method, &g, time, list)
                    }
                };
                let case = format!("{case} {method:?} at depth {at_depth}");
                let full = search(LeafMethod::Full, 0.0, &mut list).cost;
                let at = search(method, full, &mut list);
                assert_eq!(
                    drawn(&model, &list),
                    (model.leaves.len() as u32, 0, true),
                    "{case}"
                );
                assert!(close(at.cost, full), "{case}");
                let below = search(method, 0.95 * full, &mut list);
                assert!(
                    below.cost <= 0.95 * full * 1.00001 || below.truncated,
                    "{case}"
                );
                assert!(drawn(&model, &list).2, "{case}");
                let floor = if at_depth {
                    leaves_at_depth_floor(&model, &v, &costs, method, depth)
                } else {
                    leaves_floor(&model, &v, &costs, method, &g)
                };
                assert_floor(&case, floor, |time| search(method, time, &mut list));
            }
        }
    }
}

/// Leaf triangles drawn by `list`, and leaves drawn as points.
fn leaf_counts(list: &TreeDrawList) -> (u32, u32) {
    let triangles = list.leaf_triangles.iter().map(|r| r.end - r.start).sum();
    let points = list.leaf_points.iter().map(|r| r.leaves.len() as u32).sum();
    (triangles, points)
}

/// Where leaves are large on screen and a point costs four times the leaf it stands for
/// (lavapipe's learned costs), TCLOD draws what TC draws with the same time: as many leaf
/// triangles, no points. Where leaves are a pixel or less, it draws points, and covers
/// more of the tree than TC's few leaves.
#[test]
fn tclod_takes_tc_s_leaves_where_its_points_would_show_less() {
    let model = model();
    let mut costs = PrimitiveCosts::from_calibration(&Calibration::default(), 1.0);
    let per_leaf = model.leaf_triangle_count() as f32 / model.leaves.len() as f32;
    costs.point = vec![4.0 * costs.triangle * per_leaf; costs.point.len()];
    let leaf_pixels = |depth: f32| group_area(&model, &view(depth), 1, depth);
    let near = [1.0, 2.0, 3.0, 5.0, 8.0]
        .into_iter()
        .find(|&d| (30.0..400.0).contains(&leaf_pixels(d)))
        .expect("a depth where a leaf covers 30–400 px");
    let far = [300.0, 600.0, 1200.0]
        .into_iter()
        .find(|&d| leaf_pixels(d) < 0.5)
        .expect("a depth where a leaf is under a pixel");
    let tclod = LeafMethod::Tclod(PixelRange::default());
    // The leaves' full-detail cost, and TC's leaves with `share` of it.
    let tc_at = |v: &TreeView, g: &[VisibleLeafGroup], share: f32| {
        let mut list = TreeDrawList::default();
        let full = leaves(&model, v, &costs, LeafMethod::Full, g, 0.0, &mut list).cost;
        leaves(
            &model,
            v,
            &costs,
            LeafMethod::Tc,
            g,
            share * full,
            &mut list,
        );
        (full, list)
    };
    for (depth, share) in [(near, 0.6), (near, 0.9)] {
        let (v, g) = (view(depth), groups(&model, depth));
        let (full, mut list) = tc_at(&v, &g, share);
        let tc = leaf_counts(&list);
        assert!(tc.0 as f32 > 0.5 * model.leaves.len() as f32, "{tc:?}");
        let s = leaves(&model, &v, &costs, tclod, &g, share * full, &mut list);
        let ours = leaf_counts(&list);
        assert!(s.cost <= share * full * 1.0001, "{s:?}");
        // (Within a leaf in a hundred: each group rounds its share down to whole leaves,
        // and the two methods' groups are paid different floors first.)
        assert!(
            ours.0 as f32 >= 0.99 * tc.0 as f32 && ours.1 == 0,
            "at depth {depth}, {share} of full detail: TCLOD drew {ours:?} (triangles, points), TC {tc:?}"
        );
    }
    // Pixels covered: leaves as triangles their own area, points their size squared
    // (the far tree's leaves together cover far more than either).
    let (v, g) = (view(far), groups(&model, far));
    let covered = |list: &TreeDrawList| {
        let points: f32 = list
            .leaf_points
            .iter()
            .map(|r| (r.leaves.len() as u32 * r.size * r.size) as f32)
            .sum();
        leaf_counts(list).0 as f32 * leaf_pixels(far) + points
    };
    let (full, mut list) = tc_at(&v, &g, 1.0 / 8.0);
    let tc = covered(&list);
    leaves(&model, &v, &costs, tclod, &g, full / 8.0, &mut list);
    let ours = covered(&list);
    assert!(
        ours > 1.5 * tc,
        "a far tree at ⅛ of full detail: TCLOD covered {ours} px, TC {tc} px"
    );
}

/// A far tree short of time draws its crown disc: one point at its crown leaf, the side
/// of a square of the crown's projected area, cheaper than the far point of every leaf
/// group it stands for; with those points' time it draws them instead, and a model
/// without a crown (a group impostor) never draws one.
#[test]
fn a_far_tree_short_of_time_draws_one_disc_the_size_of_its_crown() {
    let costs = PrimitiveCosts::from_calibration(&Calibration::default(), 1.0);
    let method = LeafMethod::Tclod(PixelRange::default());
    let mut discs = 0;
    for name in ["slender", "broad", "grand", "dense"] {
        let model = common::species(name);
        let crown = model.crown.expect("a species' leaves have a crown");
        let (lo, hi) = (model.bounds.min, model.bounds.max);
        assert!(
            crown.center.cmpge(lo).all() && crown.center.cmple(hi).all(),
            "{name}: crown centre {} outside the tree",
            crown.center
        );
        let side_view = (hi - lo).y * (hi - lo).x.max((hi - lo).z);
        assert!(
            crown.area > 0.05 * side_view && crown.area < side_view,
            "{name}: crown area {} against a side view of {side_view}",
            crown.area
        );
        let bare = TreeModel {
            crown: None,
            ..model.clone()
        };
        let crown_leaf = model.crown_leaf();
        for depth in [60.0, 150.0, 400.0, 1500.0] {
            let v = view(depth);
            let case = format!("{name} at {depth}");
            let mut list = TreeDrawList::default();
            let chosen = leaves_at_depth(&model, &v, &costs, method, depth, 0.0, &mut list);
            let bare_floor = leaves_at_depth_floor(&bare, &v, &costs, method, depth);
            let side = crown.area.sqrt() * v.projection.pixels(1.0, depth);
            if side > 64.5 {
                // Larger than the largest point: no disc could cover it.
                assert!(
                    list.leaf_points
                        .iter()
                        .all(|r| !r.leaves.contains(&crown_leaf)),
                    "{case}: a disc of {side} px"
                );
                continue;
            }
            discs += 1;
            assert_eq!(
                list.leaf_points,
                vec![PointRun {
                    leaves: crown_leaf..crown_leaf + 1,
                    size: ((side + 0.5) as u32).max(1),
                }],
                "{case}"
            );
            assert!(list.leaf_triangles.is_empty(), "{case}");
            let floor = leaves_at_depth_floor(&model, &v, &costs, method, depth);
            assert_eq!(chosen.cost, floor, "{case}");
            assert!(chosen.truncated, "{case}: no time at all");
            assert!(
                floor < bare_floor,
                "{case}: disc {floor}, points {bare_floor}"
            );
            if side <= 8.0 {
                assert!(
                    8.0 * floor < bare_floor,
                    "{case}: disc {floor}, points {bare_floor}"
                );
            }
            // With the time of a far point per group, those points.
            let with_points =
                leaves_at_depth(&model, &v, &costs, method, depth, bare_floor, &mut list);
            assert!(!with_points.truncated, "{case}: {with_points:?}");
            assert!(
                list.leaf_points
                    .iter()
                    .all(|r| !r.leaves.contains(&crown_leaf)),
                "{case}: {list:?}"
            );
            assert!(drawn(&model, &list).2, "{case}");
            leaves_at_depth(&bare, &v, &costs, method, depth, 0.0, &mut list);
            assert!(
                list.leaf_points.iter().all(|r| r.leaves.end <= crown_leaf),
                "{case}: a crown without one"
            );
        }
    }
    assert!(discs >= 8, "{discs} discs");
}
