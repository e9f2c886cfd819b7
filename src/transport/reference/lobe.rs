//! The reference lobes (Lambert, Phong, GGX with Smith shadowing) as closed-form BRDFs with importance sampling, and the materials' reflectance `ρ(x) = Σ_k w_k(x) Σ_b λ_{k,b} ρ_b`.

use super::*;

// ---------------------------------------------------------------------------------------
// Basis lobes.

/// One colourless basis BRDF, cosine term included.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "type", rename_all = "lowercase")]
pub enum Lobe {
    /// `cos θ_i / π`.
    Lambert,
    /// Normalised Phong (Lafortune) lobe about the mirror direction, exponent `exponent`.
    Phong {
        /// The exponent N.
        exponent: f64,
    },
    /// GGX microfacet lobe with roughness `alpha` (α used directly in D and G1).
    Ggx {
        /// The roughness α.
        alpha: f64,
    },
}

/// The GGX normal distribution `D(h)` given `cos θ_h = n·h`.
pub(crate) fn ggx_d(alpha: f64, nh: f64) -> f64 {
    let a2 = alpha * alpha;
    let t = nh * nh * (a2 - 1.0) + 1.0;
    a2 / (PI * t * t)
}

/// The GGX (Smith) masking term `G1(v)` given `n·v > 0`.
pub(crate) fn ggx_g1(alpha: f64, nv: f64) -> f64 {
    let a2 = alpha * alpha;
    2.0 * nv / (nv + (a2 + (1.0 - a2) * nv * nv).sqrt())
}

/// Mirror of `wo` about `n`.
pub(crate) fn reflect(n: &Vec3, wo: &Vec3) -> Vec3 {
    n * (2.0 * n.dot(wo)) - wo
}

/// An orthonormal frame `[x, y, z]` with `z = a` (unit). Frisvad-style branchless basis
/// (Duff et al. 2017); kept local so this module shares nothing with the wavelet path.
pub(crate) fn basis(a: &Vec3) -> [Vec3; 3] {
    let sign = 1.0_f64.copysign(a.z);
    let p = -1.0 / (sign + a.z);
    let q = a.x * a.y * p;
    [
        Vec3::new(1.0 + sign * a.x * a.x * p, sign * q, -sign * a.x),
        Vec3::new(q, sign + a.y * a.y * p, -a.y),
        *a,
    ]
}

/// Direction with polar angle cosine `cos_t` and azimuth `phi` about the unit axis `a`.
pub(crate) fn about_axis(a: &Vec3, cos_t: f64, phi: f64) -> Vec3 {
    let f = basis(a);
    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    f[0] * (sin_t * phi.cos()) + f[1] * (sin_t * phi.sin()) + f[2] * cos_t
}

impl Lobe {
    /// `ρ_b(ω_i, ω_o)` including `cos θ_i`, for unit normal `n` and unit directions pointing
    /// away from the surface.
    pub fn eval(&self, n: &Vec3, wi: &Vec3, wo: &Vec3) -> f64 {
        let ci = n.dot(wi);
        if ci <= 0.0 {
            return 0.0;
        }
        match *self {
            Lobe::Lambert => ci / PI,
            Lobe::Phong { exponent } => {
                let rd = reflect(n, wo).dot(wi);
                if rd <= 0.0 {
                    return 0.0;
                }
                (exponent + 2.0) / (2.0 * PI) * rd.powf(exponent) * ci
            }
            Lobe::Ggx { alpha } => {
                let co = n.dot(wo);
                if co <= 0.0 {
                    return 0.0;
                }
                let h = wi + wo;
                let hn = h.norm();
                if hn == 0.0 {
                    return 0.0;
                }
                let nh = n.dot(&h) / hn;
                ggx_d(alpha, nh) * ggx_g1(alpha, ci) * ggx_g1(alpha, co) / (4.0 * co)
            }
        }
    }

    /// Draw `ω_i` from this lobe's sampling density given two uniforms in [0, 1).
    /// The direction may lie below the surface (then `eval` is zero); `None` when the
    /// density is degenerate there.
    pub fn sample(&self, n: &Vec3, wo: &Vec3, u1: f64, u2: f64) -> Option<Vec3> {
        let phi = 2.0 * PI * u2;
        match *self {
            // Cosine-weighted hemisphere: cos θ = sqrt(1 − u1).
            Lobe::Lambert => Some(about_axis(n, (1.0 - u1).sqrt(), phi)),
            // cos^N about the mirror direction: cos α = u^(1/(N+1)).
            Lobe::Phong { exponent } => {
                let r = reflect(n, wo);
                Some(about_axis(
                    &r.normalize(),
                    (1.0 - u1).powf(1.0 / (exponent + 1.0)),
                    phi,
                ))
            }
            // Half vector ∝ D(h)(n·h): tan²θ_h = α² u / (1 − u); reflect ω_o about h.
            Lobe::Ggx { alpha } => {
                let a2 = alpha * alpha;
                let cos_h = ((1.0 - u1) / (1.0 + (a2 - 1.0) * u1)).max(0.0).sqrt();
                let h = about_axis(n, cos_h, phi);
                let oh = wo.dot(&h);
                if oh <= 0.0 {
                    return None;
                }
                Some(h * (2.0 * oh) - wo)
            }
        }
    }

    /// The density (w.r.t. solid angle) with which [`Lobe::sample`] draws `ω_i`.
    pub fn pdf(&self, n: &Vec3, wi: &Vec3, wo: &Vec3) -> f64 {
        match *self {
            Lobe::Lambert => n.dot(wi).max(0.0) / PI,
            Lobe::Phong { exponent } => {
                let rd = reflect(n, wo).normalize().dot(wi);
                if rd <= 0.0 {
                    0.0
                } else {
                    (exponent + 1.0) / (2.0 * PI) * rd.powf(exponent)
                }
            }
            Lobe::Ggx { alpha } => {
                let h = wi + wo;
                let hn = h.norm();
                if hn == 0.0 {
                    return 0.0;
                }
                let h = h / hn;
                let nh = n.dot(&h);
                let oh = wo.dot(&h);
                if nh <= 0.0 || oh <= 0.0 {
                    return 0.0;
                }
                ggx_d(alpha, nh) * nh / (4.0 * oh)
            }
        }
    }

    /// Checks the parameter: Phong exponent ≥ 0, GGX α in (0, 1].
    pub fn validate(&self) -> Result<()> {
        match *self {
            Lobe::Lambert => Ok(()),
            Lobe::Phong { exponent } if exponent.is_finite() && exponent >= 0.0 => Ok(()),
            Lobe::Ggx { alpha } if alpha.is_finite() && alpha > 0.0 && alpha <= 1.0 => Ok(()),
            other => Err(Error::Internal(format!("invalid basis lobe {other:?}"))),
        }
    }
}

// ---------------------------------------------------------------------------------------
// Reflectance: materials and per-vertex blending weights (Eq. 11).

/// Materials over basis lobes and their per-vertex blend (paper Eq. 11).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Reflectance {
    /// The B basis lobes.
    pub lobes: Vec<Lobe>,
    /// `lambda[k][b][c]`: weight of lobe b in material k for colour channel c.
    pub lambda: Vec<Vec<[f64; 3]>>,
    /// Per-vertex blending weights, row-major `n_vertices × K`.
    pub weights: Vec<f64>,
}

impl Reflectance {
    /// Number of materials K.
    pub fn n_materials(&self) -> usize {
        self.lambda.len()
    }

    /// Checks shapes and signs against `n_vertices`.
    pub fn validate(&self, n_vertices: usize) -> Result<()> {
        for l in &self.lobes {
            l.validate()?;
        }
        let k = self.lambda.len();
        if k == 0 {
            return Err(Error::Internal("reflectance has no material".into()));
        }
        for (i, m) in self.lambda.iter().enumerate() {
            if m.len() != self.lobes.len() {
                return Err(Error::Internal(format!(
                    "material {i} has {} lobe weights, expected {}",
                    m.len(),
                    self.lobes.len()
                )));
            }
            if m.iter().flatten().any(|x| !x.is_finite() || *x < 0.0) {
                return Err(Error::Internal(format!(
                    "material {i} has a negative or non-finite weight"
                )));
            }
        }
        if self.weights.len() != n_vertices * k {
            return Err(Error::Internal(format!(
                "{} blending weights for {n_vertices} vertices × {k} materials",
                self.weights.len()
            )));
        }
        if self.weights.iter().any(|x| !x.is_finite() || *x < 0.0) {
            return Err(Error::Internal(
                "negative or non-finite blending weight".into(),
            ));
        }
        Ok(())
    }

    /// Per-lobe, per-channel weights `β_bc = Σ_k w_k λ_kbc` for material weights `w`.
    pub fn beta(&self, w: &[f64]) -> Vec<[f64; 3]> {
        let mut beta = vec![[0.0; 3]; self.lobes.len()];
        for (k, &wk) in w.iter().enumerate() {
            if wk == 0.0 {
                continue;
            }
            for (b, lam) in self.lambda[k].iter().enumerate() {
                for c in 0..3 {
                    beta[b][c] += wk * lam[c];
                }
            }
        }
        beta
    }

    /// The blending weights of vertex `v`.
    pub fn vertex_weights(&self, v: usize) -> &[f64] {
        let k = self.lambda.len();
        &self.weights[v * k..(v + 1) * k]
    }
}
