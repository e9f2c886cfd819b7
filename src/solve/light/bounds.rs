//! Clipped channels as lower bounds in the lighting step (a censored, one-sided data term;
//! Tobin 1958 for the censored regression, here its least-squares form; docs/method.md,
//! "Clipped channels as lower bounds").
//!
//! Channel `c` of an observation whose recorded `y_c` is a lower bound
//! ([`crate::observe::Observations::clipped`]) contributes `α ω (y_c − ŷ_c)²` while the
//! prediction `ŷ_c` is below it and nothing once `ŷ_c ≥ y_c`: its `ω` is set to 0 there.
//! Each pass's weighted solve then minimises the squared hinge `max(0, y_c − ŷ_c)²` on the
//! set of active bounds, which is re-read before every pass from the light the pass starts
//! at ([`super::photo::pass_weights`]); the material step keeps the lighting step's last set.

use std::ops::Range;

use crate::observe::Observations;

/// The clipped channels of the observations in `range`, or empty when none of weight
/// `α > 0` has one: the fit reads bounds only when
/// [`crate::solve::EstimateOptions::clipped_bounds`] gave them their weight.
pub(crate) fn clipped_in(obs: &Observations, range: Range<usize>) -> Vec<u8> {
    let any = !obs.clipped.is_empty()
        && range
            .clone()
            .any(|p| obs.clipped[p] != 0 && obs.weight[p] > 0.0);
    if any {
        range.map(|p| obs.clipped[p]).collect()
    } else {
        Vec::new()
    }
}

/// `ω = 0` for every channel of `clipped` (bit `c` per observation) whose prediction `pred`
/// is at or above its recorded bound `y` (module docs); the other weights as they are.
pub(crate) fn censor(clipped: &[u8], y: &[[f64; 3]], pred: &[[f64; 3]], omega: &mut [[f64; 3]]) {
    for (q, &mask) in clipped.iter().enumerate() {
        for c in (0..3).filter(|c| mask & (1 << c) != 0) {
            if pred[q][c] >= y[q][c] {
                omega[q][c] = 0.0;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bit 0 of the first observation is a bound met (0.9 ≥ 0.8): its ω goes to 0; bit 1
    /// of the second is missed (0.3 < 0.8): kept; unflagged channels keep theirs even when
    /// over-predicted.
    #[test]
    fn censor_zeroes_only_the_bounds_already_met() {
        let y = [[0.8; 3]; 2];
        let pred = [[0.9, 0.9, 0.1], [0.9, 0.3, 0.9]];
        let mut omega = [[0.5; 3]; 2];
        censor(&[0b001, 0b010], &y, &pred, &mut omega);
        assert_eq!(omega, [[0.0, 0.5, 0.5], [0.5, 0.5, 0.5]]);
    }
}
