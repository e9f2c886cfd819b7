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
//! The build goes a vertex at a time (the observations grouped by vertex): the Lambert
//! row depends only on the vertex and is computed and truncated once, and the vertex's
//! rows (its Lambert row and every observation's view-dependent rows) go through `R_nᵀ`
//! in one call ([`LocalRotation::texel_transpose_many`]: the blended rotation reads its
//! four frames' rows once per group of 8 vectors; each row's sums are those of the row
//! alone, so a row does not depend on which other observations are built with it). The
//! kernel that builds a vertex's rows is in `rows.rs`; this module runs it over the vertices
//! and owns the arrays.
//! Measured at 100K vertices × 13 photos (`bench-results/transport-by-vertex.md`): the
//! transport stage −4% to −10% (118.4 → 106.2 and 120.6 → 116.1 CPU s), every row bit for
//! bit the same.
//! Memory grows as observations × basis × `keep`: 4 bytes per kept entry (a `u16` Haar
//! index, which addresses every map up to 256², and an IEEE half-precision value,
//! [`TransportValue`]) plus an 8-byte offset per row. The rows are written by the workers straight into their slots of the final
//! arrays and compacted in place, so the build never holds them twice; truncation selects
//! the kept entries in a reused buffer (no allocation per row).
//!
//! Known limit: the blended rotation (Eq. 6) is only as good as the continuity of
//! [`crate::sphere::local_frame`] between neighbouring grid normals; that frame is
//! continuous except for normals pointing straight down in the environment frame
//! (tests/suite/transport_blended.rs checks glossy rows on both sides of `n_z = 0`). The
//! renderer's splat of the exact normal has no such limit, but as the transport's rotation
//! it raised the held-out error (`bench-results/transport-by-vertex.md`).

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
use crate::transport::brdf::{BasisBrdf, SliceGrid};
use crate::transport::visibility::Visibility;
use crate::{Error, Result, Vec3};

/// A Haar coefficient index of the global map (`< n_global² ≤ 256² = 65,536`).
pub type HaarIndex = u16;

mod rows;
mod truncate;
mod value;
use rows::{RowKernel, Scratch, SeenObs};
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

/// The final arrays of the rows before compaction: every observation and basis a slot of
/// `stride` entries ([`RowSlots`]) and its used length. The rows are never held twice
/// (per-row vectors concatenated at the end would double the peak).
struct RowStorage {
    index: Vec<HaarIndex>,
    value: Vec<TransportValue>,
    lens: Vec<usize>,
}

impl RowStorage {
    fn new(n_obs: usize, n_basis: usize, stride: usize) -> Result<Self> {
        let total_slots = n_obs
            .checked_mul(n_basis)
            .and_then(|r| r.checked_mul(stride))
            .ok_or_else(|| Error::Internal("transport: row storage size overflows".into()))?;
        Ok(RowStorage {
            index: vec![0; total_slots],
            value: vec![TransportValue::ZERO; total_slots],
            lens: vec![0usize; n_obs * n_basis],
        })
    }
}

/// What one vertex's rows read: its normal, visibility and observations, and the kernel.
struct VertexRows<'a, R> {
    normals_env: &'a [Vec3],
    obs_dir_env: &'a [Vec3],
    vis: &'a Visibility,
    solid_angle: &'a [f64],
    kernel: &'a RowKernel<'a, R>,
    groups: VertexGroups,
}

impl<R: LocalRotation> VertexRows<'_, R> {
    /// Vertex `v`'s observations' rows into their slots (none without an observation or a
    /// local frame).
    fn write(&self, v: usize, scratch: &mut Scratch, slots: &RowSlots) {
        let group = self.groups.of(v);
        if group.is_empty() {
            return;
        }
        scratch.ticks.tick(group.len() as u64);
        let Some((normal, frame)) = vertex_frame_into(
            &self.normals_env[v],
            self.vis.vertex(v),
            self.solid_angle,
            &mut scratch.v_dw,
        ) else {
            return;
        };
        scratch.seen.clear();
        scratch.seen.extend(
            group.iter().map(|&p| {
                SeenObs::new(p as usize, local_wo(&frame, &self.obs_dir_env[p as usize]))
            }),
        );
        self.kernel.vertex_rows(&normal, scratch);
        for k in 0..scratch.seen.len() {
            let p = scratch.seen[k].p;
            // SAFETY: observation `p` belongs to vertex `v` alone (`groups`), and only this
            // call writes the slots of `v`'s observations.
            let (oi, ov, ol) = unsafe { slots.row(p) };
            self.kernel.write_rows(scratch, k, oi, ov, ol);
        }
    }
}

/// The observations of each vertex (a counting sort of the observations by vertex).
struct VertexGroups {
    start: Vec<usize>,
    obs: Vec<u32>,
}

impl VertexGroups {
    fn new(obs_vertex: &[u32], n_vertices: usize) -> Self {
        let mut start = vec![0usize; n_vertices + 1];
        for &v in obs_vertex {
            start[v as usize + 1] += 1;
        }
        for v in 0..n_vertices {
            start[v + 1] += start[v];
        }
        let mut next = start.clone();
        let mut obs = vec![0u32; obs_vertex.len()];
        for (p, &v) in obs_vertex.iter().enumerate() {
            obs[next[v as usize]] = p as u32;
            next[v as usize] += 1;
        }
        VertexGroups { start, obs }
    }

    /// The observations of vertex `v`, in observation order.
    fn of(&self, v: usize) -> &[u32] {
        &self.obs[self.start[v]..self.start[v + 1]]
    }
}

/// The row slots of the final arrays, written by the workers in place: observation `p`
/// owns `stride` entries per basis from `p · n_basis · stride` and `n_basis` lengths.
struct RowSlots<'a> {
    index: *mut HaarIndex,
    value: *mut TransportValue,
    lens: *mut usize,
    n_basis: usize,
    stride: usize,
    /// The arrays stay mutably borrowed while the slots live.
    _arrays: std::marker::PhantomData<&'a mut [usize]>,
}

// SAFETY: the workers write disjoint observations' slots ([`RowSlots::row`]'s contract),
// and the borrow `'a` keeps the arrays alive and otherwise untouched meanwhile.
unsafe impl Sync for RowSlots<'_> {}
unsafe impl Send for RowSlots<'_> {}

impl<'a> RowSlots<'a> {
    fn new(
        index: &'a mut [HaarIndex],
        value: &'a mut [TransportValue],
        lens: &'a mut [usize],
        n_basis: usize,
        stride: usize,
    ) -> Self {
        assert!(index.len() == value.len() && index.len() == lens.len() * stride);
        RowSlots {
            index: index.as_mut_ptr(),
            value: value.as_mut_ptr(),
            lens: lens.as_mut_ptr(),
            n_basis,
            stride,
            _arrays: std::marker::PhantomData,
        }
    }

    /// Observation `p`'s slots.
    ///
    /// # Safety
    /// `p` is in range, and no two live borrows name the same `p`.
    #[allow(clippy::mut_from_ref)]
    unsafe fn row(&self, p: usize) -> (&mut [HaarIndex], &mut [TransportValue], &mut [usize]) {
        let (nb, stride) = (self.n_basis, self.stride);
        unsafe {
            (
                std::slice::from_raw_parts_mut(self.index.add(p * nb * stride), nb * stride),
                std::slice::from_raw_parts_mut(self.value.add(p * nb * stride), nb * stride),
                std::slice::from_raw_parts_mut(self.lens.add(p * nb), nb),
            )
        }
    }
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

/// Every observation has a direction and names a vertex of the mesh (`n_vertices`).
fn check_observations(obs_vertex: &[u32], obs_dir_env: &[Vec3], n_vertices: usize) -> Result<()> {
    if obs_vertex.len() != obs_dir_env.len() {
        return Err(Error::Internal(format!(
            "transport: {} observation vertices but {} directions",
            obs_vertex.len(),
            obs_dir_env.len()
        )));
    }
    if let Some(p) = obs_vertex.iter().position(|&v| v as usize >= n_vertices) {
        return Err(Error::Numeric {
            stage: "transport".into(),
            message: format!(
                "observation {p} names vertex {} but the mesh has {n_vertices}",
                obs_vertex[p]
            ),
        });
    }
    Ok(())
}

/// Row `r`'s `lens[r]` entries moved from its slot at `r · stride` to follow the previous
/// row's, in place (rows shorter than `stride` are rare at `keep ≪ n_global²`), the unused
/// tail given back; the rows' offsets (`lens.len() + 1`, CSR).
fn compact_rows(
    index: &mut Vec<HaarIndex>,
    value: &mut Vec<TransportValue>,
    lens: &[usize],
    stride: usize,
) -> Vec<usize> {
    let mut offsets = Vec::with_capacity(lens.len() + 1);
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
    offsets
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
    check_observations(obs_vertex, obs_dir_env, normals_env.len())?;
    let grid = SliceGrid::shared(opts.n_local)?;
    let nb = basis.len();
    let n_obs = obs_vertex.len();
    let nv = normals_env.len();
    let ng2 = opts.n_global * opts.n_global;
    // Every row gets a slot of `stride` entries in the final arrays ([`RowStorage`]),
    // filled in place by the workers and compacted at the end.
    let stride = if opts.keep == 0 {
        ng2
    } else {
        opts.keep.min(ng2)
    };
    let kernel = RowKernel::new(basis, &grid, rot, opts.keep, stride)?;
    let mut storage = RowStorage::new(n_obs, nb, stride)?;
    let slots = RowSlots::new(
        &mut storage.index,
        &mut storage.value,
        &mut storage.lens,
        nb,
        stride,
    );
    let vertices = VertexRows {
        normals_env,
        obs_dir_env,
        vis,
        solid_angle: &grid.solid_angle,
        kernel: &kernel,
        groups: VertexGroups::new(obs_vertex, nv),
    };
    // Every observation's rows straight into their slots, a vertex at a time.
    (0..nv).into_par_iter().with_min_len(16).for_each_init(
        || Scratch::new(opts.n_local),
        |scratch, v| vertices.write(v, scratch, &slots),
    );
    let RowStorage {
        mut index,
        mut value,
        lens,
    } = storage;

    let offsets = compact_rows(&mut index, &mut value, &lens, stride);
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
/// [`Transport::response`] and [`crate::render::wavelet::WaveletRenderer::vertex_radiance`] take).
pub fn light_haar(env: &OctEnv) -> [Vec<f64>; 3] {
    [0, 1, 2].map(|c| {
        let mut ch = env.channel(c);
        haar::forward(&mut ch, env.n);
        ch
    })
}
