#![doc = include_str!("../README.md")]
#![warn(missing_docs)]

pub(crate) mod budget;
pub mod cost;
pub mod culling;
pub mod display;
pub mod draw;
pub mod ecosystem;
pub mod instance;
#[cfg(feature = "render")]
pub mod ladder;
pub mod lod;
#[cfg(feature = "render")]
pub mod render;
#[cfg(any(test, feature = "testing"))]
pub mod testing;
pub mod tree;
pub mod view;
pub mod wind;

mod core_plugin;
mod rng;
mod ron_file;
mod schedule;
#[cfg(test)]
mod tests;

pub use core_plugin::SherwoodCorePlugin;
pub use ron_file::FieldError;
pub use schedule::SherwoodSystems;

use bevy::app::{PluginGroup, PluginGroupBuilder};

/// What an app author uses: `use bevy_sherwood::prelude::*;`. Settings and reports
/// beyond these are in their stages' modules ([`cost`], [`wind`], …).
pub mod prelude {
    pub use crate::cost::{
        CalibrationChoice, CalibrationNotFound, CostModel, CostPlugin, CostSettings,
    };
    pub use crate::culling::{CullingDebug, CullingPlugin};
    #[cfg(feature = "render")]
    pub use crate::display::EmulatedVsyncPlugin;
    pub use crate::display::{DisplayTiming, VsyncMode, VsyncSettings};
    pub use crate::draw::{TreeDrawList, TreeShading};
    pub use crate::ecosystem::{Ecosystem, EcosystemPlugin, Forest};
    pub use crate::instance::{FixedDrawList, ForestInstances, TreeInstance};
    #[cfg(feature = "render")]
    pub use crate::ladder::{
        LadderDiagnostics, LadderFromLodNames, LadderImportance, LadderLevelChanged, LadderPlugin,
        LadderSettings, LodLadder, generate_ladder,
    };
    pub use crate::lod::ValueFunction;
    pub use crate::lod::{
        FrameBudget, FrameGoal, LodDiagnostics, LodDiagnosticsPlugin, LodMode, LodPlugin,
        OverrunCut, SteadySelection, StrategyKind, TargetUnreachable, Unreachable,
    };
    #[cfg(feature = "hud")]
    pub use crate::render::{ForestHud, ForestHudPlugin};
    #[cfg(feature = "render")]
    pub use crate::render::{ForestRenderPlugin, ForestRenderStats};
    pub use crate::tree::{TreeModel, TreePlugin};
    pub use crate::view::{BudgetView, LodView};
    pub use crate::wind::{WindPlugin, WindSettings};
    pub use crate::{SherwoodCorePlugin, SherwoodPlugins, SherwoodSystems};
}

/// Every Sherwood plugin. Stages arrive one plugin each; leave one out with
/// `SherwoodPlugins.build().disable::<ThePlugin>()`.
///
/// | plugin | what it adds | needs |
/// |---|---|---|
/// | [`SherwoodCorePlugin`] | the [`SherwoodSystems`] order, the instance table ([`instance::ForestInstances`]), [`view::LodView`] from cameras, the display's timing ([`display::DisplayTiming`]) | — |
/// | [`cost::CostPlugin`] | frame measurement, the calibration and the learning [`cost::CostModel`] | — |
/// | [`tree::TreePlugin`] | tree assets: species (`*.species.ron`), saved models, glTF trees | `AssetPlugin` |
/// | [`ecosystem::EcosystemPlugin`] | ecosystems (`*.ecosystem.ron`): a [`ecosystem::Forest`] spawns its trees and terrain | `AssetPlugin`, `TreePlugin` |
/// | [`culling::CullingPlugin`] | the box hierarchy over every instance, culled against the view | `TreePlugin` |
/// | [`wind::WindPlugin`] | springs, ring offsets and the wind's motion LOD | `AssetPlugin`, `TreePlugin`, `CullingPlugin` |
/// | [`lod::LodPlugin`] | value, budget and each instance's [`draw::TreeDrawList`] | `TreePlugin`, `CostPlugin` |
/// | `ladder::LadderPlugin` (feature `render`) | mesh entities with a `LodLadder` in the same hand-out, their chosen level shown | `LodPlugin` |
/// | `render::ForestRenderPlugin` (feature `render`) | the forest pass: triangles, lines and points in a few instanced draws | `TreePlugin` |
///
/// A missing prerequisite stops start-up with a message naming it. Bevy's `AssetPlugin`
/// is part of `DefaultPlugins`; add it next to `MinimalPlugins` in a headless app.
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
        let group = group
            .add(ladder::LadderPlugin)
            .add(render::ForestRenderPlugin);
        group
    }
}
