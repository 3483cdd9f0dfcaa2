//! Bevy diagnostics for the LOD stages: every field of [`LodDiagnostics`] as a
//! `sherwood/...` diagnostic, for `LogDiagnosticsPlugin`, the `DiagnosticsStore` or any
//! tool that reads Bevy diagnostics.

use bevy::diagnostic::{Diagnostic, DiagnosticPath, Diagnostics, RegisterDiagnostic};
use bevy::prelude::*;

use super::LodDiagnostics;
use crate::SherwoodSystems;

/// Publishes [`LodDiagnostics`] as Bevy diagnostics each frame. Without it the resource
/// is still kept (it is a few numbers) and nothing else is done.
#[derive(Default)]
pub struct LodDiagnosticsPlugin;

/// The published diagnostics, with how each is read off [`LodDiagnostics`].
const PATHS: [(DiagnosticPath, &str, fn(&LodDiagnostics) -> f64); 22] = [
    (
        DiagnosticPath::const_new("sherwood/visible_objects"),
        "",
        |d| f64::from(d.visible_objects),
    ),
    (
        DiagnosticPath::const_new("sherwood/visible_instances"),
        "",
        |d| f64::from(d.visible_instances),
    ),
    (DiagnosticPath::const_new("sherwood/logic"), "ms", |d| {
        f64::from(d.logic_ms)
    }),
    (
        DiagnosticPath::const_new("sherwood/render_budget"),
        "ms",
        |d| f64::from(d.render_budget_ms),
    ),
    (
        DiagnosticPath::const_new("sherwood/predicted_render"),
        "ms",
        |d| f64::from(d.predicted_render_ms),
    ),
    (
        DiagnosticPath::const_new("sherwood/predicted_frame"),
        "ms",
        |d| f64::from(d.predicted_frame_ms),
    ),
    (
        DiagnosticPath::const_new("sherwood/measured_frame"),
        "ms",
        |d| f64::from(d.measured_frame_ms),
    ),
    (DiagnosticPath::const_new("sherwood/wasted"), "ms", |d| {
        f64::from(d.wasted_ms)
    }),
    (DiagnosticPath::const_new("sherwood/triangles"), "", |d| {
        d.counts.triangles as f64
    }),
    (DiagnosticPath::const_new("sherwood/lines"), "", |d| {
        d.counts.lines as f64
    }),
    (DiagnosticPath::const_new("sherwood/points"), "", |d| {
        d.counts.points as f64
    }),
    (DiagnosticPath::const_new("sherwood/truncated"), "", |d| {
        f64::from(d.truncated)
    }),
    (DiagnosticPath::const_new("sherwood/undrawn"), "", |d| {
        f64::from(d.undrawn)
    }),
    (
        DiagnosticPath::const_new("sherwood/stage_time"),
        "ms",
        |d| f64::from(d.value_stage_ms + d.budget_stage_ms + d.select_stage_ms),
    ),
    (DiagnosticPath::const_new("sherwood/overrun"), "ms", |d| {
        f64::from(d.overrun_ms)
    }),
    (
        DiagnosticPath::const_new("sherwood/floor_excess"),
        "ms",
        |d| f64::from(d.floor_excess_ms),
    ),
    (
        DiagnosticPath::const_new("sherwood/measured_logic"),
        "ms",
        |d| f64::from(d.measured_logic_ms),
    ),
    (
        DiagnosticPath::const_new("sherwood/measured_render"),
        "ms",
        |d| f64::from(d.measured_render_ms),
    ),
    (
        DiagnosticPath::const_new("sherwood/measured_frame_predicted"),
        "ms",
        |d| f64::from(d.measured_frame_predicted_ms),
    ),
    (
        DiagnosticPath::const_new("sherwood/learned_render_fixed"),
        "ms",
        |d| f64::from(d.learned.render_fixed_ms),
    ),
    (
        DiagnosticPath::const_new("sherwood/learned_render_speed"),
        "",
        |d| f64::from(d.learned.render_speed),
    ),
    (
        DiagnosticPath::const_new("sherwood/learned_logic_fixed"),
        "ms",
        |d| f64::from(d.learned.logic_fixed_ms),
    ),
];

impl Plugin for LodDiagnosticsPlugin {
    fn build(&self, app: &mut App) {
        for (path, suffix, _) in PATHS {
            app.register_diagnostic(Diagnostic::new(path).with_suffix(suffix));
        }
        app.add_systems(PostUpdate, publish.in_set(SherwoodSystems::Stats));
    }
}

fn publish(lod: Res<LodDiagnostics>, mut diagnostics: Diagnostics) {
    for (path, _, read) in &PATHS {
        diagnostics.add_measurement(path, || read(&lod));
    }
}
