//! The budget algorithms: pure functions over slices and plain numbers, no ECS. The
//! Budget stage ([`crate::lod`]) runs them; an app picks one with
//! [`StrategyKind`](crate::lod::StrategyKind).
//!
//! - [`ValueFunction`]: how much an object deserves (paper equations 8–11), or any
//!   [`ValueModel`].
//! - Strategies, all behind [`BudgetStrategy`] so they are interchangeable:
//!   [`RobinHood`] (the default: never drops a visible object),
//!   [`FunkhouserSequin`] and [`FunkhouserIncremental`] (knapsack optimisers),
//!   [`TriangleBudget`] (the SRGGE greedy) and [`HierarchicalLod`] (Mason–Blake, which
//!   also solves a [`LodHierarchy`] of groups with impostors directly).
//! - [`deadline`]: where a frame's work should end on a display that waits for its
//!   vertical blank.
//! - [`oracle`]: the exact optimum of small instances and the LP bound of any instance.

pub(crate) mod deadline;
mod funkhouser;
mod heap;
mod hierarchical;
mod hull;
pub(crate) mod oracle;
mod problem;
mod robin_hood;
mod triangle_budget;
mod value;

pub(crate) use funkhouser::{FunkhouserIncremental, FunkhouserSequin};

pub(crate) use hierarchical::{
    HierarchicalLod, HierarchyOutcome, LodHierarchy, NodeId, NodeSelection,
};

pub(crate) use problem::{
    Allocation, BudgetProblem, BudgetStats, BudgetStrategy, Level, ObjectDesc, PreviousSelection,
};
pub(crate) use robin_hood::Fit;
pub(crate) use robin_hood::RobinHood;

pub(crate) use triangle_budget::TriangleBudget;
pub use value::ValueFunction;
pub(crate) use value::{MIN_DEPTH, ValueInputs, ValueModel, finite_value};
