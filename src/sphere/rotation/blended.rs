//! The blended precomputed rotation (paper Eq. 6): `R_ν = W_l S_ν W_gᵀ` for the normals of
//! a full octahedral grid, blended bilinearly per normal (module docs of
//! [`crate::sphere::rotation`] give the construction and the balancing).

use super::resampling::{resampling_flat_with, FlatRows, ResamplingGeometry, DEFAULT_SUPERSAMPLE};
use super::symmetry::by_symmetry;
use super::LocalRotation;
use crate::sphere::haar;
use crate::sphere::SphereGrid;
use crate::Vec3;
use rayon::prelude::*;

/// How [`Rotation`] stores its operators.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RotationForm {
    /// Sparse texel resampling `S_ν`, applied between an inverse and a forward Haar transform.
    Factored,
    /// `R_ν = W_l S_ν W_gᵀ` as a sparse matrix, entries with `|R_ab| ≤ threshold` dropped.
    Sparse {
        /// Absolute threshold on the entries of `R_ν`.
        threshold: f64,
    },
}

/// Compressed rows of one normal's operator.
#[derive(Debug, Clone, Default)]
struct Csr {
    offsets: Vec<u32>,
    index: Vec<u16>,
    value: Vec<f32>,
}

impl Csr {
    fn row(&self, r: usize) -> (&[u16], &[f32]) {
        let (lo, hi) = (self.offsets[r] as usize, self.offsets[r + 1] as usize);
        (&self.index[lo..hi], &self.value[lo..hi])
    }

    fn from_flat(rows: &FlatRows<f32>) -> Self {
        Csr {
            offsets: rows.offsets.clone(),
            index: rows.entries.iter().map(|&(i, _)| i as u16).collect(),
            value: rows.entries.iter().map(|&(_, v)| v).collect(),
        }
    }

    fn from_rows(rows: &[Vec<(u32, f32)>]) -> Self {
        let mut offsets = Vec::with_capacity(rows.len() + 1);
        offsets.push(0);
        let mut c = Csr {
            offsets,
            ..Csr::default()
        };
        for row in rows {
            for &(i, v) in row {
                c.index.push(i as u16);
                c.value.push(v);
            }
            c.offsets.push(c.index.len() as u32);
        }
        c
    }

    fn bytes(&self) -> usize {
        self.offsets.len() * 4 + self.index.len() * 2 + self.value.len() * 4
    }
}

/// Precomputed rotations `R_ν` for a grid of normals (module docs).
#[derive(Debug, Clone)]
pub struct Rotation {
    /// Global octahedral map side (environment frame).
    pub n_global: usize,
    /// Local hemi-octahedral map side.
    pub n_local: usize,
    /// Normal grid side: `n_normals²` normals at the full octahedral texel centres.
    pub n_normals: usize,
    /// Sub-texels per side used to build `S_ν`.
    pub supersample: usize,
    form: RotationForm,
    /// `S_ν` rows (factored form) or `R_ν` rows (sparse form) of normal `ν`: `rows[ν]`.
    rows: Vec<Csr>,
}

thread_local! {
    static BUF: std::cell::RefCell<(Vec<f64>, Vec<f64>, Vec<f64>)> =
        const { std::cell::RefCell::new((Vec::new(), Vec::new(), Vec::new())) };
}

impl Rotation {
    /// Build all `R_ν` (in parallel). Sizes must be powers of two `≥ 2`, `n_global ≤ 256`
    /// (entries are stored with 16-bit indices).
    pub fn new(n_global: usize, n_local: usize, n_normals: usize, form: RotationForm) -> Rotation {
        Self::with_supersample(n_global, n_local, n_normals, form, DEFAULT_SUPERSAMPLE)
    }

    /// [`Rotation::new`] with a chosen number of sub-texels per side.
    pub fn with_supersample(
        n_global: usize,
        n_local: usize,
        n_normals: usize,
        form: RotationForm,
        supersample: usize,
    ) -> Rotation {
        assert!(
            n_global <= 256,
            "global map side {n_global} > 256: rotation indices are 16-bit"
        );
        let gn = SphereGrid::full(n_normals);
        let geo = ResamplingGeometry::new(n_global, n_local, supersample);
        let rows = match form {
            RotationForm::Factored => by_symmetry(&gn, &geo, Csr::from_flat),
            RotationForm::Sparse { threshold } => (0..gn.len())
                .into_par_iter()
                .map(|nu| {
                    crate::stages::tick(1);
                    let s = resampling_flat_with(&geo, &gn.texel_dir(nu));
                    let s: Vec<Vec<(u32, f32)>> = (0..s.len()).map(|j| s.row(j).to_vec()).collect();
                    Csr::from_rows(&wavelet_matrix(&s, n_global, n_local, threshold))
                })
                .collect(),
        };
        Rotation {
            n_global,
            n_local,
            n_normals,
            supersample,
            form,
            rows,
        }
    }

    /// Approximate bytes [`Rotation::new`] will hold in the factored form, before building
    /// it (for a memory check): `n_normals² · n_local²` rows of about 11 entries (measured
    /// with the default 4×4 sub-texels; 6 bytes each) plus a 4-byte offset per row.
    pub fn estimate_memory_bytes(n_local: usize, n_normals: usize) -> usize {
        let rows = n_normals * n_normals * n_local * n_local;
        rows * (11 * 6 + 4)
    }

    /// The storage form.
    pub fn form(&self) -> RotationForm {
        self.form
    }

    /// Number of normals `n_normals²`.
    pub fn len(&self) -> usize {
        self.n_normals * self.n_normals
    }

    /// Always `false`.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Normal `ν` (unit, environment frame).
    pub fn normal_dir(&self, nu: usize) -> Vec3 {
        SphereGrid::full(self.n_normals).texel_dir(nu)
    }

    /// Eq. 6 weights `φ_ν(n)` of the four grid normals nearest to `normal` (sum 1).
    pub fn blend(&self, normal: &Vec3) -> [(usize, f64); 4] {
        SphereGrid::full(self.n_normals).bilinear(normal)
    }

    fn nl2(&self) -> usize {
        self.n_local * self.n_local
    }

    fn ng2(&self) -> usize {
        self.n_global * self.n_global
    }

    /// Texel domain: `local += Σ_i w_i S_{ν_i} global` (factored form only).
    fn resample_add(&self, nus: &[(usize, f64)], global: &[f64], local: &mut [f64]) {
        self.resample_add_many(nus, [global], [local]);
    }

    /// [`Rotation::resample_add`] of `C` vectors (a light's colour channels) in one pass
    /// over the rows: each vector's sums are the ones a pass of its own makes, term by term
    /// (from `−0.0`, as `Iterator::sum`), so equal bit for bit.
    fn resample_add_many<const C: usize>(
        &self,
        nus: &[(usize, f64)],
        global: [&[f64]; C],
        local: [&mut [f64]; C],
    ) {
        for &(nu, w) in nus {
            if w == 0.0 {
                continue;
            }
            for j in 0..local[0].len() {
                let (idx, val) = self.rows[nu].row(j);
                let mut s = [-0.0_f64; C];
                for (&g, &v) in idx.iter().zip(val) {
                    let (g, v) = (g as usize, v as f64);
                    for c in 0..C {
                        s[c] += v * global[c][g];
                    }
                }
                for c in 0..C {
                    local[c][j] += w * s[c];
                }
            }
        }
    }

    /// Texel domain: `global += Σ_i w_i S_{ν_i}ᵀ local` (factored form only).
    fn resample_transpose_add(&self, nus: &[(usize, f64)], local: &[f64], global: &mut [f64]) {
        for &(nu, w) in nus {
            if w == 0.0 {
                continue;
            }
            for (j, &x) in local.iter().enumerate() {
                // Occluded texels and a narrow lobe's far side are exact zeros: nothing to
                // scatter (w · 0 · v adds +0.0, so skipping changes no bit of the sum).
                if x == 0.0 {
                    continue;
                }
                let wx = w * x;
                let (idx, val) = self.rows[nu].row(j);
                for (&g, &v) in idx.iter().zip(val) {
                    global[g as usize] += wx * v as f64;
                }
            }
        }
    }

    /// [`Rotation::resample_transpose_add`] for `K` texel-domain vectors at once, interleaved:
    /// `inter[g K + i] += Σ_(ν, w) Σ_j w x_{i,j} S_ν[j, g]` with `x_i = locals[i n_l²..]`.
    /// Each resampling row is read once for all `K` vectors; every sum takes its terms in
    /// the order of the single-vector form (a zero `x` adds `±0`, which changes no value).
    /// Compiled for AVX2 too when the CPU has it (wider vectors, no fused multiply-add:
    /// the same values bit for bit).
    fn resample_transpose_add_many<const K: usize>(
        &self,
        nus: &[(usize, f64)],
        locals: &[f64],
        inter: &mut [f64],
    ) {
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports the feature the function is compiled for.
            return unsafe { self.resample_transpose_add_many_avx2::<K>(nus, locals, inter) };
        }
        self.resample_transpose_add_many_impl::<K>(nus, locals, inter)
    }

    /// [`Rotation::resample_transpose_add_many_impl`] compiled for AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn resample_transpose_add_many_avx2<const K: usize>(
        &self,
        nus: &[(usize, f64)],
        locals: &[f64],
        inter: &mut [f64],
    ) {
        self.resample_transpose_add_many_impl::<K>(nus, locals, inter)
    }

    /// The loops behind [`Rotation::resample_transpose_add_many`].
    #[inline(always)]
    fn resample_transpose_add_many_impl<const K: usize>(
        &self,
        nus: &[(usize, f64)],
        locals: &[f64],
        inter: &mut [f64],
    ) {
        let nl2 = self.nl2();
        for &(nu, w) in nus {
            if w == 0.0 {
                continue;
            }
            for j in 0..nl2 {
                let mut wx = [0.0f64; K];
                let mut any = false;
                for (i, o) in wx.iter_mut().enumerate() {
                    let x = locals[i * nl2 + j];
                    any |= x != 0.0;
                    *o = w * x;
                }
                if !any {
                    continue;
                }
                let (idx, val) = self.rows[nu].row(j);
                for (&g, &v) in idx.iter().zip(val) {
                    let v = v as f64;
                    let at = g as usize * K;
                    let out: &mut [f64; K] =
                        (&mut inter[at..at + K]).try_into().expect("a K-wide slot");
                    for (o, a) in out.iter_mut().zip(&wx) {
                        *o += a * v;
                    }
                }
            }
        }
    }

    /// The factored form of [`LocalRotation::texel_transpose_many`] for `K` vectors.
    fn texel_transpose_k<const K: usize>(
        &self,
        nus: &[(usize, f64)],
        locals: &[f64],
        global: &mut [f64],
        inter: &mut Vec<f64>,
    ) {
        let ng2 = self.ng2();
        inter.clear();
        // The K interleaved sums, then the transforms' scratch ((n/2)² values).
        inter.resize(ng2 * K + ng2 / 4, 0.0);
        let (sums, scratch) = inter.split_at_mut(ng2 * K);
        self.resample_transpose_add_many::<K>(nus, locals, sums);
        for (i, g) in global.chunks_mut(ng2).enumerate().take(K) {
            haar::forward_interleaved(sums, K, i, g, self.n_global, scratch);
        }
    }

    /// Wavelet domain, sparse form: `local += Σ_i w_i R_{ν_i} global`.
    fn sparse_add(&self, nus: &[(usize, f64)], global: &[f64], local: &mut [f64]) {
        for &(nu, w) in nus {
            for (a, out) in local.iter_mut().enumerate() {
                let (idx, val) = self.rows[nu].row(a);
                let s: f64 = idx
                    .iter()
                    .zip(val)
                    .map(|(&b, &v)| v as f64 * global[b as usize])
                    .sum();
                *out += w * s;
            }
        }
    }

    /// Wavelet domain, sparse form: `global += Σ_i w_i R_{ν_i}ᵀ local`.
    fn sparse_transpose_add(&self, nus: &[(usize, f64)], local: &[f64], global: &mut [f64]) {
        for &(nu, w) in nus {
            for (a, &x) in local.iter().enumerate() {
                let (idx, val) = self.rows[nu].row(a);
                for (&b, &v) in idx.iter().zip(val) {
                    global[b as usize] += w * x * v as f64;
                }
            }
        }
    }

    /// `local = Σ_i w_i R_{ν_i} global` in the wavelet domain.
    fn apply_weighted(&self, nus: &[(usize, f64)], global_haar: &[f64], local_haar: &mut [f64]) {
        assert!(global_haar.len() == self.ng2() && local_haar.len() == self.nl2());
        local_haar.iter_mut().for_each(|x| *x = 0.0);
        match self.form {
            RotationForm::Sparse { .. } => self.sparse_add(nus, global_haar, local_haar),
            RotationForm::Factored => BUF.with(|b| {
                let (g, _, scratch) = &mut *b.borrow_mut();
                g.clear();
                g.extend_from_slice(global_haar);
                haar::inverse_with(g, self.n_global, scratch);
                self.resample_add(nus, g, local_haar);
                haar::forward_with(local_haar, self.n_local, scratch);
            }),
        }
    }

    /// `global += Σ_i w_i R_{ν_i}ᵀ local` in the wavelet domain.
    fn apply_weighted_transpose_add(
        &self,
        nus: &[(usize, f64)],
        local_haar: &[f64],
        global_haar: &mut [f64],
    ) {
        assert!(global_haar.len() == self.ng2() && local_haar.len() == self.nl2());
        match self.form {
            RotationForm::Sparse { .. } => self.sparse_transpose_add(nus, local_haar, global_haar),
            RotationForm::Factored => BUF.with(|b| {
                let (l, g, scratch) = &mut *b.borrow_mut();
                l.clear();
                l.extend_from_slice(local_haar);
                haar::inverse_with(l, self.n_local, scratch);
                g.clear();
                g.resize(self.ng2(), 0.0);
                self.resample_transpose_add(nus, l, g);
                haar::forward_with(g, self.n_global, scratch);
                global_haar
                    .iter_mut()
                    .zip(g.iter())
                    .for_each(|(o, x)| *o += x);
            }),
        }
    }

    /// `local_haar = R_ν global_haar` for grid normal `nu`.
    pub fn apply(&self, nu: usize, global_haar: &[f64], local_haar: &mut [f64]) {
        self.apply_weighted(&[(nu, 1.0)], global_haar, local_haar);
    }

    /// `global_haar += R_νᵀ local_haar`.
    pub fn apply_transpose_add(&self, nu: usize, local_haar: &[f64], global_haar: &mut [f64]) {
        self.apply_weighted_transpose_add(&[(nu, 1.0)], local_haar, global_haar);
    }

    /// `local_haar = Σ_i φ_i(n) R_{ν_i} global_haar` (Eq. 6).
    pub fn apply_blend(&self, normal: &Vec3, global_haar: &[f64], local_haar: &mut [f64]) {
        self.apply_weighted(&self.blend(normal), global_haar, local_haar);
    }

    /// `global_haar += (Σ_i φ_i(n) R_{ν_i})ᵀ local_haar`.
    pub fn apply_blend_transpose_add(
        &self,
        normal: &Vec3,
        local_haar: &[f64],
        global_haar: &mut [f64],
    ) {
        self.apply_weighted_transpose_add(&self.blend(normal), local_haar, global_haar);
    }

    /// Texel domain (factored form): `local_texels = S_ν global_texels` (texel averages).
    /// Panics on the sparse form, which does not keep `S_ν`.
    pub fn resample_texels(&self, nu: usize, global_texels: &[f64], local_texels: &mut [f64]) {
        assert!(
            self.form == RotationForm::Factored,
            "texel resampling needs the factored form"
        );
        local_texels.iter_mut().for_each(|x| *x = 0.0);
        self.resample_add(&[(nu, 1.0)], global_texels, local_texels);
    }

    /// Texel domain (factored form): `global_texels += S_νᵀ local_texels`.
    pub fn resample_texels_transpose_add(
        &self,
        nu: usize,
        local_texels: &[f64],
        global_texels: &mut [f64],
    ) {
        assert!(
            self.form == RotationForm::Factored,
            "texel resampling needs the factored form"
        );
        self.resample_transpose_add(&[(nu, 1.0)], local_texels, global_texels);
    }

    /// Texel domain (factored form), blended over the four nearest normals (Eq. 6).
    pub fn resample_texels_blend(
        &self,
        normal: &Vec3,
        global_texels: &[f64],
        local_texels: &mut [f64],
    ) {
        assert!(
            self.form == RotationForm::Factored,
            "texel resampling needs the factored form"
        );
        local_texels.iter_mut().for_each(|x| *x = 0.0);
        self.resample_add(&self.blend(normal), global_texels, local_texels);
    }

    /// Texel domain (factored form): `global_texels += (Σ_i φ_i S_{ν_i})ᵀ local_texels`.
    pub fn resample_texels_blend_transpose_add(
        &self,
        normal: &Vec3,
        local_texels: &[f64],
        global_texels: &mut [f64],
    ) {
        assert!(
            self.form == RotationForm::Factored,
            "texel resampling needs the factored form"
        );
        self.resample_transpose_add(&self.blend(normal), local_texels, global_texels);
    }

    /// `S_ν global_texels` for every grid normal (factored form), `n_normals² × n_local²`
    /// (row `ν`), in parallel: row `ν` equals [`Rotation::resample_texels`]`(ν, …)` bitwise.
    pub fn resample_texels_all(&self, global_texels: &[f64]) -> Vec<f64> {
        assert!(
            self.form == RotationForm::Factored,
            "texel resampling needs the factored form"
        );
        assert!(global_texels.len() == self.ng2());
        let nl2 = self.nl2();
        let mut out = vec![0.0; self.len() * nl2];
        out.par_chunks_mut(nl2)
            .enumerate()
            .for_each(|(nu, local)| self.resample_add(&[(nu, 1.0)], global_texels, local));
        out
    }

    /// `R_ν global_haar` for every grid normal, `n_normals² × n_local²` (row `ν`), in
    /// parallel.
    pub fn rotate_all(&self, global_haar: &[f64]) -> Vec<f64> {
        assert!(global_haar.len() == self.ng2());
        let nl2 = self.nl2();
        let mut out = vec![0.0; self.len() * nl2];
        match self.form {
            RotationForm::Sparse { .. } => {
                out.par_chunks_mut(nl2)
                    .enumerate()
                    .for_each(|(nu, local)| self.sparse_add(&[(nu, 1.0)], global_haar, local));
            }
            RotationForm::Factored => {
                let mut g = global_haar.to_vec();
                haar::inverse(&mut g, self.n_global);
                out.par_chunks_mut(nl2).enumerate().for_each_init(
                    Vec::new,
                    |scratch, (nu, local)| {
                        self.resample_add(&[(nu, 1.0)], &g, local);
                        haar::forward_with(local, self.n_local, scratch);
                    },
                );
            }
        }
        out
    }

    /// Number of stored matrix entries.
    pub fn nnz(&self) -> usize {
        self.rows.iter().map(|c| c.index.len()).sum()
    }

    /// Bytes held by the stored operators.
    pub fn memory_bytes(&self) -> usize {
        self.rows.iter().map(Csr::bytes).sum()
    }
}

/// `R = W_l S W_gᵀ` from the rows of `S`, thresholded: rows per local coefficient.
fn wavelet_matrix(
    s: &[Vec<(u32, f32)>],
    n_global: usize,
    n_local: usize,
    threshold: f64,
) -> Vec<Vec<(u32, f32)>> {
    let (ng2, nl2) = (n_global * n_global, n_local * n_local);
    // M = S W_gᵀ: row j is W_g applied to row j of S.
    let mut m = vec![0.0f64; nl2 * ng2];
    let mut scratch = Vec::new();
    for (j, row) in s.iter().enumerate() {
        let r = &mut m[j * ng2..(j + 1) * ng2];
        for &(g, v) in row {
            r[g as usize] = v as f64;
        }
        haar::forward_with(r, n_global, &mut scratch);
    }
    // R = W_l M: transform every column.
    let mut colbuf = vec![0.0f64; nl2];
    for b in 0..ng2 {
        for a in 0..nl2 {
            colbuf[a] = m[a * ng2 + b];
        }
        haar::forward_with(&mut colbuf, n_local, &mut scratch);
        for a in 0..nl2 {
            m[a * ng2 + b] = colbuf[a];
        }
    }
    (0..nl2)
        .map(|a| {
            m[a * ng2..(a + 1) * ng2]
                .iter()
                .enumerate()
                .filter(|(_, v)| v.abs() > threshold)
                .map(|(b, &v)| (b as u32, v as f32))
                .collect()
        })
        .collect()
}

/// The blended precomputed rotation of Eq. 6.
impl LocalRotation for Rotation {
    fn n_global(&self) -> usize {
        self.n_global
    }
    fn n_local(&self) -> usize {
        self.n_local
    }
    fn apply(&self, normal_env: &Vec3, global: &[f64], local: &mut [f64]) {
        self.apply_blend(normal_env, global, local);
    }
    fn apply_transpose_add(&self, normal_env: &Vec3, local: &[f64], global: &mut [f64]) {
        self.apply_blend_transpose_add(normal_env, local, global);
    }
    fn texel_transpose(&self, normal_env: &Vec3, local_texels: &mut [f64], global: &mut [f64]) {
        match self.form() {
            // W_lᵀ W_l = I: R_nᵀ W_l f = W_g S_nᵀ f.
            RotationForm::Factored => {
                global.fill(0.0);
                self.resample_texels_blend_transpose_add(normal_env, local_texels, global);
                haar::forward(global, self.n_global);
            }
            RotationForm::Sparse { .. } => {
                haar::forward(local_texels, self.n_local);
                global.fill(0.0);
                self.apply_blend_transpose_add(normal_env, local_texels, global);
            }
        }
    }
    fn texel_transpose_many(
        &self,
        normal_env: &Vec3,
        local_texels: &mut [f64],
        global: &mut [f64],
        scratch: &mut Vec<f64>,
    ) {
        if self.form() != RotationForm::Factored {
            for (l, g) in local_texels
                .chunks_mut(self.nl2())
                .zip(global.chunks_mut(self.ng2()))
            {
                self.texel_transpose(normal_env, l, g);
            }
            return;
        }
        let nus = self.blend(normal_env);
        // Groups of at most 8 vectors (the interleaved slot of one global texel stays
        // within a cache line).
        for (l, g) in local_texels
            .chunks(8 * self.nl2())
            .zip(global.chunks_mut(8 * self.ng2()))
        {
            match l.len() / self.nl2() {
                1 => self.texel_transpose_k::<1>(&nus, l, g, scratch),
                2 => self.texel_transpose_k::<2>(&nus, l, g, scratch),
                3 => self.texel_transpose_k::<3>(&nus, l, g, scratch),
                4 => self.texel_transpose_k::<4>(&nus, l, g, scratch),
                5 => self.texel_transpose_k::<5>(&nus, l, g, scratch),
                6 => self.texel_transpose_k::<6>(&nus, l, g, scratch),
                7 => self.texel_transpose_k::<7>(&nus, l, g, scratch),
                _ => self.texel_transpose_k::<8>(&nus, l, g, scratch),
            }
        }
    }
    fn light_texels_rgb(
        &self,
        normal_env: &Vec3,
        global_texels: [&[f64]; 3],
        global_haar: [&[f64]; 3],
        local_texels: &mut [Vec<f64>; 3],
    ) {
        if self.form() != RotationForm::Factored {
            let (t, h) = (global_texels, global_haar);
            return super::light_texels_by_channel(self, normal_env, t, h, local_texels);
        }
        for l in local_texels.iter_mut() {
            l.fill(0.0);
        }
        let [l0, l1, l2] = local_texels;
        let local = [l0.as_mut_slice(), l1.as_mut_slice(), l2.as_mut_slice()];
        self.resample_add_many(&self.blend(normal_env), global_texels, local);
    }
    fn light_texels(
        &self,
        normal_env: &Vec3,
        global_texels: &[f64],
        global_haar: &[f64],
        local_texels: &mut [f64],
    ) {
        match self.form() {
            RotationForm::Factored => {
                self.resample_texels_blend(normal_env, global_texels, local_texels)
            }
            RotationForm::Sparse { .. } => {
                self.apply_blend(normal_env, global_haar, local_texels);
                haar::inverse(local_texels, self.n_local);
            }
        }
    }
    fn n_frames(&self) -> usize {
        self.len()
    }
    fn light_texels_frames(&self, global_texels: &[f64], global_haar: &[f64]) -> Vec<f64> {
        match self.form() {
            RotationForm::Factored => self.resample_texels_all(global_texels),
            RotationForm::Sparse { .. } => {
                let mut all = self.rotate_all(global_haar);
                let nl = self.n_local;
                all.par_chunks_mut(nl * nl)
                    .for_each(|c| haar::inverse(c, nl));
                all
            }
        }
    }
    fn frame_blend(&self, normal_env: &Vec3) -> [(usize, f64); 4] {
        self.blend(normal_env)
    }
}
