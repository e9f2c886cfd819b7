//! A lat-long environment map prepared for lookup and importance sampling (texel solid angles, the luminance-weighted sampling distribution).

use super::*;

// ---------------------------------------------------------------------------------------
// The environment: piecewise-constant lat-long map with an importance-sampling CDF.

/// A lat-long environment map (docs/conventions.md) prepared for lookup and importance sampling.
#[derive(Debug, Clone)]
pub struct Environment {
    pub(crate) width: usize,
    pub(crate) height: usize,
    pub(crate) rgb: Vec<[f64; 3]>,
    /// `[e_x, e_y, e_z]` in world coordinates.
    pub(crate) frame: [Vec3; 3],
    /// Per-row cumulative texel probabilities (each row ends at 1), `height × width`.
    pub(crate) cond_cdf: Vec<f64>,
    /// Cumulative row probabilities, length `height`.
    pub(crate) marg_cdf: Vec<f64>,
    /// Texel probability `P_texel` per texel.
    pub(crate) prob: Vec<f64>,
}

/// Solid angle of every texel in row `v` of a `2H × H` map.
pub fn texel_solid_angle(width: usize, height: usize, v: usize) -> f64 {
    let t0 = PI * v as f64 / height as f64;
    let t1 = PI * (v + 1) as f64 / height as f64;
    2.0 * PI / width as f64 * (t0.cos() - t1.cos())
}

impl Environment {
    /// From `width × height` texels of linear RGB (row-major, v = 0 the top row = up) in the
    /// environment frame `frame = [e_x, e_y, e_z]` (world coordinates, see
    /// [`crate::sphere::env_frame`]). Negative values (lossy EXR) are clamped to zero.
    pub fn new(width: usize, height: usize, rgb: &[[f32; 3]], frame: [Vec3; 3]) -> Result<Self> {
        if width == 0 || height == 0 || rgb.len() != width * height {
            return Err(Error::Internal(format!(
                "environment map {width}×{height} with {} texels",
                rgb.len()
            )));
        }
        if rgb.iter().flatten().any(|x| !x.is_finite()) {
            return Err(Error::Numeric {
                stage: "reference environment".into(),
                message: "non-finite texel".into(),
            });
        }
        let rgb: Vec<[f64; 3]> = rgb
            .iter()
            .map(|p| {
                [
                    p[0].max(0.0) as f64,
                    p[1].max(0.0) as f64,
                    p[2].max(0.0) as f64,
                ]
            })
            .collect();
        // Luminance × solid angle, then per-row conditional and row marginal CDFs.
        let mut prob = vec![0.0; width * height];
        for v in 0..height {
            let om = texel_solid_angle(width, height, v);
            for u in 0..width {
                let p = &rgb[v * width + u];
                prob[v * width + u] = (LUMA[0] * p[0] + LUMA[1] * p[1] + LUMA[2] * p[2]) * om;
            }
        }
        let total: f64 = prob.iter().sum();
        let mut cond_cdf = vec![0.0; width * height];
        let mut marg_cdf = vec![0.0; height];
        if total > 0.0 {
            let mut acc_rows = 0.0;
            for v in 0..height {
                let row = &mut prob[v * width..(v + 1) * width];
                let row_sum: f64 = row.iter().sum();
                let mut acc = 0.0;
                for u in 0..width {
                    row[u] /= total;
                    acc += row[u];
                    cond_cdf[v * width + u] = if row_sum > 0.0 {
                        acc * total / row_sum
                    } else {
                        (u + 1) as f64 / width as f64
                    };
                }
                cond_cdf[v * width + width - 1] = 1.0;
                acc_rows += row_sum / total;
                marg_cdf[v] = acc_rows;
            }
            marg_cdf[height - 1] = 1.0;
        }
        Ok(Environment {
            width,
            height,
            rgb,
            frame,
            cond_cdf,
            marg_cdf,
            prob,
        })
    }

    /// A constant environment of radiance `rgb` (the white furnace), `8 × 4` texels.
    pub fn constant(rgb: [f32; 3], frame: [Vec3; 3]) -> Result<Self> {
        Environment::new(8, 4, &[rgb; 32], frame)
    }

    /// Width (2H) and height (H) in texels.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// True when the map is black everywhere (nothing to sample).
    pub fn is_black(&self) -> bool {
        self.marg_cdf.last().is_none_or(|&x| x == 0.0)
    }

    /// Texel `(u, v)` containing world direction `d` (unit).
    pub(crate) fn texel_of(&self, d: &Vec3) -> (usize, usize) {
        let (x, y, z) = (
            self.frame[0].dot(d),
            self.frame[1].dot(d),
            self.frame[2].dot(d),
        );
        let theta = z.clamp(-1.0, 1.0).acos();
        let mut phi = y.atan2(x);
        if phi < 0.0 {
            phi += 2.0 * PI;
        }
        let v = ((theta / PI * self.height as f64) as usize).min(self.height - 1);
        let u = ((phi / (2.0 * PI) * self.width as f64) as usize).min(self.width - 1);
        (u, v)
    }

    /// Radiance arriving from world direction `d` (unit): the texel containing it.
    pub fn radiance(&self, d: &Vec3) -> [f64; 3] {
        let (u, v) = self.texel_of(d);
        self.rgb[v * self.width + u]
    }

    /// Density (w.r.t. solid angle) with which [`Environment::sample`] draws `d`.
    pub fn pdf(&self, d: &Vec3) -> f64 {
        let (u, v) = self.texel_of(d);
        let p = self.prob[v * self.width + u];
        if p == 0.0 {
            0.0
        } else {
            p / texel_solid_angle(self.width, self.height, v)
        }
    }

    /// Draws a world direction from three uniforms: returns `(direction, pdf)`.
    /// `None` when the map is black.
    pub fn sample(&self, u1: f64, u2: f64, u3: f64, u4: f64) -> Option<(Vec3, f64)> {
        if self.is_black() {
            return None;
        }
        let v = self
            .marg_cdf
            .partition_point(|&c| c <= u1)
            .min(self.height - 1);
        let row = &self.cond_cdf[v * self.width..(v + 1) * self.width];
        let u = row.partition_point(|&c| c <= u2).min(self.width - 1);
        let p = self.prob[v * self.width + u];
        if p == 0.0 {
            return None;
        }
        // Uniform in (φ, cos θ) inside the texel: uniform in solid angle.
        let (h, w) = (self.height as f64, self.width as f64);
        let c0 = (PI * v as f64 / h).cos();
        let c1 = (PI * (v + 1) as f64 / h).cos();
        let cos_t = c0 + (c1 - c0) * u3;
        let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
        let phi = 2.0 * PI * (u as f64 + u4) / w;
        let d = self.frame[0] * (sin_t * phi.cos())
            + self.frame[1] * (sin_t * phi.sin())
            + self.frame[2] * cos_t;
        Some((d, p / texel_solid_angle(self.width, self.height, v)))
    }
}
