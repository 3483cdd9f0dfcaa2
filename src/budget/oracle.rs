//! Reference answers for the budget strategies: the exact optimum of small
//! multiple-choice knapsack instances, and the LP-relaxation upper bound for any size,
//! so a strategy's benefit can be reported as a percentage of the bound.
//!
//! The exact optimum is a dynamic programme over Pareto frontiers (cost, benefit) — exact
//! for real-valued costs, with no discretisation — whose frontier size is capped.

use super::hierarchical::{LodHierarchy, NodeId};
use super::hull::upper_hull;
use super::problem::{BudgetProblem, sanitize_time};

/// Frontier points the exact solvers may hold at once before giving up.
pub const MAX_FRONTIER: usize = 1 << 20;

/// Why an exact optimum was not computed.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum OracleError {
    /// The instance is too large for the exact dynamic programme.
    #[error(
        "instance too large for the exact optimum: the Pareto frontier exceeded {MAX_FRONTIER} points"
    )]
    TooLarge,
}

/// An optimal selection: one ladder index or `None` (not drawn) per object.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct OptimalSelection {
    /// The optimal total benefit.
    pub benefit: f64,
    /// Its cost.
    pub cost: f64,
    /// The chosen level per object.
    pub levels: Vec<Option<u32>>,
}

#[derive(Clone, Copy, Debug)]
struct Point {
    cost: f64,
    benefit: f64,
    /// Index of the point it extends in the previous stage's frontier.
    from: u32,
    /// Option taken at this stage: `u32::MAX` for not drawn.
    option: u32,
}

/// Keeps only points not dominated by a cheaper point with at least the same benefit.
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
pub fn optimal_selection(
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
pub fn lp_upper_bound(problem: &BudgetProblem, budget: f32) -> f64 {
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

/// The best benefit over the complete representations of `hierarchy` (every leaf covered
/// by exactly one impostor of itself or of an ancestor) within `budget`, or nothing at all
/// — the constrained problem the hierarchical strategy approximates.
pub fn hierarchy_optimum(hierarchy: &LodHierarchy, budget: f32) -> Result<f64, OracleError> {
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

/// A strategy's benefit as a percentage of the LP bound (100 when the bound is 0).
pub fn percent_of_bound(benefit: f64, bound: f64) -> f64 {
    if bound > 0.0 {
        100.0 * benefit / bound
    } else {
        100.0
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
}
