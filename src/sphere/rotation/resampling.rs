//! The resampling `S_ν` of the blended rotation (paper Eq. 6, `R_ν = W_l S_ν W_gᵀ`): for the
//! local frame of normal `ν`, each local texel `j` (hemisphere grid) as a weighted average of
//! global texels `g` (full grid). The overlap areas `A[j][g] = Σ_{sub-texels of j}
//! Δω_sub · b_g(ω_sub)` (`s × s` sub-texels with exact solid angles, `b_g` the bilinear tap of
//! global texel `g` at the sub-texel's direction) are Sinkhorn-balanced so that rows sum to
//! the local texels' solid angles `Ω_l` and the columns of global texels inside the
//! footprint to theirs, `Ω_g` (module docs of [`crate::sphere::rotation`]). The parts that
//! do not depend on `ν` ([`ResamplingGeometry`]) are built once per table.

use crate::sphere::{from_local, local_frame, SphereGrid};
use crate::Vec3;

/// Default sub-texels per side of a local texel when building `S_ν`.
pub const DEFAULT_SUPERSAMPLE: usize = 4;
/// Sinkhorn iterations balancing rows and columns of `S_ν`.
const BALANCE_ITERATIONS: usize = 12;

/// The parts of the resampling `S_ν` that do not depend on the normal `ν`: the local
/// sub-texels (their directions in the local frame and exact solid angles), both grids'
/// texel solid angles, the global texel centres and 4-neighbours. Built once per
/// [`super::Rotation`] and shared by every normal's [`resampling_rows_with`]; the values are the
/// ones the per-normal construction computes, so the rows are bit for bit the same.
#[derive(Debug, Clone)]
pub struct ResamplingGeometry {
    gg: SphereGrid,
    gl: SphereGrid,
    supersample: usize,
    /// Sub-texels of local texel `j`: `subs[j s² .. (j + 1) s²]`, (local direction, `ω`).
    subs: Vec<(Vec3, f64)>,
    omega_g: Vec<f64>,
    omega_l: Vec<f64>,
    /// Global texel centres (environment frame).
    dir_g: Vec<Vec3>,
    /// [`SphereGrid::neighbors`] of every global texel.
    nbr_g: Vec<[usize; 4]>,
}

impl ResamplingGeometry {
    /// The normal-independent parts for the given map sides and sub-texels per side.
    pub fn new(n_global: usize, n_local: usize, supersample: usize) -> Self {
        let gg = SphereGrid::full(n_global);
        let gl = SphereGrid::hemi(n_local);
        let s = supersample.max(1);
        let subs = (0..gl.len()).flat_map(|j| gl.sample_points(j, s)).collect();
        ResamplingGeometry {
            gg,
            gl,
            supersample: s,
            subs,
            omega_g: gg.solid_angles(),
            omega_l: gl.solid_angles(),
            dir_g: (0..gg.len()).map(|t| gg.texel_dir(t)).collect(),
            nbr_g: (0..gg.len()).map(|t| gg.neighbors(t)).collect(),
        }
    }

    /// The global (full octahedral) grid.
    pub(super) fn global(&self) -> &SphereGrid {
        &self.gg
    }

    /// The local (hemi-octahedral) grid.
    pub(super) fn local(&self) -> &SphereGrid {
        &self.gl
    }

    /// The sub-texels of local texel `j`.
    pub(super) fn subs_of(&self, j: usize) -> &[(Vec3, f64)] {
        let k = self.supersample * self.supersample;
        &self.subs[j * k..(j + 1) * k]
    }

    /// Global texels whose bilinear footprint (centres of the 3×3 block around them) is
    /// above the horizon of the frame with normal `up_axis`.
    pub(super) fn interior(&self, up_axis: &Vec3) -> Vec<bool> {
        let up: Vec<bool> = self.dir_g.iter().map(|d| d.dot(up_axis) > 0.0).collect();
        (0..up.len())
            .map(|t| {
                up[t]
                    && self.nbr_g[t]
                        .iter()
                        .all(|&nb| up[nb] && self.nbr_g[nb].iter().all(|&nn| up[nn]))
            })
            .collect()
    }
}

/// The resampling `S` for one exact normal, as rows `(global texel, weight)` per local texel
/// (each row a weighted average: weights sum to ~1). Module docs give the construction.
pub fn resampling_rows(
    normal: &Vec3,
    n_global: usize,
    n_local: usize,
    supersample: usize,
) -> Vec<Vec<(u32, f32)>> {
    resampling_rows_with(
        &ResamplingGeometry::new(n_global, n_local, supersample),
        normal,
    )
}

/// [`resampling_rows`] with the normal-independent parts given.
pub fn resampling_rows_with(geo: &ResamplingGeometry, normal: &Vec3) -> Vec<Vec<(u32, f32)>> {
    let flat = resampling_flat_with(geo, normal);
    (0..flat.len()).map(|j| flat.row(j).to_vec()).collect()
}

/// Rows of one normal's resampling stored flat: row `j` is
/// `entries[offsets[j]..offsets[j + 1]]` (one allocation per table instead of one per row).
#[derive(Debug, Clone, Default)]
pub(crate) struct FlatRows<T> {
    pub(crate) offsets: Vec<u32>,
    pub(crate) entries: Vec<(u32, T)>,
}

impl<T> FlatRows<T> {
    /// Number of rows.
    pub(crate) fn len(&self) -> usize {
        self.offsets.len().saturating_sub(1)
    }

    /// Row `j`.
    pub(crate) fn row(&self, j: usize) -> &[(u32, T)] {
        &self.entries[self.offsets[j] as usize..self.offsets[j + 1] as usize]
    }

    fn row_mut(&mut self, j: usize) -> &mut [(u32, T)] {
        let (lo, hi) = (self.offsets[j] as usize, self.offsets[j + 1] as usize);
        &mut self.entries[lo..hi]
    }
}

/// [`resampling_rows_with`] as [`FlatRows`].
pub(crate) fn resampling_flat_with(geo: &ResamplingGeometry, normal: &Vec3) -> FlatRows<f32> {
    let frame = local_frame(&normal.normalize());
    let mut rows = overlap_rows(geo, &frame);
    let interior = geo.interior(&frame[2]);
    balance(&mut rows, &interior, &geo.omega_g, &geo.omega_l);
    let entries = (0..rows.len())
        .flat_map(|j| {
            let omega = geo.omega_l[j];
            rows.row(j)
                .iter()
                .map(move |&(t, a)| (t, (a / omega) as f32))
        })
        .collect();
    FlatRows {
        offsets: rows.offsets,
        entries,
    }
}

/// Overlap areas `A[j][g]` (ascending `g` per local texel `j`) from the sub-texel samples
/// and their bilinear taps in the global map.
fn overlap_rows(geo: &ResamplingGeometry, frame: &[Vec3; 3]) -> FlatRows<f64> {
    let mut acc = vec![0.0f64; geo.gg.len()];
    let mut touched: Vec<usize> = Vec::new();
    let s2 = geo.supersample * geo.supersample;
    let mut rows = FlatRows {
        offsets: Vec::with_capacity(geo.gl.len() + 1),
        // About 11 global texels per local texel at the default 4 × 4 sub-texels.
        entries: Vec::with_capacity(geo.gl.len() * (s2 / 2 + 4)),
    };
    rows.offsets.push(0);
    for j in 0..geo.gl.len() {
        for (dl, w) in geo.subs_of(j) {
            let de = from_local(frame, dl);
            for (t, bw) in geo.gg.bilinear(&de) {
                if bw == 0.0 {
                    continue;
                }
                if acc[t] == 0.0 {
                    touched.push(t);
                }
                acc[t] += w * bw;
            }
        }
        touched.sort_unstable();
        rows.entries
            .extend(touched.iter().map(|&t| (t as u32, acc[t])));
        rows.offsets.push(rows.entries.len() as u32);
        for &t in &touched {
            acc[t] = 0.0;
        }
        touched.clear();
    }
    rows
}

/// Sinkhorn balancing of the overlap rows (module docs): rows to `Ω_l`, the columns of
/// `interior` global texels to `Ω_g`, ending with the columns.
fn balance(rows: &mut FlatRows<f64>, interior: &[bool], omega_g: &[f64], omega_l: &[f64]) {
    let mut col = vec![0.0f64; omega_g.len()];
    for it in 0..BALANCE_ITERATIONS {
        if it > 0 {
            for (j, &om) in omega_l.iter().enumerate().take(rows.len()) {
                let row = rows.row_mut(j);
                let s: f64 = row.iter().map(|e| e.1).sum();
                if s > 0.0 {
                    let k = om / s;
                    row.iter_mut().for_each(|e| e.1 *= k);
                }
            }
        }
        col.iter_mut().for_each(|c| *c = 0.0);
        for &(t, a) in &rows.entries {
            col[t as usize] += a;
        }
        for (t, c) in col.iter_mut().enumerate() {
            *c = if interior[t] && *c > 0.0 {
                omega_g[t] / *c
            } else {
                1.0
            };
        }
        rows.entries
            .iter_mut()
            .for_each(|e| e.1 *= col[e.0 as usize]);
    }
}
