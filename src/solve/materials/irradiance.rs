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
//! `Σ e y / Σ e²`, `e = Σ_j s_j Y_j(n)`), from the first fit's ratios until they settle. Its scale per channel
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
//! Measured (`bench-results/irradiance-start.md`): on the ablation's diffuse scene, over
//! the first fit's pure, open vertices, the model's ratios are 2.9% and 4.6% off (seeds 1–2),
//! and its own bias on exact data 2.0–4.9%; a second fit from them, with those vertices
//! made pure, meets the held-out and relit targets on 5 of 5 seeds, its worst ratio
//! 0.048–0.109 (the first fit's 0.046–0.224); on the glossy and three-material scenes the
//! highlights make them worse.

use nalgebra::{DMatrix, DVector};

use crate::observe::Observations;
use crate::solve::materials::bilinear::{self, ModelRow};
use crate::solve::Materials0;
use crate::{Error, Result, Vec3};

/// Least blending weight (weights normalised to sum 1) of a vertex the model reads.
pub const PURE: f64 = 0.95;

/// Least open fraction of the hemisphere of a vertex the model reads: at 0.8 and 0.95
/// the ablation's diffuse ratios after the second fit were alike (median worst over 5
/// seeds 0.095 and 0.092).
pub const MIN_OPEN: f64 = 0.95;

/// Most alternating least-squares rounds. The iteration converges linearly, and slowly
/// where the materials' normals overlap little: on the ablation's diffuse scene the ratios
/// still moved by 10–25% between rounds 40 and 400, and not at all after 400.
pub const MAX_ROUNDS: usize = 20_000;

/// The iteration stops when no ratio `ρ_k / ρ_0` moves by more than this (relative) in a
/// round.
pub const RATIO_TOL: f64 = 1e-12;

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
/// `min_open` and one normalised weight ≥ [`PURE`] ([`pure_rows`]), each with its normal's
/// nine harmonics.
pub fn pure_open_rows(input: &RowsInput) -> Vec<ModelRow> {
    let open = |x: usize| input.open[x] >= input.min_open;
    let harmonics = |_: usize, x: usize| sh9(&input.normals_env[x]).to_vec();
    pure_rows(
        input.obs,
        (input.seen, input.weights, input.materials),
        open,
        harmonics,
    )
}

/// The fitted (`α > 0`) observations of the seen vertices (`seen`) that `read` accepts and
/// whose normalised weights (`weights`, `V × K` row-major, `K` = `materials`) hold one
/// material at ≥ [`PURE`], each with `design(p, x)` for observation `p` of vertex `x`: the
/// rows of both ratio models ([`pure_open_rows`], [`super::coarse_light::pure_seen_rows`]).
pub fn pure_rows(
    obs: &Observations,
    (seen, weights, materials): (&[bool], &[f64], usize),
    read: impl Fn(usize) -> bool,
    mut design: impl FnMut(usize, usize) -> Vec<f64>,
) -> Vec<ModelRow> {
    let kk = materials;
    let mut rows = Vec::new();
    for (photo, range) in obs.photo_ranges.iter().enumerate() {
        for p in range.clone().filter(|&p| obs.weight[p] > 0.0) {
            let x = obs.vertex[p] as usize;
            if !seen[x] || !read(x) {
                continue;
            }
            if let Some(material) = pure_material(&weights[x * kk..(x + 1) * kk]) {
                rows.push(ModelRow {
                    photo,
                    material,
                    rgb: obs.rgb[p].map(f64::from),
                    design: design(p, x),
                });
            }
        }
    }
    rows
}

/// Channel `c`'s albedo per material (module docs) by alternating least squares from
/// `rho0` (one value per material, > 0), until the ratios settle ([`RATIO_TOL`]) or after
/// [`MAX_ROUNDS`]; a material without rows keeps its `rho0`. Each photo's normal equations
/// carry a ridge of 10⁻⁹ so that a photo whose rows span fewer than nine harmonics still
/// solves. The rows enter once, through their moments per photo and material
/// ([`bilinear::PhotoMoments`]), so a round costs `O(photos · K · 81)` whatever the number
/// of rows.
pub fn irradiance_albedos(
    rows: &[ModelRow],
    c: usize,
    n_photos: usize,
    rho0: &[f64],
) -> Result<Vec<f64>> {
    let m = bilinear::PhotoMoments::of(rows, c, n_photos, rho0.len());
    let least_squares = |mut ata: DMatrix<f64>, atb: DVector<f64>| {
        for d in 0..ata.nrows() {
            ata[(d, d)] += 1e-9;
        }
        Ok(ata
            .lu()
            .solve(&atb)
            .unwrap_or_else(|| DVector::zeros(atb.len())))
    };
    let stopping = bilinear::Stopping {
        max_rounds: MAX_ROUNDS,
        ratio_tol: RATIO_TOL,
    };
    bilinear::alternate(&m, rho0, &least_squares, stopping)
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

/// The restart's start: the normalised `weights` (from [`normalised_weights`]), each
/// vertex with a weight ≥ [`PURE`] made pure in its material ([`snap_pure`]), and each material's Lambertian `λ_{k,lambert,c}` set to the model's
/// `ρ_{k,c}` over `rows` ([`start_from_albedos`]). `None` when the rows leave a material
/// without observations.
pub fn irradiance_start(
    lambda: &[Vec<[f64; 3]>],
    weights: Vec<f64>,
    lambert: usize,
    rows: &[ModelRow],
    n_photos: usize,
) -> Result<Option<Materials0>> {
    let read = rows.iter().map(|r| r.material);
    start_from_albedos(lambda, weights, lambert, read, |c, first| {
        irradiance_albedos(rows, c, n_photos, first)
    })
}

/// A restart's start from albedos a model fits: `weights` (normalised) with [`snap_pure`],
/// and each material's Lambertian `λ_{k,lambert,c}` set to `albedos(c, first)` (one per
/// material; `first` the Lambertian `λ` of channel `c`), rescaled per channel to the
/// geometric mean of `lambda`'s (the gauge; the other lobes as they are). `read` lists the
/// material of each row the model reads; `None` when it leaves a material out.
pub fn start_from_albedos(
    lambda: &[Vec<[f64; 3]>],
    weights: Vec<f64>,
    lambert: usize,
    read: impl Iterator<Item = usize>,
    albedos: impl Fn(usize, &[f64]) -> Result<Vec<f64>>,
) -> Result<Option<Materials0>> {
    let kk = lambda.len();
    if kk == 0 || !weights.len().is_multiple_of(kk) || lambda.iter().any(|l| l.len() <= lambert) {
        return Err(Error::Internal(format!(
            "restart start: {kk} materials, {} weights, Lambertian basis {lambert}",
            weights.len()
        )));
    }
    let mut has_rows = vec![false; kk];
    read.for_each(|k| {
        if let Some(h) = has_rows.get_mut(k) {
            *h = true;
        }
    });
    if has_rows.contains(&false) {
        return Ok(None);
    }
    let mean_log = |v: &[f64]| v.iter().map(|r| r.max(1e-12).ln()).sum::<f64>() / kk as f64;
    let mut new_lambda = lambda.to_vec();
    for c in 0..3 {
        let first: Vec<f64> = lambda.iter().map(|l| l[lambert][c]).collect();
        let rho = albedos(c, &first)?;
        let shift = mean_log(&first) - mean_log(&rho);
        for (k, l) in new_lambda.iter_mut().enumerate() {
            l[lambert][c] = (rho[k].max(1e-12).ln() + shift).exp();
        }
    }
    Ok(Some(Materials0 {
        lambda: new_lambda,
        weights: snap_pure(weights, kk),
    }))
}

/// The material a vertex's normalised weights hold at ≥ [`PURE`], if any.
pub fn pure_material(row: &[f64]) -> Option<usize> {
    row.iter().position(|&w| w >= PURE)
}

/// `weights` (`V × K`, normalised) with every row that has a [`pure_material`] set to that
/// material alone: the rule by which the model reads a vertex as pure (whether or not it is
/// open and seen). Left at 0.95–0.99, the few
/// percent of another material moves their albedo by that share of the colour difference
/// (on the ablation's diffuse scene, red ratio 4: the start's worst ratio 0.073 with the
/// weights as fitted, 0.029 snapped, seed 1; over seeds 1–5 the second fit's median 0.107 →
/// 0.081).
pub fn snap_pure(mut weights: Vec<f64>, materials: usize) -> Vec<f64> {
    for row in weights.chunks_mut(materials.max(1)) {
        if let Some(k) = pure_material(row) {
            row.iter_mut()
                .enumerate()
                .for_each(|(j, v)| *v = f64::from(j == k));
        }
    }
    weights
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solve::materials::test_normals::normals;

    /// Irradiance at normal `n` from a sky of constant radiance 0.3 (quadrature over
    /// 20,000 directions) plus a sun of radiance 400 over a cap of 5° radius around `sun`,
    /// taken as one direction.
    fn sky_and_sun(n: &Vec3, sun: &Vec3) -> f64 {
        let dirs = normals(20_000, -1.0, 1.0);
        let domega = 4.0 * std::f64::consts::PI / dirs.len() as f64;
        let sun_omega = 2.0 * std::f64::consts::PI * (1.0 - 5f64.to_radians().cos());
        let sky: f64 = dirs.iter().map(|d| 0.3 * n.dot(d).max(0.0) * domega).sum();
        sky + 400.0 * sun_omega * n.dot(sun).max(0.0)
    }

    const TRUE_RHO: [[f64; 3]; 2] = [[0.8, 0.45, 0.2], [0.2, 0.3, 0.6]];

    /// Rows of two materials on overlapping but different bands of normals (material 0
    /// faces up more, material 1 down more) under `photos` exact order-2 irradiances.
    fn exact_rows(photos: usize) -> Vec<ModelRow> {
        exact_rows_on(photos, [(-0.3, 1.0), (-1.0, 0.4)])
    }

    /// As [`exact_rows`], material `k`'s normals those with `z` in `bands[k]`.
    fn exact_rows_on(photos: usize, bands: [(f64, f64); 2]) -> Vec<ModelRow> {
        let sets = bands.map(|(lo, hi)| normals(400, lo, hi));
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
                    rows.push(ModelRow {
                        photo,
                        material: k,
                        rgb,
                        design: sh.to_vec(),
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
        // true ratios. Tolerance 1e-6 relative: the iteration stops when the ratios move
        // by less than 1e-12 a round.
        let rows = exact_rows(4);
        for c in 0..3 {
            let rho = irradiance_albedos(&rows, c, 4, &[0.5, 0.5]).unwrap();
            let (got, want) = (rho[1] / rho[0], TRUE_RHO[1][c] / TRUE_RHO[0][c]);
            assert!(
                (got / want - 1.0).abs() < 1e-6,
                "channel {c}: ratio {got} against {want}"
            );
        }
    }

    /// Channel `c`'s least-squares residual of the model over `rows` with albedos
    /// `(1, t)`, each photo's coefficients solved from its rows (not from [`bilinear::PhotoMoments`]).
    fn profiled_residual(rows: &[ModelRow], c: usize, photos: usize, t: f64) -> f64 {
        let rho = [1.0, t];
        (0..photos)
            .map(|i| {
                let mine: Vec<&ModelRow> = rows.iter().filter(|r| r.photo == i).collect();
                let a = nalgebra::DMatrix::from_fn(mine.len(), 9, |r, j| {
                    mine[r].design[j] * rho[mine[r].material]
                });
                let y = nalgebra::DVector::from_fn(mine.len(), |r, _| mine[r].rgb[c]);
                let s = a.clone().svd(true, true).solve(&y, 1e-12).unwrap();
                (a * s - y).norm_squared()
            })
            .sum()
    }

    #[test]
    fn the_iteration_runs_until_the_ratios_minimise_the_residual() {
        // Irradiance not of the model's form (a sky plus a sun, by quadrature as below),
        // three photos with the sun in different places, each seeing only the normals
        // within 26° of its view (as a photo sees a patch of a surface), material 0 on the
        // upper hemisphere and material 1 on the lower one sharing a band of 0.1 in z,
        // from a start 10× off in every ratio. The residual's minimiser over the ratio,
        // found by a brute-force scan and golden-section refinement with every photo's
        // coefficients re-solved by SVD, must be the iteration's ratio to 1e-4 relative
        // (the bracket ends below 1e-7; measured worst 1.5e-6, the iteration's stopping
        // rule). 40 rounds of the same iteration leave the blue ratio 88% off.
        let suns = [(40.0f64, 0.0f64), (20.0, 120.0), (65.0, 250.0)];
        let sets = [normals(300, 0.0, 1.0), normals(300, -1.0, 0.1)];
        let mut rows = Vec::new();
        for (photo, &(elevation, azimuth)) in suns.iter().enumerate() {
            let (e, a) = (elevation.to_radians(), azimuth.to_radians());
            let sun = Vec3::new(e.cos() * a.cos(), e.cos() * a.sin(), e.sin());
            let view =
                Vec3::new(0.8 * a.cos(), 0.8 * a.sin(), 0.6 - 0.4 * photo as f64).normalize();
            for (k, set) in sets.iter().enumerate() {
                for n in set.iter().filter(|n| n.dot(&view) > 0.9) {
                    let irr = sky_and_sun(n, &sun);
                    rows.push(ModelRow {
                        photo,
                        material: k,
                        rgb: TRUE_RHO[k].map(|r| r * irr),
                        design: sh9(n).to_vec(),
                    });
                }
            }
        }
        for c in 0..3 {
            let want = TRUE_RHO[1][c] / TRUE_RHO[0][c];
            let rho = irradiance_albedos(&rows, c, 3, &[1.0, 10.0 * want]).unwrap();
            let got = rho[1] / rho[0];
            let f = |log_t: f64| profiled_residual(&rows, c, 3, log_t.exp());
            let grid: Vec<f64> = (0..=200).map(|i| -4.0 + 8.0 * i as f64 / 200.0).collect();
            let best = grid
                .iter()
                .copied()
                .min_by(|a, b| f(*a).total_cmp(&f(*b)))
                .unwrap();
            let (mut lo, mut hi) = (best - 0.04, best + 0.04);
            let g = (5f64.sqrt() - 1.0) / 2.0;
            while hi - lo > 1e-7 {
                let (m1, m2) = (hi - g * (hi - lo), lo + g * (hi - lo));
                if f(m1) < f(m2) {
                    hi = m2;
                } else {
                    lo = m1;
                }
            }
            let brute = (0.5 * (lo + hi)).exp();
            assert!(
                (got / brute - 1.0).abs() < 1e-4,
                "channel {c}: ratio {got} against the residual's minimiser {brute}"
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
        let sets = [normals(300, -0.3, 1.0), normals(300, -1.0, 0.4)];
        let mut rows = Vec::new();
        for (k, set) in sets.iter().enumerate() {
            for n in set {
                let e = sky_and_sun(n, &sun);
                rows.push(ModelRow {
                    photo: 0,
                    material: k,
                    rgb: TRUE_RHO[k].map(|r| r * e),
                    design: sh9(n).to_vec(),
                });
            }
        }
        for c in 0..3 {
            let rho = irradiance_albedos(&rows, c, 1, &[0.5, 0.5]).unwrap();
            let (got, want) = (rho[1] / rho[0], TRUE_RHO[1][c] / TRUE_RHO[0][c]);
            assert!(
                (got / want - 1.0).abs() < 0.03,
                "channel {c}: ratio {got} against {want}"
            );
        }
    }

    #[test]
    fn the_start_keeps_the_gauge_and_the_other_lobes() {
        // Lambert at basis 1, a shiny lobe at 0: the shiny lobe passes through, the
        // weights too except the nearly pure ones; the Lambertian rows take the model's
        // ratios with the first fit's geometric mean per channel (exact data: to 1e-6, as
        // above).
        let rows = exact_rows(3);
        let lambda = vec![
            vec![[0.1, 0.1, 0.1], [1.0, 1.0, 1.0]],
            vec![[0.0, 0.0, 0.0], [4.0, 1.0, 0.25]],
        ];
        // Pure, pure, blended, nearly pure in material 1 (made pure), nearly pure below
        // PURE (kept).
        let weights = vec![1.0, 0.0, 0.0, 1.0, 0.5, 0.5, 0.03, 0.97, 0.94, 0.06];
        let m = irradiance_start(&lambda, weights.clone(), 1, &rows, 3)
            .unwrap()
            .expect("both materials have rows");
        assert_eq!(
            m.weights,
            vec![1.0, 0.0, 0.0, 1.0, 0.5, 0.5, 0.0, 1.0, 0.94, 0.06]
        );
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
            clipped: Vec::new(),
            bound_weight: Vec::new(),
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
        let only0: Vec<ModelRow> = rows.into_iter().filter(|r| r.material == 0).collect();
        assert!(irradiance_start(&lambda, w, 0, &only0, 2)
            .unwrap()
            .is_none());
    }
}
