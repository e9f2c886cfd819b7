//! Whether the objective or the search puts the albedo ratios where the `defaults` fit
//! leaves them (`ABLATION_PROFILE=1|axes`).
//!
//! `F(λ, w) = min_L F(λ, w, L)` is the objective of paper Eq. 9 with the `defaults` fit's
//! light model, its prior, Laplacian weight and loss (`d.opts`), every training photo's light
//! fitted again with the reflectance held (the estimator with the materials held: one
//! lighting step to the solver's tolerance per photo, as [`fit_known_reflectance`]). With the
//! weights held their priors are constants: `F` = the robust data term `Σ α ω (y − ŷ)²` +
//! the light model's prior, and, in the comparison's first line, + the weights' priors
//! (the sum-to-one and neighbour priors the fit ran with).
//!
//! **`1`: the truth against the fit.** `F` at the true `(λ*, w*)` and at the fit's
//! `(λ̂, ŵ)`, the fit's `λ` scaled per channel so that `Σ_x Σ_b β_{x,b,c}` is the truth's
//! (the scale no photo fixes, so that the two priors compare). `F(λ̂, ŵ) > F(λ*, w*)` says the
//! objective ranks the truth better than where the alternation stopped: the miss is the
//! search's. Beside `F`: the light prior's part, the plain data term after the refit
//! (`Σ α (y − ŷ)²`), and the plain data term under every photo's TRUE map (no refit).
//!
//! **`axes`: where `F` puts the ratios near the truth.** The truth's reflectance with
//! material `j`'s Lambertian `λ` in channel `c` scaled by `1 + e_j` (`j ≥ 1`, material 0
//! held, the true weights): `e_j` is then exactly the signed ratio error the ablation
//! measures ([`crate::metrics::signed_ratio_errors`]). Per channel a quadratic
//! `F(e) ≈ F₀ + bᵀe + ½ eᵀ A e` is fitted by least squares to the points on the axes
//! `e = t u_j` and, with three materials, the diagonal `e = t (u₁ + u₂)`
//! (`t ∈ {±0.03, ±0.06}`); its minimum `e* = −A⁻¹ b` is where the objective puts the ratios
//! with everything else at the truth. The same for the plain data term after the refit
//! (where a free map per photo lets the photos put them) and under the TRUE maps (where the
//! photos put them when the light is known). Then the shiny lobes' strength: every lobe but
//! the Lambertian one scaled by `1 + s` together, each term over the three channels.
//! Each term's stiffness is the rise of its quadratic 0.03 from its minimum along each axis
//! (`½ A_jj 0.03²`) in units of the photos' noise `σ² = SSE_true,c(0) / Σ α` (the truth's
//! residual under the true maps: quantisation, the renderer's noise and the transport's
//! error together).

use crate::synth_case::*;
use relight_cpc::solve::{estimate, predict, Estimate, EstimateOptions, Materials0};

/// The steps along each direction.
const STEPS: [f64; 4] = [-0.06, -0.03, 0.03, 0.06];

/// The three terms a point reports, in [`Point::channel`]'s order.
const TERMS: [&str; 3] = [
    "F, light refitted",
    "data, light refitted",
    "data, TRUE maps",
];

/// The terms at one point of the profile.
#[derive(Debug, Clone, Copy)]
struct Point {
    /// The ratio errors `(e₁, e₂)` (`e₂` = 0 with two materials), or the shiny lobes'
    /// scale `(s, 0)`.
    e: [f64; 2],
    /// `F` after the refit, over the three channels.
    f: f64,
    /// `F` less its robust data term `Σ α ω r²`: the light model's prior (and the ridge on
    /// `λ`, when on).
    prior: f64,
    /// Per channel, the refit's plain data term `Σ α (y − ŷ)²`.
    refit: [f64; 3],
    /// Per channel, the plain data term under the TRUE maps.
    known: [f64; 3],
}

impl Point {
    /// Term `t` of [`TERMS`] as channel `c` sees it: `F` is one number over the three
    /// channels, and along one channel's directions the other channels' terms stay (the
    /// map models fit each channel on its own), so it stands for every channel.
    fn channel(&self, t: usize, c: usize) -> f64 {
        match t {
            0 => self.f,
            1 => self.refit[c],
            _ => self.known[c],
        }
    }

    /// Term `t` of [`TERMS`] over the three channels.
    fn total(&self, t: usize) -> f64 {
        match t {
            0 => self.f,
            1 => self.refit.iter().sum(),
            _ => self.known.iter().sum(),
        }
    }
}

/// The objective at the truth and at the `defaults` fit's materials (`fit`), lights refitted
/// for both; with `axes`, its profile along the ratio directions (module docs), the fit's
/// own signed ratio errors (over the `seen` vertices) beside the minima. Printed.
pub fn ratio_profile(
    case: &Case,
    opts: &EstimateOptions,
    fit: &Estimate,
    seen: &[bool],
    axes: bool,
) {
    let t0 = std::time::Instant::now();
    let with_weight_priors = EstimateOptions {
        validation_fraction: 0.0,
        ..opts.clone()
    };
    // With the weights held their priors are constants of `F`: left out, so that `F` is the
    // data term plus the light model's prior.
    let opts = EstimateOptions {
        weights_sum: 0.0,
        weights_smoothness: 0.0,
        ..with_weight_priors.clone()
    };
    let fit_lambda = in_truth_gauge(case, fit);
    let base = point(case, &opts, &case.lambda, &case.weights);
    let at_fit = point(case, &opts, &fit_lambda, &fit.weights);
    let full_f = |lambda: &[Vec<[f64; 3]>], weights: &[f64]| {
        objective(&held_fit(case, &with_weight_priors, lambda, weights))
    };
    let (truth_full, fit_full) = (
        full_f(&case.lambda, &case.weights),
        full_f(&fit_lambda, &fit.weights),
    );
    let change = |a: f64, b: f64| 100.0 * (b / a - 1.0);
    eprintln!(
        "  profile: with the weights' priors, at the truth / at the fit's materials: F {truth_full:.6e} / {fit_full:.6e} ({:+.2}%), of which the weights' priors {:.6e} / {:.6e}",
        change(truth_full, fit_full),
        truth_full - base.f,
        fit_full - at_fit.f,
    );
    let (t, f) = (|i| base.total(i), |i| at_fit.total(i));
    eprintln!(
        "  profile: at the truth / at the fit's materials, lights refitted: F {:.6e} / {:.6e} ({:+.2}%), of which the light's prior {:.6e} / {:.6e}; data {:.6e} / {:.6e} ({:+.2}%); data under the TRUE maps {:.6e} / {:.6e} ({:+.2}%)",
        t(0),
        f(0),
        change(t(0), f(0)),
        base.prior,
        at_fit.prior,
        t(1),
        f(1),
        change(t(1), f(1)),
        t(2),
        f(2),
        change(t(2), f(2)),
    );
    let k = case.lambda.len();
    if !axes || !(2..=3).contains(&k) {
        return;
    }
    let fit_signed = crate::metrics::signed_ratio_errors(case, &fit.lambda, &fit.weights, seen);
    let mut dirs: Vec<[f64; 2]> = vec![[1.0, 0.0]];
    if k == 3 {
        dirs.extend([[0.0, 1.0], [1.0, 1.0]]);
    }
    let alpha: f64 = case.train.obs.weight.iter().map(|&a| f64::from(a)).sum();
    eprintln!(
        "  profile: per channel, the minimum e* of each term's quadratic (material 1.., signed ratio error) and the stiffness Δχ² 0.03 from it per axis"
    );
    for c in 0..3 {
        let mut points = vec![base];
        for d in &dirs {
            for t in STEPS {
                points.push(ratio_point(case, &opts, c, [t * d[0], t * d[1]]));
            }
        }
        let sigma2 = base.known[c] / alpha;
        for (term, name) in TERMS.iter().enumerate() {
            let vals: Vec<([f64; 2], f64)> =
                points.iter().map(|p| (p.e, p.channel(term, c))).collect();
            let (star, rise) = quadratic_minimum(&vals, k - 1, sigma2);
            eprintln!("  profile c{c} {name}: e* {star:+.4?}  Δχ²(0.03) {rise:.2?}");
        }
        let fit: Vec<f64> = fit_signed.iter().map(|e| e[c]).collect();
        eprintln!("  profile c{c} the fit's own: {fit:+.4?}");
    }
    specular_profile(case, &opts, base, alpha);
    eprintln!("  profile: {:.0} s", t0.elapsed().as_secs_f64());
}

/// The shiny lobes' strength: every lobe but the Lambertian one, of every material, scaled
/// by `1 + s` (`s ∈ {±0.15, ±0.3}`), each term over the three channels, its stiffness in
/// units of the noise of one channel of one observation.
fn specular_profile(case: &Case, opts: &EstimateOptions, base: Point, alpha: f64) {
    if case
        .lambda
        .iter()
        .all(|l| l[1..].iter().flatten().all(|&v| v == 0.0))
    {
        return;
    }
    let mut points = vec![base];
    for s in [-0.3, -0.15, 0.15, 0.3] {
        let lambda: Vec<Vec<[f64; 3]>> = case
            .lambda
            .iter()
            .map(|l| {
                let mut l = l.clone();
                l[1..]
                    .iter_mut()
                    .for_each(|b| *b = b.map(|v| v * (1.0 + s)));
                l
            })
            .collect();
        let p = point(case, opts, &lambda, &case.weights);
        points.push(Point { e: [s, 0.0], ..p });
    }
    let sigma2 = base.total(2) / (3.0 * alpha);
    for (term, name) in TERMS.iter().enumerate() {
        let vals: Vec<([f64; 2], f64)> = points.iter().map(|p| (p.e, p.total(term))).collect();
        let (star, rise) = quadratic_minimum(&vals, 1, sigma2);
        eprintln!("  profile shiny lobes ×(1 + s) {name}: s* {star:+.4?}  Δχ²(0.03) {rise:.2?}");
    }
}

/// The fit's `λ` with each channel scaled so that `Σ_x Σ_b β_{x,b,c}` is the truth's (the
/// per-channel scale no photo fixes), so that the two points' priors compare.
fn in_truth_gauge(case: &Case, fit: &Estimate) -> Vec<Vec<[f64; 3]>> {
    let total = |lambda: &[Vec<[f64; 3]>], weights: &[f64]| {
        let beta = relight_cpc::solve::beta_per_vertex(lambda, weights, case.nv);
        [0, 1, 2].map(|c| beta.iter().map(|b| b[c]).sum::<f64>())
    };
    let (want, have) = (
        total(&case.lambda, &case.weights),
        total(&fit.lambda, &fit.weights),
    );
    fit.lambda
        .iter()
        .map(|l| {
            l.iter()
                .map(|b| [0, 1, 2].map(|c| b[c] * want[c] / have[c]))
                .collect()
        })
        .collect()
}

/// The point at the truth's `λ` with material `j`'s Lambertian lobe in channel `c` scaled
/// by `1 + e_j`.
fn ratio_point(case: &Case, opts: &EstimateOptions, c: usize, e: [f64; 2]) -> Point {
    let mut lambda = case.lambda.clone();
    for (j, ej) in e.iter().enumerate().take(lambda.len() - 1) {
        lambda[j + 1][0][c] *= 1.0 + ej;
    }
    Point {
        e,
        ..point(case, opts, &lambda, &case.weights)
    }
}

/// Every training photo's light fitted with the reflectance `(lambda, weights)` held.
fn held_fit(
    case: &Case,
    opts: &EstimateOptions,
    lambda: &[Vec<[f64; 3]>],
    weights: &[f64],
) -> Estimate {
    let init = Materials0 {
        lambda: lambda.to_vec(),
        weights: weights.to_vec(),
    };
    let held = EstimateOptions {
        fixed_materials: true,
        ..opts.clone()
    };
    estimate(&case.train.problem(case.nv), init, &held, &mut |_, _| {})
        .expect("a lighting step with the reflectance held")
}

/// `F` at the end of a fit.
fn objective(est: &Estimate) -> f64 {
    est.timeline.last().map_or(f64::NAN, |it| it.objective)
}

/// The terms (module docs) at the reflectance `(lambda, weights)`.
fn point(case: &Case, opts: &EstimateOptions, lambda: &[Vec<[f64; 3]>], weights: &[f64]) -> Point {
    let est = held_fit(case, opts, lambda, weights);
    let f = objective(&est);
    let refit = predict(&case.train.problem(case.nv), &est);
    let known = predict_with(&case.train, case.nv, lambda, weights, &case.train.lights);
    let obs = &case.train.obs;
    let robust = channel_sse(obs, &refit, Some(&est.irls_weights));
    Point {
        e: [0.0; 2],
        f,
        prior: f - robust.iter().sum::<f64>(),
        refit: channel_sse(obs, &refit, None),
        known: channel_sse(obs, &known, None),
    }
}

/// Per channel `Σ α ω (y − ŷ)²` (`ω`: the robust weights; `None`: 1).
fn channel_sse(
    obs: &relight_cpc::observe::Observations,
    pred: &[[f64; 3]],
    omega: Option<&[[f32; 3]]>,
) -> [f64; 3] {
    let mut s = [0.0; 3];
    for (p, y) in obs.rgb.iter().enumerate() {
        let a = f64::from(obs.weight[p]);
        let w = omega.map_or([1.0; 3], |o| o[p]);
        for c in 0..3 {
            let r = f64::from(y[c]) - pred[p][c];
            s[c] += a * f64::from(w[c]) * r * r;
        }
    }
    s
}

/// The minimum of the least-squares quadratic in `dim` (1 or 2) variables through `vals`
/// (`(e, value)`), and per axis its stiffness: the rise of the quadratic 0.03 away from its
/// minimum along the axis, `½ A_jj 0.03²`, in units of `sigma2`.
fn quadratic_minimum(vals: &[([f64; 2], f64)], dim: usize, sigma2: f64) -> (Vec<f64>, Vec<f64>) {
    // Features: 1, e1, e1², [e2, e2², e1 e2].
    let feats = |e: [f64; 2]| -> Vec<f64> {
        if dim == 1 {
            vec![1.0, e[0], e[0] * e[0]]
        } else {
            vec![1.0, e[0], e[0] * e[0], e[1], e[1] * e[1], e[0] * e[1]]
        }
    };
    let rows: Vec<Vec<f64>> = vals.iter().map(|v| feats(v.0)).collect();
    let x = nalgebra::DMatrix::from_fn(rows.len(), rows[0].len(), |i, j| rows[i][j]);
    let y = nalgebra::DVector::from_iterator(vals.len(), vals.iter().map(|v| v.1 - vals[0].1));
    let Ok(q) = x.svd(true, true).solve(&y, 1e-12) else {
        return (vec![f64::NAN; dim], vec![f64::NAN; dim]);
    };
    if dim == 1 {
        let (b, a) = (q[1], 2.0 * q[2]);
        return (vec![-b / a], vec![0.5 * a * 0.03 * 0.03 / sigma2]);
    }
    let b = nalgebra::Vector2::new(q[1], q[3]);
    let a = nalgebra::Matrix2::new(2.0 * q[2], q[5], q[5], 2.0 * q[4]);
    let star = a.try_inverse().map_or([f64::NAN; 2], |ai| {
        let s = -(ai * b);
        [s[0], s[1]]
    });
    let rise = |j: usize| 0.5 * a[(j, j)] * 0.03 * 0.03 / sigma2;
    (star.to_vec(), vec![rise(0), rise(1)])
}
