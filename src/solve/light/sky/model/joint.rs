//! Step 3 of a photo's sun-and-sky lighting step (parent module docs): the joint QP in
//! `z = (w, r)`, the nine colour weights and the residual's texels,
//! `min ½ zᵀ (Pᵀ Wᵀ Aᵀ D A W P + R) z − bᵀ z` subject to `z ≥ 0`, where `P z = B w + r`
//! puts the weights through the bases at the chosen `θ`, `Wᵀ Aᵀ D A W` is the photo's
//! weighted lighting system and `R` the residual prior's reweighted Haar penalty
//! (`d_k`, [`super::super::residual_weights`]). Solved matrix-free by
//! [`crate::solve::qp::bound_qp_scaled`], Jacobi scaled.

use super::{Candidate, Rows, SkyLight, N_BASIS};
use crate::solve::light::sh_prior::haar_diag_in_texels;
use crate::solve::light::sky::SkyBasis;
use crate::solve::light::system::{split3, unhaar3, PhotoSystem};
use crate::solve::problem::haar3;
use crate::solve::qp::{bound_qp_scaled, QpOptions, QpResult};
use crate::{Error, Result};

/// The joint QP's answer `z = (w, r)` as the colour weights and the residual's texels per
/// channel (`n × n` maps); zero when there was no QP (no light reaches any weighted
/// observation, so the minimiser is zero).
pub(super) fn split_joint(
    res: Option<&QpResult>,
    n: usize,
) -> ([[f64; 3]; N_BASIS], [Vec<f64>; 3]) {
    let n2 = n * n;
    match res {
        Some(res) => {
            let weights = std::array::from_fn(|j| std::array::from_fn(|c| res.x[j * 3 + c]));
            (weights, split3(&res.x[JointQp::NW..], n2))
        }
        None => ([[0.0; 3]; N_BASIS], std::array::from_fn(|_| vec![0.0; n2])),
    }
}

/// The joint QP of one photo in `z = (w, r)` (module docs of the parent).
pub(super) struct JointQp<'a> {
    pub(super) sys: &'a PhotoSystem,
    pub(super) basis: &'a SkyBasis,
    /// Residual weights `d_k` per channel.
    pub(super) d: [Vec<f64>; 3],
}

impl JointQp<'_> {
    const NW: usize = N_BASIS * 3;

    /// The texels `x = B w + r`, channel-major, of `z`.
    fn texels(&self, z: &[f64]) -> Vec<f64> {
        let n2 = self.sys.n * self.sys.n;
        let mut x = z[Self::NW..].to_vec();
        for j in 0..N_BASIS {
            for c in 0..3 {
                let w = z[j * 3 + c];
                if w != 0.0 {
                    let bm = &self.basis.maps[j][c];
                    x[c * n2..(c + 1) * n2]
                        .iter_mut()
                        .zip(bm)
                        .for_each(|(a, b)| *a += w * b);
                }
            }
        }
        x
    }

    /// `out = (Bᵀ g, g)` for a texel-space gradient `g` (channel-major).
    fn pull_back(&self, g: &[f64], out: &mut [f64]) {
        let n2 = self.sys.n * self.sys.n;
        for j in 0..N_BASIS {
            for c in 0..3 {
                let bm = &self.basis.maps[j][c];
                out[j * 3 + c] = bm
                    .iter()
                    .zip(&g[c * n2..(c + 1) * n2])
                    .map(|(a, b)| a * b)
                    .sum();
            }
        }
        out[Self::NW..].copy_from_slice(g);
    }

    /// `Wᵀ Aᵀ D A W x` for channel-major texels.
    fn data_hessian(&self, x: &[f64]) -> Vec<f64> {
        let n = self.sys.n;
        let h = haar3(&split3(x, n * n), n);
        let mut hb = vec![[0.0; 3]; n * n];
        self.sys.normal_rows(&h, &mut hb);
        unhaar3(&hb, n)
    }

    /// The Hessian product.
    fn hess(&self, z: &[f64], out: &mut [f64]) {
        let n = self.sys.n;
        let n2 = n * n;
        let hx = self.data_hessian(&self.texels(z));
        self.pull_back(&hx, out);
        let mut h = haar3(&split3(&z[Self::NW..], n2), n);
        for (k, hk) in h.iter_mut().enumerate() {
            for c in 0..3 {
                hk[c] *= self.d[c][k];
            }
        }
        let pen = unhaar3(&h, n);
        out[Self::NW..]
            .iter_mut()
            .zip(&pen)
            .for_each(|(a, b)| *a += b);
    }

    /// The Jacobi scaling: `B_jᵀ H B_j` per weight, the texel diagonal of the data term
    /// plus the prior's per residual texel.
    fn diagonal(&self, tdiag: &[[f64; 3]]) -> Vec<f64> {
        let n = self.sys.n;
        let n2 = n * n;
        let mut diag = vec![0.0; Self::NW + 3 * n2];
        for j in 0..N_BASIS {
            let x: Vec<f64> = self.basis.maps[j].iter().flatten().copied().collect();
            let hx = self.data_hessian(&x);
            for c in 0..3 {
                diag[j * 3 + c] = self.basis.maps[j][c]
                    .iter()
                    .zip(&hx[c * n2..(c + 1) * n2])
                    .map(|(a, b)| a * b)
                    .sum();
            }
        }
        for c in 0..3 {
            let pd = haar_diag_in_texels(&self.d[c], n);
            for t in 0..n2 {
                diag[Self::NW + c * n2 + t] = tdiag[t][c] + pd[t];
            }
        }
        diag
    }
}

impl SkyLight {
    /// Step 3, the joint QP from the search's weights and the previous residual, Jacobi
    /// scaled from the data term's texel diagonal `tdiag`; `None` when no light reaches any
    /// weighted observation (`b = 0`).
    pub(super) fn joint_qp(
        &self,
        qp: &JointQp,
        rows: &Rows,
        best: &Candidate,
        photo: usize,
        tdiag: &[[f64; 3]],
    ) -> Result<Option<QpResult>> {
        let (sys, n) = (qp.sys, qp.sys.n);
        let n2 = n * n;
        let prev = &self.params[photo];
        let bx = sys.texel_rhs(&rows.y);
        let mut b = vec![0.0; JointQp::NW + 3 * n2];
        qp.pull_back(&bx, &mut b);
        let bmax = b.iter().fold(0.0_f64, |a, v| a.max(v.abs()));
        if bmax == 0.0 {
            return Ok(None);
        }
        let mut z0: Vec<f64> = best.weights.iter().flatten().copied().collect();
        z0.extend(prev.residual.iter().flatten());
        let jac = qp.diagonal(tdiag);
        let opts = QpOptions {
            tol: self.opts.qp_rel_tol * bmax,
            max_iter: self.qp_max_iter,
            max_cg: self.qp_max_cg.max(1),
        };
        bound_qp_scaled(|v, o| qp.hess(v, o), &b, &z0, &opts, Some(&jac))
            .map(Some)
            .map_err(|e| Error::Numeric {
                stage: format!("sky lighting step, photo {photo}"),
                message: e.to_string(),
            })
    }
}
