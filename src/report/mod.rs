//! The run report: `report.json` for machines, `report.md` plus PNG figures for people.
//!
//! Figures in the report (docs/method.md, "Held-out evaluation"; issue 6):
//! - held-out RMSE and PSNR in linear RGB on the photo's [0, 1] scale over object pixels
//!   off its edges and not overexposed, per protocol: (a) `truth` light, (b) `half` light fitted with
//!   frozen reflectance on the left half of the object, measured on the right half,
//!   (c) `mean` of the training maps, and the naive `baseline` (the per-vertex median of
//!   the training photos' colours times a per-channel gain fitted on the left half, scored
//!   on `half`'s pixels, [`crate::run`]'s `baseline` module). `rmse` is the raw figure, `rmse_scaled` the figure
//!   after the best global scale `s* = Σ y·ŷ / Σ ŷ²` (which removes the scale ambiguity of
//!   Eq. 9 and any exposure difference), PSNR = −20 log10(rmse) for a peak of 1;
//! - `headline`: `half`'s mean RMSE after scale over `baseline`'s (below 1: the fit beats
//!   the training colours), at the top of `report.md`;
//! - `metrics`: PSNR-H, PSNR-L and SSIM per held-out photo and protocol, the Stanford-ORB
//!   definitions over the object's pixels ([`metrics`]);
//! - `truth_check` (synthetic workspaces): training photos (five megapixels' worth) under
//!   their true light, RMSE after the per-channel scale, beside the same under their fitted;
//! - error against run time (objective, training RMSE, held-out RMSE per outer iteration);
//! - wall time, CPU time and peak memory per stage;
//! - the model chosen (materials, basis, resolutions) and the reason for each choice.

pub mod html;
mod markdown;
pub mod metrics;
pub mod plot;
pub mod sky;

use crate::stages::StageRecord;
use crate::{Error, Result};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::Path;

/// One held-out figure.
#[derive(Debug, Clone, Serialize)]
pub struct HoldoutEntry {
    /// Image name as in `images.txt`.
    pub image: String,
    /// `truth`, `half`, `baseline` or `mean` (docs/method.md, "Held-out evaluation": (a),
    /// (b), the naive baseline on (b)'s pixels, (c)).
    pub protocol: String,
    /// Raw RMSE, linear RGB, [0, 1] photo scale.
    pub rmse: f64,
    /// RMSE after the best global scale.
    pub rmse_scaled: f64,
    /// The best global scale applied for `rmse_scaled`.
    pub scale: f64,
    /// PSNR in dB of the raw RMSE (peak 1).
    pub psnr: f64,
    /// Pixels compared.
    pub pixels: usize,
}

/// One training photo's fit.
#[derive(Debug, Clone, Serialize)]
pub struct TrainEntry {
    /// Image name.
    pub image: String,
    /// RMSE over its observations (linear RGB).
    pub rmse: f64,
    /// Observations used.
    pub observations: usize,
}

/// One outer iteration of the estimator.
#[derive(Debug, Clone, Serialize)]
pub struct TimelinePoint {
    /// Which start of the alternation ([`crate::solve::starts`]) the iteration belongs to, from 0
    /// (the paper's start).
    pub start: usize,
    /// Seconds since the estimator started (over all starts).
    pub seconds: f64,
    /// Objective of Eq. 9 (with regularisers).
    pub objective: f64,
    /// RMSE on the training observations.
    pub train_rmse: f64,
    /// Mean held-out RMSE (protocol (a) when available, else (c)), when evaluated.
    pub holdout_rmse: Option<f64>,
    /// What the iteration's lighting and material steps cost.
    #[serde(flatten)]
    pub steps: crate::solve::StepTimes,
}

/// The model that was fitted and why.
#[derive(Debug, Clone, Serialize, Default)]
pub struct ModelReport {
    /// Number of materials K.
    pub materials: usize,
    /// Basis BRDF labels, in order.
    pub basis: Vec<String>,
    /// Global (octahedral) map resolution per side.
    pub global_resolution: usize,
    /// Local (hemi-octahedral) resolution per side.
    pub local_resolution: usize,
    /// The renderer's local resolution per side (held-out views and renders).
    pub render_local_resolution: usize,
    /// Normal-grid resolution of the rotation per side.
    pub normal_grid: usize,
    /// Kept Haar coefficients per transport row (0 = all).
    pub kept_coefficients: usize,
    /// Energy fraction each blended lighting row may drop (0 = the exact blend).
    pub blend_tolerance: f64,
    /// One sentence per decision: what was chosen and why.
    pub reasons: Vec<String>,
    /// The adaptive model's decisions (`--adaptive on`), each against the full model.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub adaptive: Option<Vec<crate::solve::adapt::Decision>>,
    /// The per-photo light model used (`--light`) and why.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub light: Option<crate::solve::light::choose::LightDecision>,
    /// What fixes the per-channel scale between reflectance and light.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub scale_anchor: Option<ScaleAnchorReport>,
    /// The ratio step (`--ratio-steps`): whether it ran, why, and what it did.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ratio_step: Option<RatioStepReport>,
    /// The variable-projection step (`--varpro-steps`): its rounds and what they did.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub varpro_step: Option<VarproStepReport>,
    /// Each training photo's recovered sun and sky (the light model `sky`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sky: Option<sky::SkyReport>,
}

/// The variable-projection step's rounds and moves ([`crate::solve::varpro_step`]).
#[derive(Debug, Clone, Serialize, Default, PartialEq, Eq)]
pub struct VarproStepReport {
    /// `auto` (`run`'s rule, [`crate::solve::varpro_step::default_rounds`]) or `fixed`.
    pub mode: String,
    /// The first rounds that took it (0: off).
    pub rounds: usize,
    /// `broyden` (forward differences in the first round, Broyden's update after) or
    /// `forward-differences` (every round).
    pub jacobian: String,
    /// Steps tried (one a round).
    pub tried: usize,
    /// Steps kept (`F` dropped in some channel and the held-back observations did not get
    /// worse).
    pub kept: usize,
    /// Rounds the light model could not take it in.
    pub unsupported: usize,
}

/// The ratio step's rounds and moves ([`crate::solve::ratio_step`]).
#[derive(Debug, Clone, Serialize, Default, PartialEq, Eq)]
pub struct RatioStepReport {
    /// `auto` (the rounds from the training photos' count) or `fixed` (`--ratio-steps N`).
    pub mode: String,
    /// The first rounds that took it (0: off).
    pub rounds: usize,
    /// The fit's training photos (what `auto` decides by).
    pub training_photos: usize,
    /// What it did.
    #[serde(flatten)]
    pub moves: crate::solve::RatioMoves,
}

/// The light prior of held-out protocol `half`'s light fit (`crate::run` `half_prior`
/// module): none, the training maps' low-order shape at a weight `η`, or the light model's
/// own prior, chosen by replaying the protocol on training photos.
#[derive(Debug, Clone, Serialize, Default, PartialEq)]
pub struct HalfFitPriorReport {
    /// `auto` (chosen by the replay), `off`, `model` or `fixed`.
    pub mode: String,
    /// The prior the fit adds to the Laplacian: `none`, `training maps η …` or
    /// `light model's`.
    pub prior: String,
    /// The training maps' prior's relative noise level (0 when that prior is not used).
    pub eta: f64,
    /// The scale of the light model's noise levels in the fit when its prior is used
    /// (`crate::run` `half_prior::MODEL_PRIOR_SCALE`), else 0.
    pub model_prior_scale: f64,
    /// `--half-smoothness`: `fit` (the fit's own weight) or `fixed`.
    pub smoothness_mode: String,
    /// The Laplacian's weight `s` in the fit (`μ = s × max D_t`).
    pub smoothness: f64,
    /// Candidates of `auto`, `none` first (empty otherwise).
    pub candidates: Vec<String>,
    /// Per candidate, the mean over replayed photos of ln(right-half RMSE / RMSE without
    /// a prior) (negative: the prior predicted the right halves better).
    pub log_rmse_ratio: Vec<f64>,
    /// Training photos replayed.
    pub replayed_photos: usize,
    /// CPU seconds of the choice.
    pub cpu_seconds: f64,
}

/// The per-channel scale anchor ([`crate::solve::normalise::ScaleAnchor`]): its name and
/// the normalisation applied, in words.
#[derive(Debug, Clone, Serialize, Default, PartialEq)]
pub struct ScaleAnchorReport {
    /// `start` or `grey-world`.
    pub name: String,
    /// The rule, with its figures.
    pub rule: String,
}

impl HalfFitPriorReport {
    /// One sentence for `report.md`.
    pub fn sentence(&self) -> String {
        let what = match self.prior.as_str() {
            "none" => "the Laplacian prior alone".to_string(),
            "light model's" => format!(
                "the light model's own prior (the one the training photos' maps were fitted \
                 with) at {}× its noise levels",
                self.model_prior_scale
            ),
            _ => format!("the training maps' shape prior at η = {}", self.eta),
        };
        let weight = format!("Laplacian weight {:.1e}", self.smoothness);
        let why = if self.candidates.is_empty() {
            format!(
                "set by `--half-prior {}` and `--half-smoothness {}`",
                self.mode, self.smoothness_mode
            )
        } else {
            let scores: Vec<String> = self
                .candidates
                .iter()
                .zip(&self.log_rmse_ratio)
                .skip(1)
                .map(|(c, r)| format!("{c}: {r:+.4}"))
                .collect();
            format!(
                "{} by replaying the protocol on {} training photos (mean ln of the \
                 right-half RMSE ratio to no prior: {}; {:.1} CPU s)",
                if self.eta > 0.0 {
                    "that prior chosen"
                } else {
                    "no training-map prior chosen"
                },
                self.replayed_photos,
                scores.join(", "),
                self.cpu_seconds
            )
        };
        format!("Protocol `half` fits the light with {what}, at {weight} ({why}).")
    }
}

impl ModelReport {
    /// The model's figures as (label, value), in the order shown: one list feeds the
    /// paragraph of both `report.md` and `report.html`.
    pub fn facts(&self) -> Vec<(&'static str, String)> {
        let side = |n: usize| format!("{n}×{n}");
        vec![
            ("materials", self.materials.to_string()),
            ("basis BRDFs (lobes)", self.basis.join(", ")),
            ("light map per photo", side(self.global_resolution)),
            (
                "hemisphere map",
                format!(
                    "{} (renders {})",
                    side(self.local_resolution),
                    side(self.render_local_resolution)
                ),
            ),
            ("pre-rotated normals", side(self.normal_grid)),
            (
                "transport terms kept per observation",
                match self.kept_coefficients {
                    0 => "all".to_string(),
                    n => n.to_string(),
                },
            ),
            (
                "blended lighting rows",
                if self.blend_tolerance > 0.0 {
                    format!(
                        "smallest terms dropped up to {:e} of each row's energy",
                        self.blend_tolerance
                    )
                } else {
                    "exact".to_string()
                },
            ),
        ]
    }
}

/// Everything `report.json` holds.
#[derive(Debug, Clone, Serialize, Default)]
pub struct RunReport {
    /// Tool version.
    pub version: String,
    /// Workspace path.
    pub workspace: String,
    /// Seed of every random choice.
    pub seed: u64,
    /// The headline figure on held-out photos: protocol `half`'s RMSE after scale over the
    /// naive `baseline`'s, means over the photos scored under both, same pixels (below 1:
    /// the fit predicts unseen photos better than their training colours); `null` without
    /// such photos.
    pub headline: Option<f64>,
    /// The means and photo count behind `headline`.
    pub headline_detail: Option<metrics::Headline>,
    /// The light prior of protocol `half`'s light fit, when photos are held out.
    pub half_fit_prior: Option<HalfFitPriorReport>,
    /// How the held-out photos were chosen, in words.
    pub holdout_rule: String,
    /// Held-out figures, per image and protocol.
    pub holdout: Vec<HoldoutEntry>,
    /// Literature metrics (PSNR-H, PSNR-L, SSIM) per held-out photo and protocol, on the
    /// same pixels as `holdout`.
    pub metrics: Vec<metrics::MetricsEntry>,
    /// Synthetic workspaces: training photos (five megapixels' worth) under their true light.
    pub truth_check: Vec<metrics::TruthCheckEntry>,
    /// The fit's mean error under the true light over the floor's
    /// ([`metrics::truth_check_floor_ratio`]); absent unless every checked photo has a floor.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub truth_check_floor_ratio: Option<f64>,
    /// Synthetic workspaces: diffuse albedo per material, recovered against the truth.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub albedo_truth: Option<metrics::AlbedoTruth>,
    /// RMSE over all training observations.
    pub train_rmse: f64,
    /// Per training photo.
    pub train: Vec<TrainEntry>,
    /// Error against run time.
    pub timeline: Vec<TimelinePoint>,
    /// `{stage: wall seconds}`.
    pub stages: BTreeMap<String, f64>,
    /// Per stage: wall, CPU, peak memory, in run order.
    pub stage_details: Vec<StageRecord>,
    /// Peak resident memory of the run.
    pub peak_memory_bytes: u64,
    /// The model chosen.
    pub model: ModelReport,
    /// Notes on what the import found and picked, skipped photos, etc.
    pub notes: Vec<String>,
    /// Condition-number estimates of the systems the solver saw, by name.
    pub conditioning: BTreeMap<String, f64>,
    /// What the solver did with each condition number (regulariser, threshold, advice).
    pub conditioning_use: Vec<String>,
    /// With several starts ([`crate::solve::starts`]): each one's score and the one kept.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub starts: Option<crate::solve::starts::MultiStart>,
}

/// RMSE and best-scale RMSE of `pred` against `truth` (both linear RGB), over the
/// pixels where `mask` holds: `(rmse, rmse_scaled, scale, pixels)`.
pub fn compare(truth: &[[f32; 3]], pred: &[[f32; 3]], mask: &[bool]) -> (f64, f64, f64, usize) {
    let (mut syy, mut syp, mut spp, mut se, mut n) = (0.0, 0.0, 0.0, 0.0, 0usize);
    for ((t, p), &m) in truth.iter().zip(pred).zip(mask) {
        if !m {
            continue;
        }
        for c in 0..3 {
            let (y, q) = (t[c] as f64, p[c] as f64);
            syy += y * y;
            syp += y * q;
            spp += q * q;
            se += (y - q) * (y - q);
        }
        n += 1;
    }
    if n == 0 {
        return (f64::NAN, f64::NAN, 1.0, 0);
    }
    let count = 3.0 * n as f64;
    let scale = if spp > 0.0 { syp / spp } else { 1.0 };
    // Σ (y − s q)² = Σy² − 2s Σyq + s² Σq²; clamp rounding below zero.
    let se_scaled = (syy - 2.0 * scale * syp + scale * scale * spp).max(0.0);
    ((se / count).sqrt(), (se_scaled / count).sqrt(), scale, n)
}

/// PSNR in dB of an RMSE against a peak of 1.
pub fn psnr(rmse: f64) -> f64 {
    if rmse > 0.0 {
        -20.0 * rmse.log10()
    } else {
        f64::INFINITY
    }
}

impl RunReport {
    /// Write `report.json`, `report.md` and the figures `plots/*.png` into `dir`.
    /// `maps`: `(caption, width, height, lat-long pixels)` of the environment maps to show.
    pub fn write(&self, dir: &Path, maps: &[(String, usize, usize, &[[f32; 3]])]) -> Result<()> {
        let plots = dir.join("plots");
        std::fs::create_dir_all(&plots).map_err(|e| Error::io(&plots, e))?;
        let json = serde_json::to_string_pretty(&json_safe(self))
            .map_err(|e| Error::Internal(e.to_string()))?;
        let path = dir.join("report.json");
        std::fs::write(&path, json).map_err(|e| Error::io(&path, e))?;

        self.plot_timeline(&plots.join("error_vs_time.png"))?;
        self.plot_per_photo(&plots.join("per_photo_rmse.png"))?;
        self.plot_stages(&plots.join("stages.png"))?;
        if !maps.is_empty() {
            plot::gallery(&plots.join("envmaps.png"), maps)?;
        }
        let path = dir.join("report.md");
        std::fs::write(&path, self.markdown(!maps.is_empty())).map_err(|e| Error::io(&path, e))?;
        Ok(())
    }

    fn plot_timeline(&self, path: &Path) -> Result<()> {
        let t = &self.timeline;
        let pts = |f: &dyn Fn(&TimelinePoint) -> Option<f64>| -> Vec<(f64, f64)> {
            t.iter()
                .filter_map(|p| f(p).map(|v| (p.seconds, v)))
                .collect()
        };
        let mut rmse = vec![plot::Series {
            label: "training RMSE",
            points: pts(&|p| Some(p.train_rmse)),
            color: plot::PALETTE[0],
        }];
        let held = pts(&|p| p.holdout_rmse);
        if !held.is_empty() {
            rmse.push(plot::Series {
                label: "held-out RMSE",
                points: held,
                color: plot::PALETTE[1],
            });
        }
        let objective = vec![plot::Series {
            label: "objective (Eq. 9)",
            points: pts(&|p| Some(p.objective)),
            color: plot::PALETTE[2],
        }];
        plot::line_panels(
            path,
            "seconds since the estimator started",
            &[
                ("Objective against run time", "objective", objective),
                ("Error against run time", "RMSE (linear RGB)", rmse),
            ],
        )
    }

    fn plot_per_photo(&self, path: &Path) -> Result<()> {
        let mut rows: Vec<(String, f64, plotters::style::RGBColor)> = self
            .train
            .iter()
            .map(|e| (format!("{} (train)", e.image), e.rmse, plot::PALETTE[0]))
            .collect();
        for h in &self.holdout {
            rows.push((
                format!("{} ({}, scaled)", h.image, h.protocol),
                h.rmse_scaled,
                plot::PALETTE[1],
            ));
        }
        plot::bars(path, "RMSE per photo", "RMSE (linear RGB)", &rows, &|v| {
            format!("{v:.4}")
        })
        .map(drop)
    }

    fn plot_stages(&self, path: &Path) -> Result<()> {
        let rows: Vec<_> = self
            .stage_details
            .iter()
            .map(|s| {
                (
                    format!("{} ({} MiB)", s.name, s.peak_memory_bytes >> 20),
                    s.seconds,
                    plot::PALETTE[3],
                )
            })
            .collect();
        plot::bars(
            path,
            "Wall time per stage (peak memory in brackets)",
            "seconds",
            &rows,
            &|v| format!("{v:.2} s"),
        )
        .map(drop)
    }
}

/// JSON cannot hold NaN or infinities: serialise them as `null`.
fn json_safe(report: &RunReport) -> serde_json::Value {
    fn fix(v: serde_json::Value) -> serde_json::Value {
        match v {
            serde_json::Value::Array(a) => {
                serde_json::Value::Array(a.into_iter().map(fix).collect())
            }
            serde_json::Value::Object(o) => {
                serde_json::Value::Object(o.into_iter().map(|(k, v)| (k, fix(v))).collect())
            }
            other => other,
        }
    }
    // serde_json already writes non-finite f64 as null; walk the value to be explicit.
    fix(serde_json::to_value(report).unwrap_or(serde_json::Value::Null))
}

#[cfg(test)]
mod tests;
