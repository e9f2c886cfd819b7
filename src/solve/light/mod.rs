//! The per-photo light model of the estimator: what the lighting step of the alternation
//! fits while the materials are fixed.
//!
//! Whatever its parameters, a light model describes, per photo `I` and channel `c`, the
//! texels `x_{I,c}` of a global octahedral map (`n_global²`, environment frame,
//! [`crate::sphere::SphereGrid::full`]): the light the transport rows `g_{p,b}` see, so that
//! an observation's prediction is `ŷ_{p,c} = Σ_b β_{x,b,c} ⟨g_{p,b}, W x_{I(p),c}⟩` (Eq. 8) and
//! the objective is `F = data + prior(θ) + ridge` (Eq. 9 with the model's own prior).
//!
//! [`LightModel`] is what the alternation needs from a model:
//! - [`LightModel::fit`]: the lighting step. With `β` fixed it builds each photo's system
//!   from the observations and their transport rows and solves it non-negatively (for the
//!   paper's map, Eq. 10 per photo; a model that ties photos together solves them jointly),
//!   and hands back the IRLS weights of every observation and its conditioning figures;
//! - [`LightModel::maps`]: the octahedral texels its parameters describe, which the
//!   material step, the objective, rendering and the report read;
//! - [`LightModel::penalty`]: its prior's term of `F`;
//! - parameters to copy (the best iterate of early stopping), extrapolate (projected on
//!   the model's feasible set) and rescale (the gauge and the final normalisation);
//! - [`LightModel::parameter_count`], its number of free parameters.
//!
//! Implementations: [`paper::PaperLight`], the paper's free wavelet map per photo with a
//! Laplacian smoothness prior; [`shared::SharedLight`], one map per group of photos under
//! one sky with per-photo exposure and white-balance gains; [`sky::SkyLight`], a parametric
//! sun and sky plus a penalised wavelet residual. The statistical prior on the free map is
//! an option of the paper's ([`sh_prior`]). Other models go in as one file each beside
//! them.

use std::borrow::Cow;

use crate::solve::problem::Problem;
use crate::solve::result::Conditioning;
use crate::Result;

pub mod background;
pub(crate) mod bounds;
pub mod choose;
mod chroma;
pub mod frozen;
pub(crate) mod irls;
pub mod laplacian;
pub(crate) mod map_fit;
pub mod paper;
pub mod photo;
pub mod sh_prior;
pub mod shared;
pub mod sky;
pub mod system;
#[cfg(test)]
mod tests;

/// What the lighting step reads: the problem and the current materials.
pub struct LightingInput<'a> {
    /// Observations (the fitted ones: validation observations have `α = 0`) and transport.
    pub problem: &'a Problem<'a>,
    /// `β_{x,b,c}`, row-major `V × B` ([`crate::solve::beta_per_vertex`]).
    pub beta: &'a [[f64; 3]],
    /// The outer iteration, from 1 (a model may schedule its prior by it).
    pub outer_iteration: usize,
}

/// What the lighting step writes besides its own state.
pub struct LightingOutput<'a> {
    /// IRLS weights `ω` per observation and channel (1 without a robust loss): the
    /// material step and the objective weigh the data term with them.
    pub irls_weights: &'a mut [[f32; 3]],
    /// The lighting part of the conditioning figures (`lighting`, `qp_*`,
    /// `lighting_matvecs*`).
    pub conditioning: &'a mut Conditioning,
}

/// A per-photo light model (module docs).
pub trait LightModel: Send + Sync {
    /// The free parameters of every photo's light: what the best iterate keeps and
    /// extrapolation moves.
    type Params: Clone + Send + Sync;

    /// A short name for logs and reports.
    fn name(&self) -> &'static str;

    /// The number of free parameters, all photos and channels.
    fn parameter_count(&self) -> usize;

    /// The lighting step: every photo's light fitted with the materials fixed (module docs).
    fn fit(&mut self, input: &LightingInput, out: &mut LightingOutput) -> Result<()>;

    /// The current parameters.
    fn params(&self) -> &Self::Params;

    /// Replaces the parameters (the prior's weights stay).
    fn set_params(&mut self, params: Self::Params);

    /// Per photo and channel, the octahedral map texels that `params` describe.
    fn maps<'a>(&'a self, params: &'a Self::Params) -> Cow<'a, [[Vec<f64>; 3]]>;

    /// The prior's term of the objective at `params`, with the current weights.
    fn penalty(&self, params: &Self::Params) -> f64;

    /// The prior's term per channel, for a model whose channels are separable (its
    /// lighting step fits each channel on its own); `None` otherwise.
    fn channel_penalty(&self, params: &Self::Params) -> Option<[f64; 3]> {
        let _ = params;
        None
    }

    /// `Σ_i w_{i,c} θ_i` per channel, projected on the model's feasible set, for a model
    /// whose parameters are per-channel maps; `None` otherwise.
    fn combine(&self, parts: &[(&Self::Params, [f64; 3])]) -> Option<Self::Params> {
        let _ = parts;
        None
    }

    /// Holds the model's non-linear values (the sun and sky's `θ` and north) in the
    /// lighting steps while `hold` is set: the ratio step's probes refit only the linear
    /// parameters, so that [`LightModel::combine`] can mix them. A no-op for models
    /// without non-linear values.
    fn hold_shape(&mut self, hold: bool) {
        let _ = hold;
    }

    /// `θ + σ (θ − θ_prev)` projected on the model's feasible set (the extrapolation of
    /// the alternation, Bro 1998).
    fn extrapolate(&self, params: &Self::Params, prev: &Self::Params, sigma: f64) -> Self::Params;

    /// Divides every photo's light in channel `c` by `f` (the gauge inside the
    /// alternation; the prior's weights stay).
    fn divide_channel(&mut self, c: usize, f: f64);

    /// The final normalisation: every light divided by `s`, the prior's weights multiplied
    /// by `s²` so that its term of `F` is unchanged.
    fn normalise(&mut self, s: f64);

    /// Per photo and channel, the prior's weight (`μ_{I,c}` of the paper's Laplacian; 0
    /// where a model has none).
    fn prior_weights(&self) -> Vec<[f64; 3]>;

    /// The maps of the final parameters, per photo and channel.
    fn into_maps(self) -> Vec<[Vec<f64>; 3]>;

    /// Each photo's recovered sun and sky, for a parametric sky model; `None` otherwise.
    fn sky_fit(&self) -> Option<sky::summary::SkyFit> {
        None
    }

    /// The check of a lighting sample at the state `lambda`, `weights` and the current
    /// parameters, when the model fitted its lights on samples of the observations
    /// ([`crate::solve::EstimateOptions::lighting_sample`]); `None` otherwise.
    fn sample_check(
        &self,
        problem: &Problem,
        lambda: &[Vec<[f64; 3]>],
        weights: &[f64],
    ) -> Option<crate::solve::subsample::SampleCheck> {
        let _ = (problem, lambda, weights);
        None
    }
}
