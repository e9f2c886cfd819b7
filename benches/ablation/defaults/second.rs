//! Second fits from the defaults' first fit (`ABLATION_DEFAULTS_START=…`, the probes of
//! `bench-results/restart-probes.md`, `irradiance-start.md` and `coarse-light-start.md`),
//! and the second fits `run --restart auto` makes, which the `defaults` row applies.

use super::{full_lambda, start_variant, LAMBERT};
use crate::synth_case::*;
use relight_cpc::run::Restart;
use relight_cpc::solve::alternation::estimate_from_lights;
use relight_cpc::solve::materials::coarse_light;
use relight_cpc::solve::materials::reanchor::{fit_in_turn, reanchor, Reweight, StepOutcome};
use relight_cpc::solve::{estimate, Estimate, EstimateOptions, Materials0, Problem};

/// A first fit with what [`second_fit`] reads of it.
pub(super) struct Fitted<'a> {
    pub est: Estimate,
    /// The case's bases the pilot kept.
    pub kept: &'a [usize],
    /// Whether a training photo sees each vertex.
    pub seen: &'a [bool],
}

/// What every second fit works on: the first fit's problem and options, and the case.
#[derive(Clone, Copy)]
pub(super) struct Probe<'a> {
    pub problem: &'a Problem<'a>,
    pub opts: &'a EstimateOptions,
    pub case: &'a Case,
}

impl Fitted<'_> {
    /// The worst diffuse albedo ratio error per channel of materials `lambda` with weights
    /// `weights` over the kept lobes ([`crate::metrics::ratio_errors`]).
    fn ratios_of(&self, case: &Case, lambda: &[Vec<[f64; 3]>], weights: &[f64]) -> [f64; 3] {
        let full = full_lambda(case, self.kept, lambda);
        crate::metrics::ratio_errors(case, &full, weights, self.seen)
    }

    fn ratios(&self, case: &Case, e: &Estimate) -> [f64; 3] {
        self.ratios_of(case, &e.lambda, &e.weights)
    }

    /// Prints a probe's start's worst ratio beside the first fit's.
    fn print_start(&self, case: &Case, name: &str, m: &Materials0) {
        eprintln!(
            "{name} start: worst ratio {:.3?} (first fit {:.3?})",
            self.ratios_of(case, &m.lambda, &m.weights),
            self.ratios(case, &self.est)
        );
    }
}

/// The probes [`second_fit`] makes, by their `ABLATION_DEFAULTS_START` value.
const SECOND_FITS: &[&str] = &[
    "refit",
    "refit-w",
    "reanchor",
    "reanchor2",
    "reanchor-lambert",
    "reanchor-label",
    "reanchor-label2",
    "reanchor-label-truth-lambda",
    "reanchor-label-truth-weights",
    "reanchor-label-truth-diffuse",
    "reanchor-project-truth-lambda",
    "sh-ratio",
    "sh-ratio2",
    "coarse-light",
    "coarse-light-free",
    "truth-held",
];

/// The second fits after the first: with `ABLATION_DEFAULTS_START=v` one of the probes
/// ([`second_fit`], kept whatever its score unless `ABLATION_REFIT_PICK=1`; `reanchor-coarse`:
/// `run --restart on+coarse-light`); without one, as `run --restart auto`
/// ([`auto_restart`]).
pub(super) fn second_fits(p: Probe, first: Fitted, materials: usize) -> Estimate {
    match start_variant().as_deref() {
        Some(v) if SECOND_FITS.contains(&v) => {
            second_fit(p, v, first, crate::env_flag("ABLATION_REFIT_PICK"))
        }
        Some("reanchor-coarse") => restarts(p, Restart::ReanchorCoarseLight, first),
        _ => {
            let kept: Vec<_> = first.kept.iter().map(|&b| p.case.basis[b]).collect();
            restarts(p, auto_restart(&kept, materials), first)
        }
    }
}

/// The second fit of `ABLATION_DEFAULTS_START=v` from `first` (`reanchor`:
/// [`reanchor`] with projected weights, `reanchor2` twice, `reanchor-lambert` with
/// [`keep_gloss`]; `refit`, `refit-w`: [`refit`]; `truth-held`, `coarse-light`,
/// `coarse-light-free`, `sh-ratio`, `sh-ratio2`: the functions of those names), returned
/// whatever its score unless `pick`, which keeps the fit with the lower validation error as
/// `run --restart` does. Prints both fits' worst ratio errors and validation errors.
fn second_fit(p: Probe, v: &str, first: Fitted, pick: bool) -> Estimate {
    let second = match v {
        "truth-held" => truth_held_fit(p, &first),
        "coarse-light" if pick => coarse_light_restart(p, &first),
        "coarse-light" | "coarse-light-free" => coarse_light_fit(p, v, &first),
        "sh-ratio" | "sh-ratio2" => sh_ratio_fit(p, v, &first),
        v if v.starts_with("reanchor") => reanchor_fit(p, v, &first),
        _ => refit(p.problem, &first.est, p.opts, p.case, LAMBERT, v == "refit"),
    };
    let score = |e: &Estimate| e.validation.as_ref().map(|v| v.best_error());
    eprintln!(
        "second fit {v}: worst ratio {:.3?} -> {:.3?}; validation {:?} -> {:?}; objective {:.6e} -> {:.6e}",
        first.ratios(p.case, &first.est),
        first.ratios(p.case, &second),
        score(&first.est),
        score(&second),
        returned_objective(&first.est),
        returned_objective(&second)
    );
    // `coarse-light` with `pick` chose inside `fit_in_turn`, as `run` does (the held fit
    // also within one standard error of the first).
    let chosen = pick && v == "coarse-light";
    if !pick || chosen || score(&second) < score(&first.est) {
        second
    } else {
        first.est
    }
}

/// The objective at the iterate a fit returns (the validation's best one, else the last).
fn returned_objective(e: &Estimate) -> f64 {
    e.timeline
        .get(e.kept_iteration().wrapping_sub(1))
        .map_or(f64::NAN, |it| it.objective)
}

/// `truth-held`: the lights fitted again with [`truth_held_start`]'s materials held.
fn truth_held_fit(p: Probe, first: &Fitted) -> Estimate {
    let m = truth_held_start(&first.est, p.case, first.seen, first.kept, LAMBERT);
    first.print_start(p.case, "truth-held", &m);
    let held = coarse_light::held_fit_options(p.opts);
    estimate_from_lights(p.problem, m, &held, &first.est.lights, &mut |_, _| {}).expect("held fit")
}

/// `coarse-light` with `pick`, as `run --restart coarse-light`: the library's starts (two
/// over the Lambertian lobe alone, the tied one over a shiny basis), fitted in turn with
/// the materials held, each kept when its validation error is lower
/// ([`fit_in_turn`]; `ABLATION_COARSE_WEIGHTS=fit`: the first alone).
fn coarse_light_restart(p: Probe, first: &Fitted) -> Estimate {
    let est = &first.est;
    let mut steps =
        coarse_light::restart_starts(p.problem, &est.lambda, &est.weights, first.seen, LAMBERT)
            .expect("the first fit's sizes");
    if std::env::var("ABLATION_COARSE_WEIGHTS").is_ok_and(|w| w == "fit") {
        steps.truncate(1);
    }
    // `ABLATION_ONE_SE=0`: each held fit kept on the lower validation error alone, as
    // before the one-standard-error rule (`bench-results/one-standard-error.md`).
    if std::env::var("ABLATION_ONE_SE").is_ok_and(|v| v == "0") {
        for s in &mut steps {
            s.keep = relight_cpc::solve::materials::reanchor::Keep::Lower;
        }
    }
    let held = coarse_light::held_fit_options(p.opts);
    let (kept, outcomes) =
        fit_in_turn(p.problem, est.clone(), steps, &held, &mut |_, _, _| {}).expect("second fit");
    for o in &outcomes {
        match o {
            StepOutcome::Fitted {
                scores,
                kept_restart,
                paired,
                ..
            } => eprintln!(
                "coarse-light held fit: validation {:.5} against {:.5}, kept {kept_restart}{}",
                scores[1],
                scores[0],
                paired.map_or(String::new(), |q| format!(
                    " (paired: {:.2} standard errors above)",
                    q.difference / q.standard_error
                ))
            ),
            StepOutcome::Skipped { before, .. } => {
                eprintln!("coarse-light held fit skipped ({before:.5?})")
            }
        }
    }
    kept
}

/// `coarse-light` (without `pick`): the first held fit whatever its score, from the
/// Lambertian model's start whatever the basis (section 3's `coarse-held` probe);
/// `coarse-light-free`: a free fit from that start.
fn coarse_light_fit(p: Probe, v: &str, first: &Fitted) -> Estimate {
    let starts = coarse_light_starts(&first.est, p.case, first.seen, LAMBERT);
    first.print_start(p.case, "coarse-light", &starts.fit_weights);
    let m = starts.fit_weights;
    if v == "coarse-light" {
        let held = coarse_light::held_fit_options(p.opts);
        let lights = &first.est.lights;
        let mut trace = super::tracer(p.case, first.kept, first.seen, "coarse-light");
        estimate_from_lights(p.problem, m, &held, lights, &mut trace).expect("second fit")
    } else {
        estimate(p.problem, m, p.opts, &mut |_, _| {}).expect("second fit")
    }
}

/// `sh-ratio`: a fit from [`sh_ratio_start`] (with `ABLATION_SH_TRUTH` first
/// [`super::diagnosis::sh_truth_diagnosis`]); `sh-ratio2`: the model read again from that
/// fit's weights, a third fit.
fn sh_ratio_fit(p: Probe, v: &str, first: &Fitted) -> Estimate {
    let m = sh_ratio_start(&first.est, p.case, first.seen, LAMBERT);
    if std::env::var("ABLATION_SH_TRUTH").is_ok() {
        let fits = (&first.est, &m);
        super::diagnosis::sh_truth_diagnosis(p.case, fits, first.seen, first.kept, LAMBERT);
        if std::env::var("ABLATION_SH_TRUTH").is_ok_and(|v| v == "only") {
            std::process::exit(0);
        }
    }
    first.print_start(p.case, "sh-ratio", &m);
    let mut trace = super::tracer(p.case, first.kept, first.seen, "sh-ratio");
    let mut second = estimate(p.problem, m, p.opts, &mut trace).expect("second fit");
    if v == "sh-ratio2" {
        let ratios = first.ratios(p.case, &second);
        eprintln!("sh-ratio2: second fit's worst ratio {ratios:.3?}");
        let m = sh_ratio_start(&second, p.case, first.seen, LAMBERT);
        second = estimate(p.problem, m, p.opts, &mut |_, _| {}).expect("third fit");
    }
    second
}

/// `reanchor`: a fit from the first fit's materials re-anchored ([`reanchor`], projected
/// weights); `reanchor2` twice; `reanchor-lambert` with [`keep_gloss`]; `reanchor-label`
/// with one-hot weights on each vertex's label ([`Reweight::Label`]), `reanchor-label2`
/// twice; `reanchor-label-truth-lambda | -truth-weights` with half of it the truth
/// ([`super::start_probes::truth_start`]), `reanchor-label-truth-diffuse` with the true
/// Lambertian lobes and the re-anchored shiny ones.
fn reanchor_fit(p: Probe, v: &str, first: &Fitted) -> Estimate {
    let mut from = first.est.clone();
    let rounds = if v.ends_with('2') { 2 } else { 1 };
    for round in 0..rounds {
        let m = reanchor_start(p, v, first, &from);
        let mut trace = super::tracer(p.case, first.kept, first.seen, "reanchor");
        from = estimate(p.problem, m, p.opts, &mut trace).expect("second fit");
        if round + 1 < rounds {
            eprintln!(
                "{v}, round {}: worst ratio {:.3?}, objective {:.6e}",
                round + 1,
                first.ratios(p.case, &from),
                returned_objective(&from)
            );
        }
    }
    from
}

/// The start of [`reanchor_fit`]'s probe `v` from the fit `from` (printed beside the first
/// fit's ratios, but for plain `reanchor`).
fn reanchor_start(p: Probe, v: &str, first: &Fitted, from: &Estimate) -> Materials0 {
    if v == "reanchor-project-truth-lambda" {
        let m = truth_lambda_projected(from, p.case, first);
        first.print_start(p.case, v, &m);
        return m;
    }
    let how = if v.starts_with("reanchor-label") {
        Reweight::Label
    } else {
        Reweight::Project
    };
    let mut m = reanchor(&from.lambda, &from.weights, first.seen, how).expect("re-anchoring");
    if v == "reanchor-lambert" {
        keep_gloss(&mut m.lambda, &from.lambda, LAMBERT);
    }
    with_half_truth(v, &mut m, p.case, first.kept);
    if v != "reanchor" {
        first.print_start(p.case, v, &m);
    }
    m
}

/// `reanchor-label-truth-{lambda,weights,diffuse}`: the re-anchored start `m` with the true
/// `λ`, the true weights, or the true Lambertian lobes (the shiny ones re-anchored).
fn with_half_truth(v: &str, m: &mut Materials0, case: &Case, kept: &[usize]) {
    let Some(half) = v.strip_prefix("reanchor-label-") else {
        return;
    };
    let shiny = m.lambda.clone();
    let variant = if half == "truth-diffuse" {
        "truth-lambda"
    } else {
        half
    };
    super::start_probes::truth_start(variant, m, case, kept);
    if half == "truth-diffuse" {
        for (row, fit) in m.lambda.iter_mut().zip(&shiny) {
            for (b, v) in row.iter_mut().enumerate() {
                if b != LAMBERT {
                    *v = fit[b];
                }
            }
        }
    }
}

/// `reanchor-project-truth-lambda`: the true `λ` (in the fit's order, scaled per channel into
/// the fit's gauge by least squares over the seen vertices' Lambertian reflectance) with the
/// fit's reflectance projected on it as the weights ([`projected_on`]).
fn truth_lambda_projected(fit: &Estimate, case: &Case, first: &Fitted) -> Materials0 {
    use relight_cpc::solve::beta_per_vertex;
    use relight_cpc::solve::materials::reanchor::projected_on;
    let mut truth = Materials0 {
        lambda: fit.lambda.clone(),
        weights: fit.weights.clone(),
    };
    super::start_probes::truth_start("truth", &mut truth, case, first.kept);
    let nb = truth.lambda[0].len();
    let beta_true = beta_per_vertex(&truth.lambda, &truth.weights, case.nv);
    let beta_fit = beta_per_vertex(&fit.lambda, &fit.weights, case.nv);
    let mut gauge = [0.0; 3];
    for c in 0..3 {
        let (mut num, mut den) = (0.0, 0.0);
        for x in (0..case.nv).filter(|&x| first.seen[x]) {
            let (f, t) = (
                beta_fit[x * nb + LAMBERT][c],
                beta_true[x * nb + LAMBERT][c],
            );
            num += f * t;
            den += t * t;
        }
        gauge[c] = if den > 0.0 { num / den } else { 1.0 };
    }
    let mut onto = Materials0 {
        lambda: fit.lambda.clone(),
        weights: fit.weights.clone(),
    };
    super::start_probes::truth_start("truth-lambda", &mut onto, case, first.kept);
    for v in onto.lambda.iter_mut().flatten() {
        *v = [v[0] * gauge[0], v[1] * gauge[1], v[2] * gauge[2]];
    }
    eprintln!("  truth-lambda projected: the fit's gauge against the truth's {gauge:.3?}");
    let weights =
        projected_on(&onto.lambda, &fit.lambda, &fit.weights, first.seen).expect("projection");
    Materials0 {
        lambda: onto.lambda,
        weights,
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
fn restarts(p: Probe, mode: Restart, first: Fitted) -> Estimate {
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
        est = second_fit(p, v, from, true);
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
    let t = &case.train.transport;
    let blocks = coarse_light::BLOCKS.min(t.n_global);
    let input = super::mixture::rows_input(&case.train.obs, t, (seen, &weights, kk), blocks);
    let rows = relight_cpc::solve::materials::coarse_light_blend::seen_blend_rows(&input);
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
