//! The measurement harness's shared pieces, apart from the crate: frame-time statistics
//! in the paper's terms, the forest example's `--record` files read back, tree-ID colours
//! for image quality at equal time, and the large-forest report. Used by the examples that
//! measure (`forest`, `results`, `cost_report`, `cost_replay`, `quality`); not published.

pub mod frame_stats;
pub mod large_forest;
pub mod quality;
pub mod record;
