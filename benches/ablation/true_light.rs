//! The albedo ratios the photos allow when the light is known (`ABLATION_TRUE_LIGHT=1`):
//! the material step (paper Eq. 11–12: `λ` by least squares, then each vertex's `w` by
//! NNLS) with every training photo's map held at the TRUE one (the case's map at the
//! transport's resolution), so that the free map per photo, the alternation and early
//! stopping play no part. What is left are the photos (noise, 8 bits, the reference
//! renderer's sampling) seen through the estimator's transport.
//!
//! Three fits, each scored by the ablation's worst diffuse albedo ratio error per channel
//! ([`ratio_errors`]):
//! - **λ with the true weights**: one `λ` step, the weights held at the truth's;
//! - **from the truth**: 30 `λ` / `w` sweeps from the true materials;
//! - **from the k-means start**: 30 sweeps from the bench's start ([`crate::fit_start`]).
//!
//! Every observation weighs `α_p` (no IRLS): with the light known nothing is down-weighted.
//! The fit from the truth is the floor the tables quote ([`RatioFloor::worst`]): noise-free
//! it is 0 to the third decimal, so what it measures on the 8-bit photos is what they hold
//! of the ratios through this transport, whatever the light model.

use crate::metrics::ratio_errors;
use crate::synth_case::*;
use relight_cpc::solve::materials::LambdaCoupling;
use relight_cpc::solve::{basis_responses, lambda_step, weights_step, Materials0};

/// Sweeps of the two alternating fits.
const SWEEPS: usize = 30;

/// Per channel, the worst ratio errors of the three fits (module docs).
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct RatioFloor {
    pub true_weights: [f64; 3],
    pub from_truth: [f64; 3],
    pub from_start: [f64; 3],
}

impl RatioFloor {
    /// The floor the tables quote: the worst channel of the fit from the truth.
    pub fn worst(&self) -> f64 {
        worst(self.from_truth)
    }
}

/// The largest of three errors.
pub fn worst(r: [f64; 3]) -> f64 {
    r.iter().fold(0.0_f64, |a, &b| a.max(b))
}

/// The three fits of the module docs; `seen`: the vertices the ratios are taken over.
pub fn ratio_floor(case: &Case, seen: &[bool]) -> RatioFloor {
    let problem = case.train.problem(case.nv);
    let s = basis_responses(&problem, &case.train.lights);
    let dw: Vec<[f64; 3]> = case
        .train
        .obs
        .weight
        .iter()
        .map(|&a| [f64::from(a); 3])
        .collect();
    let kk = case.lambda.len();
    let coupling = LambdaCoupling {
        achromatic_except: None,
    };
    let lambda_of = |weights: &[f64]| {
        lambda_step(&problem, &s, weights, kk, &dw, None, 1e-8, coupling)
            .expect("λ step")
            .lambda
    };
    let sweeps = |m: Materials0| {
        let (mut lambda, mut weights) = (m.lambda, m.weights);
        for _ in 0..SWEEPS {
            lambda = lambda_of(&weights);
            weights = weights_step(&problem, &s, &lambda, &weights, &dw, None, None)
                .expect("w step")
                .weights;
        }
        ratio_errors(case, &lambda, &weights, seen)
    };
    RatioFloor {
        true_weights: ratio_errors(case, &lambda_of(&case.weights), &case.weights, seen),
        from_truth: sweeps(case.true_materials()),
        from_start: sweeps(crate::starts::fit_start(case)),
    }
}

/// The floor in a sentence for the table's floor line.
pub fn describe(f: &RatioFloor) -> String {
    let r = |v: [f64; 3]| format!("{:.3} / {:.3} / {:.3}", v[0], v[1], v[2]);
    format!(
        "worst albedo ratio error with the true maps (the material step alone, {SWEEPS} sweeps from the truth; R / G / B) {:.3} ({}; λ with the true weights {}; from the k-means start {})",
        f.worst(),
        r(f.from_truth),
        r(f.true_weights),
        r(f.from_start)
    )
}
