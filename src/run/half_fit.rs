//! Held-out protocol (b) (`half`, docs/method.md "Held-out evaluation"): the light of a
//! held-out photo fitted with the reflectance frozen to the observations left of the middle
//! of the object, judged on the right half.
//!
//! The fit minimises the lighting step's objective (Eq. 10 with the Laplacian, the robust
//! IRLS weights and the light prior, [`crate::solve::fit_light_frozen`]) over the photo's
//! left-half observations `p`, `Σ_p α_p ω_p (y_p − ⟨e_p, W x⟩)²` plus the priors, from the
//! mean training map, capped at [`HALF_FIT_GPCG`] × [`HALF_FIT_CG`] per IRLS pass. Every
//! left-half observation is used: the right half is an extrapolation of the map the left
//! half does not pin down, and its error follows the solver's path. Measured at 100K
//! vertices (`bench-results/speed-evaluation-2.md`): a stratified sample of 2,000–16,000 of
//! a photo's 16,000–22,000 left-half observations (Horvitz–Thompson weighted), with or
//! without a polish of 5–10 GPCG iterations on all of them, moved the right half's error on
//! one photo by −16% to +18% (+0.8% to +1.3% with 16,000 of its 22,094), and one warm IRLS
//! pass instead of three by −11%; at 30K the same error is within 0.2% of an 80-iteration
//! fit's.

use super::Fitted;
use crate::observe::Observations;
use crate::solve::{self, EstimateOptions, Problem};
use crate::sphere::envmap::OctEnv;
use crate::Result;

/// GPCG iterations and CG steps per GPCG iteration of protocol (b)'s light fit, which
/// starts from the mean training map. Measured on the Minerva model (2,930 vertices, 3
/// held-out views, `bench-results/archive/pipeline-scaling.md`): against 300 × 100 from zero (which
/// stops at its cap, not at the KKT tolerance) 4.0 instead of 10.9 CPU s, the `half` RMSEs
/// within 0.2% (0.08649 / 0.07549 / 0.09602 against 0.08651 / 0.07559 / 0.09622); 50 × 20
/// matches to 5 digits at 7.0 s, 5 × 20 under-solves (1–3% off).
pub(crate) const HALF_FIT_GPCG: usize = 20;
/// See [`HALF_FIT_GPCG`].
pub(crate) const HALF_FIT_CG: usize = 20;

/// The middle of the span of `xs`, `(min + max) / 2` (pixel centres: the middle of the
/// covered pixels), or `None` when empty: the left/right rule of protocol (b).
pub(crate) fn span_mid(xs: impl Iterator<Item = f64>) -> Option<f64> {
    let (lo, hi) = xs.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
        (lo.min(x), hi.max(x))
    });
    (lo <= hi).then_some(0.5 * (lo + hi))
}

/// The pixel `x` at which `view` sees `point`, or `None` behind the camera.
pub(crate) fn projected_x(view: &crate::import::scene::View, point: &crate::Vec3) -> Option<f64> {
    let cam = view.image.cam_from_world_point(point);
    view.camera.project(&cam).map(|px| px[0])
}

/// View `v`'s weighted observations whose vertex projects left of `mid_x` (one photo).
pub(super) fn left_half_observations(f: &Fitted, v: usize, mid_x: f64) -> Observations {
    let view = &f.scene.views[v];
    let obs = f.observations_of(v);
    let kept: Vec<usize> = (0..obs.len())
        .filter(|&p| {
            let x = obs.vertex[p] as usize;
            obs.weight[p] > 0.0
                && projected_x(view, &f.scene.mesh.positions[x]).is_some_and(|px| px < mid_x)
        })
        .collect();
    obs.gather(&kept)
}

/// Protocol (b): fit the light on the observations of view `v` left of `mid_x`, frozen
/// reflectance, from `start` (the mean training map); `None` when there are none.
pub(super) fn fit_left_half(
    f: &Fitted,
    v: usize,
    mid_x: f64,
    start: &OctEnv,
) -> Result<Option<OctEnv>> {
    let left = left_half_observations(f, v, mid_x);
    if left.is_empty() {
        return Ok(None);
    }
    let tr = f.transport_for(&left)?;
    let problem = Problem {
        obs: &left,
        transport: &tr,
        n_vertices: f.scene.mesh.positions.len(),
        n_photos: 1,
    };
    let opts = EstimateOptions {
        qp_max_iter: HALF_FIT_GPCG,
        qp_max_cg: HALF_FIT_CG,
        lighting_sample: 0,
        light_prior: f
            .half_prior
            .clone()
            .or(f.estimate_options.light_prior.clone()),
        ..f.estimate_options.clone()
    };
    let start = [0, 1, 2].map(|c| start.channel(c));
    let l = solve::fit_light_frozen(&problem, &f.beta, 0, Some(&start), &opts)?;
    Ok(Some(OctEnv::from_channels(
        f.opts.global_resolution,
        [&l[0], &l[1], &l[2]],
    )))
}
