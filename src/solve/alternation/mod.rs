//! The alternation (paper Sec. 5): lighting steps for all photos, then the material step,
//! until the objective's relative decrease is below `rel_tol`, `max_outer` is reached or
//! early stopping ends it; then the scale normalisation ([`crate::solve::normalise`]).
//!
//! One outer iteration (`Alternation::iteration`):
//! 0. at [`EstimateOptions::prune_round`] only, each material's shiny lobes but its
//!    strongest held at zero from then on ([`crate::solve::lobe_prune`]; `prune`);
//! 1. lighting: the light model's [`LightModel::fit`] with `β` fixed; in the first
//!    [`EstimateOptions::ratio_steps`] rounds then the ratio step
//!    ([`crate::solve::ratio_step`]: each material's brightness per channel moved along
//!    the valley with the lights re-solved, kept only when `F` drops and the held-back
//!    observations are predicted no worse; no more after
//!    [`crate::solve::ratio_step::PATIENCE`] rounds in a row that kept none; `ratio`); in
//!    the first [`EstimateOptions::varpro_steps`] rounds
//!    then the variable-projection step ([`crate::solve::varpro_step`]: every material's
//!    `λ` moved by a damped Gauss–Newton step with the lights re-solved, kept per channel
//!    on the same two tests; `varpro`);
//! 2. materials: `λ` then `w` ([`crate::solve::materials`]), `material_sweeps` times, then
//!    the gauge `Σ_x Σ_b β_{x,b,c}` back to its start value (`fix_gauge`);
//! 3. extrapolation (Bro 1998, "Multi-way analysis", §4.5: alternating least squares
//!    crawls along the bilinear valley): `θ + σ(θ − θ_prev)`, `σ = t^{1/3}`, projected to
//!    `≥ 0`, kept only when `F` drops, so `F` stays monotone;
//!    with [`EstimateOptions::anderson_depth`], then Anderson acceleration over `λ`
//!    ([`crate::solve::accel`], kept likewise only when `F` drops);
//! 4. validation: the held-back observations scored, the best iterate kept
//!    ([`crate::solve::validation`]).

mod prune;
mod ratio;
mod varpro;

use std::time::Instant;

use crate::solve::accel::{flatten, unflatten, AndersonHistory};
use crate::solve::light::paper::PaperLight;
use crate::solve::light::shared::SharedLight;
use crate::solve::light::sky::SkyLight;
use crate::solve::light::{LightModel, LightingInput, LightingOutput};
use crate::solve::materials::{
    blend_scaled_gamma, data_weights, lambda_step, sum_weights_gamma, sum_weights_penalty,
    weights_step, LambdaCoupling, NeighbourPull, WeightsRules, WeightsStep,
};
use crate::solve::normalise::normalise;
use crate::solve::objective::{evaluate, gauge, Objective, Point};
use crate::solve::options::{EstimateOptions, SumScope};
use crate::solve::problem::{basis_responses, beta_per_vertex, Problem};
use crate::solve::result::{
    Conditioning, Estimate, IterState, Iteration, Materials0, RatioMoves, StepTimes,
};
use crate::solve::start_check;
use crate::solve::validation::{EarlyStop, HeldBack};
use crate::stages::Stopwatch;
use crate::{Error, Result};

/// The alternation with the paper's light model ([`PaperLight`]), with the shared one
/// ([`SharedLight`]) when `opts.light_groups` is set, or with the sun-and-sky model
/// ([`SkyLight`]) when `opts.light_sky` is. `on_iter` sees every outer iteration's log
/// line and the state it reached.
pub fn estimate(
    problem: &Problem,
    init: Materials0,
    opts: &EstimateOptions,
    on_iter: &mut dyn FnMut(&Iteration, &IterState),
) -> Result<Estimate> {
    if let Some(sky) = &opts.light_sky {
        let light = SkyLight::new(problem, opts, sky)?;
        return estimate_with(problem, init, opts, light, on_iter);
    }
    if let Some(groups) = &opts.light_groups {
        let light = SharedLight::new(problem, opts, &init, groups)?;
        return estimate_with(problem, init, opts, light, on_iter);
    }
    let light = PaperLight::new(problem, opts, &init);
    estimate_with(problem, init, opts, light, on_iter)
}

/// [`estimate`] with the paper's light model started from `lights` (one map per photo, as
/// [`Estimate::lights`]) instead of zero maps: a warm start for a fit whose materials are
/// near those `lights` were fitted with, such as a restart's. Its first lighting step is a
/// warm one (one IRLS pass from the residuals of `lights`, [`crate::solve::light::photo::WARM_IRLS`]).
/// With the sky or the shared light model, as [`estimate`]. `lights` must hold one finite,
/// non-negative map of the problem's global size per photo and channel.
pub fn estimate_from_lights(
    problem: &Problem,
    init: Materials0,
    opts: &EstimateOptions,
    lights: &[[Vec<f64>; 3]],
    on_iter: &mut dyn FnMut(&Iteration, &IterState),
) -> Result<Estimate> {
    if opts.light_sky.is_some() || opts.light_groups.is_some() {
        return estimate(problem, init, opts, on_iter);
    }
    start_check::lights(problem, lights)?;
    let mut light = PaperLight::new(problem, opts, &init);
    light.set_params(lights.to_vec());
    estimate_with(problem, init, opts, light, on_iter)
}

/// The alternation with any light model, starting from `light`'s parameters.
pub fn estimate_with<M: LightModel>(
    problem: &Problem,
    init: Materials0,
    opts: &EstimateOptions,
    light: M,
    on_iter: &mut dyn FnMut(&Iteration, &IterState),
) -> Result<Estimate> {
    problem.validate()?;
    let t0 = Instant::now();
    start_check::materials(problem, &init)?;
    // Early stopping: the validation observations get α = 0 in the fitted copy.
    let held = HeldBack::new(problem, opts);
    let fit_problem = held.fit_problem(problem);
    let mut alt = Alternation::new(&fit_problem, opts, light, &init);
    let mut stop = EarlyStop::new(&held, problem.obs, held.fraction);
    let outer = if opts.fixed_materials {
        1
    } else {
        opts.max_outer.max(1)
    };
    let mut timeline = Vec::new();
    let mut prev_obj = f64::INFINITY;
    for outer_it in 1..=outer {
        let it = alt.iteration(outer_it, &mut stop, t0)?;
        let maps = alt.light.maps(alt.light.params());
        let state = IterState {
            lights: &maps,
            lambda: &alt.lambda,
            weights: &alt.weights,
        };
        on_iter(&it, &state);
        timeline.push(it);
        if stop.patience_over(outer_it, opts.patience, opts.min_iterations) {
            stop.stopped_early = outer_it < outer;
            break;
        }
        let objective = it.objective;
        if prev_obj.is_finite() && (prev_obj - objective).abs() <= opts.rel_tol * prev_obj.abs() {
            break;
        }
        prev_obj = objective;
    }
    let validation = stop.finish().map(|(best, record)| {
        alt.restore(best.state);
        alt.omega = best.omega;
        record
    });
    if held.refit {
        alt.refit_held_weights(problem, &held.idx)?;
    }
    alt.finish(&init, timeline, validation)
}

/// Light parameters and materials at one point of the alternation (the previous iterate
/// for extrapolation, the best one for early stopping).
#[derive(Clone)]
pub(crate) struct Snapshot<P> {
    pub(crate) light: P,
    pub(crate) lambda: Vec<Vec<[f64; 3]>>,
    pub(crate) weights: Vec<f64>,
}

/// What early stopping keeps of its best iterate: the parameters and the IRLS weights.
pub(crate) struct BestIterate<P> {
    state: Snapshot<P>,
    omega: Vec<[f32; 3]>,
}

/// The state the alternation carries from one step to the next.
pub(crate) struct Alternation<'a, M: LightModel> {
    pub(crate) problem: &'a Problem<'a>,
    pub(crate) opts: &'a EstimateOptions,
    pub(crate) light: M,
    /// `lambda[k][b][c]`.
    pub(crate) lambda: Vec<Vec<[f64; 3]>>,
    /// Row-major `V × K`.
    pub(crate) weights: Vec<f64>,
    /// IRLS weights of the last lighting step, per observation and channel.
    pub(crate) omega: Vec<[f32; 3]>,
    /// The λ ridge per channel, fixed at the first material step.
    ridge: Option<[f64; 3]>,
    cond: Conditioning,
    /// The gauge of the start ([`gauge`]).
    gauge0: [f64; 3],
    /// The previous iterate, for extrapolation.
    prev: Option<Snapshot<M::Params>>,
    /// `γ_x` of the weights' sum-to-one prior, when on ([`EstimateOptions::weights_sum`]).
    pub(crate) sum_gamma: Option<Vec<f64>>,
    /// The full `γ_x` when the prior ties blended vertices only ([`SumScope::Blends`]):
    /// `sum_gamma` is rescaled from it before every material step.
    sum_gamma_full: Option<Vec<f64>>,
    /// `η_x` of the neighbour prior, when on ([`EstimateOptions::weights_smoothness`]).
    pub(crate) pull_eta: Option<Vec<f64>>,
    /// Anderson acceleration's history, when on ([`crate::solve::accel`]).
    pub(crate) anderson: Option<AndersonHistory>,
    /// The ratio step's record.
    ratio_moves: RatioMoves,
    /// Rounds in a row in which the ratio step kept no move.
    ratio_idle: usize,
    /// The variable-projection step's record.
    varpro_moves: RatioMoves,
    /// `pruned[k·B + b]`: `λ_{k,b,·}` held at zero ([`crate::solve::lobe_prune`]); empty
    /// before [`EstimateOptions::prune_round`].
    pruned: Vec<bool>,
    /// The variable-projection step's Jacobian after its last kept step, for Broyden's
    /// update in the next round ([`EstimateOptions::varpro_broyden`]); its columns are the
    /// unpruned entries of `λ`, so pruning drops it.
    varpro_jacobian: Option<crate::solve::varpro_step::Jacobian>,
}

impl<'a, M: LightModel> Alternation<'a, M> {
    fn new(
        problem: &'a Problem<'a>,
        opts: &'a EstimateOptions,
        light: M,
        init: &Materials0,
    ) -> Self {
        let sum_gamma = (opts.weights_sum > 0.0)
            .then(|| sum_weights_gamma(problem.obs, problem.n_vertices, opts.weights_sum));
        let blends_only = matches!(opts.weights_sum_scope, SumScope::Blends { .. });
        Alternation {
            problem,
            opts,
            light,
            lambda: init.lambda.clone(),
            weights: init.weights.clone(),
            omega: vec![[1.0_f32; 3]; problem.obs.vertex.len()],
            ridge: None,
            cond: Conditioning::default(),
            gauge0: gauge(&init.lambda, &init.weights, problem.n_vertices),
            prev: None,
            sum_gamma_full: sum_gamma.clone().filter(|_| blends_only),
            sum_gamma,
            pull_eta: (opts.weights_smoothness > 0.0 && !opts.weights_graph.is_empty()).then(
                || sum_weights_gamma(problem.obs, problem.n_vertices, opts.weights_smoothness),
            ),
            anderson: (opts.anderson_depth > 0).then(|| AndersonHistory::new(opts.anderson_depth)),
            ratio_moves: RatioMoves::default(),
            ratio_idle: 0,
            varpro_moves: RatioMoves::default(),
            pruned: Vec::new(),
            varpro_jacobian: None,
        }
    }

    /// One outer iteration (module docs), its log line.
    fn iteration(
        &mut self,
        outer_it: usize,
        stop: &mut EarlyStop<BestIterate<M::Params>>,
        t0: Instant,
    ) -> Result<Iteration> {
        self.prune_lobes(outer_it);
        let (lighting_seconds, lighting_cpu_seconds) = self.lighting(outer_it)?;
        if !self.opts.fixed_materials {
            self.ratio_step(outer_it, stop)?;
            self.varpro_step(outer_it, stop)?;
        }
        let watch = Stopwatch::start();
        let s = self.materials()?;
        let (material_seconds, material_cpu_seconds) = watch.elapsed();
        let mut obj = self.objective(Some(&s));
        if !self.opts.fixed_materials && self.opts.extrapolate {
            obj = self.extrapolate(outer_it, obj);
            obj = self.anderson_step(outer_it, obj)?;
        }
        if !obj.value.is_finite() {
            return Err(Error::Numeric {
                stage: "estimation".into(),
                message: "the objective became non-finite".into(),
            });
        }
        let validation_rel = self.score(stop, outer_it);
        Ok(Iteration {
            seconds: t0.elapsed().as_secs_f64(),
            objective: obj.value,
            train_rmse: obj.train_rmse,
            validation_rel,
            steps: StepTimes {
                lighting_seconds,
                lighting_cpu_seconds,
                material_seconds,
                material_cpu_seconds,
            },
        })
    }

    /// The lighting step; its wall and CPU seconds.
    pub(crate) fn lighting(&mut self, outer_it: usize) -> Result<(f64, f64)> {
        let beta = beta_per_vertex(&self.lambda, &self.weights, self.problem.n_vertices);
        let watch = Stopwatch::start();
        let input = LightingInput {
            problem: self.problem,
            beta: &beta,
            outer_iteration: outer_it,
        };
        let mut out = LightingOutput {
            irls_weights: &mut self.omega,
            conditioning: &mut self.cond,
        };
        self.light.fit(&input, &mut out)?;
        Ok(watch.elapsed())
    }

    /// The material step (module docs); the basis responses `s` of the lights it ends with.
    /// After a blocked validation split ([`EstimateOptions::validation_block`]) its vertices
    /// have no fitted weights: one w step (Eq. 12) on the `full` problem, under the current
    /// maps and `λ`, gives them theirs; the other vertices keep the returned iterate's.
    fn refit_held_weights(&mut self, full: &Problem, held: &[usize]) -> Result<()> {
        let dw = data_weights(full, &self.omega, self.opts);
        let s = basis_responses(full, &self.light.maps(self.light.params()));
        let w = self.weights_on(full, &s, &dw.weights, false)?;
        let kk = self.lambda.len();
        for &p in held {
            let x = full.obs.vertex[p] as usize;
            self.weights[x * kk..(x + 1) * kk].copy_from_slice(&w.weights[x * kk..(x + 1) * kk]);
        }
        Ok(())
    }

    /// After an outer iteration whose state has objective `current`: records the pair, tries
    /// the extrapolated `λ` ([`crate::solve::accel`]) and keeps it when `F` drops. Returns the objective
    /// of the state kept.
    pub(crate) fn anderson_step(
        &mut self,
        outer_it: usize,
        current: Objective,
    ) -> Result<Objective> {
        let alt = self;
        let Some(mut hist) = alt.anderson.take() else {
            return Ok(current);
        };
        let mut kept = current;
        if let Some(cand) = hist.push(flatten(&alt.lambda)) {
            hist.tried += 1;
            let saved = (alt.snapshot(), alt.omega.clone());
            let problem = alt.problem;
            alt.lambda = unflatten(&cand, &alt.lambda);
            let dw = data_weights(problem, &alt.omega, alt.opts);
            let s = basis_responses(problem, &alt.light.maps(alt.light.params()));
            alt.weights = alt.weights_on(problem, &s, &dw.weights, false)?.weights;
            alt.lighting(outer_it)?;
            let obj = alt.objective(None);
            if obj.value.is_finite() && obj.value < current.value {
                hist.kept += 1;
                kept = obj;
            } else {
                alt.restore(saved.0);
                alt.omega = saved.1;
                hist.clear();
            }
        }
        hist.start(flatten(&alt.lambda));
        alt.anderson = Some(hist);
        Ok(kept)
    }

    /// Early stopping's score of the current iterate, kept when it is the best so far
    /// (`None` when early stopping is off).
    fn score(&self, stop: &mut EarlyStop<BestIterate<M::Params>>, outer_it: usize) -> Option<f64> {
        if !stop.is_on() {
            return None;
        }
        let beta = beta_per_vertex(&self.lambda, &self.weights, self.problem.n_vertices);
        let maps = self.light.maps(self.light.params());
        stop.score(self.problem, &maps, &beta, outer_it, || BestIterate {
            state: self.snapshot(),
            omega: self.omega.clone(),
        })
    }

    fn materials(&mut self) -> Result<Vec<[f64; 3]>> {
        let (problem, opts) = (self.problem, self.opts);
        let dw = data_weights(problem, &self.omega, opts);
        let mut s = basis_responses(problem, &self.light.maps(self.light.params()));
        if opts.fixed_materials {
            return Ok(s);
        }
        let kk = self.lambda.len();
        self.scope_sum_gamma();
        for _ in 0..opts.material_sweeps.max(1) {
            let l = lambda_step(
                problem,
                &s,
                &self.weights,
                kk,
                &dw.lambda,
                self.ridge,
                opts.beta,
                LambdaCoupling::of(opts, &self.pruned),
            )?;
            if self.ridge.is_none() {
                self.ridge = Some(l.max_diag.map(|d| opts.beta * d));
            }
            self.lambda = l.lambda;
            self.cond.lambda = l.cond;
            let w = self.weights_on(problem, &s, &dw.weights, true)?;
            self.weights = w.weights;
            self.cond.weights_max = w.cond_max;
            self.cond.weights_singular = w.singular;
        }
        if opts.fix_gauge {
            self.fix_gauge(&mut s);
        }
        Ok(s)
    }

    /// One w step (Eq. 12) on `problem` under the basis responses `s` and data weights
    /// `dw`, from the current `λ` and weights, with the sum-to-one prior when on and the
    /// neighbour prior when `pull` and on.
    fn weights_on(
        &self,
        problem: &Problem,
        s: &[[f64; 3]],
        dw: &[[f64; 3]],
        pull: bool,
    ) -> Result<WeightsStep> {
        weights_step(
            problem,
            s,
            &self.lambda,
            &self.weights,
            dw,
            WeightsRules {
                gamma: self.sum_gamma.as_deref(),
                pull: if pull { self.pull() } else { None },
                bic: self.opts.weights_bic,
            },
        )
    }

    /// With [`SumScope::Blends`], the sum-to-one prior's `γ_x` for the coming material step
    /// from the current weights ([`blend_scaled_gamma`]).
    fn scope_sum_gamma(&mut self) {
        if let (Some(full), SumScope::Blends { floor }) =
            (&self.sum_gamma_full, self.opts.weights_sum_scope)
        {
            let kk = self.lambda.len();
            self.sum_gamma = Some(blend_scaled_gamma(full, &self.weights, kk, floor));
        }
    }

    /// The weights' priors' terms of `F` at `weights` (0 when off).
    fn weights_prior(&self, weights: &[f64]) -> f64 {
        let kk = self.lambda.len();
        self.sum_gamma
            .as_ref()
            .map_or(0.0, |g| sum_weights_penalty(g, weights, kk))
            + self.pull().map_or(0.0, |p| p.penalty(weights, kk))
    }

    /// The neighbour prior's pull, when on.
    fn pull(&self) -> Option<NeighbourPull<'_>> {
        self.pull_eta.as_deref().map(|eta| NeighbourPull {
            eta,
            graph: &self.opts.weights_graph,
        })
    }

    /// Per channel, `G_c = Σ_x Σ_b β_{x,b,c}` back to its start value, the lights (and
    /// their responses `s`) taking the inverse factor: the data term is unchanged, and the
    /// prior's weights, fixed at the first lighting step, keep their meaning.
    fn fix_gauge(&mut self, s: &mut [[f64; 3]]) {
        let g_now = gauge(&self.lambda, &self.weights, self.problem.n_vertices);
        for c in 0..3 {
            if g_now[c] > 0.0 && self.gauge0[c] > 0.0 {
                let f = self.gauge0[c] / g_now[c];
                for v in self.lambda.iter_mut().flatten() {
                    v[c] *= f;
                }
                self.light.divide_channel(c, f);
                for v in s.iter_mut() {
                    v[c] /= f;
                }
            }
        }
    }

    /// `F` and the train RMSE of the current state (`s`: its basis responses, if known).
    pub(crate) fn objective(&self, s: Option<&[[f64; 3]]>) -> Objective {
        let params = self.light.params();
        let maps = self.light.maps(params);
        let at = Point {
            maps: &maps,
            lambda: &self.lambda,
            weights: &self.weights,
            prior: self.light.penalty(params) + self.weights_prior(&self.weights),
        };
        evaluate(self.problem, &at, self.ridge, &self.omega, s)
    }

    /// Tries the extrapolated state (module docs), keeps it when `F` drops; records the
    /// iterate for the next call. Returns the objective of the state kept.
    fn extrapolate(&mut self, outer_it: usize, current: Objective) -> Objective {
        let mut kept = current;
        if let Some(prev) = self.prev.take() {
            let sig = (outer_it as f64).cbrt();
            let ext = |a: f64, b: f64| (a + sig * (a - b)).max(0.0);
            let cl = self
                .light
                .extrapolate(self.light.params(), &prev.light, sig);
            let clam: Vec<Vec<[f64; 3]>> = self
                .lambda
                .iter()
                .zip(&prev.lambda)
                .map(|(l, q)| {
                    l.iter()
                        .zip(q)
                        .map(|(a, b)| [0, 1, 2].map(|c| ext(a[c], b[c])))
                        .collect()
                })
                .collect();
            let cw: Vec<f64> = self
                .weights
                .iter()
                .zip(&prev.weights)
                .map(|(&a, &b)| ext(a, b))
                .collect();
            let cand = {
                let maps = self.light.maps(&cl);
                let at = Point {
                    maps: &maps,
                    lambda: &clam,
                    weights: &cw,
                    prior: self.light.penalty(&cl) + self.weights_prior(&cw),
                };
                evaluate(self.problem, &at, self.ridge, &self.omega, None)
            };
            if cand.value < current.value {
                self.light.set_params(cl);
                self.lambda = clam;
                self.weights = cw;
                kept = cand;
            }
        }
        self.prev = Some(self.snapshot());
        kept
    }

    /// A copy of the light parameters and materials.
    pub(crate) fn snapshot(&self) -> Snapshot<M::Params> {
        Snapshot {
            light: self.light.params().clone(),
            lambda: self.lambda.clone(),
            weights: self.weights.clone(),
        }
    }

    /// Back to a snapshot (the light model's prior weights stay).
    pub(crate) fn restore(&mut self, s: Snapshot<M::Params>) {
        self.light.set_params(s.light);
        self.lambda = s.lambda;
        self.weights = s.weights;
    }

    /// The normalisation (module docs of [`crate::solve`]) and the result.
    fn finish(
        mut self,
        init: &Materials0,
        timeline: Vec<Iteration>,
        validation: Option<crate::solve::result::Validation>,
    ) -> Result<Estimate> {
        let sample_check = self
            .light
            .sample_check(self.problem, &self.lambda, &self.weights);
        let observed = self.problem.obs.seen_vertices(self.problem.n_vertices);
        let normalisation = normalise(
            &mut self.light,
            &mut self.lambda,
            &mut self.weights,
            init,
            self.opts,
            &observed,
        );
        Ok(Estimate {
            sky: self.light.sky_fit(),
            mu: self.light.prior_weights(),
            lights: self.light.into_maps(),
            lambda: self.lambda,
            weights: self.weights,
            timeline,
            normalisation,
            irls_weights: self.omega,
            conditioning: self.cond,
            validation,
            lighting_sample: sample_check,
            ratio_moves: self.ratio_moves,
            varpro_moves: self.varpro_moves,
        })
    }
}
