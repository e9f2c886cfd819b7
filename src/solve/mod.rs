//! Solve: the estimator (paper Sec. 5) and what prepares and sizes it: the initial
//! materials (clustering), the non-negative QP solvers, the starts, the adaptive pilot and
//! the memory budget.

pub mod adapt;
pub mod budget;
pub mod cluster;
pub mod estimate;
pub mod qp;
pub mod starts;
