//! The map's smoothness prior: the 4-neighbour graph Laplacian `Δ` of the full octahedral
//! grid across its folded seams ([`crate::sphere::SphereGrid::neighbors`]), the term
//! `μ ‖Δ x‖²` of the objective (Eq. 9) and its normal matrix `μ ΔᵀΔ`.

use crate::sphere::SphereGrid;

/// The map's graph Laplacian `Δ` on the full octahedral grid (4 neighbours across seams):
/// `(Δ x)_t = Σ_{s ∈ N(t)} (x_t − x_s)`, with `apply` and its transpose.
#[derive(Debug, Clone)]
pub(crate) struct Laplacian {
    nb: Vec<[usize; 4]>,
}

impl Laplacian {
    pub(crate) fn new(n: usize) -> Self {
        let g = SphereGrid::full(n);
        Laplacian {
            nb: (0..n * n).map(|t| g.neighbors(t)).collect(),
        }
    }
    pub(crate) fn apply(&self, x: &[f64], out: &mut [f64]) {
        for (t, nb) in self.nb.iter().enumerate() {
            out[t] = nb.iter().map(|&s| x[t] - x[s]).sum();
        }
    }
    /// `out += μ ΔᵀΔ x`.
    pub(crate) fn add_normal(&self, x: &[f64], mu: f64, out: &mut [f64]) {
        let mut lx = vec![0.0; x.len()];
        self.apply(x, &mut lx);
        for (t, nb) in self.nb.iter().enumerate() {
            let v = mu * lx[t];
            for &s in nb {
                out[t] += v;
                out[s] -= v;
            }
        }
    }
    /// The diagonal of `ΔᵀΔ`: `Σ_r Δ_{r,t}²` with row `r` of `Δ` = 4 at `r`, −1 at each
    /// neighbour (repeated neighbours add up).
    pub(crate) fn normal_diag(&self) -> Vec<f64> {
        let mut diag = vec![0.0; self.nb.len()];
        let mut cols: Vec<(usize, f64)> = Vec::with_capacity(5);
        for (r, nb) in self.nb.iter().enumerate() {
            cols.clear();
            cols.push((r, nb.len() as f64));
            for &s in nb {
                match cols.iter_mut().find(|(c, _)| *c == s) {
                    Some(e) => e.1 -= 1.0,
                    None => cols.push((s, -1.0)),
                }
            }
            for &(c, v) in &cols {
                diag[c] += v * v;
            }
        }
        diag
    }
    pub(crate) fn energy(&self, x: &[f64]) -> f64 {
        let mut lx = vec![0.0; x.len()];
        self.apply(x, &mut lx);
        lx.iter().map(|v| v * v).sum()
    }
}
