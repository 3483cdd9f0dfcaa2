//! Reference answers for the budget strategies: the exact optimum of small
//! multiple-choice knapsack instances, and the LP-relaxation upper bound for any size,
//! so a strategy's benefit can be reported as a percentage of the bound.
//!
//! The exact optimum is a dynamic programme over Pareto frontiers (cost, benefit) — exact
//! for real-valued costs, with no discretisation — whose frontier size is capped.

#[cfg(test)]
use super::hierarchical::{LodHierarchy, NodeId};
#[cfg(test)]
use super::hull::upper_hull;
#[cfg(test)]
use super::problem::BudgetProblem;
use super::problem::sanitize_time;

/// Frontier points the exact solvers may hold at once before giving up.
#[cfg(test)]
pub(crate) const MAX_FRONTIER: usize = 1 << 20;

/// Why an exact optimum was not computed.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
#[cfg(test)]
pub(crate) enum OracleError {
    /// The instance is too large for the exact dynamic programme.
    #[error(
        "instance too large for the exact optimum: the Pareto frontier exceeded {MAX_FRONTIER} points"
    )]
    TooLarge,
}

/// An optimal selection: one ladder index or `None` (not drawn) per object.
#[derive(Clone, Debug, PartialEq, Default)]
#[cfg(test)]
pub(crate) struct OptimalSelection {
    /// The optimal total benefit.
    pub benefit: f64,
    /// Its cost.
    pub cost: f64,
    /// The chosen level per object.
    pub levels: Vec<Option<u32>>,
}

#[derive(Clone, Copy, Debug)]
#[cfg(test)]
struct Point {
    cost: f64,
    benefit: f64,
    /// Index of the point it extends in the previous stage's frontier.
    from: u32,
    /// Option taken at this stage: `u32::MAX` for not drawn.
    option: u32,
}

/// Keeps only points not dominated by a cheaper point with at least the same benefit.
#[cfg(test)]
fn prune(points: &mut Vec<Point>) {
    points.sort_by(|a, b| {
        a.cost
            .total_cmp(&b.cost)
            .then(b.benefit.total_cmp(&a.benefit))
    });
    let mut best = f64::NEG_INFINITY;
    points.retain(|p| {
        if p.benefit > best {
            best = p.benefit;
            true
        } else {
            false
        }
    });
}

/// The exact optimum of `problem` as a multiple-choice knapsack: at most one level per
/// object (objects may be left undrawn), total cost at most `budget`, maximal benefit.
#[cfg(test)]
pub(crate) fn optimal_selection(
    problem: &BudgetProblem,
    budget: f32,
) -> Result<OptimalSelection, OracleError> {
    let budget = f64::from(sanitize_time(budget));
    let mut stages: Vec<Vec<Point>> = Vec::with_capacity(problem.len());
    let mut frontier = vec![Point {
        cost: 0.0,
        benefit: 0.0,
        from: 0,
        option: u32::MAX,
    }];
    for object in 0..problem.len() {
        let mut next = Vec::with_capacity(frontier.len() * (problem.ladder(object).len() + 1));
        for (from, p) in frontier.iter().enumerate() {
            next.push(Point {
                from: from as u32,
                option: u32::MAX,
                ..*p
            });
            for (level, l) in problem.ladder(object).iter().enumerate() {
                let cost = p.cost + f64::from(l.cost);
                if cost <= budget {
                    next.push(Point {
                        cost,
                        benefit: p.benefit + f64::from(l.benefit),
                        from: from as u32,
                        option: level as u32,
                    });
                }
            }
        }
        prune(&mut next);
        if next.len() > MAX_FRONTIER {
            return Err(OracleError::TooLarge);
        }
        stages.push(core::mem::replace(&mut frontier, next));
    }
    let best = frontier
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.benefit.total_cmp(&b.1.benefit))
        .map(|(i, _)| i)
        .unwrap_or(0);
    let mut levels = vec![None; problem.len()];
    let (benefit, cost) = (frontier[best].benefit, frontier[best].cost);
    let mut index = best;
    let mut stage = &frontier;
    for object in (0..problem.len()).rev() {
        let p = stage[index];
        levels[object] = (p.option != u32::MAX).then_some(p.option);
        index = p.from as usize;
        stage = &stages[object];
    }
    Ok(OptimalSelection {
        benefit,
        cost,
        levels,
    })
}

/// The optimum of the linear relaxation (fractions of levels allowed): an upper bound on
/// the benefit any selection within `budget` can reach. O(L log L) for L levels.
#[cfg(test)]
pub(crate) fn lp_upper_bound(problem: &BudgetProblem, budget: f32) -> f64 {
    let budget = f64::from(sanitize_time(budget));
    // The LP optimum takes hull increments in falling efficiency, the last one in part.
    let mut increments: Vec<(f64, f64, f64)> = Vec::new();
    let mut hull = Vec::new();
    for object in 0..problem.len() {
        upper_hull(problem.cheapest_first(object), budget, &mut hull);
        increments.extend(
            hull.iter()
                .map(|p| (p.efficiency, p.delta_cost, p.delta_benefit)),
        );
    }
    increments.sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut left = budget;
    let mut bound = 0.0;
    for (_, dc, db) in increments {
        if dc <= left {
            left -= dc;
            bound += db;
        } else {
            bound += db * left / dc;
            break;
        }
    }
    bound
}

/// The benefit of drawing an object of `value` whose full detail costs `full` with
/// `cost`: `value · √(cost / full)` (capped at `value`; `value` when full detail is free).
/// The benefit model of the app's ladders (`lod`), in which a representation's accuracy
/// grows with the square root of its share of the full cost.
pub(crate) fn sqrt_benefit(value: f32, full: f32, cost: f32) -> f64 {
    let value = f64::from(value.max(0.0));
    if full.is_nan() || full <= 0.0 {
        return value;
    }
    value * (f64::from(cost.max(0.0)) / f64::from(full)).min(1.0).sqrt()
}

/// The largest total [`sqrt_benefit`] of `objects` (`(value, full cost)` each, any cost
/// in `0..=full` allowed) within `budget`: an upper bound on what any selection of
/// representations on that benefit curve can reach, and the LP bound of ladders sampled
/// on it as the samples grow dense. O(n log n).
///
/// At the optimum every object not at full detail gets `cost = μ · value² / full` for one
/// `μ`; objects whose full cost is reached first are capped there.
pub(crate) fn sqrt_benefit_bound(objects: &[(f32, f32)], budget: f32) -> f64 {
    let budget = f64::from(sanitize_time(budget));
    let mut bound = 0.0;
    // Per object that must share the budget: the μ at which it reaches full detail, its
    // full cost, value² / full (its cost per unit of μ before that), and its value.
    let mut sharing: Vec<(f64, f64, f64, f64)> = Vec::with_capacity(objects.len());
    for &(value, full) in objects {
        let value = f64::from(if value.is_finite() {
            value.max(0.0)
        } else {
            0.0
        });
        if value == 0.0 {
            continue;
        }
        // As `sqrt_benefit` sees it: an infinite full cost is never reached.
        let full = f64::from(sanitize_time(full));
        if full == 0.0 {
            bound += value;
            continue;
        }
        sharing.push((
            full * full / (value * value),
            full,
            value * value / full,
            value,
        ));
    }
    if sharing.iter().map(|s| s.1).sum::<f64>() <= budget {
        return bound + sharing.iter().map(|s| s.3).sum::<f64>();
    }
    sharing.sort_by(|a, b| a.0.total_cmp(&b.0));
    // Sweep μ up through the breakpoints: cost(μ) = Σ capped full + μ Σ uncapped slope.
    let mut capped_cost = 0.0;
    let mut capped_value = 0.0;
    let mut slope: f64 = sharing.iter().map(|s| s.2).sum();
    for &(breakpoint, full, per_mu, value) in &sharing {
        if capped_cost + breakpoint * slope >= budget {
            break;
        }
        capped_cost += full;
        capped_value += value;
        slope -= per_mu;
    }
    // Between breakpoints: the uncapped share what is left. Benefit of an uncapped
    // object: value · √(μ value² / full²) = √μ · value² / full.
    let mu = if slope > 0.0 {
        ((budget - capped_cost) / slope).max(0.0)
    } else {
        0.0
    };
    bound + capped_value + mu.sqrt() * slope
}

/// The best benefit over the complete representations of `hierarchy` (every leaf covered
/// by exactly one impostor of itself or of an ancestor) within `budget`, or nothing at all
/// — the constrained problem the hierarchical strategy approximates.
#[cfg(test)]
pub(crate) fn hierarchy_optimum(hierarchy: &LodHierarchy, budget: f32) -> Result<f64, OracleError> {
    let budget = f64::from(sanitize_time(budget));
    let n = hierarchy.len();
    let mut frontiers: Vec<Vec<Point>> = Vec::with_capacity(n);
    // Children precede their groups, so index order is post-order.
    for node in 0..n as NodeId {
        let mut points: Vec<Point> = hierarchy
            .impostors(node)
            .iter()
            .filter(|l| f64::from(l.cost) <= budget)
            .map(|l| Point {
                cost: f64::from(l.cost),
                benefit: f64::from(l.benefit),
                from: 0,
                option: 0,
            })
            .collect();
        let children = hierarchy.children(node);
        if !children.is_empty() {
            let combined = combine(children.iter().map(|&c| &frontiers[c as usize]), budget)?;
            points.extend(combined);
        }
        prune(&mut points);
        frontiers.push(points);
    }
    let top: Vec<NodeId> = hierarchy.top_level().collect();
    let mut best = 0.0_f64; // the imaginary empty representation
    for p in combine(top.iter().map(|&c| &frontiers[c as usize]), budget)? {
        best = best.max(p.benefit);
    }
    Ok(best)
}

/// Minkowski sum of frontiers (every child represented), pruned and capped at `budget`.
#[cfg(test)]
fn combine<'a>(
    frontiers: impl Iterator<Item = &'a Vec<Point>>,
    budget: f64,
) -> Result<Vec<Point>, OracleError> {
    let mut acc = vec![Point {
        cost: 0.0,
        benefit: 0.0,
        from: 0,
        option: 0,
    }];
    for f in frontiers {
        let mut next = Vec::with_capacity(acc.len() * f.len());
        for a in &acc {
            for b in f {
                let cost = a.cost + b.cost;
                if cost <= budget {
                    next.push(Point {
                        cost,
                        benefit: a.benefit + b.benefit,
                        from: 0,
                        option: 0,
                    });
                }
            }
        }
        prune(&mut next);
        if next.len() > MAX_FRONTIER {
            return Err(OracleError::TooLarge);
        }
        acc = next;
    }
    Ok(acc)
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
            p.push_object(ObjectDesc::default(), &ladder).unwrap();
        }
        p
    }

    #[test]
    fn exact_optimum_by_hand() {
        // Budget 5: A0 (4, 8) alone = 8; A1 + B0 = (1 + 3, 5 + 4) = 9 is better.
        let p = problem(&[&[(4.0, 8.0), (1.0, 5.0)], &[(3.0, 4.0), (2.0, 3.0)]]);
        let best = optimal_selection(&p, 5.0).unwrap();
        assert_relative_eq!(best.benefit, 9.0);
        assert_eq!(best.levels, vec![Some(1), Some(0)]);
        assert_relative_eq!(best.cost, 4.0);
    }

    #[test]
    fn lp_bound_by_hand() {
        // One object: hull (0,0) → (1,5) → (4,8). A level costing more than the budget can
        // never be drawn, so it is left out: budget 2.5 bounds at 5, budget 4 at 8.
        let p = problem(&[&[(4.0, 8.0), (1.0, 5.0)]]);
        assert_relative_eq!(lp_upper_bound(&p, 2.5), 5.0);
        assert_relative_eq!(lp_upper_bound(&p, 4.0), 8.0);
        assert_relative_eq!(lp_upper_bound(&p, 100.0), 8.0);
        assert_relative_eq!(lp_upper_bound(&p, 0.0), 0.0);
        // Fractions: A1 (eff 5), then A0's increment (3, 3) and B (2, 2), both eff 1:
        // budget 4.5 → 5 + 3.5.
        let p = problem(&[&[(4.0, 8.0), (1.0, 5.0)], &[(2.0, 2.0)]]);
        assert_relative_eq!(lp_upper_bound(&p, 4.5), 8.5);
    }

    #[test]
    fn lp_bound_skips_points_under_the_hull() {
        // (2, 5.5) lies under the segment (1, 5) → (3, 7): A's hull increments are 5 and
        // then 1 per second, B's 0.9. Budget 3: A's (1, 5), then (2, 2) more → 7.
        // Keeping (2, 5.5) would rank a 1.5-per-second step first and give 7.4.
        let p = problem(&[&[(3.0, 7.0), (2.0, 5.5), (1.0, 5.0)], &[(1.0, 0.9)]]);
        assert_relative_eq!(lp_upper_bound(&p, 3.0), 7.0);
    }

    #[test]
    fn hierarchy_optimum_by_hand() {
        let mut h = LodHierarchy::new();
        let a = h
            .add_object(&[Level::new(4.0, 8.0), Level::new(1.0, 3.0)])
            .unwrap();
        let b = h
            .add_object(&[Level::new(4.0, 8.0), Level::new(1.0, 3.0)])
            .unwrap();
        h.add_group(&[a, b], &[Level::new(1.0, 4.0)]).unwrap();
        assert_relative_eq!(hierarchy_optimum(&h, 0.5).unwrap(), 0.0);
        assert_relative_eq!(hierarchy_optimum(&h, 1.5).unwrap(), 4.0);
        assert_relative_eq!(hierarchy_optimum(&h, 5.0).unwrap(), 11.0);
        assert_relative_eq!(hierarchy_optimum(&h, 8.0).unwrap(), 16.0);
    }

    #[test]
    fn the_sqrt_benefit_bound_caps_ladders_on_its_curve_and_is_reached_by_dense_ones() {
        use crate::rng::SplitMix64;
        let mut rng = SplitMix64::new(7);
        for _ in 0..200 {
            let n = 1 + (rng.next_u64() % 12) as usize;
            let objects: Vec<(f32, f32)> = (0..n)
                .map(|_| {
                    let value = if rng.next_u64().is_multiple_of(7) {
                        0.0
                    } else {
                        rng.unit() * 10.0
                    };
                    let full = if rng.next_u64().is_multiple_of(9) {
                        0.0
                    } else {
                        rng.unit() * 5.0
                    };
                    (value, full)
                })
                .collect();
            let total: f32 = objects.iter().map(|o| o.1).sum();
            let budget = rng.unit() * total * 1.2;
            let bound = sqrt_benefit_bound(&objects, budget);
            // Ladders on the curve, 1024 rungs each: their LP bound is below, and close
            // unless the budget is so small that a rung's step matters (the LP bound
            // leaves out levels dearer than the whole budget).
            let mut problem = BudgetProblem::new();
            for &(value, full) in &objects {
                let ladder: Vec<Level> = (0..=1024)
                    .rev()
                    .map(|k| {
                        let cost = full * k as f32 / 1024.0;
                        Level::new(cost, sqrt_benefit(value, full, cost) as f32)
                    })
                    .collect();
                problem
                    .push_object(
                        ObjectDesc {
                            value,
                            ..Default::default()
                        },
                        &ladder,
                    )
                    .unwrap();
            }
            let sampled = lp_upper_bound(&problem, budget);
            assert!(
                sampled <= bound * (1.0 + 1e-4) + 1e-6,
                "{sampled} > {bound} ({objects:?}, {budget})"
            );
            assert!(
                budget < 0.1 * total || sampled >= bound * 0.97 - 1e-6,
                "{sampled} far below {bound} ({objects:?}, {budget})"
            );
        }
    }

    #[test]
    fn the_sqrt_benefit_bound_handles_the_edges() {
        // Everything fits: every value.
        assert!((sqrt_benefit_bound(&[(2.0, 1.0), (3.0, 1.0)], 5.0) - 5.0).abs() < 1e-9);
        // No budget: only what is free.
        assert!((sqrt_benefit_bound(&[(2.0, 1.0), (3.0, 0.0)], 0.0) - 3.0).abs() < 1e-9);
        // Two equal objects, half their total: each at half its cost, √½ of its value.
        let half = sqrt_benefit_bound(&[(1.0, 1.0), (1.0, 1.0)], 1.0);
        assert!((half - 2.0 * 0.5_f64.sqrt()).abs() < 1e-9, "{half}");
        // Bad numbers are ignored, never NaN.
        let b = sqrt_benefit_bound(
            &[(f32::NAN, 1.0), (1.0, f32::INFINITY), (1.0, -1.0)],
            f32::NAN,
        );
        assert!(b.is_finite());
        // An object whose full detail costs infinitely much gains nothing, as
        // `sqrt_benefit` says.
        assert_eq!(sqrt_benefit(1.0, f32::INFINITY, 1.0), 0.0);
        assert!(sqrt_benefit_bound(&[(1.0, f32::INFINITY)], 1.0) < 1e-9);
        assert_eq!(sqrt_benefit(1.0, 4.0, 1.0), 0.5);
        assert_eq!(sqrt_benefit(1.0, 4.0, 9.0), 1.0);
        assert_eq!(sqrt_benefit(2.0, 0.0, 0.0), 2.0);
    }
}
