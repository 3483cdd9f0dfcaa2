//! Terrain (thesis §3.3): the graph of a NURBS height function over a square, sampled
//! to a grid, then roughened by "random faults"; heights and normals are queryable under
//! any (x, z) from the grid's triangles.

use bevy::math::{Vec2, Vec3, Vec3Swizzles};
use serde::{Deserialize, Serialize};

use crate::rng::SplitMix64;

/// A terrain description, as stored in an ecosystem file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TerrainDesc {
    /// Side of the square, in metres; the terrain spans x, z ∈ [0, size].
    pub size: f32,
    /// Samples per side of the grid (≥ 2).
    pub resolution: u32,
    /// Degree of the surface in both directions (≥ 1).
    pub degree: u32,
    /// Control heights, row by row (rows along z, columns along x); at least
    /// `degree + 1` in each direction.
    pub control_heights: Vec<Vec<f32>>,
    /// Weights of the control points (same shape), all 1 when absent.
    pub weights: Option<Vec<Vec<f32>>>,
    /// Knot vector along x (columns); open uniform when absent.
    pub knots_x: Option<Vec<f32>>,
    /// Knot vector along z (rows); open uniform when absent.
    pub knots_z: Option<Vec<f32>>,
    /// Random faults applied after sampling.
    pub faults: FaultsDesc,
}

/// "Random faults": repeatedly raise the terrain on one side of a random line and lower
/// it on the other, with a displacement shrinking linearly over the iterations.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FaultsDesc {
    /// Number of faults (0 for none).
    pub iterations: u32,
    /// Displacement of the first fault, in metres.
    pub amplitude: f32,
    /// Seed of the fault lines.
    pub seed: u64,
}

impl Default for FaultsDesc {
    fn default() -> Self {
        Self {
            iterations: 0,
            amplitude: 1.0,
            seed: 0,
        }
    }
}

impl Default for TerrainDesc {
    fn default() -> Self {
        Self {
            size: 100.0,
            resolution: 65,
            degree: 2,
            control_heights: vec![vec![0.0; 3]; 3],
            weights: None,
            knots_x: None,
            knots_z: None,
            faults: FaultsDesc::default(),
        }
    }
}

/// Why a terrain description was refused.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("terrain.{field}: {message}")]
pub struct TerrainError {
    /// The field at fault.
    pub field: &'static str,
    /// What is wrong.
    pub message: String,
}

fn err(field: &'static str, message: impl Into<String>) -> TerrainError {
    TerrainError {
        field,
        message: message.into(),
    }
}

/// A sampled terrain: a square grid of heights with per-vertex normals.
#[derive(Clone, Debug, PartialEq)]
pub struct Terrain {
    size: f32,
    resolution: usize,
    heights: Vec<f32>,
}

/// Open uniform knots for `count` control points of degree `p`.
fn open_uniform(count: usize, p: usize) -> Vec<f32> {
    let interior = count - p - 1;
    (0..count + p + 1)
        .map(|i| {
            if i <= p {
                0.0
            } else if i >= count {
                1.0
            } else {
                (i - p) as f32 / (interior + 1) as f32
            }
        })
        .collect()
}

/// The `p + 1` non-zero B-spline basis values at `t` and the index of the first
/// (Cox–de Boor, as in The NURBS Book, A2.2).
fn basis(knots: &[f32], p: usize, count: usize, t: f32) -> (usize, Vec<f32>) {
    let t = t.clamp(knots[p], knots[count]);
    let mut span = p;
    while span < count - 1 && t >= knots[span + 1] {
        span += 1;
    }
    let mut n = vec![0.0; p + 1];
    let mut left = vec![0.0; p + 1];
    let mut right = vec![0.0; p + 1];
    n[0] = 1.0;
    for j in 1..=p {
        left[j] = t - knots[span + 1 - j];
        right[j] = knots[span + j] - t;
        let mut saved = 0.0;
        for r in 0..j {
            let denominator = right[r + 1] + left[j - r];
            let temp = if denominator == 0.0 {
                0.0
            } else {
                n[r] / denominator
            };
            n[r] = saved + right[r + 1] * temp;
            saved = left[j - r] * temp;
        }
        n[j] = saved;
    }
    (span - p, n)
}

impl TerrainDesc {
    /// The most sample updates the faults may take (resolution² × iterations): seconds of
    /// work, not hours.
    pub(crate) const MAX_FAULT_WORK: u64 = 400_000_000;

    /// The largest side, control height and fault amplitude, in world units: beyond a
    /// million units single-precision positions lose the precision trees need, and far
    /// beyond they overflow.
    pub(crate) const MAX_EXTENT: f32 = 1_000_000.0;

    /// Checks shapes and ranges.
    pub(crate) fn validate(&self) -> Result<(), TerrainError> {
        if !(self.size.is_finite() && self.size > 0.0 && self.size <= Self::MAX_EXTENT) {
            return Err(err(
                "size",
                format!("must be a positive number up to {}", Self::MAX_EXTENT),
            ));
        }
        if !(2..=4097).contains(&self.resolution) {
            return Err(err("resolution", "must be between 2 and 4097"));
        }
        let p = self.degree as usize;
        if p == 0 || p > 7 {
            return Err(err("degree", "must be between 1 and 7"));
        }
        let rows = self.control_heights.len();
        let columns = self.control_heights.first().map_or(0, Vec::len);
        if rows <= p || columns <= p {
            return Err(err(
                "control_heights",
                format!(
                    "needs at least degree + 1 = {} rows and columns, has {rows} × {columns}",
                    p + 1
                ),
            ));
        }
        if let Some(row) = self.control_heights.iter().position(|r| r.len() != columns) {
            return Err(err(
                "control_heights",
                format!("row {row} has a different length"),
            ));
        }
        if self
            .control_heights
            .iter()
            .flatten()
            .any(|h| !(h.is_finite() && h.abs() <= Self::MAX_EXTENT))
        {
            return Err(err(
                "control_heights",
                format!("must be numbers within ±{}", Self::MAX_EXTENT),
            ));
        }
        if let Some(w) = &self.weights
            && (w.len() != rows
                || w.iter().any(|r| r.len() != columns)
                || w.iter().flatten().any(|x| !(x.is_finite() && *x > 0.0)))
        {
            return Err(err("weights", "must match control_heights and be positive"));
        }
        for (field, knots, count) in [
            ("knots_x", &self.knots_x, columns),
            ("knots_z", &self.knots_z, rows),
        ] {
            if let Some(k) = knots {
                if k.len() != count + p + 1 {
                    return Err(err(
                        field,
                        format!("needs {} knots, has {}", count + p + 1, k.len()),
                    ));
                }
                if k.iter().any(|x| !x.is_finite()) || k.windows(2).any(|w| w[0] > w[1]) {
                    return Err(err(field, "must be finite and non-decreasing"));
                }
                if k[p] >= k[count] {
                    return Err(err(field, "the knot span is empty"));
                }
            }
        }
        if !(self.faults.amplitude.is_finite()
            && (0.0..=Self::MAX_EXTENT).contains(&self.faults.amplitude))
        {
            return Err(err(
                "faults.amplitude",
                format!("must be a non-negative number up to {}", Self::MAX_EXTENT),
            ));
        }
        if self.faults.iterations > 100_000 {
            return Err(err("faults.iterations", "must be at most 100000"));
        }
        // Every fault moves every sample: bounded work, whatever the two limits allow.
        let work = u64::from(self.resolution).pow(2) * u64::from(self.faults.iterations);
        if work > Self::MAX_FAULT_WORK {
            return Err(err(
                "faults.iterations",
                format!(
                    "{} faults over a {}² grid are {work} sample updates, more than {}: fewer faults or a lower resolution",
                    self.faults.iterations,
                    self.resolution,
                    Self::MAX_FAULT_WORK
                ),
            ));
        }
        Ok(())
    }

    /// The height of the NURBS surface (before faults) at parameters `(u, v)` ∈ [0, 1]².
    pub(crate) fn surface_height(&self, u: f32, v: f32) -> f32 {
        let p = self.degree as usize;
        let rows = self.control_heights.len();
        let columns = self.control_heights[0].len();
        let kx = self
            .knots_x
            .clone()
            .unwrap_or_else(|| open_uniform(columns, p));
        let kz = self
            .knots_z
            .clone()
            .unwrap_or_else(|| open_uniform(rows, p));
        let map = |k: &[f32], count: usize, t: f32| k[p] + t * (k[count] - k[p]);
        let (i0, nx) = basis(&kx, p, columns, map(&kx, columns, u));
        let (j0, nz) = basis(&kz, p, rows, map(&kz, rows, v));
        let (mut numerator, mut denominator) = (0.0, 0.0);
        for (b, wz) in nz.iter().enumerate() {
            for (a, wx) in nx.iter().enumerate() {
                let (row, column) = (j0 + b, i0 + a);
                let weight = self.weights.as_ref().map_or(1.0, |w| w[row][column]);
                let f = wx * wz * weight;
                numerator += f * self.control_heights[row][column];
                denominator += f;
            }
        }
        if denominator > 0.0 {
            numerator / denominator
        } else {
            0.0
        }
    }

    /// Samples the surface and applies the faults.
    pub(crate) fn build(&self) -> Result<Terrain, TerrainError> {
        self.validate()?;
        let n = self.resolution as usize;
        let mut heights = Vec::with_capacity(n * n);
        for j in 0..n {
            for i in 0..n {
                let (u, v) = (i as f32 / (n - 1) as f32, j as f32 / (n - 1) as f32);
                heights.push(self.surface_height(u, v));
            }
        }
        if heights.iter().any(|h| !h.is_finite()) {
            return Err(err(
                "weights",
                "the control heights and weights overflow together: a height is not finite",
            ));
        }
        let mut rng = SplitMix64::new(self.faults.seed ^ 0x00FA_0175);
        let iterations = self.faults.iterations;
        for k in 0..iterations {
            let displacement = self.faults.amplitude * (1.0 - k as f32 / iterations as f32);
            let point = Vec2::new(rng.unit(), rng.unit());
            let angle = rng.unit() * core::f32::consts::TAU;
            let direction = Vec2::new(angle.cos(), angle.sin());
            for j in 0..n {
                for i in 0..n {
                    let q = Vec2::new(i as f32, j as f32) / (n - 1) as f32 - point;
                    let side = direction.perp_dot(q);
                    heights[j * n + i] += if side > 0.0 {
                        displacement
                    } else {
                        -displacement
                    };
                }
            }
        }
        if heights.iter().any(|h| !h.is_finite()) {
            return Err(err(
                "faults.amplitude",
                "the faults add up to a height that is not finite",
            ));
        }
        Ok(Terrain {
            size: self.size,
            resolution: n,
            heights,
        })
    }
}

impl Terrain {
    /// Side of the square.
    pub fn size(&self) -> f32 {
        self.size
    }

    /// Samples per side.
    #[cfg(test)]
    pub(crate) fn resolution(&self) -> usize {
        self.resolution
    }

    /// Height of grid vertex (i, j) (column along x, row along z).
    pub(crate) fn grid_height(&self, i: usize, j: usize) -> f32 {
        self.heights[j * self.resolution + i]
    }

    /// Position of grid vertex (i, j).
    pub(crate) fn grid_position(&self, i: usize, j: usize) -> Vec3 {
        let step = self.size / (self.resolution - 1) as f32;
        Vec3::new(i as f32 * step, self.grid_height(i, j), j as f32 * step)
    }

    /// The triangle of the grid under `(x, z)` (clamped into the square): its corners.
    fn triangle_under(&self, x: f32, z: f32) -> [Vec3; 3] {
        let cells = (self.resolution - 1) as f32;
        let fx = (x / self.size * cells).clamp(0.0, cells);
        let fz = (z / self.size * cells).clamp(0.0, cells);
        let i = (fx.floor() as usize).min(self.resolution - 2);
        let j = (fz.floor() as usize).min(self.resolution - 2);
        let (a, b, c, d) = (
            self.grid_position(i, j),
            self.grid_position(i + 1, j),
            self.grid_position(i, j + 1),
            self.grid_position(i + 1, j + 1),
        );
        // Each cell is split along its (i, j+1)–(i+1, j) diagonal, as in `mesh_indices`.
        if (fx - i as f32) + (fz - j as f32) <= 1.0 {
            [a, c, b]
        } else {
            [b, c, d]
        }
    }

    /// Height of the terrain under `(x, z)`, from the grid triangle below (clamped to the
    /// square's edge outside it).
    pub fn height_at(&self, x: f32, z: f32) -> f32 {
        let [a, b, c] = self.triangle_under(x, z);
        let p = Vec2::new(x.clamp(0.0, self.size), z.clamp(0.0, self.size));
        let (a2, b2, c2) = (a.xz(), b.xz(), c.xz());
        let area = (b2 - a2).perp_dot(c2 - a2);
        if area.abs() < f32::EPSILON {
            return a.y;
        }
        let wb = (p - a2).perp_dot(c2 - a2) / area;
        let wc = (b2 - a2).perp_dot(p - a2) / area;
        a.y + wb * (b.y - a.y) + wc * (c.y - a.y)
    }

    /// Upward unit normal of the grid triangle under `(x, z)`.
    pub fn normal_at(&self, x: f32, z: f32) -> Vec3 {
        let [a, b, c] = self.triangle_under(x, z);
        let n = (b - a).cross(c - a).normalize_or(Vec3::Y);
        if n.y < 0.0 { -n } else { n }
    }

    /// Vertex positions of the grid, row by row.
    #[cfg(any(test, feature = "render"))]
    pub(crate) fn mesh_positions(&self) -> Vec<Vec3> {
        let n = self.resolution;
        (0..n * n)
            .map(|k| self.grid_position(k % n, k / n))
            .collect()
    }

    /// Smooth vertex normals of the grid.
    #[cfg(any(test, feature = "render"))]
    pub(crate) fn mesh_normals(&self) -> Vec<Vec3> {
        let n = self.resolution;
        let step = self.size / (n - 1) as f32;
        (0..n * n)
            .map(|k| {
                let (i, j) = (k % n, k / n);
                let h = |i: usize, j: usize| self.grid_height(i, j);
                let dx = (h((i + 1).min(n - 1), j) - h(i.saturating_sub(1), j))
                    / (((i + 1).min(n - 1) - i.saturating_sub(1)) as f32 * step);
                let dz = (h(i, (j + 1).min(n - 1)) - h(i, j.saturating_sub(1)))
                    / (((j + 1).min(n - 1) - j.saturating_sub(1)) as f32 * step);
                Vec3::new(-dx, 1.0, -dz).normalize()
            })
            .collect()
    }

    /// Triangle indices of the grid (counter-clockwise seen from above).
    #[cfg(any(test, feature = "render"))]
    pub(crate) fn mesh_indices(&self) -> Vec<u32> {
        let n = self.resolution as u32;
        let mut out = Vec::with_capacity(((n - 1) * (n - 1) * 6) as usize);
        for j in 0..n - 1 {
            for i in 0..n - 1 {
                let a = j * n + i;
                let (b, c, d) = (a + 1, a + n, a + n + 1);
                out.extend([a, c, b, b, c, d]);
            }
        }
        out
    }
}
