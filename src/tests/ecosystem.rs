//! Ecosystems: terrain, placement, and the file format's errors.

use crate::ecosystem::placement::tilt_from_normal;
use crate::ecosystem::*;
use bevy::math::Vec3;

fn shipped(name: &str) -> EcosystemDesc {
    let path = format!(
        "{}/assets/forests/{name}.ecosystem.ron",
        env!("CARGO_MANIFEST_DIR")
    );
    EcosystemDesc::from_ron_str(&std::fs::read_to_string(&path).unwrap())
        .unwrap_or_else(|e| panic!("{path}: {e}"))
}

#[test]
fn terrain_interpolates_its_corner_control_points() {
    let desc = TerrainDesc {
        size: 50.0,
        resolution: 17,
        degree: 3,
        control_heights: vec![
            vec![1.0, 5.0, 5.0, 2.0],
            vec![5.0, 9.0, 9.0, 5.0],
            vec![5.0, 9.0, 9.0, 5.0],
            vec![3.0, 5.0, 5.0, 4.0],
        ],
        ..Default::default()
    };
    let terrain = desc.build().unwrap();
    let n = terrain.resolution() - 1;
    assert!((terrain.grid_height(0, 0) - 1.0).abs() < 1e-5);
    assert!((terrain.grid_height(n, 0) - 2.0).abs() < 1e-5);
    assert!((terrain.grid_height(0, n) - 3.0).abs() < 1e-5);
    assert!((terrain.grid_height(n, n) - 4.0).abs() < 1e-5);
    assert!((terrain.height_at(50.0, 50.0) - 4.0).abs() < 1e-4);
    // Inside the convex hull of the control heights.
    assert!(
        terrain
            .mesh_positions()
            .iter()
            .all(|p| (1.0..=9.0).contains(&p.y))
    );
    // Weights pull the surface towards heavy control points.
    let mut heavy = desc.clone();
    let mut weights = vec![vec![1.0; 4]; 4];
    weights[1][1] = 10.0;
    heavy.weights = Some(weights);
    assert!(heavy.surface_height(0.3, 0.3) > desc.surface_height(0.3, 0.3));
}

#[test]
fn faults_keep_the_mesh_valid_and_heights_queryable() {
    let mut desc = shipped("default").terrain;
    desc.faults.iterations = 300;
    let terrain = desc.build().unwrap();
    let positions = terrain.mesh_positions();
    let normals = terrain.mesh_normals();
    let indices = terrain.mesh_indices();
    let n = terrain.resolution();
    assert_eq!(positions.len(), n * n);
    assert_eq!(normals.len(), n * n);
    assert_eq!(indices.len(), (n - 1) * (n - 1) * 6);
    assert!(indices.iter().all(|&i| (i as usize) < positions.len()));
    assert!(positions.iter().all(|p| p.is_finite()));
    assert!(
        normals
            .iter()
            .all(|v| v.is_finite() && v.y > 0.0 && (v.length() - 1.0).abs() < 1e-4)
    );
    // Every triangle faces up.
    for t in indices.chunks_exact(3) {
        let [a, b, c] = [0, 1, 2].map(|k| positions[t[k] as usize]);
        assert!((b - a).cross(c - a).y > 0.0);
    }
    // Queries agree with the grid at vertices, and stay finite anywhere.
    for (i, j) in [(0, 0), (5, 9), (n - 1, n - 1)] {
        let p = terrain.grid_position(i, j);
        assert!((terrain.height_at(p.x, p.z) - p.y).abs() < 1e-3);
    }
    for (x, z) in [(-10.0, 5.0), (1e6, -1e6), (33.3, 77.7)] {
        assert!(terrain.height_at(x, z).is_finite());
        assert!(terrain.normal_at(x, z).y > 0.0);
    }
}

#[test]
fn placement_keeps_counts_cells_and_terrain_and_is_deterministic() {
    for name in [
        "default",
        "trees-1000",
        "trees-2000",
        "trees-20000",
        "trees-100000",
    ] {
        let desc = shipped(name);
        let layout = desc.layout().unwrap();
        let expected: usize = desc.species.iter().map(|s| s.count as usize).sum();
        assert_eq!(layout.instances.len(), expected, "{name}");
        for (s, species) in desc.species.iter().enumerate() {
            let placed = layout.instances.iter().filter(|i| i.species == s).count();
            assert_eq!(placed, species.count as usize);
        }
        // One instance per cell: cells are g × g over the square.
        let g = (expected as f64).sqrt().ceil() as usize;
        let cell = layout.terrain.size() / g as f32;
        let mut seen = std::collections::HashSet::new();
        for inst in &layout.instances {
            let p = inst.transform.translation;
            assert!(
                p.x >= 0.0
                    && p.z >= 0.0
                    && p.x <= layout.terrain.size()
                    && p.z <= layout.terrain.size()
            );
            assert!(
                (p.y - layout.terrain.height_at(p.x, p.z)).abs() < 1e-3,
                "on the terrain"
            );
            let key = ((p.x / cell) as usize, (p.z / cell) as usize);
            assert!(seen.insert(key), "{name}: two instances in cell {key:?}");
            let s = &desc.species[inst.species];
            assert!(inst.scale >= s.scale.0 && inst.scale <= s.scale.1);
        }
        let again = desc.layout().unwrap();
        assert_eq!(again.instances, layout.instances, "deterministic");
    }
    let mut other = shipped("default");
    other.seed += 1;
    assert_ne!(
        other.layout().unwrap().instances,
        shipped("default").layout().unwrap().instances
    );
}

#[test]
fn terrain_tilt_stands_trees_along_the_normal() {
    for normal in [
        Vec3::new(0.3, 1.0, 0.0),
        Vec3::new(0.0, 1.0, -0.4),
        Vec3::new(-0.2, 1.0, 0.25),
    ] {
        let normal = normal.normalize();
        let (pitch, roll) = tilt_from_normal(normal);
        let up = Angles {
            head: 0.0,
            pitch,
            roll,
        }
        .rotation()
            * Vec3::Y;
        assert!(up.angle_between(normal) < 0.06, "{normal} → {up}");
    }
}

#[test]
fn hand_placed_instances_override_the_rules() {
    let mut desc = shipped("default");
    desc.species[0].instances.push(InstanceDesc {
        position: Some((10.0, 20.0)),
        head: Some(90.0),
        pitch: Some(0.0),
        roll: Some(0.0),
        scale: Some(2.0),
    });
    let layout = desc.layout().unwrap();
    let last = layout.instances.last().unwrap();
    assert_eq!(last.species, 0);
    assert_eq!(last.scale, 2.0);
    assert!((last.transform.translation.x - 10.0).abs() < 1e-5);
    assert!((last.transform.translation.z - 20.0).abs() < 1e-5);
}

mod malformed {
    use super::*;

    fn error(text: &str) -> String {
        EcosystemDesc::from_ron_str(text).unwrap_err().to_string()
    }

    const GOOD_TERRAIN: &str =
        "terrain: (control_heights: [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])";
    const MATERIALS: &str = r#"materials: { "bark": (), "leaf": (), "ground": () }"#;

    #[test]
    fn syntax_error_names_line_and_column() {
        let e = error("(\n  seed: 3,\n  species: [\n    (tree: \"a\", count: 3,,)\n  ],\n)");
        assert!(e.starts_with("4:"), "{e}");
    }

    #[test]
    fn unknown_field_is_named() {
        let e = error("(sede: 3)");
        assert!(e.contains("sede"), "{e}");
    }

    #[test]
    fn no_species() {
        let e = error(&format!("({MATERIALS}, {GOOD_TERRAIN})"));
        assert_eq!(e, "species: needs at least one species");
    }

    #[test]
    fn unknown_material() {
        let e = error(&format!(
            r#"({MATERIALS}, {GOOD_TERRAIN}, species: [(tree: "t", count: 1, leaf_material: "leaves")])"#
        ));
        assert!(
            e.starts_with("species[0].leaf_material: no material named \"leaves\""),
            "{e}"
        );
    }

    #[test]
    fn bad_scale_range() {
        let e = error(&format!(
            r#"({MATERIALS}, {GOOD_TERRAIN}, species: [(tree: "t", scale: (2.0, 1.0))])"#
        ));
        assert!(e.starts_with("species[0].scale:"), "{e}");
    }

    #[test]
    fn too_few_control_points_for_the_degree() {
        let e = error(&format!(
            r#"({MATERIALS}, terrain: (degree: 3, control_heights: [[0.0, 0.0], [0.0, 0.0]]), species: [(tree: "t")])"#
        ));
        assert!(
            e.starts_with("terrain.control_heights: needs at least degree + 1 = 4"),
            "{e}"
        );
    }

    #[test]
    fn ragged_control_grid() {
        let e = error(&format!(
            r#"({MATERIALS}, terrain: (degree: 1, control_heights: [[0.0, 0.0], [0.0]]), species: [(tree: "t")])"#
        ));
        assert!(e.contains("row 1 has a different length"), "{e}");
    }

    #[test]
    fn bad_knots() {
        let e = error(&format!(
            r#"({MATERIALS}, terrain: (degree: 1, control_heights: [[0.0, 0.0], [0.0, 0.0]], knots_x: [0.0, 1.0, 0.5, 1.0]), species: [(tree: "t")])"#
        ));
        assert_eq!(e, "terrain.knots_x: must be finite and non-decreasing");
    }

    #[test]
    fn hand_placed_instance_with_bad_scale() {
        let e = error(&format!(
            r#"({MATERIALS}, {GOOD_TERRAIN}, species: [(tree: "t", instances: [(scale: Some(-1.0))])])"#
        ));
        assert_eq!(
            e,
            "species[0].instances[0].scale: must be positive, at most 1000"
        );
    }

    #[test]
    fn two_hand_placed_trees_in_one_place() {
        let e = error(&format!(
            r#"({MATERIALS}, {GOOD_TERRAIN}, species: [
                (tree: "t", instances: [(position: (3.0, 4.0)), (position: (9.0, 9.0))]),
                (tree: "u", instances: [(position: (5.0, 5.0)), (position: (3.004, 4.0))]),
            ])"#
        ));
        // The later entry is named, with its own position (it sorts after the first).
        assert_eq!(
            e,
            "species[1].instances[1].position: (3.004, 4) is within 0.01 m of \
             species[0].instances[0] at (3, 4): two trees in one place"
        );
        // A few centimetres apart is a choice, not a typing slip.
        let ok = EcosystemDesc::from_ron_str(&format!(
            r#"({MATERIALS}, {GOOD_TERRAIN}, species: [
                (tree: "t", instances: [(position: (3.0, 4.0)), (position: (3.02, 4.0))]),
            ])"#
        ));
        assert!(ok.is_ok(), "{ok:?}");
    }
}

#[test]
fn a_new_total_keeps_the_species_proportions_and_the_density() {
    let original = shipped("default");
    let before: u32 = original.species.iter().map(|s| s.count).sum();
    for total in [0, 1, 61, 1000, 2000] {
        let mut desc = original.clone();
        desc.set_total_trees(total).unwrap();
        let counts: Vec<u32> = desc.species.iter().map(|s| s.count).collect();
        assert_eq!(counts.iter().sum::<u32>(), total);
        for (s, o) in desc.species.iter().zip(&original.species) {
            let wanted = f64::from(o.count) * f64::from(total) / f64::from(before);
            assert!(
                (f64::from(s.count) - wanted).abs() <= desc.species.len() as f64,
                "{counts:?}"
            );
        }
        let density = |d: &EcosystemDesc, n: u32| n as f32 / (d.terrain.size * d.terrain.size);
        if total > 0 {
            assert!((density(&desc, total) / density(&original, before) - 1.0).abs() < 1e-4);
        } else {
            assert_eq!(desc.terrain.size, original.terrain.size);
        }
    }
}

#[test]
fn counts_that_are_all_zero_cannot_be_scaled() {
    let mut desc = shipped("default");
    for s in &mut desc.species {
        s.count = 0;
    }
    let before = desc.clone();
    let e = desc.set_total_trees(500).unwrap_err().to_string();
    assert!(
        e.starts_with("species[..].count: every species places 0 trees: cannot be scaled to 500"),
        "{e}"
    );
    assert_eq!(desc, before, "a refused total changed the description");
}
