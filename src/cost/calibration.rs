//! Calibrations: what an adapter's primitives and an app's logic cost, measured once and
//! saved per adapter (`*.calibration.ron`).

use bevy::prelude::{ReflectDefault, ReflectResource};
use serde::{Deserialize, Serialize};

use super::LinearCost;

/// Logic time against the number of visible instances at one target frame time, from
/// the logic benchmark; interpolated between the nearest samples at run time.
#[derive(Clone, Debug, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub(crate) struct LogicTable {
    /// The target frame time the samples were measured at, ms (the LOD's search, and so
    /// the logic time, depends on it when LOD is view-dependent).
    pub target_ms: f32,
    /// `(visible instances, seconds)`, sorted by visible count.
    pub samples: Vec<(u32, f32)>,
}

impl LogicTable {
    /// A table from samples in any order: non-finite or negative times are dropped, and
    /// samples whose visible counts lie within [`LogicTable::merge_gap`] of a run's first
    /// count are averaged into one (count and time). Frame times on a shared machine vary
    /// by tens of percent, so two samples one instance apart would otherwise make a
    /// segment whose slope is noise (the lavapipe calibration had 533 → 0 ms and
    /// 534 → 20 ms).
    pub(crate) fn new(target_ms: f32, mut samples: Vec<(u32, f32)>) -> Self {
        samples.retain(|s| s.1.is_finite() && s.1 >= 0.0);
        samples.sort_by_key(|s| s.0);
        let gap = Self::merge_gap(samples.last().map_or(0, |s| s.0));
        // (first count of the run, sum of counts, sum of times, samples)
        let mut runs: Vec<(u32, f64, f64, u32)> = Vec::new();
        for (n, t) in samples {
            match runs.last_mut() {
                Some(run) if n - run.0 <= gap => {
                    run.1 += f64::from(n);
                    run.2 += f64::from(t);
                    run.3 += 1;
                }
                _ => runs.push((n, f64::from(n), f64::from(t), 1)),
            }
        }
        Self {
            target_ms,
            samples: runs
                .into_iter()
                .map(|(_, n, t, k)| {
                    let k = f64::from(k);
                    ((n / k).round() as u32, (t / k) as f32)
                })
                .collect(),
        }
    }

    /// Samples whose visible counts differ by at most this much are one sample: 2% of the
    /// largest count, at least 2.
    pub(crate) fn merge_gap(largest_count: u32) -> u32 {
        (largest_count / 50).max(2)
    }

    /// Logic time with `visible` instances: linear between the two nearest samples;
    /// outside the sampled range, the nearest end sample extended with the table's
    /// overall slope (first to last sample, so one noisy end segment cannot send the
    /// estimate to seconds), never below zero; a single sample is a constant; an empty
    /// table is 0.
    pub(crate) fn time(&self, visible: u32) -> f32 {
        let s = &self.samples;
        let (Some(&first), Some(&last)) = (s.first(), s.last()) else {
            return 0.0;
        };
        if s.len() == 1 {
            return first.1;
        }
        let span = last.0.saturating_sub(first.0);
        let overall_slope = if span == 0 {
            0.0
        } else {
            (last.1 - first.1) / span as f32
        };
        let time = if visible <= first.0 {
            first.1 - overall_slope * (first.0 - visible) as f32
        } else if visible >= last.0 {
            last.1 + overall_slope * (visible - last.0) as f32
        } else {
            let i = s.partition_point(|p| p.0 <= visible).clamp(1, s.len() - 1);
            let (a, b) = (s[i - 1], s[i]);
            // `max(1)`: the fields are public, so a hand-built table may repeat a count.
            let t = visible.saturating_sub(a.0) as f32 / b.0.saturating_sub(a.0).max(1) as f32;
            a.1 + t.min(1.0) * (b.1 - a.1)
        };
        time.max(0.0)
    }
}

/// Logic time with `visible` instances at target `target_ms` from tables measured at
/// several targets: each table interpolated in the visible count, then linearly between
/// the two tables whose targets bracket `target_ms` (the nearest table outside their
/// range: logic time is not extrapolated in the target). No tables: 0.
pub(crate) fn logic_time(tables: &[LogicTable], visible: u32, target_ms: f32) -> f32 {
    let mut below: Option<&LogicTable> = None;
    let mut above: Option<&LogicTable> = None;
    for table in tables.iter().filter(|t| t.target_ms.is_finite()) {
        if table.target_ms <= target_ms {
            if below.is_none_or(|b| table.target_ms > b.target_ms) {
                below = Some(table);
            }
        } else if above.is_none_or(|a| table.target_ms < a.target_ms) {
            above = Some(table);
        }
    }
    match (below, above) {
        (Some(b), Some(a)) => {
            let t = (target_ms - b.target_ms) / (a.target_ms - b.target_ms);
            let (tb, ta) = (b.time(visible), a.time(visible));
            tb + t.clamp(0.0, 1.0) * (ta - tb)
        }
        (Some(only), None) | (None, Some(only)) => only.time(visible),
        (None, None) => 0.0,
    }
}

/// A saved calibration (`*.calibration.ron`): what this adapter's primitives and logic cost.
#[derive(
    bevy::asset::Asset, bevy::reflect::TypePath, Clone, Debug, PartialEq, Serialize, Deserialize,
)]
#[serde(default, deny_unknown_fields)]
pub struct Calibration {
    /// The adapter it was measured on (wgpu's adapter name).
    pub(crate) adapter: String,
    /// The driver (wgpu's driver and driver info).
    pub(crate) driver: String,
    /// Triangles.
    pub(crate) triangles: LinearCost,
    /// Lines, per width in pixels from 1 (index 0) up.
    pub(crate) lines: Vec<LinearCost>,
    /// Points, per size in pixels from 1 (index 0) up.
    pub(crate) points: Vec<LinearCost>,
    /// Logic time against visible instances, one table per target frame time measured
    /// (see [`logic_time`]): the main world's update, without the wait for the render
    /// world.
    pub(crate) logic: Vec<LogicTable>,
    /// The render world's time for a frame in which the forest draws nothing (Bevy's own
    /// passes, uploads, the present), seconds. Files written before it was measured read
    /// the default's.
    pub(crate) render_fixed: f32,
    /// Bevy's own mesh path, which `LodLadder` entities draw by (feature `render`). Files
    /// without it read the default's.
    pub(crate) meshes: MeshPathCost,
}

/// What a mesh drawn by Bevy's own pipeline (a `Mesh3d` and its material) costs the
/// render world: per draw (the entity's binding, uniforms, the draw call) and per
/// triangle, seconds.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub(crate) struct MeshPathCost {
    /// Per mesh drawn.
    pub per_draw: f32,
    /// Per triangle drawn.
    pub per_triangle: f32,
    /// Per pixel covered (the material's fragments: a PBR material on a large prop costs
    /// far more by its pixels than by its triangles).
    pub per_pixel: f32,
}

impl Default for MeshPathCost {
    /// A prior for Mesa lavapipe (Bevy's PBR path on a 2-core machine). The running app
    /// learns one factor on it from whole frames (see [`crate::cost`]); the `meshes`
    /// example holds its target with this prior, while one 2.7× dearer settled at a
    /// factor of 0.1–0.4 and oscillated (the family's share is hard to tell from whole
    /// frames). The calibration run does not measure it yet. Per pixel, 20 ns: about four
    /// times this crate's pass's fill, for a lit PBR fragment.
    fn default() -> Self {
        Self {
            per_draw: 30e-6,
            per_triangle: 0.4e-6,
            per_pixel: 20e-9,
        }
    }
}

impl Default for Calibration {
    /// A rough default, used with a warning until a calibration is measured: per-primitive
    /// costs of this crate's render pass on Mesa lavapipe (a software rasteriser), as
    /// `pass_benchmark` measured them on a 2-core machine — about 1.1 µs per small
    /// triangle, 2.6 µs per line and 1.5 µs per point, plus a few ns per covered pixel.
    /// `pixels` are covered pixels: a line's length × width, a point's size².
    fn default() -> Self {
        Self {
            adapter: UNMEASURED.into(),
            driver: UNMEASURED.into(),
            triangles: LinearCost {
                fixed: 2e-4,
                per_primitive: 1.1e-6,
                per_pixel: 5e-9,
            },
            lines: vec![
                LinearCost {
                    fixed: 2e-4,
                    per_primitive: 2.6e-6,
                    per_pixel: 5e-9,
                };
                20
            ],
            points: vec![
                LinearCost {
                    fixed: 2e-4,
                    per_primitive: 1.5e-6,
                    per_pixel: 1.2e-8,
                };
                20
            ],
            logic: vec![LogicTable::new(100.0, vec![(0, 2e-3), (1000, 6e-3)])],
            render_fixed: 5e-3,
            meshes: MeshPathCost::default(),
        }
    }
}

/// The most a calibration's fixed or logic time may be, seconds: a frame of ten seconds
/// is a stopped machine, not a cost.
pub(crate) const MAX_FIXED_SECONDS: f32 = 10.0;

/// The most one primitive (or one pixel of it) may cost, seconds.
pub(crate) const MAX_PRIMITIVE_SECONDS: f32 = 0.01;

/// Why a calibration file was refused.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CalibrationError {
    /// The RON does not parse (the message names line, column and field).
    #[error("{0}")]
    Ron(#[from] ron::error::SpannedError),
    /// A value is out of range.
    #[error("{0}")]
    Invalid(String),
    /// Reading failed.
    #[error("could not read the file: {0}")]
    Io(#[from] std::io::Error),
    /// Not UTF-8.
    #[error("the file is not UTF-8 text: {0}")]
    Utf8(#[from] core::str::Utf8Error),
}

/// The adapter and driver of the built-in default calibration.
const UNMEASURED: &str = "unknown";

impl Calibration {
    /// Whether it was measured (on the adapter it names), not the built-in default.
    pub(crate) fn is_measured(&self) -> bool {
        self.adapter != UNMEASURED
    }

    /// Parses and validates a calibration.
    pub fn from_ron_str(text: &str) -> Result<Self, CalibrationError> {
        let mut calibration: Self = crate::ron_file::ron_options().from_str(text)?;
        // Files written before near-equal counts were merged, or edited by hand.
        for table in &mut calibration.logic {
            *table = LogicTable::new(table.target_ms, core::mem::take(&mut table.samples));
        }
        // An empty family would make its primitives free.
        for (field, costs) in [
            ("lines", &calibration.lines),
            ("points", &calibration.points),
        ] {
            if costs.is_empty() {
                return Err(CalibrationError::Invalid(format!(
                    "{field}: needs at least one cost (width or size 1 first)"
                )));
            }
        }
        let families = core::iter::once(("triangles".to_owned(), &calibration.triangles))
            .chain(
                calibration
                    .lines
                    .iter()
                    .enumerate()
                    .map(|(i, c)| (format!("lines[{i}]"), c)),
            )
            .chain(
                calibration
                    .points
                    .iter()
                    .enumerate()
                    .map(|(i, c)| (format!("points[{i}]"), c)),
            );
        for (field, c) in families {
            for (part, value, most) in [
                ("fixed", c.fixed, MAX_FIXED_SECONDS),
                ("per_primitive", c.per_primitive, MAX_PRIMITIVE_SECONDS),
                ("per_pixel", c.per_pixel, MAX_PRIMITIVE_SECONDS),
            ] {
                if !(value.is_finite() && (0.0..=most).contains(&value)) {
                    return Err(CalibrationError::Invalid(format!(
                        "{field}.{part} is {value}: must be between 0 and {most} seconds"
                    )));
                }
            }
        }
        for (part, value) in [
            ("meshes.per_draw", calibration.meshes.per_draw),
            ("meshes.per_triangle", calibration.meshes.per_triangle),
            ("meshes.per_pixel", calibration.meshes.per_pixel),
        ] {
            if !(value.is_finite() && (0.0..=MAX_PRIMITIVE_SECONDS).contains(&value)) {
                return Err(CalibrationError::Invalid(format!(
                    "{part} is {value}: must be between 0 and {MAX_PRIMITIVE_SECONDS} seconds"
                )));
            }
        }
        if !(calibration.render_fixed.is_finite()
            && (0.0..=MAX_FIXED_SECONDS).contains(&calibration.render_fixed))
        {
            return Err(CalibrationError::Invalid(format!(
                "render_fixed must be between 0 and {MAX_FIXED_SECONDS} seconds"
            )));
        }
        for table in &calibration.logic {
            if let Some((n, t)) = table.samples.iter().find(|(_, t)| *t > MAX_FIXED_SECONDS) {
                return Err(CalibrationError::Invalid(format!(
                    "logic at {} ms: {t} s with {n} visible is more than {MAX_FIXED_SECONDS} seconds",
                    table.target_ms
                )));
            }
        }
        Ok(calibration)
    }

    /// The fixed per-frame part of the pass: one draw of each family (the fixed part of
    /// triangles, of the thinnest lines and of the smallest points), seconds.
    pub(crate) fn fixed_time(&self) -> f32 {
        (self.triangles.fixed
            + self.lines.first().map_or(0.0, |c| c.fixed)
            + self.points.first().map_or(0.0, |c| c.fixed))
        .max(0.0)
    }

    /// The render world's whole fixed time per frame: [`Calibration::render_fixed`] and
    /// one draw of each family ([`Calibration::fixed_time`]), seconds.
    pub(crate) fn render_fixed_time(&self) -> f32 {
        let fixed = if self.render_fixed.is_finite() {
            self.render_fixed.max(0.0)
        } else {
            0.0
        };
        fixed + self.fixed_time()
    }

    /// The logic tables as one line, `(time with nothing visible, time per visible
    /// instance)` in seconds, at the middle of the targets they were measured at (the
    /// prior of the learned logic model).
    pub(crate) fn logic_line(&self) -> (f32, f32) {
        let mut targets: Vec<f32> = self
            .logic
            .iter()
            .map(|t| t.target_ms)
            .filter(|t| t.is_finite())
            .collect();
        targets.sort_by(f32::total_cmp);
        let target = targets.get(targets.len() / 2).copied().unwrap_or(100.0);
        let widest = self
            .logic
            .iter()
            .filter_map(|t| t.samples.last().map(|s| s.0))
            .max()
            .unwrap_or(0)
            .max(1);
        let fixed = logic_time(&self.logic, 0, target);
        let slope = (logic_time(&self.logic, widest, target) - fixed) / widest as f32;
        let clean = |x: f32| if x.is_finite() { x.max(0.0) } else { 0.0 };
        (clean(fixed), clean(slope))
    }

    /// The same calibration with every cost and logic time multiplied by `factor`: a
    /// machine that much slower (above 1) or faster.
    pub fn scaled(&self, factor: f32) -> Self {
        let cost = |c: &LinearCost| LinearCost {
            fixed: c.fixed * factor,
            per_primitive: c.per_primitive * factor,
            per_pixel: c.per_pixel * factor,
        };
        Self {
            triangles: cost(&self.triangles),
            lines: self.lines.iter().map(cost).collect(),
            points: self.points.iter().map(cost).collect(),
            logic: self
                .logic
                .iter()
                .map(|t| LogicTable {
                    target_ms: t.target_ms,
                    samples: t.samples.iter().map(|&(n, s)| (n, s * factor)).collect(),
                })
                .collect(),
            render_fixed: self.render_fixed * factor,
            ..self.clone()
        }
    }

    /// The calibration as RON.
    pub fn to_ron_string(&self) -> Result<String, ron::Error> {
        ron::ser::to_string_pretty(self, ron::ser::PrettyConfig::default())
    }

    /// Parses `text`, or falls back to [`Calibration::default`] with the reason.
    #[cfg(test)]
    pub(crate) fn from_ron_str_or_default(text: &str) -> (Self, Option<CalibrationError>) {
        match Self::from_ron_str(text) {
            Ok(c) => (c, None),
            Err(e) => (Self::default(), Some(e)),
        }
    }
}

/// The adapter the app renders with, as a calibration names it. The render plugin inserts
/// it once the renderer is up; calibrations are matched against it.
#[derive(bevy::prelude::Resource, Clone, Debug, PartialEq, Eq, Default, bevy::reflect::Reflect)]
#[reflect(Resource, Default)]
pub struct AdapterIdentity {
    /// wgpu's adapter name, e.g. `llvmpipe (LLVM 15.0.6, 256 bits)`.
    pub name: String,
    /// wgpu's driver and driver info, e.g. `llvmpipe Mesa 22.3.6 (LLVM 15.0.6)`.
    pub driver: String,
    /// A software rasteriser (wgpu's `DeviceType::Cpu`, e.g. lavapipe). Its GPU timestamps
    /// are taken when the draws are handed to the rasteriser threads, before the pixels
    /// are filled, so they miss most of a pass's cost: the cost model and the calibration
    /// then measure frame times instead.
    pub cpu: bool,
}

/// The file name a calibration of `adapter` is saved under: the adapter name in lower
/// case, runs of anything but letters and digits as one `-`, then `.calibration.ron`.
#[cfg(any(test, feature = "render"))]
pub(crate) fn calibration_file_name(adapter: &str) -> String {
    let mut name = String::new();
    for c in adapter.chars() {
        if c.is_ascii_alphanumeric() {
            name.push(c.to_ascii_lowercase());
        } else if !name.ends_with('-') && !name.is_empty() {
            name.push('-');
        }
    }
    let name = name.trim_end_matches('-');
    format!(
        "{}.calibration.ron",
        if name.is_empty() { "adapter" } else { name }
    )
}
