//! A statistical prior on a per-photo environment map (issue 25, not in the paper): what
//! real captured light looks like, added to the lighting QP as two quadratic terms.
//!
//! 1. **Low-order shape, Gaussian.** The real spherical harmonics up to order 2
//!    (`Y_i`, `i = 0..9`, Sloan's "Stupid SH tricks" normalisation, `∫ Y_i Y_j dω = δ_ij`)
//!    project a map of texel averages `x` (one channel, [`crate::sphere::SphereGrid::full`])
//!    linearly: `c_i(x) = Σ_t x_t ∫_{texel t} Y_i dω = (P x)_i` ([`ShProjection`], the
//!    integral by `s × s` sub-texels with exact solid angles). The light's absolute level
//!    and colour are not determined by photos (exposure, white balance, the albedo's
//!    per-channel scale), so the prior is on the *shape* of each channel,
//!    `ĉ_{c,i} = c_{c,i} / c_{c,0}` (`i = 1..9`, 24 numbers for three channels), Gaussian with
//!    mean `m` and precision `Λ` estimated from real HDR maps ([`LightPrior`], the maps
//!    rotated about the up axis). Inside one lighting step `s_c` (the current iterate's
//!    `c_{c,0}`) is held fixed, which makes the residual linear and homogeneous in `x`:
//!
//!    `r_{c,i}(x) = (c_{c,i}(x) − m_{c,i} c_{c,0}(x)) / s_c = (A x)_{c,i}`,
//!    `E_sh(x) = ½ σ² rᵀ Λ r = ½ σ² xᵀ Aᵀ Λ A x`,
//!
//!    a rank-24 term of the QP's Hessian ([`ShPriorTerm`]). `σ²` puts it on the data term's
//!    scale: the objective `Σ (y − ŷ)² + σ² rᵀΛr` is `σ²` × the negative log posterior for
//!    Gaussian noise of standard deviation `σ` (`σ` = a relative noise level × the photo's
//!    RMS radiance, chosen by the caller).
//! 2. **Detail, sparse (Laplace / L1).** Natural illumination is sparse in wavelets (Dror,
//!    Willsky & Adelson, "Statistical characterization of real-world illumination", JOV
//!    2004). Each Haar detail coefficient `h_k` (level `m`, [`crate::haar::coefficient`]),
//!    relative to the scaling coefficient `h_0`, gets a Laplace prior with scale `b_m` = the
//!    mean `|h_k / h_0|` of real maps at that level and resolution: `−log p = Σ_k |h_k| /
//!    (h_0 b_m)`. Reweighted least squares (IRLS) replaces `|h|` by its majoriser at the
//!    current iterate `h̄`, `h² / (2 |h̄|) + |h̄| / 2`, so the QP gains a diagonal term in the
//!    Haar basis ([`haar_l1_weights`]): `½ Σ_k d_k h_k²` with
//!    `d_k = 2 σ² / (h_0 b_m (|h̄_k| + ε))`, `ε = EPS_REL · h_0 · m / n` (the magnitude of a
//!    one-texel detail `EPS_REL` of the mean).
//!
//! Both terms are PSD, so the lighting step stays a convex non-negative QP.

// Kernels index several arrays in step.
#![allow(clippy::needless_range_loop)]

use crate::envmap::LatLong;
use crate::haar;
use crate::sphere::SphereGrid;
use crate::{Error, Result, Vec3};

/// Spherical-harmonic coefficients up to order 2.
pub const N_SH: usize = 9;
/// Shape numbers per map: 8 non-constant coefficients × 3 channels.
pub const N_SHAPE: usize = 24;
/// `ε` of the Haar L1 reweighting relative to a one-texel detail of the mean (module docs).
pub const EPS_REL: f64 = 1e-2;

/// The real SH basis up to order 2 at unit direction `d`, order
/// `Y_00, Y_1−1, Y_10, Y_11, Y_2−2, Y_2−1, Y_20, Y_21, Y_22` (orthonormal on the sphere).
pub fn sh9(d: &Vec3) -> [f64; N_SH] {
    let (x, y, z) = (d.x, d.y, d.z);
    [
        0.282_094_791_773_878_1,
        0.488_602_511_902_919_9 * y,
        0.488_602_511_902_919_9 * z,
        0.488_602_511_902_919_9 * x,
        1.092_548_430_592_079_2 * x * y,
        1.092_548_430_592_079_2 * y * z,
        0.315_391_565_252_520_05 * (3.0 * z * z - 1.0),
        1.092_548_430_592_079_2 * x * z,
        0.546_274_215_296_039_6 * (x * x - y * y),
    ]
}

/// `P`: row `t` holds `∫_{texel t} Y_i dω` for the full octahedral grid of side `n`.
#[derive(Debug, Clone)]
pub struct ShProjection {
    /// Texels per side.
    pub n: usize,
    /// Per texel, the nine integrals.
    pub rows: Vec<[f64; N_SH]>,
}

impl ShProjection {
    /// The integrals by `sub × sub` sub-texels (centre value × exact solid angle).
    pub fn new(n: usize, sub: usize) -> Self {
        let grid = SphereGrid::full(n);
        let rows = (0..grid.len())
            .map(|t| {
                let mut acc = [0.0; N_SH];
                for (d, w) in grid.sample_points(t, sub) {
                    let y = sh9(&d);
                    for i in 0..N_SH {
                        acc[i] += w * y[i];
                    }
                }
                acc
            })
            .collect();
        ShProjection { n, rows }
    }

    /// `c = P x` for one channel's texel averages.
    pub fn project(&self, x: &[f64]) -> [f64; N_SH] {
        let mut c = [0.0; N_SH];
        for (row, &v) in self.rows.iter().zip(x) {
            for i in 0..N_SH {
                c[i] += row[i] * v;
            }
        }
        c
    }
}

/// SH coefficients of a lat-long map turned by `radians` about the up axis (`e_z`), per
/// channel: `Σ_p L_p Y_i(R_z(radians) ω_p) ΔΩ_p` (pixels piecewise constant, centre value).
pub fn latlong_sh(ll: &LatLong, radians: f64) -> [[f64; N_SH]; 3] {
    let (s, c) = radians.sin_cos();
    let mut out = [[0.0; N_SH]; 3];
    for v in 0..ll.height {
        let sa = ll.solid_angle(v);
        for u in 0..ll.width {
            let p = ll.rgb[v * ll.width + u];
            let d = ll.dir(u, v);
            let y = sh9(&Vec3::new(c * d.x - s * d.y, s * d.x + c * d.y, d.z));
            for ch in 0..3 {
                let w = p[ch] as f64 * sa;
                for i in 0..N_SH {
                    out[ch][i] += w * y[i];
                }
            }
        }
    }
    out
}

/// The shape vector `ĉ_{c,i} = c_{c,i} / c_{c,0}` (`i ≥ 1`, channel-major), `None` where a
/// channel has no positive mean.
pub fn shape_vector(c: &[[f64; N_SH]; 3]) -> Option<[f64; N_SHAPE]> {
    let mut out = [0.0; N_SHAPE];
    for ch in 0..3 {
        if c[ch][0] <= 0.0 || !c[ch][0].is_finite() {
            return None;
        }
        for i in 1..N_SH {
            out[ch * 8 + i - 1] = c[ch][i] / c[ch][0];
        }
    }
    Some(out)
}

/// Mean `|h_k / h_0|` of one channel's Haar coefficients per level `m = 1, 2, 4, … n/2`
/// (index `log2 m`); `None` without a positive mean.
pub fn haar_level_means(texels: &[f64], n: usize) -> Option<Vec<f64>> {
    let mut h = texels.to_vec();
    haar::forward(&mut h, n);
    if h[0] <= 0.0 {
        return None;
    }
    let levels = n.trailing_zeros() as usize;
    let (mut sum, mut count) = (vec![0.0; levels], vec![0usize; levels]);
    for (k, v) in h.iter().enumerate().skip(1) {
        if let haar::Coefficient::Wavelet { m, .. } = haar::coefficient(n, k) {
            let l = m.trailing_zeros() as usize;
            sum[l] += (v / h[0]).abs();
            count[l] += 1;
        }
    }
    Some(sum.iter().zip(&count).map(|(s, &c)| s / c as f64).collect())
}

/// Statistics of real maps ([`LightPrior::fit`]), stored as JSON
/// (`src/solve/light/light_prior.json`, written by `cargo run --release --example
/// light_prior_stats`).
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct LightPrior {
    /// Names of the maps the statistics come from.
    pub maps: Vec<String>,
    /// Rotations about the up axis per map (evenly spaced over 2π).
    pub rotations: usize,
    /// Mean shape `m` (channel-major, 8 per channel).
    pub shape_mean: Vec<f64>,
    /// Precision `Λ` (24 × 24, row-major): the inverse of the shrunk covariance.
    pub shape_precision: Vec<f64>,
    /// Shrinkage toward the diagonal used for `Λ` (fraction).
    pub shrinkage: f64,
    /// `(n, b_m per level)`: mean `|h_k / h_0|` of the maps resampled to side `n`.
    pub haar_scale: Vec<(usize, Vec<f64>)>,
}

/// One map's contribution to [`LightPrior::fit`].
#[derive(Debug, Clone)]
pub struct PriorSample {
    /// Shape vectors, one per rotation.
    pub shapes: Vec<[f64; N_SHAPE]>,
    /// `(n, level means)` per channel, averaged over channels.
    pub haar: Vec<(usize, Vec<f64>)>,
}

impl LightPrior {
    /// Mean and shrunk covariance of the samples' shapes (every rotation of every map one
    /// sample), `Σ_s = (1 − a) Σ + a diag(Σ)`, inverted; Haar scales averaged over maps.
    pub fn fit(
        names: Vec<String>,
        rotations: usize,
        samples: &[PriorSample],
        shrinkage: f64,
    ) -> Result<LightPrior> {
        let shapes: Vec<&[f64; N_SHAPE]> = samples.iter().flat_map(|s| &s.shapes).collect();
        if shapes.len() < 2 {
            return Err(Error::Config(
                "light prior: fewer than two map samples".into(),
            ));
        }
        let k = shapes.len() as f64;
        let mut mean = vec![0.0; N_SHAPE];
        for s in &shapes {
            for i in 0..N_SHAPE {
                mean[i] += s[i] / k;
            }
        }
        let mut cov = nalgebra::DMatrix::<f64>::zeros(N_SHAPE, N_SHAPE);
        for s in &shapes {
            for i in 0..N_SHAPE {
                for j in 0..N_SHAPE {
                    cov[(i, j)] += (s[i] - mean[i]) * (s[j] - mean[j]) / (k - 1.0);
                }
            }
        }
        for i in 0..N_SHAPE {
            for j in 0..N_SHAPE {
                if i != j {
                    cov[(i, j)] *= 1.0 - shrinkage;
                }
            }
        }
        let prec = cov
            .try_inverse()
            .ok_or_else(|| Error::Config("light prior: the shape covariance is singular".into()))?;
        let mut haar_scale: Vec<(usize, Vec<f64>)> = Vec::new();
        for s in samples {
            for (n, lv) in &s.haar {
                match haar_scale.iter_mut().find(|(m, _)| m == n) {
                    Some((_, acc)) => acc.iter_mut().zip(lv).for_each(|(a, v)| *a += v),
                    None => haar_scale.push((*n, lv.clone())),
                }
            }
        }
        for (_, lv) in haar_scale.iter_mut() {
            lv.iter_mut().for_each(|v| *v /= samples.len() as f64);
        }
        Ok(LightPrior {
            maps: names,
            rotations,
            shape_mean: mean,
            shape_precision: prec.transpose().iter().copied().collect(),
            shrinkage,
            haar_scale,
        })
    }

    /// The statistics committed with the crate (the eight CC0 maps `synth` embeds).
    pub fn builtin() -> Result<LightPrior> {
        serde_json::from_str(include_str!("light_prior.json"))
            .map_err(|e| Error::Config(format!("built-in light prior: {e}")))
    }

    /// `b_m` per level for side `n`, `None` when `n` was not tabulated.
    pub fn haar_scales(&self, n: usize) -> Option<&[f64]> {
        self.haar_scale
            .iter()
            .find(|(m, _)| *m == n)
            .map(|(_, v)| v.as_slice())
    }

    /// Mahalanobis distance² `rᵀ Λ r` of a map's shape from the mean (`None` without a
    /// positive mean in every channel).
    pub fn shape_distance2(&self, c: &[[f64; N_SH]; 3]) -> Option<f64> {
        let s = shape_vector(c)?;
        let r: Vec<f64> = (0..N_SHAPE).map(|i| s[i] - self.shape_mean[i]).collect();
        Some(quad(&self.shape_precision, &r))
    }
}

fn quad(a: &[f64], r: &[f64]) -> f64 {
    let n = r.len();
    let mut s = 0.0;
    for i in 0..n {
        for j in 0..n {
            s += r[i] * a[i * n + j] * r[j];
        }
    }
    s
}

/// Sides at which [`LightPrior::haar_scale`] is tabulated.
pub const HAAR_SIDES: [usize; 6] = [4, 8, 16, 32, 64, 128];

/// One map's [`PriorSample`]: its shape at `rotations` evenly spaced turns about the up
/// axis, and its Haar level means (averaged over channels and over the same turns, the map
/// resampled by [`crate::envmap::OctEnv::from_latlong`]) at every side in `sides`.
pub fn map_sample(ll: &LatLong, rotations: usize, sides: &[usize]) -> PriorSample {
    let turns: Vec<f64> = (0..rotations.max(1))
        .map(|r| 2.0 * std::f64::consts::PI * r as f64 / rotations.max(1) as f64)
        .collect();
    let shapes = turns
        .iter()
        .filter_map(|&a| shape_vector(&latlong_sh(ll, a)))
        .collect();
    // Haar statistics at 4 turns (a quarter turn maps the octahedral grid onto itself, so
    // more turns would interpolate; 4 is enough for level means).
    let haar = sides
        .iter()
        .map(|&n| {
            let mut acc = vec![0.0; n.trailing_zeros() as usize];
            let mut count = 0.0_f64;
            for q in 0..4 {
                let env = crate::envmap::OctEnv::from_latlong(
                    &ll.rotated_about_up(q as f64 * std::f64::consts::FRAC_PI_2),
                    n,
                );
                for c in 0..3 {
                    if let Some(lv) = haar_level_means(&env.channel(c), n) {
                        acc.iter_mut().zip(&lv).for_each(|(a, v)| *a += v);
                        count += 1.0;
                    }
                }
            }
            (n, acc.iter().map(|a| a / count.max(1.0)).collect())
        })
        .collect();
    PriorSample { shapes, haar }
}

/// The SH shape term of one photo's lighting QP, `½ σ² xᵀ Aᵀ Λ A x` (module docs), for
/// `x` = three channels' texels, channel-major (`3 n²`).
#[derive(Debug, Clone)]
pub struct ShPriorTerm {
    n2: usize,
    /// `σ² Λ` (24 × 24, row-major).
    weighted_precision: Vec<f64>,
    /// Rows of `A`: 24 texel vectors, row `c·8 + i − 1` acts on channel `c`.
    rows: Vec<Vec<f64>>,
}

impl ShPriorTerm {
    /// `A` from the projection, the prior's mean and the fixed scales `s_c` (> 0), and
    /// weight `sigma2`.
    pub fn new(proj: &ShProjection, prior: &LightPrior, scale: [f64; 3], sigma2: f64) -> Self {
        let n2 = proj.rows.len();
        let mut rows = Vec::with_capacity(N_SHAPE);
        for c in 0..3 {
            for i in 1..N_SH {
                let m = prior.shape_mean[c * 8 + i - 1];
                rows.push(
                    proj.rows
                        .iter()
                        .map(|p| (p[i] - m * p[0]) / scale[c])
                        .collect(),
                );
            }
        }
        ShPriorTerm {
            n2,
            weighted_precision: prior.shape_precision.iter().map(|v| v * sigma2).collect(),
            rows,
        }
    }

    /// `r = A x`.
    fn residual(&self, x: &[f64]) -> [f64; N_SHAPE] {
        let mut r = [0.0; N_SHAPE];
        for (j, row) in self.rows.iter().enumerate() {
            let c = j / 8;
            let xc = &x[c * self.n2..(c + 1) * self.n2];
            r[j] = row.iter().zip(xc).map(|(a, v)| a * v).sum();
        }
        r
    }

    /// The term's value `½ σ² rᵀ Λ r` at `x`.
    pub fn energy(&self, x: &[f64]) -> f64 {
        0.5 * quad(&self.weighted_precision, &self.residual(x))
    }

    /// `out += σ² Aᵀ Λ A v` (the gradient at `v`, and the Hessian product).
    pub fn add_hessian(&self, v: &[f64], out: &mut [f64]) {
        let r = self.residual(v);
        for (j, row) in self.rows.iter().enumerate() {
            let g: f64 = (0..N_SHAPE)
                .map(|k| self.weighted_precision[j * N_SHAPE + k] * r[k])
                .sum();
            if g == 0.0 {
                continue;
            }
            let c = j / 8;
            for (o, a) in out[c * self.n2..(c + 1) * self.n2].iter_mut().zip(row) {
                *o += g * a;
            }
        }
    }

    /// The Hessian's diagonal, `σ² Σ_{jk} A_{j,t} Λ_{jk} A_{k,t}` per texel (channel-major).
    pub fn diagonal(&self) -> Vec<f64> {
        let mut d = vec![0.0; 3 * self.n2];
        for c in 0..3 {
            for t in 0..self.n2 {
                let mut s = 0.0;
                for i in 0..8 {
                    let ai = self.rows[c * 8 + i][t];
                    for j in 0..8 {
                        let (ji, jj) = (c * 8 + i, c * 8 + j);
                        s += ai * self.weighted_precision[ji * N_SHAPE + jj] * self.rows[jj][t];
                    }
                }
                d[c * self.n2 + t] = s;
            }
        }
        d
    }
}

/// The IRLS weights `d_k` of the Haar L1 term (module docs) for one channel's Haar
/// coefficients `h` at the current iterate (side `n`, `scales` = `b_m` per level), with
/// weight `sigma2`. All zero when `h_0 ≤ 0`. `d_0 = 0` (the mean is not penalised).
pub fn haar_l1_weights(h: &[f64], n: usize, scales: &[f64], sigma2: f64) -> Vec<f64> {
    let mut d = vec![0.0; h.len()];
    let h0 = h[0];
    if h0 <= 0.0 {
        return d;
    }
    for k in 1..h.len() {
        if let haar::Coefficient::Wavelet { m, .. } = haar::coefficient(n, k) {
            let b = scales[m.trailing_zeros() as usize];
            let eps = EPS_REL * h0 * m as f64 / n as f64;
            d[k] = 2.0 * sigma2 / (h0 * b * (h[k].abs() + eps));
        }
    }
    d
}

/// The value of the majorised Haar L1 term, `½ Σ_k d_k h_k²`.
pub fn haar_l1_energy(d: &[f64], h: &[f64]) -> f64 {
    0.5 * d.iter().zip(h).map(|(a, v)| a * v * v).sum::<f64>()
}

/// The texel-basis diagonal of `Wᵀ diag(d) W`: `Σ_k d_k W_{k,t}²`, with `W_{k,t}² = (m/n)²`
/// on the support of wavelet `k` (`1/n²` for the scaling function).
pub fn haar_diag_in_texels(d: &[f64], n: usize) -> Vec<f64> {
    let mut out = vec![d[0] / (n * n) as f64; n * n];
    for (k, &dk) in d.iter().enumerate().skip(1) {
        if dk == 0.0 {
            continue;
        }
        if let haar::Coefficient::Wavelet { m, r, c, .. } = haar::coefficient(n, k) {
            let s = n / m;
            let w2 = dk * (m as f64 / n as f64).powi(2);
            for tj in r * s..(r + 1) * s {
                for ti in c * s..(c + 1) * s {
                    out[tj * n + ti] += w2;
                }
            }
        }
    }
    out
}

/// How the estimator uses the prior ([`crate::estimate::EstimateOptions::light_prior`]).
#[derive(Debug, Clone)]
pub struct LightPriorOptions {
    /// Statistics: one set for every photo, or several chosen by `per_photo`.
    pub stats: std::sync::Arc<Vec<LightPrior>>,
    /// Index into `stats` per photo (benches: statistics that leave out the map a photo
    /// was rendered with); `None` = `stats[0]` for all.
    pub per_photo: Option<Vec<usize>>,
    /// Relative noise level `η` of the SH shape term, `σ = η · rms(y)` (0 = off).
    pub sh_noise: f64,
    /// Relative noise level of the Haar L1 term (0 = off).
    pub haar_noise: f64,
}

impl LightPriorOptions {
    /// The built-in statistics with the given noise levels.
    pub fn builtin(sh_noise: f64, haar_noise: f64) -> Result<Self> {
        Ok(LightPriorOptions {
            stats: std::sync::Arc::new(vec![LightPrior::builtin()?]),
            per_photo: None,
            sh_noise,
            haar_noise,
        })
    }

    /// The statistics for `photo`.
    pub fn for_photo(&self, photo: usize) -> &LightPrior {
        let i = self
            .per_photo
            .as_ref()
            .and_then(|v| v.get(photo).copied())
            .unwrap_or(0);
        &self.stats[i.min(self.stats.len() - 1)]
    }

    /// The prior's terms for one IRLS pass of a lighting QP, linearised at the current
    /// iterate `x` (three channels' texels, channel-major, side `n`): `None` while `x` has
    /// no positive mean in some channel (the first pass from zero) or both terms are off.
    /// `y_ms` = the photo's mean squared radiance (the `rms(y)²` of `σ`).
    pub fn pass(
        &self,
        photo: usize,
        proj: &ShProjection,
        x: &[f64],
        n: usize,
        y_ms: f64,
    ) -> Option<PriorPass> {
        let n2 = n * n;
        let stats = self.for_photo(photo);
        let c0: [f64; 3] = [0, 1, 2].map(|c| proj.project(&x[c * n2..(c + 1) * n2])[0]);
        if c0.iter().any(|v| v.is_nan() || *v <= 0.0)
            || (self.sh_noise <= 0.0 && self.haar_noise <= 0.0)
        {
            return None;
        }
        let sh = (self.sh_noise > 0.0)
            .then(|| ShPriorTerm::new(proj, stats, c0, self.sh_noise.powi(2) * y_ms));
        let mut diag = sh
            .as_ref()
            .map_or_else(|| vec![0.0; 3 * n2], ShPriorTerm::diagonal);
        let haar = match (self.haar_noise > 0.0, stats.haar_scales(n)) {
            (true, Some(scales)) => {
                let s2 = self.haar_noise.powi(2) * y_ms;
                let mut d = vec![[0.0; 3]; n2];
                for c in 0..3 {
                    let mut h = x[c * n2..(c + 1) * n2].to_vec();
                    haar::forward(&mut h, n);
                    let dc = haar_l1_weights(&h, n, scales, s2);
                    let dt = haar_diag_in_texels(&dc, n);
                    for k in 0..n2 {
                        d[k][c] = dc[k];
                        diag[c * n2 + k] += dt[k];
                    }
                }
                Some(d)
            }
            _ => None,
        };
        Some(PriorPass { sh, haar, diag })
    }
}

/// The prior's quadratic terms for one IRLS pass ([`LightPriorOptions::pass`]).
#[derive(Debug, Clone)]
pub struct PriorPass {
    sh: Option<ShPriorTerm>,
    /// Haar L1 weights `d_k` per coefficient, interleaved per channel.
    haar: Option<Vec<[f64; 3]>>,
    /// The Hessian diagonal of both terms in the texel basis, channel-major.
    diag: Vec<f64>,
}

impl PriorPass {
    /// `hb += diag(d) h` for interleaved Haar coefficients `h` (the Haar L1 term).
    pub fn add_haar(&self, h: &[[f64; 3]], hb: &mut [[f64; 3]]) {
        if let Some(d) = &self.haar {
            for ((o, v), w) in hb.iter_mut().zip(h).zip(d) {
                for c in 0..3 {
                    o[c] += w[c] * v[c];
                }
            }
        }
    }

    /// `out += σ² Aᵀ Λ A v` for channel-major texels (the SH term).
    pub fn add_texel(&self, v: &[f64], out: &mut [f64]) {
        if let Some(t) = &self.sh {
            t.add_hessian(v, out);
        }
    }

    /// Texel-basis Hessian diagonal of both terms (channel-major), for Jacobi scaling.
    pub fn diagonal(&self) -> &[f64] {
        &self.diag
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    /// Texel averages of `f` on the full grid by `s × s` sub-texels.
    fn texel_averages(n: usize, s: usize, f: impl Fn(&Vec3) -> f64) -> Vec<f64> {
        let g = SphereGrid::full(n);
        (0..g.len())
            .map(|t| {
                let (mut a, mut w) = (0.0, 0.0);
                for (d, o) in g.sample_points(t, s) {
                    a += o * f(&d);
                    w += o;
                }
                a / w
            })
            .collect()
    }

    #[test]
    fn the_basis_is_orthonormal_by_quadrature() {
        // 128² texels × 4² sub-texels of exact solid angle: a midpoint rule on smooth
        // quadratics, error O(h²) with h ≈ 0.3° → well under 1e-4.
        let p = ShProjection::new(128, 4);
        let g = SphereGrid::full(128);
        for j in 0..N_SH {
            let x: Vec<f64> = (0..g.len()).map(|t| sh9(&g.texel_dir(t))[j]).collect();
            let c = p.project(&x);
            for i in 0..N_SH {
                let want = if i == j { 1.0 } else { 0.0 };
                assert!((c[i] - want).abs() < 1e-3, "⟨Y{i}, Y{j}⟩ = {}", c[i]);
            }
        }
    }

    #[test]
    fn projection_of_the_clamped_cosine_matches_its_analytic_coefficients() {
        // max(0, z): zonal, c_00 = √π/2, c_10 = √(π/3), c_20 = √(5π)/8, all others 0
        // (Ramamoorthi & Hanrahan 2001). Texel averages by 8² sub-texels; the kink at the
        // equator runs along texel edges of the full map (the inner diamond). `P x` treats the
        // map as constant over each texel, an O(h²) error in the texel size: 3.8e-3 on c_10
        // at 32² (measured), so at 64² about a quarter of that, below 2e-3.
        let n = 64;
        let x = texel_averages(n, 8, |d| d.z.max(0.0));
        let c = ShProjection::new(n, 4).project(&x);
        let want = [
            PI.sqrt() / 2.0,
            0.0,
            (PI / 3.0).sqrt(),
            0.0,
            0.0,
            0.0,
            (5.0 * PI).sqrt() / 8.0,
            0.0,
            0.0,
        ];
        for i in 0..N_SH {
            assert!(
                (c[i] - want[i]).abs() < 2e-3,
                "c{i} = {} want {}",
                c[i],
                want[i]
            );
        }
        // A constant map of 1: c_00 = 4π Y_00 = 2√π exactly (solid angles sum to 4π).
        let c1 = ShProjection::new(8, 1).project(&[1.0; 64]);
        assert!((c1[0] - 2.0 * PI.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn latlong_coefficients_turn_with_the_map() {
        // A map bright at azimuth 0 on the horizon: rotating by φ moves Y_11 (∝ x) into
        // Y_1−1 (∝ y): (c_1−1, c_11) → (sin φ, cos φ) c_11. Tolerance 1e-9: the same
        // pixel sum with rotated directions, rounding only.
        let mut ll = LatLong::black(16);
        ll.rgb[8 * ll.width] = [1.0; 3];
        let c0 = latlong_sh(&ll, 0.0);
        let phi = 0.7;
        let c1 = latlong_sh(&ll, phi);
        let (s, c) = phi.sin_cos();
        let want_y = s * c0[0][3] + c * c0[0][1];
        assert!((c1[0][1] - want_y).abs() < 1e-9);
        assert!((c1[0][0] - c0[0][0]).abs() < 1e-12);
    }

    fn toy_prior() -> LightPrior {
        // A made-up SPD precision (diagonally dominant) and mean: the gradient checks do not
        // depend on real statistics.
        let mut prec = vec![0.0; N_SHAPE * N_SHAPE];
        for i in 0..N_SHAPE {
            for j in 0..N_SHAPE {
                prec[i * N_SHAPE + j] = if i == j {
                    3.0 + i as f64 * 0.1
                } else {
                    0.05 * ((i + 2 * j) % 5) as f64 / 5.0
                };
            }
        }
        // Symmetrise.
        for i in 0..N_SHAPE {
            for j in 0..i {
                let v = 0.5 * (prec[i * N_SHAPE + j] + prec[j * N_SHAPE + i]);
                prec[i * N_SHAPE + j] = v;
                prec[j * N_SHAPE + i] = v;
            }
        }
        LightPrior {
            maps: vec![],
            rotations: 1,
            shape_mean: (0..N_SHAPE)
                .map(|i| 0.1 * (i as f64 - 12.0) / 12.0)
                .collect(),
            shape_precision: prec,
            shrinkage: 0.0,
            haar_scale: vec![],
        }
    }

    #[test]
    fn the_sh_term_gradient_matches_finite_differences() {
        // Central differences of a quadratic are exact up to rounding: relative 1e-6.
        let n = 8;
        let p = ShProjection::new(n, 2);
        let term = ShPriorTerm::new(&p, &toy_prior(), [2.0, 1.5, 0.7], 0.3);
        let x: Vec<f64> = (0..3 * n * n)
            .map(|i| 1.0 + ((i * 37) % 11) as f64 / 7.0)
            .collect();
        let mut g = vec![0.0; x.len()];
        term.add_hessian(&x, &mut g);
        let gmax = g.iter().fold(0.0_f64, |a, v| a.max(v.abs()));
        assert!(gmax > 0.0);
        for &t in &[0, 5, 63, 64, 100, 191] {
            let h = 1e-4;
            let (mut xp, mut xm) = (x.clone(), x.clone());
            xp[t] += h;
            xm[t] -= h;
            let fd = (term.energy(&xp) - term.energy(&xm)) / (2.0 * h);
            assert!(
                (fd - g[t]).abs() <= 1e-6 * gmax,
                "texel {t}: fd {fd} grad {}",
                g[t]
            );
        }
        // The diagonal: e_tᵀ H e_t by products.
        let d = term.diagonal();
        for &t in &[3, 70, 150] {
            let mut e = vec![0.0; x.len()];
            e[t] = 1.0;
            let mut he = vec![0.0; x.len()];
            term.add_hessian(&e, &mut he);
            assert!((he[t] - d[t]).abs() <= 1e-12 * d[t].abs().max(1.0));
        }
    }

    #[test]
    fn the_sh_term_vanishes_on_the_mean_shape_and_ignores_scale() {
        // A map whose shape is the prior mean has r = 0 (to the projection's rounding);
        // scaling a map and its s_c together leaves the energy unchanged.
        let n = 16;
        let p = ShProjection::new(n, 2);
        let prior = toy_prior();
        let g = SphereGrid::full(n);
        // Texel values Σ_i a_i Y_i with a_0 = 1 and a_i = m_i (shape = m exactly when the
        // projection reproduces the coefficients, which it does to ~1e-3).
        let x: Vec<f64> = (0..3)
            .flat_map(|c| {
                let prior = &prior;
                (0..g.len()).map(move |t| {
                    let y = sh9(&g.texel_dir(t));
                    y[0] + (1..N_SH)
                        .map(|i| prior.shape_mean[c * 8 + i - 1] * y[i])
                        .sum::<f64>()
                })
            })
            .collect();
        let c0 = p.project(&x[..n * n])[0];
        let term = ShPriorTerm::new(&p, &prior, [c0; 3], 1.0);
        let e_mean = term.energy(&x);
        let flat = vec![1.0; 3 * n * n];
        let e_flat =
            ShPriorTerm::new(&p, &prior, [p.project(&flat[..n * n])[0]; 3], 1.0).energy(&flat);
        // The flat map's shape is 0, distance mᵀΛm ≫ the residual of the mean map.
        assert!(e_mean < 1e-3 * e_flat, "mean {e_mean} flat {e_flat}");
        let x3: Vec<f64> = flat.iter().map(|v| 3.0 * v).collect();
        let e3 =
            ShPriorTerm::new(&p, &prior, [3.0 * p.project(&flat[..n * n])[0]; 3], 1.0).energy(&x3);
        assert!((e3 - e_flat).abs() < 1e-9 * e_flat);
    }

    #[test]
    fn haar_weights_give_the_l1_gradient_at_the_iterate() {
        // At h = h̄ the majoriser ½ d h² has gradient d h̄ = 2σ² sign(h̄) |h̄| / (h_0 b (|h̄| + ε)),
        // i.e. the L1 gradient 2σ² sign(h̄)/(h_0 b) up to the factor |h̄|/(|h̄|+ε) (exactly that
        // factor; tolerance 1e-12 relative, rounding).
        let n = 8;
        let h: Vec<f64> = (0..n * n)
            .map(|k| {
                if k == 0 {
                    4.0
                } else {
                    ((k * 13) % 7) as f64 - 3.0
                }
            })
            .collect();
        let scales = vec![0.5, 0.25, 0.125];
        let d = haar_l1_weights(&h, n, &scales, 0.2);
        assert_eq!(d[0], 0.0);
        for k in 1..n * n {
            let m = match haar::coefficient(n, k) {
                haar::Coefficient::Wavelet { m, .. } => m,
                _ => unreachable!(),
            };
            let b = scales[m.trailing_zeros() as usize];
            let eps = EPS_REL * 4.0 * m as f64 / n as f64;
            let want = 2.0 * 0.2 / (4.0 * b) * h[k].signum() * h[k].abs() / (h[k].abs() + eps);
            let got = d[k] * h[k];
            assert!((got - want).abs() <= 1e-12 * want.abs().max(1e-300));
        }
        // The texel-basis diagonal against Wᵀ diag(d) W applied to unit vectors.
        let dt = haar_diag_in_texels(&d, n);
        for &t in &[0, 9, 27, 63] {
            let mut e = vec![0.0; n * n];
            e[t] = 1.0;
            haar::forward(&mut e, n);
            e.iter_mut().zip(&d).for_each(|(v, w)| *v *= w);
            haar::inverse(&mut e, n);
            assert!((e[t] - dt[t]).abs() < 1e-9 * dt[t]);
        }
    }

    #[test]
    fn the_builtin_statistics_load_and_cover_the_estimator_resolutions() {
        let p = LightPrior::builtin().unwrap();
        assert_eq!(p.shape_mean.len(), N_SHAPE);
        assert_eq!(p.shape_precision.len(), N_SHAPE * N_SHAPE);
        for n in [8, 16, 32, 64] {
            let s = p.haar_scales(n).unwrap();
            assert_eq!(s.len(), n.trailing_zeros() as usize);
            assert!(s.iter().all(|v| *v > 0.0 && v.is_finite()));
        }
    }
}
