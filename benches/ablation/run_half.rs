//! The ablation's held-out judge (the default; `ABLATION_HALF=common` asks for the common
//! judge instead): each row's held-out column judged as `relight-cpc run` judges its
//! held-out photos (protocol (b) with `--half-prior auto`, docs/method.md "Held-out
//! evaluation") with the row's options. The common judge
//! ([`crate::metrics::half_error`]: the paper's Laplacian at the default weight, from
//! zero, for every row alike) fits every row's held-out halves through the paper's model,
//! which counts against the light models that constrain the maps even where the truth
//! prefers them (`bench-results/light-prior-shiny.md`, sections 7–8).
//!
//! As `run` does ([`relight_cpc::run::half_prior`]):
//! - the half fit's light prior is chosen by replaying protocol (b) on up to four training
//!   photos ([`choose_prior_over`]): each photo's observations thinned to
//!   [`REPLAY_MAX_OBSERVATIONS`], cut at the middle of their projected `x`, the left half's
//!   map fitted from the mean of the other training maps under the Laplacian alone or the
//!   other maps' shape prior at `η` = 3, 10, the right half scored; when none beats the
//!   Laplacian, the light model's own prior (at 0.2 of its noise levels) if it has one;
//! - the Laplacian's weight is the fit's (`--half-smoothness fit`);
//! - each held-out photo's map is fitted on its observations left of the middle of their
//!   projected `x`, from the mean training map, in the fit's IRLS passes at `run`'s caps
//!   ([`half_fit_passes`]), and the right half is scored (relative RMSE, best scale per
//!   channel, as the common judge scores).
//!
//! Differences from `run`: the halves are cut over the photo's observations, not its
//! rendered pixels; overexposed observations are not read as bounds; a held-out photo's
//! geotag sun is not used (the ablation's scenes are not geotagged). The floor is the same
//! judge with the true reflectance and the true training maps.

use crate::synth_case::*;
use relight_cpc::observe::Observations;
use relight_cpc::run::half_fit::{half_fit_passes, projected_x, sides, HALF_FIT_CG, HALF_FIT_GPCG};
use relight_cpc::run::half_prior::{
    candidates, choose_prior_over, mean_map, replay_errors_of, thin_observations,
    without_training_prior, HalfLightPrior, ReplayInputs, ReplayPhoto, REPLAY_MAX_OBSERVATIONS,
};
use relight_cpc::solve::light::frozen::fit_light_scheduled;
use relight_cpc::solve::{beta_per_vertex, EstimateOptions};
use relight_cpc::transport::Transport;

/// Whether this judge is used: always, unless `ABLATION_HALF=common` asks for the
/// common one.
pub fn wanted() -> bool {
    !std::env::var("ABLATION_HALF").is_ok_and(|v| v == "common")
}

/// The held-out error of reflectance `(lambda, weights)` with training maps `lights`,
/// fitted with options `opts`, under `run`'s judge (module docs). The row's floor is the
/// truth through the same call: under a light model with a prior of its own, the judge
/// may add it, so each row's floor is its own.
pub fn run_half_error(
    case: &Case,
    lambda: &[Vec<[f64; 3]>],
    weights: &[f64],
    lights: &[[Vec<f64>; 3]],
    opts: &EstimateOptions,
) -> f64 {
    let beta = beta_per_vertex(lambda, weights, case.nv);
    let half = EstimateOptions {
        lighting_sample: 0,
        ..opts.clone()
    };
    let prior = chosen_prior(case, &beta, lights, &half);
    let n = case.train.transport.n_global;
    let fit_opts = EstimateOptions {
        light_prior: prior
            .options(lights, n, half.light_prior.as_ref())
            .expect("half prior"),
        ..half
    };
    eprintln!("  run's half judge: prior {}", prior.name());
    let start = mean_map(lights, n * n);
    held_right_error(case, &beta, &start, &fit_opts)
}

/// `run --half-prior auto`'s prior for the half fit (module docs).
fn chosen_prior(
    case: &Case,
    beta: &[[f64; 3]],
    lights: &[[Vec<f64>; 3]],
    half: &EstimateOptions,
) -> HalfLightPrior {
    let replay_opts = EstimateOptions {
        qp_max_iter: HALF_FIT_GPCG,
        qp_max_cg: HALF_FIT_CG,
        ..half.clone()
    };
    let inputs = ReplayInputs {
        beta,
        lights,
        n: case.train.transport.n_global,
        n_vertices: case.nv,
        opts: &replay_opts,
    };
    let priors = candidates();
    let choice = choose_prior_over(lights.len(), &priors, |k| {
        replay_of(case, k)?
            .map(|r| replay_errors_of(&r, k, inputs, &priors))
            .transpose()
    })
    .expect("half prior replay");
    eprintln!("  run's half judge: replay scores {:?}", choice.scores);
    match choice.kept {
        HalfLightPrior::Laplacian => without_training_prior(half.light_prior.is_some()),
        kept => kept,
    }
}

/// Training photo `k`'s replay: its observations thinned as `run` thins them, the
/// transport's rows gathered from the training split's.
fn replay_of(case: &Case, k: usize) -> relight_cpc::Result<Option<ReplayPhoto>> {
    let range = case.train.obs.photo_ranges[k].clone();
    let rows: Vec<usize> = range.collect();
    let obs = thin_observations(case.train.obs.gather(&rows), REPLAY_MAX_OBSERVATIONS);
    let px = projected(case, &case.train.views[k], &obs.vertex);
    ReplayPhoto::new(obs, &px, |o| Ok(gathered_rows(case, &rows, o)))
}

/// The projected `x` in `view` of each observation's vertex (`vertices`).
fn projected(
    case: &Case,
    view: &relight_cpc::import::scene::View,
    vertices: &[u32],
) -> Vec<Option<f64>> {
    vertices
        .iter()
        .map(|&x| projected_x(view, &case.positions[x as usize]))
        .collect()
}

/// The training transport's rows of the observations of `obs` (a gathered, thinned
/// subset of the observations `rows` of the training split, in order).
fn gathered_rows(case: &Case, rows: &[usize], obs: &Observations) -> Transport {
    let t = &case.train.transport;
    // A photo sees a vertex once: its vertex names an observation's training row.
    let row_of: std::collections::HashMap<u32, usize> = rows
        .iter()
        .map(|&r| (case.train.obs.vertex[r], r))
        .collect();
    let src: Vec<usize> = obs.vertex.iter().map(|v| row_of[v]).collect();
    let mut out = Transport {
        n_global: t.n_global,
        n_basis: t.n_basis,
        n_obs: src.len(),
        offsets: vec![0],
        index: Vec::new(),
        value: Vec::new(),
    };
    for &p in &src {
        for b in 0..t.n_basis {
            let (idx, val) = t.row(p, b);
            out.index.extend_from_slice(idx);
            out.value.extend_from_slice(val);
            out.offsets.push(out.index.len());
        }
    }
    out
}

/// Each held-out photo's map fitted on its observations left of the middle of their
/// projected `x`, from `start`; the right halves' relative RMSE (best scale per channel).
fn held_right_error(
    case: &Case,
    beta: &[[f64; 3]],
    start: &[Vec<f64>; 3],
    opts: &EstimateOptions,
) -> f64 {
    let held = &case.held;
    let mut fit_obs = held.obs.clone();
    let mut eval_obs = held.obs.clone();
    for (i, range) in held.obs.photo_ranges.iter().enumerate() {
        let px = projected(case, &held.views[i], &held.obs.vertex[range.clone()]);
        let sides = sides(&held.obs.weight[range.clone()], &px);
        for (q, p) in range.clone().enumerate() {
            if sides.as_ref().is_some_and(|s| s[q] == Some(true)) {
                eval_obs.weight[p] = 0.0;
            } else {
                fit_obs.weight[p] = 0.0;
            }
        }
    }
    let problem = relight_cpc::solve::Problem {
        obs: &fit_obs,
        transport: &held.transport,
        n_vertices: case.nv,
        n_photos: fit_obs.photo_ranges.len(),
    };
    let passes = half_fit_passes(opts.irls_iters);
    let lights: Vec<[Vec<f64>; 3]> = (0..problem.n_photos)
        .map(|i| {
            fit_light_scheduled(&problem, beta, i, Some(start), opts, &passes)
                .expect("half fit")
                .light
        })
        .collect();
    let s = relight_cpc::solve::basis_responses(&problem, &lights);
    let pred = relight_cpc::solve::problem::predict_from(&problem, beta, &s);
    rel_rmse_per_channel(&eval_obs, &pred)
}
