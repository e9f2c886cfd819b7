//! What the two light models that fit free maps keep between lighting steps: the paper's
//! map per photo ([`super::paper::PaperLight`]) and the shared sky's map per group
//! ([`super::shared::SharedLight`]).
//!
//! Both carry the same prior, `Σ_m Σ_c μ_{m,c} ‖Δ x_{m,c}‖²` over their maps `m`
//! ([`Laplacian`]), whose weights `μ_{m,c}` are measured at a map's first lighting step
//! (`μ_1`, the schedule's start, [`crate::solve::light::laplacian::smoothness_factor`])
//! and kept as they were last used (the penalty of `F`), and the same lighting sample
//! per photo ([`EstimateOptions::lighting_sample`]): drawn at the first lighting step,
//! stratified by each vertex's dominant starting material, then fixed for the whole
//! alternation so that the lighting QPs' objective stays one function.

use crate::solve::light::laplacian::{channel_maps_penalty, maps_penalty, Laplacian};
use crate::solve::light::photo::lighting_sample;
use crate::solve::options::EstimateOptions;
use crate::solve::problem::{basis_responses, beta_per_vertex, predict_from, Problem};
use crate::solve::result::Materials0;
use crate::solve::subsample::{dominant_material, sample_check, SampleCheck, Subsample};

/// The prior's weights, the options and the lighting sample of a model with `n_maps` free
/// maps (module docs).
#[derive(Clone)]
pub(crate) struct MapFitState {
    /// `μ` of each map's latest lighting step (`None` before its first).
    pub(crate) mu: Vec<Option<[f64; 3]>>,
    /// `μ` of each map's first lighting step, the schedule's `μ_1`.
    pub(crate) mu_first: Vec<Option<[f64; 3]>>,
    pub(crate) opts: EstimateOptions,
    /// `opts` with the alternation's QP caps applied (inside the alternation the lighting
    /// QPs are inexact block steps, [`EstimateOptions::alternation_lighting`]).
    pub(crate) light_opts: EstimateOptions,
    /// The Laplacian of an `n_global²` map.
    pub(crate) lap: Laplacian,
    /// `n_global`, the maps' side.
    n_global: usize,
    /// Each vertex's dominant starting material (the lighting sample's strata).
    dominant: Vec<u32>,
    /// The lighting sample of each photo, drawn by [`Self::draw_samples`].
    samples: Option<Vec<Option<Subsample>>>,
}

impl MapFitState {
    /// No `μ` yet for `n_maps` maps of `n_global²` texels; `init` (the starting
    /// materials) gives the lighting sample's strata.
    pub(crate) fn new(
        n_maps: usize,
        n_global: usize,
        opts: &EstimateOptions,
        init: &Materials0,
    ) -> Self {
        MapFitState {
            mu: vec![None; n_maps],
            mu_first: vec![None; n_maps],
            opts: opts.clone(),
            light_opts: opts.alternation_lighting(),
            lap: Laplacian::new(n_global),
            n_global,
            dominant: dominant_material(&init.weights, init.lambda.len()),
            samples: None,
        }
    }

    /// Records the `μ` map `m`'s lighting step used (the first one also as `μ_1`).
    pub(crate) fn record_mu(&mut self, m: usize, mu: [f64; 3]) {
        self.mu_first[m].get_or_insert(mu);
        self.mu[m] = Some(mu);
    }

    /// Whether the alternation's QP caps are below a single fit's (its solver records
    /// count the QPs they stopped).
    pub(crate) fn capped(&self) -> bool {
        self.light_opts.qp_max_iter < self.opts.qp_max_iter
    }

    /// Draws each photo's lighting sample on the first call; later calls keep it.
    pub(crate) fn draw_samples(&mut self, problem: &Problem) {
        let (opts, dominant) = (&self.opts, &self.dominant);
        self.samples.get_or_insert_with(|| {
            (0..problem.n_photos)
                .map(|i| lighting_sample(problem, i, opts, Some(dominant)))
                .collect()
        });
    }

    /// Each photo's lighting sample (`None`: all its observations), empty before
    /// [`Self::draw_samples`].
    pub(crate) fn samples(&self) -> &[Option<Subsample>] {
        self.samples.as_deref().unwrap_or(&[])
    }

    /// The prior's term of `F` for `maps` (one per map `m`).
    pub(crate) fn penalty(&self, maps: &[[Vec<f64>; 3]]) -> f64 {
        maps_penalty(&self.lap, maps, &self.mu)
    }

    /// The prior's term of `F` per channel.
    pub(crate) fn channel_penalty(&self, maps: &[[Vec<f64>; 3]]) -> [f64; 3] {
        channel_maps_penalty(&self.lap, maps, &self.mu)
    }

    /// The background term of `F` per channel, photo `I` (in order) seeing the map
    /// `g_I m_I` of `photo_maps` ([`crate::solve::light::background`]; 0 when off).
    pub(crate) fn background_penalty<'m>(
        &self,
        photo_maps: impl IntoIterator<Item = (&'m [Vec<f64>; 3], [f64; 3])>,
    ) -> [f64; 3] {
        self.opts
            .background
            .as_ref()
            .map_or([0.0; 3], |t| t.channel_penalty(self.n_global, photo_maps))
    }

    /// The weights after the maps were divided by `s`: `μ s²` keeps each map's prior term.
    pub(crate) fn normalise(&mut self, s: f64) {
        for m in self.mu.iter_mut().flatten() {
            m.iter_mut().for_each(|v| *v *= s * s);
        }
    }

    /// The lighting sample's check ([`sample_check`]) of the reflectance
    /// `(lambda, weights)` under the photos' maps `photo_maps()`, when a sample was drawn.
    pub(crate) fn sample_check<'m>(
        &self,
        problem: &Problem,
        lambda: &[Vec<[f64; 3]>],
        weights: &[f64],
        photo_maps: impl FnOnce() -> std::borrow::Cow<'m, [[Vec<f64>; 3]]>,
    ) -> Option<SampleCheck> {
        let samples = self.samples.as_ref()?;
        samples.iter().any(Option::is_some).then(|| {
            let beta = beta_per_vertex(lambda, weights, problem.n_vertices);
            let pred = predict_from(problem, &beta, &basis_responses(problem, &photo_maps()));
            let o = problem.obs;
            sample_check(
                &pred,
                &o.rgb,
                &o.weight,
                &o.photo_ranges,
                samples,
                self.opts.lighting_sample,
            )
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn state(n_maps: usize, n: usize) -> MapFitState {
        let init = Materials0 {
            lambda: vec![vec![[1.0; 3]]],
            weights: vec![1.0; 4],
        };
        MapFitState::new(n_maps, n, &EstimateOptions::default(), &init)
    }

    #[test]
    fn the_first_mu_stays_the_schedules_start_and_the_latest_is_the_penaltys() {
        let mut st = state(2, 4);
        st.record_mu(1, [1.0, 2.0, 3.0]);
        st.record_mu(1, [0.5, 1.0, 1.5]);
        assert_eq!(st.mu_first, vec![None, Some([1.0, 2.0, 3.0])]);
        assert_eq!(st.mu, vec![None, Some([0.5, 1.0, 1.5])]);
    }

    #[test]
    fn normalising_keeps_each_maps_prior_term_when_the_maps_are_divided() {
        // ‖Δ(x/s)‖² = ‖Δx‖² / s², so μ s² keeps μ ‖Δx‖²: the penalty of the divided maps
        // with the normalised weights equals the penalty before, to rounding (1e-12
        // relative: a few hundred products of order-one numbers).
        let n = 4;
        let mut st = state(2, n);
        st.record_mu(0, [1.0, 0.3, 2.0]);
        st.record_mu(1, [0.7, 0.7, 0.1]);
        let map = |k: usize| -> [Vec<f64>; 3] {
            [0, 1, 2].map(|c| {
                (0..n * n)
                    .map(|t| ((t * 7 + c * 3 + k) % 5) as f64)
                    .collect()
            })
        };
        let maps = vec![map(0), map(1)];
        let before = st.penalty(&maps);
        let chan_before = st.channel_penalty(&maps);
        assert!(before > 0.0);
        let s = 3.0;
        st.normalise(s);
        let divided: Vec<[Vec<f64>; 3]> = maps
            .iter()
            .map(|m| m.clone().map(|v| v.iter().map(|x| x / s).collect()))
            .collect();
        let after = st.penalty(&divided);
        assert!(
            (after - before).abs() <= 1e-12 * before,
            "{after} vs {before}"
        );
        let chan_after = st.channel_penalty(&divided);
        let sum: f64 = chan_after.iter().sum();
        assert!((sum - before).abs() <= 1e-12 * before);
        for c in 0..3 {
            assert!((chan_after[c] - chan_before[c]).abs() <= 1e-12 * before);
        }
    }

    #[test]
    fn the_alternations_caps_are_told_apart_from_a_single_fits() {
        let st = state(1, 2);
        let d = EstimateOptions::default();
        assert_eq!(
            st.capped(),
            d.alternation_qp_iters.is_some_and(|q| q < d.qp_max_iter)
        );
        assert!(st.samples().is_empty());
    }
}
