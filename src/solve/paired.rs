//! Two fits compared on the same held-back observations, paired, with the
//! one-standard-error rule (not in the paper).
//!
//! Early stopping's score of a fit is `sqrt(S / Y)`, `S = Σ_p e_p` over the held-back
//! observations `p`, `e_p = Σ_c α_p (y_{p,c} − ŷ_{p,c})²`, `Y = Σ α y²`
//! ([`crate::solve::validation`]). Two fits scored on the same observations differ by
//! `D = S₂ − S₁ = Σ_p d_p`, `d_p = e_p⁽²⁾ − e_p⁽¹⁾`. Read as a sum of `n` draws, its
//! standard error is `SE(D) = √n · s_d`, `s_d² = Σ_p (d_p − d̄)² / (n − 1)`: the pairing
//! removes what both fits get wrong alike (the photos' noise at each observation), so `SE`
//! measures only how differently the two fits predict.
//!
//! The one-standard-error rule (Breiman, Friedman, Olshen & Stone 1984, *Classification
//! and Regression Trees*, §3.4.3; Hastie, Tibshirani & Friedman 2009, *The Elements of
//! Statistical Learning*, §7.10): of two models whose scores differ by less than the
//! difference's standard error, take the more constrained one. `run` applies it where the
//! restart's held fit (the materials held to the coarse-light model's reading, fewer free
//! values than the free fit it competes with) scores within one standard error above the
//! first fit ([`crate::solve::materials::reanchor::fit_again`]).

/// The paired comparison of two fits' validation terms (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Paired {
    /// `D = S₂ − S₁`: positive when the second fit predicts the held-back observations worse.
    pub difference: f64,
    /// `SE(D) = √n · s_d`.
    pub standard_error: f64,
}

impl Paired {
    /// The comparison of the terms `first` and `second` (the same observations, in the same
    /// order); `None` with fewer than two observations, lengths that differ, or a term that
    /// is not finite.
    pub fn of(first: &[f64], second: &[f64]) -> Option<Paired> {
        let n = first.len();
        if n < 2 || second.len() != n {
            return None;
        }
        let d: Vec<f64> = second.iter().zip(first).map(|(b, a)| b - a).collect();
        if d.iter().any(|v| !v.is_finite()) {
            return None;
        }
        let difference: f64 = d.iter().sum();
        let mean = difference / n as f64;
        let var = d.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
        Some(Paired {
            difference,
            standard_error: (n as f64 * var).sqrt(),
        })
    }

    /// Whether the second fit is within one standard error of the first: `D ≤ SE(D)`.
    pub fn second_within_one_se(&self) -> bool {
        self.difference <= self.standard_error
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_constant_difference_has_no_spread_and_is_never_within() {
        // d_p = 0.01 at every observation: D = n · 0.01 > 0 and s_d = 0, so SE = 0 and the
        // second fit is worse beyond any doubt.
        let first = vec![1.0; 50];
        let second = vec![1.01; 50];
        let p = Paired::of(&first, &second).unwrap();
        assert!((p.difference - 0.5).abs() < 1e-12);
        assert!(p.standard_error.abs() < 1e-12);
        assert!(!p.second_within_one_se());
    }

    #[test]
    fn the_standard_error_is_root_n_times_the_sample_deviation() {
        // d alternates +1, −1 around a mean of 0.1 over n = 100: d_p = 0.1 ± 1.
        // D = 10; s_d² = Σ 1 / 99 = 100 / 99; SE = √(100 · 100/99) = 10.050…, so D ≤ SE.
        let first = vec![2.0; 100];
        let second: Vec<f64> = (0..100)
            .map(|i| 2.0 + 0.1 + if i % 2 == 0 { 1.0 } else { -1.0 })
            .collect();
        let p = Paired::of(&first, &second).unwrap();
        assert!((p.difference - 10.0).abs() < 1e-9);
        let want = (100.0f64 * 100.0 / 99.0).sqrt();
        assert!((p.standard_error - want).abs() < 1e-9);
        assert!(p.second_within_one_se());
        // A mean of 0.2 puts D = 20 beyond it (SE = √(100 · 100/99) again).
        let worse: Vec<f64> = second.iter().map(|v| v + 0.1).collect();
        assert!(!Paired::of(&first, &worse).unwrap().second_within_one_se());
    }

    #[test]
    fn a_better_second_fit_is_always_within() {
        let first = vec![1.0, 2.0, 3.0];
        let second = vec![0.5, 2.0, 2.0];
        assert!(Paired::of(&first, &second).unwrap().second_within_one_se());
    }

    #[test]
    fn too_few_or_mismatched_or_non_finite_terms_give_none() {
        assert_eq!(Paired::of(&[1.0], &[2.0]), None);
        assert_eq!(Paired::of(&[1.0, 2.0], &[2.0]), None);
        assert_eq!(Paired::of(&[1.0, f64::NAN], &[2.0, 1.0]), None);
    }
}
