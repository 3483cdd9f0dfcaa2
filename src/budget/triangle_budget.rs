//! The triangle-budget greedy of the SRGGE course project: every model's contribution
//! halves with each level of detail it gains; raise the largest contributor while under
//! budget, then lower the smallest while over.
//!
//! The original counts triangles against a maximum; here the ladder's costs play the
//! role of triangle counts (they are proportional when every triangle costs the same),
//! so the strategy shares the budget slot with the others. A model's contribution at its
//! cheapest level is its value (`diagonal / distance` in the original, 0 for models
//! behind the camera); each level of detail above that halves it. Models are never
//! dropped: the cheapest level is the floor, and when even that exceeds the budget the
//! excess is reported as [`BudgetStats::overrun`].
//!
//! Misprint fixed: line 16 of the published pseudo-code doubles `contribution(maxId)`
//! in the lowering loop; it must be `contribution(minId)`, the model being lowered.

use super::heap::ItemQueues;
use super::problem::{
    Allocation, BudgetProblem, BudgetStats, BudgetStrategy, PreviousSelection, sanitize_time,
};

/// The SRGGE triangle-budget greedy, starting from last frame's levels.
#[derive(Clone, Debug, Default)]
pub(crate) struct TriangleBudget {
    /// Levels of detail gained above the cheapest, per object (0 = cheapest).
    detail: Vec<u32>,
    contribution: Vec<f32>,
    queues: ItemQueues,
}

impl TriangleBudget {
    /// A triangle-budget greedy with empty scratch buffers.
    #[cfg(any(test, feature = "testing"))]
    pub(crate) fn new() -> Self {
        Self::default()
    }

    fn requeue(&mut self, problem: &BudgetProblem, object: usize) {
        self.queues.touch(object);
        let top = problem.ladder(object).len() as u32 - 1;
        if self.detail[object] < top {
            self.queues.push_max(object, self.contribution[object]);
        }
        if self.detail[object] > 0 {
            self.queues.push_min(object, self.contribution[object]);
        }
    }

    fn cost(problem: &BudgetProblem, object: usize, detail: u32) -> f64 {
        let ladder = problem.ladder(object);
        f64::from(ladder[ladder.len() - 1 - detail as usize].cost)
    }
}

impl BudgetStrategy for TriangleBudget {
    #[cfg(test)]
    fn name(&self) -> &'static str {
        "triangle budget"
    }

    fn distribute(
        &mut self,
        problem: &BudgetProblem,
        rendering_time: f32,
        allocations: &mut Vec<Allocation>,
    ) -> BudgetStats {
        let budget = f64::from(sanitize_time(rendering_time));
        let n = problem.len();
        self.detail.clear();
        self.contribution.clear();
        self.queues.reset(n);
        let mut total = 0.0;
        for object in 0..n {
            let top = problem.ladder(object).len() as u32 - 1;
            let detail = match problem.previous(object) {
                PreviousSelection::Level(level) => top - level,
                PreviousSelection::New | PreviousSelection::Dropped => 0,
            };
            self.detail.push(detail);
            // c = value / 2^detail
            let value = problem.values()[object];
            self.contribution.push(value * 0.5_f32.powi(detail as i32));
            total += Self::cost(problem, object, detail);
        }
        for object in 0..n {
            self.requeue(problem, object);
        }

        while total < budget {
            let Some(object) = self.queues.pop_max() else {
                break;
            };
            let detail = self.detail[object];
            total += Self::cost(problem, object, detail + 1) - Self::cost(problem, object, detail);
            self.detail[object] += 1;
            self.contribution[object] *= 0.5;
            self.requeue(problem, object);
        }
        while total > budget {
            let Some(object) = self.queues.pop_min() else {
                break;
            };
            let detail = self.detail[object];
            total += Self::cost(problem, object, detail - 1) - Self::cost(problem, object, detail);
            self.detail[object] -= 1;
            self.contribution[object] *= 2.0; // minId, not maxId
            self.requeue(problem, object);
        }

        allocations.clear();
        allocations.extend((0..n).map(|object| {
            let ladder = problem.ladder(object);
            let level = (ladder.len() - 1) as u32 - self.detail[object];
            Allocation::drawn(ladder[level as usize].cost, level)
        }));
        BudgetStats::from_allocations(budget as f32, allocations)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::budget::{Level, ObjectDesc};
    use approx::assert_relative_eq;

    fn push(p: &mut BudgetProblem, value: f32, triangles: &[f32], previous: PreviousSelection) {
        let ladder: Vec<Level> = triangles.iter().map(|&t| Level::new(t, t)).collect();
        let desc = ObjectDesc {
            value,
            previous,
            ..Default::default()
        };
        p.push_object(desc, &ladder).unwrap();
    }

    #[test]
    fn by_hand() {
        // Near model (contribution 8) and far model (1), ladders 800/400/200/100 triangles.
        let ladder = [800.0, 400.0, 200.0, 100.0];
        let mut p = BudgetProblem::new();
        push(&mut p, 8.0, &ladder, PreviousSelection::New);
        push(&mut p, 1.0, &ladder, PreviousSelection::New);
        let mut out = Vec::new();
        let stats = TriangleBudget::new().distribute(&p, 700.0, &mut out);
        // Start 200. Raise near: 8→4 (300), 4→2 (500), 2→1 (900, top) → over budget.
        // Lower the smallest contribution among raised models: near (1) → 500.
        // Then raising stops, because the raising loop ran first; result 500 ≤ 700.
        assert_eq!(out[0].level, Some(1));
        assert_eq!(out[1].level, Some(3));
        assert_relative_eq!(stats.used, 500.0);
    }

    #[test]
    fn raises_far_model_when_near_one_is_done() {
        let ladder = [400.0, 200.0, 100.0];
        let mut p = BudgetProblem::new();
        push(&mut p, 8.0, &ladder, PreviousSelection::New);
        push(&mut p, 1.0, &ladder, PreviousSelection::New);
        let mut out = Vec::new();
        TriangleBudget::new().distribute(&p, 700.0, &mut out);
        // Near to the top (400), then far 100 → 200 (600), then 200 → 400 (800) → lower far.
        assert_eq!(out[0].level, Some(0));
        assert_eq!(out[1].level, Some(1));
    }

    #[test]
    fn starts_from_last_frame_and_never_drops() {
        let ladder = [400.0, 200.0, 100.0];
        let mut p = BudgetProblem::new();
        push(&mut p, 1.0, &ladder, PreviousSelection::Level(0));
        push(&mut p, 1.0, &ladder, PreviousSelection::Level(0));
        let mut out = Vec::new();
        let stats = TriangleBudget::new().distribute(&p, 150.0, &mut out);
        assert!(out.iter().all(|a| a.level == Some(2)));
        assert_eq!(stats.dropped, 0);
        assert_relative_eq!(stats.overrun, 50.0);
    }
}
