//! The pictures `report.html` shows beside `report.json`'s figures, written into
//! `report_files/`: per training photo a thumbnail (240 px wide, box-filtered) and its
//! recovered lat-long map; for synthetic workspaces the true map re-expressed in the fit's
//! environment frame (`L_fit(d) = L_true(T Fᵀ d)`, `F`, `T` the fit's and the truth's
//! `env_from_world`, bilinear lookup) as the camera saw it (times the photo's exposure and
//! white balance); and the material swatches. One exposure is shared by all recovered maps
//! ([`html::shared_exposure`]). When every training photo has a true map, the recovered
//! maps are first multiplied by the one per-channel scale that best matches them all to
//! the true maps, `s_c = Σ_{I,px} t_c f_c / Σ_{I,px} f_c²` (photos cannot fix that scale,
//! paper Eq. 9), and recovered and true maps share the true maps' exposure: side by side,
//! their brightness and colour compare directly.

use super::shading::fitted_env;
use super::truth::Truth;
use super::Fitted;
use crate::report::html::{self, HtmlInputs, Swatch, TrainingRow};
use crate::sphere::envmap::LatLong;
use crate::transport::brdf::BasisBrdf;
use crate::{Error, Result};
use std::path::Path;

/// Height of the maps shown (width twice that).
const MAP_HEIGHT: usize = 64;
/// Width of the photo thumbnails.
const THUMB_WIDTH: u32 = 240;

/// The true map of `name` in the fit's frame as its camera saw it (map × exposure × white
/// balance), when the truth has one.
fn true_map(f: &Fitted, truth: &Truth, name: &str) -> Result<Option<LatLong>> {
    let Some(p) = truth.photos.get(name) else {
        return Ok(None);
    };
    let src = LatLong::read_exr(&p.env)?.0;
    let gain = p.white_balance.map(|w| (w * p.exposure) as f32);
    let m = truth.env_from_world * f.env_from_world.transpose();
    let mut out = LatLong::black(MAP_HEIGHT);
    for v in 0..out.height {
        for u in 0..out.width {
            let rgb = src.lookup(&(m * out.dir(u, v)));
            out.rgb[v * out.width + u] = std::array::from_fn(|c| rgb[c] * gain[c]);
        }
    }
    Ok(Some(out))
}

/// Material swatches: the diffuse colour of each material (normalised by the largest
/// diffuse value over the materials) and its lobe weights.
fn swatches(lambda: &[Vec<[f64; 3]>], basis: &[BasisBrdf]) -> Vec<Swatch> {
    let lambert = basis.iter().position(|b| matches!(b, BasisBrdf::Lambert));
    let max = lambda
        .iter()
        .filter_map(|m| lambert.and_then(|l| m.get(l)))
        .flatten()
        .copied()
        .filter(|v| v.is_finite())
        .fold(0.0f64, f64::max);
    lambda
        .iter()
        .map(|m| {
            let d = lambert.and_then(|l| m.get(l)).copied().unwrap_or([0.0; 3]);
            let srgb = d.map(|v| {
                let x = if max > 0.0 { (v / max) as f32 } else { 0.0 };
                (crate::render::srgb_encode(x) * 255.0 + 0.5) as u8
            });
            Swatch {
                srgb,
                lobes: basis
                    .iter()
                    .map(|b| b.label())
                    .zip(m.iter().copied())
                    .collect(),
            }
        })
        .collect()
}

/// Write the pictures into `dir/report_files/` and describe them for the page.
pub(crate) fn html_inputs(f: &Fitted, truth: Option<&Truth>, dir: &Path) -> Result<HtmlInputs> {
    let files = dir.join("report_files");
    std::fs::create_dir_all(&files).map_err(|e| Error::io(&files, e))?;
    let mut fitted = Vec::new();
    let mut truths = Vec::new();
    for (k, &v) in f.train.iter().enumerate() {
        let name = &f.scene.views[v].image.name;
        fitted.push(fitted_env(f, k).to_latlong(MAP_HEIGHT));
        truths.push(match truth {
            Some(t) => true_map(f, t, name)?,
            None => None,
        });
    }
    let map_scale = truths
        .iter()
        .all(Option::is_some)
        .then(|| best_channel_scale(&fitted, &truths))
        .flatten();
    if let Some(s) = map_scale {
        for m in fitted.iter_mut() {
            m.rgb
                .iter_mut()
                .for_each(|p| (0..3).for_each(|c| p[c] *= s[c]));
        }
    }
    let true_refs: Vec<&LatLong> = truths.iter().flatten().collect();
    let true_exposure = (!true_refs.is_empty()).then(|| html::shared_exposure(&true_refs));
    let fit_refs: Vec<&LatLong> = fitted.iter().collect();
    let fitted_exposure = match (map_scale, true_exposure) {
        (Some(_), Some(e)) => e,
        _ => html::shared_exposure(&fit_refs),
    };
    let mut training = Vec::new();
    for (k, &v) in f.train.iter().enumerate() {
        let name = f.scene.views[v].image.name.clone();
        let stem = crate::render::views::file_stem(&name);
        let photo = &f.photos[v];
        let thumbnail = format!("report_files/{stem}.photo.png");
        html::write_thumbnail(
            &dir.join(&thumbnail),
            (photo.width, photo.height),
            &photo.rgb,
            THUMB_WIDTH,
        )?;
        let fitted_map = format!("report_files/{stem}.map.png");
        html::write_map_png(&dir.join(&fitted_map), &fitted[k], fitted_exposure)?;
        let true_map = match (&truths[k], true_exposure) {
            (Some(t), Some(e)) => {
                let rel = format!("report_files/{stem}.true_map.png");
                html::write_map_png(&dir.join(&rel), t, e)?;
                Some(rel)
            }
            _ => None,
        };
        training.push(TrainingRow {
            image: name,
            thumbnail,
            fitted_map,
            true_map,
        });
    }
    Ok(HtmlInputs {
        training,
        fitted_exposure,
        true_exposure,
        map_scale,
        materials: swatches(&f.est.lambda, &f.basis),
    })
}

/// `s_c = Σ t_c f_c / Σ f_c²` over every pixel of every pair (module docs); `None` when a
/// channel of the recovered maps is all zero or a sum is not finite.
fn best_channel_scale(fitted: &[LatLong], truths: &[Option<LatLong>]) -> Option<[f32; 3]> {
    let (mut num, mut den) = ([0.0_f64; 3], [0.0_f64; 3]);
    for (f, t) in fitted.iter().zip(truths) {
        let t = t.as_ref()?;
        for (a, b) in f.rgb.iter().zip(&t.rgb) {
            for c in 0..3 {
                num[c] += a[c] as f64 * b[c] as f64;
                den[c] += a[c] as f64 * a[c] as f64;
            }
        }
    }
    let s = [0, 1, 2].map(|c| num[c] / den[c]);
    s.iter()
        .all(|v| v.is_finite() && *v > 0.0)
        .then(|| s.map(|v| v as f32))
}
