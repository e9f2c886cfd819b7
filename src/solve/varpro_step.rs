//! The variable-projection step: every material's `λ` moved at once by a damped
//! Gauss–Newton step of the objective with the lights eliminated (issue 25, not in the
//! paper).
//!
//! The alternation moves `λ` with the lights fixed and the lights with `λ` fixed. Where a
//! change of `λ` is nearly undone by a change of the lights (a shiny lobe against the
//! diffuse colour of the same material, both against the maps), both block steps are short
//! and the alternation crawls. Variable projection (Golub & Pereyra 2003, "Separable
//! nonlinear least squares: the variable projection method and its applications", Inverse
//! Problems 19; Ruhe & Wedin 1980 for the Gauss–Newton form) takes the lights as a
//! function of the materials, `x*(λ) = argmin_x F(λ, x)`, and steps on the reduced
//! residual `r(λ) = D^{1/2} (y − ŷ(λ, x*(λ)))` (`D = α ω`, the data weights of Eq. 9).
//! The channels are separable (each channel's maps and `λ` see only that channel's data,
//! prior and ridge), so per channel `c` with `θ_c = (λ_{k,b,c})_{k,b}`:
//!
//! 1. the Jacobian by forward differences, one lighting step per `(k, b)` (all three
//!    channels at once): `J_{:,i} = (r(θ + h_i e_i) − r(θ)) / h_i`, each probe's lights
//!    re-solved from the current lights by one block step of the alternation (its QPs run
//!    four times further bought nothing for 1.9× the fit's time: the glossy scene, seed 1,
//!    the fit under the true light 0.0463 against 0.0464, `bench-results/varpro-step.md`);
//!    `r(θ)` itself from one such re-solve at `θ`, so that the columns hold what the
//!    lights' further convergence adds in common;
//! 2. the Levenberg–Marquardt step `(JᵀJ + μ diag(JᵀJ)) Δ = −Jᵀ r(θ)` ([`damped_step`]);
//!    the common scale of `λ` against the lights, which `F` barely sees, is what the
//!    damping holds;
//! 3. `θ + Δ` projected on `λ ≥ 0`, the lights re-solved there once more, and per channel
//!    the move kept where `F_c` (data, the light model's prior, ridge) drops; a channel
//!    that refuses the full step is tried again at a quarter of it.
//!
//! A step costs `K·B + 2` lighting steps (`+1` for a quarter step).
//!
//! With [`crate::solve::EstimateOptions::varpro_broyden`] only the first round (and a round
//! after one that kept nothing) probes; the next rounds carry the Jacobian over, updated by
//! Broyden's rank-one secant from each try's move and the residual change it made
//! ([`broyden_update`]), so a round costs 2 lighting steps. On the glossy Spot (seeds 1–5)
//! the fit took 4.1–4.5× the plain fit's time instead of 7–10×, and kept 35–121% (median
//! 81%) of the probed step's gain under the true light (`bench-results/varpro-step.md`,
//! section 9).

// Numerical kernels index several arrays in step; range loops read like the math.
#![allow(clippy::needless_range_loop)]

use nalgebra::{DMatrix, DVector};

/// The forward-difference step of `λ_{k,b,c}`, relative to the larger of the entry and
/// [`FLOOR_SHARE`] of the material's largest lobe in that channel: 5%, small against the
/// errors the step is for (the glossy scene's weak channels 6–12% off) while the lights'
/// response to it stays well above the inexact QPs' residual.
pub const PROBE_STEP: f64 = 0.05;

/// A zero `λ_{k,b,c}` is probed at this share of the material's largest `λ` in channel
/// `c`, so that a lobe the fit has emptied can come back.
pub const FLOOR_SHARE: f64 = 0.2;

/// Levenberg–Marquardt's `μ` (relative to `diag(JᵀJ)`).
pub const DAMPING: f64 = 1e-2;

/// Rounds that `run --varpro-steps auto` takes ([`default_rounds`]), as the ratio step's
/// default.
pub const DEFAULT_ROUNDS: usize = 8;

/// The rounds `run --varpro-steps auto` takes (with [`broyden_update`]'s Jacobian): for
/// a fit over the Lambertian lobe alone of two or more materials, where the ratio step
/// runs too ([`crate::solve::ratio_step::default_rounds`]), [`DEFAULT_ROUNDS`]; none
/// otherwise. Over the Lambertian lobe alone a round costs `K + 2` lighting steps in the
/// first round and 2 after. On the rendered diffuse Spot (two materials, 24 training
/// photos, seeds 1–5) it brought the worst albedo ratio within 3% on 5 of 5 seeds (4 of 5
/// without) at 1.3–3.2× the fit's time. On the real Buddha photos, each photo held out
/// in turn (6 folds × 3 seeds, 13 fits where it ran), the held-out headline moved by a
/// mean −0.5% (7 lower, 6 higher), so it is `run`'s default (`bench-results/varpro-step.md`,
/// sections 9–10). Shiny fits are left out: on three materials with a shiny lobe the
/// step put the fit further from the truth on 2 of 3 seeds (section 4), and on the
/// glossy scene it left the worst ratio worse than without on 5 of 5 (section 9).
pub fn default_rounds(training_photos: usize, materials: usize, lambertian_alone: bool) -> usize {
    let ratio = crate::solve::ratio_step::default_rounds(training_photos, materials);
    if lambertian_alone && materials >= 2 && ratio > 0 {
        DEFAULT_ROUNDS
    } else {
        0
    }
}

/// One entry `(k, b)` of `λ` and its forward-difference step per channel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Parameter {
    /// Material `k`.
    pub material: usize,
    /// Basis lobe `b`.
    pub lobe: usize,
    /// `h_{k,b,c}` (0 where the material is black in channel `c`).
    pub step: [f64; 3],
}

/// Every `(k, b)` of `lambda[k][b][c]` with its step (the module's constants).
pub fn parameters(lambda: &[Vec<[f64; 3]>]) -> Vec<Parameter> {
    let mut out = Vec::new();
    for (k, lk) in lambda.iter().enumerate() {
        let largest = [0, 1, 2].map(|c| lk.iter().map(|v| v[c]).fold(0.0, f64::max));
        for (b, v) in lk.iter().enumerate() {
            let step = [0, 1, 2].map(|c| PROBE_STEP * v[c].max(FLOOR_SHARE * largest[c]));
            out.push(Parameter {
                material: k,
                lobe: b,
                step,
            });
        }
    }
    out
}

/// `lambda` with entry `p` moved by its step.
pub fn probed(lambda: &[Vec<[f64; 3]>], p: &Parameter) -> Vec<Vec<[f64; 3]>> {
    let mut out = lambda.to_vec();
    let v = &mut out[p.material][p.lobe];
    for c in 0..3 {
        v[c] += p.step[c];
    }
    out
}

/// `lambda + t Δ`, projected on `λ ≥ 0`; `delta[i][c]` is the move of `params[i]`.
pub fn moved(
    lambda: &[Vec<[f64; 3]>],
    params: &[Parameter],
    delta: &[[f64; 3]],
    t: [f64; 3],
) -> Vec<Vec<[f64; 3]>> {
    let mut out = lambda.to_vec();
    for (p, d) in params.iter().zip(delta) {
        let v = &mut out[p.material][p.lobe];
        for c in 0..3 {
            v[c] = (v[c] + t[c] * d[c]).max(0.0);
        }
    }
    out
}

/// The reduced residual's Jacobian: `columns[i][p][c] = ∂r_{p,c} / ∂θ_{i,c}` (a channel of
/// a zero step has a zero column).
#[derive(Debug, Clone)]
pub struct Jacobian {
    /// One column per [`Parameter`], per observation and channel.
    pub columns: Vec<Vec<[f64; 3]>>,
}

/// The forward-difference Jacobian: column `i` is `(probes[i] − r0) / params[i].step`.
pub fn forward_differences(
    probes: &[Vec<[f64; 3]>],
    r0: &[[f64; 3]],
    params: &[Parameter],
) -> Jacobian {
    let columns = probes
        .iter()
        .zip(params)
        .map(|(probe, p)| {
            probe
                .iter()
                .zip(r0)
                .map(|(q, r)| {
                    [0, 1, 2].map(|c| {
                        let h = p.step[c];
                        if h > 0.0 {
                            (q[c] - r[c]) / h
                        } else {
                            0.0
                        }
                    })
                })
                .collect()
        })
        .collect();
    Jacobian { columns }
}

/// Broyden's rank-one update per channel (Broyden 1965, "A class of methods for solving
/// nonlinear simultaneous equations", Math. Comp. 19): `J_c ← J_c + (Δr_c − J_c s_c) s_cᵀ /
/// (s_cᵀ s_c)`, the least change of `J_c` (in the Frobenius norm) that satisfies the secant
/// condition `J_c s_c = Δr_c`; `s[i][c]` the move of parameter `i`, `dr` the residual's
/// change it made. A channel that did not move keeps its columns.
pub fn broyden_update(jac: &mut Jacobian, s: &[[f64; 3]], dr: &[[f64; 3]]) {
    for c in 0..3 {
        let ss: f64 = s.iter().map(|v| v[c] * v[c]).sum();
        if ss <= 0.0 {
            continue;
        }
        for p in 0..dr.len() {
            let js: f64 = jac
                .columns
                .iter()
                .zip(s)
                .map(|(col, v)| col[p][c] * v[c])
                .sum();
            let u = (dr[p][c] - js) / ss;
            for (col, v) in jac.columns.iter_mut().zip(s) {
                col[p][c] += u * v[c];
            }
        }
    }
}

/// Per channel, `JᵀJ` and `Jᵀ r0`.
pub fn normal_equations(jac: &Jacobian, r0: &[[f64; 3]]) -> [(DMatrix<f64>, DVector<f64>); 3] {
    let n = jac.columns.len();
    [0, 1, 2].map(|c| {
        let mut jtj = DMatrix::<f64>::zeros(n, n);
        let mut jtr = DVector::<f64>::zeros(n);
        for p in 0..r0.len() {
            for i in 0..n {
                let ji = jac.columns[i][p][c];
                if ji == 0.0 {
                    continue;
                }
                jtr[i] += ji * r0[p][c];
                for j in i..n {
                    jtj[(i, j)] += ji * jac.columns[j][p][c];
                }
            }
        }
        for i in 0..n {
            for j in 0..i {
                jtj[(i, j)] = jtj[(j, i)];
            }
        }
        (jtj, jtr)
    })
}

/// The Levenberg–Marquardt step `Δ` of `(JᵀJ + μ diag(JᵀJ)) Δ = −Jᵀ r0`; a parameter
/// whose column is zero does not move. `None` when the damped system is not positive
/// definite or the step is not finite.
pub fn damped_step(jtj: &DMatrix<f64>, jtr: &DVector<f64>, mu: f64) -> Option<DVector<f64>> {
    let n = jtr.len();
    let live: Vec<usize> = (0..n).filter(|&i| jtj[(i, i)] > 0.0).collect();
    let mut a = DMatrix::<f64>::zeros(live.len(), live.len());
    let mut g = DVector::<f64>::zeros(live.len());
    for (u, &i) in live.iter().enumerate() {
        g[u] = -jtr[i];
        for (v, &j) in live.iter().enumerate() {
            a[(u, v)] = jtj[(i, j)];
        }
        a[(u, u)] *= 1.0 + mu;
    }
    let d = a.cholesky()?.solve(&g);
    let mut out = DVector::<f64>::zeros(n);
    for (u, &i) in live.iter().enumerate() {
        out[i] = d[u];
    }
    out.iter().all(|v| v.is_finite()).then_some(out)
}

/// The three channels' steps as `delta[i][c]` (a channel without a step does not move).
pub fn steps(system: &[(DMatrix<f64>, DVector<f64>); 3], mu: f64) -> Vec<[f64; 3]> {
    let per: Vec<Option<DVector<f64>>> = system
        .iter()
        .map(|(jtj, jtr)| damped_step(jtj, jtr, mu))
        .collect();
    let n = system[0].1.len();
    (0..n)
        .map(|i| [0, 1, 2].map(|c| per[c].as_ref().map_or(0.0, |d| d[i])))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A separable linear model per channel, `r_c(θ) = y_c − A θ_c`, whose forward
    /// differences are exact: one undamped step lands on the least-squares solution.
    /// `A`, the three channels' `y`, and a start `λ`.
    type LinearCase = (DMatrix<f64>, [DVector<f64>; 3], Vec<Vec<[f64; 3]>>);

    fn linear_case() -> LinearCase {
        // 6 observations, 2 materials × 2 lobes; A of full column rank.
        let a = DMatrix::from_row_slice(
            6,
            4,
            &[
                1.0, 0.3, 0.0, 0.0, //
                0.8, 0.9, 0.1, 0.0, //
                0.0, 0.2, 1.0, 0.4, //
                0.2, 0.0, 0.7, 1.1, //
                0.5, 0.5, 0.5, 0.5, //
                0.1, 0.7, 0.0, 0.9,
            ],
        );
        let y = [
            DVector::from_row_slice(&[1.0, 2.0, 0.5, 0.7, 1.1, 0.3]),
            DVector::from_row_slice(&[0.2, 0.4, 0.9, 1.5, 0.8, 0.6]),
            DVector::from_row_slice(&[0.6, 0.6, 0.6, 0.6, 0.6, 0.6]),
        ];
        let lambda = vec![
            vec![[0.5, 0.5, 0.5], [0.1, 0.2, 0.3]],
            vec![[0.4, 0.3, 0.2], [0.0, 0.1, 0.2]],
        ];
        (a, y, lambda)
    }

    fn residuals(
        a: &DMatrix<f64>,
        y: &[DVector<f64>; 3],
        lambda: &[Vec<[f64; 3]>],
    ) -> Vec<[f64; 3]> {
        let r: Vec<DVector<f64>> = (0..3)
            .map(|c| {
                let theta = DVector::from_iterator(4, lambda.iter().flatten().map(|v| v[c]));
                &y[c] - a * theta
            })
            .collect();
        (0..a.nrows())
            .map(|p| [r[0][p], r[1][p], r[2][p]])
            .collect()
    }

    #[test]
    fn an_undamped_step_on_a_linear_model_is_the_least_squares_solution() {
        let (a, y, lambda) = linear_case();
        let params = parameters(&lambda);
        assert_eq!(params.len(), 4);
        let r0 = residuals(&a, &y, &lambda);
        let probes: Vec<Vec<[f64; 3]>> = params
            .iter()
            .map(|p| residuals(&a, &y, &probed(&lambda, p)))
            .collect();
        let system = normal_equations(&forward_differences(&probes, &r0, &params), &r0);
        let delta = steps(&system, 0.0);
        let ata = a.transpose() * &a;
        for c in 0..3 {
            // The normal equations' solution, by an independent factorisation (LU of AᵀA).
            let exact = ata.clone().lu().solve(&(a.transpose() * &y[c])).unwrap();
            for (i, p) in params.iter().enumerate() {
                let got = lambda[p.material][p.lobe][c] + delta[i][c];
                // Forward differences of a linear map are exact up to rounding of
                // (r(θ + h) − r(θ)) / h with h ≥ 0.005: 1e-9 is ~1e5 ulps of margin.
                assert!(
                    (got - exact[i]).abs() < 1e-9,
                    "channel {c} parameter {i}: {got} vs {}",
                    exact[i]
                );
            }
        }
    }

    #[test]
    fn damping_shortens_the_step_and_a_zero_column_stays_put() {
        let jtj = DMatrix::from_row_slice(2, 2, &[2.0, 0.0, 0.0, 0.0]);
        let jtr = DVector::from_row_slice(&[-4.0, 0.0]);
        // Cholesky of a diagonal system: exact up to a rounding of the square root (1e-12).
        let free = damped_step(&jtj, &jtr, 0.0).unwrap();
        assert!((free[0] - 2.0).abs() < 1e-12 && free[1] == 0.0);
        // μ = 1 doubles the diagonal: the step halves.
        let damped = damped_step(&jtj, &jtr, 1.0).unwrap();
        assert!((damped[0] - 1.0).abs() < 1e-12);
        // An indefinite system has no step.
        let bad = DMatrix::from_row_slice(2, 2, &[1.0, 2.0, 2.0, 1.0]);
        assert!(damped_step(&bad, &DVector::from_row_slice(&[1.0, 1.0]), 0.0).is_none());
    }

    #[test]
    fn probes_move_one_entry_and_zero_entries_get_a_floor_step() {
        let lambda = vec![vec![[0.5, 0.0, 1.0], [0.0, 0.0, 0.2]]];
        let params = parameters(&lambda);
        assert_eq!(params[0].step, [0.025, 0.0, 0.05]);
        // λ_{0,1,0} = 0 against the material's largest red 0.5: 5% of 0.2 × 0.5.
        assert!((params[1].step[0] - 0.005).abs() < 1e-15);
        assert_eq!(params[1].step[1], 0.0);
        let p = probed(&lambda, &params[1]);
        assert_eq!(p[0][0], lambda[0][0]);
        assert!((p[0][1][2] - 0.21).abs() < 1e-15);
        let m = moved(
            &lambda,
            &params,
            &[[-1.0, 0.0, 0.1], [0.1, 0.0, 0.0]],
            [1.0, 1.0, 0.5],
        );
        assert_eq!(m[0][0], [0.0, 0.0, 1.05]);
        assert_eq!(m[0][1][0], 0.1);
    }

    /// On a linear model the forward differences are the exact Jacobian, which an exact
    /// secant pair leaves as it is; from a wrong Jacobian one update satisfies the secant
    /// condition and leaves `J v` unchanged for `v` orthogonal to the move.
    #[test]
    fn broyden_keeps_an_exact_jacobian_and_meets_the_secant_condition() {
        let (a, y, lambda) = linear_case();
        let params = parameters(&lambda);
        let r0 = residuals(&a, &y, &lambda);
        let probes: Vec<Vec<[f64; 3]>> = params
            .iter()
            .map(|p| residuals(&a, &y, &probed(&lambda, p)))
            .collect();
        let exact = forward_differences(&probes, &r0, &params);
        let s = [
            [0.1, -0.2, 0.05],
            [0.0, 0.3, 0.1],
            [-0.1, 0.1, 0.2],
            [0.2, 0.0, -0.1],
        ];
        let dr: Vec<[f64; 3]> = (0..a.nrows())
            .map(|p| [0, 1, 2].map(|c| (0..4).map(|i| exact.columns[i][p][c] * s[i][c]).sum()))
            .collect();
        let mut same = exact.clone();
        broyden_update(&mut same, &s, &dr);
        // Rounding of sums of 4 products of O(1) numbers: 1e-12.
        let close = |x: f64, y: f64| (x - y).abs() < 1e-12;
        for (cs, ce) in same.columns.iter().zip(&exact.columns) {
            for (u, v) in cs.iter().zip(ce) {
                assert!((0..3).all(|c| close(u[c], v[c])), "{u:?} vs {v:?}");
            }
        }
        let mut wrong = Jacobian {
            columns: vec![vec![[0.5, -0.3, 1.0]; a.nrows()]; 4],
        };
        let before = wrong.clone();
        broyden_update(&mut wrong, &s, &dr);
        // Channel 0's move has no component on parameter 1: that column stays.
        for p in 0..a.nrows() {
            for c in 0..3 {
                let js: f64 = (0..4).map(|i| wrong.columns[i][p][c] * s[i][c]).sum();
                assert!(close(js, dr[p][c]), "secant: {js} vs {}", dr[p][c]);
            }
            assert!(close(wrong.columns[1][p][0], before.columns[1][p][0]));
        }
    }
}
