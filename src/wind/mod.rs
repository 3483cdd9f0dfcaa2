//! Spring-driven wind (thesis chapter 5). This release holds the springs; association
//! of rings with springs, the motion of the ring hierarchy and its level of detail come
//! with the wind stage.

mod spring;

pub use spring::{FixedStepper, GustDesc, Spring, SpringDesc, WindDesc};
