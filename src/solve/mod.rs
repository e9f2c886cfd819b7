//! The estimator's kernels (issue 24 moves the estimate here).

pub mod subsample;
