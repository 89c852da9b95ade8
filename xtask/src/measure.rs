//! Measurements the validation and the benchmarks take independently of the quantity under
//! test: those of `balloon-measure`, which the workspace's integration tests share.

pub use balloon_measure::*;
