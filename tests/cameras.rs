//! Which camera the budget follows, on the real renderer: inactive cameras, render-to-
//! texture cameras, an orthographic camera, a marked camera and a minimap kept off the
//! forest's layer. No arrangement may leave the main view's forest blank or culled for
//! another camera. Run with `cargo test --features gpu-tests`.
#![cfg(feature = "gpu-tests")]

use bevy_sherwood::testing as common;
use bevy_sherwood::testing as windowless;

use std::sync::Mutex;

use bevy::camera::RenderTarget;
use bevy::camera::visibility::RenderLayers;
use bevy::log::LogPlugin;
use bevy::prelude::*;
use bevy::render::render_resource::TextureFormat;
use bevy_sherwood::cost::{CalibrationChoice, CostSettings};
use bevy_sherwood::prelude::*;

/// One app at a time: each renders on the same two cores.
static SERIAL: Mutex<()> = Mutex::new(());

/// The main camera's eye and target in a forest of side `size`.
fn main_pose(size: f32) -> Transform {
    Transform::from_xyz(0.1 * size, 15.0, 0.1 * size)
        .looking_at(Vec3::new(0.6 * size, 0.0, 0.6 * size), Vec3::Y)
}

/// Looking out of the forest, at nothing.
fn away_pose(size: f32) -> Transform {
    Transform::from_xyz(0.1 * size, 15.0, 0.1 * size)
        .looking_at(Vec3::new(-size, 15.0, -size), Vec3::Y)
}

fn image_target(world: &mut World, width: u32, height: u32) -> RenderTarget {
    let image = Image::new_target_texture(width, height, TextureFormat::Rgba8UnormSrgb, None);
    RenderTarget::Image(world.resource_mut::<Assets<Image>>().add(image).into())
}

struct Seen {
    diagnostics: LodDiagnostics,
    stats: ForestRenderStats,
    /// The cameras carrying a `LodView`, by name.
    followed: Vec<String>,
}

/// A forest of 120 trees and the cameras `spawn` adds (given the forest's side), rendered
/// until its trees are in view of the budget (or 400 frames).
fn scene(spawn: impl FnOnce(&mut World, f32)) -> Seen {
    let _serial = SERIAL
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    let mut app = App::new();
    app.add_plugins(
        windowless::windowless_plugins(
            DefaultPlugins.build().disable::<bevy::winit::WinitPlugin>(),
        )
        .disable::<LogPlugin>(),
    )
    .add_plugins(SherwoodPlugins);
    windowless::finish_plugins(&mut app);
    {
        let world = app.world_mut();
        world.resource_mut::<CostSettings>().calibration = CalibrationChoice::Keep;
        world.resource_mut::<WindSettings>().enabled = false;
    }
    let mut desc = common::default_ecosystem();
    for s in &mut desc.species {
        s.count = 40;
    }
    let size = desc.terrain.size;
    common::spawn_forest(&mut app, desc);
    let world = app.world_mut();
    world.spawn(DirectionalLight::default());
    spawn(world, size);
    for _ in 0..400 {
        app.update();
        let done = app.world().resource::<LodDiagnostics>().visible_instances > 0
            && app.world().resource::<ForestRenderStats>().instances > 0;
        if done {
            // A few more frames: the pass reports a frame late.
            for _ in 0..3 {
                app.update();
            }
            break;
        }
    }
    let world = app.world_mut();
    let followed = world
        .query_filtered::<&Name, With<LodView>>()
        .iter(world)
        .map(|n| n.as_str().to_owned())
        .collect();
    Seen {
        diagnostics: world.resource::<LodDiagnostics>().clone(),
        stats: world.resource::<ForestRenderStats>().clone(),
        followed,
    }
}

fn main_camera(world: &mut World, size: f32) {
    let target = image_target(world, 320, 180);
    world.spawn((
        Name::new("main"),
        Camera3d::default(),
        target,
        Msaa::Off,
        main_pose(size),
    ));
}

#[test]
fn an_inactive_and_a_texture_camera_found_first_do_not_take_the_budget() {
    let alone = scene(main_camera);
    assert!(
        alone.diagnostics.visible_instances > 10,
        "{:?}",
        alone.diagnostics
    );
    let crowded = scene(|world, size| {
        let target = image_target(world, 320, 180);
        world.spawn((
            Name::new("inactive"),
            Camera3d::default(),
            Camera {
                is_active: false,
                ..default()
            },
            target,
            away_pose(size),
        ));
        let target = image_target(world, 64, 36);
        world.spawn((
            Name::new("texture"),
            Camera3d::default(),
            Camera {
                order: -1,
                ..default()
            },
            target,
            Msaa::Off,
            away_pose(size),
        ));
        main_camera(world, size);
    });
    assert_eq!(crowded.followed, ["main"]);
    assert_eq!(
        crowded.diagnostics.visible_instances, alone.diagnostics.visible_instances,
        "the main view's trees with other cameras about"
    );
}

#[test]
fn a_marked_camera_is_followed_even_when_smaller() {
    let seen = scene(|world, size| {
        main_camera(world, size);
        let target = image_target(world, 96, 54);
        world.spawn((
            Name::new("marked"),
            Camera3d::default(),
            BudgetView,
            Camera {
                order: 1,
                ..default()
            },
            target,
            Msaa::Off,
            main_pose(size),
        ));
    });
    assert_eq!(seen.followed, ["marked"]);
    assert!(seen.diagnostics.visible_instances > 10);
}

#[test]
fn an_orthographic_camera_draws_the_forest() {
    let seen = scene(|world, size| {
        let target = image_target(world, 320, 180);
        world.spawn((
            Name::new("ortho"),
            Camera3d::default(),
            Projection::Orthographic(OrthographicProjection {
                scaling_mode: bevy::camera::ScalingMode::FixedVertical {
                    viewport_height: 0.6 * size,
                },
                ..OrthographicProjection::default_3d()
            }),
            target,
            Msaa::Off,
            Transform::from_xyz(0.5 * size, 100.0, 0.5 * size)
                .looking_at(Vec3::new(0.5 * size, 0.0, 0.5 * size), Vec3::Z),
        ));
    });
    assert_eq!(seen.followed, ["ortho"]);
    let d = &seen.diagnostics;
    assert!(d.visible_instances > 10, "{d:?}");
    assert!(
        d.counts.triangles + d.counts.lines + d.counts.points > 0,
        "{d:?}"
    );
    assert!(seen.stats.instances > 10, "{:?}", seen.stats);
}

#[test]
fn a_minimap_off_the_forest_s_layer_neither_draws_it_nor_takes_the_budget() {
    let seen = scene(|world, size| {
        let target = image_target(world, 640, 360);
        world.spawn((
            Name::new("minimap"),
            Camera3d::default(),
            RenderLayers::layer(1),
            target,
            Msaa::Off,
            away_pose(size),
        ));
        main_camera(world, size);
    });
    assert_eq!(seen.followed, ["main"]);
    assert_eq!(seen.stats.views, 1, "{:?}", seen.stats);
    assert!(seen.diagnostics.visible_instances > 10);
}
