//! Stage 6 of `run`: the estimate. Initial materials (clustering or the pilot's count),
//! the starts, the alternation with the held-out tracker, then the fitted model
//! ([`Fitted`]) that the evaluation and the outputs read.

use super::half_fit::{projected_x, span_mid};
use super::pipeline::{Imported, Observed, Prepared, RunLog};
use super::tracker::HoldoutTracker;
use super::{
    check_finite, choose_material_count, conditioning_map, train_errors, Fitted, MaterialCount,
    Progress, RunOptions,
};
use crate::observe::Observations;
use crate::report::{TimelinePoint, TrainEntry};
use crate::solve::adapt::Decision;
use crate::solve::cluster::initial_materials;
use crate::solve::light::choose::LightChoice;
use crate::solve::materials::brightness;
use crate::solve::materials::propagate::propagate_unseen;
use crate::solve::starts::{self, MultiStart};
use crate::solve::validation::PhotoHalves;
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
pub(crate) fn fit<'a>(
    opts: &RunOptions,
    im: &'a Imported,
    observed: Observed,
    prepared: Prepared,
    log: &mut RunLog,
    progress: &Progress,
) -> Result<Fit<'a>> {
    let (scene, photos, held, truth) = (&im.scene, &im.photos, im.held.clone(), &im.truth);
    let Observed {
        bvh,
        mut obs,
        train,
        decisions,
    } = observed;
    let Prepared {
        env_from_world,
        normals_env,
        vis,
        render_vis,
        eff,
        pilot_k,
        mean_rgb,
        seen,
        rot,
        topts,
        tr,
        strata,
    } = prepared;
    let nv = scene.mesh.positions.len();
    // 6. Estimate.
    let lambert = lambert_of(&eff.basis)?;
    let mut reasons = Vec::new();
    let mut init = starting_materials(opts, pilot_k.clone(), &mean_rgb, &seen, &mut reasons)?;
    let mut eopts = estimate_options(&eff, lambert, &strata);
    if eopts.weights_smoothness > 0.0 {
        // The neighbour prior's graph: the one the unseen vertices' materials spread over.
        use crate::solve::materials::propagate::{knn_graph, NEIGHBOURS};
        eopts.weights_graph = knn_graph(&scene.mesh.positions, NEIGHBOURS)?.into();
    }
    // The baseline is the photos' own colours: its medians ignore the transient mask.
    let baseline = super::baseline::VertexMedians::from_observations(&obs, nv);
    let transients = if eff.transients {
        progress.stage("transients");
        let spinner = progress.spinner("pilot fit for transient occluders");
        let start = Materials0::from_initial(&init, eff.basis.len(), lambert);
        let t = log.stages.run("transients", || {
            super::transients::mask_transients(&mut obs, &tr, &scene.mesh, &start, &eopts)
        })?;
        drop(spinner);
        // The clustered start from the unmasked observations only: an occluder's colour
        // would otherwise take a material of its own.
        if t.count() > 0 {
            let (mean_rgb, seen) = super::mean_colours(&obs, nv);
            reasons.clear();
            init = starting_materials(opts, pilot_k, &mean_rgb, &seen, &mut reasons)?;
        }
        Some(t)
    } else {
        None
    };
    if eopts.weights_smoothness > 0.0 {
        reasons.push(format!(
            "material weights pulled toward their {} nearest vertices' mean at {} (--weights-smoothness)",
            crate::solve::materials::propagate::NEIGHBOURS,
            eopts.weights_smoothness
        ));
    }
    let problem = Problem {
        obs: &obs,
        transport: &tr,
        n_vertices: nv,
        n_photos: train.len(),
    };
    if matches!(opts.light, LightChoice::Shared | LightChoice::Auto) {
        let file = opts.light_groups.as_deref();
        eopts.light_groups =
            super::light_groups::resolve(file, opts.light_group_minutes, scene, &train)?;
        if let Some(g) = &eopts.light_groups {
            reasons.push(format!("shared light: {}", g.source));
        }
    }
    eopts.validation_halves = photo_halves(scene, &train, &obs, opts.validation_halves);
    let materials0 = Materials0::from_initial(&init, eff.basis.len(), lambert);
    let spinner = progress.spinner("held-out transport");
    let tracker = log.stages.run("transport", || {
        HoldoutTracker::new(
            scene,
            photos,
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
    // The held-out error of an iterate, for the timeline (finite, else none).
    let held_out = |state: &solve::IterState| {
        tracker
            .as_ref()
            .map(|t| t.rmse(state, nv))
            .filter(|v| v.is_finite())
    };
    let say = |line: &str| {
        if bar.is_hidden() {
            progress.line(line);
        } else {
            bar.println(format!("          {line}"));
        }
    };
    let mut timeline: Vec<TimelinePoint> = Vec::new();
    let light_models = crate::solve::light::choose::candidates(opts.light, &eopts)?;
    let mut fits = Vec::with_capacity(light_models.len());
    let mut timeline_ranges = Vec::with_capacity(light_models.len());
    for model in &light_models {
        let first = timeline.len();
        let family = family.clone();
        let eopts = &model.options;
        fits.push(log.stages.run("estimate", || {
            starts::estimate_best(&problem, family, eopts, &mut |si, it, state| {
                bar.inc(1);
                let holdout_rmse = held_out(state);
                let n_it = timeline.iter().filter(|p| p.start == si).count() + 1;
                say(&iteration_line(n_starts, si, n_it, it, holdout_rmse));
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
    reasons.push(format!(
        "light model `{}`: {}",
        light_decision.model, light_decision.why
    ));
    let eopts = light_models[pick].options.clone();
    let (est, multi) = fits.swap_remove(pick);
    // The timeline of the model kept.
    let mut timeline: Vec<TimelinePoint> = timeline.drain(timeline_ranges[pick].clone()).collect();
    let (mut est, multi) = if opts.start_search {
        progress.stage("start search");
        let label = multi.starts[multi.chosen].label.clone();
        // The timeline then follows the search's records: the kept start's iterations as
        // start 0, each searched start's after them on the same clock.
        timeline.retain(|p| p.start == multi.chosen);
        timeline.iter_mut().for_each(|p| p.start = 0);
        let (mut clock, mut current, mut last) =
            (0.0, 0, timeline.last().map_or(0.0, |p| p.seconds));
        log.stages.run("start search", || {
            let base = &family[0].materials;
            brightness::search(
                &problem,
                est,
                &label,
                base,
                lambert,
                &eopts,
                &mut |si, it, state| {
                    if si != current {
                        (clock, current) = (last, si);
                        bar.inc_length(eff.max_iterations as u64);
                    }
                    bar.inc(1);
                    let holdout_rmse = held_out(state);
                    let n_it = timeline.iter().filter(|p| p.start == si).count() + 1;
                    let line = iteration_line(1, si, n_it, it, holdout_rmse);
                    say(&format!("start search, start {}: {line}", si + 1));
                    last = clock + it.seconds;
                    timeline.push(timeline_point(si, last, it, holdout_rmse));
                },
            )
        })?
    } else {
        (est, multi)
    };
    // The vertices no training photo sees kept their start: give them their seen
    // neighbours' materials (the harmonic extension, `solve::materials::propagate`).
    let seen_now = super::mean_colours(&obs, nv).1;
    let k = est.lambda.len();
    let filled = log.stages.run("estimate", || {
        propagate_unseen(&scene.mesh.positions, &seen_now, &mut est.weights, k)
    })?;
    if filled.filled > 0 {
        reasons.push(format!(
            "materials of the {} vertices no training photo sees: from their seen neighbours",
            filled.filled
        ));
    }
    bar.finish_and_clear();
    check_finite(&est, &conditioning_map(&est.conditioning))?;
    let beta = solve::beta_per_vertex(&est.lambda, &est.weights, nv);
    let pred = solve::predict(&problem, &est);
    let train_entries = train_errors(scene, &train, &obs, &pred);
    let train_predictions = photo_predictions(&obs, &pred);
    drop(pred);
    // The transport rows (training and held-out) are the run's largest arrays and nothing
    // after the estimate reads them: free them before the evaluation builds its own.
    drop(tracker);
    drop(tr);

    let fitted = Fitted {
        scene,
        photos,
        train,
        held,
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
        est,
        beta,
        train_predictions,
        opts: eff.clone(),
        estimate_options: eopts,
        bvh,
        baseline,
        half_prior: None,
    };
    Ok(Fit {
        fitted,
        train_entries,
        timeline,
        multi,
        reasons,
        decisions,
        light_decision,
        transients,
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
