//! The renderer's rotation ([`SplatRotation`]) builds `S_n` for the vertex's own normal
//! `n` at every call instead of blending precomputed ones: with the global texel `g` cut
//! into `s × s` sub-texels `k` (exact solid angles `ω_k`, `Σ_k ω_k = Ω_g`, centres `d_k`),
//!
//! `(S_n L̄)_j = (1/Ω_j) Σ_g L̄_g Σ_{k ∈ g : R_nᵀ d_k ∈ texel j, z > 0} ω_k`,
//!
//! i.e. the overlap area `|texel_j ∩ R_n texel_g|` measured by the sub-texels of `g` that
//! land in local texel `j` (a splat: each sub-texel goes to exactly one local texel). Every
//! column sums to the part of `Ω_g` above the horizon, so a one-texel sun keeps exactly
//! its energy `Ω_g L̄_g` and lands where its sub-texels point, with no bilinear spread and
//! no blend of four neighbouring frames (Eq. 6 moves a light by up to the normal grid's
//! spacing, about two 64² local texels at the default 32² normal grid). Rows sum to `Ω_j`
//! up to the sub-texel quantisation (a constant sky stays constant on average over a few
//! texels, not per texel). Cost per vertex: about `n_global² s² / 2` lookups (the upper
//! half), no precomputed matrices. Measured (`bench-results/agreement.md`, sphere over a
//! plane, 8 real maps, diffuse error against the Eq. 1 reference, mean / max over maps):
//! 0.93% / 1.47% at 64² global / 64² local, against 1.11% / 1.97% for the blended factored
//! rotation at the same resolutions (which also needs 31 s and ~300 MB of tables there).

use super::LocalRotation;
use crate::sphere::haar;
use crate::sphere::{local_frame, SphereGrid};
use crate::Vec3;

/// [`SplatRotation::locate`]'s mark of a sub-texel on or below the horizon.
const BELOW: u32 = u32::MAX;

/// The renderer's per-normal rotation (module docs, "The renderer's rotation"): `S_n` by
/// splatting the sub-texels of every global texel into the local texels of the exact frame
/// [`local_frame`]`(n)`. Holds only the sub-texel directions and solid angles of the
/// global grid (`n_global² s²` of them), no per-normal matrices.
#[derive(Debug, Clone)]
pub struct SplatRotation {
    n_global: usize,
    local: SphereGrid,
    /// Sub-texels per side of a global texel.
    supersample: usize,
    /// `1 / Ω_j` per local texel.
    inv_omega_local: Vec<f64>,
    /// Per global texel: its sub-texels `lo..hi` in `dirs` / `weights`.
    ranges: Vec<(u32, u32)>,
    /// Per global texel: centre direction and the sine of its angular radius (a texel
    /// whose centre is more than that below the horizon has no sub-texel above it).
    centres: Vec<(Vec3, f64)>,
    /// Sub-texel centre directions (environment frame).
    dirs: Vec<Vec3>,
    /// Sub-texel solid angles `ω_k`.
    weights: Vec<f64>,
}

impl SplatRotation {
    /// `s × s` sub-texels per global texel (`supersample`, at least 1).
    /// [`SplatRotation::default_supersample`] picks one for the two resolutions.
    pub fn new(n_global: usize, n_local: usize, supersample: usize) -> Self {
        let s = supersample.max(1);
        let gg = SphereGrid::full(n_global);
        let local = SphereGrid::hemi(n_local);
        let inv_omega_local = local.solid_angles().iter().map(|w| 1.0 / w).collect();
        let mut ranges = Vec::with_capacity(gg.len());
        let mut centres = Vec::with_capacity(gg.len());
        let mut dirs = Vec::with_capacity(gg.len() * s * s);
        let mut weights = Vec::with_capacity(gg.len() * s * s);
        for g in 0..gg.len() {
            let c = gg.texel_dir(g);
            let lo = dirs.len() as u32;
            // Corners bound the texel's angular radius; sub-texel centres lie inside.
            let nf = n_global as f64;
            let (i, j) = ((g % n_global) as f64, (g / n_global) as f64);
            let radius = [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)]
                .iter()
                .map(|(a, b)| gg.decode([(i + a) / nf, (j + b) / nf]).angle(&c))
                .fold(0.0, f64::max);
            for (d, w) in gg.sample_points(g, s) {
                dirs.push(d);
                weights.push(w);
            }
            ranges.push((lo, dirs.len() as u32));
            centres.push((c, (radius * 1.01).min(std::f64::consts::FRAC_PI_2).sin()));
        }
        SplatRotation {
            n_global,
            local,
            supersample: s,
            inv_omega_local,
            ranges,
            centres,
            dirs,
            weights,
        }
    }

    /// [`SplatRotation::new`] with [`SplatRotation::default_supersample`] sub-texels.
    pub fn with_default_supersample(n_global: usize, n_local: usize) -> Self {
        Self::new(
            n_global,
            n_local,
            Self::default_supersample(n_global, n_local),
        )
    }

    /// Sub-texels per side: a global texel is `√2 n_local / n_global` local texels wide
    /// (full sphere `4π` over `n_global²` texels, hemisphere `2π` over `n_local²`);
    /// `s = max(2, ⌈4 n_local / n_global⌉)` makes a sub-texel at most `√2/4 ≈ 0.35` of a
    /// local texel wide, and the number of sub-texels `16 n_local²` whatever the global
    /// side (4 at 64² / 64²). Measured at 64² / 64² (`bench-results/agreement.md`, diffuse,
    /// max over 8 maps): s = 2: 2.52%, 4: 1.47%; s = 8 gave 1.39% at 4× the cost of 4 (one
    /// run outside the committed table).
    pub fn default_supersample(n_global: usize, n_local: usize) -> usize {
        (4 * n_local).div_ceil(n_global.max(1)).max(2)
    }

    /// Sub-texels per side of a global texel.
    pub fn supersample(&self) -> usize {
        self.supersample
    }

    /// Bytes held (sub-texel directions and weights, per-texel ranges and centres).
    pub fn memory_bytes(&self) -> usize {
        self.dirs.len() * (24 + 8) + self.ranges.len() * (8 + 32) + self.inv_omega_local.len() * 8
    }

    /// Visit every sub-texel above the horizon of `normal`'s frame: `f(global texel, local
    /// texel, ω_k)`, global texel by global texel, sub-texels in order.
    fn for_each_sub(&self, normal: &Vec3, mut f: impl FnMut(usize, usize, f64)) {
        let frame = local_frame(normal);
        let z = frame[2];
        let mut at = Vec::with_capacity(self.supersample * self.supersample);
        for (g, ((lo, hi), (c, sin_r))) in self.ranges.iter().zip(&self.centres).enumerate() {
            if c.dot(&z) < -sin_r {
                continue;
            }
            let (lo, hi) = (*lo as usize, *hi as usize);
            at.clear();
            at.resize(hi - lo, 0);
            self.locate(&frame, lo, &mut at);
            for (k, &j) in (lo..hi).zip(&at) {
                if j != BELOW {
                    f(g, j as usize, self.weights[k]);
                }
            }
        }
    }

    /// The local texel (in `frame`) of sub-texels `lo..lo + out.len()`, or [`BELOW`] for
    /// those on or below the horizon: AVX2 where the CPU has it, four sub-texels at a time
    /// with the scalar code's operations in its order (so the same texels; test
    /// `both_locates_give_the_same_texels`).
    fn locate(&self, frame: &[Vec3; 3], lo: usize, out: &mut [u32]) {
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2.
            unsafe { self.locate_avx2(frame, lo, out) };
            return;
        }
        self.locate_scalar(frame, lo, out);
    }

    /// [`SplatRotation::locate`] one sub-texel at a time: `l = (d·x, d·y, d·z)`, then
    /// [`SphereGrid::texel_of`] on the local hemi-octahedral grid.
    fn locate_scalar(&self, frame: &[Vec3; 3], lo: usize, out: &mut [u32]) {
        let [x, y, z] = frame;
        for (k, o) in (lo..).zip(out.iter_mut()) {
            let d = &self.dirs[k];
            let lz = d.dot(z);
            *o = if lz <= 0.0 {
                BELOW
            } else {
                self.local.texel_of(&Vec3::new(d.dot(x), d.dot(y), lz)) as u32
            };
        }
    }

    /// [`SplatRotation::locate_scalar`] with AVX2: `Vec3::dot` is `(a_x b_x + a_y b_y) +
    /// a_z b_z`, and [`crate::sphere::hemi_oct_encode`] with `texel_of`'s truncation are
    /// the same operations lane by lane (no fused multiply-add).
    ///
    /// # Safety
    /// The CPU must have AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn locate_avx2(&self, frame: &[Vec3; 3], lo: usize, out: &mut [u32]) {
        use std::arch::x86_64::*;
        let four = out.len() / 4 * 4;
        let [x, y, z] = frame;
        let b = |v: f64| _mm256_set1_pd(v);
        let (xx, xy, xz) = (b(x.x), b(x.y), b(x.z));
        let (yx, yy, yz) = (b(y.x), b(y.y), b(y.z));
        let (zx, zy, zz) = (b(z.x), b(z.y), b(z.z));
        let n = self.local.n;
        let (nf, top) = (b(n as f64), _mm_set1_epi32(n as i32 - 1));
        let (one, half, zero) = (b(1.0), b(0.5), _mm256_setzero_pd());
        let sign = b(-0.0);
        let dot = |dx, dy, dz, ax, ay, az| {
            _mm256_add_pd(
                _mm256_add_pd(_mm256_mul_pd(dx, ax), _mm256_mul_pd(dy, ay)),
                _mm256_mul_pd(dz, az),
            )
        };
        for q in (0..four).step_by(4) {
            let d = &self.dirs[lo + q..lo + q + 4];
            let dx = _mm256_setr_pd(d[0].x, d[1].x, d[2].x, d[3].x);
            let dy = _mm256_setr_pd(d[0].y, d[1].y, d[2].y, d[3].y);
            let dz = _mm256_setr_pd(d[0].z, d[1].z, d[2].z, d[3].z);
            let lz = dot(dx, dy, dz, zx, zy, zz);
            let lx = dot(dx, dy, dz, xx, xy, xz);
            let ly = dot(dx, dy, dz, yx, yy, yz);
            // hemi_oct_encode: l1 = |x| + |y| + max(z, 0), p = (x, y) / l1,
            // uv = ((p_x + p_y + 1) / 2, (p_x − p_y + 1) / 2); texel_of: ⌊uv n⌋ ≤ n − 1.
            let l1 = _mm256_add_pd(
                _mm256_add_pd(_mm256_andnot_pd(sign, lx), _mm256_andnot_pd(sign, ly)),
                _mm256_max_pd(lz, zero),
            );
            let (px, py) = (_mm256_div_pd(lx, l1), _mm256_div_pd(ly, l1));
            let u = _mm256_mul_pd(_mm256_add_pd(_mm256_add_pd(px, py), one), half);
            let v = _mm256_mul_pd(_mm256_add_pd(_mm256_sub_pd(px, py), one), half);
            let i = _mm_min_epi32(_mm256_cvttpd_epi32(_mm256_mul_pd(u, nf)), top);
            let j = _mm_min_epi32(_mm256_cvttpd_epi32(_mm256_mul_pd(v, nf)), top);
            let t = _mm_add_epi32(_mm_mullo_epi32(j, _mm_set1_epi32(n as i32)), i);
            let above = _mm256_castps256_ps128(_mm256_permutevar8x32_ps(
                _mm256_castpd_ps(_mm256_cmp_pd::<_CMP_GT_OQ>(lz, zero)),
                _mm256_setr_epi32(0, 2, 4, 6, 0, 0, 0, 0),
            ));
            let t = _mm_blendv_epi8(_mm_set1_epi32(-1), t, _mm_castps_si128(above));
            _mm_storeu_si128(out[q..q + 4].as_mut_ptr() as *mut __m128i, t);
        }
        self.locate_scalar(frame, lo + four, &mut out[four..]);
    }

    /// Texel domain, all channels in one pass: `local[c] = S_n global[c]` (texel averages).
    pub fn resample_rgb(&self, normal: &Vec3, global: [&[f64]; 3], local: &mut [Vec<f64>; 3]) {
        self.resample_rgb_many(normal, &[global], std::slice::from_mut(local));
    }

    /// [`SplatRotation::resample_rgb`] for several lights: one walk over the footprint of
    /// `normal` accumulates every light's three channels (light `i`: `global[i]` into
    /// `local[i]`), each in the same order whatever the number of lights.
    pub fn resample_rgb_many(
        &self,
        normal: &Vec3,
        global: &[[&[f64]; 3]],
        local: &mut [[Vec<f64>; 3]],
    ) {
        assert_eq!(global.len(), local.len(), "one output per light");
        for l in local.iter_mut().flatten() {
            l.clear();
            l.resize(self.local.len(), 0.0);
        }
        self.for_each_sub(normal, |g, j, w| {
            for ([g0, g1, g2], [l0, l1, l2]) in global.iter().zip(local.iter_mut()) {
                l0[j] += w * g0[g];
                l1[j] += w * g1[g];
                l2[j] += w * g2[g];
            }
        });
        for l in local.iter_mut().flatten() {
            l.iter_mut()
                .zip(&self.inv_omega_local)
                .for_each(|(x, iw)| *x *= iw);
        }
    }

    /// [`SplatRotation::resample_rgb_many`] with the lights' texels interleaved: global
    /// texel `g` of value slot `k` (a light's channel) at `global[g · width + k]`, and the
    /// `spans` of slots wanted (in order) written to `local[j · w + k']` (`j` local texel,
    /// `w` the spans' total length, `k'` the slot's position among them). Each sub-texel
    /// adds `ω_k` times a contiguous run of `w` values, which vectorises, instead of three
    /// scattered values per light; every output is the same sum in the same order as
    /// [`SplatRotation::resample_rgb_many`]'s, so equal bit for bit.
    pub fn resample_interleaved(
        &self,
        normal: &Vec3,
        global: &[f64],
        width: usize,
        spans: &[std::ops::Range<usize>],
        local: &mut Vec<f64>,
    ) {
        let w: usize = spans.iter().map(|s| s.len()).sum();
        local.clear();
        local.resize(self.local.len() * w, 0.0);
        self.for_each_sub(normal, |g, j, wk| {
            let (src, dst) = (
                &global[g * width..(g + 1) * width],
                &mut local[j * w..(j + 1) * w],
            );
            let mut at = 0;
            for s in spans {
                let d = &mut dst[at..at + s.len()];
                at += s.len();
                for (o, v) in d.iter_mut().zip(&src[s.clone()]) {
                    *o += wk * v;
                }
            }
        });
        for (row, iw) in local.chunks_mut(w.max(1)).zip(&self.inv_omega_local) {
            row.iter_mut().for_each(|x| *x *= iw);
        }
    }

    /// Texel domain: `local = S_n global` (one channel).
    pub fn resample(&self, normal: &Vec3, global: &[f64], local: &mut [f64]) {
        local.fill(0.0);
        self.for_each_sub(normal, |g, j, w| local[j] += w * global[g]);
        local
            .iter_mut()
            .zip(&self.inv_omega_local)
            .for_each(|(x, iw)| *x *= iw);
    }

    /// Texel domain: `global += S_nᵀ local`.
    pub fn resample_transpose_add(&self, normal: &Vec3, local: &[f64], global: &mut [f64]) {
        self.for_each_sub(normal, |g, j, w| {
            global[g] += w * self.inv_omega_local[j] * local[j]
        });
    }
}

/// `R_n = W_l S_n W_gᵀ` for the exact normal (no blending, no frames).
impl LocalRotation for SplatRotation {
    fn n_global(&self) -> usize {
        self.n_global
    }
    fn n_local(&self) -> usize {
        self.local.n
    }
    fn apply(&self, normal_env: &Vec3, global: &[f64], local: &mut [f64]) {
        let mut g = global.to_vec();
        haar::inverse(&mut g, self.n_global);
        self.resample(normal_env, &g, local);
        haar::forward(local, self.local.n);
    }
    fn apply_transpose_add(&self, normal_env: &Vec3, local: &[f64], global: &mut [f64]) {
        let mut l = local.to_vec();
        haar::inverse(&mut l, self.local.n);
        let mut acc = vec![0.0; self.n_global * self.n_global];
        self.resample_transpose_add(normal_env, &l, &mut acc);
        haar::forward(&mut acc, self.n_global);
        global.iter_mut().zip(&acc).for_each(|(o, a)| *o += a);
    }
    fn texel_transpose(&self, normal_env: &Vec3, local_texels: &mut [f64], global: &mut [f64]) {
        // W_lᵀ W_l = I: R_nᵀ W_l f = W_g S_nᵀ f.
        global.fill(0.0);
        self.resample_transpose_add(normal_env, local_texels, global);
        haar::forward(global, self.n_global);
    }
    fn light_texels(
        &self,
        normal_env: &Vec3,
        global_texels: &[f64],
        _global_haar: &[f64],
        local_texels: &mut [f64],
    ) {
        self.resample(normal_env, global_texels, local_texels);
    }
    fn light_texels_rgb(
        &self,
        normal_env: &Vec3,
        global_texels: [&[f64]; 3],
        _global_haar: [&[f64]; 3],
        local_texels: &mut [Vec<f64>; 3],
    ) {
        self.resample_rgb(normal_env, global_texels, local_texels);
    }
    fn light_texels_rgb_many(
        &self,
        normal_env: &Vec3,
        global_texels: &[[&[f64]; 3]],
        _global_haar: &[[&[f64]; 3]],
        local_texels: &mut [[Vec<f64>; 3]],
    ) {
        self.resample_rgb_many(normal_env, global_texels, local_texels);
    }
    fn as_splat(&self) -> Option<&SplatRotation> {
        Some(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn both_locates_give_the_same_texels() {
        // The AVX2 and scalar locates on every global texel's sub-texels for normals over
        // the whole sphere (the poles, the equator, near-horizon sub-texels), at two
        // resolution pairs and an odd sub-texel count (a scalar tail): exactly the same
        // texels, and sub-texels on or below the horizon both marked.
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("avx2") {
            for (ng, nl, s) in [(16, 16, 3), (32, 32, 4)] {
                let rot = SplatRotation::new(ng, nl, s);
                let count = rot.dirs.len();
                let (mut a, mut b) = (vec![0; count], vec![0; count]);
                for k in 0..300 {
                    let z = -1.0 + 2.0 * k as f64 / 299.0;
                    let phi = 2.399_963 * k as f64;
                    let r = (1.0 - z * z).max(0.0).sqrt();
                    let frame = local_frame(&Vec3::new(r * phi.cos(), r * phi.sin(), z));
                    // Texel by texel, as `for_each_sub` calls them (3 × 3: a tail of one).
                    for &(lo, hi) in &rot.ranges {
                        let (lo, hi) = (lo as usize, hi as usize);
                        rot.locate_scalar(&frame, lo, &mut a[lo..hi]);
                        // SAFETY: the CPU has AVX2 (checked above).
                        unsafe { rot.locate_avx2(&frame, lo, &mut b[lo..hi]) };
                    }
                    assert_eq!(a, b, "{ng}/{nl}, normal {k}");
                    let below = a.iter().filter(|&&j| j == BELOW).count();
                    assert!(
                        below > count / 4 && below < 3 * count / 4,
                        "{below} of {count}"
                    );
                }
            }
        }
    }
}
