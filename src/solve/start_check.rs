//! What the alternation checks of its start before the first step ([`super::alternation`]):
//! the starting materials, and the starting lights of
//! [`super::alternation::estimate_from_lights`]. A start that fails is the caller's error
//! ([`Error::Internal`]), not the user's: `run` builds every start itself.

use crate::solve::{Materials0, Problem};
use crate::{Error, Result};

/// The starting materials must have `K ≥ 1` materials of `B` bases, `V·K` weights, all
/// finite and `≥ 0`.
pub(crate) fn materials(problem: &Problem, init: &Materials0) -> Result<()> {
    let nb = problem.transport.n_basis;
    let kk = init.lambda.len();
    let nv = problem.n_vertices;
    if kk == 0 || init.lambda.iter().any(|l| l.len() != nb) || init.weights.len() != nv * kk {
        return Err(Error::Internal(format!(
            "initial materials: {kk} materials with {:?} bases and {} weights, expected B = {nb}, V·K = {}",
            init.lambda.iter().map(|l| l.len()).collect::<Vec<_>>(),
            init.weights.len(),
            nv * kk
        )));
    }
    let values = init.lambda.iter().flatten().flatten().chain(&init.weights);
    if !finite_non_negative(values) {
        return Err(Error::Internal(
            "initial materials must be finite and non-negative".into(),
        ));
    }
    Ok(())
}

/// The starting lights must hold one map of `n_global²` finite, non-negative texels per
/// photo and channel.
pub(crate) fn lights(problem: &Problem, lights: &[[Vec<f64>; 3]]) -> Result<()> {
    let n2 = problem.transport.n_global.pow(2);
    if lights.len() != problem.n_photos || lights.iter().flatten().any(|m| m.len() != n2) {
        return Err(Error::Internal(format!(
            "starting lights: {} photos' maps, expected {} maps of {n2} texels per channel",
            lights.len(),
            problem.n_photos
        )));
    }
    if !finite_non_negative(lights.iter().flatten().flatten()) {
        return Err(Error::Internal(
            "starting lights must be finite and non-negative".into(),
        ));
    }
    Ok(())
}

/// Whether every value is finite and `≥ 0`.
fn finite_non_negative<'a>(mut values: impl Iterator<Item = &'a f64>) -> bool {
    values.all(|v| v.is_finite() && *v >= 0.0)
}
