//! Per-vertex choice of which materials a vertex blends (not in the paper): after the
//! weights step's NNLS, backward elimination by the Bayesian information criterion.
//!
//! A vertex's weights minimise `F_x(w) = wᵀ M w − 2 wᵀ r + const` (its data term with the
//! weights' priors, [`super::weights_step`]). NNLS keeps every material that lowers `F_x`
//! at all, so a vertex of one material also takes a few percent of another wherever that
//! fits the photos' noise or the model's error there. Dropping material `k` from the
//! support costs `ΔF = F_x(w_{S∖k}) − F_x(w_S)` (each the NNLS minimiser on its support);
//! BIC (Schwarz 1978) drops it when `ΔF < σ² ln n_x`, with `n_x` the vertex's weighted
//! observations (per channel) and `σ²` the data term's residual per observation over all
//! vertices. Repeated, cheapest drop first, while one is accepted.

use nalgebra::{DMatrix, DVector};

use crate::solve::qp::{nnls, NnlsOptions};

/// `wᵀ M w − 2 wᵀ r`: `F_x` up to its constant.
pub fn quadratic(mat: &DMatrix<f64>, rhs: &DVector<f64>, w: &[f64]) -> f64 {
    let n = w.len();
    let mut f = 0.0;
    for i in 0..n {
        if w[i] == 0.0 {
            continue;
        }
        f -= 2.0 * w[i] * rhs[i];
        for j in 0..n {
            f += w[i] * mat[(i, j)] * w[j];
        }
    }
    f
}

/// The NNLS minimiser of [`quadratic`] with the weights outside `support` held at 0.
fn solve_on(mat: &DMatrix<f64>, rhs: &DVector<f64>, support: &[usize]) -> Option<Vec<f64>> {
    let m = DMatrix::from_fn(support.len(), support.len(), |i, j| {
        mat[(support[i], support[j])]
    });
    let r = DVector::from_fn(support.len(), |i, _| rhs[support[i]]);
    let sol = nnls(&m, &r, &NnlsOptions::default()).ok()?;
    let mut w = vec![0.0; rhs.len()];
    for (i, &k) in support.iter().enumerate() {
        w[k] = sol[i];
    }
    Some(w)
}

/// `w` (the NNLS minimiser on every material) with materials dropped by backward
/// elimination while the cheapest drop raises [`quadratic`] by less than `penalty`
/// (module docs: `σ² ln n_x`).
pub fn select_support(mat: &DMatrix<f64>, rhs: &DVector<f64>, w: &[f64], penalty: f64) -> Vec<f64> {
    let mut cur = w.to_vec();
    let mut f_cur = quadratic(mat, rhs, &cur);
    loop {
        let support: Vec<usize> = (0..cur.len()).filter(|&k| cur[k] > 0.0).collect();
        if support.len() <= 1 {
            return cur;
        }
        let best = support
            .iter()
            .filter_map(|&k| {
                let rest: Vec<usize> = support.iter().copied().filter(|&j| j != k).collect();
                let cand = solve_on(mat, rhs, &rest)?;
                let f = quadratic(mat, rhs, &cand);
                Some((f, cand))
            })
            .min_by(|a, b| a.0.total_cmp(&b.0));
        match best {
            Some((f, cand)) if f - f_cur < penalty => {
                cur = cand;
                f_cur = f;
            }
            _ => return cur,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;

    /// A standard normal draw (Box–Muller).
    fn gauss(rng: &mut Pcg64) -> f64 {
        let (u, v): (f64, f64) = (rng.random::<f64>().max(1e-300), rng.random());
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }

    /// A vertex's `n` rows for two materials (correlated columns, as two materials under
    /// the same light are), observations `A w_true + σ ε`: `(M, r)` of its data term.
    fn system(
        rng: &mut Pcg64,
        n: usize,
        w_true: [f64; 2],
        sigma: f64,
    ) -> (DMatrix<f64>, DVector<f64>) {
        let mut mat = DMatrix::zeros(2, 2);
        let mut rhs = DVector::zeros(2);
        for _ in 0..n {
            let s: f64 = 0.5 + rng.random::<f64>();
            let a = [
                s * (0.8 + 0.2 * rng.random::<f64>()),
                s * (0.3 + 0.4 * rng.random::<f64>()),
            ];
            let y = a[0] * w_true[0] + a[1] * w_true[1] + sigma * gauss(rng);
            for i in 0..2 {
                rhs[i] += a[i] * y;
                for j in 0..2 {
                    mat[(i, j)] += a[i] * a[j];
                }
            }
        }
        (mat, rhs)
    }

    /// On a pure vertex the second material's NNLS weight is positive about half the time
    /// (its unconstrained estimate is unbiased around 0), and then dropping it costs
    /// `ΔF = σ² χ²₁` exactly (the drop of one parameter in linear least squares). BIC keeps
    /// it when `χ²₁ > ln n`: `P = ½ P(χ²₁ > ln 60) = ½ · 0.0429 = 0.0215` (`ln 60 = 4.094`,
    /// `P(χ²₁ > 4.094) = erfc(√(4.094/2)) = 0.0430`). Over 2000 vertices the share kept has a
    /// standard deviation of `√(0.0215 · 0.9785 / 2000) = 0.0032`: the test allows 4 of them.
    #[test]
    fn a_pure_vertex_keeps_a_second_material_at_the_bic_rate() {
        let mut rng = Pcg64::seed_from_u64(7);
        let (n, sigma, trials) = (60, 0.05, 2000);
        let mut kept = 0;
        for _ in 0..trials {
            let (mat, rhs) = system(&mut rng, n, [1.0, 0.0], sigma);
            let w = nnls(&mat, &rhs, &NnlsOptions::default()).unwrap();
            let sel = select_support(&mat, &rhs, w.as_slice(), sigma * sigma * (n as f64).ln());
            assert!(sel[0] > 0.0, "the true material stays");
            kept += usize::from(sel[1] > 0.0);
        }
        let share = kept as f64 / trials as f64;
        assert!((share - 0.0215).abs() < 4.0 * 0.0032, "kept {share}");
    }

    /// A blend well above the noise is kept: 30% of the second material over 60 rows at
    /// σ = 0.05 moves `F` by hundreds of `σ²`, far above `ln 60 = 4.1`.
    #[test]
    fn a_real_blend_is_kept_and_its_weights_are_the_nnls_ones() {
        let mut rng = Pcg64::seed_from_u64(8);
        for _ in 0..100 {
            let (mat, rhs) = system(&mut rng, 60, [0.7, 0.3], 0.05);
            let w = nnls(&mat, &rhs, &NnlsOptions::default()).unwrap();
            let sel = select_support(&mat, &rhs, w.as_slice(), 0.0025 * 60f64.ln());
            assert_eq!(sel, w.as_slice().to_vec());
        }
    }

    /// [`quadratic`] is `‖A w − y‖² − ‖y‖²` (the definition of the normal equations).
    #[test]
    fn quadratic_is_the_data_term_up_to_its_constant() {
        let a: [[f64; 2]; 3] = [[1.0, 2.0], [0.5, -1.0], [3.0, 0.25]];
        let y: [f64; 3] = [1.0, 2.0, -0.5];
        let mat = DMatrix::from_fn(2, 2, |i, j| a.iter().map(|r| r[i] * r[j]).sum());
        let rhs = DVector::from_fn(2, |i, _| a.iter().zip(&y).map(|(r, y)| r[i] * y).sum());
        let w = [0.3, 0.7];
        let direct: f64 = a
            .iter()
            .zip(&y)
            .map(|(r, y)| (r[0] * w[0] + r[1] * w[1] - y).powi(2) - y * y)
            .sum();
        assert!((quadratic(&mat, &rhs, &w) - direct).abs() < 1e-12);
    }
}
