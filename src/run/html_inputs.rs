//! The pictures `report.html` shows beside `report.json`'s figures, written into
//! `report_files/`: per training photo a thumbnail (240 px wide, box-filtered) and its
//! recovered lat-long map; for synthetic workspaces the true map re-expressed in the fit's
//! environment frame (`L_fit(d) = L_true(T Fᵀ d)`, `F`, `T` the fit's and the truth's
//! `env_from_world`, bilinear lookup); and the material swatches. One exposure is shared by
//! all recovered maps and one by all true maps ([`html::shared_exposure`]).

use super::evaluate::{fitted_env, Truth};
use super::Fitted;
use crate::brdf::BasisBrdf;
use crate::envmap::LatLong;
use crate::report::html::{self, HtmlInputs, Swatch, TrainingRow};
use crate::{Error, Result};
use std::path::Path;

/// Height of the maps shown (width twice that).
const MAP_HEIGHT: usize = 64;
/// Width of the photo thumbnails.
const THUMB_WIDTH: u32 = 240;

/// The true map of `name` in the fit's frame, when the truth has one.
fn true_map(f: &Fitted, truth: &Truth, name: &str) -> Option<LatLong> {
    let p = truth.photos.get(name)?;
    let path = if p.env.is_absolute() {
        p.env.clone()
    } else {
        truth.dir.join(&p.env)
    };
    let src = LatLong::read_exr(&path).ok()?.0;
    let m = truth.env_from_world * f.env_from_world.transpose();
    let mut out = LatLong::black(MAP_HEIGHT);
    for v in 0..out.height {
        for u in 0..out.width {
            out.rgb[v * out.width + u] = src.lookup(&(m * out.dir(u, v)));
        }
    }
    Some(out)
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
        truths.push(truth.and_then(|t| true_map(f, t, name)));
    }
    let fit_refs: Vec<&LatLong> = fitted.iter().collect();
    let fitted_exposure = html::shared_exposure(&fit_refs);
    let true_refs: Vec<&LatLong> = truths.iter().flatten().collect();
    let true_exposure = (!true_refs.is_empty()).then(|| html::shared_exposure(&true_refs));
    let mut training = Vec::new();
    for (k, &v) in f.train.iter().enumerate() {
        let name = f.scene.views[v].image.name.clone();
        let stem = crate::relight::file_stem(&name);
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
        materials: swatches(&f.est.lambda, &f.basis),
    })
}
