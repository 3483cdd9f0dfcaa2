//! Moving a tree's rings with springs.

use crate::testing as common;

use crate::tree::TreeModel;
use crate::wind::*;
use bevy::math::{Quat, Vec3, Vec3A};

fn model() -> TreeModel {
    common::species("broad")
}

/// Thick rings follow spring 0 at 50%, thin ones spring 1 at 90%.
fn rules() -> Vec<AssociationRule> {
    vec![
        AssociationRule {
            spring: 0,
            min_diameter: 0.15,
            influence: 0.5,
            max_angle: 8.0,
            ..Default::default()
        },
        AssociationRule {
            spring: 1,
            influence: 0.9,
            max_angle: 25.0,
            ..Default::default()
        },
    ]
}

#[test]
fn rings_associate_by_rule_and_the_root_never_does() {
    let m = model();
    let motions = associate(&m, &rules(), 2);
    for (ring, motion) in m.rings.iter().zip(&motions) {
        if ring.is_root() {
            assert_eq!(motion.spring, None);
        } else if ring.diameter >= 0.15 {
            assert_eq!(motion.spring, Some(0));
        } else {
            assert_eq!(motion.spring, Some(1));
        }
    }
    // Each root's first child starts motion; nothing below a moving ring does.
    for (r, ring) in m.rings.iter().enumerate() {
        if motions[r].start_of_motion {
            assert!(m.rings[ring.parent as usize].is_root());
        }
    }
    // Rules naming springs the set lacks are ignored.
    assert!(
        associate(&m, &rules(), 0)
            .iter()
            .all(|x| x.spring.is_none())
    );
}

#[test]
fn root_stays_lengths_are_kept_and_angles_limited() {
    let m = model();
    let motions = associate(&m, &rules(), 2);
    let mut offsets = Vec::new();
    for springs in [
        [Vec3::new(3.0, 0.0, 1.0), Vec3::new(-2.0, 1.0, 4.0)],
        [Vec3::ZERO, Vec3::new(0.0, 0.0, 50.0)],
    ] {
        ring_offsets(
            &WindRig::new(&m, &motions),
            &springs,
            Quat::IDENTITY,
            1.0,
            0.0,
            &mut offsets,
        );
        for (r, ring) in m.rings.iter().enumerate() {
            if ring.is_root() {
                assert_eq!(offsets[r], Vec3A::ZERO);
                continue;
            }
            let p = ring.parent as usize;
            let rest = ring.center - m.rings[p].center;
            let moved = (ring.center + Vec3::from(offsets[r]))
                - (m.rings[p].center + Vec3::from(offsets[p]));
            assert!(
                (moved.length() - rest.length()).abs() <= 0.01 * rest.length() + 1e-5,
                "ring {r}"
            );
            if rest.length() > 1e-4 {
                let limit = motions[r].max_angle + 1e-3;
                assert!(
                    rest.angle_between(moved) <= limit,
                    "ring {r}: {} > {limit}",
                    rest.angle_between(moved)
                );
            }
        }
        assert!(offsets.iter().any(|o| o.length() > 0.05), "something moves");
    }
}

#[test]
fn every_tree_bends_the_same_world_direction() {
    let m = model();
    let motions = associate(&m, &rules(), 2);
    let wind = [Vec3::new(2.0, 0.0, 0.0), Vec3::new(4.0, 0.0, 0.0)];
    let tip = m
        .rings
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.center.y.total_cmp(&b.1.center.y))
        .unwrap()
        .0;
    for head in [0.0_f32, 90.0, 200.0] {
        let rotation = Quat::from_rotation_y(head.to_radians());
        let mut offsets = Vec::new();
        ring_offsets(
            &WindRig::new(&m, &motions),
            &wind,
            rotation,
            1.3,
            0.0,
            &mut offsets,
        );
        let world = rotation * offsets[tip];
        assert!(
            world.x > 0.0 && world.x > 3.0 * world.z.abs(),
            "head {head}: {world}"
        );
    }
}

#[test]
fn small_movements_accumulate_until_they_show() {
    let m = model();
    let motions = associate(&m, &rules(), 2);
    let wind = [Vec3::new(0.05, 0.0, 0.0), Vec3::new(0.05, 0.0, 0.0)];
    // Rings that move relative to their parent (not just carried along).
    let moving = |o: &[Vec3A]| {
        m.rings
            .iter()
            .enumerate()
            .filter(|(r, ring)| {
                !ring.is_root() && (o[*r] - o[ring.parent as usize]).length() > 1e-6
            })
            .count()
    };
    let rig = WindRig::new(&m, &motions);
    let (mut exact, mut thresholded, mut nothing) = (Vec::new(), Vec::new(), Vec::new());
    ring_offsets(&rig, &wind, Quat::IDENTITY, 1.0, 0.0, &mut exact);
    ring_offsets(&rig, &wind, Quat::IDENTITY, 1.0, 0.05, &mut thresholded);
    ring_offsets(&rig, &wind, Quat::IDENTITY, 1.0, 1e9, &mut nothing);
    assert!(
        moving(&thresholded) < moving(&exact),
        "{} vs {}",
        moving(&thresholded),
        moving(&exact)
    );
    assert!(
        moving(&thresholded) > 0,
        "accumulated movement shows further out"
    );
    assert_eq!(moving(&nothing), 0);
    assert!(nothing.iter().all(|o| *o == Vec3A::ZERO));
}

#[test]
fn moved_bounds_follow_the_rings() {
    let m = model();
    let motions = associate(&m, &rules(), 2);
    let mut offsets = Vec::new();
    let rig = WindRig::new(&m, &motions);
    ring_offsets(
        &rig,
        &[Vec3::new(5.0, 0.0, 0.0); 2],
        Quat::IDENTITY,
        1.0,
        0.0,
        &mut offsets,
    );
    let mut shape = crate::culling::CullShape::from(&m);
    moved_bounds(&rig, &offsets, &mut shape);
    // Every vertex where the GPU puts it: trunk vertices with their ring, leaf vertices
    // with their group's ring.
    for (p, &ring) in m.trunk_positions.iter().zip(&m.trunk_vertex_ring) {
        let moved = *p + Vec3::from(offsets[ring as usize]);
        assert!(shape.trunk.contains(moved, 1e-3), "trunk vertex {moved}");
        assert!(shape.bounds.contains(moved, 1e-3));
    }
    for (p, &leaf) in m.leaf_positions.iter().zip(&m.leaf_vertex_leaf) {
        let g = m.leaves[leaf as usize].group as usize;
        let moved = *p + Vec3::from(offsets[m.leaf_groups[g].ring as usize]);
        let sphere = shape.groups[g];
        assert!(
            sphere.center.distance(moved) <= sphere.radius * 1.001 + 1e-4,
            "leaf vertex {moved} outside its group's moved sphere"
        );
        assert!(shape.bounds.contains(moved, 1e-3));
    }
    assert!(
        shape.trunk.max.x > m.trunk_bounds.max.x,
        "the crown leans with the wind"
    );
}

#[test]
fn shipped_spring_set_loads_and_bad_ones_are_refused() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/wind/default.wind.ron");
    let set = SpringSet::from_ron_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    assert_eq!(set.springs.len(), 3);
    let m = model();
    let motions = associate(&m, &set.rules, set.springs.len());
    assert!(motions.iter().filter(|x| x.spring.is_some()).count() > m.rings.len() / 2);

    let error = |text: &str| SpringSet::from_ron_str(text).unwrap_err().to_string();
    assert!(
        error("(time_step: 0.01, springs: [(stiffness: 1e6)])")
            .starts_with("springs[0].stiffness: too stiff")
    );
    assert_eq!(
        error("(springs: [(damping: 1.5)])"),
        "springs[0].damping: must be in (0, 1]: the velocity kept per step"
    );
    assert_eq!(
        error("(springs: [()], rules: [(spring: 3)])"),
        "rules[0].spring: there are only 1 springs"
    );
    assert!(error("(springz: [])").contains("springz"));
    assert_eq!(error("(springs: [])"), "springs: needs at least one spring");
}

#[test]
fn the_rig_reach_bounds_how_far_any_ring_moves() {
    let m = model();
    let rig = WindRig::new(&m, &associate(&m, &rules(), 2));
    assert!(rig.reach() > 1.0, "several moving rings on a path");
    let mut offsets = Vec::new();
    for push in [
        Vec3::new(0.01, 0.0, 0.0),
        Vec3::new(0.0, 0.0, -0.02),
        Vec3::new(0.01, 0.01, 0.005),
    ] {
        ring_offsets(&rig, &[push; 2], Quat::IDENTITY, 1.0, 0.0, &mut offsets);
        let farthest = offsets.iter().map(|o| o.length()).fold(0.0, f32::max);
        let bound = rig.reach() * push.length();
        assert!(farthest <= 1.05 * bound, "{farthest} > {bound}");
        // Not a loose bound either for a sideways push: motion LOD would keep moving
        // trees whose motion cannot be seen.
        if push.y == 0.0 {
            assert!(farthest >= bound / 3.0, "{farthest} ≪ {bound}");
        }
    }
}

#[test]
fn a_tree_twice_as_large_responds_as_to_half_the_wind() {
    let m = model();
    let rig = WindRig::new(&m, &associate(&m, &rules(), 2));
    let wind = Vec3::new(0.3, 0.0, 0.1);
    let rotation = Quat::from_rotation_y(0.7);
    let (mut large, mut half) = (Vec::new(), Vec::new());
    ring_offsets(&rig, &[wind; 2], rotation, 2.0, 0.0, &mut large);
    ring_offsets(&rig, &[wind / 2.0; 2], rotation, 1.0, 0.0, &mut half);
    assert!(large.iter().any(|o| o.length() > 1e-3), "something moves");
    for (r, (a, b)) in large.iter().zip(&half).enumerate() {
        assert!((*a - *b).length() <= 1e-5, "ring {r}: {a} vs {b}");
    }
}

#[test]
fn update_interval_halves_the_rate_as_the_motion_halves() {
    use crate::wind::update_interval;
    // Full rate from 8 px, at most every 8th frame.
    let at = |px: f32| update_interval(px, 8.0, 8);
    assert_eq!(at(100.0), 1);
    assert_eq!(at(8.0), 1);
    assert_eq!(at(5.0), 1);
    assert_eq!(at(4.0), 2);
    assert_eq!(at(2.5), 2);
    assert_eq!(at(2.0), 4);
    assert_eq!(at(1.0), 8);
    assert_eq!(at(0.01), 8);
    assert_eq!(at(0.0), 8);
    // The limit is rounded down to a power of two; off and nonsense mean every frame.
    assert_eq!(update_interval(0.01, 8.0, 6), 4);
    assert_eq!(update_interval(0.01, 8.0, 0), 1);
    assert_eq!(update_interval(0.01, 0.0, 8), 1);
    assert_eq!(update_interval(0.01, -3.0, 8), 1);
    assert_eq!(update_interval(f32::NAN, 8.0, 8), 1);
    assert_eq!(update_interval(f32::INFINITY, 8.0, 8), 1);
    assert_eq!(update_interval(1.0, f32::NAN, 8), 1);
}

/// Every ring of a tree drawn with its bin's representative offsets lands within the
/// tolerance (in pixels) of where its own offsets put it, for headings, tilts, sizes,
/// motions and spring displacements across their ranges — strong gusts included.
#[test]
fn a_borrowed_sway_stays_within_the_tolerance_of_the_tree_s_own() {
    let model = model();
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/wind/default.wind.ron");
    let set = SpringSet::from_ron_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    let rig = WindRig::new(&model, &associate(&model, &set.rules, set.springs.len()));
    let mut rng = crate::rng::SplitMix64::new(7);
    let mut range = |lo: f32, hi: f32| lo + (hi - lo) * rng.unit();
    let (mut own, mut borrowed) = (Vec::new(), Vec::new());
    let mut shared = 0;
    for case in 0..400 {
        let rotation = Quat::from_rotation_x(range(-0.08, 0.08))
            * Quat::from_rotation_z(range(-0.08, 0.08))
            * Quat::from_rotation_y(range(-4.0, 4.0));
        let scale = range(0.6, 1.4);
        let strength = range(0.02, 1.5);
        let springs: Vec<Vec3> = (0..set.springs.len())
            .map(|_| Vec3::new(range(-1.0, 1.0), range(-0.2, 0.2), range(-1.0, 1.0)) * strength)
            .collect();
        let largest = springs.iter().map(|d| d.length()).fold(0.0, f32::max);
        let motion_pixels = range(0.3, 6.0);
        let tolerance = 0.5;
        let Some((sway, error_pixels)) = shared_sway(rotation, scale, motion_pixels, tolerance)
        else {
            continue;
        };
        shared += 1;
        ring_offsets(&rig, &springs, rotation, scale, 0.0, &mut own);
        ring_offsets(
            &rig,
            &springs,
            sway.rotation,
            sway.scale,
            0.0,
            &mut borrowed,
        );
        // World units to pixels, as the motion level of detail measures it.
        let pixels_per_unit = motion_pixels / (largest * rig.reach());
        let worst = own
            .iter()
            .zip(&borrowed)
            .map(|(a, b)| (rotation * Vec3::from(*a - *b)).length() * scale)
            .fold(0.0, f32::max)
            * pixels_per_unit;
        assert!(
            worst <= error_pixels * 1.001 && error_pixels <= tolerance,
            "case {case}: {worst} px off (bound {} px)",
            error_pixels
        );
    }
    assert!(shared > 100, "{shared} of 400 cases shared");
}
