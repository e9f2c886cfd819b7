//! The brightness search (`solve::materials::brightness::search`, `run --start-search
//! brightness`) on a known-truth scene: Spot with two Lambertian materials
//! (`spot-diffuse`, rendered by the independent reference renderer and taken through the
//! real stages, `tests/support/synth_case.rs`), its photos replaced by the true model's
//! prediction (noise-free: the minimum of Eq. 9 is at the truth, only the start keeps the
//! fit from it), the paper's k-means start.

use crate::synth_case::*;
use relight_cpc::solve::materials::brightness::search;
use relight_cpc::solve::{estimate, Estimate, EstimateOptions};

/// The worst relative error over channels of the diffuse albedo ratio material 1 / material
/// 0: per material, the median fitted Lambertian weight `β̂_{x,L,c}` over the seen vertices
/// that are truly ≥ 95% that material (invariant to the per-channel scale and to the
/// materials' order and remix), against the truth's `λ_{1,L,c} / λ_{0,L,c}`.
fn ratio_error(case: &Case, est: &Estimate, seen: &[bool]) -> f64 {
    let k = case.lambda.len();
    let beta = relight_cpc::solve::beta_per_vertex(&est.lambda, &est.weights, case.nv);
    let nb = case.basis.len();
    let median = |j: usize, c: usize| {
        let mut v: Vec<f64> = (0..case.nv)
            .filter(|&x| seen[x] && case.weights[x * k + j] >= 0.95)
            .map(|x| beta[x * nb][c])
            .collect();
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    (0..3)
        .map(|c| {
            let truth = case.lambda[1][0][c] / case.lambda[0][0][c];
            (median(1, c) / median(0, c) / truth - 1.0).abs()
        })
        .fold(0.0, f64::max)
}

#[test]
fn the_search_keeps_the_start_with_the_right_albedo_ratio() {
    let NoiseFree { case, seen, init } = noise_free("spot-diffuse", "start-search");
    let problem = case.train.problem(case.nv);
    let opts = EstimateOptions::default();
    let paper = estimate(&problem, init.clone(), &opts, &mut |_, _| {}).unwrap();
    let before = ratio_error(&case, &paper, &seen);
    let mut seen_iterations = [0usize; 3];
    let (kept, record) = search(
        &problem,
        paper,
        "paper",
        &init,
        0,
        &opts,
        &mut |si, _, _| seen_iterations[si] += 1,
    )
    .unwrap();
    let after = ratio_error(&case, &kept, &seen);
    eprintln!("ratio error {before:.4} → {after:.4}; {record:?}");
    assert_eq!(
        record.starts.len(),
        3,
        "K = 2: the paper's start and ×½, ×2"
    );
    // The callback saw every iteration of the searched starts (records 1 and 2), none of
    // the paper's fit (made before the search).
    assert_eq!(seen_iterations[0], 0);
    for (si, (&seen, r)) in seen_iterations
        .iter()
        .zip(&record.starts)
        .enumerate()
        .skip(1)
    {
        assert_eq!(seen, r.iterations, "start {si}");
    }
    let chosen = record.starts[record.chosen].score;
    assert!(record.starts.iter().all(|s| s.score >= chosen));
    // The true ratio lies toward ×2 of the k-means start (its clusters' colours carry their
    // bands' shading): the search must keep that start. Measured with the default
    // (free-weights) options: ratio error 0.536 → 0.271, training score 0.0493 (paper's
    // start), 0.0655 (×½), 0.0379 (×2). The bound 0.6 × the paper start's leaves room for
    // another seed's k-means and fails when the paper's start (0.536) is kept.
    assert_eq!(record.chosen, 2, "kept {:?}", record.starts[record.chosen]);
    assert!(
        after <= 0.6 * before,
        "ratio error {after:.4} (paper's start {before:.4})"
    );
}

/// `run --start-search brightness` on the built-in example (a small model, 2 materials):
/// the report's timeline follows the search's records, start by start — as many points
/// per start as that start's fit had iterations, on one clock that never goes back — so
/// the error-against-time plot shows every fit the search made.
#[test]
fn the_runs_timeline_holds_every_searched_start() {
    let dir = crate::scratch::scratch("start-search", "timeline");
    let mut o = crate::scratch::small_example_options(&dir);
    o.start_search = true;
    let r = relight_cpc::run::run(&o)
        .expect("run with --start-search brightness")
        .report;
    let starts = r.starts.expect("the search's records");
    assert_eq!(
        starts.starts.len(),
        3,
        "K = 2: the paper's start, ×½ and ×2"
    );
    crate::scratch::assert_timeline_follows_starts(&r.timeline, &starts);
}
