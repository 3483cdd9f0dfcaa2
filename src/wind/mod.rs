//! Spring-driven wind (thesis chapter 5): springs, rings associated with springs, the
//! ring offsets of a moving tree, and the stage that computes them every frame into the
//! `RingOffsetTable` the renderer applies.

mod asset;
mod motion;
mod plugin;
mod share;
mod spring;
mod table;

pub use asset::{SpringSet, SpringSetError};
pub use motion::AssociationRule;
#[cfg(test)]
pub(crate) use motion::update_interval;
#[cfg(any(test, feature = "testing"))]
pub(crate) use motion::{WindRig, associate, moved_bounds, ring_offsets};
pub use plugin::{WindPlugin, WindSettings, WindStats};
#[cfg(test)]
pub(crate) use share::shared_sway;

pub use spring::{GustDesc, SpringDesc, WindDesc};
#[cfg(any(test, feature = "render"))]
pub(crate) use table::RingOffsetTable;
