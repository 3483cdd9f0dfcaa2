//! A tree's crown as one disc: where its leaves' silhouette lies, how much of the view it
//! fills, and how a disc standing for it is lit. The disc is the cheapest drawing of a far
//! tree's leaves (TCLOD's floor for a tree chosen as a whole): one point instead of one per
//! leaf group, which on a renderer where every point has a fixed cost is what lets a
//! crowded view keep every visible tree covered and still have time for the near ones.

use core::f32::consts::PI;

use bevy::math::{Vec2, Vec3};
use serde::{Deserialize, Serialize};

use super::model::TreeModel;

/// The leaves of a tree seen as one disc: where their silhouette lies, how much of the view
/// it fills, and how a disc standing for it is lit. TCLOD draws it (one point) for a far
/// tree short of the time for a point per leaf group.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Crown {
    /// Centre of the leaves' silhouette, model space.
    pub center: Vec3,
    /// Area of the leaves' silhouette seen from the side, averaged over four headings
    /// (model units², unscaled): a disc of this area at `center` covers about as many
    /// pixels as the leaves do.
    pub area: f32,
    /// The normal the disc is lit with: the leaves' normals turned to face up, averaged
    /// by area.
    pub normal: Vec3,
    /// The ring whose wind offset moves the disc: that of the leaf group nearest the
    /// centre.
    pub ring: u32,
}

/// Cells across the longer side of a silhouette's box: finer than the largest disc a
/// crown is drawn as is wide in pixels, so that the area is what a rasteriser would
/// cover.
const GRID: usize = 96;

/// The side views the silhouette is averaged over: headings spread evenly over half a
/// turn (a view and its opposite see the same silhouette).
const HEADINGS: usize = 4;

/// The crown of `model`'s leaves, or `None` when it has none with area.
pub(crate) fn crown_of(model: &TreeModel) -> Option<Crown> {
    let positions = &model.leaf_positions;
    let triangles: Vec<[Vec3; 3]> = model
        .leaf_indices
        .chunks_exact(3)
        .filter_map(|t| {
            let corner = |i: u32| positions.get(i as usize).copied();
            Some([corner(t[0])?, corner(t[1])?, corner(t[2])?])
        })
        .collect();
    let (mut area, mut along_sum, mut height) = (0.0, Vec2::ZERO, 0.0);
    for k in 0..HEADINGS {
        let heading = k as f32 * PI / HEADINGS as f32;
        // The view's horizontal axis; its vertical one is +Y.
        let across = Vec3::new(heading.cos(), 0.0, -heading.sin());
        let (covered, centroid) = silhouette(&triangles, |p| Vec2::new(p.dot(across), p.y))?;
        area += covered;
        // Each view knows the centre along its axis: a least-squares fit of the
        // horizontal centre to all of them (the headings' normal equations are diagonal).
        along_sum += Vec2::new(across.x, across.z) * centroid.x;
        height += centroid.y;
    }
    let area = area / HEADINGS as f32;
    if !(area.is_finite() && area > 0.0) {
        return None;
    }
    let horizontal = along_sum * (2.0 / HEADINGS as f32);
    let center = Vec3::new(horizontal.x, height / HEADINGS as f32, horizontal.y);
    let normal = triangles
        .iter()
        .map(|[a, b, c]| {
            // Twice the area, along the normal.
            let n = (*b - *a).cross(*c - *a);
            if n.y < 0.0 { -n } else { n }
        })
        .sum::<Vec3>()
        .try_normalize()
        .unwrap_or(Vec3::Y);
    let ring = model
        .leaf_groups
        .iter()
        .min_by(|a, b| {
            a.bounds
                .center
                .distance_squared(center)
                .total_cmp(&b.bounds.center.distance_squared(center))
        })
        .map(|g| g.ring)?;
    Some(Crown {
        center,
        area,
        normal,
        ring,
    })
}

/// The area the triangles cover in the plane `project` maps them to (each point
/// counted once, however many triangles cover it), sampled at cell centres on a grid,
/// and the centroid of what they cover; `None` when they cover nothing.
fn silhouette(triangles: &[[Vec3; 3]], project: impl Fn(Vec3) -> Vec2) -> Option<(f32, Vec2)> {
    let flat: Vec<[Vec2; 3]> = triangles.iter().map(|t| t.map(&project)).collect();
    let (min, max) = flat.iter().flatten().fold(
        (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY)),
        |(lo, hi), p| (lo.min(*p), hi.max(*p)),
    );
    let extent = (max - min).max_element();
    if !(extent.is_finite() && extent > 0.0) {
        return None;
    }
    let cell = extent / GRID as f32;
    let columns = (((max.x - min.x) / cell) as usize + 1).min(GRID + 1);
    let rows = (((max.y - min.y) / cell) as usize + 1).min(GRID + 1);
    let mut covered = vec![false; columns * rows];
    let cell_of =
        |v: f32, lo: f32, count: usize| (((v - lo) / cell).max(0.0) as usize).min(count - 1);
    for t in &flat {
        let (lo, hi) = (t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2]));
        for row in cell_of(lo.y, min.y, rows)..=cell_of(hi.y, min.y, rows) {
            for column in cell_of(lo.x, min.x, columns)..=cell_of(hi.x, min.x, columns) {
                let centre = min + (Vec2::new(column as f32, row as f32) + 0.5) * cell;
                if inside(t, centre) {
                    covered[row * columns + column] = true;
                }
            }
        }
    }
    let (count, sum) = covered.iter().enumerate().filter(|(_, c)| **c).fold(
        (0usize, Vec2::ZERO),
        |(n, s), (i, _)| {
            let at = Vec2::new((i % columns) as f32, (i / columns) as f32);
            (n + 1, s + at)
        },
    );
    if count == 0 {
        return None;
    }
    let centroid = min + (sum / count as f32 + 0.5) * cell;
    Some((count as f32 * cell * cell, centroid))
}

/// Whether `p` lies in triangle `t` (either winding, edges included).
fn inside(t: &[Vec2; 3], p: Vec2) -> bool {
    let side = |a: Vec2, b: Vec2| (b - a).perp_dot(p - a);
    let (d0, d1, d2) = (side(t[0], t[1]), side(t[1], t[2]), side(t[2], t[0]));
    (d0 >= 0.0 && d1 >= 0.0 && d2 >= 0.0) || (d0 <= 0.0 && d1 <= 0.0 && d2 <= 0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(center: Vec2, side: f32) -> [[Vec3; 3]; 2] {
        let h = side / 2.0;
        let c = |x: f32, y: f32| Vec3::new(center.x + x, center.y + y, 0.0);
        [
            [c(-h, -h), c(h, -h), c(h, h)],
            [c(-h, -h), c(h, h), c(-h, h)],
        ]
    }

    #[test]
    fn a_silhouette_counts_each_point_once_and_finds_its_centre() {
        // Two overlapping unit squares (1.5 together, centred at (0.25, 0)) and a far one.
        let mut triangles = Vec::new();
        triangles.extend(square(Vec2::new(0.0, 0.0), 1.0));
        triangles.extend(square(Vec2::new(0.5, 0.0), 1.0));
        triangles.extend(square(Vec2::new(8.0, 3.0), 1.0));
        let (area, centroid) = silhouette(&triangles, Vec3::truncate).unwrap();
        // (Sampled at cell centres, 96 cells across 9 units: an edge may gain or lose a
        // row of cells.)
        assert!((area - 2.5).abs() < 0.15, "area {area}");
        let expected = (Vec2::new(0.25, 0.0) * 1.5 + Vec2::new(8.0, 3.0)) / 2.5;
        assert!(centroid.distance(expected) < 0.1, "centre {centroid}");
    }

    #[test]
    fn nothing_with_area_has_no_silhouette() {
        let line = [[Vec3::ZERO, Vec3::X, Vec3::X * 2.0]];
        assert!(silhouette(&line, Vec3::truncate).is_none());
        assert!(silhouette(&[], Vec3::truncate).is_none());
    }
}
