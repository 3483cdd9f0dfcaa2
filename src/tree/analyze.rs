//! From a trunk mesh and a leaves mesh to a [`TreeModel`] (thesis chapter 2, §4.2).
//!
//! The thesis' algorithm finds the root rings below the ground, then recursively the
//! child rings among the unvisited neighbours of each ring; rings without children are
//! terminal, and each leaf joins the group of its nearest terminal ring. Meshes made by
//! real tools need more, so the analysis also:
//! - welds vertices duplicated along UV seams (by position, with a tolerance relative
//!   to the model's size);
//! - accepts a different number of vertices per ring, caps (flat, or around a centre
//!   vertex), pointed tips (a one-vertex ring of diameter 0) and tips thinner than the
//!   weld tolerance (kept as they weld);
//! - stands the tree on its widest open ends in the ground, not on a branch or twig that
//!   merely dips into it (a bush's);
//! - attaches a branch that is a separate piece of mesh (as generators such as EZ-Tree
//!   write every branch) where its open base meets another piece's surface or axis,
//!   never at a sibling's open base (see the `rings` module);
//! - treats each connected patch of leaf triangles (a quad, a small fan) as one leaf.
//!
//! Input that cannot be a tree is refused with a [`TreeAnalysisError`] naming what is
//! wrong and where.

use std::collections::HashMap;

use bevy::math::{IVec3, Vec3};

mod rings;

use super::model::{BoundingSphere, Bounds, Leaf, LeafGroup, LinearRgb, TreeModel};
use rings::Hierarchy;

/// One part of a tree (trunk or leaves) as plain arrays.
#[derive(Clone, Copy, Debug, Default)]
pub struct MeshData<'a> {
    /// Vertex positions.
    pub positions: &'a [Vec3],
    /// Vertex normals, parallel to `positions`; computed from the faces when `None`.
    pub normals: Option<&'a [Vec3]>,
    /// Triangle list: three vertex indices per triangle.
    pub indices: &'a [u32],
    /// The part's mean colour (bark or leaf), if known.
    pub color: Option<LinearRgb>,
}

/// Which part of the tree an error is about.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TreePart {
    /// The trunk and branches mesh.
    Trunk,
    /// The leaves mesh.
    Leaves,
}

impl core::fmt::Display for TreePart {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::Trunk => "trunk",
            Self::Leaves => "leaves",
        })
    }
}

/// Why a pair of meshes cannot be analysed into a tree.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum TreeAnalysisError {
    /// The trunk has no triangles.
    #[error("the {part} mesh has no triangles")]
    NoTriangles {
        /// The part.
        part: TreePart,
    },
    /// The index count is not a multiple of three.
    #[error("the {part} mesh has {len} indices, not a multiple of 3: it must be a triangle list")]
    NotTriangles {
        /// The part.
        part: TreePart,
        /// The index count.
        len: usize,
    },
    /// An index points past the vertex arrays.
    #[error(
        "{part} triangle {triangle} uses vertex {index}, but there are only {vertices} vertices"
    )]
    IndexOutOfRange {
        /// The part.
        part: TreePart,
        /// The triangle.
        triangle: usize,
        /// The offending index.
        index: u32,
        /// The vertex count.
        vertices: usize,
    },
    /// A position is NaN or infinite.
    #[error("{part} vertex {vertex} has a non-finite position {position}")]
    NonFinitePosition {
        /// The part.
        part: TreePart,
        /// The vertex.
        vertex: usize,
        /// Its position.
        position: Vec3,
    },
    /// The normals array does not match the positions.
    #[error("the {part} mesh has {normals} normals for {positions} positions")]
    NormalCountMismatch {
        /// The part.
        part: TreePart,
        /// Normals given.
        normals: usize,
        /// Positions given.
        positions: usize,
    },
    /// No trunk vertex is at or below the ground, so no hierarchy has a root.
    #[error(
        "no root ring: no trunk vertex lies at or below y = {ground} (the lowest is at y = {lowest}); the trunk must reach into the ground"
    )]
    NoRootRing {
        /// The ground level used.
        ground: f32,
        /// The lowest trunk vertex's height.
        lowest: f32,
    },
    /// A loop of vertices that should form a ring is open.
    #[error(
        "a ring of {vertices} vertices near {position} cannot be closed: vertex {vertex} has only {neighbours} neighbour(s) in it"
    )]
    OpenRing {
        /// Centre of the offending vertices.
        position: Vec3,
        /// How many vertices it has.
        vertices: usize,
        /// A vertex with too few neighbours.
        vertex: u32,
        /// Its neighbours within the ring.
        neighbours: usize,
    },
    /// A separate piece of trunk has no open end to attach it to the rest by.
    #[error(
        "a piece of trunk near {position} ({vertices} vertices) is not connected to a root ring and has no open end to attach it by"
    )]
    DetachedTrunkPiece {
        /// A vertex of the piece.
        position: Vec3,
        /// Its vertex count.
        vertices: usize,
    },
    /// A root ring's cap has triangles but the root has no segment to give them to.
    #[error("the hierarchy rooted near {position} is a single ring with no segment")]
    NoSegment {
        /// The root ring's centre.
        position: Vec3,
    },
    /// A leaf shares a vertex position with the trunk; leaves must stand apart.
    #[error(
        "leaf vertex {vertex} at {position} touches the trunk; leaves must not share vertices with it"
    )]
    LeafTouchesTrunk {
        /// The leaf vertex (input index).
        vertex: usize,
        /// Its position.
        position: Vec3,
    },
    /// The model built fails [`TreeModel::validate`]: the input had something the checks
    /// above let through (a colour out of range), or the analysis has a bug.
    #[error("the analysed model is inconsistent: {0}")]
    Inconsistent(String),
}

/// Something odd but harmless that the analysis worked around.
#[derive(Clone, Debug, PartialEq)]
pub enum AnalysisWarning {
    /// Triangles that collapsed to a line or point after welding were dropped.
    DegenerateTriangles {
        /// The part.
        part: TreePart,
        /// How many.
        count: usize,
    },
    /// A branch was attached to a ring far from its open end.
    BranchAttachedFar {
        /// The branch's first ring.
        ring: u32,
        /// Distance from its centre to the surface of the segment it hangs from.
        distance: f32,
    },
    /// Rings whose vertices do not close into a loop were kept as they are: a tube
    /// thinner than the weld tolerance welds into a tangle (a generator's tiny twig).
    IrregularRings {
        /// How many.
        count: usize,
        /// The first one's centre.
        position: Vec3,
    },
    /// Leaves of zero area: their point has an arbitrary normal.
    ZeroAreaLeaves {
        /// How many.
        count: usize,
    },
    /// A flat, wide primitive under the tree's foot was taken for a ground plane
    /// exported with the tree and left out (name it with one of
    /// `GltfTreeSettings::skip_keywords` to leave it out without a warning).
    GroundPlaneLeftOut {
        /// Its mesh's name.
        mesh: String,
        /// Its width, in the file's units.
        width: f32,
    },
}

/// Settings of [`analyze`]; glTF users set them through
/// [`GltfTreeSettings::analysis`](crate::tree::GltfTreeSettings) (a `.meta` file beside
/// the tree, or `AssetServer::load_builder().with_settings(…)`). Every field has a default, so a RON
/// value names only what it changes: `(ground: -0.05)`.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct AnalysisOptions {
    /// Vertices closer than this fraction of the model's bounding-box diagonal are the
    /// same vertex: it joins UV-seam duplicates and a branch that continues its parent's
    /// last ring. Default: `1e-6` (seam duplicates are exact copies in every exporter
    /// seen; a larger value welds a generator's thinnest twigs shut).
    pub weld_tolerance: f32,
    /// Height of the ground, in the file's units: the open ends (or capped ends) at or
    /// below it are root rings. A side branch that merely dips below it (a bush's) is
    /// attached to its parent, not made a root. Default: `0.0`.
    pub ground: f32,
    /// Bark colour when the trunk mesh carries none. Default: a dark brown.
    pub default_bark_color: LinearRgb,
    /// Leaf colour when the leaves mesh carries none. Default: a mid green.
    pub default_leaf_color: LinearRgb,
}

impl Default for AnalysisOptions {
    fn default() -> Self {
        Self {
            weld_tolerance: 1e-6,
            ground: 0.0,
            default_bark_color: [0.18, 0.11, 0.06],
            default_leaf_color: [0.12, 0.32, 0.08],
        }
    }
}

/// A model and what the analysis had to work around.
#[derive(Clone, Debug)]
pub struct TreeAnalysis {
    /// The analysed tree.
    pub model: TreeModel,
    /// Harmless oddities, for logs.
    pub warnings: Vec<AnalysisWarning>,
}

/// Analyses a trunk mesh and a leaves mesh into a [`TreeModel`].
pub fn analyze(
    trunk: &MeshData,
    leaves: &MeshData,
    options: &AnalysisOptions,
) -> Result<TreeAnalysis, TreeAnalysisError> {
    validate(trunk, TreePart::Trunk)?;
    validate(leaves, TreePart::Leaves)?;
    if trunk.indices.is_empty() {
        return Err(TreeAnalysisError::NoTriangles {
            part: TreePart::Trunk,
        });
    }
    let all = Bounds::from_points(trunk.positions.iter().chain(leaves.positions).copied());
    let tolerance = (options.weld_tolerance * (all.max - all.min).length()).max(f32::EPSILON);
    let mut warnings = Vec::new();

    let mut welder = Welder::new(tolerance);
    let trunk_mesh = welder.weld(trunk, TreePart::Trunk, &mut warnings);
    let trunk_vertex_count = trunk_mesh.positions.len();
    let hierarchy = Hierarchy::build(&trunk_mesh, options.ground, tolerance, &mut warnings)?;

    // Leaves weld in the same space: a leaf vertex landing on a trunk vertex touches it.
    let leaf_start = trunk_vertex_count as u32;
    let leaf_mesh = welder.weld(leaves, TreePart::Leaves, &mut warnings);
    if let Some((input, _)) = leaf_mesh
        .source
        .iter()
        .enumerate()
        .find(|&(_, &w)| w < leaf_start)
    {
        return Err(TreeAnalysisError::LeafTouchesTrunk {
            vertex: input,
            position: leaves.positions[input],
        });
    }
    let mut model = hierarchy.into_model(trunk_mesh, trunk, options)?;
    attach_leaves(
        &mut model,
        leaf_mesh,
        leaf_start,
        leaves,
        options,
        &mut warnings,
    );
    model.crown = super::crown::crown_of(&model);
    // One validation for every way a model enters: what the analysis builds is checked as
    // a loaded file is (a colour out of range in the input, say, is caught here).
    model
        .validate()
        .map_err(|e| TreeAnalysisError::Inconsistent(e.to_string()))?;
    Ok(TreeAnalysis { model, warnings })
}

fn validate(mesh: &MeshData, part: TreePart) -> Result<(), TreeAnalysisError> {
    if !mesh.indices.len().is_multiple_of(3) {
        return Err(TreeAnalysisError::NotTriangles {
            part,
            len: mesh.indices.len(),
        });
    }
    if let Some(normals) = mesh.normals
        && normals.len() != mesh.positions.len()
    {
        return Err(TreeAnalysisError::NormalCountMismatch {
            part,
            normals: normals.len(),
            positions: mesh.positions.len(),
        });
    }
    if let Some((vertex, &position)) = mesh
        .positions
        .iter()
        .enumerate()
        .find(|(_, p)| !p.is_finite())
    {
        return Err(TreeAnalysisError::NonFinitePosition {
            part,
            vertex,
            position,
        });
    }
    if let Some((i, &index)) = mesh
        .indices
        .iter()
        .enumerate()
        .find(|&(_, &i)| i as usize >= mesh.positions.len())
    {
        return Err(TreeAnalysisError::IndexOutOfRange {
            part,
            triangle: i / 3,
            index,
            vertices: mesh.positions.len(),
        });
    }
    Ok(())
}

/// A welded mesh: vertex indices are global across the welder's parts.
struct WeldedMesh {
    /// Positions of the vertices this part introduced (global index `first + i`).
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    first: u32,
    /// Global welded index of every input vertex.
    source: Vec<u32>,
    /// Triangles in global welded indices, degenerate ones dropped.
    triangles: Vec<[u32; 3]>,
}

/// Merges vertices closer than a tolerance, across calls.
struct Welder {
    tolerance: f32,
    cells: HashMap<IVec3, Vec<u32>>,
    positions: Vec<Vec3>,
}

impl Welder {
    fn new(tolerance: f32) -> Self {
        Self {
            tolerance,
            cells: HashMap::new(),
            positions: Vec::new(),
        }
    }

    fn cell(&self, p: Vec3) -> IVec3 {
        (p / self.tolerance).floor().as_ivec3()
    }

    fn find_or_insert(&mut self, p: Vec3) -> u32 {
        let cell = self.cell(p);
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    if let Some(list) = self.cells.get(&(cell + IVec3::new(dx, dy, dz))) {
                        for &v in list {
                            if self.positions[v as usize].distance(p) <= self.tolerance {
                                return v;
                            }
                        }
                    }
                }
            }
        }
        let v = self.positions.len() as u32;
        self.positions.push(p);
        self.cells.entry(cell).or_default().push(v);
        v
    }

    fn weld(
        &mut self,
        mesh: &MeshData,
        part: TreePart,
        warnings: &mut Vec<AnalysisWarning>,
    ) -> WeldedMesh {
        let first = self.positions.len() as u32;
        let source: Vec<u32> = mesh
            .positions
            .iter()
            .map(|&p| self.find_or_insert(p))
            .collect();
        let count = self.positions.len() - first as usize;
        let positions = self.positions[first as usize..].to_vec();
        let mut normal_sum = vec![Vec3::ZERO; count];
        let mut triangles = Vec::with_capacity(mesh.indices.len() / 3);
        let mut degenerate = 0;
        for tri in mesh.indices.chunks_exact(3) {
            let t = [
                source[tri[0] as usize],
                source[tri[1] as usize],
                source[tri[2] as usize],
            ];
            if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
                degenerate += 1;
                continue;
            }
            triangles.push(t);
        }
        if degenerate > 0 {
            warnings.push(AnalysisWarning::DegenerateTriangles {
                part,
                count: degenerate,
            });
        }
        match mesh.normals {
            Some(normals) => {
                for (input, &w) in source.iter().enumerate() {
                    if w >= first {
                        normal_sum[(w - first) as usize] += normals[input];
                    }
                }
            }
            None => {
                for t in &triangles {
                    let p = t.map(|v| self.positions[v as usize]);
                    let n = (p[1] - p[0]).cross(p[2] - p[0]);
                    for v in t {
                        if *v >= first {
                            normal_sum[(*v - first) as usize] += n;
                        }
                    }
                }
            }
        }
        let normals = normal_sum
            .into_iter()
            .map(|n| n.try_normalize().unwrap_or(Vec3::Y))
            .collect();
        WeldedMesh {
            positions,
            normals,
            first,
            source,
            triangles,
        }
    }
}

fn mean(points: impl Iterator<Item = Vec3>) -> Vec3 {
    let (sum, n) = points.fold((Vec3::ZERO, 0_u32), |(s, n), p| (s + p, n + 1));
    if n == 0 { Vec3::ZERO } else { sum / n as f32 }
}

/// Splits the leaves mesh into leaves (connected patches), groups them by nearest
/// terminal ring, and stores them in the model.
fn attach_leaves(
    model: &mut TreeModel,
    mesh: WeldedMesh,
    first: u32,
    input: &MeshData,
    options: &AnalysisOptions,
    warnings: &mut Vec<AnalysisWarning>,
) {
    model.leaf_color = input.color.unwrap_or(options.default_leaf_color);
    let n = mesh.positions.len();
    let triangles: Vec<[u32; 3]> = mesh
        .triangles
        .iter()
        .map(|t| t.map(|v| v - first))
        .collect();
    if triangles.is_empty() {
        return;
    }
    let leaf_triangles = connected_patches(&triangles, n);

    let positions = &mesh.positions;
    let terminals: Vec<u32> = (0..model.rings.len() as u32)
        .filter(|&r| model.rings[r as usize].is_terminal())
        .collect();
    let mut zero_area = 0;
    let mut total_area = 0.0;
    // (group ring, centre, normal, triangles)
    let mut built: Vec<(u32, Vec3, Vec3, &Vec<[u32; 3]>)> =
        Vec::with_capacity(leaf_triangles.len());
    for tris in &leaf_triangles {
        let (area, center, normal) = leaf_shape(tris, positions, &mesh.normals);
        total_area += area;
        let has_area = area > 0.0;
        if !has_area {
            zero_area += 1;
        }
        let ring = terminals
            .iter()
            .copied()
            .min_by(|&a, &b| {
                let da = model.rings[a as usize].center.distance_squared(center);
                let db = model.rings[b as usize].center.distance_squared(center);
                da.total_cmp(&db)
            })
            .unwrap_or(0);
        built.push((ring, center, normal, tris));
    }
    if zero_area > 0 {
        warnings.push(AnalysisWarning::ZeroAreaLeaves { count: zero_area });
    }

    // Groups in terminal-ring order; leaves near → far from their group's centre.
    let mut by_ring: HashMap<u32, Vec<usize>> = HashMap::new();
    for (i, b) in built.iter().enumerate() {
        by_ring.entry(b.0).or_default().push(i);
    }
    let mut leaf_vertex_leaf = vec![u32::MAX; n];
    for &ring in &terminals {
        let Some(mut members) = by_ring.remove(&ring) else {
            continue;
        };
        let bounds = Bounds::from_points(
            members
                .iter()
                .flat_map(|&i| built[i].3.iter().flatten())
                .map(|&v| positions[v as usize]),
        );
        let center = bounds.center();
        let radius = members
            .iter()
            .flat_map(|&i| built[i].3.iter().flatten())
            .map(|&v| positions[v as usize].distance(center))
            .fold(0.0, f32::max);
        members.sort_by(|&a, &b| {
            built[a]
                .1
                .distance_squared(center)
                .total_cmp(&built[b].1.distance_squared(center))
        });
        let group = model.leaf_groups.len() as u32;
        let start = model.leaves.len() as u32;
        for i in members {
            let (_, c, nrm, tris) = &built[i];
            let leaf = model.leaves.len() as u32;
            let first_triangle = (model.leaf_indices.len() / 3) as u32;
            for t in tris.iter() {
                model.leaf_indices.extend_from_slice(t);
                for &v in t {
                    leaf_vertex_leaf[v as usize] = leaf;
                }
            }
            model.leaves.push(Leaf {
                center: *c,
                normal: *nrm,
                triangles: first_triangle..(model.leaf_indices.len() / 3) as u32,
                group,
            });
        }
        model.leaf_groups.push(LeafGroup {
            ring,
            bounds: BoundingSphere { center, radius },
            leaves: start..model.leaves.len() as u32,
        });
        model.rings[ring as usize].leaf_group = Some(group);
    }
    // Vertices no triangle uses belong to no leaf; give them the first leaf so every
    // per-vertex array stays valid for the renderer.
    for l in &mut leaf_vertex_leaf {
        if *l == u32::MAX {
            *l = 0;
        }
    }
    model.leaf_vertex_leaf = leaf_vertex_leaf;
    model.mean_leaf_triangle_area = total_area / triangles.len() as f32;
    model.bounds = model
        .trunk_bounds
        .union(Bounds::from_points(positions.iter().copied()));
    model.leaf_positions = mesh.positions;
    model.leaf_normals = mesh.normals;
}

/// The triangles split into connected patches (each one leaf), in the order each patch
/// first appears.
fn connected_patches(triangles: &[[u32; 3]], vertices: usize) -> Vec<Vec<[u32; 3]>> {
    // Union-find over vertices: each connected patch is one leaf.
    let mut parent: Vec<u32> = (0..vertices as u32).collect();
    fn find(parent: &mut [u32], mut v: u32) -> u32 {
        while parent[v as usize] != v {
            parent[v as usize] = parent[parent[v as usize] as usize];
            v = parent[v as usize];
        }
        v
    }
    for t in triangles {
        let a = find(&mut parent, t[0]);
        for &v in &t[1..] {
            let b = find(&mut parent, v);
            parent[b as usize] = a;
        }
    }
    let mut leaf_of_root: HashMap<u32, usize> = HashMap::new();
    let mut leaf_triangles: Vec<Vec<[u32; 3]>> = Vec::new();
    for t in triangles {
        let root = find(&mut parent, t[0]);
        let leaf = *leaf_of_root.entry(root).or_insert_with(|| {
            leaf_triangles.push(Vec::new());
            leaf_triangles.len() - 1
        });
        leaf_triangles[leaf].push(*t);
    }
    leaf_triangles
}

/// A leaf's area, centre (area-weighted; the vertices' mean when it has no area) and unit
/// normal (agreeing with the mesh's own vertex normals).
fn leaf_shape(tris: &[[u32; 3]], positions: &[Vec3], normals: &[Vec3]) -> (f32, Vec3, Vec3) {
    let mut area = 0.0;
    let mut center = Vec3::ZERO;
    let mut normal = Vec3::ZERO;
    let mut vertex_normal = Vec3::ZERO;
    for t in tris {
        let p = t.map(|v| positions[v as usize]);
        let cross = (p[1] - p[0]).cross(p[2] - p[0]);
        let a = 0.5 * cross.length();
        area += a;
        center += a * (p[0] + p[1] + p[2]) / 3.0;
        normal += cross;
        vertex_normal += t.iter().map(|&v| normals[v as usize]).sum::<Vec3>();
    }
    let center = if area > 0.0 {
        center / area
    } else {
        mean(tris.iter().flatten().map(|&v| positions[v as usize]))
    };
    let mut normal = normal.try_normalize().unwrap_or(Vec3::Y);
    if normal.dot(vertex_normal) < 0.0 {
        normal = -normal; // agree with the mesh's own normals
    }
    (area, center, normal)
}
