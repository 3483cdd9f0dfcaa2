//! Bad input ends in an error that names the field or the position, or in a documented
//! fallback: never a panic, a hang or a non-finite number in what was loaded. A suite of
//! malformed inputs for every format, then mutation fuzzing of the shipped assets: a few
//! dozen cases per format in `cargo test`, as many as `SHERWOOD_FUZZ_CASES` says for a
//! long run (`SHERWOOD_FUZZ_CASES=10000 cargo test --release --test bad_input`).

use crate::testing as common;

use super::fuzz::{cases, mutate, mutation};
use crate::cost::{Calibration, CalibrationError};
use crate::ecosystem::{EcosystemDesc, TerrainDesc};
use crate::tree::{
    AnalysisOptions, MeshData, PixelRange, Projection, SpeciesDesc, TreeAnalysisError,
    TreeFileError, TreeModel, analyze, trunk_lod,
};
use crate::wind::SpringSet;
use bevy::math::Vec3;
use proptest::prelude::*;

fn asset(path: &str) -> String {
    let file = format!("{}/assets/{path}", env!("CARGO_MANIFEST_DIR"));
    std::fs::read_to_string(&file).unwrap_or_else(|e| panic!("{file}: {e}"))
}

fn refused<T, E: std::fmt::Display>(result: Result<T, E>, case: &str) -> String {
    match result {
        Ok(_) => panic!("{case}: accepted"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn a_model_whose_rings_come_before_their_parents_is_refused() {
    let model = common::species("slender");
    let mut before = model.clone();
    before.rings[1].parent = 5;
    let message = refused(before.validate(), "a parent after its child");
    assert!(message.contains("before its parent"), "{message}");
    // A cycle is a parent after its child somewhere.
    let mut cycle = model.clone();
    cycle.rings[0].parent = 0;
    refused(cycle.validate(), "a ring its own parent");
    assert!(model.validate().is_ok());
}

#[test]
fn a_model_with_a_number_that_is_not_finite_is_refused() {
    let model = common::species("grand");
    let edits: [(&str, fn(&mut TreeModel)); 10] = [
        ("bounds", |m| m.bounds.max.x = f32::NAN),
        ("trunk_bounds", |m| m.trunk_bounds.min.y = f32::INFINITY),
        ("mean_leaf_triangle_area", |m| {
            m.mean_leaf_triangle_area = f32::INFINITY;
        }),
        ("mean_trunk_triangle_area", |m| {
            m.mean_trunk_triangle_area = -1.0;
        }),
        ("trunk_area_center", |m| m.trunk_area_center.z = f32::NAN),
        ("segments.line", |m| m.segments.line[0][1].x = f32::NAN),
        ("segments.diameter", |m| m.segments.diameter[0] = -1.0),
        ("segments.cumulative_length", |m| {
            m.segments.cumulative_length[3] = f32::NAN;
        }),
        ("leaves", |m| m.leaves[0].center = Vec3::NAN),
        ("leaf_groups", |m| {
            m.leaf_groups[0].bounds.center.x = f32::NAN;
        }),
    ];
    for (field, edit) in edits {
        let mut broken = model.clone();
        edit(&mut broken);
        let message = refused(broken.validate(), field);
        assert!(message.contains(field), "{field}: {message}");
    }
}

#[test]
fn a_binary_model_with_bytes_after_it_is_refused() {
    let model = common::species("slender");
    let mut bytes = model.to_binary().unwrap();
    assert!(TreeModel::from_binary(&bytes).is_ok());
    bytes.extend_from_slice(&[1, 2, 3]);
    assert!(matches!(
        TreeModel::from_binary(&bytes),
        Err(TreeFileError::Header(_))
    ));
}

#[test]
fn a_stray_vertex_below_the_ground_is_no_root() {
    // A generated trunk lifted off the ground, with one vertex below it that no triangle
    // uses: the analysis used to take it for a root and then index a ring that was never
    // made.
    let species = SpeciesDesc::from_ron_str(&asset("species/slender.species.ron")).unwrap();
    let mut tree = species.generate();
    for p in &mut tree.trunk_positions {
        p.y += 10.0;
    }
    tree.trunk_positions.push(Vec3::new(0.0, -5.0, 0.0));
    tree.trunk_normals.push(Vec3::Y);
    let mesh = |positions, normals, indices| MeshData {
        positions,
        normals: Some(normals),
        indices,
        color: None,
    };
    let result = analyze(
        &mesh(
            &tree.trunk_positions,
            &tree.trunk_normals,
            &tree.trunk_indices,
        ),
        &mesh(&tree.leaf_positions, &tree.leaf_normals, &tree.leaf_indices),
        &AnalysisOptions::default(),
    );
    assert!(
        matches!(result, Err(TreeAnalysisError::NoRootRing { .. })),
        "{:?}",
        result.err()
    );
}

#[test]
fn species_that_would_grow_without_end_are_refused() {
    let level = "(length: 0.7, radius: 0.5, segments: 4, ring_vertices: 6, children: 3)";
    let levels = |n: usize| vec![level; n].join(", ");
    let species =
        |levels: String| format!("(levels: [(length: 8.0, radius: 0.3, children: 4), {levels}])");
    let message = refused(
        SpeciesDesc::from_ron_str(&species(levels(SpeciesDesc::MAX_LEVELS))),
        "17 levels",
    );
    assert!(message.contains("levels"), "{message}");
    let bushy = "(length: 0.7, radius: 0.5, segments: 16, ring_vertices: 32, children: 64)";
    let message = refused(
        SpeciesDesc::from_ron_str(&species([bushy; 4].join(", "))),
        "64⁴ branches",
    );
    assert!(message.contains("vertices"), "{message}");
}

#[test]
fn terrains_that_take_forever_or_overflow_are_refused() {
    let desc = EcosystemDesc::from_ron_str(&asset("forests/default.ecosystem.ron")).unwrap();
    let mut slow: TerrainDesc = desc.terrain.clone();
    slow.resolution = 4097;
    slow.faults.iterations = 100_000;
    let message = refused(slow.validate(), "10¹² fault updates");
    assert!(message.contains("faults.iterations"), "{message}");
    // Each finite alone, too large together.
    let mut overflow = desc.terrain.clone();
    for row in &mut overflow.control_heights {
        row.fill(TerrainDesc::MAX_EXTENT);
    }
    let (rows, columns) = (
        overflow.control_heights.len(),
        overflow.control_heights[0].len(),
    );
    overflow.weights = Some(vec![vec![1e38; columns]; rows]);
    let message = refused(overflow.build(), "overflowing heights");
    assert!(
        message.contains("weights") || message.contains("faults"),
        "{message}"
    );
}

#[test]
fn wind_numbers_out_of_range_are_refused() {
    let set = SpringSet::from_ron_str(&asset("wind/default.wind.ron")).unwrap();
    let edits: [(&str, fn(&mut SpringSet)); 4] = [
        ("max_angle", |s| s.rules[0].max_angle = f32::NAN),
        ("influence", |s| s.rules[0].influence = f32::INFINITY),
        ("wind", |s| {
            s.springs[0].wind.gusts.strength.1 = f32::INFINITY;
        }),
        ("wind.strength", |s| s.springs[0].wind.strength = 3e38),
    ];
    for (field, edit) in edits {
        let mut broken = set.clone();
        edit(&mut broken);
        let message = refused(broken.validate(), field);
        assert!(message.contains(field), "{field}: {message}");
    }
}

#[test]
fn calibrations_without_a_family_or_with_absurd_costs_are_refused() {
    let text = |edit: fn(&mut Calibration)| {
        let mut c = Calibration::default();
        edit(&mut c);
        c.to_ron_string().unwrap()
    };
    for (case, edit) in [
        ("lines", (|c| c.lines.clear()) as fn(&mut Calibration)),
        ("points", |c| c.points.clear()),
        ("triangles.per_primitive", |c| {
            c.triangles.per_primitive = 5.0;
        }),
        ("render_fixed", |c| c.render_fixed = 1e9),
    ] {
        let result = Calibration::from_ron_str(&text(edit));
        assert!(
            matches!(&result, Err(CalibrationError::Invalid(m)) if m.contains(case)),
            "{case}: {:?}",
            result.err()
        );
    }
}

#[test]
fn pixel_ranges_are_sanitized_not_trusted() {
    assert_eq!(
        PixelRange {
            min: u32::MAX,
            max: 0
        }
        .sanitized(),
        PixelRange {
            min: PixelRange::LARGEST,
            max: PixelRange::LARGEST
        }
    );
    assert_eq!(
        PixelRange { min: 0, max: 0 }.sanitized(),
        PixelRange { min: 1, max: 1 }
    );
    // A width range of four billion pixels used to loop over every width.
    let model = common::species("slender");
    let lod = trunk_lod(
        &model,
        1.0,
        40.0,
        &Projection::perspective(0.8, 540.0),
        PixelRange {
            min: 1,
            max: u32::MAX,
        },
    );
    assert!(lod.lines.iter().all(|(w, _)| *w <= PixelRange::LARGEST));
}

#[test]
fn a_large_forest_places_in_near_linear_work() {
    // 250 000 trees: the old placement scanned the grid per tree (about 10¹¹ steps here).
    let mut desc = EcosystemDesc::from_ron_str(&asset("forests/default.ecosystem.ron")).unwrap();
    desc.set_total_trees(250_000).unwrap();
    let layout = desc.layout().unwrap();
    assert_eq!(layout.instances.len(), desc.instance_count());
    assert!(
        layout
            .instances
            .iter()
            .all(|i| i.transform.translation.is_finite())
    );
}

// Mutation fuzzing of the shipped assets (see `super::fuzz`).

proptest! {
    #![proptest_config(ProptestConfig::with_cases(cases()))]

    #[test]
    fn mutated_ecosystems_load_finite_or_fail(m in prop::collection::vec(mutation(), 1..6)) {
        let text = mutate(asset("forests/default.ecosystem.ron").as_bytes(), &m);
        let Ok(text) = String::from_utf8(text) else { return Ok(()) };
        if let Ok(desc) = EcosystemDesc::from_ron_str(&text) {
            // Laid out only when small enough for a test; validation bounds the rest.
            if desc.instance_count() <= 5_000
                && desc.terrain.resolution <= 257
                && let Ok(layout) = desc.layout()
            {
                for i in &layout.instances {
                    prop_assert!(i.transform.translation.is_finite(), "{i:?}");
                    prop_assert!(i.transform.matrix3.is_finite(), "{i:?}");
                }
            }
        }
    }

    #[test]
    fn mutated_species_load_finite_or_fail(m in prop::collection::vec(mutation(), 1..6)) {
        let text = mutate(asset("species/slender.species.ron").as_bytes(), &m);
        let Ok(text) = String::from_utf8(text) else { return Ok(()) };
        if let Ok(species) = SpeciesDesc::from_ron_str(&text) {
            // Bounded by validation; analysed when the mutation kept it small.
            let tree = species.generate();
            prop_assert!(tree.trunk_positions.iter().all(|p| p.is_finite()));
            if tree.trunk_positions.len() + tree.leaf_positions.len() <= 20_000
                && let Ok(analysis) = species.generate_and_analyze()
            {
                prop_assert!(analysis.model.validate().is_ok());
            }
        }
    }

    #[test]
    fn mutated_wind_files_load_finite_or_fail(m in prop::collection::vec(mutation(), 1..6)) {
        let text = mutate(asset("wind/default.wind.ron").as_bytes(), &m);
        let Ok(text) = String::from_utf8(text) else { return Ok(()) };
        if let Ok(set) = SpringSet::from_ron_str(&text) {
            for rule in &set.rules {
                prop_assert!(rule.max_angle.is_finite() && rule.influence.is_finite());
            }
        }
    }

    #[test]
    fn mutated_calibrations_load_finite_or_fail(m in prop::collection::vec(mutation(), 1..6)) {
        let file = asset("calibration/llvmpipe-llvm-15-0-6-256-bits.calibration.ron");
        let text = mutate(file.as_bytes(), &m);
        let Ok(text) = String::from_utf8(text) else { return Ok(()) };
        if let Ok(c) = Calibration::from_ron_str(&text) {
            let costs = std::iter::once(&c.triangles).chain(&c.lines).chain(&c.points);
            for cost in costs {
                prop_assert!(cost.fixed.is_finite() && cost.per_primitive.is_finite());
            }
            prop_assert!(!c.lines.is_empty() && !c.points.is_empty());
        }
    }

    #[test]
    fn mutated_binary_models_load_valid_or_fail(m in prop::collection::vec(mutation(), 1..6)) {
        let bytes = SLENDER_BINARY.with(Clone::clone);
        let mutated = mutate(&bytes, &m);
        if let Ok(model) = TreeModel::from_binary(&mutated) {
            prop_assert!(model.validate().is_ok());
        }
    }
}

thread_local! {
    /// The slender species, analysed and saved once per test thread.
    static SLENDER_BINARY: Vec<u8> = common::species("slender").to_binary().unwrap();
}
