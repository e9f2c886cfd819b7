//! Starts that differ in the materials' relative brightness (not in the paper), for a
//! search judged by the validation score.
//!
//! The paper's start (Sec. 5.2) gives each cluster the median of its vertices' mean
//! colours, which carries the cluster's mean irradiance: on the ablation's three-material
//! scene its albedo ratios are 44–87% off, and the alternation stays in the basin they
//! pick (with a free map per photo the ratios lie along a nearly flat valley of Eq. 9).
//! Started with the TRUE albedo ratios the same fit reaches relit 1.24× the floor instead
//! of 2.16× (`bench-results/estimator-ablation-iterations.md`, section 9).
//!
//! The family: material `k ≥ 1`'s Lambertian weight (basis `lambert`) scaled by
//! `c_k s^{e_k}`, `e_k ∈ {−1, 0, 1}`, every combination but `e = 0` (`3^{K−1} − 1` starts);
//! material 0 is left as it is, since a common scale of all materials is the light's
//! (Eq. 9 is invariant to it). A grid search over the `K − 1` log ratios with the
//! alternation run from each point and the fit with the lowest early-stopping validation
//! score kept, the model selection by held-out error of Hastie, Tibshirani & Friedman
//! (2009, *The Elements of Statistical Learning*, Sec. 7.10) applied to the start. A
//! second round around the kept `c` with `s` square-rooted refines it.

use crate::solve::Materials0;

/// One start of the family: the scale of every material `k ≥ 1` and the materials.
#[derive(Debug, Clone)]
pub struct BrightnessStart {
    /// `c_k s^{e_k}` for `k = 1 … K − 1`.
    pub factors: Vec<f64>,
    /// `base` with those scales applied.
    pub materials: Materials0,
}

/// The family of starts around `centre` (`K − 1` scales, all 1 for the first round) with
/// step `step` (module docs). Empty when `K < 2` or `centre` has the wrong length.
pub fn brightness_starts(
    base: &Materials0,
    lambert: usize,
    centre: &[f64],
    step: f64,
) -> Vec<BrightnessStart> {
    let kk = base.lambda.len();
    if kk < 2 || centre.len() != kk - 1 {
        return Vec::new();
    }
    let n = 3usize.pow(kk as u32 - 1);
    (0..n)
        .filter_map(|code| {
            let e: Vec<i32> = (0..kk - 1)
                .map(|j| (code / 3usize.pow(j as u32) % 3) as i32 - 1)
                .collect();
            if e.iter().all(|&v| v == 0) {
                return None;
            }
            let factors: Vec<f64> = centre
                .iter()
                .zip(&e)
                .map(|(c, &ej)| c * step.powi(ej))
                .collect();
            let mut materials = base.clone();
            for (j, f) in factors.iter().enumerate() {
                if let Some(v) = materials.lambda[j + 1].get_mut(lambert) {
                    *v = v.map(|x| x * f);
                }
            }
            Some(BrightnessStart { factors, materials })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn base(k: usize) -> Materials0 {
        Materials0 {
            lambda: (0..k)
                .map(|j| vec![[0.1 * (j + 1) as f64, 0.2, 0.3], [0.05, 0.05, 0.05]])
                .collect(),
            weights: vec![1.0 / k as f64; 4 * k],
        }
    }

    #[test]
    fn every_combination_but_the_centre_once() {
        let b = base(3);
        let s = brightness_starts(&b, 0, &[1.0, 2.0], 2.0);
        assert_eq!(s.len(), 8);
        let mut seen: Vec<Vec<f64>> = s.iter().map(|x| x.factors.clone()).collect();
        seen.sort_by(|a, b| a.partial_cmp(b).expect("finite factors"));
        seen.dedup();
        assert_eq!(seen.len(), 8);
        for f in &seen {
            assert!(f[0] == 0.5 || f[0] == 1.0 || f[0] == 2.0, "{f:?}");
            assert!(f[1] == 1.0 || f[1] == 2.0 || f[1] == 4.0, "{f:?}");
            assert!(f != &vec![1.0, 2.0]);
        }
    }

    #[test]
    fn only_the_lambertian_rows_of_materials_after_the_first_change() {
        let b = base(3);
        for st in brightness_starts(&b, 0, &[1.0, 1.0], 2.0) {
            let m = &st.materials;
            assert_eq!(m.lambda[0], b.lambda[0]);
            assert_eq!(m.weights, b.weights);
            for j in 1..3 {
                assert_eq!(m.lambda[j][1], b.lambda[j][1]);
                for c in 0..3 {
                    // A product of two floats: exact up to one rounding.
                    let want = b.lambda[j][0][c] * st.factors[j - 1];
                    assert!((m.lambda[j][0][c] - want).abs() <= 1e-15, "{j} {c}");
                }
            }
        }
    }

    #[test]
    fn one_material_or_a_wrong_centre_gives_none() {
        assert!(brightness_starts(&base(1), 0, &[], 2.0).is_empty());
        assert!(brightness_starts(&base(3), 0, &[1.0], 2.0).is_empty());
    }
}
