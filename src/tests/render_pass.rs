//! The forest render pass on a real adapter (Mesa lavapipe in CI): images rendered
//! without a window and measured. Run with `cargo test --features gpu-tests`.
//!
//! Every test renders into a 256×256 image with MSAA off, on a black background, and
//! saves what it rendered under `target/gpu-tests/` for a human to look at.
#![cfg(feature = "gpu-tests")]

use crate::testing as common;
use crate::testing as windowless;
use common::species;

use std::sync::{Arc, Mutex};

use crate::draw::{LineRun, PointRun, TreeDrawList};
use crate::ecosystem::{EcosystemPlugin, TerrainMaterial};
use crate::instance::TreeInstance;
use crate::render::ForestRenderPlugin;
use crate::tree::{AnalysisOptions, MeshData, TreeModel, TreePlugin, analyze};
use crate::{SherwoodCorePlugin, prelude::ForestRenderStats};
use bevy::camera::visibility::VisibilityRange;
use bevy::camera::{ClearColorConfig, RenderTarget};
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::log::LogPlugin;
use bevy::prelude::*;
use bevy::render::RenderApp;
use bevy::render::render_resource::{CachedPipelineState, PipelineCache, TextureFormat};
use bevy::render::view::screenshot::{Screenshot, ScreenshotCaptured};

const SIZE: u32 = 256;

/// Bevy apps share global task pools; one render test at a time keeps them honest.
static SERIAL: Mutex<()> = Mutex::new(());

/// A rendered image as RGBA8 rows.
struct Picture {
    width: u32,
    height: u32,
    rgba: Vec<u8>,
}

impl Picture {
    fn pixel(&self, x: u32, y: u32) -> [u8; 4] {
        let i = ((y * self.width + x) * 4) as usize;
        self.rgba[i..i + 4].try_into().unwrap()
    }

    fn lit(&self, x: u32, y: u32) -> bool {
        let p = self.pixel(x, y);
        p[..3].iter().any(|&c| c > 3)
    }

    fn mask(&self) -> Vec<bool> {
        (0..self.height)
            .flat_map(|y| (0..self.width).map(move |x| (x, y)))
            .map(|(x, y)| self.lit(x, y))
            .collect()
    }

    fn coverage(&self) -> usize {
        self.mask().into_iter().filter(|&b| b).count()
    }

    fn save(&self, name: &str) {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("target/gpu-tests");
        std::fs::create_dir_all(&dir).unwrap();
        let image = Image::new(
            bevy::render::render_resource::Extent3d {
                width: self.width,
                height: self.height,
                depth_or_array_layers: 1,
            },
            bevy::render::render_resource::TextureDimension::D2,
            self.rgba.clone(),
            TextureFormat::Rgba8UnormSrgb,
            default(),
        );
        image
            .try_into_dynamic()
            .unwrap()
            .to_rgba8()
            .save(dir.join(format!("{name}.png")))
            .unwrap();
    }
}

/// Renders one frame of the scene `spawn` builds, seen from `eye` looking at `target`.
fn render(
    name: &str,
    eye: Vec3,
    target: Vec3,
    spawn: impl FnOnce(&mut World) + Send + 'static,
) -> (Picture, ForestRenderStats) {
    let (mut pictures, stats) = render_views(name, &[(eye, target)], spawn);
    (pictures.remove(0), stats)
}

/// Renders one frame of the scene `spawn` builds with one camera per `(eye, target)`,
/// each into its own image.
fn render_views(
    name: &str,
    views: &[(Vec3, Vec3)],
    spawn: impl FnOnce(&mut World) + Send + 'static,
) -> (Vec<Picture>, ForestRenderStats) {
    render_views_then(name, views, spawn, |_| {})
}

/// [`render_views`], with `later` changing the scene once the pipelines are ready, a few
/// frames before the pictures are taken.
fn render_views_then(
    name: &str,
    views: &[(Vec3, Vec3)],
    spawn: impl FnOnce(&mut World) + Send + 'static,
    later: impl FnOnce(&mut World),
) -> (Vec<Picture>, ForestRenderStats) {
    let _serial = SERIAL
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    let mut app = App::new();
    app.add_plugins(
        windowless::windowless_plugins(
            DefaultPlugins.build().disable::<bevy::winit::WinitPlugin>(),
        )
        // Several apps in one process: only the first could install a logger.
        .disable::<LogPlugin>(),
    )
    .add_plugins((
        SherwoodCorePlugin,
        TreePlugin,
        ForestRenderPlugin,
        EcosystemPlugin,
    ));
    windowless::finish_plugins(&mut app);

    let world = app.world_mut();
    let mut images = Vec::new();
    for (order, &(eye, target)) in views.iter().enumerate() {
        let image = Image::new_target_texture(SIZE, SIZE, TextureFormat::Rgba8UnormSrgb, None);
        let image = world.resource_mut::<Assets<Image>>().add(image);
        world.spawn((
            Camera3d::default(),
            Camera {
                clear_color: ClearColorConfig::Custom(Color::BLACK),
                order: order as isize,
                ..default()
            },
            RenderTarget::Image(image.clone().into()),
            Msaa::Off,
            Tonemapping::None,
            Transform::from_translation(eye).looking_at(target, Vec3::Y),
        ));
        images.push(image);
    }
    world.spawn((
        DirectionalLight::default(),
        Transform::from_xyz(1.0, 3.0, 2.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    spawn(world);

    // Warm up until every pipeline (ours and Bevy's) has compiled.
    let mut ready_frames = 0;
    for _ in 0..200 {
        app.update();
        let render_world = app.sub_app(RenderApp).world();
        let cache = render_world.resource::<PipelineCache>();
        let ready = cache
            .pipelines()
            .all(|p| matches!(p.state, CachedPipelineState::Ok(_)));
        ready_frames = if ready { ready_frames + 1 } else { 0 };
        if ready_frames >= 3 {
            break;
        }
    }
    assert!(ready_frames >= 3, "{name}: pipelines never became ready");
    later(app.world_mut());
    for _ in 0..3 {
        app.update();
    }

    let mut pictures = Vec::new();
    for (i, image) in images.into_iter().enumerate() {
        let captured: Arc<Mutex<Option<Image>>> = Arc::default();
        let sink = captured.clone();
        app.world_mut().spawn(Screenshot::image(image)).observe(
            move |event: On<ScreenshotCaptured>| {
                *sink.lock().unwrap() = Some(event.image.clone());
            },
        );
        for _ in 0..20 {
            app.update();
            if captured.lock().unwrap().is_some() {
                break;
            }
        }
        let image = captured.lock().unwrap().take().expect("no screenshot");
        let picture = Picture {
            width: image.width(),
            height: image.height(),
            rgba: image.data.expect("screenshot without data"),
        };
        picture.save(&if i == 0 {
            name.to_owned()
        } else {
            format!("{name}_view{i}")
        });
        pictures.push(picture);
    }
    let stats = app.world().resource::<ForestRenderStats>().clone();
    (pictures, stats)
}

/// A vertical column along +Y: rings of radius 0.1 at heights 0, 1, 2 and 3.
fn column() -> TreeModel {
    let k = 8;
    let mut positions = Vec::new();
    let mut indices = Vec::new();
    for y in 0..4 {
        for j in 0..k {
            let a = core::f32::consts::TAU * j as f32 / k as f32;
            positions.push(Vec3::new(0.1 * a.cos(), y as f32, 0.1 * a.sin()));
        }
    }
    for y in 0..3u32 {
        let (a, b) = (y * k, (y + 1) * k);
        for j in 0..k {
            let (a0, a1) = (a + j, a + (j + 1) % k);
            let (b0, b1) = (b + j, b + (j + 1) % k);
            indices.extend([a0, b1, a1, a0, b0, b1]);
        }
    }
    let trunk = MeshData {
        positions: &positions,
        indices: &indices,
        ..Default::default()
    };
    analyze(&trunk, &MeshData::default(), &AnalysisOptions::default())
        .unwrap()
        .model
}

fn spawn_tree(world: &mut World, model: TreeModel, list: Option<TreeDrawList>) -> Entity {
    let handle = world.resource_mut::<Assets<TreeModel>>().add(model);
    let mut entity = world.spawn((TreeInstance::standalone(handle), Transform::IDENTITY));
    if let Some(list) = list {
        entity.insert(list);
    }
    entity.id()
}

/// A tree drawn at full detail. (Without a draw list it would be drawn at its coarsest
/// until the LOD stages, which these apps do not have, chose one.)
fn spawn_full_tree(world: &mut World, model: TreeModel) -> Entity {
    let full = TreeDrawList::full(&model);
    spawn_tree(world, model, Some(full))
}

fn only(list: impl FnOnce(&mut TreeDrawList)) -> TreeDrawList {
    let mut l = TreeDrawList::default();
    list(&mut l);
    l
}

/// Pixels set in exactly one of the two images, over pixels set in either.
fn coverage_difference(a: &Picture, b: &Picture) -> f64 {
    let (a, b) = (a.mask(), b.mask());
    let either = a.iter().zip(&b).filter(|(x, y)| **x || **y).count();
    let one = a.iter().zip(&b).filter(|(x, y)| **x != **y).count();
    one as f64 / either.max(1) as f64
}

#[test]
fn full_detail_covers_the_pixels_of_the_standard_renderer() {
    let model = species("slender");
    let eye = Vec3::new(0.0, 4.0, 14.0);
    let target = Vec3::new(0.0, 4.0, 0.0);
    let (ours, stats) = render("full_detail_pass", eye, target, {
        let model = model.clone();
        move |world| {
            spawn_full_tree(world, model);
        }
    });
    assert_eq!(stats.instances, 1);
    assert!(stats.counts.triangles > 0);
    assert!(stats.draw_calls_per_view <= 2, "{stats:?}");
    let (standard, _) = render("full_detail_standard", eye, target, move |world| {
        let trunk = world.resource_mut::<Assets<Mesh>>().add(model.trunk_mesh());
        let leaves = world.resource_mut::<Assets<Mesh>>().add(model.leaf_mesh());
        let mut materials = world.resource_mut::<Assets<StandardMaterial>>();
        let bark = materials.add(StandardMaterial {
            base_color: Color::WHITE,
            unlit: true,
            ..default()
        });
        let leaf = materials.add(StandardMaterial {
            base_color: Color::WHITE,
            unlit: true,
            double_sided: true,
            cull_mode: None,
            ..default()
        });
        world.spawn((Mesh3d(trunk), MeshMaterial3d(bark)));
        world.spawn((Mesh3d(leaves), MeshMaterial3d(leaf)));
    });
    let covered = standard.coverage();
    assert!(covered > 2000, "the tree should fill part of the image");
    let difference = coverage_difference(&ours, &standard);
    assert!(
        difference < 0.02,
        "coverage differs by {:.2}% ({} vs {} pixels)",
        difference * 100.0,
        ours.coverage(),
        covered
    );
}

/// A full-detail tree of species `name` standing at `x` on the X axis.
fn place_tree(world: &mut World, name: &str, x: f32) -> Entity {
    let entity = spawn_full_tree(world, species(name));
    world
        .entity_mut(entity)
        .insert(Transform::from_xyz(x, 0.0, 0.0));
    entity
}

/// Pixels lit in the columns `columns`.
fn lit_in(picture: &Picture, columns: core::ops::Range<u32>) -> usize {
    columns
        .flat_map(|x| (0..SIZE).map(move |y| (x, y)))
        .filter(|&(x, y)| picture.lit(x, y))
        .count()
}

fn assert_same_picture(picture: &Picture, expected: &Picture) {
    assert!(
        picture.rgba == expected.rgba,
        "{} pixels differ",
        picture
            .rgba
            .chunks(4)
            .zip(expected.rgba.chunks(4))
            .filter(|(a, b)| a != b)
            .count()
    );
}

/// The eye and target of the pictures with trees at x = -4, 0 and 4.
const ROW_VIEW: (Vec3, Vec3) = (Vec3::new(0.0, 5.0, 22.0), Vec3::new(0.0, 5.0, 0.0));

/// A model added after the forest's geometry went up is appended to it (group impostors
/// are published a few at a time): its own geometry drawn where it stands, the trees
/// already uploaded still drawn — the buffers it outgrew copied on the GPU — exactly as
/// when both models were there from the start.
#[test]
fn a_model_added_later_draws_as_if_it_had_been_there_from_the_start() {
    let (eye, target) = ROW_VIEW;
    let (at_once, _) = render("model_at_once", eye, target, |world| {
        place_tree(world, "slender", -4.0);
        place_tree(world, "broad", 4.0);
    });
    let (mut later, _) = render_views_then(
        "model_added_later",
        &[ROW_VIEW],
        |world| {
            place_tree(world, "slender", -4.0);
        },
        |world| {
            place_tree(world, "broad", 4.0);
        },
    );
    let later = later.remove(0);
    let halves = |p: &Picture| (lit_in(p, 0..SIZE / 2), lit_in(p, SIZE / 2..SIZE));
    let (left, right) = halves(&at_once);
    assert!(
        left > 500 && right > 500,
        "both trees in view: {left} and {right} pixels"
    );
    assert_eq!(
        halves(&later),
        (left, right),
        "pixels lit left and right of the middle"
    );
    assert_same_picture(&later, &at_once);
}

/// A model removed leaves its geometry in the atlas, unused, while a model added later is
/// appended after it: the trees still there and the new one draw as in a scene that had
/// only them from the start.
#[test]
fn a_model_removed_leaves_the_others_drawn_as_they_were() {
    let (eye, target) = ROW_VIEW;
    let (only_them, _) = render("models_without_the_removed", eye, target, |world| {
        place_tree(world, "broad", -4.0);
        place_tree(world, "grand", 4.0);
    });
    let removed: Arc<Mutex<Option<Entity>>> = Arc::default();
    let first = removed.clone();
    let (mut after, _) = render_views_then(
        "models_after_a_removal",
        &[ROW_VIEW],
        move |world| {
            *first.lock().unwrap() = Some(place_tree(world, "slender", 0.0));
            place_tree(world, "broad", -4.0);
        },
        move |world| {
            let entity = removed.lock().unwrap().take().unwrap();
            let model = world.get::<TreeInstance>(entity).unwrap().model.id();
            world.despawn(entity);
            world.resource_mut::<Assets<TreeModel>>().remove(model);
            place_tree(world, "grand", 4.0);
        },
    );
    assert!(only_them.coverage() > 1000, "{}", only_them.coverage());
    assert_same_picture(&after.remove(0), &only_them);
}

#[test]
fn lines_are_as_wide_as_asked() {
    let model = column();
    let segment = model
        .segments
        .line
        .iter()
        .position(|l| (l[0].y - 1.0).abs() < 1e-3)
        .expect("a segment from y = 1 to y = 2") as u32;
    for width in [1, 2, 3, 5, 8, 13, 20] {
        let list = only(|l| {
            l.trunk_lines.push(LineRun {
                segments: segment..segment + 1,
                width,
            });
        });
        let model = model.clone();
        let (picture, stats) = render(
            &format!("line_width_{width}"),
            Vec3::new(0.0, 1.5, 6.0),
            Vec3::new(0.0, 1.5, 0.0),
            move |world| {
                spawn_tree(world, model, Some(list));
            },
        );
        assert_eq!(stats.counts.lines, 1);
        assert_eq!(stats.draw_calls_per_view, 1);
        let y = SIZE / 2;
        let across = (0..SIZE).filter(|&x| picture.lit(x, y)).count() as i64;
        assert!(
            across >= 1 && (across - i64::from(width)).abs() <= 1,
            "a {width}-pixel line measures {across} pixels across"
        );
        // The segment spans a full metre on screen, not a dot.
        let along = (0..SIZE)
            .map(|x| (0..SIZE).filter(|&y| picture.lit(x, y)).count())
            .max()
            .unwrap_or(0);
        assert!(along > 20, "the line is {along} pixels long");
    }
}

#[test]
fn points_cover_their_size_squared() {
    let model = species("slender");
    let leaf = model.leaves.len() as u32 / 2;
    let center = model.leaves[leaf as usize].center;
    for size in [1, 2, 4, 7, 12, 20] {
        let list = only(|l| {
            l.leaf_points.push(PointRun {
                leaves: leaf..leaf + 1,
                size,
            });
        });
        let model = model.clone();
        let (picture, stats) = render(
            &format!("point_size_{size}"),
            center + Vec3::new(0.0, 0.0, 5.0),
            center,
            move |world| {
                spawn_tree(world, model, Some(list));
            },
        );
        assert_eq!(stats.counts.points, 1);
        let covered = picture.coverage() as i64;
        let size = i64::from(size);
        assert!(
            covered >= (size - 1).pow(2).max(1) && covered <= (size + 1).pow(2),
            "a {size}-pixel point covers {covered} pixels"
        );
    }
}

/// Large points are discs (the corners of their square stay empty) of the square's area,
/// lit like the leaf they stand for.
#[test]
fn large_points_are_discs_of_their_squares_area() {
    let model = species("slender");
    let leaf = model.leaves.len() as u32 / 2;
    let center = model.leaves[leaf as usize].center;
    let size = 24;
    let list = only(|l| {
        l.leaf_points.push(PointRun {
            leaves: leaf..leaf + 1,
            size,
        });
    });
    let (picture, _) = render(
        "point_disc",
        center + Vec3::new(0.0, 0.0, 5.0),
        center,
        move |world| {
            spawn_tree(world, model, Some(list));
        },
    );
    let lit: Vec<(u32, u32)> = (0..picture.height)
        .flat_map(|y| (0..picture.width).map(move |x| (x, y)))
        .filter(|&(x, y)| picture.lit(x, y))
        .collect();
    let (x0, x1) = (
        lit.iter().map(|p| p.0).min().unwrap(),
        lit.iter().map(|p| p.0).max().unwrap(),
    );
    let (y0, y1) = (
        lit.iter().map(|p| p.1).min().unwrap(),
        lit.iter().map(|p| p.1).max().unwrap(),
    );
    let area = f64::from(size * size);
    let covered = lit.len() as f64;
    assert!(
        (covered - area).abs() < 0.1 * area,
        "a {size}-pixel point covers {covered} pixels"
    );
    // A square would fill its bounding box; a disc leaves π/4 of it, and its corners.
    let bbox = f64::from((x1 - x0 + 1) * (y1 - y0 + 1));
    assert!(
        covered < 0.85 * bbox,
        "{covered} of a {bbox}-pixel box: not round"
    );
    for (x, y) in [(x0, y0), (x1, y0), (x0, y1), (x1, y1)] {
        assert!(!picture.lit(x, y), "corner ({x}, {y}) of the point is lit");
    }
}

fn cube(world: &mut World, at: Vec3) {
    unlit_cube(world, Color::srgb(1.0, 0.0, 0.0), at);
}

/// A unit cube of flat `color` at `at`.
fn unlit_cube(world: &mut World, color: Color, at: Vec3) -> Entity {
    let mesh = world
        .resource_mut::<Assets<Mesh>>()
        .add(Cuboid::new(1.0, 1.0, 1.0));
    let material = world
        .resource_mut::<Assets<StandardMaterial>>()
        .add(StandardMaterial {
            base_color: color,
            unlit: true,
            ..default()
        });
    world
        .spawn((
            Mesh3d(mesh),
            MeshMaterial3d(material),
            Transform::from_translation(at),
        ))
        .id()
}

#[test]
fn the_terrain_material_is_lambert_under_the_first_directional_light() {
    let (ambient, diffuse) = (0.1, 0.5);
    let (picture, _) = render(
        "terrain_material",
        Vec3::new(0.0, 4.0, 0.01),
        Vec3::ZERO,
        move |world| {
            let mesh = world
                .resource_mut::<Assets<Mesh>>()
                .add(Plane3d::default().mesh().size(20.0, 20.0));
            let material = world
                .resource_mut::<Assets<TerrainMaterial>>()
                .add(TerrainMaterial {
                    ambient: LinearRgba::gray(ambient),
                    diffuse: LinearRgba::gray(diffuse),
                });
            world.spawn((Mesh3d(mesh), MeshMaterial3d(material)));
        },
    );
    // The light sits at (1, 3, 2) looking at the origin; the plane's normal is +Y.
    let lambert = 3.0 / 14.0f32.sqrt();
    let expected = Color::LinearRgba(LinearRgba::gray(ambient + diffuse * lambert)).to_srgba();
    let expected = (expected.red * 255.0).round() as i32;
    for (x, y) in [(SIZE / 2, SIZE / 2), (10, 10), (SIZE - 10, SIZE - 20)] {
        let p = picture.pixel(x, y);
        for c in &p[..3] {
            assert!(
                (i32::from(*c) - expected).abs() <= 2,
                "pixel ({x}, {y}) is {p:?}, expected grey {expected}"
            );
        }
    }
}

#[test]
fn opaque_geometry_hides_lines_and_points_behind_it() {
    let column = column();
    let segment = column
        .segments
        .line
        .iter()
        .position(|l| (l[0].y - 1.0).abs() < 1e-3)
        .unwrap() as u32;
    let line = only(|l| {
        l.trunk_lines.push(LineRun {
            segments: segment..segment + 1,
            width: 6,
        });
    });
    let slender = species("slender");
    let leaf = 0;
    let center = slender.leaves[leaf as usize].center;
    let point = only(|l| {
        l.leaf_points.push(PointRun {
            leaves: leaf..leaf + 1,
            size: 10,
        });
    });

    let red = |p: &Picture| {
        (0..SIZE)
            .flat_map(|y| (0..SIZE).map(move |x| (x, y)))
            .filter(|&(x, y)| {
                let c = p.pixel(x, y);
                c[0] > 200 && c[1] < 30 && c[2] < 30
            })
            .count()
    };
    let red_only = |p: &Picture| {
        (0..SIZE)
            .flat_map(|y| (0..SIZE).map(move |x| (x, y)))
            .filter(|&(x, y)| {
                let c = p.pixel(x, y);
                p.lit(x, y) && !(c[0] > 200 && c[1] < 30 && c[2] < 30)
            })
            .count()
    };
    let cases: [(&str, TreeModel, TreeDrawList, Vec3, Vec3); 2] = [
        ("line", column, line, Vec3::new(0.0, 1.5, 0.0), Vec3::Z),
        ("point", slender, point, center, Vec3::Z),
    ];
    for (what, model, list, at, towards_eye) in cases {
        let eye = at + towards_eye * 6.0;
        for (where_, cube_at, visible) in [
            ("behind", at + towards_eye * 3.0, false),
            ("in_front", at - towards_eye * 1.5, true),
        ] {
            let (model, list) = (model.clone(), list.clone());
            let (picture, _) = render(
                &format!("occlusion_{what}_{where_}"),
                eye,
                at,
                move |world| {
                    cube(world, cube_at);
                    spawn_tree(world, model, Some(list));
                },
            );
            let not_cube = red_only(&picture);
            // The cube is drawn either way: a blank picture passes neither case.
            assert!(
                red(&picture) > 100,
                "the cube is not drawn ({what}, {where_})"
            );
            if visible {
                assert!(not_cube > 20, "the {what} in front of the cube is hidden");
            } else {
                assert_eq!(not_cube, 0, "the {what} behind the cube shows through");
            }
        }
    }
}

/// The slender tree seen from the side, drawing `list`.
fn shoot_slender(name: &str, model: &TreeModel, list: TreeDrawList) -> Picture {
    let model = model.clone();
    let (eye, target) = (Vec3::new(0.0, 5.0, 9.0), Vec3::new(0.0, 5.0, 0.0));
    render(name, eye, target, move |world| {
        spawn_tree(world, model, Some(list));
    })
    .0
}

#[test]
fn leaves_in_far_first_order_draw_the_same_leaves() {
    let model = species("slender");
    let n = model.leaves.len() as u32;
    for (kind, of) in [
        (
            "triangles",
            (|l: &mut TreeDrawList, r| l.leaf_triangles.push(r)) as fn(&mut TreeDrawList, _),
        ),
        ("points", |l, r| {
            l.leaf_points.push(PointRun { leaves: r, size: 3 });
        }),
    ] {
        let own = shoot_slender(&format!("own_order_{kind}"), &model, only(|l| of(l, 0..n)));
        let far_first = shoot_slender(
            &format!("far_first_order_{kind}"),
            &model,
            only(|l| of(l, n..2 * n)),
        );
        let covered = own.mask().iter().filter(|&&m| m).count();
        assert!(covered > 500, "{kind}: only {covered} pixels drawn");
        // The same leaves in another order: only ties in depth may resolve differently.
        let differing = (0..SIZE)
            .flat_map(|y| (0..SIZE).map(move |x| (x, y)))
            .filter(|&(x, y)| own.pixel(x, y) != far_first.pixel(x, y))
            .count();
        assert!(
            differing * 100 <= covered,
            "{kind}: {differing} of {covered} pixels differ"
        );
    }
}

#[test]
fn draw_ranges_change_exactly_the_pixels_they_name() {
    let model = species("slender");
    let leaves = model.leaves.len() as u32;
    let half = leaves / 2;
    let trunk = 0..model.trunk_triangle_count() as u32;
    let shoot = |name: &str, list: TreeDrawList| shoot_slender(name, &model, list);
    let all_triangles = shoot(
        "ranges_all_triangles",
        only(|l| {
            l.trunk_triangles = trunk.clone();
            l.leaf_triangles.push(0..leaves);
        }),
    );
    let mixed = shoot(
        "ranges_half_points",
        only(|l| {
            l.trunk_triangles = trunk.clone();
            l.leaf_triangles.push(0..half);
            l.leaf_points.push(PointRun {
                leaves: half..leaves,
                size: 3,
            });
        }),
    );
    let second_half_triangles = shoot(
        "ranges_second_half_triangles",
        only(|l| l.leaf_triangles.push(half..leaves)),
    );
    let second_half_points = shoot(
        "ranges_second_half_points",
        only(|l| {
            l.leaf_points.push(PointRun {
                leaves: half..leaves,
                size: 3,
            });
        }),
    );
    let (t2, p2) = (second_half_triangles.mask(), second_half_points.mask());
    let mut changed = 0;
    let mut outside = 0;
    for y in 0..SIZE {
        for x in 0..SIZE {
            if all_triangles.pixel(x, y) != mixed.pixel(x, y) {
                changed += 1;
                let i = (y * SIZE + x) as usize;
                if !t2[i] && !p2[i] {
                    outside += 1;
                }
            }
        }
    }
    assert!(changed > 100, "only {changed} pixels changed");
    assert_eq!(
        outside, 0,
        "{outside} of {changed} changed pixels lie outside the second half's leaves"
    );
}

/// A tree the LOD stages have not seen (spawned in `Last`, or in an app without them, as
/// here) is drawn at its coarsest, where its own `Transform` puts it: not at full detail,
/// not at the origin.
#[test]
fn a_tree_without_a_draw_list_is_drawn_at_its_coarsest_where_it_stands() {
    let model = species("slender");
    let eye = Vec3::new(0.0, 4.0, 14.0);
    let target = Vec3::new(0.0, 4.0, 0.0);
    let aside = Vec3::new(3.0, 0.0, 0.0);
    let (picture, stats) = render("unlisted_tree", eye, target, {
        let model = model.clone();
        move |world| {
            let handle = world.resource_mut::<Assets<TreeModel>>().add(model);
            world.spawn((
                TreeInstance::standalone(handle),
                Transform::from_translation(aside),
            ));
        }
    });
    let coarsest = TreeDrawList::coarsest(&model);
    assert_eq!(stats.instances, 1);
    assert_eq!(stats.counts, coarsest.counts(&model), "{stats:?}");
    assert_ne!(stats.counts, TreeDrawList::full(&model).counts(&model));
    let picture = &picture;
    let lit: Vec<u32> = (0..SIZE)
        .flat_map(|y| (0..SIZE).filter(move |&x| picture.lit(x, y)))
        .collect();
    assert!(lit.len() > 200, "only {} pixels drawn", lit.len());
    let mean_x = lit.iter().sum::<u32>() as f32 / lit.len() as f32;
    // 3 m aside at 14 m with a 45° field of view is about 66 pixels right of the middle.
    assert!(
        mean_x > SIZE as f32 / 2.0 + 40.0,
        "the tree's pixels centre at x = {mean_x:.0} of {SIZE}"
    );
}

#[test]
fn every_camera_draws_the_forest_from_its_own_eye() {
    let model = species("slender");
    let front = (Vec3::new(0.0, 4.0, 14.0), Vec3::new(0.0, 4.0, 0.0));
    let side = (Vec3::new(14.0, 4.0, 0.0), Vec3::new(0.0, 4.0, 0.0));
    let (pictures, stats) = render_views("two_views", &[front, side], move |world| {
        spawn_full_tree(world, model);
    });
    assert_eq!(stats.views, 2);
    let (a, b) = (&pictures[0], &pictures[1]);
    assert!(a.coverage() > 2000 && b.coverage() > 2000);
    assert!(
        coverage_difference(a, b) > 0.2,
        "the two views should see the tree from different sides"
    );
}

#[test]
fn ring_offsets_move_the_rings_on_the_gpu() {
    use crate::wind::RingOffsetTable;
    let model = column();
    // Every ring but the root moves 0.5 m along +X: the column leans as one piece above
    // its first ring.
    let offsets: Vec<Vec3A> = model
        .rings
        .iter()
        .map(|r| {
            if r.is_root() {
                Vec3A::ZERO
            } else {
                Vec3A::X * 0.5
            }
        })
        .collect();
    let eye = Vec3::new(0.0, 1.5, 6.0);
    let target = Vec3::new(0.0, 1.5, 0.0);
    let still = {
        let model = model.clone();
        render("wind_still", eye, target, move |world| {
            spawn_full_tree(world, model);
        })
        .0
    };
    let (moved, _) = render("wind_moved", eye, target, move |world| {
        // The only tree: instance 0 of the instance table, whose order the offsets follow.
        spawn_full_tree(world, model);
        // Another block first (of an instance the table does not have), so the tree's
        // block starts past the beginning of the uploaded offsets.
        let mut table = RingOffsetTable::at_rest(2);
        table.set(1, &[Vec3A::NEG_X * 2.0; 7]);
        table.set(0, &offsets);
        world.insert_resource(table);
    });
    // Mean x of the lit pixels in the top rows (rings at y = 2 and 3) moves right; the
    // bottom stays where it was.
    let mean_x = |p: &Picture, rows: core::ops::Range<u32>| {
        let xs: Vec<u32> = rows
            .flat_map(|y| (0..SIZE).filter(move |&x| p.lit(x, y)))
            .collect();
        xs.iter().sum::<u32>() as f64 / xs.len().max(1) as f64
    };
    let lit_in = |p: &Picture, rows: core::ops::Range<u32>| {
        rows.flat_map(|y| (0..SIZE).filter(move |&x| p.lit(x, y)))
            .count()
    };
    // The top (rings at y = 2 and 3) and the middle (y = 1 to 2) of the column.
    let (top, middle) = (40..90, 100..150);
    for (name, p) in [("still", &still), ("moved", &moved)] {
        assert!(
            lit_in(p, top.clone()) > 20 && lit_in(p, middle.clone()) > 20,
            "the {name} column is not drawn"
        );
    }
    let shift = mean_x(&moved, top.clone()) - mean_x(&still, top);
    // 0.5 m at 6 m with a 45° field of view is about 26 pixels.
    assert!(shift > 15.0, "the top moved {shift:.1} px");
}

/// Forty trees, each drawing all four primitive kinds with its own widths and sizes: still
/// one instanced draw per kind and point shape (squares and discs), whatever the number of
/// trees.
#[test]
fn many_trees_in_every_primitive_kind_take_one_draw_per_kind_and_point_shape() {
    let model = species("slender");
    let segments = model.segments.len() as u32;
    let leaves = model.leaves.len() as u32;
    let first_triangle = model.segments.triangle_offsets[(segments / 2) as usize];
    let total = model.trunk_triangle_count() as u32;
    let (picture, stats) = render(
        "forty_trees",
        Vec3::new(0.0, 10.0, 36.0),
        Vec3::new(0.0, 4.0, 0.0),
        move |world| {
            let handle = world.resource_mut::<Assets<TreeModel>>().add(model);
            for i in 0..40_u32 {
                let list = TreeDrawList {
                    trunk_triangles: first_triangle..total,
                    trunk_lines: vec![LineRun {
                        segments: 0..segments / 2,
                        width: 1 + i % 4,
                    }],
                    leaf_triangles: std::iter::once(0..leaves / 2).collect(),
                    leaf_points: vec![PointRun {
                        leaves: leaves / 2..leaves,
                        // Squares (below 6 pixels) and discs.
                        size: [1, 2, 3, 9][i as usize % 4],
                    }],
                };
                let at = Vec3::new((i % 8) as f32 * 3.0 - 10.5, 0.0, -((i / 8) as f32) * 3.0);
                world.spawn((
                    TreeInstance::standalone(handle.clone()),
                    Transform::from_translation(at),
                    list,
                ));
            }
        },
    );
    assert_eq!(stats.instances, 40, "{stats:?}");
    assert_eq!(stats.draw_calls_per_view, 5, "{stats:?}");
    assert!(stats.chunks.iter().all(|&c| c > 4), "{stats:?}");
    assert!(picture.coverage() > 1000, "{} pixels", picture.coverage());
}

/// Which 8×8 blocks of the picture have a pixel set.
fn blocks(picture: &Picture) -> Vec<bool> {
    const B: u32 = 8;
    let (w, h) = (picture.width.div_ceil(B), picture.height.div_ceil(B));
    let mut set = vec![false; (w * h) as usize];
    for y in 0..picture.height {
        for x in 0..picture.width {
            if picture.lit(x, y) {
                set[((y / B) * w + x / B) as usize] = true;
            }
        }
    }
    set
}

/// The 8×8 blocks set in `part` that are also set in `whole`, over the blocks set in
/// `part`: where two pictures draw, at the scale of a far group rather than a leaf.
fn share_inside(part: &Picture, whole: &Picture) -> f64 {
    let (p, w) = (blocks(part), blocks(whole));
    let inside = p.iter().zip(&w).filter(|(a, b)| **a && **b).count();
    inside as f64 / p.iter().filter(|a| **a).count().max(1) as f64
}

/// A box's group impostor is drawn by the pass where its trees are: sixteen slender trees
/// on a grid seen from afar, drawn in full, then their group model alone — as triangles
/// (its stems and enlarged leaves) and as lines and points.
#[test]
fn a_group_impostor_covers_where_its_trees_are() {
    use crate::tree::{GroupImpostorMember, GroupImpostorOptions, group_impostor_model};
    use bevy::math::Affine3A;
    let model = species("slender");
    let far_first = model.far_first_leaves();
    let spacing = (model.bounds.max - model.bounds.min).xz().max_element() * 1.1;
    let places: Vec<Vec3> = (0..16)
        .map(|i| Vec3::new((i % 4) as f32 - 1.5, 0.0, (i / 4) as f32 - 1.5) * spacing)
        .collect();
    let members: Vec<GroupImpostorMember> = places
        .iter()
        .map(|&p| GroupImpostorMember {
            model: &model,
            transform: Affine3A::from_translation(p),
            far_first: &far_first,
        })
        .collect();
    let group = group_impostor_model(&members, &GroupImpostorOptions::default()).unwrap();
    let height = model.bounds.max.y;
    let target = Vec3::new(0.0, height * 0.5, 0.0);
    let eye = target + Vec3::new(0.3, 1.2, 1.0).normalize() * spacing * 9.0;

    let trees_model = model.clone();
    let (trees, _) = render("group_members", eye, target, move |world| {
        let handle = world.resource_mut::<Assets<TreeModel>>().add(trees_model);
        for p in places {
            world.spawn((
                TreeInstance::standalone(handle.clone()),
                Transform::from_translation(p),
            ));
        }
    });
    let full = TreeDrawList::full(&group);
    let (as_triangles, stats) = render("group_impostor_triangles", eye, target, {
        let group = group.clone();
        move |world| {
            spawn_tree(world, group, Some(full));
        }
    });
    assert!(stats.counts.triangles > 0);
    let leaves = group.leaves.len() as u32;
    let lines_and_points = only(|l| {
        l.trunk_lines.push(LineRun {
            segments: 0..group.segments.len() as u32,
            width: 2,
        });
        l.leaf_points.push(PointRun {
            leaves: 0..leaves,
            size: 6,
        });
    });
    let (as_points, stats) = render("group_impostor_points", eye, target, move |world| {
        spawn_tree(world, group, Some(lines_and_points));
    });
    assert_eq!(stats.counts.points, u64::from(leaves));
    let trees_px = trees.coverage() as f64;
    for (name, picture) in [("triangles", &as_triangles), ("points", &as_points)] {
        // Most of what the group draws lies where its trees are, and it covers a good
        // part of their silhouette (it keeps 256 of their leaves, enlarged).
        let inside = share_inside(picture, &trees);
        let covered = share_inside(&trees, picture);
        let ratio = picture.coverage() as f64 / trees_px;
        println!("{name}: inside {inside:.3}, covers {covered:.3}, pixels ×{ratio:.2}");
        assert!(
            inside > 0.8,
            "{name}: only {inside:.3} of the group's blocks on its trees"
        );
        assert!(
            covered > 0.6,
            "{name}: covers {covered:.3} of its trees' blocks"
        );
        assert!(
            (0.3..3.0).contains(&ratio),
            "{name}: ×{ratio:.2} the trees' pixels"
        );
    }
}

/// A far tree's crown disc is drawn where its leaves are: the grand tree seen from afar
/// at full detail (its trunk hidden, leaves only) and as its crown disc alone, the point
/// sized as the LOD sizes it (the side of a square of the crown's projected area).
#[test]
fn a_crown_disc_covers_where_its_leaves_are() {
    let model = species("grand");
    let crown = model.crown.expect("a crown");
    let height = model.bounds.max.y;
    let target = Vec3::new(0.0, height * 0.5, 0.0);
    let distance = height * 4.0;
    let eye = target + Vec3::new(0.6, 0.25, 1.0).normalize() * distance;
    // The test's camera: Bevy's default perspective (45° vertical) on a square image.
    let pixels_per_unit = SIZE as f32
        / (2.0 * (core::f32::consts::FRAC_PI_4 / 2.0).tan())
        / eye.distance(crown.center);
    let size = (crown.area.sqrt() * pixels_per_unit + 0.5) as u32;
    assert!((8..=64).contains(&size), "a {size}-pixel disc");
    let leaves_only = only(|l| l.leaf_triangles.push(0..model.leaves.len() as u32));
    let (leaves, _) = render("crown_leaves", eye, target, {
        let model = model.clone();
        move |world| {
            spawn_tree(world, model, Some(leaves_only));
        }
    });
    let crown_leaf = model.crown_leaf();
    let disc = only(|l| {
        l.leaf_points.push(PointRun {
            leaves: crown_leaf..crown_leaf + 1,
            size,
        });
    });
    let (disc, stats) = render("crown_disc", eye, target, move |world| {
        spawn_tree(world, model, Some(disc));
    });
    assert_eq!(stats.counts.points, 1);
    // As many pixels as the leaves, centred on them, and mostly over them: a disc of the
    // crown's area is more compact than the leaves' ragged outline, so it covers their
    // middle, not every block they reach.
    let (inside, covered) = (share_inside(&disc, &leaves), share_inside(&leaves, &disc));
    let ratio = disc.coverage() as f64 / leaves.coverage() as f64;
    let offset = centroid(&disc).distance(centroid(&leaves));
    println!(
        "crown disc of {size} px: inside {inside:.3}, covers {covered:.3}, pixels ×{ratio:.2}, {offset:.1} px off"
    );
    assert!(
        (0.7..1.4).contains(&ratio),
        "×{ratio:.2} the leaves' pixels"
    );
    assert!(
        offset < 0.15 * size as f32,
        "{offset:.1} px off the leaves' centre"
    );
    assert!(
        inside > 0.7,
        "only {inside:.3} of the disc's blocks on the leaves"
    );
    assert!(
        covered > 0.3,
        "the disc covers {covered:.3} of the leaves' blocks"
    );
}

/// The mean position of a picture's lit pixels.
fn centroid(picture: &Picture) -> Vec2 {
    let (mut sum, mut n) = (Vec2::ZERO, 0.0);
    for y in 0..picture.height {
        for x in 0..picture.width {
            if picture.lit(x, y) {
                sum += Vec2::new(x as f32, y as f32);
                n += 1.0;
            }
        }
    }
    sum / n
}

/// An unlit cube of `color`, dithered by `range` when given.
fn dithered_cube(world: &mut World, color: Color, range: Option<VisibilityRange>) {
    let cube = unlit_cube(world, color, Vec3::ZERO);
    if let Some(range) = range {
        world.entity_mut(cube).insert(range);
    }
}

/// A ladder's cross-fade on the real renderer: at every step the level fading in and the
/// one fading out share the pixels of the dither pattern — together they cover what one
/// undithered cube covers, the new one its step's sixteenths of it.
#[test]
fn a_fade_s_two_levels_dither_into_each_other() {
    use crate::ladder::fade::{incoming_range, outgoing_range};
    let eye = Vec3::new(0.8, 0.9, 2.2);
    let (whole, _) = render("fade_whole", eye, Vec3::ZERO, |world| {
        dithered_cube(world, Color::srgb(1.0, 0.0, 0.0), None);
    });
    let whole = whole.coverage();
    assert!(whole > 5_000, "the cube covers {whole} pixels");
    for step in [2, 8, 13] {
        let (picture, _) = render(&format!("fade_{step}"), eye, Vec3::ZERO, move |world| {
            dithered_cube(
                world,
                Color::srgb(1.0, 0.0, 0.0),
                Some(incoming_range(step)),
            );
            dithered_cube(
                world,
                Color::srgb(0.0, 1.0, 0.0),
                Some(outgoing_range(step)),
            );
        });
        let (mut incoming, mut outgoing) = (0usize, 0usize);
        for y in 0..picture.height {
            for x in 0..picture.width {
                let p = picture.pixel(x, y);
                incoming += usize::from(p[0] > 128 && p[1] < 64);
                outgoing += usize::from(p[1] > 128 && p[0] < 64);
            }
        }
        let both = incoming + outgoing;
        assert!(
            both.abs_diff(whole) * 50 <= whole,
            "step {step}: the two levels cover {both} pixels, one cube {whole}"
        );
        let share = incoming as f64 / both as f64;
        assert!(
            (share - step as f64 / 16.0).abs() < 0.04,
            "step {step}: the level fading in covers {share:.3} of the pixels"
        );
    }
}
