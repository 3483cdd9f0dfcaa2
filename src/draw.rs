//! What the forest render pass draws: the per-instance [`TreeDrawList`] that the LOD
//! selection fills, and the pure packing of tree geometry and draw lists into the compact
//! records the pass uploads (no GPU types here, so it is tested headless).
//!
//! The pass draws every primitive kind with one instanced draw per view (points with two:
//! small squares and larger discs). Each instance of
//! that draw is a *chunk*: a fixed number of primitives taken from one contiguous range of
//! one tree instance. A range is cut into as many chunks as it needs; the unused tail of
//! the last chunk is degenerate. The number of draw calls therefore never depends on the
//! number of trees, leaf groups or ranges.

use core::ops::Range;

use bevy::prelude::*;
use bytemuck::{Pod, Zeroable};

use crate::tree::{NO_RING, TreeModel};

/// Triangles per triangle chunk.
pub const TRIANGLES_PER_CHUNK: u32 = 32;
/// Segments per line chunk.
pub const LINES_PER_CHUNK: u32 = 16;
/// Leaves per point chunk.
pub const POINTS_PER_CHUNK: u32 = 32;

/// A run of trunk segments drawn as screen-space lines of one width.
#[derive(Clone, Debug, PartialEq, Eq, Reflect)]
pub struct LineRun {
    /// Segment indices (into [`TreeModel::segments`]).
    pub segments: Range<u32>,
    /// Line width in pixels, 1 to [`MAX_PRIMITIVE_PIXELS`] (drawn clamped to that).
    pub width: u32,
}

/// A run of leaves drawn as screen-space squares of one size.
#[derive(Clone, Debug, PartialEq, Eq, Reflect)]
pub struct PointRun {
    /// Leaf indices (into [`TreeModel::leaves`]).
    pub leaves: Range<u32>,
    /// Square side in pixels, 1 to [`MAX_PRIMITIVE_PIXELS`] (drawn clamped to that).
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
/// [far-first order](crate::tree::TreeModel::far_first_leaves) (`n + i` is its `i`-th
/// leaf), where the `k` far leaves of every group at once are one range. A tree chosen
/// as a whole draws its leaves with one or two ranges of the second kind; a range must
/// not mix the two (one that straddles `n` draws the leaves on both sides, each once
/// per order).
///
/// A [`TreeInstance`](crate::instance::TreeInstance) without this component is drawn at
/// full detail if it has [`FixedDrawList`](crate::instance::FixedDrawList), and otherwise
/// — spawned after this frame's level of detail was chosen — at its
/// [coarsest](Self::coarsest) until the next frame gives it its own; one whose list is
/// empty is not drawn.
#[derive(Component, Clone, Debug, Default, PartialEq, Reflect)]
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
    /// model's leaf prefix each call; keep a [`ModelSlot`] to count many lists.
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

/// One vertex of the packed geometry (trunk and leaves alike).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuVertex {
    /// Model-space position.
    pub position: [f32; 3],
    /// The ring whose wind offset moves it ([`NO_RING`]: none).
    pub ring: u32,
    /// Model-space normal.
    pub normal: [f32; 3],
    /// Padding to 16-byte alignment.
    pub pad: u32,
}

/// One line (a trunk segment: its two ring centres) or one point (a leaf: its centre and
/// normal) of the packed geometry.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuPrimitive {
    /// Line: lower end. Point: centre.
    pub a: [f32; 3],
    /// Ring moving `a`.
    pub ring_a: u32,
    /// Line: upper end. Point: normal.
    pub b: [f32; 3],
    /// Line: ring moving `b`. Point: unused.
    pub ring_b: u32,
}

/// Where one model's geometry sits in a [`GeometryAtlas`].
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ModelSlot {
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
    /// Leaf indices: every leaf twice, in the model's order then in its far-first order
    /// (see [`TreeDrawList`]).
    pub point_count: u32,
    /// Ring count (the length of its slice of a ring-offset table).
    pub rings: u32,
}

impl ModelSlot {
    /// The counts and leaf prefix of `model` alone, at offset 0: enough for
    /// [`ModelSlot::counts`] without packing the geometry.
    pub fn of(model: &TreeModel) -> Self {
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
    pub fn counts(&self, list: &TreeDrawList) -> PrimitiveCounts {
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
    pub fn leaf_triangle_range(&self, leaves: &Range<u32>) -> Range<u32> {
        let r = clip(leaves, self.point_count);
        self.leaf_triangles + self.leaf_triangle_prefix[r.start as usize]
            ..self.leaf_triangles + self.leaf_triangle_prefix[r.end as usize]
    }
}

/// Every tree model's geometry packed into three arrays, uploaded once and shared by all
/// instances: vertices, triangle indices (absolute into `vertices`), and line/point
/// primitives. Leaf triangles are stored leaf after leaf, so a range of leaves is a range
/// of triangles.
#[derive(Clone, Debug, Default)]
pub struct GeometryAtlas {
    /// Packed vertices.
    pub vertices: Vec<GpuVertex>,
    /// Triangle indices into `vertices`, three per triangle.
    pub indices: Vec<u32>,
    /// Segment lines and leaf points.
    pub primitives: Vec<GpuPrimitive>,
}

impl GeometryAtlas {
    /// Appends a model and returns where it went. Leaf triangles and points are stored
    /// twice, in the two orders [`TreeDrawList`] addresses (the vertices once).
    pub fn push(&mut self, model: &TreeModel) -> ModelSlot {
        let far_first = model.far_first_leaves();
        let first_triangle = |atlas: &Self| (atlas.indices.len() / 3) as u32;
        let base = self.vertices.len() as u32;
        self.vertices.extend(
            model
                .trunk_positions
                .iter()
                .zip(&model.trunk_normals)
                .enumerate()
                .map(|(i, (p, n))| GpuVertex {
                    position: p.to_array(),
                    ring: model.trunk_vertex_ring.get(i).copied().unwrap_or(NO_RING),
                    normal: n.to_array(),
                    pad: 0,
                }),
        );
        let trunk_triangles = first_triangle(self);
        self.indices
            .extend(model.trunk_indices.iter().map(|&i| base + i));

        let leaf_base = self.vertices.len() as u32;
        let leaf_ring = |v: usize| {
            let leaf = *model.leaf_vertex_leaf.get(v)? as usize;
            let group = model.leaves.get(leaf)?.group as usize;
            Some(model.leaf_groups.get(group)?.ring)
        };
        self.vertices.extend(
            model
                .leaf_positions
                .iter()
                .zip(&model.leaf_normals)
                .enumerate()
                .map(|(i, (p, n))| GpuVertex {
                    position: p.to_array(),
                    ring: leaf_ring(i).unwrap_or(NO_RING),
                    normal: n.to_array(),
                    pad: 0,
                }),
        );
        let leaf_triangles = first_triangle(self);
        for leaf in both_orders(model, &far_first) {
            let indices = &model.leaf_indices[leaf.triangles.start as usize * 3..];
            let indices = &indices[..leaf.triangles.len() * 3];
            self.indices.extend(indices.iter().map(|&i| leaf_base + i));
        }

        let lines = self.primitives.len() as u32;
        self.primitives
            .extend(
                model
                    .segments
                    .line
                    .iter()
                    .zip(&model.segments.ring)
                    .map(|(line, &ring)| GpuPrimitive {
                        a: line[0].to_array(),
                        ring_a: model.rings.get(ring as usize).map_or(NO_RING, |r| r.parent),
                        b: line[1].to_array(),
                        ring_b: ring,
                    }),
            );
        let points = self.primitives.len() as u32;
        self.primitives
            .extend(both_orders(model, &far_first).map(|leaf| {
                GpuPrimitive {
                    a: leaf.center.to_array(),
                    ring_a: model
                        .leaf_groups
                        .get(leaf.group as usize)
                        .map_or(NO_RING, |g| g.ring),
                    b: leaf.normal.to_array(),
                    ring_b: NO_RING,
                }
            }));
        ModelSlot {
            trunk_triangles,
            leaf_triangles,
            lines,
            points,
            ..ModelSlot::with_leaf_order(model, &far_first)
        }
    }
}

/// A fixed-size piece of one range: `count` primitives from `first` (absolute), of tree
/// instance `instance` — or, when `instance` is [`GATHERED`], `count` slots of
/// [`FrameChunks::gathered`] from `first`; `param` is the line width or point size in
/// pixels, or for triangles 0 (trunk) or 1 (leaves).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct GpuChunk {
    /// Index into the frame's instance records, or [`GATHERED`].
    pub instance: u32,
    /// First primitive (triangle index or primitive index), or first gathered slot.
    pub first: u32,
    /// Primitives in this chunk, at most the kind's chunk size.
    pub count: u32,
    /// Width, size or part.
    pub param: u32,
}

/// `param` of trunk triangle chunks.
pub const PART_TRUNK: u32 = 0;
/// `param` of leaf triangle chunks.
pub const PART_LEAVES: u32 = 1;

/// The primitive kinds of the pass, in draw order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum PrimitiveKind {
    /// Lit trunk triangles, back faces culled.
    TrunkTriangles,
    /// Lit two-sided leaf triangles.
    LeafTriangles,
    /// Flat screen-space lines.
    Lines,
    /// Lit screen-space points: squares, or discs from a few pixels on.
    Points,
}

impl PrimitiveKind {
    /// Every kind, in draw order.
    pub const ALL: [Self; 4] = [
        Self::TrunkTriangles,
        Self::LeafTriangles,
        Self::Lines,
        Self::Points,
    ];

    /// Primitives per chunk.
    pub const fn per_chunk(self) -> u32 {
        match self {
            Self::TrunkTriangles | Self::LeafTriangles => TRIANGLES_PER_CHUNK,
            Self::Lines => LINES_PER_CHUNK,
            Self::Points => POINTS_PER_CHUNK,
        }
    }
}

/// A frame's chunks, per primitive kind.
///
/// Every chunk is drawn with the kind's full vertex count, so a chunk holding one
/// primitive costs as many vertex invocations as a full one. Runs are therefore split:
/// whole chunks of a run are drawn directly from the model's range, and what is left of
/// each run (every run shorter than a chunk, and the tails of longer ones) is gathered
/// per kind and width/size into a list of `(instance, primitive)` pairs and chunked from
/// there, so only one chunk per kind and parameter is partly filled. (Before, a tree
/// drawn at its cheapest — a point or two per leaf group — filled 1 in 32 slots of
/// each of its ~25 point chunks, and the wasted invocations cost more than the whole
/// budgeted pass.)
#[derive(Clone, Debug, Default)]
pub struct FrameChunks {
    /// Per kind in [`PrimitiveKind::ALL`] order.
    pub kinds: [Vec<GpuChunk>; 4],
    /// `(instance, primitive)` of each slot of the gathered chunks
    /// ([`GpuChunk::instance`] = [`GATHERED`]), which index this list.
    pub gathered: Vec<[u32; 2]>,
    /// Per kind, leftover primitives waiting for [`finish`](Self::finish):
    /// `(param, instance, primitive)`.
    pending: [Vec<(u32, u32, u32)>; 4],
}

/// What [`FrameChunks::mark`] remembers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ChunksMark {
    kinds: [usize; 4],
    pending: [usize; 4],
}

/// The widest line and the largest point the pass draws, pixels: a wider width or a
/// larger size in a draw list is drawn at this one. (The level of detail picks up to
/// 20 pixels, where primitives stop paying for themselves against triangles.)
pub const MAX_PRIMITIVE_PIXELS: u32 = 64;

/// [`GpuChunk::instance`] of a chunk whose slots are listed in [`FrameChunks::gathered`]
/// from [`GpuChunk::first`] on.
pub const GATHERED: u32 = u32::MAX;

impl FrameChunks {
    /// Empties every kind, keeping the allocations.
    pub fn clear(&mut self) {
        self.kinds.iter_mut().for_each(Vec::clear);
        self.pending.iter_mut().for_each(Vec::clear);
        self.gathered.clear();
    }

    /// The chunks of one kind (complete after [`finish`](Self::finish)).
    pub fn of(&self, kind: PrimitiveKind) -> &[GpuChunk] {
        &self.kinds[kind as usize]
    }

    /// The `(instance, primitive)` of every slot of `chunk`.
    pub fn slots(&self, chunk: &GpuChunk) -> impl Iterator<Item = (u32, u32)> + '_ {
        let (first, count) = (chunk.first as usize, chunk.count as usize);
        let (gathered, direct) = if chunk.instance == GATHERED {
            (
                self.gathered.get(first..first + count).unwrap_or_default(),
                0..0,
            )
        } else {
            (&[][..], chunk.first..chunk.first + chunk.count)
        };
        let instance = chunk.instance;
        gathered
            .iter()
            .map(|&[i, p]| (i, p))
            .chain(direct.map(move |p| (instance, p)))
    }

    /// Appends the chunks of instance `instance` drawing `list` of the model at `slot`.
    /// Call [`finish`](Self::finish) once every instance is in.
    pub fn push(&mut self, instance: u32, slot: &ModelSlot, list: &TreeDrawList) {
        let trunk = clip(&list.trunk_triangles, slot.trunk_triangle_count);
        self.push_range(
            PrimitiveKind::TrunkTriangles,
            instance,
            slot.trunk_triangles + trunk.start..slot.trunk_triangles + trunk.end,
            PART_TRUNK,
        );
        for leaves in &list.leaf_triangles {
            self.push_range(
                PrimitiveKind::LeafTriangles,
                instance,
                slot.leaf_triangle_range(leaves),
                PART_LEAVES,
            );
        }
        for run in &list.trunk_lines {
            let r = clip(&run.segments, slot.line_count);
            self.push_range(
                PrimitiveKind::Lines,
                instance,
                slot.lines + r.start..slot.lines + r.end,
                run.width.clamp(1, MAX_PRIMITIVE_PIXELS),
            );
        }
        for run in &list.leaf_points {
            let r = clip(&run.leaves, slot.point_count);
            self.push_range(
                PrimitiveKind::Points,
                instance,
                slot.points + r.start..slot.points + r.end,
                run.size.clamp(1, MAX_PRIMITIVE_PIXELS),
            );
        }
    }

    /// Where the chunks stand now, to go back to with [`truncate`](Self::truncate).
    pub fn mark(&self) -> ChunksMark {
        ChunksMark {
            kinds: self.kinds.each_ref().map(Vec::len),
            pending: self.pending.each_ref().map(Vec::len),
        }
    }

    /// Drops what was pushed since `mark` (before [`finish`](Self::finish)).
    pub fn truncate(&mut self, mark: ChunksMark) {
        for (kind, len) in self.kinds.iter_mut().zip(mark.kinds) {
            kind.truncate(len);
        }
        for (pending, len) in self.pending.iter_mut().zip(mark.pending) {
            pending.truncate(len);
        }
    }

    /// The most chunks and gathered slots [`finish`](Self::finish) can leave with what
    /// was pushed so far: the leftovers of each kind fill whole chunks but for one per
    /// line width or point size ([`MAX_PRIMITIVE_PIXELS`] at most).
    pub fn len_bound(&self) -> (usize, usize) {
        let mut chunks = 0;
        let mut gathered = 0;
        for (kind, (done, pending)) in PrimitiveKind::ALL
            .into_iter()
            .zip(self.kinds.iter().zip(&self.pending))
        {
            // Parameters are line widths and point sizes (or the two triangle parts).
            let params = pending.len().min(MAX_PRIMITIVE_PIXELS as usize);
            chunks += done.len() + pending.len() / kind.per_chunk() as usize + params;
            gathered += pending.len();
        }
        (chunks, gathered + self.gathered.len())
    }

    /// Chunks the gathered leftovers: per kind, by parameter, in the order they came.
    pub fn finish(&mut self) {
        for (kind, pending) in PrimitiveKind::ALL.into_iter().zip(&mut self.pending) {
            pending.sort_by_key(|p| p.0);
            let per_chunk = kind.per_chunk() as usize;
            let out = &mut self.kinds[kind as usize];
            for run in pending.chunk_by(|a, b| a.0 == b.0) {
                for piece in run.chunks(per_chunk) {
                    out.push(GpuChunk {
                        instance: GATHERED,
                        first: self.gathered.len() as u32,
                        count: piece.len() as u32,
                        param: piece[0].0,
                    });
                    self.gathered.extend(piece.iter().map(|p| [p.1, p.2]));
                }
            }
            pending.clear();
        }
    }

    fn push_range(&mut self, kind: PrimitiveKind, instance: u32, range: Range<u32>, param: u32) {
        let per_chunk = kind.per_chunk();
        let whole = range.len() as u32 / per_chunk * per_chunk;
        let out = &mut self.kinds[kind as usize];
        for first in (range.start..range.start + whole).step_by(per_chunk as usize) {
            out.push(GpuChunk {
                instance,
                first,
                count: per_chunk,
                param,
            });
        }
        self.pending[kind as usize]
            .extend((range.start + whole..range.end).map(|p| (param, instance, p)));
    }
}
