//! The rows of one vertex (paper Eq. 5–8, module docs of [`crate::transport`]): per
//! observation and basis BRDF, the texel product `f = V ⊙ Δω ⊙ ρ_b(ω_o)` in the vertex's
//! local map, through the rotation's transpose and the Haar transform to the dense global
//! row `g = R_nᵀ W_l f`, truncated to its `keep` largest coefficients ([`truncate_global`]).
//! The view-independent rows (Lambert) are built and truncated once per vertex; all the
//! vertex's rows go through the rotation in one call.
//!
//! Slices: a lobe is tabulated over a 32² grid of `ω_o` (bilinear lookup, ~2 µs) when its
//! scale `σ` spans at least 4 table spacings, else computed on demand (adaptive, 8–16 µs
//! at 32², `cargo bench --bench slicetime`). Measured (benches/transport.rs): the table's slice error is 0.6% (median
//! relative L2) for GGX 0.4 but 3% / 10% / 19% for GGX 0.2 / 0.1 / Phong 500, so of the
//! default lobes only Lambert (one slice) and GGX 0.4 use tables. The error depends on `σ`
//! in table spacings (test `a_slice_table_is_as_accurate_at_equal_lobe_width_in_table_spacings`:
//! GGX 0.2 on a 64² table 0.8%); 64² tables for GGX 0.2 and 0.35 did not make the 100K
//! transport stage faster (`bench-results/transport-by-vertex.md`).

use super::truncate::{truncate_global, Selection};
use super::{HaarIndex, TransportValue};
use crate::sphere::rotation::LocalRotation;
use crate::transport::brdf::{BasisBrdf, SliceGrid, SliceTable};
use crate::{Result, Vec3};

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

/// Scratch buffers for one thread (allocated once per worker, never per row).
pub(super) struct Scratch {
    /// The vertex's `V ⊙ Δω` per local texel.
    pub(super) v_dw: Vec<f64>,
    /// The selection buffers of [`truncate_global`].
    sel: Selection,
    /// The vertex's observations.
    pub(super) seen: Vec<SeenObs>,
    /// The vertex's `V ⊙ Δω ⊙ slice` per row: its fixed rows, then each observation's
    /// view-dependent rows.
    locals: Vec<f64>,
    /// Their dense global rows, in the same order.
    globals: Vec<f64>,
    /// The fixed rows truncated once per vertex: `stride` slots per fixed basis.
    fixed_idx: Vec<HaarIndex>,
    fixed_val: Vec<TransportValue>,
    fixed_len: Vec<usize>,
    /// The rotation's interleaving buffer ([`LocalRotation::texel_transpose_many`]).
    inter: Vec<f64>,
    /// Progress, passed on per chunk of observations.
    pub(super) ticks: crate::stages::Ticker,
}

impl Scratch {
    pub(super) fn new(n_local: usize) -> Self {
        Scratch {
            v_dw: Vec::with_capacity(n_local * n_local),
            sel: Selection::default(),
            seen: Vec::new(),
            locals: Vec::new(),
            globals: Vec::new(),
            fixed_idx: Vec::new(),
            fixed_val: Vec::new(),
            fixed_len: Vec::new(),
            inter: Vec::new(),
            ticks: Default::default(),
        }
    }
}

/// One observation of the vertex being built.
pub(super) struct SeenObs {
    /// The observation.
    pub(super) p: usize,
    /// `ω_o` in the vertex's local frame (`None` when degenerate: fixed rows only).
    wo: Option<Vec3>,
    /// Its first view-dependent row in [`Scratch::locals`] / [`Scratch::globals`] (set by
    /// [`RowKernel::vertex_rows`]).
    first_row: usize,
}

impl SeenObs {
    /// Observation `p` seen from `wo` (local frame).
    pub(super) fn new(p: usize, wo: Option<Vec3>) -> Self {
        SeenObs {
            p,
            wo,
            first_row: 0,
        }
    }
}

/// What every vertex's rows are built with: the bases, their slice sources, the rotation
/// and the truncation.
pub(super) struct RowKernel<'a, R> {
    basis: &'a [BasisBrdf],
    sources: Vec<SliceSource>,
    grid: &'a SliceGrid,
    /// The view-independent bases (Lambert), built once per vertex.
    fixed_bases: Vec<usize>,
    /// The others, built per observation.
    view_bases: Vec<usize>,
    rot: &'a R,
    keep: usize,
    stride: usize,
}

impl<'a, R: LocalRotation> RowKernel<'a, R> {
    /// The kernel for `basis` on `grid`, truncating to `keep` entries (0: all) into slots
    /// of `stride`.
    pub(super) fn new(
        basis: &'a [BasisBrdf],
        grid: &'a SliceGrid,
        rot: &'a R,
        keep: usize,
        stride: usize,
    ) -> Result<Self> {
        let sources: Vec<SliceSource> = basis
            .iter()
            .map(|b| SliceSource::new(b, grid))
            .collect::<Result<_>>()?;
        let fixed_bases: Vec<usize> = (0..basis.len())
            .filter(|&b| matches!(sources[b], SliceSource::Fixed(_)))
            .collect();
        let view_bases = (0..basis.len())
            .filter(|b| !fixed_bases.contains(b))
            .collect();
        Ok(RowKernel {
            basis,
            sources,
            grid,
            fixed_bases,
            view_bases,
            rot,
            keep,
            stride,
        })
    }

    /// The dense global rows `g = R_nᵀ W_l (V ⊙ Δω ⊙ slice)` of a vertex of unit normal
    /// `normal` whose `V ⊙ Δω` is in `scratch.v_dw` and whose observations are in
    /// `scratch.seen`: its fixed rows once, then each observation's view-dependent rows,
    /// all through one call of the rotation (which then reads its operator once); the
    /// fixed rows are truncated here, once for every observation.
    pub(super) fn vertex_rows(&self, normal: &Vec3, scratch: &mut Scratch) {
        let nl2 = scratch.v_dw.len();
        let ng2 = self.rot.n_global() * self.rot.n_global();
        let (nf, nview) = (self.fixed_bases.len(), self.view_bases.len());
        let mut rows = nf;
        for o in &mut scratch.seen {
            o.first_row = rows;
            if o.wo.is_some() {
                rows += nview;
            }
        }
        scratch.locals.resize(rows * nl2, 0.0);
        scratch.globals.resize(rows * ng2, 0.0);
        let mut locals = scratch.locals.chunks_mut(nl2);
        for &b in &self.fixed_bases {
            let local = locals.next().expect("a row per fixed basis");
            self.sources[b].slice(&self.basis[b], self.grid, &Vec3::z(), local);
            for (l, vw) in local.iter_mut().zip(&scratch.v_dw) {
                *l *= vw;
            }
        }
        for wo in scratch.seen.iter().filter_map(|o| o.wo.as_ref()) {
            for &b in &self.view_bases {
                let local = locals.next().expect("a row per view-dependent basis");
                self.sources[b].slice_for(&self.basis[b], self.grid, wo, &scratch.v_dw, local);
                for (l, vw) in local.iter_mut().zip(&scratch.v_dw) {
                    *l *= vw;
                }
            }
        }
        self.rot.texel_transpose_many(
            normal,
            &mut scratch.locals,
            &mut scratch.globals,
            &mut scratch.inter,
        );
        scratch.fixed_idx.resize(nf * self.stride, 0);
        scratch
            .fixed_val
            .resize(nf * self.stride, TransportValue::ZERO);
        scratch.fixed_len.resize(nf, 0);
        for j in 0..nf {
            let span = j * self.stride..(j + 1) * self.stride;
            scratch.fixed_len[j] = truncate_global(
                &scratch.globals[j * ng2..(j + 1) * ng2],
                &mut scratch.sel,
                self.fixed_bases[j],
                self.keep,
                &mut scratch.fixed_idx[span.clone()],
                &mut scratch.fixed_val[span],
            );
        }
    }

    /// The truncated rows of the vertex's `k`-th observation into its slots.
    pub(super) fn write_rows(
        &self,
        scratch: &mut Scratch,
        k: usize,
        oi: &mut [HaarIndex],
        ov: &mut [TransportValue],
        ol: &mut [usize],
    ) {
        let ng2 = self.rot.n_global() * self.rot.n_global();
        for (j, &b) in self.fixed_bases.iter().enumerate() {
            let (from, n) = (j * self.stride, scratch.fixed_len[j]);
            let to = b * self.stride;
            oi[to..to + n].copy_from_slice(&scratch.fixed_idx[from..from + n]);
            ov[to..to + n].copy_from_slice(&scratch.fixed_val[from..from + n]);
            ol[b] = n;
        }
        let SeenObs {
            wo: Some(_),
            first_row: first,
            ..
        } = scratch.seen[k]
        else {
            return;
        };
        for (i, &b) in self.view_bases.iter().enumerate() {
            let r = first + i;
            let span = b * self.stride..(b + 1) * self.stride;
            ol[b] = truncate_global(
                &scratch.globals[r * ng2..(r + 1) * ng2],
                &mut scratch.sel,
                b,
                self.keep,
                &mut oi[span.clone()],
                &mut ov[span],
            );
        }
    }
}
