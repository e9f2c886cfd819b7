//! The paper's light model (Sec. 5.1, Eq. 10): per photo a free, non-negative global
//! octahedral map (`n_global²` texels per channel), with the smoothness prior
//! `μ_{I,c} ‖Δ x_{I,c}‖²` of the map's graph Laplacian (`Laplacian`).
//!
//! `μ_{I,c}` = `smoothness` × the largest diagonal entry of the photo's system (the scale
//! [`crate::solve::SmoothnessScale`]), fixed at the photo's first lighting step, then
//! optionally decayed per outer iteration (`smoothness_decay`, floored at
//! `smoothness_min`). Photos are independent and solved in parallel, largest first
//! ([`crate::solve::par_largest_first`]); each solve is sequential, so the result does
//! not depend on the thread count. Inside the alternation each QP is an inexact block
//! step from the previous iterate, capped at
//! [`EstimateOptions::alternation_qp_iters`] GPCG iterations of at most
//! [`EstimateOptions::alternation_cg_iters`] CG steps, and after a photo's first step its
//! IRLS continues from the previous iterate's residuals in one pass
//! ([`crate::solve::light::photo::WARM_IRLS`]).

use std::borrow::Cow;

use crate::solve::light::laplacian::{
    combine_maps, extrapolate_maps, smoothness_factor, WeightedMaps,
};
use crate::solve::light::map_fit::MapFitState;
use crate::solve::light::photo::{lighting_step_warm, LightingResult, WARM_IRLS};
use crate::solve::light::{LightModel, LightingInput, LightingOutput};
use crate::solve::options::EstimateOptions;
use crate::solve::problem::{par_largest_first, Problem};
use crate::solve::result::Materials0;
use crate::solve::subsample::SampleCheck;
use crate::Result;

/// Per photo and channel, a map's texels.
pub type Maps = Vec<[Vec<f64>; 3]>;

/// The paper's free wavelet map per photo (module docs).
#[derive(Clone)]
pub struct PaperLight {
    lights: Maps,
    /// The Laplacian prior's weights per photo, the options and the lighting sample.
    state: MapFitState,
}

impl PaperLight {
    /// Zero maps for every photo of `problem`; `init` (the starting materials) gives the
    /// lighting sample's strata.
    pub fn new(problem: &Problem, opts: &EstimateOptions, init: &Materials0) -> Self {
        let n = problem.transport.n_global;
        let n2 = n * n;
        PaperLight {
            lights: (0..problem.n_photos)
                .map(|_| [vec![0.0; n2], vec![0.0; n2], vec![0.0; n2]])
                .collect(),
            state: MapFitState::new(problem.n_photos, n, opts, init),
        }
    }

    /// The background term of `F` per channel ([`MapFitState::background_penalty`]).
    fn background_penalty(&self, params: &Maps) -> [f64; 3] {
        self.state
            .background_penalty(params.iter().map(|m| (m, [1.0; 3])))
    }

    /// Takes one photo's lighting result into the state and the outputs.
    fn absorb(&mut self, problem: &Problem, i: usize, r: LightingResult, out: &mut LightingOutput) {
        let range = problem.obs.photo_ranges[i].clone();
        out.irls_weights[range].copy_from_slice(&r.irls_weights);
        self.lights[i] = r.light;
        self.state.record_mu(i, r.mu);
        let cond = &mut *out.conditioning;
        cond.lighting.push(r.cond_lower_bound);
        cond.qp_unconverged += usize::from(!r.converged);
        cond.lighting_matvecs += r.matvecs;
        cond.lighting_qps += r.qps;
        cond.lighting_matvecs_max = cond.lighting_matvecs_max.max(r.matvecs_max);
        if self.state.capped() {
            cond.qp_alternation_capped += r.unconverged_qps;
        }
    }
}

impl LightModel for PaperLight {
    type Params = Maps;

    fn name(&self) -> &'static str {
        "paper: free wavelet map per photo, Laplacian prior"
    }

    fn parameter_count(&self) -> usize {
        self.lights
            .iter()
            .map(|l| l.iter().map(Vec::len).sum::<usize>())
            .sum()
    }

    fn fit(&mut self, input: &LightingInput, out: &mut LightingOutput) -> Result<()> {
        let problem = input.problem;
        let mu_factor = smoothness_factor(&self.state.opts, input.outer_iteration);
        let sizes: Vec<usize> = problem.obs.photo_ranges.iter().map(|r| r.len()).collect();
        self.state.draw_samples(problem);
        let state = &self.state;
        let (samples, lights, mu_first) = (state.samples(), &self.lights, &state.mu_first);
        let light_opts = &state.light_opts;
        let results: Vec<Result<LightingResult>> = par_largest_first(&sizes, |i| {
            let m = mu_first[i].map(|m| m.map(|v| v * mu_factor));
            let (start, sample) = (Some(&lights[i]), samples[i].as_ref());
            lighting_step_warm(
                problem, input.beta, i, start, m, light_opts, sample, WARM_IRLS,
            )
        });
        out.conditioning.lighting.clear();
        out.conditioning.qp_unconverged = 0;
        out.conditioning.qp_alternation_capped = 0;
        for (i, r) in results.into_iter().enumerate() {
            self.absorb(problem, i, r?, out);
        }
        Ok(())
    }

    fn params(&self) -> &Maps {
        &self.lights
    }

    fn set_params(&mut self, params: Maps) {
        self.lights = params;
    }

    fn maps<'a>(&'a self, params: &'a Maps) -> Cow<'a, [[Vec<f64>; 3]]> {
        Cow::Borrowed(params)
    }

    fn penalty(&self, params: &Maps) -> f64 {
        self.state.penalty(params) + self.background_penalty(params).iter().sum::<f64>()
    }

    fn combine(&self, parts: &[(&Maps, [f64; 3])]) -> Option<Maps> {
        let maps: Vec<WeightedMaps> = parts.iter().map(|(p, w)| (p.as_slice(), *w)).collect();
        combine_maps(&maps)
    }

    fn channel_penalty(&self, params: &Maps) -> Option<[f64; 3]> {
        let (lap, bg) = (
            self.state.channel_penalty(params),
            self.background_penalty(params),
        );
        Some([0, 1, 2].map(|c| lap[c] + bg[c]))
    }

    fn extrapolate(&self, params: &Maps, prev: &Maps, sigma: f64) -> Maps {
        extrapolate_maps(params, prev, sigma)
    }

    fn divide_channel(&mut self, c: usize, f: f64) {
        for l in self.lights.iter_mut() {
            l[c].iter_mut().for_each(|v| *v /= f);
        }
    }

    fn normalise(&mut self, s: f64) {
        for l in self.lights.iter_mut() {
            for v in l.iter_mut().flatten() {
                *v /= s;
            }
        }
        self.state.normalise(s);
    }

    fn prior_weights(&self) -> Vec<[f64; 3]> {
        self.state
            .mu
            .iter()
            .map(|m| m.unwrap_or([0.0; 3]))
            .collect()
    }

    fn into_maps(self) -> Maps {
        self.lights
    }

    fn sample_check(
        &self,
        problem: &Problem,
        lambda: &[Vec<[f64; 3]>],
        weights: &[f64],
    ) -> Option<SampleCheck> {
        self.state
            .sample_check(problem, lambda, weights, || Cow::Borrowed(&self.lights))
    }
}
