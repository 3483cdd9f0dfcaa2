//! The plugin every other Sherwood plugin stands on: the stage order, the instance table
//! and the view.

use bevy::prelude::*;

use crate::instance::{ForestInstances, track_instances};
use crate::schedule::{SherwoodSystems, configure_sets};
use crate::view::LodView;

/// Orders the [`SherwoodSystems`] sets, keeps the instance table ([`ForestInstances`]) and
/// (with the `render` feature) a [`LodView`] on the camera the budget follows
/// ([`BudgetView`](crate::view::BudgetView)). Every other
/// Sherwood plugin relies on it; [`SherwoodPlugins`](crate::SherwoodPlugins) adds it
/// first.
#[derive(Default)]
pub struct SherwoodCorePlugin;

impl Plugin for SherwoodCorePlugin {
    fn build(&self, app: &mut App) {
        configure_sets(app);
        crate::display::build(app);
        app.init_resource::<ForestInstances>()
            .register_type::<LodView>()
            .register_type::<crate::instance::TreeInstance>()
            .register_type::<ForestInstances>()
            .register_type::<crate::instance::FixedDrawList>()
            .register_type::<crate::view::BudgetView>()
            .add_systems(
                PostUpdate,
                track_instances.in_set(SherwoodSystems::Instances),
            );
        #[cfg(feature = "render")]
        app.add_systems(
            PostUpdate,
            crate::view::update_lod_views.before(SherwoodSystems::Instances),
        );
    }
}

/// For a plugin that indexes the instance table, from its `build`: the table exists
/// (empty) without [`SherwoodCorePlugin`], so the app runs; [`warn_without_core`] names
/// the missing plugin once plugins are added.
pub(crate) fn use_instance_table(app: &mut App) {
    app.init_resource::<ForestInstances>();
}

/// From the `finish` of a plugin that indexes the instance table: nothing keeps the table
/// without [`SherwoodCorePlugin`].
pub(crate) fn warn_without_core(app: &App, plugin: &str) {
    if !app.is_plugin_added::<SherwoodCorePlugin>() {
        warn!(
            "bevy_sherwood: {plugin} without SherwoodCorePlugin: no tree enters the instance \
             table, so none is culled, budgeted or drawn by it"
        );
    }
}
