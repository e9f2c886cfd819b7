//! The coarse-light model ([`super::coarse_light`]) read over every seen observation, each
//! with its vertex's blend of the materials (`run --restart coarse-light` over the
//! Lambertian lobe alone; not in the paper):
//!
//! `y_{p,c} = (Σ_k w_{x,k} ρ_{k,c}) Σ_{j < r²} A_{p,j} b_{I,c,j}`,  `b_{I,c} ≥ 0`,
//!
//! with `w_x` the first fit's weights at the observed vertex `x`, normalised to sum 1, and
//! `A_p` the Lambertian row's response to each block as in the pure-vertex model.
//!
//! **Why every vertex and the fit's blend.** A photo's pixel at a vertex integrates the
//! surface around it, whose reflectance blends toward the neighbouring vertices, so next
//! to another material a vertex pure in the model is not pure in its photos. Read over
//! the TRUE pure vertices of the ablation's diffuse scene (192² photos, seeds 1–5), the
//! pure-vertex model is 2.6–5.3% off in red, the channel in which the blue material's
//! neighbour is four times brighter; on exact data (no pixel, the model's own transport)
//! 0.7–1.3%, and with the photos' residuals given random signs 0.7–2.1%, so what the
//! photos add is systematic, not noise. The first fit's weights have taken that blend in
//! (its pure vertices keep a few percent of the other material); read with them over
//! every observation the model is 1.1–2.7% off (`bench-results/coarse-light-blend.md`).
//!
//! Fitted as [`super::bilinear`] alternates, with moments per photo and pair of materials,
//! `G_{I,kl} = Σ_p w_k w_l a_p a_pᵀ` and `h_{I,k} = Σ_p w_k y_p a_p`:
//! - each photo's light by NNLS: `(Σ_{kl} ρ_k ρ_l G_{I,kl}) b_I = Σ_k ρ_k h_{I,k}`;
//! - the albedos from the `K × K` normal equations
//!   `Σ_l (Σ_I b_Iᵀ G_{I,kl} b_I) ρ_l = Σ_I b_Iᵀ h_{I,k}`.
//!
//! With one-hot weights both steps are the pure-vertex model's.

use nalgebra::{DMatrix, DVector};

use crate::solve::materials::bilinear::largest_ratio_move;
use crate::solve::materials::coarse_light::{
    block_haar, ridged_nnls, row_block_responses, CoarseRowsInput, MAX_ROUNDS, RATIO_TOL,
};
use crate::Result;

/// One observation the blend model reads: its photo, its vertex's normalised weights, its
/// radiance and its Lambertian row's response to each block.
#[derive(Debug, Clone)]
pub struct BlendRow {
    pub photo: usize,
    pub weights: Vec<f64>,
    pub rgb: [f64; 3],
    pub design: Vec<f64>,
}

/// Every fitted (`α > 0`) observation of a seen vertex whose weights are not all zero.
pub fn seen_blend_rows(input: &CoarseRowsInput) -> Vec<BlendRow> {
    let t = input.transport;
    let kk = input.materials;
    let h = block_haar(t.n_global, input.blocks);
    let obs = input.obs;
    let mut rows = Vec::new();
    for (photo, range) in obs.photo_ranges.iter().enumerate() {
        for p in range.clone().filter(|&p| obs.weight[p] > 0.0) {
            let x = obs.vertex[p] as usize;
            let w = &input.weights[x * kk..(x + 1) * kk];
            if !input.seen[x] || w.iter().sum::<f64>() <= 0.0 {
                continue;
            }
            rows.push(BlendRow {
                photo,
                weights: w.to_vec(),
                rgb: obs.rgb[p].map(f64::from),
                design: row_block_responses(t, p, input.lambert, &h),
            });
        }
    }
    rows
}

/// The materials some row holds the most of (≥ ½ of its weight): those the model can tell
/// apart from the others.
pub fn dominant_materials(rows: &[BlendRow]) -> impl Iterator<Item = usize> + '_ {
    rows.iter()
        .filter_map(|r| r.weights.iter().position(|&w| w >= 0.5))
}

/// The rows summed per photo and pair of materials (module docs): `G` once, `h` per
/// channel, so the three channels' fits share the `O(rows · K² · d²)` pass.
pub struct BlendMoments {
    materials: usize,
    /// `(photo · K + k) · K + l`.
    g: Vec<DMatrix<f64>>,
    /// Per channel, `photo · K + k`.
    h: [Vec<DVector<f64>>; 3],
}

impl BlendMoments {
    /// The moments of `rows` (designs of one length) over `n_photos` photos and `kk`
    /// materials.
    pub fn of(rows: &[BlendRow], n_photos: usize, kk: usize) -> BlendMoments {
        let d = rows.first().map_or(0, |r| r.design.len());
        let mut g = vec![DMatrix::zeros(d, d); n_photos * kk * kk];
        let mut h = [0, 1, 2].map(|_| vec![DVector::zeros(d); n_photos * kk]);
        for r in rows {
            let a = DVector::from_column_slice(&r.design);
            let aat = &a * a.transpose();
            for (k, wk) in r.weights.iter().enumerate().filter(|(_, w)| **w > 0.0) {
                for (l, wl) in r.weights.iter().enumerate().filter(|(_, w)| **w > 0.0) {
                    g[(r.photo * kk + k) * kk + l] += &aat * (wk * wl);
                }
                for (hc, y) in h.iter_mut().zip(r.rgb) {
                    hc[r.photo * kk + k] += &a * (wk * y);
                }
            }
        }
        BlendMoments {
            materials: kk,
            g,
            h,
        }
    }

    /// Channel `c`'s albedo per material (module docs) from `rho0` (one positive value per
    /// material), until no ratio `ρ_k / ρ_0` moves by more than [`RATIO_TOL`] in a round, after
    /// [`MAX_ROUNDS`], or where the albedo step has no positive solution (the last albedos
    /// kept).
    pub fn albedos(&self, c: usize, rho0: &[f64]) -> Result<Vec<f64>> {
        let mut rho: Vec<f64> = rho0.iter().map(|r| r.max(1e-9)).collect();
        for _ in 0..MAX_ROUNDS {
            let b = self.photo_lights(c, &rho)?;
            let Some(next) = self.albedos_under(c, &b) else {
                break;
            };
            let moved = largest_ratio_move(&next, &rho);
            rho = next;
            if moved <= RATIO_TOL {
                break;
            }
        }
        Ok(rho)
    }

    /// Each photo's block light in channel `c` with the albedos `rho` fixed, by the
    /// pure-vertex model's ridged NNLS ([`ridged_nnls`]).
    fn photo_lights(&self, c: usize, rho: &[f64]) -> Result<Vec<DVector<f64>>> {
        let kk = self.materials;
        let h = &self.h[c];
        (0..h.len() / kk)
            .map(|i| {
                let d = h[i * kk].len();
                let (mut ata, mut atb) = (DMatrix::zeros(d, d), DVector::zeros(d));
                for k in 0..kk {
                    for l in 0..kk {
                        ata += &self.g[(i * kk + k) * kk + l] * (rho[k] * rho[l]);
                    }
                    atb += &h[i * kk + k] * rho[k];
                }
                ridged_nnls(ata, &atb)
            })
            .collect()
    }

    /// Channel `c`'s albedos with the photos' lights `b` fixed; `None` when the normal
    /// equations are singular or give an albedo that is not positive.
    fn albedos_under(&self, c: usize, b: &[DVector<f64>]) -> Option<Vec<f64>> {
        let kk = self.materials;
        let (mut m, mut rhs) = (DMatrix::zeros(kk, kk), DVector::zeros(kk));
        for (i, bi) in b.iter().enumerate() {
            for k in 0..kk {
                for l in 0..kk {
                    m[(k, l)] += bi.dot(&(&self.g[(i * kk + k) * kk + l] * bi));
                }
                rhs[k] += bi.dot(&self.h[c][i * kk + k]);
            }
        }
        let rho = m.lu().solve(&rhs)?;
        rho.iter()
            .all(|&r| r > 0.0)
            .then(|| rho.iter().copied().collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solve::materials::bilinear::ModelRow;
    use crate::solve::materials::coarse_light::{block_responses, coarse_light_albedos};
    use crate::solve::materials::test_normals::normals;
    use crate::sphere::{haar, oct_encode, SphereGrid};

    const TRUE_RHO: [[f64; 3]; 2] = [[0.8, 0.45, 0.2], [0.2, 0.3, 0.6]];

    /// Rows of two materials on a 32² map with 8 × 8 blocks, material 0's vertices facing
    /// up more and material 1's down more, each vertex `i` of a set blended toward the
    /// other material by `leak(i)`; each photo's light a sky of 0.3 plus one block of 300
    /// that moves, so the data are of the model's form. Returns the blend rows and, for
    /// the same observations, the pure-vertex model's rows (each vertex read as the
    /// material it holds the most of).
    fn rows(photos: usize, leak: impl Fn(usize) -> f64) -> (Vec<BlendRow>, Vec<ModelRow>) {
        let (n, r) = (32, 8);
        let grid = SphereGrid::full(n);
        let h = block_haar(n, r);
        let sets = [normals(300, -0.3, 1.0), normals(300, -1.0, 0.4)];
        let (mut blend, mut pure) = (Vec::new(), Vec::new());
        for photo in 0..photos {
            let light = |t: usize| {
                let uv = oct_encode(&grid.texel_dir(t));
                let block = ((uv[1] * 8.0) as usize, (uv[0] * 8.0) as usize);
                0.3 + if block == (1 + photo, 2 + 2 * photo) {
                    300.0
                } else {
                    0.0
                }
            };
            for (k, set) in sets.iter().enumerate() {
                for (i, nrm) in set.iter().enumerate() {
                    let g: Vec<f64> = (0..grid.len())
                        .map(|t| nrm.dot(&grid.texel_dir(t)).max(0.0) * grid.solid_angle(t))
                        .collect();
                    let irr: f64 = (0..grid.len()).map(|t| g[t] * light(t)).sum();
                    let mut w = [0.0; 2];
                    w[k] = 1.0 - leak(i);
                    w[1 - k] = leak(i);
                    let rgb =
                        [0, 1, 2].map(|c| (w[0] * TRUE_RHO[0][c] + w[1] * TRUE_RHO[1][c]) * irr);
                    let mut coeffs = g.clone();
                    haar::forward(&mut coeffs, n);
                    let design = block_responses(coeffs.into_iter().enumerate(), n, &h);
                    pure.push(ModelRow {
                        photo,
                        material: k,
                        rgb,
                        design: design.clone(),
                    });
                    blend.push(BlendRow {
                        photo,
                        weights: w.to_vec(),
                        rgb,
                        design,
                    });
                }
            }
        }
        (blend, pure)
    }

    fn worst(rho: impl Fn(usize) -> Vec<f64>) -> f64 {
        (0..3)
            .map(|c| {
                let r = rho(c);
                (r[1] / r[0] / (TRUE_RHO[1][c] / TRUE_RHO[0][c]) - 1.0).abs()
            })
            .fold(0.0, f64::max)
    }

    #[test]
    fn the_blend_model_recovers_the_ratios_where_the_vertices_blend() {
        // A third of each material's vertices keep 0–20% of the other (its border), the
        // data of the model's form: from a start 4× off in every channel the ratios must
        // come back to 1e-6 (the stopping rule is 1e-9 a round, the convergence linear).
        // The pure-vertex model reading the same observations as pure must be off by more
        // than 1% (its material 1 takes in 0.8's red): the error the blend removes.
        let leak = |i: usize| {
            if i.is_multiple_of(3) {
                0.2 * (i % 7) as f64 / 6.0
            } else {
                0.0
            }
        };
        let (blend, pure) = rows(3, leak);
        let model = BlendMoments::of(&blend, 3, 2);
        let err = worst(|c| model.albedos(c, &[1.0, 4.0]).unwrap());
        assert!(err < 1e-6, "blend model: worst ratio error {err}");
        let off = worst(|c| coarse_light_albedos(&pure, c, 3, &[1.0, 4.0]).unwrap());
        assert!(off > 0.01, "pure-vertex model: worst ratio error {off}");
    }

    #[test]
    fn with_pure_vertices_the_blend_model_is_the_pure_vertex_model() {
        // One-hot weights: both alternations take the same steps (module docs), so from
        // the same start they must end at the same albedos, to 1e-9 relative (the same
        // sums in a different order, f64).
        let (blend, pure) = rows(2, |_| 0.0);
        for c in 0..3 {
            let a = BlendMoments::of(&blend, 2, 2)
                .albedos(c, &[1.0, 2.0])
                .unwrap();
            let b = coarse_light_albedos(&pure, c, 2, &[1.0, 2.0]).unwrap();
            for (x, y) in a.iter().zip(&b) {
                assert!((x / y - 1.0).abs() < 1e-9, "channel {c}: {a:?} vs {b:?}");
            }
        }
    }

    #[test]
    fn a_material_no_row_holds_the_most_of_is_not_read() {
        let row = |w: Vec<f64>| BlendRow {
            photo: 0,
            weights: w,
            rgb: [1.0; 3],
            design: vec![1.0],
        };
        let rows = [
            row(vec![0.7, 0.3, 0.0]),
            row(vec![0.4, 0.4, 0.2]),
            row(vec![0.1, 0.5, 0.4]),
        ];
        let got: Vec<usize> = dominant_materials(&rows).collect();
        assert_eq!(got, vec![0, 1]);
    }
}
