//! The crate's tests that reach its internals: the algorithms on their own (culling,
//! budgets, cost models, selection, wind) and apps whose internal state a test reads.
//! Tests of the public API alone are in `tests/`.

mod app_faults;
mod bad_input;
mod budget_properties;
mod calibration_run;
mod cost_learning;
mod cost_model;
mod culling;
mod draw_list;
mod ecosystem;
mod forest_app;
mod fuzz;
mod hierarchical;
mod instances;
mod ladders;
mod lod_app;
mod lod_select;
#[cfg(feature = "gpu-tests")]
mod near_view;
mod render_pass;
mod tree_analysis;
mod tree_gltf;
mod wind_motion;
