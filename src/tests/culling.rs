//! Box-hierarchy culling against brute force on random views.

use crate::culling::*;
use crate::tree::{BoundingSphere, Bounds};
use bevy::math::{Affine3A, Mat4, Quat, Vec3};
use proptest::prelude::*;

fn shapes() -> Vec<CullShape> {
    let tree = |h: f32, groups: usize| CullShape {
        bounds: Bounds {
            min: Vec3::new(-2.0, -0.2, -2.0),
            max: Vec3::new(2.0, h, 2.0),
        },
        trunk: Bounds {
            min: Vec3::new(-0.3, -0.2, -0.3),
            max: Vec3::new(0.3, h * 0.8, 0.3),
        },
        groups: (0..groups)
            .map(|g| {
                let a = g as f32 * 2.4;
                BoundingSphere {
                    center: Vec3::new(1.4 * a.cos(), h * 0.7, 1.4 * a.sin()),
                    radius: 0.5,
                }
            })
            .collect(),
    };
    vec![tree(6.0, 12), tree(9.0, 70), tree(4.0, 3)]
}

/// A jittered grid of `n` instances over a `size` × `size` square.
fn forest(n: usize, size: f32, seed: u64) -> Vec<CullInstance> {
    let mut s = seed;
    let mut rnd = move || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (s >> 40) as f32 / (1u64 << 24) as f32
    };
    let side = (n as f32).sqrt().ceil() as usize;
    (0..n)
        .map(|i| {
            let (x, z) = ((i % side) as f32, (i / side) as f32);
            let p = Vec3::new(
                (x + rnd()) / side as f32 * size,
                rnd() * 3.0,
                (z + rnd()) / side as f32 * size,
            );
            let transform = Affine3A::from_scale_rotation_translation(
                Vec3::splat(0.7 + 0.6 * rnd()),
                Quat::from_rotation_y(rnd() * core::f32::consts::TAU)
                    * Quat::from_rotation_x(0.1 * (rnd() - 0.5)),
                p,
            );
            CullInstance {
                transform,
                shape: (i % 3) as u32,
            }
        })
        .collect()
}

fn view(eye: Vec3, target: Vec3, fov: f32, far: Option<f32>) -> FrustumPlanes {
    let view = Mat4::look_at_rh(eye, target, Vec3::Y);
    let projection = match far {
        // Bevy's default: reverse-Z, infinite far plane.
        None => Mat4::perspective_infinite_reverse_rh(fov, 16.0 / 9.0, 0.1),
        Some(far) => Mat4::perspective_rh(fov, 16.0 / 9.0, 0.1, far),
    };
    FrustumPlanes::from_clip_from_world(projection * view)
}

fn area(size: f32) -> Bounds {
    Bounds {
        min: Vec3::ZERO,
        max: Vec3::new(size, 10.0, size),
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn hierarchy_equals_brute_force(
        seed in 0_u64..1000,
        depth in 0_u32..6,
        eye in (0_i32..400, 1_i32..60, 0_i32..400),
        target in (0_i32..400, 0_i32..10, 0_i32..400),
        fov in 20_i32..100,
        far in prop::option::of(20_i32..300),
    ) {
        let shapes = shapes();
        let instances = forest(900, 400.0, seed);
        let eye = Vec3::new(eye.0 as f32, eye.1 as f32, eye.2 as f32);
        let target = Vec3::new(target.0 as f32 + 0.5, target.1 as f32, target.2 as f32 + 0.5);
        let planes = view(eye, target, (fov as f32).to_radians(), far.map(|f| f as f32));
        let mut hierarchy = BoxHierarchy::build(depth, &area(400.0), &instances, &shapes);
        // Every fifth instance swayed: its groups moved within its box at rest (where the
        // hierarchy's boxes still hold them, so both must agree).
        let mut moved = MovedShapes::default();
        for i in (0..instances.len()).step_by(5) {
            let rest = &shapes[instances[i].shape as usize];
            let shape = moved.shape_mut(i);
            *shape = rest.clone();
            for (g, sphere) in shape.groups.iter_mut().enumerate() {
                let lean = Vec3::new(0.3 * (g as f32 + seed as f32).sin(), 0.0, 0.3);
                sphere.center = (sphere.center + lean).clamp(
                    rest.bounds.min + sphere.radius,
                    rest.bounds.max - sphere.radius,
                );
            }
        }
        let (mut fast, mut slow) = (CullResult::default(), CullResult::default());
        hierarchy.cull(&planes, &instances, &shapes, &moved, &mut fast);
        cull_brute_force(&planes, &instances, &shapes, &moved, &mut slow);
        for i in 0..instances.len() {
            let shape = moved.get(i).unwrap_or(&shapes[instances[i].shape as usize]);
            prop_assert_eq!(fast.trunk_visible(i), slow.trunk_visible(i), "instance {}", i);
            for g in 0..shape.groups.len() {
                prop_assert_eq!(fast.group_visible(i, g), slow.group_visible(i, g));
            }
            // Fully visible means the whole box is inside the view.
            if fast.visibility[i] == InstanceVisibility::Full {
                let b = transform_bounds(&instances[i].transform, &shape.bounds);
                prop_assert_eq!(planes.classify_box(&b), Containment::Inside);
            }
        }
    }

    #[test]
    fn a_refitted_hierarchy_culls_like_a_new_one(
        seed in 0_u64..1000,
        depth in 1_u32..6,
        eye in (0_i32..400, 1_i32..60, 0_i32..400),
        target in (0_i32..400, 0_i32..10, 0_i32..400),
        step in (-30_i32..30, -5_i32..5, -30_i32..30),
    ) {
        let shapes = shapes();
        let mut instances = forest(900, 400.0, seed);
        let eye = Vec3::new(eye.0 as f32, eye.1 as f32, eye.2 as f32);
        let target = Vec3::new(target.0 as f32 + 0.5, target.1 as f32, target.2 as f32 + 0.5);
        let planes = view(eye, target, 1.0, None);
        let mut refitted = BoxHierarchy::build(depth, &area(400.0), &instances, &shapes);
        // Every seventh instance steps (up to 3 m, and turns): most stay in their cell.
        let step = Vec3::new(step.0 as f32, step.1 as f32, step.2 as f32) * 0.1;
        let moved: Vec<u32> = (0..instances.len() as u32).step_by(7).collect();
        for &i in &moved {
            let t = &mut instances[i as usize].transform;
            *t = Affine3A::from_translation(step) * *t * Affine3A::from_rotation_y(0.3);
        }
        let still = MovedShapes::default();
        let (mut fast, mut fresh, mut slow) =
            (CullResult::default(), CullResult::default(), CullResult::default());
        if refitted.refit(&moved, &instances, &shapes) {
            refitted.cull(&planes, &instances, &shapes, &still, &mut fast);
        } else {
            // Some instance left its cell: refit refuses, and the caller builds anew.
            refitted = BoxHierarchy::build(depth, &area(400.0), &instances, &shapes);
            refitted.cull(&planes, &instances, &shapes, &still, &mut fast);
        }
        let mut rebuilt = BoxHierarchy::build(depth, &area(400.0), &instances, &shapes);
        // Every box, not only the ones this view tests, is what a new hierarchy has.
        let boxes = |h: &BoxHierarchy| h.nodes().map(|(b, _)| b).collect::<Vec<_>>();
        prop_assert_eq!(boxes(&refitted), boxes(&rebuilt));
        rebuilt.cull(&planes, &instances, &shapes, &still, &mut fresh);
        cull_brute_force(&planes, &instances, &shapes, &still, &mut slow);
        prop_assert_eq!(&fast.visibility, &fresh.visibility);
        for i in 0..instances.len() {
            prop_assert_eq!(fast.trunk_visible(i), slow.trunk_visible(i), "instance {}", i);
        }
    }
}

#[test]
fn a_step_within_a_cell_is_refitted_and_one_across_is_refused() {
    let shapes = shapes();
    let mut instances = forest(100, 100.0, 7);
    let mut hierarchy = BoxHierarchy::build(2, &area(100.0), &instances, &shapes);
    // Cells are 25 m wide; instance 0 stands in the first one.
    let at = Vec3::from(instances[0].transform.translation);
    instances[0].transform.translation = Vec3::new(12.5, at.y, 12.5).into();
    assert!(hierarchy.refit(&[0], &instances, &shapes));
    instances[0].transform.translation = Vec3::new(80.0, at.y, 80.0).into();
    assert!(!hierarchy.refit(&[0], &instances, &shapes));
}

#[test]
fn looking_away_sees_nothing_and_from_above_sees_everything() {
    let shapes = shapes();
    let instances = forest(400, 100.0, 7);
    let mut hierarchy = BoxHierarchy::build(3, &area(100.0), &instances, &shapes);
    let mut result = CullResult::default();
    let away = view(
        Vec3::new(-50.0, 5.0, -50.0),
        Vec3::new(-100.0, 5.0, -100.0),
        1.0,
        None,
    );
    hierarchy.cull(
        &away,
        &instances,
        &shapes,
        &MovedShapes::default(),
        &mut result,
    );
    assert!(
        result
            .visibility
            .iter()
            .all(|v| *v == InstanceVisibility::Invisible)
    );
    let above = view(
        Vec3::new(50.0, 400.0, 50.01),
        Vec3::new(50.0, 0.0, 50.0),
        1.2,
        None,
    );
    hierarchy.cull(
        &above,
        &instances,
        &shapes,
        &MovedShapes::default(),
        &mut result,
    );
    assert!(
        result
            .visibility
            .iter()
            .all(|v| *v == InstanceVisibility::Full)
    );
    assert!(hierarchy.nodes().any(|(_, v)| v == NodeVisibility::Full));
}

#[test]
fn empty_cells_are_invalid_and_skipped() {
    let shapes = shapes();
    // All instances in one corner: most cells are empty.
    let instances: Vec<CullInstance> = forest(50, 10.0, 3);
    let hierarchy = BoxHierarchy::build(4, &area(400.0), &instances, &shapes);
    let valid = hierarchy.nodes().count();
    assert!(
        valid < 20,
        "{valid} valid nodes out of {}",
        (4usize.pow(5) - 1) / 3
    );
    let total: u32 = hierarchy.leaf_ranges().map(|r| r.end - r.start).sum();
    assert_eq!(total, 50);
}

#[test]
fn a_swayed_tree_is_tested_where_it_moved() {
    // Looking along +Z from the origin; a tree on the left edge of the view whose single
    // leaf group lies outside at rest and leans into view in the wind.
    let planes = view(Vec3::ZERO, Vec3::new(0.0, 0.0, 10.0), 1.0, None);
    let rest = CullShape {
        bounds: Bounds {
            min: Vec3::new(-2.0, -1.0, -2.0),
            max: Vec3::new(4.0, 1.0, 2.0),
        },
        trunk: Bounds {
            min: Vec3::new(-0.2, -1.0, -0.2),
            max: Vec3::new(0.2, 1.0, 0.2),
        },
        groups: vec![BoundingSphere {
            center: Vec3::new(3.0, 0.0, 0.0),
            radius: 0.5,
        }],
    };
    // x = +z·tan(0.5·fov·aspect) is the left edge at depth z: put the trunk just inside.
    let edge = 10.0 * (0.5_f32 * 1.0).tan() * 16.0 / 9.0;
    let instances = [CullInstance {
        transform: Affine3A::from_translation(Vec3::new(edge - 0.5, 0.0, 10.0)),
        shape: 0,
    }];
    let shapes = [rest.clone()];
    let mut hierarchy = BoxHierarchy::build(0, &area(20.0), &instances, &shapes);
    let mut result = CullResult::default();
    hierarchy.cull(
        &planes,
        &instances,
        &shapes,
        &MovedShapes::default(),
        &mut result,
    );
    assert!(result.trunk_visible(0));
    assert!(!result.group_visible(0, 0), "the group is outside at rest");

    let mut moved = MovedShapes::default();
    let shape = moved.shape_mut(0);
    *shape = rest;
    shape.groups[0].center = Vec3::new(-1.0, 0.0, 0.0);
    hierarchy.cull(&planes, &instances, &shapes, &moved, &mut result);
    assert!(result.group_visible(0, 0), "the swayed group is in view");
    let mut reference = CullResult::default();
    cull_brute_force(&planes, &instances, &shapes, &moved, &mut reference);
    assert_eq!(result, reference);
    assert_eq!(moved.len(), 1);
    moved.clear();
    assert!(moved.is_empty() && moved.get(0).is_none());
}

/// A shape told apart from the others by `tag`.
fn shape_of(tag: usize) -> CullShape {
    CullShape {
        bounds: Bounds {
            min: Vec3::splat(tag as f32),
            max: Vec3::splat(tag as f32 + 1.0),
        },
        trunk: Bounds::EMPTY,
        groups: Vec::new(),
    }
}

#[test]
fn moved_shapes_keep_the_right_shape_per_instance_through_removals() {
    let mut moved = MovedShapes::default();
    let mut expected: Vec<bool> = vec![false; 12];
    // A fixed interleaving of writes and removals, including removing the absent.
    for step in 0..200_usize {
        let i = (step * 7 + step / 5) % 12;
        if step % 3 == 0 {
            moved.remove(i);
            expected[i] = false;
        } else {
            *moved.shape_mut(i) = shape_of(i);
            expected[i] = true;
        }
        moved.remove(40); // never written
        for (j, &has) in expected.iter().enumerate() {
            assert_eq!(
                moved.get(j).cloned(),
                has.then(|| shape_of(j)),
                "step {step}"
            );
        }
        assert_eq!(moved.len(), expected.iter().filter(|h| **h).count());
    }
}

#[test]
fn shared_and_own_moved_shapes_follow_their_instances_through_removals() {
    // What each instance should read: its own shape's tag, a shared shape's (100 + k), or
    // nothing.
    let mut moved = MovedShapes::default();
    for k in 0..3 {
        *moved.shared_mut(k) = shape_of(100 + k);
    }
    let mut expected: Vec<Option<usize>> = vec![None; 12];
    // A seeded random interleaving of every operation on every instance.
    let mut rng = crate::rng::SplitMix64::new(3);
    for step in 0..2_000_usize {
        let i = rng.next_u64() as usize % expected.len();
        match rng.next_u64() % 5 {
            0 => {
                moved.remove(i);
                expected[i] = None;
            }
            1 | 2 => {
                *moved.shape_mut(i) = shape_of(i);
                expected[i] = Some(i);
            }
            3 => {
                moved.share(i, step % 3);
                expected[i] = Some(100 + step % 3);
            }
            _ => {
                // The last instance takes `i`'s place, its shape (own or shared) with it;
                // an own shape keeps its tag, so re-tag it by the new index.
                let n = expected.len();
                moved.swap_remove(i, n);
                expected.swap_remove(i);
                if let Some(Some(tag)) = expected.get(i).copied().map(|t| t.filter(|t| *t < 100)) {
                    assert_eq!(moved.get(i).cloned(), Some(shape_of(tag)), "step {step}");
                    *moved.shape_mut(i) = shape_of(i);
                    expected[i] = Some(i);
                }
                expected.push(None);
            }
        }
        for (j, &tag) in expected.iter().enumerate() {
            assert_eq!(
                moved.get(j).cloned(),
                tag.map(shape_of),
                "step {step}, instance {j}"
            );
        }
        let own = expected.iter().flatten().filter(|t| **t < 100).count();
        assert_eq!(moved.len(), own, "step {step}");
    }
}
