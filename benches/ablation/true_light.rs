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
use relight_cpc::report::metrics::PURE_WEIGHT;
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
    let coupling = LambdaCoupling::default();
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
/// Between them, the photos' mean departure from the exact data per band of that share
/// ([`share_bias`]) and the step with the photos' residuals on one class of observations
/// alone ([`residual_split`]).
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
    eprintln!(
        "  the photos against the exact data by true specular share: {}",
        share_bias(&case.train.obs, &exact, &shares)
    );
    residual_split(case, &exact, &shares, &s, seen);
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

/// Which observations a class of [`residual_split`] holds.
type Keep<'a> = Box<dyn Fn(usize) -> bool + 'a>;

/// The λ step with the TRUE weights under the true maps on the exact data plus the
/// photos' residuals `y − ŷ` kept only on one class of observations (the exact data
/// elsewhere): by the TRUE specular share (below 0.1, 0.1 to 0.3, over 0.3) and by the
/// vertex's true material (pure in material `t`, or a blend). The step is linear in the
/// data, so up to NNLS's active set each class's error adds to the others': which of them
/// carries the floor.
fn residual_split(
    case: &Case,
    exact: &relight_cpc::observe::Observations,
    shares: &[f64],
    s: &[[f64; 3]],
    seen: &[bool],
) {
    let kk = case.lambda.len();
    // Each observation's vertex's true material when it is pure, `None` for a blend.
    let pure: Vec<Option<usize>> = case
        .train
        .obs
        .vertex
        .iter()
        .map(|&x| (0..kk).find(|&t| case.weights[x as usize * kk + t] >= PURE_WEIGHT))
        .collect();
    let pure = &pure;
    let mut classes: Vec<(String, Keep<'_>)> = vec![
        ("every observation".into(), Box::new(|_| true)),
        ("share < 0.1".into(), Box::new(|p| shares[p] < 0.1)),
        (
            "share 0.1–0.3".into(),
            Box::new(|p| (0.1..0.3).contains(&shares[p])),
        ),
        ("share ≥ 0.3".into(), Box::new(|p| shares[p] >= 0.3)),
        ("blend".into(), Box::new(|p| pure[p].is_none())),
    ];
    for t in 0..kk {
        classes.push((
            format!("pure material {t}"),
            Box::new(move |p| pure[p] == Some(t)),
        ));
    }
    for (label, keep) in &classes {
        let mut obs = exact.clone();
        let mut n = 0;
        for p in 0..obs.rgb.len() {
            if keep(p) {
                obs.rgb[p] = case.train.obs.rgb[p];
                n += 1;
            }
        }
        let lambda = lambda_under(case, s, &obs, &case.weights);
        eprintln!(
            "  λ step with the TRUE weights, the photos' residuals only on {label} ({n} obs): signed ratio error per material 1.. (R / G / B) {:+.3?}",
            crate::metrics::signed_ratio_errors(case, &lambda, &case.weights, seen)
        );
    }
}

/// Per bin of the TRUE specular share, how many fitted observations it holds and per
/// channel the photos' relative departure from the exact data, `Σ (y − ŷ) / Σ ŷ`: the
/// systematic part's sign and size where the highlights are.
fn share_bias(
    photos: &relight_cpc::observe::Observations,
    exact: &relight_cpc::observe::Observations,
    shares: &[f64],
) -> String {
    let edges = [0.0, 0.1, 0.3, 0.6, 1.01];
    let mut out = Vec::new();
    for bin in edges.windows(2) {
        let (mut n, mut diff, mut sum) = (0usize, [0.0f64; 3], [0.0f64; 3]);
        for p in 0..shares.len() {
            if photos.weight[p] <= 0.0 || shares[p] < bin[0] || shares[p] >= bin[1] {
                continue;
            }
            n += 1;
            for c in 0..3 {
                diff[c] += f64::from(photos.rgb[p][c] - exact.rgb[p][c]);
                sum[c] += f64::from(exact.rgb[p][c]);
            }
        }
        let rel = [0, 1, 2].map(|c| if sum[c] > 0.0 { diff[c] / sum[c] } else { 0.0 });
        out.push(format!(
            "[{}, {}): {n} obs, R / G / B {:+.3} / {:+.3} / {:+.3}",
            bin[0], bin[1], rel[0], rel[1], rel[2]
        ));
    }
    out.join("; ")
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
    let coupling = LambdaCoupling::default();
    lambda_step(&problem, s, w, case.lambda.len(), &dw, None, 1e-8, coupling)
        .expect("λ step")
        .lambda
}

/// `ABLATION_FIT_SHARE=1`: the `defaults` fit's own highlights left out. Under the fit's
/// maps, with its weights held, one `λ` step over every training observation (weighed
/// `α_p` times the smallest of the fit's per-channel IRLS weights), then the same step
/// without the observations whose FITTED specular share (its `λ` and weights) is over
/// 0.5, 0.3 or 0.2, and with each weighed by `(1 − share)^4`: whether what the true-share probe of [`floor_sources`]
/// found survives when the estimator, not the truth, says where the highlights are.
pub fn fitted_share_probe(case: &Case, est: &relight_cpc::solve::Estimate, seen: &[bool]) {
    let problem = case.train.problem(case.nv);
    let s = basis_responses(&problem, &est.lights);
    let shares = shares_of(case, &s, &est.lambda, &est.weights);
    let base: Vec<f32> = (0..case.train.obs.vertex.len())
        .map(|p| {
            let o = est
                .irls_weights
                .get(p)
                .map_or(1.0, |o| o.iter().fold(1.0_f32, |a, &b| a.min(b)));
            case.train.obs.weight[p] * o
        })
        .collect();
    let fitted = base.iter().filter(|&&a| a > 0.0).count();
    let step = |keep: &dyn Fn(usize) -> f32| {
        let mut obs = case.train.obs.clone();
        for (p, a) in obs.weight.iter_mut().enumerate() {
            *a = base[p] * keep(p);
        }
        let kept = obs.weight.iter().filter(|&&a| a > 0.0).count();
        (kept, lambda_under(case, &s, &obs, &est.weights))
    };
    eprintln!(
        "  the fit as it stands: R / G / B {:.3?}",
        ratio_errors(case, &est.lambda, &est.weights, seen)
    );
    let (_, lambda) = step(&|_| 1.0);
    eprintln!(
        "  one λ step under the fit's maps, its weights held, every observation: R / G / B {:.3?}",
        ratio_errors(case, &lambda, &est.weights, seen)
    );
    for cut in [0.5, 0.3, 0.2] {
        let (kept, lambda) = step(&|p| if shares[p] > cut { 0.0 } else { 1.0 });
        eprintln!(
            "  the same without the observations whose fitted specular share is over {cut} ({kept} of {fitted} kept): R / G / B {:.3?}",
            ratio_errors(case, &lambda, &est.weights, seen)
        );
    }
    let (_, lambda) = step(&|p| (1.0 - shares[p]).powi(4) as f32);
    eprintln!(
        "  the same with each observation weighed by (1 − its fitted specular share)^4: R / G / B {:.3?}",
        ratio_errors(case, &lambda, &est.weights, seen)
    );
}

/// Per training observation, the largest share of a channel's TRUE prediction owed to the
/// lobes other than the Lambertian one (`s`: the basis responses under the true maps).
fn specular_shares(case: &Case, s: &[[f64; 3]]) -> Vec<f64> {
    shares_of(case, s, &case.lambda, &case.weights)
}

/// [`specular_shares`] of the materials `lambda`, `weights` (over the case's basis, the
/// Lambertian lobe first) under the maps whose basis responses are `s`.
fn shares_of(case: &Case, s: &[[f64; 3]], lambda: &[Vec<[f64; 3]>], weights: &[f64]) -> Vec<f64> {
    let nb = case.train.transport.n_basis;
    let kk = lambda.len();
    (0..case.train.obs.vertex.len())
        .map(|p| {
            let x = case.train.obs.vertex[p] as usize;
            (0..3)
                .map(|c| {
                    let part = |b: usize| -> f64 {
                        (0..kk)
                            .map(|k| weights[x * kk + k] * lambda[k][b][c])
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
