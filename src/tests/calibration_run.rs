//! The calibration run on a real adapter (Mesa lavapipe in CI), shortened: it measures
//! every primitive family and the logic, writes a calibration, and the cost model can
//! load what it wrote. Run with `cargo test --features gpu-tests`.
#![cfg(feature = "gpu-tests")]

use crate::testing as common;
use crate::testing as windowless;

use crate::prelude::*;
use crate::render::{CalibrationProgress, CalibrationRunPlugin, CalibrationSettings};
use bevy::log::LogPlugin;
use bevy::prelude::*;

#[test]
fn a_short_calibration_run_writes_a_calibration_the_cost_model_loads() {
    let _measuring = common::measuring();
    let out = std::env::temp_dir().join(format!(
        "sherwood-calibration-run-{}.calibration.ron",
        std::process::id()
    ));
    let mut app = App::new();
    app.add_plugins(
        windowless::windowless_plugins(
            DefaultPlugins.build().disable::<bevy::winit::WinitPlugin>(),
        )
        .disable::<LogPlugin>(),
    )
    .add_plugins((SherwoodPlugins, CalibrationRunPlugin))
    .insert_resource(CalibrationSettings {
        out: Some(out.clone()),
        settle_frames: 2,
        frames_per_sample: 3,
        // Large enough that each family's time stands well above the frame's jitter.
        primitive_counts: vec![60_000, 180_000],
        sizes: vec![1, 8],
        logic_targets_ms: vec![100.0],
        logic_positions: 2,
    });
    windowless::finish_plugins(&mut app);
    let mut desc = common::default_ecosystem();
    desc.set_total_trees(60)
        .expect("the default forest has trees to scale");
    common::spawn_forest(&mut app, desc);
    common::image_camera(
        &mut app,
        Vec3::new(-20.0, 25.0, -20.0),
        Vec3::new(100.0, 0.0, 100.0),
    );

    let mut outcome = None;
    for _ in 0..3_000 {
        app.update();
        outcome = app
            .world()
            .resource::<CalibrationProgress>()
            .outcome
            .clone();
        if outcome.is_some() {
            break;
        }
    }
    let written = outcome
        .expect("the calibration run never finished")
        .unwrap();
    assert_eq!(written, out);
    let calibration =
        crate::cost::Calibration::from_ron_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    std::fs::remove_file(&out).unwrap();
    // Every family measured as something, and the logic as real time (the old run could
    // write 0 ms logic where its subtraction went negative).
    assert!(calibration.triangles.per_primitive > 0.0 || calibration.triangles.per_pixel > 0.0);
    assert!(!calibration.lines.is_empty() && !calibration.points.is_empty());
    assert!(calibration.render_fixed > 0.0, "{calibration:?}");
    // What was measured is what drawing costs, not a blank frame's noise: three times the
    // primitives take longer in every family, and 8-pixel points more than 1-pixel ones
    // (on lavapipe about twice as much; the debug build's extraction, the same for both,
    // narrows it).
    let time =
        |cost: &crate::cost::LinearCost, n: f32, pixels_each: f32| cost.time(n, n * pixels_each);
    for (family, cost, pixels) in [
        ("triangles", calibration.triangles, 20.0),
        ("1 px lines", calibration.lines[0], 3.0),
        ("1 px points", calibration.points[0], 1.0),
        ("8 px points", calibration.points[7], 64.0),
    ] {
        assert!(
            time(&cost, 180_000.0, pixels) > 1.5 * time(&cost, 60_000.0, pixels),
            "{family}: {cost:?}"
        );
    }
    assert!(
        time(&calibration.points[7], 180_000.0, 64.0)
            > 1.2 * time(&calibration.points[0], 180_000.0, 1.0),
        "8 px points cost no more than 1 px ones: {:?}",
        calibration.points
    );
    let logic = &calibration.logic;
    assert!(!logic.is_empty(), "{calibration:?}");
    assert!(
        logic.iter().flat_map(|t| &t.samples).all(|&(_, t)| t > 0.0),
        "{logic:?}"
    );
    // The cost model installed it.
    let installed = app.world().resource::<CostModel>().calibration().clone();
    assert_eq!(installed.triangles, calibration.triangles);
    assert_eq!(installed.render_fixed, calibration.render_fixed);
}
