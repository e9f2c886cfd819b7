//! The ratio step ([`relight_cpc::solve::ratio_step`]) on a rendered two-material scene
//! with known albedo: it must bring the albedo ratio between the materials nearer the
//! truth than the same number of plain rounds, and predict the held-out photos under
//! their true light no worse.

use relight_cpc::solve::{estimate, EstimateOptions};

use crate::synth_case::{initial, joint_figures, prepare, Sizes};

#[test]
fn the_ratio_step_brings_the_albedo_ratio_nearer_the_truth_than_plain_rounds() {
    let case = prepare("spot-diffuse", Sizes::spot_small(), 1, "ratio-step");
    let problem = case.train.problem(case.nv);
    let init = initial(&case, &case.train.obs, case.lambda.len(), 1);
    let rounds = 6;
    let fit = |ratio_steps: usize| {
        let opts = EstimateOptions {
            max_outer: rounds,
            rel_tol: 0.0,
            ratio_steps,
            ..EstimateOptions::default()
        };
        let mut objective = Vec::new();
        let est = estimate(&problem, init.clone(), &opts, &mut |it, _| {
            objective.push(it.objective)
        })
        .unwrap();
        (joint_figures(&case, &est, &case.train.obs, 0.0), objective)
    };
    let (plain, _) = fit(0);
    let (stepped, objective) = fit(rounds);
    let worst = |f: &[f64; 3]| f.iter().copied().fold(0.0, f64::max);
    eprintln!(
        "pure-vertex ratio error per channel {:?} → {:?}; held-out under the true light {:.4} → {:.4}; F {objective:?}",
        plain.beta_ratio_errors, stepped.beta_ratio_errors, plain.heldout_rel_model, stepped.heldout_rel_model
    );
    // Measured: worst channel 0.383 → 0.286 (×0.75), held-out 0.1622 → 0.1433. The bound
    // asks for a clear gain (×0.85) with room for another platform's rounding in the QPs.
    assert!(
        worst(&stepped.beta_ratio_errors) < 0.85 * worst(&plain.beta_ratio_errors),
        "worst channel {:.4} against plain rounds' {:.4}",
        worst(&stepped.beta_ratio_errors),
        worst(&plain.beta_ratio_errors)
    );
    assert!(
        stepped.heldout_rel_model < plain.heldout_rel_model,
        "held-out under the true light {:.4} against {:.4}",
        stepped.heldout_rel_model,
        plain.heldout_rel_model
    );
}
