//! Helpers for headless Sherwood apps, used by the crate's tests and benches (feature
//! `testing`): an app with every plugin and no window, a view without a camera, a forest
//! of any size, and waiting until it has loaded. The species and ecosystems named here are
//! the ones this crate ships under `assets/`.

use crate::culling::CullView;
use crate::prelude::*;
use crate::tree::SpeciesDesc;
pub mod workloads;

use bevy::asset::{AssetPlugin, LoadState};
use bevy::prelude::*;

/// A shipped species (`assets/species/NAME.species.ron`), generated and analysed.
pub fn species(name: &str) -> TreeModel {
    let path = format!(
        "{}/assets/species/{name}.species.ron",
        env!("CARGO_MANIFEST_DIR")
    );
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    SpeciesDesc::from_ron_str(&text)
        .unwrap()
        .generate_and_analyze()
        .unwrap()
        .model
}

/// A headless app with every Sherwood plugin, reading the crate's assets.
pub(crate) fn headless_app() -> App {
    let mut app = App::new();
    app.add_plugins((
        MinimalPlugins,
        AssetPlugin {
            file_path: concat!(env!("CARGO_MANIFEST_DIR"), "/assets").into(),
            ..Default::default()
        },
        TransformPlugin,
        SherwoodPlugins,
    ));
    app
}

/// A headless app that loads tree models from `dir`.
pub fn tree_app(dir: &std::path::Path) -> App {
    app_reading(dir, TreePlugin)
}

/// A headless app with `plugins` that reads its assets from the folder `dir`.
pub(crate) fn app_reading<M>(dir: &std::path::Path, plugins: impl bevy::app::Plugins<M>) -> App {
    let mut app = App::new();
    app.add_plugins((
        MinimalPlugins,
        AssetPlugin {
            file_path: dir.to_string_lossy().into_owned(),
            ..Default::default()
        },
    ))
    .add_plugins(plugins);
    app
}

/// Updates until the asset has loaded or failed (bounded).
pub fn settle<A: Asset>(app: &mut App, handle: &Handle<A>) -> LoadState {
    for _ in 0..2000 {
        app.update();
        let state = app
            .world()
            .resource::<AssetServer>()
            .load_state(handle.id());
        if matches!(state, LoadState::Loaded | LoadState::Failed(_)) {
            return state;
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    panic!("asset neither loaded nor failed");
}

/// The shipped default ecosystem (`assets/forests/default.ecosystem.ron`), parsed.
pub fn default_ecosystem() -> crate::ecosystem::EcosystemDesc {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/assets/forests/default.ecosystem.ron"
    ))
    .unwrap();
    crate::ecosystem::EcosystemDesc::from_ron_str(&text).unwrap()
}

/// Numbers uniform in [0, 1), the same stream on every call (xorshift64 from a fixed
/// seed): synthetic bench inputs that do not change between runs.
pub(crate) fn unit_noise() -> impl FnMut() -> f32 {
    let mut state = 0x9E37_79B9_7F4A_7C15_u64;
    move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 40) as f32 / (1u64 << 24) as f32
    }
}

/// Spawns a forest of `desc` in `app`.
pub fn spawn_forest(app: &mut App, desc: crate::ecosystem::EcosystemDesc) -> Entity {
    let handle = app
        .world_mut()
        .resource_mut::<Assets<Ecosystem>>()
        .add(Ecosystem(desc));
    app.world_mut().spawn(Forest(handle)).id()
}

/// Plants one tree of the species file `species` (under `assets/species/`) at `at`, by
/// hand: in no ecosystem.
#[cfg(test)]
pub(crate) fn plant(app: &mut App, species: &str, at: Vec3) -> Entity {
    let model = app
        .world()
        .resource::<AssetServer>()
        .load(format!("species/{species}.species.ron"));
    app.world_mut()
        .spawn((TreeInstance::new(model), Transform::from_translation(at)))
        .id()
}

/// Fells the tree `planted` last (if any) and plants one of `model` at `at` in its
/// place: an app's gardener, one tree a frame.
pub fn replant(app: &mut App, planted: &mut Option<Entity>, model: &Handle<TreeModel>, at: Vec3) {
    if let Some(tree) = planted.take() {
        app.world_mut().despawn(tree);
    }
    let tree = (
        TreeInstance::new(model.clone()),
        Transform::from_translation(at),
    );
    *planted = Some(app.world_mut().spawn(tree).id());
}

/// A 320×180 camera rendering into an image from `eye` towards `target`, and a sun.
#[cfg(all(test, feature = "gpu-tests"))]
pub(crate) fn image_camera(app: &mut App, eye: Vec3, target: Vec3) {
    use bevy::camera::RenderTarget;
    use bevy::render::render_resource::TextureFormat;
    let world = app.world_mut();
    let image = Image::new_target_texture(320, 180, TextureFormat::Rgba8UnormSrgb, None);
    let image = world.resource_mut::<Assets<Image>>().add(image);
    world.spawn((
        Camera3d::default(),
        RenderTarget::Image(image.into()),
        Msaa::Off,
        Transform::from_translation(eye).looking_at(target, Vec3::Y),
    ));
    world.spawn(DirectionalLight::default());
}

/// The picture of the (first) camera rendering into an image, as RGBA bytes, once the
/// next frame has rendered.
#[cfg(all(test, feature = "gpu-tests"))]
pub(crate) fn screenshot(app: &mut App) -> Vec<u8> {
    use bevy::camera::RenderTarget;
    use bevy::render::view::screenshot::{Screenshot, ScreenshotCaptured};
    use std::sync::{Arc, Mutex};

    let image = app
        .world_mut()
        .query::<&RenderTarget>()
        .iter(app.world())
        .find_map(|target| match target {
            RenderTarget::Image(image) => Some(image.handle.clone()),
            _ => None,
        })
        .expect("an image camera");
    let captured: Arc<Mutex<Option<Vec<u8>>>> = Arc::default();
    let sink = captured.clone();
    app.world_mut().spawn(Screenshot::image(image)).observe(
        move |event: On<ScreenshotCaptured>| {
            *sink.lock().unwrap() = event.image.data.clone();
        },
    );
    for _ in 0..20 {
        app.update();
        if let Some(rgba) = captured.lock().unwrap().take() {
            return rgba;
        }
    }
    panic!("no screenshot");
}

/// A headless app with a forest of `trees` trees (the default forest's species, in equal
/// numbers, at its density) and a culling hierarchy 6 levels deep; returns it with the
/// terrain's side. No view yet: see [`look_from`].
pub fn forest_of(trees: u32) -> (App, f32) {
    let mut app = headless_app();
    let mut desc = default_ecosystem();
    let species = desc.species.len() as u32;
    for s in &mut desc.species {
        s.count = trees / species;
    }
    desc.terrain.size *= (trees as f32 / 600.0).sqrt();
    desc.culling_depth = 6;
    let size = desc.terrain.size;
    spawn_forest(&mut app, desc);
    (app, size)
}

/// Places the view (culling and LOD; 540 × 540 pixels, 1.2 rad vertical field of view) at
/// `eye` looking at `target`, spawning it the first time.
pub fn look_from(app: &mut App, eye: Vec3, target: Vec3) {
    look_from_screen(app, eye, target, 540.0, 540.0);
}

/// [`look_from`] on a screen of `width` × `height` pixels (the forest example's is
/// 960 × 540).
pub fn look_from_screen(app: &mut App, eye: Vec3, target: Vec3, width: f32, height: f32) {
    let fov = 1.2;
    let clip_from_world = Mat4::perspective_infinite_reverse_rh(fov, width / height, 0.1)
        * Mat4::look_at_rh(eye, target, Vec3::Y);
    let view = (
        CullView::from_clip_from_world(clip_from_world),
        LodView {
            position: eye,
            forward: (target - eye).normalize(),
            focal_pixels: height / (2.0 * (fov * 0.5).tan()),
            viewport_pixels: width * height,
        },
    );
    let world = app.world_mut();
    let existing = world
        .query_filtered::<Entity, With<CullView>>()
        .iter(world)
        .next();
    match existing {
        Some(entity) => {
            world.entity_mut(entity).insert(view);
        }
        None => {
            world.spawn(view);
        }
    }
}

/// Runs one frame and returns the cost model's prediction of it (kept until the frame is
/// measured).
#[cfg(test)]
pub(crate) fn predicted_frame(app: &mut App) -> crate::cost::FramePrediction {
    app.update();
    let frame = app.world().resource::<LodDiagnostics>().frame;
    *app.world()
        .resource::<CostModel>()
        .prediction(frame)
        .expect("every frame's prediction is kept until it is measured")
}

/// Updates until the LOD stages see a tree (bounded).
pub fn until_visible(app: &mut App) {
    for _ in 0..20_000 {
        app.update();
        let loading = app
            .world()
            .resource::<crate::culling::ForestCulling>()
            .models_loading();
        if loading == 0 && app.world().resource::<LodDiagnostics>().visible_instances > 0 {
            return;
        }
        std::thread::sleep(std::time::Duration::from_millis(1));
    }
    panic!("the forest never loaded");
}

/// Spawns the default forest (600 trees) with fixed costs and no wind.
#[cfg(test)]
pub(crate) fn spawn_still_default_forest(app: &mut App) {
    // Fixed costs: tests compare selections across frames, which learned costs would
    // otherwise change (nothing is measured in a headless app, but say so).
    app.world_mut().resource_mut::<CostSettings>().online = false;
    // A still forest: swaying trees change their leaf groups' culling and pixel sizes, and
    // with them the floors, from one run to the next (the wind follows the real clock).
    app.world_mut().resource_mut::<WindSettings>().enabled = false;
    let handle = app
        .world()
        .resource::<AssetServer>()
        .load("forests/default.ecosystem.ron");
    app.world_mut().spawn(Forest(handle));
}

/// The default forest (600 trees), still and with fixed costs, seen from `eye` towards
/// `target` (1.4 rad wide, 16:9, 540 pixels high); `extra` spawns more before the first
/// frame. Returns once the forest is culled and in view.
#[cfg(test)]
pub(crate) fn default_forest_view(eye: Vec3, target: Vec3, extra: impl FnOnce(&mut App)) -> App {
    let mut app = headless_app();
    spawn_still_default_forest(&mut app);
    let clip_from_world = Mat4::perspective_infinite_reverse_rh(0.8, 16.0 / 9.0, 0.1)
        * Mat4::look_at_rh(eye, target, Vec3::Y);
    app.world_mut().spawn((
        CullView::from_clip_from_world(clip_from_world),
        LodView {
            position: eye,
            forward: (target - eye).normalize(),
            focal_pixels: 540.0 / (2.0 * (0.8f32 * 0.5).tan()),
            viewport_pixels: 540.0 * 540.0,
        },
    ));
    extra(&mut app);
    for _ in 0..3000 {
        app.update();
        let culling = app.world().resource::<crate::culling::ForestCulling>();
        if culling.hierarchy.is_some()
            && culling.models_loading() == 0
            && app.world().resource::<LodDiagnostics>().visible_instances > 0
        {
            return app;
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    panic!("the forest never finished loading");
}

/// `plugins` (Bevy's `DefaultPlugins` with `WinitPlugin` disabled, built by the caller,
/// who has winit) set up to render into images without a window, one frame per
/// `app.update()`: no primary window, pipelines compiled before the frame that needs them,
/// the render world updated on the calling thread, and assets read from this crate's
/// `assets/` wherever the binary is started. Call [`finish_plugins`] before the first
/// update.
#[cfg(feature = "render")]
pub fn windowless_plugins(plugins: bevy::app::PluginGroupBuilder) -> bevy::app::PluginGroupBuilder {
    use bevy::render::RenderPlugin;
    use bevy::render::pipelined_rendering::PipelinedRenderingPlugin;
    use bevy::window::ExitCondition;
    plugins
        .set(AssetPlugin {
            file_path: concat!(env!("CARGO_MANIFEST_DIR"), "/assets").into(),
            ..default()
        })
        .set(WindowPlugin {
            primary_window: None,
            exit_condition: ExitCondition::DontExit,
            close_when_requested: false,
            ..default()
        })
        .set(RenderPlugin {
            synchronous_pipeline_compilation: true,
            ..default()
        })
        .disable::<PipelinedRenderingPlugin>()
}

/// Completes plugin set-up (including the renderer's asynchronous start), which
/// `App::run` would otherwise do, so that `app.update()` can be called directly.
pub fn finish_plugins(app: &mut App) {
    while app.plugins_state() == bevy::app::PluginsState::Adding {
        bevy::tasks::tick_global_task_pools_on_main_thread();
    }
    app.finish();
    app.cleanup();
}

/// Held by the tests whose assertions depend on the machine's speed (real frame and logic
/// times, a calibration run): they run one at a time, as they did in their own test
/// binaries, so that one does not slow the other down while it measures.
#[cfg(test)]
pub(crate) fn measuring() -> std::sync::MutexGuard<'static, ()> {
    static MEASURING: std::sync::Mutex<()> = std::sync::Mutex::new(());
    MEASURING
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}
