//! Spring-driven wind (thesis chapter 5): springs, rings associated with springs, the
//! ring offsets of a moving tree, and the stage that computes them every frame into the
//! [`RingOffsetTable`] the renderer applies.

mod asset;
mod motion;
mod plugin;
mod spring;
mod table;

pub use asset::{MAX_WIND_DISPLACEMENT, SpringSet, SpringSetError, SpringSetLoader};
pub use motion::{
    AssociationRule, RingMotion, WindRig, associate, moved_bounds, ring_offsets, update_interval,
};
pub use plugin::{WindPlugin, WindSettings, WindStats};
pub use spring::{FixedStepper, GustDesc, Spring, SpringDesc, WindDesc};
pub use table::RingOffsetTable;
