//! The row `defaults (the pilot's choices)`: what `relight-cpc run` does with no flags, on
//! the bench's cases. The adaptive pilot ([`adapt::pilot`], the function `run` calls,
//! with the inputs `run` gives it) chooses the material count (step 3), the blending
//! weights' sum-to-one prior (step 3b) and which of the case's lobes to keep (step 4); the
//! full fit then uses those choices with the light model `run` chooses without `--light`
//! ([`light::by_scene`]: validation among the light models when the pilot keeps a shiny
//! lobe, else the paper's map; `ABLATION_DEFAULTS_LIGHT=paper` keeps the paper's), the k-means start and
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
//!
//! The probes of the ratio and start work (`ABLATION_DEFAULTS_START=…`) sit beside it:
//! [`start_probes`] (other starts for the first fit), [`second`] (second fits from the first
//! fit's materials, and `run --restart`'s) and [`diagnosis`] (the irradiance and
//! coarse-light models' ratio errors against the truth).

mod diagnosis;
mod light;
mod loss;
mod mixture;
mod second;
mod start_probes;

use crate::synth_case::*;
use relight_cpc::observe::background::BackgroundTexel;
use relight_cpc::run::RunOptions;
use relight_cpc::solve::adapt::{self, PilotInput, PilotOutcome};
use relight_cpc::solve::cluster::{unmixed_weights, InitialMaterials};
use relight_cpc::solve::materials::propagate::propagate_unseen;
use relight_cpc::solve::ratio_step;
use relight_cpc::solve::{
    estimate, Estimate, EstimateOptions, IterState, Iteration, Materials0, Problem,
};

/// The case's basis has its Lambertian lobe first (`fit_start`'s convention).
const LAMBERT: usize = 0;

/// The defaults' fit: its estimate over the case's full basis (a dropped lobe's weights
/// 0) and what the pilot decided.
pub struct DefaultsFit {
    pub est: Estimate,
    pub pilot: PilotOutcome,
    /// The light model the fit used and why ([`light::by_scene`]).
    pub light: String,
    /// The fit's options (its light model, its Laplacian weight).
    pub opts: EstimateOptions,
    pub seconds: f64,
}

/// Each vertex's mean colour over the training photos and whether one sees it: what the
/// clustered start and the unmixed starts read.
#[derive(Clone, Copy)]
struct Colours<'a> {
    mean_rgb: &'a [[f64; 3]],
    seen: &'a [bool],
}

/// The pilot on the case's training photos, then the fit with its choices (the start, the
/// first fit, `run --restart auto`'s second fits, the unseen vertices' materials); `base`:
/// the bench's options (the paper's free weights, the paper's light model).
pub fn fit_defaults(case: &Case, base: &EstimateOptions) -> DefaultsFit {
    let t0 = std::time::Instant::now();
    let base = &with_env_overrides(base, case);
    if base.background.is_some() {
        eprintln!("  background: {}", background_check(case));
    }
    let (mean_rgb, seen) = relight_cpc::run::mean_colours(&case.train.obs, case.nv);
    let colours = Colours {
        mean_rgb: &mean_rgb,
        seen: &seen,
    };
    let pilot = run_pilot(case, base, colours);
    let sub = adapt::select_bases(&case.train.transport, &pilot.kept).expect("kept bases");
    let problem = Problem {
        transport: &sub,
        ..case.train.problem(case.nv)
    };
    let init = clustered_start(case, &pilot, colours);
    let m0 = start_materials(case, &pilot, &init, colours);
    let fit_opts = fit_options(case, base, &pilot);
    let light = light::by_scene(case, &problem, &m0, fit_opts.clone(), &pilot);
    let light = loss::by_run_rule(case, &problem, &m0, light);
    let opts = with_stop_halves(case, with_prior_noise(light.options));
    let m0 = if start_variant().as_deref() == Some("stiff-spec") {
        let scope = StartScope {
            kept: &pilot.kept,
            seen: &seen,
        };
        stiff_specular_start(case, &problem, m0, fit_opts, scope)
    } else {
        m0
    };
    let judge = std::env::var("ABLATION_GRID_JUDGE")
        .is_ok_and(|v| v == "halves")
        .then(|| EstimateOptions {
            validation_halves: light::choice_halves(
                case,
                relight_cpc::run::DEFAULT_LIGHT_CHOICE_HALVES,
            ),
            ..opts.clone()
        });
    let first = second::Fitted {
        est: first_fit(
            &problem,
            m0,
            &opts,
            judge.as_ref(),
            &init,
            colours,
            &mut tracer(case, &pilot.kept, &seen, "first"),
        ),
        kept: &pilot.kept,
        seen: &seen,
    };
    eprintln!("  ratio step, first fit: {}", moves_line(&first.est));
    let probe = second::Probe {
        problem: &problem,
        opts: &opts,
        case,
    };
    let mut est = second::second_fits(probe, first, pilot.materials);
    eprintln!("  ratio step, the fit kept: {}", moves_line(&est));
    let v = &est.varpro_moves;
    if v.tried + v.unsupported > 0 {
        eprintln!(
            "  variable-projection step, the fit kept: {} of {} kept, {} rounds unsupported",
            v.kept, v.tried, v.unsupported
        );
    }
    propagate_unseen(&case.positions, &seen, &mut est.weights, pilot.materials)
        .expect("propagation");
    est.lambda = full_lambda(case, &pilot.kept, &est.lambda);
    if !case.train.background.iter().all(Vec::is_empty) {
        eprintln!(
            "  background against the fit: {}",
            background_fit(case, &est.lights)
        );
    }
    if crate::env_flag("ABLATION_TAIL") {
        eprintln!(
            "  pure vertices more than 10% off their median, the defaults' fit: {}",
            crate::metrics::tail_shares(case, &est.lambda, &est.weights, &seen)
        );
    }
    DefaultsFit {
        est,
        pilot,
        light: light.note,
        opts,
        seconds: t0.elapsed().as_secs_f64(),
    }
}

/// What the ratio step did in `est`'s alternation ([`ratio_step`]), in words: the moves
/// kept, the rounds the light model could not take it in, and where the patience stopped it.
fn moves_line(est: &Estimate) -> String {
    let m = &est.ratio_moves;
    let stop = m
        .stopped_after
        .map_or("ran every round asked for".into(), |r| {
            format!("stopped after round {r}")
        });
    let unsupported = match m.unsupported {
        0 => String::new(),
        n => format!(", the light model could not take it in {n} rounds"),
    };
    format!("{} of {} moves kept{unsupported}, {stop}", m.kept, m.tried)
}

/// The bench's options with the pilot's and the fit's IRLS overridden: `run
/// --irls-iterations N` with `ABLATION_DEFAULTS_IRLS=N`; the robust floor with
/// `ABLATION_DEFAULTS_FLOOR=X`; Huber's `k` or Tukey's biweight with
/// `ABLATION_DEFAULTS_ROBUST=K|tukey`; the maps' Laplacian weight with
/// `ABLATION_DEFAULTS_SMOOTHNESS=X` (`run --smoothness X`), its schedule with
/// `ABLATION_DEFAULTS_DECAY=D` and `ABLATION_DEFAULTS_SMOOTHNESS_MIN=M` (the estimator's
/// `smoothness_decay` and `smoothness_min`, which `run` leaves at 1 and 0); the chroma
/// prior's `κ` with `ABLATION_DEFAULTS_CHROMA=K` (`run --chroma-smoothness K`).
fn with_env_overrides(base: &EstimateOptions, case: &Case) -> EstimateOptions {
    let obs = &case.train.obs;
    // `ABLATION_BACKGROUND=γ`: the training photos' backgrounds pull their maps (photos
    // rendered with `SYNTH_SKY_BACKGROUND=1`; not a flag of `run`).
    let background = std::env::var("ABLATION_BACKGROUND")
        .ok()
        .and_then(|v| v.parse::<f64>().ok())
        .map(|weight| {
            std::sync::Arc::new(relight_cpc::solve::light::background::BackgroundTerm {
                weight,
                n_global: case.sizes.global,
                photos: case.train.background.clone(),
            })
        });
    EstimateOptions {
        background: background.or_else(|| base.background.clone()),
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
        smoothness_decay: crate::env_or("ABLATION_DEFAULTS_DECAY", base.smoothness_decay),
        smoothness_min: crate::env_or("ABLATION_DEFAULTS_SMOOTHNESS_MIN", base.smoothness_min),
        chroma_smoothness: crate::env_or("ABLATION_DEFAULTS_CHROMA", base.chroma_smoothness),
        // `ABLATION_CLIPPED_BOUNDS=1|0`: clipped channels read as lower bounds, or left out;
        // unset, `run`'s `--clipped auto` (bounds from a tenth of the observations on).
        clipped_bounds: std::env::var("ABLATION_CLIPPED_BOUNDS")
            .map_or(relight_cpc::run::auto_reads_bounds(obs), |v| v == "1"),
        ..base.clone()
    }
}

/// Per channel, sorted, `value(i, b, c)` over the texels `b` the training photos `i`'
/// backgrounds read, where it is given.
fn over_background_texels(
    case: &Case,
    value: impl Fn(usize, &BackgroundTexel, usize) -> Option<f64>,
) -> [Vec<f64>; 3] {
    let mut v: [Vec<f64>; 3] = Default::default();
    for (i, bg) in case.train.background.iter().enumerate() {
        for b in bg {
            (0..3).for_each(|c| v[c].extend(value(i, b, c)));
        }
    }
    v.iter_mut().for_each(|c| c.sort_by(f64::total_cmp));
    v
}

/// The `f`-quantile of the sorted `v` (NaN when empty).
fn quantile(v: &[f64], f: f64) -> f64 {
    v.get((f * v.len() as f64) as usize)
        .copied()
        .unwrap_or(f64::NAN)
}

/// The training backgrounds against the truth: texels and pixels read, and per channel the
/// median of `ȳ_t / x_true,t` over the texels (1 when the background is the light the
/// object sees in the model's units).
fn background_check(case: &Case) -> String {
    let bg = &case.train.background;
    let texels: usize = bg.iter().map(Vec::len).sum();
    let pixels: usize = bg.iter().flatten().map(|b| b.pixels as usize).sum();
    let lights = &case.train.lights;
    let ratios = over_background_texels(case, |i, b, c| {
        let t = lights[i][c][b.texel as usize];
        (t > 0.0).then(|| f64::from(b.mean[c]) / t)
    });
    let m = ratios.each_ref().map(|v| quantile(v, 0.5));
    format!(
        "{texels} texels, {pixels} pixels over {} photos; median background / true texel {:.3} / {:.3} / {:.3}",
        bg.len(),
        m[0],
        m[1],
        m[2]
    )
}

/// The fitted maps in the training backgrounds' texels: per channel the median of
/// `x_t / ȳ_t` and its quartiles over the median (the fit's normalisation rescales the
/// maps, so one scale per channel is free).
fn background_fit(case: &Case, lights: &[[Vec<f64>; 3]]) -> String {
    let r = over_background_texels(case, |i, b, c| {
        let y = f64::from(b.mean[c]);
        (y > 0.0).then(|| lights[i][c][b.texel as usize] / y)
    });
    let s = r.each_ref().map(|v| {
        let med = quantile(v, 0.5);
        (med, quantile(v, 0.25) / med, quantile(v, 0.75) / med)
    });
    format!(
        "x / ȳ median {:.3} / {:.3} / {:.3}, quartiles over the median R {:.2}–{:.2}, G {:.2}–{:.2}, B {:.2}–{:.2}",
        s[0].0, s[1].0, s[2].0, s[0].1, s[0].2, s[1].1, s[1].2, s[2].1, s[2].2
    )
}

/// Whether the row's fit knows the training photos' groups under one true sky: under
/// `ABLATION_DEFAULTS_LIGHT=shared`, or with `ABLATION_DEFAULTS_GROUPS=1`, where `run`'s
/// rule chooses the light as it does for photos whose EXIF capture times group them
/// (`--light auto` and `constrained` then fit the shared map as one more candidate). A
/// light forced to another model (`paper`, …) keeps no groups.
fn groups_given() -> bool {
    let light = std::env::var("ABLATION_DEFAULTS_LIGHT");
    match light.as_deref() {
        Ok("shared") => true,
        Ok("auto") | Err(_) => crate::env_flag("ABLATION_DEFAULTS_GROUPS"),
        Ok(_) => false,
    }
}

/// `run --smoothness` as the defaults' row gives it: `auto`, or with
/// `ABLATION_DEFAULTS_SMOOTHNESS` the weight it set in `base` (the pilot's and the fit's).
fn smoothness_flag(base: &EstimateOptions) -> relight_cpc::run::PriorStrength {
    if std::env::var("ABLATION_DEFAULTS_SMOOTHNESS").is_ok() {
        relight_cpc::run::PriorStrength::Fixed(base.smoothness)
    } else {
        relight_cpc::run::PriorStrength::Auto
    }
}

/// `run --achromatic-specular`: `auto` (the default) or `ABLATION_DEFAULTS_ACHROMATIC=on|off`.
fn achromatic() -> relight_cpc::run::Achromatic {
    let v = std::env::var("ABLATION_DEFAULTS_ACHROMATIC").unwrap_or_else(|_| "auto".into());
    relight_cpc::run::Achromatic::parse(&v).expect("ABLATION_DEFAULTS_ACHROMATIC")
}

/// The adaptive pilot with the inputs `run` gives it: it holds out its own observations,
/// and its lighting sample has the run's strata. Every lobe of the case's basis is kept,
/// whatever the pilot's shares, with `ABLATION_DEFAULTS_ALL_LOBES=1`.
fn run_pilot(case: &Case, base: &EstimateOptions, colours: Colours) -> PilotOutcome {
    let mut pilot = adapt::pilot(&PilotInput {
        normals_env: &case.normals_env,
        obs: &case.train.obs,
        env_from_world: &case.env_from_world,
        vis: &case.vis,
        basis: &case.basis,
        lambert: LAMBERT,
        normal_grid: case.sizes.normal_grid,
        global_resolution: case.sizes.global,
        keep: case.sizes.keep,
        estimate: EstimateOptions {
            validation_fraction: 0.0,
            // `run --smoothness auto`'s pilot weight by the training photos.
            smoothness: relight_cpc::run::pilot_smoothness_for(
                smoothness_flag(base),
                case.train.obs.photo_ranges.len(),
            )
            .0,
            lighting_strata: relight_cpc::solve::subsample::lighting_strata(
                &case.normals_env,
                &case.vis.open_fractions(),
            ),
            // As `run`: the pilot's colours free unless `on`.
            achromatic_specular: achromatic() == relight_cpc::run::Achromatic::On,
            ..base.clone()
        },
        mean_rgb: colours.mean_rgb,
        seen: colours.seen,
        materials: None,
        choose_weights_sum: true,
        start: relight_cpc::solve::matched::StartBrightness::Auto,
        max_vertices: adapt::PILOT_MAX_VERTICES,
        seed: 1,
    })
    .expect("adaptive pilot");
    if crate::env_flag("ABLATION_DEFAULTS_ALL_LOBES") {
        pilot.kept = (0..case.basis.len()).collect();
    }
    pilot
}

/// The k-means start with the pilot's count, its brightness matched by normal when the
/// pilot chose that start. `ABLATION_DEFAULTS_START=unmix-match`: the weights (and labels)
/// unmixed from the clustered colours before the brightness is matched, so that only
/// vertices the unmixing finds pure count there, then unmixed again over the matched
/// colours; `core`: each cluster's colour from its core ([`start_probes::core_colours`]).
fn clustered_start(case: &Case, pilot: &PilotOutcome, colours: Colours) -> InitialMaterials {
    let mut init = relight_cpc::solve::cluster::initial_materials(
        colours.mean_rgb,
        colours.seen,
        pilot.materials,
        1,
    )
    .expect("k-means start");
    if start_variant().as_deref() == Some("core") {
        start_probes::core_colours(&mut init, colours);
    }
    let unmix_match = start_variant().as_deref() == Some("unmix-match");
    if unmix_match {
        start_probes::unmix_initial(&mut init, colours);
    }
    if pilot.start == relight_cpc::solve::matched::StartBrightness::Matched {
        let open = case.vis.open_fractions();
        let obs = &case.train.obs;
        relight_cpc::solve::matched::match_start(&mut init, obs, &case.normals_env, &open, true);
    }
    if unmix_match {
        start_probes::unmix_initial(&mut init, colours);
    }
    init
}

/// `ABLATION_DEFAULTS_START`, the probe that replaces a part of the defaults' fit.
fn start_variant() -> Option<String> {
    std::env::var("ABLATION_DEFAULTS_START").ok()
}

/// The first fit's start over the kept lobes: the clustered start's, or with
/// `ABLATION_DEFAULTS_START=truth | truth-weights | truth-lambda` (when the pilot took the
/// true count) one of [`start_probes::truth_start`]'s; with `unmix`, each seen vertex's
/// weights unmixed from its mean colour over the start's colours ([`unmixed_weights`],
/// `--start-weights unmixed`); `unmix2`: over the best pair of materials only (a vertex
/// blends at most two). `ABLATION_START_RATIOS=1` prints the start's worst ratio errors.
fn start_materials(
    case: &Case,
    pilot: &PilotOutcome,
    init: &InitialMaterials,
    colours: Colours,
) -> Materials0 {
    let mut m0 = Materials0::from_initial(init, pilot.kept.len(), LAMBERT);
    let variant = start_variant();
    match variant.as_deref() {
        Some(v @ ("truth" | "truth-weights" | "truth-lambda"))
            if pilot.materials == case.lambda.len() =>
        {
            start_probes::truth_start(v, &mut m0, case, &pilot.kept)
        }
        Some("unmix") => m0.weights = unmixed_weights(init, colours.mean_rgb, colours.seen).0,
        Some("unmix2") => start_probes::unmix_pairs(&mut m0, colours),
        _ => {}
    }
    if let Some(x) = std::env::var("ABLATION_SPECULAR_START")
        .ok()
        .and_then(|v| v.parse().ok())
    {
        scale_specular(&mut m0, x);
    }
    if std::env::var("ABLATION_START_RATIOS").is_ok_and(|v| v == "1") {
        let lambda = full_lambda(case, &pilot.kept, &m0.lambda);
        eprintln!(
            "  the first fit's start: worst ratio per channel {:?}",
            crate::metrics::ratio_errors(case, &lambda, &m0.weights, colours.seen)
        );
    }
    m0
}

/// `ABLATION_PRIOR_SH_NOISE=η`, `ABLATION_PRIOR_HAAR_NOISE=η` (probes): the light prior's
/// relative noise levels in the row's fit, when its light model has the prior (`run`'s 0.3
/// and 0.03, `solve::light::choose::PRIOR_SH_NOISE`, `PRIOR_HAAR_NOISE`); a lower level
/// is a stronger prior.
fn with_prior_noise(mut opts: EstimateOptions) -> EstimateOptions {
    if let Some(lp) = opts.light_prior.as_mut() {
        lp.sh_noise = crate::env_or("ABLATION_PRIOR_SH_NOISE", lp.sh_noise);
        lp.haar_noise = crate::env_or("ABLATION_PRIOR_HAAR_NOISE", lp.haar_noise);
    }
    opts
}

/// The pilot's kept lobes (indices into the case's basis) and the vertices a training
/// photo sees, which the ratios are read over.
struct StartScope<'a> {
    kept: &'a [usize],
    seen: &'a [bool],
}

/// `ABLATION_DEFAULTS_START=stiff-spec` (a probe): the specular lobes' start from a fit under
/// the light prior with a stiff wavelet term (`--light prior`'s Haar L1 at relative noise
/// `ABLATION_STIFF_HAAR`, default 0.1 against the prior's 0.03), `ABLATION_STIFF_ITERS`
/// outer iterations (default 20) without early stopping; penalising the maps' detail
/// leaves more of each highlight to the lobes (`bench-results/targets-192.md` section 11).
/// `ABLATION_STIFF_TAKE=all` takes its whole `λ` and weights, else its specular lobes alone.
fn stiff_specular_start(
    case: &Case,
    problem: &Problem,
    mut m0: Materials0,
    opts: EstimateOptions,
    scope: StartScope,
) -> Materials0 {
    let mut stiff = light::candidate(case, opts, "prior");
    if let Some(lp) = stiff.light_prior.as_mut() {
        lp.haar_noise = crate::env_or("ABLATION_STIFF_HAAR", 0.1);
    }
    stiff.max_outer = crate::env_or("ABLATION_STIFF_ITERS", 20);
    stiff.validation_fraction = 0.0;
    stiff.ratio_steps = 0;
    let est = estimate(problem, m0.clone(), &stiff, &mut |_, _| {}).expect("stiff fit");
    let lambda = full_lambda(case, scope.kept, &est.lambda);
    eprintln!(
        "  stiff-light start: λ {:?}, worst ratio per channel {:?}",
        est.lambda,
        crate::metrics::ratio_errors(case, &lambda, &est.weights, scope.seen)
    );
    if std::env::var("ABLATION_STIFF_TAKE").is_ok_and(|v| v == "all") {
        return Materials0 {
            lambda: est.lambda,
            weights: est.weights,
        };
    }
    each_specular(&mut m0, |k, b, v| *v = est.lambda[k][b]);
    m0
}

/// `ABLATION_SPECULAR_START=X`: every lobe of the start but the Lambertian one at `X` times
/// its `λ` (the start the alternation keeps the specular strength near,
/// `bench-results/targets-192.md` section 11).
fn scale_specular(m0: &mut Materials0, x: f64) {
    each_specular(m0, |_, _, v| *v = v.map(|l| l * x));
}

/// `f(k, b, λ)` on every material `k`'s `λ` of each lobe `b` but the Lambertian one.
fn each_specular(m0: &mut Materials0, mut f: impl FnMut(usize, usize, &mut [f64; 3])) {
    for (k, row) in m0.lambda.iter_mut().enumerate() {
        for (b, v) in row.iter_mut().enumerate() {
            if b != LAMBERT {
                f(k, b, v);
            }
        }
    }
}

/// The full fit's options: the pilot's choices, `run`'s cap, tolerance and patience (or
/// with `ABLATION_DEFAULTS_ITERS=bench` the bench's cap and tolerance,
/// `ABLATION_DEFAULTS_PATIENCE=N` `run --patience N`; `ABLATION_DEFAULTS_VALIDATION=0`: no
/// observations held back, so no early stopping and the last iterate kept), the ratio step as `run --ratio-steps
/// auto` (`ABLATION_RATIO_STEPS=N`: `--ratio-steps N`), the neighbour prior as `run
/// --weights-smoothness auto` (`ABLATION_DEFAULTS_NEIGHBOUR=X`: `--weights-smoothness X`),
/// the maps' Laplacian weight as `run --smoothness auto` (raised with a shiny lobe and two
/// materials at 32² maps from 20 training photos; `ABLATION_DEFAULTS_SMOOTHNESS=X` gives it,
/// `ABLATION_DEFAULTS_FIT_SMOOTHNESS=X` the fit's weight alone).
/// `ABLATION_DEFAULTS_SCOPE=blends|every`: the sum-to-one prior on blended vertices, or on
/// every vertex, whatever the pilot's scope (`ABLATION_DEFAULTS_WEIGHTS_SUM=X`: at strength `X` whatever the
/// pilot's); `ABLATION_DEFAULTS_LIGHT=shared`: `run --light shared` with one map per
/// group of training photos under one true sky, with per-photo gains
/// (`SYNTH_SHARED_SKIES=1` makes such groups); `ABLATION_DEFAULTS_GROUPS=1`: those groups
/// known to `run`'s choice of light ([`groups_given`]). The specular lobes' colour as `run
/// --achromatic-specular auto` ([`achromatic`]; `ABLATION_DEFAULTS_ACHROMATIC=on|off`).
/// `ABLATION_DEFAULTS_MAX_ITERS=N`: `run --iterations N` (the cap on outer rounds).
fn fit_options(case: &Case, base: &EstimateOptions, pilot: &PilotOutcome) -> EstimateOptions {
    let (max_outer, rel_tol) =
        if std::env::var("ABLATION_DEFAULTS_ITERS").is_ok_and(|v| v == "bench") {
            (base.max_outer, base.rel_tol)
        } else {
            (
                crate::env_or(
                    "ABLATION_DEFAULTS_MAX_ITERS",
                    RunOptions::DEFAULT_MAX_ITERATIONS,
                ),
                RunOptions::DEFAULT_REL_TOL,
            )
        };
    let kept: Vec<_> = pilot.kept.iter().map(|&b| case.basis[b]).collect();
    let neighbour_prior = adapt::neighbour_prior_for(&kept).0;
    let scope = std::env::var("ABLATION_DEFAULTS_SCOPE").unwrap_or_default();
    let default_rounds =
        ratio_step::default_rounds(case.train.obs.photo_ranges.len(), pilot.materials);
    let varpro = relight_cpc::run::VarproSteps::Auto.plan(
        case.train.obs.photo_ranges.len(),
        pilot.materials,
        &kept,
    );
    let opts = EstimateOptions {
        weights_sum: crate::env_or("ABLATION_DEFAULTS_WEIGHTS_SUM", pilot.weights_sum),
        weights_sum_scope: match scope.as_str() {
            "blends" => relight_cpc::solve::SumScope::Blends {
                floor: relight_cpc::solve::BLEND_FLOOR,
            },
            "every" => relight_cpc::solve::SumScope::Every,
            _ => pilot.weights_sum_scope,
        },
        max_outer,
        patience: crate::env_or("ABLATION_DEFAULTS_PATIENCE", RunOptions::DEFAULT_PATIENCE),
        validation_fraction: crate::env_or(
            "ABLATION_DEFAULTS_VALIDATION",
            base.validation_fraction,
        ),
        rel_tol,
        ratio_steps: crate::env_or("ABLATION_RATIO_STEPS", default_rounds),
        // `run --varpro-steps auto` by the training photos, the pilot's count and lobes;
        // `ABLATION_VARPRO_STEPS=N` takes N rounds (forward differences, or Broyden's
        // update after the first round with `ABLATION_VARPRO_BROYDEN=1`).
        varpro_steps: crate::env_or("ABLATION_VARPRO_STEPS", varpro.rounds),
        prune_round: crate::env_or("ABLATION_PRUNE_ROUND", 0),
        varpro_broyden: crate::env_or("ABLATION_VARPRO_BROYDEN", u8::from(varpro.broyden)) == 1,
        varpro_refresh: crate::env_or("ABLATION_VARPRO_REFRESH", 0),
        weights_smoothness: crate::env_or("ABLATION_DEFAULTS_NEIGHBOUR", neighbour_prior),
        // `run --weights-bic auto` by the training photos, the pilot's count and lobes, or
        // `ABLATION_DEFAULTS_WEIGHTS_BIC=X` (`--weights-bic X`).
        weights_bic: crate::env_or(
            "ABLATION_DEFAULTS_WEIGHTS_BIC",
            relight_cpc::run::weights_bic_for(
                relight_cpc::run::PriorStrength::Auto,
                case.train.obs.photo_ranges.len(),
                pilot.materials,
                &kept,
            )
            .0,
        ),
        // `run --smoothness auto` by the training photos, materials and map side;
        // `ABLATION_DEFAULTS_FIT_SMOOTHNESS=X` sets the fit's weight alone (the pilot's
        // stays `run`'s).
        smoothness: crate::env_or(
            "ABLATION_DEFAULTS_FIT_SMOOTHNESS",
            relight_cpc::run::smoothness_for(
                smoothness_flag(base),
                case.train.obs.photo_ranges.len(),
                pilot.materials,
                case.sizes.global,
                &kept,
            )
            .0,
        ),
        light_groups: groups_given().then(|| case.true_light_groups()),
        achromatic_specular: relight_cpc::run::achromatic_for(achromatic(), pilot.materials, &kept)
            .0,
        ..base.clone()
    };
    crate::with_case_graph(case, opts)
}

/// The first fit from `m0`, or with `ABLATION_DEFAULTS_START=grid | grid-unmix` (up to three
/// materials) the best of [`start_probes::grid_start_fit`]'s (`ABLATION_GRID_JUDGE=halves`:
/// judged on the right halves of 4 training photos, as `--light auto` judges its models).
/// `trace` sees every round of the fit from `m0` (the grid's fits are not traced);
/// `stiff-weights`: [`stiff_weights_fit`].
fn first_fit(
    problem: &Problem,
    m0: Materials0,
    opts: &EstimateOptions,
    judge: Option<&EstimateOptions>,
    init: &InitialMaterials,
    colours: Colours,
    trace: &mut dyn FnMut(&Iteration, &IterState),
) -> Estimate {
    match start_variant().as_deref() {
        Some(v @ ("grid" | "grid-unmix")) if m0.lambda.len() <= 3 => {
            let unmix = (v == "grid-unmix").then_some(start_probes::UnmixFrom { init, colours });
            start_probes::grid_start_fit(problem, &m0, opts, judge, LAMBERT, unmix)
        }
        Some("stiff-weights") => stiff_weights_fit(problem, m0, opts, trace),
        _ => estimate(problem, m0, opts, trace).expect("defaults' fit"),
    }
}

/// `ABLATION_DEFAULTS_START=stiff-weights` (a probe): a fit with the blending weights'
/// priors (sum-to-one and neighbour) `ABLATION_STIFF_WEIGHTS` times as strong (default
/// 10), then the fit under `opts` from its materials and lights: the weights held near
/// one-hot, smooth blends while the lights are still poor (a continuation on the weights'
/// priors). `trace` sees the second fit's rounds.
fn stiff_weights_fit(
    problem: &Problem,
    m0: Materials0,
    opts: &EstimateOptions,
    trace: &mut dyn FnMut(&Iteration, &IterState),
) -> Estimate {
    let s = crate::env_or("ABLATION_STIFF_WEIGHTS", 10.0);
    let stiff = EstimateOptions {
        weights_sum: opts.weights_sum * s,
        weights_smoothness: opts.weights_smoothness * s,
        ..opts.clone()
    };
    let pre = estimate(problem, m0, &stiff, &mut |_, _| {}).expect("stiff-weights fit");
    eprintln!(
        "  stiff-weights fit ({s}×): {} rounds, λ {:?}",
        pre.timeline.len(),
        pre.lambda
    );
    let m = Materials0 {
        lambda: pre.lambda,
        weights: pre.weights,
    };
    relight_cpc::solve::alternation::estimate_from_lights(problem, m, opts, &pre.lights, trace)
        .expect("defaults' fit after the stiff one")
}

/// `ABLATION_DEFAULTS_STOP_HALVES=N`: the fit's early stopping scored on the right halves
/// of `N` training photos held back whole (`run --validation-halves N`) after the light
/// model and the loss were chosen as `run` chooses them.
fn with_stop_halves(case: &Case, opts: EstimateOptions) -> EstimateOptions {
    match crate::env_or("ABLATION_DEFAULTS_STOP_HALVES", 0usize) {
        0 => opts,
        n => EstimateOptions {
            validation_halves: light::choice_halves(case, n),
            ..opts
        },
    }
}

/// `ABLATION_TRACE=1`: a callback that prints each outer iterate's early-stopping score,
/// training RMSE, worst diffuse albedo ratio error (over materials and channels) and
/// material accuracy under `label` (`ABLATION_TRACE=signed`: also each material's signed
/// ratio error per channel); otherwise one that does nothing. The trace is how the
/// stopping point's effect on the ratios is read (`bench-results/iteration-trace.md`).
pub(super) fn tracer<'a>(
    case: &'a Case,
    kept: &'a [usize],
    seen: &'a [bool],
    label: &'a str,
) -> impl FnMut(&Iteration, &IterState) + 'a {
    let trace = std::env::var("ABLATION_TRACE").unwrap_or_default();
    let (on, signed) = (trace == "1" || trace == "signed", trace == "signed");
    move |it, state| {
        if !on {
            return;
        }
        let full = full_lambda(case, kept, state.lambda);
        let r = crate::metrics::ratio_errors(case, &full, state.weights, seen);
        let (acc, _, _) = crate::metrics::best_order_of(case, state.weights, seen);
        eprintln!(
            "  trace {label}: validation {:.6} train {:.6} worst ratio {:.4} accuracy {acc:.4}",
            it.validation_rel.unwrap_or(f64::NAN),
            it.train_rmse,
            r.iter().fold(0.0f64, |a, &b| a.max(b))
        );
        if signed {
            let s = crate::metrics::signed_ratio_errors(case, &full, state.weights, seen);
            eprintln!("  trace {label}: signed ratio errors (material 1.., R G B) {s:.4?}");
        }
    }
}

/// Every material's `λ` over the kept bases (`kept[i]`: index of the `i`-th in the case's
/// list) laid out over all the case's bases ([`full_basis`] per material).
pub(super) fn full_lambda(
    case: &Case,
    kept: &[usize],
    lambda: &[Vec<[f64; 3]>],
) -> Vec<Vec<[f64; 3]>> {
    let n = case.basis.len();
    lambda.iter().map(|row| full_basis(row, kept, n)).collect()
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
