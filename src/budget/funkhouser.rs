//! Funkhouser & Séquin (1993): level-of-detail selection as a multiple-choice knapsack
//! problem, solved greedily by `Value = Benefit / Cost`, and its incremental variant
//! that starts from last frame's selection.
//!
//! Unlike Robin Hood these maximise benefit within the budget and may leave visible
//! objects undrawn (popping); the [`BudgetStats::dropped`] count says how many.

use alloc::vec::Vec;

use super::heap::ItemQueues;
use super::problem::{
    Allocation, BudgetProblem, BudgetStats, BudgetStrategy, Level, PreviousSelection,
    sanitize_time,
};

const NOT_SELECTED: u32 = u32::MAX;

#[derive(Clone, Copy, Debug)]
struct Tuple {
    value: f32,
    object: u32,
    level: u32,
}

/// The greedy MCKP approximation of Funkhouser & Séquin.
///
/// Tuples (object, level) are taken in descending `Value`; a tuple replaces the object's
/// current one when its benefit is greater, and the scan stops at the first tuple whose
/// addition would exceed the budget. With [`half_optimality_fix`](Self::half_optimality_fix)
/// (Mason & Blake's correction) the result is compared with the single highest-benefit
/// tuple that fits on its own, and the better of the two is kept, which guarantees at
/// least half the optimal benefit.
#[derive(Clone, Debug)]
pub struct FunkhouserSequin {
    /// Compare with the best single tuple. Default: `true`.
    pub half_optimality_fix: bool,
    tuples: Vec<Tuple>,
    selection: Vec<u32>,
    used_single_best: bool,
}

impl Default for FunkhouserSequin {
    fn default() -> Self {
        Self {
            half_optimality_fix: true,
            tuples: Vec::new(),
            selection: Vec::new(),
            used_single_best: false,
        }
    }
}

impl FunkhouserSequin {
    /// The greedy with the half-optimality fix.
    pub fn new() -> Self {
        Self::default()
    }

    /// Whether the last frame's answer was the single best tuple rather than the greedy set.
    pub fn used_single_best(&self) -> bool {
        self.used_single_best
    }
}

impl BudgetStrategy for FunkhouserSequin {
    fn name(&self) -> &'static str {
        "Funkhouser–Séquin greedy"
    }

    fn distribute(
        &mut self,
        problem: &BudgetProblem,
        rendering_time: f32,
        allocations: &mut Vec<Allocation>,
    ) -> BudgetStats {
        let budget = f64::from(sanitize_time(rendering_time));
        let n = problem.len();
        self.tuples.clear();
        for object in 0..n {
            for (level, l) in problem.ladder(object).iter().enumerate() {
                self.tuples.push(Tuple {
                    value: l.value(),
                    object: object as u32,
                    level: level as u32,
                });
            }
        }
        // Radix sort: descending value, stable, O(tuples).
        radsort::sort_by_key(&mut self.tuples, |t| -t.value);

        self.selection.clear();
        self.selection.resize(n, NOT_SELECTED);
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

        self.used_single_best = false;
        if self.half_optimality_fix
            && let Some((object, level, single)) = best_single_tuple(problem, budget)
            && single > benefit
        {
            self.selection.fill(NOT_SELECTED);
            self.selection[object] = level;
            self.used_single_best = true;
        }
        write_selection(problem, &self.selection, budget as f32, allocations)
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

fn write_selection(
    problem: &BudgetProblem,
    selection: &[u32],
    rendering_time: f32,
    allocations: &mut Vec<Allocation>,
) -> BudgetStats {
    allocations.clear();
    allocations.extend(selection.iter().enumerate().map(|(object, &level)| {
        if level == NOT_SELECTED {
            Allocation::DROPPED
        } else {
            let cost = problem.ladder(object)[level as usize].cost;
            Allocation {
                given: cost,
                used: cost,
                level: Some(level),
                truncated: false,
            }
        }
    }));
    BudgetStats::from_allocations(rendering_time, allocations)
}

/// Funkhouser & Séquin's incremental optimisation: start from last frame's selection
/// (and the cheapest level for newly visible objects), repeatedly raise the object whose
/// next level has the highest `Value`, then lower the objects whose current level has
/// the lowest `Value` until the cost fits; stop when the same object was raised and
/// lowered. Gives the greedy's answer when each object's `Value` falls as its detail
/// rises, usually in far fewer steps.
///
/// [`hysteresis`](Self::hysteresis) favours staying put: the level an object drew last
/// frame counts its benefit multiplied by `1 + hysteresis`.
#[derive(Clone, Debug, Default)]
pub struct FunkhouserIncremental {
    /// Extra weight for keeping last frame's level (≥ 0; NaN or negative count as 0).
    /// Default: `0.0`.
    pub hysteresis: f32,
    /// Rank per object: 0 = not drawn, r ≥ 1 = ladder index `len − r`.
    rank: Vec<u32>,
    queues: ItemQueues,
    iterations: u32,
}

impl FunkhouserIncremental {
    /// The incremental optimiser with hysteresis `hysteresis`.
    pub fn new(hysteresis: f32) -> Self {
        Self {
            hysteresis,
            ..Self::default()
        }
    }

    /// Raise-and-lower iterations the last frame needed.
    pub fn iterations(&self) -> u32 {
        self.iterations
    }

    fn level_value(&self, problem: &BudgetProblem, object: usize, rank: u32) -> f32 {
        let ladder = problem.ladder(object);
        let level = ladder.len() as u32 - rank;
        let mut l = ladder[level as usize];
        let h = if self.hysteresis.is_finite() {
            self.hysteresis.max(0.0)
        } else {
            0.0
        };
        if problem.previous(object) == PreviousSelection::Level(level) {
            l.benefit *= 1.0 + h;
        }
        l.value()
    }

    fn requeue(&mut self, problem: &BudgetProblem, object: usize) {
        self.queues.touch(object);
        let rank = self.rank[object];
        let top = problem.ladder(object).len() as u32;
        if rank < top {
            let next = self.level_value(problem, object, rank + 1);
            self.queues.push_max(object, next);
        }
        if rank > 0 {
            let current = self.level_value(problem, object, rank);
            self.queues.push_min(object, current);
        }
    }
}

fn rank_cost(ladder: &[Level], rank: u32) -> f64 {
    if rank == 0 {
        0.0
    } else {
        f64::from(ladder[ladder.len() - rank as usize].cost)
    }
}

impl BudgetStrategy for FunkhouserIncremental {
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
        self.rank.clear();
        self.queues.reset(n);
        let mut cost = 0.0;
        let mut total_levels = 0_usize;
        for object in 0..n {
            let len = problem.ladder(object).len() as u32;
            total_levels += len as usize;
            let rank = match problem.previous(object) {
                PreviousSelection::New => 1,
                PreviousSelection::Dropped => 0,
                PreviousSelection::Level(level) => len - level,
            };
            self.rank.push(rank);
            cost += rank_cost(problem.ladder(object), rank);
        }
        for object in 0..n {
            self.requeue(problem, object);
        }

        // Each iteration raises one level; without monotone Values the raise/lower pairs
        // could cycle, so the number of iterations is bounded.
        let limit = 4 * total_levels + 16;
        self.iterations = 0;
        loop {
            self.iterations += 1;
            let raised = self.queues.pop_max();
            if let Some(object) = raised {
                let ladder = problem.ladder(object);
                cost += rank_cost(ladder, self.rank[object] + 1)
                    - rank_cost(ladder, self.rank[object]);
                self.rank[object] += 1;
                self.requeue(problem, object);
            }
            let mut lowered_the_raised = false;
            while cost > budget {
                let Some(object) = self.queues.pop_min() else {
                    break;
                };
                let ladder = problem.ladder(object);
                cost += rank_cost(ladder, self.rank[object] - 1)
                    - rank_cost(ladder, self.rank[object]);
                self.rank[object] -= 1;
                self.requeue(problem, object);
                lowered_the_raised |= raised == Some(object);
            }
            if raised.is_none() || lowered_the_raised || self.iterations as usize >= limit {
                break;
            }
        }

        allocations.clear();
        allocations.extend((0..n).map(|object| {
            let rank = self.rank[object];
            if rank == 0 {
                Allocation::DROPPED
            } else {
                let ladder = problem.ladder(object);
                let level = ladder.len() as u32 - rank;
                let cost = ladder[level as usize].cost;
                Allocation {
                    given: cost,
                    used: cost,
                    level: Some(level),
                    truncated: false,
                }
            }
        }));
        BudgetStats::from_allocations(budget as f32, allocations)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::budget::ObjectDesc;
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
        // A: (4, 8) V=2, (1, 5) V=5. B: (3, 3) V=1, (2, 3) V=1.5. Budget 5.
        // Order: A1 (5), A0 (2), B1 (1.5), B0 (1).
        // Take A1 (cost 1), replace with A0 (cost 4), B1 would make 6 > 5: stop.
        let p = problem(&[&[(4.0, 8.0), (1.0, 5.0)], &[(3.0, 3.0), (2.0, 3.0)]]);
        let mut out = Vec::new();
        let mut fs = FunkhouserSequin::new();
        let stats = fs.distribute(&p, 5.0, &mut out);
        assert_eq!(out[0].level, Some(0));
        assert_eq!(out[1].level, None);
        assert_relative_eq!(stats.used, 4.0);
        assert_eq!(stats.dropped, 1);
        assert!(!fs.used_single_best());
    }

    #[test]
    fn half_optimality_fix_takes_the_single_best() {
        // The cheap tuple has the best value, then the big one does not fit beside it.
        let p = problem(&[&[(0.1, 1.0)], &[(10.0, 50.0)]]);
        let mut out = Vec::new();
        let mut plain = FunkhouserSequin {
            half_optimality_fix: false,
            ..Default::default()
        };
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
        let mut greedy = FunkhouserSequin {
            half_optimality_fix: false,
            ..Default::default()
        };
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
