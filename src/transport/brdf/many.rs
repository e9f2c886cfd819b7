//! A lobe evaluated over many sample directions at once ([`LobeAt::eval_many`]), for the
//! slices' quadrature ([`super::BasisBrdf::slice_with`]).
//!
//! The directions come as a structure of arrays ([`Samples`]) and the GGX lobe is written
//! branch-free (a select instead of an early return), so the compiler evaluates several
//! samples per instruction. Each value is computed by the same operations in the same order
//! as [`LobeAt::eval`], so the results are bit-identical to it (unit test below). Measured
//! (`bench-results/speed-memory.md`, `cargo bench --bench slicetime`, CPU time): a GGX
//! slice of the 32² local map 14–17.5 µs against 18–23 µs before. Phong with a whole-number
//! exponent goes four samples at a time through the same squarings (`cargo bench --bench
//! slicetime`: Phong 50 and 500 slices 18–20.5 → 13–14 µs). A branch-free batch was slower
//! when every texel was sampled, since most samples lie behind the mirror direction; since
//! the texels beyond the negligible angle are skipped ([`super::BasisBrdf::negligible_angle`]),
//! most samples left are in front of it. A fractional exponent stays sample by sample.
//!
//! GGX's `ω_i`-only factor, the denominator of `G1(ω_i)`, `g = cᵢ + √(α² + (1−α²) cᵢ²)`,
//! depends on the sample and `α` alone, not on `ω_o`: it is computed once per sample array
//! and `α` ([`Samples::ggx_denominators`], the same operations, so the same bits) instead of
//! once per slice. That takes the square root, the costliest operation of a sample, out of
//! every slice; the one division stays.

use super::LobeAt;
use crate::Vec3;
use std::f64::consts::PI;

/// Sample directions (unit vectors, local frame) and their solid angles, one array per
/// component.
#[derive(Debug, Default)]
pub(crate) struct Samples {
    pub x: Vec<f64>,
    pub y: Vec<f64>,
    pub z: Vec<f64>,
    pub w: Vec<f64>,
}

/// GGX's `G1(ω_i)` denominator `g = cᵢ + √(α² + (1−α²) cᵢ²)` for `cᵢ = n·ω_i`: the
/// expression of [`LobeAt::eval`], operation for operation.
#[inline(always)]
pub(crate) fn ggx_denominator(a2: f64, ci: f64) -> f64 {
    ci + (a2 + (1.0 - a2) * ci * ci).sqrt()
}

impl Samples {
    pub fn push(&mut self, d: Vec3, w: f64) {
        self.x.push(d.x);
        self.y.push(d.y);
        self.z.push(d.z);
        self.w.push(w);
    }

    /// [`ggx_denominator`] of every sample for `α² = a2` (kept per lobe and level by the
    /// slices' grid, so computed once).
    pub fn ggx_denominators(&self, a2: f64) -> Vec<f64> {
        self.z.iter().map(|&ci| ggx_denominator(a2, ci)).collect()
    }

    #[cfg(test)]
    pub fn len(&self) -> usize {
        self.x.len()
    }

    /// Sample `i` as `(direction, solid angle)`.
    #[cfg(test)]
    pub fn get(&self, i: usize) -> (Vec3, f64) {
        (Vec3::new(self.x[i], self.y[i], self.z[i]), self.w[i])
    }
}

/// Samples per step of the whole-number Phong batch.
const PHONG_LANES: usize = 4;

/// [`super::powu`] of each lane: the same multiplications in the same order, so the same
/// bits, with the loop over the exponent's bits shared by the lanes.
#[inline(always)]
fn powu_lanes(mut x: [f64; PHONG_LANES], mut n: u32) -> [f64; PHONG_LANES] {
    let mut r = [1.0f64; PHONG_LANES];
    loop {
        if n & 1 == 1 {
            for l in 0..PHONG_LANES {
                r[l] *= x[l];
            }
        }
        n >>= 1;
        if n == 0 {
            return r;
        }
        for v in &mut x {
            *v *= *v;
        }
    }
}

impl LobeAt {
    /// `out[i] = self.eval(&(x[i], y[i], z[i]))` for the samples `range` of `s`. A GGX
    /// lobe reads its `G1(ω_i)` denominators from `ggx_g` (all of `s`'s samples,
    /// [`Samples::ggx_denominators`] for its `α²`; other lobes ignore it). Compiled for AVX2
    /// too when the CPU has it (four samples per instruction instead of two; no fused
    /// multiply-add, so the values stay bit-identical to [`LobeAt::eval`]).
    pub(crate) fn eval_many(
        &self,
        s: &Samples,
        ggx_g: &[f64],
        range: std::ops::Range<usize>,
        out: &mut [f64],
    ) {
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports the feature `eval_many_avx2` is compiled for.
            return unsafe { self.eval_many_avx2(s, ggx_g, range, out) };
        }
        self.eval_many_impl(s, ggx_g, range, out)
    }

    /// [`LobeAt::eval_many_impl`] compiled for AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn eval_many_avx2(
        &self,
        s: &Samples,
        ggx_g: &[f64],
        range: std::ops::Range<usize>,
        out: &mut [f64],
    ) {
        self.eval_many_impl(s, ggx_g, range, out)
    }

    /// The loops behind [`LobeAt::eval_many`].
    #[inline(always)]
    fn eval_many_impl(
        &self,
        s: &Samples,
        ggx_g: &[f64],
        range: std::ops::Range<usize>,
        out: &mut [f64],
    ) {
        let (x, y, z) = (
            &s.x[range.clone()],
            &s.y[range.clone()],
            &s.z[range.clone()],
        );
        let out = &mut out[..x.len()];
        match *self {
            LobeAt::Zero => out.iter_mut().for_each(|o| *o = 0.0),
            LobeAt::Lambert => {
                for (o, &ci) in out.iter_mut().zip(z) {
                    *o = if ci <= 0.0 { 0.0 } else { ci / PI };
                }
            }
            // A whole-number exponent: four samples at a time, every lane through the same
            // squarings (the exponent is the same for all), zero selected afterwards.
            LobeAt::Phong {
                mirror,
                integer: Some(n),
                norm,
                ..
            } => {
                let lanes = out.len() / PHONG_LANES * PHONG_LANES;
                for i in (0..lanes).step_by(PHONG_LANES) {
                    let mut rd = [0.0f64; PHONG_LANES];
                    for l in 0..PHONG_LANES {
                        rd[l] = mirror.x * x[i + l] + mirror.y * y[i + l] + mirror.z * z[i + l];
                    }
                    let p = powu_lanes(rd, n);
                    for l in 0..PHONG_LANES {
                        let ci = z[i + l];
                        let v = norm * p[l] * ci;
                        out[i + l] = if ci <= 0.0 || rd[l] <= 0.0 { 0.0 } else { v };
                    }
                }
                for i in lanes..out.len() {
                    out[i] = self.eval(&Vec3::new(x[i], y[i], z[i]));
                }
            }
            // A fractional exponent stays scalar (`powf`).
            LobeAt::Phong { .. } => {
                for (i, o) in out.iter_mut().enumerate() {
                    *o = self.eval(&Vec3::new(x[i], y[i], z[i]));
                }
            }
            LobeAt::Ggx { wo, a2, k } => {
                let gs = &ggx_g[range];
                for i in 0..out.len() {
                    let ci = z[i];
                    let (hx, hy, hz) = (x[i] + wo.x, y[i] + wo.y, ci + wo.z);
                    let hh = hx * hx + hy * hy + hz * hz;
                    let u = hz * hz * (a2 - 1.0) + hh;
                    let g = gs[i];
                    let v = k * hh * hh * ci / (u * u * g);
                    out[i] = if ci <= 0.0 || hh <= 0.0 { 0.0 } else { v };
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::transport::brdf::BasisBrdf;
    use rand::{Rng, SeedableRng};

    #[test]
    fn eval_many_is_bit_identical_to_eval() {
        // Random directions over the whole sphere (both hemispheres, so the zero branches
        // are taken too) and random outgoing directions: every value must equal the scalar
        // `eval` exactly (same operations in the same order), for every kind of lobe.
        let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
        let mut unit = || loop {
            let v = Vec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            );
            if v.norm() > 0.1 && v.norm() <= 1.0 {
                return v.normalize();
            }
        };
        let mut s = Samples::default();
        for _ in 0..700 {
            s.push(unit(), 1.0);
        }
        let lobes = [
            BasisBrdf::Lambert,
            BasisBrdf::Phong { exponent: 50.0 },
            BasisBrdf::Phong { exponent: 7.5 },
            BasisBrdf::Ggx { alpha: 0.1 },
            BasisBrdf::Ggx { alpha: 0.6 },
        ];
        let mut out = vec![0.0; s.len()];
        for b in lobes {
            for _ in 0..5 {
                let mut wo = unit();
                wo.z = wo.z.abs();
                let lobe = b.at(&wo);
                let g = match lobe {
                    LobeAt::Ggx { a2, .. } => s.ggx_denominators(a2),
                    _ => Vec::new(),
                };
                lobe.eval_many(&s, &g, 0..s.len(), &mut out);
                for (i, &o) in out.iter().enumerate() {
                    let (d, _) = s.get(i);
                    assert_eq!(o.to_bits(), lobe.eval(&d).to_bits(), "{b:?} sample {i}");
                }
            }
        }
        // A GGX lobe seen from below the horizon is zero everywhere.
        BasisBrdf::Ggx { alpha: 0.2 }
            .at(&Vec3::new(0.0, 0.6, -0.8))
            .eval_many(&s, &[], 0..s.len(), &mut out);
        assert!(out.iter().all(|&o| o == 0.0));
    }
}
