//! The Robin Hood distribution (paper §5, equations 1–4).
//!
//! Every visible object gets a share of the rendering time proportional to its value
//! (`t_i = v_i · t_r / v_f`); objects are visited simple → complex, and whatever an
//! object cannot use goes back into the pot for the objects after it. No visible object
//! is ever dropped: one whose cheapest representation does not fit its share is drawn
//! time-critically (truncated).
//!
//! See [`RobinHood`] for the two ways it departs from the paper.

use super::problem::{Allocation, BudgetProblem, BudgetStats, BudgetStrategy, sanitize_time};

/// What an object does with the time it is given.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub(crate) struct Fit {
    /// Predicted time of what the object will draw (seconds). May exceed the time given
    /// only when `truncated` is set.
    pub used: f32,
    /// Which representation it draws (the object's own numbering).
    pub level: u32,
    /// Even the cheapest representation did not fit: it is drawn time-critically.
    pub truncated: bool,
}

/// The best rung of a ladder (costs best → cheapest) that fits in `time`: the most
/// expensive representation not exceeding it, found by binary search. When none fits,
/// the cheapest, marked truncated (its full cost is reported as used, so the caller sees
/// the overrun).
///
/// # Panics
/// Never for a non-empty ladder; an empty ladder yields a zero-cost truncated fit.
pub(crate) fn fit_ladder(costs: impl LadderCosts, time: f32) -> Fit {
    let len = costs.len();
    if len == 0 {
        return Fit {
            used: 0.0,
            level: 0,
            truncated: true,
        };
    }
    // Costs are non-increasing, so "cost > time" holds on a prefix.
    let (mut lo, mut hi) = (0, len);
    while lo < hi {
        let mid = (lo + hi) / 2;
        if costs.cost(mid) > time {
            lo = mid + 1;
        } else {
            hi = mid;
        }
    }
    if lo < len {
        Fit {
            used: costs.cost(lo),
            level: lo as u32,
            truncated: false,
        }
    } else {
        Fit {
            used: costs.cost(len - 1),
            level: (len - 1) as u32,
            truncated: true,
        }
    }
}

/// A ladder's costs, best → cheapest: a slice of costs or of [`Level`](super::Level)s.
pub(crate) trait LadderCosts {
    /// Number of representations.
    fn len(&self) -> usize;
    /// Cost of representation `index`.
    fn cost(&self, index: usize) -> f32;
}

impl LadderCosts for &[f32] {
    fn len(&self) -> usize {
        <[f32]>::len(self)
    }
    fn cost(&self, index: usize) -> f32 {
        self[index]
    }
}

impl LadderCosts for &[super::Level] {
    fn len(&self) -> usize {
        <[super::Level]>::len(self)
    }
    fn cost(&self, index: usize) -> f32 {
        self[index].cost
    }
}

/// A semi-continuous representation, like a tree whose trunk and leaves can be drawn
/// with any number of primitives: it uses as much of its time as it can, up to `full`,
/// and never less than `minimum` (its cheapest drawable form).
///
/// The level reported is 0 at full detail, 1 for a partial drawing and 2 when truncated.
#[cfg(test)]
pub(crate) fn fit_continuous(full: f32, minimum: f32, time: f32) -> Fit {
    let full = full.max(0.0);
    let minimum = minimum.clamp(0.0, full);
    if time >= full {
        Fit {
            used: full,
            level: 0,
            truncated: false,
        }
    } else if time >= minimum {
        Fit {
            used: time,
            level: 1,
            truncated: false,
        }
    } else {
        Fit {
            used: minimum,
            level: 2,
            truncated: true,
        }
    }
}

/// Residue worth another pass, as a fraction of the rendering time (or of the floors, when
/// they exceed it).
pub(crate) const RESIDUE_FRACTION: f64 = 0.01;

/// At most this many passes over the residue after the hand-out.
pub(crate) const RESIDUE_PASSES: u32 = 3;

/// The Robin Hood strategy. Keeps scratch buffers between frames, so reuse one value.
///
/// **The floors are paid first** (a deviation from the paper, which hands out the whole
/// rendering time by value): since every visible object draws at least its cheapest
/// representation, those costs are taken off the rendering time before the hand-out, and
/// each object receives its floor plus its share of the rest. Without it, objects of low
/// value are given less than their cheapest representation, draw it anyway, and the
/// frame overruns by the sum of those differences. When even the floors do not fit, every
/// object gets its floor and the excess is reported ([`BudgetStats::floor_excess`]).
///
/// **The remainder is handed out again** (the paper suggests spending it on quality): an
/// object visited early may be given less than its full detail while the objects after it
/// cannot use all of theirs, and what they leave comes back at the end with nobody left
/// to take it. When that residue is more than [`RESIDUE_FRACTION`] of the rendering time
/// (of the floors' sum, when the floors alone exceed it), it is shared again by value among the objects still below their best representation
/// (level 0), simple → complex, each searching again with what it used plus its share;
/// up to [`RESIDUE_PASSES`] times.
#[derive(Clone, Debug, Default)]
pub(crate) struct RobinHood {
    order: Vec<u32>,
    suffix_values: Vec<f64>,
    floors: Vec<f32>,
}

impl RobinHood {
    /// A Robin Hood distributor with empty scratch buffers.
    #[cfg(any(test, feature = "testing"))]
    pub(crate) fn new() -> Self {
        Self::default()
    }

    /// The general form: `values[i]`, `complexities[i]` and `floors[i]` describe object
    /// `i`, and `fit(i, time)` says what object `i` does with `time` seconds — a ladder
    /// search ([`fit_ladder`]), a continuous form ([`fit_continuous`]) or anything else.
    /// `floors[i]` is the cost of object `i`'s cheapest representation (what `fit(i, 0)`
    /// uses): paid before the hand-out (see [`RobinHood`]).
    ///
    /// Objects are visited in ascending complexity (ties keep input order). If the
    /// complexities are already sorted — objects grouped by pre-sorted type — this costs
    /// O(n); otherwise an O(n log n) sort runs on a scratch index buffer.
    ///
    /// NaN, negative or infinite values count as 0 (such objects get no time beyond their
    /// floor). Objects beyond the end of a shorter `complexities` or `floors` slice count
    /// as complexity 0 (visited first) and floor 0; NaN, negative or infinite floors
    /// count as 0.
    pub(crate) fn distribute_with<F>(
        &mut self,
        values: &[f32],
        complexities: &[f32],
        floors: &[f32],
        rendering_time: f32,
        mut fit: F,
        allocations: &mut Vec<Allocation>,
    ) -> BudgetStats
    where
        F: FnMut(usize, f32) -> Fit,
    {
        let n = values.len();
        let rendering_time = sanitize_time(rendering_time);
        allocations.clear();
        allocations.resize(n, Allocation::DROPPED);
        self.order_by_complexity(complexities, n);
        let clean = |v: f32| {
            if v.is_finite() && v > 0.0 {
                f64::from(v)
            } else {
                0.0
            }
        };

        // v_f for every suffix of the visiting order (P-1, P-4 without cancellation).
        self.suffix_values.clear();
        self.suffix_values.resize(n + 1, 0.0);
        for k in (0..n).rev() {
            let i = self.visit(k);
            self.suffix_values[k] = self.suffix_values[k + 1] + clean(values[i]);
        }

        let floor_of = |i: usize| clean(floors.get(i).copied().unwrap_or(0.0));
        let total_floor: f64 = (0..n).map(floor_of).sum();
        let mut remaining = (f64::from(rendering_time) - total_floor).max(0.0);
        for k in 0..n {
            let i = self.visit(k);
            let value = clean(values[i]);
            let value_left = self.suffix_values[k];
            let share = if value_left > 0.0 {
                (value / value_left).min(1.0)
            } else {
                0.0
            };
            let portion = remaining * share; // P-2
            remaining -= portion; // P-3
            let given = (floor_of(i) + portion).min(f64::from(f32::MAX)) as f32;
            allocations[i] = offer(&mut fit, i, given);
            // Remainder back to the pot; an overrun is reported, not taken from others.
            remaining += f64::from((given - allocations[i].used).max(0.0));
        }
        // The residue, again, to the objects still below their best. Measured against what
        // is spent, so that a frame whose floors exceed its time does not hand out crumbs
        // that a frame with more time would leave (more time must not draw less).
        let worth_a_pass = RESIDUE_FRACTION * f64::from(rendering_time).max(total_floor);
        for _ in 0..RESIDUE_PASSES {
            if remaining <= worth_a_pass {
                break;
            }
            let hungry = |a: &Allocation| a.level.is_some_and(|l| l > 0);
            let mut value_left: f64 = (0..n)
                .filter(|&i| hungry(&allocations[i]))
                .map(|i| clean(values[i]))
                .sum();
            if value_left <= 0.0 {
                break;
            }
            for k in 0..n {
                let i = self.visit(k);
                let before = allocations[i];
                if !hungry(&before) {
                    continue;
                }
                let value = clean(values[i]);
                let share = if value_left > 0.0 {
                    (value / value_left).min(1.0)
                } else {
                    0.0
                };
                value_left -= value;
                let portion = remaining * share;
                if portion <= 0.0 {
                    continue;
                }
                remaining -= portion;
                let given = (f64::from(before.used) + portion).min(f64::from(f32::MAX)) as f32;
                let after = offer(&mut fit, i, given);
                remaining += f64::from((given - after.used).max(0.0));
                allocations[i] = Allocation {
                    truncated: after.truncated && before.truncated,
                    ..after
                };
            }
        }
        let mut stats = BudgetStats::from_allocations(rendering_time, allocations);
        stats.floor = total_floor.min(f64::from(f32::MAX)) as f32;
        stats.floor_excess =
            (total_floor - f64::from(rendering_time)).clamp(0.0, f64::from(f32::MAX)) as f32;
        stats
    }

    fn visit(&self, k: usize) -> usize {
        if self.order.is_empty() {
            k
        } else {
            self.order[k] as usize
        }
    }

    /// Leaves `order` empty when the objects are already in visiting order.
    fn order_by_complexity(&mut self, complexities: &[f32], n: usize) {
        self.order.clear();
        let key = |i: usize| complexities.get(i).copied().unwrap_or(0.0);
        if (1..n).all(|i| key(i - 1) <= key(i)) {
            return;
        }
        self.order.extend(0..n as u32);
        self.order
            .sort_by(|&a, &b| key(a as usize).total_cmp(&key(b as usize)));
    }
}

/// What object `i` does with `given` seconds, as an allocation: a time it reports that is
/// not finite counts as all it was given.
fn offer(fit: &mut impl FnMut(usize, f32) -> Fit, i: usize, given: f32) -> Allocation {
    let chosen = fit(i, given);
    Allocation {
        given,
        used: if chosen.used.is_finite() {
            chosen.used.max(0.0)
        } else {
            given
        },
        level: Some(chosen.level),
        truncated: chosen.truncated,
    }
}

impl BudgetStrategy for RobinHood {
    #[cfg(test)]
    fn name(&self) -> &'static str {
        "Robin Hood"
    }

    fn distribute(
        &mut self,
        problem: &BudgetProblem,
        rendering_time: f32,
        allocations: &mut Vec<Allocation>,
    ) -> BudgetStats {
        // Each object's floor: the cheapest rung of its ladder.
        let mut floors = core::mem::take(&mut self.floors);
        floors.clear();
        floors.extend((0..problem.len()).map(|i| problem.ladder(i).last().map_or(0.0, |l| l.cost)));
        let stats = self.distribute_with(
            problem.values(),
            problem.complexities(),
            &floors,
            rendering_time,
            |i, time| fit_ladder(problem.ladder(i), time),
            allocations,
        );
        self.floors = floors;
        stats
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::budget::{Level, ObjectDesc};
    use approx::assert_relative_eq;

    fn ladder(costs: &[f32]) -> Vec<Level> {
        costs.iter().map(|&c| Level::new(c, c)).collect()
    }

    fn problem(objects: &[(f32, f32, &[f32])]) -> BudgetProblem {
        let mut p = BudgetProblem::new();
        for &(value, complexity, costs) in objects {
            p.push_object(
                ObjectDesc {
                    value,
                    complexity,
                    ..Default::default()
                },
                &ladder(costs),
            )
            .unwrap();
        }
        p
    }

    #[test]
    fn ladder_search_picks_the_most_expensive_that_fits() {
        let costs: &[f32] = &[8.0, 4.0, 2.0, 1.0];
        assert_eq!(fit_ladder(costs, 10.0).level, 0);
        assert_eq!(fit_ladder(costs, 8.0).level, 0);
        assert_eq!(fit_ladder(costs, 7.9).level, 1);
        assert_eq!(fit_ladder(costs, 1.0).level, 3);
        let none = fit_ladder(costs, 0.5);
        assert_eq!((none.level, none.used, none.truncated), (3, 1.0, true));
    }

    #[test]
    fn shares_are_proportional_to_value_when_all_is_used() {
        // Continuous objects use everything: t_i = v_i · t_r / v_f exactly.
        let values = [1.0, 3.0, 4.0];
        let mut out = Vec::new();
        let stats = RobinHood::new().distribute_with(
            &values,
            &[0.0; 3],
            &[],
            8.0,
            |_, t| fit_continuous(100.0, 0.0, t),
            &mut out,
        );
        assert_relative_eq!(out[0].given, 1.0);
        assert_relative_eq!(out[1].given, 3.0);
        assert_relative_eq!(out[2].given, 4.0);
        assert_relative_eq!(stats.used, 8.0);
        assert_eq!(stats.wasted, 0.0);
    }

    /// Paper §5, first extreme case: a simple object with a large area gets more time than
    /// it can use, and the complex object after it inherits the remainder.
    #[test]
    fn simple_object_with_large_area_hands_its_remainder_on() {
        // Simple: best costs 1. Complex: best costs 9, then 5, then 2.
        let p = problem(&[(9.0, 1.0, &[1.0, 0.5]), (1.0, 9.0, &[9.0, 5.0, 2.0])]);
        let mut out = Vec::new();
        let stats = RobinHood::new().distribute(&p, 10.0, &mut out);
        // Floors 0.5 + 2 paid first, 7.5 handed out. Simple gets 0.5 + 9/10 · 7.5 = 7.25,
        // uses 1; complex gets 2 + 0.75 + 6.25 = 9 and draws its best level.
        assert_relative_eq!(stats.floor, 2.5);
        assert_relative_eq!(out[0].given, 7.25);
        assert_eq!(out[0].level, Some(0));
        assert_relative_eq!(out[1].given, 9.0);
        assert_eq!(out[1].level, Some(0));
        assert_relative_eq!(stats.used, 10.0);
        assert_relative_eq!(stats.wasted, 0.0);
    }

    /// Paper §5, second extreme case: a complex object with a large area uses its share,
    /// and the simple objects before it keep theirs.
    #[test]
    fn complex_object_with_large_area_uses_its_share() {
        let p = problem(&[
            (1.0, 1.0, &[1.0, 0.5]),
            (1.0, 1.0, &[1.0, 0.5]),
            (8.0, 9.0, &[9.0, 8.0, 2.0]),
        ]);
        let mut out = Vec::new();
        let stats = RobinHood::new().distribute(&p, 10.0, &mut out);
        // Floors 0.5 + 0.5 + 2, then 7 by value: 0.5 + 0.7 (uses 1, leaves 0.2), 0.5 +
        // (6.3 + 0.2) / 9, and the rest, 8.
        assert_relative_eq!(out[0].given, 1.2);
        assert_relative_eq!(out[1].given, 0.5 + 6.5 / 9.0);
        assert_relative_eq!(out[2].given, 8.0, max_relative = 1e-6);
        assert_eq!(out[2].level, Some(1));
        assert_relative_eq!(stats.used, 10.0);
    }

    #[test]
    fn visits_simple_to_complex_whatever_the_input_order() {
        // The complex object comes first in the input but must be visited last, so it
        // can absorb the simple object's remainder.
        let p = problem(&[(1.0, 9.0, &[9.0, 5.0, 2.0]), (9.0, 1.0, &[1.0, 0.5])]);
        let mut out = Vec::new();
        RobinHood::new().distribute(&p, 10.0, &mut out);
        assert_eq!(out[0].level, Some(0));
        assert_relative_eq!(out[0].given, 9.0);
    }

    #[test]
    fn floors_beyond_the_time_are_drawn_and_reported() {
        let p = problem(&[(1.0, 1.0, &[4.0, 3.0]), (1.0, 2.0, &[4.0, 3.0])]);
        let mut out = Vec::new();
        let stats = RobinHood::new().distribute(&p, 1.0, &mut out);
        // Each gets its floor, nothing more: drawn at the cheapest, never dropped.
        assert!(out.iter().all(|a| a.level == Some(1) && a.given == 3.0));
        assert_eq!((stats.drawn, stats.dropped), (2, 0));
        assert_relative_eq!(stats.floor, 6.0);
        assert_relative_eq!(stats.floor_excess, 5.0);
        assert_relative_eq!(stats.overrun, 5.0);
    }

    #[test]
    fn without_floors_a_share_below_the_cheapest_is_truncated() {
        // The paper's hand-out: no floors given, so low shares draw truncated.
        let mut out = Vec::new();
        let stats = RobinHood::new().distribute_with(
            &[1.0, 1.0],
            &[1.0, 2.0],
            &[],
            1.0,
            |_, time| fit_ladder(&[4.0_f32, 3.0][..], time),
            &mut out,
        );
        assert!(out.iter().all(|a| a.truncated && a.level == Some(1)));
        assert_eq!((stats.drawn, stats.dropped, stats.truncated), (2, 0, 2));
        assert_relative_eq!(stats.overrun, 5.0);
        // The first object's overrun does not starve the second.
        assert_relative_eq!(out[1].given, 0.5);
    }

    #[test]
    fn zero_time_or_values_never_produce_nan() {
        let p = problem(&[(0.0, 1.0, &[1.0]), (0.0, 1.0, &[1.0])]);
        for time in [0.0, -1.0, f32::NAN, f32::INFINITY] {
            let mut out = Vec::new();
            let stats = RobinHood::new().distribute(&p, time, &mut out);
            assert!(out.iter().all(|a| a.given.is_finite() && a.given >= 0.0));
            assert!(stats.used.is_finite() && stats.wasted.is_finite());
            assert_eq!(stats.dropped, 0);
        }
    }

    #[test]
    fn continuous_fit_uses_what_it_can() {
        assert_eq!(fit_continuous(4.0, 1.0, 9.0).used, 4.0);
        assert_eq!(fit_continuous(4.0, 1.0, 2.5).used, 2.5);
        let t = fit_continuous(4.0, 1.0, 0.5);
        assert!(t.truncated && t.used == 1.0);
    }
}
