//! The light a photo shows directly: its background pixels, read as views of the distant
//! environment (beyond the paper; the idea of Lalonde, Efros & Narasimhan 2009, who read
//! the illumination of outdoor photos from their sky pixels).
//!
//! A pixel the object does not cover sees, along its camera ray
//! `d = R_env · Rᵀ K⁻¹ (x, y, 1)` (environment frame, docs/conventions.md), the light
//! arriving from that direction, under the photo's own exposure and white balance:
//! `y_q = e_I wb_{I,c} L̃_c(d_q)`. The photo's estimated map `x_{I,c}` is in exactly those
//! units (the object's pixels `y_p = Σ_b β ⟨g_{p,b}, W x_{I,c}⟩` carry the same `e_I wb_I`),
//! so each background pixel observes one texel of `x_{I,c}` with no free scale: the
//! texel `t(d_q)` of the global octahedral map that contains `d_q`. Summed per texel,
//! `Σ_q (x_{t(q),c} − y_{q,c})² = Σ_t n_t (x_{t,c} − ȳ_{t,c})² + const`, with `n_t` the
//! pixels in texel `t` and `ȳ_t` their mean: a diagonal quadratic the lighting QP adds
//! ([`crate::solve::light::background`]).
//!
//! A texel is read only when the photo shows all of it as background: every pixel whose
//! ray falls in it is off the rasterised mesh ([`super::raster`]) by at least
//! [`BackgroundOptions::margin_px`] (a silhouette pixel mixes object and sky, and a real
//! mask is never exact) and not overexposed (a clipped sky is only a lower bound, and the
//! rest of the texel would read low, its brightest part missing), and those pixels cover
//! at least [`BackgroundOptions::min_coverage`] of the texel's solid angle. The model's
//! texel is the map's mean over the texel, so a texel seen in part would read the mean of
//! that part; the pixels are weighted by their solid angle, `dω = cos³θ / (f_x f_y)` for a
//! pinhole, so the mean is over directions, not pixels.
//!
//! The model is only right where the background is far: a sky, distant hills. Nearby
//! walls, the ground at the object's foot and passers-by are not the light at the object,
//! which is why reading them is an option, off by default.

use rayon::prelude::*;

use crate::import::mesh::Mesh;
use crate::import::photo::Photo;
use crate::import::scene::View;
use crate::observe::margins::distance_to;
use crate::observe::raster::rasterize;
use crate::sphere::SphereGrid;
use nalgebra::Matrix3;

/// Which background pixels are read, and onto which map.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BackgroundOptions {
    /// Texels per side of the global octahedral map the pixels observe.
    pub n_global: usize,
    /// Least distance (pixels, between centres) from the object's rasterised mask.
    pub margin_px: f64,
    /// Least share of a texel's solid angle its background pixels must cover.
    pub min_coverage: f64,
}

impl BackgroundOptions {
    /// The defaults on a map of `n_global` per side: 2 pixels from the object, 90% of
    /// the texel seen.
    pub fn new(n_global: usize) -> Self {
        BackgroundOptions {
            n_global,
            margin_px: 2.0,
            min_coverage: 0.9,
        }
    }
}

/// The mean of one photo's background pixels inside one texel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BackgroundTexel {
    /// Texel index of the global octahedral map ([`SphereGrid::full`]).
    pub texel: u32,
    /// Pixels read in it.
    pub pixels: u32,
    /// Their mean linear RGB, weighted by solid angle.
    pub mean: [f32; 3],
}

/// Per view (in the order given), the texels its background pixels observe, by texel index.
pub type BackgroundLight = Vec<Vec<BackgroundTexel>>;

/// Reads the background of every view (module docs); `env_from_world` takes world
/// directions to the environment frame of the maps.
pub fn extract<P: std::borrow::Borrow<Photo> + Sync>(
    mesh: &Mesh,
    views: &[View],
    photos: &[P],
    env_from_world: &Matrix3<f64>,
    opts: &BackgroundOptions,
) -> BackgroundLight {
    views
        .par_iter()
        .zip(photos.par_iter())
        .map(|(view, photo)| view_background(mesh, view, photo.borrow(), env_from_world, opts))
        .collect()
}

/// One view's background texels (module docs); none when the photo's size is not the
/// camera's (its pixels would not be the rays computed here).
fn view_background(
    mesh: &Mesh,
    view: &View,
    photo: &Photo,
    env_from_world: &Matrix3<f64>,
    opts: &BackgroundOptions,
) -> Vec<BackgroundTexel> {
    let cam = &view.camera;
    if photo.width != cam.width || photo.height != cam.height || photo.rgb.is_empty() {
        return Vec::new();
    }
    let (w, h) = (cam.width as usize, cam.height as usize);
    let raster = rasterize(mesh, cam, &view.image);
    let distance = distance_to(&raster.mask(), w, h);
    let env_from_cam = env_from_world * view.image.cam_from_world_rotation().matrix().transpose();
    let (fx, fy) = cam.focal();
    let grid = SphereGrid::full(opts.n_global);
    let mut acc = vec![TexelSum::default(); grid.len()];
    for (i, (&rgb, &d)) in photo.rgb.iter().zip(&distance).enumerate() {
        let pixel = [(i % w) as f64 + 0.5, (i / w) as f64 + 0.5];
        let Some(ray) = cam.unproject(pixel) else {
            continue;
        };
        let t = grid.texel_of(&(env_from_cam * ray));
        // A pinhole pixel's solid angle: `dω = cos³θ / (f_x f_y)`, `cos θ = 1 / |(u, v, 1)|`.
        let d_omega = (1.0 / ray.norm()).powi(3) / (fx * fy);
        let clipped = photo.overexposed.get(i).copied().unwrap_or(false)
            || rgb.iter().any(|&v| v >= photo.clip_level || !v.is_finite());
        acc[t].add(rgb, d_omega, (d as f64) >= opts.margin_px.max(1.0), clipped);
    }
    acc.iter()
        .enumerate()
        .filter(|&(t, s)| s.whole(grid.solid_angle(t), opts.min_coverage))
        .map(|(t, s)| BackgroundTexel {
            texel: t as u32,
            pixels: s.pixels,
            mean: s.rgb.map(|v| (v / s.omega) as f32),
        })
        .collect()
}

/// One texel's background pixels: their solid-angle-weighted colour sum, solid angle and
/// count, and whether a pixel in it was overexposed or not background.
#[derive(Debug, Clone, Copy, Default)]
struct TexelSum {
    rgb: [f64; 3],
    omega: f64,
    pixels: u32,
    spoilt: bool,
}

impl TexelSum {
    /// Adds a pixel of colour `rgb` and solid angle `d_omega`: to the sums when it is
    /// background, else it spoils the texel (so does a clipped background pixel).
    fn add(&mut self, rgb: [f32; 3], d_omega: f64, background: bool, clipped: bool) {
        if !background || clipped {
            self.spoilt = true;
            return;
        }
        for (s, &v) in self.rgb.iter_mut().zip(&rgb) {
            *s += d_omega * f64::from(v);
        }
        self.omega += d_omega;
        self.pixels += 1;
    }

    /// Whether the texel is read: unspoilt, and its background pixels cover at least
    /// `min_coverage` of its solid angle `texel_omega`.
    fn whole(&self, texel_omega: f64, min_coverage: f64) -> bool {
        !self.spoilt && self.pixels > 0 && self.omega >= min_coverage * texel_omega
    }
}
