//! The row `defaults (the pilot's choices)`: what `relight-cpc run` does with no flags,
//! on the bench's cases. The adaptive pilot ([`adapt::pilot`], the function `run` calls,
//! with the inputs `run` gives it) chooses the material count (step 3), the blending
//! weights' sum-to-one prior (step 3b) and which of the case's lobes to keep (step 4); the
//! full fit then uses those choices with the paper's light model, the k-means start and
//! `run`'s outer-iteration cap and tolerance ([`RunOptions`]: 8 and 10⁻³, where the other
//! rows take the bench's 20 and 10⁻⁵; `ABLATION_DEFAULTS_ITERS=bench` gives it those too); then, as `run` does, the vertices no training
//! photo sees take their seen neighbours' materials ([`propagate_unseen`]); the ratio step
//! runs as `--ratio-steps auto` decides ([`ratio_step::default_rounds`]), and early stopping
//! has `run`'s patience ([`RunOptions::DEFAULT_PATIENCE`]; `ABLATION_DEFAULTS_PATIENCE=N`
//! gives it `run --patience N`; the neighbour prior over the case's vertex graph is on when the
//! pilot keeps a shiny lobe, as `run --weights-smoothness auto` decides
//! ([`adapt::neighbour_prior_for`]), and `ABLATION_DEFAULTS_NEIGHBOUR=X` gives it
//! `run --weights-smoothness X`). The map sizes
//! stay the bench's (16² / 8²: the pilot's resolution choice, step 5, is the only default
//! left out).

use crate::synth_case::*;
use relight_cpc::run::{Restart, RunOptions};
use relight_cpc::solve::adapt::{self, PilotInput, PilotOutcome};
use relight_cpc::solve::cluster::{unmixed_weights, InitialMaterials};
use relight_cpc::solve::materials::propagate::propagate_unseen;
use relight_cpc::solve::ratio_step;
use relight_cpc::solve::starts::{estimate_best, Start};
use relight_cpc::solve::{estimate, Estimate, EstimateOptions, Materials0, Problem};

/// The defaults' fit: its estimate over the case's full basis (a dropped lobe's weights
/// 0) and what the pilot decided.
pub struct DefaultsFit {
    pub est: Estimate,
    pub pilot: PilotOutcome,
    pub seconds: f64,
}

/// The pilot on the case's training photos, then the fit with its choices; `base`: the
/// bench's options (the paper's free weights, the paper's light model).
pub fn fit_defaults(case: &Case, base: &EstimateOptions) -> DefaultsFit {
    let t0 = std::time::Instant::now();
    // The pilot's and the fit's IRLS: `run --irls-iterations N` with
    // `ABLATION_DEFAULTS_IRLS=N`; the robust floor with `ABLATION_DEFAULTS_FLOOR=X`; Huber's
    // `k` or Tukey's biweight with `ABLATION_DEFAULTS_ROBUST=K|tukey`; the maps' Laplacian
    // weight with `ABLATION_DEFAULTS_SMOOTHNESS=X` (`run --smoothness X`).
    let base = &EstimateOptions {
        irls_iters: crate::env_or("ABLATION_DEFAULTS_IRLS", base.irls_iters),
        robust_floor: crate::env_or("ABLATION_DEFAULTS_FLOOR", base.robust_floor),
        robust: match std::env::var("ABLATION_DEFAULTS_ROBUST").as_deref() {
            Ok("tukey") => relight_cpc::solve::Robust::Tukey { c: 4.685 },
            Ok(k) => k
                .parse()
                .map_or(base.robust, |k| relight_cpc::solve::Robust::Huber { k }),
            Err(_) => base.robust,
        },
        smoothness: crate::env_or("ABLATION_DEFAULTS_SMOOTHNESS", base.smoothness),
        ..base.clone()
    };
    let obs = &case.train.obs;
    let (mean_rgb, seen) = relight_cpc::run::mean_colours(obs, case.nv);
    // The case's basis has its Lambertian lobe first (`fit_start`'s convention).
    let lambert = 0;
    let pilot = adapt::pilot(&PilotInput {
        normals_env: &case.normals_env,
        obs,
        env_from_world: &case.env_from_world,
        vis: &case.vis,
        basis: &case.basis,
        lambert,
        normal_grid: case.sizes.normal_grid,
        global_resolution: case.sizes.global,
        keep: case.sizes.keep,
        // As `run` does: the pilot holds out its own observations, and its lighting
        // sample has the run's strata.
        estimate: EstimateOptions {
            validation_fraction: 0.0,
            lighting_strata: relight_cpc::solve::subsample::lighting_strata(
                &case.normals_env,
                &case.vis.open_fractions(),
            ),
            ..base.clone()
        },
        mean_rgb: &mean_rgb,
        seen: &seen,
        materials: None,
        choose_weights_sum: true,
        start: relight_cpc::solve::matched::StartBrightness::Auto,
        max_vertices: adapt::PILOT_MAX_VERTICES,
        seed: 1,
    })
    .expect("adaptive pilot");
    // Every lobe of the case's basis kept, whatever the pilot's shares, with
    // `ABLATION_DEFAULTS_ALL_LOBES=1`.
    let mut pilot = pilot;
    if crate::env_flag("ABLATION_DEFAULTS_ALL_LOBES") {
        pilot.kept = (0..case.basis.len()).collect();
    }
    let sub = adapt::select_bases(&case.train.transport, &pilot.kept).expect("kept bases");
    let problem = Problem {
        transport: &sub,
        ..case.train.problem(case.nv)
    };
    let mut init =
        relight_cpc::solve::cluster::initial_materials(&mean_rgb, &seen, pilot.materials, 1)
            .expect("k-means start");
    // `ABLATION_DEFAULTS_START=unmix-match`: the weights (and labels) unmixed from the
    // clustered colours before the brightness is matched, so that only vertices the
    // unmixing finds pure count there, then unmixed again over the matched colours.
    let unmix_match = std::env::var("ABLATION_DEFAULTS_START").is_ok_and(|v| v == "unmix-match");
    if unmix_match {
        unmix_initial(&mut init, &mean_rgb, &seen);
    }
    if pilot.start == relight_cpc::solve::matched::StartBrightness::Matched {
        let open = case.vis.open_fractions();
        relight_cpc::solve::matched::match_start(&mut init, obs, &case.normals_env, &open, true);
    }
    if unmix_match {
        unmix_initial(&mut init, &mean_rgb, &seen);
    }
    let mut m0 = Materials0::from_initial(&init, pilot.kept.len(), lambert);
    // With `ABLATION_DEFAULTS_START=truth | truth-weights | truth-lambda`, when the pilot took
    // the true count: the fit from the TRUE materials (the kept lobes' λ), from the true
    // weights with the start's λ (its materials put in the truth's order), or from the
    // true λ with the start's weights (the truth's materials put in the start's order).
    if pilot.materials == case.lambda.len() {
        let t = case.true_materials();
        let true_lambda: Vec<Vec<[f64; 3]>> = t
            .lambda
            .iter()
            .map(|row| pilot.kept.iter().map(|&b| row[b]).collect())
            .collect();
        // perm[k] = the true material nearest start material k in Lambertian colour.
        let perm = nearest_order(&m0.lambda, &true_lambda, lambert);
        match std::env::var("ABLATION_DEFAULTS_START").as_deref() {
            Ok("truth") => {
                m0 = Materials0 {
                    lambda: true_lambda,
                    weights: t.weights,
                }
            }
            Ok("truth-weights") => {
                let mut lambda = m0.lambda.clone();
                for (k, &j) in perm.iter().enumerate() {
                    lambda[j] = m0.lambda[k].clone();
                }
                m0.lambda = lambda;
                m0.weights = t.weights;
            }
            Ok("truth-lambda") => {
                for (k, &j) in perm.iter().enumerate() {
                    m0.lambda[k] = true_lambda[j].clone();
                }
            }
            _ => {}
        }
    }
    // With `ABLATION_DEFAULTS_START=unmix`: each seen vertex's start weights unmixed from
    // its mean colour over the start's colours ([`unmixed_weights`], `--start-weights unmixed`).
    // `unmix2`: over the best pair of materials only (a vertex blends at most two).
    match std::env::var("ABLATION_DEFAULTS_START").as_deref() {
        Ok("unmix") => m0.weights = unmixed_weights(&init, &mean_rgb, &seen).0,
        Ok("unmix2") => unmix_pairs(&mut m0, &mean_rgb, &seen, lambert),
        _ => {}
    }
    // `run`'s cap and tolerance, or with `ABLATION_DEFAULTS_ITERS=bench` the bench's.
    let (max_outer, rel_tol) =
        if std::env::var("ABLATION_DEFAULTS_ITERS").is_ok_and(|v| v == "bench") {
            (base.max_outer, base.rel_tol)
        } else {
            (
                RunOptions::DEFAULT_MAX_ITERATIONS,
                RunOptions::DEFAULT_REL_TOL,
            )
        };
    let kept: Vec<_> = pilot.kept.iter().map(|&b| case.basis[b]).collect();
    let neighbour_prior = adapt::neighbour_prior_for(&kept).0;
    let opts = EstimateOptions {
        weights_sum: pilot.weights_sum,
        // `ABLATION_DEFAULTS_SCOPE=blends`: the prior on blended vertices whatever the
        // pilot's scope.
        weights_sum_scope: if std::env::var("ABLATION_DEFAULTS_SCOPE").is_ok_and(|v| v == "blends")
        {
            relight_cpc::solve::SumScope::Blends {
                floor: relight_cpc::solve::BLEND_FLOOR,
            }
        } else {
            pilot.weights_sum_scope
        },
        max_outer,
        patience: crate::env_or("ABLATION_DEFAULTS_PATIENCE", RunOptions::DEFAULT_PATIENCE),
        rel_tol,
        // As `run --ratio-steps auto`, or with `ABLATION_RATIO_STEPS=N` `--ratio-steps N`
        // (bench-results/ratio-step.md).
        ratio_steps: crate::env_or(
            "ABLATION_RATIO_STEPS",
            ratio_step::default_rounds(case.train.obs.photo_ranges.len(), pilot.materials),
        ),
        // As `run --weights-smoothness auto` (the pilot's kept lobes), or
        // `run --weights-smoothness X` with `ABLATION_DEFAULTS_NEIGHBOUR=X`.
        weights_smoothness: crate::env_or("ABLATION_DEFAULTS_NEIGHBOUR", neighbour_prior),
        // `run --light shared` with `ABLATION_DEFAULTS_LIGHT=shared`: one map per group of
        // training photos under one true sky, with per-photo gains (`SYNTH_SHARED_SKIES=1`
        // makes such groups).
        light_groups: std::env::var("ABLATION_DEFAULTS_LIGHT")
            .is_ok_and(|v| v == "shared")
            .then(|| case.true_light_groups()),
        ..base.clone()
    };
    let opts = crate::with_case_graph(case, opts);
    let mut est = match std::env::var("ABLATION_DEFAULTS_START").as_deref() {
        Ok(v @ ("grid" | "grid-unmix")) if m0.lambda.len() <= 3 => {
            let unmix = (v == "grid-unmix").then_some(UnmixFrom {
                init: &init,
                mean_rgb: &mean_rgb,
                seen: &seen,
            });
            grid_start_fit(&problem, &m0, &opts, lambert, unmix)
        }
        _ => estimate(&problem, m0, &opts, &mut |_, _| {}).expect("defaults' fit"),
    };
    // `ABLATION_DEFAULTS_START=refit | refit-w | reanchor | reanchor2`: a second fit from
    // the first fit's own materials (bench-results/restart-probes.md). Without one, as
    // `run --restart auto`: the coarse-light restart when the pilot kept the Lambertian
    // lobe alone, kept when its validation error is lower (`ABLATION_DEFAULTS_RESTART=off`:
    // `run --restart off`).
    let first = Fitted {
        est,
        kept: &pilot.kept,
        seen: &seen,
    };
    est = match std::env::var("ABLATION_DEFAULTS_START").as_deref() {
        Ok(
            v @ ("refit" | "refit-w" | "reanchor" | "reanchor2" | "reanchor-lambert" | "sh-ratio"
            | "sh-ratio2" | "coarse-light" | "coarse-light-free" | "truth-held"),
            // Kept whatever its score unless `ABLATION_REFIT_PICK=1`.
        ) => {
            let pick = crate::env_flag("ABLATION_REFIT_PICK");
            second_fit(v, &problem, first, &opts, case, lambert, pick)
        }
        // `reanchor-coarse`: `run --restart on+coarse-light`.
        Ok("reanchor-coarse") => restarts(
            Restart::ReanchorCoarseLight,
            &problem,
            first,
            &opts,
            case,
            lambert,
        ),
        _ => restarts(
            auto_restart(&kept, pilot.materials),
            &problem,
            first,
            &opts,
            case,
            lambert,
        ),
    };
    propagate_unseen(&case.positions, &seen, &mut est.weights, pilot.materials)
        .expect("propagation");
    est.lambda = est
        .lambda
        .iter()
        .map(|row| full_basis(row, &pilot.kept, case.basis.len()))
        .collect();
    DefaultsFit {
        est,
        pilot,
        seconds: t0.elapsed().as_secs_f64(),
    }
}

/// What `grid-unmix` unmixes each start's weights from: the clustered start and each
/// vertex's mean colour and whether a training photo sees it.
#[derive(Clone, Copy)]
struct UnmixFrom<'a> {
    init: &'a InitialMaterials,
    mean_rgb: &'a [[f64; 3]],
    seen: &'a [bool],
}

/// `ABLATION_DEFAULTS_START=grid | grid-unmix`: a fit from each start on a grid of the
/// materials' log brightness around `m0` (`λ_k e^{Σ_j t_j u_{j,k}}`, `u_j = e_j − 1/K` for
/// `j < K − 1`, `t_j ∈ {−n·δ … n·δ}`, `δ = ABLATION_GRID_STEP` (0.2), `n = ABLATION_GRID_N`
/// (3 with two materials, 2 otherwise)), its weights `m0`'s or (`grid-unmix`) unmixed
/// from the mean colours over the start's Lambertian colours; the fit with the lowest
/// validation score is kept. With more than three materials (a wrong count), the plain fit.
fn grid_start_fit(
    problem: &Problem,
    m0: &Materials0,
    opts: &EstimateOptions,
    lambert: usize,
    unmix: Option<UnmixFrom>,
) -> Estimate {
    let kk = m0.lambda.len();
    let step: f64 = crate::env_or("ABLATION_GRID_STEP", 0.2);
    let n = crate::env_or("ABLATION_GRID_N", if kk == 2 { 3 } else { 2 }) as i64;
    let dims = kk.saturating_sub(1);
    let side = (2 * n + 1) as usize;
    let starts: Vec<Start> = (0..side.pow(dims as u32))
        .map(|cell| {
            let t: Vec<f64> = (0..dims)
                .map(|j| ((cell / side.pow(j as u32)) % side) as f64 - n as f64)
                .map(|i| i * step)
                .collect();
            let mut lambda = m0.lambda.clone();
            for (j, &tj) in t.iter().enumerate() {
                lambda = ratio_step::scaled(&lambda, &ratio_step::direction(kk, j), [tj; 3]);
            }
            let weights = match unmix {
                Some(u) => {
                    let mut scaled = u.init.clone();
                    scaled.albedo = lambda.iter().map(|row| row[lambert]).collect();
                    unmixed_weights(&scaled, u.mean_rgb, u.seen).0
                }
                None => m0.weights.clone(),
            };
            Start {
                label: format!("t = {t:?}"),
                materials: Materials0 { lambda, weights },
            }
        })
        .collect();
    // The fit with the lowest validation score, as `--starts` keeps it.
    let (est, multi) =
        estimate_best(problem, starts, opts, &mut |_, _, _| {}).expect("grid starts' fits");
    for r in &multi.starts {
        eprintln!("grid start {}: validation {:.5}", r.label, r.score);
    }
    let kept = &multi.starts[multi.chosen];
    eprintln!(
        "grid start kept: {}, validation {:.5}",
        kept.label, kept.score
    );
    est
}

/// The permutation `perm` (start material `k` ↔ true material `perm[k]`) that brings the
/// start's Lambertian chromaticities nearest the truth's (least summed squared distance).
fn nearest_order(start: &[Vec<[f64; 3]>], truth: &[Vec<[f64; 3]>], lambert: usize) -> Vec<usize> {
    let chroma = |a: [f64; 3]| {
        let s = (a[0] + a[1] + a[2]).max(f64::MIN_POSITIVE);
        a.map(|v| v / s)
    };
    let dist = |a: [f64; 3], b: [f64; 3]| {
        let (a, b) = (chroma(a), chroma(b));
        (0..3).map(|c| (a[c] - b[c]).powi(2)).sum::<f64>()
    };
    crate::metrics::permutations(start.len())
        .into_iter()
        .min_by(|p, q| {
            let cost = |p: &Vec<usize>| -> f64 {
                p.iter()
                    .enumerate()
                    .map(|(k, &j)| dist(start[k][lambert], truth[j][lambert]))
                    .sum()
            };
            cost(p).total_cmp(&cost(q))
        })
        .unwrap_or_default()
}

/// [`unmixed_weights`] over the pair of materials with the least residual only (all of
/// them with two or fewer): a vertex blends at most two. A vertex whose `v` is 0 keeps
/// its weights.
fn unmix_pairs(m0: &mut Materials0, mean_rgb: &[[f64; 3]], seen: &[bool], lambert: usize) {
    let kk = m0.lambda.len();
    let subsets: Vec<Vec<usize>> = if kk > 2 {
        (0..kk)
            .flat_map(|a| (a + 1..kk).map(move |b| vec![a, b]))
            .collect()
    } else {
        vec![(0..kk).collect()]
    };
    for x in (0..seen.len()).filter(|&x| seen[x]) {
        let best = subsets
            .iter()
            .filter_map(|set| unmix_over(&m0.lambda, set, mean_rgb[x], lambert))
            .min_by(|a, b| a.1.total_cmp(&b.1));
        let Some((w, _)) = best else { continue };
        m0.weights[x * kk..(x + 1) * kk].copy_from_slice(&w);
    }
}

/// [`unmixed_weights`] on the clustered start in place: its weights and labels.
fn unmix_initial(init: &mut InitialMaterials, mean_rgb: &[[f64; 3]], seen: &[bool]) {
    (init.weights, init.labels) = unmixed_weights(init, mean_rgb, seen);
}

/// The weights (over all `K` materials, 0 outside `set`) of `c` unmixed over the Lambertian
/// colours of the materials in `set`, and the squared residual; `None` when they are 0.
fn unmix_over(
    lambda: &[Vec<[f64; 3]>],
    set: &[usize],
    c: [f64; 3],
    lambert: usize,
) -> Option<(Vec<f64>, f64)> {
    use nalgebra::{DMatrix, DVector};
    use relight_cpc::solve::qp::{nnls, NnlsOptions};
    let a = DMatrix::from_fn(3, set.len(), |ch, j| lambda[set[j]][lambert][ch]);
    let y = DVector::from_row_slice(&c);
    let v = nnls(
        &(a.transpose() * &a),
        &(a.transpose() * &y),
        &NnlsOptions::default(),
    )
    .ok()?;
    let total = v.sum();
    if total <= 0.0 {
        return None;
    }
    let residual = (&a * &v - &y).norm_squared();
    let mut w = vec![0.0; lambda.len()];
    for (j, &k) in set.iter().enumerate() {
        w[k] = v[j] / total;
    }
    Some((w, residual))
}

/// A material's weights over the kept bases (`kept[i]`: index of the `i`-th in the full
/// list) laid out over all `n` bases, 0 for a dropped one.
fn full_basis(row: &[[f64; 3]], kept: &[usize], n: usize) -> Vec<[f64; 3]> {
    let mut full = vec![[0.0; 3]; n];
    for (v, &b) in row.iter().zip(kept) {
        full[b] = *v;
    }
    full
}

/// The pilot's choices in a sentence, for the table's notes.
pub fn describe(case: &Case, p: &PilotOutcome) -> String {
    let kept: Vec<String> = p.kept.iter().map(|&b| case.basis[b].label()).collect();
    format!(
        "the pilot chose K = {}, the {} start, the weights' sum-to-one prior at {}{} and the lobes {} ({}; {}; {})",
        p.materials,
        p.start.name(),
        p.weights_sum,
        match p.weights_sum_scope {
            relight_cpc::solve::SumScope::Every => "",
            relight_cpc::solve::SumScope::Blends { .. } => " on blended vertices",
        },
        kept.join(", "),
        p.weights_sum_reason
            .as_deref()
            .unwrap_or("weights' prior not chosen"),
        p.start_reason.as_deref().unwrap_or("start not chosen"),
        p.basis_reason
    )
}

/// A first fit with what [`second_fit`] reads of it.
struct Fitted<'a> {
    est: Estimate,
    /// The case's bases the pilot kept.
    kept: &'a [usize],
    /// Whether a training photo sees each vertex.
    seen: &'a [bool],
}

/// The second fit of `ABLATION_DEFAULTS_START=v` from `first` (`reanchor`:
/// [`relight_cpc::solve::materials::reanchor::reanchor`] with projected weights, `reanchor2`
/// twice, `reanchor-lambert` with [`keep_gloss`]; `refit`, `refit-w`: [`refit`]), returned whatever its score unless
/// `pick`, which keeps the fit with the lower validation error as `run --restart` does.
/// Prints both fits' worst ratio errors and validation errors.
fn second_fit(
    v: &str,
    problem: &Problem,
    first: Fitted,
    opts: &EstimateOptions,
    case: &Case,
    lambert: usize,
    pick: bool,
) -> Estimate {
    use relight_cpc::solve::alternation::estimate_from_lights;
    use relight_cpc::solve::materials::coarse_light;
    use relight_cpc::solve::materials::reanchor::{fit_in_turn, reanchor, Reweight, StepOutcome};
    let Fitted { est, kept, seen } = first;
    let ratios_of = |lambda: &[Vec<[f64; 3]>], weights: &[f64]| {
        let full: Vec<Vec<[f64; 3]>> = lambda
            .iter()
            .map(|row| full_basis(row, kept, case.basis.len()))
            .collect();
        crate::metrics::ratio_errors(case, &full, weights, seen)
    };
    let ratios = |e: &Estimate| ratios_of(&e.lambda, &e.weights);
    let start_ratios = |m: &Materials0| ratios_of(&m.lambda, &m.weights);
    let second = if v == "truth-held" {
        let m = truth_held_start(&est, case, seen, kept, lambert);
        eprintln!(
            "truth-held start: worst ratio {:.3?} (first fit {:.3?})",
            start_ratios(&m),
            ratios(&est)
        );
        let held = coarse_light::held_fit_options(opts);
        estimate_from_lights(problem, m, &held, &est.lights, &mut |_, _| {}).expect("held fit")
    } else if v == "coarse-light" && pick {
        // As `run --restart coarse-light`: the library's starts (two over the Lambertian
        // lobe alone, the tied one over a shiny basis), fitted in turn with the materials
        // held, each kept when its validation error is lower (`reanchor::fit_in_turn`;
        // `ABLATION_COARSE_WEIGHTS=fit`: the first alone).
        let mut steps =
            coarse_light::restart_starts(problem, &est.lambda, &est.weights, seen, lambert)
                .expect("the first fit's sizes");
        if std::env::var("ABLATION_COARSE_WEIGHTS").is_ok_and(|w| w == "fit") {
            steps.truncate(1);
        }
        let held = coarse_light::held_fit_options(opts);
        let (kept, outcomes) =
            fit_in_turn(problem, est.clone(), steps, &held, &mut |_, _, _| {}).expect("second fit");
        for o in &outcomes {
            match o {
                StepOutcome::Fitted {
                    scores,
                    kept_restart,
                    ..
                } => eprintln!(
                    "coarse-light held fit: validation {:.5} against {:.5}, kept {kept_restart}",
                    scores[1], scores[0]
                ),
                StepOutcome::Skipped { before, .. } => {
                    eprintln!("coarse-light held fit skipped ({before:.5?})")
                }
            }
        }
        kept
    } else if v.starts_with("coarse-light") {
        let starts = coarse_light_starts(&est, case, seen, lambert);
        eprintln!(
            "coarse-light start: worst ratio {:.3?} (first fit {:.3?})",
            start_ratios(&starts.fit_weights),
            ratios(&est)
        );
        let held = coarse_light::held_fit_options(opts);
        if v == "coarse-light" {
            // The first held fit whatever its score, from the Lambertian model's start
            // whatever the basis (section 3's `coarse-held` probe).
            estimate_from_lights(
                problem,
                starts.fit_weights,
                &held,
                &est.lights,
                &mut |_, _| {},
            )
            .expect("second fit")
        } else {
            estimate(problem, starts.fit_weights, opts, &mut |_, _| {}).expect("second fit")
        }
    } else if v.starts_with("sh-ratio") {
        let m = sh_ratio_start(&est, case, seen, lambert);
        if std::env::var("ABLATION_SH_TRUTH").is_ok() {
            sh_truth_diagnosis(case, (&est, &m), seen, kept, lambert);
            if std::env::var("ABLATION_SH_TRUTH").is_ok_and(|v| v == "only") {
                std::process::exit(0);
            }
        }
        eprintln!(
            "sh-ratio start: worst ratio {:.3?} (first fit {:.3?})",
            start_ratios(&m),
            ratios(&est)
        );
        let mut second = estimate(problem, m, opts, &mut |_, _| {}).expect("second fit");
        // `sh-ratio2`: the model read again from the second fit's weights, a third fit.
        if v == "sh-ratio2" {
            eprintln!(
                "sh-ratio2: second fit's worst ratio {:.3?}",
                ratios(&second)
            );
            let m = sh_ratio_start(&second, case, seen, lambert);
            second = estimate(problem, m, opts, &mut |_, _| {}).expect("third fit");
        }
        second
    } else if v.starts_with("reanchor") {
        let mut from = est.clone();
        for _ in 0..if v == "reanchor2" { 2 } else { 1 } {
            let mut m = reanchor(&from.lambda, &from.weights, seen, Reweight::Project)
                .expect("re-anchoring");
            if v == "reanchor-lambert" {
                keep_gloss(&mut m.lambda, &from.lambda, lambert);
            }
            from = estimate(problem, m, opts, &mut |_, _| {}).expect("second fit");
        }
        from
    } else {
        refit(problem, &est, opts, case, lambert, v == "refit")
    };
    let score = |e: &Estimate| e.validation.as_ref().map(|v| v.best_error());
    eprintln!(
        "second fit {v}: worst ratio {:.3?} -> {:.3?}; validation {:?} -> {:?}",
        ratios(&est),
        ratios(&second),
        score(&est),
        score(&second)
    );
    if !pick || score(&second) < score(&est) {
        second
    } else {
        est
    }
}

/// The restart `run --restart auto` makes after the defaults' fit
/// ([`Restart::resolve`] over the pilot's kept lobes; none with fewer than two materials
/// or with `ABLATION_DEFAULTS_RESTART=off`).
fn auto_restart(kept: &[relight_cpc::transport::brdf::BasisBrdf], materials: usize) -> Restart {
    let off = std::env::var("ABLATION_DEFAULTS_RESTART").is_ok_and(|v| v == "off");
    if off || materials < 2 {
        return Restart::Off;
    }
    Restart::Auto.resolve(kept)
}

/// The second fits `run --restart mode` makes from `first` ([`Restart::steps`], each the
/// [`second_fit`] of the same name from the fit kept before it, kept when its validation
/// error is lower).
fn restarts(
    mode: Restart,
    problem: &Problem,
    first: Fitted,
    opts: &EstimateOptions,
    case: &Case,
    lambert: usize,
) -> Estimate {
    let Fitted {
        mut est,
        kept,
        seen,
    } = first;
    for step in mode.steps() {
        let v = match step {
            Restart::Reanchor => "reanchor",
            Restart::Irradiance => "sh-ratio",
            Restart::CoarseLight => "coarse-light",
            Restart::Auto | Restart::Off | Restart::ReanchorCoarseLight => continue,
        };
        let from = Fitted { est, kept, seen };
        est = second_fit(v, problem, from, opts, case, lambert, true);
    }
    est
}

/// `reanchor-lambert`: every non-Lambertian lobe of each re-anchored material set to keep
/// the first fit's ratio to its Lambertian lobe, per channel (`λ'_{k,b} = λ_{k,b} ·
/// λ'_{k,L} / λ_{k,L}`).
fn keep_gloss(lambda: &mut [Vec<[f64; 3]>], first: &[Vec<[f64; 3]>], lambert: usize) {
    for (row, was) in lambda.iter_mut().zip(first) {
        for c in 0..3 {
            let f = if was[lambert][c] > 0.0 {
                row[lambert][c] / was[lambert][c]
            } else {
                1.0
            };
            for (b, v) in row.iter_mut().enumerate() {
                if b != lambert {
                    v[c] = was[b][c] * f;
                }
            }
        }
    }
}

/// `ABLATION_DEFAULTS_START=refit | refit-w`: a second fit from the first fit's own
/// materials: each vertex's weights divided by their sum (the shading a free weight took
/// on given back to λ: each material's λ times the median sum over its pure vertices),
/// and with `refit` each material's Lambertian λ per channel matched by normal
/// ([`relight_cpc::solve::matched::relative_brightness`]) over the vertices the first fit
/// finds pure (normalised weight ≥ 0.95), the per-channel geometric mean kept.
fn refit(
    problem: &Problem,
    est: &Estimate,
    opts: &EstimateOptions,
    case: &Case,
    lambert: usize,
    matched: bool,
) -> Estimate {
    use relight_cpc::solve::matched::{relative_brightness, MatchedInput};
    let kk = est.lambda.len();
    let nv = case.nv;
    let mut w = est.weights.clone();
    let mut sums = vec![0.0; nv];
    for x in 0..nv {
        let s: f64 = w[x * kk..(x + 1) * kk].iter().sum();
        sums[x] = s;
        if s > 0.0 {
            w[x * kk..(x + 1) * kk].iter_mut().for_each(|v| *v /= s);
        }
    }
    let pure = |k: usize| -> Vec<usize> { (0..nv).filter(|&x| w[x * kk + k] >= 0.95).collect() };
    let mut lambda = est.lambda.clone();
    for k in 0..kk {
        let mut s: Vec<f64> = pure(k).iter().map(|&x| sums[x]).collect();
        if s.is_empty() {
            continue;
        }
        let mid = s.len() / 2;
        let med = *s.select_nth_unstable_by(mid, f64::total_cmp).1;
        if med > 0.0 {
            lambda[k].iter_mut().for_each(|b| *b = b.map(|v| v * med));
        }
    }
    if matched {
        let labels: Vec<usize> = (0..nv)
            .map(|x| {
                (0..kk)
                    .max_by(|&a, &b| w[x * kk + a].total_cmp(&w[x * kk + b]))
                    .unwrap()
            })
            .collect();
        let lw: Vec<f64> = (0..nv)
            .map(|x| {
                if w[x * kk + labels[x]] >= 0.95 {
                    1.0
                } else {
                    0.0
                }
            })
            .collect();
        let open = case.vis.open_fractions();
        let fitted = relative_brightness(&MatchedInput {
            obs: &case.train.obs,
            labels: &labels,
            label_weight: &lw,
            normals: &case.normals_env,
            open: &open,
            k: kk,
        });
        eprintln!(
            "refit: the normal-matched model over {} photo × normal cells",
            fitted.cells
        );
        let idx: Vec<usize> = (0..kk).filter(|&k| fitted.a[k].is_some()).collect();
        if idx.len() >= 2 {
            for c in 0..3 {
                let n = idx.len() as f64;
                let mean_log: f64 = idx
                    .iter()
                    .map(|&k| lambda[k][lambert][c].max(1e-12).ln())
                    .sum::<f64>()
                    / n;
                let mean_a: f64 = idx.iter().map(|&k| fitted.a[k].unwrap()[c]).sum::<f64>() / n;
                for &k in &idx {
                    lambda[k][lambert][c] = (fitted.a[k].unwrap()[c] - mean_a + mean_log).exp();
                }
            }
        }
    }
    estimate(
        problem,
        Materials0 { lambda, weights: w },
        opts,
        &mut |_, _| {},
    )
    .expect("refit")
}

/// `ABLATION_DEFAULTS_START=coarse-light`: `run --restart coarse-light`'s two starts
/// ([`relight_cpc::solve::materials::coarse_light::coarse_light_starts`]) from the first fit.
fn coarse_light_starts(
    est: &Estimate,
    case: &Case,
    seen: &[bool],
    lambert: usize,
) -> relight_cpc::solve::materials::coarse_light::CoarseStarts {
    use relight_cpc::solve::materials::{coarse_light, irradiance};
    let kk = est.lambda.len();
    let weights = irradiance::normalised_weights(&est.weights, kk);
    let rows = coarse_light::pure_seen_rows(&coarse_light::CoarseRowsInput {
        obs: &case.train.obs,
        transport: &case.train.transport,
        seen,
        weights: &weights,
        materials: kk,
        lambert: 0,
        blocks: coarse_light::BLOCKS.min(case.train.transport.n_global),
    });
    let n_photos = case.train.obs.photo_ranges.len();
    coarse_light::coarse_light_starts(&est.lambda, &est.weights, seen, lambert, &rows, n_photos)
        .expect("the first fit's sizes")
        .expect("every material has pure seen vertices")
}

/// `ABLATION_DEFAULTS_START=truth-held` (an oracle probe): the TRUE materials' λ over the
/// kept lobes, matched to the first fit's materials by best accuracy and scaled per channel
/// so the Lambertian lobes' geometric mean is the first fit's, over weights chosen by
/// `ABLATION_ORACLE_WEIGHTS=fit` (the first fit's normalised, pure ones snapped; default),
/// `resorted` (`coarse_light::resorted_weights`, snapped), `projected` (the first fit's
/// re-sorted on the TRUE materials, `reanchor::projected_on`, snapped) or `true` (the
/// truth's); the lights fitted again with them held (`bench-results/coarse-light-start.md`
/// section 15).
fn truth_held_start(
    est: &Estimate,
    case: &Case,
    seen: &[bool],
    kept: &[usize],
    lambert: usize,
) -> Materials0 {
    use relight_cpc::solve::materials::{coarse_light, irradiance};
    let kk = est.lambda.len();
    let (_, _, perm) = crate::metrics::best_order(case, est, seen);
    let mut lambda: Vec<Vec<[f64; 3]>> = perm
        .iter()
        .map(|&t| kept.iter().map(|&b| case.lambda[t][b]).collect())
        .collect();
    let mean_log = |v: &[f64]| v.iter().map(|r| r.max(1e-12).ln()).sum::<f64>() / kk as f64;
    for c in 0..3 {
        let first: Vec<f64> = est.lambda.iter().map(|l| l[lambert][c]).collect();
        let truth: Vec<f64> = lambda.iter().map(|l| l[lambert][c]).collect();
        let s = (mean_log(&first) - mean_log(&truth)).exp();
        lambda
            .iter_mut()
            .for_each(|l| l.iter_mut().for_each(|v| v[c] *= s));
    }
    let weights = match std::env::var("ABLATION_ORACLE_WEIGHTS").as_deref() {
        Ok("true") => {
            let mut w = vec![0.0; case.nv * kk];
            for x in 0..case.nv {
                for j in 0..kk {
                    w[x * kk + j] = case.weights[x * kk + perm[j]];
                }
            }
            w
        }
        Ok("resorted") => irradiance::snap_pure(
            coarse_light::resorted_weights(&est.lambda, &est.weights, seen).expect("re-sorted"),
            kk,
        ),
        Ok("projected") => {
            let w = relight_cpc::solve::materials::reanchor::projected_on(
                &lambda,
                &est.lambda,
                &est.weights,
                seen,
            )
            .expect("projection");
            irradiance::snap_pure(irradiance::normalised_weights(&w, kk), kk)
        }
        _ => irradiance::snap_pure(irradiance::normalised_weights(&est.weights, kk), kk),
    };
    Materials0 { lambda, weights }
}

/// `ABLATION_DEFAULTS_START=sh-ratio`: `run --restart irradiance`'s start
/// ([`relight_cpc::solve::materials::irradiance`]) from the first fit, over the vertices
/// with an open fraction ≥ `ABLATION_SH_OPEN` (`run`'s 0.95).
fn sh_ratio_start(est: &Estimate, case: &Case, seen: &[bool], lambert: usize) -> Materials0 {
    use relight_cpc::solve::materials::irradiance::{self, RowsInput};
    let kk = est.lambda.len();
    let weights = irradiance::normalised_weights(&est.weights, kk);
    let open = case.vis.open_fractions();
    let rows = irradiance::pure_open_rows(&RowsInput {
        obs: &case.train.obs,
        normals_env: &case.normals_env,
        open: &open,
        seen,
        weights: &weights,
        materials: kk,
        min_open: crate::env_or("ABLATION_SH_OPEN", irradiance::MIN_OPEN),
    });
    let counts: Vec<usize> = (0..kk)
        .map(|k| rows.iter().filter(|r| r.material == k).count())
        .collect();
    eprintln!("sh-ratio: observations per material {counts:?}");
    let n_photos = case.train.obs.photo_ranges.len();
    irradiance::irradiance_start(&est.lambda, weights, lambert, &rows, n_photos)
        .expect("the first fit's sizes")
        .expect("every material has pure, open vertices")
}

/// `ABLATION_SH_TRUTH=1` with `sh-ratio` (`only`: then stop): the irradiance model's
/// worst Lambertian ratio error (the library's converged fit) over the pure, open vertices
/// of the TRUE weights or of the first fit's, each region eroded by 0–2 rings of the
/// 8-nearest-neighbour graph (a vertex kept when its neighbours are pure in the same
/// material), read from the photos, and over the TRUE vertices from the true model's exact
/// prediction through the case's transport (no pixel mixing, no 8-bit): the model's own
/// bias (order-2 truncation, cast shadows, interreflection). Before that,
/// [`weights_purity`] of the first fit and of the model's start. Only when the pilot took
/// the true count.
fn sh_truth_diagnosis(
    case: &Case,
    (first, start): (&Estimate, &Materials0),
    seen: &[bool],
    kept: &[usize],
    lambert: usize,
) {
    use relight_cpc::solve::materials::irradiance::normalised_weights;
    use relight_cpc::solve::materials::propagate::{knn_graph, NEIGHBOURS};
    let kt = case.lambda.len();
    if first.lambda.len() != kt {
        return;
    }
    let true_kept: Vec<Vec<[f64; 3]>> = case
        .lambda
        .iter()
        .map(|row| kept.iter().map(|&b| row[b]).collect())
        .collect();
    let fit_order = nearest_order(&first.lambda, &true_kept, lambert);
    let purity = |lambda: &[Vec<[f64; 3]>], raw: &[f64]| {
        weights_purity(case, (lambda, raw), seen, (kept, lambert), &fit_order)
    };
    eprintln!(
        "sh-truth first fit: {}",
        purity(&first.lambda, &first.weights)
    );
    eprintln!(
        "sh-truth irradiance start: {}",
        purity(&start.lambda, &start.weights)
    );
    let exact = crate::true_prediction(case, &case.train);
    let mut exact_obs = case.train.obs.clone();
    crate::replace_colours(&mut exact_obs, &exact);
    let graph = knn_graph(&case.positions, NEIGHBOURS).expect("graph");
    let open = case.vis.open_fractions();
    let sources = [
        ("truth", case.weights.clone(), (0..kt).collect::<Vec<_>>()),
        ("fit", normalised_weights(&first.weights, kt), fit_order),
    ];
    for (source, mut w, order) in sources {
        for rings in 0..3 {
            if rings > 0 {
                w = eroded(&w, &graph, kt);
            }
            if rings == 0 {
                block_light_diagnosis(case, source, &exact_obs, (seen, &w, &order));
            }
            let mut data = vec![("photos", &case.train.obs)];
            if source == "truth" && rings == 0 {
                data.push(("exact", &exact_obs));
            }
            for (label, obs) in data {
                let (rows, errs) = model_ratio_errors(case, (obs, &open), seen, &w, &order);
                eprintln!(
                    "sh-truth {source} eroded {rings} {label}: {rows} rows, worst ratio per channel {errs:.3?}"
                );
            }
        }
    }
}

/// `w` (`V × K`) with every vertex that has a neighbour of another pure material (or of
/// none) made impure (its row zeroed).
fn eroded(
    w: &[f64],
    graph: &relight_cpc::solve::materials::propagate::VertexGraph,
    kk: usize,
) -> Vec<f64> {
    use relight_cpc::solve::materials::irradiance::pure_material;
    let label = |x: usize| pure_material(&w[x * kk..(x + 1) * kk]);
    let mut out = w.to_vec();
    for x in 0..w.len() / kk {
        if graph
            .neighbours(x)
            .iter()
            .any(|&y| label(y as usize) != label(x))
        {
            out[x * kk..(x + 1) * kk].iter_mut().for_each(|v| *v = 0.0);
        }
    }
    out
}

/// The true Lambertian ratio of material `j` to material 0 in channel `c`.
fn true_ratio(case: &Case, j: usize, c: usize) -> f64 {
    case.lambda[j][0][c] / case.lambda[0][0][c]
}

/// The worst relative error per channel of the ratios `rho[k] / rho[0]`, material `k` of
/// `rho` read as true material `order[k]`.
fn worst_ratio_errors(case: &Case, rho: impl Fn(usize, usize) -> f64, order: &[usize]) -> [f64; 3] {
    [0, 1, 2].map(|c| {
        let mut by_truth = vec![f64::NAN; order.len()];
        for (k, &j) in order.iter().enumerate() {
            by_truth[j] = rho(k, c);
        }
        (1..order.len())
            .map(|j| (by_truth[j] / by_truth[0] / true_ratio(case, j, c) - 1.0).abs())
            .fold(0.0, f64::max)
    })
}

/// The rows the model reads with weights `w` (observations and open fractions `obs_open`)
/// and its worst Lambertian ratio error per channel against the truth, fit material `k`
/// read as true material `order[k]`.
fn model_ratio_errors(
    case: &Case,
    (obs, open): (&relight_cpc::observe::Observations, &[f64]),
    seen: &[bool],
    w: &[f64],
    order: &[usize],
) -> (usize, [f64; 3]) {
    use relight_cpc::solve::materials::irradiance::{self, RowsInput};
    let kk = order.len();
    let rows = irradiance::pure_open_rows(&RowsInput {
        obs,
        normals_env: &case.normals_env,
        open,
        seen,
        weights: w,
        materials: kk,
        min_open: crate::env_or("ABLATION_SH_OPEN", irradiance::MIN_OPEN),
    });
    let n_photos = obs.photo_ranges.len();
    let rho: Vec<Vec<f64>> = (0..3)
        .map(|c| {
            irradiance::irradiance_albedos(&rows, c, n_photos, &vec![1.0; kk]).expect("finite rows")
        })
        .collect();
    (
        rows.len(),
        worst_ratio_errors(case, |k, c| rho[c][k], order),
    )
}

/// A fit's weights at the TRUE pure seen vertices: quantiles of the normalised weight on
/// the true material; the ablation's ratio metric ([`crate::metrics::ratio_errors`]) with
/// the raw weights and with the normalised ones; and the worst ratio of the materials'
/// Lambertian λ alone.
fn weights_purity(
    case: &Case,
    (lambda, raw): (&[Vec<[f64; 3]>], &[f64]),
    seen: &[bool],
    (kept, lambert): (&[usize], usize),
    order: &[usize],
) -> String {
    let (kt, kf) = (case.lambda.len(), lambda.len());
    let w = relight_cpc::solve::materials::irradiance::normalised_weights(raw, kf);
    let mut on_true = Vec::new();
    for x in (0..case.nv).filter(|&x| seen[x]) {
        for t in (0..kt).filter(|&t| case.weights[x * kt + t] >= 0.95) {
            let k = order.iter().position(|&j| j == t).expect("a permutation");
            on_true.push(w[x * kf + k]);
        }
    }
    on_true.sort_by(f64::total_cmp);
    let q = |p: f64| on_true[((on_true.len() - 1) as f64 * p) as usize];
    let full: Vec<Vec<[f64; 3]>> = lambda
        .iter()
        .map(|row| full_basis(row, kept, case.basis.len()))
        .collect();
    let metric = |weights: &[f64]| crate::metrics::ratio_errors(case, &full, weights, seen);
    let lambda_only = worst_ratio_errors(case, |k, c| lambda[k][lambert][c], order);
    format!(
        "weight on the true material q10 {:.3} q25 {:.3} q50 {:.3}; ratio raw {:.3?}, normalised {:.3?}, λ alone {lambda_only:.3?}",
        q(0.1), q(0.25), q(0.5), metric(raw), metric(&w)
    )
}

/// [`block_light_ratio_errors`] for each `r` of `ABLATION_SH_BLOCKS`, on the photos and,
/// for the TRUE weights, on the exact data.
fn block_light_diagnosis(
    case: &Case,
    source: &str,
    exact: &relight_cpc::observe::Observations,
    (seen, w, order): (&[bool], &[f64], &[usize]),
) {
    let Ok(blocks) = std::env::var("ABLATION_SH_BLOCKS") else {
        return;
    };
    for r in blocks
        .split(',')
        .map(|v| v.parse::<usize>().expect("a block side"))
    {
        let mut data = vec![("photos", &case.train.obs)];
        if source == "truth" {
            data.push(("exact", exact));
        }
        for (label, obs) in data {
            let (rows, errs) = block_light_ratio_errors(case, obs, (seen, w, order), r);
            eprintln!(
                "sh-blocks {source} {r}x{r} {label}: {rows} rows, worst ratio per channel {errs:.3?}"
            );
        }
    }
}

/// `ABLATION_SH_BLOCKS=r,…`: the worst ratio per channel of `run --restart coarse-light`'s
/// model ([`relight_cpc::solve::materials::coarse_light`]) with `r × r` blocks over the
/// pure seen vertices of `w` read from `obs`, fit material `k` read as true material
/// `order[k]`; and the row count.
fn block_light_ratio_errors(
    case: &Case,
    obs: &relight_cpc::observe::Observations,
    (seen, w, order): (&[bool], &[f64], &[usize]),
    r: usize,
) -> (usize, [f64; 3]) {
    use relight_cpc::solve::materials::coarse_light;
    let kk = order.len();
    let rows = coarse_light::pure_seen_rows(&coarse_light::CoarseRowsInput {
        obs,
        transport: &case.train.transport,
        seen,
        weights: w,
        materials: kk,
        lambert: 0,
        blocks: r,
    });
    let n_photos = obs.photo_ranges.len();
    let rho: Vec<Vec<f64>> = (0..3)
        .map(|c| {
            coarse_light::coarse_light_albedos(&rows, c, n_photos, &vec![1.0; kk])
                .expect("finite rows")
        })
        .collect();
    (
        rows.len(),
        worst_ratio_errors(case, |k, c| rho[c][k], order),
    )
}
