//! Packing tree geometry and draw lists into the render pass's records (pure, headless).

use crate::testing as common;
use common::species;

use crate::draw::packing::*;
use crate::draw::*;
use crate::tree::TreeModel;
use bevy::math::Vec3;
use proptest::prelude::*;

#[test]
fn the_atlas_keeps_each_model_apart_and_addresses_leaves_by_range() {
    let (slender, broad) = (species("slender"), species("broad"));
    let mut atlas = GeometryAtlas::default();
    let a = atlas.push(&slender);
    let b = atlas.push(&broad);
    let vertices = atlas.vertices.len() as u32;
    assert!(atlas.indices.iter().all(|&i| i < vertices));
    assert_eq!(
        b.trunk_triangles,
        a.leaf_triangles + a.leaf_triangle_prefix[a.point_count as usize]
    );
    // The second model's trunk triangles use the second model's vertices, which start
    // after all of the first model's.
    let first_of_b = (slender.trunk_positions.len() + slender.leaf_positions.len()) as u32;
    let trunk_b = &atlas.indices[b.trunk_triangles as usize * 3..][..broad.trunk_indices.len()];
    assert!(trunk_b.iter().all(|&i| i >= first_of_b));
    for (i, (&packed, &own)) in trunk_b.iter().zip(&broad.trunk_indices).enumerate() {
        assert_eq!(packed, own + first_of_b, "index {i}");
    }
    // Leaf `l`'s packed triangles are its own triangles, whatever order the model keeps.
    for (l, leaf) in broad.leaves.iter().enumerate() {
        let packed = b.leaf_triangles + b.leaf_triangle_prefix[l];
        assert_eq!(
            b.leaf_triangle_prefix[l + 1] - b.leaf_triangle_prefix[l],
            leaf.triangles.len() as u32
        );
        let leaf_base = first_of_b + broad.trunk_positions.len() as u32;
        for t in 0..leaf.triangles.len() {
            for k in 0..3 {
                let own = broad.leaf_indices[(leaf.triangles.start as usize + t) * 3 + k];
                assert_eq!(
                    atlas.indices[(packed as usize + t) * 3 + k],
                    own + leaf_base
                );
            }
        }
    }
    // Lines join each segment's rings; points sit at leaf centres.
    let line = atlas.primitives[(b.lines) as usize];
    assert_eq!(Vec3::from(line.b), broad.segments.line[0][1]);
    let point = atlas.primitives[(b.points + 3) as usize];
    assert_eq!(Vec3::from(point.a), broad.leaves[3].center);
    assert_eq!(
        point.ring_a,
        broad.leaf_groups[broad.leaves[3].group as usize].ring
    );
}

/// A model appended after the atlas was taken for upload is placed, and its indices
/// point, after everything taken: the uploads together are the atlas packed at once.
#[test]
fn a_model_appended_after_an_upload_lands_where_packing_all_at_once_puts_it() {
    let (slender, broad) = (species("slender"), species("broad"));
    let mut whole = GeometryAtlas::default();
    let whole_slots = [whole.push(&slender), whole.push(&broad)];
    let mut appended = GeometryAtlas::default();
    let first = appended.push(&slender);
    let (mut vertices, mut indices, mut primitives) = appended.take();
    let second = appended.push(&broad);
    let (more_vertices, more_indices, more_primitives) = appended.take();
    assert_eq!([first, second], whole_slots);
    vertices.extend(more_vertices);
    indices.extend(more_indices);
    primitives.extend(more_primitives);
    assert!(vertices == whole.vertices, "vertices differ");
    assert!(indices == whole.indices, "indices differ");
    assert!(primitives == whole.primitives, "lines and points differ");
    assert!(appended.take().0.is_empty(), "taken once");
}

#[test]
fn leaves_past_the_model_s_count_are_its_far_first_order() {
    let model = species("broad");
    let mut atlas = GeometryAtlas::default();
    let slot = atlas.push(&model);
    let n = model.leaves.len() as u32;
    // Both orders, then the crown disc.
    assert_eq!(slot.point_count, 2 * n + 1);
    let crown = model.crown.unwrap();
    let disc = &atlas.primitives[(slot.points + model.crown_leaf()) as usize];
    assert_eq!(
        (disc.a, disc.ring_a, disc.b),
        (crown.center.to_array(), crown.ring, crown.normal.to_array())
    );
    let crown_leaf = model.crown_leaf();
    assert!(
        slot.leaf_triangle_range(&(crown_leaf..crown_leaf + 1))
            .is_empty()
    );
    let far_first = model.far_first_leaves();
    for (i, &leaf) in far_first.iter().enumerate() {
        let index = n + i as u32;
        // The same point, and the same triangles, as the leaf in the model's own order.
        assert_eq!(
            atlas.primitives[(slot.points + index) as usize],
            atlas.primitives[(slot.points + leaf) as usize]
        );
        let (own, far) = (
            slot.leaf_triangle_range(&(leaf..leaf + 1)),
            slot.leaf_triangle_range(&(index..index + 1)),
        );
        assert_eq!(own.len(), far.len());
        let triangle = |t: u32| &atlas.indices[t as usize * 3..t as usize * 3 + 3];
        for (a, b) in own.zip(far) {
            assert_eq!(triangle(a), triangle(b));
        }
    }
    // Counting and chunking see a far-first range like any other.
    let list = TreeDrawList {
        leaf_points: vec![PointRun {
            leaves: n..n + 40,
            size: 2,
        }],
        ..Default::default()
    };
    assert_eq!(
        slot.counts(&list),
        PrimitiveCounts {
            triangles: 0,
            lines: 0,
            points: 40
        }
    );
}

#[test]
fn full_detail_is_every_triangle_in_few_chunks() {
    let model = species("grand");
    let mut atlas = GeometryAtlas::default();
    let slot = atlas.push(&model);
    let list = TreeDrawList::full(&model);
    let counts = slot.counts(&list);
    assert_eq!(
        counts,
        PrimitiveCounts {
            triangles: (model.trunk_triangle_count() + model.leaf_triangle_count()) as u64,
            lines: 0,
            points: 0,
        }
    );
    let mut chunks = FrameChunks::default();
    chunks.push(7, &slot, &list);
    chunks.finish();
    let trunk = chunks.of(PrimitiveKind::TrunkTriangles);
    assert_eq!(
        trunk.len() as u32,
        (model.trunk_triangle_count() as u32).div_ceil(TRIANGLES_PER_CHUNK)
    );
    assert!(trunk.iter().all(|c| c.param == PART_TRUNK));
    // Whole chunks are drawn straight from the range, the tail is gathered.
    let partial = trunk
        .iter()
        .filter(|c| c.count < TRIANGLES_PER_CHUNK)
        .count();
    assert!(partial <= 1);
    assert!(
        trunk
            .iter()
            .all(|c| (c.instance == 7) == (c.count == TRIANGLES_PER_CHUNK))
    );
    assert!(chunks.of(PrimitiveKind::Lines).is_empty());
    assert!(chunks.of(PrimitiveKind::Points).is_empty());
}

#[test]
fn ranges_past_the_model_are_clipped_not_trusted() {
    let model = species("slender");
    let mut atlas = GeometryAtlas::default();
    let slot = atlas.push(&model);
    let leaves = model.leaves.len() as u32;
    let segments = model.segments.len() as u32;
    let list = TreeDrawList {
        trunk_triangles: 10..u32::MAX,
        trunk_lines: vec![LineRun {
            segments: segments - 1..segments + 40,
            width: 0,
        }],
        // Past both orders of the leaves.
        leaf_triangles: std::iter::once(2 * leaves + 5..2 * leaves + 9).collect(),
        leaf_points: vec![PointRun {
            // Backwards: empty.
            leaves: core::ops::Range { start: 30, end: 10 },
            size: 3,
        }],
    };
    let counts = slot.counts(&list);
    assert_eq!(counts.triangles, model.trunk_triangle_count() as u64 - 10);
    assert_eq!(counts.lines, 1);
    assert_eq!(counts.points, 0);
    let mut chunks = FrameChunks::default();
    chunks.push(0, &slot, &list);
    chunks.finish();
    let lines = chunks.of(PrimitiveKind::Lines);
    assert_eq!(lines.len(), 1);
    assert_eq!(lines[0].param, 1, "a zero width is drawn one pixel wide");
    assert!(chunks.of(PrimitiveKind::LeafTriangles).is_empty());
    assert!(chunks.of(PrimitiveKind::Points).is_empty());
}

#[test]
fn an_empty_list_draws_nothing() {
    let model = species("slender");
    let mut list = TreeDrawList::full(&model);
    assert!(!list.is_empty());
    list.clear();
    assert!(list.is_empty());
    let mut atlas = GeometryAtlas::default();
    let slot = atlas.push(&model);
    let mut chunks = FrameChunks::default();
    chunks.push(0, &slot, &list);
    chunks.finish();
    assert!(PrimitiveKind::ALL.iter().all(|&k| chunks.of(k).is_empty()));
    assert!(chunks.gathered.is_empty());
}

static BROAD: std::sync::LazyLock<TreeModel> = std::sync::LazyLock::new(|| species("broad"));

proptest! {
    /// Chunks tile every requested range exactly once, in order, none empty or oversized.
    #[test]
    fn chunks_tile_the_ranges(
        cuts in proptest::collection::vec(0u32..8000, 0..12),
        widths in proptest::collection::vec(1u32..21, 12),
    ) {
        let model = &*BROAD;
        let mut atlas = GeometryAtlas::default();
        let slot = atlas.push(model);
        let leaves = model.leaves.len() as u32;
        let segments = model.segments.len() as u32;
        // Either order of the leaves, and ranges across both.
        let mut cuts: Vec<u32> = cuts.into_iter().map(|c| c % (2 * leaves + 1)).collect();
        cuts.sort_unstable();
        let mut list = TreeDrawList {
            trunk_triangles: 0..model.trunk_triangle_count() as u32 / 2,
            ..Default::default()
        };
        for (i, pair) in cuts.windows(2).enumerate() {
            if i % 2 == 0 {
                list.leaf_triangles.push(pair[0]..pair[1]);
            } else {
                list.leaf_points.push(PointRun { leaves: pair[0]..pair[1], size: widths[i] });
            }
        }
        let split = segments / 2;
        list.trunk_lines.push(LineRun { segments: 0..split, width: widths[0] });
        list.trunk_lines.push(LineRun { segments: split..segments, width: widths[1] });

        // Two instances, so gathered chunks mix them.
        let mut chunks = FrameChunks::default();
        chunks.push(3, &slot, &list);
        chunks.push(5, &slot, &list);
        chunks.finish();
        let expected = |kind: PrimitiveKind| {
            let mut wanted: Vec<(u32, u32, u32)> = Vec::new();
            for instance in [3, 5] {
                let mut add = |range: core::ops::Range<u32>, param: u32| {
                    wanted.extend(range.map(|p| (instance, p, param)));
                };
                match kind {
                    PrimitiveKind::TrunkTriangles => add(
                        slot.trunk_triangles + list.trunk_triangles.start
                            ..slot.trunk_triangles + list.trunk_triangles.end,
                        PART_TRUNK,
                    ),
                    PrimitiveKind::LeafTriangles => list
                        .leaf_triangles
                        .iter()
                        .for_each(|r| add(slot.leaf_triangle_range(r), PART_LEAVES)),
                    PrimitiveKind::Lines => list.trunk_lines.iter().for_each(|r| {
                        add(slot.lines + r.segments.start..slot.lines + r.segments.end, r.width);
                    }),
                    PrimitiveKind::Points => list.leaf_points.iter().for_each(|r| {
                        add(slot.points + r.leaves.start..slot.points + r.leaves.end, r.size);
                    }),
                }
            }
            wanted.sort_unstable();
            wanted
        };
        // The counts, from the primitives the list names (each instance's once).
        let counts = slot.counts(&list);
        let named = |kind| expected(kind).len() as u64 / 2;
        prop_assert_eq!(
            counts,
            PrimitiveCounts {
                triangles: named(PrimitiveKind::TrunkTriangles) + named(PrimitiveKind::LeafTriangles),
                lines: named(PrimitiveKind::Lines),
                points: named(PrimitiveKind::Points),
            }
        );
        let mut drawn_total = 0;
        for kind in PrimitiveKind::ALL {
            let mut drawn: Vec<(u32, u32, u32)> = Vec::new();
            let mut partial = std::collections::HashSet::new();
            for c in chunks.of(kind) {
                prop_assert!(c.count > 0 && c.count <= kind.per_chunk());
                if c.count < kind.per_chunk() {
                    // At most one partly filled chunk per parameter.
                    prop_assert!(partial.insert(c.param));
                }
                drawn.extend(chunks.slots(c).map(|(i, p)| (i, p, c.param)));
            }
            drawn_total += drawn.len() as u64;
            drawn.sort_unstable();
            // Every requested primitive exactly once, with its instance and width/size.
            prop_assert_eq!(drawn, expected(kind));
        }
        prop_assert_eq!(drawn_total, 2 * (counts.triangles + counts.lines + counts.points));
    }
}

/// The leaves of each group in the first `k` of `order`: how many, and whether they are
/// the group's far end.
fn prefix_per_group(groups: &[core::ops::Range<u32>], order: &[u32], k: usize) -> Vec<(u32, bool)> {
    groups
        .iter()
        .map(|g| {
            let taken: Vec<u32> = order[..k]
                .iter()
                .copied()
                .filter(|l| g.contains(l))
                .collect();
            let count = taken.len() as u32;
            (count, taken.iter().all(|&l| l >= g.end - count))
        })
        .collect()
}

proptest! {
    /// Any prefix of the far-first order takes every group's far leaves in proportion
    /// to its size (within one leaf), and one of every group once it is long enough.
    #[test]
    fn a_far_first_prefix_is_every_group_s_far_share(
        sizes in proptest::collection::vec(1u32..40, 1..30),
        at in 0.0f64..=1.0,
    ) {
        let mut model = BROAD.clone();
        let mut start = 0;
        model.leaf_groups.truncate(1);
        let template = model.leaf_groups[0].clone();
        model.leaf_groups = sizes
            .iter()
            .map(|&len| {
                start += len;
                crate::tree::LeafGroup { leaves: start - len..start, ..template.clone() }
            })
            .collect();
        let total = start as usize;
        let order = model.far_first_leaves();
        let mut sorted = order.clone();
        sorted.sort_unstable();
        prop_assert_eq!(sorted, (0..start).collect::<Vec<_>>(), "a permutation");
        let groups: Vec<_> = model.leaf_groups.iter().map(|g| g.leaves.clone()).collect();
        let k = (at * total as f64) as usize;
        let per_group = prefix_per_group(&groups, &order, k);
        for (g, &(count, far_end)) in per_group.iter().enumerate() {
            prop_assert!(far_end, "group {} takes near leaves first", g);
            prop_assert!(k < groups.len() || count >= 1, "group {} undrawn at {}", g, k);
        }
        // count / size ∈ [t, t + 1/size] for one threshold t shared by all groups.
        let fraction = |g: usize| f64::from(per_group[g].0) / f64::from(sizes[g]);
        let low = (0..sizes.len()).map(fraction).fold(f64::INFINITY, f64::min);
        for (g, &size) in sizes.iter().enumerate() {
            prop_assert!(fraction(g) <= low + 1.0 / f64::from(size) + 1e-9, "group {}", g);
        }
    }
}
