//! `ABLATION_SH_MIX=s,…` (probe): the coarse-light model read over every seen observation
//! with its vertex's blend of the materials instead of the pure vertices alone,
//!
//! `y_{p,c} = (Σ_k w̃_{p,k} ρ_{k,c}) a_pᵀ b_{I,c}`, `b_{I,c} ≥ 0`,
//!
//! with `w̃_x = (1 − s) w_x + s · mean_{y ∈ N(x)} w_y` (the 8 nearest vertices): a pixel
//! around vertex `x` sees the surface between `x` and its neighbours, whose reflectance
//! the renderer interpolates between the vertices, so a vertex pure in the model is not
//! pure in its photos next to another material. The model is the library's
//! ([`relight_cpc::solve::materials::coarse_light_blend`]); `s` = 0 is what `run` reads.

use relight_cpc::observe::Observations;
use relight_cpc::solve::materials::coarse_light::CoarseRowsInput;
use relight_cpc::solve::materials::coarse_light_blend;
use relight_cpc::transport::Transport;

/// Each channel's albedos of the library's blend model
/// ([`relight_cpc::solve::materials::coarse_light_blend`]) over the fitted observations
/// of the seen vertices with the weights `w`, `r × r` blocks.
pub(super) fn mixture_albedos(
    obs: &Observations,
    t: &Transport,
    (seen, w, kk): (&[bool], &[f64], usize),
    r: usize,
) -> [Vec<f64>; 3] {
    let rows = coarse_light_blend::seen_blend_rows(&rows_input(obs, t, (seen, w, kk), r));
    let model = coarse_light_blend::BlendMoments::of(&rows, obs.photo_ranges.len(), kk);
    [0, 1, 2].map(|c| model.albedos(c, &vec![1.0; kk]).expect("finite rows"))
}

/// What the coarse-light models read: `obs` through `t` (the Lambertian basis first), the
/// seen vertices' normalised weights `w` (`V × K`), `r × r` blocks.
pub(super) fn rows_input<'a>(
    obs: &'a Observations,
    t: &'a Transport,
    (seen, w, kk): (&'a [bool], &'a [f64], usize),
    r: usize,
) -> CoarseRowsInput<'a> {
    CoarseRowsInput {
        obs,
        transport: t,
        seen,
        weights: w,
        materials: kk,
        lambert: 0,
        blocks: r,
    }
}
