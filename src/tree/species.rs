//! A seeded procedural generator of tree species whose meshes satisfy the analysis'
//! constraints: a trunk reaching below the ground, branches as tapered tubes of rings
//! (each a separate piece starting inside its parent, as modelling tools export them)
//! ending in a pointed tip, and leaves as small separate patches around the twigs.
//!
//! Species are described in RON (`*.species.ron`, see [`SpeciesDesc`]).

use crate::ron_file::invalid;
use core::f32::consts::TAU;

use bevy::math::{Quat, Vec3};
use bevy::reflect::Reflect;
use serde::{Deserialize, Serialize};

use super::analyze::{AnalysisOptions, MeshData, TreeAnalysis, TreeAnalysisError, analyze};
use super::model::LinearRgb;
use crate::rng::SplitMix64;

/// One level of branching: the trunk (level 0), its branches, their branches…
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Reflect)]
#[serde(default, deny_unknown_fields)]
pub struct BranchLevel {
    /// Trunk: length in metres. Other levels: length as a fraction of the parent's.
    pub length: f32,
    /// Trunk: base radius in metres. Other levels: base radius as a fraction of the
    /// parent's radius where the branch starts (below 1, so it starts inside the parent).
    pub radius: f32,
    /// Tip radius as a fraction of the base radius (the last ring before the tip).
    pub taper: f32,
    /// Cylinders along the branch.
    pub segments: u32,
    /// Vertices per ring (at least 3).
    pub ring_vertices: u32,
    /// Branches of the next level grown along this one.
    pub children: u32,
    /// Children start between this fraction of the branch's length and its end.
    pub children_start: f32,
    /// Angle between a child and this branch, in degrees.
    pub angle: f32,
    /// Random variation of the angle, in degrees (±).
    pub angle_jitter: f32,
    /// Random variation of the length, as a fraction (±).
    pub length_jitter: f32,
    /// Bend per segment towards the ground (negative: towards the sky), in degrees.
    pub droop: f32,
}

impl Default for BranchLevel {
    fn default() -> Self {
        Self {
            length: 0.5,
            radius: 0.5,
            taper: 0.4,
            segments: 3,
            ring_vertices: 5,
            children: 0,
            children_start: 0.4,
            angle: 45.0,
            angle_jitter: 10.0,
            length_jitter: 0.15,
            droop: 0.0,
        }
    }
}

/// The shape of one leaf.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize, Reflect)]
pub enum LeafShape {
    /// One triangle.
    Triangle,
    /// A quad: two triangles sharing an edge.
    #[default]
    Quad,
}

/// The leaves, grown around the branches of the last level (the twigs).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Reflect)]
#[serde(default, deny_unknown_fields)]
pub struct LeafDesc {
    /// Leaves per twig.
    pub per_twig: u32,
    /// Leaf size (edge length) in metres.
    pub size: f32,
    /// Shape of each leaf.
    pub shape: LeafShape,
    /// Distance of a leaf's centre from the twig's axis, in metres.
    pub spread: f32,
    /// Leaves grow along this last fraction of each twig.
    pub along: f32,
}

impl Default for LeafDesc {
    fn default() -> Self {
        Self {
            per_twig: 20,
            size: 0.25,
            shape: LeafShape::Quad,
            spread: 0.35,
            along: 0.7,
        }
    }
}

/// A tree species: the parameters of the generator, as stored in `*.species.ron`.
///
/// ```
/// # use bevy_sherwood::tree::SpeciesDesc;
/// let species = SpeciesDesc::from_ron_str(r#"(
///     name: "sapling",
///     seed: 3,
///     levels: [
///         (length: 2.0, radius: 0.08, segments: 3, ring_vertices: 6, children: 3),
///         (length: 0.5, radius: 0.5, segments: 2, ring_vertices: 4),
///     ],
///     leaves: (per_twig: 6, size: 0.15),
/// )"#).unwrap();
/// let analysis = species.generate_and_analyze().unwrap();
/// assert!(analysis.model.leaves.len() == 3 * 6);
/// ```
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Reflect)]
#[serde(default, deny_unknown_fields)]
pub struct SpeciesDesc {
    /// Name, for logs and reports.
    pub name: String,
    /// Seed of the generator: the same description always gives the same tree.
    pub seed: u64,
    /// Branching levels, trunk first. At least one.
    pub levels: Vec<BranchLevel>,
    /// The leaves.
    pub leaves: LeafDesc,
    /// How far the trunk reaches below the ground, in metres.
    pub root_depth: f32,
    /// Bark colour (linear RGB) of lines.
    pub bark_color: LinearRgb,
    /// Leaf colour (linear RGB) of points.
    pub leaf_color: LinearRgb,
}

impl Default for SpeciesDesc {
    fn default() -> Self {
        Self {
            name: String::from("unnamed"),
            seed: 0,
            levels: vec![BranchLevel {
                length: 4.0,
                radius: 0.15,
                ..BranchLevel::default()
            }],
            leaves: LeafDesc::default(),
            root_depth: 0.1,
            bark_color: [0.18, 0.11, 0.06],
            leaf_color: [0.12, 0.32, 0.08],
        }
    }
}

/// Why a species description was refused.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SpeciesError {
    /// The RON text does not parse; the message names line, column and field.
    #[error("{0}")]
    Ron(#[from] ron::error::SpannedError),
    /// A value is out of its range.
    #[error("{0}")]
    Invalid(#[from] crate::ron_file::FieldError),
    /// The generated meshes did not analyse: the generator made something the analysis
    /// refuses (with a validated description this is a bug in the generator).
    #[error("the generated tree does not analyse: {0}")]
    Analysis(#[from] TreeAnalysisError),
}

/// Generated meshes, ready for [`analyze`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GeneratedTree {
    /// Trunk positions.
    pub trunk_positions: Vec<Vec3>,
    /// Trunk normals.
    pub trunk_normals: Vec<Vec3>,
    /// Trunk triangles.
    pub trunk_indices: Vec<u32>,
    /// Leaf positions.
    pub leaf_positions: Vec<Vec3>,
    /// Leaf normals.
    pub leaf_normals: Vec<Vec3>,
    /// Leaf triangles.
    pub leaf_indices: Vec<u32>,
}

impl SpeciesDesc {
    /// The most levels of branching a species may have.
    pub(crate) const MAX_LEVELS: usize = 16;

    /// The largest trunk length, trunk radius, leaf size and spread, and root depth, in
    /// model units.
    pub(crate) const MAX_SIZE: f32 = 10_000.0;

    /// The smallest length, radius (a branch's, of its parent's) and taper, and leaf size.
    pub(crate) const MIN_SIZE: f32 = 1e-3;

    /// The most vertices (estimated from the levels) a species may generate: about ten
    /// times the largest shipped species.
    pub(crate) const MAX_VERTICES: u64 = 600_000;

    /// Parses and validates a species description.
    pub fn from_ron_str(text: &str) -> Result<Self, SpeciesError> {
        let desc: Self = crate::ron_file::ron_options().from_str(text)?;
        desc.validate()?;
        Ok(desc)
    }

    /// Checks every value is in range.
    pub(crate) fn validate(&self) -> Result<(), SpeciesError> {
        if self.levels.is_empty() {
            return Err(invalid("levels".into(), "needs at least the trunk"));
        }
        for (i, l) in self.levels.iter().enumerate() {
            let f = |name: &str| format!("levels[{i}].{name}");
            // Not so small that a branch collapses to a point (its direction is then no
            // number).
            let positive = |x: f32| x.is_finite() && x >= Self::MIN_SIZE;
            if !positive(l.length) {
                return Err(invalid(
                    f("length"),
                    format!("must be a number of at least {}", Self::MIN_SIZE),
                ));
            }
            if !positive(l.radius) || (i > 0 && l.radius >= 1.0) {
                return Err(invalid(
                    f("radius"),
                    format!(
                        "must be at least {} (and below 1 for branches, a fraction of the parent's radius)",
                        Self::MIN_SIZE
                    ),
                ));
            }
            if !(l.taper.is_finite() && l.taper >= Self::MIN_SIZE && l.taper <= 1.0) {
                return Err(invalid(f("taper"), "must be in (0, 1]"));
            }
            if l.segments == 0 || l.segments > 256 {
                return Err(invalid(f("segments"), "must be between 1 and 256"));
            }
            if l.ring_vertices < 3 || l.ring_vertices > 64 {
                return Err(invalid(f("ring_vertices"), "must be between 3 and 64"));
            }
            if l.children > 64 {
                return Err(invalid(f("children"), "must be at most 64"));
            }
            if !(0.0..1.0).contains(&l.children_start) {
                return Err(invalid(f("children_start"), "must be in [0, 1)"));
            }
            for (name, x) in [
                ("angle", l.angle),
                ("angle_jitter", l.angle_jitter),
                ("length_jitter", l.length_jitter),
                ("droop", l.droop),
            ] {
                if !(x.is_finite() && x.abs() <= 3600.0) {
                    return Err(invalid(f(name), "must be a number of degrees within ±3600"));
                }
            }
            // Sizes a tree can have: a trunk of kilometres or branches a thousand times
            // their parent's length overflow the generated positions.
            let (most, unit) = if i == 0 {
                (Self::MAX_SIZE, "units")
            } else {
                (100.0, "times the parent's length")
            };
            if l.length > most {
                return Err(invalid(
                    f("length"),
                    format!("must be at most {most} {unit}"),
                ));
            }
            if i == 0 && l.radius > Self::MAX_SIZE {
                return Err(invalid(
                    f("radius"),
                    format!("must be at most {} units", Self::MAX_SIZE),
                ));
            }
            if !(0.0..1.0).contains(&l.length_jitter) {
                return Err(invalid(f("length_jitter"), "must be in [0, 1)"));
            }
        }
        let leaves = &self.leaves;
        for (name, x) in [
            ("leaves.size", leaves.size),
            ("leaves.spread", leaves.spread),
            ("root_depth", self.root_depth),
        ] {
            if x > Self::MAX_SIZE {
                return Err(invalid(
                    name.into(),
                    format!("must be at most {} units", Self::MAX_SIZE),
                ));
            }
        }
        if !(leaves.size.is_finite() && leaves.size >= Self::MIN_SIZE) {
            return Err(invalid("leaves.size".into(), "must be a positive number"));
        }
        if !(leaves.spread.is_finite() && leaves.spread >= 0.0) {
            return Err(invalid(
                "leaves.spread".into(),
                "must be a non-negative number",
            ));
        }
        if !(leaves.along.is_finite() && leaves.along > 0.0 && leaves.along <= 1.0) {
            return Err(invalid("leaves.along".into(), "must be in (0, 1]"));
        }
        if leaves.per_twig > 10_000 {
            return Err(invalid("leaves.per_twig".into(), "must be at most 10000"));
        }
        // Bounded work: every level multiplies the branches, so a species must stay a size
        // the analysis can take (the largest shipped one has about 60 000 vertices).
        if self.levels.len() > Self::MAX_LEVELS {
            return Err(invalid(
                "levels".into(),
                format!(
                    "at most {} levels of branching, got {}",
                    Self::MAX_LEVELS,
                    self.levels.len()
                ),
            ));
        }
        let vertices = self.estimated_vertices();
        if vertices > Self::MAX_VERTICES {
            return Err(invalid(
                "levels".into(),
                format!(
                    "the branching would make about {vertices} vertices, more than {}: fewer children, segments, ring vertices or leaves per twig",
                    Self::MAX_VERTICES
                ),
            ));
        }
        if !(self.root_depth.is_finite() && self.root_depth > 0.0) {
            return Err(invalid(
                "root_depth".into(),
                "must be positive: the trunk must reach below the ground",
            ));
        }
        for (name, c) in [
            ("bark_color", self.bark_color),
            ("leaf_color", self.leaf_color),
        ] {
            if c.iter().any(|x| !x.is_finite() || *x < 0.0) {
                return Err(invalid(
                    name.into(),
                    "components must be finite and non-negative",
                ));
            }
        }
        Ok(())
    }

    /// An upper estimate of the generated vertices: branches per level times each
    /// branch's rings, and four vertices per leaf on every twig.
    fn estimated_vertices(&self) -> u64 {
        let mut branches: u64 = 1;
        let mut vertices: u64 = 0;
        for (i, l) in self.levels.iter().enumerate() {
            let per_branch = u64::from(l.segments + 1) * u64::from(l.ring_vertices);
            vertices = vertices.saturating_add(branches.saturating_mul(per_branch));
            if i + 1 == self.levels.len() {
                let leaves = u64::from(self.leaves.per_twig) * 4;
                vertices = vertices.saturating_add(branches.saturating_mul(leaves));
            }
            branches = branches.saturating_mul(u64::from(l.children));
        }
        vertices
    }

    /// Generates the trunk and leaves meshes.
    pub fn generate(&self) -> GeneratedTree {
        let mut out = GeneratedTree::default();
        let mut rng = SplitMix64::new(self.seed ^ 0x005E_ED0F_7EE5);
        let trunk = &self.levels[0];
        let base = Vec3::new(0.0, -self.root_depth, 0.0);
        let tilt =
            Quat::from_rotation_z(0.03 * rng.signed()) * Quat::from_rotation_x(0.03 * rng.signed());
        let direction = tilt * Vec3::Y;
        let length = trunk.length * (1.0 + trunk.length_jitter * rng.signed());
        self.grow(
            &mut out,
            &mut rng,
            0,
            base,
            direction,
            length + self.root_depth,
            trunk.radius,
        );
        out
    }

    /// Generates and analyses the species.
    pub fn generate_and_analyze(&self) -> Result<TreeAnalysis, SpeciesError> {
        self.generate_and_analyze_with(&AnalysisOptions::default())
    }

    /// Generates the species and analyses it with `options`.
    pub fn generate_and_analyze_with(
        &self,
        options: &AnalysisOptions,
    ) -> Result<TreeAnalysis, SpeciesError> {
        self.validate()?;
        let tree = self.generate();
        let trunk = MeshData {
            positions: &tree.trunk_positions,
            normals: Some(&tree.trunk_normals),
            indices: &tree.trunk_indices,
            color: Some(self.bark_color),
        };
        let leaves = MeshData {
            positions: &tree.leaf_positions,
            normals: Some(&tree.leaf_normals),
            indices: &tree.leaf_indices,
            color: Some(self.leaf_color),
        };
        Ok(analyze(&trunk, &leaves, options)?)
    }

    #[expect(clippy::too_many_arguments, reason = "recursion state")]
    fn grow(
        &self,
        out: &mut GeneratedTree,
        rng: &mut SplitMix64,
        level: usize,
        start: Vec3,
        direction: Vec3,
        length: f32,
        radius: f32,
    ) {
        let desc = &self.levels[level];
        let n = desc.segments as usize;
        // The branch's axis: straight segments bending towards the ground by `droop`.
        let mut points = Vec::with_capacity(n + 1);
        let mut p = start;
        let mut d = direction.normalize();
        points.push(p);
        let step = length / n as f32;
        for _ in 0..n {
            let side = d.cross(Vec3::Y);
            if side.length_squared() > 1e-6 {
                d = (Quat::from_axis_angle(side.normalize(), -desc.droop.to_radians()) * d)
                    .normalize();
            }
            p += d * step;
            points.push(p);
        }
        let radii: Vec<f32> = (0..=n)
            .map(|i| radius * (1.0 + (desc.taper - 1.0) * i as f32 / n as f32))
            .collect();
        tube(
            out,
            &points,
            &radii,
            desc.ring_vertices as usize,
            rng.unit() * TAU,
        );

        if level + 1 < self.levels.len() {
            let child = &self.levels[level + 1];
            for c in 0..desc.children {
                // Spread children along the branch and around it (golden angle).
                let t = desc.children_start
                    + (1.0 - desc.children_start) * (c as f32 + 0.5 + 0.4 * rng.signed())
                        / desc.children as f32;
                let t = t.clamp(desc.children_start, 0.98);
                let at = t * n as f32;
                let i = (at as usize).min(n - 1);
                let f = at - i as f32;
                let origin = points[i].lerp(points[i + 1], f);
                let axis = (points[i + 1] - points[i]).normalize();
                let parent_radius = radii[i] + (radii[i + 1] - radii[i]) * f;
                let azimuth = c as f32 * 2.399_963 + 0.5 * rng.signed();
                let angle = (child.angle + child.angle_jitter * rng.signed()).to_radians();
                let perpendicular = any_perpendicular(axis);
                let around = Quat::from_axis_angle(axis, azimuth) * perpendicular;
                let dir = (Quat::from_axis_angle(around.cross(axis).normalize(), -angle) * axis)
                    .normalize();
                let child_length =
                    length * child.length * (1.0 + child.length_jitter * rng.signed());
                let child_radius = parent_radius * child.radius;
                self.grow(out, rng, level + 1, origin, dir, child_length, child_radius);
            }
        } else {
            self.leaves_around(out, rng, &points);
        }
    }

    fn leaves_around(&self, out: &mut GeneratedTree, rng: &mut SplitMix64, axis: &[Vec3]) {
        let leaves = &self.leaves;
        let n = axis.len() - 1;
        for _ in 0..leaves.per_twig {
            let t = 1.0 - leaves.along * rng.unit();
            let at = t * n as f32;
            let i = (at as usize).min(n - 1);
            let point = axis[i].lerp(axis[i + 1], at - i as f32);
            let dir = (axis[i + 1] - axis[i]).normalize();
            let out_dir = Quat::from_axis_angle(dir, rng.unit() * TAU) * any_perpendicular(dir);
            let center = point
                + out_dir * leaves.spread * (0.6 + 0.4 * rng.unit())
                + dir * 0.2 * leaves.spread * rng.signed();
            // Leaves face mostly outwards and upwards, with some randomness.
            let normal = (out_dir
                + Vec3::Y * 0.8
                + 0.4 * Vec3::new(rng.signed(), rng.signed(), rng.signed()))
            .try_normalize()
            .unwrap_or(Vec3::Y);
            let u = any_perpendicular(normal);
            let v = normal.cross(u);
            let s = leaves.size * (0.8 + 0.4 * rng.unit());
            let first = out.leaf_positions.len() as u32;
            match leaves.shape {
                LeafShape::Triangle => {
                    for corner in [u, -0.5 * u + 0.866 * v, -0.5 * u - 0.866 * v] {
                        out.leaf_positions.push(center + corner * s * 0.577);
                        out.leaf_normals.push(normal);
                    }
                    out.leaf_indices.extend([first, first + 1, first + 2]);
                }
                LeafShape::Quad => {
                    for corner in [-u - v, u - v, u + v, -u + v] {
                        out.leaf_positions.push(center + corner * s * 0.5);
                        out.leaf_normals.push(normal);
                    }
                    out.leaf_indices.extend([
                        first,
                        first + 1,
                        first + 2,
                        first,
                        first + 2,
                        first + 3,
                    ]);
                }
            }
        }
    }
}

/// A unit vector perpendicular to `v` (stable: avoids the axis `v` is closest to).
fn any_perpendicular(v: Vec3) -> Vec3 {
    let other = if v.x.abs() < 0.9 { Vec3::X } else { Vec3::Z };
    v.cross(other).normalize()
}

/// Appends a tapered tube along `points` with `radii`, `k` vertices per ring, closed by a
/// pointed tip one ring-spacing beyond the last ring, open at its start.
pub(crate) fn tube(out: &mut GeneratedTree, points: &[Vec3], radii: &[f32], k: usize, twist: f32) {
    let first = out.trunk_positions.len() as u32;
    let mut frame_u = any_perpendicular((points[1] - points[0]).normalize());
    for (i, (&p, &r)) in points.iter().zip(radii).enumerate() {
        let dir = if i + 1 < points.len() {
            points[i + 1] - points[i]
        } else {
            points[i] - points[i - 1]
        }
        .normalize();
        // Parallel transport keeps rings from twisting between segments.
        frame_u = (frame_u - dir * frame_u.dot(dir)).normalize();
        let frame_v = dir.cross(frame_u);
        for j in 0..k {
            let a = twist + TAU * j as f32 / k as f32;
            let offset = frame_u * a.cos() + frame_v * a.sin();
            out.trunk_positions.push(p + offset * r);
            out.trunk_normals.push(offset);
        }
    }
    let k32 = k as u32;
    for i in 0..points.len() as u32 - 1 {
        for j in 0..k32 {
            let a = first + i * k32 + j;
            let b = first + i * k32 + (j + 1) % k32;
            let c = a + k32;
            let d = b + k32;
            out.trunk_indices.extend([a, b, d, a, d, c]);
        }
    }
    let last = points.len() - 1;
    let tip_dir = (points[last] - points[last - 1]).normalize();
    let tip = points[last] + tip_dir * radii[last].max(1e-4) * 2.0;
    let apex = out.trunk_positions.len() as u32;
    out.trunk_positions.push(tip);
    out.trunk_normals.push(tip_dir);
    let ring = first + last as u32 * k32;
    for j in 0..k32 {
        out.trunk_indices
            .extend([ring + j, ring + (j + 1) % k32, apex]);
    }
}
