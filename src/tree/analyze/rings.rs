//! The trunk's ring hierarchy (thesis §4.2): root rings at the ground, child rings
//! grown through the mesh, separate pieces attached where their open base meets
//! another piece, and the hierarchy turned into the model's rings and segments.

use std::collections::HashMap;

use bevy::math::Vec3;

use super::{AnalysisOptions, AnalysisWarning, MeshData, TreeAnalysisError, WeldedMesh, mean};
use crate::tree::model::{Bounds, NO_RING, Ring, Segments, TreeModel};

/// Vertex adjacency in compressed rows.
struct Adjacency {
    offsets: Vec<u32>,
    neighbours: Vec<u32>,
}

impl Adjacency {
    fn new(vertices: usize, triangles: &[[u32; 3]], first: u32) -> Self {
        let mut edges: Vec<(u32, u32)> = Vec::with_capacity(triangles.len() * 6);
        for t in triangles {
            for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
                edges.push((a - first, b - first));
                edges.push((b - first, a - first));
            }
        }
        edges.sort_unstable();
        edges.dedup();
        Self::from_sorted_edges(vertices, &edges)
    }

    /// Rows from directed edges `(from, to)` sorted by `from`.
    fn from_sorted_edges(vertices: usize, edges: &[(u32, u32)]) -> Self {
        let mut offsets = vec![0_u32; vertices + 1];
        for &(a, _) in edges {
            offsets[a as usize + 1] += 1;
        }
        for i in 0..vertices {
            offsets[i + 1] += offsets[i];
        }
        Self {
            offsets,
            neighbours: edges.iter().map(|&(_, b)| b).collect(),
        }
    }

    fn of(&self, v: u32) -> &[u32] {
        &self.neighbours[self.offsets[v as usize] as usize..self.offsets[v as usize + 1] as usize]
    }
}

/// The ring hierarchy under construction (local trunk vertex indices).
pub(super) struct Hierarchy {
    /// The weld tolerance (absolute).
    tolerance: f32,
    /// Rings whose vertices do not close (a tube welded into a tangle where it is
    /// thinner than the tolerance): how many, and where the first is.
    irregular: (usize, Option<Vec3>),
    rings: Vec<RingBuild>,
    vertex_ring: Vec<u32>,
    triangles: Vec<[u32; 3]>,
}

struct RingBuild {
    loop_vertices: Vec<u32>,
    extra_vertices: Vec<u32>,
    center: Vec3,
    diameter: f32,
    parent: u32,
    level: u32,
    /// The open end a separate piece was attached by: its link to the parent is no
    /// surface, and nothing attaches near it.
    piece_base: bool,
}

/// A closed piece of trunk no larger than this many weld tolerances (from its centre)
/// is a speck of welded twig, attached where it lies, not an error.
const SPECK_TOLERANCES: f32 = 100.0;

/// Within its base radius of a piece's open base, an open end attaches to that piece
/// only when its centre is within this fraction of the radius from the axis.
const OPEN_BASE_AXIS: f32 = 0.25;

/// A root ring thinner than this fraction of the thickest is no stem: it is a twig's end
/// in the ground, and the twig is attached by its other end.
const ROOT_FRACTION: f32 = 0.25;

/// Where an open end would attach: lower is better, surface distance first.
#[derive(Clone, Copy, Debug)]
struct Place {
    /// Distance from the open end's centre to the segment's surface (0 inside it).
    surface: f32,
    /// Distance to the segment's axis over its radius there.
    axis: f32,
    /// The ring to hang from.
    parent: u32,
}

impl Place {
    const NONE: Self = Self {
        surface: f32::INFINITY,
        axis: f32::INFINITY,
        parent: NO_RING,
    };

    fn better_than(&self, other: &Self) -> bool {
        (self.surface, self.axis) < (other.surface, other.axis)
    }

    fn better(self, other: Self) -> Self {
        if other.better_than(&self) {
            other
        } else {
            self
        }
    }
}

impl Hierarchy {
    pub(super) fn build(
        mesh: &WeldedMesh,
        ground: f32,
        tolerance: f32,
        warnings: &mut Vec<AnalysisWarning>,
    ) -> Result<Self, TreeAnalysisError> {
        let n = mesh.positions.len();
        let triangles: Vec<[u32; 3]> = mesh
            .triangles
            .iter()
            .map(|t| t.map(|v| v - mesh.first))
            .collect();
        let adjacency = Adjacency::new(n, &triangles, 0);
        let mut h = Self {
            tolerance,
            irregular: (0, None),
            rings: Vec::new(),
            vertex_ring: vec![NO_RING; n],
            triangles,
        };
        let positions = &mesh.positions;
        let boundary = boundary_loops(&h.triangles, n);

        // Root rings: among the vertices at or below the ground that a triangle uses (a
        // stray vertex below the ground is no root), each connected part gives the open
        // ends lying wholly in it (a tube cut below the ground), or, when it has none, is
        // itself the ring (a capped end). A part that is neither is a branch dipping into
        // the ground (a bush's side branch): it is no root, and its piece is attached by
        // its open end below like any other.
        let used: Vec<bool> = {
            let mut u = vec![false; n];
            for t in &h.triangles {
                for &v in t {
                    u[v as usize] = true;
                }
            }
            u
        };
        let below: Vec<bool> = positions.iter().map(|p| p.y <= ground).collect();
        if !(0..n).any(|v| below[v] && used[v]) {
            let lowest = lowest_used(&used, positions);
            return Err(TreeAnalysisError::NoRootRing { ground, lowest });
        }
        let mut on_open_end = vec![false; n];
        for &v in boundary.iter().flatten() {
            on_open_end[v as usize] = true;
        }
        // Each vertex's piece (connected part of the mesh), each open end's radius, and
        // the widest open end of each piece.
        let mut piece_of = vec![u32::MAX; n];
        let mut pieces = 0;
        for v in 0..n as u32 {
            if piece_of[v as usize] == u32::MAX {
                for w in components([v], &adjacency, |_| true).remove(0) {
                    piece_of[w as usize] = pieces;
                }
                pieces += 1;
            }
        }
        let end_centers: Vec<Vec3> = boundary
            .iter()
            .map(|lp| mean(lp.iter().map(|&v| positions[v as usize])))
            .collect();
        let end_radius: Vec<f32> = boundary
            .iter()
            .zip(&end_centers)
            .map(|(lp, &center)| {
                lp.iter()
                    .map(|&v| positions[v as usize].distance(center))
                    .sum::<f32>()
                    / lp.len() as f32
            })
            .collect();
        let mut widest_end = vec![0.0_f32; pieces as usize];
        for (lp, &radius) in boundary.iter().zip(&end_radius) {
            let piece = piece_of[lp[0] as usize] as usize;
            widest_end[piece] = widest_end[piece].max(radius);
        }
        let (candidates, not_a_ring) = root_candidates(
            &RootSearch {
                boundary: &boundary,
                end_radius: &end_radius,
                widest_end: &widest_end,
                piece_of: &piece_of,
                below: &below,
                used: &used,
                on_open_end: &on_open_end,
            },
            positions,
            &adjacency,
            tolerance,
        );
        let mut queue = Vec::new();
        // Stems stand side by side; a twig whose parent dips into the ground (a bush's)
        // may stand there on its widest end too, but it is far thinner than the trunk,
        // and is attached to its parent instead.
        let thickest = candidates.iter().map(|c| c.1).fold(0.0, f32::max);
        for (vertices, radius) in candidates {
            if radius + tolerance >= ROOT_FRACTION * thickest {
                queue.push(h.add_ring(vertices, NO_RING, positions, &adjacency));
            }
        }
        if queue.is_empty() {
            let lowest = lowest_used(&used, positions);
            return Err(not_a_ring.unwrap_or(TreeAnalysisError::NoRootRing { ground, lowest }));
        }
        h.grow(&mut queue, positions, &adjacency);
        h.attach_pieces(
            &boundary,
            &end_centers,
            positions,
            &adjacency,
            tolerance,
            warnings,
        );
        h.hang_specks(&used, positions, &adjacency, tolerance)?;
        if let (count, Some(position)) = h.irregular {
            warnings.push(AnalysisWarning::IrregularRings { count, position });
        }
        Ok(h)
    }

    /// The pieces left without a ring have no open end. A speck (a twig thinner and
    /// shorter than a few hundred tolerances, welded shut) hangs where it is as one ring;
    /// anything larger floating apart from the tree is an error.
    fn hang_specks(
        &mut self,
        used: &[bool],
        positions: &[Vec3],
        adjacency: &Adjacency,
        tolerance: f32,
    ) -> Result<(), TreeAnalysisError> {
        let n = positions.len();
        while let Some(v) = (0..n).find(|&v| used[v] && self.vertex_ring[v] == NO_RING) {
            let piece = components([v as u32], adjacency, |_| true).remove(0);
            let center = mean(piece.iter().map(|&w| positions[w as usize]));
            let extent = piece
                .iter()
                .map(|&w| positions[w as usize].distance(center))
                .fold(0.0, f32::max);
            if extent > SPECK_TOLERANCES * tolerance {
                return Err(TreeAnalysisError::DetachedTrunkPiece {
                    position: positions[v],
                    vertices: piece.len(),
                });
            }
            let parent = self.best_place(center, tolerance).parent;
            let ring = self.add_ring(piece, parent, positions, adjacency);
            self.rings[ring as usize].piece_base = true;
        }
        Ok(())
    }

    /// Attaches the separate pieces (branches modelled apart) by their open ends, nearest
    /// first, so branches of branches follow their parents.
    ///
    /// An open end attaches where its centre meets the surface or the axis of what is
    /// already attached: the nearest point on a segment, scored first by the distance to
    /// the segment's surface (zero inside the tube), then by the distance to its axis
    /// relative to its radius. Generators start a side branch inside its parent, often
    /// a few centimetres from its siblings' bases, so the nearest *ring centre* is often a
    /// sibling's base; the axis is not. A piece's open base is never a place to attach
    /// to: neither the link from a piece to its parent (no surface) nor the first
    /// segment of a piece within its base radius counts.
    fn attach_pieces(
        &mut self,
        boundary: &[Vec<u32>],
        centers: &[Vec3],
        positions: &[Vec3],
        adjacency: &Adjacency,
        tolerance: f32,
        warnings: &mut Vec<AnalysisWarning>,
    ) {
        // Each open end's best place so far, updated only against rings added since.
        let mut best_place = vec![Place::NONE; boundary.len()];
        let mut rings_seen = 0;
        let mut queue = Vec::new();
        loop {
            let mut best: Option<usize> = None;
            for (i, lp) in boundary.iter().enumerate() {
                if lp.iter().any(|&v| self.vertex_ring[v as usize] != NO_RING) {
                    continue;
                }
                for r in rings_seen..self.rings.len() {
                    if let Some(place) = self.place_on_segment(r as u32, centers[i], tolerance)
                        && place.better_than(&best_place[i])
                    {
                        best_place[i] = place;
                    }
                }
                if best.is_none_or(|b| best_place[i].better_than(&best_place[b])) {
                    best = Some(i);
                }
            }
            rings_seen = self.rings.len();
            let Some(i) = best else {
                return;
            };
            let mut place = best_place[i];
            if place.parent == NO_RING {
                place = self.best_place(centers[i], tolerance);
            }
            let ring = self.add_ring(boundary[i].clone(), place.parent, positions, adjacency);
            self.rings[ring as usize].piece_base = true;
            let reach = 2.0
                * (self.rings[place.parent as usize].diameter + self.rings[ring as usize].diameter);
            if place.surface > reach.max(tolerance) {
                warnings.push(AnalysisWarning::BranchAttachedFar {
                    ring,
                    distance: place.surface,
                });
            }
            queue.push(ring);
            self.grow(&mut queue, positions, adjacency);
        }
    }

    /// The best place for `point` on any segment, or, when no segment takes it (nothing
    /// but lone root rings), the nearest ring.
    fn best_place(&self, point: Vec3, tolerance: f32) -> Place {
        let on_segments = (0..self.rings.len() as u32)
            .filter_map(|r| self.place_on_segment(r, point, tolerance))
            .fold(Place::NONE, Place::better);
        if on_segments.parent != NO_RING {
            return on_segments;
        }
        self.rings
            .iter()
            .enumerate()
            .map(|(r, ring)| Place {
                surface: ring.center.distance(point),
                axis: 0.0,
                parent: r as u32,
            })
            .fold(Place::NONE, Place::better)
    }

    /// Where `point` meets the segment ending at ring `r`, if that segment is one a
    /// piece may attach to.
    fn place_on_segment(&self, r: u32, point: Vec3, tolerance: f32) -> Option<Place> {
        let ring = &self.rings[r as usize];
        if ring.parent == NO_RING || ring.piece_base {
            return None;
        }
        let lower = &self.rings[ring.parent as usize];
        let (a, axis) = (lower.center, ring.center - lower.center);
        let length_squared = axis.length_squared();
        let t = if length_squared > 0.0 {
            ((point - a).dot(axis) / length_squared).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let to_axis = point.distance(a + t * axis);
        let radius = 0.5 * (lower.diameter + t * (ring.diameter - lower.diameter));
        // Near a piece's open base only what lies on its axis hangs from it (a twig
        // starting at the base of its branch); a sibling starting beside it does not.
        if lower.piece_base
            && t * length_squared.sqrt() < 0.5 * lower.diameter
            && to_axis > OPEN_BASE_AXIS * radius
        {
            return None;
        }
        let surface = (to_axis - radius).max(0.0);
        Some(Place {
            surface: if surface <= tolerance { 0.0 } else { surface },
            axis: to_axis / radius.max(tolerance),
            parent: if t < 0.5 { ring.parent } else { r },
        })
    }

    /// Breadth-first: the unvisited neighbours of each ring, split into connected
    /// components, are its child rings.
    fn grow(&mut self, queue: &mut Vec<u32>, positions: &[Vec3], adjacency: &Adjacency) {
        let mut head = 0;
        let mut candidates = Vec::new();
        while head < queue.len() {
            let ring = queue[head];
            head += 1;
            candidates.clear();
            let r = &self.rings[ring as usize];
            for &v in r.loop_vertices.iter().chain(&r.extra_vertices) {
                for &w in adjacency.of(v) {
                    if self.vertex_ring[w as usize] == NO_RING {
                        candidates.push(w);
                    }
                }
            }
            candidates.sort_unstable();
            candidates.dedup();
            let set: &[u32] = &candidates;
            for component in components(set.iter().copied(), adjacency, |w| {
                set.binary_search(&w).is_ok()
            }) {
                let child = self.add_ring(component, ring, positions, adjacency);
                queue.push(child);
            }
        }
        queue.clear();
    }

    /// Adds a set of vertices as a ring: its loop and cap centre if they close, all of
    /// them as the loop (counted in [`Hierarchy::irregular`]) if they do not.
    fn add_ring(
        &mut self,
        vertices: Vec<u32>,
        parent: u32,
        positions: &[Vec3],
        adjacency: &Adjacency,
    ) -> u32 {
        let RingShape {
            loop_vertices,
            extra,
            center,
        } = ring_shape(&vertices, positions, adjacency, self.tolerance).unwrap_or_else(|_| {
            let center = mean(vertices.iter().map(|&v| positions[v as usize]));
            self.irregular.0 += 1;
            self.irregular.1.get_or_insert(center);
            RingShape {
                loop_vertices: vertices,
                extra: Vec::new(),
                center,
            }
        });
        let diameter = 2.0
            * loop_vertices
                .iter()
                .map(|&v| positions[v as usize].distance(center))
                .sum::<f32>()
            / loop_vertices.len() as f32;
        let id = self.rings.len() as u32;
        for &v in loop_vertices.iter().chain(&extra) {
            self.vertex_ring[v as usize] = id;
        }
        let level = if parent == NO_RING {
            0
        } else {
            self.rings[parent as usize].level + 1
        };
        self.rings.push(RingBuild {
            loop_vertices,
            extra_vertices: extra,
            center,
            diameter,
            parent,
            level,
            piece_base: false,
        });
        id
    }

    pub(super) fn into_model(
        self,
        mesh: WeldedMesh,
        input: &MeshData,
        options: &AnalysisOptions,
    ) -> Result<TreeModel, TreeAnalysisError> {
        let Self {
            rings: built,
            mut vertex_ring,
            triangles,
            ..
        } = self;
        // Vertices no triangle uses belong to no ring; point them at ring 0 so per-vertex
        // ring lookups on the GPU stay in range.
        for r in &mut vertex_ring {
            if *r == NO_RING {
                *r = 0;
            }
        }
        let (rings, ring_vertices, ring_vectors) = model_rings(&built, &mesh.positions);
        let (segments, trunk_indices) = trunk_segments(&rings, &triangles, &vertex_ring)?;

        let positions = mesh.positions;
        let mut area_sum = 0.0_f32;
        let mut area_center = Vec3::ZERO;
        for t in trunk_indices.chunks_exact(3) {
            let p = [0, 1, 2].map(|i| positions[t[i] as usize]);
            let area = 0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length();
            area_sum += area;
            area_center += area * (p[0] + p[1] + p[2]) / 3.0;
        }
        let trunk_bounds = Bounds::from_points(positions.iter().copied());
        let triangle_count = (trunk_indices.len() / 3).max(1) as f32;
        Ok(TreeModel {
            rings,
            ring_vertices,
            ring_vectors,
            segments,
            trunk_normals: mesh.normals,
            trunk_vertex_ring: vertex_ring,
            trunk_indices,
            mean_trunk_triangle_area: area_sum / triangle_count,
            trunk_area_center: if area_sum > 0.0 {
                area_center / area_sum
            } else {
                trunk_bounds.center()
            },
            trunk_positions: positions,
            leaf_positions: Vec::new(),
            leaf_normals: Vec::new(),
            leaf_vertex_leaf: Vec::new(),
            leaf_indices: Vec::new(),
            leaves: Vec::new(),
            leaf_groups: Vec::new(),
            bounds: trunk_bounds,
            trunk_bounds,
            mean_leaf_triangle_area: 0.0,
            bark_color: input.color.unwrap_or(options.default_bark_color),
            leaf_color: options.default_leaf_color,
            crown: None,
        })
    }
}

/// A set of vertices checked to be a closed ring: its loop, its cap's centre vertex (if
/// any), and the loop's centre.
struct RingShape {
    loop_vertices: Vec<u32>,
    extra: Vec<u32>,
    center: Vec3,
}

/// Checks that `vertices` close into a ring (each loop vertex has two neighbours in it).
///
/// A ring no wider than a few weld tolerances is taken as it is: a tube tapering to a
/// tip (EZ-Tree ends its twigs at radius 0.001) welds partly, into two or three vertices
/// that cannot close, and is a point for every purpose of the model.
fn ring_shape(
    vertices: &[u32],
    positions: &[Vec3],
    adjacency: &Adjacency,
    tolerance: f32,
) -> Result<RingShape, TreeAnalysisError> {
    // Membership by binary search: a "ring" can be large (a ground plane exported with
    // the tree lies below the ground too), and a linear search per neighbour made
    // this quadratic in its vertices.
    let mut sorted = vertices.to_vec();
    sorted.sort_unstable();
    let inside = |v: u32| sorted.binary_search(&v).is_ok();
    let degree = |v: u32| adjacency.of(v).iter().filter(|&&w| inside(w)).count();
    // A single hub joined to every other vertex is a cap's centre, not part of the loop
    // (two such vertices are a quad with a diagonal: both belong to the loop).
    let hubs: Vec<u32> = vertices
        .iter()
        .copied()
        .filter(|&v| vertices.len() >= 4 && degree(v) == vertices.len() - 1)
        .collect();
    // A hub is a cap's centre only if the rest closes without it; otherwise (a flat cap
    // triangulated as a fan from one of its own rim vertices) it belongs to the loop.
    let close = |extra: Vec<u32>| -> Result<RingShape, TreeAnalysisError> {
        let loop_vertices: Vec<u32> = vertices
            .iter()
            .copied()
            .filter(|v| !extra.contains(v))
            .collect();
        let center = mean(loop_vertices.iter().map(|&v| positions[v as usize]));
        let microscopic = loop_vertices
            .iter()
            .all(|&v| positions[v as usize].distance(center) <= 2.0 * tolerance);
        if loop_vertices.len() > 1 && !microscopic {
            let in_loop = |w: u32| inside(w) && !extra.contains(&w);
            for &v in &loop_vertices {
                let neighbours = adjacency.of(v).iter().filter(|&&w| in_loop(w)).count();
                if neighbours < 2 {
                    return Err(TreeAnalysisError::OpenRing {
                        position: center,
                        vertices: loop_vertices.len(),
                        vertex: v,
                        neighbours,
                    });
                }
            }
        }
        Ok(RingShape {
            loop_vertices,
            extra,
            center,
        })
    };
    match hubs.as_slice() {
        &[hub] => close(vec![hub]).or_else(|_| close(Vec::new())),
        _ => close(Vec::new()),
    }
}

/// Whether points spread like a flat disc: thin across their plane, and not much
/// longer one way than the other within it (the principal axes of their covariance).
fn is_flat_and_round(vertices: &[u32], positions: &[Vec3]) -> bool {
    if vertices.len() < 3 {
        return false;
    }
    let center = mean(vertices.iter().map(|&v| positions[v as usize]));
    let mut covariance = [[0.0_f64; 3]; 3];
    for &v in vertices {
        let d = (positions[v as usize] - center).as_dvec3().to_array();
        for i in 0..3 {
            for j in 0..3 {
                covariance[i][j] += d[i] * d[j];
            }
        }
    }
    let [small, middle, large] = symmetric_eigenvalues(covariance);
    large > 0.0 && small <= 0.01 * middle && middle >= 0.25 * large
}

/// Eigenvalues of a symmetric 3×3 matrix, smallest first (the trigonometric solution of
/// its characteristic cubic).
fn symmetric_eigenvalues(a: [[f64; 3]; 3]) -> [f64; 3] {
    let off = a[0][1].powi(2) + a[0][2].powi(2) + a[1][2].powi(2);
    let mut e = if off == 0.0 {
        [a[0][0], a[1][1], a[2][2]]
    } else {
        let q = (a[0][0] + a[1][1] + a[2][2]) / 3.0;
        let p =
            (((a[0][0] - q).powi(2) + (a[1][1] - q).powi(2) + (a[2][2] - q).powi(2) + 2.0 * off)
                / 6.0)
                .sqrt();
        let b = |i: usize, j: usize| (a[i][j] - if i == j { q } else { 0.0 }) / p;
        let det = b(0, 0) * (b(1, 1) * b(2, 2) - b(1, 2) * b(2, 1))
            - b(0, 1) * (b(1, 0) * b(2, 2) - b(1, 2) * b(2, 0))
            + b(0, 2) * (b(1, 0) * b(2, 1) - b(1, 1) * b(2, 0));
        let phi = (det / 2.0).clamp(-1.0, 1.0).acos() / 3.0;
        let largest = q + 2.0 * p * phi.cos();
        let smallest = q + 2.0 * p * (phi + 2.0 * core::f64::consts::PI / 3.0).cos();
        [largest, 3.0 * q - largest - smallest, smallest]
    };
    e.sort_by(f64::total_cmp);
    e
}

/// Connected components of `seeds` through edges whose both ends satisfy `member`.
fn components(
    seeds: impl IntoIterator<Item = u32>,
    adjacency: &Adjacency,
    member: impl Fn(u32) -> bool,
) -> Vec<Vec<u32>> {
    let mut seen: HashMap<u32, ()> = HashMap::new();
    let mut out = Vec::new();
    for seed in seeds {
        if seen.contains_key(&seed) {
            continue;
        }
        let mut component = vec![seed];
        seen.insert(seed, ());
        let mut i = 0;
        while i < component.len() {
            let v = component[i];
            i += 1;
            for &w in adjacency.of(v) {
                if member(w) && !seen.contains_key(&w) {
                    seen.insert(w, ());
                    component.push(w);
                }
            }
        }
        component.sort_unstable();
        out.push(component);
    }
    out
}

/// Loops of boundary edges (edges used by one triangle): the open ends of tubes.
fn boundary_loops(triangles: &[[u32; 3]], vertices: usize) -> Vec<Vec<u32>> {
    let mut edges: Vec<(u32, u32)> = triangles
        .iter()
        .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
        .map(|(a, b)| (a.min(b), a.max(b)))
        .collect();
    edges.sort_unstable();
    let mut boundary = Vec::new();
    let mut i = 0;
    while i < edges.len() {
        let mut j = i;
        while j < edges.len() && edges[j] == edges[i] {
            j += 1;
        }
        if j - i == 1 {
            boundary.push(edges[i]);
            boundary.push((edges[i].1, edges[i].0));
        }
        i = j;
    }
    boundary.sort_unstable();
    let adjacency = Adjacency::from_sorted_edges(vertices, &boundary);
    let on_boundary: Vec<bool> = (0..vertices as u32)
        .map(|v| !adjacency.of(v).is_empty())
        .collect();
    components(
        (0..vertices as u32).filter(|&v| on_boundary[v as usize]),
        &adjacency,
        |_| true,
    )
}

/// What the search for root rings reads of the mesh, per vertex and per open end.
struct RootSearch<'a> {
    boundary: &'a [Vec<u32>],
    end_radius: &'a [f32],
    /// Per piece, its widest open end's radius.
    widest_end: &'a [f32],
    piece_of: &'a [u32],
    below: &'a [bool],
    used: &'a [bool],
    on_open_end: &'a [bool],
}

/// The root rings' candidates (vertices and radius), and what kept the first part in the
/// ground that failed from being a ring.
fn root_candidates(
    r: &RootSearch,
    positions: &[Vec3],
    adjacency: &Adjacency,
    tolerance: f32,
) -> (Vec<(Vec<u32>, f32)>, Option<TreeAnalysisError>) {
    let n = positions.len();
    let mut candidates: Vec<(Vec<u32>, f32)> = Vec::new();
    let mut not_a_ring = None;
    for part in components(
        (0..n as u32).filter(|&v| r.below[v as usize] && r.used[v as usize]),
        adjacency,
        |v| r.below[v as usize],
    ) {
        let inside = |v: &u32| part.binary_search(v).is_ok();
        let ends: Vec<usize> = (0..r.boundary.len())
            .filter(|&e| r.boundary[e].iter().all(inside))
            .collect();
        if !ends.is_empty() {
            // A piece stands on its widest open end; a narrower one in the ground is
            // a drooping twig's tip, and the twig is attached by its base instead.
            for e in ends {
                let piece = r.piece_of[r.boundary[e][0] as usize] as usize;
                if r.end_radius[e] + tolerance >= r.widest_end[piece] {
                    candidates.push((r.boundary[e].clone(), r.end_radius[e]));
                }
            }
            continue;
        }
        if part.iter().any(|&v| r.on_open_end[v as usize]) {
            // Part of an open end, the rest of which stands above the ground. Should
            // nothing else be a root, this part is what failed to be one.
            if let Err(e) = ring_shape(&part, positions, adjacency, tolerance) {
                not_a_ring.get_or_insert(e);
            }
            continue;
        }
        // No open end in it: a capped end (a fan around a centre, or a flat round
        // polygon) is a root; a patch of a tube's side dipping into the ground (a
        // drooping twig's middle) is neither.
        match ring_shape(&part, positions, adjacency, tolerance) {
            Ok(shape) if !shape.extra.is_empty() || is_flat_and_round(&part, positions) => {
                let radius = shape
                    .loop_vertices
                    .iter()
                    .map(|&v| positions[v as usize].distance(shape.center))
                    .sum::<f32>()
                    / shape.loop_vertices.len() as f32;
                candidates.push((part, radius));
            }
            Ok(_) => {}
            Err(e) => {
                not_a_ring.get_or_insert(e);
            }
        }
    }
    (candidates, not_a_ring)
}

/// The height of the lowest vertex a triangle uses.
fn lowest_used(used: &[bool], positions: &[Vec3]) -> f32 {
    (0..positions.len())
        .filter(|&v| used[v])
        .map(|v| positions[v].y)
        .fold(f32::INFINITY, f32::min)
}

/// The model's rings from the built ones, with their children, and each ring's loop
/// vertices with their offsets from its centre.
fn model_rings(built: &[RingBuild], positions: &[Vec3]) -> (Vec<Ring>, Vec<u32>, Vec<Vec3>) {
    let mut rings: Vec<Ring> = built
        .iter()
        .map(|r| Ring {
            center: r.center,
            diameter: r.diameter,
            parent: r.parent,
            children: Vec::new(),
            level: r.level,
            distance_to_parent: if r.parent == NO_RING {
                0.0
            } else {
                r.center.distance(built[r.parent as usize].center)
            },
            vertices: 0..0,
            leaf_group: None,
        })
        .collect();
    for i in 0..rings.len() {
        let p = rings[i].parent;
        if p != NO_RING {
            rings[p as usize].children.push(i as u32);
        }
    }
    let mut ring_vertices = Vec::new();
    let mut ring_vectors = Vec::new();
    for (ring, b) in rings.iter_mut().zip(built) {
        let start = ring_vertices.len() as u32;
        for &v in &b.loop_vertices {
            ring_vertices.push(v);
            ring_vectors.push(positions[v as usize] - b.center);
        }
        ring.vertices = start..ring_vertices.len() as u32;
    }
    (rings, ring_vertices, ring_vectors)
}

/// The trunk's segments, thin → thick, and its triangles ordered by segment.
fn trunk_segments(
    rings: &[Ring],
    triangles: &[[u32; 3]],
    vertex_ring: &[u32],
) -> Result<(Segments, Vec<u32>), TreeAnalysisError> {
    // Each triangle belongs to the segment ending at its deepest ring; a root cap goes
    // to the root's first child.
    let mut segment_of_triangle = Vec::with_capacity(triangles.len());
    for t in triangles {
        let mut ring = t
            .iter()
            .map(|&v| vertex_ring[v as usize])
            .max_by_key(|&r| (rings[r as usize].level, r))
            .unwrap_or(0);
        if rings[ring as usize].is_root() {
            match rings[ring as usize].children.first() {
                Some(&c) => ring = c,
                None => {
                    return Err(TreeAnalysisError::NoSegment {
                        position: rings[ring as usize].center,
                    });
                }
            }
        }
        segment_of_triangle.push(ring);
    }
    let mut order: Vec<u32> = (0..rings.len() as u32)
        .filter(|&r| !rings[r as usize].is_root())
        .collect();
    let segment_diameter = |r: u32| {
        rings[r as usize]
            .diameter
            .max(rings[rings[r as usize].parent as usize].diameter)
    };
    order.sort_by(|&a, &b| {
        segment_diameter(a)
            .total_cmp(&segment_diameter(b))
            .then(a.cmp(&b))
    });
    let mut slot = vec![u32::MAX; rings.len()];
    for (s, &r) in order.iter().enumerate() {
        slot[r as usize] = s as u32;
    }
    let mut counts = vec![0_u32; order.len() + 1];
    for &r in &segment_of_triangle {
        counts[slot[r as usize] as usize + 1] += 1;
    }
    for s in 0..order.len() {
        counts[s + 1] += counts[s];
    }
    let triangle_offsets = counts.clone();
    let mut cursor = counts;
    let mut trunk_indices = vec![0_u32; triangles.len() * 3];
    for (t, &r) in triangles.iter().zip(&segment_of_triangle) {
        let s = slot[r as usize] as usize;
        let at = cursor[s] as usize * 3;
        trunk_indices[at..at + 3].copy_from_slice(t);
        cursor[s] += 1;
    }
    let mut segments = Segments {
        triangle_offsets,
        ..Segments::default()
    };
    let mut total_length = 0.0;
    for &r in &order {
        let ring = &rings[r as usize];
        let lower = rings[ring.parent as usize].center;
        segments.ring.push(r);
        segments.line.push([lower, ring.center]);
        segments.diameter.push(segment_diameter(r));
        total_length += lower.distance(ring.center);
        segments.cumulative_length.push(total_length);
    }
    Ok((segments, trunk_indices))
}
