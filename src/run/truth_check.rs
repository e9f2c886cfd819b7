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
//! photos' renderer) on the same pixels (object pixels not overexposed), after the best
//! per-channel scale
//! `s_c = Σ y_c ŷ_c / Σ ŷ_c²` (a per-channel global scale can never be recovered from
//! photos): `RMSE = √(Σ_c Σ_pixels (y_c − s_c ŷ_c)² / 3n)`, and relative to the photo's RMS
//! on those pixels. Protocol `truth` of the held-out photos is the same check on photos
//! the fit never saw.
//!
//! Beside it, the diffuse albedo per material against the truth ([`albedo_truth`]), after
//! the per-channel scale that best maps the recovered per-vertex diffuse albedo onto the
//! true one (the anchor's scale is arbitrary; ratios between materials are not).

use super::shading::{fitted_env, valid_mask};
use super::{Fitted, Truth};
use crate::render::{Raster, ShadedViews, ViewToShade};
use crate::report::metrics::{
    rmse_after_channel_scale, AlbedoTruth, AlbedoTruthEntry, TruthCheckEntry, PURE_WEIGHT,
};
use crate::sphere::envmap::OctEnv;
use crate::transport::brdf::BasisBrdf;
use crate::{Error, Result};
use rayon::prelude::*;

/// A training photo the truth check renders: its view, its two lights (the true one, then
/// the fitted one) and its raster.
pub(crate) struct CheckedView {
    v: usize,
    envs: [OctEnv; 2],
    raster: Raster,
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
            Ok(Some(CheckedView {
                v,
                envs: [true_env, fitted_env(f, k)],
                raster,
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
        let mask = valid_mask(&c.raster, photo);
        let (rmse_t, rms, scale_t) = rmse_after_channel_scale(&photo.rgb, &rgbs[0], &mask);
        let (rmse_f, _, _) = rmse_after_channel_scale(&photo.rgb, &rgbs[1], &mask);
        let rel = |r: f64| if rms > 0.0 { r / rms } else { f64::NAN };
        out.push(TruthCheckEntry {
            image: f.scene.views[c.v].image.name.clone(),
            rmse_true_light: rmse_t,
            relative_true_light: rel(rmse_t),
            scale_true_light: scale_t,
            rmse_fitted_light: rmse_f,
            relative_fitted_light: rel(rmse_f),
            pixels: mask.iter().filter(|&&m| m).count(),
        });
    }
    out
}

/// The truth's materials: per-vertex blending weights (row-major `V × J`), names and
/// diffuse albedos (`truth/weights.ply`, `truth/materials.json`).
struct TrueMaterials {
    names: Vec<String>,
    diffuse: Vec<[f64; 3]>,
    weights: Vec<f64>,
}

impl TrueMaterials {
    /// `None` when the truth has no materials file, no Lambertian lobe or no weights.
    fn read(truth: &Truth) -> Result<Option<Self>> {
        let path = truth.dir.join("materials.json");
        let Ok(text) = std::fs::read_to_string(&path) else {
            return Ok(None);
        };
        let bad = |m: &str| Error::format(&path, "materials", m.to_string());
        let json: serde_json::Value = serde_json::from_str(&text)
            .map_err(|e| Error::format(&path, format!("line {}", e.line()), e.to_string()))?;
        let lobes = json["lobes"]
            .as_array()
            .ok_or_else(|| bad("no `lobes` list"))?;
        let Some(lt) = lobes.iter().position(|l| l["type"] == "lambert") else {
            return Ok(None);
        };
        let mut names = Vec::new();
        let mut diffuse = Vec::new();
        for m in json["materials"]
            .as_array()
            .ok_or_else(|| bad("no `materials` list"))?
        {
            names.push(m["name"].as_str().unwrap_or("?").to_string());
            let d = &m["lambda"][lt];
            let rgb = [0, 1, 2].map(|c| d[c].as_f64());
            if rgb.iter().any(Option::is_none) {
                return Err(bad("a material's lambert weight is not three numbers"));
            }
            diffuse.push(rgb.map(|v| v.unwrap_or(0.0)));
        }
        let wpath = truth.dir.join("weights.ply");
        let Ok(file) = std::fs::File::open(&wpath) else {
            return Ok(None);
        };
        let ply = ply_rs::parser::Parser::<ply_rs::ply::DefaultElement>::new()
            .read_ply(&mut std::io::BufReader::new(file))
            .map_err(|_| Error::format(&wpath, "header", "not a readable PLY file"))?;
        let verts = ply.payload.get("vertex").map_or(&[][..], |v| v.as_slice());
        let j = names.len();
        let mut weights = Vec::with_capacity(verts.len() * j);
        for (x, v) in verts.iter().enumerate() {
            for m in 0..j {
                let w = match v.get(&format!("w{m}")) {
                    Some(ply_rs::ply::Property::Float(w)) => *w as f64,
                    Some(ply_rs::ply::Property::Double(w)) => *w,
                    _ => {
                        return Err(Error::format(
                            &wpath,
                            format!("vertex {x}"),
                            format!("no float property w{m}"),
                        ))
                    }
                };
                weights.push(w);
            }
        }
        Ok(Some(TrueMaterials {
            names,
            diffuse,
            weights,
        }))
    }
}

/// The dominant material of each vertex with any weight (`None` elsewhere).
fn dominant(weights: &[f64], k: usize) -> Vec<Option<usize>> {
    weights
        .chunks(k.max(1))
        .map(|w| {
            let (i, &m) = w.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1))?;
            (m > 0.0).then_some(i)
        })
        .collect()
}

/// Diffuse albedo per material against the truth (`report.json` `albedo_truth`); `None`
/// without true materials, with a mesh of another vertex count, or without a Lambertian
/// lobe in the fit.
///
/// Per channel `s_c = Σ_x b_{x,c} β_{x,c} / Σ_x β_{x,c}²` over the vertices with weights in
/// both (`b`, `β` the true and recovered per-vertex diffuse albedo); each recovered
/// material `k` stands for the true material most vertices it dominates are dominated by;
/// its ratio error is `s_c λ_{k,lb,c} / λ^true_{j,lambert,c} − 1`; its pure-vertex error is
/// the mean of `s_c β_{x,c}` over the vertices it dominates whose true weight of `j` is at
/// least [`PURE_WEIGHT`], over `λ^true_{j,lambert,c}`, − 1.
pub(crate) fn albedo_truth(f: &Fitted, truth: &Truth) -> Result<Option<AlbedoTruth>> {
    let Some(t) = TrueMaterials::read(truth)? else {
        return Ok(None);
    };
    let nv = f.scene.mesh.positions.len();
    let (kk, jj, nb) = (f.est.lambda.len(), t.names.len(), f.basis.len());
    let Some(lb) = f.basis.iter().position(|b| matches!(b, BasisBrdf::Lambert)) else {
        return Ok(None);
    };
    if jj == 0 || t.weights.len() != nv * jj || f.est.weights.len() != nv * kk {
        return Ok(None);
    }
    let (dom_fit, dom_true) = (dominant(&f.est.weights, kk), dominant(&t.weights, jj));
    let (mut num, mut den, mut n) = ([0.0_f64; 3], [0.0_f64; 3], 0);
    for x in 0..nv {
        if dom_fit[x].is_none() || dom_true[x].is_none() {
            continue;
        }
        n += 1;
        let beta = f.beta[x * nb + lb];
        for c in 0..3 {
            let b: f64 = (0..jj)
                .map(|j| t.weights[x * jj + j] * t.diffuse[j][c])
                .sum();
            num[c] += b * beta[c];
            den[c] += beta[c] * beta[c];
        }
    }
    let scale = [0, 1, 2].map(|c| {
        if den[c] > 0.0 {
            num[c] / den[c]
        } else {
            f64::NAN
        }
    });
    let mut materials = Vec::new();
    for k in 0..kk {
        let mut votes = vec![0usize; jj];
        for x in 0..nv {
            if let (Some(a), Some(b)) = (dom_fit[x], dom_true[x]) {
                if a == k {
                    votes[b] += 1;
                }
            }
        }
        let total: usize = votes.iter().sum();
        let (j, &v) = votes
            .iter()
            .enumerate()
            .max_by_key(|e| *e.1)
            .unwrap_or((0, &0));
        if total == 0 {
            continue;
        }
        let recovered = f.est.lambda[k][lb];
        let recovered_scaled = [0, 1, 2].map(|c| scale[c] * recovered[c]);
        let ratio_error = [0, 1, 2].map(|c| recovered_scaled[c] / t.diffuse[j][c] - 1.0);
        let pure: Vec<usize> = (0..nv)
            .filter(|&x| dom_fit[x] == Some(k) && t.weights[x * jj + j] >= PURE_WEIGHT)
            .collect();
        let pure_ratio_error = [0, 1, 2].map(|c| {
            let mean = pure
                .iter()
                .map(|&x| scale[c] * f.beta[x * nb + lb][c])
                .sum::<f64>()
                / pure.len() as f64;
            mean / t.diffuse[j][c] - 1.0
        });
        materials.push(AlbedoTruthEntry {
            material: k,
            true_material: t.names[j].clone(),
            agreement: v as f64 / total as f64,
            recovered,
            recovered_scaled,
            truth: t.diffuse[j],
            ratio_error,
            pure_vertices: pure.len(),
            pure_ratio_error,
        });
    }
    let max_ratio_error = materials
        .iter()
        .flat_map(|m| m.ratio_error)
        .map(f64::abs)
        .fold(0.0, f64::max);
    let max_pure_ratio_error = materials
        .iter()
        .flat_map(|m| m.pure_ratio_error)
        .filter(|e| e.is_finite())
        .map(f64::abs)
        .fold(0.0, f64::max);
    Ok(Some(AlbedoTruth {
        scale,
        vertices: n,
        materials,
        max_ratio_error,
        max_pure_ratio_error,
    }))
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
