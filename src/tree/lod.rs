//! The thesis' points-and-lines level of detail without a budget (§4.4): thin trunk
//! segments become screen-space lines of several widths, leaves become points, both
//! chosen by their projected size. The time-critical searches build on the same pieces.

use core::ops::Range;

#[cfg(test)]
use super::model::TreeModel;

/// How the view projects: pixels covered by one world unit at unit depth.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Projection {
    /// `viewport height / (2·tan(vertical fov / 2))`, in pixels.
    pub focal_pixels: f32,
}

impl Projection {
    /// The projection of a perspective camera with vertical field of view `fov` (radians)
    /// on a viewport `height` pixels tall.
    #[cfg(any(test, feature = "testing"))]
    pub(crate) fn perspective(fov: f32, height: f32) -> Self {
        Self {
            focal_pixels: height / (2.0 * (fov * 0.5).tan()).max(1e-6),
        }
    }

    /// Pixels covered by `length` world units at `depth`.
    pub(crate) fn pixels(&self, length: f32, depth: f32) -> f32 {
        length * self.focal_pixels / depth.max(1e-3)
    }
}

/// The range of integer line widths or point sizes, in pixels.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize, bevy::reflect::Reflect,
)]
pub struct PixelRange {
    /// Thinnest or smallest.
    pub min: u32,
    /// Widest or largest.
    pub max: u32,
}

impl Default for PixelRange {
    fn default() -> Self {
        Self { min: 1, max: 20 }
    }
}

impl PixelRange {
    /// The widest line or largest point the LOD uses: larger settings are taken as this.
    pub(crate) const LARGEST: u32 = 64;

    /// The range as the LOD uses it: `min` at least 1, `max` at least `min`, both at most
    /// [`PixelRange::LARGEST`] (a range a user typed as `max: 0` or `min: u32::MAX`
    /// still means something, and no loop over widths runs for billions of steps).
    pub(crate) fn sanitized(self) -> Self {
        let min = self.min.clamp(1, Self::LARGEST);
        Self {
            min,
            max: self.max.clamp(min, Self::LARGEST),
        }
    }
}

/// What one trunk draws: segment ranges (in the model's thin → thick order).
#[derive(Clone, Debug, PartialEq, Eq, Default)]
#[cfg(test)]
pub(crate) struct TrunkLod {
    /// Segments too thin to see (below half a pixel of the thinnest width).
    pub dropped: Range<u32>,
    /// `(width in pixels, segments)` drawn as lines, thin → thick.
    pub lines: Vec<(u32, Range<u32>)>,
    /// Segments drawn as triangles (the thickest).
    pub triangles: Range<u32>,
}

/// Static trunk LOD for an instance of `scale` at `depth` (thesis §4.4.1): a segment is
/// drawn as a line of width `w` when its projected diameter lies in `[w − ½, w + ½)`
/// pixels; thinner than the thinnest width's range it is dropped; thicker than the
/// widest width's it is drawn as triangles.
#[cfg(test)]
pub(crate) fn trunk_lod(
    model: &TreeModel,
    scale: f32,
    depth: f32,
    projection: &Projection,
    widths: PixelRange,
) -> TrunkLod {
    let diameters = model.segments.diameters();
    let mut lines = Vec::new();
    let (drawn, thick) = trunk_line_runs(
        diameters,
        projection.pixels(scale, depth),
        widths,
        |width, segments| lines.push((width, segments)),
    );
    TrunkLod {
        dropped: 0..drawn,
        lines,
        triangles: thick..diameters.len() as u32,
    }
}

/// The core of [`trunk_lod`] for segments of `diameters` (thin → thick) projecting
/// `pixels_per_unit` pixels per model unit: each line run is handed to `line` as
/// `(width, segments)`, thin → thick, and the result is `(first segment drawn, first
/// segment drawn as triangles)`. Allocates nothing, so that the time-critical searches
/// can write the runs straight into a draw list.
pub(crate) fn trunk_line_runs(
    diameters: &[f32],
    pixels_per_unit: f32,
    widths: PixelRange,
    mut line: impl FnMut(u32, Range<u32>),
) -> (u32, u32) {
    let n = diameters.len() as u32;
    let projected = |d: f32| d * pixels_per_unit;
    // Segments are stored thin → thick, so where the projected diameters reach a bound is
    // a search. A tree seen from afar shows only its thickest few segments, so it gallops
    // in from the thick end: O(log k) for the k segments past the bound, and a far tree's
    // trunk is decided in O(widths · log k).
    let reaching = |from: u32, bound: f32| {
        let below = |d: &f32| projected(*d) < bound;
        let rest = &diameters[from as usize..];
        // Every segment from `hi` on reaches the bound.
        let (mut hi, mut step) = (rest.len(), 1);
        let lo = loop {
            if step > hi {
                break 0;
            }
            let probe = hi - step;
            if below(&rest[probe]) {
                break probe + 1;
            }
            hi = probe;
            step *= 2;
        };
        from + (lo + rest[lo..hi].partition_point(below)) as u32
    };
    let PixelRange { min, max } = widths.sanitized();
    if n == 0 || projected(diameters[0]) >= max as f32 + 0.5 {
        return (0, 0);
    }
    if projected(diameters[n as usize - 1]) < min as f32 - 0.5 {
        // Even the thickest is too thin to see: most trees of a large forest.
        return (n, n);
    }
    let drawn = reaching(0, min as f32 - 0.5);
    let mut s = drawn;
    for w in min..=max {
        let start = s;
        s = reaching(s, w as f32 + 0.5);
        if s > start {
            line(w, start..s);
        }
        if s == n {
            break;
        }
    }
    (drawn, s)
}

/// What one leaf group draws.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg(test)]
pub(crate) struct GroupLod {
    /// Leaves drawn as points.
    pub points: u32,
    /// Whether the points are the group's far leaves (`true`) or its near ones.
    pub points_from_far_end: bool,
    /// Leaves drawn as triangles (the rest of the group).
    pub triangle_leaves: u32,
}

/// Static leaf LOD for group `group` of an instance of `scale` at the group's `depth`
/// (thesis §4.4.2): the group projects `a_g = n·a_h·s² / (1.8·z²)` (T-4.4; half the leaves
/// assumed to face the camera), a point of `point_size` pixels covers `point_size²`, and
/// `n_p = a_g / a_p` points are drawn from the far end when fewer than the `n` leaves;
/// between `n` and `2n`, `2n − n_p` near points and the rest as triangles (T-4.6);
/// beyond, every leaf as triangles.
#[cfg(test)]
pub(crate) fn group_lod(
    model: &TreeModel,
    group: usize,
    scale: f32,
    depth: f32,
    projection: &Projection,
    point_size: u32,
) -> GroupLod {
    let n = model.leaf_groups[group].leaves.len() as f32;
    let leaf_area = model.mean_leaf_triangle_area * model.leaf_triangle_count() as f32
        / model.leaves.len().max(1) as f32;
    let pixels_per_unit = projection.pixels(1.0, depth);
    let projected = n * leaf_area * scale * scale * pixels_per_unit * pixels_per_unit / 1.8;
    let point_area = (point_size.max(1) as f32).powi(2);
    let wanted = (projected / point_area).max(1.0);
    let total = n as u32;
    if wanted < n {
        GroupLod {
            points: (wanted.round() as u32).clamp(1, total),
            points_from_far_end: true,
            triangle_leaves: 0,
        }
    } else if wanted < 2.0 * n {
        let points = ((2.0 * n - wanted).round() as u32).min(total);
        GroupLod {
            points,
            points_from_far_end: false,
            triangle_leaves: total - points,
        }
    } else {
        GroupLod {
            points: 0,
            points_from_far_end: true,
            triangle_leaves: total,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tree::grand_model as model;

    const PROJECTION: Projection = Projection {
        focal_pixels: 600.0,
    };

    fn covers_every_segment(lod: &TrunkLod, n: u32) {
        let mut next = lod.dropped.end;
        assert_eq!(lod.dropped.start, 0);
        for (_, r) in &lod.lines {
            assert_eq!(r.start, next);
            next = r.end;
        }
        assert_eq!(lod.triangles, next..n);
    }

    #[test]
    fn near_trees_are_triangles_far_trees_lines_and_widths_follow_diameter() {
        let m = model();
        let n = m.segments.len() as u32;
        // Close enough that even the thinnest segment projects 25 px (> 20 + ½).
        let near_depth = m.segments.diameter[0] * PROJECTION.focal_pixels / 25.0;
        let near = trunk_lod(&m, 1.0, near_depth, &PROJECTION, PixelRange::default());
        assert_eq!(near.triangles, 0..n);
        assert!(near.lines.is_empty());
        // The trunk's base projects ~35 px (triangles) while twigs project ~1 px (lines).
        let middle = trunk_lod(&m, 1.0, 12.0, &PROJECTION, PixelRange::default());
        covers_every_segment(&middle, n);
        assert!(!middle.lines.is_empty() && !middle.triangles.is_empty());
        assert!(
            middle.lines.windows(2).all(|w| w[0].0 < w[1].0),
            "widths rise thin → thick"
        );
        // Each line's width matches its segments' projected diameters within ½ pixel.
        for (w, r) in &middle.lines {
            for s in r.clone() {
                let px = PROJECTION.pixels(m.segments.diameter[s as usize], 12.0);
                assert!(
                    (px - *w as f32).abs() <= 0.5 + 1e-4,
                    "segment {s}: {px} px as width {w}"
                );
            }
        }
        let far = trunk_lod(&m, 1.0, 5_000.0, &PROJECTION, PixelRange::default());
        covers_every_segment(&far, n);
        assert!(far.triangles.is_empty() && far.dropped.len() > middle.dropped.len());
        // At any depth and scale, every segment is where its own projected diameter says
        // (a sweep of depths, so that every boundary falls at many distances from the
        // thick end the search starts from).
        let widths = PixelRange { min: 2, max: 6 };
        let sweep = (0..400).map(|i| (0.7 + 0.6 * (i % 7) as f32 / 6.0, 1.03f32.powi(i)));
        for (scale, depth) in [
            (1.0, 2.0),
            (1.0, 12.0),
            (0.7, 40.0),
            (1.3, 300.0),
            (1.0, 5e4),
        ]
        .into_iter()
        .chain(sweep)
        {
            let lod = trunk_lod(&m, scale, depth, &PROJECTION, widths);
            covers_every_segment(&lod, n);
            let px = |s: u32| PROJECTION.pixels(m.segments.diameter[s as usize] * scale, depth);
            assert!(lod.dropped.clone().all(|s| px(s) < 1.5), "at {depth}");
            assert!(lod.triangles.clone().all(|s| px(s) >= 6.5), "at {depth}");
            for (w, r) in &lod.lines {
                let (low, high) = (*w as f32 - 0.5, *w as f32 + 0.5);
                assert!(
                    r.clone().all(|s| (low..high).contains(&px(s))),
                    "at {depth}"
                );
            }
        }
    }

    #[test]
    fn leaf_groups_go_from_triangles_to_mixed_to_points_with_distance() {
        let m = model();
        let g = (0..m.leaf_groups.len())
            .max_by_key(|&g| m.leaf_groups[g].leaves.len())
            .unwrap();
        let n = m.leaf_groups[g].leaves.len() as u32;
        let mut seen_mixed = false;
        for depth in [1.0, 10.0, 20.0, 40.0, 80.0, 200.0, 1000.0] {
            let lod = group_lod(&m, g, 1.0, depth, &PROJECTION, 2);
            if lod.points_from_far_end {
                assert_eq!(
                    lod.triangle_leaves + lod.points,
                    if lod.points == 0 { n } else { lod.points }
                );
            } else {
                seen_mixed = true;
                assert_eq!(lod.points + lod.triangle_leaves, n);
            }
            assert!(lod.points <= n && lod.points >= 1 || lod.triangle_leaves == n);
        }
        assert!(seen_mixed, "some depth mixes near points with triangles");
        assert_eq!(
            group_lod(&m, g, 1.0, 0.5, &PROJECTION, 2).triangle_leaves,
            n
        );
        assert_eq!(group_lod(&m, g, 1.0, 1e5, &PROJECTION, 2).points, 1);
    }
}
