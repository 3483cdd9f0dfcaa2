//! Spring-driven wind (thesis chapter 5): springs, rings associated with springs, and
//! the ring offsets of a moving tree. The ECS stage (spring-set assets, motion level of
//! detail, the renderer's ring-offset table) comes with the wind stage.

mod asset;
mod motion;
mod spring;

pub use asset::{SpringSet, SpringSetError, SpringSetLoader, WindPlugin};
pub use motion::{AssociationRule, RingMotion, associate, moved_bounds, ring_offsets};
pub use spring::{FixedStepper, GustDesc, Spring, SpringDesc, WindDesc};
