//! What the forest render pass draws: the per-instance [`TreeDrawList`] that the LOD
//! selection fills, and (in `packing`, crate-private) the pure packing of tree geometry
//! and draw lists into the compact records the pass uploads (no GPU types there, so it is
//! tested headless).
//!
//! The pass draws every primitive kind with one instanced draw per view (points with two:
//! small squares and larger discs). Each instance of
//! that draw is a *chunk*: a fixed number of primitives taken from one contiguous range of
//! one tree instance. A range is cut into as many chunks as it needs; the unused tail of
//! the last chunk is degenerate. The number of draw calls therefore never depends on the
//! number of trees, leaf groups or ranges.

use core::ops::Range;

use bevy::prelude::*;

use crate::tree::TreeModel;

#[cfg(any(test, feature = "render"))]
pub(crate) mod packing;

/// The widest line and the largest point the pass draws, pixels: a wider width or a
/// larger size in a draw list is drawn at this one. (The level of detail picks lines and
/// leaf points up to 20 pixels, where they stop paying for themselves against
/// triangles; a crown disc may be larger.)
pub(crate) const MAX_PRIMITIVE_PIXELS: u32 = 64;

/// A run of trunk segments drawn as screen-space lines of one width.
#[derive(Clone, Debug, PartialEq, Eq, Reflect)]
pub struct LineRun {
    /// Segment indices (into [`TreeModel::segments`]).
    pub segments: Range<u32>,
    /// Line width in pixels, 1 to `MAX_PRIMITIVE_PIXELS` (drawn clamped to that).
    pub width: u32,
}

/// A run of leaves drawn as screen-space squares of one size.
#[derive(Clone, Debug, PartialEq, Eq, Reflect)]
pub struct PointRun {
    /// Leaf indices (into [`TreeModel::leaves`]).
    pub leaves: Range<u32>,
    /// Square side in pixels, 1 to `MAX_PRIMITIVE_PIXELS` (drawn clamped to that).
    pub size: u32,
}

/// What the forest render pass draws of one tree instance this frame.
///
/// The LOD selection stage fills it, every frame for every visible instance (so change
/// detection sees it changed every frame); the pass only follows it. Ranges index the
/// instance's [`TreeModel`]; ranges past the model's end are clipped to it. Segments are
/// stored thin → thick, so the thick end of the trunk is the *tail* of the trunk
/// triangles, and each leaf group's leaves are stored near → far from its ring, so a
/// group's far leaves are the tail of [`LeafGroup::leaves`](crate::tree::LeafGroup::leaves).
///
/// Leaves are addressed twice: `0..n` (`n` the model's leaf count) in the model's own
/// order, group by group, and `n..2n` in its
/// far-first order (`n + i` is its `i`-th
/// leaf), where the `k` far leaves of every group at once are one range. A tree chosen
/// as a whole draws its leaves with one or two ranges of the second kind; a range must
/// not mix the two (one that straddles `n` draws the leaves on both sides, each once
/// per order). Leaf `2n` ([`TreeModel::crown_leaf`]), drawn as a point, is the
/// [crown](TreeModel::crown) disc: a point at the crown's centre standing for all the
/// leaves (a point of size `s` covers `s²` pixels, so the size whose square is the
/// crown's projected area covers as much as the leaves).
///
/// A [`TreeInstance`](crate::instance::TreeInstance) without this component is drawn at
/// full detail if it has [`FixedDrawList`](crate::instance::FixedDrawList), and otherwise
/// — spawned after this frame's level of detail was chosen — at its
/// [coarsest](Self::coarsest) until the next frame gives it its own; one whose list is
/// empty is not drawn.
#[derive(Component, Debug, Default, PartialEq, Reflect)]
#[reflect(Component, Default)]
pub struct TreeDrawList {
    /// Trunk triangles drawn lit, a range of triangle indices into
    /// [`TreeModel::trunk_indices`] (triangle `t` is indices `3t..3t + 3`).
    pub trunk_triangles: Range<u32>,
    /// Trunk segments drawn as lines, flat in the bark colour.
    pub trunk_lines: Vec<LineRun>,
    /// Leaves drawn as lit, two-sided triangles: ranges of leaf indices (in either order,
    /// see above).
    pub leaf_triangles: Vec<Range<u32>>,
    /// Leaves drawn as lit points (leaf indices in either order).
    pub leaf_points: Vec<PointRun>,
}

impl Clone for TreeDrawList {
    fn clone(&self) -> Self {
        let mut list = Self::default();
        list.clone_from(self);
        list
    }

    /// Into the lists' own allocations: the LOD stages copy every visible tree's list
    /// each frame, which would otherwise allocate and free them all.
    fn clone_from(&mut self, source: &Self) {
        // Every field named: a new one cannot be forgotten here.
        let Self {
            trunk_triangles,
            trunk_lines,
            leaf_triangles,
            leaf_points,
        } = self;
        trunk_triangles.clone_from(&source.trunk_triangles);
        trunk_lines.clone_from(&source.trunk_lines);
        leaf_triangles.clone_from(&source.leaf_triangles);
        leaf_points.clone_from(&source.leaf_points);
    }
}

impl TreeDrawList {
    /// Everything as triangles: the full-detail representation.
    pub fn full(model: &TreeModel) -> Self {
        Self {
            trunk_triangles: 0..model.trunk_triangle_count() as u32,
            trunk_lines: Vec::new(),
            leaf_triangles: core::iter::once(0..model.leaves.len() as u32).collect(),
            leaf_points: Vec::new(),
        }
    }

    /// Every trunk segment as a 1-pixel line and every leaf as a 1-pixel point: what a tree
    /// the level of detail has not seen yet is drawn as (its cheapest representation that
    /// still shows the whole tree, whatever the view).
    pub fn coarsest(model: &TreeModel) -> Self {
        let leaves = model.leaves.len() as u32;
        Self {
            trunk_triangles: 0..0,
            trunk_lines: vec![LineRun {
                segments: 0..model.segments.len() as u32,
                width: 1,
            }],
            leaf_triangles: Vec::new(),
            leaf_points: vec![PointRun {
                leaves: 0..leaves,
                size: 1,
            }],
        }
    }

    /// Draws nothing.
    pub fn clear(&mut self) {
        self.trunk_triangles = 0..0;
        self.trunk_lines.clear();
        self.leaf_triangles.clear();
        self.leaf_points.clear();
    }

    /// Whether it draws nothing at all.
    pub fn is_empty(&self) -> bool {
        self.trunk_triangles.is_empty()
            && self.trunk_lines.iter().all(|r| r.segments.is_empty())
            && self.leaf_triangles.iter().all(Range::is_empty)
            && self.leaf_points.iter().all(|r| r.leaves.is_empty())
    }

    /// How many primitives it draws of `model` (ranges clipped to the model). Builds the
    /// model's leaf prefix each call; keep a `ModelSlot` to count many lists.
    pub fn counts(&self, model: &TreeModel) -> PrimitiveCounts {
        ModelSlot::of(model).counts(self)
    }
}

/// Primitives drawn, by kind.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Reflect)]
pub struct PrimitiveCounts {
    /// Triangles (trunk and leaves).
    pub triangles: u64,
    /// Screen-space lines.
    pub lines: u64,
    /// Screen-space points.
    pub points: u64,
}

impl core::ops::AddAssign for PrimitiveCounts {
    fn add_assign(&mut self, other: Self) {
        self.triangles += other.triangles;
        self.lines += other.lines;
        self.points += other.points;
    }
}

/// Blinn–Phong material of one part of a tree, in linear RGB.
#[derive(Clone, Copy, Debug, PartialEq, Reflect)]
pub struct Shading {
    /// Colour without light.
    pub ambient: Vec3,
    /// Colour under full light.
    pub diffuse: Vec3,
    /// Highlight colour.
    pub specular: Vec3,
    /// Highlight exponent.
    pub shininess: f32,
}

impl Shading {
    /// A plain colour: ambient a quarter of it, no highlight.
    pub fn from_color(color: [f32; 3]) -> Self {
        let diffuse = Vec3::from(color);
        Self {
            ambient: diffuse * 0.25,
            diffuse,
            specular: Vec3::ZERO,
            shininess: 1.0,
        }
    }
}

/// Materials of a tree instance's trunk and leaves. Instances without it use their
/// model's bark and leaf colours.
#[derive(Component, Clone, Copy, Debug, PartialEq, Reflect)]
#[reflect(Component)]
pub struct TreeShading {
    /// Trunk triangles and lines.
    pub trunk: Shading,
    /// Leaf triangles and points.
    pub leaves: Shading,
}

impl TreeShading {
    /// The model's own bark and leaf colours.
    pub fn of_model(model: &TreeModel) -> Self {
        Self {
            trunk: Shading::from_color(model.bark_color),
            leaves: Shading::from_color(model.leaf_color),
        }
    }
}

/// The model's leaves in the order [`TreeDrawList`] addresses them: its own, then
/// `far_first`.
fn both_orders<'a>(
    model: &'a TreeModel,
    far_first: &'a [u32],
) -> impl Iterator<Item = &'a crate::tree::Leaf> + 'a {
    model.leaves.iter().chain(
        far_first
            .iter()
            .filter_map(|&l| model.leaves.get(l as usize)),
    )
}

fn clip(range: &Range<u32>, len: u32) -> Range<u32> {
    let end = range.end.min(len);
    range.start.min(end)..end
}

/// Where one model's geometry sits in a [`GeometryAtlas`].
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub(crate) struct ModelSlot {
    /// First trunk triangle (in triangles into [`GeometryAtlas::indices`]).
    pub trunk_triangles: u32,
    /// Trunk triangle count.
    pub trunk_triangle_count: u32,
    /// First leaf triangle, in triangles.
    pub leaf_triangles: u32,
    /// Prefix over the leaf indices of the leaves' triangle counts (length
    /// `point_count + 1`): leaves `a..b` are triangles `leaf_triangles + prefix[a] ..
    /// leaf_triangles + prefix[b]`.
    pub leaf_triangle_prefix: Vec<u32>,
    /// First segment line in [`GeometryAtlas::primitives`].
    pub lines: u32,
    /// Segment count.
    pub line_count: u32,
    /// First leaf point in [`GeometryAtlas::primitives`].
    pub points: u32,
    /// Leaf indices: every leaf twice, in the model's order then in its far-first order,
    /// then the crown disc if the model has one (see [`TreeDrawList`]).
    pub point_count: u32,
    /// Ring count (the length of its slice of a ring-offset table).
    pub rings: u32,
}

impl ModelSlot {
    /// The counts and leaf prefix of `model` alone, at offset 0: enough for
    /// [`ModelSlot::counts`] without packing the geometry.
    pub(crate) fn of(model: &TreeModel) -> Self {
        Self::with_leaf_order(model, &model.far_first_leaves())
    }

    fn with_leaf_order(model: &TreeModel, far_first: &[u32]) -> Self {
        let leaves = both_orders(model, far_first);
        let mut prefix = Vec::with_capacity(model.leaves.len() + far_first.len() + 1);
        prefix.push(0);
        let mut total = 0;
        for leaf in leaves {
            total += leaf.triangles.len() as u32;
            prefix.push(total);
        }
        if model.crown.is_some() {
            // The crown disc, a point only.
            prefix.push(total);
        }
        Self {
            trunk_triangles: 0,
            trunk_triangle_count: model.trunk_triangle_count() as u32,
            leaf_triangles: 0,
            lines: 0,
            line_count: model.segments.len() as u32,
            points: 0,
            point_count: (prefix.len() - 1) as u32,
            leaf_triangle_prefix: prefix,
            rings: model.rings.len() as u32,
        }
    }

    /// How many primitives `list` draws of this model (ranges clipped to the model), in
    /// time proportional to the number of ranges.
    pub(crate) fn counts(&self, list: &TreeDrawList) -> PrimitiveCounts {
        let len = |r: Range<u32>| u64::from(r.end - r.start);
        PrimitiveCounts {
            triangles: len(clip(&list.trunk_triangles, self.trunk_triangle_count))
                + list
                    .leaf_triangles
                    .iter()
                    .map(|r| len(self.leaf_triangle_range(r)))
                    .sum::<u64>(),
            lines: list
                .trunk_lines
                .iter()
                .map(|r| len(clip(&r.segments, self.line_count)))
                .sum(),
            points: list
                .leaf_points
                .iter()
                .map(|r| len(clip(&r.leaves, self.point_count)))
                .sum(),
        }
    }

    /// The atlas triangles of a range of this model's leaves (clipped to the model).
    pub(crate) fn leaf_triangle_range(&self, leaves: &Range<u32>) -> Range<u32> {
        let r = clip(leaves, self.point_count);
        self.leaf_triangles + self.leaf_triangle_prefix[r.start as usize]
            ..self.leaf_triangles + self.leaf_triangle_prefix[r.end as usize]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_list_copied_into_another_is_equal_and_keeps_the_others_allocations() {
        let source = TreeDrawList {
            trunk_triangles: 3..9,
            trunk_lines: vec![LineRun {
                segments: 0..4,
                width: 2,
            }],
            leaf_triangles: vec![0..5, 9..12],
            leaf_points: vec![PointRun {
                leaves: 5..9,
                size: 3,
            }],
        };
        let mut copy = TreeDrawList {
            leaf_points: Vec::with_capacity(16),
            leaf_triangles: Vec::with_capacity(16),
            ..TreeDrawList::default()
        };
        let (points, triangles) = (copy.leaf_points.as_ptr(), copy.leaf_triangles.as_ptr());
        copy.clone_from(&source);
        assert_eq!(copy, source);
        assert_eq!(copy.clone(), source);
        assert_eq!(
            (copy.leaf_points.as_ptr(), copy.leaf_triangles.as_ptr()),
            (points, triangles)
        );
    }
}
