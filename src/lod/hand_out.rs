//! The Budget stage: the rendering time the cost model leaves in the target, handed out
//! by the configured [`strategy`](super::strategy) with each object's search inside the
//! hand-out, and what was chosen priced for the cost model to learn from.

use std::time::{Duration, Instant};

use bevy::ecs::system::SystemParam;
use bevy::prelude::*;

use super::aim::{AimCalibration, AimInputs};
use super::alerts::{self, TargetWatch};
use super::draw_lists::ChosenLists;
use super::group_impostors::GroupImpostors;
use super::logic_hitch::{self, UsualLogic};
use super::search::{self, Choices, ObjectSearch};
use super::select::{PrimitiveCosts, Selected};
use super::steady;
use super::strategy::{self, HandOut, Outcome, Scene, Strategies};
use super::value::{FarDecisions, Object, Part, VisibleObjects, VisibleTree};
use super::{
    AppMeshLoad, BenefitReport, FrameBudget, HierarchicalCut, LadderEntry, LadderObjects,
    LodDiagnostics, SteadySelection, StrategyKind,
};
use crate::budget::{Allocation, oracle};
use crate::cost::{
    CostModel, FamilyScales, FamilyTimes, FrameClock, FramePrediction, MeasuredPacing,
};
use crate::culling::ForestCulling;
use crate::display::{DisplayTiming, VsyncSettings};
use crate::draw::{PrimitiveCounts, TreeDrawList};
use crate::tree::TreeModel;
use crate::view::LodView;

/// What the display and its pacing tell the aim, the aim's calibration, and the usual
/// logic the rendering time is never cut below for a hitch.
#[derive(SystemParam)]
pub(super) struct Pacing<'w, 's> {
    display: Option<Res<'w, DisplayTiming>>,
    measured: Option<Res<'w, MeasuredPacing>>,
    vsync: Option<Res<'w, VsyncSettings>>,
    calibration: Local<'s, AimCalibration>,
    usual_logic: Local<'s, UsualLogic>,
}

/// The tree models, and what the hierarchical strategy reads beside the objects.
#[derive(SystemParam)]
pub(super) struct Boxes<'w> {
    impostors: Res<'w, GroupImpostors>,
    culling: Option<Res<'w, ForestCulling>>,
    cut: ResMut<'w, HierarchicalCut>,
    models: Res<'w, Assets<TreeModel>>,
}

/// The Budget stage's own state, kept between frames.
#[derive(Default)]
pub(super) struct BudgetState {
    allocations: Vec<Allocation>,
    scratch: TreeDrawList,
    /// Per visible tree, what its parts drew (while far trees are held).
    tree_parts: Vec<Selected>,
    /// Since when (real seconds since start-up) the target has been at or below the
    /// logic time, and whether that was reported.
    target: TargetWatch,
    /// The last fresh hand-out, for a still scene to keep ([`FrameBudget::steady`]).
    kept: Option<KeptHandOut>,
    /// A forgotten hand-out's allocations, for the next one kept.
    spare: KeptBuffers,
    /// Per object, what this frame's hand-out drew.
    drawn: Vec<Selected>,
    blend: BlendScratch,
}

/// This frame's fresh hand-out and the scene it was made for, as
/// [`BudgetState::remember`] keeps it.
struct FreshHandOut<'a> {
    budget: &'a FrameBudget,
    visible: &'a VisibleObjects,
    ladders: &'a LadderObjects,
    outcome: &'a Outcome,
    selection: &'a Selection,
    costs: &'a PrimitiveCosts,
    scales: FamilyScales,
    score: Option<(f32, f32)>,
    room: steady::Room,
}

impl BudgetState {
    /// Keeps a fresh hand-out for a still scene to reuse when `may_keep` and its price
    /// fits ([`FrameBudget::steady`]), else forgets the kept one; the kept lists' buffers
    /// are reused either way.
    fn remember(&mut self, fresh: FreshHandOut, may_keep: bool) {
        let FreshHandOut {
            budget,
            visible,
            ladders,
            outcome,
            selection,
            costs,
            scales,
            score,
            room,
        } = fresh;
        let fit = budget.steady.fit(outcome.stats.used, room);
        let mut buffers = match self.kept.take() {
            Some(kept) => kept.buffers,
            None => core::mem::take(&mut self.spare),
        };
        let Some(fit) = fit.filter(|_| may_keep) else {
            self.spare = buffers;
            return;
        };
        buffers.objects.clear();
        buffers
            .objects
            .extend(identities(visible, &ladders.entries));
        buffers.mesh_levels.clone_from(&ladders.chosen);
        self.kept = Some(KeptHandOut {
            budget: budget.clone(),
            view: visible.view,
            calibrated: by_family(
                selection.drawn,
                selection.predicted,
                selection.counts,
                costs,
            )
            .unscaled(scales),
            outcome: outcome.clone(),
            counts: selection.counts,
            trees_drawn: selection.trees_drawn,
            score,
            fit,
            buffers,
        });
    }
}

/// Whether a hand-out pays for a ladder's cross-fade (two levels drawn): not kept, since
/// the fade ends while the scene stays still.
fn pays_a_fade(ladders: &[LadderEntry], chosen: &[Option<u32>]) -> bool {
    ladders
        .iter()
        .zip(chosen)
        .any(|(entry, level)| level.is_some_and(|level| entry.hold.fading_for(level).is_some()))
}

/// A hand-out and the scene it was made for, kept while the scene stays still and the
/// selection still fits ([`FrameBudget::steady`]); its lists stay in [`ChosenLists`].
struct KeptHandOut {
    budget: FrameBudget,
    view: Option<LodView>,
    outcome: Outcome,
    /// The trees' and ladders' selection priced by the calibration alone.
    calibrated: FamilyTimes,
    /// What the selection draws, and how many trees on their own.
    counts: PrimitiveCounts,
    trees_drawn: u32,
    /// The hand-out's benefit and its bound, when [`BenefitReport`] scored it.
    score: Option<(f32, f32)>,
    /// How it fills the render world's time, as handed out and smoothed since.
    fit: steady::Fit,
    buffers: KeptBuffers,
}

/// What a kept hand-out holds per object and ladder. Its trees' lists are the ones the
/// `DrawLists` stage wrote, and what each object drew is [`BudgetState::drawn`]: both stay
/// as they are while the hand-out is kept, and are read only when a still scene hands out
/// anew (a moving camera, which never reuses its hand-out, copies nothing).
#[derive(Default)]
struct KeptBuffers {
    /// Per visible object, its entity, part and value.
    objects: Vec<(Entity, Part, f32)>,
    mesh_levels: Vec<Option<u32>>,
}

impl KeptHandOut {
    /// Whether this frame's scene is the kept one's: the same settings and camera, the
    /// same objects in the same order, each of nearly the same value, and every mesh
    /// ladder showing the level chosen (a level the hysteresis still holds back will
    /// change, and the kept price is the level shown when it was chosen).
    fn is_still(
        &self,
        budget: &FrameBudget,
        visible: &VisibleObjects,
        ladders: &[LadderEntry],
        scored: bool,
    ) -> bool {
        self.budget == *budget
            && self.score.is_some() == scored
            && self.view == visible.view
            && self.buffers.objects.len() == visible.objects.len()
            && ladders.len() == self.buffers.mesh_levels.len()
            && ladders
                .iter()
                .zip(&self.buffers.mesh_levels)
                .all(|(entry, level)| {
                    level.is_none_or(|level| {
                        entry.hold.shown == level && entry.hold.fading.is_none()
                    })
                })
            && self
                .buffers
                .objects
                .iter()
                .zip(identities(visible, ladders))
                .all(|(&(entity, part, then), (now_entity, now_part, now))| {
                    entity == now_entity && part == now_part && budget.steady.same_value(then, now)
                })
    }

    /// The kept hand-out again, when it still fits `room` at this frame's learned
    /// costs: its outcome and selection repriced, its score and ladder levels.
    fn reused(
        &mut self,
        budget: &FrameBudget,
        visible: &VisibleObjects,
        scales: FamilyScales,
        room: steady::Room,
    ) -> Option<(Outcome, Selection, Option<(f32, f32)>, Vec<Option<u32>>)> {
        let outcome = self.repriced(scales);
        let price = outcome.stats.used;
        budget.steady.keeps(&mut self.fit, price, room).then(|| {
            let selection = Selection {
                drawn: outcome.drawn,
                predicted: outcome.stats.used,
                counts: self.counts,
                visible_instances: visible.instances_in_view(),
                trees_drawn: self.trees_drawn,
            };
            (
                outcome,
                selection,
                self.score,
                self.buffers.mesh_levels.clone(),
            )
        })
    }

    /// The kept outcome priced at this frame's learned costs.
    fn repriced(&self, scales: FamilyScales) -> Outcome {
        let now = steady::rescaled(self.calibrated, scales);
        let mut outcome = self.outcome.clone();
        outcome.drawn = Selected {
            cost: now.total(),
            lines: now.lines,
            points: now.points,
            meshes: now.meshes,
            mesh_pixels: now.mesh_pixels,
            ..outcome.drawn
        };
        outcome.stats.used = now.total();
        outcome
    }

    /// This frame's fresh hand-out (`lists`, `drawn`, `outcome`) for the still scene
    /// this one was kept for, blended with it: every tree draws what it drew, but for the
    /// fewest whose fresh drawing takes the price within half the steadiness band around
    /// the rendering time ([`steady::change_fewest`]). What a tree drew is its list as written
    /// (`shown`), what an object drew `state.kept_drawn`. Group impostors are not blended.
    fn blend_into(
        &self,
        fresh: Fresh,
        shown: &Query<&TreeDrawList>,
        state: &mut BlendScratch,
        scales: FamilyScales,
    ) {
        let Fresh {
            objects,
            trees,
            values,
            lists,
            drawn,
            outcome,
            room,
            steady,
        } = fresh;
        let ratio = self.repriced(scales).stats.used / self.outcome.stats.used;
        if outcome.impostors_drawn > 0
            || self.outcome.impostors_drawn > 0
            || trees.len() > lists.len()
            || state.kept_drawn.len() != drawn.len()
            || objects.len() != drawn.len()
            || !(ratio.is_finite() && ratio > 0.0)
        {
            return;
        }
        // (Object, its tree) for the tree parts.
        let parts = || {
            objects
                .iter()
                .enumerate()
                .filter(|(_, o)| o.part != Part::Mesh)
                .map(|(i, o)| (i, o.index as usize))
        };
        state.changes.clear();
        state.changes.resize(lists.len(), (0.0, 0.0));
        state.shown.clear();
        state.shown.resize(lists.len(), 0.0);
        for (i, tree) in parts() {
            state.changes[tree].0 += state.kept_drawn[i].cost * ratio;
            state.changes[tree].1 += drawn[i].cost;
            state.shown[tree] += values.get(i).copied().unwrap_or(0.0);
        }
        let blended = steady::change_fewest(
            &state.changes,
            &state.shown,
            steady.blend_band(room),
            &mut state.order,
            &mut state.keep,
        );
        for ((keep, tree), list) in state.keep.iter_mut().zip(trees).zip(lists.iter_mut()) {
            match shown.get(tree.entity) {
                Ok(kept) if *keep && list != kept => list.clone_from(kept),
                // A tree whose list is gone keeps its fresh one.
                Err(_) => *keep = false,
                Ok(_) => {}
            }
        }
        for (i, tree) in parts() {
            if state.keep[tree] {
                let kept = steady::scaled(state.kept_drawn[i], ratio);
                outcome.drawn = steady::shifted(outcome.drawn, drawn[i], kept);
                drawn[i] = kept;
            }
        }
        let stats = &mut outcome.stats;
        stats.used = blended;
        stats.wasted = (stats.rendering_time - blended).max(0.0);
        stats.overrun = (blended - stats.rendering_time).max(0.0);
    }
}

/// A fresh hand-out, to blend with a kept one.
struct Fresh<'a> {
    objects: &'a [Object],
    trees: &'a [VisibleTree],
    /// Per object, its value.
    values: &'a [f32],
    lists: &'a mut [TreeDrawList],
    drawn: &'a mut [Selected],
    outcome: &'a mut Outcome,
    room: steady::Room,
    steady: SteadySelection,
}

/// The blend's scratch: what each object of the kept hand-out drew (copied before the
/// fresh hand-out overwrites it); per tree the kept and the fresh cost and its value, an
/// order, which trees keep what they drew.
#[derive(Default)]
struct BlendScratch {
    kept_drawn: Vec<Selected>,
    changes: Vec<(f32, f32)>,
    shown: Vec<f32>,
    order: Vec<u32>,
    keep: Vec<bool>,
}

/// Per visible object, its entity, part and value.
fn identities<'a>(
    visible: &'a VisibleObjects,
    ladders: &'a [LadderEntry],
) -> impl Iterator<Item = (Entity, Part, f32)> + 'a {
    visible
        .objects
        .iter()
        .zip(&visible.values)
        .map(|(object, &value)| {
            let entity = match object.part {
                Part::Mesh => ladders.get(object.index as usize).map(|entry| entry.entity),
                _ => visible
                    .trees
                    .get(object.index as usize)
                    .map(|tree| tree.entity),
            };
            (entity.unwrap_or(Entity::PLACEHOLDER), object.part, value)
        })
}

/// The frame's time as the budget sees it, seconds.
struct FrameTimes {
    /// The logic measured so far this frame, and predicted in all.
    logic_so_far: f32,
    logic: f32,
    /// The rendering's fixed part, and the app's own meshes' predicted time.
    fixed: f32,
    app_meshes: Selected,
    app_mesh_draws: u32,
    /// The target, and what the work is aimed at.
    target: f32,
    aim: super::aim::Aim,
    /// [`LodDiagnostics::tail_offsets`].
    tail_offsets: [f32; 2],
    /// The rendering time left for the trees and ladders.
    rendering: f32,
    /// The render world's time in the aim, the rendering time one part of it.
    render_world: f32,
    /// No rendering time is left in the target (in a time-critical mode).
    target_below_logic: bool,
}

impl FrameTimes {
    /// The rendering time left for the objects decided this frame (the trees held from
    /// earlier frames, `held` seconds, keep theirs), within the render world's time.
    fn room(&self, held: f32) -> steady::Room {
        steady::Room {
            rendering: (self.rendering - held).max(0.0),
            render_world: self.render_world,
        }
    }
}

fn frame_times(
    budget: &FrameBudget,
    cost_model: &CostModel,
    costs: &PrimitiveCosts,
    clock: &FrameClock,
    visible_instances: u32,
    app_mesh_load: AppMeshLoad,
    pacing: &mut Pacing,
) -> FrameTimes {
    // This frame's logic so far is known: only the rest of the update is predicted.
    let logic_so_far = clock.elapsed();
    let after_budget = cost_model.logic_after_budget(visible_instances);
    let logic = logic_so_far + after_budget;
    let usual_logic = pacing.usual_logic.observe(logic_so_far) + after_budget;
    let target = budget.target_ms.max(0.0) / 1000.0;
    let inputs = AimInputs {
        display: pacing.display.as_deref(),
        pacing: pacing.measured.as_deref(),
        vsync: pacing.vsync.as_deref(),
        model: cost_model,
        overrun_cut: budget.overrun_cut,
    };
    let aim = super::aim::aim(
        &mut pacing.calibration,
        clock.frame,
        target,
        budget.goal,
        &inputs,
    );
    let available = logic_hitch::rendering_time(cost_model.overlap(), logic, usual_logic, aim.work);
    // The app's own visible meshes are not budgeted but predicted: they take their time
    // first, like the fixed part.
    let meshes = app_mesh_load.draws as f32 * costs.mesh_draw
        + app_mesh_load.triangles as f32 * costs.mesh_triangle;
    let mesh_pixels = costs.mesh_pixels(app_mesh_load.pixels);
    let app_meshes = Selected {
        cost: meshes + mesh_pixels,
        meshes,
        mesh_pixels,
        ..Selected::default()
    };
    let fixed = cost_model.render_fixed();
    FrameTimes {
        logic_so_far,
        logic,
        fixed,
        app_meshes,
        app_mesh_draws: app_mesh_load.draws,
        target,
        aim,
        tail_offsets: pacing.calibration.offsets(),
        rendering: (available - fixed - app_meshes.cost).max(0.0),
        render_world: available,
        target_below_logic: available <= 0.0 && budget.mode.is_time_critical(),
    }
}

pub(super) fn hand_out_time(
    visible: Res<VisibleObjects>,
    mut far: ResMut<FarDecisions>,
    mut strategies: ResMut<Strategies>,
    mut chosen: ResMut<ChosenLists>,
    mut state: Local<BudgetState>,
    budget: Res<FrameBudget>,
    mut cost_model: ResMut<CostModel>,
    clock: Res<FrameClock>,
    time: Res<Time<Real>>,
    mut diagnostics: ResMut<LodDiagnostics>,
    mut ladders: ResMut<LadderObjects>,
    report: Res<BenefitReport>,
    mut boxes: Boxes,
    mut pacing: Pacing,
    shown: Query<&TreeDrawList>,
    mut commands: Commands,
) {
    let start = Instant::now();
    let state = &mut *state;
    let costs = cost_model
        .primitive_costs()
        .within_viewport(visible.viewport_pixels);
    let times = frame_times(
        &budget,
        &cost_model,
        &costs,
        &clock,
        visible.instances_in_view(),
        ladders.app_meshes,
        &mut pacing,
    );

    let time_critical = budget.mode.is_time_critical();
    let keeping = time_critical && !far.holding();
    let scales = cost_model.family_scales();
    let room = times.room(visible.held_parts.cost);
    // A cut aim (after frames over the goal's limit) hands out anew at once.
    let still = keeping
        && !times.aim.cut
        && state
            .kept
            .as_ref()
            .is_some_and(|kept| kept.is_still(&budget, &visible, &ladders.entries, report.enabled));
    let fresh = FreshInputs {
        budget: &budget,
        visible: &visible,
        costs: &costs,
        rendering: room.rendering,
        scored_rendering: report.enabled.then_some(times.rendering),
        far_holding: far.holding(),
    };
    let sinks = Sinks {
        chosen: &mut chosen,
        ladders: &mut ladders,
        boxes: &mut boxes,
        strategies: &mut strategies,
    };
    let Handed {
        outcome,
        score,
        selection,
    } = kept_or_fresh(fresh, still.then_some(room), scales, state, sinks, &shown);
    let selection_kept = selection.is_some();
    let selection = selection.unwrap_or_else(|| {
        Selection::of(
            &visible,
            &chosen.trees,
            &mut far,
            &state.tree_parts,
            &outcome,
        )
    });
    if !selection_kept {
        let may_keep =
            keeping && !outcome.settling && !pays_a_fade(&ladders.entries, &ladders.chosen);
        state.remember(
            FreshHandOut {
                budget: &budget,
                visible: &visible,
                ladders: &ladders,
                outcome: &outcome,
                selection: &selection,
                costs: &costs,
                scales,
                score: score.map(|(benefit, bound, _)| (benefit, bound)),
                room,
            },
            may_keep,
        );
    }
    let priced = record_prediction(&mut cost_model, &clock, &times, &costs, &selection);
    let (benefit, benefit_bound, report_time) = score.unwrap_or_default();
    *diagnostics = LodDiagnostics {
        benefit,
        benefit_bound,
        budget_stage_ms: (start.elapsed() - report_time).as_secs_f32() * 1000.0,
        // Counted after the hand-out, over the measured frames (`count_frames_over`).
        frames_over_share: diagnostics.frames_over_share,
        selection_kept,
        ..frame_diagnostics(
            &budget,
            &cost_model,
            &clock,
            &times,
            &visible,
            &outcome,
            &selection,
            &priced,
        )
    };
    if let Some(alert) = state.target.observe(&diagnostics, time.elapsed_secs()) {
        alerts::raise(&mut commands, alert);
    }
}

/// Where a hand-out writes: the chosen lists, the ladders' levels, the hierarchical
/// cut's boxes and the strategies' scratch.
struct Sinks<'a, 'w> {
    chosen: &'a mut ChosenLists,
    ladders: &'a mut LadderObjects,
    boxes: &'a mut Boxes<'w>,
    strategies: &'a mut Strategies,
}

/// This frame's hand-out, and its score with the time the scoring took (with the benefit
/// report on).
struct Handed {
    outcome: Outcome,
    score: Option<(f32, f32, Duration)>,
    /// The kept selection, when a still scene kept its hand-out (otherwise derived from
    /// the chosen lists).
    selection: Option<Selection>,
}

/// A still scene (`still`: this frame's room) keeps its hand-out while that still fits;
/// otherwise the time is handed out anew, and a still scene's fresh hand-out is blended
/// with the kept one when the steadiness is [`gradual`](SteadySelection::gradual).
fn kept_or_fresh(
    fresh: FreshInputs,
    still: Option<steady::Room>,
    scales: FamilyScales,
    state: &mut BudgetState,
    sinks: Sinks,
    shown: &Query<&TreeDrawList>,
) -> Handed {
    let budget = fresh.budget;
    let visible = fresh.visible;
    let kept = state
        .kept
        .as_mut()
        .zip(still)
        .and_then(|(kept, room)| kept.reused(budget, visible, scales, room));
    if let Some((outcome, selection, score, mesh_levels)) = kept {
        sinks.ladders.chosen = mesh_levels;
        return Handed {
            outcome,
            score: score.map(|(benefit, bound)| (benefit, bound, Duration::ZERO)),
            selection: Some(selection),
        };
    }
    let blend = still.filter(|_| budget.steady.gradual);
    if blend.is_some() {
        // The kept hand-out's choices, before the fresh one overwrites them.
        state.blend.kept_drawn.clone_from(&state.drawn);
    }
    let (mut outcome, score) = hand_out_fresh(
        fresh,
        state,
        sinks.chosen,
        sinks.ladders,
        sinks.boxes,
        sinks.strategies,
    );
    if let Some(room) = blend.filter(|_| score.is_none())
        && let Some(kept) = &state.kept
    {
        let fresh = Fresh {
            objects: &visible.objects,
            trees: &visible.trees,
            values: &visible.values,
            lists: &mut sinks.chosen.trees,
            drawn: &mut state.drawn,
            outcome: &mut outcome,
            room,
            steady: budget.steady,
        };
        kept.blend_into(fresh, shown, &mut state.blend, scales);
    }
    Handed {
        outcome,
        score,
        selection: None,
    }
}

/// What a fresh hand-out is made from.
struct FreshInputs<'a> {
    budget: &'a FrameBudget,
    visible: &'a VisibleObjects,
    costs: &'a PrimitiveCosts,
    /// The rendering time handed out.
    rendering: f32,
    /// With the benefit report on: the rendering time the hand-out is scored against.
    scored_rendering: Option<f32>,
    /// Far trees are held (their parts are kept per tree).
    far_holding: bool,
}

/// Hands the rendering time out anew — the strategy in the time-critical modes, every
/// object at its mode's representation otherwise — into the chosen lists, the ladders'
/// levels and what each object drew; scored against the bound with the benefit report.
fn hand_out_fresh(
    fresh: FreshInputs,
    state: &mut BudgetState,
    chosen: &mut ChosenLists,
    ladders: &mut LadderObjects,
    boxes: &mut Boxes,
    strategies: &mut Strategies,
) -> (Outcome, Option<(f32, f32, Duration)>) {
    let FreshInputs {
        budget,
        visible,
        costs,
        rendering,
        scored_rendering,
        far_holding,
    } = fresh;
    let time_critical = budget.mode.is_time_critical();
    chosen.clear_for(visible.trees.len());
    let LadderObjects {
        entries,
        triangles,
        chosen: mesh_levels,
        ..
    } = ladders;
    let search = object_search(visible, budget, costs, &boxes.models, entries, triangles);
    let ChosenLists {
        trees: lists,
        impostors: impostor_lists,
        ..
    } = chosen;
    state.drawn.clear();
    state
        .drawn
        .resize(visible.objects.len(), Selected::default());
    let mut hand_out = HandOut {
        search: &search,
        choices: Choices {
            lists,
            mesh_levels,
            drawn: &mut state.drawn,
        },
        values: &visible.values,
        complexities: &visible.complexities,
        rendering,
        allocations: &mut state.allocations,
        scratch: &mut state.scratch,
        tree_parts: far_holding.then_some(&mut state.tree_parts),
        scene: Scene {
            culling: boxes.culling.as_deref(),
            impostors: &boxes.impostors,
            models: &boxes.models,
            cut: &mut boxes.cut,
            impostor_lists,
        },
    };
    let outcome = if time_critical {
        strategies.get(budget.strategy).hand_out(&mut hand_out)
    } else {
        strategy::draw_everything(&mut hand_out)
    };
    let score = scored_rendering
        .filter(|_| time_critical)
        .map(|given| score_hand_out(&mut hand_out, &outcome, given));
    (outcome, score)
}

/// Every visible object's search, by the mode's methods.
fn object_search<'a>(
    visible: &'a VisibleObjects,
    budget: &FrameBudget,
    costs: &'a PrimitiveCosts,
    models: &'a Assets<TreeModel>,
    ladders: &'a [LadderEntry],
    ladder_triangles: &'a [u32],
) -> ObjectSearch<'a> {
    let (trunk, leaves) = search::methods(budget);
    ObjectSearch {
        objects: &visible.objects,
        trees: &visible.trees,
        leaf_groups: &visible.leaf_groups,
        models: visible
            .infos
            .iter()
            .map(|info| models.get(info.id))
            .collect(),
        costs,
        trunk,
        leaves,
        ladders,
        ladder_triangles,
        view: visible.view,
        keep_shown: budget.strategy == StrategyKind::RobinHood,
    }
}

/// What the frame draws, the held far trees' included.
struct Selection {
    /// Its lines', points' and meshes' parts (the rest is triangles).
    drawn: Selected,
    /// Its predicted rendering time, seconds.
    predicted: f32,
    counts: PrimitiveCounts,
    visible_instances: u32,
    /// Visible trees drawn on their own.
    trees_drawn: u32,
}

impl Selection {
    /// The frame's selection, with each far tree's decision kept while far trees are held.
    fn of(
        visible: &VisibleObjects,
        lists: &[TreeDrawList],
        far: &mut FarDecisions,
        tree_parts: &[Selected],
        outcome: &Outcome,
    ) -> Self {
        let mut counts = count_and_remember(visible, lists, far, tree_parts);
        counts += outcome.impostor_counts;
        counts += visible.held_counts;
        Self {
            drawn: Selected::both(outcome.drawn, visible.held_parts),
            predicted: outcome.stats.used + visible.held_parts.cost,
            counts,
            visible_instances: visible.instances_in_view(),
            trees_drawn: lists[..visible.trees.len()]
                .iter()
                .filter(|list| !list.is_empty())
                .count() as u32,
        }
    }
}

/// Per visible tree, its list's primitives (summed); and, while far trees are held, each
/// far tree's decision kept for the frames it will be held (a tree not decided as a
/// whole has none to keep).
fn count_and_remember(
    visible: &VisibleObjects,
    lists: &[TreeDrawList],
    far: &mut FarDecisions,
    tree_parts: &[Selected],
) -> PrimitiveCounts {
    let mut counts = PrimitiveCounts::default();
    let remember = far.holding();
    if remember {
        far.decided.resize(visible.instances(), None);
    }
    for (t, (tree, list)) in visible.trees.iter().zip(lists).enumerate() {
        let Some(info) = visible.infos.get(tree.model as usize) else {
            continue;
        };
        let tree_counts = info.slot.counts(list);
        counts += tree_counts;
        if remember
            && let (Some(slot), Some(parts)) = (
                far.decided.get_mut(tree.instance as usize),
                tree_parts.get(t),
            )
        {
            *slot = tree.leaf_depth.is_some().then_some((*parts, tree_counts));
        }
    }
    counts
}

/// The selection priced as the cost model will learn from it.
struct Priced {
    /// By family, as the calibration alone prices it.
    calibrated: FamilyTimes,
    /// The predicted rendering and frame time, seconds.
    render: f32,
    frame_time: f32,
}

/// A selection's predicted time by family: what is not lines, points or meshes is
/// triangles, per triangle up to the triangles' learned cost and the rest per pixel.
fn by_family(
    drawn: Selected,
    predicted: f32,
    counts: PrimitiveCounts,
    costs: &PrimitiveCosts,
) -> FamilyTimes {
    let triangles =
        (predicted - drawn.lines - drawn.points - drawn.meshes - drawn.mesh_pixels).max(0.0);
    let triangle_vertices = (counts.triangles as f32 * costs.triangle).min(triangles);
    FamilyTimes {
        triangles: triangle_vertices,
        triangle_pixels: triangles - triangle_vertices,
        lines: drawn.lines,
        points: drawn.points,
        meshes: drawn.meshes,
        mesh_pixels: drawn.mesh_pixels,
    }
}

/// Records this frame's prediction with the cost model: the selection by family, priced
/// as the calibration alone would, for the model to learn from once the frame is
/// measured.
fn record_prediction(
    cost_model: &mut CostModel,
    clock: &FrameClock,
    times: &FrameTimes,
    costs: &PrimitiveCosts,
    selection: &Selection,
) -> Priced {
    let mut by_family = by_family(
        selection.drawn,
        selection.predicted,
        selection.counts,
        costs,
    );
    by_family.meshes += times.app_meshes.meshes;
    by_family.mesh_pixels += times.app_meshes.mesh_pixels;
    let render = times.fixed + times.app_meshes.cost + selection.predicted;
    let frame_time = cost_model.overlap().frame_time(times.logic, render);
    let calibrated = by_family.unscaled(cost_model.family_scales());
    cost_model.record(FramePrediction {
        frame: clock.frame,
        visible_instances: selection.visible_instances,
        calibrated,
        logic: times.logic,
        logic_so_far: times.logic_so_far,
        render,
        frame_time,
    });
    Priced {
        calibrated,
        render,
        frame_time,
    }
}

/// The diagnostics of the frame's times, what the cost model measured and learned, and
/// what was drawn (the benefit and the stage's time are the caller's).
fn frame_diagnostics(
    budget: &FrameBudget,
    cost_model: &CostModel,
    clock: &FrameClock,
    times: &FrameTimes,
    visible: &VisibleObjects,
    outcome: &Outcome,
    selection: &Selection,
    priced: &Priced,
) -> LodDiagnostics {
    let shown = super::aim::shown(cost_model.last_learned(), times.target, times.aim.period);
    let measured = cost_model.last_learned().copied().unwrap_or_default();
    let stats = &outcome.stats;
    let ms = |seconds: f32| seconds * 1000.0;
    LodDiagnostics {
        frame: clock.frame,
        target_ms: budget.target_ms,
        logic_ms: ms(times.logic),
        logic_so_far_ms: ms(times.logic_so_far),
        app_meshes_ms: ms(times.app_meshes.cost),
        render_budget_ms: ms(times.rendering),
        render_fixed_ms: ms(times.fixed),
        predicted_render_ms: ms(priced.render),
        predicted_frame_ms: ms(priced.frame_time),
        measured_frame: measured.measured.frame,
        measured_frame_ms: ms(measured.measured.interval),
        measured_logic_ms: ms(measured.measured.logic),
        measured_render_ms: ms(measured.measured.render),
        measured_frame_predicted_ms: ms(measured.predicted.frame_time),
        work_target_ms: ms(times.aim.work),
        vsync_period_ms: ms(times.aim.period.unwrap_or(0.0)),
        frame_spread: cost_model.frame_spread().sigma(),
        tail_offsets: times.tail_offsets,
        overrun_factor: times.aim.overrun_factor,
        measured_work_ms: shown.work_ms,
        measured_gpu_ms: shown.gpu_ms,
        measured_waited_ms: shown.waited_ms,
        measured_bound: shown.bound,
        measured_periods: shown.periods,
        missed_vblank: shown.missed_vblank,
        wasted_ms: ms(stats.wasted),
        floor_ms: ms(stats.floor),
        floor_excess_ms: ms(stats.floor_excess),
        learned: cost_model.learned(),
        calibrated: priced.calibrated,
        target_below_logic: times.target_below_logic,
        overrun_ms: ms((selection.predicted - times.rendering).max(0.0)),
        visible_objects: visible.objects.len() as u32,
        visible_instances: selection.visible_instances,
        app_mesh_draws: times.app_mesh_draws,
        counts: selection.counts,
        truncated: stats.truncated,
        undrawn: stats.dropped,
        impostors_drawn: outcome.impostors_drawn,
        held_trees: visible.held.len() as u32,
        trees_drawn: selection.trees_drawn,
        value_stage_ms: visible.value_ms,
        ..LodDiagnostics::default()
    }
}

/// How much of the best possible benefit the hand-out reached
/// ([`BenefitReport`]): its benefit, the bound within `rendering`, and the time scoring
/// took (left out of the stage's time).
fn score_hand_out(
    hand_out: &mut HandOut,
    outcome: &Outcome,
    rendering: f32,
) -> (f32, f32, Duration) {
    let start = Instant::now();
    let search = hand_out.search;
    let full: Vec<f32> = (0..search.objects.len())
        .map(|i| search.full_cost(i, hand_out.scratch))
        .collect();
    let benefit = outcome.benefit.unwrap_or_else(|| {
        hand_out
            .allocations
            .iter()
            .zip(hand_out.values)
            .zip(&full)
            .map(|((a, &value), &full)| {
                let used = if a.level.is_some() { a.used } else { 0.0 };
                oracle::sqrt_benefit(value, full, used)
            })
            .sum::<f64>() as f32
    });
    let pairs: Vec<(f32, f32)> = hand_out.values.iter().copied().zip(full).collect();
    let bound = oracle::sqrt_benefit_bound(&pairs, rendering) as f32;
    (benefit, bound, start.elapsed())
}
