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

use crate::report::plot::{line_panels, Series, PALETTE};
use crate::run::{self, Holdout, MaterialCount, RunOptions};
use crate::solve::StepTimes;
use crate::stages::StageRecord;
use crate::synth::{self, SynthOptions};
use crate::{Error, Result};
use serde::{Deserialize, Serialize};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

mod child;
mod markdown;
mod sweep;
#[cfg(test)]
mod tests;

use child::{measure, shell_line};
pub use markdown::markdown;
use markdown::{mib, plot_sweep};
use sweep::{mode_settings, scene, stage_costs, sweep_knobs, BenchScene};

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

/// The model the bench's runs fit (the `run` flags `--materials`, `--basis`, `--adaptive`,
/// `--large-mesh`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Model {
    /// Number of materials; `None` = `auto`.
    pub materials: Option<usize>,
    /// Basis BRDF list as `run --basis` takes it; `None` = run's default.
    pub basis: Option<String>,
    /// `run --adaptive`.
    pub adaptive: bool,
    /// `run --large-mesh` ([`crate::run::LARGE_MESH`], beside the knobs).
    pub large_mesh: bool,
}

impl Default for Model {
    /// `run`'s defaults with the adaptive model off (the knobs are then what is measured).
    fn default() -> Self {
        Model {
            materials: None,
            basis: None,
            adaptive: false,
            large_mesh: false,
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
            large_mesh: false,
        }
    }

    /// Short label, e.g. `K6 B7 adaptive off`.
    pub fn label(&self) -> String {
        let b = self
            .basis
            .as_deref()
            .map_or(3, |s| s.split(',').filter(|t| !t.trim().is_empty()).count());
        format!(
            "K{} B{} adaptive {}{}",
            self.materials.map_or("auto".into(), |k| k.to_string()),
            b,
            if self.adaptive { "on" } else { "off" },
            if self.large_mesh { " large-mesh" } else { "" }
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

impl BenchReport {
    /// The report of a bench with `opts` run by `command`, before any run.
    pub fn started(opts: &BenchOptions, command: String) -> Self {
        BenchReport {
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
            command,
        }
    }

    /// The sweep's dense reference, once it has run.
    pub fn reference_run(&self) -> Option<&BenchRun> {
        self.reference.and_then(|i| self.sweep.get(i))
    }

    /// The reference the sweep's plot is drawn against, once there is a plot to draw: the
    /// reference has run (the sweep runs it after other settings) beside another setting.
    pub fn plot_reference(&self) -> Option<&BenchRun> {
        self.reference_run().filter(|_| self.sweep.len() > 1)
    }
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
        crate::transport::brdf::parse_list(b)?;
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

/// The bench's rows in order (vertices, photos, then the error-against-time sweep), the
/// report saved after every row so that an interrupted bench keeps what it measured.
fn bench_in(
    opts: &BenchOptions,
    files: &crate::out_dir::OutFiles,
    work: &Path,
    temporary: bool,
    t0: std::time::Instant,
) -> Result<BenchReport> {
    let (_, _, _, sweep_base) = mode_settings(opts.quick);
    let mut b = Session {
        opts,
        files,
        work,
        temporary,
        t0,
        base: Knobs {
            iterations: opts.iterations.unwrap_or(sweep_base.iterations),
            ..sweep_base
        },
        report: BenchReport::started(opts, shell_line(std::env::args().skip(1))),
    };
    let sizes = sorted_unique(&opts.sizes);
    if !opts.sweep_only {
        b.vertex_rows(&sizes)?;
        b.photo_rows(&sizes)?;
    }
    if !opts.no_sweep {
        b.sweep_rows(
            sizes.first().copied().unwrap_or(opts.base_vertices),
            sweep_base,
        )?;
    }
    b.report.complete = true;
    b.save()?;
    Ok(b.report)
}

/// `v` sorted, each value once.
fn sorted_unique(v: &[usize]) -> Vec<usize> {
    let mut v = v.to_vec();
    v.sort_unstable();
    v.dedup();
    v
}

/// One bench in progress: where it works and writes, the knobs of its scaling rows, the
/// report so far.
struct Session<'a> {
    opts: &'a BenchOptions,
    files: &'a crate::out_dir::OutFiles,
    work: &'a Path,
    /// Whether the scenes are removed once measured.
    temporary: bool,
    t0: std::time::Instant,
    base: Knobs,
    report: BenchReport,
}

impl Session<'_> {
    /// The report summarised and written as it stands.
    fn save(&mut self) -> Result<()> {
        summarise(&mut self.report);
        self.report.seconds = self.t0.elapsed().as_secs_f64();
        write_outputs(&self.report, self.files, &self.opts.name)
    }

    /// A scene measured: removed when the bench's scenes are temporary.
    fn done(&self, s: &BenchScene) -> Result<()> {
        if self.temporary {
            std::fs::remove_dir_all(&s.dir).map_err(|e| Error::io(&s.dir, e))?;
        }
        Ok(())
    }

    /// Scaling in vertices at the base photo count (with `--adaptive-rows`, each size also
    /// with the adaptive model).
    fn vertex_rows(&mut self, sizes: &[usize]) -> Result<()> {
        let opts = self.opts;
        let adaptive = Model {
            adaptive: true,
            ..opts.model.clone()
        };
        for &n in sizes {
            let s = scene(opts, self.work, n, opts.base_photos)?;
            let r = measure("vertices", &s, self.base, &opts.model, opts)?;
            self.report.vertex_runs.push(r);
            self.save()?;
            if opts.adaptive_rows {
                let r = measure("adaptive", &s, self.base, &adaptive, opts)?;
                self.report.adaptive_runs.push(r);
                self.save()?;
            }
            self.done(&s)?;
        }
        Ok(())
    }

    /// Scaling in photos at the base vertex count; the (vertices, photos) pair the vertex
    /// rows already ran is reused.
    fn photo_rows(&mut self, sizes: &[usize]) -> Result<()> {
        let opts = self.opts;
        for p in sorted_unique(&opts.photos) {
            if let Some(i) = sizes
                .iter()
                .position(|&n| n == opts.base_vertices && p == opts.base_photos)
            {
                let mut r = self.report.vertex_runs[i].clone();
                r.group = "photos".into();
                self.report.photo_runs.push(r);
                continue;
            }
            let s = scene(opts, self.work, opts.base_vertices, p)?;
            let r = measure("photos", &s, self.base, &opts.model, opts)?;
            self.report.photo_runs.push(r);
            self.save()?;
            self.done(&s)?;
        }
        Ok(())
    }

    /// Error against time on the scene of `n` vertices: every knob setting of the sweep
    /// around `sweep_base`.
    fn sweep_rows(&mut self, n: usize, sweep_base: Knobs) -> Result<()> {
        let opts = self.opts;
        let s = scene(opts, self.work, n, opts.base_photos)?;
        let (list, idx) = sweep_knobs(sweep_base, opts.quick);
        self.report.reference = Some(idx);
        for k in list {
            let r = measure("sweep", &s, k, &opts.model, opts)?;
            self.report.sweep.push(r);
            self.save()?;
        }
        self.done(&s)
    }
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
        .map_err(|e| Error::Internal(format!("bench: could not encode the report: {e}")))?;
    files.write(&json_name, json.as_bytes())?;
    files.write(&md_name, markdown(report, name).as_bytes())?;
    if let Some(reference) = report.plot_reference() {
        files.write_with(&png_name, |p| plot_sweep(report, reference, p))?;
    }
    Ok(())
}
