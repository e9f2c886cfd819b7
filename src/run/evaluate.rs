//! Held-out evaluation (docs/method.md, "Held-out evaluation") and view rendering with the fitted model.
//!
//! A held-out photo was not used to fit the reflectance; its light is unknown, so each
//! protocol that applies is reported:
//! - (a) `truth`: the workspace's `truth/` gives the photo's map (and the exposure and white
//!   balance it was taken with), resampled into this run's environment frame;
//! - (b) `half`: the light fitted with the reflectance frozen to observations on the left
//!   half of the object's pixels (`x` below the middle of the object's bounding box),
//!   the error measured on the right half only;
//! - (c) `mean`: the mean of the training maps;
//! - `baseline`, beside (b) on its photos and pixels: no model, the per-vertex median of
//!   the training photos' colours times a per-channel gain fitted on (b)'s left half
//!   ([`super::baseline`]); `headline` = (b)'s error over the baseline's.
//!
//! Every protocol's prediction also gets the literature metrics (PSNR-H, PSNR-L, SSIM,
//! [`crate::report::metrics`]) on the same pixels.
//!
//! Each view is rendered by rasterising the mesh (z-buffer) and interpolating per-vertex
//! radiance from the wavelet renderer (Eq. 5–8, untruncated) across triangles; RMSE is over
//! object pixels that are not overexposed in the photo.
//! The held-out photos and the truth check's training photos ([`super::truth_check`]) are
//! shaded in one vertex-major pass ([`render::shade_views`]): a vertex's footprint is walked
//! once for the lights of every photo that shows it, reading all lights' texels interleaved
//! ([`crate::sphere::rotation::SplatRotation::resample_interleaved`]); every image is bit
//! for bit the one a pass of its photo alone gives.
//!
//! The renderer has its own local resolution (`--render-local-resolution`, by default the
//! estimator's: 32² at the defaults) and its own rotation
//! ([`crate::sphere::rotation::SplatRotation`]: the footprint of the vertex's exact normal instead
//! of the blend of four precomputed frames, Eq. 6). Visibility is traced once, at the finer
//! of the two resolutions ([`trace_visibility`]), and averaged down for the other.
//! Measured (`bench-results/agreement.md`, sphere over a plane under 8 real maps, a KNOWN
//! model): a 64² renderer draws a Phong-50 lobe closer to the Eq. 1 reference than a 32²
//! one (3.95% against 7.17% mean), diffuse 0.93% against 1.56%. For a FITTED model the
//! finer renderer buys nothing measurable: the Minerva model (6 materials, 7 lobes) on
//! `spot-varying` with 13 photos of 1 MP gave held-out RMSE (true light, after scale)
//! 0.0767 / 0.0765 at 2,930 vertices and 0.0766 / 0.0767 at 11,714 (64² / 32²), while 32²
//! halves the visibility trace (16.3 → 8.0 CPU s at 11,714) and the evaluation (48.2 →
//! 23.8 CPU s): the fit's own 32² transport, not the renderer, bounds what it can show. So
//! the default renders at the fit's resolution; `--render-local-resolution 64` is for
//! relighting a known or very sharp model under novel light.

pub(crate) use super::half_fit::{projected_x, span_mid, HALF_FIT_CG, HALF_FIT_GPCG};
use super::truth::Truth;
use super::Fitted;
use crate::import::photo::Photo;
use crate::observe::{self, Observations, ObserveOptions};
use crate::render::{self, Raster};
use crate::report::metrics::{image_metrics, MetricsEntry};
use crate::report::{compare, psnr, HoldoutEntry};
use crate::solve;
use crate::sphere::envmap::OctEnv;
use crate::transport::visibility::Visibility;
use crate::transport::{self, TransportOptions};
use crate::{Error, Result, Vec3};
use nalgebra::Matrix3;
use rayon::prelude::*;
use std::path::Path;
use std::sync::Arc;

/// Held-out error as the estimator goes (the `timeline`'s `holdout_rmse`): the held-out
/// photos' observations predicted with the current reflectance under their true light
/// (protocol (a)) when the workspace has `truth/`, else under the mean of the current
/// training maps (protocol (c)); RMSE over observations with `α > 0`, after the best
/// global scale (the state before the final normalisation has an arbitrary scale).
/// At most [`TRACKER_MAX_OBSERVATIONS`] observations are tracked (every `k`-th, in photo
/// order, when there are more): their transport rows would otherwise cost a third of the
/// training rows' memory (3 of 13 photos held out) for a figure that 20,000 observations
/// already give to about 1% (the relative standard error of a mean square over `n`
/// roughly independent residuals is `√(2/n)`).
pub(crate) struct HoldoutTracker {
    obs: Observations,
    transport: crate::transport::Transport,
    /// Haar coefficients of each held-out view's true light, when known (by view order).
    truth: Option<Vec<[Vec<f64>; 3]>>,
    n_global: usize,
}

impl HoldoutTracker {
    /// Observations and transport of the held-out views; `None` when there are none.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn new(
        scene: &crate::import::scene::Scene,
        photos: &[Photo],
        held: &[usize],
        bvh: &crate::observe::trace::SceneBvh,
        normals_env: &[Vec3],
        env_from_world: &Matrix3<f64>,
        vis: &crate::transport::visibility::Visibility,
        basis: &[crate::transport::brdf::BasisBrdf],
        rot: &crate::sphere::rotation::Rotation,
        topts: &TransportOptions,
        truth: Option<&Truth>,
    ) -> Result<Option<Self>> {
        if held.is_empty() {
            return Ok(None);
        }
        let views: Vec<_> = held.iter().map(|&i| scene.views[i].clone()).collect();
        let ph: Vec<&Photo> = held.iter().map(|&i| &photos[i]).collect();
        let obs = observe::extract(&scene.mesh, bvh, &views, &ph, &ObserveOptions::default());
        let obs = every_kth(obs, TRACKER_MAX_OBSERVATIONS);
        if obs.weight.iter().all(|&w| w <= 0.0) {
            return Ok(None);
        }
        let transport =
            transport::build(normals_env, &obs, env_from_world, vis, basis, rot, topts)?;
        let truth = match truth {
            Some(t) => {
                let mut lights = Vec::new();
                for v in &views {
                    match t.light(&v.image.name, topts.n_global, env_from_world)? {
                        Some(env) => lights.push(transport::light_haar(&env)),
                        None => {
                            return Ok(Some(Self {
                                obs,
                                transport,
                                truth: None,
                                n_global: topts.n_global,
                            }))
                        }
                    }
                }
                Some(lights)
            }
            None => None,
        };
        Ok(Some(HoldoutTracker {
            obs,
            transport,
            truth,
            n_global: topts.n_global,
        }))
    }

    /// The scaled RMSE for the estimator's current state.
    pub(crate) fn rmse(&self, state: &solve::IterState, n_vertices: usize) -> f64 {
        let beta = solve::beta_per_vertex(state.lambda, state.weights, n_vertices);
        let mean_haar = || {
            let n2 = self.n_global * self.n_global;
            let k = state.lights.len().max(1) as f64;
            [0, 1, 2].map(|c| {
                let mut m = vec![0.0; n2];
                for l in state.lights {
                    for (a, b) in m.iter_mut().zip(&l[c]) {
                        *a += b / k;
                    }
                }
                crate::sphere::haar::forward(&mut m, self.n_global);
                m
            })
        };
        let mean = if self.truth.is_none() {
            Some(mean_haar())
        } else {
            None
        };
        let nb = self.transport.n_basis;
        let (mut syy, mut syp, mut spp, mut n) = (0.0, 0.0, 0.0, 0usize);
        for p in 0..self.obs.len() {
            if self.obs.weight[p] <= 0.0 {
                continue;
            }
            let light = match (&self.truth, &mean) {
                (Some(t), _) => &t[self.obs.photo[p] as usize],
                (None, Some(m)) => m,
                (None, None) => return f64::NAN,
            };
            let x = self.obs.vertex[p] as usize;
            for c in 0..3 {
                let pred: f64 = (0..nb)
                    .map(|b| beta[x * nb + b][c] * self.transport.response(p, b, &light[c]))
                    .sum();
                let y = self.obs.rgb[p][c] as f64;
                syy += y * y;
                syp += y * pred;
                spp += pred * pred;
            }
            n += 3;
        }
        if n == 0 {
            return f64::NAN;
        }
        let s = if spp > 0.0 { syp / spp } else { 0.0 };
        ((syy - 2.0 * s * syp + s * s * spp).max(0.0) / n as f64).sqrt()
    }
}

/// Observations the held-out tracker keeps at most ([`HoldoutTracker`]).
pub(crate) const TRACKER_MAX_OBSERVATIONS: usize =
    crate::solve::budget::HELD_OUT_TRACKED_MAX as usize;

/// Every `⌈len / max⌉`-th observation of `obs` (all of them when `len ≤ max`), photo
/// ranges recomputed.
fn every_kth(obs: Observations, max: usize) -> Observations {
    let n = obs.len();
    if n <= max || max == 0 {
        return obs;
    }
    let k = n.div_ceil(max);
    let kept: Vec<usize> = obs
        .photo_ranges
        .iter()
        .flat_map(|r| r.clone().filter(|p| p % k == 0))
        .collect();
    obs.gather(&kept)
}

/// What the evaluation found.
pub(crate) struct Evaluation {
    pub holdout: Vec<HoldoutEntry>,
    pub mean_holdout_rmse: Option<f64>,
    /// Wall and CPU seconds of the renders: rasterising and shading the held-out photos
    /// under every protocol's light and, in the same pass, the truth check's training
    /// photos under their true and fitted lights.
    pub render_seconds: [f64; 2],
    /// Wall and CPU seconds of protocol (b)'s light fits (observations, transport and a
    /// capped lighting solve per view, [`super::half_fit`]).
    pub half_fit_seconds: [f64; 2],
    /// Literature metrics per held-out photo and protocol ([`crate::report::metrics`]).
    pub metrics: Vec<crate::report::metrics::MetricsEntry>,
    /// Protocol `half` against the naive baseline ([`super::baseline`]).
    pub headline: Option<crate::report::metrics::Headline>,
    /// The truth check of the training photos ([`super::truth_check`]; empty without
    /// `truth/`).
    pub truth_check: Vec<crate::report::metrics::TruthCheckEntry>,
}

/// Adds the wall and CPU seconds `f` takes to `acc`.
fn timed<T>(acc: &mut [f64; 2], f: impl FnOnce() -> T) -> T {
    let watch = crate::stages::Stopwatch::start();
    let out = f();
    let (wall, cpu) = watch.elapsed();
    acc[0] += wall;
    acc[1] += cpu;
    out
}

/// A rendered view: the raster and the linear RGB image.
pub(crate) struct RenderedView {
    pub raster: Raster,
    pub rgb: Vec<[f32; 3]>,
}

/// The render's local resolution for `opts`: `--render-local-resolution`, else the
/// estimator's local resolution (module docs: why not finer by default).
pub fn render_local_resolution(opts: &super::RunOptions) -> usize {
    opts.render_local_resolution
        .unwrap_or(opts.local_resolution)
}

/// Visibility rays per texel of the finer grid so that every texel of the estimator's
/// grid (`n_est` per side, `rays` asked for) still gets at least `rays`:
/// `max(1, ⌈rays · (n_est / n_fine)²⌉)` (1 ray per 64² texel = 4 per 32² texel at the
/// defaults).
pub fn fine_rays(rays: usize, n_est: usize, n_fine: usize) -> usize {
    let ratio = (n_fine / n_est.max(1)).max(1);
    rays.div_ceil(ratio * ratio).max(1)
}

/// Trace visibility once at the finer of the estimator's and the renderer's local
/// resolutions (module docs) and return `(estimator's, renderer's)`: one allocation when
/// the two resolutions are equal (the default; 100 MB at 100K vertices and 32²).
pub(crate) fn trace_visibility(
    mesh: &crate::import::mesh::Mesh,
    bvh: &crate::observe::trace::SceneBvh,
    env_from_world: &Matrix3<f64>,
    opts: &super::RunOptions,
) -> (Arc<Visibility>, Arc<Visibility>) {
    let n_render = render_local_resolution(opts);
    let n_fine = opts.local_resolution.max(n_render);
    let rays = fine_rays(opts.rays_per_texel, opts.local_resolution, n_fine);
    let sampling =
        crate::transport::visibility::Sampling::new(rays, opts.edge_rays, opts.ray_lattice);
    let fine = Arc::new(crate::transport::visibility::compute_sampled(
        mesh,
        bvh,
        env_from_world,
        n_fine,
        sampling,
        opts.seed,
        true,
    ));
    let coarser = |n: usize| {
        if n < n_fine {
            Arc::new(crate::solve::adapt::downsample_visibility(&fine, n))
        } else {
            fine.clone()
        }
    };
    (coarser(opts.local_resolution), coarser(n_render))
}

/// The wavelet renderer's model of the fit, with visibility `vis`.
fn wavelet_model<'a>(
    f: &'a Fitted,
    vis: &'a crate::transport::visibility::Visibility,
) -> render::WaveletModel<'a> {
    render::WaveletModel {
        mesh: &f.scene.mesh,
        normals_env: &f.normals_env,
        vis,
        env_from_world: &f.env_from_world,
        basis: &f.basis,
        beta: &f.beta,
    }
}

/// Training photo `k`'s render under its fitted map: the model exactly as it was fitted.
/// At the photo's observations the radiance is the estimator's own prediction
/// ([`Fitted::train_predictions`], through the kept transport rows); the visible vertices
/// that were not observed (grazing, on a depth discontinuity) are rendered with the
/// estimator's visibility and blended rotation (Eq. 6, the light rotated once per frame)
/// ([`render::shade_wavelet_known`]).
pub(crate) fn render_training_view(f: &Fitted, k: usize) -> Result<RenderedView> {
    let v = f.train[k];
    let view = &f.scene.views[v];
    let raster = render::rasterize(&f.scene.mesh, &view.camera, &view.image);
    let mut given = vec![None; f.scene.mesh.positions.len()];
    for &(x, rgb) in &f.train_predictions[k] {
        given[x as usize] = Some(rgb);
    }
    let rgb = render::shade_wavelet_known(
        &wavelet_model(f, &f.vis),
        &raster,
        &view.image,
        &fitted_env(f, k),
        &f.rot,
        &given,
    )?;
    Ok(RenderedView { raster, rgb })
}

/// Shade several views (each under its lights) with the renderer's visibility and rotation
/// (`--render-local-resolution`, [`crate::sphere::rotation::SplatRotation`]) in one
/// vertex-major pass ([`render::shade_views`]: a vertex's footprint walked once for the
/// lights of every view that shows it, its BRDF slices once per view).
pub(super) fn shade_views(
    f: &Fitted,
    views: &[render::ViewToShade],
) -> Result<render::ShadedViews> {
    render::shade_views(&wavelet_model(f, &f.render_vis), views, &f.render_rot)
}

/// The texels of a photo's fitted map as an [`OctEnv`].
pub(crate) fn fitted_env(f: &Fitted, k: usize) -> OctEnv {
    let l = &f.est.lights[k];
    OctEnv::from_channels(f.opts.global_resolution, [&l[0], &l[1], &l[2]])
}

/// The mean of the training maps.
pub(crate) fn mean_env(f: &Fitted) -> OctEnv {
    let n2 = f.opts.global_resolution * f.opts.global_resolution;
    let mut sum = [vec![0.0; n2], vec![0.0; n2], vec![0.0; n2]];
    for l in &f.est.lights {
        for c in 0..3 {
            for (s, v) in sum[c].iter_mut().zip(&l[c]) {
                *s += v;
            }
        }
    }
    let k = f.est.lights.len().max(1) as f64;
    for ch in sum.iter_mut() {
        ch.iter_mut().for_each(|v| *v /= k);
    }
    OctEnv::from_channels(f.opts.global_resolution, [&sum[0], &sum[1], &sum[2]])
}

/// Pixels that count: object pixels not overexposed in the photo.
pub(super) fn valid_mask(raster: &Raster, photo: &Photo) -> Vec<bool> {
    raster
        .face
        .iter()
        .zip(&photo.overexposed)
        .map(|(&face, &over)| face != u32::MAX && !over)
        .collect()
}

fn entry(
    image: &str,
    protocol: &str,
    photo: &Photo,
    pred: &[[f32; 3]],
    mask: &[bool],
) -> HoldoutEntry {
    let (rmse, rmse_scaled, scale, pixels) = compare(&photo.rgb, pred, mask);
    HoldoutEntry {
        image: image.to_string(),
        protocol: protocol.to_string(),
        rmse,
        rmse_scaled,
        scale,
        psnr: psnr(rmse),
        pixels,
    }
}

/// The middle of the object's bounding box in `x` (pixels), or `None` for an empty raster.
fn object_mid_x(raster: &Raster) -> Option<f64> {
    let w = raster.width as usize;
    let xs = raster
        .face
        .iter()
        .enumerate()
        .filter(|(_, &f)| f != u32::MAX)
        .map(|(i, _)| (i % w) as f64 + 0.5);
    span_mid(xs)
}

/// Evaluate every held-out view under each protocol that applies; write its renders.
pub(crate) fn evaluate(
    f: &Fitted,
    truth: Option<&super::Truth>,
    dir: &Path,
    progress: &super::Progress,
) -> Result<Evaluation> {
    let mut holdout = Vec::new();
    let renders = dir.join("renders");
    std::fs::create_dir_all(&renders).map_err(|e| Error::io(&renders, e))?;
    let mean = mean_env(f);
    let bar = progress.bar(f.held.len() as u64, "held-out photos");
    let mut headline = Vec::new();
    let (mut metrics, mut versus_baseline) = (Vec::new(), Vec::new());
    let (mut render_seconds, mut half_fit_seconds) = ([0.0; 2], [0.0; 2]);
    // Every view's raster, then protocol (b)'s light fits in chunks of one view per thread
    // (each fit's lighting QP is sequential, so a lone fit leaves the other cores idle; the
    // results do not depend on the chunking), then every view's renders in one
    // vertex-major pass ([`render::shade_views`]).
    let rasters: Vec<Raster> = timed(&mut render_seconds, || {
        f.held
            .iter()
            .map(|&v| {
                let view = &f.scene.views[v];
                render::rasterize(&f.scene.mesh, &view.camera, &view.image)
            })
            .collect()
    });
    let mids: Vec<Option<f64>> = rasters.iter().map(object_mid_x).collect();
    let chunk = rayon::current_num_threads().max(1);
    let mut half_envs = Vec::with_capacity(f.held.len());
    for (views, mids) in f.held.chunks(chunk).zip(mids.chunks(chunk)) {
        let halves: Vec<Result<Option<OctEnv>>> = timed(&mut half_fit_seconds, || {
            views
                .par_iter()
                .zip(mids)
                .map(|(&v, mid)| match mid {
                    Some(mid) => super::half_fit::fit_left_half(f, v, *mid, &mean),
                    None => Ok(None),
                })
                .collect()
        });
        for h in halves {
            half_envs.push(h?);
        }
    }
    // The lights of the protocols that apply, in report order: (a) truth, (b) the
    // left-half fit (judged on the right half), (c) the mean of the training maps.
    // Each map resampled from its lat-long file on a thread of its own.
    let true_envs: Vec<Option<OctEnv>> = f
        .held
        .par_iter()
        .map(|&v| {
            let name = f.scene.views[v].image.name.as_str();
            match truth {
                Some(t) => t.light(name, f.opts.global_resolution, &f.env_from_world),
                None => Ok(None),
            }
        })
        .collect::<Result<_>>()?;
    let lights: Vec<Vec<(&str, &OctEnv)>> = true_envs
        .iter()
        .zip(&half_envs)
        .map(|(t, h)| {
            [
                ("truth", t.as_ref()),
                ("half", h.as_ref()),
                ("mean", Some(&mean)),
            ]
            .into_iter()
            .filter_map(|(p, e)| e.map(|e| (p, e)))
            .collect()
        })
        .collect();
    // The truth check's training photos are shaded in the same pass: a vertex's footprint
    // is walked once for the lights of every photo, held out or not, that shows it.
    let checked = match truth {
        Some(t) => timed(&mut render_seconds, || {
            super::truth_check::checked_views(f, t)
        })?,
        None => Vec::new(),
    };
    let to_shade: Vec<render::ViewToShade> = f
        .held
        .iter()
        .zip(&rasters)
        .zip(&lights)
        .map(|((&v, raster), l)| render::ViewToShade {
            raster,
            image: &f.scene.views[v].image,
            envs: l.iter().map(|&(_, e)| e).collect(),
        })
        .chain(checked.iter().map(|c| c.to_shade(f)))
        .collect();
    let shaded = timed(&mut render_seconds, || shade_views(f, &to_shade))?;
    let truth_check = super::truth_check::score(f, &checked, &shaded, f.held.len());
    for (i, ((&v, raster), lights)) in f.held.iter().zip(&rasters).zip(&lights).enumerate() {
        {
            let view = &f.scene.views[v];
            let name = view.image.name.as_str();
            let photo = &f.photos[v];
            let stem = crate::render::relight::file_stem(name);
            let mid = mids[i];
            let half_env = &half_envs[i];
            let rgbs = timed(&mut render_seconds, || {
                shaded.images(i, raster, &f.scene.mesh)
            });

            let valid = valid_mask(raster, photo);
            let w = raster.width as usize;
            let side = |right: bool| -> Option<Vec<bool>> {
                let mid = mid?;
                Some(
                    valid
                        .iter()
                        .enumerate()
                        .map(|(i, &m)| m && ((i % w) as f64 >= mid) == right)
                        .collect(),
                )
            };
            let right_half = side(true);
            // The naive baseline on protocol (b)'s photos and pixels, its gain fitted on
            // the left half (super::baseline).
            let baseline = match (&half_env, side(false)) {
                (Some(_), Some(left)) => {
                    let (rgb, _) = super::baseline::predict(
                        &f.scene.mesh,
                        raster,
                        &f.baseline,
                        &photo.rgb,
                        &left,
                    );
                    Some(rgb)
                }
                _ => None,
            };
            let mut scored: Vec<(&str, &[[f32; 3]])> = lights
                .iter()
                .zip(&rgbs)
                .map(|(&(p, _), rgb)| (p, rgb.as_slice()))
                .collect();
            if let Some(b) = &baseline {
                let at = scored
                    .iter()
                    .position(|s| s.0 == "half")
                    .map_or(0, |i| i + 1);
                scored.insert(at, ("baseline", b.as_slice()));
            }
            // The first protocol that applies is the headline (truth, else half, else mean).
            // Each protocol's figures and PNGs on their own thread (independent images).
            let scored_entries: Vec<Result<(HoldoutEntry, MetricsEntry)>> = scored
                .par_iter()
                .map(|&(protocol, rgb)| {
                    let mask: &[bool] = match (protocol, &right_half) {
                        ("half" | "baseline", Some(right)) => right,
                        _ => &valid,
                    };
                    let e = entry(name, protocol, photo, rgb, mask);
                    let h = raster.height as usize;
                    let m = MetricsEntry {
                        image: name.to_string(),
                        protocol: protocol.to_string(),
                        metrics: image_metrics(&photo.rgb, rgb, w, h, mask),
                    };
                    let path = renders.join(format!("{stem}.{protocol}.png"));
                    super::output::write_triptych(&path, photo, raster, rgb, e.scale)?;
                    Ok((e, m))
                })
                .collect();
            let mut best: Option<f64> = None;
            let mut pair = [None, None];
            for scored_entry in scored_entries {
                let (e, m) = scored_entry?;
                best.get_or_insert(e.rmse_scaled);
                match e.protocol.as_str() {
                    "half" => pair[0] = Some(e.rmse_scaled),
                    "baseline" => pair[1] = Some(e.rmse_scaled),
                    _ => {}
                }
                metrics.push(m);
                holdout.push(e);
            }
            if let [Some(m), Some(b)] = pair {
                versus_baseline.push((m, b));
            }
            if let Some(rmse) = best {
                if rmse.is_finite() {
                    headline.push(rmse);
                }
            }
            bar.inc(1);
        }
    }
    bar.finish_and_clear();
    let mean_holdout_rmse =
        (!headline.is_empty()).then(|| headline.iter().sum::<f64>() / headline.len() as f64);
    Ok(Evaluation {
        holdout,
        mean_holdout_rmse,
        render_seconds,
        half_fit_seconds,
        metrics,
        headline: crate::report::metrics::Headline::from_pairs(&versus_baseline),
        truth_check,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_kth_keeps_a_stride_and_its_photo_ranges() {
        // 10 observations, photos 0..6 and 6..10; at most 4 → every 3rd: 0, 3, | 6, 9.
        let mut obs = Observations::default();
        for p in 0..10u32 {
            obs.vertex.push(100 + p);
            obs.photo.push(u32::from(p >= 6));
            obs.rgb.push([p as f32; 3]);
            obs.weight.push(1.0);
            obs.dir.push([0.0, 0.0, 1.0]);
        }
        obs.photo_ranges = vec![0..6, 6..10];
        let small = every_kth(obs.clone(), 4);
        assert_eq!(small.vertex, vec![100, 103, 106, 109]);
        assert_eq!(small.photo, vec![0, 0, 1, 1]);
        assert_eq!(small.photo_ranges, vec![0..2, 2..4]);
        // At or under the cap nothing changes.
        assert_eq!(every_kth(obs.clone(), 10).vertex, obs.vertex);
    }
}
