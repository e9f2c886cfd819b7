//! Slices of the basis BRDFs (paper Sec. 5.2): `ρ_b(·, ω_o)` for a fixed outgoing
//! direction, tabulated as texel AVERAGES over the hemi-octahedral texels of the local
//! hemisphere ([`super::BasisBrdf::slice`]): a texel holds `∫_texel ρ dω / Δω_texel`,
//! computed by solid-angle-weighted supersampling that refines adaptively where the lobe
//! is sharp, so a lobe narrower than a texel still integrates to its albedo. The
//! quadrature weights `Δω` are not in the slice (they live in the transport,
//! docs/conventions.md).
//!
//! - [`SliceGrid`]: the grid's texel centres, solid angles and radii, and the sub-texels
//!   of each refinement level, shared per grid side; with, per lobe, its refinement rule
//!   (`LobeTexels`) and GGX's per-sample `G1` denominators, built on first use.
//! - The slice itself ([`super::BasisBrdf::slice_with`]): a level per texel, then the
//!   samples of each run of texels at one level evaluated together (`LobeAt::eval_many`)
//!   and averaged.
//! - [`SliceTable`]: slices tabulated over `ω_o` and interpolated, for broad lobes.

use super::many::Samples;
use super::{BasisBrdf, LobeAt};
use crate::sphere::SphereGrid;
use crate::{Error, Result, Vec3};
use std::collections::HashMap;
use std::f64::consts::PI;
use std::sync::{Arc, Mutex, OnceLock};

/// Precomputed sample points of the hemi-octahedral grid used by [`BasisBrdf::slice`]:
/// texel centres, exact solid angles, angular radii, and `s × s` sub-texels (centre
/// direction, exact solid angle) for the refinement levels `s = 2, 4, 8, 16`.
#[derive(Debug)]
pub struct SliceGrid {
    /// The hemi-octahedral grid (`n_local × n_local`).
    pub grid: SphereGrid,
    /// Centre direction of each texel.
    pub centre: Vec<Vec3>,
    /// `‖centre‖` of each texel (the centres are unit vectors up to rounding; the peak test
    /// divides by the norm as computed, without a square root per texel and slice).
    centre_norm: Vec<f64>,
    /// The centres' components, one array each (the level rule reads them in step).
    centre_x: Vec<f64>,
    centre_y: Vec<f64>,
    centre_z: Vec<f64>,
    /// Exact solid angle `Δω` of each texel.
    pub solid_angle: Vec<f64>,
    /// Largest angle between a texel's centre and its corners (radians).
    pub radius: Vec<f64>,
    /// `levels[k]`: sub-texels at `s = 2^(k+1)`, texel-major (`s²` per texel).
    levels: Vec<Samples>,
    /// `level_solid_angle[k][t]`: the sum of texel `t`'s sub-texel solid angles at `levels[k]`
    /// (summed in sample order, as the quadrature's denominator).
    level_solid_angle: Vec<Vec<f64>>,
    /// The refinement rules of the lobes sliced so far ([`SliceGrid::lobe_texels`]).
    rules: Mutex<Vec<(BasisBrdf, Arc<LobeTexels>)>>,
}

/// Finest refinement level: `s = 2^MAX_LEVEL` sub-texels per side.
pub(super) const MAX_LEVEL: usize = 4;

/// Lobe values below this fraction of the peak are written as exact zeros
/// ([`BasisBrdf::negligible_angle`]).
pub(super) const NEGLIGIBLE: f64 = 1e-18;

impl SliceGrid {
    /// Build the sample tables for an `n × n` hemi-octahedral grid (`n` a power of two ≥ 2).
    pub fn new(n: usize) -> Result<Self> {
        if n < 2 || !n.is_power_of_two() {
            return Err(Error::Internal(format!(
                "local map size {n} is not a power of two >= 2"
            )));
        }
        let grid = SphereGrid::hemi(n);
        let centre: Vec<Vec3> = (0..grid.len()).map(|t| grid.texel_dir(t)).collect();
        let centre_norm = centre.iter().map(|c| c.norm()).collect();
        let solid_angle = grid.solid_angles();
        let nf = n as f64;
        let radius: Vec<f64> = (0..grid.len())
            .map(|t| {
                let (i, j) = ((t % n) as f64, (t / n) as f64);
                [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)]
                    .iter()
                    .map(|(a, b)| {
                        let c = grid.decode([(i + a) / nf, (j + b) / nf]);
                        c.angle(&centre[t])
                    })
                    .fold(0.0, f64::max)
            })
            .collect();
        let mut levels = Vec::new();
        let mut level_solid_angle = Vec::new();
        for k in 1..=MAX_LEVEL {
            let s = 1usize << k;
            let mut samples = Samples::default();
            let mut sums = Vec::with_capacity(grid.len());
            for t in 0..grid.len() {
                let mut den = 0.0;
                for (d, w) in grid.sample_points(t, s) {
                    samples.push(d, w);
                    den += w;
                }
                sums.push(den);
            }
            levels.push(samples);
            level_solid_angle.push(sums);
        }
        Ok(SliceGrid {
            grid,
            centre_x: centre.iter().map(|c| c.x).collect(),
            centre_y: centre.iter().map(|c| c.y).collect(),
            centre_z: centre.iter().map(|c| c.z).collect(),
            centre,
            centre_norm,
            solid_angle,
            radius,
            levels,
            level_solid_angle,
            rules: Mutex::new(Vec::new()),
        })
    }

    /// Lobe `b`'s refinement rule over this grid, built on the first call for `b`.
    fn lobe_texels(&self, b: &BasisBrdf) -> Arc<LobeTexels> {
        // A poisoned lock only means another thread panicked while pushing: the list is
        // still a list of complete entries.
        let mut rules = self.rules.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((_, r)) = rules.iter().find(|(k, _)| k == b) {
            return r.clone();
        }
        let r = Arc::new(LobeTexels::new(b, self));
        rules.push((*b, r.clone()));
        r
    }

    /// Grid side `n`.
    pub fn n(&self) -> usize {
        self.grid.n
    }

    /// The shared sample tables for side `n` (built once per process and size).
    pub fn shared(n: usize) -> Result<Arc<SliceGrid>> {
        static CACHE: OnceLock<Mutex<HashMap<usize, Arc<SliceGrid>>>> = OnceLock::new();
        let cache = CACHE.get_or_init(|| Mutex::new(HashMap::new()));
        if let Some(g) = cache.lock().map_err(poisoned)?.get(&n) {
            return Ok(g.clone());
        }
        let g = Arc::new(SliceGrid::new(n)?);
        cache.lock().map_err(poisoned)?.insert(n, g.clone());
        Ok(g)
    }

    /// Sub-texels of texel `t` at level `s = 2^level` (`1 ≤ level ≤ 4`).
    #[cfg(test)]
    pub(super) fn subsamples(&self, t: usize, level: usize) -> Vec<(Vec3, f64)> {
        let s2 = 1usize << (2 * level);
        (t * s2..(t + 1) * s2)
            .map(|i| self.levels[level - 1].get(i))
            .collect()
    }
}

fn poisoned<T>(_: T) -> Error {
    Error::Numeric {
        stage: "brdf slice tables".into(),
        message: "a thread panicked while building the tables".into(),
    }
}

impl BasisBrdf {
    /// Angular scale (radians) of the lobe's peak: `1/√N` for Phong (`cos^N θ ≈
    /// e^{−Nθ²/2}`), `α` for GGX (the half-vector spread; the reflected spread is about
    /// twice that), `∞` for Lambert.
    pub fn lobe_sigma(&self) -> f64 {
        match *self {
            BasisBrdf::Lambert => f64::INFINITY,
            BasisBrdf::Phong { exponent } => 1.0 / exponent.sqrt(),
            BasisBrdf::Ggx { alpha } => alpha,
        }
    }

    /// The angle from the mirror direction beyond which the lobe is below `10⁻¹⁸` of its
    /// peak: Phong's `cos^N θ = 10⁻¹⁸`, i.e. `θ_z = acos(10^(−18/N))` (0.40 rad at
    /// `N = 500`, 1.12 at 50). `None` for Lambert and GGX, whose tails are not negligible.
    pub fn negligible_angle(&self) -> Option<f64> {
        match *self {
            BasisBrdf::Phong { exponent } if exponent > 0.0 => {
                Some((NEGLIGIBLE.ln() / exponent).exp().acos())
            }
            _ => None,
        }
    }

    /// Refinement level (`s = 2^level` sub-texels per side, 0 = the centre sample) for
    /// texels near the lobe's peak: sub-texels no wider than about half the lobe's scale.
    fn peak_level(&self, texel_radius: f64) -> usize {
        let sigma = self.lobe_sigma();
        let need = 4.0 * texel_radius / sigma;
        let mut level = 1;
        while level < MAX_LEVEL && ((1usize << level) as f64) < need {
            level += 1;
        }
        level
    }

    /// The slice `ρ(·, ω_o)` as texel averages over the `n_local × n_local` hemi-octahedral
    /// grid of the local frame: `out[t] = ∫_texel ρ(ω, ω_o) dω / Δω_t`. `wo` is a unit
    /// vector in the local frame. Uses the shared tables of [`SliceGrid::shared`].
    ///
    /// Panics if `n_local` is not a power of two ≥ 2 or `out.len() != n_local²`
    /// (programming errors; resolutions are checked where the user gives them).
    pub fn slice(&self, wo: &Vec3, n_local: usize, out: &mut [f64]) {
        let grid = SliceGrid::shared(n_local).expect("slice: invalid local map size");
        self.slice_with(&grid, wo, out);
    }

    /// [`BasisBrdf::slice`] with explicit sample tables.
    ///
    /// Quadrature: each texel is integrated by the midpoint rule over sub-texels with exact
    /// solid angles. Texels within `5σ` (plus their own radius) of the lobe's peak
    /// ([`BasisBrdf::lobe_sigma`]) use `s × s` sub-texels no wider than about `σ/2`; the
    /// rest use `2 × 2` (Lambert: `4 × 4` everywhere; it does not depend on `ω_o`).
    ///
    /// A Phong texel that lies wholly beyond [`BasisBrdf::negligible_angle`] of the mirror
    /// direction is written as 0 without sampling: there `ρ ≤ (N+2)/(2π) ·
    /// cos^N θ < 10⁻¹⁸ (N+2)/(2π)`, eighteen orders below the lobe's peak and far below
    /// the `f32` rounding of the transport rows it feeds.
    pub fn slice_with(&self, grid: &SliceGrid, wo: &Vec3, out: &mut [f64]) {
        self.slice_sampled(grid, wo, out, true, None);
    }

    /// [`BasisBrdf::slice_with`] for a consumer that multiplies the slice by `weight`
    /// (the transport's `V ⊙ Δω`): texels with `weight[t] == 0` (occluded) are written as 0
    /// without sampling, every other texel as [`BasisBrdf::slice_with`] writes it, bit for
    /// bit (a texel's average sums its own sub-texels only). The product `weight ⊙ slice`
    /// is therefore the same as with the full slice: `0 · ρ = 0` for the finite `ρ ≥ 0`.
    pub fn slice_masked(&self, grid: &SliceGrid, wo: &Vec3, weight: &[f64], out: &mut [f64]) {
        assert_eq!(weight.len(), out.len(), "slice: weight length");
        self.slice_sampled(grid, wo, out, true, Some(weight));
    }

    /// [`BasisBrdf::slice_with`], with the negligible texels skipped or sampled and the
    /// texels of zero `weight` skipped when one is given.
    pub(super) fn slice_sampled(
        &self,
        grid: &SliceGrid,
        wo: &Vec3,
        out: &mut [f64],
        skip_negligible: bool,
        weight: Option<&[f64]>,
    ) {
        assert_eq!(out.len(), grid.centre.len(), "slice: output length");
        let rule = grid.lobe_texels(self);
        let p = self.peak(wo).normalize();
        let n = out.len();
        let mut levels = vec![0u8; n];
        texel_levels(grid, &rule, &p, skip_negligible, &mut levels);
        if let Some(w) = weight {
            for (level, &w) in levels.iter_mut().zip(&w[..n]) {
                if w == 0.0 {
                    *level = 0;
                }
            }
        }
        integrate_texels(&self.at(wo), grid, &rule, &levels, out);
    }
}

/// Each texel's refinement level under `rule` for the peak direction `p` (0: written as
/// zero without sampling; `skip_negligible` allows it), compiled for AVX2 too when the CPU
/// has it (the same operations lane by lane: the same levels).
fn texel_levels(
    grid: &SliceGrid,
    rule: &LobeTexels,
    p: &Vec3,
    skip_negligible: bool,
    levels: &mut [u8],
) {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports the feature the function is compiled for.
        return unsafe { texel_levels_avx2(grid, rule, p, skip_negligible, levels) };
    }
    texel_levels_impl(grid, rule, p, skip_negligible, levels)
}

/// [`texel_levels`] compiled for AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn texel_levels_avx2(
    grid: &SliceGrid,
    rule: &LobeTexels,
    p: &Vec3,
    skip_negligible: bool,
    levels: &mut [u8],
) {
    texel_levels_impl(grid, rule, p, skip_negligible, levels)
}

/// The loops behind [`texel_levels`], in blocks of [`LEVEL_BLOCK`] texels: first every
/// texel's cosine to the peak (the division several texels at a time), then its level,
/// branch-free.
#[inline(always)]
fn texel_levels_impl(
    grid: &SliceGrid,
    rule: &LobeTexels,
    p: &Vec3,
    skip_negligible: bool,
    levels: &mut [u8],
) {
    let n = levels.len();
    let mut cos_peak = [0.0f64; LEVEL_BLOCK];
    for start in (0..n).step_by(LEVEL_BLOCK) {
        let end = (start + LEVEL_BLOCK).min(n);
        let (cx, cy, cz) = (
            &grid.centre_x[start..end],
            &grid.centre_y[start..end],
            &grid.centre_z[start..end],
        );
        let norm = &grid.centre_norm[start..end];
        let cos_peak = &mut cos_peak[..end - start];
        for (k, c) in cos_peak.iter_mut().enumerate() {
            // nalgebra's `dot` of the centre and p̂ (in its order), over the norm.
            *c = (cx[k] * p.x + cy[k] * p.y + cz[k] * p.z) / norm[k];
        }
        let (zero_cos, near_cos) = (&rule.zero_cos[start..end], &rule.near_cos[start..end]);
        let always_near = &rule.always_near[start..end];
        let near_level = &rule.near_level[start..end];
        for (k, level) in levels[start..end].iter_mut().enumerate() {
            let zero = skip_negligible & (cos_peak[k] < zero_cos[k]);
            let near = always_near[k] | (cos_peak[k] > near_cos[k]);
            let l = if near { near_level[k] } else { 1 };
            *level = if zero { 0 } else { l };
        }
    }
}

/// Texels per block of [`texel_levels`] (their cosines on the stack).
const LEVEL_BLOCK: usize = 64;

/// A lobe's refinement rule over a grid's texels ([`BasisBrdf::slice_with`]), the parts
/// that do not depend on `ω_o`, computed once per lobe and grid
/// ([`SliceGrid::lobe_texels`]). With `c` the cosine between a texel's centre and the
/// peak, texel `t` is at `near_level[t]` when `always_near[t]` or `c > near_cos[t]`,
/// written as zero when `c < zero_cos[t]`, and at level 1 otherwise.
#[derive(Debug)]
struct LobeTexels {
    /// `peak_level(r_t)` (Lambert: 2 everywhere).
    near_level: Vec<u8>,
    /// `5σ + r_t ≥ π` (Lambert: everywhere): the texel is near whatever the peak.
    always_near: Vec<bool>,
    /// `cos(5σ + r_t) = cos 5σ cos r_t − sin 5σ sin r_t`: angle(c, peak) < 5σ + r_t ⇔
    /// `c > near_cos[t]`.
    near_cos: Vec<f64>,
    /// The same at the negligible angle `θ_z` (the texel wholly beyond it), `−∞` when the
    /// lobe has none or `θ_z + r_t ≥ π`.
    zero_cos: Vec<f64>,
    /// GGX: `α²` and, per refinement level, the `G1(ω_i)` denominator of every sample
    /// ([`Samples::ggx_denominators`]), built on the level's first use.
    ggx: Option<(f64, [OnceLock<Vec<f64>>; MAX_LEVEL])>,
}

impl LobeTexels {
    fn new(b: &BasisBrdf, grid: &SliceGrid) -> Self {
        let n = grid.centre.len();
        if let BasisBrdf::Lambert = b {
            return LobeTexels {
                near_level: vec![2; n],
                always_near: vec![true; n],
                near_cos: vec![f64::NEG_INFINITY; n],
                zero_cos: vec![f64::NEG_INFINITY; n],
                ggx: None,
            };
        }
        let sigma = b.lobe_sigma();
        let (c5, s5) = ((5.0 * sigma).cos(), (5.0 * sigma).sin());
        let zero_at = b.negligible_angle();
        let (cz, sz) = zero_at.map_or((0.0, 0.0), |z| (z.cos(), z.sin()));
        let texel = |t: usize| {
            let r = grid.radius[t];
            let (cr, sr) = (r.cos(), r.sin());
            let zero = match zero_at {
                Some(z) if z + r < PI => cz * cr - sz * sr,
                _ => f64::NEG_INFINITY,
            };
            (
                b.peak_level(r) as u8,
                5.0 * sigma + r >= PI,
                c5 * cr - s5 * sr,
                zero,
            )
        };
        let all: Vec<_> = (0..n).map(texel).collect();
        LobeTexels {
            near_level: all.iter().map(|a| a.0).collect(),
            always_near: all.iter().map(|a| a.1).collect(),
            near_cos: all.iter().map(|a| a.2).collect(),
            zero_cos: all.iter().map(|a| a.3).collect(),
            // α² as `BasisBrdf::at` computes it, so the denominators are its bits.
            ggx: match *b {
                BasisBrdf::Ggx { alpha } => Some((alpha * alpha, Default::default())),
                _ => None,
            },
        }
    }

    /// GGX's `G1(ω_i)` denominators of `samples`, the sub-texels of `level` (1-based);
    /// empty for other lobes.
    fn ggx_denominators(&self, level: usize, samples: &Samples) -> &[f64] {
        match &self.ggx {
            Some((a2, by_level)) => {
                by_level[level - 1].get_or_init(|| samples.ggx_denominators(*a2))
            }
            None => &[],
        }
    }
}

/// Samples per batch of [`integrate_texels`] (a stack buffer).
const TEXEL_BATCH: usize = 256;

/// `out[t] = Σ ρ(d) w / Σ w` over texel `t`'s sub-texels at `levels[t]` (0 for level 0):
/// runs of consecutive texels at one level are contiguous in the level's sample arrays, so
/// they are evaluated together (`LobeAt::eval_many`), then summed texel by texel in
/// sample order.
fn integrate_texels(
    lobe: &LobeAt,
    grid: &SliceGrid,
    rule: &LobeTexels,
    levels: &[u8],
    out: &mut [f64],
) {
    let mut vals = [0.0f64; TEXEL_BATCH];
    // A batch's texels' weighted sums (at least 4 samples a texel).
    let mut nums = [0.0f64; TEXEL_BATCH / 4];
    let mut t = 0;
    while t < out.len() {
        let level = levels[t] as usize;
        if level == 0 {
            out[t] = 0.0;
            t += 1;
            continue;
        }
        let s2 = 1usize << (2 * level);
        let per_batch = (TEXEL_BATCH / s2).max(1);
        let mut end = t + 1;
        while end < out.len() && end - t < per_batch && levels[end] as usize == level {
            end += 1;
        }
        let samples = &grid.levels[level - 1];
        let dens = &grid.level_solid_angle[level - 1];
        let g = rule.ggx_denominators(level, samples);
        for chunk in (t * s2..end * s2).step_by(TEXEL_BATCH) {
            let hi = (chunk + TEXEL_BATCH).min(end * s2);
            lobe.eval_many(samples, g, chunk..hi, &mut vals);
            // The batch's texels are contiguous: their weighted sums, then their divisions
            // in one loop (so that the divisions overlap instead of each ending a texel).
            let (t0, texels) = (chunk / s2, (hi - chunk) / s2);
            let ws = &samples.w[chunk..hi];
            for ((num, tex_vals), tex_ws) in nums
                .iter_mut()
                .zip(vals[..hi - chunk].chunks_exact(s2))
                .zip(ws.chunks_exact(s2))
            {
                let mut sum = 0.0;
                for (v, w) in tex_vals.iter().zip(tex_ws) {
                    sum += v * w;
                }
                *num = sum;
            }
            for ((o, &num), &den) in out[t0..t0 + texels]
                .iter_mut()
                .zip(&nums)
                .zip(&dens[t0..t0 + texels])
            {
                *o = if den > 0.0 { num / den } else { 0.0 };
            }
        }
        t = end;
    }
}

/// Slices tabulated over outgoing directions: one slice per texel centre of an
/// `n_out × n_out` hemi-octahedral grid of `ω_o`, interpolated bilinearly
/// ([`SphereGrid::bilinear`]). Cheaper than [`BasisBrdf::slice_with`] per lookup, but a lobe
/// sharper than the `ω_o` spacing is smeared into ghost copies: measure before using it for
/// sharp lobes (benches/transport.rs).
#[derive(Debug, Clone)]
pub struct SliceTable {
    /// The `ω_o` grid.
    pub out_grid: SphereGrid,
    /// Texels per slice, `n_local²`.
    pub len: usize,
    /// Slices, `ω_o`-texel-major, `f32`.
    pub data: Vec<f32>,
}

impl SliceTable {
    /// Tabulate `brdf` over an `n_out × n_out` grid of outgoing directions.
    pub fn new(brdf: &BasisBrdf, grid: &SliceGrid, n_out: usize) -> Result<Self> {
        if n_out < 2 || !n_out.is_power_of_two() {
            return Err(Error::Internal(format!(
                "slice table size {n_out} is not a power of two >= 2"
            )));
        }
        let out_grid = SphereGrid::hemi(n_out);
        let len = grid.centre.len();
        let mut data = vec![0.0f32; out_grid.len() * len];
        let mut buf = vec![0.0; len];
        for (k, chunk) in data.chunks_mut(len).enumerate() {
            let mut wo = out_grid.texel_dir(k);
            // Keep ω_o strictly above the horizon.
            wo.z = wo.z.max(1e-4);
            brdf.slice_with(grid, &wo.normalize(), &mut buf);
            for (c, &b) in chunk.iter_mut().zip(&buf) {
                *c = b as f32;
            }
        }
        Ok(SliceTable {
            out_grid,
            len,
            data,
        })
    }

    /// Interpolated slice for `wo` (local frame) into `out` (`len` values).
    pub fn lookup(&self, wo: &Vec3, out: &mut [f64]) {
        out.iter_mut().for_each(|o| *o = 0.0);
        for (k, w) in self.out_grid.bilinear(wo) {
            if w == 0.0 {
                continue;
            }
            let s = &self.data[k * self.len..(k + 1) * self.len];
            for (o, &v) in out.iter_mut().zip(s) {
                *o += w * v as f64;
            }
        }
    }

    /// Bytes held.
    pub fn memory_bytes(&self) -> usize {
        self.data.len() * std::mem::size_of::<f32>()
    }
}
