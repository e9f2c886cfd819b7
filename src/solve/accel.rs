//! Anderson acceleration of the alternation over the materials' `λ` (issue 25, not in the
//! paper; [`crate::solve::EstimateOptions::anderson_depth`]).
//!
//! Seen from the `K·B·3` material parameters, one outer iteration of the alternation is a
//! fixed-point map `λ ↦ G(λ)`: the lights and the blending weights are re-solved by their
//! block minimisations and `λ` by its NNLS (variable projection's view, with `λ` the outer
//! variables and the lights and weights eliminated). The iteration crawls along the
//! bilinear valley (`estimator-ablation-iterations.md`); Anderson acceleration (Walker &
//! Ni 2011, "Anderson acceleration for fixed-point iterations", SIAM J. Numer. Anal.
//! 49(4), Eq. 2.1–2.3, the "type II" form) extrapolates from the last `m + 1` pairs
//! `(x_i, g_i = G(x_i))` with residuals `f_i = g_i − x_i`:
//!
//! `γ = argmin_γ ‖f_t − ΔF γ‖₂` (columns `f_{i+1} − f_i`), `x̂ = g_t − ΔG γ` (columns
//! `g_{i+1} − g_i`), projected to `≥ 0`.
//!
//! On a linear map `G(x) = A x + b` of dimension `n` with `m ≥ n` it reaches the fixed
//! point in at most `n + 1` steps (it is then equivalent to GMRES, Walker & Ni Sec. 4).
//! **Safeguard**: the candidate's weights are re-solved (the `w` step under the current
//! lights), its lights refitted (one lighting step) and `F` evaluated; it is kept only
//! when `F` is below the current iterate's, otherwise the state (lights, `λ`, `w`, IRLS
//! weights) is restored, so `F` never rises. The history is then cleared (a rejected
//! candidate means the local linear model is stale). Each try costs one lighting step.
//! The step itself is the alternation's (`Alternation::anderson_step`); this module holds
//! the history and the extrapolation.

use std::collections::VecDeque;

use nalgebra::{DMatrix, DVector};

/// The pairs `(x_i, G(x_i))` Anderson acceleration extrapolates from.
#[derive(Debug, Clone, Default)]
pub struct AndersonHistory {
    /// How many differences the extrapolation uses (`m`).
    depth: usize,
    /// Inputs `x_i` of the last outer iterations (flattened `λ`).
    xs: VecDeque<Vec<f64>>,
    /// Their outputs `g_i`.
    gs: VecDeque<Vec<f64>>,
    /// The input of the running outer iteration.
    input: Option<Vec<f64>>,
    /// Candidates tried and kept.
    pub tried: usize,
    /// Candidates kept.
    pub kept: usize,
}

impl AndersonHistory {
    /// An empty history of depth `m`.
    pub fn new(depth: usize) -> Self {
        AndersonHistory {
            depth,
            ..Default::default()
        }
    }

    /// Records `g = G(input)` and returns the extrapolated point, if the history has two
    /// pairs or more.
    pub fn push(&mut self, g: Vec<f64>) -> Option<Vec<f64>> {
        let x = self.input.take()?;
        self.xs.push_back(x);
        self.gs.push_back(g);
        while self.xs.len() > self.depth + 1 {
            self.xs.pop_front();
            self.gs.pop_front();
        }
        let (xs, gs): (Vec<Vec<f64>>, Vec<Vec<f64>>) = (
            self.xs.iter().cloned().collect(),
            self.gs.iter().cloned().collect(),
        );
        anderson_mix(&xs, &gs)
    }

    /// Marks `x` as the input of the next outer iteration.
    pub fn start(&mut self, x: Vec<f64>) {
        self.input = Some(x);
    }

    /// Forgets the pairs (after a rejected candidate).
    pub fn clear(&mut self) {
        self.xs.clear();
        self.gs.clear();
    }
}

/// Anderson's extrapolation (module docs) from pairs `(xs[i], gs[i])`, oldest first;
/// `None` with fewer than two pairs or a non-finite result.
pub fn anderson_mix(xs: &[Vec<f64>], gs: &[Vec<f64>]) -> Option<Vec<f64>> {
    let n = xs.len();
    if n < 2 {
        return None;
    }
    let dim = xs[0].len();
    let f: Vec<Vec<f64>> = (0..n)
        .map(|i| (0..dim).map(|j| gs[i][j] - xs[i][j]).collect())
        .collect();
    let cols = n - 1;
    let df = DMatrix::from_fn(dim, cols, |j, i| f[i + 1][j] - f[i][j]);
    let ft = DVector::from_column_slice(&f[n - 1]);
    let scale = df.iter().fold(0.0_f64, |a, &v| a.max(v.abs()));
    if scale == 0.0 {
        return None;
    }
    let gamma = df.svd(true, true).solve(&ft, 1e-12 * scale).ok()?;
    let out: Vec<f64> = (0..dim)
        .map(|j| {
            let dg: f64 = (0..cols)
                .map(|i| (gs[i + 1][j] - gs[i][j]) * gamma[i])
                .sum();
            gs[n - 1][j] - dg
        })
        .collect();
    out.iter().all(|v| v.is_finite()).then_some(out)
}

/// `λ[k][b][c]` flattened, `k` major.
pub(crate) fn flatten(lambda: &[Vec<[f64; 3]>]) -> Vec<f64> {
    lambda.iter().flatten().flatten().copied().collect()
}

/// `flat` back into `lambda`'s shape, projected to `≥ 0`.
pub(crate) fn unflatten(flat: &[f64], like: &[Vec<[f64; 3]>]) -> Vec<Vec<[f64; 3]>> {
    let mut it = flat.iter().map(|v| v.max(0.0));
    like.iter()
        .map(|l| {
            l.iter()
                .map(|_| [0, 1, 2].map(|_| it.next().unwrap_or(0.0)))
                .collect()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `G(x) = A x + b` with a slowly contracting `A` (spectral radius 0.95): the plain
    /// iteration is still ~0.95^k away after k steps; Anderson with `m ≥ n` reaches the
    /// fixed point `x* = (I − A)⁻¹ b` in `n + 1` steps (module docs).
    #[test]
    fn anderson_solves_a_linear_fixed_point_in_n_plus_one_steps() {
        let a = [[0.9, 0.05, 0.0], [0.02, 0.85, 0.05], [0.0, 0.1, 0.8]];
        let b = [1.0, 0.5, 0.25];
        let g = |x: &[f64]| -> Vec<f64> {
            (0..3)
                .map(|i| (0..3).map(|j| a[i][j] * x[j]).sum::<f64>() + b[i])
                .collect()
        };
        // x* by Gaussian elimination of (I − A) x = b (nalgebra's LU).
        let m = DMatrix::from_fn(3, 3, |i, j| f64::from(u8::from(i == j)) - a[i][j]);
        let xstar = m.lu().solve(&DVector::from_row_slice(&b)).unwrap();
        let mut hist = AndersonHistory::new(3);
        let mut x = vec![0.0; 3];
        let mut plain = x.clone();
        for _ in 0..5 {
            hist.start(x.clone());
            let gx = g(&x);
            x = hist.push(gx.clone()).unwrap_or(gx);
            plain = g(&plain);
        }
        // After n + 1 = 4 pairs the extrapolation is exact up to rounding (the SVD's
        // least squares on differences of size ~0.1: 1e-9 is ample).
        for i in 0..3 {
            assert!((x[i] - xstar[i]).abs() < 1e-9, "{x:?} vs {xstar}");
        }
        // The plain iteration after the same 5 maps is still far (≥ 10% off somewhere).
        let worst = (0..3)
            .map(|i| (plain[i] - xstar[i]).abs() / xstar[i])
            .fold(0.0_f64, f64::max);
        assert!(worst > 0.1, "{plain:?} vs {xstar}");
    }

    #[test]
    fn fewer_than_two_pairs_give_no_step() {
        assert!(anderson_mix(&[vec![1.0]], &[vec![2.0]]).is_none());
        let mut h = AndersonHistory::new(2);
        assert!(h.push(vec![1.0]).is_none());
    }
}
