//! The wavelet renderer: the model's radiance at arbitrary vertices and views under one or
//! more environment maps, paper Eq. 5–8 evaluated per vertex (the light rotated into the
//! vertex's local frame, then the local triple product as a texel sum).
//!
//! Per channel `c`, with the light's local texel averages `L_{c,t}`, the slices
//! `ρ_b(t, ω_o)`, visibility `V_t` and solid angles `Δω_t`:
//! `I_c = Σ_b β_{b,c} Σ_t ρ_b(t, ω_o) V_t Δω_t L_{c,t} = Σ_t K_{c,t} L_{c,t}` with the
//! light-independent kernel `K_{c,t} = V_t Δω_t Σ_b β_{b,c} ρ_b(t, ω_o)`, formed once per
//! vertex and view; each light then costs one product per texel and channel.

use crate::sphere::envmap::OctEnv;
use crate::sphere::rotation::LocalRotation;
use crate::transport::brdf::{BasisBrdf, SliceGrid};
use crate::transport::{light_haar, local_wo, vertex_frame_into};
use crate::{Error, Result, Vec3};

/// Precomputed state for evaluating the model's radiance at arbitrary vertices and views
/// under one or more environment maps (the wavelet renderer, Eq. 5–8): per vertex, the
/// light rotated into its local frame (`W_lᵀ R_n L̃`, texel domain) is computed by
/// [`WaveletRenderer::vertex_radiance`]. After [`WaveletRenderer::with_frames`], the light is
/// rotated once into each of the rotation's precomputed frames `ν` and a vertex only blends
/// the four frames of its normal, `Σ_i φ_i(n) W_lᵀ R_{ν_i} L̃` (Eq. 6: the same sum the
/// per-vertex path forms, so equal to it up to rounding) — `n_local²` × 4 multiply-adds per
/// vertex instead of a resampling of the whole footprint.
///
/// With several lights ([`WaveletRenderer::new_many`], [`WaveletRenderer::vertex_radiance_all`])
/// the parts of Eq. 8 that do not depend on the light — the vertex frame, `V ⊙ Δω` and the
/// `B` BRDF slices `ρ_b(·, ω_o)` and the kernel `K` (module docs) — are computed once per
/// vertex and view and shared; only the rotation and the final sums are per light. Each
/// light's sums run in the same order as a renderer of that light alone, so the results
/// are bitwise those of separate renders.
pub struct WaveletRenderer<'a, R: LocalRotation> {
    rot: &'a R,
    basis: &'a [BasisBrdf],
    lights: Vec<RendererLight>,
    grid: std::sync::Arc<SliceGrid>,
    /// Per basis, its slice when it does not depend on `ω_o` (Lambert: computed once here,
    /// bitwise what every vertex would compute).
    fixed: Vec<Option<Vec<f64>>>,
    /// With a [`crate::sphere::rotation::SplatRotation`] rotation: every light's texels interleaved, global texel
    /// `g` of light `l`, channel `c` at `[g · 3L + 3l + c]`, so that one footprint walk
    /// reads all of a vertex's lights as contiguous runs
    /// ([`crate::sphere::rotation::SplatRotation::resample_interleaved`]).
    interleaved: Option<Vec<f64>>,
}

/// Reusable buffers of [`WaveletRenderer::vertex_radiance_all`], one per thread: the
/// vertex's `V ⊙ Δω`, the bases it uses, their slices and every light's local texels, so
/// that rendering a vertex allocates nothing.
#[derive(Debug, Default)]
pub struct RadianceScratch {
    v_dw: Vec<f64>,
    used: Vec<usize>,
    slices: Vec<f64>,
    /// Per channel, `(V Δω)_t Σ_b β_{b,c} slice_{b,t}` of the view being shaded.
    kernel: [Vec<f64>; 3],
    locals: Vec<[Vec<f64>; 3]>,
    /// The listed lights' local texels interleaved (texel-major), before they are split
    /// into `locals`.
    interleaved: Vec<f64>,
}

/// One light of a [`WaveletRenderer`]: Haar coefficients and texels per channel, and after
/// [`WaveletRenderer::with_frames`] the light's local texels in every precomputed frame
/// (every light has them or none does).
struct RendererLight {
    haar: [Vec<f64>; 3],
    texels: [Vec<f64>; 3],
    /// Per channel, frame-major.
    frames: Option<[Vec<f64>; 3]>,
}

impl<'a, R: LocalRotation> WaveletRenderer<'a, R> {
    /// A renderer for `env` (its side must equal the rotation's global side).
    pub fn new(rot: &'a R, basis: &'a [BasisBrdf], env: &OctEnv) -> Result<Self> {
        Self::new_many(rot, basis, &[env])
    }

    /// A renderer for several lights at once (every side must equal the rotation's global
    /// side; at least one light).
    pub fn new_many(rot: &'a R, basis: &'a [BasisBrdf], envs: &[&OctEnv]) -> Result<Self> {
        if envs.is_empty() {
            return Err(Error::Internal(
                "wavelet renderer: no light to render".into(),
            ));
        }
        if let Some(env) = envs.iter().find(|e| e.n != rot.n_global()) {
            return Err(Error::Internal(format!(
                "wavelet renderer: environment map is {}² but the rotation expects {}²",
                env.n,
                rot.n_global()
            )));
        }
        let grid = SliceGrid::shared(rot.n_local())?;
        let fixed = basis
            .iter()
            .map(|b| {
                (!b.view_dependent()).then(|| {
                    let mut s = vec![0.0; grid.centre.len()];
                    b.slice_with(&grid, &Vec3::z(), &mut s);
                    s
                })
            })
            .collect();
        let interleaved = rot.as_splat().map(|_| interleave_texels(envs));
        Ok(WaveletRenderer {
            rot,
            basis,
            fixed,
            interleaved,
            lights: envs
                .iter()
                .map(|env| RendererLight {
                    haar: light_haar(env),
                    texels: [0, 1, 2].map(|c| env.channel(c)),
                    frames: None,
                })
                .collect(),
            grid,
        })
    }

    /// Number of lights this renderer evaluates.
    pub fn n_lights(&self) -> usize {
        self.lights.len()
    }

    /// Rotate every light into every precomputed frame of the rotation now (when it has
    /// frames), so that [`WaveletRenderer::vertex_radiance`] blends instead of rotating.
    /// Worth it when more vertices are rendered than there are frames; memory
    /// `3 · n_frames · n_local² · 8` bytes per light.
    pub fn with_frames(mut self) -> Self {
        if self.rot.n_frames() > 0 {
            let rot = self.rot;
            for l in &mut self.lights {
                l.frames =
                    Some([0, 1, 2].map(|c| rot.light_texels_frames(&l.texels[c], &l.haar[c])));
            }
        }
        self
    }

    /// Whether [`WaveletRenderer::with_frames`] took effect.
    pub fn has_frames(&self) -> bool {
        self.lights[0].frames.is_some()
    }

    /// Radiance `Σ_b β_{b,c} ∫ ρ_b(ω, ω_o) V(ω) L_c(ω) dω` (linear RGB) under the first light
    /// at a vertex with unit normal `normal_env`, visibility row `vis_row` (`n_local²`
    /// fractions) and outgoing direction `wo_env` (both in the environment frame), for
    /// per-basis RGB weights `beta` (`B` entries). Untruncated: the reference the kept
    /// transport rows approximate. Returns zero for a degenerate normal or direction.
    pub fn vertex_radiance(
        &self,
        normal_env: &Vec3,
        vis_row: &[u8],
        wo_env: &Vec3,
        beta: &[[f64; 3]],
    ) -> [f64; 3] {
        let mut out = [[0.0; 3]];
        let view = VertexView {
            wo_env: *wo_env,
            lights: 0..1,
        };
        self.radiance_into(
            &mut RadianceScratch::default(),
            normal_env,
            vis_row,
            beta,
            std::slice::from_ref(&view),
            &mut out,
        );
        out[0]
    }

    /// [`WaveletRenderer::vertex_radiance`] under every light, into `out` (one RGB per
    /// light, in the order given to [`WaveletRenderer::new_many`]): the slices are computed
    /// once for all of them, in `scratch`'s buffers.
    pub fn vertex_radiance_all(
        &self,
        scratch: &mut RadianceScratch,
        normal_env: &Vec3,
        vis_row: &[u8],
        wo_env: &Vec3,
        beta: &[[f64; 3]],
        out: &mut [[f64; 3]],
    ) {
        assert_eq!(out.len(), self.lights.len(), "one output per light");
        let view = VertexView {
            wo_env: *wo_env,
            lights: 0..self.lights.len(),
        };
        self.radiance_into(
            scratch,
            normal_env,
            vis_row,
            beta,
            std::slice::from_ref(&view),
            out,
        );
    }

    /// The radiance of one vertex toward several views, each under its own lights
    /// (`views[i].lights`, a range of the lights given to [`WaveletRenderer::new_many`]),
    /// into `out`: the lights of view 0, then those of view 1, … (`Σ_i |views[i].lights|`
    /// entries). The light-independent work of the vertex (frame, `V ⊙ Δω`) and the
    /// rotation of every listed light into its frame (one walk of the footprint for all of
    /// them) are done once for all the views; the slices once per view. Every value equals
    /// [`WaveletRenderer::vertex_radiance_all`] of a renderer of that view's lights alone,
    /// bit for bit.
    pub fn vertex_radiance_views(
        &self,
        scratch: &mut RadianceScratch,
        normal_env: &Vec3,
        vis_row: &[u8],
        beta: &[[f64; 3]],
        views: &[VertexView],
        out: &mut [[f64; 3]],
    ) {
        let n: usize = views.iter().map(|v| v.lights.len()).sum();
        assert_eq!(out.len(), n, "one output per listed light");
        assert!(
            views.iter().all(|v| v.lights.end <= self.lights.len()),
            "a view names a light the renderer does not have"
        );
        self.radiance_into(scratch, normal_env, vis_row, beta, views, out);
    }

    /// The listed lights (in `views` order) rotated into the vertex's local frame, into
    /// `locals`: blended from the frames (every light has them or none does), or one
    /// footprint walk for all of them.
    fn rotate_lights(
        &self,
        normal: &Vec3,
        views: &[VertexView],
        locals: &mut [[Vec<f64>; 3]],
        buffer: &mut Vec<f64>,
    ) {
        let nl2 = self.rot.n_local() * self.rot.n_local();
        if let (Some(splat), Some(il)) = (self.rot.as_splat(), &self.interleaved) {
            // The views' slots, those of consecutive views as one run (the same slots in
            // the same places, fewer and longer loops per sub-texel).
            let mut spans: Vec<std::ops::Range<usize>> = Vec::with_capacity(views.len());
            for v in views.iter().filter(|v| !v.lights.is_empty()) {
                let s = 3 * v.lights.start..3 * v.lights.end;
                match spans.last_mut() {
                    Some(last) if last.end == s.start => last.end = s.end,
                    _ => spans.push(s),
                }
            }
            splat.resample_interleaved(normal, il, 3 * self.lights.len(), &spans, buffer);
            split_interleaved(buffer, nl2, locals);
            return;
        }
        let listed = views
            .iter()
            .flat_map(|v| self.lights[v.lights.clone()].iter());
        if self.lights[0].frames.is_some() {
            // Same accumulation order as the blended resampling (frame by frame, zero
            // weights skipped).
            let blend = self.rot.frame_blend(normal);
            for (light, local) in listed.zip(locals.iter_mut()) {
                let frames = light.frames.as_ref().expect("every light has frames");
                for (l, f) in local.iter_mut().zip(frames) {
                    l.fill(0.0);
                    for &(nu, w) in &blend {
                        if w == 0.0 {
                            continue;
                        }
                        for (o, x) in l.iter_mut().zip(&f[nu * nl2..(nu + 1) * nl2]) {
                            *o += w * x;
                        }
                    }
                }
            }
        } else {
            let listed: Vec<&RendererLight> = listed.collect();
            let channels = |f: fn(&RendererLight) -> &[Vec<f64>; 3]| -> Vec<[&[f64]; 3]> {
                listed
                    .iter()
                    .map(|&l| {
                        let ch = f(l);
                        [0, 1, 2].map(|c| ch[c].as_slice())
                    })
                    .collect()
            };
            let texels = channels(|l| &l.texels);
            let haar = channels(|l| &l.haar);
            self.rot
                .light_texels_rgb_many(normal, &texels, &haar, locals);
        }
    }

    fn radiance_into(
        &self,
        scratch: &mut RadianceScratch,
        normal_env: &Vec3,
        vis_row: &[u8],
        beta: &[[f64; 3]],
        views: &[VertexView],
        out: &mut [[f64; 3]],
    ) {
        out.iter_mut().for_each(|o| *o = [0.0; 3]);
        let RadianceScratch {
            v_dw,
            used,
            slices,
            kernel,
            locals,
            interleaved,
        } = scratch;
        let Some((normal, frame)) =
            vertex_frame_into(normal_env, vis_row, &self.grid.solid_angle, v_dw)
        else {
            return;
        };
        let nl2 = self.rot.n_local() * self.rot.n_local();
        // The bases with a non-zero weight.
        used.clear();
        used.extend(
            (0..self.basis.len().min(beta.len())).filter(|&b| beta[b].iter().any(|&x| x != 0.0)),
        );
        slices.resize(used.len() * nl2, 0.0);
        locals.resize_with(out.len(), || [0, 1, 2].map(|_| vec![0.0; nl2]));
        let locals = &mut locals[..out.len()];
        self.rotate_lights(&normal, views, locals, interleaved);
        let mut at = 0;
        for view in views {
            let (lo, hi) = (at, at + view.lights.len());
            at = hi;
            let Some(wo) = local_wo(&frame, &view.wo_env) else {
                continue;
            };
            // The slices once for every light of the view.
            for (&b, s) in used.iter().zip(slices.chunks_mut(nl2)) {
                match &self.fixed[b] {
                    Some(f) => s.copy_from_slice(f),
                    None => self.basis[b].slice_with(&self.grid, &wo, s),
                }
            }
            view_kernel(used, slices, v_dw, beta, kernel);
            for (local, o) in locals[lo..hi].iter().zip(out[lo..hi].iter_mut()) {
                for c in 0..3 {
                    o[c] = kernel[c].iter().zip(&local[c]).map(|(k, l)| k * l).sum();
                }
            }
        }
    }
}

/// Every light's texels interleaved texel-major: texel `g`, light `l`, channel `c` at
/// `[g · 3L + 3l + c]` (`L` lights).
fn interleave_texels(envs: &[&OctEnv]) -> Vec<f64> {
    let width = 3 * envs.len();
    let channels: Vec<Vec<f64>> = envs
        .iter()
        .flat_map(|e| [0, 1, 2].map(|c| e.channel(c)))
        .collect();
    let texels = channels.first().map_or(0, Vec::len);
    let mut out = vec![0.0; texels * width];
    for (k, ch) in channels.iter().enumerate() {
        for (g, v) in ch.iter().enumerate() {
            out[g * width + k] = *v;
        }
    }
    out
}

/// `locals[i][c][j] = buffer[j · 3n + 3i + c]` (`n = locals.len()` lights, `nl2` texels).
fn split_interleaved(buffer: &[f64], nl2: usize, locals: &mut [[Vec<f64>; 3]]) {
    let w = 3 * locals.len();
    for (i, local) in locals.iter_mut().enumerate() {
        for (c, l) in local.iter_mut().enumerate() {
            l.clear();
            l.extend((0..nl2).map(|j| buffer[j * w + 3 * i + c]));
        }
    }
}

/// One view of a vertex in [`WaveletRenderer::vertex_radiance_views`]: the outgoing
/// direction (unit, environment frame, vertex → camera) and the renderer's lights the view
/// is shaded under.
#[derive(Debug, Clone, PartialEq)]
pub struct VertexView {
    /// Unit direction from the vertex toward the camera, environment frame.
    pub wo_env: Vec3,
    /// The renderer's lights of this view (indices into [`WaveletRenderer::new_many`]'s).
    pub lights: std::ops::Range<usize>,
}

/// The light-independent factor of Eq. 8 as a texel sum for one view, per channel:
/// `kernel_{c,t} = (V Δω)_t Σ_b β_{b,c} slice_{b,t}` over the `used` bases (their slices
/// consecutive in `slices`, `n_local²` each), so that a light with local texels `L_{c,t}`
/// gives `out_c = Σ_t kernel_{c,t} L_{c,t}` (one product per texel and light instead of one
/// per texel, basis and light).
fn view_kernel(
    used: &[usize],
    slices: &[f64],
    v_dw: &[f64],
    beta: &[[f64; 3]],
    kernel: &mut [Vec<f64>; 3],
) {
    let nl2 = v_dw.len();
    for k in kernel.iter_mut() {
        k.clear();
        k.resize(nl2, 0.0);
    }
    for (&b, slice) in used.iter().zip(slices.chunks(nl2)) {
        let w = &beta[b];
        for c in 0..3 {
            for (k, s) in kernel[c].iter_mut().zip(slice) {
                *k += w[c] * s;
            }
        }
    }
    for k in kernel.iter_mut() {
        k.iter_mut().zip(v_dw).for_each(|(k, vw)| *k *= vw);
    }
}
