//! Materials of the vertices no training photo sees (`solve::materials::propagate`) on a
//! known-truth scene: Spot with two Lambertian materials (`spot-diffuse`, the estimator
//! tests' small case), the TRUE blending weights kept at the vertices the training photos
//! see, the others reset to the uniform start and propagated, then compared with the truth.

use crate::synth_case::*;
use relight_cpc::solve::materials::propagate::propagate_unseen;

/// `(fraction whose largest weight is the true largest, RMS weight error)` over `xs`.
fn score(w: &[f64], truth: &[f64], k: usize, xs: &[usize]) -> (f64, f64) {
    let argmax = |r: &[f64]| (0..k).max_by(|&a, &b| r[a].total_cmp(&r[b])).unwrap_or(0);
    let (mut hit, mut se) = (0usize, 0.0);
    for &x in xs {
        let (a, t) = (&w[x * k..(x + 1) * k], &truth[x * k..(x + 1) * k]);
        hit += usize::from(argmax(a) == argmax(t));
        se += a.iter().zip(t).map(|(p, q)| (p - q).powi(2)).sum::<f64>();
    }
    let n = xs.len().max(1) as f64;
    (hit as f64 / n, (se / n).sqrt())
}

#[test]
fn propagated_materials_match_the_truth_where_no_training_photo_looks() {
    let case = prepare("spot-diffuse", Sizes::spot_small(), 1, "propagate");
    let k = case.lambda.len();
    let (_, seen) = relight_cpc::run::mean_colours(&case.train.obs, case.nv);
    let unseen: Vec<usize> = (0..case.nv).filter(|&x| !seen[x]).collect();
    let mut w = case.weights.clone();
    for &x in &unseen {
        w[x * k..(x + 1) * k].fill(1.0 / k as f64);
    }
    let before = score(&w, &case.weights, k, &unseen);
    let p = propagate_unseen(&case.positions, &seen, &mut w, k).unwrap();
    let after = score(&w, &case.weights, k, &unseen);
    eprintln!(
        "{} unseen of {}: {p:?}, before {before:?}, after {after:?}",
        unseen.len(),
        case.nv
    );
    // Spot is one connected surface: every unseen vertex has a seen one in its graph
    // component (1,143 of 2,930 here).
    assert_eq!((p.filled, p.isolated), (unseen.len(), 0));
    // Measured: the largest weight is the true one at 94% of the unseen vertices (the
    // uniform start: 38%, a tie read as material 0) and the RMS weight error is 0.23 (start
    // 0.66). The misses lie where the two materials meet: a harmonic extension blurs a
    // boundary across the unseen band, so 90% and 0.3 leave room for a different seed's
    // band without admitting the start.
    assert!(after.0 >= 0.9, "accuracy {after:?} (start {before:?})");
    assert!(
        after.1 <= 0.3 && after.1 <= 0.5 * before.1,
        "RMS {after:?} (start {before:?})"
    );
    // The maximum principle: each filled row sums within the seen rows' range (the truth's
    // rows sum to one up to the PLY's f32 rounding), to CG's 1e-9.
    let sums: Vec<f64> = (0..case.nv)
        .map(|x| w[x * k..(x + 1) * k].iter().sum())
        .collect();
    let seen_sums = (0..case.nv).filter(|&x| seen[x]).map(|x| sums[x]);
    let (lo, hi) = seen_sums.fold((f64::INFINITY, 0.0_f64), |(l, h), v| (l.min(v), h.max(v)));
    for &x in &unseen {
        assert!(
            sums[x] >= lo - 1e-9 && sums[x] <= hi + 1e-9,
            "vertex {x}: {}",
            sums[x]
        );
        assert!(w[x * k..(x + 1) * k].iter().all(|&v| v >= 0.0));
    }
}
