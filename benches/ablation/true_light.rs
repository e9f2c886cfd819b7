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
//!
//! The same fits give the material accuracy the known light allows: of the fit from the
//! truth, and of one weights step with the TRUE `λ` as well (each vertex's NNLS with
//! everything else known). Where two materials blend near evenly, the argmax that the
//! accuracy counts turns on a small difference of weights, so this is what the photos
//! hold of the blends, whatever the estimator.

use crate::metrics::{best_order_of, ratio_errors};
use crate::synth_case::*;
use relight_cpc::solve::materials::LambdaCoupling;
use relight_cpc::solve::{basis_responses, lambda_step, weights_step, Materials0, WeightsRules};

/// Sweeps of the two alternating fits.
const SWEEPS: usize = 30;

/// Per channel, the worst ratio errors of the three fits (module docs), and the material
/// accuracy the known light allows.
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct RatioFloor {
    pub true_weights: [f64; 3],
    pub from_truth: [f64; 3],
    pub from_start: [f64; 3],
    /// Material accuracy over the seen vertices of one weights step (each vertex's NNLS)
    /// with the TRUE `λ` and the true maps: what the photos hold of the blends when
    /// everything but the weights is known.
    pub accuracy_true_lambda: f64,
    /// Material accuracy of the fit from the truth (the ratio floor's fit).
    pub accuracy_from_truth: f64,
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
    ratio_floor_of(case, &case.train.obs, seen)
}

/// [`ratio_floor`] with the training photos' colours read from `obs` (the same
/// observations).
fn ratio_floor_of(
    case: &Case,
    obs: &relight_cpc::observe::Observations,
    seen: &[bool],
) -> RatioFloor {
    let problem = relight_cpc::solve::Problem {
        obs,
        ..case.train.problem(case.nv)
    };
    let s = basis_responses(&problem, &case.train.lights);
    let dw: Vec<[f64; 3]> = obs.weight.iter().map(|&a| [f64::from(a); 3]).collect();
    let kk = case.lambda.len();
    let coupling = LambdaCoupling {
        achromatic_except: None,
    };
    let lambda_of = |weights: &[f64]| {
        lambda_step(&problem, &s, weights, kk, &dw, None, 1e-8, coupling)
            .expect("λ step")
            .lambda
    };
    let weights_of = |lambda: &[Vec<[f64; 3]>], weights: &[f64]| {
        weights_step(&problem, &s, lambda, weights, &dw, WeightsRules::default())
            .expect("w step")
            .weights
    };
    let sweeps = |m: Materials0| {
        let (mut lambda, mut weights) = (m.lambda, m.weights);
        for _ in 0..SWEEPS {
            lambda = lambda_of(&weights);
            weights = weights_of(&lambda, &weights);
        }
        (lambda, weights)
    };
    let accuracy = |weights: &[f64]| best_order_of(case, weights, seen).0;
    let (truth_lambda, truth_weights) = sweeps(case.true_materials());
    let (start_lambda, start_weights) = sweeps(crate::starts::fit_start(case));
    if crate::env_flag("ABLATION_TAIL") {
        eprintln!(
            "  pure vertices more than 10% off their median, the true maps (from the start): {}",
            crate::metrics::tail_shares(case, &start_lambda, &start_weights, seen)
        );
    }
    RatioFloor {
        true_weights: ratio_errors(case, &lambda_of(&case.weights), &case.weights, seen),
        from_truth: ratio_errors(case, &truth_lambda, &truth_weights, seen),
        from_start: ratio_errors(case, &start_lambda, &start_weights, seen),
        accuracy_true_lambda: accuracy(&weights_of(&case.lambda, &case.weights)),
        accuracy_from_truth: accuracy(&truth_weights),
    }
}

/// The floor in a sentence for the table's floor line.
pub fn describe(f: &RatioFloor) -> String {
    let r = |v: [f64; 3]| format!("{:.3} / {:.3} / {:.3}", v[0], v[1], v[2]);
    format!(
        "worst albedo ratio error with the true maps (the material step alone, {SWEEPS} sweeps from the truth; R / G / B) {:.3} ({}; λ with the true weights {}; from the k-means start {}); material accuracy with the true maps {:.4} from the truth, {:.4} with the true λ (one weights step)",
        f.worst(),
        r(f.from_truth),
        r(f.true_weights),
        r(f.from_start),
        f.accuracy_from_truth,
        f.accuracy_true_lambda
    )
}

/// `ABLATION_FLOOR_FLIP=1`: the ratio floor's fit from the truth on the exact data (the
/// true model through the case's transport at the same observations) and on the exact
/// data plus the photos' residuals with random signs ([`crate::metrics::flipped_residuals`]):
/// whether what the photos cost the floor is noise or systematic. Before them, one `λ` step
/// with the TRUE weights mixed with their 8 nearest vertices' by 0, 0.15 and 0.3: whether
/// reading each pixel as a blend with the neighbours lowers it; and the same step without
/// the observations the lobes other than the Lambertian one dominate (over 0.3, 0.1, 0.03
/// of a channel's TRUE prediction), or with each weighed by `(1 − share)^q`, `q` = 1, 2, 4.
pub fn floor_sources(case: &Case, seen: &[bool]) {
    let mut exact = case.train.obs.clone();
    replace_colours(&mut exact, &true_prediction(case, &case.train));
    let flipped = crate::metrics::flipped_residuals(&case.train.obs, &exact);
    let graph = relight_cpc::solve::materials::propagate::knn_graph(&case.positions, 8)
        .expect("the vertex graph");
    // The basis responses under the true maps depend on the observations' places, not on
    // their colours or weights: one set serves every λ step below.
    let s = basis_responses(&case.train.problem(case.nv), &case.train.lights);
    let lambda_with =
        |obs: &relight_cpc::observe::Observations, w: &[f64]| lambda_under(case, &s, obs, w);
    for mix in [0.0, 0.15, 0.3] {
        let w = crate::metrics::smoothed(&case.weights, &graph, case.lambda.len(), mix);
        let lambda = lambda_with(&case.train.obs, &w);
        eprintln!(
            "  floor's λ step on the photos with the TRUE weights mixed with their neighbours' by {mix}: R / G / B {:.3?}",
            ratio_errors(case, &lambda, &case.weights, seen)
        );
    }
    let shares = specular_shares(case, &s);
    let fitted = case.train.obs.weight.iter().filter(|&&a| a > 0.0).count();
    for share in [0.3, 0.1, 0.03] {
        let mut obs = case.train.obs.clone();
        for (p, _) in shares.iter().enumerate().filter(|(_, &sh)| sh > share) {
            obs.mask_out(p);
        }
        let kept = obs.weight.iter().filter(|&&a| a > 0.0).count();
        let lambda = lambda_with(&obs, &case.weights);
        eprintln!(
            "  floor's λ step with the TRUE weights, observations whose true specular share is over {share} left out ({kept} of {fitted} kept): R / G / B {:.3?}",
            ratio_errors(case, &lambda, &case.weights, seen)
        );
    }
    for power in [1, 2, 4] {
        let mut obs = case.train.obs.clone();
        for (a, sh) in obs.weight.iter_mut().zip(&shares) {
            *a *= (1.0 - sh).powi(power) as f32;
        }
        let lambda = lambda_with(&obs, &case.weights);
        eprintln!(
            "  floor's λ step with the TRUE weights, each observation weighed by (1 − its true specular share)^{power}: R / G / B {:.3?}",
            ratio_errors(case, &lambda, &case.weights, seen)
        );
    }
    for (label, obs) in [("exact", &exact), ("exact+flipped", &flipped)] {
        let f = ratio_floor_of(case, obs, seen);
        eprintln!(
            "  floor on {label}: from the truth R / G / B {:.3?}, accuracy {:.4}",
            f.from_truth, f.accuracy_from_truth
        );
    }
}

/// One `λ` step under the true maps (basis responses `s`) with the weights `w` held, the
/// colours and confidences from `obs`.
fn lambda_under(
    case: &Case,
    s: &[[f64; 3]],
    obs: &relight_cpc::observe::Observations,
    w: &[f64],
) -> Vec<Vec<[f64; 3]>> {
    let problem = relight_cpc::solve::Problem {
        obs,
        ..case.train.problem(case.nv)
    };
    let dw: Vec<[f64; 3]> = obs.weight.iter().map(|&a| [f64::from(a); 3]).collect();
    let coupling = LambdaCoupling {
        achromatic_except: None,
    };
    lambda_step(&problem, s, w, case.lambda.len(), &dw, None, 1e-8, coupling)
        .expect("λ step")
        .lambda
}

/// Per training observation, the largest share of a channel's TRUE prediction owed to the
/// lobes other than the Lambertian one (`s`: the basis responses under the true maps).
fn specular_shares(case: &Case, s: &[[f64; 3]]) -> Vec<f64> {
    let nb = case.train.transport.n_basis;
    let kk = case.lambda.len();
    (0..case.train.obs.vertex.len())
        .map(|p| {
            let x = case.train.obs.vertex[p] as usize;
            (0..3)
                .map(|c| {
                    let part = |b: usize| -> f64 {
                        (0..kk)
                            .map(|k| case.weights[x * kk + k] * case.lambda[k][b][c])
                            .sum::<f64>()
                            * s[p * nb + b][c]
                    };
                    let total: f64 = (0..nb).map(part).sum();
                    if total > 0.0 {
                        (total - part(0)) / total
                    } else {
                        0.0
                    }
                })
                .fold(0.0, f64::max)
        })
        .collect()
}
