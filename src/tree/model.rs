//! The analysed tree: a hierarchy of rings (the ends of generalized cylinders), the
//! trunk segments between them sorted thin → thick, and the leaves gathered in groups
//! around terminal rings — everything the LOD, culling, wind and the renderer read.

use core::ops::Range;

use bevy::asset::Asset;
use bevy::math::Vec3;
use bevy::reflect::TypePath;
use serde::{Deserialize, Serialize};

use super::crown::Crown;

/// Marks "no ring" in [`Ring::parent`].
pub const NO_RING: u32 = u32::MAX;

/// An axis-aligned box.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Bounds {
    /// Smallest corner.
    pub min: Vec3,
    /// Largest corner.
    pub max: Vec3,
}

impl Bounds {
    /// The empty box (contains nothing, grows to the first point added).
    pub(crate) const EMPTY: Self = Self {
        min: Vec3::splat(f32::INFINITY),
        max: Vec3::splat(f32::NEG_INFINITY),
    };

    /// The smallest box around `points` ([`Bounds::EMPTY`] for none).
    pub(crate) fn from_points(points: impl IntoIterator<Item = Vec3>) -> Self {
        points.into_iter().fold(Self::EMPTY, Self::grown)
    }

    /// This box grown to contain `p`.
    pub(crate) fn grown(self, p: Vec3) -> Self {
        Self {
            min: self.min.min(p),
            max: self.max.max(p),
        }
    }

    /// The smallest box containing both.
    pub(crate) fn union(self, other: Self) -> Self {
        Self {
            min: self.min.min(other.min),
            max: self.max.max(other.max),
        }
    }

    /// Whether `p` lies inside or on the box, with `tolerance` slack.
    pub fn contains(&self, p: Vec3, tolerance: f32) -> bool {
        p.cmpge(self.min - tolerance).all() && p.cmple(self.max + tolerance).all()
    }

    /// Centre of the box.
    pub fn center(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }

    /// Half the box's extent along each axis.
    pub fn half_extents(&self) -> Vec3 {
        (self.max - self.min) * 0.5
    }

    /// Whether the box contains no point.
    pub(crate) fn is_empty(&self) -> bool {
        self.min.cmpgt(self.max).any()
    }
}

/// A bounding sphere.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct BoundingSphere {
    /// Centre.
    pub center: Vec3,
    /// Radius.
    pub radius: f32,
}

/// A ring ("radio" in the thesis): the loop of vertices where two generalized cylinders
/// meet, one node of the trunk hierarchy.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Ring {
    /// Average of its vertices.
    pub center: Vec3,
    /// Average distance from the centre to its vertices, doubled (0 for a branch tip).
    pub diameter: f32,
    /// Parent ring, or [`NO_RING`] for a root ring.
    pub parent: u32,
    /// Child rings.
    pub children: Vec<u32>,
    /// Depth in the hierarchy: 0 for a root ring.
    pub level: u32,
    /// Distance from the parent ring's centre (0 for a root ring).
    pub distance_to_parent: f32,
    /// Range of this ring's vertices in [`TreeModel::ring_vertices`] and
    /// [`TreeModel::ring_vectors`].
    pub vertices: Range<u32>,
    /// Leaf group hanging from this ring, if it is terminal and has leaves.
    pub leaf_group: Option<u32>,
}

impl Ring {
    /// A ring with no children: a branch ends here.
    pub fn is_terminal(&self) -> bool {
        self.children.is_empty()
    }

    /// A ring without a parent: the bottom of a hierarchy.
    pub fn is_root(&self) -> bool {
        self.parent == NO_RING
    }
}

/// The trunk segments — two connected rings each — sorted by diameter ascending, as
/// parallel arrays (index `s` in each describes segment `s`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Segments {
    /// The segment's upper ring; its lower ring is that ring's parent.
    pub ring: Vec<u32>,
    /// Prefix offsets into [`TreeModel::trunk_indices`], in triangles: segment `s` owns
    /// triangles `triangle_offsets[s]..triangle_offsets[s + 1]`. Length `segments + 1`.
    /// Segments may own different numbers of triangles (a branch joined to its parent by
    /// proximity owns none).
    pub triangle_offsets: Vec<u32>,
    /// The line drawn instead of the triangles: the two ring centres (lower, upper).
    pub line: Vec<[Vec3; 2]>,
    /// The larger of its two rings' diameters.
    pub diameter: Vec<f32>,
    /// Length of this and every thinner segment's line: `cumulative_length[s]` is the
    /// summed length of segments `0..=s`.
    pub cumulative_length: Vec<f32>,
}

impl Segments {
    /// Number of segments.
    pub fn len(&self) -> usize {
        self.ring.len()
    }

    /// The diameters of the segments, clipped to their number (a model that was not
    /// validated may have more).
    pub(crate) fn diameters(&self) -> &[f32] {
        &self.diameter[..self.len().min(self.diameter.len())]
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.ring.is_empty()
    }

    /// Triangles of segment `s`, as a range of triangle indices.
    pub fn triangles(&self, s: usize) -> Range<u32> {
        self.triangle_offsets[s]..self.triangle_offsets[s + 1]
    }
}

/// The leaves around one terminal ring.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LeafGroup {
    /// The terminal ring the group hangs from (wind moves the group with it).
    pub ring: u32,
    /// Bounding sphere of every leaf vertex of the group.
    pub bounds: BoundingSphere,
    /// The group's leaves in [`TreeModel::leaves`], sorted near → far from the centre.
    pub leaves: Range<u32>,
}

/// One leaf: a connected patch of leaf triangles (often a single triangle or a quad).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Leaf {
    /// Area-weighted centre of its triangles: where its point is drawn.
    pub center: Vec3,
    /// Area-weighted unit normal: how its point is lit.
    pub normal: Vec3,
    /// Its triangles in [`TreeModel::leaf_indices`].
    pub triangles: Range<u32>,
    /// The leaf group it belongs to (whose terminal ring carries it in the wind).
    pub group: u32,
}

/// Linear RGB colour, as stored in models (the renderer converts it).
pub type LinearRgb = [f32; 3];

/// An analysed tree type. Built by [`analyze`](super::analyze) from a trunk mesh and a
/// leaves mesh, or loaded from a species or model file.
///
/// Geometry is stored once per tree type, reorganised so that every LOD decision is a
/// contiguous range: trunk triangles grouped by segment (thin → thick), leaf triangles
/// grouped by leaf, leaves grouped by leaf group (near → far within a group).
#[derive(Asset, TypePath, Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TreeModel {
    /// The rings of every hierarchy; root rings have no parent.
    pub rings: Vec<Ring>,
    /// Trunk vertex index of every ring vertex, ring by ring (see [`Ring::vertices`]).
    pub ring_vertices: Vec<u32>,
    /// Vector from the ring's centre to each ring vertex, parallel to `ring_vertices`.
    pub ring_vectors: Vec<Vec3>,
    /// The trunk segments, sorted thin → thick.
    pub segments: Segments,

    /// Trunk vertex positions (welded).
    pub trunk_positions: Vec<Vec3>,
    /// Trunk vertex normals.
    pub trunk_normals: Vec<Vec3>,
    /// The ring every trunk vertex belongs to, for per-ring wind offsets on the GPU.
    pub trunk_vertex_ring: Vec<u32>,
    /// Trunk triangles (three vertex indices each), grouped by segment in segment order.
    pub trunk_indices: Vec<u32>,

    /// Leaf vertex positions (welded).
    pub leaf_positions: Vec<Vec3>,
    /// Leaf vertex normals.
    pub leaf_normals: Vec<Vec3>,
    /// The leaf every leaf vertex belongs to.
    pub leaf_vertex_leaf: Vec<u32>,
    /// Leaf triangles (three vertex indices each), grouped by leaf in leaf order.
    pub leaf_indices: Vec<u32>,
    /// Every leaf, grouped by leaf group, near → far within each group.
    pub leaves: Vec<Leaf>,
    /// The leaf groups.
    pub leaf_groups: Vec<LeafGroup>,

    /// Box around the whole tree.
    pub bounds: Bounds,
    /// Box around the trunk only.
    pub trunk_bounds: Bounds,
    /// Mean area of a leaf triangle.
    pub mean_leaf_triangle_area: f32,
    /// Mean area of a trunk triangle.
    pub mean_trunk_triangle_area: f32,
    /// Area-weighted centre of the trunk's triangles: projecting the trunk's area at this
    /// point's depth beats using the box centre (thesis §4.2).
    pub trunk_area_center: Vec3,
    /// Colour lines are drawn with (mean bark colour).
    pub bark_color: LinearRgb,
    /// Colour points are drawn with (mean leaf colour).
    pub leaf_color: LinearRgb,
    /// The leaves seen as one disc: a far tree's cheapest drawing of its leaves (`None`
    /// without leaves, and for group impostors, which stand for many crowns). Addressed
    /// by [`TreeDrawList`](crate::draw::TreeDrawList) as leaf
    /// [`crown_leaf`](Self::crown_leaf).
    pub crown: Option<Crown>,
}

impl TreeModel {
    /// Number of trunk triangles.
    pub fn trunk_triangle_count(&self) -> usize {
        self.trunk_indices.len() / 3
    }

    /// Number of leaf triangles.
    pub fn leaf_triangle_count(&self) -> usize {
        self.leaf_indices.len() / 3
    }

    /// The leaf index a [`TreeDrawList`](crate::draw::TreeDrawList) draws the
    /// [crown](Self::crown) disc with, as a point: `2 · leaves.len()`, after the leaves'
    /// two orders.
    pub fn crown_leaf(&self) -> u32 {
        2 * self.leaves.len() as u32
    }

    /// The ring vertices of ring `ring` (trunk vertex indices).
    #[cfg(test)]
    pub(crate) fn vertices_of(&self, ring: u32) -> &[u32] {
        let r = &self.rings[ring as usize].vertices;
        &self.ring_vertices[r.start as usize..r.end as usize]
    }

    /// The leaf group's leaves.
    #[cfg(test)]
    pub(crate) fn leaves_of(&self, group: usize) -> &[Leaf] {
        let r = &self.leaf_groups[group].leaves;
        &self.leaves[r.start as usize..r.end as usize]
    }

    /// Indices of the root rings.
    pub fn roots(&self) -> impl Iterator<Item = u32> + '_ {
        (0..self.rings.len() as u32).filter(|&r| self.rings[r as usize].is_root())
    }

    /// Every leaf once, in *far-first order*: each group's farthest leaf (groups in
    /// order), then the leaves ordered by how far in from their group's far end they
    /// sit, as a fraction of the group's size.
    ///
    /// So the first `k` leaves of this order are, in every group at once, the group's
    /// share of `k` taken from its far end — at least one leaf of every non-empty group
    /// once `k` reaches the number of non-empty groups — and the last `k` are every
    /// group's near leaves. A tree far enough away to be chosen as a whole draws its
    /// leaves as one or two runs of this order instead of one or two per group (see
    /// [`TreeDrawList`](crate::draw::TreeDrawList), which addresses it as leaves
    /// `leaves.len()..2 · leaves.len()`).
    pub(crate) fn far_first_leaves(&self) -> Vec<u32> {
        // (group, steps in from the far end, group size); ordered by steps / size, exactly.
        let mut keyed: Vec<(u32, u32, u32)> = self
            .leaf_groups
            .iter()
            .enumerate()
            .flat_map(|(g, group)| {
                let len = group.leaves.end.saturating_sub(group.leaves.start);
                (0..len).map(move |steps| (g as u32, steps, len))
            })
            .collect();
        keyed.sort_by(|a, b| {
            (u64::from(a.1) * u64::from(b.2))
                .cmp(&(u64::from(b.1) * u64::from(a.2)))
                .then(a.0.cmp(&b.0))
        });
        keyed
            .into_iter()
            .map(|(g, steps, _)| self.leaf_groups[g as usize].leaves.end - 1 - steps)
            .collect()
    }
}
