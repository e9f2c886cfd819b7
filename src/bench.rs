//! `relight-cpc bench`: cost of the whole pipeline at set sizes, how each stage's cost
//! grows with the problem, and held-out error against run time over the speed knobs
//! (issue 9).
//!
//! Every run builds a known-truth scene with [`crate::synth::build`] and fits it with
//! [`crate::run::run`]; the figures come from the run's own [`crate::stages`] records
//! (wall, CPU, per-stage peak resident memory) and its report (training RMSE, held-out
//! RMSE of protocol (a), true light, after the best global scale).
//!
//! Growth of a stage between two sizes `n₁ < n₂` with times `t₁, t₂` is given two ways:
//! the ratio `(t₂/t₁) / (n₂/n₁)` (1 = linear, < 1 sub-linear) and the log-log exponent
//! `p = ln(t₂/t₁) / ln(n₂/n₁)` of a power law `t ∝ nᵖ`. The paper's cost model (Eq. 7–12:
//! one transport row per observation, the lighting and material steps summing over
//! observations) predicts `p ≈ 1` in the number of observations.
//!
//! The error-against-time sweep varies the global map resolution, the coefficient budget
//! (`keep`) and the outer iteration count on one small scene; the dense untruncated model
//! (`keep` 0 at the largest resolution) is the reference. A setting is on the Pareto front
//! when no other setting is both at least as fast and at least as accurate, and strictly
//! better in one of the two.

use crate::report::plot::{line_panels, Series, PALETTE};
use crate::run::{self, Holdout, MaterialCount, RunOptions};
use crate::stages::StageRecord;
use crate::synth::{self, SynthOptions};
use crate::{Error, Result};
use serde::Serialize;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Options of [`bench`].
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
    /// Output folder (`pipeline.json`, `pipeline.md`, `pipeline.png`).
    pub out: PathBuf,
    /// Small photos, cheap renderer and small maps: a smoke run of a few minutes.
    pub quick: bool,
    /// The `synth` scene.
    pub scene: String,
    /// Skip the error-against-time sweep.
    pub no_sweep: bool,
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
            quick: false,
            scene: "spot-varying".into(),
            no_sweep: false,
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
            quick: true,
            scene: "sphere-plane".into(),
            no_sweep: false,
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
}

impl Knobs {
    /// Short label, e.g. `g64 k128 it8`.
    pub fn label(&self) -> String {
        let keep = if self.keep == 0 {
            "all".to_string()
        } else {
            self.keep.to_string()
        };
        format!(
            "g{} k{} it{}",
            self.global_resolution, keep, self.iterations
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
    /// Seconds `synth` spent building the scene (not part of the run).
    pub synth_seconds: f64,
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
}

/// Growth of one stage's wall time between two consecutive sizes.
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
    /// Sweep runs.
    pub sweep: Vec<BenchRun>,
    /// Index in `sweep` of the dense reference.
    pub reference: Option<usize>,
    /// Per sweep run: on the Pareto front of (time, held-out error).
    pub pareto: Vec<bool>,
    /// Wall seconds of the whole benchmark.
    pub seconds: f64,
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

/// Per-stage seconds of a run, with a `total` entry.
fn stage_seconds(run: &BenchRun) -> Vec<(String, f64)> {
    let mut v: Vec<(String, f64)> = run
        .stages
        .iter()
        .map(|s| (s.name.clone(), s.seconds))
        .collect();
    v.push(("total".into(), run.total_seconds));
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
            },
        )
    }
}

/// The sweep's settings and the index of the dense reference among them.
fn sweep_knobs(base: Knobs, quick: bool) -> (Vec<Knobs>, usize) {
    let (resolutions, keeps, iterations): (&[usize], &[usize], &[usize]) = if quick {
        (&[8, 16, 32], &[16, 32, 64, 0], &[1, 2, 3])
    } else {
        (&[16, 32, 64], &[32, 64, 128, 0], &[2, 4, 8])
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
    let reference = Knobs { keep: 0, ..at_top };
    push(reference);
    let idx = list.iter().position(|k| *k == reference).unwrap_or(0);
    (list, idx)
}

/// Build (or reuse) a synth workspace in `work` for `(vertices, photos)`.
fn scene(
    opts: &BenchOptions,
    work: &Path,
    vertices: usize,
    photos: usize,
) -> Result<(PathBuf, synth::SynthSummary)> {
    let (width, height, samples, _) = mode_settings(opts.quick);
    let dir = work.join(format!("{}-v{vertices}-p{photos}", opts.scene));
    if dir.exists() {
        std::fs::remove_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
    }
    let s = synth::build(
        &opts.scene,
        &dir,
        &SynthOptions {
            width,
            height,
            photos: Some(photos),
            seed: 1,
            vertices: Some(vertices),
            samples,
            ..SynthOptions::default()
        },
    )?;
    Ok((dir, s))
}

/// Fit `ws` with `knobs` and measure it.
fn measure(
    group: &str,
    ws: &Path,
    s: &synth::SynthSummary,
    knobs: Knobs,
    quick: bool,
) -> Result<BenchRun> {
    let (width, height, _, _) = mode_settings(quick);
    let out = ws.with_extension("fit");
    let mut o = RunOptions::new(ws.to_path_buf(), out.clone());
    o.holdout = Holdout::Default;
    o.materials = MaterialCount::Auto;
    o.global_resolution = knobs.global_resolution;
    o.local_resolution = knobs.local_resolution;
    o.normal_grid = knobs.normal_grid;
    o.keep = knobs.keep;
    o.max_iterations = knobs.iterations;
    o.progress = false;
    o.force = true;
    o.render_training = false;
    let summary = run::run(&o)?;
    let r = summary.report;
    let pick = |p: &str| -> Vec<f64> {
        r.holdout
            .iter()
            .filter(|h| h.protocol == p && h.rmse_scaled.is_finite())
            .map(|h| h.rmse_scaled)
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
        photos: s.photos.len(),
        observations: r.train.iter().map(|t| t.observations).sum(),
        width,
        height,
        knobs,
        synth_seconds: s.render_seconds,
        total_seconds: r.stage_details.iter().map(|x| x.seconds).sum(),
        total_cpu_seconds: r.stage_details.iter().map(|x| x.cpu_seconds).sum(),
        stages: r.stage_details,
        peak_memory_bytes: r.peak_memory_bytes,
        train_rmse: r.train_rmse,
        holdout_rmse,
    };
    let _ = std::fs::remove_dir_all(&out);
    eprintln!(
        "bench {group}: {} vertices, {} photos, {}: {:.1} s, held-out RMSE {:.4}",
        run.vertices,
        run.photos,
        knobs.label(),
        run.total_seconds,
        run.holdout_rmse
    );
    Ok(run)
}

/// Run the benchmark and write `pipeline.{json,md,png}` into `opts.out`.
pub fn bench(opts: &BenchOptions) -> Result<BenchReport> {
    if opts.sizes.is_empty() && opts.photos.is_empty() && opts.no_sweep {
        return Err(Error::Config("bench: nothing to run".into()));
    }
    if opts.sizes.iter().chain(&opts.photos).any(|&n| n == 0) || opts.base_photos < 2 {
        return Err(Error::Config(
            "bench: sizes and photo counts must be at least 1 (2 for --base-photos)".into(),
        ));
    }
    let t0 = std::time::Instant::now();
    std::fs::create_dir_all(&opts.out).map_err(|e| Error::io(&opts.out, e))?;
    let work = std::env::temp_dir().join(format!("relight-bench-{}", std::process::id()));
    std::fs::create_dir_all(&work).map_err(|e| Error::io(&work, e))?;
    let result = bench_in(opts, &work, t0);
    let _ = std::fs::remove_dir_all(&work);
    result
}

fn bench_in(opts: &BenchOptions, work: &Path, t0: std::time::Instant) -> Result<BenchReport> {
    let (_, _, _, base) = mode_settings(opts.quick);
    let mut sizes = opts.sizes.clone();
    sizes.sort_unstable();
    sizes.dedup();
    let mut photos = opts.photos.clone();
    photos.sort_unstable();
    photos.dedup();

    // Scaling in vertices, then in photos; a (vertices, photos) pair already run is reused.
    let mut vertex_runs = Vec::new();
    for &n in &sizes {
        let (ws, s) = scene(opts, work, n, opts.base_photos)?;
        vertex_runs.push(measure("vertices", &ws, &s, base, opts.quick)?);
        std::fs::remove_dir_all(&ws).map_err(|e| Error::io(&ws, e))?;
    }
    let mut photo_runs = Vec::new();
    for &p in &photos {
        if let Some(i) = sizes
            .iter()
            .position(|&n| n == opts.base_vertices && p == opts.base_photos)
        {
            let mut r = vertex_runs[i].clone();
            r.group = "photos".into();
            photo_runs.push(r);
            continue;
        }
        let (ws, s) = scene(opts, work, opts.base_vertices, p)?;
        photo_runs.push(measure("photos", &ws, &s, base, opts.quick)?);
        std::fs::remove_dir_all(&ws).map_err(|e| Error::io(&ws, e))?;
    }
    let vertex_growth = growth_rates(
        &vertex_runs
            .iter()
            .map(|r| (r.vertices as f64, stage_seconds(r)))
            .collect::<Vec<_>>(),
    );
    let photo_growth = growth_rates(
        &photo_runs
            .iter()
            .map(|r| (r.photos as f64, stage_seconds(r)))
            .collect::<Vec<_>>(),
    );

    // Error against time on the smallest scene.
    let (mut sweep, mut reference, mut pareto) = (Vec::new(), None, Vec::new());
    if !opts.no_sweep {
        let n = sizes.first().copied().unwrap_or(opts.base_vertices);
        let (ws, s) = scene(opts, work, n, opts.base_photos)?;
        let (list, idx) = sweep_knobs(base, opts.quick);
        for k in list {
            sweep.push(measure("sweep", &ws, &s, k, opts.quick)?);
        }
        std::fs::remove_dir_all(&ws).map_err(|e| Error::io(&ws, e))?;
        reference = Some(idx);
        pareto = pareto_front(
            &sweep
                .iter()
                .map(|r| (r.total_seconds, r.holdout_rmse))
                .collect::<Vec<_>>(),
        );
    }

    let report = BenchReport {
        quick: opts.quick,
        scene: opts.scene.clone(),
        vertex_runs,
        photo_runs,
        vertex_growth,
        photo_growth,
        sweep,
        reference,
        pareto,
        seconds: t0.elapsed().as_secs_f64(),
    };
    write_outputs(&report, &opts.out)?;
    Ok(report)
}

fn write_outputs(report: &BenchReport, out: &Path) -> Result<()> {
    let json_path = out.join("pipeline.json");
    let json = serde_json::to_string_pretty(report)
        .map_err(|e| Error::Config(format!("bench: could not encode the report: {e}")))?;
    std::fs::write(&json_path, json).map_err(|e| Error::io(&json_path, e))?;
    let md_path = out.join("pipeline.md");
    std::fs::write(&md_path, markdown(report)).map_err(|e| Error::io(&md_path, e))?;
    if !report.sweep.is_empty() {
        plot_sweep(report, &out.join("pipeline.png"))?;
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
        "\n| vertices | photos | {}² photos | training RMSE | held-out RMSE (scaled) | synth s |\n|---:|---:|---|---:|---:|---:|",
        runs[0].width
    );
    for r in runs {
        let _ = writeln!(
            md,
            "| {} | {} | {}×{} | {:.4} | {:.4} | {:.1} |",
            r.vertices, r.photos, r.width, r.height, r.train_rmse, r.holdout_rmse, r.synth_seconds
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
        "| stage | {what} from → to | time ratio | (t₂/t₁)/(n₂/n₁) | exponent p |\n|---|---|---:|---:|---:|"
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

/// The Markdown report.
pub fn markdown(report: &BenchReport) -> String {
    let mut md = String::new();
    let _ = writeln!(
        md,
        "# Pipeline benchmark{}\n\nScene `{}` built by `synth`, fitted by `run` (quiet, no training renders). \
Times are wall seconds of each stage as recorded by the run; CPU is user + system over all \
threads; peak is the stage's own resident high-water mark. Held-out RMSE: protocol (a) (true \
light), linear RGB, after the best global scale. Whole benchmark: {:.0} s.\n",
        if report.quick { " (--quick)" } else { "" },
        report.scene,
        report.seconds
    );
    md.push_str(
        "Memory: all runs share one process, so a stage's peak (the high-water mark reset \
before the stage) includes heap the allocator kept from earlier runs; the first run's \
figures are exact, later ones are upper bounds. For a clean figure run one size alone.\n\n",
    );
    if !report.vertex_runs.is_empty() {
        md.push_str("## Scaling in vertices\n\n");
        stage_table(&mut md, &report.vertex_runs);
        md.push_str("Growth between consecutive sizes (n = vertices; p = ln(t₂/t₁)/ln(n₂/n₁), 1 = linear; stages under ~0.05 s are timer noise):\n\n");
        growth_table(&mut md, "vertices", &report.vertex_growth);
    }
    if !report.photo_runs.is_empty() {
        md.push_str("## Scaling in photos\n\n");
        stage_table(&mut md, &report.photo_runs);
        md.push_str("Growth between consecutive photo counts (n = photos):\n\n");
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
        md.push_str("| setting | global | keep | iterations | wall s | peak MiB | training RMSE | held-out RMSE | ratio | front |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---|\n");
        let ref_err = reference.map(|r| r.holdout_rmse).unwrap_or(f64::NAN);
        for (i, r) in report.sweep.iter().enumerate() {
            let on = report.pareto.get(i).copied().unwrap_or(false);
            let _ = writeln!(
                md,
                "| {}{} | {} | {} | {} | {:.2} | {:.0} | {:.4} | {:.4} | {:.3} | {} |",
                r.knobs.label(),
                if Some(i) == report.reference {
                    " (reference)"
                } else {
                    ""
                },
                r.knobs.global_resolution,
                r.knobs.keep,
                r.knobs.iterations,
                r.total_seconds,
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
        md.push_str("\nPlot: `pipeline.png` (held-out RMSE against wall time, per knob family).\n");
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
    let series = vec![
        Series {
            label: "global resolution",
            points: family(&|k| k.keep == base.keep && k.iterations == base.iterations),
            color: PALETTE[0],
        },
        Series {
            label: "keep (coefficients)",
            points: family(&|k| k.global_resolution == top && k.iterations == base.iterations),
            color: PALETTE[1],
        },
        Series {
            label: "iterations",
            points: family(&|k| k.global_resolution == top && k.keep == base.keep),
            color: PALETTE[2],
        },
        Series {
            label: "Pareto front",
            points: front,
            color: PALETTE[5],
        },
    ];
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
