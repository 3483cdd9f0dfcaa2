//! Box-hierarchy culling of 100 000 instances against brute force, at several depths.
//! Goal (release, one core): under 1 ms per frame. `cargo bench --bench culling`.

use std::hint::black_box;
use std::time::Duration;

use bevy::math::{Affine3A, Mat4, Quat, Vec3};
use bevy_sherwood::culling::*;
use bevy_sherwood::tree::{BoundingSphere, Bounds};
use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};

const SIZE: f32 = 2000.0;

fn shapes() -> Vec<CullShape> {
    [(6.0, 12), (8.0, 21), (9.0, 24)]
        .iter()
        .map(|&(h, groups)| CullShape {
            bounds: Bounds {
                min: Vec3::new(-3.0, -0.1, -3.0),
                max: Vec3::new(3.0, h, 3.0),
            },
            trunk: Bounds {
                min: Vec3::new(-0.3, -0.1, -0.3),
                max: Vec3::new(0.3, h * 0.8, 0.3),
            },
            groups: (0..groups)
                .map(|g| {
                    let a = g as f32 * 2.4;
                    BoundingSphere {
                        center: Vec3::new(2.0 * a.cos(), h * 0.7, 2.0 * a.sin()),
                        radius: 0.6,
                    }
                })
                .collect(),
        })
        .collect()
}

fn forest(n: usize) -> Vec<CullInstance> {
    let side = (n as f32).sqrt().ceil() as usize;
    let mut s = 12345_u64;
    let mut rnd = move || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (s >> 40) as f32 / (1u64 << 24) as f32
    };
    (0..n)
        .map(|i| {
            let (x, z) = ((i % side) as f32 + rnd(), (i / side) as f32 + rnd());
            CullInstance {
                transform: Affine3A::from_scale_rotation_translation(
                    Vec3::splat(0.8 + 0.4 * rnd()),
                    Quat::from_rotation_y(rnd() * 6.0),
                    Vec3::new(x / side as f32 * SIZE, 0.0, z / side as f32 * SIZE),
                ),
                shape: (i % 3) as u32,
            }
        })
        .collect()
}

fn culling(c: &mut Criterion) {
    let shapes = shapes();
    let instances = forest(100_000);
    // Standing at the forest's edge, looking across it (Bevy's reverse-Z infinite projection).
    let view = Mat4::perspective_infinite_reverse_rh(1.0, 16.0 / 9.0, 0.1)
        * Mat4::look_at_rh(
            Vec3::new(-50.0, 30.0, SIZE / 2.0),
            Vec3::new(SIZE, 0.0, SIZE * 0.6),
            Vec3::Y,
        );
    let planes = FrustumPlanes::from_clip_from_world(view);
    let none = MovedShapes::default();
    let area = Bounds {
        min: Vec3::ZERO,
        max: Vec3::new(SIZE, 10.0, SIZE),
    };
    let mut result = CullResult::default();
    let mut group = c.benchmark_group("cull_100k");
    group.measurement_time(Duration::from_secs(3));
    group.bench_function("brute_force", |b| {
        b.iter(|| cull_brute_force(&planes, &instances, &shapes, &none, black_box(&mut result)));
    });
    for depth in [3, 4, 5, 6, 7] {
        let mut hierarchy = BoxHierarchy::build(depth, &area, &instances, &shapes);
        hierarchy.cull(&planes, &instances, &shapes, &none, &mut result);
        let visible = result
            .visibility
            .iter()
            .filter(|v| **v != InstanceVisibility::Invisible)
            .count();
        println!("depth {depth}: {visible} of 100000 instances visible");
        group.bench_with_input(BenchmarkId::new("hierarchy", depth), &depth, |b, _| {
            b.iter(|| hierarchy.cull(&planes, &instances, &shapes, &none, black_box(&mut result)));
        });
    }
    group.finish();
}

criterion_group!(benches, culling);
criterion_main!(benches);
