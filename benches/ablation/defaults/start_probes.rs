//! The first fit's other starts, `ABLATION_DEFAULTS_START=…` (bench-only probes of
//! `bench-results/ratio-floor.md` and `validation-search.md`): the TRUE materials or half
//! of them, weights unmixed from each vertex's mean colour, and a grid over the materials'
//! log brightness judged by the validation score.

use super::Colours;
use crate::synth_case::*;
use relight_cpc::solve::cluster::{unmixed_weights, InitialMaterials};
use relight_cpc::solve::ratio_step;
use relight_cpc::solve::starts::{estimate_best, Start};
use relight_cpc::solve::{estimate, Estimate, EstimateOptions, Materials0, Problem};

/// `ABLATION_DEFAULTS_START=truth | truth-weights | truth-lambda` (the pilot took the true
/// count): the fit from the TRUE materials (the kept lobes' λ), from the true weights with
/// the start's λ (its materials put in the truth's order), or from the true λ with the
/// start's weights (the truth's materials put in the start's order).
pub(super) fn truth_start(variant: &str, m0: &mut Materials0, case: &Case, kept: &[usize]) {
    let t = case.true_materials();
    let true_lambda: Vec<Vec<[f64; 3]>> = t
        .lambda
        .iter()
        .map(|row| kept.iter().map(|&b| row[b]).collect())
        .collect();
    // perm[k] = the true material nearest start material k in Lambertian colour.
    let perm = nearest_order(&m0.lambda, &true_lambda, super::LAMBERT);
    match variant {
        "truth" => {
            *m0 = Materials0 {
                lambda: true_lambda,
                weights: t.weights,
            }
        }
        "truth-weights" => {
            let mut lambda = m0.lambda.clone();
            for (k, &j) in perm.iter().enumerate() {
                lambda[j] = m0.lambda[k].clone();
            }
            m0.lambda = lambda;
            m0.weights = t.weights;
        }
        _ => {
            for (k, &j) in perm.iter().enumerate() {
                m0.lambda[k] = true_lambda[j].clone();
            }
        }
    }
}

/// What `grid-unmix` unmixes each start's weights from: the clustered start and each
/// vertex's mean colour and whether a training photo sees it.
#[derive(Clone, Copy)]
pub(super) struct UnmixFrom<'a> {
    pub init: &'a InitialMaterials,
    pub colours: Colours<'a>,
}

/// `ABLATION_DEFAULTS_START=grid | grid-unmix`: a fit from each start on a grid of the
/// materials' log brightness around `m0` (`λ_k e^{Σ_j t_j u_{j,k}}`, `u_j = e_j − 1/K` for
/// `j < K − 1`, `t_j ∈ {−n·δ … n·δ}`, `δ = ABLATION_GRID_STEP` (0.2), `n = ABLATION_GRID_N`
/// (3 with two materials, 2 otherwise)), its weights `m0`'s or (`grid-unmix`) unmixed
/// from the mean colours over the start's Lambertian colours; the fit with the lowest
/// validation score is kept (`judge`: scored with those options, the start kept fitted
/// again with `opts`). With more than three materials (a wrong count), the plain fit.
pub(super) fn grid_start_fit(
    problem: &Problem,
    m0: &Materials0,
    opts: &EstimateOptions,
    judge: Option<&EstimateOptions>,
    lambert: usize,
    unmix: Option<UnmixFrom>,
) -> Estimate {
    let kk = m0.lambda.len();
    let step: f64 = crate::env_or("ABLATION_GRID_STEP", 0.2);
    let n = crate::env_or("ABLATION_GRID_N", if kk == 2 { 3 } else { 2 }) as i64;
    let dims = kk.saturating_sub(1);
    let side = (2 * n + 1) as usize;
    let starts: Vec<Start> = (0..side.pow(dims as u32))
        .map(|cell| {
            let t: Vec<f64> = (0..dims)
                .map(|j| ((cell / side.pow(j as u32)) % side) as f64 - n as f64)
                .map(|i| i * step)
                .collect();
            let mut lambda = m0.lambda.clone();
            for (j, &tj) in t.iter().enumerate() {
                lambda = ratio_step::scaled(&lambda, &ratio_step::direction(kk, j), [tj; 3]);
            }
            let weights = match unmix {
                Some(u) => {
                    let mut scaled = u.init.clone();
                    scaled.albedo = lambda.iter().map(|row| row[lambert]).collect();
                    unmixed_weights(&scaled, u.colours.mean_rgb, u.colours.seen).0
                }
                None => m0.weights.clone(),
            };
            Start {
                label: format!("t = {t:?}"),
                materials: Materials0 { lambda, weights },
            }
        })
        .collect();
    // The fit with the lowest validation score, as `--starts` keeps it; with `judge` (the
    // right halves of some training photos held back) the start it picks is fitted again
    // with `opts`, as `run` fits the light model `--light auto` keeps.
    let refit_from = judge.map(|_| starts.clone());
    let (est, multi) = estimate_best(problem, starts, judge.unwrap_or(opts), &mut |_, _, _| {})
        .expect("grid starts' fits");
    let est = match refit_from {
        Some(mut starts) => {
            let kept = starts.swap_remove(multi.chosen).materials;
            estimate(problem, kept, opts, &mut |_, _| {}).expect("the start kept, fitted again")
        }
        None => est,
    };
    for r in &multi.starts {
        eprintln!("grid start {}: validation {:.5}", r.label, r.score);
    }
    let kept = &multi.starts[multi.chosen];
    eprintln!(
        "grid start kept: {}, validation {:.5}",
        kept.label, kept.score
    );
    est
}

/// The permutation `perm` (start material `k` ↔ true material `perm[k]`) that brings the
/// start's Lambertian chromaticities nearest the truth's (least summed squared distance).
pub(super) fn nearest_order(
    start: &[Vec<[f64; 3]>],
    truth: &[Vec<[f64; 3]>],
    lambert: usize,
) -> Vec<usize> {
    let chroma = |a: [f64; 3]| {
        let s = (a[0] + a[1] + a[2]).max(f64::MIN_POSITIVE);
        a.map(|v| v / s)
    };
    let dist = |a: [f64; 3], b: [f64; 3]| {
        let (a, b) = (chroma(a), chroma(b));
        (0..3).map(|c| (a[c] - b[c]).powi(2)).sum::<f64>()
    };
    crate::metrics::permutations(start.len())
        .into_iter()
        .min_by(|p, q| {
            let cost = |p: &Vec<usize>| -> f64 {
                p.iter()
                    .enumerate()
                    .map(|(k, &j)| dist(start[k][lambert], truth[j][lambert]))
                    .sum()
            };
            cost(p).total_cmp(&cost(q))
        })
        .unwrap_or_default()
}

/// [`unmixed_weights`] over the pair of materials with the least residual only (all of
/// them with two or fewer): a vertex blends at most two. A vertex whose `v` is 0 keeps
/// its weights.
pub(super) fn unmix_pairs(m0: &mut Materials0, colours: Colours) {
    let Colours { mean_rgb, seen } = colours;
    let lambert = super::LAMBERT;
    let kk = m0.lambda.len();
    let subsets: Vec<Vec<usize>> = if kk > 2 {
        (0..kk)
            .flat_map(|a| (a + 1..kk).map(move |b| vec![a, b]))
            .collect()
    } else {
        vec![(0..kk).collect()]
    };
    for x in (0..seen.len()).filter(|&x| seen[x]) {
        let best = subsets
            .iter()
            .filter_map(|set| unmix_over(&m0.lambda, set, mean_rgb[x], lambert))
            .min_by(|a, b| a.1.total_cmp(&b.1));
        let Some((w, _)) = best else { continue };
        m0.weights[x * kk..(x + 1) * kk].copy_from_slice(&w);
    }
}

/// [`unmixed_weights`] on the clustered start in place: its weights and labels.
pub(super) fn unmix_initial(init: &mut InitialMaterials, colours: Colours) {
    (init.weights, init.labels) = unmixed_weights(init, colours.mean_rgb, colours.seen);
}

/// The weights (over all `K` materials, 0 outside `set`) of `c` unmixed over the Lambertian
/// colours of the materials in `set`, and the squared residual; `None` when they are 0.
fn unmix_over(
    lambda: &[Vec<[f64; 3]>],
    set: &[usize],
    c: [f64; 3],
    lambert: usize,
) -> Option<(Vec<f64>, f64)> {
    use nalgebra::{DMatrix, DVector};
    use relight_cpc::solve::qp::{nnls, NnlsOptions};
    let a = DMatrix::from_fn(3, set.len(), |ch, j| lambda[set[j]][lambert][ch]);
    let y = DVector::from_row_slice(&c);
    let v = nnls(
        &(a.transpose() * &a),
        &(a.transpose() * &y),
        &NnlsOptions::default(),
    )
    .ok()?;
    let total = v.sum();
    if total <= 0.0 {
        return None;
    }
    let residual = (&a * &v - &y).norm_squared();
    let mut w = vec![0.0; lambda.len()];
    for (j, &k) in set.iter().enumerate() {
        w[k] = v[j] / total;
    }
    Some((w, residual))
}

/// `ABLATION_DEFAULTS_START=core`: each cluster's colour the per-channel median over its
/// core, the `ABLATION_CORE` fraction (0.3) of its seen members nearest its centroid in
/// hue space, instead of over all its members: a band's blended vertices tint the median
/// of a material's weak channels, and they lie at the cluster's edge.
pub(super) fn core_colours(init: &mut InitialMaterials, colours: Colours) {
    use relight_cpc::solve::cluster::hue_feature;
    let frac: f64 = crate::env_or("ABLATION_CORE", 0.3);
    for (k, centre) in init.centroids.iter().enumerate() {
        let mut members: Vec<(f64, usize)> = (0..colours.seen.len())
            .filter(|&x| colours.seen[x] && init.labels[x] == k)
            .map(|x| {
                let f = hue_feature(colours.mean_rgb[x]);
                let d: f64 = (0..3).map(|i| (f[i] - centre[i]).powi(2)).sum();
                (d, x)
            })
            .collect();
        if members.len() < 10 {
            continue;
        }
        members.sort_by(|a, b| a.0.total_cmp(&b.0));
        let keep = ((members.len() as f64 * frac).ceil() as usize).max(5);
        let core = &members[..keep];
        let before = init.albedo[k];
        for c in 0..3 {
            let mut v: Vec<f64> = core.iter().map(|&(_, x)| colours.mean_rgb[x][c]).collect();
            v.sort_by(f64::total_cmp);
            init.albedo[k][c] = v[v.len() / 2];
        }
        eprintln!(
            "core colour of cluster {k}: {before:.4?} -> {:.4?} ({keep} of {} members)",
            init.albedo[k],
            members.len()
        );
    }
}
