//! Where the relit error of a fit comes from (`ABLATION_DIAGNOSE=1`): the relit metric's
//! squared error (held-out photos under their TRUE maps, the best scale `s_c` per channel,
//! module docs of `benches/ablation.rs`) split by the category of each held-out
//! observation's vertex, and the same metric with parts of the fitted reflectance replaced
//! by the truth (counterfactuals).
//!
//! With the lights fixed to the truth the relit prediction is linear in the per-vertex
//! reflectance `β_x = Σ_k w_k(x) λ_k`, so the error of a held-out observation `p` of
//! vertex `x` is `Σ_b (β_{x,b,c} − s_c β̂_{x,b,c}) t_{p,b,c}`: on a Lambertian scene it is
//! the vertex's albedo error times its irradiance. The categories:
//! - **training views**: how many training photos observe the vertex (`α > 0`);
//! - **held-out α**: the observation's grazing weight `α_p` (the observe stage's cosine
//!   ramp, `src/observe/mod.rs`), low = grazing;
//! - **open sky**: the vertex's Lambertian response to a white map of radiance 1 through
//!   the transport (its cosine-weighted unoccluded fraction; 1 = nothing in the way);
//! - **|Σŵ − 1|**: how far the fitted blending weights are from summing to one;
//! - **true material**: the truth's largest weight, pure (≥ 0.95) or mixed.
//!
//! The per-vertex albedo error is `‖s ⊙ β̂_{x,L} − β_{x,L}‖ / ‖β_{x,L}‖` over the three
//! channels of the Lambertian lobe `L`.

use crate::synth_case::*;
use relight_cpc::solve::{beta_per_vertex, Estimate};
use relight_cpc::transport::brdf::BasisBrdf;
use serde_json::{json, Value};

/// Per held-out observation and vertex, what the categories need.
struct Facts {
    /// Training photos observing each vertex.
    views: Vec<usize>,
    /// Per held-out observation, the vertex's open-sky fraction.
    open: Vec<f64>,
    /// Per vertex, the fit's per-channel-scaled Lambertian albedo error.
    albedo_err: Vec<f64>,
    /// Per vertex, `Σ_k ŵ_k(x)`.
    wsum: Vec<f64>,
    /// The relit metric's per-channel scale.
    scale: [f64; 3],
}

/// Training photos with `α > 0` per vertex.
pub fn training_views(case: &Case) -> Vec<usize> {
    let obs = &case.train.obs;
    let mut views = vec![0usize; case.nv];
    let mut last = vec![usize::MAX; case.nv];
    for (i, r) in obs.photo_ranges.iter().enumerate() {
        for p in r.clone() {
            let x = obs.vertex[p] as usize;
            if obs.weight[p] > 0.0 && last[x] != i {
                last[x] = i;
                views[x] += 1;
            }
        }
    }
    views
}

/// The index of the Lambertian basis lobe.
fn lambert_index(case: &Case) -> usize {
    case.basis
        .iter()
        .position(|b| matches!(b, BasisBrdf::Lambert))
        .expect("every synthetic scene has a Lambertian lobe")
}

/// The best per-channel scale `s_c = Σ y ŷ / Σ ŷ²` of `pred` against the held-out photos.
fn channel_scale(case: &Case, pred: &[[f64; 3]]) -> [f64; 3] {
    let obs = &case.held.obs;
    [0, 1, 2].map(|c| {
        let (mut yp, mut pp) = (0.0, 0.0);
        for p in (0..obs.len()).filter(|&p| obs.weight[p] > 0.0) {
            yp += obs.rgb[p][c] as f64 * pred[p][c];
            pp += pred[p][c] * pred[p][c];
        }
        if pp > 0.0 {
            yp / pp
        } else {
            1.0
        }
    })
}

fn facts(case: &Case, est: &Estimate, pred: &[[f64; 3]]) -> Facts {
    let kk = est.lambda.len();
    let nb = case.basis.len();
    let lb = lambert_index(case);
    // One white material of the Lambertian lobe alone, weight 1 everywhere.
    let white = vec![(0..nb)
        .map(|b| if b == lb { [1.0; 3] } else { [0.0; 3] })
        .collect::<Vec<_>>()];
    let maps: Vec<[Vec<f64>; 3]> = case
        .held
        .lights
        .iter()
        .map(|l| [0, 1, 2].map(|c| vec![1.0; l[c].len()]))
        .collect();
    let open = predict_with(&case.held, case.nv, &white, &vec![1.0; case.nv], &maps)
        .iter()
        .map(|v| v[0])
        .collect();
    let scale = channel_scale(case, pred);
    let fit_beta = beta_per_vertex(&est.lambda, &est.weights, case.nv);
    let true_beta = true_beta(case);
    let albedo_err = (0..case.nv)
        .map(|x| {
            let (f, t) = (fit_beta[x * nb + lb], true_beta[x * nb + lb]);
            let num: f64 = (0..3).map(|c| (scale[c] * f[c] - t[c]).powi(2)).sum();
            let den: f64 = (0..3).map(|c| t[c] * t[c]).sum();
            (num / den.max(1e-30)).sqrt()
        })
        .collect();
    let wsum = (0..case.nv)
        .map(|x| est.weights[x * kk..(x + 1) * kk].iter().sum())
        .collect();
    Facts {
        views: training_views(case),
        open,
        albedo_err,
        wsum,
        scale,
    }
}

/// One category's bins: label and the bin of a held-out observation `p`.
struct Category {
    name: &'static str,
    labels: Vec<String>,
    bin: Box<dyn Fn(usize) -> usize>,
}

fn categories(case: &Case, f: &Facts) -> Vec<Category> {
    let obs = case.held.obs.clone();
    let k = case.lambda.len();
    let truth = case.weights.clone();
    let views = f.views.clone();
    let open = f.open.clone();
    let wsum = f.wsum.clone();
    let vx = move |p: usize| obs.vertex[p] as usize;
    let (v1, v2, v3, v4) = (vx.clone(), vx.clone(), vx.clone(), vx.clone());
    let alpha = case.held.obs.weight.clone();
    let s = |v: &[&str]| v.iter().map(|x| x.to_string()).collect::<Vec<_>>();
    let mut mats: Vec<String> = (0..k).map(|j| format!("pure {j}")).collect();
    mats.push("mixed".into());
    vec![
        Category {
            name: "training views",
            labels: s(&["0", "1", "2", "≥ 3"]),
            bin: Box::new(move |p| views[v1(p)].min(3)),
        },
        Category {
            name: "held-out α (grazing weight)",
            labels: s(&["< 0.25", "0.25–0.5", "≥ 0.5"]),
            bin: Box::new(move |p| bin3(alpha[p] as f64, 0.25, 0.5)),
        },
        Category {
            name: "open sky",
            labels: s(&["< 0.5", "0.5–0.8", "≥ 0.8"]),
            bin: Box::new(move |p| bin3(open[p], 0.5, 0.8)),
        },
        Category {
            name: "|Σŵ − 1|",
            labels: s(&["< 0.05", "0.05–0.2", "≥ 0.2"]),
            bin: Box::new(move |p| bin3((wsum[v3(p)] - 1.0).abs(), 0.05, 0.2)),
        },
        Category {
            name: "true material",
            labels: mats,
            bin: Box::new(move |p| {
                let x = v4(p);
                let w = &truth[x * k..(x + 1) * k];
                (0..k).find(|&j| w[j] >= 0.95).unwrap_or(k)
            }),
        },
        Category {
            name: "vertex albedo error",
            labels: s(&["< 2%", "2–5%", "5–10%", "≥ 10%"]),
            bin: {
                let e = f.albedo_err.clone();
                Box::new(move |p| {
                    let v = e[v2(p)];
                    usize::from(v >= 0.02) + usize::from(v >= 0.05) + usize::from(v >= 0.1)
                })
            },
        },
    ]
}

fn bin3(v: f64, a: f64, b: f64) -> usize {
    usize::from(v >= a) + usize::from(v >= b)
}

/// One bin's figures.
#[derive(Default, Clone, Copy)]
struct Bin {
    obs: usize,
    se: f64,
    yy: f64,
    albedo_se: f64,
}

/// The breakdown of the relit squared error of `pred` and the counterfactuals, as a
/// Markdown section and JSON.
pub fn diagnose(case: &Case, est: &Estimate, label: &str) -> (String, Value) {
    let pred = case.predict_held(&est.lambda, &est.weights);
    let f = facts(case, est, &pred);
    let obs = &case.held.obs;
    let used: Vec<usize> = (0..obs.len()).filter(|&p| obs.weight[p] > 0.0).collect();
    let se_of = |p: usize| -> f64 {
        (0..3)
            .map(|c| (obs.rgb[p][c] as f64 - f.scale[c] * pred[p][c]).powi(2))
            .sum()
    };
    let total_se: f64 = used.iter().map(|&p| se_of(p)).sum();
    let total_yy: f64 = used.iter().map(|&p| yy_of(obs, p)).sum();
    let mut md = format!(
        "#### Relit error of `{label}` by category\n\nRelit {:.4} (per-channel scale {:.3} / {:.3} / {:.3}); share of held-out observations / share of the relit squared error / the bin's own relative error / RMS albedo error of the bin's vertices (per observation).\n\n",
        (total_se / total_yy).sqrt(),
        f.scale[0],
        f.scale[1],
        f.scale[2]
    );
    let mut cats = Vec::new();
    for cat in categories(case, &f) {
        let mut bins = vec![Bin::default(); cat.labels.len()];
        for &p in &used {
            let b = &mut bins[(cat.bin)(p)];
            b.obs += 1;
            b.se += se_of(p);
            b.yy += yy_of(obs, p);
            b.albedo_se += f.albedo_err[obs.vertex[p] as usize].powi(2);
        }
        md.push_str(&format!(
            "| {} | obs | SE share | rel. error | albedo error |\n|---|---|---|---|---|\n",
            cat.name
        ));
        let mut rows = Vec::new();
        for (l, b) in cat.labels.iter().zip(&bins) {
            let n = b.obs.max(1) as f64;
            let row = (
                b.obs as f64 / used.len() as f64,
                b.se / total_se,
                (b.se / b.yy.max(1e-30)).sqrt(),
                (b.albedo_se / n).sqrt(),
            );
            md.push_str(&format!(
                "| {l} | {:.3} | {:.3} | {:.4} | {:.4} |\n",
                row.0, row.1, row.2, row.3
            ));
            rows.push(json!({"bin": l, "obs_share": row.0, "se_share": row.1, "rel": row.2, "albedo_rms": row.3}));
        }
        md.push('\n');
        cats.push(json!({"category": cat.name, "bins": rows}));
    }
    let (cf_md, cf) = counterfactuals(case, est, &f);
    md.push_str(&cf_md);
    (md, json!({"categories": cats, "counterfactuals": cf}))
}

fn yy_of(obs: &relight_cpc::observe::Observations, p: usize) -> f64 {
    obs.rgb[p].iter().map(|&v| (v as f64).powi(2)).sum()
}

/// The relit metric with each vertex's reflectance from the fit (`false`) or the truth
/// (`true`, divided by the metric's scale `s_c`), the fit's weights multiplied by
/// `fit_factor[x]`: materials `fit λ ++ true λ / s`,
/// weights `[factor·ŵ_x, 0]` or `[0, w_x]`.
fn relit_mixed(
    case: &Case,
    est: &Estimate,
    f: &Facts,
    truth_at: &[bool],
    fit_factor: &[f64],
) -> f64 {
    let (kf, kt) = (est.lambda.len(), case.lambda.len());
    let mut lambda = est.lambda.clone();
    // The truth in the fit's per-channel scale, so that mixing the two adds no colour cast.
    lambda.extend(case.lambda.iter().map(|l| {
        l.iter()
            .map(|v| [0, 1, 2].map(|c| v[c] / f.scale[c]))
            .collect()
    }));
    let mut w = vec![0.0; case.nv * (kf + kt)];
    for x in 0..case.nv {
        let row = &mut w[x * (kf + kt)..(x + 1) * (kf + kt)];
        if truth_at[x] {
            row[kf..].copy_from_slice(&case.weights[x * kt..(x + 1) * kt]);
        } else {
            for k in 0..kf {
                row[k] = fit_factor[x] * est.weights[x * kf + k];
            }
        }
    }
    rel_rmse_per_channel(&case.held.obs, &case.predict_held(&lambda, &w))
}

/// Relit error with parts of the reflectance replaced (module docs).
fn counterfactuals(case: &Case, est: &Estimate, f: &Facts) -> (String, Value) {
    let nv = case.nv;
    let ones = vec![1.0; nv];
    let unit: Vec<f64> = f
        .wsum
        .iter()
        .map(|&s| if s > 0.0 { 1.0 / s } else { 1.0 })
        .collect();
    let none = vec![false; nv];
    let views_le = |n: usize| -> Vec<bool> { f.views.iter().map(|&v| v <= n).collect() };
    let worst = |q: f64| -> Vec<bool> {
        let mut e: Vec<f64> = f.albedo_err.clone();
        e.sort_by(f64::total_cmp);
        let cut = e[((1.0 - q) * nv as f64) as usize];
        f.albedo_err.iter().map(|&v| v >= cut).collect()
    };
    let cases: Vec<(&str, f64)> = vec![
        ("as fitted", relit_mixed(case, est, f, &none, &ones)),
        (
            "truth at vertices seen by 0 training photos",
            relit_mixed(case, est, f, &views_le(0), &ones),
        ),
        (
            "truth at vertices seen by ≤ 1",
            relit_mixed(case, est, f, &views_le(1), &ones),
        ),
        (
            "truth at vertices seen by ≤ 2",
            relit_mixed(case, est, f, &views_le(2), &ones),
        ),
        (
            "fitted weights divided by their sum (Σŵ = 1)",
            relit_mixed(case, est, f, &none, &unit),
        ),
        (
            "truth at the 5% of vertices with the largest albedo error",
            relit_mixed(case, est, f, &worst(0.05), &ones),
        ),
        (
            "truth at the 20% of vertices with the largest albedo error",
            relit_mixed(case, est, f, &worst(0.2), &ones),
        ),
    ];
    let mut cases = cases;
    cases.extend(split_counterfactuals(case, est, f));
    let mut md = String::from("| counterfactual | relit |\n|---|---|\n");
    for (l, v) in &cases {
        md.push_str(&format!("| {l} | {v:.4} |\n"));
    }
    md.push('\n');
    let j = cases
        .iter()
        .map(|(l, v)| json!({"case": l, "relit": v}))
        .collect::<Vec<_>>();
    (md, Value::Array(j))
}

/// The materials against the blending weights: the relit metric with the TRUE materials
/// (in the fit's per-channel scale, matched to the fitted ones by the order of best
/// material accuracy) under the fitted weights, and the fitted materials under the TRUE
/// weights (in the same order).
fn split_counterfactuals(case: &Case, est: &Estimate, f: &Facts) -> Vec<(&'static str, f64)> {
    let (_, seen) = relight_cpc::run::mean_colours(&case.train.obs, case.nv);
    let (_, _, perm) = crate::metrics::best_order(case, est, &seen);
    let k = est.lambda.len();
    if k != case.lambda.len() {
        return Vec::new();
    }
    let true_lambda: Vec<Vec<[f64; 3]>> = perm
        .iter()
        .map(|&t| {
            case.lambda[t]
                .iter()
                .map(|v| [0, 1, 2].map(|c| v[c] / f.scale[c]))
                .collect()
        })
        .collect();
    let mut true_w = vec![0.0; case.nv * k];
    for x in 0..case.nv {
        for j in 0..k {
            true_w[x * k + j] = case.weights[x * k + perm[j]];
        }
    }
    for (j, t) in true_lambda.iter().enumerate() {
        eprintln!(
            "  material {j} (true {}): fitted λ {:?}, true λ (fit's scale) {:?}",
            perm[j], est.lambda[j], t
        );
    }
    let rel = |l: &[Vec<[f64; 3]>], w: &[f64]| {
        rel_rmse_per_channel(&case.held.obs, &case.predict_held(l, w))
    };
    vec![
        (
            "TRUE materials λ, fitted weights",
            rel(&true_lambda, &est.weights),
        ),
        (
            "fitted materials λ, TRUE weights",
            rel(&est.lambda, &true_w),
        ),
    ]
}
