//! Wavelet rotation of the lighting into local frames (paper Sec. 4.2, Eq. 6; Wang, Ng and
//! Xu, "Rotating the light: precomputed wavelet rotations", 2006).
//!
//! The lighting `L̃` lives in the global octahedral map (`n_global²` texels, environment
//! frame, Haar coefficients `ℓ = W_g L̄`). A surface point with normal `ν` needs it in its
//! local hemi-octahedral map (`n_local²` texels in [`crate::sphere::local_frame`]`(ν)`):
//!
//! `R_ν = W_l · S_ν · W_gᵀ`
//!
//! where `S_ν` maps global texel averages to local texel averages. Row `j` of `S_ν` is the
//! footprint of local texel `j`: `s × s` sub-texels with their exact solid angles
//! ([`crate::sphere::SphereGrid::sample_points`]), each looking the global map up bilinearly, normalised by
//! the texel's solid angle `Ω_j`. Then the matrix `A = diag(Ω_l) S_ν` (overlap areas) is
//! balanced (Sinkhorn iterations) so that its rows sum to `Ω_j` (a constant sky stays
//! constant) and, for every global texel whose bilinear footprint lies above the horizon,
//! its column sums to `Ω_g` — so the energy `Σ_j Ω_j (S_ν L̄)_j` of a one-texel sun is exactly
//! `Ω_g L̄_g`: rotation conserves energy, as docs/method.md requires. The balancing ends with
//! the columns; the remaining row error is measured in the tests.
//!
//! Normals `ν` are the texel centres of the full octahedral grid `SphereGrid::full(n_normals)`
//! (environment frame). An arbitrary normal `n` uses the bilinear blend of the four nearest
//! (Eq. 6): `R(n) = Σ_i φ_i(n) R_{ν_i}`.
//!
//! Two forms ([`RotationForm`]): *factored* stores the sparse `S_ν` and applies
//! inverse Haar, resample, Haar (exactly the matrix product); *sparse* stores `R_ν` itself
//! with entries below a threshold dropped. The benchmark (`benches/core.rs`) compares them.
//!
//! Three implementations of [`LocalRotation`], the rotation as the transport and the
//! renderer see it: [`Rotation`] (blended precomputed frames, Eq. 6, `blended.rs`),
//! [`SplatRotation`] (the renderer's exact-normal splat, `splat.rs`) and
//! [`ExactRotation`] (a supersampled per-normal reference for tests, `exact.rs`).

mod blended;
mod exact;
mod resampling;
mod splat;
mod symmetry;
#[cfg(test)]
mod tests;

pub use blended::{Rotation, RotationForm};
pub use exact::ExactRotation;
pub use resampling::{
    resampling_rows, resampling_rows_with, ResamplingGeometry, DEFAULT_SUPERSAMPLE,
};
pub use splat::SplatRotation;

use crate::sphere::haar;
use crate::Vec3;

/// The lighting rotation as the transport sees it: `R_n` maps the global Haar coefficients
/// of a light (`n_global²`) to the local Haar coefficients (`n_local²`) in the frame of
/// unit normal `n` (environment frame). Implemented for [`crate::sphere::rotation::Rotation`]
/// (blended, Eq. 6) and for [`ExactRotation`] (a per-normal supersampled reference).
pub trait LocalRotation: Sync {
    /// Global map side.
    fn n_global(&self) -> usize;
    /// Local map side.
    fn n_local(&self) -> usize;
    /// `local = R_n global` (overwrites `local`).
    fn apply(&self, normal_env: &Vec3, global: &[f64], local: &mut [f64]);
    /// `global += R_nᵀ local`.
    fn apply_transpose_add(&self, normal_env: &Vec3, local: &[f64], global: &mut [f64]);
    /// `global = R_nᵀ W_l local_texels` (overwrites `global`): the transpose applied to a
    /// texel-domain vector. The default goes through the local Haar transform; a factored
    /// rotation can skip it.
    fn texel_transpose(&self, normal_env: &Vec3, local_texels: &mut [f64], global: &mut [f64]) {
        haar::forward(local_texels, self.n_local());
        global.fill(0.0);
        self.apply_transpose_add(normal_env, local_texels, global);
    }
    /// [`LocalRotation::texel_transpose`] for `k = local_texels.len() / n_local²` vectors at
    /// once (vector `i` is `local_texels[i n_local²..]`, its result
    /// `global[i n_global²..]`); `scratch` is a reused buffer. Each result equals a call
    /// for that vector alone (a rotation that walks per-normal rows reads them once for all
    /// `k`).
    fn texel_transpose_many(
        &self,
        normal_env: &Vec3,
        local_texels: &mut [f64],
        global: &mut [f64],
        scratch: &mut Vec<f64>,
    ) {
        let _ = scratch;
        let (nl2, ng2) = (
            self.n_local() * self.n_local(),
            self.n_global() * self.n_global(),
        );
        for (l, g) in local_texels.chunks_mut(nl2).zip(global.chunks_mut(ng2)) {
            self.texel_transpose(normal_env, l, g);
        }
    }
    /// `local_texels = W_lᵀ R_n W_g global_texels`: the light's local texel averages, given
    /// the global light both as texels and as Haar coefficients (`global_haar = W_g
    /// global_texels`). The default goes through Haar; a factored rotation resamples
    /// texels directly.
    fn light_texels(
        &self,
        normal_env: &Vec3,
        global_texels: &[f64],
        global_haar: &[f64],
        local_texels: &mut [f64],
    ) {
        let _ = global_texels;
        self.apply(normal_env, global_haar, local_texels);
        haar::inverse(local_texels, self.n_local());
    }
    /// [`LocalRotation::light_texels`] for the three colour channels at once (a rotation
    /// that looks its footprint up per call does it once for all three).
    fn light_texels_rgb(
        &self,
        normal_env: &Vec3,
        global_texels: [&[f64]; 3],
        global_haar: [&[f64]; 3],
        local_texels: &mut [Vec<f64>; 3],
    ) {
        light_texels_by_channel(self, normal_env, global_texels, global_haar, local_texels);
    }
    /// [`LocalRotation::light_texels_rgb`] for several lights at once: light `i`'s channels
    /// `global_texels[i]` / `global_haar[i]` into `local_texels[i]`. A rotation that walks a
    /// per-normal footprint does it once for all lights; each light's values equal those
    /// of a call for that light alone, bit for bit.
    fn light_texels_rgb_many(
        &self,
        normal_env: &Vec3,
        global_texels: &[[&[f64]; 3]],
        global_haar: &[[&[f64]; 3]],
        local_texels: &mut [[Vec<f64>; 3]],
    ) {
        for ((t, h), l) in global_texels.iter().zip(global_haar).zip(local_texels) {
            self.light_texels_rgb(normal_env, *t, *h, l);
        }
    }
    /// Number of precomputed frames `ν` that [`LocalRotation::light_texels`] blends (Eq. 6),
    /// or 0 when the rotation has no finite set of frames (then the two methods below are
    /// never called).
    fn n_frames(&self) -> usize {
        0
    }
    /// `W_lᵀ R_ν W_g L` for every precomputed frame `ν` (frame-major, `n_local²` texels
    /// each): the light rotated once per frame, to be blended per vertex.
    fn light_texels_frames(&self, global_texels: &[f64], global_haar: &[f64]) -> Vec<f64> {
        let _ = (global_texels, global_haar);
        Vec::new()
    }
    /// The Eq. 6 blend weights `φ_ν(n)` of the frames for `normal_env`, in the order
    /// [`LocalRotation::light_texels`] accumulates them.
    fn frame_blend(&self, normal_env: &Vec3) -> [(usize, f64); 4] {
        let _ = normal_env;
        [(0, 0.0); 4]
    }
    /// The rotation as a [`SplatRotation`], when it is one: its footprint walk can then
    /// read several lights' texels interleaved ([`SplatRotation::resample_interleaved`]).
    fn as_splat(&self) -> Option<&SplatRotation> {
        None
    }
}

/// [`LocalRotation::light_texels_rgb`] as three calls of [`LocalRotation::light_texels`],
/// one per channel (the trait's default, and the blended rotation's sparse form).
fn light_texels_by_channel<R: LocalRotation + ?Sized>(
    rot: &R,
    normal_env: &Vec3,
    global_texels: [&[f64]; 3],
    global_haar: [&[f64]; 3],
    local_texels: &mut [Vec<f64>; 3],
) {
    for (c, l) in local_texels.iter_mut().enumerate() {
        rot.light_texels(normal_env, global_texels[c], global_haar[c], l);
    }
}
