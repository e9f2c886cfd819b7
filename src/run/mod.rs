//! `relight-cpc run`: the whole pipeline, workspace → scene → observations → transport →
//! estimate → renders and report (DESIGN §1, §4).
//!
//! The stages, in order, each timed and measured by [`crate::stages`]:
//! 1. `import`: discover the workspace, read the model, the mesh and the photos;
//! 2. `observations`: BVH, per-vertex observations in every registered photo;
//! 3. `visibility`: per-vertex visibility over the local hemisphere (Sec. 3);
//!    with [`RunOptions::adaptive`], `pilot`: a cheap held-out fit decides the materials,
//!    the basis BRDFs, the map resolution and `keep` ([`crate::adapt`]; duplicate photos
//!    are skipped after step 2), each decision written to the report with its reason;
//! 4. `rotation`: the wavelet rotations `R_ν` (Sec. 4.2, Eq. 6);
//! 5. `transport`: `g_{p,b} = R_nᵀ T_x ρ_b(ω_o)` per observation (Eq. 5–8);
//! 6. `estimate`: alternating lighting (Eq. 10) and material (Eq. 11–12) steps;
//! 7. `evaluation`: held-out photos under each protocol of DESIGN §4;
//! 8. `output`: environment maps, materials, coloured mesh, renders, report.
//!
//! The condition numbers the estimator sees (lighting, Eq. 10; λ and w, Eq. 11–12) go to
//! the report with what bounds each (the Laplacian prior, the λ ridge, the minimum-norm w
//! fallback) and, past [`crate::adapt::KAPPA_LIGHTING`] / [`crate::adapt::KAPPA_LAMBDA`],
//! what to change; a non-finite estimate stops the run with those figures.
//!
//! The output folder follows [`crate::out_dir`]: everything is written into a hidden
//! staging sibling and moved into place, stamp last, only when complete, so an interrupted
//! run never leaves a folder that looks finished.

mod baseline;
mod evaluate;
mod example;
mod holdout;
mod html_inputs;
mod output;
pub mod progress;
mod truth_check;

pub use evaluate::{fine_rays, render_local_resolution, Truth};
pub use example::builtin_example;
pub use holdout::{default_holdout, DEFAULT_HOLDOUT_EVERY};
pub use progress::Progress;

use crate::brdf::BasisBrdf;
use crate::cluster::initial_materials;
use crate::estimate::{self, EstimateOptions, Materials0, Problem, Robust};
use crate::observe::{self, Observations, ObserveOptions};
use crate::report::{ModelReport, RunReport, TimelinePoint};
use crate::rotation::{Rotation, RotationForm};
use crate::scene::{self, Scene};
use crate::stages::Stages;
use crate::starts;
use crate::trace::SceneBvh;
use crate::transport::{self, Transport, TransportOptions};
use crate::visibility;
use crate::workspace::Workspace;
use crate::{Error, Result, Vec3};
use nalgebra::Matrix3;
use std::path::{Path, PathBuf};

/// How many materials to fit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MaterialCount {
    /// Choose from the data: with [`RunOptions::adaptive`], the smallest count within 1%
    /// of the best held-out error of a pilot fit ([`crate::adapt`]); without it, the
    /// smallest count whose k-means clustering of the hue features leaves little
    /// unexplained (see [`choose_material_count`]).
    Auto,
    /// Exactly this many.
    Fixed(usize),
}

/// Which photos are held out.
#[derive(Debug, Clone, PartialEq, Default)]
pub enum Holdout {
    /// The workspace's `truth/manifest.json` list when present, else every 5th registered
    /// photo, at least one ([`default_holdout`]).
    #[default]
    Default,
    /// No photo.
    None,
    /// These image names.
    Names(Vec<String>),
    /// Every N-th registered photo (by name order), starting with the N-th.
    Every(usize),
}

/// Checked options of a run.
#[derive(Debug, Clone)]
pub struct RunOptions {
    /// The COLMAP workspace.
    pub workspace: PathBuf,
    /// Output folder.
    pub out: PathBuf,
    /// A mesh to use instead of the workspace's.
    pub mesh: Option<PathBuf>,
    /// Held-out photos.
    pub holdout: Holdout,
    /// World up; estimated from the cameras when `None`.
    pub up: Option<Vec3>,
    /// Number of materials.
    pub materials: MaterialCount,
    /// Basis BRDF specifications (`lambert`, `phong:50`, `ggx:0.2`); the first Lambertian
    /// one carries the diffuse colour.
    pub basis: Vec<BasisBrdf>,
    /// Global octahedral map side.
    pub global_resolution: usize,
    /// Local hemi-octahedral map side.
    pub local_resolution: usize,
    /// Local map side of the renderer (held-out views, renders, `relight.bin`); `None`:
    /// `local_resolution` ([`evaluate::render_local_resolution`]).
    pub render_local_resolution: Option<usize>,
    /// Normal-grid side of the rotation.
    pub normal_grid: usize,
    /// Haar coefficients kept per transport row (0 = all).
    pub keep: usize,
    /// Visibility rays per local texel.
    pub rays_per_texel: usize,
    /// Outer iterations at most.
    pub max_iterations: usize,
    /// Stop when the objective improves by less than this fraction.
    pub rel_tol: f64,
    /// Laplacian smoothness, as a fraction of the largest system value.
    pub smoothness: f64,
    /// IRLS passes per lighting step (1 = no reweighting).
    pub irls_iterations: usize,
    /// GPCG iterations per lighting QP inside the alternation
    /// ([`EstimateOptions::alternation_qp_iters`]); 0 = every QP to the KKT tolerance.
    pub lighting_qp_iterations: usize,
    /// Conjugate-gradient steps per GPCG iteration of a lighting QP inside the alternation
    /// ([`EstimateOptions::alternation_cg_iters`]); 0 = the solver's own cap
    /// ([`EstimateOptions::qp_max_cg`]).
    pub lighting_cg_iterations: usize,
    /// Early stopping: outer iterations without a better validation score before the
    /// alternation stops ([`EstimateOptions::patience`]).
    pub patience: usize,
    /// At most this many observations per photo in its lighting QPs, a stratified sample
    /// ([`EstimateOptions::lighting_sample`]); 0 = all.
    pub lighting_sample: usize,
    /// Starts of the alternation tried, the best kept ([`crate::starts`]; not in the
    /// paper): 1 = the paper's clustered start alone. Each start costs one estimate.
    pub starts: usize,
    /// Lower bound on IRLS's robust scale relative to each photo's RMS radiance
    /// ([`EstimateOptions::robust_floor`]; 0 = the residuals' MAD alone).
    pub robust_floor: f64,
    /// Fraction of the training observations held back, seeded, for early stopping
    /// ([`EstimateOptions::validation_fraction`]; 0 = off: the last iterate is returned).
    pub validation: f64,
    /// Overexposure threshold on the encoded [0, 1] scale.
    pub clip: f32,
    /// Seed of every random choice.
    pub seed: u64,
    /// Progress bars on standard error.
    pub progress: bool,
    /// Replace an existing output folder.
    pub force: bool,
    /// Write renders of every view (not only held-out ones).
    pub render_training: bool,
    /// Leave out what the scene does not need ([`crate::adapt`]): redundant photos,
    /// basis BRDFs whose weights vanish, map resolution and coefficient budget beyond what
    /// the kept lobes resolve; the number of materials by held-out error. The requested
    /// resolutions and `keep` are then upper bounds. Off in [`RunOptions::new`] (the full
    /// model, as the benchmarks' knobs assume); the CLI turns it on unless `--adaptive off`.
    pub adaptive: bool,
    /// The per-photo light model ([`crate::light_choose`]): the paper's free map, the
    /// map under the statistical prior, or both and the lower validation score kept.
    pub light: crate::light_choose::LightChoice,
}

/// Default of [`RunOptions::lighting_sample`]: 2,000 observations per photo. On
/// `spot-varying` at 30K vertices (13 photos of 1 MP, the Minerva model;
/// `bench-results/lighting-sample.md`) the estimate took 5.3× less CPU than with every
/// observation (32.6 against 171.3 s; the run 2.3×, 119.4 against 276.7 s) with held-out
/// error 0.07732 against 0.07711 (+0.3%); 4,000 took 65.7 s at 0.07806 (+1.2%): the error
/// moves by about 1% either way with the sample, not monotonically. Photos with fewer
/// fitted observations (the built-in example, scenes under ~6,000 vertices) are not
/// sampled.
pub const DEFAULT_LIGHTING_SAMPLE: usize = 2000;

/// The lighting sample's check fails (a note in the report says so) when the fit's relative
/// RMSE on the observations outside the samples exceeds this multiple of that inside
/// ([`crate::estimate::SampleCheck`]): a 10% gap is well beyond the sampling noise of a
/// mean square over thousands of observations (`√(2/n)` ≈ 2% at n = 5,000).
pub const LIGHTING_SAMPLE_MAX_RATIO: f64 = 1.1;

impl RunOptions {
    /// Default of [`RunOptions::lighting_qp_iterations`]: the estimator's
    /// ([`EstimateOptions::alternation_qp_iters`], `None` → 0).
    pub fn default_lighting_qp_iterations() -> usize {
        EstimateOptions::default().alternation_qp_iters.unwrap_or(0)
    }
    /// Default of [`RunOptions::lighting_cg_iterations`]: the estimator's
    /// ([`EstimateOptions::alternation_cg_iters`], `None` → 0).
    pub fn default_lighting_cg_iterations() -> usize {
        EstimateOptions::default().alternation_cg_iters.unwrap_or(0)
    }
    /// Default of [`RunOptions::patience`]: the estimator's ([`EstimateOptions::patience`]).
    pub fn default_patience() -> usize {
        EstimateOptions::default().patience
    }
    /// Defaults for a workspace (the README says why each default).
    pub fn new(workspace: PathBuf, out: PathBuf) -> Self {
        RunOptions {
            workspace,
            out,
            mesh: None,
            holdout: Holdout::Default,
            up: None,
            materials: MaterialCount::Auto,
            basis: vec![
                BasisBrdf::Lambert,
                BasisBrdf::Phong { exponent: 50.0 },
                BasisBrdf::Phong { exponent: 500.0 },
            ],
            global_resolution: 64,
            local_resolution: 32,
            render_local_resolution: None,
            normal_grid: 32,
            keep: 128,
            rays_per_texel: 2,
            max_iterations: 8,
            rel_tol: 1e-3,
            smoothness: 1e-3,
            irls_iterations: 3,
            lighting_qp_iterations: Self::default_lighting_qp_iterations(),
            lighting_cg_iterations: Self::default_lighting_cg_iterations(),
            patience: Self::default_patience(),
            lighting_sample: DEFAULT_LIGHTING_SAMPLE,
            starts: 1,
            robust_floor: EstimateOptions::default().robust_floor,
            validation: EstimateOptions::default().validation_fraction,
            clip: crate::photo::DEFAULT_CLIP,
            seed: 1,
            progress: true,
            force: false,
            render_training: true,
            adaptive: false,
            light: crate::light_choose::LightChoice::Paper,
        }
    }

    /// Reject impossible values with a message naming the option.
    pub fn check(&self) -> Result<()> {
        let pow2 = |name: &str, v: usize, lo: usize, hi: usize| {
            if v.is_power_of_two() && (lo..=hi).contains(&v) {
                Ok(())
            } else {
                Err(Error::Config(format!(
                    "--{name} {v}: must be a power of two from {lo} to {hi}"
                )))
            }
        };
        pow2("global-resolution", self.global_resolution, 4, 256)?;
        pow2("local-resolution", self.local_resolution, 4, 128)?;
        if let Some(n) = self.render_local_resolution {
            pow2("render-local-resolution", n, 4, 128)?;
        }
        pow2("normal-grid", self.normal_grid, 2, 128)?;
        if self.basis.is_empty() {
            return Err(Error::Config(
                "--basis: at least one basis BRDF is needed".into(),
            ));
        }
        if let MaterialCount::Fixed(k) = self.materials {
            if k == 0 || k > 32 {
                return Err(Error::Config(format!(
                    "--materials {k}: must be from 1 to 32, or auto"
                )));
            }
        }
        if !(self.clip > 0.0 && self.clip <= 1.0) {
            return Err(Error::Config(format!(
                "--clip {}: must be in (0, 1]",
                self.clip
            )));
        }
        if !(self.smoothness >= 0.0 && self.smoothness.is_finite()) {
            return Err(Error::Config(format!(
                "--smoothness {}: must be a finite number ≥ 0",
                self.smoothness
            )));
        }
        if !(self.rel_tol >= 0.0 && self.rel_tol.is_finite()) {
            return Err(Error::Config(format!(
                "--tolerance {}: must be a finite number ≥ 0",
                self.rel_tol
            )));
        }
        if self.rays_per_texel == 0 || self.rays_per_texel > 64 {
            return Err(Error::Config(format!(
                "--rays-per-texel {}: must be from 1 to 64",
                self.rays_per_texel
            )));
        }
        if self.max_iterations == 0 {
            return Err(Error::Config(
                "--iterations 0: at least one is needed".into(),
            ));
        }
        if self.irls_iterations == 0 {
            return Err(Error::Config(
                "--irls-iterations 0: at least one (plain least squares) is needed".into(),
            ));
        }
        if !(0.0..1.0).contains(&self.robust_floor) {
            return Err(Error::Config(format!(
                "--robust-floor {}: must be in [0, 1) (a fraction of the RMS radiance)",
                self.robust_floor
            )));
        }
        if self.starts == 0 {
            return Err(Error::Config(
                "--starts 0: the alternation needs at least one start".into(),
            ));
        }
        if self.patience == 0 {
            return Err(Error::Config(
                "--patience 0: at least one iteration without improvement must be allowed".into(),
            ));
        }
        if !(0.0..0.5).contains(&self.validation) {
            return Err(Error::Config(format!(
                "--validation {}: the held-back fraction must be in [0, 0.5) (0 turns early \
                 stopping off)",
                self.validation
            )));
        }
        if let Some(up) = self.up {
            if !(up.norm() > 0.0 && up.iter().all(|v| v.is_finite())) {
                return Err(Error::Config(
                    "--up: must be a non-zero finite vector".into(),
                ));
            }
        }
        if let Holdout::Every(0) = self.holdout {
            return Err(Error::Config(
                "--holdout-every 0: must be at least 1".into(),
            ));
        }
        Ok(())
    }
}

/// What a finished run hands back (also written to `OUT/report.json`).
#[derive(Debug)]
pub struct RunSummary {
    /// The output folder.
    pub out: PathBuf,
    /// The report that was written.
    pub report: RunReport,
}

/// World up from the cameras (DESIGN §3): the mean of their `−y` axes in world
/// coordinates (COLMAP cameras have y pointing down in the image).
pub fn estimate_up(views: &[scene::View]) -> Option<Vec3> {
    let sum: Vec3 = views
        .iter()
        .map(|v| -v.image.rotation().matrix().row(1).transpose())
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
        .map(|(c, _)| crate::cluster::hue_feature(*c))
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

/// Per-vertex mean colour (α-weighted) over the observations, and whether each vertex was seen.
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
    let seen: Vec<bool> = wsum.iter().map(|&w| w > 0.0).collect();
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
    pub photos: &'a [crate::photo::Photo],
    pub train: Vec<usize>,
    pub held: Vec<usize>,
    pub env_from_world: Matrix3<f64>,
    pub normals_env: Vec<Vec3>,
    pub vis: visibility::Visibility,
    pub rot: Rotation,
    /// The renderer's visibility and rotation ([`evaluate`] module docs).
    pub render_vis: visibility::Visibility,
    pub render_rot: crate::rotation::SplatRotation,
    pub basis: Vec<BasisBrdf>,
    pub est: estimate::Estimate,
    pub beta: Vec<[f64; 3]>,
    /// The estimator's predictions at each training photo's observations (vertex, linear
    /// RGB), in training order: what the training renders show where a vertex was observed.
    pub train_predictions: Vec<Vec<(u32, [f32; 3])>>,
    pub opts: &'a RunOptions,
    pub estimate_options: EstimateOptions,
    pub bvh: SceneBvh,
    /// The naive baseline's per-vertex colours ([`baseline`]).
    pub baseline: baseline::VertexMedians,
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
    let report = run_into(opts, out.path(), &progress)?;
    let out = out.commit()?;
    progress.finish(
        &format!("results in {}", out.display()),
        &report.stage_details,
    );
    Ok(RunSummary { out, report })
}

fn run_into(opts: &RunOptions, dir: &Path, progress: &Progress) -> Result<RunReport> {
    let mut stages = Stages::new();
    let mut notes: Vec<String> = Vec::new();

    // 1. Import.
    progress.stage("import");
    let (scene, photos) = stages.run("import", || -> Result<_> {
        let ws = Workspace::discover(&opts.workspace, opts.mesh.as_deref())?;
        let scene = scene::load_scene(ws)?;
        let photos = scene::load_photos(&scene, opts.clip)?;
        Ok((scene, photos))
    })?;
    notes.extend(scene.workspace.notes.iter().cloned());
    notes.extend(scene.skipped.iter().map(|s| format!("skipped {s}")));
    for s in &scene.skipped {
        progress.warn(&format!("skipped photo {s}"));
    }
    let truth = match &scene.workspace.truth_dir {
        Some(t) => Some(Truth::read(t)?),
        None => None,
    };
    let held = holdout_views(&scene, &opts.holdout, truth.as_ref())?;
    let holdout_rule = holdout_rule(&scene, &opts.holdout, truth.is_some(), &held);
    if matches!(opts.holdout, Holdout::Default) && truth.is_none() && !held.is_empty() {
        progress.note(&format!("held out: {holdout_rule}"));
    }
    notes.push(format!("held-out photos: {holdout_rule}"));
    let mut train: Vec<usize> = (0..scene.views.len())
        .filter(|i| !held.contains(i))
        .collect();
    let nv = scene.mesh.positions.len();

    // Memory, checked with the real observation count before anything large (visibility,
    // rotations, transport, solver) is allocated.
    let photo_pixels: u64 = photos
        .iter()
        .map(|p| p.width as u64 * p.height as u64)
        .sum();
    let sizes = |observations: u64| crate::budget::Sizes {
        vertices: nv as u64,
        photos: train.len() as u64,
        held_photos: held.len() as u64,
        photo_pixels,
        threads: rayon::current_num_threads() as u64,
        observations,
        basis: opts.basis.len() as u64,
        global_resolution: opts.global_resolution as u64,
        local_resolution: opts.local_resolution as u64,
        render_local_resolution: render_local_resolution(opts) as u64,
        normal_grid: opts.normal_grid as u64,
        keep: opts.keep as u64,
    };
    // 2. Observations of the training photos (held-out ones are extracted by the evaluation).
    progress.stage("observations");
    let (bvh, mut obs) = stages.run("observations", || {
        let bvh = SceneBvh::new(&scene.mesh);
        let views: Vec<_> = train.iter().map(|&i| scene.views[i].clone()).collect();
        let ph: Vec<&crate::photo::Photo> = train.iter().map(|&i| &photos[i]).collect();
        let obs = observe::extract(&scene.mesh, &bvh, &views, &ph, &ObserveOptions::default());
        (bvh, obs)
    });
    let budget = crate::budget::check(&sizes(obs.len() as u64))?;
    notes.push(format!(
        "memory plan: {:.0} MiB for the large arrays (largest: {})",
        budget.total() as f64 / (1u64 << 20) as f64,
        budget.largest().name
    ));
    let useful = obs.weight.iter().filter(|&&w| w > 0.0).count();
    if useful == 0 {
        return Err(Error::Numeric {
            stage: "observations".into(),
            message: "no vertex is seen un-clipped in any training photo: check the mesh \
                      against the cameras (`relight-cpc inspect`) and the --clip threshold"
                .into(),
        });
    }
    // Photos with no light in them carry no information about reflectance or light: refuse
    // rather than fit zero maps and arbitrary materials. The threshold is far below one
    // 8-bit step (sRGB 1/255 decodes to 3e-4 linear).
    let brightest = obs
        .rgb
        .iter()
        .zip(&obs.weight)
        .filter(|(_, &w)| w > 0.0)
        .map(|(c, _)| c[0].max(c[1]).max(c[2]))
        .fold(0.0f32, f32::max);
    if brightest <= 1e-5 {
        return Err(Error::Numeric {
            stage: "observations".into(),
            message: format!(
                "every observed pixel of the {} training photos is black (brightest {:.1e} linear): \
                 there is no light to fit; check the photos and their exposure",
                train.len(),
                brightest
            ),
        });
    }
    for (k, &i) in train.iter().enumerate() {
        if obs.photo_ranges[k].is_empty() {
            notes.push(format!(
                "{}: no vertex observed in it; its map stays black",
                scene.views[i].image.name
            ));
        }
    }
    // Photos that add no new observation (adaptive model, crate::adapt step 1).
    let mut decisions: Vec<crate::adapt::Decision> = Vec::new();
    if opts.adaptive {
        let red = crate::adapt::redundant_photos(&obs, nv);
        let n = train.len();
        if !red.is_empty() && red.len() < n {
            let drop: Vec<usize> = red.iter().map(|r| r.0).collect();
            for &(k, by) in &red {
                progress.line(&format!(
                    "skipped photo {}: it adds no new observation (duplicates {})",
                    scene.views[train[k]].image.name, scene.views[train[by]].image.name
                ));
                notes.push(format!(
                    "{}: skipped, it adds no new observation (every vertex it sees is seen in {} from within {}° and with the same colour within {:.0}%)",
                    scene.views[train[k]].image.name,
                    scene.views[train[by]].image.name,
                    crate::adapt::DUPLICATE_ANGLE_DEG,
                    100.0 * crate::adapt::DUPLICATE_RGB
                ));
            }
            obs = crate::adapt::drop_photos(&obs, &drop);
            train = train
                .iter()
                .enumerate()
                .filter(|(k, _)| !drop.contains(k))
                .map(|(_, &i)| i)
                .collect();
            decisions.push(crate::adapt::Decision {
                what: "photos".into(),
                full: n.to_string(),
                chosen: train.len().to_string(),
                reason: format!(
                    "{} training photo(s) duplicate an earlier one (same view within {}°, same colour within {:.0}%): a duplicate adds a light map to estimate and no information",
                    drop.len(),
                    crate::adapt::DUPLICATE_ANGLE_DEG,
                    100.0 * crate::adapt::DUPLICATE_RGB
                ),
            });
        } else {
            decisions.push(crate::adapt::Decision {
                what: "photos".into(),
                full: n.to_string(),
                chosen: n.to_string(),
                reason: format!(
                    "every training photo adds observations: none repeats an earlier photo's view (within {}°) with the same colours (within {:.0}%); a photo from the same view under another light is new information, since every photo has its own light",
                    crate::adapt::DUPLICATE_ANGLE_DEG,
                    100.0 * crate::adapt::DUPLICATE_RGB
                ),
            });
        }
    }

    // Frames.
    let up = match opts.up {
        Some(u) => u.normalize(),
        None => {
            let u = estimate_up(&scene.views).ok_or_else(|| {
                Error::Config("cannot estimate world up from the cameras (their −y axes cancel out); give --up X,Y,Z".into())
            })?;
            notes.push(format!(
                "world up estimated from the cameras' −y axes: ({:.4}, {:.4}, {:.4})",
                u.x, u.y, u.z
            ));
            u
        }
    };
    let env_from_world = env_from_world(&up)?;
    let normals_env: Vec<Vec3> = scene
        .mesh
        .normals
        .iter()
        .map(|n| env_from_world * n)
        .collect();

    // 3. Visibility.
    progress.stage("visibility");
    let bar = progress.stage_bar(nv as u64, "vertices");
    let (vis, render_vis) = stages.run("visibility", || {
        evaluate::trace_visibility(&scene.mesh, &bvh, &env_from_world, opts)
    });
    drop(bar);
    notes.push(format!(
        "visibility: {} of {} vertices have a provably open hemisphere and skipped their rays; {} rays traced",
        vis.open_count(),
        nv,
        vis.rays_traced
    ));

    // Strata of the lighting step's sample: normal (8 × 8 octahedral bins) × open sky
    // (3 levels of the mean visible fraction).
    let strata =
        crate::solve::subsample::vertex_strata(&normals_env, Some(&vis.open_fractions()), 8, 3);
    let lambert_of = |basis: &[BasisBrdf]| {
        basis
            .iter()
            .position(|b| matches!(b, BasisBrdf::Lambert))
            .ok_or_else(|| {
                Error::Config(
                    "--basis: a Lambertian lobe is needed to carry the diffuse colour".into(),
                )
            })
    };
    let estimate_options = |o: &RunOptions, lambert: usize| EstimateOptions {
        max_outer: o.max_iterations,
        rel_tol: o.rel_tol,
        smoothness: o.smoothness,
        robust: if o.irls_iterations > 1 {
            Robust::Huber { k: 1.345 }
        } else {
            Robust::None
        },
        irls_iters: o.irls_iterations,
        robust_floor: o.robust_floor,
        alternation_qp_iters: (o.lighting_qp_iterations > 0).then_some(o.lighting_qp_iterations),
        alternation_cg_iters: (o.lighting_cg_iterations > 0).then_some(o.lighting_cg_iterations),
        patience: o.patience,
        lighting_sample: o.lighting_sample,
        lighting_strata: strata.clone(),
        lambert_basis: lambert,
        validation_seed: o.seed,
        validation_fraction: o.validation,
        ..EstimateOptions::default()
    };
    let (mean_rgb, seen) = mean_colours(&obs, nv);

    // Adaptive model (crate::adapt steps 2–5): a pilot fit decides the materials, the
    // bases, the map resolution and the coefficient budget; `eff` holds what is used.
    let mut eff = opts.clone();
    let mut pilot_k: Option<(usize, String)> = None;
    if opts.adaptive {
        progress.stage("pilot");
        let spinner = progress.spinner("pilot fits");
        let lambert = lambert_of(&opts.basis)?;
        let outcome = stages.run("pilot", || {
            crate::adapt::pilot(&crate::adapt::PilotInput {
                normals_env: &normals_env,
                obs: &obs,
                env_from_world: &env_from_world,
                vis: &vis,
                basis: &opts.basis,
                lambert,
                normal_grid: opts.normal_grid,
                global_resolution: opts.global_resolution,
                keep: opts.keep,
                // The pilot holds out its own observations: no early stopping inside it.
                estimate: EstimateOptions {
                    validation_fraction: 0.0,
                    ..estimate_options(opts, lambert)
                },
                mean_rgb: &mean_rgb,
                seen: &seen,
                materials: match opts.materials {
                    MaterialCount::Fixed(k) => Some(k),
                    MaterialCount::Auto => None,
                },
                seed: opts.seed,
            })
        })?;
        drop(spinner);
        decisions.extend(adaptive_decisions(opts, &outcome, &vis, nv, &mut eff));
        pilot_k = Some((outcome.materials, outcome.materials_reason.clone()));
    }

    // 4. Rotation.
    progress.stage("rotation");
    let bar = progress.stage_bar((eff.normal_grid * eff.normal_grid) as u64, "normals");
    let rot = stages.run("rotation", || {
        Rotation::new(
            eff.global_resolution,
            eff.local_resolution,
            eff.normal_grid,
            RotationForm::Factored,
        )
    });

    drop(bar);

    // 5. Transport.
    progress.stage("transport");
    let bar = progress.stage_bar(obs.vertex.len() as u64, "observations");
    let topts = TransportOptions {
        n_global: eff.global_resolution,
        n_local: eff.local_resolution,
        keep: eff.keep,
    };
    let tr: Transport = stages.run("transport", || {
        transport::build(
            &normals_env,
            &obs,
            &env_from_world,
            &vis,
            &eff.basis,
            &rot,
            &topts,
        )
    })?;
    drop(bar);

    // 6. Estimate.
    let lambert = lambert_of(&eff.basis)?;
    let (k, k_reason) = match (pilot_k, opts.materials) {
        (Some(p), _) => p,
        (None, MaterialCount::Fixed(k)) => (k, format!("materials: {k}, as given by --materials")),
        (None, MaterialCount::Auto) => choose_material_count(&mean_rgb, &seen, opts.seed),
    };
    let init = initial_materials(&mean_rgb, &seen, k, opts.seed)?;
    let mut reasons = vec![k_reason];
    if init.albedo.len() < k {
        reasons.push(format!(
            "only {} distinct colour clusters exist, so {} materials are fitted",
            init.albedo.len(),
            init.albedo.len()
        ));
    }
    let problem = Problem {
        obs: &obs,
        transport: &tr,
        n_vertices: nv,
        n_photos: train.len(),
    };
    let eopts = estimate_options(&eff, lambert);
    let materials0 = Materials0::from_initial(&init, eff.basis.len(), lambert);
    let spinner = progress.spinner("held-out transport");
    let tracker = stages.run("transport", || {
        evaluate::HoldoutTracker::new(
            &scene,
            &photos,
            &held,
            &bvh,
            &normals_env,
            &env_from_world,
            &vis,
            &eff.basis,
            &rot,
            &topts,
            truth.as_ref(),
        )
    })?;
    drop(spinner);
    progress.stage("estimate");
    let available = starts::family_len(eff.basis.len(), lambert);
    if opts.starts > available {
        reasons.push(format!(
            "--starts {}: this basis gives {available} distinct starts, all tried",
            opts.starts
        ));
    }
    let family = starts::variants(materials0, lambert, starts::GLOSS_FRACTION, opts.starts);
    let n_starts = family.len();
    let bar = progress.bar((eff.max_iterations * n_starts) as u64, "outer iterations");
    let mut timeline: Vec<TimelinePoint> = Vec::new();
    let light_models = crate::light_choose::candidates(opts.light, &eopts)?;
    let mut fits = Vec::with_capacity(light_models.len());
    let mut timeline_ranges = Vec::with_capacity(light_models.len());
    for model in &light_models {
        let first = timeline.len();
        let family = family.clone();
        let eopts = &model.options;
        fits.push(stages.run("estimate", || {
            starts::estimate_best(&problem, family, eopts, &mut |si, it, state| {
                bar.inc(1);
                let holdout_rmse = tracker
                    .as_ref()
                    .map(|t| t.rmse(state, nv))
                    .filter(|v| v.is_finite());
                let n_it = timeline.iter().filter(|p| p.start == si).count() + 1;
                let line = format!(
                    "{}iteration {n_it}: objective {:.4e}, training RMSE {:.5}{} ({:.1} s)",
                    if n_starts > 1 {
                        format!("start {} of {n_starts}, ", si + 1)
                    } else {
                        String::new()
                    },
                    it.objective,
                    it.train_rmse,
                    holdout_rmse.map_or(String::new(), |h| format!(", held-out {h:.5}")),
                    it.seconds
                );
                if bar.is_hidden() {
                    progress.line(&line);
                } else {
                    bar.println(format!("          {line}"));
                }
                timeline.push(TimelinePoint {
                    start: si,
                    seconds: it.seconds,
                    objective: it.objective,
                    train_rmse: it.train_rmse,
                    holdout_rmse,
                    steps: it.steps,
                });
            })
        })?);
        timeline_ranges.push(first..timeline.len());
    }
    let scores: Vec<f64> = fits
        .iter()
        .map(|(e, _)| e.validation.as_ref().map_or(f64::NAN, |v| v.best_error()))
        .collect();
    let names: Vec<&str> = light_models.iter().map(|m| m.name).collect();
    let (pick, light_decision) = crate::light_choose::decide(opts.light, &names, &scores);
    reasons.push(format!(
        "light model `{}`: {}",
        light_decision.model, light_decision.why
    ));
    let eopts = light_models[pick].options.clone();
    let (est, multi) = fits.swap_remove(pick);
    // The timeline of the model kept.
    let timeline: Vec<TimelinePoint> = timeline.drain(timeline_ranges[pick].clone()).collect();
    bar.finish_and_clear();
    check_finite(&est, &conditioning_map(&est.conditioning))?;
    let beta = estimate::beta_per_vertex(&est.lambda, &est.weights, nv);
    let pred = estimate::predict(&problem, &est);
    let train_entries = train_errors(&scene, &train, &obs, &pred);
    let train_predictions: Vec<Vec<(u32, [f32; 3])>> = obs
        .photo_ranges
        .iter()
        .map(|r| {
            r.clone()
                .map(|p| (obs.vertex[p], pred[p].map(|v| v as f32)))
                .collect()
        })
        .collect();
    drop(pred);
    // The transport rows (training and held-out) are the run's largest arrays and nothing
    // after the estimate reads them: free them before the evaluation builds its own.
    drop(tracker);
    drop(tr);

    let fitted = Fitted {
        scene: &scene,
        photos: &photos,
        train,
        held,
        env_from_world,
        normals_env,
        vis,
        rot,
        render_rot: crate::rotation::SplatRotation::with_default_supersample(
            eff.global_resolution,
            render_vis.n_local,
        ),
        render_vis,
        basis: eff.basis.clone(),
        est,
        beta,
        train_predictions,
        opts: &eff,
        estimate_options: eopts,
        bvh,
        baseline: baseline::VertexMedians::from_observations(&obs, nv),
    };

    // 7. Evaluation of held-out photos, and per-photo training error.
    progress.stage("evaluation");
    let (evaluation, truth_check) = stages.run("evaluation", || -> Result<_> {
        let e = evaluate::evaluate(&fitted, truth.as_ref(), dir, progress)?;
        let t = match &truth {
            Some(t) => truth_check::truth_check(&fitted, t)?,
            None => Vec::new(),
        };
        Ok((e, t))
    })?;

    // 8. Outputs.
    progress.stage("output");
    stages.run("output", || output::write_results(&fitted, dir, progress))?;

    let c = &fitted.est.conditioning;
    let conditioning = conditioning_map(c);
    if c.weights_singular > 0 {
        notes.push(format!(
            "{} vertices had fewer independent observations than materials (their blending weights are minimum-norm)",
            c.weights_singular
        ));
    }
    if c.qp_unconverged > 0 {
        notes.push(format!(
            "{} photos' lighting solves in the last outer iteration stopped at the iteration cap before the KKT tolerance ({} of the QPs, one per photo and IRLS pass, at the alternation's cap of {} GPCG iterations, by design: --lighting-qp-iterations)",
            c.qp_unconverged,
            c.qp_alternation_capped,
            opts.lighting_qp_iterations
        ));
    }
    if multi.starts.len() > 1 {
        notes.push(format!(
            "{} starts tried, kept start {} ({}) by the {}: {}",
            multi.starts.len(),
            multi.chosen + 1,
            multi.starts[multi.chosen].label,
            multi.criterion,
            multi
                .starts
                .iter()
                .enumerate()
                .map(|(i, r)| format!("start {} {:.4} in {:.1} s", i + 1, r.score, r.seconds))
                .collect::<Vec<_>>()
                .join(", ")
        ));
    }
    notes.push(format!("scale normalisation: {}", fitted.est.normalisation));
    if let Some(v) = &fitted.est.validation {
        notes.push(format!(
            "early stopping: {} training observations ({:.0}%) left out of the fit and scored after every outer iteration (relative RMSE {}); kept iteration {} of {}{}",
            v.observations,
            100.0 * v.fraction,
            v.errors
                .iter()
                .map(|e| format!("{e:.4}"))
                .collect::<Vec<_>>()
                .join(", "),
            v.best_iteration,
            v.errors.len(),
            if v.stopped_early {
                " (stopped: no lower score for the patience)"
            } else {
                ""
            }
        ));
    }
    if let Some(s) = &fitted.est.lighting_sample {
        notes.push(format!(
            "lighting sample: the lighting steps of {} photo(s) saw at most {} of their observations each (stratified by normal, open sky and material); relative RMSE of the fit {:.4} on the {} sampled observations and {:.4} on the {} others (ratio {:.3}){}",
            s.photos_sampled,
            s.budget,
            s.rel_rmse_in,
            s.in_sample,
            s.rel_rmse_out,
            s.out_of_sample,
            s.ratio,
            if s.ratio > LIGHTING_SAMPLE_MAX_RATIO {
                format!(": above {LIGHTING_SAMPLE_MAX_RATIO}, the maps over-fit their samples; rerun with a larger --lighting-sample or 0 (all)")
            } else {
                String::new()
            }
        ));
    }
    let conditioning_use = conditioning_use(c, &fitted.estimate_options, opts.adaptive);

    let mut report = RunReport {
        version: env!("CARGO_PKG_VERSION").to_string(),
        workspace: opts.workspace.display().to_string(),
        seed: opts.seed,
        holdout: evaluation.holdout,
        // The iterate returned: early stopping's choice, else the last.
        train_rmse: fitted
            .est
            .validation
            .as_ref()
            .and_then(|v| fitted.est.timeline.get(v.best_iteration - 1))
            .or(fitted.est.timeline.last())
            .map_or(f64::NAN, |t| t.train_rmse),
        train: train_entries,
        timeline,
        model: ModelReport {
            materials: fitted.est.lambda.len(),
            basis: eff.basis.iter().map(|b| b.label()).collect(),
            global_resolution: eff.global_resolution,
            local_resolution: eff.local_resolution,
            render_local_resolution: fitted.render_vis.n_local,
            normal_grid: eff.normal_grid,
            kept_coefficients: eff.keep,
            reasons,
            adaptive: if opts.adaptive { Some(decisions) } else { None },
            light: Some(light_decision),
        },
        notes,
        conditioning,
        conditioning_use,
        starts: (multi.starts.len() > 1).then_some(multi),
        ..Default::default()
    };
    report.headline = evaluation.headline.map(|h| h.ratio);
    report.headline_detail = evaluation.headline;
    report.metrics = evaluation.metrics;
    report.truth_check = truth_check;
    report.holdout_rule = holdout_rule;
    if !fitted.held.is_empty() {
        let (r, h) = (evaluation.render_seconds, evaluation.half_fit_seconds);
        report.notes.push(format!(
            "evaluation of {} held-out photos: renders {:.1} s wall / {:.1} CPU s, the half \
             protocol's light fits {:.1} s / {:.1} CPU s",
            fitted.held.len(),
            r[0],
            r[1],
            h[0],
            h[1]
        ));
    }
    if fitted.baseline.unseen > 0 && !fitted.held.is_empty() {
        report.notes.push(format!(
            "baseline: {} of {} vertices are in no training photo; they take the median of the other vertices' medians",
            fitted.baseline.unseen,
            nv
        ));
    }
    if let Some(h) = evaluation.mean_holdout_rmse {
        report.notes.push(format!(
            "the timeline's held-out RMSE is over the held-out photos' observations (per vertex, after the best global scale, true light when known, else the mean training map); the final per-pixel figure, mean over held-out photos, is {h:.5}"
        ));
    }
    progress.stage("report");
    // The report's own writing is timed but cannot appear in the file it is writing.
    report.stage_details = stages.records.clone();
    report.stages = report
        .stage_details
        .iter()
        .map(|s| (s.name.clone(), s.seconds))
        .collect();
    report.peak_memory_bytes = stages.peak_memory_bytes();
    let maps = output::gallery_maps(&fitted);
    let refs: Vec<(String, usize, usize, &[[f32; 3]])> = maps
        .iter()
        .map(|(n, ll)| (n.clone(), ll.width, ll.height, ll.rgb.as_slice()))
        .collect();
    report.write(dir, &refs)?;
    let inputs = html_inputs::html_inputs(&fitted, truth.as_ref(), dir)?;
    crate::report::html::write(dir, &report, &inputs)?;
    Ok(report)
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

/// The adaptive model's decisions from the pilot's `outcome` (crate::adapt steps 3–5),
/// applied to `eff`.
fn adaptive_decisions(
    opts: &RunOptions,
    outcome: &crate::adapt::PilotOutcome,
    vis: &visibility::Visibility,
    nv: usize,
    eff: &mut RunOptions,
) -> Vec<crate::adapt::Decision> {
    use crate::adapt::Decision;
    let mut d = Vec::new();
    let full_k = match opts.materials {
        MaterialCount::Fixed(k) => k.to_string(),
        MaterialCount::Auto => "auto".to_string(),
    };
    d.push(Decision {
        what: "materials".into(),
        full: full_k,
        chosen: outcome.materials.to_string(),
        reason: outcome.materials_reason.clone(),
    });
    eff.basis = outcome.kept.iter().map(|&b| opts.basis[b]).collect();
    let labels = |b: &[BasisBrdf]| b.iter().map(|x| x.label()).collect::<Vec<_>>().join(",");
    d.push(Decision {
        what: "basis".into(),
        full: labels(&opts.basis),
        chosen: labels(&eff.basis),
        reason: outcome.basis_reason.clone(),
    });
    let shadowed = vis.open_count() < nv;
    let (g, why) =
        crate::adapt::global_resolution_for(&eff.basis, opts.global_resolution, shadowed);
    eff.global_resolution = g;
    d.push(Decision {
        what: "global_resolution".into(),
        full: opts.global_resolution.to_string(),
        chosen: g.to_string(),
        reason: why,
    });
    let cap = g * g;
    let keep = if opts.keep == 0 || opts.keep > cap {
        cap
    } else {
        opts.keep
    };
    eff.keep = keep;
    d.push(Decision {
        what: "keep".into(),
        full: opts.keep.to_string(),
        chosen: keep.to_string(),
        reason: format!(
            "{keep} of the {cap} Haar coefficients of a {g}² map per transport row ({:.0}%){}",
            100.0 * keep as f64 / cap as f64,
            if keep == opts.keep {
                ", as requested".to_string()
            } else {
                ": the budget cannot exceed the map's coefficient count".to_string()
            }
        ),
    });
    // Conditioning (issue 8: use the condition numbers the solver sees): a lighting system
    // beyond KAPPA_LIGHTING is regularised harder.
    use crate::adapt::KAPPA_LIGHTING;
    if outcome.kappa_lighting > KAPPA_LIGHTING && opts.smoothness < 1e-4 {
        eff.smoothness = 1e-4;
        d.push(Decision {
            what: "smoothness".into(),
            full: format!("{:e}", opts.smoothness),
            chosen: "1e-4".into(),
            reason: format!(
                "the pilot's lighting systems have condition number ≥ {:.1e} > {KAPPA_LIGHTING:.0e}: the Laplacian prior is raised to 1e-4 so the map directions the photos do not constrain are filled smoothly instead of by rounding",
                outcome.kappa_lighting
            ),
        });
    } else {
        d.push(Decision {
            what: "smoothness".into(),
            full: format!("{:e}", opts.smoothness),
            chosen: format!("{:e}", opts.smoothness),
            reason: format!(
                "the pilot's lighting condition number bound is {:.1e} (≤ {KAPPA_LIGHTING:.0e} or the prior is already ≥ 1e-4) and its λ systems' {:.1e}: no change",
                outcome.kappa_lighting,
                outcome.kappa_lambda.iter().copied().fold(0.0, f64::max)
            ),
        });
    }
    d
}

/// The condition numbers of the report, by name.
fn conditioning_map(c: &estimate::Conditioning) -> std::collections::BTreeMap<String, f64> {
    let mut conditioning = std::collections::BTreeMap::new();
    if let Some(max) = c
        .lighting
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .reduce(f64::max)
    {
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
/// past the thresholds of [`crate::adapt`], what to change.
fn conditioning_use(
    c: &estimate::Conditioning,
    eopts: &EstimateOptions,
    adaptive: bool,
) -> Vec<String> {
    let digits = |k: f64| k.max(1.0).log10();
    let mut out = Vec::new();
    let lighting = c
        .lighting
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max);
    if lighting > 0.0 {
        let mut line = format!(
            "lighting (Eq. 10): κ ≥ {lighting:.2e} (largest over photos; a lower bound from the Ritz values of the conjugate-gradient steps), about {:.0} of 16 digits; the Laplacian prior μ = {:.0e} × the largest texel-basis diagonal regularises the directions the photos do not see, and the QP stops at a relative KKT residual of {:.0e}",
            digits(lighting),
            eopts.smoothness,
            eopts.qp_rel_tol
        );
        if lighting > crate::adapt::KAPPA_LIGHTING {
            line.push_str(&format!(
                "; above {:.0e}, so the solution's unconstrained directions are set by rounding: {}",
                crate::adapt::KAPPA_LIGHTING,
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
    if lam > crate::adapt::KAPPA_LAMBDA {
        line.push_str(&format!(
            "; above {:.0e}: two basis lobes are nearly indistinguishable in these photos and the ridge, not the data, splits the weight between them: {}",
            crate::adapt::KAPPA_LAMBDA,
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
    est: &estimate::Estimate,
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
