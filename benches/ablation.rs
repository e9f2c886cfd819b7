//! The light-model ablation of issue 25: `cargo bench --bench ablation` writes
//! `bench-results/estimator-ablation.{md,json}`.
//!
//! Scenes made by `relight-cpc synth` (the reference renderer, the eight embedded CC0 maps,
//! a different map and rotation per photo) and taken through the real pipeline stages
//! (`tests/support/synth_case.rs`): `spot-diffuse` (two Lambertian materials),
//! `spot-varying` (two glossy materials) and `spot-three` (three materials). Every fourth
//! photo is held out; with 16 photos cycling the 8 maps the held-out photos are lit by
//! maps 3 and 7, which no training photo sees: the held-out photos are the *unseen maps*.
//! Each scene twice: as rendered (Monte Carlo noise, 1% clipping, 8-bit sRGB) and
//! noise-free (every observation replaced by the true model's prediction through the
//! case's own transport, so every error is the estimator's).
//!
//! Per light model (one line of [`rows`] each) and case:
//! - **held-out** (the run's half protocol): each held-out photo's light fitted with the
//!   reflectance frozen on the observations left of its centre line, judged as `run`
//!   judges it with the row's options ([`run_half`]: the half prior `run` would learn,
//!   the row's Laplacian weight, from the mean training map), the right half predicted,
//!   relative RMSE after the best scale per channel; *photo floor* = the truth (true
//!   reflectance, true training maps) through the same judge, so each row has its own.
//!   `ABLATION_HALF=common` judges every row alike instead ([`half_error`]: the paper's
//!   Laplacian, no light prior, from zero), against the truth through that judge;
//! - **relit** under the unseen maps: the held-out photos predicted under their TRUE maps,
//!   best scale per channel (the light colour is not observable), against the photos;
//!   *MC floor* = the true reflectance doing the same (the renderer's noise and the
//!   transport's discretisation: the metric's own floor);
//! - **albedo ratios**: per channel and material `j ≥ 1`, the median estimated Lambertian
//!   weight `β̂_{x,L,c}` over the vertices truly pure material `j` (weight ≥ 0.95) over the
//!   same median for material 0, against the truth's `λ_{j,L,c} / λ_{0,L,c}`: invariant to
//!   the K×K material remix and the per-channel scale; the worst relative error;
//!   *ratio floor* = the same error of the material step alone under the TRUE maps, from
//!   the truth ([`true_light`]): what the photos hold of the ratios through the case's
//!   transport, whatever the light model;
//! - **material accuracy**: the fraction of seen vertices whose largest estimated weight
//!   is their true largest material (best of the K! orders), fitted with the true K;
//! - **K chosen**: the adaptive pilot's rule ([`relight_cpc::solve::adapt`], step 3) with
//!   the row's light model: K = 1 … K_true + 1 fitted for
//!   [`adapt::PILOT_ITERATIONS`] outer iterations on the training observations with 1 in
//!   [`adapt::HELDOUT_EVERY`] held out, the smallest K within [`adapt::MATERIAL_TOL`] of
//!   the best held-out RMSE.
//!
//! The row `defaults (the pilot's choices)` is what `relight-cpc run` does with no flags
//! (`ablation/defaults.rs`): the adaptive pilot itself chooses the count, the weights'
//! prior and the lobes from the case's basis, and the fit uses its choices; its *K* column
//! is the pilot's own search.
//!
//! Every prior row uses leave-one-map-out statistics: a photo's prior never contains the
//! map it was rendered with ([`with_case_priors`]).
//!
//! Environment: `ABLATION_SCENES` (comma list), `ABLATION_ROWS` (`;`-separated row
//! labels), `ABLATION_CLEAN=0|1` (only the 8-bit or only the noise-free cases),
//! `ABLATION_WIDTH`, `ABLATION_VERTICES`, `ABLATION_PHOTOS`, `ABLATION_ITERS` (≤ outer iterations, default 20),
//! `ABLATION_NO_K=1` (skip the K search), `ABLATION_START=truth|gloss|open|matched|…`
//! ([`fit_start`]; `ABLATION_MATCH_COS` for `matched`, `ABLATION_K1_ITERS` for `k1`),
//! `ABLATION_DEFAULTS_ITERS=bench` (the `defaults` row at the bench's iteration cap instead
//! of `run`'s, `ablation/defaults.rs`), `ABLATION_DEFAULTS_MAX_ITERS=N` (the `defaults` row
//! with `run --iterations N`), `ABLATION_DEFAULTS_STOP_HALVES=N` (its early stopping on the
//! right halves of `N` training photos, `run --validation-halves N`), `ABLATION_TRACE=1`
//! (each outer round's early-stopping score, worst albedo ratio error and material
//! accuracy, `defaults::tracer`; `signed`: also each material's signed ratio errors),
//! `ABLATION_RATIO_STEPS=N` (the `defaults` row with
//! `run --ratio-steps N`), `ABLATION_DEFAULTS_PATIENCE=N` (the `defaults` row with
//! `run --patience N`), `ABLATION_DEFAULTS_IRLS=N`, `ABLATION_DEFAULTS_FLOOR=X`,
//! `ABLATION_DEFAULTS_ROBUST=K|tukey` (the `defaults` row with `run --irls-iterations N`,
//! IRLS's robust floor `X`, Huber's `k` or Tukey's biweight), `ABLATION_DEFAULTS_ALL_LOBES=1`
//! (the `defaults` row keeps every lobe the pilot would drop),
//! `ABLATION_DEFAULTS_START=truth|truth-weights|truth-lambda|unmix|unmix2|unmix-match|grid|grid-unmix|refit|refit-w|reanchor|reanchor2|reanchor-lambert|reanchor-label|reanchor-label2|reanchor-label-truth-lambda|reanchor-label-truth-weights|reanchor-label-truth-diffuse|reanchor-project-truth-lambda|sh-ratio|sh-ratio2|coarse-light|coarse-light-free|reanchor-coarse|stiff-spec|stiff-weights`
//! (with `ABLATION_GRID_STEP=X`, `ABLATION_GRID_N=N` for the grids; the last sixteen a second
//! fit from the first fit's materials (`sh-ratio2`: and a third fit from the model read
//! again over the second fit's weights), `ABLATION_REFIT_PICK=1` keeping the one with the
//! lower validation error, `ABLATION_SH_OPEN=X` the least open fraction of the vertices
//! `sh-ratio` (`run --restart irradiance`'s start) reads, `run`'s 0.95,
//! `ABLATION_SH_TRUTH=1|only` its diagnosis over the true and the fitted pure vertices,
//! `only` stopping after it, with `ABLATION_SH_BLOCKS=r,…` the coarse-light
//! model's too (over the pure vertices, on the photos, exact data and exact data plus the
//! photos' residuals with random signs; `ABLATION_SH_BLOCKS_ERODED=1` for the eroded
//! regions too, `ABLATION_SH_DIM=X` also with every observation whose brightest channel
//! reaches `X` left out, `ABLATION_SH_MIX=s,…` the blend model over every observation with
//! the weights mixed with their neighbours' by each `s`, `ablation/defaults/mixture.rs`); `coarse-light` is `run --restart coarse-light`, the lights
//! fitted again with the start's materials held, `coarse-light-free` a free second fit
//! from the same start; without one, the row makes `run --restart auto`'s second fit,
//! `ABLATION_DEFAULTS_RESTART=off` none; `reanchor-coarse` is `run --restart
//! on+coarse-light`; `ABLATION_ONE_SE=0` keeps each coarse-light held fit on the lower
//! validation error alone, without the one-standard-error rule; `stiff-spec` starts the
//! specular lobes from a stiff-light fit, `ABLATION_STIFF_HAAR`, `ABLATION_STIFF_ITERS`,
//! `ABLATION_STIFF_TAKE=all`, `ablation/defaults/mod.rs`; `stiff-weights` fits first with
//! the weights' priors `ABLATION_STIFF_WEIGHTS` times as strong, default 10, then from that
//! fit under the row's options; `reanchor-label` is `reanchor` with one-hot weights,
//! `reanchor-label2` twice, `reanchor-label-truth-lambda|weights|diffuse` with the true `λ`,
//! the true weights or the true Lambertian lobes in place of the re-anchored ones,
//! `reanchor-project-truth-lambda` the true `λ` with the fit's reflectance projected on it),
//! `ABLATION_DEFAULTS_SCOPE=blends` (the `defaults` row with the
//! sum-to-one prior on blended vertices whatever the pilot's scope), and
//! `ABLATION_DEFAULTS_SMOOTHNESS=X` (its start and its maps' Laplacian weight,
//! `ablation/defaults.rs`), `ABLATION_DEFAULTS_LIGHT=paper|shared|oracle-sh` (the `defaults` row with
//! `run --light paper`, or `--light shared` with the groups the photos' true skies, or the
//! prior centred on each training photo's TRUE low-order shape at `ABLATION_ORACLE_FACTOR`
//! times its precision, a probe; without it the row's light is `run`'s choice by scene),
//! `ABLATION_DEFAULTS_GROUPS=1` (the training photos' groups under one true sky known to
//! `run`'s choice, as EXIF capture times give them: `--light auto` adds the shared map),
//! `ABLATION_PRIOR_SH_NOISE=η`, `ABLATION_PRIOR_HAAR_NOISE=η` (the light prior's noise
//! levels in the `defaults` row's fit when its model has the prior), `SYNTH_SHARED_SKIES=1` (the
//! scenes rendered with photos `i` and `i + 8` under one sky: the same map at the same
//! rotation, so the training photos form 6 groups of two seen from opposite sides and the
//! `shared` row has groups; the held-out photos' maps stay unseen), `ABLATION_SEARCH`,
//! `ABLATION_SEARCH_ROUNDS`, `ABLATION_SEARCH_CHANNELS`, `ABLATION_SEARCH_SCORE` (the start
//! search, `ablation/search.rs`), `ABLATION_QP` (solver steps per lighting fit inside a
//! round, `run --lighting-qp-iterations`; default the estimator's),
//! `ABLATION_CLIPPED_BOUNDS=1` (clipped channels read as lower bounds, `run --clipped bound`),
//! `ABLATION_ACCURACY_MISSES=1` (where the `defaults` row's material-accuracy misses are,
//! [`metrics::accuracy_misses`]), `ABLATION_TAIL=1` (the share of each material's seen
//! pure vertices far off its median albedo, facing down and not, for the true maps and the
//! `defaults` fit, [`metrics::tail_shares`]), `ABLATION_FLOOR_FLIP=1` (the ratio floor's fit
//! from the truth on exact data and on exact data plus the photos' residuals with random
//! signs, and one `λ` step with the TRUE weights mixed with their neighbours' and without
//! the highlight-dominated observations, and the photos' residuals kept on one class of
//! observations at a time, [`true_light::floor_sources`]), `ABLATION_FIT_SHARE=1` (one `λ`
//! step under the `defaults` fit's maps without the observations its own shiny lobes
//! dominate, [`true_light::fitted_share_probe`]), `ABLATION_PROFILE=1` (the objective
//! at the truth and at the `defaults` fit's materials, the lights refitted for both;
//! `axes`: also along the albedo ratio directions and where its minimum lies, [`profile`]), `ABLATION_NORMAL_GRID=N` (the rotation's
//! normal grid, `run`'s 32 by default; `SYNTH_SPLAT_ROTATION=1` rotates at each vertex's
//! exact normal instead), `ABLATION_LAMBDA=1` (every fit's `λ` per
//! material and lobe against the truth's, after the per-channel scale of the diffuse
//! colours, [`metrics::scaled_lambda`]), `ABLATION_SPECULAR_START=X` (the `defaults` row's
//! start with every lobe but the Lambertian one at `X` times its `λ`: with
//! `ABLATION_DEFAULTS_START=truth-lambda`, `X` times the truth's), `ABLATION_SEED` (the scenes' `synth` seed, default 1: other photos, maps and noise),
//! `ABLATION_HALF=common` (every row's held-out column judged by the common judge,
//! [`half_error`], instead of `run`'s, [`run_half`]), `RESULTS_SUFFIX=S`
//! (`estimator-ablation-S.*`).

#![allow(clippy::needless_range_loop)]

#[path = "../tests/support/synth_case.rs"]
mod synth_case;

use relight_cpc::observe::Observations;
use relight_cpc::solve::light::choose::{candidates, decide, LightChoice};
use relight_cpc::solve::materials::propagate::propagate_unseen;
use relight_cpc::solve::{adapt, estimate, Estimate};
use relight_cpc::solve::{EstimateOptions, Materials0};
use serde_json::{json, Value};
use std::time::Instant;
use synth_case::*;

#[path = "ablation/defaults/mod.rs"]
mod defaults;
#[path = "ablation/diagnose.rs"]
mod diagnose;
#[path = "ablation/metrics.rs"]
mod metrics;
#[path = "ablation/profile.rs"]
mod profile;
#[path = "ablation/run_half.rs"]
mod run_half;
#[path = "support/run_line.rs"]
mod run_line;
#[path = "ablation/search.rs"]
mod search;
#[path = "ablation/starts.rs"]
mod starts;
#[path = "ablation/table.rs"]
mod table;
#[path = "support/today.rs"]
mod today;
#[path = "ablation/true_light.rs"]
mod true_light;
use metrics::*;
use search::{brightness_search, restarts};
use starts::fit_start;
use table::table;

/// How a row's estimator options are made from the bench's base options; `None` when the
/// model is not in this build (a `--light` name the binary does not know yet).
type Make = fn(&EstimateOptions) -> Option<EstimateOptions>;

/// One row of the ablation.
enum Row {
    /// A fit with the options `make` returns.
    Fit { label: &'static str, make: Make },
    /// No fit of its own: the row among `among()` (labels of earlier rows) with the lowest
    /// early-stopping validation score ([`decide`], as `--light auto` keeps a model).
    Pick {
        label: &'static str,
        among: fn() -> Vec<String>,
    },
    /// What `run` does with no flags: the adaptive pilot's choices, then the fit
    /// (`ablation/defaults.rs`).
    Defaults { label: &'static str },
}

/// The row label of `--light NAME`'s model.
fn label_of(name: &str) -> String {
    match name {
        "prior" => PRIOR.to_string(),
        other => other.to_string(),
    }
}

/// The defaults' row label.
const DEFAULTS: &str = "defaults (the pilot's choices)";

/// The `--light prior` row's label.
const PRIOR: &str = "prior (SH 0.3 + Haar 0.03)";

/// The models `--light auto` fits in this build, as row labels.
fn auto_models() -> Vec<String> {
    candidates(LightChoice::Auto, &EstimateOptions::default())
        .map(|v| v.iter().map(|c| label_of(c.name)).collect())
        .unwrap_or_default()
}

fn labels(v: &[&str]) -> Vec<String> {
    v.iter().map(|s| s.to_string()).collect()
}

/// A `--light NAME` model as `run` builds it (its first candidate).
fn choice(name: &str, base: &EstimateOptions) -> Option<EstimateOptions> {
    let c = LightChoice::parse(name).ok()?;
    candidates(c, base)
        .ok()?
        .into_iter()
        .next()
        .map(|c| c.options)
}

/// The free map under the SH shape prior at noise level `sh` and the Haar L1 prior at
/// `haar` (statistics filled in per case).
fn prior(base: &EstimateOptions, sh: f64, haar: f64) -> Option<EstimateOptions> {
    let mut o = choice("prior", base)?;
    let lp = o.light_prior.as_mut()?;
    lp.sh_noise = sh;
    lp.haar_noise = haar;
    Some(o)
}

/// `o` with the blending weights' sum-to-one prior at strength `tau`
/// ([`EstimateOptions::weights_sum`]).
fn sum1(o: Option<EstimateOptions>, tau: f64) -> Option<EstimateOptions> {
    o.map(|o| EstimateOptions {
        weights_sum: tau,
        ..o
    })
}

/// `o` with its sum-to-one prior on blended vertices only
/// ([`relight_cpc::solve::SumScope::Blends`] at `run`'s floor).
fn on_blends(o: Option<EstimateOptions>) -> Option<EstimateOptions> {
    o.map(|o| EstimateOptions {
        weights_sum_scope: relight_cpc::solve::SumScope::Blends {
            floor: relight_cpc::solve::BLEND_FLOOR,
        },
        ..o
    })
}

/// `o` with the neighbour prior on the blending weights at strength `tau`
/// ([`EstimateOptions::weights_smoothness`]; its graph filled in per case by [`with_case_graph`]).
fn pull(o: Option<EstimateOptions>, tau: f64) -> Option<EstimateOptions> {
    o.map(|o| EstimateOptions {
        weights_smoothness: tau,
        ..o
    })
}

/// `o` with the case's vertex graph when the neighbour prior is on (the run's graph:
/// the symmetrised 8-nearest-neighbour graph of the positions).
fn with_case_graph(case: &Case, o: EstimateOptions) -> EstimateOptions {
    if o.weights_smoothness <= 0.0 {
        return o;
    }
    use relight_cpc::solve::materials::propagate::{knn_graph, NEIGHBOURS};
    let graph = knn_graph(&case.positions, NEIGHBOURS).expect("the case's vertex graph");
    EstimateOptions {
        weights_graph: graph.into(),
        ..o
    }
}

/// The rows, in table order. Adding a light model is one line here.
#[rustfmt::skip]
fn rows() -> Vec<Row> {
    vec![
        Row::Fit { label: "paper", make: |b| choice("paper", b) },
        Row::Fit { label: "prior SH η=0.3", make: |b| prior(b, 0.3, 0.0) },
        Row::Fit { label: PRIOR, make: |b| choice("prior", b) },
        Row::Fit { label: "paper, Σw=1 prior 1", make: |b| sum1(choice("paper", b), 1.0) },
        Row::Fit { label: "prior, Σw=1 prior 1", make: |b| sum1(choice("prior", b), 1.0) },
        Row::Fit { label: "sky", make: |b| choice("sky", b) },
        Row::Fit { label: "shared", make: |b| choice("shared", b) },
        Row::Defaults { label: DEFAULTS },
        Row::Pick { label: "auto (--light auto)", among: auto_models },
        Row::Pick {
            label: "prior η by validation",
            among: || labels(&["prior SH η=0.1", "prior SH η=0.3", "prior SH η=1", PRIOR]),
        },
        Row::Pick {
            label: "Σw=1 with or without achromatic specular",
            among: || labels(&["paper, Σw=1 prior 1", "paper, Σw=1 prior 1, achromatic specular"]),
        },
        Row::Pick {
            label: "Σw=1 long run with or without achromatic specular",
            among: || labels(&["paper, Σw=1 prior 1, no IRLS, patience 1000", "paper, Σw=1 prior 1, achromatic specular, no IRLS, patience 1000"]),
        },
        Row::Pick {
            label: "auto with and without Σw=1",
            among: || {
                let mut v = auto_models();
                v.extend(labels(&["paper, Σw=1 prior 1", "prior, Σw=1 prior 1"]));
                v
            },
        },
    ]
}

/// `o` without IRLS (plain least squares in every step).
fn no_irls(o: Option<EstimateOptions>) -> Option<EstimateOptions> {
    o.map(|o| EstimateOptions {
        robust: relight_cpc::solve::Robust::None,
        ..o
    })
}

/// `o` with one specular weight per material across R, G and B
/// ([`EstimateOptions::achromatic_specular`]).
fn achromatic(o: Option<EstimateOptions>) -> Option<EstimateOptions> {
    o.map(|o| EstimateOptions {
        achromatic_specular: true,
        ..o
    })
}

/// `o` with Anderson acceleration over λ of depth `m` ([`EstimateOptions::anderson_depth`]).
fn anderson(o: Option<EstimateOptions>, m: usize) -> Option<EstimateOptions> {
    o.map(|o| EstimateOptions {
        anderson_depth: m,
        ..o
    })
}

/// `o` with IRLS's robust scale floored at `floor` of the photo's RMS radiance
/// ([`EstimateOptions::robust_floor`], default 0.05).
fn floor(o: Option<EstimateOptions>, floor: f64) -> Option<EstimateOptions> {
    o.map(|o| EstimateOptions {
        robust_floor: floor,
        ..o
    })
}

/// `o` with early stopping's patience at 4 outer iterations (default 1).
fn patient(o: Option<EstimateOptions>) -> Option<EstimateOptions> {
    o.map(|o| EstimateOptions { patience: 4, ..o })
}

/// `o` with early stopping's patience at `n` outer iterations (the best-validation iterate
/// still returned).
fn patience(o: Option<EstimateOptions>, n: usize) -> Option<EstimateOptions> {
    o.map(|o| EstimateOptions { patience: n, ..o })
}

/// `o` with the Laplacian schedule `smoothness_decay` = `decay` down to `smoothness_min` = `min`.
fn decay(o: Option<EstimateOptions>, decay: f64, min: f64) -> Option<EstimateOptions> {
    o.map(|o| EstimateOptions {
        smoothness_decay: decay,
        smoothness_min: min,
        ..o
    })
}

/// Rows run only when `ABLATION_ROWS` names them (variants measured once, not part of the
/// standard table).
#[rustfmt::skip]
fn extra_rows() -> Vec<Row> {
    vec![
        Row::Fit { label: "prior SH η=0.1", make: |b| prior(b, 0.1, 0.0) },
        Row::Fit { label: "prior SH η=1", make: |b| prior(b, 1.0, 0.0) },
        Row::Fit { label: "prior SH η=0.3, Haar η=0.1", make: |b| prior(b, 0.3, 0.1) },
        Row::Fit { label: "prior SH η=0.3, Haar η=0.3", make: |b| prior(b, 0.3, 0.3) },
        Row::Fit { label: "paper, Σw=1 prior 0.1", make: |b| sum1(choice("paper", b), 0.1) },
        Row::Fit { label: "paper, Σw=1 prior 1 on blends", make: |b| on_blends(sum1(choice("paper", b), 1.0)) },
        Row::Fit { label: "paper, neighbour prior 0.1", make: |b| pull(choice("paper", b), 0.1) },
        Row::Fit { label: "paper, Σw=1 prior 1, neighbour prior 0.1", make: |b| pull(sum1(choice("paper", b), 1.0), 0.1) },
        Row::Fit { label: "paper, Σw=1 prior 0.3", make: |b| sum1(choice("paper", b), 0.3) },
        Row::Fit { label: "paper, Σw=1 prior 10", make: |b| sum1(choice("paper", b), 10.0) },
        Row::Fit { label: "paper, no IRLS", make: |b| no_irls(choice("paper", b)) },
        Row::Fit { label: "paper, Σw=1 prior 1, no IRLS", make: |b| no_irls(sum1(choice("paper", b), 1.0)) },
        Row::Fit { label: "prior, Σw=1 prior 1, no IRLS", make: |b| no_irls(sum1(choice("prior", b), 1.0)) },
        Row::Fit { label: "paper, patience 4", make: |b| patient(choice("paper", b)) },
        Row::Fit { label: "paper, Σw=1 prior 1, patience 4", make: |b| patient(sum1(choice("paper", b), 1.0)) },
        Row::Fit { label: "paper, Σw=1 prior 1, patience 50", make: |b| patience(sum1(choice("paper", b), 1.0), 50) },
        Row::Fit { label: "paper, Σw=1 prior 1, Laplacian ×0.8 per iteration to 1e-5", make: |b| decay(sum1(choice("paper", b), 1.0), 0.8, 1e-5) },
        Row::Fit { label: "paper, Σw=1 prior 1, Laplacian ×0.8 per iteration to 1e-4", make: |b| decay(sum1(choice("paper", b), 1.0), 0.8, 1e-4) },
        Row::Fit { label: "paper, Σw=1 prior 1, no IRLS, patience 50", make: |b| patience(no_irls(sum1(choice("paper", b), 1.0)), 50) },
        Row::Fit { label: "paper, Σw=1 prior 1, no IRLS, patience 1000", make: |b| patience(no_irls(sum1(choice("paper", b), 1.0)), 1000) },
        Row::Fit { label: "paper, Σw=1 prior 10, no IRLS, patience 1000", make: |b| patience(no_irls(sum1(choice("paper", b), 10.0)), 1000) },
        Row::Fit { label: "paper, Σw=1 prior 1, patience 1000", make: |b| patience(sum1(choice("paper", b), 1.0), 1000) },
        Row::Fit { label: "paper, no IRLS, patience 1000", make: |b| patience(no_irls(choice("paper", b)), 1000) },
        Row::Fit { label: "paper, achromatic specular", make: |b| achromatic(choice("paper", b)) },
        Row::Fit { label: "paper, Σw=1 prior 1, achromatic specular", make: |b| achromatic(sum1(choice("paper", b), 1.0)) },
        Row::Fit { label: "paper, Σw=1 prior 1, achromatic specular, no IRLS, patience 1000", make: |b| patience(no_irls(achromatic(sum1(choice("paper", b), 1.0))), 1000) },
        Row::Fit { label: "prior, Σw=1 prior 1, achromatic specular", make: |b| achromatic(sum1(choice("prior", b), 1.0)) },
        Row::Fit { label: "paper, Σw=1 prior 1, Anderson 3", make: |b| anderson(sum1(choice("paper", b), 1.0), 3) },
        Row::Fit { label: "paper, Σw=1 prior 1, Anderson 3, no IRLS, patience 1000", make: |b| patience(no_irls(anderson(sum1(choice("paper", b), 1.0), 3)), 1000) },
        Row::Fit { label: "paper, Σw=1 prior 1, achromatic specular, Anderson 3, no IRLS, patience 1000", make: |b| patience(no_irls(anderson(achromatic(sum1(choice("paper", b), 1.0)), 3)), 1000) },
        Row::Fit { label: "prior, Σw=1 prior 1, no IRLS, patience 1000", make: |b| patience(no_irls(sum1(choice("prior", b), 1.0)), 1000) },
        Row::Fit { label: "prior SH η=0.3, Σw=1 prior 1, no IRLS, patience 1000", make: |b| patience(no_irls(sum1(prior(b, 0.3, 0.0), 1.0)), 1000) },
        Row::Fit { label: "prior SH η=1, Σw=1 prior 1", make: |b| sum1(prior(b, 1.0, 0.0), 1.0) },
        Row::Fit { label: "prior SH η=3, Σw=1 prior 1", make: |b| sum1(prior(b, 3.0, 0.0), 1.0) },
        Row::Fit { label: "prior SH η=3, Σw=1 prior 1, no IRLS, patience 1000", make: |b| patience(no_irls(sum1(prior(b, 3.0, 0.0), 1.0)), 1000) },
        Row::Fit { label: "prior SH η=10, Σw=1 prior 1, no IRLS, patience 1000", make: |b| patience(no_irls(sum1(prior(b, 10.0, 0.0), 1.0)), 1000) },
        Row::Fit { label: "paper, robust floor 0.15", make: |b| floor(choice("paper", b), 0.15) },
        Row::Fit { label: "paper, Σw=1 prior 1, robust floor 0.1", make: |b| floor(sum1(choice("paper", b), 1.0), 0.1) },
        Row::Fit { label: "paper, Σw=1 prior 1, robust floor 0.15", make: |b| floor(sum1(choice("paper", b), 1.0), 0.15) },
        Row::Fit { label: "paper, Σw=1 prior 1, robust floor 0.3", make: |b| floor(sum1(choice("paper", b), 1.0), 0.3) },
        Row::Fit { label: "prior SH η=1, Σw=1 prior 1, no IRLS, patience 1000", make: |b| patience(no_irls(sum1(prior(b, 1.0, 0.0), 1.0)), 1000) },
    ]
}

/// The rows whose material count is searched (the K search costs about one more fit; the
/// other rows show `–`).
const K_ROWS: [&str; 4] = ["paper", PRIOR, "paper, Σw=1 prior 1", "prior, Σw=1 prior 1"];

/// The scenes: (synth name, what it stands for).
const SCENES: [(&str, &str); 3] = [
    ("spot-diffuse", "diffuse"),
    ("spot-varying", "glossy"),
    ("spot-three", "three materials"),
];

/// The environment variable `k` parsed as a `T`, or `d` when it is unset or does not parse.
fn env_or<T: std::str::FromStr>(k: &str, d: T) -> T {
    std::env::var(k)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(d)
}

/// The cases' sizes: 96² photos (`ABLATION_WIDTH`), 8 spp (`ABLATION_SPP`), Spot's 2,930
/// vertices (`ABLATION_VERTICES=N`: at least N, the mesh subdivided as `synth --vertices`), 16²
/// global / 8² local maps (`ABLATION_GLOBAL`, `ABLATION_LOCAL`), 2 shadow rays per local
/// texel (`ABLATION_RAYS`), `run`'s 32² normal grid for the rotation into each vertex's
/// frame (`ABLATION_NORMAL_GRID`; the bench used 16² until 2026-12-06, which raised the
/// three-material ratio floor, `bench-results/normal-grid-floor.md`), every coefficient
/// kept.
fn sizes() -> Sizes {
    let small = Sizes::spot_small();
    Sizes {
        width: env_or("ABLATION_WIDTH", 96) as u32,
        photos: std::env::var("ABLATION_PHOTOS")
            .ok()
            .and_then(|v| v.parse().ok()),
        vertices: env_or("ABLATION_VERTICES", 2_000),
        spp: env_or("ABLATION_SPP", 8) as u32,
        global: env_or("ABLATION_GLOBAL", small.global),
        local: env_or("ABLATION_LOCAL", small.local),
        rays_per_texel: env_or("ABLATION_RAYS", small.rays_per_texel),
        normal_grid: env_or(
            "ABLATION_NORMAL_GRID",
            relight_cpc::run::RunOptions::DEFAULT_NORMAL_GRID,
        ),
        ..small
    }
}

/// The bench's base options: the defaults with the paper's free blending weights
/// (`weights_sum` 0: the rows that use the sum-to-one prior say so), ≤ `ABLATION_ITERS`
/// outer iterations, `ABLATION_QP` solver steps per lighting fit.
fn base_options() -> EstimateOptions {
    let d = EstimateOptions::default();
    EstimateOptions {
        max_outer: env_or("ABLATION_ITERS", 20),
        alternation_qp_iters: d.alternation_qp_iters.map(|q| env_or("ABLATION_QP", q)),
        rel_tol: 1e-5,
        weights_sum: 0.0,
        ..d
    }
}

/// Every observation replaced by the true model's prediction (training and held out).
fn noise_free(case: &mut Case) {
    let t = true_prediction(case, &case.train);
    replace_colours(&mut case.train.obs, &t);
    let h = true_prediction(case, &case.held);
    replace_colours(&mut case.held.obs, &h);
}

/// The paper's start: k-means on the per-vertex mean colours, Lambertian only.
fn start(case: &Case, obs: &Observations, k: usize) -> Option<Materials0> {
    let (mean, seen) = relight_cpc::run::mean_colours(obs, case.nv);
    let init = relight_cpc::solve::cluster::initial_materials(&mean, &seen, k, 1).ok()?;
    (init.albedo.len() == k).then(|| Materials0::from_initial(&init, case.basis.len(), 0))
}

/// The figures of one fit.
#[derive(Debug, Clone, serde::Serialize)]
struct Figures {
    /// Half protocol, estimated reflectance (relative RMSE, per-channel scale).
    heldout: f64,
    /// Half protocol, true reflectance.
    heldout_floor: f64,
    /// Held-out photos under their true (unseen) maps, per-channel scale, vs the photos.
    relit: f64,
    /// The true reflectance doing the same.
    relit_floor: f64,
    /// The relit prediction against the true reflectance's (the estimator's own error).
    relit_model: f64,
    /// Worst relative diffuse-ratio error over materials j ≥ 1, per channel.
    ratio_errors: [f64; 3],
    /// The same for the k-means start.
    start_ratio_errors: [f64; 3],
    /// Material accuracy over the seen vertices (all; pure).
    assignment: f64,
    assignment_pure: f64,
    /// Training relative RMSE.
    train_rel: f64,
    /// The early-stopping validation score (NaN without validation).
    validation: f64,
    iterations: usize,
    seconds: f64,
}

/// The floors of a case: the true reflectance through the same protocols.
struct Floors {
    heldout: f64,
    relit: f64,
    left: Vec<bool>,
    seen: Vec<bool>,
    truth_held: Vec<[f64; 3]>,
    /// The albedo ratios' floor: the material step under the true maps ([`true_light`]).
    ratio: true_light::RatioFloor,
}

fn floors(case: &Case) -> Floors {
    let left = left_half(case);
    let (_, seen) = relight_cpc::run::mean_colours(&case.train.obs, case.nv);
    let truth_held = true_prediction(case, &case.held);
    if env_flag("ABLATION_FLOOR_FLIP") {
        true_light::floor_sources(case, &seen);
    }
    Floors {
        heldout: half_error(case, &case.lambda, &case.weights, &left),
        relit: rel_rmse_per_channel(&case.held.obs, &truth_held),
        ratio: true_light::ratio_floor(case, &seen),
        left,
        seen,
        truth_held,
    }
}

/// The k-means start's ratio errors.
fn start_ratio_errors(case: &Case, fl: &Floors) -> [f64; 3] {
    let init = start(case, &case.train.obs, case.lambda.len()).expect("k-means start");
    ratio_errors(case, &init.lambda, &init.weights, &fl.seen)
}

/// Fit `case` with options `o` from [`fit_start`] with the true K; its figures.
fn fit(case: &Case, fl: &Floors, o: &EstimateOptions) -> (Estimate, Figures) {
    let problem = case.train.problem(case.nv);
    let init = fit_start(case);
    eprintln!(
        "  start ratio errors: {:?}",
        ratio_errors(case, &init.lambda, &init.weights, &fl.seen)
    );
    let t0 = Instant::now();
    let est = estimate(&problem, init, o, &mut |_, _| {}).unwrap();
    let seconds = t0.elapsed().as_secs_f64();
    let f = figures(case, fl, (&est, o), start_ratio_errors(case, fl), seconds);
    (est, f)
}

/// The held-out column of reflectance `est` fitted with options `o`, and its floor:
/// `run`'s judge with the row's options against the truth through that judge
/// ([`run_half`]), or with `ABLATION_HALF=common` the common judge ([`half_error`])
/// against the case's floor.
fn held_out(case: &Case, fl: &Floors, est: &Estimate, o: &EstimateOptions) -> (f64, f64) {
    if !run_half::wanted() {
        return (
            half_error(case, &est.lambda, &est.weights, &fl.left),
            fl.heldout,
        );
    }
    let fitted = run_half::run_half_error(case, &est.lambda, &est.weights, &est.lights, o);
    let floor = run_half::run_half_error(case, &case.lambda, &case.weights, &case.train.lights, o);
    (fitted, floor)
}

/// The figures of a fitted reflectance `est` and the options it was fitted with.
fn figures(
    case: &Case,
    fl: &Floors,
    (est, o): (&Estimate, &EstimateOptions),
    start: [f64; 3],
    seconds: f64,
) -> Figures {
    let (heldout, heldout_floor) = held_out(case, fl, est, o);
    let problem = case.train.problem(case.nv);
    let hp = case.predict_held(&est.lambda, &est.weights);
    let mut model = case.held.obs.clone();
    replace_colours(&mut model, &fl.truth_held);
    let pred = relight_cpc::solve::predict(&problem, est);
    // Accuracy and ratios compare material by material: only with the true count.
    let ((assignment, assignment_pure), ratio_errors) = if est.lambda.len() == case.lambda.len() {
        (
            assignment(case, est, &fl.seen),
            ratio_errors(case, &est.lambda, &est.weights, &fl.seen),
        )
    } else {
        ((f64::NAN, f64::NAN), [f64::NAN; 3])
    };
    if crate::env_flag("ABLATION_LAMBDA") && est.lambda.len() == case.lambda.len() {
        eprint!("{}", crate::metrics::scaled_lambda(case, est, &fl.seen));
    }
    Figures {
        heldout,
        heldout_floor,
        relit: rel_rmse_per_channel(&case.held.obs, &hp),
        relit_floor: fl.relit,
        relit_model: rel_rmse_per_channel(&model, &hp),
        ratio_errors,
        start_ratio_errors: start,
        assignment,
        assignment_pure,
        train_rel: rel_rmse(&case.train.obs, &pred, false).0,
        validation: est.validation.as_ref().map_or(f64::NAN, |v| v.best_error()),
        iterations: est.timeline.len(),
        seconds,
    }
}

fn env_flag(k: &str) -> bool {
    std::env::var(k).is_ok_and(|v| v == "1")
}

/// `ABLATION_DIAGNOSE=1`: the relit error's breakdown ([`diagnose`]).
fn diagnosed(case: &Case, est: &Estimate, label: &str) -> Option<(String, Value)> {
    env_flag("ABLATION_DIAGNOSE").then(|| diagnose::diagnose(case, est, label))
}

/// The row `label`'s fit with the weights of the vertices no training photo sees
/// propagated from the seen ones ([`propagate_unseen`]); the fit itself is unchanged, so
/// the training figures and its `seconds` are the fit's (the propagation's own cost:
/// `ESTIMATOR_BENCH=propagate`).
fn propagated(
    case: &Case,
    fl: &Floors,
    (mut est, o): (Estimate, &EstimateOptions),
    label: &str,
    seconds: f64,
) -> Done {
    let k = est.lambda.len();
    let p = propagate_unseen(&case.positions, &fl.seen, &mut est.weights, k).expect("propagation");
    let label = format!("{label}, unseen propagated");
    let f = figures(case, fl, (&est, o), start_ratio_errors(case, fl), seconds);
    eprintln!("  {label}: {p:?} {f:?}");
    Done {
        diagnosis: diagnosed(case, &est, &label),
        label,
        figures: f,
        k: None,
        note: format!(
            "{} unseen vertices filled, {} isolated",
            p.filled, p.isolated
        ),
    }
}

/// The material count the pilot's rule picks with light options `o` (module docs):
/// `(K chosen, (K, held-out RMSE) per K tried)`.
fn choose_k(case: &Case, o: &EstimateOptions) -> (usize, Vec<(usize, f64)>) {
    let (split, held) = adapt::holdout_split(&case.train.obs, 1);
    // Scored as the pilot scores the count (its step 3).
    let held = adapt::count_scored(&split, &held, case.nv);
    let problem = case.train_problem_with(&split);
    let opts = EstimateOptions {
        max_outer: adapt::PILOT_ITERATIONS,
        rel_tol: 0.0,
        robust: relight_cpc::solve::Robust::None,
        irls_iters: 1,
        validation_fraction: 0.0,
        ..o.clone()
    };
    let mut scores = Vec::new();
    for k in 1..=case.lambda.len() + 1 {
        let Some(init) = start(case, &split, k) else {
            break;
        };
        let est = estimate(&problem, init, &opts, &mut |_, _| {}).unwrap();
        let pred = relight_cpc::solve::predict(&problem, &est);
        scores.push((k, adapt::heldout_rmse(&case.train.obs, &held, &pred)));
    }
    let best = scores.iter().map(|s| s.1).fold(f64::INFINITY, f64::min);
    let k = scores
        .iter()
        .find(|s| adapt::as_good(s.1, best, adapt::MATERIAL_TOL))
        .map_or(0, |s| s.0);
    (k, scores)
}

/// One fitted or picked row of a case.
struct Done {
    label: String,
    figures: Figures,
    k: Option<(usize, Vec<(usize, f64)>)>,
    note: String,
    /// `ABLATION_DIAGNOSE=1`: where the relit error comes from ([`diagnose`]).
    diagnosis: Option<(String, Value)>,
}

/// Whether `ABLATION_ROWS` (`wanted`) leaves the row `label` out.
fn left_out(wanted: &Option<Vec<String>>, label: &str) -> bool {
    wanted
        .as_ref()
        .is_some_and(|w| !w.iter().any(|l| l == label))
}

fn run_case(case: &Case, clean: bool, wanted: &Option<Vec<String>>) -> (Vec<Done>, Floors) {
    let fl = floors(case);
    let base = base_options();
    // The `shared` row's groups: training photos under one true sky (none unless the
    // scene was rendered with `SYNTH_SHARED_SKIES=1`).
    let groups = case.true_light_groups();
    let with_groups = EstimateOptions {
        light_groups: groups.any_shared().then_some(groups),
        ..base.clone()
    };
    // The K search on the 8-bit photos only: what a user's photos ask of it.
    let no_k = clean || std::env::var("ABLATION_NO_K").is_ok_and(|v| v == "1");
    let mut done: Vec<Done> = Vec::new();
    // Extra rows (when asked for) go before the picks, which choose among every fit.
    let (picks, mut all): (Vec<Row>, Vec<Row>) = rows()
        .into_iter()
        .partition(|r| matches!(r, Row::Pick { .. }));
    if wanted.is_some() {
        all.extend(extra_rows());
    }
    all.extend(picks);
    for row in all {
        match row {
            Row::Fit { label, make } => {
                if left_out(wanted, label) {
                    continue;
                }
                let Some(o) = make(&with_groups) else {
                    // Not in this build, or not applicable (`shared` needs photos that
                    // share a map; every photo here has its own).
                    eprintln!("{label}: not available for this scene in this build, skipped");
                    continue;
                };
                let o = with_case_graph(case, with_case_priors(case, &o));
                eprintln!(
                    "{} {}: {label}",
                    case.scene,
                    if clean { "noise-free" } else { "8-bit" }
                );
                let (est, figures) = fit(case, &fl, &o);
                let seconds = figures.seconds;
                let k = (!no_k && K_ROWS.contains(&label)).then(|| choose_k(case, &o));
                eprintln!("  {figures:?} K {k:?}");
                done.push(Done {
                    label: label.into(),
                    figures,
                    k,
                    note: String::new(),
                    diagnosis: diagnosed(case, &est, label),
                });
                let est = restarts(case, &fl, &o, est, label, &mut done);
                let est = brightness_search(case, &fl, &o, est, label, &mut done);
                if env_flag("ABLATION_PROPAGATE") {
                    done.push(propagated(case, &fl, (est, &o), label, seconds));
                }
            }
            Row::Defaults { label } => {
                if left_out(wanted, label) {
                    continue;
                }
                eprintln!("{}: {label}", case.scene);
                let d = defaults::fit_defaults(case, &base);
                let figures = figures(
                    case,
                    &fl,
                    (&d.est, &d.opts),
                    start_ratio_errors(case, &fl),
                    d.seconds,
                );
                eprintln!("  {figures:?} pilot {:?}", d.pilot.material_scores);
                if env_flag("ABLATION_FIT_SHARE") {
                    true_light::fitted_share_probe(case, &d.est, &fl.seen);
                }
                let profile = std::env::var("ABLATION_PROFILE").unwrap_or_default();
                if profile == "1" || profile == "axes" {
                    profile::ratio_profile(case, &d.opts, &d.est, &fl.seen, profile == "axes");
                }
                if env_flag("ABLATION_ACCURACY_MISSES") {
                    eprintln!(
                        "  misses: {}",
                        metrics::accuracy_misses(case, &d.est, &fl.seen)
                    );
                    eprintln!(
                        "  blend shares: {}",
                        metrics::blend_shares(case, &d.est, &fl.seen)
                    );
                    eprintln!(
                        "  rescaled: {}",
                        metrics::rescaled_accuracy(case, &d.est, &fl.seen)
                    );
                }
                done.push(Done {
                    label: label.into(),
                    figures,
                    k: Some((d.pilot.materials, d.pilot.material_scores.clone())),
                    note: format!("{}; {}", defaults::describe(case, &d.pilot), d.light),
                    diagnosis: diagnosed(case, &d.est, label),
                });
            }
            Row::Pick { label, among } => {
                let idx: Vec<usize> = among()
                    .iter()
                    .filter_map(|a| done.iter().position(|d| d.label == *a))
                    .collect();
                if idx.len() < 2 {
                    continue;
                }
                let names: Vec<&str> = idx.iter().map(|&i| done[i].label.as_str()).collect();
                let scores: Vec<f64> = idx.iter().map(|&i| done[i].figures.validation).collect();
                let (pick, decision) = decide(LightChoice::Auto, &names, &scores);
                let from = &done[idx[pick]];
                let note = format!("kept `{}` ({})", decision.model, decision.why);
                done.push(Done {
                    label: label.into(),
                    figures: from.figures.clone(),
                    k: from.k.clone(),
                    note,
                    diagnosis: None,
                });
            }
        }
    }
    (done, fl)
}

fn main() {
    let t0 = Instant::now();
    let s = sizes();
    let only_scenes = std::env::var("ABLATION_SCENES").ok();
    let wanted: Option<Vec<String>> = std::env::var("ABLATION_ROWS")
        .ok()
        .map(|v| v.split(';').map(|x| x.trim().to_string()).collect());
    let cleans: Vec<bool> = match std::env::var("ABLATION_CLEAN").as_deref() {
        Ok("0") => vec![false],
        Ok("1") => vec![true],
        _ => vec![false, true],
    };
    let base = base_options();
    let mut md = format!(
        "# Light-model ablation (issue 25)\n\nWritten by `cargo bench --bench ablation` (module docs of `benches/ablation.rs`: definitions). \
         Spot, {}² photos at {} spp × {} MIS pairs, 1 in 4 held out (maps 3 and 7, unseen in training), {}² global / {}² local maps, \
         the light rotated over a {}² normal grid, all coefficients, the scene's true lobes as basis, the k-means start, ≤ {} outer iterations with the default early stopping. \
         Held-out photos judged {}.\n\n",
        s.width, s.spp, s.light_samples, s.global, s.local, s.normal_grid, base.max_outer,
        if run_half::wanted() {
            "as `run` judges them (each row's learned half prior and Laplacian weight; its floor the truth through the same judge)"
        } else {
            "by the common judge (`ABLATION_HALF=common`: the paper's Laplacian, no light prior, for every row)"
        }
    );
    md.push_str(&run_line::environment_line(
        "ablation",
        &["ABLATION_", "SYNTH_", "RESULTS_SUFFIX"],
    ));
    let mut out = Vec::new();
    for (scene, what) in SCENES {
        if only_scenes
            .as_ref()
            .is_some_and(|o| !o.split(',').any(|v| v == scene))
        {
            continue;
        }
        let mut case = prepare(
            scene,
            s,
            env_or("ABLATION_SEED", 1) as u64,
            &format!("ablation-{scene}"),
        );
        eprintln!(
            "{scene}: {:.1} + {:.1} s, {} vertices, {} / {} observations",
            case.seconds_synth,
            case.seconds_prepare,
            case.nv,
            case.train.obs.len(),
            case.held.obs.len()
        );
        let k_true = case.lambda.len();
        let pure: Vec<usize> = (0..k_true)
            .map(|j| {
                (0..case.nv)
                    .filter(|&x| case.weights[x * k_true + j] >= 0.95)
                    .count()
            })
            .collect();
        eprintln!("{scene}: pure vertices per material {pure:?}");
        for &clean in &cleans {
            if clean {
                noise_free(&mut case);
            }
            let (done, fl) = run_case(&case, clean, &wanted);
            md.push_str(&format!(
                "## {what}: `{scene}`, {}\n\n{} materials, {} training / {} held-out photos, {} / {} observations.\n\n",
                if clean { "noise-free" } else { "8-bit photos" },
                k_true,
                case.train.views.len(),
                case.held.views.len(),
                case.train.obs.len(),
                case.held.obs.len()
            ));
            table(&mut md, &done, &fl, clean, k_true);
            eprintln!("{scene}: case done at {:.0} s", t0.elapsed().as_secs_f64());
            out.push(json!({
                "scene": scene,
                "kind": what,
                "noise_free": clean,
                "materials": k_true,
                "floor_heldout": fl.heldout,
                "floor_relit": fl.relit,
                "floor_ratio": fl.ratio,
                "rows": done.iter().map(|d| json!({"model": d.label, "figures": d.figures, "k": d.k, "note": d.note, "diagnosis": d.diagnosis.as_ref().map(|x| &x.1)})).collect::<Vec<_>>(),
            }));
            // After every case, so that an interrupted run keeps what it measured.
            write(&md, &out, t0, s, &base, false);
        }
    }
    write(&md, &out, t0, s, &base, true);
}

/// `bench-results/estimator-ablation[-S].{md,json}` (`RESULTS_SUFFIX=S`); with `last` the
/// Markdown also goes to standard output.
fn write(md: &str, out: &[Value], t0: Instant, s: Sizes, base: &EstimateOptions, last: bool) {
    let mut md = md.to_string();
    md.push_str(&format!(
        "Bench so far: {:.0} s wall.\n",
        t0.elapsed().as_secs_f64()
    ));
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("bench-results");
    let stem = match std::env::var("RESULTS_SUFFIX") {
        Ok(sfx) if !sfx.is_empty() => format!("estimator-ablation-{sfx}"),
        _ => "estimator-ablation".to_string(),
    };
    std::fs::write(dir.join(format!("{stem}.md")), &md).unwrap();
    let v: Value = json!({"sizes": format!("{s:?}"), "options": format!("{base:?}"), "cases": out, "seconds": t0.elapsed().as_secs_f64()});
    std::fs::write(
        dir.join(format!("{stem}.json")),
        serde_json::to_string_pretty(&v).unwrap(),
    )
    .unwrap();
    if last {
        println!("{md}");
    }
}
