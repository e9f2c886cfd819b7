//! `relight-cpc bench`: cost of the whole pipeline at set sizes, how each stage's cost
//! grows with the problem, and held-out error against run time over the speed knobs
//! (issue 9).
//!
//! Every run builds a known-truth scene with [`crate::synth::build`] and fits it with
//! [`crate::run::run`]; the figures come from the run's own [`crate::stages`] records
//! (wall, CPU, per-stage peak resident memory) and its report (training RMSE, held-out
//! RMSE of protocol (a), true light, after the best global scale).
//!
//! Growth of a stage between two runs with `n₁ < n₂` training observations and CPU times
//! `t₁, t₂` (user + system: on a shared machine wall time measures the other jobs too) is
//! given two ways: the ratio `(t₂/t₁) / (n₂/n₁)` (1 = linear, < 1 sub-linear) and the
//! log-log exponent `p = ln(t₂/t₁) / ln(n₂/n₁)` of a power law `t ∝ nᵖ`; the run's peak
//! resident memory gets the same two figures. The paper's cost model (Eq. 7–12: one
//! transport row per observation, the lighting and material steps summing over
//! observations) predicts `p ≈ 1` in the number of observations.
//!
//! The error-against-time sweep varies the global map resolution, the coefficient budget
//! (`keep`) and the outer iteration count on one small scene; the dense untruncated model
//! (`keep` 0 at the largest resolution) is the reference. A setting is on the Pareto front
//! when no other setting is both at least as fast and at least as accurate, and strictly
//! better in one of the two.

use crate::estimate::StepTimes;
use crate::report::plot::{line_panels, Series, PALETTE};
use crate::run::{self, Holdout, MaterialCount, RunOptions};
use crate::stages::StageRecord;
use crate::synth::{self, SynthOptions};
use crate::{Error, Result};
use serde::{Deserialize, Serialize};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Options of [`bench()`].
#[derive(Debug, Clone)]
pub struct BenchOptions {
    /// Minimum vertex counts of the vertex-scaling runs (at `base_photos` photos).
    pub sizes: Vec<usize>,
    /// Photo counts of the photo-scaling runs (at `base_vertices` vertices).
    pub photos: Vec<usize>,
    /// Photos of the vertex-scaling runs.
    pub base_photos: usize,
    /// Minimum vertices of the photo-scaling runs.
    pub base_vertices: usize,
    /// Output folder (`NAME.json`, `NAME.md`, `NAME.png`).
    pub out: PathBuf,
    /// File stem of the outputs (default `pipeline`).
    pub name: String,
    /// Replace a previous result of the same name in `out` ([`crate::out_dir::OutFiles`]).
    pub force: bool,
    /// Outer iterations of the scaling runs (`None`: the run default); the sweep sets its
    /// own.
    pub iterations: Option<usize>,
    /// Small photos, cheap renderer and small maps: a smoke run of a few minutes.
    pub quick: bool,
    /// The `synth` scene.
    pub scene: String,
    /// Skip the error-against-time sweep.
    pub no_sweep: bool,
    /// Only the error-against-time sweep (on the smallest of `sizes`), no scaling runs.
    pub sweep_only: bool,
    /// Keep the synth workspaces here and reuse one whose `bench-params.json` matches
    /// (`None`: a temporary folder, removed at the end).
    pub work: Option<PathBuf>,
    /// The meshes have exactly the vertex counts asked for (`synth --exact-vertices`,
    /// spot scenes), not the first subdivision level at or above them.
    pub exact_vertices: bool,
    /// The model every run fits.
    pub model: Model,
    /// Also fit each vertex-scaling scene with the adaptive model (`--adaptive on`).
    pub adaptive_rows: bool,
    /// Per-run progress of the pipeline's stages on standard error.
    pub progress: bool,
    /// Fit every run in a child process of this `relight-cpc` executable (`run` with the
    /// same options), so that each run's peak memory is its own and not the heap an earlier,
    /// larger run left behind; `None`: in this process (library callers, tests).
    pub executable: Option<PathBuf>,
}

/// The model the bench's runs fit (the `run` flags `--materials`, `--basis`, `--adaptive`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Model {
    /// Number of materials; `None` = `auto`.
    pub materials: Option<usize>,
    /// Basis BRDF list as `run --basis` takes it; `None` = run's default.
    pub basis: Option<String>,
    /// `run --adaptive`.
    pub adaptive: bool,
}

impl Default for Model {
    /// `run`'s defaults with the adaptive model off (the knobs are then what is measured).
    fn default() -> Self {
        Model {
            materials: None,
            basis: None,
            adaptive: false,
        }
    }
}

impl Model {
    /// The paper's Minerva configuration (Table 1): 6 materials, 7 basis BRDFs (Lambert,
    /// four GGX roughnesses, Phong 50 and 500), the full model as given (`--adaptive off`).
    pub fn minerva() -> Self {
        Model {
            materials: Some(6),
            basis: Some("lambert,ggx:0.1,ggx:0.2,ggx:0.35,ggx:0.6,phong:50,phong:500".into()),
            adaptive: false,
        }
    }

    /// Short label, e.g. `K6 B7 adaptive off`.
    pub fn label(&self) -> String {
        let b = self
            .basis
            .as_deref()
            .map_or(3, |s| s.split(',').filter(|t| !t.trim().is_empty()).count());
        format!(
            "K{} B{} adaptive {}",
            self.materials.map_or("auto".into(), |k| k.to_string()),
            b,
            if self.adaptive { "on" } else { "off" }
        )
    }
}

impl BenchOptions {
    /// Issue 9's sizes: 10K → 100K → 400K vertices at 13 photos, 6 → 13 → 30 photos at
    /// 100K vertices, photos of about one megapixel.
    pub fn new(out: PathBuf) -> Self {
        BenchOptions {
            sizes: vec![10_000, 100_000, 400_000],
            photos: vec![6, 13, 30],
            base_photos: 13,
            base_vertices: 100_000,
            out,
            name: "pipeline".into(),
            force: false,
            iterations: None,
            quick: false,
            scene: "spot-varying".into(),
            exact_vertices: true,
            no_sweep: false,
            sweep_only: false,
            work: None,
            model: Model::default(),
            adaptive_rows: false,
            progress: true,
            executable: None,
        }
    }

    /// A smoke run of a few minutes: 2K → 8K → 32K vertices at 6 photos, 4 → 8 → 16
    /// photos at 8K vertices, the sphere-plane scene (cast shadows) at 192² pixels.
    pub fn quick(out: PathBuf) -> Self {
        BenchOptions {
            sizes: vec![2_000, 8_000, 32_000],
            photos: vec![4, 8, 16],
            base_photos: 6,
            base_vertices: 8_000,
            out,
            name: "pipeline".into(),
            force: false,
            iterations: None,
            quick: true,
            scene: "sphere-plane".into(),
            exact_vertices: false,
            no_sweep: false,
            sweep_only: false,
            work: None,
            model: Model::default(),
            adaptive_rows: false,
            progress: false,
            executable: None,
        }
    }
}

/// The knobs that trade accuracy for speed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct Knobs {
    /// Global octahedral map side.
    pub global_resolution: usize,
    /// Local hemi-octahedral map side.
    pub local_resolution: usize,
    /// Normal-grid side of the rotation.
    pub normal_grid: usize,
    /// Haar coefficients kept per transport row (0 = all).
    pub keep: usize,
    /// Outer iterations at most.
    pub iterations: usize,
    /// GPCG iterations per lighting QP inside the alternation (`--lighting-qp-iterations`).
    pub lighting_qp: usize,
}

impl Knobs {
    /// The knobs the sweep varies, in the order of [`Knobs::differs_from`].
    pub const SWEPT: [&'static str; 5] = [
        "global resolution",
        "keep (coefficients)",
        "iterations",
        "normal grid (rotation)",
        "lighting QP cap",
    ];

    /// Which knobs differ from `other`: the five of [`Knobs::SWEPT`], then the local
    /// resolution (not swept).
    pub fn differs_from(&self, other: &Knobs) -> [bool; 6] {
        [
            self.global_resolution != other.global_resolution,
            self.keep != other.keep,
            self.iterations != other.iterations,
            self.normal_grid != other.normal_grid,
            self.lighting_qp != other.lighting_qp,
            self.local_resolution != other.local_resolution,
        ]
    }

    /// Short label, e.g. `g64 k128 it8`.
    pub fn label(&self) -> String {
        let keep = if self.keep == 0 {
            "all".to_string()
        } else {
            self.keep.to_string()
        };
        format!(
            "g{} k{} it{} n{} qp{}",
            self.global_resolution, keep, self.iterations, self.normal_grid, self.lighting_qp
        )
    }
}

/// One measured run.
#[derive(Debug, Clone, Serialize)]
pub struct BenchRun {
    /// Which group it belongs to (`vertices`, `photos`, `sweep`).
    pub group: String,
    /// Mesh vertices (actual, after subdivision).
    pub vertices: usize,
    /// Registered photos (training + held out).
    pub photos: usize,
    /// Training observations the estimator used.
    pub observations: usize,
    /// Photo size in pixels.
    pub width: u32,
    /// Photo height in pixels.
    pub height: u32,
    /// Knobs of the run.
    pub knobs: Knobs,
    /// The model fitted.
    pub model: Model,
    /// Seconds the reference renderer spent on the scene's photos when it was built (not
    /// part of the run; a reused workspace reports its original figure).
    pub synth_seconds: f64,
    /// Whether the workspace was reused from `--work` rather than built for this run.
    pub synth_reused: bool,
    /// Per stage, in run order.
    pub stages: Vec<StageRecord>,
    /// Sum of stage wall seconds.
    pub total_seconds: f64,
    /// Sum of stage CPU seconds.
    pub total_cpu_seconds: f64,
    /// Peak resident memory of the run, bytes.
    pub peak_memory_bytes: u64,
    /// Training RMSE (linear RGB).
    pub train_rmse: f64,
    /// Mean held-out RMSE after the best global scale, protocol (a) (true light) when the
    /// scene has it, else (c).
    pub holdout_rmse: f64,
    /// Outer iterations the estimator ran (early stopping may return an earlier one).
    pub outer_iterations: usize,
    /// The estimate stage's lighting and material steps, summed over its iterations.
    pub steps: StepTimes,
    /// The `relight-cpc run` command of a run fitted in a child process.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub command: Option<String>,
}

/// Growth of one stage's CPU time (or of the peak memory) between two consecutive sizes.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Growth {
    /// Stage name (`total` for the whole run).
    pub stage: String,
    /// Smaller size.
    pub from: f64,
    /// Larger size.
    pub to: f64,
    /// `t₂ / t₁`.
    pub time_ratio: f64,
    /// `(t₂/t₁) / (n₂/n₁)`: 1 = linear.
    pub relative: f64,
    /// `ln(t₂/t₁) / ln(n₂/n₁)`: the power-law exponent.
    pub exponent: f64,
}

/// Everything `pipeline.json` holds.
#[derive(Debug, Clone, Serialize)]
pub struct BenchReport {
    /// Whether this was a `--quick` run.
    pub quick: bool,
    /// Whether every fit ran in a child process (peak memory per run exact).
    pub isolated: bool,
    /// Whether the benchmark finished (`false` while rows are still being written).
    pub complete: bool,
    /// The model of the scaling runs.
    pub model: Model,
    /// How the photos were rendered.
    pub synth: String,
    /// The scene.
    pub scene: String,
    /// Vertex-scaling runs, by size.
    pub vertex_runs: Vec<BenchRun>,
    /// Photo-scaling runs, by count.
    pub photo_runs: Vec<BenchRun>,
    /// Growth per stage between consecutive vertex sizes.
    pub vertex_growth: Vec<Growth>,
    /// Growth per stage between consecutive photo counts.
    pub photo_growth: Vec<Growth>,
    /// The same scenes fitted with the adaptive model (`--adaptive-rows`).
    pub adaptive_runs: Vec<BenchRun>,
    /// Sweep runs.
    pub sweep: Vec<BenchRun>,
    /// Index in `sweep` of the dense reference.
    pub reference: Option<usize>,
    /// Per sweep run: on the Pareto front of (time, held-out error).
    pub pareto: Vec<bool>,
    /// Wall seconds of the whole benchmark.
    pub seconds: f64,
    /// The command line that produced this report (regenerate with it).
    pub command: String,
}

/// Growth between consecutive entries of `series`: `(size, [(stage, seconds)])`, sorted by
/// size. A stage missing from either entry, or with a non-positive time, or two equal
/// sizes, gives no row.
pub fn growth_rates(series: &[(f64, Vec<(String, f64)>)]) -> Vec<Growth> {
    let mut out = Vec::new();
    for pair in series.windows(2) {
        let ((n1, s1), (n2, s2)) = (&pair[0], &pair[1]);
        let size_ratio = n2 / n1;
        if !(size_ratio.is_finite() && size_ratio > 0.0 && size_ratio != 1.0) {
            continue;
        }
        for (stage, t1) in s1 {
            let Some((_, t2)) = s2.iter().find(|(s, _)| s == stage) else {
                continue;
            };
            if !(*t1 > 0.0 && *t2 > 0.0) {
                continue;
            }
            let time_ratio = t2 / t1;
            out.push(Growth {
                stage: stage.clone(),
                from: *n1,
                to: *n2,
                time_ratio,
                relative: time_ratio / size_ratio,
                exponent: time_ratio.ln() / size_ratio.ln(),
            });
        }
    }
    out
}

/// Pareto front of `(time, error)` points, both minimised: `true` where no other point is
/// at least as good in both and strictly better in one. Non-finite points are never on it.
pub fn pareto_front(points: &[(f64, f64)]) -> Vec<bool> {
    points
        .iter()
        .map(|&(t, e)| {
            t.is_finite()
                && e.is_finite()
                && !points.iter().any(|&(t2, e2)| {
                    t2.is_finite() && e2.is_finite() && t2 <= t && e2 <= e && (t2 < t || e2 < e)
                })
        })
        .collect()
}

/// Per-stage CPU seconds of a run, with a `total` entry, and its peak memory (MiB) as
/// `peak memory`.
fn stage_costs(run: &BenchRun) -> Vec<(String, f64)> {
    let mut v: Vec<(String, f64)> = run
        .stages
        .iter()
        .map(|s| (s.name.clone(), s.cpu_seconds))
        .collect();
    if run.outer_iterations > 0 {
        v.push(("lighting step".into(), run.steps.lighting_cpu_seconds));
        v.push(("material step".into(), run.steps.material_cpu_seconds));
    }
    v.push(("total".into(), run.total_cpu_seconds));
    v.push(("peak memory".into(), mib(run.peak_memory_bytes)));
    v
}

/// Photo size, renderer effort and default knobs for the mode.
fn mode_settings(quick: bool) -> (u32, u32, crate::reference::Samples, Knobs) {
    if quick {
        (
            192,
            192,
            crate::reference::Samples {
                per_pixel: 1,
                light: 16,
                seed: 1,
            },
            Knobs {
                global_resolution: 16,
                local_resolution: 8,
                normal_grid: 8,
                keep: 32,
                iterations: 3,
                lighting_qp: RunOptions::default_lighting_qp_iterations(),
            },
        )
    } else {
        // 1024² ≈ 1.05 MP, the paper's photo size; the reference renderer is kept cheap
        // (one path per pixel, 16 MIS pairs) since its noise is not what is measured.
        (
            1024,
            1024,
            crate::reference::Samples {
                per_pixel: 1,
                light: 16,
                seed: 1,
            },
            Knobs {
                global_resolution: 64,
                local_resolution: 32,
                normal_grid: 32,
                keep: 128,
                iterations: 8,
                lighting_qp: RunOptions::default_lighting_qp_iterations(),
            },
        )
    }
}

/// The sweep's settings and the index of the dense reference among them.
fn sweep_knobs(base: Knobs, quick: bool) -> (Vec<Knobs>, usize) {
    // The rotation's accuracy knob is its normal grid (Eq. 6: the light is rotated into
    // `n × n` precomputed frames and blended between the four nearest); the rotation is
    // applied in factored form, without a threshold on its entries.
    // Two iteration counts: the outer alternation's cap and each lighting QP's GPCG cap.
    type Lists<'a> = (
        &'a [usize],
        &'a [usize],
        &'a [usize],
        &'a [usize],
        &'a [usize],
    );
    let (resolutions, keeps, iterations, grids, qps): Lists = if quick {
        (
            &[8, 16, 32],
            &[16, 32, 64, 0],
            &[1, 2, 3],
            &[4, 8, 16],
            &[2, 3, 5],
        )
    } else {
        (
            &[16, 32, 64],
            &[32, 64, 128, 0],
            &[2, 4, 8],
            &[16, 32, 64],
            &[3, 4, 5],
        )
    };
    let top = *resolutions.last().unwrap_or(&base.global_resolution);
    let mut list: Vec<Knobs> = Vec::new();
    let mut push = |k: Knobs| {
        if !list.contains(&k) {
            list.push(k);
        }
    };
    let at_top = Knobs {
        global_resolution: top,
        ..base
    };
    for &g in resolutions {
        push(Knobs {
            global_resolution: g,
            ..base
        });
    }
    for &k in keeps {
        push(Knobs { keep: k, ..at_top });
    }
    for &it in iterations {
        push(Knobs {
            iterations: it,
            ..at_top
        });
    }
    for &n in grids {
        push(Knobs {
            normal_grid: n,
            ..at_top
        });
    }
    for &q in qps {
        push(Knobs {
            lighting_qp: q,
            ..at_top
        });
    }
    let reference = Knobs { keep: 0, ..at_top };
    push(reference);
    let idx = list.iter().position(|k| *k == reference).unwrap_or(0);
    (list, idx)
}

/// What identifies a synth workspace: reused from `--work` only when all of it matches.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct SceneParams {
    scene: String,
    vertices: usize,
    photos: usize,
    width: u32,
    height: u32,
    per_pixel: u32,
    light: u32,
    sample_seed: u64,
    seed: u64,
    /// `synth --exact-vertices` (absent in files written before the flag: false).
    #[serde(default)]
    exact_vertices: bool,
    /// What `synth` reported, kept so that a reused workspace reports it too.
    summary_vertices: usize,
    summary_photos: usize,
    render_seconds: f64,
}

impl SceneParams {
    fn same_scene(&self, o: &SceneParams) -> bool {
        (
            &self.scene,
            self.vertices,
            self.photos,
            self.width,
            self.height,
            self.per_pixel,
            self.light,
            self.sample_seed,
            self.seed,
            self.exact_vertices,
        ) == (
            &o.scene,
            o.vertices,
            o.photos,
            o.width,
            o.height,
            o.per_pixel,
            o.light,
            o.sample_seed,
            o.seed,
            o.exact_vertices,
        )
    }
}

/// A workspace ready to fit.
struct BenchScene {
    dir: PathBuf,
    vertices: usize,
    photos: usize,
    render_seconds: f64,
    reused: bool,
}

/// Build a synth workspace in `work` for `(vertices, photos)`, or reuse the one there whose
/// `bench-params.json` (written last, so only a finished build has it) matches.
fn scene(opts: &BenchOptions, work: &Path, vertices: usize, photos: usize) -> Result<BenchScene> {
    let (width, height, samples, _) = mode_settings(opts.quick);
    let dir = work.join(format!(
        "{}-v{vertices}-p{photos}-{width}x{height}",
        opts.scene
    ));
    let params_path = dir.join("bench-params.json");
    let mut want = SceneParams {
        scene: opts.scene.clone(),
        vertices,
        photos,
        width,
        height,
        per_pixel: samples.per_pixel,
        light: samples.light,
        sample_seed: samples.seed,
        seed: 1,
        exact_vertices: opts.exact_vertices,
        summary_vertices: 0,
        summary_photos: 0,
        render_seconds: 0.0,
    };
    if let Ok(text) = std::fs::read_to_string(&params_path) {
        if let Ok(have) = serde_json::from_str::<SceneParams>(&text) {
            if have.same_scene(&want) {
                eprintln!("bench: reusing {}", dir.display());
                return Ok(BenchScene {
                    dir,
                    vertices: have.summary_vertices,
                    photos: have.summary_photos,
                    render_seconds: have.render_seconds,
                    reused: true,
                });
            }
        }
    }
    if dir.exists() {
        std::fs::remove_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
    }
    eprintln!(
        "bench: synth {} with {}{vertices} vertices, {photos} photos of {width}×{height} ({} primary ray(s)/pixel, {} MIS pairs) → {}",
        opts.scene,
        if opts.exact_vertices { "" } else { "≥ " },
        samples.per_pixel,
        samples.light,
        dir.display()
    );
    let t0 = std::time::Instant::now();
    let s = synth::build(
        &opts.scene,
        &dir,
        &SynthOptions {
            width,
            height,
            photos: Some(photos),
            seed: want.seed,
            vertices: Some(vertices),
            exact_vertices: opts.exact_vertices,
            samples,
            ..SynthOptions::default()
        },
    )?;
    eprintln!(
        "bench: synth done in {:.1} s ({} vertices, renderer {:.1} s)",
        t0.elapsed().as_secs_f64(),
        s.vertices,
        s.render_seconds
    );
    want.summary_vertices = s.vertices;
    want.summary_photos = s.photos.len();
    want.render_seconds = s.render_seconds;
    let text = serde_json::to_string_pretty(&want)
        .map_err(|e| Error::Config(format!("bench: could not encode scene parameters: {e}")))?;
    std::fs::write(&params_path, text).map_err(|e| Error::io(&params_path, e))?;
    Ok(BenchScene {
        dir,
        vertices: s.vertices,
        photos: s.photos.len(),
        render_seconds: s.render_seconds,
        reused: false,
    })
}

/// Fit `ws` with `knobs` and measure it.
fn measure(
    group: &str,
    s: &BenchScene,
    knobs: Knobs,
    model: &Model,
    opts: &BenchOptions,
) -> Result<BenchRun> {
    let (width, height, _, _) = mode_settings(opts.quick);
    let ws = &s.dir;
    let out = ws.with_extension("fit");
    let mut o = RunOptions::new(ws.to_path_buf(), out.clone());
    o.holdout = Holdout::Default;
    o.materials = model
        .materials
        .map_or(MaterialCount::Auto, MaterialCount::Fixed);
    if let Some(b) = &model.basis {
        o.basis = crate::brdf::parse_list(b)?;
    }
    o.adaptive = model.adaptive;
    o.global_resolution = knobs.global_resolution;
    o.local_resolution = knobs.local_resolution;
    o.normal_grid = knobs.normal_grid;
    o.keep = knobs.keep;
    o.max_iterations = knobs.iterations;
    o.lighting_qp_iterations = knobs.lighting_qp;
    o.progress = opts.progress;
    o.force = true;
    o.render_training = false;
    eprintln!(
        "bench {group}: fitting {} vertices, {} photos, {}, {} …",
        s.vertices,
        s.photos,
        knobs.label(),
        model.label()
    );
    let (fit, command) = match &opts.executable {
        Some(exe) => {
            let (fit, command) = fit_in_child(exe, &o, model)?;
            (fit, Some(command))
        }
        None => (Fit::from_report(&run::run(&o)?.report)?, None),
    };
    let pick = |p: &str| -> Vec<f64> {
        fit.holdout
            .iter()
            .filter(|h| h.protocol == p)
            .filter_map(|h| h.rmse_scaled.filter(|x| x.is_finite()))
            .collect()
    };
    let mut held = pick("truth");
    if held.is_empty() {
        held = pick("mean");
    }
    let holdout_rmse = if held.is_empty() {
        f64::NAN
    } else {
        held.iter().sum::<f64>() / held.len() as f64
    };
    let run = BenchRun {
        group: group.into(),
        vertices: s.vertices,
        photos: s.photos,
        observations: fit.train.iter().map(|t| t.observations).sum(),
        width,
        height,
        knobs,
        model: model.clone(),
        synth_seconds: s.render_seconds,
        synth_reused: s.reused,
        total_seconds: fit.stage_details.iter().map(|x| x.seconds).sum(),
        total_cpu_seconds: fit.stage_details.iter().map(|x| x.cpu_seconds).sum(),
        stages: fit.stage_details,
        peak_memory_bytes: fit.peak_memory_bytes,
        train_rmse: fit.train_rmse.unwrap_or(f64::NAN),
        holdout_rmse,
        outer_iterations: fit.timeline.len(),
        steps: fit.timeline.iter().copied().sum(),
        command,
    };
    let _ = std::fs::remove_dir_all(&out);
    eprintln!(
        "bench {group}: {} vertices, {} photos, {}: {:.1} s wall, {:.1} s CPU, {:.0} MiB peak, held-out RMSE {:.4}",
        run.vertices,
        run.photos,
        knobs.label(),
        run.total_seconds,
        run.total_cpu_seconds,
        mib(run.peak_memory_bytes),
        run.holdout_rmse
    );
    Ok(run)
}

/// What the bench reads of a run's report (`report.json` of a child run, or the
/// in-process [`run::RunReport`] through the same JSON); NaN figures are `null` in the
/// JSON, hence the options.
#[derive(Debug, Deserialize)]
struct Fit {
    holdout: Vec<FitHoldout>,
    train_rmse: Option<f64>,
    train: Vec<FitTrain>,
    stage_details: Vec<StageRecord>,
    peak_memory_bytes: u64,
    /// One entry per outer iteration run.
    timeline: Vec<StepTimes>,
}

#[derive(Debug, Deserialize)]
struct FitHoldout {
    protocol: String,
    rmse_scaled: Option<f64>,
}

#[derive(Debug, Deserialize)]
struct FitTrain {
    observations: usize,
}

impl Fit {
    fn from_report(r: &crate::report::RunReport) -> Result<Self> {
        serde_json::to_value(r)
            .and_then(serde_json::from_value)
            .map_err(|e| Error::Config(format!("bench: could not read the run's report: {e}")))
    }

    fn from_json(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        serde_json::from_str(&text)
            .map_err(|e| Error::Config(format!("{}: not a run report: {e}", path.display())))
    }
}

/// `relight-cpc` and `args` as one shell line, arguments with white space in quotes.
fn shell_line(args: impl IntoIterator<Item = String>) -> String {
    std::iter::once("relight-cpc".to_string())
        .chain(args.into_iter().map(|a| {
            if a.contains(char::is_whitespace) {
                format!("'{a}'")
            } else {
                a
            }
        }))
        .collect::<Vec<_>>()
        .join(" ")
}

/// The `relight-cpc run` arguments that reproduce `o` (the bench sets only these; every
/// other option is at its default, which the CLI and [`RunOptions::new`] share).
fn run_args(o: &RunOptions, model: &Model) -> Vec<String> {
    let mut a: Vec<String> = vec![
        "run".into(),
        o.workspace.display().to_string(),
        "--out".into(),
        o.out.display().to_string(),
        "--force".into(),
        "--no-training-renders".into(),
        "--adaptive".into(),
        (if o.adaptive { "on" } else { "off" }).into(),
        "--materials".into(),
        match o.materials {
            MaterialCount::Auto => "auto".into(),
            MaterialCount::Fixed(k) => k.to_string(),
        },
    ];
    if let Some(b) = &model.basis {
        a.extend(["--basis".into(), b.clone()]);
    }
    for (flag, v) in [
        ("--global-resolution", o.global_resolution),
        ("--local-resolution", o.local_resolution),
        ("--normal-grid", o.normal_grid),
        ("--keep", o.keep),
        ("--iterations", o.max_iterations),
        ("--lighting-qp-iterations", o.lighting_qp_iterations),
    ] {
        a.extend([flag.into(), v.to_string()]);
    }
    if !o.progress {
        a.push("--quiet".into());
    }
    a
}

/// Fit in a child process `exe run …` and read its `report.json`; also returns the
/// command line, for the report.
fn fit_in_child(exe: &Path, o: &RunOptions, model: &Model) -> Result<(Fit, String)> {
    let args = run_args(o, model);
    let command = shell_line(args.iter().cloned());
    // The child's summary lines go to our standard error: standard output is the bench's.
    let status = std::process::Command::new(exe)
        .args(&args)
        .stdout(std::io::stderr())
        .status()
        .map_err(|e| Error::io(exe, e))?;
    if !status.success() {
        return Err(Error::Config(format!(
            "bench: `{command}` failed ({status})"
        )));
    }
    Ok((Fit::from_json(&o.out.join("report.json"))?, command))
}

/// Run the benchmark and write `NAME.{json,md,png}` (`opts.name`) into `opts.out`, rewritten after
/// every run (with `complete: false` until the last), so a long benchmark that is stopped
/// keeps the rows it finished.
pub fn bench(opts: &BenchOptions) -> Result<BenchReport> {
    if opts.no_sweep && (opts.sweep_only || (opts.sizes.is_empty() && opts.photos.is_empty())) {
        return Err(Error::Config("bench: nothing to run".into()));
    }
    if opts.sizes.iter().chain(&opts.photos).any(|&n| n == 0) || opts.base_photos < 2 {
        return Err(Error::Config(
            "bench: sizes and photo counts must be at least 1 (2 for --base-photos)".into(),
        ));
    }
    if let Some(b) = &opts.model.basis {
        crate::brdf::parse_list(b)?;
    }
    let t0 = std::time::Instant::now();
    let inputs: Vec<&Path> = opts.work.as_deref().into_iter().collect();
    let files = crate::out_dir::OutFiles::claim(
        &opts.out,
        &output_names(&opts.name).each_ref().map(|s| s.as_str()),
        opts.force,
        &inputs,
        is_bench_report,
    )?;
    let (work, temporary) = match &opts.work {
        Some(w) => (w.clone(), false),
        None => (
            std::env::temp_dir().join(format!("relight-bench-{}", std::process::id())),
            true,
        ),
    };
    std::fs::create_dir_all(&work).map_err(|e| Error::io(&work, e))?;
    let result = bench_in(opts, &files, &work, temporary, t0);
    if temporary {
        let _ = std::fs::remove_dir_all(&work);
    }
    result
}

/// How `synth` renders the photos, for the report.
fn synth_label(quick: bool) -> String {
    let (w, h, s, _) = mode_settings(quick);
    format!(
        "{w}×{h} photos by the reference renderer (Eq. 1 by MIS Monte Carlo with shadow rays), {} primary ray(s) per pixel, {} MIS pairs per shading point",
        s.per_pixel, s.light
    )
}

/// Fills in growth rates and the Pareto front from the runs so far.
fn summarise(report: &mut BenchReport) {
    let growth = |runs: &[BenchRun], size: fn(&BenchRun) -> usize| {
        growth_rates(
            &runs
                .iter()
                .map(|r| (size(r) as f64, stage_costs(r)))
                .collect::<Vec<_>>(),
        )
    };
    report.vertex_growth = growth(&report.vertex_runs, |r| r.observations);
    report.photo_growth = growth(&report.photo_runs, |r| r.observations);
    report.pareto = pareto_front(
        &report
            .sweep
            .iter()
            .map(|r| (r.total_seconds, r.holdout_rmse))
            .collect::<Vec<_>>(),
    );
}

fn bench_in(
    opts: &BenchOptions,
    files: &crate::out_dir::OutFiles,
    work: &Path,
    temporary: bool,
    t0: std::time::Instant,
) -> Result<BenchReport> {
    let (_, _, _, sweep_base) = mode_settings(opts.quick);
    let base = Knobs {
        iterations: opts.iterations.unwrap_or(sweep_base.iterations),
        ..sweep_base
    };
    let mut sizes = opts.sizes.clone();
    sizes.sort_unstable();
    sizes.dedup();
    let mut photos = opts.photos.clone();
    photos.sort_unstable();
    photos.dedup();
    let mut report = BenchReport {
        quick: opts.quick,
        isolated: opts.executable.is_some(),
        complete: false,
        model: opts.model.clone(),
        synth: synth_label(opts.quick),
        scene: opts.scene.clone(),
        vertex_runs: Vec::new(),
        photo_runs: Vec::new(),
        vertex_growth: Vec::new(),
        photo_growth: Vec::new(),
        adaptive_runs: Vec::new(),
        sweep: Vec::new(),
        reference: None,
        pareto: Vec::new(),
        seconds: 0.0,
        command: shell_line(std::env::args().skip(1)),
    };
    let save = |report: &mut BenchReport| -> Result<()> {
        summarise(report);
        report.seconds = t0.elapsed().as_secs_f64();
        write_outputs(report, files, &opts.name)
    };
    let done = |s: &BenchScene| -> Result<()> {
        if temporary {
            std::fs::remove_dir_all(&s.dir).map_err(|e| Error::io(&s.dir, e))?;
        }
        Ok(())
    };
    let adaptive = Model {
        adaptive: true,
        ..opts.model.clone()
    };

    // Scaling in vertices, then in photos; a (vertices, photos) pair already run is reused.
    let (sizes_run, photos_run) = if opts.sweep_only {
        (&[][..], &[][..])
    } else {
        (&sizes[..], &photos[..])
    };
    for &n in sizes_run {
        let s = scene(opts, work, n, opts.base_photos)?;
        let r = measure("vertices", &s, base, &opts.model, opts)?;
        report.vertex_runs.push(r);
        save(&mut report)?;
        if opts.adaptive_rows {
            let r = measure("adaptive", &s, base, &adaptive, opts)?;
            report.adaptive_runs.push(r);
            save(&mut report)?;
        }
        done(&s)?;
    }
    for &p in photos_run {
        if let Some(i) = sizes
            .iter()
            .position(|&n| n == opts.base_vertices && p == opts.base_photos)
        {
            let mut r = report.vertex_runs[i].clone();
            r.group = "photos".into();
            report.photo_runs.push(r);
            continue;
        }
        let s = scene(opts, work, opts.base_vertices, p)?;
        let r = measure("photos", &s, base, &opts.model, opts)?;
        report.photo_runs.push(r);
        save(&mut report)?;
        done(&s)?;
    }

    // Error against time on the smallest scene.
    if !opts.no_sweep {
        let n = sizes.first().copied().unwrap_or(opts.base_vertices);
        let s = scene(opts, work, n, opts.base_photos)?;
        let (list, idx) = sweep_knobs(sweep_base, opts.quick);
        report.reference = Some(idx);
        for k in list {
            let r = measure("sweep", &s, k, &opts.model, opts)?;
            report.sweep.push(r);
            save(&mut report)?;
        }
        done(&s)?;
    }
    report.complete = true;
    save(&mut report)?;
    Ok(report)
}

/// The files a bench named `name` writes: `NAME.json` (first: it identifies the result),
/// `NAME.md`, `NAME.png`.
fn output_names(name: &str) -> [String; 3] {
    ["json", "md", "png"].map(|ext| format!("{name}.{ext}"))
}

/// A bench report written by this tool: a JSON object with the report's `command` and
/// `complete` fields.
fn is_bench_report(path: &Path) -> bool {
    std::fs::read_to_string(path)
        .ok()
        .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
        .is_some_and(|v| v.get("command").is_some() && v.get("complete").is_some())
}

/// Writes `NAME.{json,md,png}`, each atomically (temporary file, then rename).
fn write_outputs(report: &BenchReport, files: &crate::out_dir::OutFiles, name: &str) -> Result<()> {
    let [json_name, md_name, png_name] = output_names(name);
    let json = serde_json::to_string_pretty(report)
        .map_err(|e| Error::Config(format!("bench: could not encode the report: {e}")))?;
    files.write(&json_name, json.as_bytes())?;
    files.write(&md_name, markdown(report, name).as_bytes())?;
    if report.sweep.len() > 1 {
        files.write_with(&png_name, |p| plot_sweep(report, p))?;
    }
    Ok(())
}

fn mib(b: u64) -> f64 {
    b as f64 / (1024.0 * 1024.0)
}

/// One stage table for a group of runs.
fn stage_table(md: &mut String, runs: &[BenchRun]) {
    if runs.is_empty() {
        return;
    }
    let _ = writeln!(
        md,
        "| vertices | photos | observations | stage | wall s | CPU s | peak MiB |\n|---:|---:|---:|---|---:|---:|---:|"
    );
    for r in runs {
        for s in &r.stages {
            let _ = writeln!(
                md,
                "| {} | {} | {} | {} | {:.2} | {:.2} | {:.0} |",
                r.vertices,
                r.photos,
                r.observations,
                s.name,
                s.seconds,
                s.cpu_seconds,
                mib(s.peak_memory_bytes)
            );
            if s.name == "estimate" && r.outer_iterations > 0 {
                for (step, wall, cpu) in [
                    (
                        "lighting step",
                        r.steps.lighting_seconds,
                        r.steps.lighting_cpu_seconds,
                    ),
                    (
                        "material step",
                        r.steps.material_seconds,
                        r.steps.material_cpu_seconds,
                    ),
                ] {
                    let _ = writeln!(
                        md,
                        "| {} | {} | {} | … {step} ({} iterations, within estimate) | {wall:.2} | {cpu:.2} | |",
                        r.vertices, r.photos, r.observations, r.outer_iterations
                    );
                }
            }
        }
        let _ = writeln!(
            md,
            "| {} | {} | {} | **total** | **{:.2}** | **{:.2}** | **{:.0}** |",
            r.vertices,
            r.photos,
            r.observations,
            r.total_seconds,
            r.total_cpu_seconds,
            mib(r.peak_memory_bytes)
        );
    }
    let _ = writeln!(
        md,
        "\n| vertices | photos | photo size | model | outer iterations | training RMSE | held-out RMSE (scaled) | synth s |\n|---:|---:|---|---|---:|---:|---:|---:|"
    );
    for r in runs {
        let _ = writeln!(
            md,
            "| {} | {} | {}×{} | {} | {} | {:.4} | {:.4} | {:.1}{} |",
            r.vertices,
            r.photos,
            r.width,
            r.height,
            r.model.label(),
            r.outer_iterations,
            r.train_rmse,
            r.holdout_rmse,
            r.synth_seconds,
            if r.synth_reused { " (reused)" } else { "" }
        );
    }
    md.push('\n');
}

fn growth_table(md: &mut String, what: &str, rows: &[Growth]) {
    if rows.is_empty() {
        return;
    }
    let _ = writeln!(
        md,
        "| stage | training observations from → to ({what}) | CPU (or MiB) ratio | (t₂/t₁)/(n₂/n₁) | exponent p |\n|---|---|---:|---:|---:|"
    );
    for g in rows {
        let flag = if g.exponent > 1.25 {
            " (super-linear)"
        } else {
            ""
        };
        let _ = writeln!(
            md,
            "| {} | {} → {} | {:.2} | {:.2} | {:.2}{flag} |",
            g.stage, g.from, g.to, g.time_ratio, g.relative, g.exponent
        );
    }
    md.push('\n');
}

/// The Markdown report; `name` is the file stem, for the link to the plot.
pub fn markdown(report: &BenchReport, name: &str) -> String {
    let mut md = String::new();
    let _ = writeln!(
        md,
        "# Pipeline benchmark{}\n\nRegenerate: `{}`\n\nScene `{}` built by `synth`, fitted by `run` (no training renders). \
Times are wall seconds of each stage as recorded by the run; CPU is user + system over all \
threads; peak is the stage's own resident high-water mark. Held-out RMSE: protocol (a) (true \
light), linear RGB, after the best global scale. Whole benchmark: {:.0} s.\n",
        if report.quick { " (--quick)" } else { "" },
        report.command,
        report.scene,
        report.seconds
    );
    let _ = writeln!(
        md,
        "Model fitted: {} (basis `{}`). Photos: {}; the same photos for every setting of a \
scene, so settings compare fairly. Synth time is reported apart and is not part of a run's \
time.{}\n",
        report.model.label(),
        report
            .model
            .basis
            .as_deref()
            .unwrap_or("lambert,phong:50,phong:500"),
        report.synth,
        if report.complete {
            ""
        } else {
            " **Incomplete: the benchmark was still running (or was stopped) when this was written.**"
        }
    );
    md.push_str(if report.isolated {
        "Every fit ran in a process of its own (`relight-cpc run`, its command line in the \
JSON), so each peak is that run's alone.\n\n"
    } else {
        "Memory: all runs share one process, so a stage's peak (the high-water mark reset \
before the stage) includes heap the allocator kept from earlier runs; the first run's \
figures are exact, later ones are upper bounds. For a clean figure run one size alone.\n\n"
    });
    if !report.vertex_runs.is_empty() {
        md.push_str("## Scaling in vertices\n\n");
        stage_table(&mut md, &report.vertex_runs);
        md.push_str("Growth between consecutive sizes in CPU seconds (and peak MiB), against n = training observations (p = ln(t₂/t₁)/ln(n₂/n₁), 1 = linear; stages under ~0.05 s are timer noise):\n\n");
        growth_table(&mut md, "vertices", &report.vertex_growth);
    }
    if !report.adaptive_runs.is_empty() {
        md.push_str("## The same scenes with the adaptive model (`--adaptive on`)\n\n");
        stage_table(&mut md, &report.adaptive_runs);
    }
    if !report.photo_runs.is_empty() {
        md.push_str("## Scaling in photos\n\n");
        stage_table(&mut md, &report.photo_runs);
        md.push_str("Growth between consecutive photo counts in CPU seconds (and peak MiB), against n = training observations:\n\n");
        growth_table(&mut md, "photos", &report.photo_growth);
    }
    if !report.sweep.is_empty() {
        let reference = report.reference.and_then(|i| report.sweep.get(i));
        let _ = writeln!(
            md,
            "## Error against run time\n\nOne scene ({} vertices, {} photos); reference: the dense untruncated model `{}`. \
`ratio` = held-out RMSE / reference's. ★ = on the Pareto front of (wall time, held-out RMSE).\n",
            report.sweep[0].vertices,
            report.sweep[0].photos,
            reference.map(|r| r.knobs.label()).unwrap_or_default()
        );
        md.push_str("| setting | global | keep | iterations | normal grid | lighting QP cap | wall s | CPU s | peak MiB | training RMSE | held-out RMSE | ratio | front |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|\n");
        let ref_err = reference.map(|r| r.holdout_rmse).unwrap_or(f64::NAN);
        for (i, r) in report.sweep.iter().enumerate() {
            let on = report.pareto.get(i).copied().unwrap_or(false);
            let _ = writeln!(
                md,
                "| {}{} | {} | {} | {} | {} | {} | {:.2} | {:.2} | {:.0} | {:.4} | {:.4} | {:.3} | {} |",
                r.knobs.label(),
                if Some(i) == report.reference {
                    " (reference)"
                } else {
                    ""
                },
                r.knobs.global_resolution,
                r.knobs.keep,
                r.knobs.iterations,
                r.knobs.normal_grid,
                r.knobs.lighting_qp,
                r.total_seconds,
                r.total_cpu_seconds,
                mib(r.peak_memory_bytes),
                r.train_rmse,
                r.holdout_rmse,
                r.holdout_rmse / ref_err,
                if on { "★" } else { "" }
            );
        }
        let front: Vec<String> = report
            .sweep
            .iter()
            .zip(&report.pareto)
            .filter(|(_, &on)| on)
            .map(|(r, _)| format!("`{}`", r.knobs.label()))
            .collect();
        let within: Vec<&BenchRun> = report
            .sweep
            .iter()
            .filter(|r| r.holdout_rmse <= 1.05 * ref_err)
            .collect();
        let fastest = within.iter().min_by(|a, b| {
            a.total_seconds
                .partial_cmp(&b.total_seconds)
                .unwrap_or(std::cmp::Ordering::Equal)
        });
        let _ = writeln!(
            md,
            "\nOn the Pareto front: {}.",
            if front.is_empty() {
                "none".into()
            } else {
                front.join(", ")
            }
        );
        if let Some(f) = fastest {
            let _ = writeln!(
                md,
                "Fastest setting within 5% of the reference's held-out error: `{}` ({:.2} s, ratio {:.3}).",
                f.knobs.label(),
                f.total_seconds,
                f.holdout_rmse / ref_err
            );
        }
        let errs: Vec<f64> = report
            .sweep
            .iter()
            .map(|r| r.holdout_rmse)
            .filter(|e| e.is_finite())
            .collect();
        let (lo, hi) = errs
            .iter()
            .fold((f64::MAX, f64::MIN), |(a, b), &e| (a.min(e), b.max(e)));
        if lo > 0.0 && hi >= lo {
            let _ = writeln!(
                md,
                "Held-out RMSE across all settings spans {lo:.4} to {hi:.4} ({:.1}% of the smallest): \
when this is small, the error is set by something the knobs do not touch (photo noise, \
renderer noise, the model's basis), and the front is decided by time.",
                100.0 * (hi - lo) / lo
            );
        }
        let _ = writeln!(
            md,
            "\nPlot: `{name}.png` (held-out RMSE against wall time, per knob family)."
        );
    }
    md
}

fn plot_sweep(report: &BenchReport, path: &Path) -> Result<()> {
    let reference = report.reference.and_then(|i| report.sweep.get(i));
    let Some(reference) = reference else {
        return Ok(());
    };
    // Families of the sweep: vary one knob from the default knobs (at the top resolution).
    let (_, _, _, base) = mode_settings(report.quick);
    let top = reference.knobs.global_resolution;
    let family = |f: &dyn Fn(&Knobs) -> bool| -> Vec<(f64, f64)> {
        let mut v: Vec<(f64, f64)> = report
            .sweep
            .iter()
            .filter(|r| f(&r.knobs))
            .map(|r| (r.total_seconds.log10(), r.holdout_rmse))
            .collect();
        v.sort_by(|a, b| a.0.partial_cmp(&b.0).unwrap_or(std::cmp::Ordering::Equal));
        v
    };
    let mut front: Vec<(f64, f64)> = report
        .sweep
        .iter()
        .zip(&report.pareto)
        .filter(|(_, &on)| on)
        .map(|(r, _)| (r.total_seconds.log10(), r.holdout_rmse))
        .collect();
    front.sort_by(|a, b| a.0.partial_cmp(&b.0).unwrap_or(std::cmp::Ordering::Equal));
    // Which knob a setting changes from the defaults at the top resolution (`None`: none).
    let at_top = Knobs {
        global_resolution: top,
        ..base
    };
    let varied = |k: &Knobs| -> Option<usize> { k.differs_from(&at_top).iter().position(|&d| d) };
    let mut series: Vec<Series> = Knobs::SWEPT
        .iter()
        .enumerate()
        .map(|(i, &label)| Series {
            label,
            // The family: the defaults and every setting that changes this knob alone.
            points: family(&|k| varied(k).is_none_or(|v| v == i)),
            color: PALETTE[i],
        })
        .collect();
    series.push(Series {
        label: "Pareto front",
        points: front,
        color: PALETTE[5],
    });
    line_panels(
        path,
        "log10 of the run's wall seconds",
        &[(
            "held-out RMSE against run time",
            "held-out RMSE (scaled)",
            series,
        )],
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stages(v: &[(&str, f64)]) -> Vec<(String, f64)> {
        v.iter().map(|(s, t)| (s.to_string(), *t)).collect()
    }

    /// Every sweep setting differs from the default knobs (at the top resolution) in at
    /// most one knob, each knob takes each of its listed values once, and the reference is
    /// the untruncated model with every other knob at its default.
    #[test]
    fn sweep_varies_one_knob_at_a_time() {
        for quick in [false, true] {
            let (_, _, _, base) = mode_settings(quick);
            let (list, idx) = sweep_knobs(base, quick);
            let top = list.iter().map(|k| k.global_resolution).max().unwrap();
            let at_top = Knobs {
                global_resolution: top,
                ..base
            };
            assert_eq!(list[idx], Knobs { keep: 0, ..at_top });
            for (i, k) in list.iter().enumerate() {
                assert!(!list[..i].contains(k), "{k:?} twice");
                let differ = k.differs_from(&at_top);
                assert!(differ.iter().filter(|&&d| d).count() <= 1, "{k:?}");
                assert!(!differ[5], "{k:?}: the local resolution is not swept");
            }
            // Three values of each knob other than keep (four, with the untruncated 0).
            let values = |f: fn(&Knobs) -> usize| {
                let mut v: Vec<usize> = list.iter().map(f).collect();
                v.sort_unstable();
                v.dedup();
                v.len()
            };
            assert_eq!(values(|k| k.global_resolution), 3);
            assert_eq!(values(|k| k.keep), 4);
            assert_eq!(values(|k| k.iterations), 3);
            assert_eq!(values(|k| k.normal_grid), 3);
            assert_eq!(values(|k| k.lighting_qp), 3);
            assert!(list.contains(&at_top), "the default knobs are a row");
        }
    }

    /// Power laws t = c·nᵖ give back their exponent and ratio (n₂/n₁)^(p−1) exactly up to
    /// floating-point rounding (1e-12 relative is many ulps above it).
    #[test]
    fn growth_of_power_laws() {
        let series: Vec<(f64, Vec<(String, f64)>)> = [1e4, 1e5, 4e5]
            .iter()
            .map(|&n: &f64| {
                (
                    n,
                    stages(&[
                        ("linear", 3e-5 * n),
                        ("quadratic", 1e-9 * n * n),
                        ("constant", 0.7),
                    ]),
                )
            })
            .collect();
        let g = growth_rates(&series);
        assert_eq!(g.len(), 6);
        for row in &g {
            let p = match row.stage.as_str() {
                "linear" => 1.0,
                "quadratic" => 2.0,
                _ => 0.0,
            };
            let r = row.to / row.from;
            assert!((row.exponent - p).abs() < 1e-12, "{row:?}");
            assert!(
                (row.relative - r.powf(p - 1.0)).abs() < 1e-12 * r.powf(p),
                "{row:?}"
            );
            assert!(
                (row.time_ratio - r.powf(p)).abs() < 1e-12 * r.powf(p),
                "{row:?}"
            );
        }
    }

    /// Missing stages, zero times and equal sizes give no row rather than NaN or ∞.
    #[test]
    fn growth_skips_undefined_rows() {
        let series = vec![
            (10.0, stages(&[("a", 1.0), ("b", 0.0), ("c", 1.0)])),
            (10.0, stages(&[("a", 2.0)])),
            (20.0, stages(&[("a", 4.0), ("b", 1.0)])),
        ];
        let g = growth_rates(&series);
        assert_eq!(g.len(), 1);
        assert_eq!(g[0].stage, "a");
        assert!((g[0].exponent - 1.0).abs() < 1e-12);
    }

    /// The front of a small hand-checked set: (1, 5) (2, 3) (4, 1) are each best in some
    /// trade-off; (3, 4) is beaten by (2, 3); (4, 2) by (4, 1); duplicates both stay.
    #[test]
    fn pareto_by_hand() {
        let pts = [
            (1.0, 5.0),
            (2.0, 3.0),
            (3.0, 4.0),
            (4.0, 1.0),
            (4.0, 2.0),
            (f64::NAN, 0.0),
        ];
        assert_eq!(
            pareto_front(&pts),
            vec![true, true, false, true, false, false]
        );
        assert_eq!(pareto_front(&[(1.0, 1.0), (1.0, 1.0)]), vec![true, true]);
    }
}
