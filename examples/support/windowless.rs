//! A Bevy app that renders into images without a window, one frame per `app.update()`:
//! shared by the examples and render tests that drive frames themselves.

use bevy::app::{PluginGroupBuilder, PluginsState};
use bevy::prelude::*;
use bevy::render::RenderPlugin;
use bevy::render::pipelined_rendering::PipelinedRenderingPlugin;
use bevy::window::ExitCondition;
use bevy::winit::WinitPlugin;

/// Bevy's default plugins with no window (and no winit), pipelines compiled before the
/// frame that needs them, the render world updated on the calling thread, and assets read
/// from the crate's `assets/` wherever the binary is started.
pub fn windowless_plugins() -> PluginGroupBuilder {
    DefaultPlugins
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
        .disable::<WinitPlugin>()
        .disable::<PipelinedRenderingPlugin>()
}

/// Completes plugin set-up (including the renderer's asynchronous start), which
/// `App::run` would otherwise do, so that `app.update()` can be called directly.
pub fn finish_plugins(app: &mut App) {
    while app.plugins_state() == PluginsState::Adding {
        bevy::tasks::tick_global_task_pools_on_main_thread();
    }
    app.finish();
    app.cleanup();
}
