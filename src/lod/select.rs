//! Per-object representation searches (pure): given the time an object was handed, the
//! best representation of a trunk or of a tree's leaves that fits, written into a
//! [`TreeDrawList`].
//!
//! * **TC** (thesis §6.4): triangles only — the trunk from its thickest segment down,
//!   each leaf group from its far leaves in.
//! * **TCLOD** (thesis §6.5): the trunk's thin segments as lines of several widths and
//!   leaves as points of several sizes, with as many triangles as the time allows.
//! * **Static** (thesis §4.4): the pixel-driven points-and-lines LOD, no time involved.
//!
//! Every search runs in time independent of the number of segments or leaves (a few
//! binary searches over the model's prefix arrays), so a frame's selection costs
//! O(visible trees × visible leaf groups).
//!
//! Counts are rounded down (or to nearest) by `as` casts of non-negative values rather
//! than `floor`/`round`, which on the baseline x86-64 target are library calls, and these
//! run hundreds of thousands of times a frame in a large forest.

use core::ops::Range;

pub(crate) use crate::cost::PrimitiveCosts;
use crate::draw::{LineRun, MAX_PRIMITIVE_PIXELS, PointRun, TreeDrawList};
use crate::tree::{PixelRange, Projection, TreeModel};

/// Mean ratio of a segment's projected length to its length: trunks and branches are
/// seen from the side more often than end-on.
pub(crate) const PROJECTED_LENGTH_FACTOR: f32 = 0.8;

/// A leaf group's projected area over `n · a_h · s² / z²`: half the leaves face the
/// camera (thesis T-4.4).
const LEAF_FACING: f32 = 1.0 / 1.8;

/// How one tree instance is seen this frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct TreeView {
    /// Uniform instance scale.
    pub scale: f32,
    /// Depth of the trunk's area-density centre.
    pub trunk_depth: f32,
    /// The camera's projection.
    pub projection: Projection,
}

/// What a search drew: its predicted time, and whether even the cheapest representation
/// overran the time it had.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Selected {
    /// Predicted rendering time, seconds.
    pub cost: f32,
    /// The part of `cost` spent on lines (the rest on triangles and points).
    pub lines: f32,
    /// The part of `cost` spent on points.
    pub points: f32,
    /// The part of `cost` spent on meshes drawn by Bevy's own path (a ladder level), per
    /// draw and per triangle.
    pub meshes: f32,
    /// The part of `cost` spent on those meshes' covered pixels.
    pub mesh_pixels: f32,
    /// The time was below the cheapest representation, which is drawn anyway.
    pub truncated: bool,
    /// Full detail is drawn: every triangle of the object (of its visible leaf groups),
    /// no line, no point. More time would change nothing.
    pub full: bool,
}

impl Selected {
    /// Two parts drawn together (a tree's trunk and leaves).
    pub(crate) fn both(a: Self, b: Self) -> Self {
        Self {
            cost: a.cost + b.cost,
            lines: a.lines + b.lines,
            points: a.points + b.points,
            meshes: a.meshes + b.meshes,
            mesh_pixels: a.mesh_pixels + b.mesh_pixels,
            truncated: a.truncated || b.truncated,
            full: a.full && b.full,
        }
    }
}

fn pixels_per_unit(view: &TreeView, depth: f32) -> f32 {
    view.projection.pixels(view.scale, depth)
}

/// Trunk triangles `first..total` of a trunk whose triangles project `area` pixels each.
fn trunk_triangle_cost(
    model: &TreeModel,
    costs: &PrimitiveCosts,
    from_segment: u32,
    area: f32,
) -> f32 {
    let offsets = &model.segments.triangle_offsets;
    let total = offsets.last().copied().unwrap_or(0);
    let first = offsets.get(from_segment as usize).copied().unwrap_or(total);
    costs.triangles(total - first, area)
}

/// Length of segments `range` (world units, unscaled).
fn segment_length(model: &TreeModel, range: &Range<u32>) -> f32 {
    let cumulative = &model.segments.cumulative_length;
    if range.is_empty() {
        return 0.0;
    }
    let upto = |s: u32| {
        if s == 0 {
            0.0
        } else {
            cumulative[s as usize - 1]
        }
    };
    upto(range.end) - upto(range.start)
}

/// The trunk as triangles only, the thickest `count` segments' worth: triangle range.
fn thick_end(model: &TreeModel, from_segment: u32) -> Range<u32> {
    let offsets = &model.segments.triangle_offsets;
    let total = offsets.last().copied().unwrap_or(0);
    offsets.get(from_segment as usize).copied().unwrap_or(total)..total
}

/// TC trunk: as many triangles as `time` pays for, from the thickest segment down; at
/// least the thickest segment (truncated when even that does not fit).
pub(crate) fn trunk_tc(
    model: &TreeModel,
    view: &TreeView,
    costs: &PrimitiveCosts,
    time: f32,
    out: &mut TreeDrawList,
) -> Selected {
    out.trunk_lines.clear();
    let total = model.trunk_triangle_count() as u32;
    let area = trunk_cost_area(model, pixels_per_unit(view, view.trunk_depth), costs);
    let each = costs.triangles(1, area);
    // (Full detail tested first: a division can land a hair below the whole count.)
    let affordable = if each > 0.0 && costs.triangles(total, area) > time {
        (time.max(0.0) / each).min(total as f32) as u32
    } else {
        total
    };
    // The thickest segment that owns triangles is the minimum.
    let minimum = thickest_triangles(model);
    let count = affordable.max(minimum);
    out.trunk_triangles = total - count..total;
    Selected {
        cost: costs.triangles(count, area),
        truncated: affordable < minimum,
        full: count == total,
        ..Selected::default()
    }
}

/// Projected area in pixels of one trunk triangle of this instance.
#[cfg(any(test, feature = "render"))]
pub(crate) fn trunk_triangle_area(model: &TreeModel, view: &TreeView) -> f32 {
    let p = pixels_per_unit(view, view.trunk_depth);
    model.mean_trunk_triangle_area * p * p
}

/// The area one trunk triangle is charged for when the trunk projects `px` pixels per
/// model unit: its projected area, with the whole trunk covering at most
/// `costs.max_pixels`, so that the cost stays linear in the count.
fn trunk_cost_area(model: &TreeModel, px: f32, costs: &PrimitiveCosts) -> f32 {
    let total = model.trunk_triangle_count().max(1) as f32;
    let area = model.mean_trunk_triangle_area * px * px;
    // (Compared before dividing: the cap only binds for trees seen from close.)
    if area * total > costs.max_pixels {
        costs.max_pixels / total
    } else {
        area
    }
}

/// The static LOD's line runs (thesis §4.4.1) for a trunk projecting `px` pixels per
/// model unit, written into `out.trunk_lines`: `(first segment drawn, first segment drawn
/// as triangles)`.
fn static_lines(
    model: &TreeModel,
    px: f32,
    widths: PixelRange,
    out: &mut TreeDrawList,
) -> (u32, u32) {
    out.trunk_lines.clear();
    crate::tree::trunk_line_runs(model.segments.diameters(), px, widths, |width, segments| {
        out.trunk_lines.push(LineRun { segments, width });
    })
}

/// Cost of segments `dropped..k` drawn as the line `runs` assign them, for a trunk
/// projecting `px` pixels per model unit.
fn lines_cost(
    runs: &[LineRun],
    dropped: u32,
    model: &TreeModel,
    costs: &PrimitiveCosts,
    px: f32,
    k: u32,
) -> f32 {
    let mut cost = 0.0;
    for run in runs {
        let r = run.segments.start.max(dropped)..run.segments.end.min(k);
        if r.is_empty() {
            continue;
        }
        let length = segment_length(model, &r) * px * PROJECTED_LENGTH_FACTOR;
        cost += costs.lines(run.width, r.end - r.start, length);
    }
    cost
}

/// Keeps of the line `runs` segments `dropped..k`.
fn clip_lines(runs: &mut Vec<LineRun>, dropped: u32, k: u32) {
    runs.retain_mut(|run| {
        run.segments = run.segments.start.max(dropped)..run.segments.end.min(k);
        !run.segments.is_empty()
    });
}

/// Static trunk (thesis §4.4.1): the pixel-driven lines of several widths for the thin
/// segments and triangles for the rest, whatever the time.
pub(crate) fn trunk_static(
    model: &TreeModel,
    view: &TreeView,
    costs: &PrimitiveCosts,
    widths: PixelRange,
    out: &mut TreeDrawList,
) -> Selected {
    let px = pixels_per_unit(view, view.trunk_depth);
    let (drawn, k) = static_lines(model, px, widths, out);
    out.trunk_triangles = thick_end(model, k);
    let area = trunk_cost_area(model, px, costs);
    let lines = lines_cost(&out.trunk_lines, drawn, model, costs, px, k);
    Selected {
        cost: lines + trunk_triangle_cost(model, costs, k, area),
        lines,
        ..Selected::default()
    }
}

/// TCLOD trunk (thesis §6.5): the static LOD's lines of several widths for the thin
/// segments and triangles for the rest. With time to spare, line segments go back to
/// triangles, thickest first, as many as fit (the integer solution of T-6.21..6.24);
/// short of time, the thinnest lines are removed until it fits, and if the triangles
/// alone are too dear the trunk is drawn as in TC from the thick end. A trunk too thick
/// for the widest line (seen from close) is drawn as in TC.
pub(crate) fn trunk_tclod(
    model: &TreeModel,
    view: &TreeView,
    costs: &PrimitiveCosts,
    widths: PixelRange,
    time: f32,
    out: &mut TreeDrawList,
) -> Selected {
    let n = model.segments.len() as u32;
    let px = pixels_per_unit(view, view.trunk_depth);
    let time = time.max(0.0);
    let area = trunk_cost_area(model, px, costs);
    // Full detail whenever the time pays for it: the search only runs below (thesis §6.5).
    // A trunk too thin to see (most trees of a large forest) tries it only once its
    // thickest segment's triangles fit, which full detail includes.
    let full = |out: &mut TreeDrawList| {
        let cost = trunk_triangle_cost(model, costs, 0, area);
        (cost <= time).then(|| {
            out.trunk_lines.clear();
            out.trunk_triangles = thick_end(model, 0);
            Selected {
                cost,
                full: true,
                ..Selected::default()
            }
        })
    };
    let (drawn, static_k) = static_lines(model, px, widths, out);
    if static_k == 0 {
        // Too thick for the widest line (or no segments).
        return trunk_tc(model, view, costs, time, out);
    }
    if drawn == n {
        // Everything below half a pixel (most trees of a large forest): the thickest
        // segment stays, as the thinnest line, or as triangles when both fit — what the
        // searches below would choose for a single line.
        let thickest = n - 1..n;
        let width = widths.sanitized().min;
        let line = costs.lines(
            width,
            1,
            segment_length(model, &thickest) * px * PROJECTED_LENGTH_FACTOR,
        );
        let thick = trunk_triangle_cost(model, costs, n - 1, area);
        let thick_triangles = thick_end(model, n - 1);
        // (A segment joined to its parent by proximity owns no triangles: it stays a line.)
        return if !thick_triangles.is_empty() && line <= time && thick <= time {
            if let Some(full) = full(out) {
                return full;
            }
            out.trunk_triangles = thick_triangles;
            Selected {
                cost: thick,
                ..Selected::default()
            }
        } else {
            out.trunk_lines.push(LineRun {
                segments: thickest,
                width,
            });
            out.trunk_triangles = thick_end(model, n);
            Selected {
                cost: line,
                lines: line,
                truncated: line > time,
                ..Selected::default()
            }
        };
    }
    let triangles = |k: u32| trunk_triangle_cost(model, costs, k, area);
    // Lines are cheaper than the triangles they replace and removing lines is cheaper
    // still, so each cost below is monotone in its variable: binary searches find the
    // extreme that fits.
    let cost_of = |runs: &[LineRun], dropped: u32, k: u32| {
        lines_cost(runs, dropped, model, costs, px, k) + triangles(k)
    };
    // (Lines covering a screenful each can cost more than the whole trunk's triangles,
    // which cover it once: full detail is tried whatever the lines cost.)
    if let Some(full) = full(out) {
        return full;
    }
    let static_fits = cost_of(&out.trunk_lines, drawn, static_k) <= time;
    let runs = &out.trunk_lines;
    let cost = |dropped: u32, k: u32| cost_of(runs, dropped, k);
    let smallest = |mut lo: u32, mut hi: u32, fits: &dyn Fn(u32) -> bool| {
        while lo < hi {
            let mid = lo + (hi - lo) / 2;
            if fits(mid) {
                hi = mid;
            } else {
                lo = mid + 1;
            }
        }
        lo
    };
    let (dropped, k) = if static_fits {
        // The most triangles: the smallest first-triangle segment that fits.
        (
            drawn,
            smallest(drawn, static_k, &|k| cost(drawn, k) <= time),
        )
    } else if triangles(static_k) <= time {
        // Fewer lines: drop the thinnest until it fits. A trunk all of lines keeps at
        // least its thickest one (drawn truncated when even that does not fit).
        let last = if static_k == n { n - 1 } else { static_k };
        (
            smallest(drawn, last, &|d| cost(d, static_k) <= time),
            static_k,
        )
    } else {
        return trunk_tc(model, view, costs, time, out);
    };
    let lines = lines_cost(runs, dropped, model, costs, px, k);
    let used = lines + triangles(k);
    clip_lines(&mut out.trunk_lines, dropped, k);
    out.trunk_triangles = thick_end(model, k);
    Selected {
        cost: used,
        lines,
        truncated: used > time,
        ..Selected::default()
    }
}

/// The thickest segment that owns triangles: how many triangles it has (the trunk's
/// cheapest drawing as triangles).
fn thickest_triangles(model: &TreeModel) -> u32 {
    let total = model.trunk_triangle_count() as u32;
    model
        .segments
        .triangle_offsets
        .windows(2)
        .rev()
        .map(|w| w[1] - w[0])
        .find(|&n| n > 0)
        .unwrap_or(0)
        .min(total)
}

/// A ladder entity moves to a better level only when that level costs at most this
/// fraction of its time, and keeps the level it shows while that still fits: between the
/// two, frame-to-frame changes of its share do not flip it back and forth.
pub(crate) const LADDER_UPGRADE_FRACTION: f32 = 0.85;

/// The level of a LOD ladder (`triangles`: each level's count, best first; `pixels`: what
/// the entity covers on screen, at every level) chosen with `time` seconds, when it shows
/// `shown`: the best level costing at most [`LADDER_UPGRADE_FRACTION`] of the time if that
/// is better than `shown`, else `shown` if it fits, else the best that fits, else the
/// cheapest (nothing visible is dropped); with its cost on Bevy's mesh path. A ladder
/// without levels costs nothing.
pub(crate) fn ladder_level(
    costs: &PrimitiveCosts,
    triangles: &[u32],
    pixels: f32,
    time: f32,
    shown: Option<u32>,
) -> (u32, Selected) {
    let Some(last) = triangles.len().checked_sub(1) else {
        return (0, Selected::default());
    };
    let fragments = costs.mesh_pixels(pixels);
    let cost = |level: usize| costs.mesh(triangles[level]) + fragments;
    let best_within = |budget: f32| (0..=last).find(|&level| cost(level) <= budget);
    let shown = shown.map(|s| (s as usize).min(last));
    let level = match (best_within(LADDER_UPGRADE_FRACTION * time), shown) {
        (Some(better), Some(s)) if better < s => better,
        (_, Some(s)) if cost(s) <= time => s,
        _ => best_within(time).unwrap_or(last),
    };
    let selected = ladder_cost(costs, triangles, pixels, level as u32);
    (
        level as u32,
        Selected {
            truncated: selected.cost > time,
            ..selected
        },
    )
}

/// What showing `level` of a ladder (`triangles` and `pixels` as for [`ladder_level`])
/// costs on Bevy's mesh path (the last level past the end; nothing for no levels).
pub(crate) fn ladder_cost(
    costs: &PrimitiveCosts,
    triangles: &[u32],
    pixels: f32,
    level: u32,
) -> Selected {
    let Some(&count) = triangles.get(level as usize).or(triangles.last()) else {
        return Selected::default();
    };
    let meshes = costs.mesh(count);
    let mesh_pixels = costs.mesh_pixels(pixels);
    Selected {
        cost: meshes + mesh_pixels,
        meshes,
        mesh_pixels,
        full: level == 0,
        ..Selected::default()
    }
}

/// How the hysteresis treats a ladder entity this frame: the level it shows, and whether
/// a choice one level better, or one level cheaper, would still be held back (the choice
/// has not yet lasted the frames it must).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct LadderHold {
    /// The level shown (0 = best).
    pub shown: u32,
    /// A choice one level better would keep `shown`.
    pub better: bool,
    /// A choice one level cheaper would keep `shown`.
    pub cheaper: bool,
    /// The level a running cross-fade draws beside `shown` this frame, if it goes on.
    pub fading: Option<u32>,
    /// A change of the level shown this frame fades from it (both are drawn while the
    /// fade runs).
    pub fades: bool,
}

impl LadderHold {
    /// The level shown this frame when the budget chooses `wanted`.
    pub(crate) fn shown_for(&self, wanted: u32) -> u32 {
        let held =
            (wanted + 1 == self.shown && self.better) || (wanted == self.shown + 1 && self.cheaper);
        if held { self.shown } else { wanted }
    }

    /// The level a cross-fade draws beside the one shown this frame when the budget
    /// chooses `wanted`: the level shown until now if the choice changes it and changes
    /// fade, else the running fade's.
    pub(crate) fn fading_for(&self, wanted: u32) -> Option<u32> {
        if self.shown_for(wanted) != self.shown {
            self.fades.then_some(self.shown)
        } else {
            self.fading
        }
    }
}

/// What [`trunk_tc`] (`widths` `None`) or [`trunk_tclod`] draws with no time at all: the
/// cost of the trunk's cheapest representation, found without searching (the budget
/// pays every visible object's floor before it hands out the rest).
pub(crate) fn trunk_floor(
    model: &TreeModel,
    view: &TreeView,
    costs: &PrimitiveCosts,
    widths: Option<PixelRange>,
) -> f32 {
    let px = pixels_per_unit(view, view.trunk_depth);
    let area = trunk_cost_area(model, px, costs);
    let tc_floor = || {
        if costs.triangles(1, area) > 0.0 {
            costs.triangles(thickest_triangles(model), area)
        } else {
            // Free triangles: all of them.
            costs.triangles(model.trunk_triangle_count() as u32, area)
        }
    };
    let Some(widths) = widths else {
        return tc_floor();
    };
    let full = trunk_triangle_cost(model, costs, 0, area);
    if full <= 0.0 {
        return full;
    }
    let n = model.segments.len() as u32;
    // The static lines' cost, and the width of the run holding the thickest segment.
    let mut lines = 0.0;
    let mut thickest_width = None;
    let (drawn, static_k) =
        crate::tree::trunk_line_runs(model.segments.diameters(), px, widths, |width, r| {
            if r.contains(&(n - 1)) {
                thickest_width = Some(width);
            }
            let length = segment_length(model, &r) * px * PROJECTED_LENGTH_FACTOR;
            lines += costs.lines(width, r.end - r.start, length);
        });
    if static_k == 0 {
        return tc_floor();
    }
    let thickest_line = |width: u32| {
        costs.lines(
            width,
            1,
            segment_length(model, &(n - 1..n)) * px * PROJECTED_LENGTH_FACTOR,
        )
    };
    if drawn == n {
        return thickest_line(widths.sanitized().min);
    }
    let static_cost = lines + trunk_triangle_cost(model, costs, static_k, area);
    if static_cost <= 0.0 {
        static_cost
    } else if trunk_triangle_cost(model, costs, static_k, area) <= 0.0 {
        // All lines (or free triangles): the thickest line alone.
        match (static_k == n, thickest_width) {
            (true, Some(width)) => thickest_line(width),
            _ => 0.0,
        }
    } else {
        tc_floor()
    }
}

/// One visible leaf group of a tree: its index and depth.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct VisibleLeafGroup {
    /// Index into [`TreeModel::leaf_groups`].
    pub group: u32,
    /// Depth of the group's centre.
    pub depth: f32,
}

/// Mean area of one leaf (world units, unscaled).
pub(crate) fn mean_leaf_area(model: &TreeModel) -> f32 {
    model.mean_leaf_triangle_area * model.leaf_triangle_count() as f32
        / model.leaves.len().max(1) as f32
}

/// Projected area in pixels of a group of `leaves` leaves at `depth` (T-4.4).
pub(crate) fn group_area(model: &TreeModel, view: &TreeView, leaves: u32, depth: f32) -> f32 {
    let p = pixels_per_unit(view, depth);
    leaves as f32 * mean_leaf_area(model) * p * p * LEAF_FACING
}

/// What drawing a leaf as triangles costs in one tree, whose leaves project `tree_area`
/// pixels in all.
struct LeafTriangles {
    /// Triangles per leaf.
    per_leaf: f32,
    /// The share of a leaf's projected pixels one of its triangles is charged for: a
    /// tree's leaves together cover at most a screenful (the LOD decisions still see the
    /// projected areas).
    share: f32,
}

impl LeafTriangles {
    fn of(model: &TreeModel, costs: &PrimitiveCosts, tree_area: f32) -> Self {
        let per_leaf = model.leaf_triangle_count() as f32 / model.leaves.len().max(1) as f32;
        let charged = if tree_area > costs.max_pixels {
            costs.max_pixels / tree_area
        } else {
            1.0
        };
        Self {
            per_leaf,
            share: charged / per_leaf.max(1.0),
        }
    }

    /// The time of one leaf as triangles, the leaf projecting `leaf_area` pixels.
    fn per_leaf(&self, costs: &PrimitiveCosts, leaf_area: f32) -> f32 {
        costs.triangles(1, leaf_area * self.share) * self.per_leaf
    }
}

/// How the leaves of a tree are chosen.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum LeafMethod {
    /// Triangles only, far leaves first.
    Tc,
    /// Points of several sizes and triangles.
    Tclod(PixelRange),
    /// The static LOD at one point size.
    Static(u32),
    /// Every leaf as triangles (full detail), whatever the time.
    Full,
}

/// A tree's leaves: the time is shared among its visible groups by projected area, each
/// group's remainder going to the groups after it and the last remainder back to the
/// caller (thesis §6.5). `groups` lists the visible groups.
pub(crate) fn leaves(
    model: &TreeModel,
    view: &TreeView,
    costs: &PrimitiveCosts,
    method: LeafMethod,
    groups: &[VisibleLeafGroup],
    time: f32,
    out: &mut TreeDrawList,
) -> Selected {
    out.leaf_triangles.clear();
    out.leaf_points.clear();
    let mut area_left = leaves_area(model, view, groups);
    let leaf_cost = LeafTriangles::of(model, costs, area_left);
    let time = time.max(0.0);
    // Full detail whenever the time pays for it: the search only runs below (thesis §6.5).
    let method = match method {
        LeafMethod::Tc | LeafMethod::Tclod(_)
            if group_leaf_costs(model, view, costs, &leaf_cost, groups)
                .map(|(n, leaf)| leaf * n as f32)
                .sum::<f32>()
                <= time =>
        {
            LeafMethod::Full
        }
        other => other,
    };
    // Each group's cheapest drawing is paid first and the rest shared by area, as Robin
    // Hood pays every object's: a near group would otherwise buy a second leaf with a far
    // group's floor, and the tree overrun its floor.
    let floors: f32 = group_leaf_costs(model, view, costs, &leaf_cost, groups)
        .zip(groups_with_leaves(model, view, groups))
        .map(|((_, leaf), (_, area))| group_floor(method, costs, area, leaf))
        .sum();
    let mut extra = (time - floors).max(0.0);
    let mut total = Selected::default();
    for g in groups {
        let leaves = model.leaf_groups[g.group as usize].leaves.clone();
        let n = leaves.end - leaves.start;
        if n == 0 {
            continue;
        }
        let area = group_area(model, view, n, g.depth);
        let area = if area.is_finite() { area } else { 0.0 };
        let share = if area_left > 0.0 {
            (area / area_left).min(1.0)
        } else {
            1.0
        };
        area_left -= area;
        let triangle_leaf = leaf_cost.per_leaf(costs, area / n as f32);
        let portion = extra * share;
        extra -= portion;
        let given = group_floor(method, costs, area, triangle_leaf) + portion;
        let chosen = match method {
            LeafMethod::Tc => group_tc(&leaves, triangle_leaf, given, out),
            LeafMethod::Full => {
                write_group(&leaves, 0, true, n, 1, out);
                Selected {
                    cost: triangle_leaf * n as f32,
                    ..Selected::default()
                }
            }
            LeafMethod::Static(size) => {
                let (points, far, tris) = static_split(n, area, size);
                write_group(&leaves, points, far, tris, size, out);
                let point_cost = costs.points(size, points);
                Selected {
                    cost: point_cost + triangle_leaf * tris as f32,
                    points: point_cost,
                    ..Selected::default()
                }
            }
            LeafMethod::Tclod(sizes) => {
                group_tclod(&leaves, area, triangle_leaf, costs, sizes, given, out)
            }
        };
        extra += (given - chosen.cost).max(0.0);
        total.cost += chosen.cost;
        total.points += chosen.points;
    }
    total.full = method == LeafMethod::Full && !groups.is_empty();
    total.truncated = overran(method, total.cost, time);
    total
}

/// The projected area of the visible groups' leaves together, pixels.
fn leaves_area(model: &TreeModel, view: &TreeView, groups: &[VisibleLeafGroup]) -> f32 {
    groups_with_leaves(model, view, groups)
        .map(|(_, area)| area)
        .sum()
}

/// Per visible group with leaves, its leaf count and projected area.
fn groups_with_leaves<'a>(
    model: &'a TreeModel,
    view: &'a TreeView,
    groups: &'a [VisibleLeafGroup],
) -> impl Iterator<Item = (u32, f32)> + 'a {
    groups.iter().filter_map(move |g| {
        let n = model.leaf_groups[g.group as usize].leaves.len() as u32;
        let area = group_area(model, view, n, g.depth);
        (n > 0).then_some((n, if area.is_finite() { area } else { 0.0 }))
    })
}

/// The cost of one group's cheapest drawing by `method`: one far leaf as triangles (TC)
/// or, with TCLOD, one far point at the largest size for the group or one far leaf as
/// triangles, whichever is cheaper ([`tclod_choice`]); 0 for the methods that take no
/// time.
fn group_floor(method: LeafMethod, costs: &PrimitiveCosts, area: f32, triangle_leaf: f32) -> f32 {
    match method {
        LeafMethod::Tc => triangle_leaf,
        LeafMethod::Tclod(sizes) => cheaper_floor(
            costs.points(largest_point(area, 1, sizes), 1),
            triangle_leaf,
        ),
        LeafMethod::Static(_) | LeafMethod::Full => 0.0,
    }
}

/// Whether a search by `method` that drew `cost` with `time` overran it (drew its
/// cheapest, which did not fit).
fn overran(method: LeafMethod, cost: f32, time: f32) -> bool {
    matches!(method, LeafMethod::Tc | LeafMethod::Tclod(_)) && exceeds(cost, time)
}

/// Whether `cost` is more than `time`, beyond the rounding of prices.
fn exceeds(cost: f32, time: f32) -> bool {
    cost > time * (1.0 + 1e-6)
}

/// How many primitives of `each` seconds `time` pays for, with the rounding [`exceeds`]
/// allows: a time priced as `k` of them divides back to `k`, not a hair below.
fn affordable_count(time: f32, each: f32) -> f32 {
    time * (1.0 + 1e-6) / each
}

/// Per visible group, its leaf count and the time of one of its leaves as triangles.
fn group_leaf_costs<'a>(
    model: &'a TreeModel,
    view: &'a TreeView,
    costs: &'a PrimitiveCosts,
    leaf_cost: &'a LeafTriangles,
    groups: &'a [VisibleLeafGroup],
) -> impl Iterator<Item = (u32, f32)> + 'a {
    groups_with_leaves(model, view, groups)
        .map(move |(n, area)| (n, leaf_cost.per_leaf(costs, area / n as f32)))
}

/// What [`leaves`] draws with no time at all: the cost of the leaves' cheapest
/// representation, found without searching.
pub(crate) fn leaves_floor(
    model: &TreeModel,
    view: &TreeView,
    costs: &PrimitiveCosts,
    method: LeafMethod,
    groups: &[VisibleLeafGroup],
) -> f32 {
    let leaf_cost = LeafTriangles::of(model, costs, leaves_area(model, view, groups));
    let each = || group_leaf_costs(model, view, costs, &leaf_cost, groups);
    let full: f32 = each().map(|(n, leaf)| leaf * n as f32).sum();
    match method {
        LeafMethod::Full => full,
        _ if full <= 0.0 => full,
        LeafMethod::Tc | LeafMethod::Tclod(_) => each()
            .zip(groups_with_leaves(model, view, groups))
            .map(|((_, leaf), (_, area))| group_floor(method, costs, area, leaf))
            .sum(),
        LeafMethod::Static(_) => {
            let mut scratch = TreeDrawList::default();
            leaves(model, view, costs, method, groups, 0.0, &mut scratch).cost
        }
    }
}

/// The static split of a group of `n` leaves projecting `area` pixels at point `size`
/// (T-4.5, T-4.6): `(points, from the far end, triangle leaves)`.
fn static_split(n: u32, area: f32, size: u32) -> (u32, bool, u32) {
    let s = size.max(1) as f32;
    // (The smallest size, the one tried first, needs no division.)
    let wanted = if size <= 1 { area } else { area / (s * s) };
    let nf = n as f32;
    if wanted < nf {
        (((wanted + 0.5) as u32).clamp(1, n), true, 0)
    } else if wanted < 2.0 * nf {
        let points = ((2.0 * nf - wanted + 0.5) as u32).min(n);
        (points, false, n - points)
    } else {
        (0, false, n)
    }
}

fn write_group(
    leaves: &Range<u32>,
    points: u32,
    far: bool,
    triangles: u32,
    size: u32,
    out: &mut TreeDrawList,
) {
    let n = leaves.end - leaves.start;
    let points = points.min(n);
    let triangles = triangles.min(n - points);
    if far {
        // Far points, and triangles (if any) just before them.
        let p = leaves.end - points..leaves.end;
        let t = p.start - triangles..p.start;
        push(out, t, p, size);
    } else {
        let p = leaves.start..leaves.start + points;
        let t = p.end..p.end + triangles;
        push(out, t, p, size);
    }
}

fn push(out: &mut TreeDrawList, triangles: Range<u32>, points: Range<u32>, size: u32) {
    if !triangles.is_empty() {
        // Adjacent groups' ranges join into one.
        match out.leaf_triangles.last_mut() {
            Some(last) if last.end == triangles.start => last.end = triangles.end,
            _ => out.leaf_triangles.push(triangles),
        }
    }
    if !points.is_empty() {
        match out.leaf_points.last_mut() {
            Some(last) if last.leaves.end == points.start && last.size == size => {
                last.leaves.end = points.end;
            }
            _ => out.leaf_points.push(PointRun {
                leaves: points,
                size,
            }),
        }
    }
}

/// TC group: far leaves as triangles, as many as fit, at least one.
fn group_tc(
    leaves: &Range<u32>,
    triangle_leaf: f32,
    time: f32,
    out: &mut TreeDrawList,
) -> Selected {
    let n = leaves.end - leaves.start;
    let affordable = if triangle_leaf > 0.0 && triangle_leaf * n as f32 > time {
        (time / triangle_leaf).min(n as f32) as u32
    } else {
        n
    };
    let count = affordable.max(1);
    write_group(leaves, 0, true, count, 1, out);
    Selected {
        cost: triangle_leaf * count as f32,
        truncated: affordable == 0,
        ..Selected::default()
    }
}

/// The largest point size for `groups` groups projecting `area` pixels together: no
/// point is larger than an average group on screen.
fn largest_point(area: f32, groups: u32, sizes: PixelRange) -> u32 {
    let PixelRange { min, max } = sizes.sanitized();
    let above_min = (min + 1) as f32;
    // A far tree's groups cover less than a point of the next size: no root to take.
    if area < above_min * above_min * groups as f32 {
        return min;
    }
    ((area / groups.max(1) as f32).sqrt() as u32).clamp(min, max)
}

/// What TCLOD draws of `n` leaves projecting `area` pixels, given `time`.
#[derive(Clone, Copy, Debug, PartialEq)]
enum TclodChoice {
    /// Every leaf as triangles.
    Full,
    /// The static split at this point size.
    Split(u32),
    /// Only this many far points (at least one) at the largest size.
    FarPoints { size: u32, count: u32 },
    /// Only this many far leaves as triangles (TC's choice), where they show more of the
    /// leaves than the points would.
    Triangles(u32),
}

impl TclodChoice {
    /// How much of `n` leaves projecting `area` pixels this choice shows, pixels: the
    /// leaves drawn as triangles, exactly; the pixels points cover, discounted by the
    /// ratio of a leaf's area to a point's on screen: a disc larger than a leaf shows
    /// about one leaf — where it is and its colour, not the shapes of the leaves it
    /// covers (a pixel is the finest detail there is). With the discount linear in the
    /// size, near leaf groups chose 10–20 px discs over as many triangle leaves, and SSIM
    /// at a near view fell below TC's (issue #42).
    fn shown(self, n: u32, area: f32) -> f32 {
        let leaf_area = area / n.max(1) as f32;
        let leaf_size = leaf_area.sqrt().max(1.0);
        let points = |count: u32, size: u32, room: f32| {
            let s = size.max(1) as f32;
            (count as f32 * s * s).min(room.max(0.0)) * (leaf_size / s).min(1.0).powi(2)
        };
        match self {
            Self::Full => area,
            Self::Triangles(count) => count.min(n) as f32 * leaf_area,
            Self::FarPoints { size, count } => points(count, size, area),
            Self::Split(size) => {
                let (count, _, tris) = static_split(n, area, size);
                let triangles = tris as f32 * leaf_area;
                triangles + points(count, size, area - triangles)
            }
        }
    }
}

/// TCLOD's decision for `n` leaves projecting `area` pixels in `groups` groups, given
/// `time`: [`points_choice`], unless TC's choice — as many far leaves as triangles as fit,
/// at least one a group — fits and [shows](TclodChoice::shown) at least as much of the
/// leaves. Where leaves are large on screen and points cost more than the leaves they
/// stand for, points would show less for the same time (issue #42: a near view's leaves
/// as 10–20 px discs that cost more than the triangles they replaced).
fn tclod_choice(
    n: u32,
    area: f32,
    groups: u32,
    triangle_leaf: f32,
    costs: &PrimitiveCosts,
    sizes: PixelRange,
    time: f32,
) -> (TclodChoice, Selected) {
    let points = points_choice(n, area, groups, triangle_leaf, costs, sizes, time);
    if points.0 == TclodChoice::Full || triangle_leaf <= 0.0 {
        return points;
    }
    let affordable = affordable_count(time, triangle_leaf).min(n as f32) as u32;
    let as_triangles = |count: u32| {
        let cost = triangle_leaf * count as f32;
        (
            TclodChoice::Triangles(count),
            Selected {
                cost,
                truncated: exceeds(cost, time),
                ..Selected::default()
            },
        )
    };
    let least = groups.max(1);
    if affordable >= least
        && TclodChoice::Triangles(affordable).shown(n, area) >= points.0.shown(n, area)
    {
        return as_triangles(affordable);
    }
    // Where even the far points do not fit and a far leaf a group as triangles costs
    // less (points dear on this machine), the triangles are the cheaper floor: TCLOD's
    // cheapest drawing is never dearer than TC's.
    // (Far points are drawn at least one a group.)
    let points_cost = match points.0 {
        TclodChoice::FarPoints { size, count } => costs.points(size, count.max(least)),
        _ => points.1.cost,
    };
    let cheapest = as_triangles(affordable.max(least));
    if exceeds(points_cost, time) && cheapest.1.cost < points_cost {
        return cheapest;
    }
    points
}

/// TCLOD's decision by points for `n` leaves projecting `area` pixels: the smallest point
/// size (best quality) whose static split fits; at the largest size, only the far points
/// that fit, at least one. No point is larger than an average of the leaves' `groups`
/// groups on screen.
fn points_choice(
    n: u32,
    area: f32,
    groups: u32,
    triangle_leaf: f32,
    costs: &PrimitiveCosts,
    sizes: PixelRange,
    time: f32,
) -> (TclodChoice, Selected) {
    // Full detail whenever the time pays for it: the search only runs below (thesis §6.5).
    let full = triangle_leaf * n as f32;
    if full <= time {
        return (
            TclodChoice::Full,
            Selected {
                cost: full,
                ..Selected::default()
            },
        );
    }
    let min = sizes.sanitized().min;
    let max = largest_point(area, groups, sizes);
    // (The whole cost, and its points' part.)
    let split_at = |size: u32| {
        let (points, _, tris) = static_split(n, area, size);
        // Points alone are drawn at least one a group (`leaves_at_depth`).
        let points = if tris == 0 {
            points.max(groups.min(n))
        } else {
            points
        };
        let point_cost = costs.points(size, points);
        (point_cost + triangle_leaf * tris as f32, point_cost)
    };
    let cost_at = |size: u32| split_at(size).0;
    let fits = |size: u32| {
        let (cost, points) = split_at(size);
        (cost <= time).then_some((
            TclodChoice::Split(size),
            Selected {
                cost,
                points,
                ..Selected::default()
            },
        ))
    };
    // Full detail when every leaf fits as a triangle and the group is big enough on
    // screen to want it at the smallest size.
    if let Some(chosen) = fits(min) {
        return chosen;
    }
    // Cost falls as the size grows: the smallest size that fits.
    let (mut lo, mut hi) = (min, max);
    while lo < hi {
        let mid = lo + (hi - lo) / 2;
        if cost_at(mid) <= time {
            hi = mid;
        } else {
            lo = mid + 1;
        }
    }
    // (The smallest size is known not to fit.)
    if lo > min
        && let Some(chosen) = fits(lo)
    {
        return chosen;
    }
    let each = costs.points(max, 1);
    // Never more points of the largest size than cover the group: more would only
    // overdraw it, with time another object could use.
    let covering = static_split(n, area, max).0.max(1);
    let affordable = if each > 0.0 {
        affordable_count(time, each).min(covering as f32) as u32
    } else {
        covering
    };
    let count = affordable.max(1);
    (
        TclodChoice::FarPoints { size: max, count },
        Selected {
            cost: each * count as f32,
            lines: 0.0,
            points: each * count as f32,
            meshes: 0.0,
            mesh_pixels: 0.0,
            truncated: affordable == 0,
            full: false,
        },
    )
}

/// TCLOD group: [`tclod_choice`] for one group, written.
fn group_tclod(
    leaves: &Range<u32>,
    area: f32,
    triangle_leaf: f32,
    costs: &PrimitiveCosts,
    sizes: PixelRange,
    time: f32,
    out: &mut TreeDrawList,
) -> Selected {
    let n = leaves.end - leaves.start;
    let (choice, selected) = tclod_choice(n, area, 1, triangle_leaf, costs, sizes, time);
    match choice {
        TclodChoice::Full => write_group(leaves, 0, true, n, 1, out),
        TclodChoice::Split(size) => {
            let (points, far, tris) = static_split(n, area, size);
            write_group(leaves, points, far, tris, size, out);
        }
        TclodChoice::FarPoints { size, count } => write_group(leaves, count, true, 0, size, out),
        TclodChoice::Triangles(count) => write_group(leaves, 0, true, count, 1, out),
    }
    selected
}

/// A tree's leaves, all at one depth.
struct TreeAtDepth {
    /// Leaves.
    n: u32,
    /// Leaf groups (at most `n`).
    groups: u32,
    /// The leaves' projected area, pixels.
    area: f32,
    /// The time of one leaf as triangles.
    triangle_leaf: f32,
    /// The depth.
    depth: f32,
}

impl TreeAtDepth {
    fn of(model: &TreeModel, view: &TreeView, costs: &PrimitiveCosts, depth: f32) -> Option<Self> {
        // Valid models' groups tile the leaves and none is empty (`TreeModel::validate`).
        let n = model.leaves.len() as u32;
        if n == 0 {
            return None;
        }
        let leaf_area = group_area(model, view, 1, depth);
        let (leaf_area, area) = match n as f32 * leaf_area {
            area if area.is_finite() => (leaf_area, area),
            _ => (0.0, 0.0),
        };
        Some(Self {
            n,
            groups: (model.leaf_groups.len() as u32).min(n),
            area,
            triangle_leaf: LeafTriangles::of(model, costs, area).per_leaf(costs, leaf_area),
            depth,
        })
    }
}

/// What [`leaves_at_depth`] draws with no time at all: the cost of the leaves' cheapest
/// representation, found without searching.
pub(crate) fn leaves_at_depth_floor(
    model: &TreeModel,
    view: &TreeView,
    costs: &PrimitiveCosts,
    method: LeafMethod,
    depth: f32,
) -> f32 {
    let Some(tree) = TreeAtDepth::of(model, view, costs, depth) else {
        return 0.0;
    };
    let full = tree.triangle_leaf * tree.n as f32;
    match method {
        LeafMethod::Full => full,
        _ if full <= 0.0 => full,
        // A far leaf of every group.
        LeafMethod::Tc => tree.triangle_leaf * tree.groups as f32,
        // The crown disc where it is cheaper than drawing something of every group.
        LeafMethod::Tclod(sizes) => {
            let groups = every_group_floor(&tree, costs, sizes);
            crown_size(model, view, depth)
                .map(|size| costs.points(size, 1))
                .filter(|&crown| crown < groups)
                .unwrap_or(groups)
        }
        LeafMethod::Static(_) => {
            let mut scratch = TreeDrawList::default();
            leaves_at_depth(model, view, costs, method, depth, 0.0, &mut scratch).cost
        }
    }
}

/// The cost of TCLOD's far points for a tree chosen as a whole: one for every group, at
/// the largest size for a group of average size.
fn far_points_floor(tree: &TreeAtDepth, costs: &PrimitiveCosts, sizes: PixelRange) -> f32 {
    costs.points(largest_point(tree.area, tree.groups, sizes), tree.groups)
}

/// The cheapest drawing of a tree chosen as a whole that shows every group: its far
/// points, or a far leaf of every group as triangles where that is cheaper (points dear
/// on this machine; [`tclod_choice`]).
fn every_group_floor(tree: &TreeAtDepth, costs: &PrimitiveCosts, sizes: PixelRange) -> f32 {
    cheaper_floor(
        far_points_floor(tree, costs, sizes),
        tree.triangle_leaf * tree.groups as f32,
    )
}

/// TCLOD's floor from its far `points` and TC's far leaves as `triangles` (the same
/// groups): the cheaper, the triangles only when they are priced.
fn cheaper_floor(points: f32, triangles: f32) -> f32 {
    if triangles > 0.0 {
        points.min(triangles)
    } else {
        points
    }
}

/// The point size of `model`'s [crown](TreeModel::crown) disc at `depth`: the side of a
/// square of the crown's projected area (a point of size `s` covers `s²` pixels, round or
/// not). `None` when the model has no crown or the disc would be larger than the largest
/// point drawn, and so would not cover it.
fn crown_size(model: &TreeModel, view: &TreeView, depth: f32) -> Option<u32> {
    let crown = model.crown.as_ref()?;
    let side = crown.area.sqrt() * pixels_per_unit(view, depth);
    (side.is_finite() && side < MAX_PRIMITIVE_PIXELS as f32 + 0.5)
        .then(|| ((side + 0.5) as u32).max(1))
}

/// TCLOD's crown disc for a tree chosen as a whole, written, when `time` does not pay for
/// something of every group ([`every_group_floor`]) and the disc costs less: one point
/// covering the crown, the cheapest drawing that still shows where all its leaves are
/// (issue #42).
fn crown_choice(
    model: &TreeModel,
    view: &TreeView,
    costs: &PrimitiveCosts,
    sizes: PixelRange,
    tree: &TreeAtDepth,
    time: f32,
    out: &mut TreeDrawList,
) -> Option<Selected> {
    let size = crown_size(model, view, tree.depth)?;
    let cost = costs.points(size, 1);
    let every_group = every_group_floor(tree, costs, sizes);
    if time >= every_group || cost >= every_group {
        return None;
    }
    let leaf = model.crown_leaf();
    push(out, 0..0, leaf..leaf + 1, size);
    Some(Selected {
        cost,
        points: cost,
        truncated: exceeds(cost, time),
        ..Selected::default()
    })
}

/// A tree's leaves, all at one depth: the choice [`leaves`] makes group by group, made
/// once for the whole tree and drawn in the model's
/// [far-first order](TreeModel::far_first_leaves).
///
/// For a tree entirely in view and far compared with its size, every group is at about
/// the depth of the tree's centre, so each group would get time in proportion to its
/// leaves and choose the same point size. Deciding once costs O(1) instead of a search
/// per group, and because the first `k` leaves of the far-first order are every group's
/// share of `k` from its far end (and the last `k` every group's near ones), writing the
/// choice is O(1) too: one or two ranges, which the render pass also chunks in one go.
/// The predicted cost is exactly that of what is drawn. As group by group, every group
/// draws at least one leaf; unlike it, when only far points fit every group's points
/// have one size, the largest for a group of average size. With TCLOD and less time
/// than those far points cost, the tree's [crown](TreeModel::crown) disc stands for all
/// its leaves (when it is cheaper and no larger than the largest point).
pub(crate) fn leaves_at_depth(
    model: &TreeModel,
    view: &TreeView,
    costs: &PrimitiveCosts,
    method: LeafMethod,
    depth: f32,
    time: f32,
    out: &mut TreeDrawList,
) -> Selected {
    out.leaf_triangles.clear();
    out.leaf_points.clear();
    let Some(tree) = TreeAtDepth::of(model, view, costs, depth) else {
        return Selected::default();
    };
    let time = time.max(0.0);
    if let LeafMethod::Tclod(sizes) = method
        && let Some(crown) = crown_choice(model, view, costs, sizes, &tree, time, out)
    {
        return crown;
    }
    let TreeAtDepth {
        n,
        groups,
        area,
        triangle_leaf,
        ..
    } = tree;
    // The tree's (points, triangle leaves, point size). Points alone are far points, and
    // with triangles near ones (`static_split`).
    let (points, tris, size) = match method {
        LeafMethod::Full => (0, n, 1),
        LeafMethod::Tc => {
            // (Full detail tested first: a division can land a hair below `n`.)
            let affordable = if triangle_leaf > 0.0 && triangle_leaf * n as f32 > time {
                (time / triangle_leaf).min(n as f32) as u32
            } else {
                n
            };
            (0, affordable, 1)
        }
        LeafMethod::Static(size) => {
            let (points, _, tris) = static_split(n, area, size);
            (points, tris, size)
        }
        LeafMethod::Tclod(sizes) => {
            match tclod_choice(n, area, groups, triangle_leaf, costs, sizes, time) {
                (TclodChoice::Full, _) => (0, n, 1),
                (TclodChoice::Split(size), _) => {
                    let (points, _, tris) = static_split(n, area, size);
                    (points, tris, size)
                }
                (TclodChoice::FarPoints { size, count }, _) => (count, 0, size),
                (TclodChoice::Triangles(count), _) => (0, count, 1),
            }
        }
    };
    let far_first = n..2 * n;
    let (points, tris) = if points > 0 && tris > 0 {
        // Mixed: every leaf drawn, the far ones as triangles and the near ones as points.
        let tris = n - points.min(n);
        push(
            out,
            far_first.start..far_first.start + tris,
            far_first.start + tris..far_first.end,
            size,
        );
        (n - tris, tris)
    } else if points > 0 {
        let points = points.clamp(groups, n);
        push(out, 0..0, far_first.start..far_first.start + points, size);
        (points, 0)
    } else {
        let tris = tris.clamp(groups, n);
        push(out, far_first.start..far_first.start + tris, 0..0, size);
        (0, tris)
    };
    let point_cost = costs.points(size, points);
    let cost = point_cost + triangle_leaf * tris as f32;
    Selected {
        cost,
        lines: 0.0,
        points: point_cost,
        meshes: 0.0,
        mesh_pixels: 0.0,
        truncated: overran(method, cost, time),
        full: points == 0 && tris == n,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Costs where a triangle costs `triangle` seconds and a point `point` whatever its
    /// size, nothing per pixel.
    fn costs(triangle: f32, point: f32) -> PrimitiveCosts {
        PrimitiveCosts {
            triangle,
            triangle_pixel: 0.0,
            line: vec![1e-6; MAX_PRIMITIVE_PIXELS as usize],
            line_pixel: vec![0.0; MAX_PRIMITIVE_PIXELS as usize],
            point: vec![point; MAX_PRIMITIVE_PIXELS as usize],
            point_pixel: vec![0.0; MAX_PRIMITIVE_PIXELS as usize],
            mesh_draw: 0.0,
            mesh_triangle: 0.0,
            mesh_pixel: 0.0,
            max_pixels: f32::INFINITY,
        }
    }

    /// A near group of 100 leaves of 16 px each, a point costing two leaves as
    /// triangles, time for 20 leaves: 20 leaves as triangles, not 9 discs of 13 px (which
    /// cover more pixels, but each shows one leaf where it is, not the shapes of the 10
    /// it covers). A far group of 1 px leaves whose points are cheaper than its
    /// triangles: points, covering every leaf's pixel.
    #[test]
    fn near_leaves_stay_triangles_where_discs_would_show_fewer_leaves() {
        let sizes = PixelRange::default();
        let near = tclod_choice(100, 1600.0, 1, 1e-6, &costs(1e-6, 2e-6), sizes, 20e-6);
        assert_eq!(near.0, TclodChoice::Triangles(20), "{near:?}");
        assert!((near.1.cost - 20e-6).abs() < 1e-9, "{near:?}");
        let far = tclod_choice(100, 100.0, 1, 1e-6, &costs(1e-6, 0.5e-6), sizes, 20e-6);
        assert_eq!(far.0, TclodChoice::Split(2), "{far:?}");
    }
}
