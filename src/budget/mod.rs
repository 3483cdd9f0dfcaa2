//! The budget algorithms: pure functions over slices and plain numbers, no ECS.
//!
//! - [`ValueFunction`]: how much an object deserves (paper equations 8–11), or any
//!   [`ValueModel`] of your own.
//! - [`FrameTimeModel`]: the rendering time left in a target frame time once the logic
//!   is paid for (P-5..P-7, T-6.14), and [`combined_frame_time`] (T-6.1).
//! - Strategies, all behind [`BudgetStrategy`] so they are interchangeable:
//!   [`RobinHood`] (the default: never drops a visible object),
//!   [`FunkhouserSequin`] and [`FunkhouserIncremental`] (knapsack optimisers),
//!   [`TriangleBudget`] (the SRGGE greedy) and [`HierarchicalLod`] (Mason–Blake, which
//!   also solves a [`LodHierarchy`] of groups with impostors directly).
//! - [`deadline`]: where a frame's work should end on a display that waits for its
//!   vertical blank.
//! - [`oracle`]: the exact optimum of small instances and the LP bound of any instance.
//!
//! ```
//! use bevy_sherwood::budget::*;
//!
//! let mut problem = BudgetProblem::new();
//! // A near trunk (valuable) and a far one; ladders run best → cheapest, costs in seconds.
//! let ladder = [Level::new(0.004, 1.0), Level::new(0.002, 0.7), Level::new(0.0005, 0.3)];
//! for value in [3.0, 1.0] {
//!     let desc = ObjectDesc { value, complexity: 0.004, ..Default::default() };
//!     problem.push_object(desc, &ladder).unwrap();
//! }
//! let rendering_time = FrameTimeModel::default().rendering_time(0.002, 0.01);
//! let mut allocations = Vec::new();
//! let stats = RobinHood::new().distribute(&problem, rendering_time, &mut allocations);
//! assert_eq!(stats.dropped, 0);
//! assert!(allocations[0].level <= allocations[1].level); // the near trunk gets more detail
//! ```

pub mod deadline;
mod frame_model;
mod funkhouser;
mod heap;
mod hierarchical;
mod hull;
pub mod oracle;
mod problem;
mod robin_hood;
mod triangle_budget;
mod value;

pub use frame_model::{FrameTimeModel, combined_frame_time};
pub use funkhouser::{FunkhouserIncremental, FunkhouserSequin, ValueOrdering};
pub use hierarchical::{
    HierarchicalLod, HierarchyError, HierarchyOutcome, LodHierarchy, NodeId, NodeSelection,
};
pub use problem::{
    Allocation, BudgetInputError, BudgetProblem, BudgetStats, BudgetStrategy, Level, ObjectDesc,
    PreviousSelection,
};
pub use robin_hood::{
    Fit, LadderCosts, RESIDUE_FRACTION, RESIDUE_PASSES, RobinHood, fit_continuous, fit_ladder,
};
pub use triangle_budget::TriangleBudget;
pub use value::{MIN_DEPTH, ValueFunction, ValueInputs, ValueModel, finite_value};
