//! Funkhouser & Séquin (1993): level-of-detail selection as a multiple-choice knapsack
//! problem, solved greedily by `Value = Benefit / Cost`, and its incremental variant
//! that starts from last frame's selection.
//!
//! Unlike Robin Hood these maximise benefit within the budget and may leave visible
//! objects undrawn (popping); the [`BudgetStats::dropped`] count says how many.
//!
//! # Which `Value`
//! The published greedy ranks every tuple by its own `Benefit / Cost`. With that ranking
//! the claimed half-optimality does not hold, not even with Mason & Blake's correction
//! (compare with the best single tuple): our property tests found two-object
//! counterexamples, kept as regression tests. By default the greedy therefore ranks the
//! *increments* along each object's upper convex hull of (cost, benefit) — the classical
//! greedy for the multiple-choice knapsack — where `Value` is Δbenefit / Δcost and falls
//! monotonically within every object; with the correction that is provably at least half
//! optimal (the LP optimum is at most the greedy plus one tuple). The published ranking
//! stays available as [`ValueOrdering::Published`] for comparisons.

use bevy::reflect::Reflect;
use serde::{Deserialize, Serialize};

use super::heap::ItemQueues;
use super::hull::{HullPoint, upper_hull};
use super::problem::{
    Allocation, BudgetProblem, BudgetStats, BudgetStrategy, PreviousSelection, sanitize_time,
};

const NOT_SELECTED: u32 = u32::MAX;

/// How the Funkhouser–Séquin greedy ranks tuples.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default, Serialize, Deserialize, Reflect)]
pub(crate) enum ValueOrdering {
    /// Increments along each object's upper convex hull (LP-undominated tuples only),
    /// ranked by Δbenefit / Δcost: at least half optimal with the correction.
    #[default]
    Hull,
    /// Every tuple by its own Benefit / Cost, as published; no optimality guarantee.
    Published,
}

#[derive(Clone, Copy, Debug)]
struct Tuple {
    value: f32,
    object: u32,
    level: u32,
}

/// The greedy MCKP approximation of Funkhouser & Séquin.
///
/// Tuples (object, level) are taken in descending `Value` (see [`ValueOrdering`]); a
/// tuple replaces the object's current one when its benefit is greater, and the scan
/// stops at the first tuple whose addition would exceed the budget. With
/// [`half_optimality_fix`](Self::half_optimality_fix) (Mason & Blake's correction) the
/// result is compared with the single highest-benefit tuple that fits on its own, and
/// the better of the two is kept.
#[derive(Clone, Debug)]
pub(crate) struct FunkhouserSequin {
    /// Compare with the best single tuple. Default: `true`.
    pub half_optimality_fix: bool,
    /// How tuples are ranked. Default: [`ValueOrdering::Hull`].
    pub ordering: ValueOrdering,
    tuples: Vec<Tuple>,
    increments: Vec<Increment>,
    bucket_costs: Vec<f64>,
    boundary: Vec<Increment>,
    selection: Vec<u32>,
    hull: Vec<HullPoint>,
    used_single_best: bool,
}

impl Default for FunkhouserSequin {
    fn default() -> Self {
        Self {
            half_optimality_fix: true,
            ordering: ValueOrdering::Hull,
            tuples: Vec::new(),
            increments: Vec::new(),
            bucket_costs: Vec::new(),
            boundary: Vec::new(),
            selection: Vec::new(),
            hull: Vec::new(),
            used_single_best: false,
        }
    }
}

impl FunkhouserSequin {
    /// The hull-ranked greedy with the half-optimality fix.
    #[cfg(any(test, feature = "testing"))]
    pub(crate) fn new() -> Self {
        Self::default()
    }

    /// The greedy with or without the half-optimality fix (without it, exactly the set
    /// that [`FunkhouserIncremental`] converges to).
    #[cfg(test)]
    pub(crate) fn with_half_optimality_fix(fix: bool) -> Self {
        Self {
            half_optimality_fix: fix,
            ..Self::default()
        }
    }

    /// The published algorithm: tuples ranked by their own Benefit / Cost, no fix.
    #[cfg(test)]
    pub(crate) fn published() -> Self {
        Self {
            half_optimality_fix: false,
            ordering: ValueOrdering::Published,
            ..Self::default()
        }
    }

    /// Whether the last frame's answer was the single best tuple rather than the greedy set.
    #[cfg(test)]
    pub(crate) fn used_single_best(&self) -> bool {
        self.used_single_best
    }

    /// The published greedy: every tuple by its own Value, replacing, stopping at the
    /// first tuple that does not fit. Returns the benefit of the selection.
    fn published_greedy(&mut self, problem: &BudgetProblem, budget: f64) -> f64 {
        self.tuples.clear();
        for object in 0..problem.len() {
            let ladder = problem.ladder(object);
            self.tuples
                .extend(ladder.iter().enumerate().map(|(level, l)| Tuple {
                    value: l.value(),
                    object: object as u32,
                    level: level as u32,
                }));
        }
        // Radix sort: descending value, stable, O(tuples).
        radsort::sort_by_key(&mut self.tuples, |t| -t.value);
        let mut cost = 0.0_f64;
        let mut benefit = 0.0_f64;
        for t in &self.tuples {
            let ladder = problem.ladder(t.object as usize);
            let candidate = ladder[t.level as usize];
            let current = self.selection[t.object as usize];
            let (current_cost, current_benefit) = if current == NOT_SELECTED {
                (0.0, 0.0)
            } else {
                let l = ladder[current as usize];
                (f64::from(l.cost), f64::from(l.benefit))
            };
            if current != NOT_SELECTED && current_benefit >= f64::from(candidate.benefit) {
                continue;
            }
            let new_cost = cost - current_cost + f64::from(candidate.cost);
            if new_cost > budget {
                break;
            }
            cost = new_cost;
            benefit += f64::from(candidate.benefit) - current_benefit;
            self.selection[t.object as usize] = t.level;
        }
        benefit
    }

    /// The greedy over hull increments. Within an object they come in falling Value, so
    /// the greedy's answer is the longest prefix, in (Value ↓, object ↑) order, whose costs
    /// fit, found in O(n) by [`take_fitting_prefix`].
    fn hull_greedy(&mut self, problem: &BudgetProblem, budget: f64) -> f64 {
        self.increments.clear();
        for object in 0..problem.len() {
            upper_hull(problem.cheapest_first(object), budget, &mut self.hull);
            self.increments.extend(self.hull.iter().map(|p| Increment {
                value: p.efficiency as f32,
                cost: p.delta_cost as f32,
                object: object as u32,
                level: p.level,
            }));
        }
        let selection = &mut self.selection;
        let (costs, boundary) = (&mut self.bucket_costs, &mut self.boundary);
        take_fitting_prefix(&self.increments, budget, costs, boundary, |inc| {
            let current = &mut selection[inc.object as usize];
            let ladder = problem.ladder(inc.object as usize);
            // The object's deepest increment taken is its level (costs rise along a hull).
            if *current == NOT_SELECTED
                || ladder[inc.level as usize].cost > ladder[*current as usize].cost
            {
                *current = inc.level;
            }
        });
        self.selection
            .iter()
            .enumerate()
            .filter(|&(_, &l)| l != NOT_SELECTED)
            .map(|(object, &l)| f64::from(problem.ladder(object)[l as usize].benefit))
            .sum()
    }
}

/// One step along an object's hull.
#[derive(Clone, Copy, Debug)]
struct Increment {
    /// Δbenefit / Δcost.
    value: f32,
    /// Δcost.
    cost: f32,
    object: u32,
    level: u32,
}

/// Buckets of the Value histogram: the top 16 bits of a non-negative `f32`.
const BUCKETS: usize = 1 << 16;

fn bucket(value: f32) -> usize {
    // Non-negative floats order like their bit patterns; NaN cannot occur (validated input).
    (value.max(0.0).to_bits() >> 16) as usize
}

/// Calls `take` for every increment of the longest prefix (in greedy order) whose summed
/// cost fits `budget`: the greedy with stop semantics, without a full sort. One pass sums
/// costs per Value bucket; walking buckets from the highest Value finds the bucket where
/// the budget runs out; every increment above it is taken and only that bucket is sorted.
fn take_fitting_prefix(
    items: &[Increment],
    budget: f64,
    bucket_costs: &mut Vec<f64>,
    boundary: &mut Vec<Increment>,
    mut take: impl FnMut(&Increment),
) {
    let by_greedy_order =
        |a: &Increment, b: &Increment| b.value.total_cmp(&a.value).then(a.object.cmp(&b.object));
    boundary.clear();
    if items.len() * 16 < BUCKETS {
        // Few increments: sorting them beats clearing and walking the histogram.
        boundary.extend_from_slice(items);
        boundary.sort_unstable_by(by_greedy_order);
        take_while_it_fits(boundary, budget, take);
        return;
    }
    bucket_costs.clear();
    bucket_costs.resize(BUCKETS, 0.0);
    for item in items {
        bucket_costs[bucket(item.value)] += f64::from(item.cost);
    }
    let mut left = budget;
    let mut split = None;
    for b in (0..BUCKETS).rev() {
        if bucket_costs[b] > left {
            split = Some(b);
            break;
        }
        left -= bucket_costs[b];
    }
    for item in items {
        let b = bucket(item.value);
        match split {
            Some(s) if b == s => boundary.push(*item),
            Some(s) if b < s => {}
            _ => take(item),
        }
    }
    boundary.sort_unstable_by(by_greedy_order);
    take_while_it_fits(boundary, left, take);
}

/// Takes `sorted` increments in order until the first that does not fit.
fn take_while_it_fits(sorted: &[Increment], mut left: f64, mut take: impl FnMut(&Increment)) {
    for item in sorted {
        if f64::from(item.cost) > left {
            return;
        }
        left -= f64::from(item.cost);
        take(item);
    }
}

impl BudgetStrategy for FunkhouserSequin {
    #[cfg(test)]
    fn name(&self) -> &'static str {
        match self.ordering {
            ValueOrdering::Hull => "Funkhouser–Séquin greedy",
            ValueOrdering::Published => "Funkhouser–Séquin greedy (published ranking)",
        }
    }

    fn distribute(
        &mut self,
        problem: &BudgetProblem,
        rendering_time: f32,
        allocations: &mut Vec<Allocation>,
    ) -> BudgetStats {
        let budget = f64::from(sanitize_time(rendering_time));
        let n = problem.len();
        self.selection.clear();
        self.selection.resize(n, NOT_SELECTED);
        let benefit = match self.ordering {
            ValueOrdering::Hull => self.hull_greedy(problem, budget),
            ValueOrdering::Published => self.published_greedy(problem, budget),
        };

        self.used_single_best = false;
        if self.half_optimality_fix
            && let Some((object, level, single)) = best_single_tuple(problem, budget)
            && single > benefit
        {
            self.selection.fill(NOT_SELECTED);
            self.selection[object] = level;
            self.used_single_best = true;
        }
        allocations.clear();
        allocations.extend(self.selection.iter().enumerate().map(|(object, &level)| {
            if level == NOT_SELECTED {
                Allocation::DROPPED
            } else {
                Allocation::drawn(problem.ladder(object)[level as usize].cost, level)
            }
        }));
        BudgetStats::from_allocations(budget as f32, allocations)
    }
}

/// The highest-benefit tuple that fits the budget alone: (object, level, benefit).
fn best_single_tuple(problem: &BudgetProblem, budget: f64) -> Option<(usize, u32, f64)> {
    let mut best: Option<(usize, u32, f64)> = None;
    for object in 0..problem.len() {
        for (level, l) in problem.ladder(object).iter().enumerate() {
            let b = f64::from(l.benefit);
            if f64::from(l.cost) <= budget && best.is_none_or(|(_, _, bb)| b > bb) {
                best = Some((object, level as u32, b));
            }
        }
    }
    best
}

/// Funkhouser & Séquin's incremental optimisation: start from last frame's selection
/// (and the cheapest representation for newly visible objects), repeatedly raise the
/// object whose next representation has the highest `Value`, then lower the objects
/// whose current representation has the lowest `Value` until the cost fits; stop when
/// the same object was raised and lowered. Representations and `Value`s are those of
/// [`ValueOrdering::Hull`], along which `Value` always falls, so this converges to the
/// greedy's set (without the single-tuple correction), usually in far fewer steps.
///
/// [`hysteresis`](Self::hysteresis) favours staying put: the level an object drew last
/// frame counts its benefit multiplied by `1 + hysteresis`.
#[derive(Clone, Debug, Default)]
pub(crate) struct FunkhouserIncremental {
    /// Extra weight for keeping last frame's level (≥ 0; NaN or negative count as 0).
    /// Default: `0.0`.
    pub hysteresis: f32,
    /// Hull points of every object, and where each object's start.
    hulls: Vec<HullPoint>,
    hull_start: Vec<u32>,
    /// Rank per object: 0 = not drawn, r ≥ 1 = hull point r − 1.
    rank: Vec<u32>,
    hull: Vec<HullPoint>,
    queues: ItemQueues,
    iterations: u32,
}

impl FunkhouserIncremental {
    /// The incremental optimiser with hysteresis `hysteresis`.
    #[cfg(any(test, feature = "testing"))]
    pub(crate) fn new(hysteresis: f32) -> Self {
        Self {
            hysteresis,
            ..Self::default()
        }
    }

    fn hull_of(&self, object: usize) -> &[HullPoint] {
        &self.hulls[self.hull_start[object] as usize..self.hull_start[object + 1] as usize]
    }

    fn rank_cost(&self, object: usize, rank: u32) -> f64 {
        if rank == 0 {
            0.0
        } else {
            self.hull_of(object)[rank as usize - 1].cost
        }
    }

    fn requeue(&mut self, object: usize) {
        self.queues.touch(object);
        let rank = self.rank[object] as usize;
        let hull = self.hull_of(object);
        let next = hull.get(rank).map(|p| p.efficiency as f32);
        let current = rank.checked_sub(1).map(|r| hull[r].efficiency as f32);
        if let Some(v) = next {
            self.queues.push_max(object, v);
        }
        if let Some(v) = current {
            self.queues.push_min(object, v);
        }
    }

    fn build_hulls(&mut self, problem: &BudgetProblem, budget: f64) {
        let weight = if self.hysteresis.is_finite() {
            1.0 + f64::from(self.hysteresis.max(0.0))
        } else {
            1.0
        };
        self.hulls.clear();
        self.hull_start.clear();
        self.hull_start.push(0);
        self.rank.clear();
        for object in 0..problem.len() {
            let ladder = problem.ladder(object);
            let previous = problem.previous(object);
            let points = problem
                .cheapest_first(object)
                .map(|(level, cost, benefit)| {
                    let kept = previous == PreviousSelection::Level(level);
                    (level, cost, benefit * if kept { weight } else { 1.0 })
                });
            upper_hull(points, budget, &mut self.hull);
            // Start at the richest hull point no costlier than last frame's level.
            let rank = match previous {
                PreviousSelection::Dropped => 0,
                PreviousSelection::New => self.hull.len().min(1),
                PreviousSelection::Level(level) => {
                    let cost = f64::from(ladder[level as usize].cost);
                    self.hull.iter().take_while(|p| p.cost <= cost).count()
                }
            };
            self.rank.push(rank as u32);
            self.hulls.extend_from_slice(&self.hull);
            self.hull_start.push(self.hulls.len() as u32);
        }
    }
}

impl BudgetStrategy for FunkhouserIncremental {
    #[cfg(test)]
    fn name(&self) -> &'static str {
        "Funkhouser–Séquin incremental"
    }

    fn distribute(
        &mut self,
        problem: &BudgetProblem,
        rendering_time: f32,
        allocations: &mut Vec<Allocation>,
    ) -> BudgetStats {
        let budget = f64::from(sanitize_time(rendering_time));
        let n = problem.len();
        self.build_hulls(problem, budget);
        self.queues.reset(n);
        let mut cost = 0.0;
        for object in 0..n {
            cost += self.rank_cost(object, self.rank[object]);
        }
        // Heapify every object's entries at once: O(n) instead of n pushes.
        let (hulls, starts, ranks) = (&self.hulls, &self.hull_start, &self.rank);
        let hull = |object: usize| &hulls[starts[object] as usize..starts[object + 1] as usize];
        self.queues.extend_max((0..n).filter_map(|object| {
            let next = hull(object).get(ranks[object] as usize)?;
            Some((object, next.efficiency as f32))
        }));
        self.queues.extend_min((0..n).filter_map(|object| {
            let current = (ranks[object] as usize).checked_sub(1)?;
            Some((object, hull(object)[current].efficiency as f32))
        }));

        // Each iteration raises one step; the bound only guards against float ties cycling.
        let limit = 4 * self.hulls.len() + 16;
        self.iterations = 0;
        loop {
            self.iterations += 1;
            let raised = self.queues.pop_max();
            if let Some(object) = raised {
                let rank = self.rank[object];
                cost += self.rank_cost(object, rank + 1) - self.rank_cost(object, rank);
                self.rank[object] += 1;
                self.requeue(object);
            }
            let mut lowered_the_raised = false;
            while cost > budget {
                let Some(object) = self.queues.pop_min() else {
                    break;
                };
                let rank = self.rank[object];
                cost += self.rank_cost(object, rank - 1) - self.rank_cost(object, rank);
                self.rank[object] -= 1;
                self.requeue(object);
                lowered_the_raised |= raised == Some(object);
            }
            if raised.is_none() || lowered_the_raised || self.iterations as usize >= limit {
                break;
            }
        }

        allocations.clear();
        allocations.extend((0..n).map(|object| match self.rank[object] {
            0 => Allocation::DROPPED,
            rank => {
                let level = self.hull_of(object)[rank as usize - 1].level;
                Allocation::drawn(problem.ladder(object)[level as usize].cost, level)
            }
        }));
        BudgetStats::from_allocations(budget as f32, allocations)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::budget::{Level, ObjectDesc};
    use approx::assert_relative_eq;

    fn problem(objects: &[&[(f32, f32)]]) -> BudgetProblem {
        let mut p = BudgetProblem::new();
        for ladder in objects {
            let ladder: Vec<Level> = ladder.iter().map(|&(c, b)| Level::new(c, b)).collect();
            p.push_object(
                ObjectDesc {
                    value: 1.0,
                    ..Default::default()
                },
                &ladder,
            )
            .unwrap();
        }
        p
    }

    #[test]
    fn greedy_by_hand() {
        // A: (4, 8), (1, 5). B: (3, 3), (2, 3). Budget 5.
        // Hull increments: A1 5/1 = 5, A0 3/3 = 1; B's (3, 3) is dominated by (2, 3): B1 1.5.
        // Take A1 (cost 1), B1 (cost 3), then A0 would make 6 > 5: stop.
        let p = problem(&[&[(4.0, 8.0), (1.0, 5.0)], &[(3.0, 3.0), (2.0, 3.0)]]);
        let mut out = Vec::new();
        let mut fs = FunkhouserSequin::new();
        let stats = fs.distribute(&p, 5.0, &mut out);
        assert_eq!((out[0].level, out[1].level), (Some(1), Some(1)));
        assert_relative_eq!(stats.used, 3.0);
        assert_eq!(stats.dropped, 0);
        assert!(!fs.used_single_best());

        // Published ranking: A1 (5), A0 (2), B1 (1.5), B0 (1). A1, then A0 replaces it
        // (cost 4), then B1 would make 6 > 5: stop, B dropped.
        let stats = FunkhouserSequin::published().distribute(&p, 5.0, &mut out);
        assert_eq!((out[0].level, out[1].level), (Some(0), None));
        assert_relative_eq!(stats.used, 4.0);
        assert_eq!(stats.dropped, 1);
    }

    #[test]
    fn half_optimality_fix_takes_the_single_best() {
        // The cheap tuple has the best value, then the big one does not fit beside it.
        let p = problem(&[&[(0.1, 1.0)], &[(10.0, 50.0)]]);
        let mut out = Vec::new();
        let mut plain = FunkhouserSequin::with_half_optimality_fix(false);
        plain.distribute(&p, 10.0, &mut out);
        assert_relative_eq!(p.benefit_of(&out), 1.0);
        let mut fixed = FunkhouserSequin::new();
        fixed.distribute(&p, 10.0, &mut out);
        assert_relative_eq!(p.benefit_of(&out), 50.0);
        assert!(fixed.used_single_best());
    }

    #[test]
    fn incremental_matches_greedy_from_any_start() {
        // Values fall with detail: A (6, 6) V=1, (2, 4) V=2; B (5, 4) V=.8, (1, 3) V=3.
        let mut p = BudgetProblem::new();
        let ladders = [
            [Level::new(6.0, 6.0), Level::new(2.0, 4.0)],
            [Level::new(5.0, 4.0), Level::new(1.0, 3.0)],
        ];
        let starts = [
            PreviousSelection::New,
            PreviousSelection::Dropped,
            PreviousSelection::Level(0),
        ];
        let mut greedy = FunkhouserSequin::with_half_optimality_fix(false);
        for budget in [0.5, 1.0, 3.0, 7.0, 8.0, 11.0] {
            for &sa in &starts {
                for &sb in &starts {
                    p.clear();
                    for (ladder, previous) in ladders.iter().zip([sa, sb]) {
                        let desc = ObjectDesc {
                            value: 1.0,
                            previous,
                            ..Default::default()
                        };
                        p.push_object(desc, ladder).unwrap();
                    }
                    let (mut a, mut b) = (Vec::new(), Vec::new());
                    greedy.distribute(&p, budget, &mut a);
                    FunkhouserIncremental::new(0.0).distribute(&p, budget, &mut b);
                    assert_eq!(a, b, "budget {budget}, start {sa:?} {sb:?}");
                }
            }
        }
    }

    #[test]
    fn hysteresis_keeps_last_frames_level() {
        // Two equally good objects; B was drawn at its best level last frame.
        let mut p = BudgetProblem::new();
        let ladder = [Level::new(2.0, 2.0), Level::new(1.0, 1.5)];
        for previous in [PreviousSelection::Level(1), PreviousSelection::Level(0)] {
            let desc = ObjectDesc {
                value: 1.0,
                previous,
                ..Default::default()
            };
            p.push_object(desc, &ladder).unwrap();
        }
        let mut out = Vec::new();
        FunkhouserIncremental::new(0.5).distribute(&p, 3.0, &mut out);
        assert_eq!(out[1].level, Some(0));
        assert_eq!(out[0].level, Some(1));
    }

    /// The published ranking (tuples by their own benefit over cost), even with the
    /// single-tuple fix, can fall below half the optimum; the hull ranking does not.
    #[test]
    fn published_ranking_is_not_half_optimal_but_hull_ranking_is() {
        // (The instance this test had before reached the optimum with either ranking;
        // this one was found by a random search.)
        let p = problem(&[
            &[
                (0.896_944_6, 5.075_413_7),
                (0.788_578_5, 6.216_793_5),
                (0.366_073_16, 1.339_150_2),
            ],
            &[(2.546_023_1, 16.921_751), (0.750_023_37, 8.113_423)],
            &[
                (2.325_558_4, 24.441_18),
                (1.804_233_7, 4.067_466_3),
                (0.980_119_9, 7.656_532),
            ],
        ]);
        let budget = 2.180_679;
        let optimum = crate::budget::oracle::optimal_selection(&p, budget)
            .unwrap()
            .benefit;
        let mut out = Vec::new();
        let mut published = FunkhouserSequin {
            half_optimality_fix: true,
            ..FunkhouserSequin::published()
        };
        published.distribute(&p, budget, &mut out);
        let published_benefit = p.benefit_of(&out);
        FunkhouserSequin::new().distribute(&p, budget, &mut out);
        let hull_benefit = p.benefit_of(&out);
        assert!(hull_benefit >= 0.5 * optimum, "{hull_benefit} vs {optimum}");
        assert!(
            published_benefit < 0.5 * optimum,
            "the published ranking reaches {published_benefit} of {optimum}"
        );
    }

    #[test]
    fn nothing_fits_drops_everything() {
        let p = problem(&[&[(2.0, 1.0)], &[(3.0, 1.0)]]);
        let mut out = Vec::new();
        let stats = FunkhouserSequin::new().distribute(&p, 1.0, &mut out);
        assert_eq!(stats.dropped, 2);
        let stats = FunkhouserIncremental::new(0.0).distribute(&p, 1.0, &mut out);
        assert_eq!(stats.dropped, 2);
        assert_eq!(stats.used, 0.0);
    }
}
