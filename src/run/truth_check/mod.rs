//! The truth check of synthetic workspaces (issue 25): training photos rendered from the
//! fit under the **true** light they were taken in (`truth/manifest.json`: the map, the
//! exposure and the white balance), against the photos. Every training photo while their
//! pixels fit in [`TRUTH_CHECK_PIXELS`] (five megapixel photos), else as many as fit,
//! spread evenly over the training list ([`checked_positions`]): each is shaded at every
//! vertex it sees like a held-out photo, which at 10 training photos of 1 MP was two
//! thirds of the evaluation's shading; five of them estimate the mean relative error to
//! within a few tenths of a point at 30K and 100K vertices
//! (`bench-results/speed-evaluation-4.md`).
//!
//! A per-photo free light map can absorb wrong reflectance: the fit then reproduces its
//! training photos under its *fitted* maps, yet not under the true ones. Both figures are
//! reported, with the same renderer ([`super::shading::shade_views`], the held-out
//! photos' renderer) on the same pixels (object pixels off its edges, not overexposed), after the best
//! per-channel scale
//! `s_c = Σ y_c ŷ_c / Σ ŷ_c²` (a per-channel global scale can never be recovered from
//! photos): `RMSE = √(Σ_c Σ_pixels (y_c − s_c ŷ_c)² / 3n)`, and relative to the photo's RMS
//! on those pixels. Protocol `truth` of the held-out photos is the same check on photos
//! the fit never saw.
//!
//! Beside it, the diffuse albedo per material against the truth ([`albedo_truth`]), after
//! the per-channel scale that best maps the recovered per-vertex diffuse albedo onto the
//! true one (the anchor's scale is arbitrary; ratios between materials are not).
//!
//! - [`true_materials`]: the truth's materials read from `truth/materials.json` and
//!   `truth/weights.ply`, and its reflectance in a basis (the floor's);
//! - [`albedo`]: the diffuse albedo per material against the truth.

mod albedo;
mod true_materials;

pub(crate) use albedo::albedo_truth;
pub(crate) use true_materials::TrueMaterials;

use super::shading::{fitted_env, valid_mask};
use super::{Fitted, Truth};
use crate::render::{Raster, ShadedViews, ViewToShade};
use crate::report::metrics::{rmse_after_channel_scale, TruthCheckEntry};
use crate::sphere::envmap::OctEnv;
use crate::Result;
use rayon::prelude::*;

/// A training photo the truth check renders: its view, its two lights (the true one, then
/// the fitted one), its raster and the pixels scored there ([`valid_mask`]).
pub(crate) struct CheckedView {
    v: usize,
    envs: [OctEnv; 2],
    raster: Raster,
    mask: Vec<bool>,
}

impl CheckedView {
    /// The view as [`crate::render::shade_views`] takes it.
    pub(crate) fn to_shade<'a>(&'a self, f: &'a Fitted) -> ViewToShade<'a> {
        ViewToShade {
            raster: &self.raster,
            image: &f.scene.views[self.v].image,
            envs: self.envs.iter().collect(),
        }
    }
}

/// The truth check's budget in photo pixels: five photos of 1024² ([`checked_positions`]).
pub(crate) const TRUTH_CHECK_PIXELS: u64 = 5 * 1024 * 1024;

/// The positions in a training list whose photos have `pixels` pixels each that the truth
/// check renders: all of them when their sum fits in [`TRUTH_CHECK_PIXELS`], else the `k`
/// photos the budget buys at their mean size (`k = ⌊budget · m / Σ pixels⌋`, at least
/// one) spread evenly over the list (`⌊i m / k⌋`, from the first). Each checked photo's
/// figures are those of the check of every photo; the mean is over fewer photos (module
/// docs).
pub(crate) fn checked_positions(pixels: &[u64]) -> Vec<usize> {
    let m = pixels.len();
    let total: u64 = pixels.iter().sum();
    let k = if total <= TRUTH_CHECK_PIXELS {
        m
    } else {
        ((TRUTH_CHECK_PIXELS as u128 * m as u128 / total as u128) as usize).clamp(1, m)
    };
    (0..k).map(|i| i * m / k).collect()
}

/// The training photos at [`checked_positions`] the manifest gives a light for, with their
/// lights and rasters. They are shaded in the held-out renders' vertex-major pass
/// ([`super::evaluate`]: a vertex seen in several photos is rotated into its frame once
/// for all their lights), then scored by [`score`].
pub(crate) fn checked_views(f: &Fitted, truth: &Truth) -> Result<Vec<CheckedView>> {
    let pixels: Vec<u64> = f
        .train
        .iter()
        .map(|&v| u64::from(f.photos[v].width) * u64::from(f.photos[v].height))
        .collect();
    // Each photo's true map (resampled from its lat-long file) and raster on a thread of
    // its own; kept in the photos' order.
    let checked: Vec<Option<CheckedView>> = checked_positions(&pixels)
        .into_par_iter()
        .map(|k| {
            let v = f.train[k];
            let view = &f.scene.views[v];
            let name = view.image.name.as_str();
            let Some(true_env) = truth.light(name, f.opts.global_resolution, &f.env_from_world)?
            else {
                return Ok(None);
            };
            let raster =
                crate::observe::raster::rasterize(&f.scene.mesh, &view.camera, &view.image);
            let mask = valid_mask(&raster, &f.photos[v]);
            Ok(Some(CheckedView {
                v,
                envs: [true_env, fitted_env(f, k)],
                raster,
                mask,
            }))
        })
        .collect::<Result<_>>()?;
    Ok(checked.into_iter().flatten().collect())
}

/// The truth check of the `checked` photos, shaded as views `first..` of `shaded`: each
/// photo's two images interpolated and scored in turn.
pub(crate) fn score(
    f: &Fitted,
    checked: &[CheckedView],
    shaded: &ShadedViews,
    first: usize,
) -> Vec<TruthCheckEntry> {
    let mut out = Vec::with_capacity(checked.len());
    for (i, c) in checked.iter().enumerate() {
        let rgbs = shaded.images(first + i, &c.raster, &f.scene.mesh);
        let photo = &f.photos[c.v];
        let mask = &c.mask;
        let (rmse_t, rms, scale_t) = rmse_after_channel_scale(&photo.rgb, &rgbs[0], mask);
        let (rmse_f, _, _) = rmse_after_channel_scale(&photo.rgb, &rgbs[1], mask);
        let rel = |r: f64| relative(r, rms);
        out.push(TruthCheckEntry {
            image: f.scene.views[c.v].image.name.clone(),
            rmse_true_light: rmse_t,
            relative_true_light: rel(rmse_t),
            scale_true_light: scale_t,
            rmse_fitted_light: rmse_f,
            relative_fitted_light: rel(rmse_f),
            rmse_true_reflectance: None,
            relative_true_reflectance: None,
            pixels: mask.iter().filter(|&&m| m).count(),
        });
    }
    out
}

/// The truth check's floor: the TRUE reflectance, in the truth's own lobes
/// ([`TrueMaterials::used_lobes`], [`TrueMaterials::beta_in_basis`]), shaded by the fit's
/// renderer (its mesh, visibility and rotation) under each checked photo's true light and
/// scored the same way, into each entry's `*_true_reflectance`. A lobe the fit's basis
/// lacks (the example's GGX) is rendered all the same: the floor is what the photos allow
/// this renderer, whatever model the fit chose. Nothing when the truth uses a lobe of a type
/// this build does not know.
pub(crate) fn add_true_reflectance(
    f: &Fitted,
    t: &TrueMaterials,
    checked: &[CheckedView],
    entries: &mut [TruthCheckEntry],
) -> Result<()> {
    let Some(basis) = t.used_lobes() else {
        return Ok(());
    };
    let Some(beta) = t.beta_in_basis(&basis, f.scene.mesh.positions.len()) else {
        return Ok(());
    };
    // Each view with its true light alone.
    let views: Vec<ViewToShade> = checked
        .iter()
        .map(|c| {
            let mut v = c.to_shade(f);
            v.envs.truncate(1);
            v
        })
        .collect();
    let shaded = super::shading::shade_views_with(f, &basis, &beta, &views)?;
    for (i, (c, e)) in checked.iter().zip(entries.iter_mut()).enumerate() {
        let rgbs = shaded.images(i, &c.raster, &f.scene.mesh);
        let (rmse, rms, _) = rmse_after_channel_scale(&f.photos[c.v].rgb, &rgbs[0], &c.mask);
        e.rmse_true_reflectance = Some(rmse);
        e.relative_true_reflectance = Some(relative(rmse, rms));
    }
    Ok(())
}

/// An RMSE over the photo's RMS on the same pixels (NaN on black pixels).
fn relative(rmse: f64, rms: f64) -> f64 {
    if rms > 0.0 {
        rmse / rms
    } else {
        f64::NAN
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn checked_positions_keep_small_lists_and_spread_large_ones() {
        const MP: u64 = 1024 * 1024;
        // Within the budget: every photo, in order (the built-in example's six 192² photos).
        assert_eq!(checked_positions(&[]), Vec::<usize>::new());
        assert_eq!(checked_positions(&[192 * 192; 6]), vec![0, 1, 2, 3, 4, 5]);
        assert_eq!(checked_positions(&[MP; 5]), vec![0, 1, 2, 3, 4]);
        // 10 photos of 1 MP: the budget buys five, every second one.
        assert_eq!(checked_positions(&[MP; 10]), vec![0, 2, 4, 6, 8]);
        // One photo larger than the budget is still checked.
        assert_eq!(checked_positions(&[8 * MP]), vec![0]);
        // Any longer list of 1 MP photos: five, strictly increasing, inside the list, no
        // gap wider than ⌈m / 5⌉ (evenly spread).
        for m in 6..200 {
            let p = checked_positions(&vec![MP; m]);
            assert_eq!(p.len(), 5);
            assert!(p
                .windows(2)
                .all(|w| w[0] < w[1] && w[1] - w[0] <= m.div_ceil(5)));
            assert!(p[0] == 0 && p[4] < m);
        }
    }
}
