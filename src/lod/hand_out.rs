//! The Budget and Select stages: the rendering time the cost model leaves in the target,
//! handed out by the configured strategy with each object's search inside the hand-out,
//! and the chosen lists written to the instances.

use std::time::{Duration, Instant};

use bevy::prelude::*;

use super::groups::GroupImpostors;
use super::hierarchical::{Drawn, HierarchicalCut, HierarchyInputs, Ladder};
use super::select::{self, LeafMethod, PrimitiveCosts, VisibleGroup};
use super::value::{Object, Part, VisibleTree};
use super::{
    BenefitReport, FrameBudget, LADDER_FRACTIONS, LadderObjects, LodDiagnostics, LodFrame, LodMode,
    StrategyKind, TARGET_WARNING_SECS,
};
use crate::budget::{
    Allocation, BudgetStats, BudgetStrategy, Fit, Level, MIN_DEPTH, ObjectDesc, PreviousSelection,
    oracle,
};
use crate::cost::{CostModel, FamilyTimes, FrameClock, FramePrediction, MeasuredPacing};
use crate::culling::ForestCulling;
use crate::display::{DisplayTiming, VsyncSettings};
use crate::draw::{PrimitiveCounts, TreeDrawList};
use crate::instance::ForestInstances;
use crate::tree::TreeModel;

/// Time given to a search that is to find an object's full detail, seconds: more than
/// any object's full detail costs.
const FULL_DETAIL_TIME: f32 = 1.0e6;

pub(super) fn hand_out_time(
    mut frame: ResMut<LodFrame>,
    budget: Res<FrameBudget>,
    mut cost_model: ResMut<CostModel>,
    clock: Res<FrameClock>,
    models: Res<Assets<TreeModel>>,
    time: Res<Time<Real>>,
    mut diagnostics: ResMut<LodDiagnostics>,
    mut ladders: ResMut<LadderObjects>,
    report: Res<BenefitReport>,
    impostors: Res<GroupImpostors>,
    culling: Option<Res<ForestCulling>>,
    mut cut: ResMut<HierarchicalCut>,
    display: Option<Res<DisplayTiming>>,
    pacing: Option<Res<MeasuredPacing>>,
    vsync: Option<Res<VsyncSettings>>,
) {
    let start = Instant::now();
    let frame = &mut *frame;
    let scales = cost_model.family_scales();
    let costs = cost_model
        .primitive_costs()
        .within_viewport(frame.viewport_pixels);
    let visible_instances = (frame.trees.len() + frame.held.len()) as u32;
    // This frame's logic so far is known: only the rest of the update is predicted.
    let logic_so_far = clock.elapsed();
    let logic = logic_so_far + cost_model.logic_after_budget(visible_instances);
    let overlap = cost_model.overlap();
    let fixed = cost_model.render_fixed();
    let target = (budget.target_ms.max(0.0)) / 1000.0;
    let aim = super::aim::aim(
        target,
        budget.goal,
        display.as_deref(),
        pacing.as_deref(),
        vsync.as_deref(),
        &cost_model,
    );
    let available = overlap.rendering_time(logic, aim.work);
    let target_below_logic =
        available <= 0.0 && budget.mode != LodMode::Unlimited && budget.mode != LodMode::Static;
    if target_below_logic {
        let now = time.elapsed_secs();
        let since = *frame.target_below_logic_since.get_or_insert(now);
        if !frame.warned_target && now - since >= TARGET_WARNING_SECS {
            warn!(
                "FrameBudget: target {:.1} ms has been at or below the logic time ({:.1} ms now) for {TARGET_WARNING_SECS} s; every object is drawn at its cheapest",
                budget.target_ms,
                logic * 1000.0
            );
            frame.warned_target = true;
        }
    } else {
        frame.target_below_logic_since = None;
        frame.warned_target = false;
    }
    // The app's own visible meshes are not budgeted but predicted: they take their time
    // first, like the fixed part.
    let app_meshes = {
        let load = ladders.app_meshes;
        let meshes =
            load.draws as f32 * costs.mesh_draw + load.triangles as f32 * costs.mesh_triangle;
        let mesh_pixels = costs.mesh_pixels(load.pixels);
        select::Selected {
            cost: meshes + mesh_pixels,
            meshes,
            mesh_pixels,
            ..select::Selected::default()
        }
    };
    let rendering = (available - fixed - app_meshes.cost).max(0.0);

    // The models by `VisibleTree::model`, looked up once a frame.
    let tree_models: Vec<Option<&TreeModel>> =
        frame.infos.iter().map(|info| models.get(info.id)).collect();
    let model_of = |tree: &VisibleTree| tree_models.get(tree.model as usize).copied().flatten();

    // Per tree, a fresh list.
    frame
        .lists
        .resize_with(frame.trees.len(), TreeDrawList::default);
    for list in &mut frame.lists[..frame.trees.len()] {
        list.clear();
    }

    let mut predicted = 0.0f32;
    // What of it went to lines, to points and to ladder meshes (the rest to triangles).
    let mut parts = select::Selected::default();
    let mut take = |chosen: select::Selected| {
        parts.lines += chosen.lines;
        parts.points += chosen.points;
        parts.meshes += chosen.meshes;
        parts.mesh_pixels += chosen.mesh_pixels;
        chosen
    };
    let LadderObjects {
        entries: ladder_entries,
        triangles: ladder_triangles,
        chosen: ladder_chosen,
        ..
    } = &mut *ladders;
    // The pixels a ladder entity covers, whatever its level.
    let view = frame.view;
    let ladder_pixels = |e: u32| match (ladder_entries.get(e as usize), view) {
        (Some(entry), Some(view)) => view.sphere_pixels(entry.center, entry.radius),
        _ => 0.0,
    };
    // A ladder entry's level shown now, which Robin Hood's choice keeps while it fits
    // (the ladder strategies price exact rungs and keep their own previous choice).
    let keep_shown = budget.strategy == StrategyKind::RobinHood;
    let hold_of = |e: u32| {
        ladder_entries
            .get(e as usize)
            .map_or(select::LadderHold::default(), |entry| entry.hold)
    };
    // A ladder entry's levels' triangle counts, best first.
    let levels_of = |e: u32| {
        ladder_entries
            .get(e as usize)
            .and_then(|entry| {
                ladder_triangles.get(entry.levels.start as usize..entry.levels.end as usize)
            })
            .unwrap_or(&[])
    };
    // The level the budget wants for a ladder entity with `time`, and the cost of what it
    // will show: the hysteresis may hold the level shown, and then that is what is paid.
    let ladder_pick = |object: Object, time: f32| {
        let hold = hold_of(object.index);
        let levels = levels_of(object.index);
        let pixels = ladder_pixels(object.index);
        let (wanted, chosen) = select::ladder_level(
            &costs,
            levels,
            pixels,
            time,
            keep_shown.then_some(hold.shown),
        );
        let shown = hold.shown_for(wanted);
        let paid = if shown == wanted {
            chosen
        } else {
            select::ladder_cost(&costs, levels, pixels, shown)
        };
        (wanted, paid)
    };
    let mut truncated = 0;
    let mut wasted = 0.0;
    let mut undrawn = 0;
    let mut floor = 0.0;
    let mut floor_excess = 0.0;
    let mut benefit = 0.0;
    let mut benefit_bound = 0.0;
    let mut report_time = Duration::ZERO;
    let mut groups_drawn = 0;
    let mut group_counts = PrimitiveCounts::default();
    // The hierarchical cut's benefit (its groups' included), for the report.
    let mut cut_benefit = None;
    match budget.mode {
        LodMode::Unlimited | LodMode::Static => {
            for (tree, list) in frame.trees.iter().zip(&mut frame.lists) {
                let Some(m) = model_of(tree) else {
                    continue;
                };
                let unlimited = budget.mode == LodMode::Unlimited;
                if tree.trunk_visible {
                    predicted += take(if unlimited {
                        select::trunk_tc(m, &tree.view, &costs, f32::INFINITY, list)
                    } else {
                        select::trunk_static(m, &tree.view, &costs, budget.line_widths, list)
                    })
                    .cost;
                }
                let method = if unlimited {
                    LeafMethod::Full
                } else {
                    LeafMethod::Static(budget.point_sizes.sanitized().min)
                };
                predicted += take(tree_leaves(
                    m,
                    tree,
                    &frame.groups,
                    &costs,
                    method,
                    0.0,
                    list,
                ))
                .cost;
            }
            // Ladders show their best level (no static rule of their own).
            for object in frame.objects.iter().filter(|o| o.part == Part::Ladder) {
                let (level, chosen) = ladder_pick(*object, f32::INFINITY);
                predicted += take(chosen).cost;
                ladder_chosen[object.index as usize] = Some(level);
            }
        }
        LodMode::Tc | LodMode::Tclod => {
            let tclod = budget.mode == LodMode::Tclod;
            let (trees, groups, objects, lists, scratch) = (
                &frame.trees,
                &frame.groups,
                &frame.objects,
                &mut frame.lists,
                &mut frame.scratch,
            );
            let leaf_method = if tclod {
                LeafMethod::Tclod(budget.point_sizes)
            } else {
                LeafMethod::Tc
            };
            // What object `i` draws with `given` seconds, written into `list` (a ladder
            // entity's level is `select::ladder_level`'s; it writes no list).
            let search = |i: usize, given: f32, list: &mut TreeDrawList| {
                let object = objects[i];
                if object.part == Part::Ladder {
                    return ladder_pick(object, given).1;
                }
                let tree = &trees[object.index as usize];
                let Some(m) = model_of(tree) else {
                    return select::Selected::default();
                };
                if object.part == Part::Leaves {
                    tree_leaves(m, tree, groups, &costs, leaf_method, given, list)
                } else if tclod {
                    select::trunk_tclod(m, &tree.view, &costs, budget.line_widths, given, list)
                } else {
                    select::trunk_tc(m, &tree.view, &costs, given, list)
                }
            };
            // Draws object `i` with `given` seconds: a tree part into its tree's list, a
            // ladder entity's level into `ladder_chosen` (returned too); what it costs.
            let mut draw = |i: usize, given: f32| {
                let object = objects[i];
                if object.part == Part::Ladder {
                    let (level, chosen) = ladder_pick(object, given);
                    ladder_chosen[object.index as usize] = Some(level);
                    (chosen, Some(level))
                } else {
                    (search(i, given, &mut lists[object.index as usize]), None)
                }
            };
            let entity_of = |object: Object| match object.part {
                Part::Ladder => ladder_entries[object.index as usize].entity,
                _ => trees[object.index as usize].entity,
            };
            let stats = if budget.strategy == StrategyKind::RobinHood {
                // Every object's cheapest representation, paid before the hand-out.
                let floors = &mut frame.floors;
                floors.clear();
                floors.extend(objects.iter().map(|object| {
                    if object.part == Part::Ladder {
                        let pixels = ladder_pixels(object.index);
                        return select::ladder_level(
                            &costs,
                            levels_of(object.index),
                            pixels,
                            0.0,
                            None,
                        )
                        .1
                        .cost;
                    }
                    let tree = &trees[object.index as usize];
                    let Some(m) = model_of(tree) else {
                        return 0.0;
                    };
                    if object.part == Part::Leaves {
                        tree_leaves_floor(m, tree, groups, &costs, leaf_method)
                    } else {
                        select::trunk_floor(
                            m,
                            &tree.view,
                            &costs,
                            tclod.then_some(budget.line_widths),
                        )
                    }
                }));
                // Far trees held this frame keep what they draw; the rest share what
                // is left (`FrameBudget::far_refresh`).
                let holding = frame.decided_key.is_some();
                let choices = &mut frame.object_choices;
                choices.clear();
                choices.resize(objects.len(), select::Selected::default());
                let stats = frame.robin_hood.distribute_with(
                    &frame.values,
                    &frame.complexities,
                    &frame.floors,
                    (rendering - frame.held_parts.cost).max(0.0),
                    |i, given| {
                        let (chosen, ladder_level) = draw(i, given);
                        // A residue pass offers the object more and replaces this choice:
                        // only the last one is drawn, priced and learned from.
                        choices[i] = chosen;
                        // A tree part's level: 0 at full detail, nothing more to buy.
                        let level = ladder_level.unwrap_or(u32::from(!chosen.full));
                        Fit {
                            used: chosen.cost,
                            level,
                            truncated: chosen.truncated,
                        }
                    },
                    &mut frame.allocations,
                );
                let tree_parts = &mut frame.tree_parts;
                tree_parts.clear();
                if holding {
                    tree_parts.resize(trees.len(), select::Selected::default());
                }
                for (object, chosen) in objects.iter().zip(choices.iter()) {
                    let chosen = take(*chosen);
                    if let Some(tree) = tree_parts.get_mut(object.index as usize)
                        && object.part != Part::Ladder
                    {
                        *tree = select::Selected::both(*tree, chosen);
                    }
                }
                stats
            } else {
                // Ladders: each object's representations at fractions of its full cost.
                let values = &frame.values;
                let mut ladder_of = |i: usize| -> Ladder {
                    let full = search(i, FULL_DETAIL_TIME, scratch).cost;
                    let mut ladder = [Level::new(0.0, 0.0); LADDER_FRACTIONS.len()];
                    let mut times = [0.0; LADDER_FRACTIONS.len()];
                    let mut previous_cost = f32::INFINITY;
                    for (j, fraction) in LADDER_FRACTIONS.iter().enumerate() {
                        times[j] = full * fraction;
                        let cost = search(i, times[j], scratch).cost.min(previous_cost);
                        previous_cost = cost;
                        let benefit = oracle::sqrt_benefit(values[i], full, cost) as f32;
                        ladder[j] = Level::new(cost, benefit);
                    }
                    (ladder, times)
                };
                if budget.strategy == StrategyKind::Hierarchical {
                    let view = frame.view;
                    let group_lists = &mut frame.group_lists;
                    // A group impostor's search: its trunk and leaves each given `fraction`
                    // of their full detail's time (`fulls`, searched when not given);
                    // what it draws, and the full details' times.
                    let group_search = |node: usize,
                                        fraction: f32,
                                        fulls: Option<(f32, f32)>,
                                        list: &mut TreeDrawList|
                     -> (select::Selected, (f32, f32)) {
                        let (Some(g), Some(view)) =
                            (impostors.nodes.get(node).and_then(Option::as_ref), view)
                        else {
                            return Default::default();
                        };
                        let Some(m) = models.get(&g.model) else {
                            return Default::default();
                        };
                        let depth = |at: Vec3| view.depth(g.origin + at).max(MIN_DEPTH);
                        let tree_view = select::TreeView {
                            scale: 1.0,
                            trunk_depth: depth(m.trunk_area_center),
                            projection: view.projection(),
                        };
                        let trunk = |time: f32, list: &mut TreeDrawList| {
                            if tclod {
                                select::trunk_tclod(
                                    m,
                                    &tree_view,
                                    &costs,
                                    budget.line_widths,
                                    time,
                                    list,
                                )
                            } else {
                                select::trunk_tc(m, &tree_view, &costs, time, list)
                            }
                        };
                        let leaves = |time: f32, list: &mut TreeDrawList| {
                            select::leaves_at_depth(
                                m,
                                &tree_view,
                                &costs,
                                leaf_method,
                                depth(m.bounds.center()),
                                time,
                                list,
                            )
                        };
                        let (full_trunk, full_leaves) = fulls.unwrap_or_else(|| {
                            (
                                trunk(FULL_DETAIL_TIME, list).cost,
                                leaves(FULL_DETAIL_TIME, list).cost,
                            )
                        });
                        let chosen = select::Selected::both(
                            trunk(full_trunk * fraction, list),
                            leaves(full_leaves * fraction, list),
                        );
                        (chosen, (full_trunk, full_leaves))
                    };
                    let boxes = culling.as_deref().and_then(|c| c.hierarchy.as_ref());
                    let has_group = |node: usize| impostors.has_group(culling.as_deref(), node);
                    let inputs = HierarchyInputs {
                        boxes,
                        instances: culling.as_deref().map_or(0, |c| c.result.visibility.len()),
                        trees,
                        objects,
                        values,
                        ladders: ladder_entries,
                        rendering,
                        layout: culling
                            .as_deref()
                            .and_then(ForestCulling::hierarchy_version),
                        has_group: &has_group,
                    };
                    let mut group_scratch = TreeDrawList::default();
                    let mut group_ladder = |node: usize, value: f32, members_full: f32| {
                        if !has_group(node) {
                            return None;
                        }
                        let scratch = &mut group_scratch;
                        let (best, fulls) = group_search(node, 1.0, None, scratch);
                        let full = best.cost;
                        let mut ladder = [Level::new(0.0, 0.0); LADDER_FRACTIONS.len()];
                        let mut previous_cost = f32::INFINITY;
                        for (j, &fraction) in LADDER_FRACTIONS.iter().enumerate() {
                            let cost = group_search(node, fraction, Some(fulls), scratch)
                                .0
                                .cost
                                .min(previous_cost);
                            previous_cost = cost;
                            // Judged against its trees' full detail, not its own.
                            ladder[j] = Level::new(
                                cost,
                                oracle::sqrt_benefit(value, members_full.max(full), cost) as f32,
                            );
                        }
                        Some((ladder, LADDER_FRACTIONS))
                    };
                    let outcome = frame.hierarchical.solve(
                        &inputs,
                        &mut ladder_of,
                        &mut group_ladder,
                        &mut cut,
                    );
                    frame.allocations.clear();
                    frame.allocations.resize(objects.len(), Allocation::DROPPED);
                    let mut used = 0.0;
                    let mut truncated = 0;
                    let mut lists_used = 0;
                    for drawn in &frame.hierarchical.drawn {
                        match *drawn {
                            Drawn::Object {
                                object,
                                level,
                                time,
                            } => {
                                let chosen = take(draw(object as usize, time).0);
                                used += chosen.cost;
                                truncated += u32::from(chosen.truncated);
                                frame.allocations[object as usize] =
                                    Allocation::drawn(chosen.cost, level);
                            }
                            Drawn::Group { node, fraction, .. } => {
                                let Some(g) =
                                    impostors.nodes.get(node as usize).and_then(Option::as_ref)
                                else {
                                    continue;
                                };
                                if group_lists.len() <= lists_used {
                                    group_lists.push((g.entity, TreeDrawList::default()));
                                }
                                let (entity, list) = &mut group_lists[lists_used];
                                *entity = g.entity;
                                lists_used += 1;
                                let chosen =
                                    take(group_search(node as usize, fraction, None, list).0);
                                group_counts += g.slot.counts(list);
                                used += chosen.cost;
                                truncated += u32::from(chosen.truncated);
                            }
                        }
                    }
                    group_lists.truncate(lists_used);
                    groups_drawn = outcome.groups_drawn;
                    cut_benefit = Some(outcome.solved.benefit as f32);
                    // Not even the coarsest cut fitted: it is the floor, and its overrun
                    // the one no choice could avoid.
                    let floor = if outcome.scene_dropped { used } else { 0.0 };
                    BudgetStats {
                        rendering_time: rendering,
                        given: used,
                        used,
                        wasted: (rendering - used).max(0.0),
                        overrun: (used - rendering).max(0.0),
                        drawn: frame.hierarchical.drawn.len() as u32,
                        dropped: 0,
                        truncated,
                        floor,
                        floor_excess: (floor - rendering).max(0.0),
                    }
                } else {
                    frame.problem.clear();
                    frame.rung_times.clear();
                    frame.next_previous.clear();
                    for (i, &object) in objects.iter().enumerate() {
                        let (ladder, times) = ladder_of(i);
                        let key = (entity_of(object), object.part);
                        let previous = frame
                            .previous
                            .get(&key)
                            .map_or(PreviousSelection::New, |&l| PreviousSelection::Level(l));
                        let desc = ObjectDesc {
                            value: values[i],
                            complexity: frame.complexities[i],
                            previous,
                        };
                        if frame.problem.push_object(desc, &ladder).is_err() {
                            // Not expected: values and costs are finite by construction. Keep
                            // the indices aligned with a free, worthless object.
                            let _ = frame
                                .problem
                                .push_object(ObjectDesc::default(), &[Level::new(0.0, 0.0)]);
                        }
                        frame.rung_times.push(times);
                    }
                    let strategy: &mut dyn BudgetStrategy = match budget.strategy {
                        StrategyKind::FunkhouserSequin => &mut frame.funkhouser,
                        StrategyKind::FunkhouserIncremental => &mut frame.incremental,
                        _ => &mut frame.triangle_budget,
                    };
                    let stats =
                        strategy.distribute(&frame.problem, rendering, &mut frame.allocations);
                    for (i, allocation) in frame.allocations.iter().enumerate() {
                        let object = objects[i];
                        if let Some(level) = allocation.level {
                            let time = frame.rung_times[i][level as usize];
                            take(draw(i, time).0);
                            frame
                                .next_previous
                                .insert((entity_of(object), object.part), level);
                        }
                    }
                    core::mem::swap(&mut frame.previous, &mut frame.next_previous);
                    stats
                }
            };
            if report.enabled {
                let report_start = Instant::now();
                let full: Vec<f32> = (0..objects.len())
                    .map(|i| search(i, FULL_DETAIL_TIME, scratch).cost)
                    .collect();
                benefit = cut_benefit.unwrap_or_else(|| {
                    frame
                        .allocations
                        .iter()
                        .zip(&frame.values)
                        .zip(&full)
                        .map(|((a, &value), &full)| {
                            let used = if a.level.is_some() { a.used } else { 0.0 };
                            oracle::sqrt_benefit(value, full, used)
                        })
                        .sum::<f64>() as f32
                });
                let pairs: Vec<(f32, f32)> = frame
                    .values
                    .iter()
                    .copied()
                    .zip(full.iter().copied())
                    .collect();
                benefit_bound = oracle::sqrt_benefit_bound(&pairs, rendering) as f32;
                report_time = report_start.elapsed();
            }
            predicted = stats.used + take(frame.held_parts).cost;
            truncated = stats.truncated;
            undrawn = stats.dropped;
            wasted = stats.wasted;
            floor = stats.floor;
            floor_excess = stats.floor_excess;
        }
    }

    let mut counts = group_counts;
    counts += frame.held_counts;
    let remember = frame.decided_key.is_some();
    if remember {
        frame.decided.resize(frame.placed.len(), None);
    }
    for (t, (tree, list)) in frame.trees.iter().zip(&frame.lists).enumerate() {
        if let Some(info) = frame.infos.get(tree.model as usize) {
            let tree_counts = info.slot.counts(list);
            counts += tree_counts;
            // A far tree's decision, kept for the frames it is held (a tree not decided
            // as a whole has none to keep).
            if remember
                && let (Some(slot), Some(parts)) = (
                    frame.decided.get_mut(tree.instance as usize),
                    frame.tree_parts.get(t),
                )
            {
                *slot = tree.leaf_depth.is_some().then_some((*parts, tree_counts));
            }
        }
    }
    // The selection by family, priced as the calibration alone would: what the cost
    // model learns from once the frame is measured.
    let triangles =
        (predicted - parts.lines - parts.points - parts.meshes - parts.mesh_pixels).max(0.0);
    let triangle_vertices = (counts.triangles as f32 * costs.triangle).min(triangles);
    let priced = FamilyTimes {
        triangles: triangle_vertices,
        triangle_pixels: triangles - triangle_vertices,
        lines: parts.lines,
        points: parts.points,
        meshes: parts.meshes + app_meshes.meshes,
        mesh_pixels: parts.mesh_pixels + app_meshes.mesh_pixels,
    };
    let render = fixed + app_meshes.cost + predicted;
    let frame_time = overlap.frame_time(logic, render);
    let calibrated = priced.unscaled(scales);
    cost_model.record(FramePrediction {
        frame: clock.frame,
        visible_instances,
        calibrated,
        logic,
        logic_so_far,
        render,
        frame_time,
    });
    let shown = super::aim::shown(cost_model.last_learned(), target, aim.period);
    let measured = cost_model.last_learned().copied().unwrap_or_default();
    *diagnostics = LodDiagnostics {
        frame: clock.frame,
        target_ms: budget.target_ms,
        visible_objects: frame.objects.len() as u32,
        visible_instances,
        logic_ms: logic * 1000.0,
        logic_so_far_ms: logic_so_far * 1000.0,
        app_meshes_ms: app_meshes.cost * 1000.0,
        app_mesh_draws: ladders.app_meshes.draws,
        render_budget_ms: rendering * 1000.0,
        render_fixed_ms: fixed * 1000.0,
        predicted_render_ms: render * 1000.0,
        predicted_frame_ms: frame_time * 1000.0,
        measured_frame: measured.measured.frame,
        measured_frame_ms: measured.measured.interval * 1000.0,
        measured_logic_ms: measured.measured.logic * 1000.0,
        measured_render_ms: measured.measured.render * 1000.0,
        measured_frame_predicted_ms: measured.predicted.frame_time * 1000.0,
        work_target_ms: aim.work * 1000.0,
        vsync_period_ms: aim.period.unwrap_or(0.0) * 1000.0,
        frame_spread: cost_model.frame_spread().sigma(),
        measured_work_ms: shown.work_ms,
        measured_gpu_ms: shown.gpu_ms,
        measured_waited_ms: shown.waited_ms,
        measured_bound: shown.bound,
        measured_periods: shown.periods,
        missed_vblank: shown.missed_vblank,
        wasted_ms: wasted * 1000.0,
        overrun_ms: (predicted - rendering).max(0.0) * 1000.0,
        floor_ms: floor * 1000.0,
        floor_excess_ms: floor_excess * 1000.0,
        learned: cost_model.learned(),
        calibrated,
        counts,
        truncated,
        undrawn,
        groups_drawn,
        held_trees: frame.held.len() as u32,
        trees_drawn: frame.lists[..frame.trees.len()]
            .iter()
            .filter(|list| !list.is_empty())
            .count() as u32,
        benefit,
        benefit_bound,
        value_stage_ms: frame.value_ms,
        budget_stage_ms: (start.elapsed() - report_time).as_secs_f32() * 1000.0,
        select_stage_ms: 0.0,
        target_below_logic,
        // Counted after the hand-out, over the measured frames (`count_frames_over`).
        frames_over_share: diagnostics.frames_over_share,
    };
}

/// What [`tree_leaves`] draws with no time: the cost of the leaves' cheapest
/// representation.
fn tree_leaves_floor(
    model: &TreeModel,
    tree: &VisibleTree,
    groups: &[VisibleGroup],
    costs: &PrimitiveCosts,
    method: LeafMethod,
) -> f32 {
    match tree.leaf_depth {
        Some(depth) => select::leaves_at_depth_floor(model, &tree.view, costs, method, depth),
        None => {
            let groups = &groups[tree.groups.start as usize..tree.groups.end as usize];
            select::leaves_floor(model, &tree.view, costs, method, groups)
        }
    }
}

/// A tree's leaves by `method` with `time`: group by group, or all at one depth.
fn tree_leaves(
    model: &TreeModel,
    tree: &VisibleTree,
    groups: &[VisibleGroup],
    costs: &PrimitiveCosts,
    method: LeafMethod,
    time: f32,
    list: &mut TreeDrawList,
) -> select::Selected {
    match tree.leaf_depth {
        Some(depth) => select::leaves_at_depth(model, &tree.view, costs, method, depth, time, list),
        None => {
            let groups = &groups[tree.groups.start as usize..tree.groups.end as usize];
            select::leaves(model, &tree.view, costs, method, groups, time, list)
        }
    }
}

pub(super) fn write_draw_lists(
    mut frame: ResMut<LodFrame>,
    table: Res<ForestInstances>,
    mut lists: Query<&mut TreeDrawList>,
    mut diagnostics: ResMut<LodDiagnostics>,
) {
    let start = Instant::now();
    let frame = &mut *frame;
    // Trees shown last frame and not chosen now draw nothing; the chosen ones get their
    // list. (Only those: the rest of a large forest is left alone, already empty.)
    frame.stamp = frame.stamp.wrapping_add(1).max(1);
    let stamp = frame.stamp;
    frame.stamps.resize(table.len(), 0);
    let held = frame.held.iter().copied();
    for instance in frame.trees.iter().map(|t| t.instance).chain(held) {
        if let Some(s) = frame.stamps.get_mut(instance as usize) {
            *s = stamp;
        }
    }
    for entity in frame.trees_shown.drain(..) {
        let chosen = table
            .index_of(entity)
            .is_some_and(|i| frame.stamps.get(i as usize) == Some(&stamp));
        if !chosen && let Ok(mut list) = lists.get_mut(entity) {
            list.clear();
        }
    }
    for (tree, chosen) in frame.trees.iter().zip(&mut frame.lists) {
        let Ok(mut list) = lists.get_mut(tree.entity) else {
            continue;
        };
        // Swapped, not compared and copied: the frame's list gets the old one's
        // allocations to fill next frame.
        core::mem::swap(&mut *list, chosen);
        if !list.is_empty() {
            frame.trees_shown.push(tree.entity);
        }
    }
    // Held far trees keep last frame's list.
    frame.trees_shown.extend(
        frame
            .held
            .iter()
            .filter_map(|&i| table.entities.get(i as usize)),
    );
    // Group impostors: last frame's cleared, this frame's cut swapped in.
    for entity in frame.groups_shown.drain(..) {
        if let Ok(mut list) = lists.get_mut(entity) {
            list.clear();
        }
    }
    for (entity, chosen) in &mut frame.group_lists {
        if let Ok(mut list) = lists.get_mut(*entity) {
            core::mem::swap(&mut *list, chosen);
            frame.groups_shown.push(*entity);
        }
    }
    diagnostics.select_stage_ms = start.elapsed().as_secs_f32() * 1000.0;
}
