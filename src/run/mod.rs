//! `relight-cpc run`: the whole pipeline, workspace → scene → observations → transport →
//! estimate → renders and report (docs/method.md).
//!
//! The stages, in order, each timed and measured by [`crate::stages`]:
//! 1. `import`: discover the workspace, read the model, the mesh and the photos;
//! 2. `observations`: BVH, per-vertex observations in every registered photo;
//! 3. `visibility`: per-vertex visibility over the local hemisphere (Sec. 3);
//!    with [`RunOptions::adaptive`], `pilot`: a cheap held-out fit decides the materials,
//!    the basis BRDFs, the map resolution and `keep` ([`crate::solve::adapt`]; duplicate photos
//!    are skipped after step 2), each decision written to the report with its reason;
//! 4. `rotation`: the wavelet rotations `R_ν` (Sec. 4.2, Eq. 6);
//! 5. `transport`: `g_{p,b} = R_nᵀ T_x ρ_b(ω_o)` per observation (Eq. 5–8);
//! 6. `estimate`: alternating lighting (Eq. 10) and material (Eq. 11–12) steps;
//! 7. `evaluation`: held-out photos under each protocol of docs/method.md ("Held-out evaluation");
//! 8. `output`: environment maps, materials, coloured mesh, renders, report.
//!
//! The condition numbers the estimator sees (lighting, Eq. 10; λ and w, Eq. 11–12) go to
//! the report with what bounds each (the Laplacian prior, the λ ridge, the minimum-norm w
//! fallback) and, past [`crate::solve::adapt::KAPPA_LIGHTING`] / [`crate::solve::adapt::KAPPA_LAMBDA`],
//! what to change; a non-finite estimate stops the run with those figures.
//!
//! The output folder follows [`crate::out_dir`]: everything is written into a hidden
//! staging sibling and moved into place, stamp last, only when complete, so an interrupted
//! run never leaves a folder that looks finished.

mod baseline;
mod clipped;
mod decisions;
mod evaluate;
mod example;
mod fit;
pub mod geotag_suns;
pub mod half_fit;
pub mod half_prior;
mod holdout;
mod html_inputs;
pub mod light_groups;
mod notes;
mod options;
mod output;
mod pipeline;
pub mod progress;
mod shading;
mod sky_report;
mod state;
mod tracker;
mod transients;
mod truth;
mod truth_check;
mod write;

pub use clipped::auto_reads_bounds;
pub use example::builtin_example;
pub use fit::photo_halves;
pub use holdout::{default_holdout, DEFAULT_HOLDOUT_EVERY};
pub(crate) use options::smoothness_base;
pub use options::{
    achromatic_for, pilot_smoothness_for, scene_light, smoothness_for, weights_bic_for, Achromatic,
    Clipped, FitShape, Holdout, LargeMeshSettings, MaterialCount, PriorStrength, RatioSteps,
    Restart, RunOptions, StartBrightness, VarproPlan, VarproSteps, WeightsSmoothness, WeightsSum,
    ACHROMATIC_FROM_MATERIALS, BIC_FROM_PHOTOS, CLIPPED_AUTO_SHARE, CONSTRAINED_FROM_MATERIALS,
    DEFAULT_LIGHTING_SAMPLE, DEFAULT_LIGHT_CHOICE_HALVES, DEFAULT_LIGHT_GROUP_MINUTES, LARGE_MESH,
    LIGHTING_SAMPLE_MAX_RATIO, PRIOR_FROM_PHOTOS, SMOOTHNESS_FROM_PHOTOS,
};
pub use progress::Progress;
pub use shading::{fine_rays, render_local_resolution};
pub use truth::{Truth, TruthPhoto};

use crate::import::scene::{self, Scene};
use crate::observe::trace::SceneBvh;
use crate::observe::Observations;
use crate::report::RunReport;
use crate::solve::cluster::initial_materials;
use crate::solve::{self, EstimateOptions};
use crate::sphere::rotation::Rotation;
use crate::transport::brdf::BasisBrdf;
use crate::transport::visibility;
use crate::{Error, Result, Vec3};
use nalgebra::Matrix3;
use std::path::{Path, PathBuf};

/// What a finished run hands back (also written to `OUT/report.json`).
#[derive(Debug)]
pub struct RunSummary {
    /// The output folder.
    pub out: PathBuf,
    /// The report that was written.
    pub report: RunReport,
}

/// World up from the cameras (docs/conventions.md): the mean of their `−y` axes in world
/// coordinates (COLMAP cameras have y pointing down in the image).
pub fn estimate_up(views: &[scene::View]) -> Option<Vec3> {
    let sum: Vec3 = views
        .iter()
        .map(|v| {
            -v.image
                .cam_from_world_rotation()
                .matrix()
                .row(1)
                .transpose()
        })
        .sum();
    (sum.norm() > 1e-9 * views.len().max(1) as f64).then(|| sum.normalize())
}

/// The matrix with rows `e_x, e_y, e_z` (environment from world).
pub fn env_from_world(up: &Vec3) -> Result<Matrix3<f64>> {
    let f = crate::sphere::env_frame(up)
        .ok_or_else(|| Error::Config("the up vector must be non-zero and finite".into()))?;
    Ok(Matrix3::from_rows(&[
        f[0].transpose(),
        f[1].transpose(),
        f[2].transpose(),
    ]))
}

/// Indices of the held-out views under `holdout` (the truth manifest's list for
/// [`Holdout::Default`]). Unknown names are an error naming them.
fn holdout_views(scene: &Scene, holdout: &Holdout, truth: Option<&Truth>) -> Result<Vec<usize>> {
    let names: Vec<String> = match holdout {
        Holdout::None => Vec::new(),
        Holdout::Default => match truth {
            Some(t) => t.held_out.clone(),
            None => default_holdout(scene.views.len())
                .into_iter()
                .map(|i| scene.views[i].image.name.clone())
                .collect(),
        },
        Holdout::Names(n) => n.clone(),
        Holdout::Every(k) => scene
            .views
            .iter()
            .enumerate()
            .filter(|(i, _)| (i + 1) % k == 0)
            .map(|(_, v)| v.image.name.clone())
            .collect(),
    };
    let mut idx = Vec::new();
    for name in &names {
        match scene.views.iter().position(|v| &v.image.name == name) {
            Some(i) => idx.push(i),
            None if matches!(holdout, Holdout::Default) => {}
            None => {
                return Err(Error::Config(format!(
                    "--holdout {name}: no registered photo of that name (known: {})",
                    scene
                        .views
                        .iter()
                        .map(|v| v.image.name.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                )))
            }
        }
    }
    idx.sort_unstable();
    idx.dedup();
    if idx.len() >= scene.views.len() {
        return Err(Error::Config(format!(
            "all {} photos are held out: at least one must be used for fitting",
            scene.views.len()
        )));
    }
    Ok(idx)
}

/// How the held-out photos `held` were chosen, in words (console and report).
fn holdout_rule(scene: &Scene, holdout: &Holdout, has_truth: bool, held: &[usize]) -> String {
    let names = held
        .iter()
        .map(|&i| scene.views[i].image.name.as_str())
        .collect::<Vec<_>>()
        .join(", ");
    let n = format!("{} of {} photos", held.len(), scene.views.len());
    match holdout {
        Holdout::Default if has_truth => {
            format!("{n}, the workspace's truth/manifest.json list ({names})")
        }
        Holdout::Default if held.is_empty() => {
            format!("none: the workspace has {} photo(s) and the fit needs one", scene.views.len())
        }
        Holdout::Default => format!(
            "{n}, chosen by default (every {DEFAULT_HOLDOUT_EVERY}th in name order, at least one): {names}; the fit does not use them, they score its renders (--holdout none fits on every photo)"
        ),
        Holdout::None => "none (--holdout none)".into(),
        Holdout::Names(_) => format!("{n}, named with --holdout ({names})"),
        Holdout::Every(k) => format!("{n}, every {k}th (--holdout-every {k}): {names}"),
    }
}

/// Choose the number of materials from the per-vertex mean colours: the smallest K in
/// 1..=6 after which one more cluster lowers the k-means inertia of the hue features by
/// less than a quarter (an elbow rule), with the reason in words.
pub fn choose_material_count(mean_rgb: &[[f64; 3]], seen: &[bool], seed: u64) -> (usize, String) {
    let feats: Vec<[f64; 3]> = mean_rgb
        .iter()
        .zip(seen)
        .filter(|(_, &s)| s)
        .map(|(c, _)| crate::solve::cluster::hue_feature(*c))
        .collect();
    let inertia = |k: usize| -> Option<f64> {
        let init = initial_materials(mean_rgb, seen, k, seed).ok()?;
        let mut sum = 0.0;
        let mut fi = 0;
        for (x, &s) in seen.iter().enumerate() {
            if !s {
                continue;
            }
            let c = init.centroids.get(init.labels[x])?;
            let f = feats[fi];
            fi += 1;
            sum += (0..3).map(|i| (f[i] - c[i]).powi(2)).sum::<f64>();
        }
        Some(sum)
    };
    let total = inertia(1).unwrap_or(0.0);
    if total <= 1e-12 * feats.len().max(1) as f64 {
        return (
            1,
            "materials: 1, the observed colours all have the same hue and saturation".into(),
        );
    }
    let mut prev = total;
    for k in 1..6 {
        let next = inertia(k + 1).unwrap_or(prev);
        if next > 0.75 * prev {
            return (
                k,
                format!(
                    "materials: {k} (auto), k-means of (cos 2πH, sin 2πH, S): a {}th cluster would remove only {:.0}% of the remaining spread ({:.3e} → {:.3e})",
                    k + 1,
                    100.0 * (1.0 - next / prev.max(1e-300)),
                    prev,
                    next
                ),
            );
        }
        prev = next;
    }
    (
        6,
        "materials: 6 (auto, the cap): every extra cluster still removed over a quarter of the spread".into(),
    )
}

/// Per-vertex mean colour (α-weighted) over the observations, and whether each vertex was
/// seen ([`Observations::seen_vertices`]).
pub fn mean_colours(obs: &Observations, n_vertices: usize) -> (Vec<[f64; 3]>, Vec<bool>) {
    let mut sum = vec![[0.0f64; 3]; n_vertices];
    let mut wsum = vec![0.0f64; n_vertices];
    for p in 0..obs.len() {
        let v = obs.vertex[p] as usize;
        let w = obs.weight[p] as f64;
        if w <= 0.0 {
            continue;
        }
        for (s, &x) in sum[v].iter_mut().zip(&obs.rgb[p]) {
            *s += w * x as f64;
        }
        wsum[v] += w;
    }
    let seen = obs.seen_vertices(n_vertices);
    let mean = sum
        .iter()
        .zip(&wsum)
        .map(|(s, &w)| {
            if w > 0.0 {
                [s[0] / w, s[1] / w, s[2] / w]
            } else {
                [0.0; 3]
            }
        })
        .collect();
    (mean, seen)
}

/// The state shared by the evaluation and output stages.
pub(crate) struct Fitted<'a> {
    pub scene: &'a Scene,
    pub photos: &'a [crate::import::photo::Photo],
    pub train: Vec<usize>,
    pub held: Vec<usize>,
    pub env_from_world: Matrix3<f64>,
    pub normals_env: Vec<Vec3>,
    pub vis: std::sync::Arc<visibility::Visibility>,
    pub rot: Rotation,
    /// The renderer's visibility and rotation ([`shading`] module docs); the same
    /// allocation as `vis` when both have the estimator's resolution.
    pub render_vis: std::sync::Arc<visibility::Visibility>,
    pub render_rot: crate::sphere::rotation::SplatRotation,
    pub basis: Vec<BasisBrdf>,
    pub est: solve::Estimate,
    pub beta: Vec<[f64; 3]>,
    /// The estimator's predictions at each training photo's observations (vertex, linear
    /// RGB), in training order: what the training renders show where a vertex was observed.
    pub train_predictions: Vec<Vec<(u32, [f32; 3])>>,
    /// The options in effect (the adaptive pilot's choices applied).
    pub opts: RunOptions,
    pub estimate_options: EstimateOptions,
    pub bvh: SceneBvh,
    /// The naive baseline's per-vertex colours ([`baseline`]).
    pub baseline: baseline::VertexMedians,
    /// The light prior and Laplacian weight of held-out protocol (b)'s fit
    /// ([`half_prior`]); `None` before the evaluation chose them: no prior, the training
    /// fit's weight.
    pub half_fit: Option<half_prior::HalfFitSetup>,
    /// Per held-out view (in `held`'s order), its sun from its geotag when protocol (b)
    /// fits its light within the sun and sky ([`half_fit::held_out_suns`]); empty before
    /// the evaluation or when none does.
    pub held_out_suns: Vec<Option<crate::solve::light::sky::clock::ClockSun>>,
}

impl Fitted<'_> {
    /// The observations of view `v` alone (one photo range), with the run's options.
    pub(crate) fn observations_of(&self, v: usize) -> crate::observe::Observations {
        crate::observe::extract(
            &self.scene.mesh,
            &self.bvh,
            std::slice::from_ref(&self.scene.views[v]),
            std::slice::from_ref(&self.photos[v]),
            &observe_options(&self.opts),
        )
    }

    /// The fit's transport (its maps, lobes, visibility and rotation) for observations
    /// `obs` it did not train on: a held-out photo's, or a training photo replayed.
    pub(crate) fn transport_for(
        &self,
        obs: &crate::observe::Observations,
    ) -> Result<crate::transport::Transport> {
        let topts = self.opts.transport_options();
        crate::transport::build(
            &self.normals_env,
            obs,
            &self.env_from_world,
            &self.vis,
            &self.basis,
            &self.rot,
            &topts,
        )
    }
}

/// The observation options of a run: the defaults, with the edge margin as
/// [`RunOptions::edge_margin`] says.
pub(crate) fn observe_options(o: &RunOptions) -> crate::observe::ObserveOptions {
    let d = crate::observe::ObserveOptions::default();
    crate::observe::ObserveOptions {
        edge_margin: if o.edge_margin { d.edge_margin } else { None },
        ..d
    }
}

/// Run the pipeline with `opts`, reporting progress to `progress`. The output folder is
/// claimed before any work ([`crate::out_dir`]): results are written into a staging folder
/// and moved into place, stamp last, only when complete.
pub fn run(opts: &RunOptions) -> Result<RunSummary> {
    opts.check()?;
    let progress = Progress::new(opts.progress);
    let inputs: Vec<&Path> = std::iter::once(opts.workspace.as_path())
        .chain(opts.mesh.as_deref())
        .collect();
    let out = crate::out_dir::OutDir::claim(&opts.out, opts.force, &inputs, "run")?;
    let report = pipeline::run_into(opts, out.path(), &progress)?;
    let out = out.commit()?;
    progress.finish(
        &format!("results in {}", out.display()),
        &report.stage_details,
    );
    Ok(RunSummary { out, report })
}

/// RMSE per training photo over its observations with `α > 0` (linear RGB).
fn train_errors(
    scene: &Scene,
    train: &[usize],
    obs: &Observations,
    pred: &[[f64; 3]],
) -> Vec<crate::report::TrainEntry> {
    train
        .iter()
        .enumerate()
        .map(|(k, &v)| {
            let (mut se, mut n) = (0.0, 0usize);
            for p in obs.photo_ranges[k].clone() {
                if obs.weight[p] > 0.0 {
                    for (&y, &q) in obs.rgb[p].iter().zip(&pred[p]) {
                        se += (y as f64 - q).powi(2);
                    }
                    n += 1;
                }
            }
            crate::report::TrainEntry {
                image: scene.views[v].image.name.clone(),
                rmse: if n > 0 {
                    (se / (3 * n) as f64).sqrt()
                } else {
                    f64::NAN
                },
                observations: n,
            }
        })
        .collect()
}

/// The condition numbers of the report, by name.
fn conditioning_map(c: &solve::Conditioning) -> std::collections::BTreeMap<String, f64> {
    let mut conditioning = std::collections::BTreeMap::new();
    if let Some(max) = c.lighting_max() {
        conditioning.insert("lighting (max over photos, lower bound)".to_string(), max);
    }
    for (ch, v) in ["R", "G", "B"].iter().zip(c.lambda) {
        conditioning.insert(format!("material weights λ, channel {ch}"), v);
    }
    conditioning.insert(
        "blending weights w (max over vertices)".into(),
        c.weights_max,
    );
    conditioning
}

/// What the solver did with each condition number it saw (issue 8), in words: the figure,
/// the digits of float64's ~16 it costs (`log₁₀ κ`), the regulariser that bounds it and,
/// past the thresholds of [`crate::solve::adapt`], what to change.
fn conditioning_use(
    c: &solve::Conditioning,
    eopts: &EstimateOptions,
    adaptive: bool,
) -> Vec<String> {
    let digits = |k: f64| k.max(1.0).log10();
    let mut out = Vec::new();
    // Condition numbers are ≥ 1: 0 means no photo has a bound.
    let lighting = c.lighting_max().unwrap_or(0.0);
    if lighting > 0.0 {
        let mut line = format!(
            "lighting (Eq. 10): κ ≥ {lighting:.2e} (largest over photos; a lower bound from the Ritz values of the conjugate-gradient steps), about {:.0} of 16 digits; the Laplacian prior μ = {:.0e} × the largest texel-basis diagonal regularises the directions the photos do not see, and the QP stops at a relative KKT residual of {:.0e}",
            digits(lighting),
            eopts.smoothness,
            eopts.qp_rel_tol
        );
        if lighting > crate::solve::adapt::KAPPA_LIGHTING {
            line.push_str(&format!(
                "; above {:.0e}, so the solution's unconstrained directions are set by rounding: {}",
                crate::solve::adapt::KAPPA_LIGHTING,
                if adaptive && eopts.smoothness >= 1e-4 {
                    "the adaptive model already raised the prior".to_string()
                } else {
                    "raise --smoothness (1e-4 or more) or run with --adaptive on".to_string()
                }
            ));
        }
        if c.qp_unconverged > 0 {
            line.push_str(&format!(
                "; {} photos' lighting solves hit the iteration cap first ({} QPs at the alternation's cap of {} GPCG iterations, by design; otherwise {})",
                c.qp_unconverged,
                c.qp_alternation_capped,
                eopts.alternation_qp_iters.unwrap_or(eopts.qp_max_iter),
                eopts.qp_max_iter
            ));
        }
        out.push(line);
    }
    let lam = c.lambda.iter().copied().fold(0.0, f64::max);
    let mut line = format!(
        "material weights λ (Eq. 11): κ = {lam:.2e} (exact, largest over channels), about {:.0} digits; the ridge {:.0e} × the largest diagonal entry bounds it by about {:.0e}",
        digits(lam),
        eopts.beta,
        1.0 / eopts.beta.max(1e-300)
    );
    if lam > crate::solve::adapt::KAPPA_LAMBDA {
        line.push_str(&format!(
            "; above {:.0e}: two basis lobes are nearly indistinguishable in these photos and the ridge, not the data, splits the weight between them: {}",
            crate::solve::adapt::KAPPA_LAMBDA,
            if adaptive {
                "the adaptive pilot's held-out ablation keeps only one of such lobes"
            } else {
                "drop one of the similar lobes from --basis or run with --adaptive on"
            }
        ));
    }
    out.push(line);
    out.push(format!(
        "blending weights w (Eq. 12): κ ≤ {:.2e} over the vertices with a full-rank system, about {:.0} digits; {} vertices with fewer independent observations than materials get the minimum-norm non-negative solution",
        c.weights_max,
        digits(c.weights_max),
        c.weights_singular
    ));
    out
}

/// Stop with an explanation rather than write non-finite maps or materials.
fn check_finite(
    est: &solve::Estimate,
    conditioning: &std::collections::BTreeMap<String, f64>,
) -> Result<()> {
    let bad_light = est
        .lights
        .iter()
        .position(|l| l.iter().any(|ch| ch.iter().any(|v| !v.is_finite())));
    let bad_lambda = est
        .lambda
        .iter()
        .flatten()
        .flatten()
        .any(|v| !v.is_finite());
    let bad_w = est.weights.iter().any(|v| !v.is_finite());
    if bad_light.is_none() && !bad_lambda && !bad_w {
        return Ok(());
    }
    let what = match bad_light {
        Some(i) => format!("the light of training photo {i}"),
        None if bad_lambda => "the material weights λ".to_string(),
        None => "the blending weights w".to_string(),
    };
    Err(Error::Numeric {
        stage: "estimate".into(),
        message: format!(
            "{what} came out non-finite; the condition numbers the solver saw were {}; raise --smoothness, drop similar lobes from --basis, or use fewer --materials",
            conditioning
                .iter()
                .map(|(k, v)| format!("{k} {v:.2e}"))
                .collect::<Vec<_>>()
                .join(", ")
        ),
    })
}
