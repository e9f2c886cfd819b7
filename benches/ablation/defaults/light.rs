//! The defaults row's light model as `run` without `--light` chooses it
//! ([`relight_cpc::run::scene_light`]): below 50K vertices, when the pilot keeps a shiny
//! lobe, `--light auto` ([`choose::candidates`]: the paper's map, the map under the prior of
//! real skies, the sun and sky; `--light constrained`, without the paper's map, with
//! [`relight_cpc::run::CONSTRAINED_FROM_MATERIALS`] or more materials from
//! [`relight_cpc::run::PRIOR_FROM_PHOTOS`] training photos) fits
//! each candidate from the start with the right halves of
//! [`DEFAULT_LIGHT_CHOICE_HALVES`] training photos held back ([`photo_halves`], the split
//! `run` makes), keeps the one of lowest validation error on them ([`choose::decide`]), and
//! the row's fit then runs with its options and early stopping's own held-back
//! observations, as `run` fits the kept model again. Over the Lambertian lobe alone the
//! paper's map, or the prior of real skies with two or more materials from
//! [`relight_cpc::run::PRIOR_FROM_PHOTOS`] training photos. `ABLATION_DEFAULTS_LIGHT=paper` (or `shared`) keeps the row's light as
//! given, the row before `run` chose by scene (`prior` or `sky`: that candidate of
//! `--light auto`, forced; `auto`: `--light auto` whatever the lobes);
//! `ABLATION_LIGHT_HALVES=k` scores on `k` photos' halves (`run --light-choice-halves k`).

use crate::synth_case::Case;
use relight_cpc::run::{
    photo_halves, scene_light, FitShape, RunOptions, DEFAULT_LIGHT_CHOICE_HALVES,
};
use relight_cpc::solve::adapt::PilotOutcome;
use relight_cpc::solve::light::choose::{self, LightChoice};
use relight_cpc::solve::{estimate, EstimateOptions, Materials0, Problem};

/// The light model chosen and why, for the table's notes.
pub struct ChosenLight {
    pub options: EstimateOptions,
    pub note: String,
    /// The kept model's validation score on the choice's photo halves, when it was chosen
    /// on them (the robust loss's score for [`super::loss`]).
    pub robust_score: Option<f64>,
}

/// The row's light model for `opts` (the pilot's choices under the paper's map) from the
/// start `m0`: as given when `ABLATION_DEFAULTS_LIGHT` is set, else `run`'s rule.
pub fn by_scene(
    case: &Case,
    problem: &Problem,
    m0: &Materials0,
    opts: EstimateOptions,
    pilot: &PilotOutcome,
) -> ChosenLight {
    let given = std::env::var("ABLATION_DEFAULTS_LIGHT").ok();
    let forced_auto = given.as_deref() == Some("auto");
    if let Some(given) = given.filter(|g| g != "auto") {
        let note = format!("light `{given}` (ABLATION_DEFAULTS_LIGHT)");
        let options = match given.as_str() {
            "prior" | "sky" => candidate(case, opts, &given),
            "oracle-sh" => oracle_sh(case, candidate(case, opts, "prior")),
            _ => opts,
        };
        return ChosenLight {
            options,
            note,
            robust_score: None,
        };
    }
    match (run_rule(case, pilot), forced_auto) {
        (_, true) => chosen_on_halves(case, problem, m0, opts, LightChoice::Auto),
        (Some(c), _) if c.chooses() => chosen_on_halves(case, problem, m0, opts, c),
        (Some(LightChoice::Prior), _) => ChosenLight {
            options: candidate(case, opts, "prior"),
            note: "light `prior` (run's rule: the Lambertian lobe alone, two or more materials and many photos)".to_string(),
            robust_score: None,
        },
        _ => ChosenLight {
            options: opts,
            note: "light `paper` (run's rule: the Lambertian lobe alone)".to_string(),
            robust_score: None,
        },
    }
}

/// The light model `run` without `--light` takes for the case's fit with the pilot's
/// choices ([`scene_light`]).
fn run_rule(case: &Case, pilot: &PilotOutcome) -> Option<LightChoice> {
    let kept: Vec<_> = pilot.kept.iter().map(|&b| case.basis[b]).collect();
    let mut run = RunOptions::new("ws".into(), "out".into());
    run.light_by_scene = true;
    let shape = FitShape {
        vertices: case.nv,
        basis: &kept,
        photos: case.train.obs.photo_ranges.len(),
        // `run` counts the materials its start clusters; on these coloured scenes the
        // clustering finds every material the pilot chose.
        materials: Some(pilot.materials),
    };
    scene_light(&run, shape).map(|(light, _)| light)
}

/// `--light auto`: each candidate fitted from `m0` with the right halves of
/// `ABLATION_LIGHT_HALVES` training photos held back, the lowest validation error kept.
fn chosen_on_halves(
    case: &Case,
    problem: &Problem,
    m0: &Materials0,
    opts: EstimateOptions,
    choice: LightChoice,
) -> ChosenLight {
    let k = crate::env_or("ABLATION_LIGHT_HALVES", DEFAULT_LIGHT_CHOICE_HALVES);
    let halves = choice_halves(case, k);
    let candidates = candidates(case, opts, choice);
    let scores: Vec<f64> = candidates
        .iter()
        .map(|c| {
            let scored = EstimateOptions {
                validation_halves: halves.clone(),
                ..c.options.clone()
            };
            let est = estimate(problem, m0.clone(), &scored, &mut |_, _| {}).expect("light fit");
            est.validation_error()
        })
        .collect();
    let names: Vec<&str> = candidates.iter().map(|c| c.name).collect();
    let (pick, decision) = choose::decide(choice, &names, &scores);
    let scored: Vec<String> = names
        .iter()
        .zip(&scores)
        .map(|(n, s)| format!("{n} {s:.4e}"))
        .collect();
    ChosenLight {
        options: candidates[pick].options.clone(),
        note: format!(
            "light `{}` by run's rule (--light {} on the right halves of {} photos: {})",
            decision.model,
            choice.name(),
            k,
            scored.join(", ")
        ),
        // The loss choice scores on the same halves ([`super::loss`]).
        robust_score: Some(scores[pick]),
    }
}

/// `ABLATION_DEFAULTS_LIGHT=oracle-sh` (a probe, not a model a collection can have): the
/// prior's candidate with each training photo's SH shape prior centred on its TRUE map's
/// shape (orders 1–2 over order 0, per channel, so exposure and white balance stay free)
/// and its precision `ABLATION_ORACLE_FACTOR` (default 100) times the real skies'. What
/// the fit's ratios would be if the maps' low-order shape were known.
fn oracle_sh(case: &Case, mut opts: EstimateOptions) -> EstimateOptions {
    use relight_cpc::run::half_prior::map_shape;
    use relight_cpc::solve::light::sh_prior::ShProjection;
    let lp = opts
        .light_prior
        .clone()
        .expect("the prior candidate's prior");
    let base = lp.stats[0].clone();
    let factor: f64 = crate::env_or("ABLATION_ORACLE_FACTOR", 100.0);
    let proj = ShProjection::new(case.sizes.global, 4);
    let stats: Vec<_> = case
        .train
        .lights
        .iter()
        .map(|l| {
            let mut p = base.clone();
            p.shape_mean = map_shape(l, &proj).expect("a lit true map").to_vec();
            p.shape_precision = base.shape_precision.iter().map(|v| v * factor).collect();
            p
        })
        .collect();
    let n = stats.len();
    opts.light_prior = Some(relight_cpc::solve::light::sh_prior::LightPriorOptions {
        stats: std::sync::Arc::new(stats),
        per_photo: Some((0..n).collect()),
        ..lp
    });
    opts
}

/// The options of `--light auto`'s candidate `name` (`prior`, `sky`) for `opts`.
pub(super) fn candidate(case: &Case, opts: EstimateOptions, name: &str) -> EstimateOptions {
    candidates(case, opts, LightChoice::Auto)
        .into_iter()
        .find(|c| c.name == name)
        .expect("a candidate of --light auto")
        .options
}

/// The candidate models of `choice` for `opts`, with the case's geotagged suns as `run`
/// reads them.
fn candidates(
    case: &Case,
    opts: EstimateOptions,
    choice: LightChoice,
) -> Vec<choose::LightCandidate> {
    let base = EstimateOptions {
        sun_clock: case.geotag_suns.clone(),
        ..opts
    };
    choose::candidates(choice, &base).expect("light candidates")
}

/// The right halves of `k` training photos held back whole, the split `run` scores
/// `--light auto` on ([`photo_halves`]).
pub fn choice_halves(
    case: &Case,
    k: usize,
) -> Option<std::sync::Arc<relight_cpc::solve::options::PhotoHalves>> {
    let views: Vec<_> = case.train.views.iter().collect();
    photo_halves(&views, &case.positions, &case.train.obs, k)
}
