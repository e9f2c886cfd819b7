//! The data weights of one pass of a lighting step: IRLS (Huber or Tukey on residuals
//! scaled by `σ = max(1.4826 · MAD, robust_floor · rms(y))`, module docs of
//! [`super::photo`]) and the clipped channels' bounds ([`super::bounds`]), both read from
//! the prediction of the light the pass starts at.

use crate::solve::light::photo::{predict_all, PhotoData};
use crate::solve::light::system::PhotoSystem;
use crate::solve::options::{EstimateOptions, Robust};
use crate::solve::problem::Problem;

/// `ω(r)` of a residual `r` at scale `σ`: 1 without a robust loss, Huber's `min(1, kσ/|r|)`,
/// Tukey's biweight `(1 − (r/cσ)²)²` inside `cσ` and 0 outside.
pub(crate) fn robust_weight(robust: Robust, r: f64, sigma: f64) -> f64 {
    match robust {
        Robust::None => 1.0,
        Robust::Huber { k } => {
            let t = k * sigma;
            if r.abs() <= t {
                1.0
            } else {
                t / r.abs()
            }
        }
        Robust::Tukey { c } => {
            let u = r / (c * sigma);
            if u.abs() < 1.0 {
                (1.0 - u * u).powi(2)
            } else {
                0.0
            }
        }
    }
}

/// A pass's data weights `ω` from the texels `x` it starts at: IRLS ([`robust_weights`])
/// when `reweigh`, else as they are; then the bounds already met set to 0
/// ([`super::bounds::censor`]). One prediction serves both; none is made when neither
/// needs it (no reweighing, and no bounds or a zero start, which meets none).
#[allow(clippy::too_many_arguments)]
pub(super) fn pass_weights(
    problem: &Problem,
    beta: &[[f64; 3]],
    sys: &PhotoSystem,
    x: &[f64],
    data: &PhotoData,
    opts: &EstimateOptions,
    reweigh: bool,
    omega: &mut [[f64; 3]],
) {
    let bounds = data.has_bounds() && x.iter().any(|&v| v != 0.0);
    if !(reweigh || bounds) {
        return;
    }
    let pred = predict_all(problem, beta, sys, x, data);
    if reweigh {
        robust_weights(&pred, data, opts, omega);
    }
    if bounds {
        super::bounds::censor(&data.clipped_all, &data.y_all, &pred, omega);
    }
}

/// IRLS weights from the predictions `pred` of every observation of the photo, per channel
/// scaled by `σ = max(1.4826 · MAD, robust_floor · rms(y))` (module docs).
fn robust_weights(
    pred: &[[f64; 3]],
    data: &PhotoData,
    opts: &EstimateOptions,
    omega: &mut [[f64; 3]],
) {
    let len = data.range.len();
    let (alpha, y) = (&data.alpha_all, &data.y_all);
    for c in 0..3 {
        let mut ab: Vec<f64> = (0..len)
            .filter(|&q| alpha[q] > 0.0)
            .map(|q| (y[q][c] - pred[q][c]).abs())
            .collect();
        if ab.is_empty() {
            continue;
        }
        let n_fit = ab.len();
        let mid = n_fit / 2;
        let (_, med, _) = ab.select_nth_unstable_by(mid, f64::total_cmp);
        let scale = y.iter().map(|v| v[c].abs()).sum::<f64>() / y.len() as f64;
        // The noise floor: a fraction of the RMS observed radiance (struct docs of
        // `EstimateOptions::robust_floor`).
        let rms = ((0..len)
            .filter(|&q| alpha[q] > 0.0)
            .map(|q| y[q][c] * y[q][c])
            .sum::<f64>()
            / n_fit as f64)
            .sqrt();
        let sigma = (1.4826 * *med)
            .max(opts.robust_floor * rms)
            .max(1e-9 * scale)
            .max(f64::MIN_POSITIVE);
        for q in 0..len {
            omega[q][c] = robust_weight(opts.robust, y[q][c] - pred[q][c], sigma);
        }
    }
}
