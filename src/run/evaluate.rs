//! Held-out evaluation (docs/method.md, "Held-out evaluation").
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
//! Each view is rendered as [`super::shading`] says; RMSE is over object pixels off its edges
//! (silhouette and depth jumps, [`super::shading::valid_mask`]) and not overexposed in the photo. The held-out photos and the truth check's training photos ([`super::truth_check`]) are
//! shaded in one vertex-major pass ([`render::shade_views`]): a vertex's footprint is walked
//! once for the lights of every photo that shows it, reading all lights' texels interleaved
//! ([`crate::sphere::rotation::SplatRotation::resample_interleaved`]); every image is bit
//! for bit the one a pass of its photo alone gives.
//!
//! The stage runs as steps over the held-out views ([`evaluate`]): rasters, protocol (b)'s
//! light fits, every protocol's light, one shading pass, then each view scored
//! ([`score_view`]).

use super::half_fit::span_mid;
use super::shading::{mean_env, shade_views, valid_mask, write_triptych};
use super::{truth_check, Fitted};
use crate::import::photo::Photo;
use crate::render::{self, Raster};
use crate::report::metrics::{image_metrics, MetricsEntry};
use crate::report::{compare, psnr, HoldoutEntry};
use crate::sphere::envmap::OctEnv;
use crate::{Error, Result};
use rayon::prelude::*;
use std::path::Path;

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
    /// Diffuse albedo per material against the truth ([`super::truth_check::albedo_truth`]).
    pub albedo_truth: Option<crate::report::metrics::AlbedoTruth>,
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

/// Wall and CPU seconds of the evaluation's two kinds of work ([`Evaluation`]).
#[derive(Default)]
struct Clocks {
    render: [f64; 2],
    half_fit: [f64; 2],
}

/// What the scored views add up to, in view order.
#[derive(Default)]
struct Scores {
    holdout: Vec<HoldoutEntry>,
    metrics: Vec<MetricsEntry>,
    /// Per view, the scaled RMSE of the first protocol that applies (truth, else half,
    /// else mean), when finite: the mean held-out RMSE's terms.
    first: Vec<f64>,
    /// Per view, protocol (b)'s scaled RMSE and the baseline's on the same pixels.
    versus_baseline: Vec<(f64, f64)>,
}

impl Scores {
    /// One view's entries, in report order.
    fn add_view(&mut self, entries: Vec<(HoldoutEntry, MetricsEntry)>) {
        let mut first: Option<f64> = None;
        let (mut half, mut baseline) = (None, None);
        for (e, m) in entries {
            first.get_or_insert(e.rmse_scaled);
            match e.protocol.as_str() {
                "half" => half = Some(e.rmse_scaled),
                "baseline" => baseline = Some(e.rmse_scaled),
                _ => {}
            }
            self.metrics.push(m);
            self.holdout.push(e);
        }
        if let (Some(m), Some(b)) = (half, baseline) {
            self.versus_baseline.push((m, b));
        }
        if let Some(rmse) = first.filter(|r| r.is_finite()) {
            self.first.push(rmse);
        }
    }

    fn into_evaluation(
        self,
        clocks: Clocks,
        truth_check: Vec<crate::report::metrics::TruthCheckEntry>,
        albedo_truth: Option<crate::report::metrics::AlbedoTruth>,
    ) -> Evaluation {
        let n = self.first.len();
        Evaluation {
            mean_holdout_rmse: (n > 0).then(|| self.first.iter().sum::<f64>() / n as f64),
            holdout: self.holdout,
            render_seconds: clocks.render,
            half_fit_seconds: clocks.half_fit,
            metrics: self.metrics,
            headline: crate::report::metrics::Headline::from_pairs(&self.versus_baseline),
            truth_check,
            albedo_truth,
        }
    }
}

/// One held-out view as the scoring sees it.
struct HeldView<'a> {
    /// Index into the scene's views.
    view: usize,
    raster: &'a Raster,
    /// The middle of the object's `x` span (protocol (b)'s split), when it has pixels.
    mid: Option<f64>,
    /// Whether protocol (b) fitted a light (then the baseline is scored beside it).
    half_fitted: bool,
    /// Each protocol that applies and its light, in report order.
    lights: &'a [(&'a str, &'a OctEnv)],
}

/// Evaluate every held-out view under each protocol that applies; write its renders.
/// Every view's raster, then protocol (b)'s light fits, then every view's renders in one
/// vertex-major pass ([`render::shade_views`]), then each view scored.
pub(crate) fn evaluate(
    f: &Fitted,
    truth: Option<&super::Truth>,
    dir: &Path,
    progress: &super::Progress,
) -> Result<Evaluation> {
    let renders = dir.join("renders");
    std::fs::create_dir_all(&renders).map_err(|e| Error::io(&renders, e))?;
    let mean = mean_env(f);
    let bar = progress.bar(f.held.len() as u64, "held-out photos");
    let mut clocks = Clocks::default();
    let rasters = timed(&mut clocks.render, || held_rasters(f));
    let mids: Vec<Option<f64>> = rasters.iter().map(object_mid_x).collect();
    let half_envs = half_fits(f, &mids, &mean, &mut clocks.half_fit)?;
    let true_envs = true_lights(f, truth)?;
    let lights = protocol_lights(&true_envs, &half_envs, &mean);
    // The truth check's training photos are shaded in the same pass: a vertex's footprint
    // is walked once for the lights of every photo, held out or not, that shows it.
    let checked = match truth {
        Some(t) => timed(&mut clocks.render, || truth_check::checked_views(f, t))?,
        None => Vec::new(),
    };
    let to_shade = views_to_shade(f, &rasters, &lights, &checked);
    let shaded = timed(&mut clocks.render, || shade_views(f, &to_shade))?;
    let mut truth_check = truth_check::score(f, &checked, &shaded, f.held.len());
    // The truth's materials, read once for the floor and the albedo against the truth.
    let true_materials = match truth {
        Some(t) => truth_check::TrueMaterials::read(t)?,
        None => None,
    };
    if let Some(tm) = &true_materials {
        timed(&mut clocks.render, || {
            truth_check::add_true_reflectance(f, tm, &checked, &mut truth_check)
        })?;
    }
    let albedo_truth = true_materials
        .as_ref()
        .and_then(|tm| truth_check::albedo_truth(f, tm));
    let mut scores = Scores::default();
    for (i, (&v, raster)) in f.held.iter().zip(&rasters).enumerate() {
        let rgbs = timed(&mut clocks.render, || {
            shaded.images(i, raster, &f.scene.mesh)
        });
        let held = HeldView {
            view: v,
            raster,
            mid: mids[i],
            half_fitted: half_envs[i].is_some(),
            lights: &lights[i],
        };
        scores.add_view(score_view(f, &held, &rgbs, &renders)?);
        bar.inc(1);
    }
    bar.finish_and_clear();
    Ok(scores.into_evaluation(clocks, truth_check, albedo_truth))
}

/// Every held-out view's raster.
fn held_rasters(f: &Fitted) -> Vec<Raster> {
    f.held
        .iter()
        .map(|&v| {
            let view = &f.scene.views[v];
            render::rasterize(&f.scene.mesh, &view.camera, &view.image)
        })
        .collect()
}

/// Protocol (b)'s light per held-out view (`None` where the object has no pixels), fitted
/// in chunks of one view per thread: each fit's lighting QP is sequential, so a lone fit
/// would leave the other cores idle (the results do not depend on the chunking).
fn half_fits(
    f: &Fitted,
    mids: &[Option<f64>],
    mean: &OctEnv,
    seconds: &mut [f64; 2],
) -> Result<Vec<Option<OctEnv>>> {
    let chunk = rayon::current_num_threads().max(1);
    let mut half_envs = Vec::with_capacity(f.held.len());
    for (views, mids) in f.held.chunks(chunk).zip(mids.chunks(chunk)) {
        let halves: Vec<Result<Option<OctEnv>>> = timed(seconds, || {
            views
                .par_iter()
                .zip(mids)
                .map(|(&v, mid)| match mid {
                    Some(mid) => super::half_fit::fit_left_half(f, v, *mid, mean),
                    None => Ok(None),
                })
                .collect()
        });
        for h in halves {
            half_envs.push(h?);
        }
    }
    Ok(half_envs)
}

/// Protocol (a)'s light per held-out view, when the workspace has `truth/`: each map
/// resampled from its lat-long file on a thread of its own.
fn true_lights(f: &Fitted, truth: Option<&super::Truth>) -> Result<Vec<Option<OctEnv>>> {
    f.held
        .par_iter()
        .map(|&v| {
            let name = f.scene.views[v].image.name.as_str();
            match truth {
                Some(t) => t.light(name, f.opts.global_resolution, &f.env_from_world),
                None => Ok(None),
            }
        })
        .collect()
}

/// Per held-out view, the lights of the protocols that apply, in report order: (a) truth,
/// (b) the left-half fit (judged on the right half), (c) the mean of the training maps.
fn protocol_lights<'a>(
    true_envs: &'a [Option<OctEnv>],
    half_envs: &'a [Option<OctEnv>],
    mean: &'a OctEnv,
) -> Vec<Vec<(&'static str, &'a OctEnv)>> {
    true_envs
        .iter()
        .zip(half_envs)
        .map(|(t, h)| {
            [
                ("truth", t.as_ref()),
                ("half", h.as_ref()),
                ("mean", Some(mean)),
            ]
            .into_iter()
            .filter_map(|(p, e)| e.map(|e| (p, e)))
            .collect()
        })
        .collect()
}

/// The held-out views under their protocols' lights, then the truth check's views.
fn views_to_shade<'a>(
    f: &'a Fitted,
    rasters: &'a [Raster],
    lights: &'a [Vec<(&'static str, &'a OctEnv)>],
    checked: &'a [truth_check::CheckedView],
) -> Vec<render::ViewToShade<'a>> {
    f.held
        .iter()
        .zip(rasters)
        .zip(lights)
        .map(|((&v, raster), l)| render::ViewToShade {
            raster,
            image: &f.scene.views[v].image,
            envs: l.iter().map(|&(_, e)| e).collect(),
        })
        .chain(checked.iter().map(|c| c.to_shade(f)))
        .collect()
}

/// One held-out view's figures under each protocol (`rgbs`, in `held.lights` order) and,
/// beside protocol (b), the naive baseline on the same pixels, its gain fitted on the left
/// half ([`super::baseline`]); each protocol's triptych written to `renders`.
fn score_view(
    f: &Fitted,
    held: &HeldView,
    rgbs: &[Vec<[f32; 3]>],
    renders: &Path,
) -> Result<Vec<(HoldoutEntry, MetricsEntry)>> {
    let photo = &f.photos[held.view];
    let valid = valid_mask(held.raster, photo);
    let w = held.raster.width as usize;
    let side = |right: bool| -> Option<Vec<bool>> {
        let mid = held.mid?;
        Some(
            valid
                .iter()
                .enumerate()
                .map(|(i, &m)| m && ((i % w) as f64 >= mid) == right)
                .collect(),
        )
    };
    let right_half = side(true);
    let baseline = side(false).filter(|_| held.half_fitted).map(|left| {
        let (rgb, _) =
            super::baseline::predict(&f.scene.mesh, held.raster, &f.baseline, &photo.rgb, &left);
        rgb
    });
    let mut scored: Vec<(&str, &[[f32; 3]])> = held
        .lights
        .iter()
        .zip(rgbs)
        .map(|(&(p, _), rgb)| (p, rgb.as_slice()))
        .collect();
    if let Some(b) = &baseline {
        let at = scored
            .iter()
            .position(|s| s.0 == "half")
            .map_or(0, |i| i + 1);
        scored.insert(at, ("baseline", b.as_slice()));
    }
    // Each protocol's figures and PNGs on their own thread (independent images).
    let out = Scored {
        name: f.scene.views[held.view].image.name.as_str(),
        photo,
        raster: held.raster,
        renders,
    };
    scored
        .par_iter()
        .map(|&(protocol, rgb)| {
            let mask: &[bool] = match (protocol, &right_half) {
                ("half" | "baseline", Some(right)) => right,
                _ => &valid,
            };
            out.protocol(protocol, rgb, mask)
        })
        .collect()
}

/// What scoring one protocol of a view needs besides its prediction and pixels.
struct Scored<'a> {
    name: &'a str,
    photo: &'a Photo,
    raster: &'a Raster,
    renders: &'a Path,
}

impl Scored<'_> {
    /// Protocol `protocol`'s figures for prediction `rgb` over `mask`; its triptych
    /// `renders/STEM.PROTOCOL.png`.
    fn protocol(
        &self,
        protocol: &str,
        rgb: &[[f32; 3]],
        mask: &[bool],
    ) -> Result<(HoldoutEntry, MetricsEntry)> {
        let e = entry(self.name, protocol, self.photo, rgb, mask);
        let (w, h) = (self.raster.width as usize, self.raster.height as usize);
        let m = MetricsEntry {
            image: self.name.to_string(),
            protocol: protocol.to_string(),
            metrics: image_metrics(&self.photo.rgb, rgb, w, h, mask),
        };
        let stem = crate::render::views::file_stem(self.name);
        let path = self.renders.join(format!("{stem}.{protocol}.png"));
        write_triptych(&path, self.photo, self.raster, rgb, e.scale)?;
        Ok((e, m))
    }
}
