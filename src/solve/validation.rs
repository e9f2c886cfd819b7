//! Early stopping (not in the paper): a seeded fraction of the training observations is
//! given `α = 0` for the whole alternation and scored after every outer iteration,
//! `sqrt(Σ α (y − ŷ)²) / sqrt(Σ α y²)`; the iterate with the lowest score is returned.

// Numerical kernels index several arrays in step; range loops read like the math.
#![allow(clippy::needless_range_loop)]

use rayon::prelude::*;

use crate::observe::Observations;
use crate::solve::alternation::{Alternation, Snapshot};
use crate::solve::light::LightModel;
use crate::solve::materials::by_vertex;
use crate::solve::options::{EstimateOptions, VALIDATION_MIN_FIT};
use crate::solve::problem::{beta_per_vertex, haar3, Problem, CHUNK};
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

/// Early stopping's score: `sqrt(Σ α (y − ŷ)²) / sqrt(Σ α y²)` over the observations `idx`
/// and channels (`α` from `obs`, the unmasked observations).
pub(crate) fn validation_error(
    problem: &Problem,
    obs: &Observations,
    lights: &[[Vec<f64>; 3]],
    beta: &[[f64; 3]],
    idx: &[usize],
) -> f64 {
    let t = problem.transport;
    let (n, nb) = (t.n_global, t.n_basis);
    let hs: Vec<Vec<[f64; 3]>> = lights.par_iter().map(|l| haar3(l, n)).collect();
    let parts: Vec<(f64, f64)> = idx
        .par_chunks(CHUNK)
        .map(|ch| {
            let (mut se, mut yy) = (0.0, 0.0);
            for &p in ch {
                let h = &hs[obs.photo[p] as usize];
                let x = obs.vertex[p] as usize;
                let mut pred = [0.0; 3];
                for b in 0..nb {
                    let (ix, val) = t.row(p, b);
                    let be = beta[x * nb + b];
                    for (&m, &g) in ix.iter().zip(val) {
                        let hm = h[m as usize];
                        for c in 0..3 {
                            pred[c] += be[c] * g as f64 * hm[c];
                        }
                    }
                }
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
    let (se, yy) = parts
        .into_iter()
        .fold((0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
    if yy > 0.0 {
        (se / yy).sqrt()
    } else {
        se.sqrt()
    }
}

/// The validation observations of early stopping and the fitted copy of the observations,
/// with them masked (`α = 0`).
pub(crate) struct HeldBack {
    /// Indices of the validation observations, sorted (empty when early stopping is off).
    pub(crate) idx: Vec<usize>,
    masked: Option<Observations>,
}

impl HeldBack {
    /// The split of [`validation_split`] when early stopping is on (a fraction `> 0`, more
    /// than one outer iteration, materials not fixed).
    pub(crate) fn new(problem: &Problem, opts: &EstimateOptions) -> Self {
        let on = !opts.fixed_materials && opts.validation_fraction > 0.0 && opts.max_outer > 1;
        let idx = if on {
            validation_split(
                problem.obs,
                problem.n_vertices,
                opts.validation_fraction,
                opts.validation_seed,
            )
        } else {
            Vec::new()
        };
        let masked = (!idx.is_empty()).then(|| {
            let mut m = problem.obs.clone();
            for &p in &idx {
                m.weight[p] = 0.0;
            }
            m
        });
        HeldBack { idx, masked }
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
struct Best<P> {
    /// Its outer iteration, from 1.
    iteration: usize,
    state: Snapshot<P>,
    omega: Vec<[f32; 3]>,
}

/// Early stopping's running record.
pub(crate) struct EarlyStop<'a, P> {
    idx: &'a [usize],
    /// The unmasked observations (their `α` weigh the score).
    full_obs: &'a Observations,
    fraction: f64,
    errors: Vec<f64>,
    best: Option<Best<P>>,
    /// Whether the loop ended before `max_outer` for want of a better score.
    pub(crate) stopped_early: bool,
}

impl<'a, P: Clone> EarlyStop<'a, P> {
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

    /// Scores the alternation's state after outer iteration `outer_it` and keeps it when
    /// it is the best so far; `None` when early stopping is off.
    pub(crate) fn score<M: LightModel<Params = P>>(
        &mut self,
        alt: &Alternation<M>,
        outer_it: usize,
    ) -> Option<f64> {
        if self.idx.is_empty() {
            return None;
        }
        let beta = beta_per_vertex(&alt.lambda, &alt.weights, alt.problem.n_vertices);
        let maps = alt.light.maps(alt.light.params());
        let e = validation_error(alt.problem, self.full_obs, &maps, &beta, self.idx);
        self.errors.push(e);
        if self
            .best
            .as_ref()
            .is_none_or(|b| e < self.errors[b.iteration - 1])
        {
            self.best = Some(Best {
                iteration: outer_it,
                state: alt.snapshot(),
                omega: alt.omega.clone(),
            });
        }
        Some(e)
    }

    /// Whether `patience` iterations have passed without a better score.
    pub(crate) fn patience_over(&self, outer_it: usize, patience: usize) -> bool {
        self.best
            .as_ref()
            .is_some_and(|b| outer_it >= b.iteration + patience.max(1))
    }

    /// Puts the best iterate back into `alt` (light parameters, materials, IRLS weights)
    /// and returns the record, when early stopping was on.
    pub(crate) fn finish<M: LightModel<Params = P>>(
        self,
        alt: &mut Alternation<M>,
    ) -> Option<Validation> {
        let observations = self.idx.len();
        let (errors, fraction, stopped_early) = (self.errors, self.fraction, self.stopped_early);
        self.best.map(|b| {
            alt.restore(b.state);
            alt.omega = b.omega;
            Validation {
                observations,
                fraction,
                errors,
                best_iteration: b.iteration,
                stopped_early,
            }
        })
    }
}
