//! The ground every stage stands on: the [`SherwoodSystems`] sets that order the stages
//! of a frame, and the check that names a missing plugin.

use bevy::ecs::schedule::SystemSet;
use bevy::prelude::*;
use bevy::transform::TransformSystems;

/// The stages of one Sherwood frame, chained in this order in [`PostUpdate`], after
/// transform propagation (and, with the `render` feature, after camera frusta update).
///
/// Every stage reads what the stages before it wrote this frame, so user systems can be
/// ordered against any stage, e.g. `.before(SherwoodSystems::Budget)`. Three reads reach
/// a later stage's result of the frame before, each on purpose:
///
/// * **Animate ← Cull**: the wind steps the springs of the trees last frame's culling saw
///   (or that are near the view); this frame's culling then bounds them where they sway.
/// * **Value ← Budget, the last cut**: with [`StrategyKind::Hierarchical`](crate::lod::StrategyKind::Hierarchical)
///   only the trees last frame's cut can open to this frame are valued.
/// * **Value ← Budget, far trees**: with [`FrameBudget::far_refresh`](crate::lod::FrameBudget::far_refresh)
///   above 1, a far tree not on its turn keeps its last decision.
#[derive(SystemSet, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SherwoodSystems {
    /// The instance table ([`ForestInstances`](crate::instance::ForestInstances)): trees
    /// spawned, despawned and moved since the last frame.
    Instances,
    /// Wind: springs step and move the rings of instances that are visible or near the view.
    Animate,
    /// Box-hierarchy culling: which instances, trunks and leaf groups are visible.
    Cull,
    /// A value per visible object (trunk and leaves of each tree) from the value function.
    Value,
    /// Logic-time estimate and rendering time; the strategy hands out time, and each
    /// object chooses the representation that fits what it was given.
    Budget,
    /// The chosen representations become the instances' draw lists.
    DrawLists,
    /// Predicted against measured times, counts, and frame statistics.
    Stats,
}

/// Chains the [`SherwoodSystems`] sets after transform propagation (and, with the
/// `render` feature, after camera frusta update).
pub(crate) fn configure_sets(app: &mut App) {
    app.configure_sets(
        PostUpdate,
        (
            SherwoodSystems::Instances,
            SherwoodSystems::Animate,
            SherwoodSystems::Cull,
            SherwoodSystems::Value,
            SherwoodSystems::Budget,
            SherwoodSystems::DrawLists,
            SherwoodSystems::Stats,
        )
            .chain()
            .after(TransformSystems::Propagate),
    );
    #[cfg(feature = "render")]
    app.configure_sets(
        PostUpdate,
        SherwoodSystems::Instances.after(bevy::camera::visibility::VisibilitySystems::UpdateFrusta),
    );
}

/// Stops start-up with a message naming the missing plugin, instead of a missing-resource
/// panic deep inside a system on the first frame.
///
/// Called from the `finish` of a plugin that needs `P` (plugins may be added in any order
/// until then); for Bevy's `AssetPlugin`, which must come first, from `build`.
pub(crate) fn require_plugin<P: Plugin>(app: &App, plugin: &str, needed: &str) {
    if !app.is_plugin_added::<P>() {
        panic!(
            "bevy_sherwood: {plugin} needs {needed}, which is not added. `SherwoodPlugins` adds \
             every Sherwood plugin; Bevy's `AssetPlugin` comes with `DefaultPlugins`, or add \
             `AssetPlugin::default()` next to `MinimalPlugins` (before the Sherwood plugins)."
        );
    }
}
