//! Outdoor sun and sky (issue 25, not in the paper): a per-photo light that is a
//! physically plausible parametric map plus a penalised non-negative wavelet residual.
//!
//! **The map.** With the non-linear values `θ = (s, T, κ)` fixed (sun direction `s`, a unit
//! vector of the environment frame whose `e_z` is up; turbidity `T ∈ [1, 10]`; sun-lobe
//! sharpness `κ`), photo `I`'s light in channel `c` is
//!
//! `L_{I,c}(ω) = Σ_j w_{j,c} B_{j,c}(ω; θ) + r_c(ω)`, `w ≥ 0`, `r ≥ 0`,
//!
//! linear and non-negative in the nine colour weights `w` and the residual texels `r`. The
//! three bases ([`SkyBasis`]), each scaled to integrate to 1 over the sphere so that a
//! weight is the term's radiant power per unit solid-angle-integral:
//! 1. **sky**: the Hosek–Wilkie 2012 clear-sky radiance ("An analytic model for full
//!    spectral sky-dome radiance", SIGGRAPH 2012) in channel `c`, for view zenith angle
//!    `θ_v` and angle `γ` to the sun, sun elevation `asin s_z` clamped to `[0, π/2]`, ground
//!    albedo 0.3; zero below the horizon. Evaluated by the `hw-skymodel` crate (the
//!    authors' fitted RGB coefficients, MIT): the model's 9-parameter formula needs its
//!    coefficient tables, which a hand-written Preetham 1999 would replace by a less
//!    accurate fit, so the crate is used as-is;
//! 2. **sun**: a normalised von Mises–Fisher lobe around `s`,
//!    `B_sun(ω) = κ / (2π (1 − e^{−2κ})) · exp(κ (ω·s − 1))` (the sun disc blurred to the
//!    resolution the transport can resolve; `κ` its shape);
//! 3. **ground**: `1 / (2π)` below the horizon (light bounced off the ground), 0 above.
//!
//! Texel values are the averages of the basis over the texel (`sub × sub` sub-texels with
//! exact solid angles, [`crate::sphere::SphereGrid::sample_points`]). The sky's radiance is
//! smooth away from the sun and the horizon, and there its texels average 3 × 3 sub-texels
//! instead of 6 × 6, as do the sun lobe's where it is below `e^{−12}` of its peak
//! ([`SkySampling`]): 0.04% of the sky map's L1 norm on a 32² map, 0.85× the built-in
//! example's wall time (`bench-results/sky-sampling.md`).
//!
//! **The residual's prior.** Natural illumination is sparse in wavelets (Dror et al. 2004,
//! as in [`crate::solve::light::sh_prior`]): each Haar coefficient `h_k` of `r_c` (the
//! scaling coefficient too) gets the convex penalty
//! `φ(h_k) = 2σ² (u − ln(1 + u))`, `u = |h_k| / a_k`, `a_k = h_{0,c} b_{m(k)}`,
//! quadratic (`σ² u²`) for small residuals and L1 (`2σ² u`) for large ones. `h_{0,c}` is the
//! whole light's scaling coefficient (so the penalty is invariant to the light's scale),
//! `b_m` the mean `|h_k / h_0|` of real maps at the coefficient's level (the built-in light
//! prior's statistics, the coarsest level for the scaling coefficient), `σ = η · rms(y)`.
//! Reweighted least squares majorises `φ` at the current residual `h̄` by
//! `½ d_k h_k² + const`, `d_k = φ'(h̄_k)/h̄_k = 2σ² / (a_k (|h̄_k| + a_k))` ([`residual_weights`]),
//! so each lighting step is one convex non-negative QP in `(w, r)` whose value never rises
//! (majorise–minimise, one reweighting per outer iteration).
//!
//! **The lighting step** ([`SkyLight::fit`](model::SkyLight)), per photo with `β` fixed:
//! 1. `θ` search with `r` fixed: for each candidate `θ`, the nine weights by NNLS on the
//!    photo's observations (3 × 3 per channel, from the bases' responses through the
//!    transport) and its weighted squared error; on the photo's first step a grid of
//!    [`GRID_SUNS`] sun directions on the upper hemisphere (Fibonacci) at `T = 3`, `κ = 64`,
//!    then a pattern search over `(azimuth, elevation, ln κ, T)` with halving steps; through
//!    the third outer iteration the grid runs again and the better of its best and the
//!    previous `θ` is refined; later steps only refine the previous `θ` with small steps
//!    ([`search`]);
//! 2. the joint QP in `(w, r) ≥ 0` at the chosen `θ`, warm-started from the search's `w`
//!    and the previous `r`, solved by [`crate::solve::qp::bound_qp_scaled`].
//!
//! **Geotagged photos** ([`clock`]): a photo whose EXIF gives its place and UTC instant
//! has its sun's elevation and compass azimuth from the solar position algorithm; only
//! north's azimuth `ν` in the environment frame is unknown, one value for the whole
//! collection. Before each lighting step `ν` is chosen by the search error summed over
//! those photos (a 5° grid through the third outer iteration, then ±2.5° by 0.5° around
//! the best), and step 1 above searches only their turbidity and lobe.
//!
//! **Held-out photos** ([`held_out`]): held-out protocol (b) fits a geotagged held-out
//! photo's light within this model, its sun the clock's at the training photos' north.

// Kernels index several arrays in step; range loops read like the math.
#![allow(clippy::needless_range_loop)]

pub mod clock;
pub mod held_out;
pub mod model;
pub mod samples;
pub mod search;
pub mod summary;
#[cfg(test)]
mod tests;

use hw_skymodel::rgb::{Channel, SkyParams, SkyState};

use crate::{Error, Result, Vec3};

pub use model::{SkyLight, SkyOptions};
pub use samples::{SkySampling, TexelSamples, LOBE_COARSE_FROM, SKY_SAMPLING};

/// The number of basis maps: sky, sun, ground.
pub const N_BASIS: usize = 3;
/// Basis index of the Hosek–Wilkie sky.
pub const SKY: usize = 0;
/// Basis index of the sun lobe.
pub const SUN: usize = 1;
/// Basis index of the ground.
pub const GROUND: usize = 2;
/// Ground albedo of the Hosek–Wilkie sky (a typical outdoor value; the ground's own
/// radiance is the separate ground basis).
pub const SKY_GROUND_ALBEDO: f64 = 0.3;
/// Sun directions of the first step's grid (about 18° apart on the upper hemisphere).
pub const GRID_SUNS: usize = 64;
/// Sub-texels per texel side when texel averages are formed.
pub const SUB_TEXELS: usize = 6;
/// Range of the sun lobe's `κ`: from a lobe ~40° wide to one well below a texel of the
/// finest map the transport uses.
pub const KAPPA_RANGE: (f64, f64) = (2.0, 4000.0);

/// The non-linear values of one photo's sun and sky (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SunSky {
    /// Unit sun direction, environment frame (`e_z` up).
    pub sun: Vec3,
    /// Atmospheric turbidity, `[1, 10]`.
    pub turbidity: f64,
    /// Sharpness of the sun lobe, [`KAPPA_RANGE`].
    pub kappa: f64,
}

impl SunSky {
    /// The sun at `azimuth` (from `e_x` toward `e_y`) and `elevation` above the horizon.
    pub fn from_angles(azimuth: f64, elevation: f64, turbidity: f64, kappa: f64) -> Self {
        let (se, ce) = elevation.sin_cos();
        let (sa, ca) = azimuth.sin_cos();
        SunSky {
            sun: Vec3::new(ce * ca, ce * sa, se),
            turbidity,
            kappa,
        }
    }

    /// `(azimuth, elevation)` of the sun.
    pub fn angles(&self) -> (f64, f64) {
        let s = &self.sun;
        (s.y.atan2(s.x), s.z.clamp(-1.0, 1.0).asin())
    }
}

/// Hosek–Wilkie state for a sun direction and turbidity (elevation clamped to `[0, π/2]`,
/// turbidity to `[1, 10]`).
pub fn sky_state(p: &SunSky) -> Result<SkyState> {
    let (_, elev) = p.angles();
    let params = SkyParams {
        elevation: elev.clamp(0.0, std::f64::consts::FRAC_PI_2) as f32,
        turbidity: p.turbidity.clamp(1.0, 10.0) as f32,
        albedo: [SKY_GROUND_ALBEDO as f32; 3],
    };
    SkyState::new(&params).map_err(|e| Error::Numeric {
        stage: "sky model".into(),
        message: e.to_string(),
    })
}

/// Hosek–Wilkie radiance per channel seen in direction `d` (unit) under sun `sun`: zero at
/// or below the horizon.
pub fn sky_radiance(state: &SkyState, d: &Vec3, sun: &Vec3) -> [f64; 3] {
    sky_radiance_at(state, d, d.z.clamp(-1.0, 1.0).acos() as f32, sun)
}

/// [`sky_radiance`] with the view zenith angle `theta = acos d_z` given.
fn sky_radiance_at(state: &SkyState, d: &Vec3, theta: f32, sun: &Vec3) -> [f64; 3] {
    if d.z <= 0.0 {
        return [0.0; 3];
    }
    let gamma = d.dot(sun).clamp(-1.0, 1.0).acos() as f32;
    [Channel::R, Channel::G, Channel::B].map(|c| (state.radiance(theta, gamma, c) as f64).max(0.0))
}

/// The normalised sun lobe at `cos γ = ω·s` (module docs): integrates to 1 over the sphere.
pub fn sun_lobe(kappa: f64, cos_gamma: f64) -> f64 {
    sun_lobe_normed(sun_lobe_norm(kappa), kappa, cos_gamma)
}

/// The sun lobe's normalisation `κ / (2π (1 − e^{−2κ}))`, [`sun_lobe`] at `cos γ = 1`.
fn sun_lobe_norm(kappa: f64) -> f64 {
    kappa / (2.0 * std::f64::consts::PI * (-(-2.0 * kappa).exp_m1()))
}

/// [`sun_lobe`] with its normalisation `norm` ([`sun_lobe_norm`]) given.
fn sun_lobe_normed(norm: f64, kappa: f64, cos_gamma: f64) -> f64 {
    norm * (kappa * (cos_gamma - 1.0)).exp()
}

/// The ground basis at `d`: `1/(2π)` below the horizon.
pub fn ground(d: &Vec3) -> f64 {
    if d.z < 0.0 {
        0.5 / std::f64::consts::PI
    } else {
        0.0
    }
}

/// The basis maps of one `θ` on the full octahedral grid of side `n`: per basis and
/// channel, texel averages, each basis scaled to unit integral per channel.
#[derive(Debug, Clone)]
pub struct SkyBasis {
    /// Texels per side.
    pub n: usize,
    /// `maps[j][c]`: basis `j`'s texels in channel `c`.
    pub maps: [[Vec<f64>; 3]; N_BASIS],
}

impl SkyBasis {
    /// The bases at `p` (texel averages by `sub × sub` sub-texels, [`TexelSamples`]).
    pub fn new(n: usize, sub: usize, p: &SunSky) -> Result<SkyBasis> {
        let samples = TexelSamples::shared(n, sub);
        let mut maps: [[Vec<f64>; 3]; N_BASIS] = Default::default();
        maps[SKY] = Self::sky_map(&samples, p)?;
        maps[SUN] = Self::lobe_map(&samples, p);
        maps[GROUND] = std::array::from_fn(|_| samples.ground.clone());
        Ok(SkyBasis { n, maps })
    }

    /// The sky basis at `p`, texel averages over `samples`: the Hosek–Wilkie radiance,
    /// scaled to unit integral per channel. It depends on `p`'s sun and turbidity only.
    /// Texels where the radiance is smooth across the texel ([`SkySampling`]) average the
    /// coarser samples of [`SKY_SAMPLING`].
    pub fn sky_map(samples: &TexelSamples, p: &SunSky) -> Result<[Vec<f64>; 3]> {
        Self::sky_map_sampled(samples, p, Some(&SKY_SAMPLING))
    }

    /// [`Self::sky_map`] with every texel over `samples` (`sampling` `None`) or the
    /// coarse samples where `sampling` allows.
    pub fn sky_map_sampled(
        samples: &TexelSamples,
        p: &SunSky,
        sampling: Option<&SkySampling>,
    ) -> Result<[Vec<f64>; 3]> {
        let state = sky_state(p)?;
        let sun = p.sun.normalize();
        let mut map = samples.texel_means_mixed(
            sampling,
            |k, t| k.smooth_at(samples, t, &sun),
            |s, i, d| sky_radiance_at(&state, d, s.zenith[i], &sun),
        );
        for ch in map.iter_mut() {
            let total: f64 = ch
                .iter()
                .zip(&samples.solid_angle)
                .map(|(v, o)| v * o)
                .sum();
            if total > 0.0 {
                ch.iter_mut().for_each(|v| *v /= total);
            }
        }
        Ok(map)
    }

    /// The sun lobe basis at `p` (unit integral by formula), texel averages over
    /// `samples`. It depends on `p`'s sun and `κ` only. Texels where the whole lobe is
    /// below `e^{−`[`LOBE_COARSE_FROM`]`}` of its peak ([`SkySampling::lobe_negligible_at`])
    /// average the coarse samples of [`SKY_SAMPLING`].
    pub fn lobe_map(samples: &TexelSamples, p: &SunSky) -> [Vec<f64>; 3] {
        Self::lobe_map_sampled(samples, p, Some(&SKY_SAMPLING))
    }

    /// [`Self::lobe_map`] with every texel over `samples` (`sampling` `None`) or the
    /// coarse samples where `sampling` allows.
    pub fn lobe_map_sampled(
        samples: &TexelSamples,
        p: &SunSky,
        sampling: Option<&SkySampling>,
    ) -> [Vec<f64>; 3] {
        let sun = p.sun.normalize();
        let lobe_norm = sun_lobe_norm(p.kappa);
        samples.texel_means_mixed(
            sampling,
            |k, t| k.lobe_negligible_at(samples, t, &sun, p.kappa),
            |_, _, d| [sun_lobe_normed(lobe_norm, p.kappa, d.dot(&sun)); 3],
        )
    }

    /// `Σ_j w_{j,c} B_{j,c}` per channel.
    pub fn combine(&self, w: &[[f64; 3]; N_BASIS]) -> [Vec<f64>; 3] {
        let n2 = self.n * self.n;
        std::array::from_fn(|c| {
            (0..n2)
                .map(|t| (0..N_BASIS).map(|j| w[j][c] * self.maps[j][c][t]).sum())
                .collect()
        })
    }
}

/// `b_{m(k)}` per Haar coefficient of a side-`n` map from the level means `scales`
/// ([`crate::solve::light::sh_prior::LightPrior::haar_scales`]); the scaling coefficient
/// takes the coarsest level's.
pub fn coefficient_scales(n: usize, scales: &[f64]) -> Vec<f64> {
    use crate::sphere::haar::{coefficient, Coefficient};
    (0..n * n)
        .map(|k| match coefficient(n, k) {
            Coefficient::Scaling => scales[0],
            Coefficient::Wavelet { m, .. } => scales[m.trailing_zeros() as usize],
        })
        .collect()
}

/// The residual prior's IRLS weights `d_k = 2σ² / (a_k (|h̄_k| + a_k))`, `a_k = h0 b_k`
/// (module docs), for one channel's Haar coefficients `h` of the residual.
pub fn residual_weights(h: &[f64], h0: f64, b: &[f64], sigma2: f64) -> Vec<f64> {
    h.iter()
        .zip(b)
        .map(|(v, bk)| {
            let a = h0 * bk;
            2.0 * sigma2 / (a * (v.abs() + a))
        })
        .collect()
}

/// The residual prior's value `Σ_k 2σ² (u_k − ln(1 + u_k))`, `u_k = |h_k| / (h0 b_k)`.
pub fn residual_penalty(h: &[f64], h0: f64, b: &[f64], sigma2: f64) -> f64 {
    h.iter()
        .zip(b)
        .map(|(v, bk)| {
            let u = v.abs() / (h0 * bk);
            2.0 * sigma2 * (u - u.ln_1p())
        })
        .sum()
}
