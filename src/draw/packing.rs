//! The pure packing of tree geometry and draw lists into the compact records the forest
//! pass uploads: every model's geometry in one [`GeometryAtlas`], every frame's draw lists
//! cut into fixed-size chunks ([`FrameChunks`]). No GPU types, so it is tested headless.

use core::ops::Range;

use bytemuck::{Pod, Zeroable};

use super::{MAX_PRIMITIVE_PIXELS, ModelSlot, TreeDrawList, both_orders, clip};
use crate::tree::{NO_RING, TreeModel};

/// Triangles per triangle chunk.
pub(crate) const TRIANGLES_PER_CHUNK: u32 = 32;
/// Segments per line chunk.
pub(crate) const LINES_PER_CHUNK: u32 = 16;
/// Leaves per point chunk.
pub(crate) const POINTS_PER_CHUNK: u32 = 32;

/// One vertex of the packed geometry (trunk and leaves alike).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub(crate) struct GpuVertex {
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
pub(crate) struct GpuPrimitive {
    /// Line: lower end. Point: centre.
    pub a: [f32; 3],
    /// Ring moving `a`.
    pub ring_a: u32,
    /// Line: upper end. Point: normal.
    pub b: [f32; 3],
    /// Line: ring moving `b`. Point: unused.
    pub ring_b: u32,
}

/// Every tree model's geometry packed into three arrays, uploaded once and shared by all
/// instances: vertices, triangle indices (absolute into `vertices`), and line/point
/// primitives. Leaf triangles are stored leaf after leaf, so a range of leaves is a range
/// of triangles.
#[derive(Clone, Debug, Default)]
pub(crate) struct GeometryAtlas {
    /// Packed vertices.
    pub vertices: Vec<GpuVertex>,
    /// Triangle indices into `vertices`, three per triangle.
    pub indices: Vec<u32>,
    /// Segment lines and leaf points.
    pub primitives: Vec<GpuPrimitive>,
    /// How many vertices, indices and primitives were [taken](Self::take) before these:
    /// a model appended later is placed after them.
    taken: [u32; 3],
}

impl GeometryAtlas {
    /// The vertices, indices and primitives appended since the last call, for upload;
    /// models appended afterwards are placed after them.
    pub(crate) fn take(&mut self) -> (Vec<GpuVertex>, Vec<u32>, Vec<GpuPrimitive>) {
        self.taken[0] += self.vertices.len() as u32;
        self.taken[1] += self.indices.len() as u32;
        self.taken[2] += self.primitives.len() as u32;
        (
            core::mem::take(&mut self.vertices),
            core::mem::take(&mut self.indices),
            core::mem::take(&mut self.primitives),
        )
    }

    /// Appends a model and returns where it went. Leaf triangles and points are stored
    /// twice, in the two orders [`TreeDrawList`] addresses (the vertices once).
    pub(crate) fn push(&mut self, model: &TreeModel) -> ModelSlot {
        let far_first = model.far_first_leaves();
        let first_triangle = |atlas: &Self| (atlas.taken[1] + atlas.indices.len() as u32) / 3;
        let base = self.taken[0] + self.vertices.len() as u32;
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

        let leaf_base = self.taken[0] + self.vertices.len() as u32;
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

        let lines = self.taken[2] + self.primitives.len() as u32;
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
        let points = self.taken[2] + self.primitives.len() as u32;
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
        self.primitives
            .extend(model.crown.map(|crown| GpuPrimitive {
                a: crown.center.to_array(),
                ring_a: crown.ring,
                b: crown.normal.to_array(),
                ring_b: NO_RING,
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
pub(crate) struct GpuChunk {
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
pub(crate) const PART_TRUNK: u32 = 0;
/// `param` of leaf triangle chunks.
pub(crate) const PART_LEAVES: u32 = 1;

/// The primitive kinds of the pass, in draw order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub(crate) enum PrimitiveKind {
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
    pub(crate) const ALL: [Self; 4] = [
        Self::TrunkTriangles,
        Self::LeafTriangles,
        Self::Lines,
        Self::Points,
    ];

    /// Primitives per chunk.
    pub(crate) const fn per_chunk(self) -> u32 {
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
pub(crate) struct FrameChunks {
    /// Per kind in [`PrimitiveKind::ALL`] order.
    pub kinds: [Vec<GpuChunk>; 4],
    /// `(instance, primitive)` of each slot of the gathered chunks
    /// ([`GpuChunk::instance`] = [`GATHERED`]), which index this list.
    pub gathered: Vec<[u32; 2]>,
    /// Per kind, leftover primitives waiting for [`finish`](Self::finish):
    /// `(param, instance, primitive)`.
    pending: [Vec<(u32, u32, u32)>; 4],
    /// [`finish`](Self::finish)'s scratch: a kind's leftovers in parameter order.
    by_param: Vec<(u32, u32, u32)>,
}

/// What [`FrameChunks::mark`] remembers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg(feature = "render")]
pub(crate) struct ChunksMark {
    kinds: [usize; 4],
    pending: [usize; 4],
}

/// [`GpuChunk::instance`] of a chunk whose slots are listed in [`FrameChunks::gathered`]
/// from [`GpuChunk::first`] on.
pub(crate) const GATHERED: u32 = u32::MAX;

impl FrameChunks {
    /// Empties every kind, keeping the allocations.
    #[cfg(feature = "render")]
    pub(crate) fn clear(&mut self) {
        self.kinds.iter_mut().for_each(Vec::clear);
        self.pending.iter_mut().for_each(Vec::clear);
        self.gathered.clear();
    }

    /// The chunks of one kind (complete after [`finish`](Self::finish)).
    pub(crate) fn of(&self, kind: PrimitiveKind) -> &[GpuChunk] {
        &self.kinds[kind as usize]
    }

    /// The `(instance, primitive)` of every slot of `chunk`.
    #[cfg(test)]
    pub(crate) fn slots(&self, chunk: &GpuChunk) -> impl Iterator<Item = (u32, u32)> + '_ {
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
    pub(crate) fn push(&mut self, instance: u32, slot: &ModelSlot, list: &TreeDrawList) {
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
    #[cfg(feature = "render")]
    pub(crate) fn mark(&self) -> ChunksMark {
        ChunksMark {
            kinds: self.kinds.each_ref().map(Vec::len),
            pending: self.pending.each_ref().map(Vec::len),
        }
    }

    /// Drops what was pushed since `mark` (before [`finish`](Self::finish)).
    #[cfg(feature = "render")]
    pub(crate) fn truncate(&mut self, mark: ChunksMark) {
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
    #[cfg(feature = "render")]
    pub(crate) fn len_bound(&self) -> (usize, usize) {
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
    pub(crate) fn finish(&mut self) {
        for (kind, pending) in PrimitiveKind::ALL.into_iter().zip(&mut self.pending) {
            let sorted = &mut self.by_param;
            sort_by_param(pending, sorted);
            let per_chunk = kind.per_chunk() as usize;
            let out = &mut self.kinds[kind as usize];
            for run in sorted.chunk_by(|a, b| a.0 == b.0) {
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
        let param = param.min(MAX_PRIMITIVE_PIXELS);
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

/// `pending` in ascending parameter order into `sorted`, each parameter's entries in the
/// order they came (a stable sort): a counting sort, since parameters are at most
/// [`MAX_PRIMITIVE_PIXELS`] (`push_range` clamps them). A large forest leaves a hundred
/// thousand leftovers a frame, and a comparison sort of them took a millisecond.
fn sort_by_param(pending: &[(u32, u32, u32)], sorted: &mut Vec<(u32, u32, u32)>) {
    const PARAMS: usize = MAX_PRIMITIVE_PIXELS as usize + 1;
    let mut starts = [0usize; PARAMS + 1];
    for p in pending {
        starts[p.0 as usize + 1] += 1;
    }
    for i in 1..=PARAMS {
        starts[i] += starts[i - 1];
    }
    sorted.clear();
    sorted.resize(pending.len(), (0, 0, 0));
    for &p in pending {
        let slot = &mut starts[p.0 as usize];
        sorted[*slot] = p;
        *slot += 1;
    }
}
