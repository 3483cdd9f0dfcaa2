//! The ecosystem file (`*.ecosystem.ron`, thesis chapter 3): materials, species with
//! their global placement rules and hand-placed overrides, the terrain, and a seed.

use crate::ron_file::invalid;
use std::collections::BTreeMap;

use bevy::math::{Affine3A, Vec3};
use serde::{Deserialize, Serialize};

use super::placement::{Angles, Tilt, place, tilt_from_normal};
use super::terrain::{Terrain, TerrainDesc, TerrainError};
use crate::rng::SplitMix64;

/// The largest instance scale an ecosystem may ask for: a tree a thousand times its
/// model's size.
pub(crate) const MAX_SCALE: f32 = 1000.0;

/// How close two hand-placed instances may stand, metres: closer, an ecosystem is
/// refused as one position typed twice.
pub(crate) const MIN_HAND_PLACED_SPACING: f32 = 0.01;

/// A Blinn-Phong material (thesis §3.1); colours are linear RGB.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MaterialDesc {
    /// Ambient colour.
    pub ambient: [f32; 3],
    /// Diffuse colour.
    pub diffuse: [f32; 3],
    /// Specular colour.
    pub specular: [f32; 3],
    /// Emitted colour.
    pub emission: [f32; 3],
    /// Specular exponent.
    pub shininess: f32,
    /// Opacity, 0–1.
    pub alpha: f32,
    /// Texture path, relative to the assets folder.
    pub texture: Option<String>,
}

impl Default for MaterialDesc {
    fn default() -> Self {
        Self {
            ambient: [0.2; 3],
            diffuse: [0.8; 3],
            specular: [0.0; 3],
            emission: [0.0; 3],
            shininess: 8.0,
            alpha: 1.0,
            texture: None,
        }
    }
}

/// One hand-placed instance; anything left out follows the species' global rules.
#[derive(Clone, Debug, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct InstanceDesc {
    /// Position on the terrain, `(x, z)`; the height comes from the terrain.
    pub position: Option<(f32, f32)>,
    /// Rotation about Y, degrees.
    pub head: Option<f32>,
    /// Rotation about X, degrees.
    pub pitch: Option<f32>,
    /// Rotation about Z, degrees.
    pub roll: Option<f32>,
    /// Uniform scale.
    pub scale: Option<f32>,
}

/// A species in the ecosystem and the rules its instances follow.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SpeciesEntry {
    /// The tree asset: a `*.species.ron`, `*.tree.ron`/`.bin` or `*.tree.glb` path.
    pub tree: String,
    /// Instances placed by the global rules (hand-placed ones come on top).
    pub count: u32,
    /// Random head (rotation about Y) up to this many degrees.
    pub max_head: f32,
    /// How instances lean.
    pub tilt: Tilt,
    /// Random uniform scale within this range.
    pub scale: (f32, f32),
    /// Trunk material (a key of `materials`).
    pub trunk_material: String,
    /// Leaf material (a key of `materials`).
    pub leaf_material: String,
    /// Which wind setup moves these trees.
    pub motion: u32,
    /// Hand-placed instances.
    pub instances: Vec<InstanceDesc>,
}

impl Default for SpeciesEntry {
    fn default() -> Self {
        Self {
            tree: String::new(),
            count: 0,
            max_head: 360.0,
            tilt: Tilt::Random(3.0),
            scale: (0.8, 1.2),
            trunk_material: "bark".into(),
            leaf_material: "leaf".into(),
            motion: 0,
            instances: Vec::new(),
        }
    }
}

/// A whole ecosystem, as stored in `*.ecosystem.ron`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct EcosystemDesc {
    /// Seed of every random choice: the same file always gives the same forest.
    pub seed: u64,
    /// Materials by name, shared by the terrain, trunks and leaves.
    pub materials: BTreeMap<String, MaterialDesc>,
    /// The species and their instances.
    pub species: Vec<SpeciesEntry>,
    /// The terrain.
    pub terrain: TerrainDesc,
    /// The terrain's material (a key of `materials`).
    pub terrain_material: String,
    /// Margin kept between an instance and its cell's edges, as a fraction of the cell.
    pub cell_margin: f32,
    /// Levels of the culling box hierarchy below the root: spawning the forest sets
    /// [`CullingSettings::depth`](crate::culling::CullingSettings::depth) to it (the last
    /// ecosystem spawned decides for all trees).
    pub culling_depth: u32,
}

impl Default for EcosystemDesc {
    fn default() -> Self {
        Self {
            seed: 0,
            materials: BTreeMap::new(),
            species: Vec::new(),
            terrain: TerrainDesc::default(),
            terrain_material: "ground".into(),
            cell_margin: 0.15,
            culling_depth: 4,
        }
    }
}

/// Why an ecosystem file was refused.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum EcosystemError {
    /// The RON does not parse (the message names line, column and field).
    #[error("{0}")]
    Ron(#[from] ron::error::SpannedError),
    /// A value is out of range or refers to nothing.
    #[error("{0}")]
    Invalid(#[from] crate::ron_file::FieldError),
    /// The terrain is malformed.
    #[error("{0}")]
    Terrain(#[from] TerrainError),
}

/// One instance ready to spawn.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct InstanceLayout {
    /// Index into [`EcosystemDesc::species`].
    pub species: usize,
    /// Local → world.
    pub transform: Affine3A,
    /// Uniform scale (also inside `transform`).
    pub scale: f32,
    /// Index into the materials, in name order.
    pub trunk_material: usize,
    /// Index into the materials, in name order.
    pub leaf_material: usize,
    /// Wind setup.
    pub motion: u32,
}

/// An ecosystem laid out: its terrain and every instance.
#[derive(Clone, Debug)]
pub(crate) struct EcosystemLayout {
    /// The sampled terrain.
    pub terrain: Terrain,
    /// Every instance: rule-placed ones first, species by species, then hand-placed ones.
    pub instances: Vec<InstanceLayout>,
}

impl EcosystemDesc {
    /// Sets the total number of trees to `total`, split across the species in the file's
    /// proportions (the last species takes the rounding), and grows or shrinks the terrain
    /// so the forest keeps its density (a total of 0 leaves the terrain as it is).
    ///
    /// # Errors
    /// A file whose rule-placed counts are all 0 has no proportions to split by nor a
    /// density to keep: it is refused (naming `species[..].count`) rather than given to
    /// one species on a terrain grown without bound.
    pub fn set_total_trees(&mut self, total: u32) -> Result<(), EcosystemError> {
        let sum: u32 = self.species.iter().map(|s| s.count).sum();
        if sum == 0 {
            return Err(invalid(
                "species[..].count".into(),
                format!(
                    "every species places 0 trees: cannot be scaled to {total} trees \
                     (give the species counts in the proportions wanted)"
                ),
            ));
        }
        let n = self.species.len();
        let mut given = 0;
        for (i, s) in self.species.iter_mut().enumerate() {
            s.count = if i + 1 == n {
                total - given
            } else {
                (u64::from(s.count) * u64::from(total) / u64::from(sum)) as u32
            };
            given += s.count;
        }
        // No trees have no density to keep: the terrain stays as it was.
        if total > 0 {
            self.terrain.size *= (total as f32 / sum as f32).sqrt();
        }
        Ok(())
    }

    /// Parses and validates an ecosystem description.
    ///
    /// Optional fields may be written bare (`knots_x: [...]`) or as `Some(...)`: RON's
    /// `implicit_some` extension is on.
    pub fn from_ron_str(text: &str) -> Result<Self, EcosystemError> {
        let desc: Self = crate::ron_file::ron_options().from_str(text)?;
        desc.validate()?;
        Ok(desc)
    }

    /// Total instances: rule-placed plus hand-placed.
    pub fn instance_count(&self) -> usize {
        self.species
            .iter()
            .map(|s| s.count as usize + s.instances.len())
            .sum()
    }

    /// Checks ranges and references.
    pub fn validate(&self) -> Result<(), EcosystemError> {
        self.terrain.validate()?;
        if self.species.is_empty() {
            return Err(invalid("species".into(), "needs at least one species"));
        }
        let material = |field: String, name: &str| -> Result<(), EcosystemError> {
            if self.materials.contains_key(name) {
                Ok(())
            } else {
                let known: Vec<&String> = self.materials.keys().collect();
                Err(invalid(
                    field,
                    format!("no material named {name:?} (known: {known:?})"),
                ))
            }
        };
        material("terrain_material".into(), &self.terrain_material)?;
        for (i, s) in self.species.iter().enumerate() {
            let f = |name: &str| format!("species[{i}].{name}");
            if s.tree.is_empty() {
                return Err(invalid(f("tree"), "names no tree asset"));
            }
            let (lo, hi) = s.scale;
            if !(lo.is_finite() && hi.is_finite() && lo > 0.0 && lo <= hi && hi <= MAX_SCALE) {
                return Err(invalid(
                    f("scale"),
                    format!("must be (min, max) with 0 < min ≤ max ≤ {MAX_SCALE}"),
                ));
            }
            if !s.max_head.is_finite() || s.max_head < 0.0 || s.max_head > 3600.0 {
                return Err(invalid(
                    f("max_head"),
                    "must be a non-negative number of degrees",
                ));
            }
            if let Tilt::Random(max) = s.tilt
                && !(max.is_finite() && (0.0..=90.0).contains(&max))
            {
                return Err(invalid(
                    f("tilt"),
                    "a random tilt must be between 0 and 90 degrees",
                ));
            }
            material(f("trunk_material"), &s.trunk_material)?;
            material(f("leaf_material"), &s.leaf_material)?;
            for (k, inst) in s.instances.iter().enumerate() {
                let g = |name: &str| format!("species[{i}].instances[{k}].{name}");
                let extent = TerrainDesc::MAX_EXTENT;
                if let Some((x, z)) = inst.position
                    && !(x.is_finite() && z.is_finite() && x.abs() <= extent && z.abs() <= extent)
                {
                    return Err(invalid(
                        g("position"),
                        format!("must be finite and within ±{extent}"),
                    ));
                }
                if inst
                    .scale
                    .is_some_and(|s| !(s.is_finite() && s > 0.0 && s <= MAX_SCALE))
                {
                    return Err(invalid(
                        g("scale"),
                        format!("must be positive, at most {MAX_SCALE}"),
                    ));
                }
                for (name, angle) in [
                    ("head", inst.head),
                    ("pitch", inst.pitch),
                    ("roll", inst.roll),
                ] {
                    if angle.is_some_and(|a| !a.is_finite()) {
                        return Err(invalid(g(name), "must be finite"));
                    }
                }
            }
        }
        for (name, m) in &self.materials {
            let colours = [m.ambient, m.diffuse, m.specular, m.emission];
            if colours
                .iter()
                .flatten()
                .any(|c| !(c.is_finite() && *c >= 0.0))
                || !(m.shininess.is_finite() && m.shininess >= 0.0)
                || !(0.0..=1.0).contains(&m.alpha)
            {
                return Err(invalid(
                    format!("materials[{name:?}]"),
                    "colours must be non-negative, shininess non-negative, alpha within 0–1",
                ));
            }
        }
        if !(0.0..0.5).contains(&self.cell_margin) {
            return Err(invalid("cell_margin".into(), "must be within [0, 0.5)"));
        }
        if self.culling_depth > 10 {
            return Err(invalid("culling_depth".into(), "must be at most 10"));
        }
        if self.instance_count() > 10_000_000 {
            return Err(invalid("species".into(), "more than 10 million instances"));
        }
        self.validate_hand_placed_spacing()
    }

    /// Two hand-placed trees closer than [`MIN_HAND_PLACED_SPACING`] are one position
    /// typed twice (a copied line): drawn, they would stand inside each other.
    fn validate_hand_placed_spacing(&self) -> Result<(), EcosystemError> {
        let mut placed: Vec<(f32, f32, usize, usize)> = Vec::new();
        for (i, s) in self.species.iter().enumerate() {
            for (k, inst) in s.instances.iter().enumerate() {
                if let Some((x, z)) = inst.position {
                    placed.push((x, z, i, k));
                }
            }
        }
        placed.sort_by(|a, b| a.0.total_cmp(&b.0));
        for (n, &(x, z, i, k)) in placed.iter().enumerate() {
            let near = placed[n + 1..]
                .iter()
                .take_while(|p| p.0 - x < MIN_HAND_PLACED_SPACING)
                .find(|p| (p.0 - x).hypot(p.1 - z) < MIN_HAND_PLACED_SPACING);
            if let Some(&other) = near {
                // The later of the two in the file is named, with its own position.
                let (first, second) = if (i, k) < (other.2, other.3) {
                    ((x, z, i, k), other)
                } else {
                    (other, (x, z, i, k))
                };
                return Err(invalid(
                    format!("species[{}].instances[{}].position", second.2, second.3),
                    format!(
                        "({}, {}) is within {MIN_HAND_PLACED_SPACING} m of \
                         species[{}].instances[{}] at ({}, {}): two trees in one place",
                        second.0, second.1, first.2, first.3, first.0, first.1
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Builds the terrain and places every instance. Deterministic for a given seed.
    pub(crate) fn layout(&self) -> Result<EcosystemLayout, EcosystemError> {
        self.validate()?;
        let terrain = self.terrain.build()?;
        let mut rng = SplitMix64::new(self.seed ^ 0x00D1_CE5E_ED00);
        let counts: Vec<usize> = self.species.iter().map(|s| s.count as usize).collect();
        let placed = place(&counts, &terrain, self.cell_margin, &mut rng);
        let material_index =
            |name: &str| self.materials.keys().position(|k| k == name).unwrap_or(0);
        let mut instances = Vec::with_capacity(self.instance_count());
        let mut build =
            |species: usize, position: Vec3, manual: &InstanceDesc, rng: &mut SplitMix64| {
                let s = &self.species[species];
                let scale = manual
                    .scale
                    .unwrap_or_else(|| s.scale.0 + rng.unit() * (s.scale.1 - s.scale.0));
                let head = manual.head.unwrap_or_else(|| rng.unit() * s.max_head);
                let (pitch, roll) = match s.tilt {
                    Tilt::Terrain => tilt_from_normal(terrain.normal_at(position.x, position.z)),
                    Tilt::Random(max) => (
                        (2.0 * rng.unit() - 1.0) * max,
                        (2.0 * rng.unit() - 1.0) * max,
                    ),
                };
                let angles = Angles {
                    head,
                    pitch: manual.pitch.unwrap_or(pitch),
                    roll: manual.roll.unwrap_or(roll),
                };
                instances.push(InstanceLayout {
                    species,
                    transform: Affine3A::from_scale_rotation_translation(
                        Vec3::splat(scale),
                        angles.rotation(),
                        position,
                    ),
                    scale,
                    trunk_material: material_index(&s.trunk_material),
                    leaf_material: material_index(&s.leaf_material),
                    motion: s.motion,
                });
            };
        for p in &placed {
            build(p.species, p.position, &InstanceDesc::default(), &mut rng);
        }
        for (species, s) in self.species.iter().enumerate() {
            for manual in &s.instances {
                let (x, z) = manual
                    .position
                    .unwrap_or_else(|| (rng.unit() * terrain.size(), rng.unit() * terrain.size()));
                let position = Vec3::new(x, terrain.height_at(x, z), z);
                build(species, position, manual, &mut rng);
            }
        }
        Ok(EcosystemLayout { terrain, instances })
    }
}
