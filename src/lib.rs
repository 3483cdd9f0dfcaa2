#![doc = include_str!("../README.md")]
#![warn(missing_docs)]

pub mod budget;
pub mod cost;
pub mod culling;
pub mod draw;
pub mod ecosystem;
pub mod lod;
#[cfg(feature = "render")]
pub mod render;
pub mod tree;
pub mod view;
pub mod wind;

mod rng;

/// How every RON file of the crate is read: optional fields may be written bare
/// (`knots_x: [...]`) or as `Some(...)`.
pub(crate) fn ron_options() -> ron::Options {
    ron::Options::default().with_default_extension(ron::extensions::Extensions::IMPLICIT_SOME)
}

use bevy::app::{PluginGroup, PluginGroupBuilder};
use bevy::ecs::schedule::SystemSet;
use bevy::prelude::*;
use bevy::transform::TransformSystems;

/// The most used items: `use bevy_sherwood::prelude::*;`.
pub mod prelude {
    pub use crate::budget::{
        BudgetProblem, BudgetStats, BudgetStrategy, FrameTimeModel, Level, RobinHood, ValueFunction,
    };
    pub use crate::culling::{CullView, CullingDebug, CullingPlugin, ForestCulling};
    pub use crate::draw::{LineRun, PointRun, TreeDrawList, TreeShading};
    pub use crate::ecosystem::{Ecosystem, EcosystemPlugin, Forest, TreeInstance};
    pub use crate::lod::{FrameBudget, LodDiagnostics, LodMode, LodPlugin};
    #[cfg(feature = "render")]
    pub use crate::render::{ForestHud, ForestHudPlugin, ForestRenderPlugin, ForestRenderStats};
    pub use crate::tree::{SpeciesDesc, TreeModel, TreePlugin};
    pub use crate::view::LodView;
    pub use crate::{SherwoodCorePlugin, SherwoodPlugins, SherwoodSystems};
}

/// The stages of one Sherwood frame, chained in this order in [`PostUpdate`], after
/// transform propagation (and, with the `render` feature, after camera frusta update).
///
/// Every stage reads what the stages before it wrote and nothing after it, so user
/// systems can be ordered against any stage, e.g. `.before(SherwoodSystems::Budget)`.
#[derive(SystemSet, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SherwoodSystems {
    /// Wind: springs step and move the rings of instances that are visible or near the view.
    Animate,
    /// Box-hierarchy culling: which instances, trunks and leaf groups are visible.
    Cull,
    /// A value per visible object (trunk and leaves of each tree) from the value function.
    Value,
    /// Logic-time estimate, rendering time, and the strategy's time per object.
    Budget,
    /// Per object, the representation that fits its time; fills the draw lists.
    Select,
    /// Predicted against measured times, counts, and frame statistics.
    Stats,
}

/// Orders the [`SherwoodSystems`] sets. Every other Sherwood plugin relies on it;
/// [`SherwoodPlugins`] adds it first.
#[derive(Default)]
pub struct SherwoodCorePlugin;

impl Plugin for SherwoodCorePlugin {
    fn build(&self, app: &mut App) {
        app.configure_sets(
            PostUpdate,
            (
                SherwoodSystems::Animate,
                SherwoodSystems::Cull,
                SherwoodSystems::Value,
                SherwoodSystems::Budget,
                SherwoodSystems::Select,
                SherwoodSystems::Stats,
            )
                .chain()
                .after(TransformSystems::Propagate),
        );
        view::build(app);
        #[cfg(feature = "render")]
        app.configure_sets(
            PostUpdate,
            SherwoodSystems::Animate
                .after(bevy::camera::visibility::VisibilitySystems::UpdateFrusta),
        );
    }
}

/// Every Sherwood plugin. Stages arrive one plugin each; leave one out with
/// `SherwoodPlugins.build().disable::<ThePlugin>()`.
///
/// Needs Bevy's `AssetPlugin` (part of `DefaultPlugins`; add it next to `MinimalPlugins`
/// in a headless app).
pub struct SherwoodPlugins;

impl PluginGroup for SherwoodPlugins {
    fn build(self) -> PluginGroupBuilder {
        let group = PluginGroupBuilder::start::<Self>()
            .add(SherwoodCorePlugin)
            .add(cost::CostPlugin)
            .add(tree::TreePlugin)
            .add(ecosystem::EcosystemPlugin)
            .add(culling::CullingPlugin)
            .add(wind::WindPlugin)
            .add(lod::LodPlugin);
        #[cfg(feature = "render")]
        let group = group.add(render::ForestRenderPlugin);
        group
    }
}
