//! The restart from a fit's own materials re-anchored (`solve::materials::reanchor::restart`,
//! `run --restart`) on a known-truth scene: Spot with three materials in blended bands
//! (`spot-three`, rendered by the independent reference renderer and taken through the
//! real stages, `tests/support/synth_case.rs`), its photos replaced by the true model's
//! prediction (noise-free: what is left is the estimator's), the paper's k-means start;
//! and the restarts (`--restart on | irradiance | coarse-light | on+coarse-light | auto`)
//! as `run` reports
//! them on the built-in example. The irradiance model's own kernel is tested against exact and quadrature
//! irradiance in `src/solve/materials/irradiance.rs`.

use crate::synth_case::*;
use relight_cpc::run::Restart;
use relight_cpc::solve::materials::coarse_light::RESORT_WITHIN;
use relight_cpc::solve::materials::reanchor::restart;
use relight_cpc::solve::{estimate, Estimate, EstimateOptions};

/// Material accuracy over the seen vertices: the share whose largest fitted weight is on
/// their largest true material, over the best order of the fitted materials.
fn accuracy(case: &Case, est: &Estimate, seen: &[bool]) -> f64 {
    let k = case.lambda.len();
    let argmax = |w: &[f64]| (0..w.len()).max_by(|&a, &b| w[a].total_cmp(&w[b])).unwrap();
    let seen_x: Vec<usize> = (0..case.nv).filter(|&x| seen[x]).collect();
    let orders: Vec<[usize; 3]> = vec![
        [0, 1, 2],
        [0, 2, 1],
        [1, 0, 2],
        [1, 2, 0],
        [2, 0, 1],
        [2, 1, 0],
    ];
    assert_eq!(k, 3, "the scene has three materials");
    orders
        .iter()
        .map(|perm| {
            let hits = seen_x
                .iter()
                .filter(|&&x| {
                    perm[argmax(&est.weights[x * k..(x + 1) * k])]
                        == argmax(&case.weights[x * k..(x + 1) * k])
                })
                .count();
            hits as f64 / seen_x.len() as f64
        })
        .fold(0.0, f64::max)
}

#[test]
fn the_first_fit_sorts_the_blends_of_three_materials_and_the_restart_keeps_them() {
    let NoiseFree { case, seen, init } = noise_free("spot-three", "restart");
    let problem = case.train.problem(case.nv);
    let opts = EstimateOptions::default();
    let first = estimate(&problem, init, &opts, &mut |_, _| {}).unwrap();
    let before = accuracy(&case, &first, &seen);
    let mut iterations = 0;
    let done = restart(&problem, first, &seen, &opts, &mut |_, _| iterations += 1).unwrap();
    let after = accuracy(&case, &done.est, &seen);
    let [s0, s1] = done.scores;
    eprintln!(
        "accuracy {before:.4} → {after:.4}; validation {s0:.5} → {s1:.5}; kept restart {}",
        done.kept_restart
    );
    // The callback saw every iteration of the restart's fit, and its record says so.
    assert_eq!(iterations, done.record.iterations);
    assert_eq!(done.record.score, s1);
    // The rule: the restart is kept exactly when it predicts the held-back observations
    // better.
    assert_eq!(done.kept_restart, s1 < s0);
    let kept_score = done.est.validation.as_ref().unwrap().best_error();
    assert_eq!(kept_score, s0.min(s1));
    // Measured: accuracy 0.9580 → 0.9536, validation 0.0242 → 0.0228 (restart kept).
    // The first fit's accuracy is the scale normalisation's: with its median weight taken
    // over every vertex, the unobserved ones' uniform start weights pulled one material's
    // gauge off and the first fit read 0.913 (the restart, which renormalises, 0.949).
    // 0.94 fails on that defect with room for the renderer's noise; the restart may move
    // a few near-even blends either way, 0.01 (20 of the ~2,000 seen vertices) of them.
    assert!(before >= 0.94, "first fit's accuracy {before:.4}");
    assert!(done.kept_restart, "validation {s0:.5} → {s1:.5}");
    assert!(after >= before - 0.01, "accuracy {before:.4} → {after:.4}");
}

/// `run --restart on` on the built-in example (a small model, 2 materials): the report's
/// starts hold the first fit and the restart, the timeline as many points per start as
/// that fit had iterations on one clock that never goes back, and the model's reasons say
/// what the restart did and which fit was kept (the one with the lower validation error).
#[test]
fn the_runs_report_holds_the_restart() {
    assert_restart_reported(Restart::Reanchor, "report", REANCHOR_REASON);
}

/// The same with `run --restart irradiance` (the second fit's Lambertian ratios from the
/// order-2 irradiance model, `solve::materials::irradiance`).
#[test]
fn the_runs_report_holds_the_irradiance_restart() {
    assert_restart_reported(
        Restart::Irradiance,
        "report-irradiance",
        "restart from the fit's weights with each material's Lambertian colour ratios",
    );
}

/// The same with `run --restart coarse-light` over the example's shiny basis: one held
/// fit, whose materials' colours come from the coarse-light model with each shiny lobe
/// tied to its material's diffuse one (`solve::materials::coarse_light_shiny`), over the
/// fit's weights re-sorted on them.
#[test]
fn the_runs_report_holds_the_coarse_light_restart_over_a_shiny_basis() {
    let dir = crate::scratch::scratch("restart", "report-coarse-light");
    let mut o = crate::scratch::small_example_options(&dir);
    o.restart = Restart::CoarseLight;
    assert_options_restarts_reported(&o, &[TIED_REASON]);
}

/// The same with `run --restart on+coarse-light` over the Lambertian lobe alone: the
/// re-anchored restart, then the coarse-light one's two held fits from the fit kept, four
/// starts, each restart's reason read against the fit kept before it.
#[test]
fn the_runs_report_holds_both_restarts_in_order() {
    use relight_cpc::transport::brdf::BasisBrdf;
    let dir = crate::scratch::scratch("restart", "report-on-coarse-light");
    let mut o = crate::scratch::small_example_options(&dir);
    o.restart = Restart::ReanchorCoarseLight;
    o.basis = vec![BasisBrdf::Lambert];
    assert_options_restarts_reported(&o, &[REANCHOR_REASON, COARSE_LIGHT_REASON, RESORTED_REASON]);
}

/// How the re-anchored restart's reason starts.
const REANCHOR_REASON: &str = "restart from the fit's own materials";

/// How the coarse-light restart's reason starts.
const COARSE_LIGHT_REASON: &str = "restart from the fit's weights with each material's Lambertian colour ratios fitted with each photo's light a coarse non-negative map";

/// How the reason of the coarse-light restart over a shiny basis starts.
const TIED_REASON: &str = "restart from the fit's weights re-sorted on materials whose colours were fitted with each photo's light a coarse non-negative map";

/// How the reason of the coarse-light restart's second held fit (the weights re-sorted)
/// starts.
const RESORTED_REASON: &str =
    "restart from the fit's weights re-sorted on its own re-anchored materials";

/// The real Buddha photos (`tests/fixtures/colmap-dense-buddha`) over the Lambertian lobe
/// alone, where the coarse-light held fit predicts the held-back observations far worse
/// than the first fit (measured 0.360 against 0.247 at these sizes; 0.372 against 0.218 at
/// `run`'s): its re-sorted twin shares its materials, so it is not made, and the reasons
/// say so with both scores (the helper checks they are past
/// [`RESORT_WITHIN`]).
#[test]
fn the_resorted_held_fit_is_skipped_when_the_first_scores_far_above_the_fit() {
    use relight_cpc::run::{Holdout, MaterialCount, RunOptions};
    use relight_cpc::transport::brdf::BasisBrdf;
    let dir = crate::scratch::scratch("restart", "buddha-gate");
    let ws =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/colmap-dense-buddha");
    let mut o = RunOptions::new(ws, dir.join("out"));
    (
        o.global_resolution,
        o.local_resolution,
        o.normal_grid,
        o.keep,
    ) = (16, 8, 16, 32);
    (
        o.rays_per_texel,
        o.edge_rays,
        o.max_iterations,
        o.irls_iterations,
    ) = (1, 0, 2, 1);
    (o.materials, o.holdout) = (MaterialCount::Fixed(2), Holdout::Every(4));
    (o.progress, o.render_training, o.force) = (false, false, true);
    o.basis = vec![BasisBrdf::Lambert];
    let r = assert_options_restarts_reported(&o, &[COARSE_LIGHT_REASON, RESORTED_REASON]);
    let starts = r.starts.as_ref().expect("the starts' records");
    assert_eq!(
        starts.starts.len(),
        2,
        "the re-sorted fit skipped: {starts:?}"
    );
    assert!(
        r.model
            .reasons
            .iter()
            .any(|s| s.starts_with(RESORTED_REASON) && s.ends_with("more than 25% above")),
        "{:?}",
        r.model.reasons
    );
}

/// `run --restart auto` (the default) on the example: over the Lambertian lobe alone
/// (`--basis lambert`) the coarse-light restart, reported as above, with a reason that says
/// why; over the default basis (two shiny lobes) no restart, and a reason that names them.
#[test]
fn the_auto_restart_is_the_coarse_light_one_over_the_lambertian_lobe_alone() {
    use relight_cpc::transport::brdf::BasisBrdf;
    let dir = crate::scratch::scratch("restart", "report-auto-lambert");
    let mut o = crate::scratch::small_example_options(&dir);
    assert_eq!(o.restart, Restart::Auto, "the default");
    o.basis = vec![BasisBrdf::Lambert];
    let r = assert_options_restarts_reported(&o, &[COARSE_LIGHT_REASON, RESORTED_REASON]);
    assert!(
        r.model.reasons.iter().any(|s| s
            == "--restart auto: a restart from a coarse non-negative light, as the fit's basis is the Lambertian lobe alone"),
        "{:?}",
        r.model.reasons
    );

    let dir = crate::scratch::scratch("restart", "report-auto-shiny");
    let o = crate::scratch::small_example_options(&dir);
    let r = relight_cpc::run::run(&o).expect("run").report;
    assert!(r.starts.is_none(), "one fit: {:?}", r.starts);
    assert!(
        r.model.reasons.iter().any(|s| s.starts_with(
            "--restart auto: no restart, as the fit keeps a shiny lobe (lambert, phong:50, phong:500, ggx:0.3)"
        )),
        "{:?}",
        r.model.reasons
    );
}

/// The example run with `mode` (one restart): two starts, the timeline per start, the
/// kept one the lower score, and a reason starting with `prefix` that says which was kept.
fn assert_restart_reported(mode: Restart, name: &str, prefix: &str) {
    let dir = crate::scratch::scratch("restart", name);
    let mut o = crate::scratch::small_example_options(&dir);
    o.restart = mode;
    assert_options_restarts_reported(&o, &[prefix]);
}

/// The run with options `o`, whose restarts' reasons start with `prefixes` in order: one
/// start per restart made after the first fit (a re-sorted held fit skipped by its gate
/// makes none, and its reason says the fit before it scored above the gate), the timeline
/// per start, each restart kept when its score is below the fit kept before it, or by the
/// one-standard-error rule against the first fit (its reason says which), and the chosen
/// start the last one kept; a refused one's reason says "the first fit kept" while no
/// restart has been kept, else "the previous fit kept"; the report.
fn assert_options_restarts_reported(
    o: &relight_cpc::run::RunOptions,
    prefixes: &[&str],
) -> relight_cpc::report::RunReport {
    let r = relight_cpc::run::run(o).expect("run with --restart").report;
    let starts = r
        .starts
        .as_ref()
        .expect("the first fit's and the restarts' records");
    crate::scratch::assert_timeline_follows_starts(&r.timeline, starts);
    let (mut made, mut kept, mut read_against) = (0, 0, 0);
    for prefix in prefixes {
        let reason = r
            .model
            .reasons
            .iter()
            .find(|s| s.starts_with(prefix))
            .unwrap_or_else(|| panic!("the restart's reason in {:?}", r.model.reasons));
        if reason.contains(" skipped: the held fit before it scored ") {
            // The re-sorted held fit is made only when the one before it scored within
            // `RESORT_WITHIN` of the fit it was read against.
            let (before, prev) = (starts.starts[read_against].score, starts.starts[made].score);
            assert!(prev > RESORT_WITHIN * before, "{reason} ({starts:?})");
            continue;
        }
        made += 1;
        let better = starts.starts[made].score < starts.starts[kept].score;
        let refused = if kept == 0 {
            "the first fit kept"
        } else {
            "the previous fit kept"
        };
        // A held coarse-light fit scored above the free fit its step started from may
        // still be kept by the one-standard-error rule.
        let by_rule = reason.contains(", kept: ") && reason.contains("one-standard-error rule");
        if by_rule {
            assert!(!better, "{reason} ({starts:?})");
        } else if better {
            assert!(reason.ends_with(", kept"), "{reason} ({starts:?})");
        } else {
            assert!(
                reason.contains(&format!(", {refused}")),
                "{reason} ({starts:?})"
            );
        }
        read_against = kept;
        if better || by_rule {
            kept = made;
        }
    }
    assert_eq!(starts.starts.len(), made + 1, "{starts:?}");
    assert_eq!(starts.chosen, kept, "{starts:?}");
    r
}
