//! How the forest pass draws the frame's chunks: one instanced draw per batch, the points
//! split by shape so that neither shape pays for the other.
//!
//! On a software rasterizer (lavapipe) a fragment shader that may `discard` turns off the
//! early depth test for the whole draw, and a vertex shared by two triangles is shaded
//! twice unless an index buffer names it. So points are never cut out of a square: small
//! ones are squares, larger ones octagons, and every quad or octagon shares its corners
//! through [`CORNER_INDICES`]. Measured with `pass_benchmark` on lavapipe (per point, the
//! old quad with `discard` against these shapes): 1 px 0.66 → 0.49 µs, 4 px 1.3 → 0.84 µs,
//! 10 px 3.1 → 2.6 µs, 20 px 7.4 → 4.2 µs.

use bevy::render::render_resource::Face;

use crate::draw::packing::{
    GpuChunk, LINES_PER_CHUNK, POINTS_PER_CHUNK, PrimitiveKind, TRIANGLES_PER_CHUNK,
};

/// Points of this many pixels and more are drawn round (as octagons of the square's
/// area); smaller ones stay squares. Up to five pixels a disc of a square's area,
/// centred on a pixel, lights the same pixels as the square, or nearly.
pub(crate) const ROUND_FROM_SIZE: u32 = 6;

/// One instanced draw of the forest pass.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(super) enum DrawBatch {
    TrunkTriangles,
    LeafTriangles,
    Lines,
    /// Points below [`ROUND_FROM_SIZE`].
    SquarePoints,
    /// Points of [`ROUND_FROM_SIZE`] and more.
    RoundPoints,
}

/// Indices per quad (two triangles over four corners).
const QUAD_INDICES: u32 = 6;
/// Corners per round point.
const OCTAGON_CORNERS: u32 = 8;
/// Indices per round point: a fan of six triangles.
const OCTAGON_INDICES: u32 = 3 * (OCTAGON_CORNERS - 2);
/// Quads per chunk, at most.
const QUADS: u32 = if LINES_PER_CHUNK > POINTS_PER_CHUNK {
    LINES_PER_CHUNK
} else {
    POINTS_PER_CHUNK
};
const INDEX_COUNT: usize = (QUAD_INDICES * QUADS + OCTAGON_INDICES * POINTS_PER_CHUNK) as usize;

/// The index buffer of the quad and octagon batches: first `QUADS` quads (quad `q` is the
/// triangles `(4q, 4q+1, 4q+2)` and `(4q, 4q+2, 4q+3)`), then `POINTS_PER_CHUNK`
/// octagons (octagon `p` is the fan `(8p, 8p+k, 8p+k+1)`, `k` in `1..7`).
pub(super) const CORNER_INDICES: [u16; INDEX_COUNT] = {
    let mut out = [0u16; INDEX_COUNT];
    let mut i = 0;
    let mut quad = 0;
    while quad < QUADS as u16 {
        let v = 4 * quad;
        let corners = [v, v + 1, v + 2, v, v + 2, v + 3];
        let mut c = 0;
        while c < corners.len() {
            out[i] = corners[c];
            i += 1;
            c += 1;
        }
        quad += 1;
    }
    let mut point = 0;
    while point < POINTS_PER_CHUNK as u16 {
        let v = OCTAGON_CORNERS as u16 * point;
        let mut k = 1;
        while k < OCTAGON_CORNERS as u16 - 1 {
            out[i] = v;
            out[i + 1] = v + k;
            out[i + 2] = v + k + 1;
            i += 3;
            k += 1;
        }
        point += 1;
    }
    out
};

impl DrawBatch {
    /// Every batch, in draw order.
    pub(super) const ALL: [Self; 5] = [
        Self::TrunkTriangles,
        Self::LeafTriangles,
        Self::Lines,
        Self::SquarePoints,
        Self::RoundPoints,
    ];

    /// The batch a chunk of `kind` is drawn in (a point chunk's by its size, `param`).
    pub(super) fn of(kind: PrimitiveKind, chunk: &GpuChunk) -> Self {
        match kind {
            PrimitiveKind::TrunkTriangles => Self::TrunkTriangles,
            PrimitiveKind::LeafTriangles => Self::LeafTriangles,
            PrimitiveKind::Lines => Self::Lines,
            PrimitiveKind::Points if chunk.param < ROUND_FROM_SIZE => Self::SquarePoints,
            PrimitiveKind::Points => Self::RoundPoints,
        }
    }

    /// The primitive kind of its chunks.
    pub(super) fn kind(self) -> PrimitiveKind {
        match self {
            Self::TrunkTriangles => PrimitiveKind::TrunkTriangles,
            Self::LeafTriangles => PrimitiveKind::LeafTriangles,
            Self::Lines => PrimitiveKind::Lines,
            Self::SquarePoints | Self::RoundPoints => PrimitiveKind::Points,
        }
    }

    /// Vertex and fragment entry points, and the faces culled.
    pub(super) fn shaders(self) -> (&'static str, &'static str, Option<Face>) {
        match self {
            Self::TrunkTriangles => ("vs_triangles", "fs_lit", Some(Face::Back)),
            Self::LeafTriangles => ("vs_triangles", "fs_lit", None),
            Self::Lines => ("vs_lines", "fs_flat", None),
            Self::SquarePoints => ("vs_square_points", "fs_flat", None),
            Self::RoundPoints => ("vs_round_points", "fs_flat", None),
        }
    }

    /// What one chunk draws: `(Some(first), count)` indices of [`CORNER_INDICES`], or
    /// `(None, count)` vertices without an index buffer.
    pub(super) fn corners(self) -> (Option<u32>, u32) {
        match self {
            Self::TrunkTriangles | Self::LeafTriangles => (None, 3 * TRIANGLES_PER_CHUNK),
            Self::Lines => (Some(0), QUAD_INDICES * LINES_PER_CHUNK),
            Self::SquarePoints => (Some(0), QUAD_INDICES * POINTS_PER_CHUNK),
            Self::RoundPoints => (
                Some(QUAD_INDICES * QUADS),
                OCTAGON_INDICES * POINTS_PER_CHUNK,
            ),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_index_stays_within_its_chunk_and_every_batch_within_the_buffer() {
        for batch in DrawBatch::ALL {
            let (first, count) = batch.corners();
            let Some(first) = first else {
                continue;
            };
            let (first, count) = (first as usize, count as usize);
            assert!(first + count <= CORNER_INDICES.len(), "{batch:?}");
            let per_chunk = batch.kind().per_chunk();
            let corners = if batch == DrawBatch::RoundPoints {
                OCTAGON_CORNERS
            } else {
                4
            };
            let indices = &CORNER_INDICES[first..first + count];
            assert!(
                indices.iter().all(|&i| u32::from(i) < corners * per_chunk),
                "{batch:?}"
            );
            // Each primitive's triangles use exactly its own corners.
            let per_primitive = count / per_chunk as usize;
            for (p, own) in indices.chunks(per_primitive).enumerate() {
                let mut used: Vec<u16> = own.to_vec();
                used.sort_unstable();
                used.dedup();
                let expected: Vec<u16> = (0..corners as u16)
                    .map(|c| c + corners as u16 * p as u16)
                    .collect();
                assert_eq!(used, expected, "{batch:?} primitive {p}");
            }
        }
    }

    #[test]
    fn points_go_to_the_batch_of_their_shape() {
        let chunk = |param| GpuChunk {
            param,
            ..GpuChunk::default()
        };
        assert_eq!(
            DrawBatch::of(PrimitiveKind::Points, &chunk(ROUND_FROM_SIZE - 1)),
            DrawBatch::SquarePoints
        );
        assert_eq!(
            DrawBatch::of(PrimitiveKind::Points, &chunk(ROUND_FROM_SIZE)),
            DrawBatch::RoundPoints
        );
        for batch in DrawBatch::ALL {
            let param = if batch == DrawBatch::RoundPoints {
                20
            } else {
                1
            };
            assert_eq!(DrawBatch::of(batch.kind(), &chunk(param)), batch);
        }
    }
}
