//! Measures the forest render pass on this machine's adapter, without a window:
//!
//! 1. a forest at full detail through the pass against the same triangles through Bevy's
//!    standard mesh path (one shared mesh per species, `StandardMaterial`);
//! 2. the cost per primitive — triangles, lines of several widths, points of several
//!    sizes — as the slope of frame time between two primitive counts;
//! 3. draw calls and frame time for 2000 trees drawn in all four primitive kinds.
//!
//! ```sh
//! cargo run --release -p sherwood-lab -- pass-benchmark
//! cargo run --release -p sherwood-lab -- pass-benchmark --picture docs/render-primitive-kinds.png
//! ```
//!
//! Frame time is wall time of one `App::update` followed by waiting for the GPU (on
//! lavapipe the "GPU" is the CPU, so the two are one cost). Each figure is the median of
//! the measured frames, after every pipeline has compiled.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use bevy_sherwood::testing as windowless;

use bevy::camera::{ClearColorConfig, RenderTarget};
use bevy::prelude::*;
use bevy::render::RenderApp;
use bevy::render::diagnostic::RenderDiagnosticsPlugin;
use bevy::render::render_resource::{
    CachedPipelineState, PipelineCache, PollType, TextureFormat, TextureUsages,
};
use bevy::render::renderer::RenderDevice;
use bevy::render::view::screenshot::{Screenshot, save_to_disk};
use bevy_sherwood::draw::{LineRun, PointRun, TreeDrawList};
use bevy_sherwood::instance::{FixedDrawList, TreeInstance};
use bevy_sherwood::prelude::*;
use bevy_sherwood::render::ForestRenderStats;
use bevy_sherwood::tree::SpeciesDesc;

const WIDTH: u32 = 960;
const HEIGHT: u32 = 540;

/// Everything a scene spawned, despawned before the next.
#[derive(Component)]
struct SceneEntity;

struct Bench {
    app: App,
    image: Handle<Image>,
}

impl Bench {
    fn new() -> Self {
        let mut app = App::new();
        app.add_plugins(windowless::windowless_plugins(
            DefaultPlugins.build().disable::<bevy::winit::WinitPlugin>(),
        ))
        .add_plugins((
            SherwoodCorePlugin,
            TreePlugin,
            ForestRenderPlugin,
            RenderDiagnosticsPlugin,
        ));
        windowless::finish_plugins(&mut app);
        let world = app.world_mut();
        let mut image =
            Image::new_target_texture(WIDTH, HEIGHT, TextureFormat::Rgba8UnormSrgb, None);
        image.texture_descriptor.usage |= TextureUsages::COPY_SRC;
        let image = world.resource_mut::<Assets<Image>>().add(image);
        world.spawn((
            DirectionalLight::default(),
            Transform::from_xyz(1.0, 3.0, 2.0).looking_at(Vec3::ZERO, Vec3::Y),
        ));
        Self { app, image }
    }

    fn camera(&mut self, eye: Vec3, target: Vec3) {
        let image = self.image.clone();
        self.app.world_mut().spawn((
            SceneEntity,
            Camera3d::default(),
            Camera {
                clear_color: ClearColorConfig::Custom(Color::srgb(0.62, 0.76, 0.92)),
                ..default()
            },
            RenderTarget::Image(image.into()),
            Transform::from_translation(eye).looking_at(target, Vec3::Y),
        ));
    }

    fn clear(&mut self) {
        let world = self.app.world_mut();
        let old: Vec<Entity> = world
            .query_filtered::<Entity, With<SceneEntity>>()
            .iter(world)
            .collect();
        for e in old {
            world.despawn(e);
        }
    }

    fn frame(&mut self) -> f64 {
        let start = Instant::now();
        self.app.update();
        let device = self
            .app
            .sub_app(RenderApp)
            .world()
            .resource::<RenderDevice>();
        let _ = device.poll(PollType::wait_indefinitely());
        start.elapsed().as_secs_f64() * 1000.0
    }

    /// Median frame time over `frames` frames, after the pipelines are ready.
    fn measure(&mut self, frames: usize) -> f64 {
        let mut ready = 0;
        for _ in 0..500 {
            self.frame();
            let cache = self
                .app
                .sub_app(RenderApp)
                .world()
                .resource::<PipelineCache>();
            let all = cache
                .pipelines()
                .all(|p| matches!(p.state, CachedPipelineState::Ok(_)));
            ready = if all { ready + 1 } else { 0 };
            if ready >= 5 {
                break;
            }
        }
        let mut times: Vec<f64> = (0..frames).map(|_| self.frame()).collect();
        times.sort_by(f64::total_cmp);
        times[times.len() / 2]
    }

    fn stats(&self) -> ForestRenderStats {
        self.app.world().resource::<ForestRenderStats>().clone()
    }

    fn add_model(&mut self, model: TreeModel) -> Handle<TreeModel> {
        self.app
            .world_mut()
            .resource_mut::<Assets<TreeModel>>()
            .add(model)
    }

    fn tree(&mut self, model: &Handle<TreeModel>, at: Vec3, list: Option<TreeDrawList>) {
        let mut e = self.app.world_mut().spawn((
            SceneEntity,
            TreeInstance::standalone(model.clone()),
            FixedDrawList,
            Transform::from_translation(at),
        ));
        if let Some(list) = list {
            e.insert(list);
        }
    }
}

fn species(name: &str) -> TreeModel {
    let path = crate::assets::root().join(format!("species/{name}.species.ron"));
    let path = path.display();
    let text = std::fs::read_to_string(path.to_string()).unwrap_or_else(|e| panic!("{path}: {e}"));
    SpeciesDesc::from_ron_str(&text)
        .and_then(|s| Ok(s.generate_and_analyze()?.model))
        .unwrap_or_else(|e| panic!("{path}: {e}"))
}

/// Grid positions, `n` of them, `spacing` apart, centred on the origin.
fn grid(n: usize, spacing: f32) -> Vec<Vec3> {
    let side = (n as f32).sqrt().ceil() as usize;
    let half = (side as f32 - 1.0) * spacing / 2.0;
    (0..n)
        .map(|i| {
            Vec3::new(
                (i % side) as f32 * spacing - half,
                0.0,
                (i / side) as f32 * spacing - half,
            )
        })
        .collect()
}

/// The thick half of the trunk as triangles, the thin half as lines 1–4 px wide by
/// thickness, and in every leaf group the near half as triangles, the far half as
/// 3-pixel points.
fn all_kinds(model: &TreeModel) -> TreeDrawList {
    let segments = model.segments.len() as u32;
    let thin = segments / 2;
    let first_triangle = model.segments.triangle_offsets[thin as usize];
    let mut list = TreeDrawList {
        trunk_triangles: first_triangle..model.trunk_triangle_count() as u32,
        ..default()
    };
    for w in 0..4 {
        list.trunk_lines.push(LineRun {
            segments: thin * w / 4..thin * (w + 1) / 4,
            width: w + 1,
        });
    }
    for group in &model.leaf_groups {
        let mid = group.leaves.start + group.leaves.len() as u32 / 2;
        list.leaf_triangles.push(group.leaves.start..mid);
        list.leaf_points.push(PointRun {
            leaves: mid..group.leaves.end,
            size: 3,
        });
    }
    list
}

fn picture(path: &Path) {
    let mut bench = Bench::new();
    let model = species("grand");
    let list = all_kinds(&model);
    let height = model.bounds.max.y;
    let handle = bench.add_model(model);
    bench.tree(&handle, Vec3::ZERO, Some(list));
    bench.camera(
        Vec3::new(0.0, height * 0.5, height * 1.45),
        Vec3::new(0.0, height * 0.5, 0.0),
    );
    bench.measure(3);
    let path = path.to_owned();
    let image = bench.image.clone();
    bench
        .app
        .world_mut()
        .spawn(Screenshot::image(image))
        .observe(save_to_disk(path.clone()));
    for _ in 0..10 {
        bench.frame();
    }
    println!("wrote {}", path.display());
}

/// The pass benchmark's command line.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Instead of measuring, save a picture of a tree drawn in all four primitive kinds.
    #[arg(long, value_name = "FILE.png")]
    picture: Option<PathBuf>,
}

/// Runs the pass benchmark.
pub fn run(args: Args) -> ExitCode {
    match &args.picture {
        Some(path) => picture(path),
        None => benchmark(),
    }
    ExitCode::SUCCESS
}

fn benchmark() {
    let mut bench = Bench::new();
    let models: Vec<TreeModel> = ["slender", "broad", "grand"]
        .into_iter()
        .map(species)
        .collect();
    let handles: Vec<Handle<TreeModel>> =
        models.iter().map(|m| bench.add_model(m.clone())).collect();
    let frames = 15;

    // 1. The pass against Bevy's standard mesh path, same triangles.
    let trees = 150;
    let positions = grid(trees, 14.0);
    let eye = Vec3::new(0.0, 90.0, 150.0);
    bench.camera(eye, Vec3::ZERO);
    for (i, &at) in positions.iter().enumerate() {
        bench.tree(&handles[i % 3], at, None);
    }
    let pass_ms = bench.measure(frames);
    let pass_stats = bench.stats();
    bench.clear();
    bench.camera(eye, Vec3::ZERO);
    {
        let world = bench.app.world_mut();
        let meshes: Vec<(Handle<Mesh>, Handle<Mesh>)> = models
            .iter()
            .map(|m| {
                let mut assets = world.resource_mut::<Assets<Mesh>>();
                (assets.add(m.trunk_mesh()), assets.add(m.leaf_mesh()))
            })
            .collect();
        let mut materials = world.resource_mut::<Assets<StandardMaterial>>();
        let (bark, leaf) = (
            materials.add(StandardMaterial {
                base_color: Color::srgb(0.3, 0.2, 0.12),
                ..default()
            }),
            materials.add(StandardMaterial {
                base_color: Color::srgb(0.2, 0.45, 0.12),
                double_sided: true,
                cull_mode: None,
                ..default()
            }),
        );
        for (i, &at) in positions.iter().enumerate() {
            let (trunk, leaves) = meshes[i % 3].clone();
            let t = Transform::from_translation(at);
            world.spawn((SceneEntity, Mesh3d(trunk), MeshMaterial3d(bark.clone()), t));
            world.spawn((SceneEntity, Mesh3d(leaves), MeshMaterial3d(leaf.clone()), t));
        }
    }
    let standard_ms = bench.measure(frames);
    bench.clear();
    let empty_ms = {
        bench.camera(eye, Vec3::ZERO);
        let ms = bench.measure(frames);
        bench.clear();
        ms
    };
    println!(
        "full detail, {trees} trees, {} triangles, {WIDTH}x{HEIGHT}:",
        pass_stats.counts.triangles
    );
    println!("  empty frame            {empty_ms:8.1} ms");
    println!(
        "  forest pass            {pass_ms:8.1} ms  ({} draw calls; pass GPU time {})",
        pass_stats.draw_calls_per_view,
        pass_stats
            .gpu_time_ms
            .map_or("not measured".into(), |t| format!("{t:.1} ms"))
    );
    println!(
        "  Bevy standard meshes   {standard_ms:8.1} ms  (pass / standard = {:.2}, above empty {:.2})",
        pass_ms / standard_ms,
        (pass_ms - empty_ms) / (standard_ms - empty_ms)
    );

    // 2. Cost per primitive: slope between 30 and 120 instances of the grand tree.
    let grand = &models[2];
    let segments = grand.segments.len() as u32;
    let leaves = grand.leaves.len() as u32;
    let mut configs: Vec<(String, TreeDrawList)> =
        vec![("triangle".into(), TreeDrawList::full(grand))];
    for w in [1, 4, 10, 20] {
        configs.push((
            format!("line {w:>2} px"),
            TreeDrawList {
                trunk_lines: vec![LineRun {
                    segments: 0..segments,
                    width: w,
                }],
                ..default()
            },
        ));
    }
    for s in [1, 4, 10, 20] {
        configs.push((
            format!("point {s:>2} px"),
            TreeDrawList {
                leaf_points: vec![PointRun {
                    leaves: 0..leaves,
                    size: s,
                }],
                ..default()
            },
        ));
    }
    println!("cost per primitive (slope between 30 and 120 grand trees, 6 m apart):");
    for (name, list) in configs {
        let mut points = Vec::new();
        for n in [30, 120] {
            bench.camera(Vec3::new(0.0, 60.0, 110.0), Vec3::new(0.0, 8.0, 0.0));
            for at in grid(n, 6.0) {
                bench.tree(&handles[2], at, Some(list.clone()));
            }
            let ms = bench.measure(frames);
            let c = bench.stats().counts;
            points.push((ms, (c.triangles + c.lines + c.points) as f64));
            bench.clear();
        }
        let (a, b) = (points[0], points[1]);
        let slope_us = (b.0 - a.0) / (b.1 - a.1) * 1000.0;
        println!(
            "  {name:<12} {slope_us:7.3} µs each  ({:.0} → {:.0} primitives: {:.1} → {:.1} ms)",
            a.1, b.1, a.0, b.0
        );
    }

    // 3. Many trees in every primitive kind: draw calls stay at four.
    let n = 2000;
    bench.camera(Vec3::new(0.0, 150.0, 260.0), Vec3::ZERO);
    for (i, at) in grid(n, 6.0).into_iter().enumerate() {
        let list = all_kinds(&models[i % 3]);
        bench.tree(&handles[i % 3], at, Some(list));
    }
    let ms = bench.measure(5);
    let stats = bench.stats();
    println!(
        "{n} trees in all four kinds: {ms:.1} ms, {} draw calls per view, chunks {:?}, {} triangles, {} lines, {} points",
        stats.draw_calls_per_view,
        stats.chunks,
        stats.counts.triangles,
        stats.counts.lines,
        stats.counts.points
    );
}
