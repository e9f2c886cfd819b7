//! Held-out protocol (b) (`half`, docs/method.md "Held-out evaluation"): the light of a
//! held-out photo fitted with the reflectance frozen to the observations left of the middle
//! of the object, judged on the right half.
//!
//! The fit minimises the lighting step's objective (Eq. 10 with the Laplacian, the robust
//! IRLS weights and the light prior, [`crate::solve::light::frozen`]) over the photo's
//! left-half observations `p`, `Σ_p α_p ω_p (y_p − ⟨e_p, W x⟩)²` plus the priors, from the
//! mean training map, in the run's IRLS passes (3 by default) capped by [`half_fit_passes`] (those
//! before the last at half its GPCG iterations: they only set the next pass's weights). Every
//! left-half observation is used: the right half is an extrapolation of the map the left
//! half does not pin down, and its error follows the solver's path. Measured at 100K
//! vertices (`bench-results/speed-evaluation-2.md`): a stratified sample of 2,000–16,000 of
//! a photo's 16,000–22,000 left-half observations (Horvitz–Thompson weighted), with or
//! without a polish of 5–10 GPCG iterations on all of them, moved the right half's error on
//! one photo by −16% to +18% (+0.8% to +1.3% with 16,000 of its 22,094), and one warm IRLS
//! pass instead of three by −11%. At 30K a fit converged in every pass (2.2–3.7× the
//! products) is within 0.2% of the capped fits' right-half error
//! (`bench-results/speed-evaluation-4.md`).
//!
//! Under the sun-and-sky model (the fit's light was `sky`: `--light sky`, or `auto`
//! keeping it) a geotagged held-out photo's left-half light is fitted within that model
//! instead ([`crate::solve::light::sky::held_out`]), its sun the clock's at the training
//! photos' north. Without a geotag the sun would have to be searched from half a photo:
//! measured on the real Buddha photos that took the headline from 0.8665 to 0.9403, so
//! those photos keep the free map (`bench-results/sky-geotag.md`, section 6).

use super::Fitted;
use crate::observe::Observations;
use crate::solve::light::frozen::{fit_light_scheduled, PassCaps};
use crate::solve::light::sky::clock::{ClockSun, ClockSuns};
use crate::solve::Problem;
use crate::sphere::envmap::OctEnv;
use crate::Result;

/// GPCG iterations (of the last IRLS pass, [`half_fit_passes`]) and CG steps per GPCG
/// iteration of protocol (b)'s light fit, which starts from the mean training map.
///
/// Many short face solves instead of few long ones. Measured back to back on the 30K and
/// 100K workspaces' three held-out photos (`bench-results/speed-levers-3.md`), against the
/// caps before (10 / 10 / 20 GPCG iterations × 20 CG steps): at 100K the light fits
/// 52.7–53.7 → 43.4 CPU s, the right half's RMSE −0.27% / +0.23% / −0.17%; at 30K
/// 14.0 → 11.9 CPU s, −0.15% / +0.26% / −0.05%, and the maps as near a fit converged in
/// every pass (relative distance 0.159 / 0.253 / 0.032 against 0.137 / 0.281 / 0.050).
/// 10 CG steps with the old GPCG caps were cheaper (100K: 38.0 CPU s) but moved one photo's
/// right half by −2.3%; 5 CG steps, or 5 / 5 / 10 GPCG iterations, by up to 1%.
/// The caps before were measured on the Minerva model (2,930 vertices,
/// `bench-results/archive/pipeline-scaling.md`): 300 × 100 from zero took 10.9 CPU s
/// against 4.0, the `half` RMSEs within 0.2%; 5 × 20 under-solved (1–3% off).
pub const HALF_FIT_GPCG: usize = 28;
/// See [`HALF_FIT_GPCG`].
pub const HALF_FIT_CG: usize = 7;

/// Protocol (b)'s IRLS passes ([`fit_light_scheduled`]), `irls_iters` of them (at least
/// one): those before the last, which only set the next pass's weights, at half the last's
/// GPCG cap. Measured on the 30K workspace's three
/// held-out photos (`bench-results/speed-evaluation-4.md`): Hessian products 1,991 / 2,001 /
/// 1,885 → 1,314 / 1,291 / 1,277 per fit (−34%), the right half's RMSE over its
/// observations −1.3% / −0.3% / +0.1%; a fit converged in every pass (KKT tolerance 10⁻⁷)
/// takes 4,373 / 7,306 / 4,624 products and moves that RMSE by +0.1% / +0.2% / −0.1%.
pub fn half_fit_passes(irls_iters: usize) -> Vec<PassCaps> {
    let early = PassCaps {
        gpcg: HALF_FIT_GPCG / 2,
        cg: HALF_FIT_CG,
    };
    let last = PassCaps {
        gpcg: HALF_FIT_GPCG,
        cg: HALF_FIT_CG,
    };
    let mut passes = vec![early; irls_iters.max(1) - 1];
    passes.push(last);
    passes
}

/// The middle of the span of `xs`, `(min + max) / 2` (pixel centres: the middle of the
/// covered pixels), or `None` when empty: the left/right rule of protocol (b).
pub fn span_mid(xs: impl Iterator<Item = f64>) -> Option<f64> {
    let (lo, hi) = xs.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
        (lo.min(x), hi.max(x))
    });
    (lo <= hi).then_some(0.5 * (lo + hi))
}

/// Protocol (b)'s cut of one photo's observations by their projected `x` (`px`, `None`
/// behind the camera): per observation, `Some(true)` left of the middle of the span of the
/// seen ones (positive `weight`, in front of the camera, [`span_mid`]), `Some(false)` at
/// or right of it, `None` not seen; `None` when no observation is seen.
pub fn sides(weight: &[f32], px: &[Option<f64>]) -> Option<Vec<Option<bool>>> {
    let seen = |p: usize| weight[p] > 0.0 && px[p].is_some();
    let mid = span_mid((0..px.len()).filter(|&p| seen(p)).filter_map(|p| px[p]))?;
    let side = |p: usize| px[p].is_some_and(|u| u < mid);
    Some((0..px.len()).map(|p| seen(p).then(|| side(p))).collect())
}

/// The pixel `x` at which `view` sees `point`, or `None` behind the camera.
pub fn projected_x(view: &crate::import::scene::View, point: &crate::Vec3) -> Option<f64> {
    let cam = view.image.cam_from_world_point(point);
    view.camera.project(&cam).map(|px| px[0])
}

/// View `v`'s observations whose vertex projects left of `mid_x` (one photo), as the
/// light fit reads them ([`fit_rows`]).
pub(super) fn left_half_observations(f: &Fitted, v: usize, mid_x: f64) -> Observations {
    let view = &f.scene.views[v];
    let positions = &f.scene.mesh.positions;
    let left = |x: usize| projected_x(view, &positions[x]).is_some_and(|px| px < mid_x);
    fit_rows(
        &f.observations_of(v),
        left,
        f.estimate_options.clipped_bounds,
    )
}

/// The observations of `obs` at vertices `keep` accepts that a held-out light fit reads:
/// those of positive weight, and with `bounds` (the fit read clipped channels as lower
/// bounds, [`EstimateOptions::clipped_bounds`]) the overexposed ones too, weighted by
/// their bound weight, so that the light step reads them as the fit's did. With the
/// reflectance frozen nothing else has to hold a vertex seen only clipped, so every such
/// observation takes part, not only those at vertices a value also reads.
fn fit_rows(obs: &Observations, keep: impl Fn(usize) -> bool, bounds: bool) -> Observations {
    let bounds = bounds && obs.has_bounds();
    let kept: Vec<usize> = (0..obs.len())
        .filter(|&p| obs.weight[p] > 0.0 || (bounds && obs.bound_weight[p] > 0.0))
        .filter(|&p| keep(obs.vertex[p] as usize))
        .collect();
    let mut rows = obs.gather(&kept);
    if bounds {
        rows.weigh_bounds_at(|_| true);
    }
    rows
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
    let opts = super::half_prior::left_half_options(f);
    let north = f.est.sky.as_ref().and_then(|s| s.north);
    let sun = f
        .held
        .iter()
        .position(|&h| h == v)
        .and_then(|i| f.held_out_suns.get(i).copied().flatten());
    if let (Some(sky), Some(sun), Some(north)) = (&opts.light_sky, sun, north) {
        let clock = ClockSuns {
            per_photo: vec![Some(sun)],
            source: "the held-out photo's geotag".into(),
        };
        let maps = crate::solve::light::sky::held_out::fit_held_out(
            &problem, &f.beta, &opts, sky, clock, north,
        )?;
        return Ok(maps
            .first()
            .map(|l| OctEnv::from_channels(f.opts.global_resolution, [&l[0], &l[1], &l[2]])));
    }
    let start = [0, 1, 2].map(|c| start.channel(c));
    let passes = half_fit_passes(opts.irls_iters);
    let l = fit_light_scheduled(&problem, &f.beta, 0, Some(&start), &opts, &passes)?;
    Ok(Some(OctEnv::from_channels(
        f.opts.global_resolution,
        [&l.light[0], &l.light[1], &l.light[2]],
    )))
}

/// Per held-out view (in `f.held`'s order), its sun from its geotag (one EXIF read per
/// photo), when the fit's light was the sun and sky with a north found from the training
/// photos' geotags (and `--no-geotag-suns` not given); empty otherwise.
pub(super) fn held_out_suns(f: &Fitted) -> Vec<Option<ClockSun>> {
    let with_north = f.est.sky.as_ref().is_some_and(|s| s.north.is_some());
    if !with_north || !f.opts.geotag_suns {
        return Vec::new();
    }
    super::geotag_suns::suns_of(&f.scene.photo_paths(&f.held))
        .map_or_else(Vec::new, |c| c.per_photo)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Four observations of one photo at vertices 0–3: a value, an overexposed one, an
    /// overexposed one at a vertex `keep` refuses, one masked out (no weight as either).
    /// Without bounds only the value is read; with them the overexposed one at a kept
    /// vertex too, its weight its bound weight and its clipped channels carried along.
    #[test]
    fn the_held_out_fit_reads_overexposed_observations_only_with_bounds() {
        let obs = Observations {
            vertex: vec![0, 1, 2, 3],
            photo: vec![0; 4],
            rgb: vec![[0.5; 3], [1.0; 3], [1.0; 3], [0.2; 3]],
            weight: vec![0.7, 0.0, 0.0, 0.0],
            dir: vec![[0.0, 0.0, 1.0]; 4],
            photo_ranges: std::iter::once(0..4).collect(),
            clipped: vec![0, 0b101, 0b111, 0],
            bound_weight: vec![0.0, 0.6, 0.9, 0.0],
        };
        let keep = |x: usize| x != 2;
        let values = fit_rows(&obs, keep, false);
        assert_eq!(values.vertex, [0]);
        assert_eq!(values.weight, [0.7]);
        let bounded = fit_rows(&obs, keep, true);
        assert_eq!(bounded.vertex, [0, 1]);
        assert_eq!(bounded.weight, [0.7, 0.6]);
        assert_eq!(bounded.clipped, [0, 0b101]);
        assert_eq!(bounded.photo_ranges.first(), Some(&(0..2)));
        assert_eq!(bounded.photo_ranges.len(), 1);
    }

    #[test]
    fn half_fit_passes_halve_every_pass_but_the_last() {
        let (early, last) = (PassCaps { gpcg: 14, cg: 7 }, PassCaps { gpcg: 28, cg: 7 });
        assert_eq!(half_fit_passes(3), vec![early, early, last]);
        // No robust passes asked for: one pass, the full caps.
        assert_eq!(half_fit_passes(0), vec![last]);
        assert_eq!(half_fit_passes(1), vec![last]);
    }
}
