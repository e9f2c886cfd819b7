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

use super::shading::{fitted_env, valid_mask};
use super::{Fitted, Truth};
use crate::render::{Raster, ShadedViews, ViewToShade};
use crate::report::metrics::{
    rmse_after_channel_scale, upper_median, AlbedoTruth, AlbedoTruthEntry, TruthCheckEntry,
    PURE_OFF, PURE_WEIGHT,
};
use crate::sphere::envmap::OctEnv;
use crate::transport::brdf::BasisBrdf;
use crate::{Error, Result};
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

/// The truth's materials: per-vertex blending weights (row-major `V × J`), names and
/// lobe weights (`truth/weights.ply`, `truth/materials.json`), read once per run for the
/// truth check's floor and the albedo against the truth.
pub(crate) struct TrueMaterials {
    names: Vec<String>,
    /// Index of the Lambertian lobe in `lobes`.
    lambert: usize,
    weights: Vec<f64>,
    /// Every lobe of the truth (`None`: a type this build does not know).
    lobes: Vec<Option<BasisBrdf>>,
    /// `lambda[j][b]`: material `j`'s weight of lobe `b` per channel.
    lambda: Vec<Vec<[f64; 3]>>,
}

impl TrueMaterials {
    /// `None` when the truth has no materials file, no Lambertian lobe or no weights.
    pub(crate) fn read(truth: &Truth) -> Result<Option<Self>> {
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
        let materials = json["materials"]
            .as_array()
            .ok_or_else(|| bad("no `materials` list"))?;
        let TrueLambda { names, lambda } = read_lambda(&path, materials, lobes.len())?;
        let Some(weights) = read_weights(&truth.dir.join("weights.ply"), names.len())? else {
            return Ok(None);
        };
        Ok(Some(TrueMaterials {
            names,
            lambert: lt,
            weights,
            lobes: lobes.iter().map(lobe_of).collect(),
            lambda,
        }))
    }

    /// The lobes some material of the truth uses, in the truth's order: the basis its
    /// reflectance is rendered in for the floor ([`add_true_reflectance`]). `None` when one
    /// of them is of a type this build does not know.
    fn used_lobes(&self) -> Option<Vec<BasisBrdf>> {
        (0..self.lobes.len())
            .filter(|&b| self.lambda.iter().any(|m| m[b].iter().any(|&v| v != 0.0)))
            .map(|b| self.lobes[b])
            .collect()
    }

    /// Material `j`'s diffuse (Lambertian) albedo.
    fn diffuse(&self, j: usize) -> [f64; 3] {
        self.lambda[j][self.lambert]
    }

    /// The true per-vertex weights `β_{x,b,c} = Σ_j w_j(x) λ_{j,b',c}` in the lobes of
    /// `basis` (row-major `V × B`), each truth lobe `b'` carried by the basis lobe equal to
    /// it; `None` when a truth lobe that any material uses is not in `basis` (or of a type
    /// this build does not know), or the weights are not `nv` rows.
    fn beta_in_basis(&self, basis: &[BasisBrdf], nv: usize) -> Option<Vec<[f64; 3]>> {
        let (jj, nb) = (self.names.len(), basis.len());
        if jj == 0 || self.weights.len() != nv * jj {
            return None;
        }
        let mut to_basis = Vec::with_capacity(self.lobes.len());
        for (bt, lobe) in self.lobes.iter().enumerate() {
            let used = self.lambda.iter().any(|m| m[bt].iter().any(|&v| v != 0.0));
            let at = lobe.and_then(|l| basis.iter().position(|b| same_lobe(b, &l)));
            match (at, used) {
                (None, true) => return None,
                (at, _) => to_basis.push(at),
            }
        }
        let mut beta = vec![[0.0; 3]; nv * nb];
        for x in 0..nv {
            for (j, rows) in self.lambda.iter().enumerate() {
                let w = self.weights[x * jj + j];
                for (bt, at) in to_basis.iter().enumerate() {
                    if let Some(b) = at {
                        for c in 0..3 {
                            beta[x * nb + b][c] += w * rows[bt][c];
                        }
                    }
                }
            }
        }
        Some(beta)
    }
}

/// The truth's materials as `materials.json` lists them ([`read_lambda`]).
#[derive(Debug)]
struct TrueLambda {
    names: Vec<String>,
    /// Per material, per lobe, RGB.
    lambda: Vec<Vec<[f64; 3]>>,
}

/// Each material's name and per-lobe colour weights `λ` from the truth's
/// `materials.json` (`path`, for errors): `n_lobes` triples of numbers per material.
fn read_lambda(
    path: &std::path::Path,
    materials: &[serde_json::Value],
    n_lobes: usize,
) -> Result<TrueLambda> {
    let mut names = Vec::new();
    let mut lambda = Vec::new();
    for m in materials {
        let name = m["name"].as_str().unwrap_or("?").to_string();
        let mut rows = Vec::with_capacity(n_lobes);
        for b in 0..n_lobes {
            let d = &m["lambda"][b];
            let rgb = [0, 1, 2].map(|c| d[c].as_f64());
            if rgb.iter().any(Option::is_none) {
                return Err(Error::format(
                    path,
                    "materials",
                    format!("material `{name}`: the weight of lobe {b} is not three numbers"),
                ));
            }
            rows.push(rgb.map(|v| v.unwrap_or(0.0)));
        }
        names.push(name);
        lambda.push(rows);
    }
    Ok(TrueLambda { names, lambda })
}

/// The truth's blending weights from `weights.ply` (`w0 … w{j−1}` per vertex, vertex-major);
/// `None` when the file is absent.
fn read_weights(path: &std::path::Path, j: usize) -> Result<Option<Vec<f64>>> {
    let Ok(file) = std::fs::File::open(path) else {
        return Ok(None);
    };
    let ply = ply_rs::parser::Parser::<ply_rs::ply::DefaultElement>::new()
        .read_ply(&mut std::io::BufReader::new(file))
        .map_err(|_| Error::format(path, "header", "not a readable PLY file"))?;
    let verts = ply.payload.get("vertex").map_or(&[][..], |v| v.as_slice());
    let mut weights = Vec::with_capacity(verts.len() * j);
    for (x, v) in verts.iter().enumerate() {
        for m in 0..j {
            let w = match v.get(&format!("w{m}")) {
                Some(ply_rs::ply::Property::Float(w)) => *w as f64,
                Some(ply_rs::ply::Property::Double(w)) => *w,
                _ => {
                    return Err(Error::format(
                        path,
                        format!("vertex {x}"),
                        format!("no float property w{m}"),
                    ))
                }
            };
            weights.push(w);
        }
    }
    Ok(Some(weights))
}

/// A truth lobe of `materials.json` (`{"type": "lambert" | "phong", "exponent" | "ggx",
/// "alpha"}`) as a basis BRDF; `None` for another type.
fn lobe_of(l: &serde_json::Value) -> Option<BasisBrdf> {
    match l["type"].as_str()? {
        "lambert" => Some(BasisBrdf::Lambert),
        "phong" => Some(BasisBrdf::Phong {
            exponent: l["exponent"].as_f64()?,
        }),
        "ggx" => Some(BasisBrdf::Ggx {
            alpha: l["alpha"].as_f64()?,
        }),
        _ => None,
    }
}

/// Whether two lobes are the same BRDF (parameters within 1e-9 relative).
fn same_lobe(a: &BasisBrdf, b: &BasisBrdf) -> bool {
    let close = |x: f64, y: f64| (x - y).abs() <= 1e-9 * x.abs().max(y.abs());
    match (a, b) {
        (BasisBrdf::Lambert, BasisBrdf::Lambert) => true,
        (BasisBrdf::Phong { exponent: x }, BasisBrdf::Phong { exponent: y }) => close(*x, *y),
        (BasisBrdf::Ggx { alpha: x }, BasisBrdf::Ggx { alpha: y }) => close(*x, *y),
        _ => false,
    }
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

/// Diffuse albedo per material against the truth `t` (`report.json` `albedo_truth`);
/// `None` with a mesh of another vertex count or without a Lambertian lobe in the fit.
///
/// Per channel `s_c = Σ_x b_{x,c} β_{x,c} / Σ_x β_{x,c}²` over the vertices with weights in
/// both (`b`, `β` the true and recovered per-vertex diffuse albedo); each recovered
/// material `k` stands for the true material most vertices it dominates are dominated by;
/// its ratio error is `s_c λ_{k,lb,c} / λ^true_{j,lambert,c} − 1`; its pure-vertex error is
/// the mean of `s_c β_{x,c}` over the vertices it dominates whose true weight of `j` is at
/// least [`PURE_WEIGHT`], over `λ^true_{j,lambert,c}`, − 1; beside it their median ([`PureFigures`]).
pub(crate) fn albedo_truth(f: &Fitted, t: &TrueMaterials) -> Option<AlbedoTruth> {
    let nv = f.scene.mesh.positions.len();
    let (kk, jj) = (f.est.lambda.len(), t.names.len());
    let lb = f
        .basis
        .iter()
        .position(|b| matches!(b, BasisBrdf::Lambert))?;
    if jj == 0 || t.weights.len() != nv * jj || f.est.weights.len() != nv * kk {
        return None;
    }
    let dom = Dominant {
        fit: dominant(&f.est.weights, kk),
        truth: dominant(&t.weights, jj),
    };
    let (scale, vertices) = diffuse_scale(f, t, &dom, lb);
    let materials: Vec<AlbedoTruthEntry> = (0..kk)
        .filter_map(|k| material_albedo(f, t, &dom, lb, scale, k))
        .collect();
    Some(AlbedoTruth {
        scale,
        vertices,
        max_ratio_error: max_abs(materials.iter().flat_map(|m| m.ratio_error)),
        max_pure_ratio_error: max_abs(
            materials
                .iter()
                .flat_map(|m| m.pure_ratio_error)
                .filter(|e| e.is_finite()),
        ),
        max_median_ratio_error: crate::report::metrics::max_median_ratio_error(&materials),
        materials,
    })
}

/// The largest absolute value (0 for none).
fn max_abs(values: impl Iterator<Item = f64>) -> f64 {
    values.map(f64::abs).fold(0.0, f64::max)
}

/// Each vertex's dominant material in the fit and in the truth ([`dominant`]).
struct Dominant {
    fit: Vec<Option<usize>>,
    truth: Vec<Option<usize>>,
}

impl Dominant {
    /// Whether vertex `x` has weights in both.
    fn both(&self, x: usize) -> bool {
        self.fit[x].is_some() && self.truth[x].is_some()
    }
}

/// The per-channel scale `s_c = Σ_x b_{x,c} β_{x,c} / Σ_x β_{x,c}²` over the vertices with
/// weights in both ([`albedo_truth`]), and how many vertices that is.
fn diffuse_scale(f: &Fitted, t: &TrueMaterials, dom: &Dominant, lb: usize) -> ([f64; 3], usize) {
    let (nb, jj) = (f.basis.len(), t.names.len());
    let (mut num, mut den, mut n) = ([0.0_f64; 3], [0.0_f64; 3], 0);
    for x in (0..dom.fit.len()).filter(|&x| dom.both(x)) {
        n += 1;
        let beta = f.beta[x * nb + lb];
        for c in 0..3 {
            let b: f64 = (0..jj)
                .map(|j| t.weights[x * jj + j] * t.diffuse(j)[c])
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
    (scale, n)
}

/// Recovered material `k` against the true material most of the vertices it dominates are
/// dominated by ([`albedo_truth`]); `None` when it dominates no vertex with true weights.
fn material_albedo(
    f: &Fitted,
    t: &TrueMaterials,
    dom: &Dominant,
    lb: usize,
    scale: [f64; 3],
    k: usize,
) -> Option<AlbedoTruthEntry> {
    let (nb, jj, nv) = (f.basis.len(), t.names.len(), dom.fit.len());
    let mut votes = vec![0usize; jj];
    for x in (0..nv).filter(|&x| dom.fit[x] == Some(k)) {
        if let Some(b) = dom.truth[x] {
            votes[b] += 1;
        }
    }
    let total: usize = votes.iter().sum();
    if total == 0 {
        return None;
    }
    let (j, &v) = votes.iter().enumerate().max_by_key(|e| *e.1)?;
    let recovered = f.est.lambda[k][lb];
    let recovered_scaled = [0, 1, 2].map(|c| scale[c] * recovered[c]);
    let ratio_error = [0, 1, 2].map(|c| recovered_scaled[c] / t.diffuse(j)[c] - 1.0);
    let pure: Vec<usize> = (0..nv)
        .filter(|&x| dom.fit[x] == Some(k) && t.weights[x * jj + j] >= PURE_WEIGHT)
        .collect();
    let truth = t.diffuse(j);
    let scaled: Vec<[f64; 3]> = pure
        .iter()
        .map(|&x| [0, 1, 2].map(|c| scale[c] * f.beta[x * nb + lb][c]))
        .collect();
    let figures = pure_figures(&scaled, truth);
    Some(AlbedoTruthEntry {
        material: k,
        true_material: t.names[j].clone(),
        agreement: v as f64 / total as f64,
        recovered,
        recovered_scaled,
        truth,
        ratio_error,
        pure_vertices: pure.len(),
        pure_ratio_error: figures.mean_error,
        pure_median_error: figures.median_error,
        pure_off_share: figures.off_share,
    })
}

/// One material's scaled per-vertex diffuse albedo over its pure vertices against the
/// truth ([`AlbedoTruthEntry`]'s last three fields).
#[derive(Debug, PartialEq)]
struct PureFigures {
    /// `mean_x a_{x,c} / t_c − 1`.
    mean_error: [f64; 3],
    /// `median_x a_{x,c} / t_c − 1` ([`upper_median`]).
    median_error: [f64; 3],
    /// The share of `x` with `|a_{x,c} / t_c − 1| > PURE_OFF` in some channel.
    off_share: f64,
}

/// [`PureFigures`] of the scaled albedos `a` against the true albedo `t` (NaN errors and a
/// share of 0 when `a` is empty).
fn pure_figures(a: &[[f64; 3]], t: [f64; 3]) -> PureFigures {
    let (mut mean_error, mut median_error) = ([0.0; 3], [0.0; 3]);
    for c in 0..3 {
        let values: Vec<f64> = a.iter().map(|v| v[c]).collect();
        mean_error[c] = values.iter().sum::<f64>() / a.len() as f64 / t[c] - 1.0;
        median_error[c] = upper_median(values) / t[c] - 1.0;
    }
    let off = a
        .iter()
        .filter(|v| (0..3).any(|c| (v[c] / t[c] - 1.0).abs() > PURE_OFF))
        .count();
    PureFigures {
        mean_error,
        median_error,
        off_share: if a.is_empty() {
            0.0
        } else {
            off as f64 / a.len() as f64
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Five vertices of a material whose true albedo is (0.5, 0.2, 0.1): the mean, the
    /// median and the share off by more than 10%, counted by hand.
    #[test]
    fn pure_figures_read_the_mean_the_median_and_the_share_off() {
        let t = [0.5, 0.2, 0.1];
        let a = [
            [0.50, 0.20, 0.10], // exact
            [0.52, 0.20, 0.10], // +4% in red: within 10%
            [0.50, 0.19, 0.10], // −5% in green
            [0.50, 0.20, 0.15], // +50% in blue: off
            [0.40, 0.20, 0.10], // −20% in red: off
        ];
        let f = pure_figures(&a, t);
        let close = |x: f64, y: f64| (x - y).abs() < 1e-12;
        // Means 2.42 / 5, 0.99 / 5, 0.55 / 5; medians 0.50, 0.20, 0.10.
        for (c, mean) in [2.42 / 5.0, 0.99 / 5.0, 0.55 / 5.0].iter().enumerate() {
            assert!(close(f.mean_error[c], mean / t[c] - 1.0), "{f:?}");
            assert!(close(f.median_error[c], 0.0), "{f:?}");
        }
        assert!(close(f.off_share, 2.0 / 5.0), "{f:?}");
        // An even count takes the upper of the two middle values.
        let even = pure_figures(&[[0.4, 0.2, 0.1], [0.6, 0.2, 0.1]], t);
        assert!(close(even.median_error[0], 0.6 / 0.5 - 1.0), "{even:?}");
        let none = pure_figures(&[], t);
        assert!(none.mean_error[0].is_nan() && none.median_error[0].is_nan());
        assert_eq!(none.off_share, 0.0);
    }

    /// The truth's `materials.json` and `weights.ply` readers: values as written, an
    /// absent weights file as "no truth to check", and bad records named by file, material
    /// or vertex.
    #[test]
    fn the_truth_readers_take_good_files_and_name_bad_records() {
        let dir =
            std::env::temp_dir().join(format!("relight-truth-readers-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let json = dir.join("materials.json");
        let good: serde_json::Value = serde_json::json!([
            {"name": "a", "lambda": [[0.1, 0.2, 0.3]]},
            {"name": "b", "lambda": [[0.4, 0.5, 0.6]]}
        ]);
        let TrueLambda { names, lambda } = read_lambda(&json, good.as_array().unwrap(), 1).unwrap();
        assert_eq!(names, ["a", "b"]);
        assert_eq!(lambda, [vec![[0.1, 0.2, 0.3]], vec![[0.4, 0.5, 0.6]]]);
        let short = serde_json::json!([{"name": "b", "lambda": [[0.4, 0.5]]}]);
        let e = read_lambda(&json, short.as_array().unwrap(), 1)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("materials.json") && e.contains("material `b`"),
            "{e}"
        );
        assert!(e.contains("lobe 0 is not three numbers"), "{e}");

        let ply = dir.join("weights.ply");
        assert!(read_weights(&ply, 2).unwrap().is_none());
        let header =
            |props: &str| format!("ply\nformat ascii 1.0\nelement vertex 2\n{props}end_header\n");
        let two = "property float w0\nproperty float w1\n";
        std::fs::write(&ply, header(two) + "0.25 0.75\n1 0\n").unwrap();
        assert_eq!(
            read_weights(&ply, 2).unwrap().unwrap(),
            [0.25, 0.75, 1.0, 0.0]
        );
        std::fs::write(&ply, header("property float w0\n") + "0.25\n1\n").unwrap();
        let e = read_weights(&ply, 2).unwrap_err().to_string();
        assert!(e.contains("weights.ply") && e.contains("vertex 0"), "{e}");
        assert!(e.contains("no float property w1"), "{e}");
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn the_true_reflectance_goes_into_the_fits_basis_lobe_by_lobe() {
        // Two materials over lobes [lambert, phong 50], two vertices (one pure, one a
        // 0.25 / 0.75 blend); β by hand: Σ_j w_j λ_{j,b}, each truth lobe at the index of
        // the equal basis lobe, whatever the basis order.
        let t = TrueMaterials {
            names: vec!["a".into(), "b".into()],
            lambert: 0,
            weights: vec![1.0, 0.0, 0.25, 0.75],
            lobes: vec![
                Some(BasisBrdf::Lambert),
                Some(BasisBrdf::Phong { exponent: 50.0 }),
            ],
            lambda: vec![
                vec![[0.8, 0.4, 0.2], [0.1, 0.1, 0.1]],
                vec![[0.2, 0.3, 0.6], [0.0, 0.0, 0.0]],
            ],
        };
        let basis = [
            BasisBrdf::Phong { exponent: 50.0 },
            BasisBrdf::Ggx { alpha: 0.3 },
            BasisBrdf::Lambert,
        ];
        let b = t.beta_in_basis(&basis, 2).unwrap();
        let want = [
            [0.1, 0.1, 0.1],
            [0.0; 3],
            [0.8, 0.4, 0.2],
            [0.025, 0.025, 0.025],
            [0.0; 3],
            [0.35, 0.325, 0.5],
        ];
        for (got, w) in b.iter().zip(&want) {
            for c in 0..3 {
                assert!((got[c] - w[c]).abs() < 1e-12, "{b:?}");
            }
        }
        // A lobe the truth uses and the basis lacks (phong 50, or phong 500 ≠ 50): none.
        assert!(t.beta_in_basis(&[BasisBrdf::Lambert], 2).is_none());
        let other = [BasisBrdf::Lambert, BasisBrdf::Phong { exponent: 500.0 }];
        assert!(t.beta_in_basis(&other, 2).is_none());
        // A lobe no material uses may be missing; so may an unknown type then.
        let mut diffuse_only = t.clone_without_gloss();
        assert!(diffuse_only
            .beta_in_basis(&[BasisBrdf::Lambert], 2)
            .is_some());
        diffuse_only.lobes[1] = None;
        assert!(diffuse_only
            .beta_in_basis(&[BasisBrdf::Lambert], 2)
            .is_some());
        // Weights of another vertex count: none.
        assert!(t.beta_in_basis(&basis, 3).is_none());
        // The floor's basis: the lobes some material uses, in the truth's order; none when
        // a used lobe is of an unknown type, whatever an unused one is.
        assert_eq!(
            t.used_lobes(),
            Some(vec![
                BasisBrdf::Lambert,
                BasisBrdf::Phong { exponent: 50.0 }
            ])
        );
        assert_eq!(diffuse_only.used_lobes(), Some(vec![BasisBrdf::Lambert]));
        let mut unknown = t.clone_without_gloss();
        unknown.lobes[0] = None;
        assert_eq!(unknown.used_lobes(), None);
    }

    impl TrueMaterials {
        fn clone_without_gloss(&self) -> TrueMaterials {
            TrueMaterials {
                names: self.names.clone(),
                lambert: self.lambert,
                weights: self.weights.clone(),
                lobes: self.lobes.clone(),
                lambda: self.lambda.iter().map(|m| vec![m[0], [0.0; 3]]).collect(),
            }
        }
    }

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
