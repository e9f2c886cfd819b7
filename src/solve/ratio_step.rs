//! The ratio step: each material's brightness moved per channel along the valley of
//! Eq. 9, with the lights re-solved (issue 25, not in the paper).
//!
//! With a free map per photo, scaling one material's `λ_{k,·,c}` while the maps take up the
//! difference barely changes `F`: the alternation crawls along that valley about 2% of the
//! way a round, so the start's albedo ratios survive the rounds that held-back
//! observations allow, in each material's weakest channel most
//! (`bench-results/albedo-weak-channel.md`). Variable projection's view (Golub & Pereyra
//! 2003, "Separable nonlinear least squares: the variable projection method and its
//! applications", Inverse Problems 19) eliminates the lights: `φ_c(t) = min_x F(λ(t), x)`
//! along the direction `λ_{k,b,c}(t) = λ_{k,b,c} e^{t u_k}` is a function of one variable per
//! channel, and the channels are separable (each channel's maps and `λ` see only that
//! channel's data, prior and ridge). `u = e_j − 1/K` moves material `j` against the mean of
//! all, so the common scale, which the gauge holds, stays put; with two materials one
//! direction covers both.
//!
//! One step, right after a round's lighting step (its lights are the probe at `t = 0`):
//! 1. the lights re-solved by one lighting step at `t = ±δ` ([`PROBE_STEP`]);
//! 2. per channel, the parabola through `(−δ, φ_−)`, `(0, φ_0)`, `(δ, φ_+)` and its
//!    minimiser, clamped to `[−2δ, 2δ]` (a trust region: the lights of the probes are
//!    inexact block steps, so the parabola is a model, [`parabola_step`]);
//! 3. the lights at `t*` interpolated from the three probes' by Lagrange's quadratic
//!    ([`lagrange_weights`]), projected on `x ≥ 0`, so the step costs two lighting steps,
//!    not three;
//! 4. kept when `F` at `t*` is below `F` at `t = 0` and the held-back observations of
//!    early stopping are predicted no worse, otherwise the round goes on from `t = 0`. The
//!    second test is there because a lower `F` along the valley need not be nearer the
//!    truth's ratios: on the built-in example it took one of two seeds' loss in held-out
//!    error under the true light from +14.4% to +1.1%;
//! 5. after [`PATIENCE`] rounds in a row that kept no move, no more steps in this fit:
//!    where the valley's lower `F` is refused early it is rarely right later (the
//!    built-in example at seed 1 lost 15.8% to moves kept from round 3 on, after two
//!    refused), and a try costs two lighting steps.

/// Rounds that take the step when `run` takes it by default ([`default_rounds`]): the
/// alternation's default cap, so every round does (`bench-results/ratio-step.md`).
pub const DEFAULT_ROUNDS: usize = 8;

/// Training photos from which `run` takes the step by default ([`default_rounds`]). From
/// 9 on it paid on every scene where it kept moves (24 rendered runs: held-out error
/// under the true light ×0.91 median, worst +0.8%; the real Buddha photos ±0.0%). At 6
/// the gain was rarer (3 of 14 runs better) while the first [`PATIENCE`] rounds' probes
/// still cost ~10% of a small run's CPU (`bench-results/ratio-step.md`).
pub const MIN_PHOTOS: usize = 9;

/// Materials up to which `run` takes the step by default ([`default_rounds`]). A round
/// tries one direction per material (two lighting steps each) and the patience stops the
/// step only after two rounds, so its least cost grows with `K`: with the paper's six
/// Minerva materials (10K vertices × 13 photos, the Pareto sweep's defaults) its first two
/// rounds kept none of 12 moves and took the estimate from 11.4 to 43.4 s, the run from
/// 34.4 to 70.6 s. Its gains were measured with 2 to 4 materials
/// (`bench-results/ratio-step.md`).
pub const MAX_MATERIALS: usize = 4;

/// The rounds `run --ratio-steps auto` takes with `training_photos` training photos and
/// `materials` materials: [`DEFAULT_ROUNDS`] from [`MIN_PHOTOS`] photos on and up to
/// [`MAX_MATERIALS`] materials, none otherwise.
pub fn default_rounds(training_photos: usize, materials: usize) -> usize {
    if training_photos >= MIN_PHOTOS && materials <= MAX_MATERIALS {
        DEFAULT_ROUNDS
    } else {
        0
    }
}

/// Rounds in a row that keep no move after which the step stops for the rest of the fit
/// (step 5 above). Over 42 runs of 21 workspaces it changed no run whose moves were kept
/// from the start, took the built-in example's +15.8% and +1.1% to ±0 (bit for bit the
/// plain fit) and every `spot-varying` run to ±0 at ×0.9–1.3 the CPU instead of ×1.4–1.8;
/// it gave up one gain, a 6-photo glossy scene's −29% (`bench-results/ratio-step.md`).
pub const PATIENCE: usize = 2;

/// Probe step `δ` of the log brightness: 10%, about a third of the weak-channel errors
/// the step is for (25–47%, `bench-results/albedo-weak-channel.md`) and three times the
/// ratio error target of issue 25.
pub const PROBE_STEP: f64 = 0.1;

/// The minimiser of the parabola through `(−δ, fm)`, `(0, f0)`, `(δ, fp)`, clamped to
/// `[−2δ, 2δ]`; when the three points are not convex, the end of that interval on the
/// lower probe's side; 0 when any value is not finite.
pub fn parabola_step(fm: f64, f0: f64, fp: f64, delta: f64) -> f64 {
    if !(fm.is_finite() && f0.is_finite() && fp.is_finite() && delta > 0.0) {
        return 0.0;
    }
    let curvature = (fp + fm - 2.0 * f0) / (2.0 * delta * delta);
    let slope = (fp - fm) / (2.0 * delta);
    let t = if curvature > 0.0 {
        -slope / (2.0 * curvature)
    } else if fp < fm {
        2.0 * delta
    } else if fm < fp {
        -2.0 * delta
    } else {
        0.0
    };
    t.clamp(-2.0 * delta, 2.0 * delta)
}

/// Lagrange's weights of the nodes `−δ, 0, δ` at `t`: `Σ_i w_i q(t_i) = q(t)` for every
/// quadratic `q`.
pub fn lagrange_weights(t: f64, delta: f64) -> [f64; 3] {
    let d2 = delta * delta;
    [
        t * (t - delta) / (2.0 * d2),
        (delta - t) * (delta + t) / d2,
        t * (t + delta) / (2.0 * d2),
    ]
}

/// The direction `u = e_j − 1/K` of material `j` among `K`.
pub fn direction(kk: usize, j: usize) -> Vec<f64> {
    (0..kk)
        .map(|k| f64::from(u8::from(k == j)) - 1.0 / kk as f64)
        .collect()
}

/// `λ_{k,b,c} e^{t_c u_k}` (`lambda[k][b][c]`).
pub fn scaled(lambda: &[Vec<[f64; 3]>], u: &[f64], t: [f64; 3]) -> Vec<Vec<[f64; 3]>> {
    lambda
        .iter()
        .zip(u)
        .map(|(lk, &uk)| {
            lk.iter()
                .map(|v| [0, 1, 2].map(|c| v[c] * (t[c] * uk).exp()))
                .collect()
        })
        .collect()
}

/// The directions one step tries: one with two materials (it moves both), one per material
/// otherwise.
pub fn directions(kk: usize) -> usize {
    match kk {
        0 | 1 => 0,
        2 => 1,
        k => k,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_takes_the_step_from_the_photo_threshold_on_up_to_the_material_bound() {
        assert_eq!(default_rounds(0, 2), 0);
        assert_eq!(default_rounds(MIN_PHOTOS - 1, 2), 0);
        assert_eq!(default_rounds(MIN_PHOTOS, 2), DEFAULT_ROUNDS);
        assert_eq!(
            default_rounds(10 * MIN_PHOTOS, MAX_MATERIALS),
            DEFAULT_ROUNDS
        );
        assert_eq!(default_rounds(10 * MIN_PHOTOS, MAX_MATERIALS + 1), 0);
    }

    #[test]
    fn the_parabola_step_finds_a_quadratics_minimum_inside_the_trust_region() {
        // q(t) = 3 (t − m)² + 1, sampled at −δ, 0, δ: the step is m exactly (to rounding,
        // 1e-12 relative to δ) while |m| ≤ 2δ, and the nearer end of the region beyond.
        let delta = 0.1;
        for m in [-0.2, -0.13, -0.05, 0.0, 0.031, 0.17, 0.2] {
            let q = |t: f64| 3.0 * (t - m) * (t - m) + 1.0;
            let t = parabola_step(q(-delta), q(0.0), q(delta), delta);
            assert!((t - m).abs() < 1e-12, "m {m}: t {t}");
        }
        for (m, end) in [(-0.5, -0.2), (0.9, 0.2)] {
            let q = |t: f64| (t - m) * (t - m);
            assert_eq!(parabola_step(q(-delta), q(0.0), q(delta), delta), end);
        }
    }

    #[test]
    fn a_concave_or_flat_or_broken_triple_steps_to_the_lower_side_or_stays() {
        assert_eq!(parabola_step(1.0, 2.0, 0.5, 0.1), 0.2);
        assert_eq!(parabola_step(0.5, 2.0, 1.0, 0.1), -0.2);
        assert_eq!(parabola_step(1.0, 1.0, 1.0, 0.1), 0.0);
        assert_eq!(parabola_step(f64::NAN, 1.0, 0.5, 0.1), 0.0);
        assert_eq!(parabola_step(1.0, 1.0, f64::INFINITY, 0.1), 0.0);
    }

    #[test]
    fn lagrange_weights_reproduce_every_quadratic_and_the_nodes() {
        // Exact for 1, t, t² (so for every quadratic); at a node the weights are its
        // indicator. Tolerance: a few ulps of sums of terms of size ≤ (2δ/δ)² = 4.
        let delta = 0.1;
        for t in [-0.2, -0.1, -0.037, 0.0, 0.05, 0.1, 0.2] {
            let w = lagrange_weights(t, delta);
            let nodes = [-delta, 0.0, delta];
            for (p, exact) in [(0, 1.0), (1, t), (2, t * t)] {
                let got: f64 = (0..3).map(|i| w[i] * nodes[i].powi(p)).sum();
                assert!(
                    (got - exact).abs() < 1e-14,
                    "t {t} power {p}: {got} vs {exact}"
                );
            }
        }
        assert_eq!(lagrange_weights(-0.1, 0.1), [1.0, 0.0, 0.0]);
        assert_eq!(lagrange_weights(0.0, 0.1), [0.0, 1.0, 0.0]);
    }

    #[test]
    fn a_direction_moves_one_material_against_the_mean_and_keeps_the_geometric_mean() {
        // Σ_k u_k = 0: the product of the materials' factors e^{t u_k} is 1, so the step
        // never moves the scale the gauge fixes.
        for kk in 2..6 {
            for j in 0..kk {
                let u = direction(kk, j);
                assert!(u.iter().sum::<f64>().abs() < 1e-15);
                assert!((u[j] - (1.0 - 1.0 / kk as f64)).abs() < 1e-15);
            }
        }
        let lambda = vec![vec![[1.0, 2.0, 4.0]], vec![[1.0, 1.0, 1.0]]];
        let s = scaled(&lambda, &direction(2, 0), [0.2, 0.0, -0.4]);
        let e = |x: f64| x.exp();
        assert_eq!(s[0][0], [e(0.1), 2.0, 4.0 * e(-0.2)]);
        assert_eq!(s[1][0], [e(-0.1), 1.0, e(0.2)]);
        assert_eq!((directions(1), directions(2), directions(3)), (0, 1, 3));
    }
}
