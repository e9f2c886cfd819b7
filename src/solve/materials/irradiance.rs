//! The materials' Lambertian ratios from a low-order irradiance model, for a restart of
//! the alternation (`run --restart irradiance`, not in the paper).
//!
//! With a free map per photo, `F` (Eq. 9) barely changes when one material's `λ_{k,·,c}`
//! is scaled and the maps take up the difference: the alternation keeps about the albedo
//! ratios it starts from (`bench-results/ratio-floor.md`, section 3). Over the vertices
//! that see nearly all of their hemisphere, a distant light's irradiance is not free: for
//! a convex Lambertian surface it is, to within a few percent, an order-2 spherical-harmonic
//! function of the normal, whatever the light (Ramamoorthi & Hanrahan 2001, "An efficient
//! representation for irradiance environment maps", SIGGRAPH; the clamped cosine's
//! harmonics vanish at odd `l ≥ 3` and fall as `l^{-5/2}` at even `l`). So within photo `I` and channel
//! `c`, a pure vertex `x` of material `k` has radiance
//!
//! `y_{x,I,c} = ρ_{k,c} Σ_{j<9} s_{I,c,j} Y_j(n_x)`,
//!
//! nine free coefficients per photo and channel and one albedo per material and channel,
//! with no map left to absorb one material's brightness against another's. The model is
//! bilinear; [`irradiance_albedos`] fits it by alternating least squares (each photo's
//! nine coefficients by their normal equations, then each `ρ_{k,c}` in closed form
//! `Σ e y / Σ e²`, `e = Σ_j s_j Y_j(n)`), from the first fit's ratios. Its scale per channel
//! is free (the gauge): [`irradiance_start`] keeps the first fit's geometric mean.
//!
//! The rows ([`pure_open_rows`]) are the training observations of the seen vertices whose
//! weights, normalised to sum 1, give one material at least [`PURE`] and whose open
//! fraction is at least [`MIN_OPEN`]: the first fit's weights, not the clustered colours,
//! because blended vertices among a material's rows pull its ratio toward the other's
//! (`bench-results/ratio-step-directions.md`, section 1). A shiny lobe's highlights enter
//! the model as if they were irradiance, so the ratios are the diffuse albedo's only where
//! the materials are Lambertian.
//!
//! Measured (`bench-results/irradiance-start.md`): on the ablation's diffuse scene the model's
//! ratios are 6–19% off (the first fit's 5–22%), and a second fit from them meets the
//! held-out and relit targets on 5 of 5 seeds; on the glossy and three-material scenes
//! the highlights make them worse.

use crate::observe::Observations;
use crate::solve::Materials0;
use crate::{Error, Result, Vec3};

/// Least blending weight (weights normalised to sum 1) of a vertex the model reads.
pub const PURE: f64 = 0.95;

/// Least open fraction of the hemisphere of a vertex the model reads: at 0.8 and 0.95
/// the ablation's diffuse ratios after the second fit were alike (median worst over 5
/// seeds 0.095 and 0.092).
pub const MIN_OPEN: f64 = 0.95;

/// Alternating least-squares rounds: on exact order-2 data from a start with both
/// materials alike the ratios end within 10⁻⁶ of the truth (the tests).
pub const ROUNDS: usize = 40;

type M9 = nalgebra::SMatrix<f64, 9, 9>;
type V9 = nalgebra::SVector<f64, 9>;

/// The real spherical harmonics of order ≤ 2 of a unit normal, their constant factors
/// dropped (each photo's coefficients are free): `1, y, z, x, xy, yz, 3z² − 1, xz, x² − y²`.
pub fn sh9(n: &Vec3) -> [f64; 9] {
    let (x, y, z) = (n.x, n.y, n.z);
    [
        1.0,
        y,
        z,
        x,
        x * y,
        y * z,
        3.0 * z * z - 1.0,
        x * z,
        x * x - y * y,
    ]
}

/// One observation the model reads: its photo, its vertex's material, its radiance and the
/// harmonics of its vertex's normal.
#[derive(Debug, Clone)]
pub struct IrradianceRow {
    pub photo: usize,
    pub material: usize,
    pub rgb: [f64; 3],
    pub sh: [f64; 9],
}

/// What [`pure_open_rows`] reads.
pub struct RowsInput<'a> {
    pub obs: &'a Observations,
    /// Environment-frame unit normal per vertex.
    pub normals_env: &'a [Vec3],
    /// Fraction of each vertex's hemisphere open to the sky.
    pub open: &'a [f64],
    /// Whether a training photo sees each vertex.
    pub seen: &'a [bool],
    /// Blending weights normalised to sum 1, `V × K` row-major.
    pub weights: &'a [f64],
    /// `K`.
    pub materials: usize,
    /// Least open fraction of a vertex read ([`MIN_OPEN`] in `run`).
    pub min_open: f64,
}

/// The fitted (`α > 0`) observations of the seen vertices with open fraction ≥
/// `min_open` and one normalised weight ≥ [`PURE`].
pub fn pure_open_rows(input: &RowsInput) -> Vec<IrradianceRow> {
    let (obs, kk) = (input.obs, input.materials);
    let material = |x: usize| -> Option<usize> {
        if !input.seen[x] || input.open[x] < input.min_open {
            return None;
        }
        (0..kk).find(|&k| input.weights[x * kk + k] >= PURE)
    };
    let mut rows = Vec::new();
    for (photo, range) in obs.photo_ranges.iter().enumerate() {
        for p in range.clone().filter(|&p| obs.weight[p] > 0.0) {
            let x = obs.vertex[p] as usize;
            if let Some(material) = material(x) {
                rows.push(IrradianceRow {
                    photo,
                    material,
                    rgb: obs.rgb[p].map(f64::from),
                    sh: sh9(&input.normals_env[x]),
                });
            }
        }
    }
    rows
}

/// Channel `c`'s albedo per material (module docs) by [`ROUNDS`] of alternating least
/// squares from `rho0` (one value per material, > 0); a material without rows keeps its
/// `rho0`. Each photo's normal equations carry a ridge of 10⁻⁹ so that a photo whose rows
/// span fewer than nine harmonics still solves.
pub fn irradiance_albedos(
    rows: &[IrradianceRow],
    c: usize,
    n_photos: usize,
    rho0: &[f64],
) -> Vec<f64> {
    let kk = rho0.len();
    let mut rho: Vec<f64> = rho0.iter().map(|r| r.max(1e-9)).collect();
    let mut s = vec![V9::zeros(); n_photos];
    for _ in 0..ROUNDS {
        photo_coefficients(rows, c, &rho, &mut s);
        let (mut num, mut den) = (vec![0.0; kk], vec![0.0; kk]);
        for r in rows {
            let e = s[r.photo].dot(&V9::from_column_slice(&r.sh));
            num[r.material] += e * r.rgb[c];
            den[r.material] += e * e;
        }
        for k in 0..kk {
            if den[k] > 0.0 && num[k] > 0.0 {
                rho[k] = num[k] / den[k];
            }
        }
    }
    rho
}

/// Each photo's nine coefficients by least squares with the albedos `rho` fixed.
fn photo_coefficients(rows: &[IrradianceRow], c: usize, rho: &[f64], s: &mut [V9]) {
    let n_photos = s.len();
    let mut ata = vec![M9::identity() * 1e-9; n_photos];
    let mut aty = vec![V9::zeros(); n_photos];
    for r in rows {
        let a = V9::from_column_slice(&r.sh) * rho[r.material];
        ata[r.photo] += a * a.transpose();
        aty[r.photo] += a * r.rgb[c];
    }
    for (i, si) in s.iter_mut().enumerate() {
        if let Some(sol) = ata[i].lu().solve(&aty[i]) {
            *si = sol;
        }
    }
}

/// `weights` (`V × K` row-major) with each vertex's row divided by its sum (rows that sum
/// to 0 kept).
pub fn normalised_weights(weights: &[f64], materials: usize) -> Vec<f64> {
    let mut w = weights.to_vec();
    for row in w.chunks_mut(materials.max(1)) {
        let s: f64 = row.iter().sum();
        if s > 0.0 {
            row.iter_mut().for_each(|v| *v /= s);
        }
    }
    w
}

/// The restart's start: the normalised `weights` (from [`normalised_weights`]) and each
/// material's Lambertian `λ_{k,lambert,c}` set to the model's `ρ_{k,c}` over `rows`,
/// rescaled per channel to the geometric mean of `lambda`'s (the other lobes as they are).
/// `None` when the rows leave a material without observations.
pub fn irradiance_start(
    lambda: &[Vec<[f64; 3]>],
    weights: Vec<f64>,
    lambert: usize,
    rows: &[IrradianceRow],
    n_photos: usize,
) -> Result<Option<Materials0>> {
    let kk = lambda.len();
    if kk == 0 || !weights.len().is_multiple_of(kk) || lambda.iter().any(|l| l.len() <= lambert) {
        return Err(Error::Internal(format!(
            "irradiance start: {kk} materials, {} weights, Lambertian basis {lambert}",
            weights.len()
        )));
    }
    if (0..kk).any(|k| !rows.iter().any(|r| r.material == k)) {
        return Ok(None);
    }
    let mean_log = |v: &[f64]| v.iter().map(|r| r.max(1e-12).ln()).sum::<f64>() / kk as f64;
    let mut new_lambda = lambda.to_vec();
    for c in 0..3 {
        let first: Vec<f64> = lambda.iter().map(|l| l[lambert][c]).collect();
        let rho = irradiance_albedos(rows, c, n_photos, &first);
        let shift = mean_log(&first) - mean_log(&rho);
        for (k, l) in new_lambda.iter_mut().enumerate() {
            l[lambert][c] = (rho[k].max(1e-12).ln() + shift).exp();
        }
    }
    Ok(Some(Materials0 {
        lambda: new_lambda,
        weights,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `n` unit normals spread over the sphere (a Fibonacci lattice), those with
    /// `z ∈ [lo, hi]`.
    fn normals(n: usize, lo: f64, hi: f64) -> Vec<Vec3> {
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        (0..n)
            .map(|i| {
                let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
                let r = (1.0 - z * z).sqrt();
                let phi = golden * i as f64;
                Vec3::new(r * phi.cos(), r * phi.sin(), z)
            })
            .filter(|v| v.z >= lo && v.z <= hi)
            .collect()
    }

    const TRUE_RHO: [[f64; 3]; 2] = [[0.8, 0.45, 0.2], [0.2, 0.3, 0.6]];

    /// Rows of two materials on overlapping but different bands of normals (material 0
    /// faces up more, material 1 down more) under `photos` exact order-2 irradiances.
    fn exact_rows(photos: usize) -> Vec<IrradianceRow> {
        let sets = [normals(400, -0.3, 1.0), normals(400, -1.0, 0.4)];
        let mut rows = Vec::new();
        for photo in 0..photos {
            // Each photo's coefficients per channel: a positive constant term and
            // photo-dependent directional terms.
            let coef = |c: usize, j: usize| -> f64 {
                if j == 0 {
                    1.0 + 0.2 * c as f64
                } else {
                    0.3 * ((photo * 7 + j * 3 + c) as f64).sin()
                }
            };
            for (k, set) in sets.iter().enumerate() {
                for n in set {
                    let sh = sh9(n);
                    let rgb = [0, 1, 2].map(|c| {
                        let e: f64 = (0..9).map(|j| coef(c, j) * sh[j]).sum();
                        TRUE_RHO[k][c] * e
                    });
                    rows.push(IrradianceRow {
                        photo,
                        material: k,
                        rgb,
                        sh,
                    });
                }
            }
        }
        rows
    }

    #[test]
    fn the_model_recovers_the_ratios_of_exact_order_2_irradiance() {
        // Data made by the model itself: from a start with both materials alike (the true
        // red ratio is 0.25, the blue one 3), the alternating least squares must reach the
        // true ratios. Tolerance 1e-6 relative: the iteration converges linearly from
        // there and 40 rounds leave it far below that.
        let rows = exact_rows(4);
        for c in 0..3 {
            let rho = irradiance_albedos(&rows, c, 4, &[0.5, 0.5]);
            let (got, want) = (rho[1] / rho[0], TRUE_RHO[1][c] / TRUE_RHO[0][c]);
            assert!(
                (got / want - 1.0).abs() < 1e-6,
                "channel {c}: ratio {got} against {want}"
            );
        }
    }

    #[test]
    fn the_model_reads_a_real_lights_ratios_to_a_few_percent() {
        // Irradiance of a real light by quadrature, not the model's: a sky of constant
        // radiance 0.3 plus a sun (radiance 400 over a cap of 5° radius, taken as one
        // direction) 40° above the horizon, ten times the sky's irradiance, on normals of
        // the two bands of `exact_rows` (whose different normal ranges are what a wrong
        // model would bias). A point-like source is the hardest case for order 2 (the
        // clamped cosine's truncation error is all there); measured worst over the
        // channels 1.3% (blue, whose brighter material weighs most in the fit of the
        // irradiance), so 3%.
        let sun = Vec3::new(40f64.to_radians().cos(), 0.0, 40f64.to_radians().sin());
        let dirs = normals(20_000, -1.0, 1.0);
        let cap = 5f64.to_radians().cos();
        let domega = 4.0 * std::f64::consts::PI / dirs.len() as f64;
        let sun_omega = 2.0 * std::f64::consts::PI * (1.0 - cap);
        let irradiance = |n: &Vec3| -> f64 {
            let sky: f64 = dirs.iter().map(|d| 0.3 * n.dot(d).max(0.0) * domega).sum();
            sky + 400.0 * sun_omega * n.dot(&sun).max(0.0)
        };
        let sets = [normals(300, -0.3, 1.0), normals(300, -1.0, 0.4)];
        let mut rows = Vec::new();
        for (k, set) in sets.iter().enumerate() {
            for n in set {
                let e = irradiance(n);
                rows.push(IrradianceRow {
                    photo: 0,
                    material: k,
                    rgb: TRUE_RHO[k].map(|r| r * e),
                    sh: sh9(n),
                });
            }
        }
        for c in 0..3 {
            let rho = irradiance_albedos(&rows, c, 1, &[0.5, 0.5]);
            let (got, want) = (rho[1] / rho[0], TRUE_RHO[1][c] / TRUE_RHO[0][c]);
            assert!(
                (got / want - 1.0).abs() < 0.03,
                "channel {c}: ratio {got} against {want}"
            );
        }
    }

    #[test]
    fn the_start_keeps_the_gauge_and_the_other_lobes() {
        // Lambert at basis 1, a shiny lobe at 0: the shiny lobe and the weights pass
        // through; the Lambertian rows take the model's ratios with the first fit's
        // geometric mean per channel (exact data: to 1e-6, as above).
        let rows = exact_rows(3);
        let lambda = vec![
            vec![[0.1, 0.1, 0.1], [1.0, 1.0, 1.0]],
            vec![[0.0, 0.0, 0.0], [4.0, 1.0, 0.25]],
        ];
        let weights = vec![1.0, 0.0, 0.0, 1.0, 0.5, 0.5];
        let m = irradiance_start(&lambda, weights.clone(), 1, &rows, 3)
            .unwrap()
            .expect("both materials have rows");
        assert_eq!(m.weights, weights);
        for c in 0..3 {
            assert_eq!(m.lambda[0][0][c], 0.1);
            assert_eq!(m.lambda[1][0][c], 0.0);
            let (a, b) = (m.lambda[0][1][c], m.lambda[1][1][c]);
            let mean_before = (lambda[0][1][c] * lambda[1][1][c]).sqrt();
            assert!(
                ((a * b).sqrt() / mean_before - 1.0).abs() < 1e-9,
                "gauge {c}"
            );
            let want = TRUE_RHO[1][c] / TRUE_RHO[0][c];
            assert!((b / a / want - 1.0).abs() < 1e-6, "ratio {c}: {}", b / a);
        }
    }

    #[test]
    fn only_the_pure_open_seen_fitted_observations_are_read() {
        // Vertices: 0 pure and open, 1 pure but half shut, 2 blended, 3 unseen, 4 pure
        // material 1 and open; photo 0 sees all, photo 1 sees 0 and 4 with 4's α = 0.
        let obs = Observations {
            vertex: vec![0, 1, 2, 3, 4, 0, 4],
            photo: vec![0, 0, 0, 0, 0, 1, 1],
            rgb: vec![[0.5; 3]; 7],
            weight: vec![1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 0.0],
            dir: vec![[0.0, 0.0, 1.0]; 7],
            photo_ranges: vec![0..5, 5..7],
        };
        let normals_env = vec![Vec3::z(); 5];
        let open = [1.0, 0.5, 1.0, 1.0, 0.97];
        let seen = [true, true, true, false, true];
        let w = normalised_weights(&[2.0, 0.0, 3.0, 0.0, 1.2, 0.8, 1.0, 0.0, 0.0, 0.5], 2);
        let rows = pure_open_rows(&RowsInput {
            obs: &obs,
            normals_env: &normals_env,
            open: &open,
            seen: &seen,
            weights: &w,
            materials: 2,
            min_open: MIN_OPEN,
        });
        let got: Vec<(usize, usize)> = rows.iter().map(|r| (r.photo, r.material)).collect();
        assert_eq!(got, vec![(0, 0), (0, 1), (1, 0)]);
        // Without material 1's rows the start is `None`, not a guess.
        let lambda = vec![vec![[1.0; 3]], vec![[1.0; 3]]];
        let only0: Vec<IrradianceRow> = rows.into_iter().filter(|r| r.material == 0).collect();
        assert!(irradiance_start(&lambda, w, 0, &only0, 2)
            .unwrap()
            .is_none());
    }
}
