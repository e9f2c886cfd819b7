//! One measured run: `relight-cpc run` in a child process (its own peak memory), its report read back.

use super::*;

/// Fit `ws` with `knobs` and measure it.
pub(crate) fn measure(
    group: &str,
    s: &BenchScene,
    knobs: Knobs,
    model: &Model,
    opts: &BenchOptions,
) -> Result<BenchRun> {
    let (width, height, _, _) = mode_settings(opts.quick);
    let out = s.dir.with_extension("fit");
    let o = bench_options(s, &out, &knobs, model, opts)?;
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
    let holdout_rmse = fit.holdout_mean();
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

/// `run`'s options for one bench fit of `s` into `out`: the model's count, basis and
/// adaptivity, the knobs' sides, budget and caps, `--large-mesh` when the model asks;
/// no training renders, and `out` replaced.
fn bench_options(
    s: &BenchScene,
    out: &std::path::Path,
    knobs: &Knobs,
    model: &Model,
    opts: &BenchOptions,
) -> Result<RunOptions> {
    let mut o = RunOptions::new(s.dir.to_path_buf(), out.to_path_buf());
    o.holdout = Holdout::Default;
    o.materials = model
        .materials
        .map_or(MaterialCount::Auto, MaterialCount::Fixed);
    if let Some(b) = &model.basis {
        o.basis = crate::transport::brdf::parse_list(b)?;
    }
    o.adaptive = model.adaptive;
    o.global_resolution = knobs.global_resolution;
    o.local_resolution = knobs.local_resolution;
    o.normal_grid = knobs.normal_grid;
    o.keep = knobs.keep;
    o.max_iterations = knobs.iterations;
    o.lighting_qp_iterations = knobs.lighting_qp;
    if model.large_mesh {
        crate::run::LARGE_MESH.apply(&mut o);
    }
    o.progress = opts.progress;
    o.force = true;
    o.render_training = false;
    Ok(o)
}

/// What the bench reads of a run's report (`report.json` of a child run, or the
/// in-process [`crate::report::RunReport`] through the same JSON); NaN figures are `null` in the
/// JSON, hence the options.
#[derive(Debug, Deserialize)]
pub(crate) struct Fit {
    pub(crate) holdout: Vec<FitHoldout>,
    pub(crate) train_rmse: Option<f64>,
    pub(crate) train: Vec<FitTrain>,
    pub(crate) stage_details: Vec<StageRecord>,
    pub(crate) peak_memory_bytes: u64,
    /// One entry per outer iteration run.
    pub(crate) timeline: Vec<StepTimes>,
}

#[derive(Debug, Deserialize)]
pub(crate) struct FitHoldout {
    pub(crate) protocol: String,
    pub(crate) rmse_scaled: Option<f64>,
}

#[derive(Debug, Deserialize)]
pub(crate) struct FitTrain {
    pub(crate) observations: usize,
}

impl Fit {
    pub(crate) fn from_report(r: &crate::report::RunReport) -> Result<Self> {
        serde_json::to_value(r)
            .and_then(serde_json::from_value)
            .map_err(|e| Error::Internal(format!("bench: could not read the run's report: {e}")))
    }

    pub(crate) fn from_json(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        serde_json::from_str(&text)
            .map_err(|e| Error::Internal(format!("{}: not a run report: {e}", path.display())))
    }

    /// The mean scaled RMSE of the held-out photos under their true light (`truth`), or,
    /// without a truth, of protocol `mean`; NaN when neither has a finite figure.
    pub(crate) fn holdout_mean(&self) -> f64 {
        let pick = |p: &str| -> Vec<f64> {
            self.holdout
                .iter()
                .filter(|h| h.protocol == p)
                .filter_map(|h| h.rmse_scaled.filter(|x| x.is_finite()))
                .collect()
        };
        let mut held = pick("truth");
        if held.is_empty() {
            held = pick("mean");
        }
        if held.is_empty() {
            f64::NAN
        } else {
            held.iter().sum::<f64>() / held.len() as f64
        }
    }
}

/// `relight-cpc` and `args` as one shell line, arguments with white space in quotes.
pub(crate) fn shell_line(args: impl IntoIterator<Item = String>) -> String {
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
pub(crate) fn run_args(o: &RunOptions, model: &Model) -> Vec<String> {
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
    ] {
        a.extend([flag.into(), v.to_string()]);
    }
    let cap = o.lighting_qp_iterations.to_string();
    a.extend(["--lighting-qp-iterations".into(), cap]);
    // The light model as the bench gives it, never chosen by mesh size.
    a.extend(["--light".into(), o.light.name().into()]);
    // The model's settings as the bench gives them, never chosen by mesh size.
    a.push(
        if model.large_mesh {
            "--large-mesh"
        } else {
            "--no-large-mesh"
        }
        .into(),
    );
    if !o.progress {
        a.push("--quiet".into());
    }
    a
}

/// Fit in a child process `exe run …` and read its `report.json`; also returns the
/// command line, for the report.
pub(crate) fn fit_in_child(exe: &Path, o: &RunOptions, model: &Model) -> Result<(Fit, String)> {
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
