//! Re-anchoring the materials on a fit's own reflectance, for a restart of the alternation
//! (not in the paper).
//!
//! The model `β_x = Σ_k w_k(x) λ_k` (paper Eq. 4) is bilinear: any non-negative remix
//! `λ' = A λ`, `w'(x) = w(x) A⁻¹` predicts the same reflectance, and the alternation of
//! Sec. 5 ends in a local minimum that depends on its start. From the paper's start
//! (k-means on the vertices' mean colours, Sec. 5.2, whose albedo ratios carry the
//! scene's shading) the three-material scene of the ablation ends with its materials
//! remixed (weights far from summing to one) and its albedo ratios 40–80% off, while the
//! same alternation started at the TRUE materials stays there (relit 1.03× the floor,
//! `bench-results/estimator-ablation-iterations.md`, section 9).
//!
//! The re-anchored start is k-means' second pass, on the fitted reflectance instead of
//! the photos' colours (the cluster-then-refine scheme of Lloyd 1982, "Least squares
//! quantization in PCM", applied to the per-vertex reflectance `β̂_x`, as in the paper's
//! own start but after the light has been taken out):
//! 1. every seen vertex takes the label of the material contributing most to its
//!    reflectance, `argmax_k w_k(x) Σ_{b,c} λ_{k,b,c}`;
//! 2. each material becomes the component-wise median of `β̂_x` over the vertices with
//!    its label (a pure, physically meaningful reflectance: the gauge `Σ_k w_k = 1` at
//!    pure vertices that the sum-to-one prior asks for);
//! 3. the weights: with [`Reweight::Project`] every seen vertex's `w'(x) ≥ 0` minimises
//!    `‖Σ_k w'_k λ'_k − β̂_x‖²` over its `B·3` components (an NNLS with `K` unknowns), so
//!    the start keeps the fit's reflectance as well as the new materials can express it;
//!    with [`Reweight::Label`] the weights are one-hot on the label (the paper's start
//!    with the clusters and their materials taken from the fit).
//!
//! A material no vertex is labelled with keeps its fitted row; vertices without a label
//! (not seen, or with zero reflectance) keep their weights.
//!
//! [`restart`] fits again from the re-anchored start and keeps whichever of the two fits
//! predicts the held-back observations better (`run --restart on`). On the ablation's
//! three-material scene (96² photos, 5 seeds, `run`'s defaults) it takes the material
//! accuracy from 0.899–0.933 to 0.960–0.978, near the TRUE start's 0.977–0.983 (a gain
//! that was the weights' scale, since fixed in [`crate::solve::normalise`]: the first fit
//! now reads 0.958–0.977 and the restart 0.967–0.982, `bench-results/weights-gauge.md`), but
//! through `run` at 192² it moved `spot-three`'s accuracy by −0.009 and +0.020 and its
//! error under the true light up 5% on both seeds, and `sphere-plane`'s (4 materials
//! fitted) error under the true light down 6% and 16%: it is opt-in
//! (`bench-results/restart-probes.md`).

use nalgebra::{DMatrix, DVector};

use crate::solve::alternation::estimate_from_lights;
use crate::solve::paired::Paired;
use crate::solve::qp::{nnls, NnlsOptions};
use crate::solve::starts::StartRecord;
use crate::solve::validation::{held_back_indices, validation_terms};
use crate::solve::{
    beta_per_vertex, estimate, Estimate, EstimateOptions, IterState, Iteration, Materials0, Problem,
};
use crate::stats::median;
use crate::{Error, Result};

/// How the re-anchored start's blending weights are made (module docs, step 3).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reweight {
    /// The non-negative projection of the fitted reflectance on the new materials.
    Project,
    /// One-hot on the vertex's label.
    Label,
}

/// Each seen vertex's label (module docs, step 1); `None` when unseen or when no
/// material contributes.
pub fn labels(lambda: &[Vec<[f64; 3]>], weights: &[f64], seen: &[bool]) -> Vec<Option<usize>> {
    let kk = lambda.len();
    let size: Vec<f64> = lambda
        .iter()
        .map(|l| l.iter().flatten().sum::<f64>())
        .collect();
    (0..seen.len())
        .map(|x| {
            if !seen[x] {
                return None;
            }
            let row = &weights[x * kk..(x + 1) * kk];
            let (k, c) = (0..kk)
                .map(|k| (k, row[k] * size[k]))
                .fold((0, 0.0), |b, v| if v.1 > b.1 { v } else { b });
            (c > 0.0).then_some(k)
        })
        .collect()
}

/// The re-anchored start of a fit `(lambda, weights)` (`weights` row-major `V × K`, `seen`
/// the vertices with training observations). Errors: `Internal` when the sizes disagree;
/// `Numeric` from a vertex's projection.
pub fn reanchor(
    lambda: &[Vec<[f64; 3]>],
    weights: &[f64],
    seen: &[bool],
    how: Reweight,
) -> Result<Materials0> {
    let kk = lambda.len();
    let nv = seen.len();
    let nb = lambda.first().map_or(0, |l| l.len());
    if kk == 0 || weights.len() != nv * kk || lambda.iter().any(|l| l.len() != nb) {
        return Err(Error::Internal(format!(
            "re-anchoring: {kk} materials, {} weights for {nv} vertices",
            weights.len()
        )));
    }
    let label = labels(lambda, weights, seen);
    let beta = beta_per_vertex(lambda, weights, nv);
    let mut new_lambda = lambda.to_vec();
    for (k, row) in new_lambda.iter_mut().enumerate() {
        let members: Vec<usize> = (0..nv).filter(|&x| label[x] == Some(k)).collect();
        if members.is_empty() {
            continue;
        }
        for (b, v) in row.iter_mut().enumerate() {
            for (c, vc) in v.iter_mut().enumerate() {
                let mut vals: Vec<f64> = members.iter().map(|&x| beta[x * nb + b][c]).collect();
                *vc = median(&mut vals).unwrap_or(0.0);
            }
        }
    }
    let mut new_w = weights.to_vec();
    match how {
        Reweight::Label => {
            for (x, l) in label.iter().enumerate() {
                if let Some(k) = *l {
                    let row = &mut new_w[x * kk..(x + 1) * kk];
                    row.fill(0.0);
                    row[k] = 1.0;
                }
            }
        }
        Reweight::Project => project(&new_lambda, &beta, &label, &mut new_w)?,
    }
    Ok(Materials0 {
        lambda: new_lambda,
        weights: new_w,
    })
}

/// The fit `(lambda, weights)`'s weights re-sorted on the materials `onto` (same count and
/// lobes): each seen vertex's fitted reflectance projected on them by NNLS (module docs,
/// step 3), the other vertices' weights as fitted. Errors as [`reanchor`].
pub fn projected_on(
    onto: &[Vec<[f64; 3]>],
    lambda: &[Vec<[f64; 3]>],
    weights: &[f64],
    seen: &[bool],
) -> Result<Vec<f64>> {
    let nv = seen.len();
    let kk = lambda.len();
    let nb = lambda.first().map_or(0, |l| l.len());
    let sizes_agree = onto.len() == kk && onto.iter().chain(lambda).all(|l| l.len() == nb);
    if kk == 0 || weights.len() != nv * kk || !sizes_agree {
        return Err(Error::Internal(format!(
            "re-sorting weights: {kk} materials ({} to project on), {} weights for {nv} vertices",
            onto.len(),
            weights.len()
        )));
    }
    let label = labels(lambda, weights, seen);
    let beta = beta_per_vertex(lambda, weights, nv);
    let mut new_w = weights.to_vec();
    project(onto, &beta, &label, &mut new_w)?;
    Ok(new_w)
}

/// What [`restart`] and [`fit_again`] return: the fit kept and the restart's record.
pub struct Restarted {
    /// The fit kept ([`choose`]).
    pub est: Estimate,
    /// Whether `est` is the restart's fit.
    pub kept_restart: bool,
    /// The early-stopping validation error of the first fit and of the restart's.
    pub scores: [f64; 2],
    /// With [`Keep::SecondWithinOneSe`] and the restart's score not the lower: the paired
    /// comparison that decided ([`crate::solve::paired`]).
    pub paired: Option<Paired>,
    /// The restart's fit as a start of the run's record.
    pub record: StartRecord,
}

/// How [`fit_again`] chooses between the fit before it and the second fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Keep {
    /// The lower validation error; the first on a tie or a score that is not finite.
    Lower,
    /// As [`Keep::Lower`], and the second also when its validation error is within one
    /// standard error above the first's, the two compared paired on the same held-back
    /// observations ([`crate::solve::paired`]): for a second fit that is the more
    /// constrained model (its materials held).
    SecondWithinOneSe,
}

/// The restart (module docs): `first` re-anchored with projected weights ([`reanchor`],
/// `seen` the vertices with training observations), fitted again with `opts`, and the fit
/// with the lower early-stopping validation error kept; without validation (or on a tie,
/// or a non-finite score) the first. `on_iter` sees every iteration of the restart's fit.
pub fn restart(
    problem: &Problem,
    first: Estimate,
    seen: &[bool],
    opts: &EstimateOptions,
    on_iter: &mut dyn FnMut(&Iteration, &IterState),
) -> Result<Restarted> {
    let start = reanchor(&first.lambda, &first.weights, seen, Reweight::Project)?;
    let second = SecondFit {
        start,
        what: "the fit's own materials re-anchored",
        lights_from: None,
        keep: Keep::Lower,
    };
    fit_again(problem, first, second, opts, on_iter)
}

/// What [`fit_again`] fits after `first`: its start, what it is (for the record), the
/// lights a held fit's one lighting fit starts from (`None`: `first`'s) and how it is
/// weighed against `first`.
pub struct SecondFit<'a> {
    pub start: Materials0,
    pub what: &'a str,
    pub lights_from: Option<&'a [[Vec<f64>; 3]]>,
    pub keep: Keep,
}

/// The second fit `second` after `first`, and the one of the two its [`Keep`] chooses
/// kept ([`choose`]). With the materials held ([`EstimateOptions::fixed_materials`]) the
/// second is one lighting fit from [`SecondFit::lights_from`]
/// ([`estimate_from_lights`]), else a whole fit ([`estimate`]).
pub fn fit_again(
    problem: &Problem,
    first: Estimate,
    second: SecondFit,
    opts: &EstimateOptions,
    on_iter: &mut dyn FnMut(&Iteration, &IterState),
) -> Result<Restarted> {
    let SecondFit {
        start,
        what,
        lights_from,
        keep,
    } = second;
    let second = if opts.fixed_materials {
        let lights = lights_from.unwrap_or(&first.lights);
        estimate_from_lights(problem, start, opts, lights, on_iter)?
    } else {
        estimate(problem, start, opts, on_iter)?
    };
    let (kept_restart, scores, paired) = choose(problem, &first, &second, keep, opts);
    let record = StartRecord::of(
        format!(
            "{what} (validation {:.4} against the fit kept before it, {:.4})",
            scores[1], scores[0]
        ),
        scores[1],
        &second,
    );
    Ok(Restarted {
        est: if kept_restart { second } else { first },
        kept_restart,
        scores,
        paired,
        record,
    })
}

/// Whether `second` is kept over `first` by `keep`, their validation errors, and the
/// paired comparison when it was made: the lower error wins; without validation, on a tie
/// or a score that is not finite, `first`; with [`Keep::SecondWithinOneSe`] a `second`
/// scored higher is kept when within one standard error ([`paired_scores`]).
fn choose(
    problem: &Problem,
    first: &Estimate,
    second: &Estimate,
    keep: Keep,
    opts: &EstimateOptions,
) -> (bool, [f64; 2], Option<Paired>) {
    let scores = [first.validation_error(), second.validation_error()];
    let lower = scores[1] < scores[0];
    let consult = keep == Keep::SecondWithinOneSe && !lower && scores.iter().all(|s| s.is_finite());
    let paired = consult
        .then(|| paired_scores(problem, first, second, opts))
        .flatten();
    let kept = lower || paired.is_some_and(|p| p.second_within_one_se());
    (kept, scores, paired)
}

/// The paired comparison ([`Paired`]) of `first` and `second` on the observations early
/// stopping holds back under `opts` ([`held_back_indices`]), each fit's reflectance `β`
/// from its materials; `None` without held-back observations.
fn paired_scores(
    problem: &Problem,
    first: &Estimate,
    second: &Estimate,
    opts: &EstimateOptions,
) -> Option<Paired> {
    let idx = held_back_indices(problem, opts);
    let terms = |e: &Estimate| {
        let beta = beta_per_vertex(&e.lambda, &e.weights, problem.n_vertices);
        validation_terms(problem, problem.obs, &e.lights, &beta, &idx)
    };
    Paired::of(&terms(first), &terms(second))
}

/// One start of a restart step ([`fit_in_turn`]): the start, what it is (for the record)
/// and its gate: with `within`, made only when the fit before it in the step scored at
/// most that many times the fit it was read against
/// ([`super::coarse_light::RESORT_WITHIN`]).
pub struct StepStart {
    pub from: Materials0,
    pub what: &'static str,
    pub within: Option<f64>,
    /// How it is weighed against the step's first fit ([`fit_again`]); against a start of
    /// the step kept before it, always [`Keep::Lower`] (two fits of one kind).
    pub keep: Keep,
}

/// What became of one start of a step ([`fit_in_turn`]).
pub enum StepOutcome {
    /// Fitted against the fit kept before it: whether it was kept, the two scores (that
    /// fit's, its own) and its record.
    Fitted {
        what: &'static str,
        kept_restart: bool,
        scores: [f64; 2],
        /// The paired comparison when it decided ([`Restarted::paired`]).
        paired: Option<Paired>,
        record: StartRecord,
    },
    /// Not made: its gate saw the fit before it score `before[1]` against `before[0]`.
    Skipped {
        what: &'static str,
        within: f64,
        before: [f64; 2],
    },
}

/// A restart step: each of `starts` in turn fitted against the fit kept before it
/// ([`fit_again`], each kept by its [`StepStart::keep`] while `first` is the fit kept, by
/// the lower validation error after) unless its gate skips it; with more than one start,
/// every held fit starts from `first`'s lights. Returns the
/// fit kept and each start's outcome, in order. `on_iter(n, …)` sees every iteration of
/// the `n`-th fit made.
pub fn fit_in_turn(
    problem: &Problem,
    first: Estimate,
    starts: Vec<StepStart>,
    opts: &EstimateOptions,
    on_iter: &mut dyn FnMut(usize, &Iteration, &IterState),
) -> Result<(Estimate, Vec<StepOutcome>)> {
    let lights_from = (starts.len() > 1).then(|| first.lights.clone());
    let (mut est, mut last, mut made) = (first, None::<[f64; 2]>, 0);
    let mut outcomes = Vec::with_capacity(starts.len());
    let mut first_kept = true;
    for s in starts {
        if let (Some(within), Some(before)) = (s.within, last) {
            let near = before[1] <= within * before[0];
            if !near {
                outcomes.push(StepOutcome::Skipped {
                    what: s.what,
                    within,
                    before,
                });
                continue;
            }
        }
        let n = made;
        let second = SecondFit {
            start: s.from,
            what: s.what,
            lights_from: lights_from.as_deref(),
            keep: if first_kept { s.keep } else { Keep::Lower },
        };
        let done = fit_again(problem, est, second, opts, &mut |it, state| {
            on_iter(n, it, state)
        })?;
        made += 1;
        last = Some(done.scores);
        est = done.est;
        first_kept &= !done.kept_restart;
        outcomes.push(StepOutcome::Fitted {
            what: s.what,
            kept_restart: done.kept_restart,
            scores: done.scores,
            paired: done.paired,
            record: done.record,
        });
    }
    Ok((est, outcomes))
}

/// Step 3 with [`Reweight::Project`]: per labelled vertex, the NNLS `min ‖Λ w − β̂_x‖²`,
/// `Λ` the `B·3 × K` matrix of the new materials.
fn project(
    lambda: &[Vec<[f64; 3]>],
    beta: &[[f64; 3]],
    label: &[Option<usize>],
    weights: &mut [f64],
) -> Result<()> {
    let kk = lambda.len();
    let nb = lambda[0].len();
    let col = |k: usize| lambda[k].iter().flatten().copied().collect::<Vec<f64>>();
    let cols: Vec<Vec<f64>> = (0..kk).map(col).collect();
    let ata = DMatrix::from_fn(kk, kk, |i, j| {
        cols[i]
            .iter()
            .zip(&cols[j])
            .map(|(a, b)| a * b)
            .sum::<f64>()
    });
    // A tiny ridge keeps two equal materials solvable; 1e-12 of the trace changes no
    // weight measurably.
    let ridge = 1e-12 * ata.trace().max(f64::MIN_POSITIVE);
    let ata = ata + DMatrix::identity(kk, kk) * ridge;
    for (x, l) in label.iter().enumerate() {
        if l.is_none() {
            continue;
        }
        let bx: Vec<f64> = beta[x * nb..(x + 1) * nb]
            .iter()
            .flatten()
            .copied()
            .collect();
        let atb = DVector::from_fn(kk, |i, _| cols[i].iter().zip(&bx).map(|(a, b)| a * b).sum());
        let w = nnls(&ata, &atb, &NnlsOptions::default()).map_err(|e| Error::Numeric {
            stage: format!("re-anchoring the materials (vertex {x})"),
            message: e.to_string(),
        })?;
        weights[x * kk..(x + 1) * kk].copy_from_slice(w.as_slice());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two materials of two lobes; vertices 0–3 pure material 0, 4–7 pure material 1,
    /// 8 an even blend, 9 unseen. Returns (λ, w, seen).
    fn truth() -> (Vec<Vec<[f64; 3]>>, Vec<f64>, Vec<bool>) {
        let lambda = vec![
            vec![[0.8, 0.45, 0.2], [0.25, 0.25, 0.25]],
            vec![[0.2, 0.3, 0.6], [0.0, 0.0, 0.0]],
        ];
        let mut w = Vec::new();
        for x in 0..10 {
            w.extend_from_slice(match x {
                0..=3 => &[1.0, 0.0],
                4..=7 => &[0.0, 1.0],
                _ => &[0.5, 0.5],
            });
        }
        let seen = (0..10).map(|x| x != 9).collect();
        (lambda, w, seen)
    }

    /// The same reflectance in another gauge: `λ'_0 = 2 λ_0`, `λ'_1 = λ_1 / 2`, the weights
    /// the inverse (what the alternation may return).
    fn remixed(lambda: &[Vec<[f64; 3]>], w: &[f64]) -> (Vec<Vec<[f64; 3]>>, Vec<f64>) {
        let s = [2.0, 0.5];
        let l = (0..2)
            .map(|k| lambda[k].iter().map(|v| v.map(|c| c * s[k])).collect())
            .collect();
        let w = w.iter().enumerate().map(|(i, v)| v / s[i % 2]).collect();
        (l, w)
    }

    #[test]
    fn project_recovers_the_pure_materials_and_their_weights() {
        let (lambda, w, seen) = truth();
        let (l2, w2) = remixed(&lambda, &w);
        let m = reanchor(&l2, &w2, &seen, Reweight::Project).unwrap();
        // The medians are over 4 identical pure vertices and at most 1 blend (5 values): the
        // pure value exactly; the projection of a reflectance the new materials express
        // exactly is exact up to the NNLS's rounding (1e-9 on values of order 1).
        for k in 0..2 {
            for b in 0..2 {
                for c in 0..3 {
                    assert!(
                        (m.lambda[k][b][c] - lambda[k][b][c]).abs() < 1e-12,
                        "λ {k} {b} {c}"
                    );
                }
            }
        }
        for x in 0..9 {
            for k in 0..2 {
                let (got, want) = (m.weights[x * 2 + k], w[x * 2 + k]);
                assert!((got - want).abs() < 1e-9, "w {x} {k}: {got} against {want}");
            }
        }
        // The unseen vertex keeps what it had.
        assert_eq!(&m.weights[18..20], &w2[18..20]);
    }

    #[test]
    fn label_gives_one_hot_weights() {
        let (lambda, w, seen) = truth();
        let (l2, w2) = remixed(&lambda, &w);
        let m = reanchor(&l2, &w2, &seen, Reweight::Label).unwrap();
        for x in 0..8 {
            let want = if x < 4 { [1.0, 0.0] } else { [0.0, 1.0] };
            assert_eq!(&m.weights[x * 2..x * 2 + 2], &want, "vertex {x}");
        }
        // The blend's label: material 0 contributes Σ λ_0 = 2.2 × 0.5 against 1.1 × 0.5.
        assert_eq!(labels(&l2, &w2, &seen)[8], Some(0));
        assert_eq!(labels(&l2, &w2, &seen)[9], None);
    }

    #[test]
    fn mismatched_sizes_are_an_error() {
        let (lambda, w, seen) = truth();
        assert!(reanchor(&lambda, &w[..10], &seen, Reweight::Project).is_err());
    }
}
