//! The alternating fit the restarts' ratio models share
//! ([`super::irradiance`], [`super::coarse_light`]).
//!
//! Both models predict an observation `p` of a pure vertex of material `k` in photo `I`
//! and channel `c` as `y_{p,c} = ρ_{k,c} a_pᵀ x_{I,c}`: a known design row `a_p` (the
//! normal's harmonics, or the transport's block responses), one unknown vector per photo
//! `x_I` (free, or non-negative) and one albedo per material. The model is bilinear, so it
//! is fitted by alternating the two blocks, each exactly:
//!
//! - with `ρ` fixed, each photo's `x_I` from its normal equations
//!   `(Σ_k ρ_k² G_{I,k}) x_I = Σ_k ρ_k h_{I,k}` (the model's own solve: least squares or
//!   NNLS);
//! - with the `x_I` fixed, each `ρ_k = Σ_I x_I·h_{I,k} / Σ_I x_Iᵀ G_{I,k} x_I`,
//!
//! over the rows' moments per photo and material, `G_{I,k} = Σ a aᵀ` and
//! `h_{I,k} = Σ a y_c`, so a round costs `O(photos · K · d²)` (`d` = the design's length)
//! whatever the number of rows. Each round lowers the squared residual; the ratios
//! `ρ_k / ρ_0` are what the scale-free model determines, so the fit stops when none moves
//! by more than a tolerance.

use nalgebra::{DMatrix, DVector};

use crate::Result;

/// One channel's rows summed per photo and material (module docs).
pub struct PhotoMoments {
    materials: usize,
    /// `photo · K + k`.
    g: Vec<DMatrix<f64>>,
    h: Vec<DVector<f64>>,
}

/// One observation a ratio model reads: its photo, its vertex's material, its radiance and
/// its design row `a_p` (the normal's harmonics, or the transport's block responses).
#[derive(Debug, Clone)]
pub struct ModelRow {
    pub photo: usize,
    pub material: usize,
    pub rgb: [f64; 3],
    pub design: Vec<f64>,
}

impl PhotoMoments {
    /// Channel `c`'s moments of `rows` (designs of one length) over `n_photos` photos and
    /// `materials` materials.
    pub fn of(rows: &[ModelRow], c: usize, n_photos: usize, materials: usize) -> PhotoMoments {
        let dim = rows.first().map_or(0, |r| r.design.len());
        let mut g = vec![DMatrix::zeros(dim, dim); n_photos * materials];
        let mut h = vec![DVector::zeros(dim); n_photos * materials];
        for r in rows {
            let a = DVector::from_column_slice(&r.design);
            let i = r.photo * materials + r.material;
            g[i] += &a * a.transpose();
            h[i] += &a * r.rgb[c];
        }
        PhotoMoments { materials, g, h }
    }

    /// Each photo's unknowns with the albedos `rho` fixed: `solve(Σ_k ρ_k² G_{I,k},
    /// Σ_k ρ_k h_{I,k})`.
    fn photo_unknowns(
        &self,
        rho: &[f64],
        solve: &dyn Fn(DMatrix<f64>, DVector<f64>) -> Result<DVector<f64>>,
    ) -> Result<Vec<DVector<f64>>> {
        let kk = self.materials;
        (0..self.g.len() / kk)
            .map(|i| {
                let d = self.g[i * kk].nrows();
                let (mut ata, mut atb) = (DMatrix::zeros(d, d), DVector::zeros(d));
                for (k, r) in rho.iter().enumerate() {
                    ata += &self.g[i * kk + k] * (r * r);
                    atb += &self.h[i * kk + k] * *r;
                }
                solve(ata, atb)
            })
            .collect()
    }

    /// Each material's albedo in closed form with the photos' unknowns `x` fixed (`rho`'s
    /// value kept where the closed form is not positive).
    fn albedos(&self, x: &[DVector<f64>], rho: &[f64]) -> Vec<f64> {
        let kk = self.materials;
        (0..kk)
            .map(|k| {
                let (mut num, mut den) = (0.0, 0.0);
                for (i, xi) in x.iter().enumerate() {
                    num += xi.dot(&self.h[i * kk + k]);
                    den += xi.dot(&(&self.g[i * kk + k] * xi));
                }
                if den > 0.0 && num > 0.0 {
                    num / den
                } else {
                    rho[k]
                }
            })
            .collect()
    }
}

/// When the alternation stops.
#[derive(Debug, Clone, Copy)]
pub struct Stopping {
    /// Most rounds.
    pub max_rounds: usize,
    /// Stop when no ratio `ρ_k / ρ_0` moves by more than this (relative) in a round.
    pub ratio_tol: f64,
}

/// The albedos per material (module docs) from `rho0` (> 0), each photo's unknowns by
/// `solve`; a material without rows keeps its `rho0`.
pub fn alternate(
    m: &PhotoMoments,
    rho0: &[f64],
    solve: &dyn Fn(DMatrix<f64>, DVector<f64>) -> Result<DVector<f64>>,
    stopping: Stopping,
) -> Result<Vec<f64>> {
    let mut rho: Vec<f64> = rho0.iter().map(|r| r.max(1e-9)).collect();
    for _ in 0..stopping.max_rounds {
        let x = m.photo_unknowns(&rho, solve)?;
        let next = m.albedos(&x, &rho);
        let moved = largest_ratio_move(&next, &rho);
        rho = next;
        if moved <= stopping.ratio_tol {
            break;
        }
    }
    Ok(rho)
}

/// The largest relative move of a ratio `ρ_k / ρ_0` from `rho` to `next` (what
/// [`Stopping::ratio_tol`] bounds).
pub fn largest_ratio_move(next: &[f64], rho: &[f64]) -> f64 {
    (1..rho.len())
        .map(|k| (next[k] / next[0] / (rho[k] / rho[0]) - 1.0).abs())
        .fold(0.0, f64::max)
}
