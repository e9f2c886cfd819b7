//! The ratio step ([`relight_cpc::solve::ratio_step`]) on a rendered two-material scene
//! with known albedo (`spot-diffuse`, rendered by the independent reference renderer and
//! taken through the real stages): it must bring the albedo ratio between the materials
//! nearer the truth than the same number of plain rounds, and predict the held-out photos
//! under their true light no worse.

use relight_cpc::solve::ratio_step::PATIENCE;
use relight_cpc::solve::{estimate, EstimateOptions, RatioMoves};

use crate::synth_case::{initial, joint_figures, prepare, JointFigures, Sizes};

/// The worst channel's pure-vertex ratio error (remix- and scale-invariant).
fn worst(f: &JointFigures) -> f64 {
    f.beta_ratio_errors.iter().copied().fold(0.0, f64::max)
}

#[test]
fn the_ratio_step_brings_the_albedo_ratio_nearer_the_truth_than_plain_rounds() {
    let case = prepare("spot-diffuse", Sizes::spot_small(), 1, "ratio-step");
    let problem = case.train.problem(case.nv);
    let init = initial(&case, &case.train.obs, case.lambda.len(), 1);
    let rounds = 6;
    let fit = |ratio_steps: usize, validation_fraction: f64| {
        let opts = EstimateOptions {
            max_outer: rounds,
            rel_tol: 0.0,
            ratio_steps,
            validation_fraction,
            ..EstimateOptions::default()
        };
        let est = estimate(&problem, init.clone(), &opts, &mut |_, _| {}).unwrap();
        (
            joint_figures(&case, &est, &case.train.obs, 0.0),
            est.ratio_moves,
        )
    };
    let report = |what: &str, plain: &JointFigures, stepped: &JointFigures| {
        eprintln!(
            "{what}: pure-vertex ratio error per channel {:?} → {:?}; held-out under the true light {:.4} → {:.4}",
            plain.beta_ratio_errors, stepped.beta_ratio_errors, plain.heldout_rel_model, stepped.heldout_rel_model
        );
    };
    // The step alone (no held-back observations, so no validation gate). Measured: worst
    // channel 0.383 → 0.254 (×0.66), held-out 0.1654 → 0.1389. The bound asks for a clear
    // gain (×0.85) with room for another platform's rounding in the QPs.
    let ((plain, none), (stepped, moves)) = (fit(0, 0.0), fit(rounds, 0.0));
    report("no validation", &plain, &stepped);
    // Two materials: one direction a round, every round until the step's patience stops
    // it (no early stop without held-back observations); the paper's free map takes every
    // one. A stop comes only after `PATIENCE` rounds in a row kept nothing.
    assert_eq!(none, RatioMoves::default());
    let ran = moves.stopped_after.unwrap_or(rounds);
    assert_eq!((moves.tried, moves.unsupported), (ran, 0), "{moves:?}");
    assert!(moves.kept >= 1 && moves.kept <= moves.tried, "{moves:?}");
    if moves.stopped_after.is_some() {
        assert!(moves.kept + PATIENCE <= ran, "{moves:?}");
    }
    assert!(
        worst(&stepped) < 0.85 * worst(&plain),
        "worst channel {:.4} against plain rounds' {:.4}",
        worst(&stepped),
        worst(&plain)
    );
    assert!(stepped.heldout_rel_model < plain.heldout_rel_model);
    // With early stopping's held-back observations (the default) a move is also kept only
    // when they are predicted no worse: fewer moves, never a worse fit. Measured: 0.383 →
    // 0.341, held-out 0.1622 → 0.1517.
    let ((plain, _), (stepped, _)) = (
        fit(0, EstimateOptions::default().validation_fraction),
        fit(rounds, EstimateOptions::default().validation_fraction),
    );
    report("default validation", &plain, &stepped);
    assert!(worst(&stepped) < worst(&plain));
    assert!(stepped.heldout_rel_model < plain.heldout_rel_model);
}
