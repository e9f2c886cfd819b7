//! The light prior of held-out protocol (b) (`half`), learnt from the training photos'
//! fitted maps (docs/method.md, "Held-out evaluation").
//!
//! Protocol (b) fits a held-out photo's map on the left half of the object and predicts
//! the right half: the part of the map that only the right half sees is extrapolated, by
//! the Laplacian prior alone. Photos of one collection are often lit alike (one site, one
//! kind of sky, one world frame), and then the training photos' fitted maps say where the
//! new photo's light comes from. The prior is the Gaussian shape term of
//! [`crate::solve::light::sh_prior`] with its statistics taken from those maps:
//!
//! - each training map `k`, per channel `c`, projected on the real SH up to order 2,
//!   `c_{k,c,i} = (P x_{k,c})_i`, reduced to its shape `ĉ_{k,c,i} = c_{k,c,i} / c_{k,c,0}`
//!   (`i = 1..9`, 24 numbers; level and colour are free: exposure and white balance differ);
//! - mean `m = (1/K) Σ_k ĉ_k` and covariance `Σ = (1/(K−1)) Σ_k (ĉ_k − m)(ĉ_k − m)ᵀ`, shrunk
//!   toward its diagonal, `Σ_s = (1 − a) Σ + a diag(Σ)` ([`SHRINKAGE`]: `K` is about 10
//!   against 24 numbers, `Σ` alone is singular), plus a floor `f² I` ([`SHAPE_FLOOR`]) so that
//!   a coefficient on which the training maps happen to agree is not pinned;
//! - in the QP, `½ σ² (A x)ᵀ (Σ_s + f² I)⁻¹ (A x)`, `σ = η · rms(y)` (`σ²` × the negative
//!   log prior, [`crate::solve::light::sh_prior`] module docs).
//!
//! Under `--light prior` the light model has a prior of its own, the built-in one of real
//! HDR maps ([`crate::solve::light::sh_prior`]), which the training maps were fitted with.
//! `auto` uses it when the replay below keeps no training prior
//! ([`without_training_prior`]), at [`MODEL_PRIOR_SCALE`] of its noise levels (0.04× its
//! training weight); it is not a candidate of the replay. Measured
//! (`bench-results/half-model-prior.md`): at its training weight it extrapolates worse than
//! the Laplacian alone on the built-in example at 2 of 3 seeds (right halves' RMSE +27%,
//! +26%, −2%) and better on three 128² rendered scenes (−7%, −2.5%, −1%), while the
//! replay on training photos ranks it the other way on 5 of those 6 cases at the replay's
//! caps, and on 3 of 3 with the half fit's own (every observation, three IRLS passes).
//! Weakened it is better than the Laplacian on 11 of 11 workspaces and than itself at
//! full weight on 10 ([`MODEL_PRIOR_SCALE`]).
//! Scored instead on the right halves of training photos that `--light auto` holds back
//! whole (no reflectance saw them), it ranks the prior opposite to the held-out photos on
//! 8 of 8 cases (`bench-results/half-prior-held-halves.md`).
//!
//! Whether the training prior helps is a property of the collection, so it is chosen by
//! replaying protocol (b) on training photos (`choose_prior`): for up to
//! [`LOO_PHOTOS`] training photos `k` (spread over the list), the left half of `k`'s
//! observations (projected `x` below the middle of their span, `super::half_fit::span_mid`)
//! fits its map from the mean of the other training maps, the training prior learnt from
//! the other maps only (leave one out), reflectance frozen, the right half scored
//! (α-weighted MSE). The kept candidate (the Laplacian alone or the training prior at an
//! `η > 0` of [`ETA_GRID`]) minimises the mean over photos of
//! `½ ln(MSE / MSE_Laplacian)` (the log of the RMSE ratio: no photo's scale dominates), in
//! two rounds of every other replayed photo, the second skipped when the first already
//! rules every prior out ([`RULE_OUT`]). The
//! replay's reflectance saw photo `k` (it is a training photo), so the replay scores the
//! light's extrapolation, not the reflectance's generalisation, which the prior cannot
//! change.
//!
//! The replay's cost must not grow with the mesh: its light fits stop after
//! [`REPLAY_GPCG`] GPCG iterations of one least-squares pass ([`REPLAY_IRLS`]), and a photo with more than
//! [`REPLAY_MAX_OBSERVATIONS`] observations is replayed on every `k`-th of them
//! (`k = ⌈N / max⌉`, [`thin_observations`]), each kept observation weighted `N / n`
//! (Horvitz–Thompson: the data term `Σ_p α_p (y_p − ŷ_p)²` keeps its expected value, so
//! its balance against the prior term, which does not scale with `N`, is that of the
//! full photo; Cochran, "Sampling Techniques", 3rd ed., §8 on systematic sampling).

use crate::report::HalfFitPriorReport;
use crate::solve::light::sh_prior::{
    shape_vector, LightPrior, LightPriorOptions, PriorSample, ShProjection, N_SH, N_SHAPE,
};
use crate::solve::EstimateOptions;
use crate::{Error, Result};

mod replay;
mod smoothness;
pub(crate) use replay::choose_prior;
pub use replay::{
    choose_prior_over, log_ratio_scores, mean_map, mean_without, replay_errors_of, replay_rounds,
    thin_observations, weighted_mse, ReplayChoice, ReplayInputs, ReplayPhoto, RULE_OUT,
};
pub use smoothness::HalfSmoothnessMode;

/// Shrinkage of the training maps' shape covariance toward its diagonal (module docs).
pub const SHRINKAGE: f64 = 0.5;
/// Floor `f` of the shape covariance, in units of the shape `ĉ` (module docs).
pub const SHAPE_FLOOR: f64 = 0.05;
/// Training photos the choice of `η` replays at most.
pub const LOO_PHOTOS: usize = 4;
/// Observations of one training photo the replay fits and scores at most (module docs):
/// at 100K vertices a photo has ~25,000, and 12 light fits on all of them would cost
/// more than the evaluation itself. 500, a quarter of the estimator's default lighting
/// sample (2,000 before): on 12 runs (the built-in example and the real Buddha photos at
/// seeds 1–4, four rendered scenes) every `η` chosen is the same, so every figure; the
/// scores move by up to 0.13 in `½ ln` (the example at seed 2: +0.70 → +0.83 at `η` = 3),
/// never across a choice; the replay costs 22–62% less CPU (the Buddha's 2.1–2.3 → 1.0–1.1
/// s), `bench-results/replay-sample.md`.
pub const REPLAY_MAX_OBSERVATIONS: usize = 500;
/// GPCG iterations of a replay's light fit at most (protocol (b)'s own fit runs 28). The
/// replay compares `η` values; at 10 its scores on Buddha are within 3% of the 20-iteration
/// ones (−0.098 / −0.131 against −0.101 / −0.133 at seeds 1 / 2, the same `η`), at 5 they
/// shrink to a quarter (the prior's effect has not yet developed),
/// `bench-results/realphoto-headline.md`.
pub const REPLAY_GPCG: usize = 10;
/// CG steps per GPCG iteration of a replay's light fit: 20, the cap [`REPLAY_GPCG`] was
/// measured with. Protocol (b)'s own fit takes more, shorter steps
/// (`super::half_fit::HALF_FIT_CG`); the replay keeps its measured caps, so its `η`
/// choices are the ones its measurements describe.
pub const REPLAY_CG: usize = 20;
/// IRLS passes of a replay's light fit: one, plain least squares (protocol (b)'s own fit
/// runs the estimator's 3). The replay ranks `η` values on observations the fit saw in
/// training, and every choice measured is the same as with 3 passes at under half the
/// cost: the built-in example's first round +0.72 / +1.07 against +0.85 / +1.10 (`η` = 0,
/// ruled out either way; half prior 0.90 → 0.39 CPU s), Buddha −0.074 / −0.027 against
/// −0.154 / −0.122 at seed 1 and −0.069 / −0.027 against −0.055 / −0.025 at seed 2 (`η` = 3
/// both times, headline unchanged; 2.45 → 1.14 CPU s), `bench-results/example-speed.md`.
pub const REPLAY_IRLS: usize = 1;
/// Candidate relative noise levels `η` (0 = no prior).
pub const ETA_GRID: [f64; 3] = [0.0, 3.0, 10.0];

/// `--half-prior`: which light prior protocol (b)'s fit adds to the Laplacian.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum HalfPriorMode {
    /// Chosen by the replay on training photos among [`candidates`] (module docs).
    Auto,
    /// No prior: the Laplacian alone.
    Off,
    /// The light model's own prior (`--light prior`: the built-in prior of real HDR maps,
    /// at [`MODEL_PRIOR_SCALE`] of its noise levels; the Laplacian alone under the other
    /// models).
    Model,
    /// The training maps' shape prior at a fixed `η > 0`.
    Fixed(f64),
}

impl HalfPriorMode {
    /// `auto`, `off`, `model` or a positive number.
    pub fn parse(s: &str) -> Result<Self> {
        match s {
            "auto" => Ok(HalfPriorMode::Auto),
            "off" => Ok(HalfPriorMode::Off),
            "model" => Ok(HalfPriorMode::Model),
            _ => match s.parse::<f64>() {
                Ok(v) if v.is_finite() && v > 0.0 => Ok(HalfPriorMode::Fixed(v)),
                _ => Err(Error::Config(format!(
                    "--half-prior {s}: expected auto, off, model or a positive number (η)"
                ))),
            },
        }
    }
}

/// One light prior protocol (b)'s fit may add to the Laplacian.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum HalfLightPrior {
    /// None: the Laplacian alone.
    Laplacian,
    /// The training maps' shape prior at relative noise level `η > 0`.
    Training(f64),
    /// The light model's own prior (the estimator's `light_prior`: under `--light prior`
    /// the built-in prior learnt from real HDR maps) at [`MODEL_PRIOR_SCALE`] of its
    /// noise levels.
    Model,
}

impl HalfLightPrior {
    /// The report's name: `none`, `training maps η 3`, `light model's`.
    pub fn name(&self) -> String {
        match self {
            HalfLightPrior::Laplacian => "none".into(),
            HalfLightPrior::Training(eta) => format!("training maps η {eta}"),
            HalfLightPrior::Model => "light model's".into(),
        }
    }

    /// The fit's light-prior options: `lights` the maps a training prior is learnt from
    /// (side `n`), `model` the light model's own prior.
    pub fn options(
        &self,
        lights: &[[Vec<f64>; 3]],
        n: usize,
        model: Option<&LightPriorOptions>,
    ) -> Result<Option<LightPriorOptions>> {
        match self {
            HalfLightPrior::Laplacian => Ok(None),
            HalfLightPrior::Training(eta) => half_fit_prior(lights, n, *eta).map(Some),
            HalfLightPrior::Model => Ok(model.map(model_prior_for_half)),
        }
    }
}

/// Scale of the light model's relative noise levels (`η` of its SH shape term and of its
/// Haar L1 term, `σ = η · rms(y)`) in protocol (b)'s fit: the prior's terms weigh
/// `σ²`, so 0.2 puts them at 0.04× their weight in the training fit. Measured with
/// `--light prior` (`bench-results/half-model-prior-strength.md`), the mean `half` RMSE
/// over 11 workspaces (the built-in example at seeds 1–5, five 128² rendered scenes): at
/// 0.2 below the Laplacian alone on 11 of 11 (−0.8% to −14%, the example 0.0530 → 0.0513 at
/// seed 1) and below the prior at its training strength on 10 (−24% at the example's seed
/// 1, +0.7% on `spot-diffuse`). Swept on six of them: 0.1, 0.3 and 0.5 give the same picture
/// with a smaller margin on one side (0.3 is +0.2% over the Laplacian on one of the
/// other five), 3 and 10 raise it on all six.
pub const MODEL_PRIOR_SCALE: f64 = 0.2;

/// The light model's prior as protocol (b) adds it: its noise levels scaled by
/// [`MODEL_PRIOR_SCALE`].
pub fn model_prior_for_half(model: &LightPriorOptions) -> LightPriorOptions {
    LightPriorOptions {
        sh_noise: model.sh_noise * MODEL_PRIOR_SCALE,
        haar_noise: model.haar_noise * MODEL_PRIOR_SCALE,
        ..model.clone()
    }
}

/// The priors `--half-prior auto` replays: the Laplacian alone (the scores' reference,
/// first) and the training maps' prior at every `η > 0` of [`ETA_GRID`]. The light
/// model's own prior is not among them: the replay on training photos ranks it opposite
/// to the held-out photos on 5 of 6 cases measured (module docs).
pub fn candidates() -> Vec<HalfLightPrior> {
    let mut c = vec![HalfLightPrior::Laplacian];
    c.extend(
        ETA_GRID
            .iter()
            .filter(|&&eta| eta > 0.0)
            .map(|&eta| HalfLightPrior::Training(eta)),
    );
    c
}

/// The light model's own prior when it has one (the prior the training maps were fitted
/// with), else the Laplacian: what `--half-prior model` uses, and `auto` when the replay
/// keeps no training prior.
pub fn without_training_prior(model_has_prior: bool) -> HalfLightPrior {
    if model_has_prior {
        HalfLightPrior::Model
    } else {
        HalfLightPrior::Laplacian
    }
}

/// The shape vector of one map (three channels' texels on the full octahedral grid),
/// `None` where a channel has no positive mean.
pub fn map_shape(light: &[Vec<f64>; 3], proj: &ShProjection) -> Option<[f64; N_SHAPE]> {
    let c: [[f64; N_SH]; 3] = [0, 1, 2].map(|c| proj.project(&light[c]));
    shape_vector(&c)
}

/// Mean and precision `(Σ_s + f² I)⁻¹` of the maps' shapes (module docs) as a
/// [`LightPrior`] without Haar statistics; `n` the maps' side. Errors when fewer than two
/// maps have light in every channel.
pub fn training_prior(
    lights: &[[Vec<f64>; 3]],
    n: usize,
    shrinkage: f64,
    floor: f64,
) -> Result<LightPrior> {
    let proj = ShProjection::new(n, 4);
    let samples: Vec<PriorSample> = lights
        .iter()
        .filter_map(|l| map_shape(l, &proj))
        .map(|s| PriorSample {
            shapes: vec![s],
            haar: Vec::new(),
        })
        .collect();
    if samples.len() < 2 {
        return Err(Error::Config(format!(
            "half-fit light prior: {} of {} training maps have light in every channel, need 2",
            samples.len(),
            lights.len()
        )));
    }
    let names = (0..samples.len())
        .map(|k| format!("training map {k}"))
        .collect();
    let mut prior = LightPrior::fit(names, 1, &samples, shrinkage)?;
    prior.shape_precision = add_floor(&prior.shape_precision, floor)?;
    Ok(prior)
}

/// `(Λ₀⁻¹ + f² I)⁻¹` for a row-major `N_SHAPE²` precision `Λ₀`.
fn add_floor(precision: &[f64], floor: f64) -> Result<Vec<f64>> {
    let p = nalgebra::DMatrix::from_row_slice(N_SHAPE, N_SHAPE, precision);
    let singular = || Error::Config("half-fit light prior: singular shape covariance".into());
    let cov = p.try_inverse().ok_or_else(singular)?
        + nalgebra::DMatrix::<f64>::identity(N_SHAPE, N_SHAPE) * (floor * floor);
    let prec = cov.try_inverse().ok_or_else(singular)?;
    Ok(prec.transpose().iter().copied().collect())
}

/// The light-prior options of the half fit: the training maps' shape term at `eta`.
pub fn half_fit_prior(lights: &[[Vec<f64>; 3]], n: usize, eta: f64) -> Result<LightPriorOptions> {
    Ok(LightPriorOptions {
        stats: std::sync::Arc::new(vec![training_prior(lights, n, SHRINKAGE, SHAPE_FLOOR)?]),
        per_photo: None,
        sh_noise: eta,
        haar_noise: 0.0,
    })
}

/// What protocol (b)'s light fit takes beyond the training fit's options.
#[derive(Debug, Clone)]
pub(crate) struct HalfFitSetup {
    /// The light prior the half fit adds to the Laplacian (`None`: none).
    pub light_prior: Option<LightPriorOptions>,
    /// The Laplacian's weight `s` in the half fit ([`HalfSmoothnessMode`]).
    pub smoothness: f64,
}

impl HalfFitSetup {
    /// The half fit's options: `base` ([`half_fit_options`]) with this prior and weight.
    pub(crate) fn options(&self, base: EstimateOptions) -> EstimateOptions {
        EstimateOptions {
            light_prior: self.light_prior.clone(),
            smoothness: self.smoothness,
            ..base
        }
    }
}

/// The half fit's prior and weight for a fitted run and what the report says of them.
pub(crate) struct HalfPrior {
    /// The half fit's prior and weight.
    pub setup: HalfFitSetup,
    /// report.json's `half_fit_prior`.
    pub report: HalfFitPriorReport,
}

/// The options of protocol (b)'s light fit before its prior is chosen: the fit's, over
/// every observation ([`HalfFitSetup::options`] adds the prior).
pub(crate) fn half_fit_base(f: &super::Fitted) -> EstimateOptions {
    EstimateOptions {
        lighting_sample: 0,
        ..f.estimate_options.clone()
    }
}

/// The options of protocol (b)'s light fit of a held-out photo's left half
/// ([`super::half_fit::fit_left_half`]): [`half_fit_base`] with the prior chosen for it
/// ([`HalfFitSetup::options`]), or with no light prior when none was chosen.
pub(crate) fn left_half_options(f: &super::Fitted) -> EstimateOptions {
    let base = half_fit_base(f);
    match &f.half_fit {
        Some(h) => h.options(base),
        None => EstimateOptions {
            light_prior: None,
            ..base
        },
    }
}

/// [`half_fit_base`] with the half fit's iteration caps, for the replays that choose its
/// prior ([`super::half_fit::fit_left_half`]'s passes set the caps of each IRLS pass).
pub(crate) fn half_fit_options(f: &super::Fitted) -> EstimateOptions {
    EstimateOptions {
        qp_max_iter: super::half_fit::HALF_FIT_GPCG,
        qp_max_cg: super::half_fit::HALF_FIT_CG,
        ..half_fit_base(f)
    }
}

/// The half fit's prior under `mode` and its Laplacian weight under `smoothness`; `opts`
/// the half fit's options (its `light_prior` the light model's own, its `smoothness` the
/// fit's).
pub(crate) fn prepare(
    f: &super::Fitted,
    mode: HalfPriorMode,
    smoothness: HalfSmoothnessMode,
    opts: &EstimateOptions,
) -> Result<HalfPrior> {
    let watch = crate::stages::Stopwatch::start();
    let s = smoothness.weight(opts.smoothness);
    let opts = &EstimateOptions {
        smoothness: s,
        ..opts.clone()
    };
    let priors = candidates();
    let choice = match mode {
        HalfPriorMode::Off => fixed(HalfLightPrior::Laplacian),
        HalfPriorMode::Model => fixed(without_training_prior(opts.light_prior.is_some())),
        HalfPriorMode::Fixed(eta) => fixed(HalfLightPrior::Training(eta)),
        HalfPriorMode::Auto if f.held.is_empty() => fixed(HalfLightPrior::Laplacian),
        HalfPriorMode::Auto => {
            let mut c = choose_prior(f, opts, &priors)?;
            if c.kept == HalfLightPrior::Laplacian {
                c.kept = without_training_prior(opts.light_prior.is_some());
            }
            c
        }
    };
    // `auto` only keeps a training prior when it could be built on the replays; a fixed
    // η with too few lit maps is an error naming the cause.
    let n = f.opts.global_resolution;
    let options = choice
        .kept
        .options(&f.est.lights, n, opts.light_prior.as_ref())?;
    let (_, cpu) = watch.elapsed();
    Ok(HalfPrior {
        report: prior_report(mode, (smoothness, s), &priors, choice, cpu),
        setup: HalfFitSetup {
            light_prior: options,
            smoothness: s,
        },
    })
}

/// report.json's `half_fit_prior`: `choice` among `priors` under `mode`, at the weight
/// `smoothness` gives (the flag and its value), in `cpu` seconds.
fn prior_report(
    mode: HalfPriorMode,
    smoothness: (HalfSmoothnessMode, f64),
    priors: &[HalfLightPrior],
    choice: ReplayChoice,
    cpu: f64,
) -> HalfFitPriorReport {
    let mode_name = match mode {
        HalfPriorMode::Auto => "auto",
        HalfPriorMode::Off => "off",
        HalfPriorMode::Model => "model",
        HalfPriorMode::Fixed(_) => "fixed",
    };
    let replayed = !choice.scores.is_empty();
    HalfFitPriorReport {
        mode: mode_name.to_string(),
        prior: choice.kept.name(),
        eta: match choice.kept {
            HalfLightPrior::Training(eta) => eta,
            _ => 0.0,
        },
        model_prior_scale: match choice.kept {
            HalfLightPrior::Model => MODEL_PRIOR_SCALE,
            _ => 0.0,
        },
        smoothness_mode: smoothness.0.name().to_string(),
        smoothness: smoothness.1,
        candidates: if replayed {
            priors.iter().map(HalfLightPrior::name).collect()
        } else {
            Vec::new()
        },
        log_rmse_ratio: choice.scores,
        replayed_photos: choice.photos,
        cpu_seconds: cpu,
    }
}

/// A choice made without the replay.
fn fixed(kept: HalfLightPrior) -> ReplayChoice {
    ReplayChoice {
        kept,
        scores: Vec::new(),
        photos: 0,
    }
}

#[cfg(test)]
mod tests;
