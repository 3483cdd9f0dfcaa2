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
    pub(crate) fn rotation(&self) -> Quat {
        Quat::from_rotation_x(self.pitch.to_radians())
            * Quat::from_rotation_z(self.roll.to_radians())
            * Quat::from_rotation_y(self.head.to_radians())
    }
}

/// Pitch and roll (degrees) that stand a tree perpendicular to a terrain with `normal`
/// (thesis §3.2.1). The thesis' pseudo-code gives pitch a negative sign in both branches;
/// here it follows the sign of the normal's z, as roll follows (the opposite of) its x.
pub(crate) fn tilt_from_normal(normal: Vec3) -> (f32, f32) {
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
pub(crate) struct Placement {
    /// Index of the species.
    pub species: usize,
    /// Position on the terrain (height from the terrain).
    pub position: Vec3,
    /// Cell index in the grid (row-major).
    pub cell: usize,
}

/// Places `counts[s]` instances of each species `s` on `terrain`, keeping each one
/// `cell_margin` (a fraction of the cell, 0–0.49) away from its cell's edges.
pub(crate) fn place(
    counts: &[usize],
    terrain: &Terrain,
    cell_margin: f32,
    rng: &mut SplitMix64,
) -> Vec<Placement> {
    let total: usize = counts.iter().sum();
    let g = (total as f64).sqrt().ceil() as usize;
    let g = if g * g < total { g + 1 } else { g };
    let cells = g * g;
    let mut free = FreeCells::new(cells);
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
            if cell < cells && !free.is_free(cell) {
                cell = free.first_free_from(cell).unwrap_or(cells);
            }
            if cell >= cells {
                // Past the last cell: a random free one (there is one: cells ≥ instances).
                let remaining = free.remaining();
                let pick = (rng.unit() * remaining as f32) as usize;
                cell = free.nth(pick.min(remaining.saturating_sub(1))).unwrap_or(0);
            }
            free.take(cell);
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

/// The grid's free cells, with "the first free cell from `c`" and "the `k`-th free cell"
/// in O(log cells) (a Fenwick tree of free counts), so that placing n instances costs
/// O(n log n) rather than a scan of the grid per instance: a million trees place in well
/// under a second.
struct FreeCells {
    free: Vec<bool>,
    /// Fenwick tree (1-based) of free counts.
    tree: Vec<u32>,
    remaining: usize,
}

impl FreeCells {
    fn new(cells: usize) -> Self {
        // Every cell free: each node counts the cells it covers, its lowest set bit.
        let tree = (0..=cells).map(|i| (i & i.wrapping_neg()) as u32).collect();
        Self {
            free: vec![true; cells],
            tree,
            remaining: cells,
        }
    }

    fn is_free(&self, cell: usize) -> bool {
        self.free.get(cell).copied().unwrap_or(false)
    }

    fn remaining(&self) -> usize {
        self.remaining
    }

    fn take(&mut self, cell: usize) {
        if !self.is_free(cell) {
            return;
        }
        self.free[cell] = false;
        self.remaining -= 1;
        let mut i = cell + 1;
        while i < self.tree.len() {
            self.tree[i] -= 1;
            i += i & i.wrapping_neg();
        }
    }

    /// Free cells before `cell`.
    fn free_before(&self, cell: usize) -> usize {
        let mut i = cell.min(self.free.len());
        let mut count = 0;
        while i > 0 {
            count += self.tree[i] as usize;
            i &= i - 1;
        }
        count
    }

    /// The `k`-th free cell (from 0) in cell order.
    fn nth(&self, k: usize) -> Option<usize> {
        if k >= self.remaining {
            return None;
        }
        // Descend the tree: the largest prefix holding at most k free cells.
        let (mut position, mut left) = (0, k);
        let mut step = (self.tree.len()).next_power_of_two();
        while step > 0 {
            let next = position + step;
            if next < self.tree.len() && (self.tree[next] as usize) <= left {
                position = next;
                left -= self.tree[next] as usize;
            }
            step /= 2;
        }
        Some(position)
    }

    /// The first free cell at or after `cell`.
    fn first_free_from(&self, cell: usize) -> Option<usize> {
        self.nth(self.free_before(cell))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn free_cells_answer_as_a_scan_would() {
        let mut cells = FreeCells::new(37);
        let mut plain = [true; 37];
        let mut state = 7_u64;
        for _ in 0..30 {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1);
            let c = (state >> 33) as usize % 37;
            cells.take(c);
            plain[c] = false;
            for from in 0..37 {
                let scan = (from..37).find(|&f| plain[f]);
                assert_eq!(cells.first_free_from(from), scan, "from {from}");
            }
            let free: Vec<usize> = (0..37).filter(|&f| plain[f]).collect();
            assert_eq!(cells.remaining(), free.len());
            for (k, &f) in free.iter().enumerate() {
                assert_eq!(cells.nth(k), Some(f));
            }
            assert_eq!(cells.nth(free.len()), None);
        }
    }
}
