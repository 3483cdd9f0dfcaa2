//! Tree analysis: the thesis' figures rebuilt by hand, meshes as real tools make them,
//! malformed inputs, and the invariants of every shipped species.

use crate::tree::*;
use bevy::math::Vec3;

/// A ring of `k` vertices around the Y axis at height `y`, centred at `(x, z)`.
fn ring(out: &mut Vec<Vec3>, center: Vec3, radius: f32, k: usize) -> u32 {
    let first = out.len() as u32;
    for j in 0..k {
        let a = core::f32::consts::TAU * j as f32 / k as f32;
        out.push(center + Vec3::new(radius * a.cos(), 0.0, radius * a.sin()));
    }
    first
}

/// Quads between two rings of `k` vertices starting at `a` and `b`.
fn connect(indices: &mut Vec<u32>, a: u32, b: u32, k: u32) {
    for j in 0..k {
        let (a0, a1) = (a + j, a + (j + 1) % k);
        let (b0, b1) = (b + j, b + (j + 1) % k);
        indices.extend([a0, a1, b1, a0, b1, b0]);
    }
}

fn trunk_only(positions: &[Vec3], indices: &[u32]) -> Result<TreeAnalysis, TreeAnalysisError> {
    let trunk = MeshData {
        positions,
        indices,
        ..Default::default()
    };
    analyze(&trunk, &MeshData::default(), &AnalysisOptions::default())
}

/// Thesis figure 2.2: one hierarchy, four rings of four vertices, three cylinders.
fn figure_2_2() -> (Vec<Vec3>, Vec<u32>) {
    let mut p = Vec::new();
    let mut idx = Vec::new();
    let rings: Vec<u32> = [(-0.5, 0.4), (1.0, 0.3), (2.0, 0.2), (3.0, 0.1)]
        .iter()
        .map(|&(y, r)| ring(&mut p, Vec3::new(0.0, y, 0.0), r, 4))
        .collect();
    for w in rings.windows(2) {
        connect(&mut idx, w[0], w[1], 4);
    }
    (p, idx)
}

#[test]
fn figure_2_2_one_chain_of_four_rings() {
    let (p, idx) = figure_2_2();
    let a = trunk_only(&p, &idx).unwrap();
    let m = &a.model;
    assert!(a.warnings.is_empty(), "{:?}", a.warnings);
    assert_eq!(m.rings.len(), 4);
    assert_eq!(m.segments.len(), 3);
    assert_eq!(m.roots().count(), 1);
    let levels: Vec<u32> = m.rings.iter().map(|r| r.level).collect();
    assert_eq!(levels, vec![0, 1, 2, 3]);
    assert_eq!(m.rings.iter().filter(|r| r.is_terminal()).count(), 1);
    for r in &m.rings {
        assert_eq!(r.vertices.len(), 4);
    }
    // Thinnest segment first, each with 8 triangles.
    assert!(m.segments.diameter.windows(2).all(|w| w[0] <= w[1]));
    for s in 0..3 {
        assert_eq!(m.segments.triangles(s).len(), 8);
    }
    assert!((m.rings[0].diameter - 0.8).abs() < 1e-5);
    assert!((m.segments.cumulative_length[2] - 3.5).abs() < 1e-5);
}

#[test]
fn figure_2_3_branching_at_the_root_ring() {
    let mut p = Vec::new();
    let mut idx = Vec::new();
    let root = ring(&mut p, Vec3::new(0.0, -0.5, 0.0), 0.5, 4);
    for dir in [
        Vec3::new(-1.0, 0.0, 0.0),
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(0.0, 0.0, 1.0),
    ] {
        let b = ring(&mut p, Vec3::new(0.0, 1.0, 0.0) + dir, 0.3, 4);
        let c = ring(&mut p, Vec3::new(0.0, 2.0, 0.0) + 2.0 * dir, 0.2, 4);
        connect(&mut idx, root, b, 4);
        connect(&mut idx, b, c, 4);
    }
    let m = trunk_only(&p, &idx).unwrap().model;
    assert_eq!(m.rings.len(), 7);
    assert_eq!(m.segments.len(), 6);
    let root = m.roots().next().unwrap();
    assert_eq!(m.rings[root as usize].children.len(), 3);
    assert_eq!(m.rings.iter().filter(|r| r.is_terminal()).count(), 3);
    assert_eq!(m.rings.iter().filter(|r| r.level == 2).count(), 3);
    assert_eq!(m.trunk_triangle_count(), 6 * 8);
}

#[test]
fn uv_seam_duplicates_are_welded() {
    let (mut p, idx) = figure_2_2();
    // Duplicate every ring's first vertex (a UV seam) and use the copy on one side.
    let mut seam_idx = idx.clone();
    for r in 0..4_u32 {
        let copy = p.len() as u32;
        p.push(p[(r * 4) as usize]);
        for (t, tri) in idx.chunks_exact(3).enumerate() {
            // The quads wrapping from vertex 3 back to 0 use the copy.
            if tri.contains(&(r * 4 + 3)) {
                for i in 0..3 {
                    if seam_idx[t * 3 + i] == r * 4 {
                        seam_idx[t * 3 + i] = copy;
                    }
                }
            }
        }
    }
    let welded = trunk_only(&p, &seam_idx).unwrap().model;
    assert_eq!(welded.rings.len(), 4);
    assert_eq!(welded.trunk_positions.len(), 16);
    assert!(welded.rings.iter().all(|r| r.vertices.len() == 4));
}

/// A trunk (8 vertices per ring) with a branch (4 per ring) modelled as a separate tube
/// that starts inside it, and quad leaves around the branch tip and the trunk top.
fn trunk_with_detached_branch() -> (Vec<Vec3>, Vec<u32>, Vec<Vec3>, Vec<u32>) {
    let mut p = Vec::new();
    let mut idx = Vec::new();
    let trunk: Vec<u32> = [-0.2, 1.0, 2.0, 3.0]
        .iter()
        .map(|&y| ring(&mut p, Vec3::new(0.0, y, 0.0), 0.3, 8))
        .collect();
    for w in trunk.windows(2) {
        connect(&mut idx, w[0], w[1], 8);
    }
    let branch: Vec<u32> = [(0.0, 1.5), (0.8, 2.0), (1.6, 2.5)]
        .iter()
        .map(|&(x, y)| ring(&mut p, Vec3::new(x, y, 0.0), 0.1, 4))
        .collect();
    for w in branch.windows(2) {
        connect(&mut idx, w[0], w[1], 4);
    }
    let mut leaves = Vec::new();
    let mut leaf_idx = Vec::new();
    for (i, c) in [
        Vec3::new(1.9, 2.7, 0.0),
        Vec3::new(2.1, 2.6, 0.2),
        Vec3::new(1.7, 3.0, -0.3),
        Vec3::new(0.0, 3.5, 0.0),
        Vec3::new(0.3, 3.4, 0.2),
    ]
    .iter()
    .enumerate()
    {
        let first = leaves.len() as u32;
        let s = 0.1 + 0.01 * i as f32;
        leaves.extend([
            *c + Vec3::new(-s, 0.0, -s),
            *c + Vec3::new(s, 0.0, -s),
            *c + Vec3::new(s, 0.0, s),
            *c + Vec3::new(-s, 0.0, s),
        ]);
        leaf_idx.extend([first, first + 1, first + 2, first, first + 2, first + 3]);
    }
    (p, idx, leaves, leaf_idx)
}

fn analyze_full(
    p: &[Vec3],
    idx: &[u32],
    l: &[Vec3],
    li: &[u32],
) -> Result<TreeAnalysis, TreeAnalysisError> {
    let trunk = MeshData {
        positions: p,
        indices: idx,
        ..Default::default()
    };
    let leaves = MeshData {
        positions: l,
        indices: li,
        ..Default::default()
    };
    analyze(&trunk, &leaves, &AnalysisOptions::default())
}

#[test]
fn detached_branch_is_attached_to_the_nearest_ring() {
    let (p, idx, l, li) = trunk_with_detached_branch();
    let a = analyze_full(&p, &idx, &l, &li).unwrap();
    let m = &a.model;
    assert!(a.warnings.is_empty(), "{:?}", a.warnings);
    assert_eq!(m.rings.len(), 7);
    // The branch's first ring (centre y = 1.5) hangs from a trunk ring at y = 1 or 2.
    let first = m
        .rings
        .iter()
        .position(|r| (r.center - Vec3::new(0.0, 1.5, 0.0)).length() < 1e-4)
        .unwrap();
    let parent = &m.rings[m.rings[first].parent as usize];
    assert!((parent.center.y - 1.0).abs() < 1e-4 || (parent.center.y - 2.0).abs() < 1e-4);
    assert_eq!(m.rings[first].vertices.len(), 4);
    // The joining segment has no triangles; the rest keep theirs.
    let slot = m
        .segments
        .ring
        .iter()
        .position(|&r| r as usize == first)
        .unwrap();
    assert_eq!(m.segments.triangles(slot).len(), 0);
    assert_eq!(m.trunk_triangle_count(), 3 * 16 + 2 * 8);
    // Different ring sizes in one tree.
    let sizes: std::collections::BTreeSet<usize> =
        m.rings.iter().map(|r| r.vertices.len()).collect();
    assert_eq!(sizes.into_iter().collect::<Vec<_>>(), vec![4, 8]);
}

#[test]
fn leaf_quads_are_single_leaves_grouped_by_nearest_terminal_ring() {
    let (p, idx, l, li) = trunk_with_detached_branch();
    let m = analyze_full(&p, &idx, &l, &li).unwrap().model;
    assert_eq!(m.leaves.len(), 5);
    assert_eq!(m.leaf_triangle_count(), 10);
    assert!(m.leaves.iter().all(|leaf| leaf.triangles.len() == 2));
    assert_eq!(m.leaf_groups.len(), 2);
    let sizes: Vec<usize> = m.leaf_groups.iter().map(|g| g.leaves.len()).collect();
    assert_eq!(sizes.iter().sum::<usize>(), 5);
    assert!(sizes.contains(&3) && sizes.contains(&2));
    for (gi, g) in m.leaf_groups.iter().enumerate() {
        assert!(m.rings[g.ring as usize].is_terminal());
        assert_eq!(m.rings[g.ring as usize].leaf_group, Some(gi as u32));
        let d: Vec<f32> = m
            .leaves_of(gi)
            .iter()
            .map(|x| x.center.distance(g.bounds.center))
            .collect();
        assert!(d.windows(2).all(|w| w[0] <= w[1]), "near → far: {d:?}");
    }
    for leaf in &m.leaves {
        assert!((leaf.normal.length() - 1.0).abs() < 1e-4);
        assert!(leaf.normal.y.abs() > 0.99);
    }
}

mod malformed {
    use super::*;

    fn err(p: &[Vec3], idx: &[u32]) -> TreeAnalysisError {
        trunk_only(p, idx).unwrap_err()
    }

    #[test]
    fn no_triangles() {
        let (p, _) = figure_2_2();
        assert!(matches!(
            err(&p, &[]),
            TreeAnalysisError::NoTriangles {
                part: TreePart::Trunk
            }
        ));
    }

    #[test]
    fn not_a_triangle_list() {
        let (p, idx) = figure_2_2();
        let e = err(&p, &idx[..idx.len() - 1]);
        assert!(matches!(e, TreeAnalysisError::NotTriangles { len, .. } if len == idx.len() - 1));
    }

    #[test]
    fn index_out_of_range() {
        let (p, mut idx) = figure_2_2();
        idx[7] = 99;
        let e = err(&p, &idx);
        assert_eq!(
            e,
            TreeAnalysisError::IndexOutOfRange {
                part: TreePart::Trunk,
                triangle: 2,
                index: 99,
                vertices: 16
            }
        );
        assert!(e.to_string().contains("triangle 2 uses vertex 99"));
    }

    #[test]
    fn nan_position() {
        let (mut p, idx) = figure_2_2();
        p[5].x = f32::NAN;
        assert!(matches!(
            err(&p, &idx),
            TreeAnalysisError::NonFinitePosition { vertex: 5, .. }
        ));
    }

    #[test]
    fn normals_do_not_match_positions() {
        let (p, idx) = figure_2_2();
        let normals = vec![Vec3::Y; 3];
        let trunk = MeshData {
            positions: &p,
            normals: Some(&normals),
            indices: &idx,
            color: None,
        };
        let e = analyze(&trunk, &MeshData::default(), &AnalysisOptions::default()).unwrap_err();
        assert!(matches!(
            e,
            TreeAnalysisError::NormalCountMismatch {
                normals: 3,
                positions: 16,
                ..
            }
        ));
    }

    #[test]
    fn no_root_ring_above_ground() {
        let (mut p, idx) = figure_2_2();
        for v in &mut p {
            v.y += 1.0;
        }
        let e = err(&p, &idx);
        assert!(
            matches!(e, TreeAnalysisError::NoRootRing { lowest, .. } if (lowest - 0.5).abs() < 1e-5)
        );
        assert!(e.to_string().contains("must reach into the ground"));
    }

    #[test]
    fn ring_that_cannot_be_closed() {
        // A ribbon: two open rows of vertices, the lower one below ground.
        let mut p = Vec::new();
        for x in 0..4 {
            p.push(Vec3::new(x as f32, -0.5, 0.0));
        }
        for x in 0..4 {
            p.push(Vec3::new(x as f32, 1.0, 0.0));
        }
        let mut idx = Vec::new();
        for x in 0..3 {
            idx.extend([x, x + 1, x + 5, x, x + 5, x + 4]);
        }
        assert!(matches!(
            err(&p, &idx),
            TreeAnalysisError::OpenRing { neighbours: 1, .. }
        ));
    }

    #[test]
    fn detached_piece_without_an_open_end() {
        let (mut p, mut idx) = figure_2_2();
        // A closed tetrahedron floating beside the trunk.
        let first = p.len() as u32;
        p.extend([
            Vec3::new(3.0, 1.0, 0.0),
            Vec3::new(4.0, 1.0, 0.0),
            Vec3::new(3.5, 1.0, 1.0),
            Vec3::new(3.5, 2.0, 0.5),
        ]);
        for t in [[0, 1, 2], [0, 3, 1], [1, 3, 2], [2, 3, 0]] {
            idx.extend(t.map(|v| first + v));
        }
        assert!(matches!(
            err(&p, &idx),
            TreeAnalysisError::DetachedTrunkPiece { vertices: 4, .. }
        ));
    }

    #[test]
    fn a_lone_root_ring_has_no_segment() {
        let p = [
            Vec3::new(0.0, -1.0, 0.0),
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(0.0, -1.0, 1.0),
        ];
        assert!(matches!(
            err(&p, &[0, 1, 2]),
            TreeAnalysisError::NoSegment { .. }
        ));
    }

    #[test]
    fn leaf_touching_the_trunk() {
        let (p, idx) = figure_2_2();
        let leaves = [p[12], Vec3::new(1.0, 3.5, 0.0), Vec3::new(0.5, 3.8, 0.0)];
        let e = analyze(
            &MeshData {
                positions: &p,
                indices: &idx,
                ..Default::default()
            },
            &MeshData {
                positions: &leaves,
                indices: &[0, 1, 2],
                ..Default::default()
            },
            &AnalysisOptions::default(),
        )
        .unwrap_err();
        assert!(matches!(
            e,
            TreeAnalysisError::LeafTouchesTrunk { vertex: 0, .. }
        ));
    }

    #[test]
    fn leaf_index_out_of_range_names_the_leaves() {
        let (p, idx) = figure_2_2();
        let leaves = [Vec3::new(1.0, 3.5, 0.0)];
        let e = analyze(
            &MeshData {
                positions: &p,
                indices: &idx,
                ..Default::default()
            },
            &MeshData {
                positions: &leaves,
                indices: &[0, 0, 3],
                ..Default::default()
            },
            &AnalysisOptions::default(),
        )
        .unwrap_err();
        assert!(e.to_string().starts_with("leaves triangle 0 uses vertex 3"));
    }
}

/// Invariants every analysed model must satisfy.
pub fn check_invariants(m: &TreeModel) {
    let segs = &m.segments;
    assert!(
        segs.diameter.windows(2).all(|w| w[0] <= w[1]),
        "segments sorted thin → thick"
    );
    assert_eq!(segs.triangle_offsets.len(), segs.len() + 1);
    assert_eq!(segs.triangle_offsets[0], 0);
    assert!(segs.triangle_offsets.windows(2).all(|w| w[0] <= w[1]));
    assert_eq!(
        *segs.triangle_offsets.last().unwrap() as usize,
        m.trunk_triangle_count()
    );
    assert!(segs.cumulative_length.windows(2).all(|w| w[0] <= w[1]));
    for (s, &r) in segs.ring.iter().enumerate() {
        let ring = &m.rings[r as usize];
        assert!(!ring.is_root());
        assert_eq!(segs.line[s][1], ring.center);
        assert_eq!(segs.line[s][0], m.rings[ring.parent as usize].center);
    }
    // Every non-root ring is exactly one segment.
    assert_eq!(segs.len(), m.rings.iter().filter(|r| !r.is_root()).count());
    // Ring vectors reproduce ring vertices.
    for (i, ring) in m.rings.iter().enumerate() {
        for (k, &v) in m.vertices_of(i as u32).iter().enumerate() {
            let vec = m.ring_vectors[ring.vertices.start as usize + k];
            assert!((ring.center + vec - m.trunk_positions[v as usize]).length() < 1e-4);
            assert_eq!(m.trunk_vertex_ring[v as usize], i as u32);
        }
        for &c in &ring.children {
            assert_eq!(m.rings[c as usize].parent, i as u32);
            assert_eq!(m.rings[c as usize].level, ring.level + 1);
        }
    }
    assert_eq!(m.trunk_vertex_ring.len(), m.trunk_positions.len());
    assert!(
        m.trunk_vertex_ring
            .iter()
            .all(|&r| (r as usize) < m.rings.len())
    );
    // Bounds contain all geometry.
    let tol = 1e-4;
    assert!(
        m.trunk_positions
            .iter()
            .all(|&p| m.trunk_bounds.contains(p, tol) && m.bounds.contains(p, tol))
    );
    assert!(m.leaf_positions.iter().all(|&p| m.bounds.contains(p, tol)));
    // Every leaf in exactly one group; every leaf triangle in exactly one leaf.
    let mut next = 0;
    for (gi, g) in m.leaf_groups.iter().enumerate() {
        assert_eq!(g.leaves.start, next);
        next = g.leaves.end;
        assert!(m.rings[g.ring as usize].is_terminal());
        for leaf in m.leaves_of(gi) {
            assert_eq!(leaf.group, gi as u32);
            for t in leaf.triangles.clone() {
                for k in 0..3 {
                    let v = m.leaf_indices[t as usize * 3 + k] as usize;
                    assert!(m.leaf_positions[v].distance(g.bounds.center) <= g.bounds.radius + tol);
                }
            }
        }
        let d: Vec<f32> = m
            .leaves_of(gi)
            .iter()
            .map(|l| l.center.distance(g.bounds.center))
            .collect();
        assert!(d.windows(2).all(|w| w[0] <= w[1] + 1e-6));
    }
    assert_eq!(next as usize, m.leaves.len());
    let mut next = 0;
    for leaf in &m.leaves {
        assert_eq!(leaf.triangles.start, next);
        next = leaf.triangles.end;
    }
    assert_eq!(next as usize, m.leaf_triangle_count());
    assert_eq!(m.leaf_vertex_leaf.len(), m.leaf_positions.len());
}

#[test]
fn hand_made_models_satisfy_the_invariants() {
    let (p, idx, l, li) = trunk_with_detached_branch();
    check_invariants(&analyze_full(&p, &idx, &l, &li).unwrap().model);
    let (p, idx) = figure_2_2();
    check_invariants(&trunk_only(&p, &idx).unwrap().model);
}

const SPECIES: [(&str, usize, usize); 4] = [
    ("slender", 620, 480),
    ("broad", 890, 720),
    ("grand", 1740, 1800),
    ("dense", 11_000, 9_000),
];

#[test]
fn shipped_species_analyse_cleanly_with_the_papers_triangle_counts() {
    for (name, trunk, leaves) in SPECIES {
        let path = format!(
            "{}/assets/species/{name}.species.ron",
            env!("CARGO_MANIFEST_DIR")
        );
        let text = std::fs::read_to_string(&path).unwrap();
        let desc = SpeciesDesc::from_ron_str(&text).unwrap_or_else(|e| panic!("{path}: {e}"));
        let generated = desc.generate();
        let analysis = desc.generate_and_analyze().unwrap();
        let m = &analysis.model;
        assert!(
            analysis.warnings.is_empty(),
            "{name}: {:?}",
            analysis.warnings
        );
        check_invariants(m);
        // Triangle counts preserved by the analysis.
        assert_eq!(
            m.trunk_triangle_count(),
            generated.trunk_indices.len() / 3,
            "{name}"
        );
        assert_eq!(
            m.leaf_triangle_count(),
            generated.leaf_indices.len() / 3,
            "{name}"
        );
        // Within 10% of the paper's table 1 (and ~20k in all for the dense variant).
        let near = |got: usize, want: usize| (got as f32 - want as f32).abs() <= 0.1 * want as f32;
        assert!(
            near(m.trunk_triangle_count(), trunk),
            "{name}: {} trunk triangles",
            m.trunk_triangle_count()
        );
        assert!(
            near(m.leaf_triangle_count(), leaves),
            "{name}: {} leaf triangles",
            m.leaf_triangle_count()
        );
        // Generation is deterministic.
        assert_eq!(desc.generate(), generated);
    }
}

#[test]
fn malformed_species_files_name_line_and_field() {
    let e =
        SpeciesDesc::from_ron_str("(\n  name: \"x\",\n  levels: [(lenght: 2.0)],\n)").unwrap_err();
    let text = e.to_string();
    assert!(text.contains("3:") && text.contains("lenght"), "{text}");
    let e = SpeciesDesc::from_ron_str("(levels: [(length: 2.0, ring_vertices: 2)])").unwrap_err();
    assert_eq!(
        e.to_string(),
        "levels[0].ring_vertices: must be between 3 and 64"
    );
    let e = SpeciesDesc::from_ron_str("(levels: [])").unwrap_err();
    assert!(e.to_string().starts_with("levels:"));
}

/// Bevy meshes in, the same model out as from plain arrays; non-triangle meshes refused.
#[cfg(feature = "render")]
#[test]
fn bevy_meshes_analyse_like_plain_arrays() {
    use bevy::asset::RenderAssetUsages;
    use bevy::mesh::{Indices, Mesh, PrimitiveTopology};

    let (p, idx) = figure_2_2();
    let mesh = Mesh::new(
        PrimitiveTopology::TriangleList,
        RenderAssetUsages::default(),
    )
    .with_inserted_attribute(
        Mesh::ATTRIBUTE_POSITION,
        p.iter().map(Vec3::to_array).collect::<Vec<_>>(),
    )
    .with_inserted_indices(Indices::U16(idx.iter().map(|&i| i as u16).collect()));
    let owned = OwnedMeshData::from_mesh(&mesh).unwrap();
    assert_eq!(owned.indices, idx);
    let from_mesh = analyze(
        &owned.as_mesh_data(),
        &MeshData::default(),
        &AnalysisOptions::default(),
    )
    .unwrap();
    assert_eq!(from_mesh.model, trunk_only(&p, &idx).unwrap().model);
    // The model's own meshes round-trip too.
    let again = OwnedMeshData::from_mesh(&from_mesh.model.trunk_mesh()).unwrap();
    assert_eq!(again.positions, from_mesh.model.trunk_positions);

    let lines = Mesh::new(PrimitiveTopology::LineList, RenderAssetUsages::default())
        .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, vec![[0.0_f32; 3]; 2]);
    assert!(matches!(
        OwnedMeshData::from_mesh(&lines),
        Err(MeshConversionError::NotTriangleList(
            PrimitiveTopology::LineList
        ))
    ));
}

/// Trunk meshes built from [`tube`]s (open at the start, pointed at the end).
mod separate_pieces {
    use super::*;

    fn straight(from: Vec3, to: Vec3, radius: f32, rings: usize) -> (Vec<Vec3>, Vec<f32>) {
        let points = (0..rings)
            .map(|i| from.lerp(to, i as f32 / (rings - 1) as f32))
            .collect();
        (points, vec![radius; rings])
    }

    fn add(tree: &mut GeneratedTree, (points, radii): (Vec<Vec3>, Vec<f32>), k: usize) {
        tube(tree, &points, &radii, k, 0.0);
    }

    fn analyse(tree: &GeneratedTree) -> TreeAnalysis {
        trunk_only(&tree.trunk_positions, &tree.trunk_indices).unwrap()
    }

    fn ring_at(m: &TreeModel, p: Vec3) -> usize {
        m.rings
            .iter()
            .position(|r| r.center.distance(p) < 1e-4)
            .unwrap_or_else(|| panic!("no ring at {p}"))
    }

    fn parent_center(m: &TreeModel, ring: usize) -> Vec3 {
        m.rings[m.rings[ring].parent as usize].center
    }

    /// A trunk (8 vertices per ring, radius 0.3, from y = -0.5 to 4) and two branches
    /// (5 per ring), each `(base, direction, radius)`.
    fn trunk_with_two_branches(branches: [(Vec3, Vec3, f32); 2]) -> GeneratedTree {
        let mut tree = GeneratedTree::default();
        add(
            &mut tree,
            straight(Vec3::new(0.0, -0.5, 0.0), Vec3::new(0.0, 4.0, 0.0), 0.3, 5),
            8,
        );
        for (base, direction, radius) in branches {
            add(&mut tree, straight(base, base + direction, radius, 3), 5);
        }
        tree
    }

    /// The branch starting at `base` hangs on a ring of the trunk (8 vertices).
    fn assert_hangs_on_the_trunk(m: &TreeModel, base: Vec3) {
        let up = m.rings[ring_at(m, base)].parent as usize;
        assert_eq!(
            m.rings[up].vertices.len(),
            8,
            "the branch at {base} hangs on {}, not on a trunk ring",
            m.rings[up].center
        );
    }

    /// Two branches start inside the trunk on its axis, 2 cm apart, far from any trunk
    /// ring: the nearest ring *centre* to the second is the first's base, but both hang
    /// on the trunk (EZ-Tree's whorls).
    #[test]
    fn siblings_starting_side_by_side_both_hang_on_the_trunk() {
        let a = Vec3::new(0.0, 2.3, 0.0);
        let b = Vec3::new(0.0, 2.32, 0.0);
        let tree = trunk_with_two_branches([
            (a, Vec3::new(1.5, 0.6, 0.0), 0.08),
            (b, Vec3::new(-1.2, 0.5, 0.8), 0.08),
        ]);
        let analysis = analyse(&tree);
        let m = &analysis.model;
        assert!(analysis.warnings.is_empty(), "{:?}", analysis.warnings);
        for base in [a, b] {
            assert_hangs_on_the_trunk(m, base);
        }
        assert_eq!(m.roots().count(), 1);
    }

    /// A branch starting on its parent's surface attaches to the parent, not to a
    /// sibling whose open base is closer.
    #[test]
    fn a_piece_never_attaches_to_another_piece_s_open_base() {
        let a = Vec3::new(0.3, 2.3, 0.0);
        let b = Vec3::new(0.3, 2.35, 0.02);
        let tree = trunk_with_two_branches([
            (a, Vec3::new(1.5, 0.2, 0.0), 0.1),
            (b, Vec3::new(1.4, 0.6, 0.3), 0.1),
        ]);
        let m = analyse(&tree).model;
        for base in [a, b] {
            assert_hangs_on_the_trunk(&m, base);
        }
    }

    /// A bush: a short trunk whose side branches are tilted so far that part of their
    /// base ring lies below the ground, and one twig droops with its tip into the ground.
    /// Neither is a root; the tree has one.
    #[test]
    fn branches_and_tips_dipping_into_the_ground_are_no_roots() {
        let mut tree = GeneratedTree::default();
        add(
            &mut tree,
            straight(Vec3::ZERO, Vec3::new(0.0, 0.1, 0.0), 0.5, 4),
            6,
        );
        let base = Vec3::new(0.0, 0.05, 0.0);
        // Nearly flat: its base ring (radius 0.4) reaches below y = 0.
        add(
            &mut tree,
            straight(base, Vec3::new(3.0, 0.6, 0.0), 0.4, 4),
            6,
        );
        // A twig hanging down from the branch with its (thin) end in the ground.
        let twig = Vec3::new(2.0, 0.4, 0.0);
        add(
            &mut tree,
            (
                vec![twig, Vec3::new(2.3, 0.1, 0.3), Vec3::new(2.5, -0.3, 0.5)],
                vec![0.1, 0.06, 0.03],
            ),
            5,
        );
        let analysis = analyse(&tree);
        let m = &analysis.model;
        assert_eq!(
            m.roots().count(),
            1,
            "{:?}",
            m.roots()
                .map(|r| m.rings[r as usize].center)
                .collect::<Vec<_>>()
        );
        assert!(m.rings[m.roots().next().unwrap() as usize].center.length() < 1e-4);
        let twig_up = parent_center(m, ring_at(m, twig));
        assert!(
            twig_up.y > 0.1,
            "the twig hangs on the branch, not on {twig_up}"
        );
    }

    /// A root capped by a fan (a centre vertex) or a flat polygon still stands: it is
    /// the only end in the ground.
    #[test]
    fn capped_roots_still_stand() {
        for fan in [true, false] {
            let mut tree = GeneratedTree::default();
            add(
                &mut tree,
                straight(Vec3::new(0.0, -0.5, 0.0), Vec3::new(0.0, 3.0, 0.0), 0.3, 4),
                6,
            );
            if fan {
                let hub = tree.trunk_positions.len() as u32;
                tree.trunk_positions.push(Vec3::new(0.0, -0.5, 0.0));
                tree.trunk_normals.push(Vec3::NEG_Y);
                for j in 0..6 {
                    tree.trunk_indices.extend([hub, (j + 1) % 6, j]);
                }
            } else {
                for j in 1..5 {
                    tree.trunk_indices.extend([0, j + 1, j]);
                }
            }
            let m = analyse(&tree).model;
            assert_eq!(m.roots().count(), 1, "fan: {fan}");
            assert!((m.rings[0].center.y + 0.5).abs() < 1e-4);
        }
    }

    /// A twig thinner than the weld tolerance at its tip welds into a tangle there, and
    /// a whole speck of one welds shut: both are kept and reported, not errors.
    #[test]
    fn twigs_thinner_than_the_weld_tolerance_are_kept() {
        let mut tree = GeneratedTree::default();
        add(
            &mut tree,
            straight(Vec3::new(0.0, -0.5, 0.0), Vec3::new(0.0, 10.0, 0.0), 0.3, 5),
            8,
        );
        // Tolerance: 1e-5 × a diagonal of about 10.5 → 1e-4, so a 7-vertex ring of
        // radius 1e-4 welds in part, and the speck welds shut.
        let twig = Vec3::new(0.0, 5.0, 0.0);
        add(
            &mut tree,
            (
                vec![
                    twig,
                    twig + Vec3::new(0.5, 0.2, 0.0),
                    twig + Vec3::new(1.0, 0.4, 0.0),
                ],
                vec![0.05, 0.02, 1e-4],
            ),
            7,
        );
        let speck = Vec3::new(0.0, 7.0, 0.0);
        add(
            &mut tree,
            (
                vec![
                    speck,
                    speck + Vec3::new(1e-3, 0.0, 0.0),
                    speck + Vec3::new(2e-3, 0.0, 0.0),
                ],
                vec![3e-5, 2e-5, 1e-5],
            ),
            5,
        );
        let trunk = MeshData {
            positions: &tree.trunk_positions,
            indices: &tree.trunk_indices,
            ..Default::default()
        };
        let options = AnalysisOptions {
            weld_tolerance: 1e-5,
            ..Default::default()
        };
        let analysis = analyze(&trunk, &MeshData::default(), &options).unwrap();
        analysis.model.validate().unwrap();
        assert_eq!(analysis.model.roots().count(), 1);
    }
}
