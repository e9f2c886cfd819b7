//! The truth check of synthetic workspaces (issue 25): each training photo rendered from
//! the fit under the **true** light it was taken in (`truth/manifest.json`: the map, the
//! exposure and the white balance), against the photo.
//!
//! A per-photo free light map can absorb wrong reflectance: the fit then reproduces its
//! training photos under its *fitted* maps, yet not under the true ones. Both figures are
//! reported, with the same renderer ([`super::evaluate`]'s held-out renderer) on the same
//! pixels (object pixels not overexposed), after the best per-channel scale
//! `s_c = Σ y_c ŷ_c / Σ ŷ_c²` (a per-channel global scale can never be recovered from
//! photos): `RMSE = √(Σ_c Σ_pixels (y_c − s_c ŷ_c)² / 3n)`, and relative to the photo's RMS
//! on those pixels. Protocol `truth` of the held-out photos is the same check on photos
//! the fit never saw.

use super::evaluate::{fitted_env, shade_view, valid_mask};
use super::{Fitted, Truth};
use crate::report::metrics::{rmse_after_channel_scale, TruthCheckEntry};
use crate::Result;

/// The truth check of every training photo the manifest lists.
pub(crate) fn truth_check(f: &Fitted, truth: &Truth) -> Result<Vec<TruthCheckEntry>> {
    let mut out = Vec::new();
    for (k, &v) in f.train.iter().enumerate() {
        let view = &f.scene.views[v];
        let name = view.image.name.as_str();
        let Some(true_env) = truth.light(name, f.opts.global_resolution, &f.env_from_world)? else {
            continue;
        };
        let fitted = fitted_env(f, k);
        let raster = crate::render::rasterize(&f.scene.mesh, &view.camera, &view.image);
        let rgbs = shade_view(f, v, &raster, &[&true_env, &fitted])?;
        let photo = &f.photos[v];
        let mask = valid_mask(&raster, photo);
        let (rmse_t, rms, scale_t) = rmse_after_channel_scale(&photo.rgb, &rgbs[0], &mask);
        let (rmse_f, _, _) = rmse_after_channel_scale(&photo.rgb, &rgbs[1], &mask);
        let rel = |r: f64| if rms > 0.0 { r / rms } else { f64::NAN };
        out.push(TruthCheckEntry {
            image: name.to_string(),
            rmse_true_light: rmse_t,
            relative_true_light: rel(rmse_t),
            scale_true_light: scale_t,
            rmse_fitted_light: rmse_f,
            relative_fitted_light: rel(rmse_f),
            pixels: mask.iter().filter(|&&m| m).count(),
        });
    }
    Ok(out)
}
