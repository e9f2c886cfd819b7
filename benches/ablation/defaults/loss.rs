//! The defaults row's data loss as `run --loss auto` chooses it
//! ([`relight_cpc::solve::loss_choice`]): below 50K vertices, the light model kept is
//! fitted from the start with the robust loss and with plain least squares, each with the
//! right halves of [`DEFAULT_LIGHT_CHOICE_HALVES`] training photos held back (the light
//! choice's split), and the lower validation score is kept; the row's fit then runs with
//! early stopping's own held-back observations, as `run` fits the kept loss again. Under
//! the sun and sky the robust loss stays without the second fit, as in `run`
//! ([`relight_cpc::solve::loss_choice::loss_acts`]).
//! `ABLATION_DEFAULTS_LOSS=robust|plain` keeps that loss, as `run --loss robust|plain`;
//! `ABLATION_LIGHT_HALVES=k` scores on `k` photos' halves, as `run --light-choice-halves k`
//! sets both choices' split.

use super::light::{choice_halves, ChosenLight};
use crate::synth_case::Case;
use relight_cpc::run::{LargeMeshSettings, DEFAULT_LIGHT_CHOICE_HALVES};
use relight_cpc::solve::loss_choice::{decide, is_robust, loss_acts, plain};
use relight_cpc::solve::{estimate, EstimateOptions, Materials0, Problem};

/// The row's loss for the light model `light` kept: as `ABLATION_DEFAULTS_LOSS` gives it,
/// else `run`'s rule (module docs).
pub fn by_run_rule(
    case: &Case,
    problem: &Problem,
    m0: &Materials0,
    light: ChosenLight,
) -> ChosenLight {
    let given = std::env::var("ABLATION_DEFAULTS_LOSS").unwrap_or_else(|_| "auto".into());
    if given == "plain" {
        return ChosenLight {
            options: plain(&light.options),
            note: format!(
                "{}; plain least squares (ABLATION_DEFAULTS_LOSS)",
                light.note
            ),
            robust_score: None,
        };
    }
    let k = crate::env_or("ABLATION_LIGHT_HALVES", DEFAULT_LIGHT_CHOICE_HALVES);
    let halves = choice_halves(case, k);
    let applies = given == "auto"
        && is_robust(&light.options)
        && loss_acts(&light.options)
        && case.nv < LargeMeshSettings::FROM_VERTICES
        && halves.is_some();
    if !applies {
        return light;
    }
    let score = |o: &EstimateOptions| {
        let scored = EstimateOptions {
            validation_halves: halves.clone(),
            ..o.clone()
        };
        estimate(problem, m0.clone(), &scored, &mut |_, _| {})
            .expect("loss fit")
            .validation_error()
    };
    let robust = light.robust_score.unwrap_or_else(|| score(&light.options));
    let plain_options = plain(&light.options);
    let d = decide(robust, score(&plain_options), k);
    ChosenLight {
        options: if d.plain {
            plain_options
        } else {
            light.options
        },
        note: format!("{}; {}", light.note, d.why),
        robust_score: None,
    }
}
