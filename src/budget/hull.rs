//! The upper convex hull of a ladder's (cost, benefit) points from (0, 0): its
//! LP-undominated representations. Along it the incremental `Value`
//! (Δbenefit / Δcost) strictly falls, which is what makes the greedy knapsack
//! approximation at least half optimal and the LP relaxation solvable greedily.

/// One representation on the hull.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct HullPoint {
    /// Ladder index of the representation.
    pub level: u32,
    pub cost: f64,
    pub benefit: f64,
    /// Δbenefit / Δcost from the previous hull point (from (0, 0) for the first);
    /// +∞ for a free representation with a benefit.
    pub efficiency: f64,
    /// Cost added by stepping here from the previous hull point (from 0 for the first).
    pub delta_cost: f64,
    /// Benefit added by that step.
    pub delta_benefit: f64,
}

/// Fills `hull` with the upper convex hull of the `(level, cost, benefit)` points costing
/// at most `max_cost`, starting from (0, 0) (the "not drawn" choice, not itself
/// included). Dominated points (no cheaper for no more benefit) and points on or under
/// the hull are left out.
///
/// Points must come in ascending cost — a ladder read cheapest first — so no sort is
/// needed; among equal costs the one with the most benefit wins.
pub(crate) fn upper_hull(
    points: impl Iterator<Item = (u32, f64, f64)>,
    max_cost: f64,
    hull: &mut Vec<HullPoint>,
) {
    hull.clear();
    let origin = (0.0_f64, 0.0_f64);
    for (level, cost, benefit) in points {
        if cost > max_cost || benefit <= 0.0 {
            continue;
        }
        debug_assert!(
            hull.last().is_none_or(|h| h.cost <= cost),
            "points must ascend in cost"
        );
        let last = hull.last().map_or(origin, |h| (h.cost, h.benefit));
        if benefit <= last.1 {
            continue; // dominated
        }
        // Pop points on or under the segment from their predecessor to this point.
        while let Some(b) = hull.last() {
            let a = if hull.len() >= 2 {
                let a = hull[hull.len() - 2];
                (a.cost, a.benefit)
            } else {
                origin
            };
            let cross = (b.cost - a.0) * (benefit - a.1) - (b.benefit - a.1) * (cost - a.0);
            if cross >= 0.0 {
                hull.pop();
            } else {
                break;
            }
        }
        hull.push(HullPoint {
            level,
            cost,
            benefit,
            efficiency: 0.0,
            delta_cost: 0.0,
            delta_benefit: 0.0,
        });
    }
    let mut previous = origin;
    for p in hull.iter_mut() {
        let (dc, db) = (p.cost - previous.0, p.benefit - previous.1);
        p.efficiency = if dc > 0.0 { db / dc } else { f64::INFINITY };
        (p.delta_cost, p.delta_benefit) = (dc, db);
        previous = (p.cost, p.benefit);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hull_of(points: &[(f64, f64)], max_cost: f64) -> Vec<(u32, f64)> {
        // The hull wants ascending cost, as a ladder read cheapest first gives it.
        let mut sorted: Vec<(u32, f64, f64)> = points
            .iter()
            .enumerate()
            .map(|(i, &(c, b))| (i as u32, c, b))
            .collect();
        sorted.sort_by(|a, b| a.1.total_cmp(&b.1));
        let mut hull = Vec::new();
        upper_hull(sorted.into_iter(), max_cost, &mut hull);
        hull.iter().map(|p| (p.level, p.efficiency)).collect()
    }

    #[test]
    fn keeps_only_the_concave_frontier() {
        // (1, 5) at 5 per second; (2, 6) lies under the segment (1, 5) → (4, 12), dropped.
        let h = hull_of(&[(4.0, 12.0), (2.0, 6.0), (1.0, 5.0)], 10.0);
        assert_eq!(h, vec![(2, 5.0), (0, 7.0 / 3.0)]);
    }

    #[test]
    fn drops_dominated_and_unaffordable_points() {
        let h = hull_of(&[(5.0, 4.0), (3.0, 4.0), (1.0, 2.0)], 4.0);
        assert_eq!(h, vec![(2, 2.0), (1, 1.0)]);
        let h = hull_of(&[(5.0, 4.0)], 4.0);
        assert!(h.is_empty());
    }

    #[test]
    fn free_points_are_infinitely_efficient() {
        let h = hull_of(&[(2.0, 3.0), (0.0, 1.0)], 10.0);
        assert_eq!(h, vec![(1, f64::INFINITY), (0, 1.0)]);
    }

    #[test]
    fn efficiencies_fall_along_the_hull() {
        let pts = [
            (9.0, 10.0),
            (6.0, 9.0),
            (4.0, 8.5),
            (3.0, 6.0),
            (1.0, 3.0),
            (0.5, 0.1),
        ];
        let h = hull_of(&pts, 100.0);
        assert!(h.windows(2).all(|w| w[0].1 > w[1].1), "{h:?}");
    }
}
