//! The bench's outputs: the Markdown tables (stages, growth, the sweep's front) and the sweep's plot.

use super::*;

pub(crate) fn mib(b: u64) -> f64 {
    b as f64 / (1024.0 * 1024.0)
}

/// One stage table for a group of runs.
pub(crate) fn stage_table(md: &mut String, runs: &[BenchRun]) {
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

pub(crate) fn growth_table(md: &mut String, what: &str, rows: &[Growth]) {
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
    header(&mut md, report);
    scaling_sections(&mut md, report);
    if !report.sweep.is_empty() {
        sweep_section(&mut md, report, name);
    }
    md
}

/// The title, the command that regenerates the file, what was fitted and how memory was
/// measured.
fn header(md: &mut String, report: &BenchReport) {
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
}

/// The vertex, adaptive and photo scaling tables, each with its growth exponents.
fn scaling_sections(md: &mut String, report: &BenchReport) {
    if !report.vertex_runs.is_empty() {
        md.push_str("## Scaling in vertices\n\n");
        stage_table(md, &report.vertex_runs);
        md.push_str("Growth between consecutive sizes in CPU seconds (and peak MiB), against n = training observations (p = ln(t₂/t₁)/ln(n₂/n₁), 1 = linear; stages under ~0.05 s are timer noise):\n\n");
        growth_table(md, "vertices", &report.vertex_growth);
    }
    if !report.adaptive_runs.is_empty() {
        md.push_str("## The same scenes with the adaptive model (`--adaptive on`)\n\n");
        stage_table(md, &report.adaptive_runs);
    }
    if !report.photo_runs.is_empty() {
        md.push_str("## Scaling in photos\n\n");
        stage_table(md, &report.photo_runs);
        md.push_str("Growth between consecutive photo counts in CPU seconds (and peak MiB), against n = training observations:\n\n");
        growth_table(md, "photos", &report.photo_growth);
    }
}

/// Error against run time: the sweep's table, its Pareto front, the fastest setting within
/// 5% of the reference and the plot's name.
fn sweep_section(md: &mut String, report: &BenchReport, name: &str) {
    let reference = report.reference_run();
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
    sweep_summary(md, report, ref_err);
    if report.plot_reference().is_some() {
        let _ = writeln!(
            md,
            "\nPlot: `{name}.png` (held-out RMSE against wall time, per knob family)."
        );
    }
}

/// The sweep's Pareto front, its fastest setting within 5% of the reference's held-out error
/// (`ref_err`) and the spread of held-out errors.
fn sweep_summary(md: &mut String, report: &BenchReport, ref_err: f64) {
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
}

pub(crate) fn plot_sweep(report: &BenchReport, reference: &BenchRun, path: &Path) -> Result<()> {
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
