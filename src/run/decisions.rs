//! The adaptive model's decisions ([`crate::solve::adapt`] steps 3–5): what the pilot's
//! outcome changes in the run's options, each change recorded with its reason for the
//! report's "adaptive model" table.
//!
//! In order: the material count, the blending weights' prior and the start's brightness
//! (the pilot's choices); the basis BRDFs it kept and the neighbour prior they call for; the global map's side (the sharpest
//! kept lobe, and whether anything casts shadows), the local maps' side and the Haar
//! coefficients kept per transport row (both bounded by the global side); the Laplacian
//! prior's weight (raised when the pilot's lighting systems are ill-conditioned).

use super::{
    smoothness_base, MaterialCount, PriorStrength, RunOptions, StartBrightness, WeightsSmoothness,
    WeightsSum,
};
use crate::solve::adapt::{self, Decision, PilotOutcome, KAPPA_LIGHTING};
use crate::solve::SumScope;
use crate::transport::brdf::BasisBrdf;
use crate::transport::visibility::Visibility;

/// Every decision from the pilot's `outcome`, applied to `eff` (the run's options `opts`
/// as the fit will use them). `nv`: the mesh's vertex count.
pub(super) fn adaptive_decisions(
    opts: &RunOptions,
    outcome: &PilotOutcome,
    vis: &Visibility,
    nv: usize,
    eff: &mut RunOptions,
) -> Vec<Decision> {
    let mut d = material_decisions(opts, outcome, eff);
    d.push(basis_decision(opts, outcome, eff));
    d.extend(neighbour_prior_decision(opts, eff));
    let shadowed = vis.open_count() < nv;
    d.extend(resolution_decisions(opts, shadowed, eff));
    d.push(smoothness_decision(opts, outcome, eff));
    d
}

/// The material count, and the weights' prior and the start's brightness when the pilot
/// chose them.
fn material_decisions(
    opts: &RunOptions,
    outcome: &PilotOutcome,
    eff: &mut RunOptions,
) -> Vec<Decision> {
    let full_k = match opts.materials {
        MaterialCount::Fixed(k) => k.to_string(),
        MaterialCount::Auto => "auto".to_string(),
    };
    let mut d = vec![Decision::new(
        "materials",
        full_k,
        outcome.materials,
        outcome.materials_reason.clone(),
    )];
    if let Some(why) = &outcome.weights_sum_reason {
        eff.weights_sum = WeightsSum::Fixed(outcome.weights_sum);
        eff.weights_sum_scope = outcome.weights_sum_scope;
        let on_blends = matches!(outcome.weights_sum_scope, SumScope::Blends { .. });
        d.push(Decision::new(
            "weights_sum",
            "auto",
            if on_blends {
                format!("{} on blended vertices", outcome.weights_sum)
            } else {
                outcome.weights_sum.to_string()
            },
            why.clone(),
        ));
    }
    if let Some(why) = &outcome.start_reason {
        eff.start_brightness = outcome.start;
        d.push(Decision::new(
            "start_brightness",
            StartBrightness::Auto.name(),
            outcome.start.name(),
            why.clone(),
        ));
    }
    d
}

/// The basis BRDFs the pilot kept.
fn basis_decision(opts: &RunOptions, outcome: &PilotOutcome, eff: &mut RunOptions) -> Decision {
    eff.basis = outcome.kept.iter().map(|&b| opts.basis[b]).collect();
    let labels = |b: &[BasisBrdf]| b.iter().map(|x| x.label()).collect::<Vec<_>>().join(",");
    Decision::new(
        "basis",
        labels(&opts.basis),
        labels(&eff.basis),
        outcome.basis_reason.clone(),
    )
}

/// The neighbour prior on the blending weights for the kept basis, when `auto`.
fn neighbour_prior_decision(opts: &RunOptions, eff: &mut RunOptions) -> Option<Decision> {
    if opts.weights_smoothness != WeightsSmoothness::Auto {
        return None;
    }
    let (tau, why) = adapt::neighbour_prior_for(&eff.basis);
    eff.weights_smoothness = WeightsSmoothness::Fixed(tau);
    Some(Decision::new("weights_smoothness", "auto", tau, why))
}

/// The global map's side for the kept basis (`shadowed`: some vertex does not see the
/// whole sky), the local side from it, and the kept coefficients bounded by its `g²`.
fn resolution_decisions(opts: &RunOptions, shadowed: bool, eff: &mut RunOptions) -> Vec<Decision> {
    let (g, why) = adapt::global_resolution_for(&eff.basis, opts.global_resolution, shadowed);
    eff.global_resolution = g;
    let global = Decision::new("global_resolution", opts.global_resolution, g, why);
    let (l, why) = adapt::local_resolution_for(g, opts.local_resolution);
    eff.local_resolution = l;
    let local = Decision::new("local_resolution", opts.local_resolution, l, why);
    let cap = g * g;
    let keep = if opts.keep == 0 || opts.keep > cap {
        cap
    } else {
        opts.keep
    };
    eff.keep = keep;
    let kept = Decision::new(
        "keep",
        opts.keep,
        keep,
        format!(
            "{keep} of the {cap} Haar coefficients of a {g}² map per transport row ({:.0}%){}",
            100.0 * keep as f64 / cap as f64,
            if keep == opts.keep {
                ", as requested".to_string()
            } else {
                ": the budget cannot exceed the map's coefficient count".to_string()
            }
        ),
    );
    vec![global, local, kept]
}

/// The Laplacian prior's weight (issue 8: use the condition numbers the solver sees): a
/// lighting system beyond [`KAPPA_LIGHTING`] is regularised harder.
fn smoothness_decision(
    opts: &RunOptions,
    outcome: &PilotOutcome,
    eff: &mut RunOptions,
) -> Decision {
    let base = smoothness_base(opts.smoothness);
    let full = format!("{base:e}");
    if outcome.kappa_lighting > KAPPA_LIGHTING && base < 1e-4 {
        eff.smoothness = PriorStrength::Fixed(1e-4);
        return Decision::new(
            "smoothness",
            full,
            "1e-4",
            format!(
                "the pilot's lighting systems have condition number ≥ {:.1e} > {KAPPA_LIGHTING:.0e}: the Laplacian prior is raised to 1e-4 so the map directions the photos do not constrain are filled smoothly instead of by rounding",
                outcome.kappa_lighting
            ),
        );
    }
    Decision::new(
        "smoothness",
        &full,
        &full,
        format!(
            "the pilot's lighting condition number bound is {:.1e} (≤ {KAPPA_LIGHTING:.0e} or the prior is already ≥ 1e-4) and its λ systems' {:.1e}: no change",
            outcome.kappa_lighting,
            outcome.kappa_lambda.iter().copied().fold(0.0, f64::max)
        ),
    )
}
