//! Held-out photos' sun and sky with the reflectance frozen: held-out protocol (b)
//! (`run::half_fit`) for a fit whose training light was the sun-and-sky model, so that a
//! held-out photo's light is fitted, on the observations left of the object's middle,
//! within the model the training photos' light was fitted in: the `θ` search, the
//! residual's prior and the joint QP of [`SkyLight`]'s lighting step (parent module docs),
//! repeated [`HELD_OUT_ROUNDS`] times with `β` fixed (each round one majorise–minimise
//! reweighting of the residual's prior). A geotagged photo's sun is its clock sun at the
//! training collection's north, which the photo's own observations do not search again.

use super::clock::ClockSuns;
use super::model::{SkyLight, SkyOptions};
use crate::solve::light::{LightModel, LightingInput, LightingOutput};
use crate::solve::options::EstimateOptions;
use crate::solve::problem::Problem;
use crate::solve::result::Conditioning;
use crate::Result;

/// Lighting steps of a held-out fit: the first searches the grid of suns, the next refine
/// the suns and reweight the residual's prior.
pub const HELD_OUT_ROUNDS: usize = 4;

/// The light of every photo of `problem` with `beta` frozen (module docs): texels per
/// photo and channel. `clock` holds the photos' suns from their geotags (one entry per
/// photo), placed at the training collection's `north`.
pub fn fit_held_out(
    problem: &Problem,
    beta: &[[f64; 3]],
    opts: &EstimateOptions,
    sky: &SkyOptions,
    clock: ClockSuns,
    north: f64,
) -> Result<Vec<[Vec<f64>; 3]>> {
    let opts = EstimateOptions {
        sun_clock: Some(clock),
        ..opts.clone()
    };
    let mut light = SkyLight::new(problem, &opts, sky)?;
    light.fix_north(north);
    let mut omega = vec![[1.0f32; 3]; problem.obs.len()];
    let mut cond = Conditioning::default();
    for round in 1..=HELD_OUT_ROUNDS {
        let input = LightingInput {
            problem,
            beta,
            outer_iteration: round,
        };
        let mut out = LightingOutput {
            irls_weights: &mut omega,
            conditioning: &mut cond,
        };
        light.fit(&input, &mut out)?;
    }
    Ok(light.into_maps())
}
