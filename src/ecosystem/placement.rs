//! The thesis' jittered-grid placement (§3.2.2) and instance orientation (§3.2.1).
//!
//! The smallest `g` with `g² ≥` instances gives a `g × g` grid of cells. A current cell
//! starts at the first cell; for each species in turn, each instance moves it on by
//! `cells / instances of this species`, plus or minus a random margin, takes the first
//! free cell from there, and — once the current cell runs past the last — goes to a
//! random free cell. Each instance sits at a random point of its cell, kept a margin away
//! from the cell's edges so neighbours do not collide.

use bevy::math::{Quat, Vec2, Vec3};
use serde::{Deserialize, Serialize};

use super::terrain::Terrain;
use crate::rng::SplitMix64;

/// How instances of a species lean.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum Tilt {
    /// Perpendicular to the terrain under the instance.
    Terrain,
    /// Random pitch and roll, each up to this many degrees either way.
    Random(f32),
}

/// Per-instance orientation angles, in degrees (the thesis' head, pitch and roll).
#[derive(Clone, Copy, Debug, PartialEq, Default, Serialize, Deserialize)]
pub struct Angles {
    /// About Y.
    pub head: f32,
    /// About X.
    pub pitch: f32,
    /// About Z.
    pub roll: f32,
}

impl Angles {
    /// The rotation: head about the tree's own axis, then the tilt.
    pub fn rotation(&self) -> Quat {
        Quat::from_rotation_x(self.pitch.to_radians())
            * Quat::from_rotation_z(self.roll.to_radians())
            * Quat::from_rotation_y(self.head.to_radians())
    }
}

/// Pitch and roll (degrees) that stand a tree perpendicular to a terrain with `normal`
/// (thesis §3.2.1). The thesis' pseudo-code gives pitch a negative sign in both branches;
/// here it follows the sign of the normal's z, as roll follows (the opposite of) its x.
pub fn tilt_from_normal(normal: Vec3) -> (f32, f32) {
    let roll_axis = Vec2::new(normal.x, normal.y).normalize_or(Vec2::Y);
    let roll = roll_axis.y.clamp(-1.0, 1.0).acos().to_degrees();
    let roll = if roll_axis.x > 0.0 { -roll } else { roll };
    let pitch_axis = Vec2::new(normal.z, normal.y).normalize_or(Vec2::Y);
    let pitch = pitch_axis.y.clamp(-1.0, 1.0).acos().to_degrees();
    let pitch = if pitch_axis.x < 0.0 { -pitch } else { pitch };
    (pitch, roll)
}

/// One placed instance: which species, where, and its grid cell.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placement {
    /// Index of the species.
    pub species: usize,
    /// Position on the terrain (height from the terrain).
    pub position: Vec3,
    /// Cell index in the grid (row-major).
    pub cell: usize,
}

/// Places `counts[s]` instances of each species `s` on `terrain`, keeping each one
/// `cell_margin` (a fraction of the cell, 0–0.49) away from its cell's edges.
pub fn place(
    counts: &[usize],
    terrain: &Terrain,
    cell_margin: f32,
    rng: &mut SplitMix64,
) -> Vec<Placement> {
    let total: usize = counts.iter().sum();
    let g = (total as f64).sqrt().ceil() as usize;
    let g = if g * g < total { g + 1 } else { g };
    let cells = g * g;
    let mut free = vec![true; cells];
    let mut placements = Vec::with_capacity(total);
    let margin = cell_margin.clamp(0.0, 0.49);
    let cell_size = terrain.size() / g.max(1) as f32;
    let mut current = 0.0_f64;
    for (species, &count) in counts.iter().enumerate() {
        if count == 0 {
            continue;
        }
        let ideal = cells as f64 / count as f64;
        for _ in 0..count {
            current += ideal + (f64::from(rng.unit()) - 0.5) * ideal;
            let mut cell = current as usize;
            if cell < cells && !free[cell] {
                cell = (cell..cells).find(|&c| free[c]).unwrap_or(cells);
            }
            if cell >= cells {
                // Past the last cell: a random free one.
                let remaining = free.iter().filter(|&&f| f).count();
                let pick = (rng.unit() * remaining as f32) as usize;
                cell = free
                    .iter()
                    .enumerate()
                    .filter(|(_, f)| **f)
                    .nth(pick.min(remaining - 1))
                    .map(|(c, _)| c)
                    .unwrap_or(0);
            }
            free[cell] = false;
            let (cx, cz) = ((cell % g) as f32, (cell / g) as f32);
            let x = (cx + margin + rng.unit() * (1.0 - 2.0 * margin)) * cell_size;
            let z = (cz + margin + rng.unit() * (1.0 - 2.0 * margin)) * cell_size;
            placements.push(Placement {
                species,
                position: Vec3::new(x, terrain.height_at(x, z), z),
                cell,
            });
        }
    }
    placements
}
