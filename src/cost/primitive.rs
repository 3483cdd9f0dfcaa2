//! What primitives cost, per primitive and per covered pixel, as the searches price them.

use bevy::reflect::Reflect;
use serde::{Deserialize, Serialize};

use super::{Calibration, LinearCost};

/// Factors on a calibration's per-primitive costs, one per primitive family: how much
/// dearer (above 1) or cheaper each family is on this machine now than the calibration
/// says. The cost model learns them ([`CostModel`](super::CostModel)).
#[derive(Clone, Copy, Debug, PartialEq, Reflect, Serialize, Deserialize)]
pub struct FamilyScales {
    /// Per triangle (vertex work, set-up).
    pub triangles: f32,
    /// Per covered pixel of triangles (fill).
    pub triangle_pixels: f32,
    /// Lines, every width (per line and per pixel alike).
    pub lines: f32,
    /// Points, every size.
    pub points: f32,
    /// Meshes on Bevy's own path (ladder entities and the app's own), per draw and per
    /// triangle alike.
    pub meshes: f32,
    /// Per covered pixel of those meshes (their materials' fragments).
    pub mesh_pixels: f32,
}

impl FamilyScales {
    /// Every family as calibrated.
    pub(crate) const ONE: Self = Self::uniform(1.0);

    /// The same factor for every family.
    pub(crate) const fn uniform(scale: f32) -> Self {
        Self {
            triangles: scale,
            triangle_pixels: scale,
            lines: scale,
            points: scale,
            meshes: scale,
            mesh_pixels: scale,
        }
    }
}

impl Default for FamilyScales {
    fn default() -> Self {
        Self::ONE
    }
}

/// A predicted rendering time split by primitive family, seconds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Reflect, Serialize, Deserialize)]
pub struct FamilyTimes {
    /// Triangles' per-primitive part.
    pub triangles: f32,
    /// Triangles' per-pixel part.
    pub triangle_pixels: f32,
    /// Lines.
    pub lines: f32,
    /// Points.
    pub points: f32,
    /// Meshes on Bevy's own path (ladder entities and the app's own), per draw and per
    /// triangle.
    pub meshes: f32,
    /// Their covered pixels.
    pub mesh_pixels: f32,
}

impl FamilyTimes {
    /// The whole time.
    pub fn total(&self) -> f32 {
        self.triangles
            + self.triangle_pixels
            + self.lines
            + self.points
            + self.meshes
            + self.mesh_pixels
    }

    /// Each part divided by its family's factor: the same selection priced by the
    /// calibration alone. A factor that is not finite and positive counts as 1.
    pub(crate) fn unscaled(&self, scales: FamilyScales) -> Self {
        let over = |t: f32, s: f32| if s.is_finite() && s > 0.0 { t / s } else { t };
        Self {
            triangles: over(self.triangles, scales.triangles),
            triangle_pixels: over(self.triangle_pixels, scales.triangle_pixels),
            lines: over(self.lines, scales.lines),
            points: over(self.points, scales.points),
            meshes: over(self.meshes, scales.meshes),
            mesh_pixels: over(self.mesh_pixels, scales.mesh_pixels),
        }
    }
}

impl core::ops::AddAssign for FamilyTimes {
    fn add_assign(&mut self, other: Self) {
        self.triangles += other.triangles;
        self.triangle_pixels += other.triangle_pixels;
        self.lines += other.lines;
        self.points += other.points;
        self.meshes += other.meshes;
        self.mesh_pixels += other.mesh_pixels;
    }
}

/// Predicted time of primitives, per primitive (fixed per-frame parts are accounted for
/// once per frame, not here), in seconds.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct PrimitiveCosts {
    /// Per triangle.
    pub triangle: f32,
    /// Per covered pixel of triangles.
    pub triangle_pixel: f32,
    /// Per line, by width (index 0 = 1 px).
    pub line: Vec<f32>,
    /// Per covered pixel of lines, by width.
    pub line_pixel: Vec<f32>,
    /// Per point, by size (index 0 = 1 px).
    pub point: Vec<f32>,
    /// Per covered pixel of points, by size.
    pub point_pixel: Vec<f32>,
    /// Per mesh drawn on Bevy's own path (ladder entities).
    pub mesh_draw: f32,
    /// Per triangle of such a mesh.
    pub mesh_triangle: f32,
    /// Per pixel such a mesh covers.
    pub mesh_pixel: f32,
    /// The most pixels one object (a trunk, a tree's leaves) or one batch of primitives
    /// can cover: the viewport's. A tree at the camera projects to millions of pixels per
    /// triangle, but its triangles together fill the screen, no more (the depth test
    /// rejects what is hidden before it is shaded).
    pub max_pixels: f32,
}

impl PrimitiveCosts {
    /// The per-primitive parts of a calibration, each scaled by `scale` (a measured speed
    /// of this machine against the calibration's).
    pub(crate) fn from_calibration(calibration: &Calibration, scale: f32) -> Self {
        Self::scaled(calibration, FamilyScales::uniform(scale))
    }

    /// The per-primitive parts of a calibration, each family scaled by its factor (what
    /// the cost model learned). A factor that is not finite and positive counts as 1.
    pub(crate) fn scaled(calibration: &Calibration, scales: FamilyScales) -> Self {
        let factor = |s: f32| if s.is_finite() && s > 0.0 { s } else { 1.0 };
        let clean = |x: f32, s: f32| {
            if x.is_finite() {
                x.max(0.0) * factor(s)
            } else {
                0.0
            }
        };
        let each = |costs: &[LinearCost], part: fn(&LinearCost) -> f32, s: f32| {
            costs.iter().map(|c| clean(part(c), s)).collect()
        };
        Self {
            triangle: clean(calibration.triangles.per_primitive, scales.triangles),
            triangle_pixel: clean(calibration.triangles.per_pixel, scales.triangle_pixels),
            line: each(&calibration.lines, |c| c.per_primitive, scales.lines),
            line_pixel: each(&calibration.lines, |c| c.per_pixel, scales.lines),
            point: each(&calibration.points, |c| c.per_primitive, scales.points),
            point_pixel: each(&calibration.points, |c| c.per_pixel, scales.points),
            mesh_draw: clean(calibration.meshes.per_draw, scales.meshes),
            mesh_triangle: clean(calibration.meshes.per_triangle, scales.meshes),
            mesh_pixel: clean(calibration.meshes.per_pixel, scales.mesh_pixels),
            max_pixels: f32::INFINITY,
        }
    }

    /// The same costs with each object's coverage capped at `viewport_pixels` (ignored
    /// unless positive).
    pub(crate) fn within_viewport(mut self, viewport_pixels: f32) -> Self {
        if viewport_pixels > 0.0 {
            self.max_pixels = viewport_pixels;
        }
        self
    }

    fn pick(values: &[f32], size: u32) -> f32 {
        let i = (size.max(1) as usize - 1).min(values.len().saturating_sub(1));
        values.get(i).copied().unwrap_or(0.0)
    }

    /// `count` triangles of `area` pixels each, covering at most a screenful together.
    pub(crate) fn triangles(&self, count: u32, area: f32) -> f32 {
        let n = count as f32;
        n * self.triangle + self.triangle_pixel * (n * area.max(0.0)).min(self.max_pixels)
    }

    /// `count` lines `width` pixels wide, `length` pixels long in total, covering at most a
    /// screenful together.
    pub(crate) fn lines(&self, width: u32, count: u32, length: f32) -> f32 {
        let covered = (length * width as f32).min(self.max_pixels);
        count as f32 * Self::pick(&self.line, width) + Self::pick(&self.line_pixel, width) * covered
    }

    /// One mesh of `triangles` triangles on Bevy's own path.
    pub(crate) fn mesh(&self, triangles: u32) -> f32 {
        self.mesh_draw + triangles as f32 * self.mesh_triangle
    }

    /// The fragments of meshes on Bevy's path covering `pixels` (capped at the viewport's).
    pub(crate) fn mesh_pixels(&self, pixels: f32) -> f32 {
        if pixels.is_finite() && pixels > 0.0 {
            pixels.min(self.max_pixels) * self.mesh_pixel
        } else {
            0.0
        }
    }

    /// `count` points of `size` pixels.
    pub(crate) fn points(&self, size: u32, count: u32) -> f32 {
        let s = size as f32;
        count as f32 * (Self::pick(&self.point, size) + Self::pick(&self.point_pixel, size) * s * s)
    }
}
