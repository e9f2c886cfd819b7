//! Early stopping (not in the paper): a seeded fraction of the training observations is
//! given `α = 0` for the whole alternation and scored after every outer iteration,
//! `sqrt(Σ α (y − ŷ)²) / sqrt(Σ α y²)`; the iterate with the lowest score is returned.
//! The draw is per observation ([`validation_split`]) or, with
//! [`EstimateOptions::validation_block`] `= n > 0`, per block of `n` consecutive vertex ids
//! ([`validation_split_blocked`]: every observation of a drawn vertex is held back, so no
//! held-back observation has a fitted one at its own vertex). With
//! [`EstimateOptions::validation_halves`] set, the split is by photo half
//! ([`photo_halves_split`]): in each of a few chosen training photos, every observation of a
//! vertex projecting right of the object's middle is held back, so those photos' lights
//! are fitted on their left halves only and the score measures how a light fitted on one
//! side of a photo extrapolates to the other (the rule of the `half` protocol).

// Numerical kernels index several arrays in step; range loops read like the math.
#![allow(clippy::needless_range_loop)]

use rayon::prelude::*;

use crate::observe::Observations;
use crate::solve::materials::by_vertex;
use crate::solve::options::{EstimateOptions, PhotoHalves, VALIDATION_MIN_FIT};
use crate::solve::problem::{haar3, Problem, CHUNK};
use crate::solve::result::Validation;

/// Early stopping's validation observations (sorted): per vertex in order, each of its
/// `α > 0` observations is drawn with probability `fraction` (seeded PCG), never leaving
/// the vertex fewer than [`VALIDATION_MIN_FIT`] fitted ones.
pub fn validation_split(
    obs: &Observations,
    n_vertices: usize,
    fraction: f64,
    seed: u64,
) -> Vec<usize> {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let (off, list) = by_vertex(obs, n_vertices);
    let mut out = Vec::new();
    for x in 0..n_vertices {
        let mine: Vec<usize> = list[off[x]..off[x + 1]]
            .iter()
            .copied()
            .filter(|&p| obs.weight[p] > 0.0)
            .collect();
        let mut left = mine.len();
        for p in mine {
            let u: f64 = rng.random();
            if u < fraction && left > VALIDATION_MIN_FIT {
                out.push(p);
                left -= 1;
            }
        }
    }
    out.sort_unstable();
    out
}

/// Blocked validation observations (sorted): vertices `0..n_vertices` are cut into blocks
/// of `block` consecutive ids (the last may be shorter); each block is drawn with
/// probability `fraction` (seeded PCG) and then every `α > 0` observation of its vertices
/// is held back. Drawn vertices keep no fitted observation (their weights stay at the
/// start); vertex ids of a mesh are roughly spatially coherent, so a drawn block is a
/// patch of surface rather than points scattered between fitted ones.
pub fn validation_split_blocked(
    obs: &Observations,
    n_vertices: usize,
    fraction: f64,
    block: usize,
    seed: u64,
) -> Vec<usize> {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let block = block.max(1);
    let drawn: Vec<bool> = (0..n_vertices.div_ceil(block))
        .map(|_| rng.random::<f64>() < fraction)
        .collect();
    (0..obs.len())
        .filter(|&p| obs.weight[p] > 0.0 && drawn[obs.vertex[p] as usize / block])
        .collect()
}

/// Photo-half validation observations (sorted): every `α > 0` observation of a chosen
/// photo whose vertex lies in that photo's right half.
pub fn photo_halves_split(obs: &Observations, halves: &PhotoHalves) -> Vec<usize> {
    (0..obs.len())
        .filter(|&p| {
            let (k, x) = (obs.photo[p], obs.vertex[p] as usize);
            obs.weight[p] > 0.0
                && halves
                    .right
                    .iter()
                    .any(|(q, r)| *q == k && r.get(x).copied().unwrap_or(false))
        })
        .collect()
}

/// Early stopping's score: `sqrt(Σ α (y − ŷ)²) / sqrt(Σ α y²)` over the observations `idx`
/// and channels (`α` from `obs`, the unmasked observations).
pub(crate) fn validation_error(
    problem: &Problem,
    obs: &Observations,
    lights: &[[Vec<f64>; 3]],
    beta: &[[f64; 3]],
    idx: &[usize],
) -> f64 {
    let (se, yy) = validation_sums(problem, obs, lights, beta, idx);
    rel(se, yy)
}

/// `(Σ α (y − ŷ)², Σ α y²)` over the observations `idx` and channels.
fn validation_sums(
    problem: &Problem,
    obs: &Observations,
    lights: &[[Vec<f64>; 3]],
    beta: &[[f64; 3]],
    idx: &[usize],
) -> (f64, f64) {
    let t = problem.transport;
    let hs: Vec<Vec<[f64; 3]>> = lights.par_iter().map(|l| haar3(l, t.n_global)).collect();
    let parts: Vec<(f64, f64)> = idx
        .par_chunks(CHUNK)
        .map(|ch| {
            let (mut se, mut yy) = (0.0, 0.0);
            for &p in ch {
                let pred = predict_observation(t, &hs[obs.photo[p] as usize], beta, obs, p);
                let a = obs.weight[p] as f64;
                for c in 0..3 {
                    let y = obs.rgb[p][c] as f64;
                    se += a * (y - pred[c]).powi(2);
                    yy += a * y * y;
                }
            }
            (se, yy)
        })
        .collect();
    parts
        .into_iter()
        .fold((0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1))
}

/// Observation `p`'s prediction `ŷ_p = Σ_b β_{x,b} ⊙ (T_{p,b} · h)` (Eq. 9) under its
/// photo's light `h` (the map's Haar coefficients per channel, [`haar3`]) and the
/// per-vertex reflectance `beta` (`V × B` row-major).
fn predict_observation(
    t: &crate::transport::Transport,
    h: &[[f64; 3]],
    beta: &[[f64; 3]],
    obs: &Observations,
    p: usize,
) -> [f64; 3] {
    let (nb, x) = (t.n_basis, obs.vertex[p] as usize);
    let mut pred = [0.0; 3];
    for b in 0..nb {
        let (ix, val) = t.row(p, b);
        let be = beta[x * nb + b];
        for (&m, &g) in ix.iter().zip(val) {
            let hm = h[m as usize];
            for c in 0..3 {
                pred[c] += be[c] * f64::from(g) * hm[c];
            }
        }
    }
    pred
}

/// Per observation of `idx`, in order, its term `Σ_c α (y − ŷ)²` of
/// [`validation_error`]'s numerator under `(lights, beta)`: what a paired comparison of two
/// fits on the same held-back observations reads ([`crate::solve::paired`]).
pub(crate) fn validation_terms(
    problem: &Problem,
    obs: &Observations,
    lights: &[[Vec<f64>; 3]],
    beta: &[[f64; 3]],
    idx: &[usize],
) -> Vec<f64> {
    let t = problem.transport;
    let hs: Vec<Vec<[f64; 3]>> = lights.par_iter().map(|l| haar3(l, t.n_global)).collect();
    idx.par_iter()
        .map(|&p| {
            let pred = predict_observation(t, &hs[obs.photo[p] as usize], beta, obs, p);
            let a = obs.weight[p] as f64;
            (0..3)
                .map(|c| a * (obs.rgb[p][c] as f64 - pred[c]).powi(2))
                .sum()
        })
        .collect()
}

/// GPCG iterations and CG steps per GPCG iteration of [`half_score`]'s light fits, which
/// start from the fit's mean map: the caps of `run`'s protocol (b), measured there to stay
/// within 0.2% of a fit to the KKT tolerance (`crate::run` module `half_fit`).
pub const HALF_SCORE_GPCG: usize = 20;
/// See [`HALF_SCORE_GPCG`].
pub const HALF_SCORE_CG: usize = 20;

/// The two halves of every photo, by viewing direction alone (no camera needed): with `c`
/// the mean position of the photo's observed vertices and `d` the mean of its directions
/// toward the camera, an observation is *left* when `(x − c) · (d × u) < 0`, `u` the world
/// `y` axis (the `z` axis when `d` is within 10° of `y`). The plane through `c` spanned by
/// `d` and `u` cuts the visible surface into two sides of the photo, as protocol (b)'s
/// centre line does in the image.
pub fn left_by_view(obs: &Observations, positions: &[crate::Vec3]) -> Vec<bool> {
    use crate::Vec3;
    let mut left = vec![false; obs.len()];
    for r in &obs.photo_ranges {
        let n = r.len().max(1) as f64;
        let (mut c, mut d) = (Vec3::zeros(), Vec3::zeros());
        for p in r.clone() {
            c += positions[obs.vertex[p] as usize] / n;
            d += Vec3::new(
                obs.dir[p][0].into(),
                obs.dir[p][1].into(),
                obs.dir[p][2].into(),
            );
        }
        let up = if d.normalize().y.abs() > 10f64.to_radians().cos() {
            Vec3::z()
        } else {
            Vec3::y()
        };
        let right = d.cross(&up);
        for p in r.clone() {
            left[p] = (positions[obs.vertex[p] as usize] - c).dot(&right) < 0.0;
        }
    }
    left
}

/// The data term of a fit on every training observation, a score for comparing fits of
/// one model from different starts (not in the paper): `sqrt(Σ_p α_p ‖y_p − ŷ_p‖²) /
/// sqrt(Σ_p α_p ‖y_p‖²)` over all `α > 0` observations, the early-stopping ones included,
/// with the fit's own maps `lights` (Eq. 9 without the Laplacian, the priors and the IRLS
/// weights). Fits of the same model with the same unknowns differ in it only by the local
/// minimum they reached: the lowest is the deepest, the criterion of a multi-start local
/// optimisation.
pub fn training_score(problem: &Problem, beta: &[[f64; 3]], lights: &[[Vec<f64>; 3]]) -> f64 {
    let obs = problem.obs;
    let idx: Vec<usize> = (0..obs.len()).filter(|&p| obs.weight[p] > 0.0).collect();
    validation_error(problem, obs, lights, beta, &idx)
}

/// Protocol (b) on the training photos, a score for comparing fits (not in the paper):
/// for every photo the light is refitted with the reflectance `beta` frozen on the
/// observations marked `left` and the other half is predicted (`refit_sums`):
/// `sqrt(Σ_{p right} α_p ‖y_p − ŷ_p‖²) / sqrt(Σ_{p right} α_p ‖y_p‖²)`.
///
/// The reflectance has seen both halves, so this ranks fits of the same observations; it
/// is not an estimate of the held-out error.
pub fn half_score(
    problem: &Problem,
    beta: &[[f64; 3]],
    lights: &[[Vec<f64>; 3]],
    left: &[bool],
    opts: &EstimateOptions,
) -> crate::Result<f64> {
    let held: Vec<bool> = left.iter().map(|&l| !l).collect();
    let (se, yy) = refit_sums(problem, beta, lights, &held, opts)?;
    Ok(rel(se, yy))
}

/// Leave one material group out, a score for comparing fits that differ in their albedo
/// ratios (not in the paper): the vertices are cut into groups (`group[x]`, e.g. the
/// paper's clusters); for every group `g` each photo's light is refitted with the
/// reflectance `beta` frozen on the observations of the other groups and predicts group
/// `g`'s (`refit_sums`); the score is `sqrt(Σ_g Σ_{p ∈ g} α_p ‖y_p − ŷ_p‖² / Σ_g Σ_{p ∈ g}
/// α_p ‖y_p‖²)`.
///
/// A fit's own maps adapt to its albedo ratios: a free map per photo brightens the
/// directions one material faces (Eq. 9's valley). A map fitted on the other materials
/// only has to predict this one's radiance where their normals overlap, which it does
/// only with the right ratio.
pub fn material_holdout_score(
    problem: &Problem,
    beta: &[[f64; 3]],
    lights: &[[Vec<f64>; 3]],
    group: &[usize],
    opts: &EstimateOptions,
) -> crate::Result<f64> {
    let obs = problem.obs;
    let n_groups = group.iter().copied().max().map_or(0, |g| g + 1);
    let (mut se, mut yy) = (0.0, 0.0);
    for g in 0..n_groups {
        let held: Vec<bool> = obs.vertex.iter().map(|&x| group[x as usize] == g).collect();
        if !held.iter().any(|&h| h) || held.iter().all(|&h| h) {
            continue;
        }
        let (a, b) = refit_sums(problem, beta, lights, &held, opts)?;
        se += a;
        yy += b;
    }
    Ok(rel(se, yy))
}

/// `sqrt(se / yy)` (`sqrt(se)` when `yy` is 0).
fn rel(se: f64, yy: f64) -> f64 {
    if yy > 0.0 {
        (se / yy).sqrt()
    } else {
        se.sqrt()
    }
}

/// Every photo's light refitted with the reflectance `beta` frozen on the observations not
/// marked `held` (the lighting step's objective, Eq. 10 with the Laplacian and the
/// options' priors, from the mean of `lights`, capped at [`HALF_SCORE_GPCG`] ×
/// [`HALF_SCORE_CG`]); `(Σ α (y − ŷ)², Σ α y²)` over the held observations.
fn refit_sums(
    problem: &Problem,
    beta: &[[f64; 3]],
    lights: &[[Vec<f64>; 3]],
    held: &[bool],
    opts: &EstimateOptions,
) -> crate::Result<(f64, f64)> {
    let obs = problem.obs;
    let mut fit_obs = obs.clone();
    for (p, &h) in held.iter().enumerate() {
        if h {
            fit_obs.mask_out(p);
        }
    }
    let fit_problem = Problem {
        obs: &fit_obs,
        ..*problem
    };
    let start = mean_map(lights);
    let o = EstimateOptions {
        qp_max_iter: HALF_SCORE_GPCG,
        qp_max_cg: HALF_SCORE_CG,
        lighting_sample: 0,
        ..opts.clone()
    };
    let refit: Vec<[Vec<f64>; 3]> = (0..problem.n_photos)
        .map(|i| crate::solve::fit_light_frozen(&fit_problem, beta, i, start.as_ref(), &o))
        .collect::<crate::Result<_>>()?;
    let idx: Vec<usize> = (0..obs.len())
        .filter(|&p| held[p] && obs.weight[p] > 0.0)
        .collect();
    Ok(validation_sums(problem, obs, &refit, beta, &idx))
}

/// The texel-wise mean of `maps` (`None` when empty).
fn mean_map(maps: &[[Vec<f64>; 3]]) -> Option<[Vec<f64>; 3]> {
    let first = maps.first()?;
    let n = maps.len() as f64;
    Some([0, 1, 2].map(|c| {
        (0..first[c].len())
            .map(|t| maps.iter().map(|m| m[c][t]).sum::<f64>() / n)
            .collect()
    }))
}

/// The validation observations of early stopping and the fitted copy of the observations,
/// with them masked (`α = 0`).
pub(crate) struct HeldBack {
    /// Indices of the validation observations, sorted (empty when early stopping is off).
    pub(crate) idx: Vec<usize>,
    /// The share of the `α > 0` observations held back: `validation_fraction` for the
    /// drawn splits, the share actually taken by the photo-half split (a rule, no draw).
    pub(crate) fraction: f64,
    /// Whether the held-back vertices' weights are refitted after the stop: the blocked
    /// split only, whose drawn vertices keep no fitted observation.
    pub(crate) refit: bool,
    masked: Option<Observations>,
}

/// The observations early stopping holds back under `opts` (sorted; empty when it is
/// off): [`photo_halves_split`], [`validation_split_blocked`] or [`validation_split`], in
/// that order of precedence, when a fraction `> 0` and more than one outer iteration ask
/// for it, or with fixed materials when [`EstimateOptions::validate_fixed_materials`] asks
/// for a score. [`HeldBack::new`] masks them; the paired comparison of two fits reads them
/// alone ([`crate::solve::paired`]).
pub(crate) fn held_back_indices(problem: &Problem, opts: &EstimateOptions) -> Vec<usize> {
    let on = if opts.fixed_materials {
        opts.validate_fixed_materials && opts.validation_fraction > 0.0
    } else {
        opts.validation_fraction > 0.0 && opts.max_outer > 1
    };
    if !on {
        return Vec::new();
    }
    if let Some(h) = &opts.validation_halves {
        photo_halves_split(problem.obs, h)
    } else if opts.validation_block > 0 {
        validation_split_blocked(
            problem.obs,
            problem.n_vertices,
            opts.validation_fraction,
            opts.validation_block,
            opts.validation_seed,
        )
    } else {
        validation_split(
            problem.obs,
            problem.n_vertices,
            opts.validation_fraction,
            opts.validation_seed,
        )
    }
}

/// Whether the fit reads clipped channels as lower bounds: asked (every light model
/// reads them), and some observation is one.
fn reads_bounds(problem: &Problem, opts: &EstimateOptions) -> bool {
    opts.clipped_bounds && problem.obs.has_bounds()
}

impl HeldBack {
    /// The split of [`held_back_indices`], masked for the fit; the fit's copy gives the
    /// clipped observations their weight as bounds when asked
    /// ([`EstimateOptions::clipped_bounds`]).
    pub(crate) fn new(problem: &Problem, opts: &EstimateOptions) -> Self {
        let idx = held_back_indices(problem, opts);
        let halves = opts.validation_halves.is_some();
        let blocked = !halves && opts.validation_block > 0;
        let bounds = reads_bounds(problem, opts);
        let masked = (!idx.is_empty() || bounds).then(|| {
            let mut m = problem.obs.clone();
            if bounds {
                m.weigh_bounds(problem.n_vertices);
            }
            for &p in &idx {
                m.mask_out(p);
            }
            m
        });
        let fraction = if halves && !idx.is_empty() {
            let usable = problem.obs.weight.iter().filter(|&&a| a > 0.0).count();
            idx.len() as f64 / usable.max(1) as f64
        } else {
            opts.validation_fraction
        };
        let refit = blocked && !idx.is_empty();
        HeldBack {
            idx,
            fraction,
            refit,
            masked,
        }
    }

    /// `problem` with the validation observations masked.
    pub(crate) fn fit_problem<'a>(&'a self, problem: &Problem<'a>) -> Problem<'a> {
        match &self.masked {
            Some(m) => Problem { obs: m, ..*problem },
            None => *problem,
        }
    }
}

/// The best iterate so far by validation score.
struct Best<S> {
    /// Its outer iteration, from 1.
    iteration: usize,
    /// What the alternation keeps of it (its parameters and IRLS weights).
    state: S,
}

/// Early stopping's running record; `S` is the state kept of the best iterate.
pub(crate) struct EarlyStop<'a, S> {
    idx: &'a [usize],
    /// The unmasked observations (their `α` weigh the score).
    full_obs: &'a Observations,
    fraction: f64,
    errors: Vec<f64>,
    best: Option<Best<S>>,
    /// Whether the loop ended before `max_outer` for want of a better score.
    pub(crate) stopped_early: bool,
}

impl<'a, S> EarlyStop<'a, S> {
    pub(crate) fn new(held: &'a HeldBack, full_obs: &'a Observations, fraction: f64) -> Self {
        EarlyStop {
            idx: &held.idx,
            full_obs,
            fraction,
            errors: Vec::new(),
            best: None,
            stopped_early: false,
        }
    }

    /// Whether early stopping is on (some observations are held back).
    pub(crate) fn is_on(&self) -> bool {
        !self.idx.is_empty()
    }

    /// Scores the state `(maps, beta)` after outer iteration `outer_it`
    /// ([`validation_error`]) and keeps `keep()` when it is the best so far; `None` when
    /// early stopping is off.
    pub(crate) fn score(
        &mut self,
        problem: &Problem,
        maps: &[[Vec<f64>; 3]],
        beta: &[[f64; 3]],
        outer_it: usize,
        keep: impl FnOnce() -> S,
    ) -> Option<f64> {
        let e = self.peek(problem, maps, beta)?;
        self.errors.push(e);
        if self
            .best
            .as_ref()
            .is_none_or(|b| e < self.errors[b.iteration - 1])
        {
            self.best = Some(Best {
                iteration: outer_it,
                state: keep(),
            });
        }
        Some(e)
    }

    /// [`validation_error`] of the state `(maps, beta)` without recording it; `None` when
    /// early stopping is off.
    pub(crate) fn peek(
        &self,
        problem: &Problem,
        maps: &[[Vec<f64>; 3]],
        beta: &[[f64; 3]],
    ) -> Option<f64> {
        self.is_on()
            .then(|| validation_error(problem, self.full_obs, maps, beta, self.idx))
    }

    /// Whether `patience` iterations have passed without a better score, at outer
    /// iteration `min_iterations` or later.
    pub(crate) fn patience_over(
        &self,
        outer_it: usize,
        patience: usize,
        min_iterations: usize,
    ) -> bool {
        outer_it >= min_iterations
            && self
                .best
                .as_ref()
                .is_some_and(|b| outer_it >= b.iteration + patience.max(1))
    }

    /// The best iterate's kept state and the record, when early stopping was on.
    pub(crate) fn finish(self) -> Option<(S, Validation)> {
        let observations = self.idx.len();
        let (errors, fraction, stopped_early) = (self.errors, self.fraction, self.stopped_early);
        self.best.map(|b| {
            (
                b.state,
                Validation {
                    observations,
                    fraction,
                    errors,
                    best_iteration: b.iteration,
                    stopped_early,
                },
            )
        })
    }
}

#[cfg(test)]
mod tests;
