//! `ABLATION_SH_TRUTH=…` and `ABLATION_SH_BLOCKS=…`: the irradiance and coarse-light
//! models' worst Lambertian ratio errors against the truth, read from the photos over the
//! first fit's or the TRUE pure vertices and from exact data
//! (`bench-results/irradiance-start.md` section 1c, `coarse-light-start.md`).

use super::full_lambda;
use super::start_probes::nearest_order;
use crate::synth_case::*;
use relight_cpc::solve::{Estimate, Materials0};

/// `ABLATION_SH_TRUTH=1` with `sh-ratio` (`only`: then stop): the irradiance model's
/// worst Lambertian ratio error (the library's converged fit) over the pure, open vertices
/// of the TRUE weights or of the first fit's, each region eroded by 0–2 rings of the
/// 8-nearest-neighbour graph (a vertex kept when its neighbours are pure in the same
/// material), read from the photos, and over the TRUE vertices from the true model's exact
/// prediction through the case's transport (no pixel mixing, no 8-bit): the model's own
/// bias (order-2 truncation, cast shadows, interreflection). Before that,
/// [`weights_purity`] of the first fit and of the model's start. Only when the pilot took
/// the true count.
pub(super) fn sh_truth_diagnosis(
    case: &Case,
    (first, start): (&Estimate, &Materials0),
    seen: &[bool],
    kept: &[usize],
    lambert: usize,
) {
    use relight_cpc::solve::materials::irradiance::normalised_weights;
    use relight_cpc::solve::materials::propagate::{knn_graph, NEIGHBOURS};
    let kt = case.lambda.len();
    if first.lambda.len() != kt {
        return;
    }
    let true_kept: Vec<Vec<[f64; 3]>> = case
        .lambda
        .iter()
        .map(|row| kept.iter().map(|&b| row[b]).collect())
        .collect();
    let fit_order = nearest_order(&first.lambda, &true_kept, lambert);
    let purity = |lambda: &[Vec<[f64; 3]>], raw: &[f64]| {
        weights_purity(case, (lambda, raw), seen, (kept, lambert), &fit_order)
    };
    eprintln!(
        "sh-truth first fit: {}",
        purity(&first.lambda, &first.weights)
    );
    eprintln!(
        "sh-truth irradiance start: {}",
        purity(&start.lambda, &start.weights)
    );
    let exact = crate::true_prediction(case, &case.train);
    let mut exact_obs = case.train.obs.clone();
    crate::replace_colours(&mut exact_obs, &exact);
    let graph = knn_graph(&case.positions, NEIGHBOURS).expect("graph");
    let open = case.vis.open_fractions();
    let sources = [
        ("truth", case.weights.clone(), (0..kt).collect::<Vec<_>>()),
        ("fit", normalised_weights(&first.weights, kt), fit_order),
    ];
    for (source, mut w, order) in sources {
        for rings in 0..3 {
            if rings > 0 {
                w = eroded(&w, &graph, kt);
            }
            if rings == 0 {
                mixture_diagnosis(case, source, &exact_obs, (seen, &w, &order), &graph);
            }
            if rings == 0 || crate::env_flag("ABLATION_SH_BLOCKS_ERODED") {
                eprintln!("sh-blocks {source}: eroded {rings}");
                block_light_diagnosis(case, source, &exact_obs, (seen, &w, &order));
            }
            let mut data = vec![("photos", &case.train.obs)];
            if source == "truth" && rings == 0 {
                data.push(("exact", &exact_obs));
            }
            for (label, obs) in data {
                let (rows, errs) = model_ratio_errors(case, (obs, &open), seen, &w, &order);
                eprintln!(
                    "sh-truth {source} eroded {rings} {label}: {rows} rows, worst ratio per channel {errs:.3?}"
                );
            }
        }
    }
}

/// `ABLATION_SH_MIX=s,…`: [`super::mixture`]'s model over every seen observation with the
/// weights `w` mixed with their neighbours' by each `s`, 8 × 8 blocks, on the photos and,
/// for the TRUE weights, on the exact data.
fn mixture_diagnosis(
    case: &Case,
    source: &str,
    exact: &relight_cpc::observe::Observations,
    (seen, w, order): (&[bool], &[f64], &[usize]),
    graph: &relight_cpc::solve::materials::propagate::VertexGraph,
) {
    let Ok(list) = std::env::var("ABLATION_SH_MIX") else {
        return;
    };
    let kk = order.len();
    for s in list
        .split(',')
        .map(|v| v.parse::<f64>().expect("a mixing share"))
    {
        let ws = crate::metrics::smoothed(w, graph, kk, s);
        let mut data = vec![("photos", &case.train.obs)];
        if source == "truth" {
            data.push(("exact", exact));
        }
        for (label, obs) in data {
            let rho =
                super::mixture::mixture_albedos(obs, &case.train.transport, (seen, &ws, kk), 8);
            let errs = worst_ratio_errors(case, |k, c| rho[c][k], order);
            eprintln!("sh-mix {source} s={s} {label}: worst ratio per channel {errs:.3?}");
        }
    }
}

/// `w` (`V × K`) with every vertex that has a neighbour of another pure material (or of
/// none) made impure (its row zeroed).
fn eroded(
    w: &[f64],
    graph: &relight_cpc::solve::materials::propagate::VertexGraph,
    kk: usize,
) -> Vec<f64> {
    use relight_cpc::solve::materials::irradiance::pure_material;
    let label = |x: usize| pure_material(&w[x * kk..(x + 1) * kk]);
    let mut out = w.to_vec();
    for x in 0..w.len() / kk {
        if graph
            .neighbours(x)
            .iter()
            .any(|&y| label(y as usize) != label(x))
        {
            out[x * kk..(x + 1) * kk].iter_mut().for_each(|v| *v = 0.0);
        }
    }
    out
}

/// The true Lambertian ratio of material `j` to material 0 in channel `c`.
fn true_ratio(case: &Case, j: usize, c: usize) -> f64 {
    case.lambda[j][0][c] / case.lambda[0][0][c]
}

/// The worst relative error per channel of the ratios `rho[k] / rho[0]`, material `k` of
/// `rho` read as true material `order[k]`.
fn worst_ratio_errors(case: &Case, rho: impl Fn(usize, usize) -> f64, order: &[usize]) -> [f64; 3] {
    [0, 1, 2].map(|c| {
        let mut by_truth = vec![f64::NAN; order.len()];
        for (k, &j) in order.iter().enumerate() {
            by_truth[j] = rho(k, c);
        }
        (1..order.len())
            .map(|j| (by_truth[j] / by_truth[0] / true_ratio(case, j, c) - 1.0).abs())
            .fold(0.0, f64::max)
    })
}

/// The rows the model reads with weights `w` (observations and open fractions `obs_open`)
/// and its worst Lambertian ratio error per channel against the truth, fit material `k`
/// read as true material `order[k]`.
fn model_ratio_errors(
    case: &Case,
    (obs, open): (&relight_cpc::observe::Observations, &[f64]),
    seen: &[bool],
    w: &[f64],
    order: &[usize],
) -> (usize, [f64; 3]) {
    use relight_cpc::solve::materials::irradiance::{self, RowsInput};
    let kk = order.len();
    let rows = irradiance::pure_open_rows(&RowsInput {
        obs,
        normals_env: &case.normals_env,
        open,
        seen,
        weights: w,
        materials: kk,
        min_open: crate::env_or("ABLATION_SH_OPEN", irradiance::MIN_OPEN),
    });
    let n_photos = obs.photo_ranges.len();
    let rho: Vec<Vec<f64>> = (0..3)
        .map(|c| {
            irradiance::irradiance_albedos(&rows, c, n_photos, &vec![1.0; kk]).expect("finite rows")
        })
        .collect();
    (
        rows.len(),
        worst_ratio_errors(case, |k, c| rho[c][k], order),
    )
}

/// A fit's weights at the TRUE pure seen vertices: quantiles of the normalised weight on
/// the true material; the ablation's ratio metric ([`crate::metrics::ratio_errors`]) with
/// the raw weights and with the normalised ones; and the worst ratio of the materials'
/// Lambertian λ alone.
fn weights_purity(
    case: &Case,
    (lambda, raw): (&[Vec<[f64; 3]>], &[f64]),
    seen: &[bool],
    (kept, lambert): (&[usize], usize),
    order: &[usize],
) -> String {
    let (kt, kf) = (case.lambda.len(), lambda.len());
    let w = relight_cpc::solve::materials::irradiance::normalised_weights(raw, kf);
    let mut on_true = Vec::new();
    for x in (0..case.nv).filter(|&x| seen[x]) {
        for t in (0..kt).filter(|&t| case.weights[x * kt + t] >= 0.95) {
            let k = order.iter().position(|&j| j == t).expect("a permutation");
            on_true.push(w[x * kf + k]);
        }
    }
    on_true.sort_by(f64::total_cmp);
    let q = |p: f64| on_true[((on_true.len() - 1) as f64 * p) as usize];
    let full = full_lambda(case, kept, lambda);
    let metric = |weights: &[f64]| crate::metrics::ratio_errors(case, &full, weights, seen);
    let lambda_only = worst_ratio_errors(case, |k, c| lambda[k][lambert][c], order);
    format!(
        "weight on the true material q10 {:.3} q25 {:.3} q50 {:.3}; ratio raw {:.3?}, normalised {:.3?}, λ alone {lambda_only:.3?}",
        q(0.1), q(0.25), q(0.5), metric(raw), metric(&w)
    )
}

/// [`block_light_ratio_errors`] for each `r` of `ABLATION_SH_BLOCKS`, on the photos and,
/// for the TRUE weights, on the exact data.
fn block_light_diagnosis(
    case: &Case,
    source: &str,
    exact: &relight_cpc::observe::Observations,
    (seen, w, order): (&[bool], &[f64], &[usize]),
) {
    let Ok(blocks) = std::env::var("ABLATION_SH_BLOCKS") else {
        return;
    };
    for r in blocks
        .split(',')
        .map(|v| v.parse::<usize>().expect("a block side"))
    {
        let flipped = crate::metrics::flipped_residuals(&case.train.obs, exact);
        let dim: Option<f32> = std::env::var("ABLATION_SH_DIM")
            .ok()
            .and_then(|v| v.parse().ok());
        let dimmed = dim.map(|x| {
            (
                dim_only_as(&case.train.obs, &case.train.obs, x),
                dim_only_as(exact, &case.train.obs, x),
            )
        });
        let mut data = vec![("photos", &case.train.obs)];
        if source == "truth" {
            data.push(("exact", exact));
            data.push(("exact+flipped", &flipped));
        }
        if let Some((p, e)) = &dimmed {
            data.push(("photos dim", p));
            if source == "truth" {
                data.push(("exact dim", e));
            }
        }
        for (label, obs) in data {
            let (rows, errs) = block_light_ratio_errors(case, obs, (seen, w, order), r);
            eprintln!(
                "sh-blocks {source} {r}x{r} {label}: {rows} rows, worst ratio per channel {errs:.3?}"
            );
        }
    }
}

/// `obs` with every observation where `photos`' brightest channel reaches `x` (linear)
/// given no weight: far from the clip level, so clipping selects none of those left.
fn dim_only_as(
    obs: &relight_cpc::observe::Observations,
    photos: &relight_cpc::observe::Observations,
    x: f32,
) -> relight_cpc::observe::Observations {
    let mut out = obs.clone();
    for (p, y) in photos.rgb.iter().enumerate() {
        if y.iter().any(|&v| v >= x) {
            out.mask_out(p);
        }
    }
    out
}

/// `ABLATION_SH_BLOCKS=r,…`: the worst ratio per channel of `run --restart coarse-light`'s
/// model ([`relight_cpc::solve::materials::coarse_light`]) with `r × r` blocks over the
/// pure seen vertices of `w` read from `obs`, fit material `k` read as true material
/// `order[k]`; and the row count.
fn block_light_ratio_errors(
    case: &Case,
    obs: &relight_cpc::observe::Observations,
    (seen, w, order): (&[bool], &[f64], &[usize]),
    r: usize,
) -> (usize, [f64; 3]) {
    use relight_cpc::solve::materials::coarse_light;
    let kk = order.len();
    let input = super::mixture::rows_input(obs, &case.train.transport, (seen, w, kk), r);
    let rows = coarse_light::pure_seen_rows(&input);
    let n_photos = obs.photo_ranges.len();
    let rho: Vec<Vec<f64>> = (0..3)
        .map(|c| {
            coarse_light::coarse_light_albedos(&rows, c, n_photos, &vec![1.0; kk])
                .expect("finite rows")
        })
        .collect();
    (
        rows.len(),
        worst_ratio_errors(case, |k, c| rho[c][k], order),
    )
}
