//! The fitted model as images: the views a run renders and how.
//!
//! Each view is rendered by rasterising the mesh (z-buffer) and interpolating per-vertex
//! radiance from the wavelet renderer (Eq. 5–8, untruncated) across triangles
//! ([`crate::render`]). A training photo is drawn under its fitted map with the
//! estimator's own predictions where it has observations ([`render_training_view`]); the
//! held-out photos and the truth check's training photos are shaded in one vertex-major
//! pass ([`shade_views`]).
//!
//! The renderer has its own local resolution (`--render-local-resolution`, by default the
//! estimator's: half the global side with the adaptive model, so 16² at a 32² map) and its
//! own rotation
//! ([`crate::sphere::rotation::SplatRotation`]: the footprint of the vertex's exact normal instead
//! of the blend of four precomputed frames, Eq. 6). Visibility is traced once, at the finer
//! of the two resolutions ([`trace_visibility`]), and averaged down for the other.
//! Measured (`bench-results/agreement.md`, sphere over a plane under 8 real maps, a KNOWN
//! model): a 64² renderer draws a Phong-50 lobe closer to the Eq. 1 reference than a 32²
//! one (3.95% against 7.17% mean), diffuse 0.93% against 1.56%. For a FITTED model the
//! finer renderer buys nothing measurable: the Minerva model (6 materials, 7 lobes) on
//! `spot-varying` with 13 photos of 1 MP gave held-out RMSE (true light, after scale)
//! 0.0767 / 0.0765 at 2,930 vertices and 0.0766 / 0.0767 at 11,714 (64² / 32²), while 32²
//! halves the visibility trace (16.3 → 8.0 CPU s at 11,714) and the evaluation (48.2 →
//! 23.8 CPU s): the fit's own 32² transport, not the renderer, bounds what it can show. So
//! the default renders at the fit's resolution; `--render-local-resolution 64` is for
//! relighting a known or very sharp model under novel light.

use super::Fitted;
use crate::import::photo::Photo;
use crate::render::{self, Raster};
use crate::sphere::envmap::OctEnv;
use crate::transport::visibility::Visibility;
use crate::{Error, Result};
use nalgebra::Matrix3;
use std::path::Path;
use std::sync::Arc;

/// A rendered view: the raster and the linear RGB image.
pub(crate) struct RenderedView {
    pub raster: Raster,
    pub rgb: Vec<[f32; 3]>,
}

/// The render's local resolution for `opts`: `--render-local-resolution`, else the
/// estimator's local resolution (module docs: why not finer by default).
pub fn render_local_resolution(opts: &super::RunOptions) -> usize {
    opts.render_local_resolution
        .unwrap_or(opts.local_resolution)
}

/// Visibility rays per texel of the finer grid so that every texel of the estimator's
/// grid (`n_est` per side, `rays` asked for) still gets at least `rays`:
/// `max(1, ⌈rays · (n_est / n_fine)²⌉)` (1 ray per 64² texel = 4 per 32² texel at the
/// defaults).
pub fn fine_rays(rays: usize, n_est: usize, n_fine: usize) -> usize {
    let ratio = (n_fine / n_est.max(1)).max(1);
    rays.div_ceil(ratio * ratio).max(1)
}

/// Trace visibility once at the finer of the estimator's and the renderer's local
/// resolutions (module docs) and return `(estimator's, renderer's)`: one allocation when
/// the two resolutions are equal (the default; 100 MB at 100K vertices and 32²).
pub(crate) fn trace_visibility(
    mesh: &crate::import::mesh::Mesh,
    bvh: &crate::observe::trace::SceneBvh,
    env_from_world: &Matrix3<f64>,
    opts: &super::RunOptions,
) -> (Arc<Visibility>, Arc<Visibility>) {
    let n_render = render_local_resolution(opts);
    let n_fine = opts.local_resolution.max(n_render);
    let rays = fine_rays(opts.rays_per_texel, opts.local_resolution, n_fine);
    let sampling =
        crate::transport::visibility::Sampling::new(rays, opts.edge_rays, opts.ray_lattice);
    let fine = Arc::new(crate::transport::visibility::compute_sampled(
        mesh,
        bvh,
        env_from_world,
        n_fine,
        sampling,
        opts.seed,
        true,
    ));
    (
        at_side(&fine, opts.local_resolution),
        at_side(&fine, n_render),
    )
}

/// Visibility `fine` at `n ≤ fine.n_local` texels per side: `fine` itself when `n` is its
/// side, else averaged down ([`crate::solve::adapt::downsample_visibility`]).
pub(crate) fn at_side(fine: &Arc<Visibility>, n: usize) -> Arc<Visibility> {
    match crate::solve::adapt::downsample_visibility(fine, n) {
        std::borrow::Cow::Borrowed(_) => fine.clone(),
        std::borrow::Cow::Owned(v) => Arc::new(v),
    }
}

/// The wavelet renderer's model of the fit, with visibility `vis`.
fn wavelet_model<'a>(
    f: &'a Fitted,
    vis: &'a crate::transport::visibility::Visibility,
) -> render::WaveletModel<'a> {
    render::WaveletModel {
        mesh: &f.scene.mesh,
        normals_env: &f.normals_env,
        vis,
        env_from_world: &f.env_from_world,
        basis: &f.basis,
        beta: &f.beta,
    }
}

/// Training photo `k`'s render under its fitted map: the model exactly as it was fitted.
/// At the photo's observations the radiance is the estimator's own prediction
/// ([`Fitted::train_predictions`], through the kept transport rows); the visible vertices
/// that were not observed (grazing, on a depth discontinuity) are rendered with the
/// estimator's visibility and blended rotation (Eq. 6, the light rotated once per frame)
/// ([`render::shade_wavelet_known`]).
pub(crate) fn render_training_view(f: &Fitted, k: usize) -> Result<RenderedView> {
    let v = f.train[k];
    let view = &f.scene.views[v];
    let raster = render::rasterize(&f.scene.mesh, &view.camera, &view.image);
    let mut given = vec![None; f.scene.mesh.positions.len()];
    for &(x, rgb) in &f.train_predictions[k] {
        given[x as usize] = Some(rgb);
    }
    let rgb = render::shade_wavelet_known(
        &wavelet_model(f, &f.vis),
        &raster,
        &view.image,
        &fitted_env(f, k),
        &f.rot,
        &given,
    )?;
    Ok(RenderedView { raster, rgb })
}

/// Shade several views (each under its lights) with the renderer's visibility and rotation
/// (`--render-local-resolution`, [`crate::sphere::rotation::SplatRotation`]) in one
/// vertex-major pass ([`render::shade_views`]: a vertex's footprint walked once for the
/// lights of every view that shows it, its BRDF slices once per view).
pub(super) fn shade_views(
    f: &Fitted,
    views: &[render::ViewToShade],
) -> Result<render::ShadedViews> {
    render::shade_views(&wavelet_model(f, &f.render_vis), views, &f.render_rot)
}

/// [`shade_views`] with another reflectance in place of the fit's: per-vertex weights
/// `beta` (row-major `V × B`) of the lobes `basis`.
pub(super) fn shade_views_with(
    f: &Fitted,
    basis: &[crate::transport::brdf::BasisBrdf],
    beta: &[[f64; 3]],
    views: &[render::ViewToShade],
) -> Result<render::ShadedViews> {
    let model = render::WaveletModel {
        basis,
        beta,
        ..wavelet_model(f, &f.render_vis)
    };
    render::shade_views(&model, views, &f.render_rot)
}

/// The texels of a photo's fitted map as an [`OctEnv`].
pub(crate) fn fitted_env(f: &Fitted, k: usize) -> OctEnv {
    let l = &f.est.lights[k];
    OctEnv::from_channels(f.opts.global_resolution, [&l[0], &l[1], &l[2]])
}

/// The mean of the training maps ([`super::half_prior::mean_map`]).
pub(crate) fn mean_env(f: &Fitted) -> OctEnv {
    let n = f.opts.global_resolution;
    let mean = super::half_prior::mean_map(&f.est.lights, n * n);
    OctEnv::from_channels(n, [&mean[0], &mean[1], &mean[2]])
}

/// Pixels that count: object pixels off the object's edges and not overexposed in the
/// photo. An edge pixel ([`crate::observe::margins::edge_pixels`]: a 4-neighbour is
/// background, or lies across a depth jump of [`crate::observe::margins::DEPTH_JUMP`], the
/// observations' own) mixes the object with
/// what lies beside it: the photo's pixel covers both, the render draws one face there, so
/// no reflectance can predict it. The observations leave out the same pixels (weight 0
/// within one pixel of an edge). On `spot-diffuse` photos of 128² the true reflectance
/// under the true light scores 10.7% over every covered pixel and 5.9% without the edge
/// pixels, the same as at 256² (5.7%): what is left is the photos' own noise
/// (`bench-results/truth-check-floor.md`).
pub(super) fn valid_mask(raster: &Raster, photo: &Photo) -> Vec<bool> {
    let (w, h) = (raster.width as usize, raster.height as usize);
    let edges = crate::observe::margins::edge_pixels(
        &raster.depth,
        w,
        h,
        crate::observe::margins::DEPTH_JUMP,
    );
    raster
        .face
        .iter()
        .zip(&photo.overexposed)
        .zip(&edges)
        .map(|((&face, &over), &edge)| face != u32::MAX && !over && !edge)
        .collect()
}

/// photo | render | |difference| × 4 side by side, sRGB PNG. The render is shown after
/// multiplying by `scale` (the best global scale), so shading differences are visible
/// apart from the unknown overall brightness.
pub(crate) fn write_triptych(
    path: &Path,
    photo: &Photo,
    raster: &Raster,
    rgb: &[[f32; 3]],
    scale: f64,
) -> Result<()> {
    let (w, h) = (photo.width as usize, photo.height as usize);
    let s = if scale.is_finite() && scale > 0.0 {
        scale as f32
    } else {
        1.0
    };
    let mut out = vec![[0.0f32; 3]; 3 * w * h];
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            let inside = raster.face[i] != u32::MAX;
            let p = photo.rgb[i];
            let q = rgb[i].map(|v| v * s);
            out[y * 3 * w + x] = p;
            out[y * 3 * w + w + x] = if inside { q } else { [0.0; 3] };
            out[y * 3 * w + 2 * w + x] = if inside {
                [0, 1, 2].map(|c| 4.0 * (p[c] - q[c]).abs())
            } else {
                [0.0; 3]
            };
        }
    }
    crate::render::write_png(path, (3 * w) as u32, h as u32, &out, None, 1.0)?;
    // The same three panels as separate files, the difference as a heat map with its
    // range, for report.html: renders/panels/STEM.{photo,render,diff}.png.
    if let (Some(parent), Some(stem)) = (path.parent(), path.file_stem()) {
        let panels = parent.join("panels");
        std::fs::create_dir_all(&panels).map_err(|e| Error::io(&panels, e))?;
        crate::report::html::write_panels(
            &panels.join(stem),
            (photo.width, photo.height),
            &photo.rgb,
            rgb,
            &raster.mask(),
            s,
        )?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A raster of `w × h` pixels covered where `depth` is finite (face 0 there).
    fn raster(w: u32, h: u32, depth: Vec<f32>) -> Raster {
        Raster {
            width: w,
            height: h,
            face: depth
                .iter()
                .map(|z| if z.is_finite() { 0 } else { u32::MAX })
                .collect(),
            bary: vec![[1.0, 0.0, 0.0]; depth.len()],
            depth,
        }
    }

    #[test]
    fn scored_pixels_leave_out_silhouettes_depth_jumps_and_overexposure() {
        // 7 × 5 pixels: a 5 × 3 block at columns 1..=5, rows 1..=3. Columns 1–2 lie at
        // depth 1, columns 3–5 at depth 2 (a jump of 100% > 5%). Counted by hand: the
        // block's outer ring touches the background (a 4-neighbour outside), and columns 2
        // and 3 face each other across the jump, so of row 2 only column 4 is off every
        // edge. Overexpose it and nothing is left.
        let inf = f32::INFINITY;
        let (w, h) = (7usize, 5usize);
        let mut depth = vec![inf; w * h];
        for y in 1..=3 {
            for x in 1..=5 {
                depth[y * w + x] = if x <= 2 { 1.0 } else { 2.0 };
            }
        }
        let r = raster(w as u32, h as u32, depth);
        let mut photo = Photo::from_linear(w as u32, h as u32, vec![[0.5; 3]; w * h]);
        let mask = valid_mask(&r, &photo);
        let scored: Vec<usize> = (0..w * h).filter(|&i| mask[i]).collect();
        assert_eq!(scored, vec![2 * w + 4]);
        photo.overexposed[2 * w + 4] = true;
        assert!(!valid_mask(&r, &photo).contains(&true));
    }

    #[test]
    fn a_smooth_surface_is_scored_inside_its_one_pixel_rim() {
        // 9 × 9 pixels fully covered by a tilted plane whose depth changes 1% a pixel
        // (below the 5% jump): no edge inside, and the photo's border is not an edge, so
        // every pixel counts. Cut out the centre pixel (background): its four neighbours
        // leave, the other 76 stay.
        let (w, h) = (9usize, 9usize);
        let mut depth: Vec<f32> = (0..w * h).map(|i| 1.0 + 0.01 * (i % w) as f32).collect();
        let photo = Photo::from_linear(w as u32, h as u32, vec![[0.5; 3]; w * h]);
        let full = valid_mask(&raster(w as u32, h as u32, depth.clone()), &photo);
        assert_eq!(full.iter().filter(|&&m| m).count(), w * h);
        depth[4 * w + 4] = f32::INFINITY;
        let holed = valid_mask(&raster(w as u32, h as u32, depth), &photo);
        assert_eq!(holed.iter().filter(|&&m| m).count(), w * h - 5);
    }
}
