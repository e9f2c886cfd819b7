//! Protocol (b) replayed on training photos: the choice of the half fit's light prior
//! ([`choose_prior`], module docs of [`super`]). Each replayed photo's observations are
//! thinned ([`thin_observations`]), cut at the middle of their projected `x`
//! ([`ReplayPhoto`]), its left half's map fitted from the mean of the other training maps
//! ([`mean_without`]) under each candidate prior, the right half scored ([`weighted_mse`]);
//! the candidates are ranked by the mean of `½ ln(MSE / MSE_Laplacian)` over the photos
//! ([`log_ratio_scores`]) in two rounds ([`replay_rounds`], [`RULE_OUT`]).

use super::{
    fixed, HalfLightPrior, LOO_PHOTOS, REPLAY_CG, REPLAY_GPCG, REPLAY_IRLS, REPLAY_MAX_OBSERVATIONS,
};
use crate::observe::Observations;
use crate::solve::{EstimateOptions, Problem};
use crate::Result;
use rayon::prelude::*;

/// `α`-weighted mean square error of `pred` against the observations `idx`, over channels
/// (`∞` when they weigh nothing).
pub fn weighted_mse(obs: &Observations, pred: &[[f64; 3]], idx: &[usize]) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for &p in idx {
        let a = f64::from(obs.weight[p]);
        for (y, q) in obs.rgb[p].iter().zip(&pred[p]) {
            num += a * (f64::from(*y) - q).powi(2);
        }
        den += 3.0 * a;
    }
    if den > 0.0 {
        num / den
    } else {
        f64::INFINITY
    }
}

/// The mean over `lights` of every map, per channel, `n2` texels each (zero without
/// maps): protocol (b)'s start for a held-out photo.
pub fn mean_map(lights: &[[Vec<f64>; 3]], n2: usize) -> [Vec<f64>; 3] {
    let mut sum = [vec![0.0; n2], vec![0.0; n2], vec![0.0; n2]];
    for l in lights {
        for c in 0..3 {
            for (s, v) in sum[c].iter_mut().zip(&l[c]) {
                *s += v;
            }
        }
    }
    let k = lights.len().max(1) as f64;
    for ch in sum.iter_mut() {
        ch.iter_mut().for_each(|v| *v /= k);
    }
    sum
}

/// The mean over `lights` of every map but the `k`-th, per channel.
pub fn mean_without(lights: &[[Vec<f64>; 3]], k: usize) -> [Vec<f64>; 3] {
    let n2 = lights.first().map_or(0, |l| l[0].len());
    let mut m = [vec![0.0; n2], vec![0.0; n2], vec![0.0; n2]];
    let others = lights.len().saturating_sub(1).max(1) as f64;
    for (_, l) in lights.iter().enumerate().filter(|&(j, _)| j != k) {
        for c in 0..3 {
            for (a, v) in m[c].iter_mut().zip(&l[c]) {
                *a += v / others;
            }
        }
    }
    m
}

/// Every `⌈N / max⌉`-th observation of `obs` (all when `N ≤ max`) with its weight `α`
/// multiplied by `N / n` (module docs: the data term's expected value is kept); photo
/// ranges those of the kept observations.
pub fn thin_observations(obs: Observations, max: usize) -> Observations {
    let n_all = obs.len();
    if n_all <= max || max == 0 {
        return obs;
    }
    let step = n_all.div_ceil(max);
    let kept: Vec<usize> = (0..n_all).step_by(step).collect();
    let scale = n_all as f32 / kept.len() as f32;
    let mut out = obs.gather(&kept);
    out.weight.iter_mut().for_each(|w| *w *= scale);
    out.bound_weight.iter_mut().for_each(|w| *w *= scale);
    out
}

/// Protocol (b) replayed on one training photo: its observations (thinned to
/// [`REPLAY_MAX_OBSERVATIONS`] by the caller), the fit's copy with the right half's `α`
/// zeroed, the right half's indices, the transport over the observations.
pub struct ReplayPhoto {
    pub obs: Observations,
    pub fit: Observations,
    pub right: Vec<usize>,
    pub transport: crate::transport::Transport,
}

impl ReplayPhoto {
    /// The replay of one photo's observations `obs`, cut at the middle of the span of
    /// `px` (each observation's projected `x`, `None` behind the camera) over the
    /// observations of positive weight; `transport` builds the transport over the kept
    /// observations. The replay is photo 0 of its own problem. `None` without both halves.
    pub fn new(
        mut obs: Observations,
        px: &[Option<f64>],
        transport: impl FnOnce(&Observations) -> Result<crate::transport::Transport>,
    ) -> Result<Option<Self>> {
        let Some(sides) = crate::run::half_fit::sides(&obs.weight, px) else {
            return Ok(None);
        };
        let right: Vec<usize> = (0..px.len()).filter(|&p| sides[p] == Some(false)).collect();
        let mut fit = obs.clone();
        for (p, side) in sides.iter().enumerate() {
            if *side != Some(true) {
                fit.mask_out(p);
            }
        }
        if right.is_empty() || fit.weight.iter().all(|&w| w <= 0.0) {
            return Ok(None);
        }
        let all = 0..obs.len();
        for o in [&mut obs, &mut fit] {
            o.photo_ranges = vec![all.clone()];
            o.photo.iter_mut().for_each(|p| *p = 0);
        }
        let transport = transport(&obs)?;
        Ok(Some(ReplayPhoto {
            obs,
            fit,
            right,
            transport,
        }))
    }
}

/// [`ReplayPhoto`] of training photo `k` (training order); `None` without both halves.
fn replay(f: &crate::run::Fitted, k: usize) -> Result<Option<ReplayPhoto>> {
    let view = &f.scene.views[f.train[k]];
    let obs = thin_observations(f.observations_of(f.train[k]), REPLAY_MAX_OBSERVATIONS);
    let px: Vec<Option<f64>> = obs
        .vertex
        .iter()
        .map(|&x| crate::run::half_fit::projected_x(view, &f.scene.mesh.positions[x as usize]))
        .collect();
    ReplayPhoto::new(obs, &px, |o| f.transport_for(o))
}

/// What the replay of one training photo reads beyond the photo: the frozen reflectance
/// per vertex (`beta`, the mesh's `n_vertices`), the training maps (side `n`) the training
/// prior and the start are taken from, the half fit's options (`light_prior` the light
/// model's own).
#[derive(Clone, Copy)]
pub struct ReplayInputs<'a> {
    pub beta: &'a [[f64; 3]],
    pub lights: &'a [[Vec<f64>; 3]],
    pub n: usize,
    pub n_vertices: usize,
    pub opts: &'a EstimateOptions,
}

/// Right-half MSE of replay `r` of training photo `k` under each of `priors` (module
/// docs): the start and the training prior from every training map but `k`'s.
pub fn replay_errors_of(
    r: &ReplayPhoto,
    k: usize,
    inputs: ReplayInputs,
    priors: &[HalfLightPrior],
) -> Result<Vec<f64>> {
    let lights = inputs.lights;
    let opts = inputs.opts;
    let others: Vec<[Vec<f64>; 3]> = (0..lights.len())
        .filter(|&j| j != k)
        .map(|j| lights[j].clone())
        .collect();
    let start = mean_without(lights, k);
    let full = Problem {
        obs: &r.obs,
        transport: &r.transport,
        n_vertices: inputs.n_vertices,
        n_photos: 1,
    };
    let fit = Problem {
        obs: &r.fit,
        ..full
    };
    let mut out = Vec::with_capacity(priors.len());
    for prior in priors {
        // Too few lit maps for a training prior: this candidate scores nothing (the photo
        // is then left out of the choice, [`log_ratio_scores`]).
        let Ok(light_prior) = prior.options(&others, inputs.n, opts.light_prior.as_ref()) else {
            out.push(f64::INFINITY);
            continue;
        };
        let o = EstimateOptions {
            light_prior,
            qp_max_iter: opts.qp_max_iter.min(REPLAY_GPCG),
            qp_max_cg: REPLAY_CG,
            irls_iters: REPLAY_IRLS,
            ..opts.clone()
        };
        let l = crate::solve::fit_light_frozen(&fit, inputs.beta, 0, Some(&start), &o)?;
        let s = crate::solve::basis_responses(&full, std::slice::from_ref(&l));
        let pred = crate::solve::problem::predict_from(&full, inputs.beta, &s);
        out.push(weighted_mse(&r.obs, &pred, &r.right));
    }
    Ok(out)
}

/// The mean over photos of `½ ln(MSE_η / MSE_0)` per grid value (photos whose errors are
/// not all finite and positive left out), and how many photos counted.
pub fn log_ratio_scores(errors: &[Vec<f64>]) -> (Vec<f64>, usize) {
    let ok: Vec<&Vec<f64>> = errors
        .iter()
        .filter(|e| e.iter().all(|v| v.is_finite() && *v > 0.0))
        .collect();
    let len = errors.first().map_or(0, Vec::len);
    let mut score = vec![0.0; len];
    for e in &ok {
        for (s, v) in score.iter_mut().zip(e.iter()) {
            *s += 0.5 * (v / e[0]).ln() / ok.len() as f64;
        }
    }
    (score, ok.len())
}

/// The replay's choice: the prior kept, every candidate's score, photos scored.
pub struct ReplayChoice {
    /// The candidate kept.
    pub kept: HalfLightPrior,
    /// Per candidate of `priors` (the Laplacian's 0), the mean `½ ln(MSE / MSE_Laplacian)`.
    pub scores: Vec<f64>,
    /// Training photos scored.
    pub photos: usize,
}

/// The prior by the replay on up to [`LOO_PHOTOS`] training photos (module docs): among
/// `priors` (the Laplacian alone first), the one with the lowest [`log_ratio_scores`], the
/// Laplacian on ties or without a scored photo. The replay runs in two rounds
/// ([`replay_rounds`]); when every prior scores at least [`RULE_OUT`] on the first, the
/// second is skipped and the Laplacian kept.
pub(crate) fn choose_prior(
    f: &crate::run::Fitted,
    opts: &EstimateOptions,
    priors: &[HalfLightPrior],
) -> Result<ReplayChoice> {
    let inputs = ReplayInputs {
        beta: &f.beta,
        lights: &f.est.lights,
        n: f.opts.global_resolution,
        n_vertices: f.scene.mesh.positions.len(),
        opts,
    };
    choose_prior_over(f.est.lights.len(), priors, |k| {
        replay(f, k)?
            .map(|r| replay_errors_of(&r, k, inputs, priors))
            .transpose()
    })
}

/// [`choose_prior`] over `kk` training photos, `errors(k)` the right-half MSEs of training
/// photo `k` under each of `priors` ([`replay_errors_of`]; `None` when `k` has not both
/// halves): the picks, the two rounds and the rule that keeps a prior. Fewer than three
/// training photos keep the Laplacian without a replay.
pub fn choose_prior_over(
    kk: usize,
    priors: &[HalfLightPrior],
    errors: impl Fn(usize) -> Result<Option<Vec<f64>>> + Sync,
) -> Result<ReplayChoice> {
    if kk < 3 {
        return Ok(fixed(HalfLightPrior::Laplacian));
    }
    let m = LOO_PHOTOS.min(kk);
    let picks: Vec<usize> = (0..m).map(|i| (2 * i + 1) * kk / (2 * m)).collect();
    let [first, second] = replay_rounds(m);
    let replay_all = |round: &[usize]| -> Result<Vec<(usize, Vec<f64>)>> {
        round
            .par_iter()
            .map(|&i| Ok(errors(picks[i])?.map(|e| (i, e))))
            .collect::<Result<Vec<_>>>()
            .map(|v| v.into_iter().flatten().collect())
    };
    let mut errors = replay_all(&first)?;
    let (early, _) = log_ratio_scores(&only_errors(&errors));
    let ruled_out = early.len() > 1 && early[1..].iter().all(|&s| s >= RULE_OUT);
    if !ruled_out {
        errors.extend(replay_all(&second)?);
    }
    // Pick order, so the mean sums the photos as a single round would.
    errors.sort_by_key(|e| e.0);
    let (scores, photos) = log_ratio_scores(&only_errors(&errors));
    let kept = (0..scores.len())
        .filter(|&i| scores[i] < 0.0)
        .min_by(|&a, &b| scores[a].total_cmp(&scores[b]))
        .map_or(HalfLightPrior::Laplacian, |i| priors[i]);
    Ok(ReplayChoice {
        kept,
        scores,
        photos,
    })
}

/// A first replay round's mean `½ ln(MSE_η / MSE_0)` at or above which every `η > 0` is
/// ruled out without the second round: the first round's photos' right-half RMSE is then
/// on average ≥ e^0.5 = 1.65× that without the prior, and for the mean over both rounds
/// to turn negative the second round's photos would have to gain 39% (a mean score below
/// −0.5). The largest gain measured on any replayed photo is 38% (Buddha at seed 1, photo 00018:
/// −0.48, where the prior wins), the built-in example's first round scores +0.84 / +1.10
/// (`η` = 3 / 10; `bench-results/example-speed.md`).
pub const RULE_OUT: f64 = 0.5;

/// The replay's two rounds over `m` picks (indices into the picks): every other pick
/// first (0, 2, …: still spread over the training list), then the rest.
pub fn replay_rounds(m: usize) -> [Vec<usize>; 2] {
    [(0..m).step_by(2).collect(), (1..m).step_by(2).collect()]
}

fn only_errors(errors: &[(usize, Vec<f64>)]) -> Vec<Vec<f64>> {
    errors.iter().map(|e| e.1.clone()).collect()
}
