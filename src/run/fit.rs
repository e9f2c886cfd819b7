//! Stage 6 of `run`: the estimate. Initial materials (clustering or the pilot's count),
//! the starts, the alternation with the held-out tracker, then the fitted model
//! ([`Fitted`]) that the evaluation and the outputs read.

use super::half_fit::{projected_x, span_mid};
use super::state::{Imported, Observed, Prepared, RunLog};
use super::tracker::HoldoutTracker;
use super::{
    check_finite, choose_material_count, conditioning_map, train_errors, Fitted, MaterialCount,
    Progress, RunOptions, StartBrightness,
};
use crate::observe::Observations;
use crate::report::{TimelinePoint, TrainEntry};
use crate::solve::adapt::Decision;
use crate::solve::cluster::initial_materials;
use crate::solve::light::choose::LightChoice;
use crate::solve::materials::brightness;
use crate::solve::materials::propagate::{propagate_unseen_over, VertexGraph};
use crate::solve::options::PhotoHalves;
use crate::solve::starts::{self, MultiStart};
use crate::solve::{self, EstimateOptions, Materials0, Problem, Robust};
use crate::transport::brdf::BasisBrdf;
use crate::{Error, Result};

/// After the fit: the fitted model and what the report needs of the fit.
pub(crate) struct Fit<'a> {
    pub(crate) fitted: Fitted<'a>,
    pub(crate) train_entries: Vec<TrainEntry>,
    pub(crate) timeline: Vec<TimelinePoint>,
    pub(crate) multi: MultiStart,
    /// Why the model has its size (materials).
    pub(crate) reasons: Vec<String>,
    pub(crate) decisions: Vec<Decision>,
    /// The per-photo light model kept and why.
    pub(crate) light_decision: crate::solve::light::choose::LightDecision,
    /// What the transient pass masked (`None`: `--transients off`).
    pub(crate) transients: Option<super::transients::Transients>,
}

/// The index of the Lambertian basis BRDF, which carries the diffuse colour.
pub(crate) fn lambert_of(basis: &[BasisBrdf]) -> Result<usize> {
    basis
        .iter()
        .position(|b| matches!(b, BasisBrdf::Lambert))
        .ok_or_else(|| {
            Error::Config("--basis: a Lambertian lobe is needed to carry the diffuse colour".into())
        })
}

/// The estimator's options from the run's.
pub(crate) fn estimate_options(o: &RunOptions, lambert: usize, strata: &[u32]) -> EstimateOptions {
    EstimateOptions {
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
        weights_sum: o.weights_sum.value(),
        weights_sum_scope: o.weights_sum_scope,
        weights_smoothness: o.weights_smoothness,
        achromatic_specular: o.achromatic_specular,
        alternation_qp_iters: (o.lighting_qp_iterations > 0).then_some(o.lighting_qp_iterations),
        alternation_cg_iters: (o.lighting_cg_iterations > 0).then_some(o.lighting_cg_iterations),
        patience: o.patience,
        min_iterations: o.min_iterations,
        lambert_basis: lambert,
        validation_seed: o.seed,
        validation_fraction: o.validation,
        validation_block: o.validation_block,
        lighting_sample: o.lighting_sample,
        blend_tolerance: o.blend_tolerance,
        lighting_strata: strata.to_vec(),
        scale_anchor: o.scale_anchor,
        ..EstimateOptions::default()
    }
}

/// Early stopping's split by photo half (`--validation-halves k`): `k` training photos
/// spread evenly over the list (the middle of each of `k` equal runs), and in each the
/// vertices it observes projecting at or right of the middle of their `x` span
/// ([`span_mid`], the left/right rule of protocol `half`). `None` for `k = 0` or
/// when `k` is not below the number of training photos.
fn photo_halves(
    scene: &crate::import::scene::Scene,
    train: &[usize],
    obs: &Observations,
    k: usize,
) -> Option<std::sync::Arc<PhotoHalves>> {
    let n = train.len();
    if k == 0 || k >= n {
        return None;
    }
    let positions = &scene.mesh.positions;
    let right = (0..k)
        .map(|i| {
            let t = (2 * i + 1) * n / (2 * k);
            let view = &scene.views[train[t]];
            let px: Vec<(usize, f64)> = obs
                .photo_ranges
                .get(t)
                .cloned()
                .unwrap_or_default()
                .filter(|&p| obs.weight[p] > 0.0)
                .filter_map(|p| {
                    let x = obs.vertex[p] as usize;
                    projected_x(view, &positions[x]).map(|u| (x, u))
                })
                .collect();
            let mut right = vec![false; positions.len()];
            if let Some(mid) = span_mid(px.iter().map(|&(_, u)| u)) {
                for &(x, u) in &px {
                    right[x] = u >= mid;
                }
            }
            (t as u32, right)
        })
        .collect();
    Some(std::sync::Arc::new(PhotoHalves { right }))
}

/// Stage 6, the estimate: initial materials, the starts, the alternation; the fitted model.
/// Steps: the start and the estimator's options ([`prepare_start`]), the alternation under
/// each candidate light model with the held-out tracker ([`alternate`]), the unseen
/// vertices' materials ([`fill_unseen`]), then the [`Fitted`] model ([`FinalEstimate`],
/// [`fitted_model`]).
pub(crate) fn fit<'a>(
    opts: &RunOptions,
    im: &'a Imported,
    observed: Observed,
    prepared: Prepared,
    log: &mut RunLog,
    progress: &Progress,
) -> Result<Fit<'a>> {
    let scene = &im.scene;
    let Observed {
        bvh,
        mut obs,
        train,
        decisions,
    } = observed;
    let p = prepared;
    let nv = scene.mesh.positions.len();
    // The baseline is the photos' own colours: its medians ignore the transient mask.
    let baseline = super::baseline::VertexMedians::from_observations(&obs, nv);
    let mut start = prepare_start(opts, im, &p, &train, &mut obs, log, progress)?;
    let problem = Problem {
        obs: &obs,
        transport: &p.tr,
        n_vertices: nv,
        n_photos: train.len(),
    };
    let Estimated {
        est: mut estimate,
        multi,
        eopts,
        light_decision,
        timeline,
    } = {
        let tracker = held_out_tracker(im, &bvh, &p, log, progress)?;
        alternate(opts, &p, &problem, &mut start, tracker, log, progress)?
    };
    fill_unseen(
        &obs,
        &scene.mesh.positions,
        &eopts.weights_graph,
        &mut estimate,
        &mut start.reasons,
        log,
    )?;
    let done = FinalEstimate::new(scene, &problem, &train, estimate)?;
    let fitted = fitted_model(
        im,
        p,
        FitParts {
            train,
            bvh,
            est: done.est,
            beta: done.beta,
            train_predictions: done.train_predictions,
            estimate_options: eopts,
            baseline,
        },
    );
    Ok(Fit {
        fitted,
        train_entries: done.train_entries,
        timeline,
        multi,
        reasons: start.reasons,
        decisions,
        light_decision,
        transients: start.transients,
    })
}

/// The start and the estimator's options ([`FitStart`]): the transient pass when on (it
/// masks occluders in `obs`, and the start keeps what it masked), the options that depend on the observations kept, and the
/// start's brightness matched by normal when the pilot chose it.
fn prepare_start(
    opts: &RunOptions,
    im: &Imported,
    p: &Prepared,
    train: &[usize],
    obs: &mut Observations,
    log: &mut RunLog,
    progress: &Progress,
) -> Result<FitStart> {
    let scene = &im.scene;
    let lambert = lambert_of(&p.eff.basis)?;
    let mut start = FitStart::new(opts, p, &scene.mesh.positions, lambert, train.len())?;
    if p.eff.transients {
        start.mask_transients(opts, obs, p, scene, log, progress)?;
    }
    start.finish_options(opts, scene, train, obs)?;
    if p.eff.start_brightness == StartBrightness::Matched {
        start.match_brightness(p, obs);
    }
    Ok(start)
}

/// The alternation from the start's family ([`FitStart::family`]) under each candidate
/// light model ([`fit_light_models`]), then the start search when asked, with a progress
/// bar and the held-out tracker ([`held_out_tracker`]) scoring every iterate for the
/// timeline. The tracker's transport rows (the held-out photos') are freed on return.
fn alternate(
    opts: &RunOptions,
    p: &Prepared,
    problem: &Problem,
    start: &mut FitStart,
    tracker: Option<HoldoutTracker>,
    log: &mut RunLog,
    progress: &Progress,
) -> Result<Estimated> {
    let lambert = start.eopts.lambert_basis;
    progress.stage("estimate");
    let family = start.family(opts, p.eff.basis.len(), lambert);
    let bar = progress.bar(
        (p.eff.max_iterations * family.len()) as u64,
        "outer iterations",
    );
    let monitor = Monitor {
        bar: &bar,
        progress,
        tracker: tracker.as_ref(),
        n_vertices: problem.n_vertices,
    };
    let mut est = fit_light_models(opts, problem, &family, start, &monitor, log)?;
    if opts.start_search {
        est = search_starts(problem, est, &family[0].materials, lambert, &monitor, log)?;
    }
    bar.finish_and_clear();
    Ok(est)
}

/// The estimate once it is final, with what the fitted model and the report derive from
/// it: the per-vertex diffuse albedo `β`, the training photos' predictions and errors.
struct FinalEstimate {
    est: solve::Estimate,
    beta: Vec<[f64; 3]>,
    train_predictions: Vec<Vec<(u32, [f32; 3])>>,
    train_entries: Vec<TrainEntry>,
}

impl FinalEstimate {
    /// `est` checked finite (else the error names the conditioning), then `β` and the
    /// training photos' predictions.
    fn new(
        scene: &crate::import::scene::Scene,
        problem: &Problem,
        train: &[usize],
        est: solve::Estimate,
    ) -> Result<Self> {
        check_finite(&est, &conditioning_map(&est.conditioning))?;
        let beta = solve::beta_per_vertex(&est.lambda, &est.weights, problem.n_vertices);
        let pred = solve::predict(problem, &est);
        Ok(FinalEstimate {
            train_entries: train_errors(scene, train, problem.obs, &pred),
            train_predictions: photo_predictions(problem.obs, &pred),
            est,
            beta,
        })
    }
}

/// What the fit adds to the prepared stage to make the [`Fitted`] model.
struct FitParts {
    train: Vec<usize>,
    bvh: crate::observe::trace::SceneBvh,
    est: solve::Estimate,
    beta: Vec<[f64; 3]>,
    train_predictions: Vec<Vec<(u32, [f32; 3])>>,
    estimate_options: EstimateOptions,
    baseline: super::baseline::VertexMedians,
}

/// The fitted model the evaluation and the outputs read. The training transport rows are
/// the run's largest arrays and nothing after the estimate reads them: they are freed here,
/// before the evaluation builds its own.
fn fitted_model<'a>(im: &'a Imported, p: Prepared, parts: FitParts) -> Fitted<'a> {
    let Prepared {
        env_from_world,
        normals_env,
        vis,
        render_vis,
        eff,
        rot,
        tr,
        ..
    } = p;
    drop(tr);
    Fitted {
        scene: &im.scene,
        photos: &im.photos,
        train: parts.train,
        held: im.held.clone(),
        env_from_world,
        normals_env,
        vis,
        rot,
        render_rot: crate::sphere::rotation::SplatRotation::with_default_supersample(
            eff.global_resolution,
            render_vis.n_local,
        ),
        render_vis,
        basis: eff.basis.clone(),
        est: parts.est,
        beta: parts.beta,
        train_predictions: parts.train_predictions,
        opts: eff,
        estimate_options: parts.estimate_options,
        bvh: parts.bvh,
        baseline: parts.baseline,
        half_prior: None,
    }
}

/// The held-out photos' observations and transport for the timeline's held-out error
/// ([`HoldoutTracker`]; `None` without held-out photos).
fn held_out_tracker(
    im: &Imported,
    bvh: &crate::observe::trace::SceneBvh,
    p: &Prepared,
    log: &mut RunLog,
    progress: &Progress,
) -> Result<Option<HoldoutTracker>> {
    let _spinner = progress.spinner("held-out transport");
    log.stages.run("transport", || {
        HoldoutTracker::new(
            &im.scene,
            &im.photos,
            &im.held,
            bvh,
            &p.normals_env,
            &p.env_from_world,
            &p.vis,
            &p.eff.basis,
            &p.rot,
            &p.topts,
            im.truth.as_ref(),
        )
    })
}

/// The vertices no training photo sees kept their start: give them their seen
/// neighbours' materials (the harmonic extension, `solve::materials::propagate`), over the
/// neighbour prior's graph when it built one (`graph` not empty; the same graph).
fn fill_unseen(
    obs: &Observations,
    positions: &[crate::Vec3],
    graph: &VertexGraph,
    est: &mut solve::Estimate,
    reasons: &mut Vec<String>,
    log: &mut RunLog,
) -> Result<()> {
    let seen_now = super::mean_colours(obs, positions.len()).1;
    let k = est.lambda.len();
    let filled = log.stages.run("estimate", || {
        let built = Some(graph).filter(|g| !g.is_empty());
        propagate_unseen_over(positions, built, &seen_now, &mut est.weights, k)
    })?;
    if filled.filled > 0 {
        reasons.push(format!(
            "materials of the {} vertices no training photo sees: from their seen neighbours",
            filled.filled
        ));
    }
    Ok(())
}

/// The fit's start: the initial materials, the estimator's options and the reasons so far.
struct FitStart {
    init: crate::solve::cluster::InitialMaterials,
    eopts: EstimateOptions,
    /// Why the model has its size (the report's reasons).
    reasons: Vec<String>,
    /// What the transient pass masked (`None`: `--transients off`).
    transients: Option<super::transients::Transients>,
}

impl FitStart {
    /// The clustered start with the pilot's count (or `--materials`, or a count from the
    /// colours) and the estimator's options, with the ratio step's rounds for
    /// `training_photos` and the start's materials, and the neighbour prior's graph when on.
    fn new(
        opts: &RunOptions,
        p: &Prepared,
        positions: &[crate::Vec3],
        lambert: usize,
        training_photos: usize,
    ) -> Result<Self> {
        let mut reasons = Vec::new();
        let init = starting_materials(opts, p.pilot_k.clone(), &p.mean_rgb, &p.seen, &mut reasons)?;
        let mut eopts = estimate_options(&p.eff, lambert, &p.strata);
        eopts.ratio_steps = p.eff.ratio_steps.rounds(training_photos, init.albedo.len());
        if eopts.weights_smoothness > 0.0 {
            // The neighbour prior's graph: the one the unseen vertices' materials spread over.
            use crate::solve::materials::propagate::{knn_graph, NEIGHBOURS};
            eopts.weights_graph = knn_graph(positions, NEIGHBOURS)?.into();
        }
        Ok(FitStart {
            init,
            eopts,
            reasons,
            transients: None,
        })
    }

    /// The transient pass (`--transients`): masks occluders in `obs` and keeps what it
    /// masked; when it masked any, the start is clustered again from the unmasked
    /// observations only (an occluder's colour would otherwise take a material of its own).
    fn mask_transients(
        &mut self,
        opts: &RunOptions,
        obs: &mut Observations,
        p: &Prepared,
        scene: &crate::import::scene::Scene,
        log: &mut RunLog,
        progress: &Progress,
    ) -> Result<()> {
        let lambert = self.eopts.lambert_basis;
        progress.stage("transients");
        let spinner = progress.spinner("pilot fit for transient occluders");
        let start = Materials0::from_initial(&self.init, p.eff.basis.len(), lambert);
        let t = log.stages.run("transients", || {
            super::transients::mask_transients(obs, &p.tr, &scene.mesh, &start, &self.eopts)
        })?;
        drop(spinner);
        if t.count() > 0 {
            let (mean_rgb, seen) = super::mean_colours(obs, scene.mesh.positions.len());
            self.reasons.clear();
            self.init =
                starting_materials(opts, p.pilot_k.clone(), &mean_rgb, &seen, &mut self.reasons)?;
        }
        self.transients = Some(t);
        Ok(())
    }

    /// The options that depend on the observations kept: the shared light's groups and
    /// early stopping's photo halves; the neighbour prior's reason.
    fn finish_options(
        &mut self,
        opts: &RunOptions,
        scene: &crate::import::scene::Scene,
        train: &[usize],
        obs: &Observations,
    ) -> Result<()> {
        if self.eopts.weights_smoothness > 0.0 {
            self.reasons.push(format!(
                "material weights pulled toward their {} nearest vertices' mean at {} (--weights-smoothness)",
                crate::solve::materials::propagate::NEIGHBOURS,
                self.eopts.weights_smoothness
            ));
        }
        if matches!(opts.light, LightChoice::Shared | LightChoice::Auto) {
            let file = opts.light_groups.as_deref();
            self.eopts.light_groups =
                super::light_groups::resolve(file, opts.light_group_minutes, scene, train)?;
            if let Some(g) = &self.eopts.light_groups {
                self.reasons.push(format!("shared light: {}", g.source));
            }
        }
        self.eopts.validation_halves = photo_halves(scene, train, obs, opts.validation_halves);
        Ok(())
    }

    /// The start's material brightness matched by normal ([`crate::solve::matched`]) on
    /// the training observations; the change, or why none, goes to the reasons.
    fn match_brightness(&mut self, p: &Prepared, obs: &Observations) {
        let open = p.vis.open_fractions();
        let how =
            crate::solve::matched::match_start(&mut self.init, obs, &p.normals_env, &open, true);
        self.reasons.push(if how.applied() {
            format!("start brightness matched by normal: {}", how.describe())
        } else {
            format!(
                "start brightness: the clustered colours; {}",
                how.describe()
            )
        });
    }

    /// The starts the estimate runs from (`--starts`), and why when fewer exist.
    fn family(&mut self, opts: &RunOptions, n_basis: usize, lambert: usize) -> Vec<starts::Start> {
        let available = starts::family_len(n_basis, lambert);
        if opts.starts > available {
            self.reasons.push(format!(
                "--starts {}: this basis gives {available} distinct starts, all tried",
                opts.starts
            ));
        }
        let materials0 = Materials0::from_initial(&self.init, n_basis, lambert);
        starts::variants(materials0, lambert, starts::GLOSS_FRACTION, opts.starts)
    }
}

/// The estimate's progress: its bar, its console lines and the held-out error of each
/// iterate (the report's timeline).
struct Monitor<'a> {
    bar: &'a indicatif::ProgressBar,
    progress: &'a Progress,
    tracker: Option<&'a HoldoutTracker>,
    n_vertices: usize,
}

impl Monitor<'_> {
    /// The held-out error of an iterate, for the timeline (finite, else none).
    fn held_out(&self, state: &solve::IterState) -> Option<f64> {
        self.tracker
            .map(|t| t.rmse(state, self.n_vertices))
            .filter(|v| v.is_finite())
    }

    /// A console line under the bar (or alone when the bar is hidden).
    fn say(&self, line: &str) {
        if self.bar.is_hidden() {
            self.progress.line(line);
        } else {
            self.bar.println(format!("          {line}"));
        }
    }
}

/// The estimate kept: the fit, its starts, its options and light model, its timeline.
struct Estimated {
    est: solve::Estimate,
    multi: MultiStart,
    eopts: EstimateOptions,
    light_decision: crate::solve::light::choose::LightDecision,
    timeline: Vec<TimelinePoint>,
}

/// Each candidate light model (`--light`) fitted from every start; the one the validation
/// score keeps ([`crate::solve::light::choose::decide`]), its reason pushed to `start`.
fn fit_light_models(
    opts: &RunOptions,
    problem: &Problem,
    family: &[starts::Start],
    start: &mut FitStart,
    monitor: &Monitor,
    log: &mut RunLog,
) -> Result<Estimated> {
    let n_starts = family.len();
    let mut timeline: Vec<TimelinePoint> = Vec::new();
    let light_models = crate::solve::light::choose::candidates(opts.light, &start.eopts)?;
    let mut fits = Vec::with_capacity(light_models.len());
    let mut timeline_ranges = Vec::with_capacity(light_models.len());
    for model in &light_models {
        let first = timeline.len();
        let family = family.to_vec();
        let eopts = &model.options;
        fits.push(log.stages.run("estimate", || {
            starts::estimate_best(problem, family, eopts, &mut |si, it, state| {
                monitor.bar.inc(1);
                let holdout_rmse = monitor.held_out(state);
                let n_it = timeline.iter().filter(|p| p.start == si).count() + 1;
                monitor.say(&iteration_line(n_starts, si, n_it, it, holdout_rmse));
                timeline.push(timeline_point(si, it.seconds, it, holdout_rmse));
            })
        })?);
        timeline_ranges.push(first..timeline.len());
    }
    let scores: Vec<f64> = fits
        .iter()
        .map(|(e, _)| e.validation.as_ref().map_or(f64::NAN, |v| v.best_error()))
        .collect();
    let names: Vec<&str> = light_models.iter().map(|m| m.name).collect();
    let (pick, light_decision) = crate::solve::light::choose::decide(opts.light, &names, &scores);
    start.reasons.push(format!(
        "light model `{}`: {}",
        light_decision.model, light_decision.why
    ));
    let (est, multi) = fits.swap_remove(pick);
    Ok(Estimated {
        est,
        multi,
        eopts: light_models[pick].options.clone(),
        light_decision,
        // The timeline of the model kept.
        timeline: timeline.drain(timeline_ranges[pick].clone()).collect(),
    })
}

/// The start search (`--start-search`, [`brightness::search`]) from the kept fit, around
/// `base` (the first start's materials; `lambert` its Lambertian basis). The
/// timeline then follows the search's records: the kept start's iterations as start 0,
/// each searched start's after them on the same clock.
fn search_starts(
    problem: &Problem,
    fitted: Estimated,
    base: &Materials0,
    lambert: usize,
    monitor: &Monitor,
    log: &mut RunLog,
) -> Result<Estimated> {
    let Estimated {
        est,
        multi,
        eopts,
        light_decision,
        mut timeline,
    } = fitted;
    monitor.progress.stage("start search");
    let label = multi.starts[multi.chosen].label.clone();
    timeline.retain(|p| p.start == multi.chosen);
    timeline.iter_mut().for_each(|p| p.start = 0);
    let (mut clock, mut current, mut last) = (0.0, 0, timeline.last().map_or(0.0, |p| p.seconds));
    let (est, multi) = log.stages.run("start search", || {
        brightness::search(
            problem,
            est,
            &label,
            base,
            lambert,
            &eopts,
            &mut |si, it, state| {
                if si != current {
                    (clock, current) = (last, si);
                    monitor.bar.inc_length(eopts.max_outer as u64);
                }
                monitor.bar.inc(1);
                let holdout_rmse = monitor.held_out(state);
                let n_it = timeline.iter().filter(|p| p.start == si).count() + 1;
                let line = iteration_line(1, si, n_it, it, holdout_rmse);
                monitor.say(&format!("start search, start {}: {line}", si + 1));
                last = clock + it.seconds;
                timeline.push(timeline_point(si, last, it, holdout_rmse));
            },
        )
    })?;
    Ok(Estimated {
        est,
        multi,
        eopts,
        light_decision,
        timeline,
    })
}

/// The starting materials: clustered mean colours with the pilot's count, `--materials`,
/// or a count chosen from the colours; why, pushed to `reasons`.
fn starting_materials(
    opts: &RunOptions,
    pilot_k: Option<(usize, String)>,
    mean_rgb: &[[f64; 3]],
    seen: &[bool],
    reasons: &mut Vec<String>,
) -> Result<crate::solve::cluster::InitialMaterials> {
    let (k, k_reason) = match (pilot_k, opts.materials) {
        (Some(p), _) => p,
        (None, MaterialCount::Fixed(k)) => (k, format!("materials: {k}, as given by --materials")),
        (None, MaterialCount::Auto) => choose_material_count(mean_rgb, seen, opts.seed),
    };
    let init = initial_materials(mean_rgb, seen, k, opts.seed)?;
    reasons.push(k_reason);
    if init.albedo.len() < k {
        reasons.push(format!(
            "only {} distinct colour clusters exist, so {} materials are fitted",
            init.albedo.len(),
            init.albedo.len()
        ));
    }
    Ok(init)
}

/// One point of the report's timeline: iteration `it` of start `start`, `seconds` on the
/// estimator's clock.
fn timeline_point(
    start: usize,
    seconds: f64,
    it: &solve::Iteration,
    holdout_rmse: Option<f64>,
) -> TimelinePoint {
    TimelinePoint {
        start,
        seconds,
        objective: it.objective,
        train_rmse: it.train_rmse,
        holdout_rmse,
        steps: it.steps,
    }
}

/// The console line for outer iteration `n_it` of start `si` (of `n_starts`).
fn iteration_line(
    n_starts: usize,
    si: usize,
    n_it: usize,
    it: &solve::Iteration,
    holdout_rmse: Option<f64>,
) -> String {
    format!(
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
    )
}

/// Per training photo, the fitted prediction `pred` of each of its observations, by vertex.
fn photo_predictions(obs: &Observations, pred: &[[f64; 3]]) -> Vec<Vec<(u32, [f32; 3])>> {
    obs.photo_ranges
        .iter()
        .map(|r| {
            r.clone()
                .map(|p| (obs.vertex[p], pred[p].map(|v| v as f32)))
                .collect()
        })
        .collect()
}
