//! Visibility: which instances, trunks and leaf groups the camera sees, through the
//! thesis' box hierarchy ([`BoxHierarchy`]).

mod hierarchy;
mod plugin;

pub use hierarchy::{
    BoxHierarchy, Containment, CullInstance, CullResult, CullShape, FrustumPlanes,
    InstanceVisibility, MovedShapes, NodeVisibility, cull_brute_force, transform_bounds,
};
#[cfg(feature = "render")]
pub use plugin::FullyVisibleBoxes;
pub use plugin::{
    CullView, CullingDebug, CullingPlugin, CullingSettings, ForestCulling, LOADING_WARNING_SECS,
};
