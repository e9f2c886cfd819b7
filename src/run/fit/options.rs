//! The estimator's options for the fit, from the run's ([`estimate_options`]), the
//! Lambertian lobe that carries the diffuse colour ([`lambert_of`]), and early stopping's
//! split by photo half ([`photo_halves`]).

use crate::import::scene::View;
use crate::observe::Observations;
use crate::run::half_fit::{projected_x, span_mid};
use crate::run::RunOptions;
use crate::solve::loss_choice::{self, LossChoice};
use crate::solve::options::PhotoHalves;
use crate::solve::{EstimateOptions, Robust};
use crate::transport::brdf::BasisBrdf;
use crate::{Error, Result, Vec3};

/// The index of the Lambertian basis BRDF, which carries the diffuse colour.
pub(crate) fn lambert_of(basis: &[BasisBrdf]) -> Result<usize> {
    basis
        .iter()
        .position(|b| matches!(b, BasisBrdf::Lambert))
        .ok_or_else(|| {
            Error::Config("--basis: a Lambertian lobe is needed to carry the diffuse colour".into())
        })
}

/// The estimator's options from the run's (`--loss plain`: [`loss_choice::plain`] of them).
pub(crate) fn estimate_options(o: &RunOptions, lambert: usize, strata: &[u32]) -> EstimateOptions {
    let opts = EstimateOptions {
        max_outer: o.max_iterations,
        rel_tol: o.rel_tol,
        smoothness: crate::run::smoothness_base(o.smoothness),
        chroma_smoothness: o.chroma_smoothness,
        robust: if o.irls_iterations > 1 {
            Robust::Huber { k: 1.345 }
        } else {
            Robust::None
        },
        irls_iters: o.irls_iterations,
        robust_floor: o.robust_floor,
        weights_sum: o.weights_sum.value(),
        weights_sum_scope: o.weights_sum_scope,
        weights_smoothness: o.weights_smoothness.value(),
        weights_bic: o.weights_bic.value(),
        // `auto` leaves the pilot free; the full fit applies the rule ([`achromatic_for`]).
        achromatic_specular: o.achromatic_specular == crate::run::Achromatic::On,
        alternation_qp_iters: (o.lighting_qp_iterations > 0).then_some(o.lighting_qp_iterations),
        alternation_cg_iters: (o.lighting_cg_iterations > 0).then_some(o.lighting_cg_iterations),
        patience: o.patience,
        min_iterations: o.min_iterations,
        lambert_basis: lambert,
        validation_seed: o.seed,
        validation_fraction: o.validation,
        validation_block: o.validation_block,
        lighting_sample: o.lighting_sample,
        blend_tolerance: o.blend_tolerance,
        lighting_strata: strata.to_vec(),
        scale_anchor: o.scale_anchor,
        clipped_bounds: o.clipped == super::super::Clipped::Bound,
        ..EstimateOptions::default()
    };
    match o.loss {
        LossChoice::Plain => loss_choice::plain(&opts),
        LossChoice::Robust | LossChoice::Auto => opts,
    }
}

/// Early stopping's split by photo half (`--validation-halves k`), and the halves `--light
/// auto` scores its candidates on: `k` of the training photos `train_views` (in the
/// observations' order) spread evenly over the list (the middle of each of `k` equal runs),
/// and in each the vertices it observes projecting at or right of the middle of their `x`
/// span (`span_mid`, the left/right rule of protocol `half`). `None` for `k = 0` or when
/// `k` is not below the number of training photos.
pub fn photo_halves(
    train_views: &[&View],
    positions: &[Vec3],
    obs: &Observations,
    k: usize,
) -> Option<std::sync::Arc<PhotoHalves>> {
    let n = train_views.len();
    if k == 0 || k >= n {
        return None;
    }
    let right = (0..k)
        .map(|i| {
            let t = (2 * i + 1) * n / (2 * k);
            let view = train_views[t];
            let px: Vec<(usize, f64)> = obs
                .photo_ranges
                .get(t)
                .cloned()
                .unwrap_or_default()
                .filter(|&p| obs.weight[p] > 0.0)
                .filter_map(|p| {
                    let x = obs.vertex[p] as usize;
                    projected_x(view, &positions[x]).map(|u| (x, u))
                })
                .collect();
            let mut right = vec![false; positions.len()];
            if let Some(mid) = span_mid(px.iter().map(|&(_, u)| u)) {
                for &(x, u) in &px {
                    right[x] = u >= mid;
                }
            }
            (t as u32, right)
        })
        .collect();
    Some(std::sync::Arc::new(PhotoHalves { right }))
}
