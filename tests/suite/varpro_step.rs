//! The variable-projection step ([`relight_cpc::solve::varpro_step`]) on a rendered glossy
//! scene with known materials (`spot-varying`: a Phong and a GGX material, rendered by the
//! independent reference renderer and taken through the real stages): with the lights
//! re-solved at every probe it must predict the held-out photos under their true light
//! better than the same number of plain rounds, and so must the step whose Jacobian is
//! carried over by Broyden's update after the first round.

use relight_cpc::solve::{estimate, EstimateOptions, RatioMoves};

use crate::synth_case::{initial, joint_figures, prepare, JointFigures, Sizes};

#[test]
fn the_varpro_step_fits_the_true_light_better_than_plain_rounds() {
    let case = prepare("spot-varying", Sizes::spot_small(), 1, "varpro-step");
    let problem = case.train.problem(case.nv);
    let init = initial(&case, &case.train.obs, case.lambda.len(), 1);
    let rounds = 6;
    let fit = |varpro_steps: usize, varpro_broyden: bool| {
        let opts = EstimateOptions {
            max_outer: rounds,
            rel_tol: 0.0,
            varpro_steps,
            varpro_broyden,
            validation_fraction: 0.0,
            ..EstimateOptions::default()
        };
        let est = estimate(&problem, init.clone(), &opts, &mut |_, _| {}).unwrap();
        (
            joint_figures(&case, &est, &case.train.obs, 0.0),
            est.varpro_moves,
        )
    };
    let ((plain, none), (stepped, moves)): ((JointFigures, _), (JointFigures, _)) =
        (fit(0, false), fit(rounds, false));
    let (broyden, broyden_moves) = fit(rounds, true);
    eprintln!(
        "held-out under the true light {:.4} → {:.4} (Broyden {:.4}); pure-vertex ratio error per channel {:?} → {:?}; moves {moves:?}, Broyden's {broyden_moves:?}",
        plain.heldout_rel_model, stepped.heldout_rel_model, broyden.heldout_rel_model, plain.beta_ratio_errors, stepped.beta_ratio_errors
    );
    // One step a round, every round asked for; the paper's free map can always take it.
    assert_eq!(none, RatioMoves::default());
    assert_eq!((moves.tried, moves.unsupported), (rounds, 0), "{moves:?}");
    assert!(moves.kept >= 1, "{moves:?}");
    // Measured: 0.1940 → 0.1471 (×0.76), the worst channel's ratio error 0.292 → 0.260.
    // The bound asks for a clear gain (×0.9) with room for another platform's rounding in
    // the QPs.
    assert!(
        stepped.heldout_rel_model < 0.9 * plain.heldout_rel_model,
        "held-out under the true light {:.4} against plain rounds' {:.4}",
        stepped.heldout_rel_model,
        plain.heldout_rel_model
    );
    // Broyden's Jacobian after the first round: measured 0.1504 (×0.78), 6 of 6 kept; the
    // same bound, since it must keep most of the probed step's gain to be worth having.
    assert_eq!(broyden_moves.tried, rounds, "{broyden_moves:?}");
    assert!(
        broyden.heldout_rel_model < 0.9 * plain.heldout_rel_model,
        "Broyden: held-out under the true light {:.4} against plain rounds' {:.4}",
        broyden.heldout_rel_model,
        plain.heldout_rel_model
    );
}
