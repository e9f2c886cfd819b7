use super::*;
use crate::observe::Observations;
use crate::sphere::SphereGrid;

/// Texel averages of `f` on the full grid of side `n` by 8² sub-texels.
fn texels(n: usize, f: impl Fn(&crate::Vec3) -> f64) -> Vec<f64> {
    let g = SphereGrid::full(n);
    (0..g.len())
        .map(|t| {
            let (mut a, mut w) = (0.0, 0.0);
            for (d, o) in g.sample_points(t, 8) {
                a += o * f(&d);
                w += o;
            }
            a / w
        })
        .collect()
}

#[test]
fn shape_of_a_linear_map_matches_its_analytic_ratio() {
    // L(ω) = 1 + a z: c_00 = 4π Y_00, c_10 = a · 0.4886 · 4π/3, so c_10 / c_00 = a / √3,
    // every other order-1..2 coefficient 0. The projection treats each texel as constant,
    // an O(h²) error in the texel size: 1.1e-3 on c_10 / c_00 at 32² (measured), so at 64²
    // about a quarter of that, below the 1e-3 allowed.
    let n = 64;
    let a = [0.5, 0.2, -0.3];
    let light = a.map(|ac| texels(n, |d| 1.0 + ac * d.z));
    let s = map_shape(&light, &ShProjection::new(n, 4)).unwrap();
    for c in 0..3 {
        for i in 0..8 {
            let want = if i == 1 { a[c] / 3f64.sqrt() } else { 0.0 };
            assert!(
                (s[c * 8 + i] - want).abs() < 1e-3,
                "c{c} i{i}: {} vs {want}",
                s[c * 8 + i]
            );
        }
    }
}

#[test]
fn training_prior_matches_the_brute_force_shrunk_floored_covariance() {
    // Four maps 1 + a_k z + b_k x with distinct (a_k, b_k): the mean and the precision
    // against the definitions computed here by plain loops (shapes, sample covariance,
    // shrinkage, floor, inverse). Both sides use the same projection, so only rounding
    // separates them: 1e-8 relative.
    let n = 16;
    let ab = [(0.5, 0.1), (0.2, -0.3), (-0.1, 0.2), (0.3, 0.4)];
    let lights: Vec<[Vec<f64>; 3]> = ab
        .iter()
        .map(|&(a, b)| [1.0, 0.8, 0.6].map(|g| texels(n, |d| g * (1.0 + a * d.z + b * d.x))))
        .collect();
    let (shrink, floor) = (0.3, 0.05);
    let prior = training_prior(&lights, n, shrink, floor).unwrap();
    let proj = ShProjection::new(n, 4);
    let shapes: Vec<[f64; N_SHAPE]> = lights
        .iter()
        .map(|l| map_shape(l, &proj).unwrap())
        .collect();
    let k = shapes.len() as f64;
    let mean: Vec<f64> = (0..N_SHAPE)
        .map(|i| shapes.iter().map(|s| s[i]).sum::<f64>() / k)
        .collect();
    let mut cov = nalgebra::DMatrix::<f64>::zeros(N_SHAPE, N_SHAPE);
    for i in 0..N_SHAPE {
        for j in 0..N_SHAPE {
            let c: f64 = shapes
                .iter()
                .map(|s| (s[i] - mean[i]) * (s[j] - mean[j]))
                .sum::<f64>()
                / (k - 1.0);
            cov[(i, j)] = if i == j {
                c + floor * floor
            } else {
                (1.0 - shrink) * c
            };
        }
    }
    let want = cov.try_inverse().unwrap();
    for i in 0..N_SHAPE {
        assert!((prior.shape_mean[i] - mean[i]).abs() < 1e-12);
        for j in 0..N_SHAPE {
            let got = prior.shape_precision[i * N_SHAPE + j];
            let w = want[(i, j)];
            assert!(
                (got - w).abs() <= 1e-8 * w.abs().max(1.0),
                "Λ[{i},{j}] {got} vs {w}"
            );
        }
    }
}

#[test]
fn a_dark_collection_is_a_clear_error() {
    let dark = vec![[vec![0.0; 16], vec![0.0; 16], vec![0.0; 16]]; 3];
    let e = training_prior(&dark, 4, SHRINKAGE, SHAPE_FLOOR).unwrap_err();
    assert!(e.to_string().contains("0 of 3 training maps"), "{e}");
}

#[test]
fn log_ratio_scores_against_hand_computed_means() {
    // Photo 1: MSE 4 → 1 → 16 (RMSE ratio 1/2, 2); photo 2 unchanged; photo 3 has a
    // non-finite entry and is left out. Means: [0, ½ ln ½, ½ ln 2].
    let e = vec![
        vec![4.0, 1.0, 16.0],
        vec![1.0, 1.0, 1.0],
        vec![1.0, f64::INFINITY, 1.0],
    ];
    let (s, n) = log_ratio_scores(&e);
    assert_eq!(n, 2);
    let want = [0.0, 0.5 * 0.5f64.ln(), 0.5 * 2f64.ln()];
    for (a, b) in s.iter().zip(want) {
        assert!((a - b).abs() < 1e-12, "{s:?} vs {want:?}");
    }
}

#[test]
fn mean_without_matches_the_brute_force_mean() {
    let lights: Vec<[Vec<f64>; 3]> = (0..4)
        .map(|k| [0, 1, 2].map(|c| (0..5).map(|t| (k * 7 + c * 3 + t) as f64).collect()))
        .collect();
    let m = mean_without(&lights, 2);
    for c in 0..3 {
        for t in 0..5 {
            let want = [0, 1, 3].iter().map(|&k| lights[k][c][t]).sum::<f64>() / 3.0;
            assert!((m[c][t] - want).abs() < 1e-12);
        }
    }
}

#[test]
fn half_prior_flag_parses_and_rejects() {
    assert_eq!(HalfPriorMode::parse("auto").unwrap(), HalfPriorMode::Auto);
    assert_eq!(HalfPriorMode::parse("off").unwrap(), HalfPriorMode::Off);
    assert_eq!(HalfPriorMode::parse("model").unwrap(), HalfPriorMode::Model);
    assert_eq!(
        HalfPriorMode::parse("3").unwrap(),
        HalfPriorMode::Fixed(3.0)
    );
    for bad in ["-1", "0", "nan", "strong"] {
        let e = HalfPriorMode::parse(bad).unwrap_err().to_string();
        assert!(e.contains("--half-prior"), "{bad}: {e}");
    }
}

#[test]
fn candidates_start_with_the_laplacian_then_the_training_prior_at_each_eta() {
    // The scores are ratios to the first candidate, so it must be the Laplacian alone.
    let c = candidates();
    assert_eq!(c[0], HalfLightPrior::Laplacian);
    let etas: Vec<f64> = ETA_GRID.iter().copied().filter(|&e| e > 0.0).collect();
    let training: Vec<HalfLightPrior> = etas.iter().map(|&e| HalfLightPrior::Training(e)).collect();
    assert_eq!(c[1..], training[..]);
    // Without a training prior kept, the model's own when there is one.
    assert_eq!(without_training_prior(true), HalfLightPrior::Model);
    assert_eq!(without_training_prior(false), HalfLightPrior::Laplacian);
}

#[test]
fn each_candidate_gives_its_own_light_prior_options() {
    // Three maps 1 + a z (two would do; three as a collection has): the training prior
    // at η is the shape term alone with σ-scale η; the model's keeps its statistics at
    // its noise levels scaled.
    let n = 8;
    let lights: Vec<[Vec<f64>; 3]> = [0.1, 0.4, -0.2]
        .iter()
        .map(|&a| [1.0, 0.9, 0.8].map(|g| texels(n, |d| g * (1.0 + a * d.z))))
        .collect();
    let model = LightPriorOptions::builtin(0.3, 0.03).unwrap();
    let none = HalfLightPrior::Laplacian
        .options(&lights, n, Some(&model))
        .unwrap();
    assert!(none.is_none());
    let t = HalfLightPrior::Training(3.0)
        .options(&lights, n, Some(&model))
        .unwrap()
        .unwrap();
    assert_eq!((t.sh_noise, t.haar_noise), (3.0, 0.0));
    let m = HalfLightPrior::Model
        .options(&lights, n, Some(&model))
        .unwrap()
        .unwrap();
    // The model's own statistics at its noise levels × MODEL_PRIOR_SCALE.
    assert!(std::sync::Arc::ptr_eq(&m.stats, &model.stats));
    let want = (0.3 * MODEL_PRIOR_SCALE, 0.03 * MODEL_PRIOR_SCALE);
    assert_eq!((m.sh_noise, m.haar_noise), want);
    // No model prior (the paper's free map): the model candidate adds nothing.
    assert!(HalfLightPrior::Model
        .options(&lights, n, None)
        .unwrap()
        .is_none());
}

/// Observations `0..n` of one photo with `α_p = w(p)` and `y_p = (p, 2p, 3p)`.
fn numbered_observations(n: usize, w: impl Fn(usize) -> f32) -> Observations {
    let all = 0..n;
    Observations {
        vertex: (0..n as u32).collect(),
        photo: vec![0; n],
        rgb: (0..n)
            .map(|p| [p as f32, 2.0 * p as f32, 3.0 * p as f32])
            .collect(),
        weight: (0..n).map(w).collect(),
        dir: vec![[0.0, 0.0, 1.0]; n],
        photo_ranges: vec![all],
        clipped: Vec::new(),
        bound_weight: Vec::new(),
    }
}

#[test]
fn thinning_keeps_small_photos_whole_and_the_data_terms_expected_size() {
    // At or under the cap nothing changes.
    let small = numbered_observations(50, |_| 1.0);
    assert_eq!(thin_observations(small.clone(), 50), small);
    // Over it: every ⌈N / max⌉-th observation, in order, its record intact.
    let n = 10_007;
    let max = 1_000;
    let thin = thin_observations(numbered_observations(n, |_| 0.5), max);
    let step = n.div_ceil(max);
    assert!(thin.len() <= max && thin.len() == n.div_ceil(step));
    for (i, &v) in thin.vertex.iter().enumerate() {
        assert_eq!(v as usize, i * step);
        assert_eq!(thin.rgb[i], [v as f32, 2.0 * v as f32, 3.0 * v as f32]);
    }
    assert_eq!(thin.photo_ranges.len(), 1);
    assert_eq!(thin.photo_ranges[0], 0..thin.len());
    // Horvitz–Thompson: with equal α the kept weights sum to the photo's total exactly
    // (n · N/n = N, up to f32 rounding of the ratio: 1e-6 relative), and a smooth term's
    // weighted sum (here Σ α_p · p) to within the systematic sample's error, at most one
    // step's worth of the largest term (step · N / Σ p ≈ 2 · 11 / N ≈ 2e-3 relative).
    let total: f64 = thin.weight.iter().map(|&w| w as f64).sum();
    assert!((total - 0.5 * n as f64).abs() < 1e-6 * n as f64, "{total}");
    let exact: f64 = (0..n).map(|p| 0.5 * p as f64).sum();
    let sampled: f64 = thin
        .weight
        .iter()
        .zip(&thin.vertex)
        .map(|(&w, &v)| w as f64 * v as f64)
        .sum();
    assert!(
        (sampled - exact).abs() < 2e-3 * exact,
        "{sampled} against {exact}"
    );
}

#[test]
fn replay_rounds_take_every_pick_once_every_other_first() {
    for m in 0..=LOO_PHOTOS + 3 {
        let [first, second] = replay_rounds(m);
        let mut all: Vec<usize> = first.iter().chain(&second).copied().collect();
        all.sort_unstable();
        assert_eq!(all, (0..m).collect::<Vec<_>>(), "m = {m}");
        // The first round spans the picks (its first and, from 3 picks on, a later one)
        // and is never the smaller half.
        assert!(first.len() >= second.len());
        if m >= 3 {
            assert_eq!(first[0], 0);
            assert!(*first.last().unwrap() >= m / 2);
        }
    }
}

/// An empty transport over `n` observations (one basis function): the replay's cut
/// never reads it.
fn empty_transport(n: usize) -> crate::transport::Transport {
    crate::transport::Transport {
        n_global: 2,
        n_basis: 1,
        n_obs: n,
        offsets: vec![0; n + 1],
        index: Vec::new(),
        value: Vec::new(),
    }
}

#[test]
fn a_replayed_photo_is_cut_at_the_middle_of_its_seen_span() {
    // Six observations: x = 0, 10, 4, 6 seen; one behind the camera; one at x = 100 that
    // weighs nothing (not seen: it neither widens the span nor lands in a half).
    let mut obs = numbered_observations(6, |p| if p == 5 { 0.0 } else { 1.0 });
    // Photo 3 of a split: the replay is photo 0 of its own problem.
    obs.photo = vec![3; 6];
    let px = [
        Some(0.0),
        Some(10.0),
        Some(4.0),
        Some(6.0),
        None,
        Some(100.0),
    ];
    let r = ReplayPhoto::new(obs.clone(), &px, |o| Ok(empty_transport(o.len())))
        .unwrap()
        .unwrap();
    // The span of the seen x is 0..10, its middle 5: right = x ≥ 5 among the seen.
    assert_eq!(r.right, vec![1, 3]);
    // The fit reads the seen left half only: x = 0 and 4.
    let fitted: Vec<usize> = (0..6).filter(|&p| r.fit.weight[p] > 0.0).collect();
    assert_eq!(fitted, vec![0, 2]);
    // The scored copy keeps every observation and its weight; one photo spans them.
    assert_eq!(r.obs.weight, obs.weight);
    assert!(r.obs.photo.iter().chain(&r.fit.photo).all(|&p| p == 0));
    assert_eq!(r.obs.photo_ranges, vec![0..6]);
    assert_eq!(r.fit.photo_ranges, vec![0..6]);
    // Every seen x equal: the left half is empty, no replay.
    let flat = [Some(3.0); 6];
    assert!(
        ReplayPhoto::new(obs.clone(), &flat, |o| Ok(empty_transport(o.len())))
            .unwrap()
            .is_none()
    );
    // Nothing seen: no replay, and the transport is never built.
    assert!(ReplayPhoto::new(obs, &[None; 6], |_| unreachable!())
        .unwrap()
        .is_none());
}

#[test]
fn the_replay_keeps_the_lowest_negative_score_and_rules_out_early() {
    let priors = candidates();
    // Per training photo, MSE under the Laplacian, η = 3, η = 10: η = 3 lowers every
    // photo's error by 19% (½ ln 0.81 ≈ −0.105), η = 10 by 1%; η = 3 is kept.
    let calls = std::sync::atomic::AtomicUsize::new(0);
    let c = choose_prior_over(8, &priors, |_| {
        calls.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        Ok(Some(vec![1.0, 0.81, 0.99]))
    })
    .unwrap();
    assert_eq!(c.kept, HalfLightPrior::Training(3.0));
    assert_eq!(c.photos, LOO_PHOTOS);
    assert_eq!(calls.into_inner(), LOO_PHOTOS);
    assert!((c.scores[1] - 0.5 * 0.81_f64.ln()).abs() < 1e-12);
    // Every prior raising the first round's error by e (score ½ ≥ RULE_OUT): the second
    // round is skipped and the Laplacian kept.
    let calls = std::sync::atomic::AtomicUsize::new(0);
    let c = choose_prior_over(8, &priors, |_| {
        calls.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        Ok(Some(vec![1.0, std::f64::consts::E, 10.0]))
    })
    .unwrap();
    assert_eq!(c.kept, HalfLightPrior::Laplacian);
    assert_eq!(calls.into_inner(), replay_rounds(LOO_PHOTOS)[0].len());
    // Fewer than three training photos: the Laplacian, without a replay.
    let c = choose_prior_over(2, &priors, |_| unreachable!()).unwrap();
    assert_eq!(c.kept, HalfLightPrior::Laplacian);
    assert!(c.scores.is_empty());
}
