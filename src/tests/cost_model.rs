//! Cost-model groundwork: fitting, logic interpolation, calibration files. The online
//! learning is tested in `cost_learning.rs`.

use crate::cost::*;

#[test]
fn fitting_recovers_known_parameters_from_noisy_samples() {
    let truth = LinearCost {
        fixed: 3e-3,
        per_primitive: 1.2e-6,
        per_pixel: 4e-9,
    };
    let mut state = 7_u64;
    let mut noise = move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((state >> 40) as f32 / (1u64 << 24) as f32 - 0.5) * 2.0 // ±1
    };
    let mut samples = Vec::new();
    for n in [500.0, 2_000.0, 8_000.0, 20_000.0, 50_000.0] {
        for pixels_per in [5.0, 40.0, 200.0] {
            let pixels = n * pixels_per;
            let time = truth.time(n, pixels) * (1.0 + 0.03 * noise()); // 3% noise
            samples.push(CostSample {
                primitives: n,
                pixels,
                time,
            });
        }
    }
    let fit = fit_linear_cost(&samples).unwrap();
    let close = |a: f32, b: f32| ((a - b) / b).abs() < 0.05;
    assert!(close(fit.fixed, truth.fixed), "{fit:?}");
    assert!(close(fit.per_primitive, truth.per_primitive), "{fit:?}");
    assert!(close(fit.per_pixel, truth.per_pixel), "{fit:?}");
}

#[test]
fn fitting_refuses_too_few_or_degenerate_samples() {
    let s = |n: f32, p: f32| CostSample {
        primitives: n,
        pixels: p,
        time: 1e-3,
    };
    assert_eq!(
        fit_linear_cost(&[s(1.0, 1.0), s(2.0, 2.0)]),
        Err(FitError::TooFewSamples(2))
    );
    // Pixels always 10 × primitives: the two parts cannot be told apart.
    let collinear: Vec<_> = (1..10).map(|i| s(i as f32, 10.0 * i as f32)).collect();
    assert_eq!(fit_linear_cost(&collinear), Err(FitError::Degenerate));
}

#[test]
fn logic_interpolation_at_between_and_outside_the_samples() {
    let table = LogicTable::new(
        100.0,
        vec![(1000, 0.010), (0, 0.002), (500, 0.004), (500, 0.006)],
    );
    assert_eq!(table.samples, vec![(0, 0.002), (500, 0.005), (1000, 0.010)]);
    assert!((table.time(500) - 0.005).abs() < 1e-7); // at
    assert!((table.time(250) - 0.0035).abs() < 1e-7); // between
    assert!((table.time(750) - 0.0075).abs() < 1e-7);
    // Beyond: the last sample extended with the overall slope (0.008 s per 1000).
    assert!((table.time(1500) - 0.014).abs() < 1e-6);
    let falling = LogicTable::new(100.0, vec![(100, 0.001), (200, 0.0005)]);
    assert_eq!(falling.time(1000), 0.0); // never negative
    assert_eq!(LogicTable::default().time(10), 0.0);
    assert_eq!(LogicTable::new(0.0, vec![(5, 0.003)]).time(99), 0.003);
}

#[test]
fn noisy_neighbouring_logic_samples_cannot_send_the_estimate_to_seconds() {
    // Shaped like the 200 ms table of the first lavapipe calibration: two samples one
    // instance apart, 20 ms different (frame-time noise).
    let table = LogicTable::new(
        200.0,
        vec![
            (0, 0.0),
            (41, 0.0016),
            (300, 0.03),
            (533, 0.0),
            (534, 0.0203),
        ],
    );
    assert_eq!(table.samples.len(), 4, "533 and 534 are one sample");
    assert_eq!(table.samples[3], (534, 0.01015));
    // Overall slope 0.01015 s / 534 instances: about 19 ms at 1000, not the ~9 s the
    // last raw segment (20 ms per instance) would give.
    let at_1000 = table.time(1000);
    let expected = 0.01015 + 0.01015 / 534.0 * 466.0;
    assert!((at_1000 - expected).abs() < 1e-5, "{at_1000} vs {expected}");
    // A hand-built table with a repeated count still gives finite times.
    let repeated = LogicTable {
        target_ms: 100.0,
        samples: vec![(10, 0.001), (10, 0.002), (20, 0.003)],
    };
    for visible in [0, 10, 15, 20, 40] {
        assert!(repeated.time(visible).is_finite());
    }
}

#[test]
fn logic_interpolation_across_targets() {
    let tables = [
        LogicTable::new(200.0, vec![(0, 0.004), (1000, 0.024)]),
        LogicTable::new(50.0, vec![(0, 0.002), (1000, 0.012)]),
    ];
    // At a measured target, that table.
    assert!((logic_time(&tables, 500, 50.0) - 0.007).abs() < 1e-7);
    assert!((logic_time(&tables, 500, 200.0) - 0.014).abs() < 1e-7);
    // Between targets, linear in the target.
    assert!((logic_time(&tables, 500, 125.0) - 0.0105).abs() < 1e-6);
    // Outside, the nearest table (no extrapolation in the target).
    assert!((logic_time(&tables, 500, 10.0) - 0.007).abs() < 1e-7);
    assert!((logic_time(&tables, 500, 1000.0) - 0.014).abs() < 1e-7);
    assert_eq!(logic_time(&[], 500, 100.0), 0.0);
}

#[test]
fn sized_fits_recover_each_size_and_interpolate_between() {
    // Lines: pixels vary with projected length independently of the count.
    let truth = |w: u32| LinearCost {
        fixed: 1e-3,
        per_primitive: (2.0 + 0.1 * w as f32) * 1e-6,
        per_pixel: 5e-9,
    };
    let mut samples = Vec::new();
    for w in [1, 4, 8] {
        for n in [2_000.0, 10_000.0, 40_000.0] {
            for length in [3.0, 30.0] {
                let pixels = n * length * w as f32;
                samples.push((
                    w,
                    CostSample {
                        primitives: n,
                        pixels,
                        time: truth(w).time(n, pixels),
                    },
                ));
            }
        }
    }
    let costs = fit_sized_costs(&samples, 10).unwrap();
    assert_eq!(costs.len(), 10);
    let close = |a: f32, b: f32| ((a - b) / b).abs() < 1e-3;
    for w in [1, 4, 8] {
        let c = costs[w as usize - 1];
        assert!(close(c.per_primitive, truth(w).per_primitive), "{w}: {c:?}");
        assert!(close(c.per_pixel, truth(w).per_pixel), "{w}: {c:?}");
    }
    // Between measured widths: linear in the parts; beyond: the nearest.
    let mid = (truth(4).per_primitive + truth(8).per_primitive) / 2.0;
    assert!(close(costs[5].per_primitive, mid), "{:?}", costs[5]);
    assert!(close(costs[9].per_primitive, truth(8).per_primitive));

    // Points: pixels = count × size², so only fixed + per-primitive can be told apart.
    let points: Vec<(u32, CostSample)> = [1_000.0, 5_000.0, 20_000.0]
        .into_iter()
        .map(|n| {
            (
                4,
                CostSample {
                    primitives: n,
                    pixels: n * 16.0,
                    time: 2e-4 + n * 3e-6,
                },
            )
        })
        .collect();
    let point = fit_sized_costs(&points, 4).unwrap()[3];
    assert!(
        close(point.per_primitive, 3e-6) && point.per_pixel == 0.0,
        "{point:?}"
    );
    assert!((point.fixed - 2e-4).abs() < 1e-6, "{point:?}");
    // Noise that would make a part negative gives a smaller model, never a negative part.
    let noisy: Vec<(u32, CostSample)> = [(100.0, 1e-3), (200.0, 0.9e-3), (300.0, 1.1e-3)]
        .into_iter()
        .map(|(n, t)| {
            (
                1,
                CostSample {
                    primitives: n,
                    pixels: n,
                    time: t,
                },
            )
        })
        .collect();
    let c = fit_sized_costs(&noisy, 1).unwrap()[0];
    assert!(c.fixed >= 0.0 && c.per_primitive >= 0.0 && c.per_pixel >= 0.0);
    assert!(fit_sized_costs(&[], 4).is_err());
}

fn llvmpipe() -> AdapterIdentity {
    AdapterIdentity {
        name: "llvmpipe (LLVM 15.0.6, 256 bits)".into(),
        driver: "llvmpipe Mesa 22.3.6".into(),
        cpu: true,
    }
}

#[test]
fn calibrations_are_chosen_by_adapter_then_driver() {
    let adapter = llvmpipe();
    assert_eq!(
        calibration_file_name(&adapter.name),
        "llvmpipe-llvm-15-0-6-256-bits.calibration.ron"
    );
    assert!(choose_calibration([], &adapter).is_none());
    let mut other_driver = Calibration {
        adapter: adapter.name.clone(),
        driver: "llvmpipe Mesa 21".into(),
        ..Default::default()
    };
    other_driver.triangles.per_primitive = 9e-6;
    let exact = Calibration {
        adapter: adapter.name.clone(),
        driver: adapter.driver.clone(),
        ..Default::default()
    };
    let foreign = Calibration {
        adapter: "NVIDIA GeForce".into(),
        ..Default::default()
    };
    // Same adapter, other driver: used when nothing better exists.
    assert_eq!(
        choose_calibration([&other_driver, &foreign], &adapter),
        Some(&other_driver)
    );
    assert_eq!(
        choose_calibration([&other_driver, &foreign, &exact], &adapter),
        Some(&exact)
    );
    assert!(choose_calibration([&foreign], &adapter).is_none());
}

/// An app reading calibrations from the asset folder `dir` (with no window, no renderer:
/// the adapter is inserted by hand).
fn calibration_app(dir: &std::path::Path, adapter: AdapterIdentity) -> bevy::prelude::App {
    let mut app = crate::testing::app_reading(dir, CostPlugin);
    app.insert_resource(adapter);
    app
}

/// Updates until the calibration changes from `before` (bounded), and returns it.
fn loaded_calibration(app: &mut bevy::prelude::App, before: &Calibration) -> Calibration {
    for _ in 0..2000 {
        app.update();
        let now = app.world().resource::<CostModel>().calibration();
        if now != before {
            return now.clone();
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    before.clone()
}

#[test]
fn the_adapter_s_calibration_loads_from_the_app_s_index_and_bad_files_are_skipped() {
    let dir = std::env::temp_dir().join(format!("sherwood-calibrations-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("calibration")).unwrap();
    let adapter = llvmpipe();
    let mut exact = Calibration {
        adapter: adapter.name.clone(),
        driver: adapter.driver.clone(),
        ..Default::default()
    };
    exact.points[0].per_primitive = 3e-7;
    let foreign = Calibration {
        adapter: "NVIDIA GeForce".into(),
        ..Default::default()
    };
    let write = |name: &str, text: String| {
        std::fs::write(dir.join("calibration").join(name), text).unwrap();
    };
    write("nvidia.calibration.ron", foreign.to_ron_string().unwrap());
    write("broken.calibration.ron", "(adapter: 3)".into());
    write("mine.calibration.ron", exact.to_ron_string().unwrap());
    write(
        "index.calibrations.ron",
        r#"["nvidia.calibration.ron", "broken.calibration.ron", "mine.calibration.ron"]"#.into(),
    );
    let mut app = calibration_app(&dir, adapter.clone());
    // The app's own calibration comes before the shipped one for the same adapter.
    assert_eq!(loaded_calibration(&mut app, &Calibration::default()), exact);
    // The broken file was skipped; loaded on its own, it fails with its place named.
    let broken: bevy::asset::Handle<Calibration> = app
        .world()
        .resource::<bevy::asset::AssetServer>()
        .load("calibration/broken.calibration.ron");
    match crate::testing::settle(&mut app, &broken) {
        bevy::asset::LoadState::Failed(e) => {
            let e = e.to_string();
            assert!(
                e.contains("broken.calibration.ron") && e.contains("1:"),
                "{e}"
            );
        }
        other => panic!("the broken calibration should have failed: {other:?}"),
    }
    // Without an index of its own, the app finds the calibration this crate ships.
    std::fs::remove_file(
        dir.join("calibration")
            .join(APP_INDEX.trim_start_matches("calibration/")),
    )
    .unwrap();
    let mut app = calibration_app(&dir, adapter);
    let shipped = loaded_calibration(&mut app, &Calibration::default());
    assert_eq!(shipped.adapter, "llvmpipe (LLVM 15.0.6, 256 bits)");
    assert_ne!(shipped, exact);
    // An adapter nobody measured: the default costs.
    let unknown = AdapterIdentity {
        name: "unknown".into(),
        ..Default::default()
    };
    let mut app = calibration_app(&dir, unknown.clone());
    #[derive(bevy::prelude::Resource, Default)]
    struct Missing(Vec<AdapterIdentity>);
    app.init_resource::<Missing>().add_observer(
        |missing: bevy::prelude::On<CalibrationNotFound>,
         mut seen: bevy::prelude::ResMut<Missing>| {
            seen.0.push(missing.adapter.clone());
        },
    );
    for _ in 0..200 {
        app.update();
        std::thread::sleep(std::time::Duration::from_millis(1));
    }
    assert_eq!(
        *app.world().resource::<CostModel>().calibration(),
        Calibration::default()
    );
    assert_eq!(
        app.world().resource::<Missing>().0,
        [unknown],
        "announced once"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_calibration_run_adds_its_file_to_the_index() {
    let dir =
        std::env::temp_dir().join(format!("sherwood-calibration-index-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    add_to_index(&dir, "a.calibration.ron").unwrap();
    add_to_index(&dir, "b.calibration.ron").unwrap();
    add_to_index(&dir, "a.calibration.ron").unwrap();
    let text = std::fs::read_to_string(dir.join("index.calibrations.ron")).unwrap();
    let index: Vec<String> = ron::from_str(&text).unwrap();
    assert_eq!(index, ["a.calibration.ron", "b.calibration.ron"]);
    std::fs::write(dir.join("index.calibrations.ron"), "[3]").unwrap();
    assert!(add_to_index(&dir, "c.calibration.ron").is_err());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn calibration_files_round_trip_and_bad_ones_fall_back() {
    let calibration = Calibration {
        adapter: "llvmpipe (LLVM 15.0.6, 256 bits)".into(),
        ..Default::default()
    };
    let text = calibration.to_ron_string().unwrap();
    assert_eq!(Calibration::from_ron_str(&text).unwrap(), calibration);
    let (fallback, error) = Calibration::from_ron_str_or_default("(adapter: \"x\", trianglez: ())");
    assert_eq!(fallback, Calibration::default());
    let message = error.unwrap().to_string();
    assert!(
        message.contains("trianglez") && message.starts_with("1:"),
        "{message}"
    );
    let mut negative = calibration.clone();
    negative.lines[3].per_primitive = -1.0;
    assert!(matches!(
        Calibration::from_ron_str(&negative.to_ron_string().unwrap()),
        Err(CalibrationError::Invalid(_))
    ));
}
