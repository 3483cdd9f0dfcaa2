//! Visibility: which instances, trunks and leaf groups the camera sees, through the
//! thesis' box hierarchy (`BoxHierarchy`).

mod hierarchy;
mod plugin;

#[cfg(test)]
pub(crate) use hierarchy::Containment;
#[cfg(any(test, feature = "render"))]
pub(crate) use hierarchy::transform_bounds;
pub(crate) use hierarchy::{
    BoxHierarchy, CullShape, FrustumPlanes, InstanceVisibility, MovedShapes, NodeVisibility,
};
#[cfg(any(test, feature = "testing"))]
pub(crate) use hierarchy::{CullInstance, CullResult, cull_brute_force};
pub use plugin::CullView;
#[cfg(test)]
pub(crate) use plugin::LOADING_WARNING_SECS;
pub use plugin::{CullingDebug, CullingPlugin, CullingSettings, ForestCulling};
