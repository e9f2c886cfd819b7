//! Light transport per observation (paper Eq. 5–8), precomputed once per run.
//!
//! For observation `p` (vertex `x` seen from local direction `ω_o`) and basis BRDF `b`, the
//! radiance under a distant light `L̃` (one colour channel, global octahedral map, Haar
//! coefficients `L̃_m`) is linear in the light:
//!
//! `s_{p,b}(L̃) = ∫_Ω ρ_b(ω_o, ω) V_x(ω) (R_{n_x} L̃)(ω) dω = Σ_m g_{p,b,m} L̃_m`
//!
//! where `R_n` is the blended wavelet rotation (Eq. 6) into the vertex's local frame and the
//! local triple product (Eq. 5, with `T_x = Σ_l C_klm V_l`, Eq. 7) has been folded into the
//! global transport vector `g_{p,b} = R_nᵀ T_x ρ_b(ω_o)`. The model of an observation
//! (Eq. 8, 11) is then, per channel `c`,
//! `y_{p,c} = Σ_b β_{x,b,c} s_{p,b}(L̃_{I(p),c})`, with `β_{x,b,c} = Σ_k w_k(x) λ_{k,b,c}`.
//!
//! [`Transport`] stores the `g_{p,b}` sparsely (the kept Haar coefficients, largest first
//! after truncation), in compressed rows indexed by `p * n_basis + b`.
//!
//! Building it ([`build`]): per observation, in the vertex's local hemi-octahedral map
//! (`n_local²` texels, frame [`crate::sphere::local_frame`] of the env-frame normal), the
//! texel product `f_t = V_t · ρ_b(ω_o)_t · Δω_t` (visibility fraction, texel-averaged slice
//! [`crate::transport::brdf::BasisBrdf::slice`], exact texel solid angle) so that, with `L_t` the local
//! texel averages of the light, `s = Σ_t f_t L_t` is the midpoint-rule value of Eq. 1 (the
//! quadrature weights `Δω` live here and nowhere else). With the orthonormal Haar matrices
//! `W` ([`crate::sphere::haar`]) and `L_local = W_lᵀ R_n L̃` this is `s = (R_nᵀ W_l f)ᵀ L̃`, i.e.
//! `g_{p,b} = R_nᵀ W_l f` — the triple product of Eq. 5/7 evaluated in the texel domain,
//! where for piecewise-constant functions on one grid it is exact and costs `O(n_local²)`.
//! `g` is then truncated to its `keep` largest-magnitude coefficients, which minimises the
//! `ℓ²` norm of what is dropped and hence the worst-case response error `‖g_drop‖ ‖L̃‖`.
//! The Lambert row depends only on the vertex and is computed once per vertex; an
//! observation's view-dependent rows go through `R_nᵀ` together
//! ([`LocalRotation::texel_transpose_many`]: the rotation's rows are read once for all of
//! them, the sums are those of one row at a time).
//! Memory grows as observations × basis × `keep`: 4 bytes per kept entry (a `u16` Haar
//! index, which addresses every map up to 256², and an IEEE half-precision value,
//! [`TransportValue`]) plus an 8-byte offset per row. The rows are written by the workers straight into their slots of the final
//! arrays and compacted in place, so the build never holds them twice; truncation selects
//! the kept entries in a reused buffer (no allocation per row).
//!
//! Slices: a lobe is tabulated over a 32² grid of `ω_o` (bilinear lookup, ~2 µs) when its
//! scale `σ` spans at least 4 table spacings, else computed on demand (adaptive, 45–105 µs
//! at 32²). Measured (benches/transport.rs): the table's slice error is 0.6% (median
//! relative L2) for GGX 0.4 but 3% / 10% / 19% for GGX 0.2 / 0.1 / Phong 500, so of the
//! default lobes only Lambert (one slice) and GGX 0.4 use tables.
//!
//! Known limit: the blended rotation (Eq. 6) is only as good as the continuity of
//! [`crate::sphere::local_frame`] between neighbouring grid normals; that frame flips by
//! 180° about `n` across `n_z = 0` (environment frame), which breaks glossy rows of
//! vertices with near-horizontal normals (tests/suite/transport_blended.rs, ignored test).

pub mod brdf;
pub mod reference;
pub mod visibility;

use nalgebra::Matrix3;
use rayon::prelude::*;

use crate::observe::Observations;
use crate::sphere::envmap::OctEnv;
use crate::sphere::haar;
use crate::sphere::rotation::LocalRotation;
use crate::sphere::{local_frame, to_local};
use crate::transport::brdf::{BasisBrdf, SliceGrid, SliceTable};
use crate::transport::visibility::Visibility;
use crate::{Error, Result, Vec3};

/// A Haar coefficient index of the global map (`< n_global² ≤ 256² = 65,536`).
pub type HaarIndex = u16;

mod truncate;
mod value;
use truncate::{truncate_global, Selection};
pub use value::TransportValue;

/// Largest global map side whose Haar indices fit in [`HaarIndex`].
pub const MAX_GLOBAL_SIDE: usize = 256;

/// Sparse per-observation, per-basis transport vectors in the global Haar basis.
#[derive(Debug, Clone, Default)]
pub struct Transport {
    /// The global octahedral map is `n_global × n_global` texels; Haar index space
    /// `0..n_global²` (the layout of [`crate::sphere::haar`]).
    pub n_global: usize,
    /// Number of basis BRDFs `B`.
    pub n_basis: usize,
    /// Number of observations `P`.
    pub n_obs: usize,
    /// Row `r = p * n_basis + b` spans `index[offsets[r]..offsets[r + 1]]`.
    pub offsets: Vec<usize>,
    /// Haar coefficient indices of the kept entries (2 bytes: `n_global ≤ 256`, so every
    /// index is below 65,536; [`build_rows`] refuses larger maps).
    pub index: Vec<HaarIndex>,
    /// Values of the kept entries.
    pub value: Vec<TransportValue>,
}

impl Transport {
    /// The kept entries `(indices, values)` of `g_{p,b}`.
    pub fn row(&self, p: usize, b: usize) -> (&[HaarIndex], &[TransportValue]) {
        let r = p * self.n_basis + b;
        let (lo, hi) = (self.offsets[r], self.offsets[r + 1]);
        (&self.index[lo..hi], &self.value[lo..hi])
    }

    /// `s_{p,b}(L̃) = Σ_m g_{p,b,m} L̃_m` for one channel of a light given by its Haar
    /// coefficients (`light.len() == n_global²`).
    pub fn response(&self, p: usize, b: usize, light: &[f64]) -> f64 {
        let (idx, val) = self.row(p, b);
        idx.iter()
            .zip(val)
            .map(|(&m, &g)| f64::from(g) * light[m as usize])
            .sum()
    }

    /// A bound on how far [`Transport::response`] lies from the same sum over the unrounded
    /// values: each stored value is within `2⁻¹¹ |g|` of its `f64` original when normal and
    /// within `2⁻²⁵` when subnormal ([`TransportValue`]), so the sum is within
    /// `Σ_m (2⁻¹¹ |g_m| + 2⁻²⁵) |L̃_m|` (plus `f64` rounding, far smaller).
    pub fn rounding_bound(&self, p: usize, b: usize, light: &[f64]) -> f64 {
        let (idx, val) = self.row(p, b);
        idx.iter()
            .zip(val)
            .map(|(&m, &g)| {
                (f64::from(g).abs() * 2f64.powi(-11) + 2f64.powi(-25)) * light[m as usize].abs()
            })
            .sum()
    }

    /// Bytes held by the sparse rows.
    pub fn memory_bytes(&self) -> usize {
        self.offsets.len() * std::mem::size_of::<usize>()
            + self.index.len() * std::mem::size_of::<HaarIndex>()
            + self.value.len() * std::mem::size_of::<TransportValue>()
    }
}

/// Resolutions and truncation of the transport.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TransportOptions {
    /// Global octahedral map side (default 64).
    pub n_global: usize,
    /// Local hemi-octahedral map side (default 32).
    pub n_local: usize,
    /// Kept coefficients per row (largest magnitude); 0 keeps every non-zero one.
    pub keep: usize,
}

impl Default for TransportOptions {
    fn default() -> Self {
        TransportOptions {
            n_global: 64,
            n_local: 32,
            keep: 128,
        }
    }
}

/// How a basis BRDF's slices are produced for the transport: tabulated over `ω_o` and
/// interpolated when the lobe is broad compared with the table spacing, computed on demand
/// otherwise (see benches/transport.rs for the measurement behind the threshold).
enum SliceSource {
    /// View-independent (Lambert): one slice.
    Fixed(Vec<f64>),
    Table(SliceTable),
    OnDemand,
}

/// `ω_o` table side for tabulated slices.
const TABLE_SIDE: usize = 32;
/// Lobes with `σ` at least this many `ω_o` table spacings are tabulated.
const TABLE_MIN_SIGMA_SPACINGS: f64 = 4.0;

impl SliceSource {
    fn new(b: &BasisBrdf, grid: &SliceGrid) -> Result<Self> {
        if !b.view_dependent() {
            let mut s = vec![0.0; grid.centre.len()];
            b.slice_with(grid, &Vec3::z(), &mut s);
            return Ok(SliceSource::Fixed(s));
        }
        // Spacing of the ω_o table: π/2 over TABLE_SIDE/√2 texels along a diagonal, roughly.
        let spacing = std::f64::consts::PI / TABLE_SIDE as f64;
        if b.lobe_sigma() >= TABLE_MIN_SIGMA_SPACINGS * spacing {
            Ok(SliceSource::Table(SliceTable::new(b, grid, TABLE_SIDE)?))
        } else {
            Ok(SliceSource::OnDemand)
        }
    }

    fn slice(&self, b: &BasisBrdf, grid: &SliceGrid, wo: &Vec3, out: &mut [f64]) {
        match self {
            SliceSource::Fixed(s) => out.copy_from_slice(s),
            SliceSource::Table(t) => t.lookup(wo, out),
            SliceSource::OnDemand => b.slice_with(grid, wo, out),
        }
    }

    /// [`SliceSource::slice`] for a product with `weight` (`V ⊙ Δω`): on-demand slices skip
    /// the texels of zero weight ([`BasisBrdf::slice_masked`]; the product is unchanged).
    fn slice_for(
        &self,
        b: &BasisBrdf,
        grid: &SliceGrid,
        wo: &Vec3,
        weight: &[f64],
        out: &mut [f64],
    ) {
        match self {
            SliceSource::OnDemand => b.slice_masked(grid, wo, weight, out),
            _ => self.slice(b, grid, wo, out),
        }
    }
}

/// Outgoing direction in the local frame, kept strictly above the horizon.
pub(crate) fn local_wo(frame: &[Vec3; 3], wo_env: &Vec3) -> Option<Vec3> {
    let mut w = to_local(frame, wo_env);
    if !w.iter().all(|c| c.is_finite()) || w.norm() == 0.0 {
        return None;
    }
    w.z = w.z.max(1e-3 * w.norm());
    Some(w.normalize())
}

/// The unit normal and local frame of a vertex, with `V ⊙ Δω` written into `v_dw`
/// (reused buffer); `None` for a degenerate normal.
pub(crate) fn vertex_frame_into(
    normal_env: &Vec3,
    vis_row: &[u8],
    solid_angle: &[f64],
    v_dw: &mut Vec<f64>,
) -> Option<(Vec3, [Vec3; 3])> {
    let nn = normal_env.norm();
    if !(nn.is_finite() && nn > 0.0) {
        return None;
    }
    let normal = normal_env / nn;
    v_dw.clear();
    v_dw.extend(
        vis_row
            .iter()
            .zip(solid_angle)
            .map(|(&v, &w)| v as f64 / 255.0 * w),
    );
    Some((normal, local_frame(&normal)))
}

/// Scratch buffers for one thread (allocated once per worker, never per row).
struct Scratch {
    slice: Vec<f64>,
    local: Vec<f64>,
    global: Vec<f64>,
    v_dw: Vec<f64>,
    /// The selection buffers of [`truncate_into`].
    sel: Selection,
    /// The view-dependent bases' `V ⊙ Δω ⊙ slice` of one observation, basis-major.
    locals: Vec<f64>,
    /// Their dense global rows, basis-major.
    globals: Vec<f64>,
    /// The rotation's interleaving buffer ([`LocalRotation::texel_transpose_many`]).
    inter: Vec<f64>,
    /// Progress, passed on per chunk of observations.
    ticks: crate::stages::Ticker,
}

impl Scratch {
    fn new(n_local: usize, n_global: usize) -> Self {
        Scratch {
            slice: vec![0.0; n_local * n_local],
            local: vec![0.0; n_local * n_local],
            global: vec![0.0; n_global * n_global],
            v_dw: Vec::with_capacity(n_local * n_local),
            sel: Selection::default(),
            locals: Vec::new(),
            globals: Vec::new(),
            inter: Vec::new(),
            ticks: Default::default(),
        }
    }
}

/// `g = R_nᵀ W_l (V ⊙ Δω ⊙ slice)` into `scratch.global` (dense; `scratch.local` is
/// clobbered), for a vertex of unit normal `normal` whose `V ⊙ Δω` is in `scratch.v_dw`.
fn dense_row<R: LocalRotation>(normal: &Vec3, rot: &R, scratch: &mut Scratch) {
    for ((l, s), vw) in scratch
        .local
        .iter_mut()
        .zip(&scratch.slice)
        .zip(&scratch.v_dw)
    {
        *l = s * vw;
    }
    rot.texel_transpose(normal, &mut scratch.local, &mut scratch.global);
}

/// The `keep` largest-magnitude non-zero coefficients of `scratch.global` (all non-zero
/// ones for `keep == 0`) into `idx`/`val`, largest first, ties by index: the same entries
/// in the same order as [`haar::keep_largest`], without allocating (a selection over the
/// non-zero coefficients, then a sort of the kept part only). Returns how many were kept
/// (`≤ idx.len()`).
fn truncate_into(
    scratch: &mut Scratch,
    keep: usize,
    idx: &mut [HaarIndex],
    val: &mut [TransportValue],
) -> usize {
    truncate_global(&scratch.global, &mut scratch.sel, keep, idx, val)
}

fn check_inputs<R: LocalRotation>(
    n_vertices: usize,
    vis: &Visibility,
    basis: &[BasisBrdf],
    rot: &R,
    opts: &TransportOptions,
) -> Result<()> {
    if basis.is_empty() {
        return Err(Error::Internal("transport: no basis BRDFs".into()));
    }
    if opts.n_global > MAX_GLOBAL_SIDE {
        return Err(Error::Config(format!(
            "transport: a {}² global map has {} Haar coefficients, more than the 65,536 that \
             its 2-byte indices address (--global-resolution at most {MAX_GLOBAL_SIDE})",
            opts.n_global,
            opts.n_global * opts.n_global
        )));
    }
    if rot.n_global() != opts.n_global || rot.n_local() != opts.n_local {
        return Err(Error::Internal(format!(
            "transport: the rotation is {}→{} texels per side but the options ask for {}→{}",
            rot.n_global(),
            rot.n_local(),
            opts.n_global,
            opts.n_local
        )));
    }
    if vis.n_local != opts.n_local || vis.frac.len() != n_vertices * opts.n_local * opts.n_local {
        return Err(Error::Internal(format!(
            "transport: visibility holds {} vertices at {}² texels, expected {} vertices at {}²",
            vis.frac.len() / (vis.n_local * vis.n_local).max(1),
            vis.n_local,
            n_vertices,
            opts.n_local
        )));
    }
    Ok(())
}

/// Build the transport for observations given by their vertex and their outgoing
/// direction in the ENVIRONMENT frame (unit, vertex → camera). The kernel behind [`build`];
/// generic over the rotation so tests can use [`ExactRotation`](crate::sphere::rotation::ExactRotation).
pub fn build_rows<R: LocalRotation>(
    normals_env: &[Vec3],
    obs_vertex: &[u32],
    obs_dir_env: &[Vec3],
    vis: &Visibility,
    basis: &[BasisBrdf],
    rot: &R,
    opts: &TransportOptions,
) -> Result<Transport> {
    check_inputs(normals_env.len(), vis, basis, rot, opts)?;
    if obs_vertex.len() != obs_dir_env.len() {
        return Err(Error::Internal(format!(
            "transport: {} observation vertices but {} directions",
            obs_vertex.len(),
            obs_dir_env.len()
        )));
    }
    if let Some(p) = obs_vertex
        .iter()
        .position(|&v| v as usize >= normals_env.len())
    {
        return Err(Error::Numeric {
            stage: "transport".into(),
            message: format!(
                "observation {p} names vertex {} but the mesh has {}",
                obs_vertex[p],
                normals_env.len()
            ),
        });
    }
    let grid = SliceGrid::shared(opts.n_local)?;
    let sources: Vec<SliceSource> = basis
        .iter()
        .map(|b| SliceSource::new(b, &grid))
        .collect::<Result<_>>()?;
    let nb = basis.len();
    let n_obs = obs_vertex.len();
    let nv = normals_env.len();
    let ng2 = opts.n_global * opts.n_global;
    // Every row gets a slot of `stride` entries in the final arrays, filled in place by
    // the workers and compacted at the end: the rows are never held twice (the old
    // per-row vectors doubled the peak while they were concatenated).
    let stride = if opts.keep == 0 {
        ng2
    } else {
        opts.keep.min(ng2)
    };
    let fixed_bases: Vec<usize> = (0..nb)
        .filter(|&b| matches!(sources[b], SliceSource::Fixed(_)))
        .collect();
    let nf = fixed_bases.len();
    let view_bases: Vec<usize> = (0..nb).filter(|b| !fixed_bases.contains(b)).collect();

    // View-independent (Lambert) rows depend only on the vertex: once per observed vertex.
    let mut observed = vec![false; nv];
    for &v in obs_vertex {
        observed[v as usize] = true;
    }
    let mut fixed_idx: Vec<HaarIndex> = vec![0; if nf > 0 { nv * nf * stride } else { 0 }];
    let mut fixed_val = vec![TransportValue::ZERO; fixed_idx.len()];
    let mut fixed_len = vec![0usize; nv * nf];
    if nf > 0 {
        fixed_idx
            .par_chunks_mut(nf * stride)
            .zip(fixed_val.par_chunks_mut(nf * stride))
            .zip(fixed_len.par_chunks_mut(nf))
            .enumerate()
            .with_min_len(16)
            .for_each_init(
                || Scratch::new(opts.n_local, opts.n_global),
                |scratch, (v, ((fi, fv), fl))| {
                    if !observed[v] {
                        return;
                    }
                    let Some((normal, _)) = vertex_frame_into(
                        &normals_env[v],
                        vis.vertex(v),
                        &grid.solid_angle,
                        &mut scratch.v_dw,
                    ) else {
                        return;
                    };
                    for (j, &b) in fixed_bases.iter().enumerate() {
                        sources[b].slice(&basis[b], &grid, &Vec3::z(), &mut scratch.slice);
                        dense_row(&normal, rot, scratch);
                        let span = j * stride..(j + 1) * stride;
                        fl[j] =
                            truncate_into(scratch, opts.keep, &mut fi[span.clone()], &mut fv[span]);
                    }
                },
            );
    }

    // Every observation's rows, in observation order, straight into their slots.
    let total_slots = n_obs
        .checked_mul(nb)
        .and_then(|r| r.checked_mul(stride))
        .ok_or_else(|| Error::Internal("transport: row storage size overflows".into()))?;
    let mut index: Vec<HaarIndex> = vec![0; total_slots];
    let mut value = vec![TransportValue::ZERO; total_slots];
    let mut lens = vec![0usize; n_obs * nb];
    index
        .par_chunks_mut(nb * stride)
        .zip(value.par_chunks_mut(nb * stride))
        .zip(lens.par_chunks_mut(nb))
        .enumerate()
        .with_min_len(16)
        .for_each_init(
            || Scratch::new(opts.n_local, opts.n_global),
            |scratch, (p, ((oi, ov), ol))| {
                scratch.ticks.tick(1);
                let v = obs_vertex[p] as usize;
                let Some((normal, frame)) = vertex_frame_into(
                    &normals_env[v],
                    vis.vertex(v),
                    &grid.solid_angle,
                    &mut scratch.v_dw,
                ) else {
                    return;
                };
                for (j, &b) in fixed_bases.iter().enumerate() {
                    let span = b * stride..(b + 1) * stride;
                    let k = fixed_len[v * nf + j];
                    let from = (v * nf + j) * stride;
                    oi[span.start..span.start + k].copy_from_slice(&fixed_idx[from..from + k]);
                    ov[span.start..span.start + k].copy_from_slice(&fixed_val[from..from + k]);
                    ol[b] = k;
                }
                let Some(wo) = local_wo(&frame, &obs_dir_env[p]) else {
                    return;
                };
                // The view-dependent rows of the observation, rotated together (the
                // rotation's rows are read once for all of them).
                let nl2 = scratch.v_dw.len();
                scratch.locals.resize(view_bases.len() * nl2, 0.0);
                scratch.globals.resize(view_bases.len() * ng2, 0.0);
                for (&b, local) in view_bases.iter().zip(scratch.locals.chunks_mut(nl2)) {
                    sources[b].slice_for(&basis[b], &grid, &wo, &scratch.v_dw, local);
                    for (l, vw) in local.iter_mut().zip(&scratch.v_dw) {
                        *l *= vw;
                    }
                }
                rot.texel_transpose_many(
                    &normal,
                    &mut scratch.locals,
                    &mut scratch.globals,
                    &mut scratch.inter,
                );
                for (&b, global) in view_bases.iter().zip(scratch.globals.chunks(ng2)) {
                    let span = b * stride..(b + 1) * stride;
                    ol[b] = truncate_global(
                        global,
                        &mut scratch.sel,
                        opts.keep,
                        &mut oi[span.clone()],
                        &mut ov[span],
                    );
                }
            },
        );
    drop((fixed_idx, fixed_val, fixed_len));

    // Compact the slots in place (rows shorter than `stride` are rare at `keep ≪ n_global²`)
    // and give the unused tail back.
    let mut offsets = Vec::with_capacity(n_obs * nb + 1);
    offsets.push(0usize);
    let mut end = 0usize;
    for (r, &k) in lens.iter().enumerate() {
        let from = r * stride;
        if from != end {
            index.copy_within(from..from + k, end);
            value.copy_within(from..from + k, end);
        }
        end += k;
        offsets.push(end);
    }
    index.truncate(end);
    index.shrink_to_fit();
    value.truncate(end);
    value.shrink_to_fit();
    Ok(Transport {
        n_global: opts.n_global,
        n_basis: nb,
        n_obs,
        offsets,
        index,
        value,
    })
}

/// Build the transport of every observation (module docs): `normals_env` are the unit
/// vertex normals in the environment frame, `env_from_world` the matrix with rows
/// `e_x, e_y, e_z` (observation directions are world vectors).
pub fn build<R: LocalRotation>(
    normals_env: &[Vec3],
    obs: &Observations,
    env_from_world: &Matrix3<f64>,
    vis: &Visibility,
    basis: &[BasisBrdf],
    rot: &R,
    opts: &TransportOptions,
) -> Result<Transport> {
    let dirs: Vec<Vec3> = obs
        .dir
        .iter()
        .map(|d| env_from_world * Vec3::new(d[0] as f64, d[1] as f64, d[2] as f64))
        .collect();
    build_rows(normals_env, &obs.vertex, &dirs, vis, basis, rot, opts)
}

/// The Haar coefficients of each channel of an octahedral environment map (the `L̃` that
/// [`Transport::response`] and [`WaveletRenderer::vertex_radiance`] take).
pub fn light_haar(env: &OctEnv) -> [Vec<f64>; 3] {
    [0, 1, 2].map(|c| {
        let mut ch = env.channel(c);
        haar::forward(&mut ch, env.n);
        ch
    })
}
