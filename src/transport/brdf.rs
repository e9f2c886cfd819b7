//! Basis BRDFs (paper Sec. 5.2, Eq. 11): the lobes `ρ_b` whose non-negative mixtures make
//! the materials, `ρ(x) = Σ_k w_k(x) Σ_b λ_kb ρ_b`.
//!
//! Every lobe is colourless (colour lives in `λ`) and INCLUDES the cosine term of Eq. 1,
//! `cos θ_i = max(0, n·ω_i)`. Directions are unit vectors in the local frame of
//! [`crate::sphere::local_frame`] (`z` = normal), pointing away from the surface.
//!
//! - Lambert: `ρ = cos θ_i / π` (albedo 1).
//! - Phong, the normalised Lafortune cosine lobe with exponent `N`:
//!   `ρ = (N+2)/(2π) · max(0, r·ω_i)^N · cos θ_i`, `r = 2(n·ω_o)n − ω_o`; its albedo is 1 at
//!   normal incidence and falls toward grazing angles.
//! - GGX Cook–Torrance with roughness `α` (used directly), Fresnel = 1:
//!   `ρ = D(h) G1(ω_i) G1(ω_o) / (4 cos θ_o)` (the `cos θ_i` of Eq. 1 cancels the one in
//!   the microfacet denominator), `h = normalize(ω_i + ω_o)`,
//!   `D = α² / (π ((n·h)²(α²−1)+1)²)`, `G1(v) = 2(n·v) / ((n·v) + sqrt(α² + (1−α²)(n·v)²))`;
//!   zero when either cosine is ≤ 0.
//!
//! A *slice* is `ρ_b(·, ω_o)` for a fixed outgoing direction, tabulated as texel averages
//! over the local hemisphere ([`mod@slice`]).

use crate::{Error, Result, Vec3};
use std::f64::consts::PI;

/// One basis BRDF lobe (colourless, includes `cos θ_i`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum BasisBrdf {
    /// `cos θ_i / π`.
    Lambert,
    /// Normalised Lafortune/Phong cosine lobe around the mirror direction.
    Phong {
        /// Lobe exponent `N > 0`.
        exponent: f64,
    },
    /// GGX Cook–Torrance microfacet lobe, Fresnel = 1.
    Ggx {
        /// Roughness `α` in `(0, 1]`.
        alpha: f64,
    },
}

/// The default set of basis BRDFs: a Lambertian lobe, GGX lobes of roughness 0.1, 0.2 and
/// 0.4, and Phong lobes of exponent 50 and 500 (the paper's synthetic tests use 7 lobes of
/// this kind).
pub fn default_basis() -> Vec<BasisBrdf> {
    vec![
        BasisBrdf::Lambert,
        BasisBrdf::Ggx { alpha: 0.1 },
        BasisBrdf::Ggx { alpha: 0.2 },
        BasisBrdf::Ggx { alpha: 0.4 },
        BasisBrdf::Phong { exponent: 50.0 },
        BasisBrdf::Phong { exponent: 500.0 },
    ]
}

/// Parse a comma-separated list of basis BRDFs (`"lambert,ggx:0.2,phong:50"`).
pub fn parse_list(s: &str) -> Result<Vec<BasisBrdf>> {
    let list: Vec<BasisBrdf> = s
        .split(',')
        .filter(|t| !t.trim().is_empty())
        .map(BasisBrdf::parse)
        .collect::<Result<_>>()?;
    if list.is_empty() {
        return Err(Error::Config(format!("basis BRDF list `{s}` is empty")));
    }
    Ok(list)
}

/// GGX normal distribution `D(h)` for `c = n·h` (the textbook form; [`LobeAt`] folds it
/// into one division, checked against this in the tests).
#[cfg(test)]
fn ggx_d(alpha: f64, c: f64) -> f64 {
    let a2 = alpha * alpha;
    let t = c * c * (a2 - 1.0) + 1.0;
    a2 / (PI * t * t)
}

/// Separable Smith masking term `G1(v)` for `c = n·v > 0`.
fn ggx_g1(alpha: f64, c: f64) -> f64 {
    let a2 = alpha * alpha;
    2.0 * c / (c + (a2 + (1.0 - a2) * c * c).sqrt())
}

/// A lobe with its outgoing direction fixed: the factors of [`BasisBrdf::eval`] that depend
/// on `ω_o` only, computed once, so that the hundreds of samples of a slice pay only for what
/// depends on `ω_i` (GGX: one square root and one division instead of three and five;
/// Phong: the mirror direction, and the integer power by squaring inline, the same
/// operations as the runtime's `powi`, which is an out-of-line call).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LobeAt {
    /// Zero for every `ω_i` (GGX with `ω_o` at or below the horizon).
    Zero,
    /// `cos θ_i / π`.
    Lambert,
    /// `norm · max(0, r·ω_i)^N · cos θ_i`.
    Phong {
        /// The mirror direction `r` of `ω_o`.
        mirror: Vec3,
        /// `N`.
        exponent: f64,
        /// `N` when it is a whole number (the usual case).
        integer: Option<u32>,
        /// `(N + 2) / 2π`.
        norm: f64,
    },
    /// GGX (see [`BasisBrdf::at`] for `k`).
    Ggx {
        /// `ω_o`.
        wo: Vec3,
        /// `α²`.
        a2: f64,
        /// The `ω_o`-only factor.
        k: f64,
    },
}

impl LobeAt {
    /// `ρ(ω_i, ω_o)` including `cos θ_i` (`wi` a unit vector in the local frame).
    #[inline]
    pub fn eval(&self, wi: &Vec3) -> f64 {
        let ci = wi.z;
        if ci <= 0.0 {
            return 0.0;
        }
        match *self {
            LobeAt::Zero => 0.0,
            LobeAt::Lambert => ci / PI,
            LobeAt::Phong {
                mirror,
                exponent,
                integer,
                norm,
            } => {
                let rd = mirror.dot(wi);
                if rd <= 0.0 {
                    return 0.0;
                }
                let p = match integer {
                    Some(n) => powu(rd, n),
                    None => rd.powf(exponent),
                };
                norm * p * ci
            }
            LobeAt::Ggx { wo, a2, k } => {
                let h = wi + wo;
                let hh = h.dot(&h);
                if hh <= 0.0 {
                    return 0.0;
                }
                let u = h.z * h.z * (a2 - 1.0) + hh;
                let g = many::ggx_denominator(a2, ci);
                k * hh * hh * ci / (u * u * g)
            }
        }
    }
}

/// `x^n` by repeated squaring (compiler-rt's `__powidf2` loop, inline).
#[inline]
fn powu(mut x: f64, mut n: u32) -> f64 {
    let mut r = 1.0;
    loop {
        if n & 1 == 1 {
            r *= x;
        }
        n >>= 1;
        if n == 0 {
            return r;
        }
        x *= x;
    }
}

impl BasisBrdf {
    /// `ρ(ω_i, ω_o)` including `cos θ_i`; `wi`, `wo` unit vectors in the local frame.
    pub fn eval(&self, wi: &Vec3, wo: &Vec3) -> f64 {
        self.at(wo).eval(wi)
    }

    /// The lobe with its outgoing direction fixed ([`LobeAt`]).
    pub fn at(&self, wo: &Vec3) -> LobeAt {
        match *self {
            BasisBrdf::Lambert => LobeAt::Lambert,
            BasisBrdf::Phong { exponent } => LobeAt::Phong {
                // r·ω_i = 2(n·ω_o)(n·ω_i) − ω_o·ω_i with r = (−ω_o,x, −ω_o,y, ω_o,z).
                mirror: Vec3::new(-wo.x, -wo.y, wo.z),
                exponent,
                integer: (exponent.fract() == 0.0 && exponent <= u32::MAX as f64)
                    .then_some(exponent as u32),
                norm: (exponent + 2.0) / (2.0 * PI),
            },
            BasisBrdf::Ggx { alpha } => {
                let co = wo.z;
                if co <= 0.0 {
                    return LobeAt::Zero;
                }
                let a2 = alpha * alpha;
                LobeAt::Ggx {
                    wo: *wo,
                    a2,
                    // D G1(ω_i) G1(ω_o) / (4 cos θ_o) = k · hh² cᵢ / (u² (cᵢ + √(α² +
                    // (1−α²) cᵢ²))) with h = ω_i + ω_o unnormalised, hh = h·h,
                    // u = h_z² (α² − 1) + hh (so (n·ĥ)²(α²−1)+1 = u / hh), and
                    // k = α² · 2 · G1(ω_o) / (4 cos θ_o π).
                    k: a2 * ggx_g1(alpha, co) / (2.0 * PI * co),
                }
            }
        }
    }

    /// Parse `"lambert"`, `"phong:N"` (N > 0) or `"ggx:α"` (0 < α ≤ 1).
    pub fn parse(s: &str) -> Result<Self> {
        let t = s.trim().to_ascii_lowercase();
        let (name, arg) = match t.split_once(':') {
            Some((n, a)) => (n.trim(), Some(a.trim())),
            None => (t.as_str(), None),
        };
        let number = |what: &str| -> Result<f64> {
            let a = arg.ok_or_else(|| {
                Error::Config(format!("basis BRDF `{s}`: expected `{name}:{what}`"))
            })?;
            a.parse::<f64>()
                .map_err(|_| Error::Config(format!("basis BRDF `{s}`: `{a}` is not a number")))
        };
        match name {
            "lambert" | "lambertian" | "diffuse" => {
                if arg.is_some() {
                    return Err(Error::Config(format!(
                        "basis BRDF `{s}`: lambert takes no parameter"
                    )));
                }
                Ok(BasisBrdf::Lambert)
            }
            "phong" | "lafortune" => {
                let exponent = number("exponent")?;
                if !(exponent.is_finite() && exponent > 0.0 && exponent <= 1.0e5) {
                    return Err(Error::Config(format!(
                        "basis BRDF `{s}`: the Phong exponent must lie in (0, 1e5]"
                    )));
                }
                Ok(BasisBrdf::Phong { exponent })
            }
            "ggx" | "cook-torrance" | "ct" => {
                let alpha = number("roughness")?;
                if !(1.0e-3..=1.0).contains(&alpha) {
                    return Err(Error::Config(format!(
                        "basis BRDF `{s}`: the GGX roughness must lie in [0.001, 1]"
                    )));
                }
                Ok(BasisBrdf::Ggx { alpha })
            }
            _ => Err(Error::Config(format!(
                "unknown basis BRDF `{s}` (expected lambert, phong:N or ggx:alpha)"
            ))),
        }
    }

    /// A short label that [`BasisBrdf::parse`] reads back (`"ggx:0.2"`).
    pub fn label(&self) -> String {
        match self {
            BasisBrdf::Lambert => "lambert".to_string(),
            BasisBrdf::Phong { exponent } => format!("phong:{exponent}"),
            BasisBrdf::Ggx { alpha } => format!("ggx:{alpha}"),
        }
    }

    /// Whether the lobe depends on `ω_o` (Lambert does not: one slice serves every view).
    pub fn view_dependent(&self) -> bool {
        !matches!(self, BasisBrdf::Lambert)
    }

    /// Angular half-width (radians) inside which the lobe holds most of its energy; used to
    /// decide where slices need finer supersampling.
    pub fn lobe_width(&self) -> f64 {
        match *self {
            BasisBrdf::Lambert => PI,
            // cos^N(θ) = e^{-1} at θ ≈ sqrt(2/N) (small angles); 3 of those hold the lobe.
            BasisBrdf::Phong { exponent } => (3.0 * (2.0 / exponent).sqrt()).min(PI),
            // Half-vector spread ~α, reflected direction spread ~2α.
            BasisBrdf::Ggx { alpha } => (6.0 * alpha).min(PI),
        }
    }

    /// The lobe's peak direction for outgoing `wo` (local frame): the mirror direction.
    pub fn peak(&self, wo: &Vec3) -> Vec3 {
        match self {
            BasisBrdf::Lambert => Vec3::z(),
            _ => Vec3::new(-wo.x, -wo.y, wo.z),
        }
    }
}

mod many;
pub mod slice;
pub use slice::{SliceGrid, SliceTable};
#[cfg(test)]
use slice::{MAX_LEVEL, NEGLIGIBLE};

#[cfg(test)]
mod tests;
