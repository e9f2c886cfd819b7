//! Images from per-vertex quantities: rasterise the mesh into a COLMAP camera
//! ([`crate::observe::raster`], re-exported here), interpolate per-vertex values (radiance
//! from the wavelet renderer, Eq. 8, or anything else) across the triangles, and write PNG
//! (sRGB) or EXR (linear) with an object mask.
//!
//! Encoding: PNG stores `srgb(exposure · v)` with the exact piecewise sRGB curve
//! (`12.92 v` for `v ≤ 0.0031308`, else `1.055 v^{1/2.4} − 0.055`), clamped to `[0, 1]`;
//! EXR stores linear `f32`. With a mask, both carry an alpha channel (1 object, 0 not).

pub mod relight;
pub mod views;
pub mod wavelet;

pub use crate::observe::raster::{
    interpolate_scalar, rasterize, rasterize_projected, shade_vertices, Raster,
};

use std::path::Path;

use rayon::prelude::*;

use nalgebra::Matrix3;

use crate::import::colmap::{Camera, Image};
use crate::import::mesh::Mesh;
use crate::render::wavelet::{RadianceScratch, VertexView, WaveletRenderer};
use crate::sphere::envmap::OctEnv;
use crate::sphere::rotation::LocalRotation;
use crate::transport::brdf::BasisBrdf;
use crate::transport::visibility::Visibility;
use crate::{Error, Result, Vec3};

/// The exact sRGB transfer curve ([`crate::import::photo::linear_to_srgb`]), with non-finite values
/// encoded as 0.
pub fn srgb_encode(v: f32) -> f32 {
    crate::import::photo::linear_to_srgb(if v.is_finite() { v } else { 0.0 })
}

fn check_size(path: &Path, width: u32, height: u32, n: usize, mask: Option<&[bool]>) -> Result<()> {
    let want = width as usize * height as usize;
    if n != want || mask.is_some_and(|m| m.len() != want) || want == 0 {
        return Err(Error::Image {
            path: path.to_path_buf(),
            message: format!(
                "image {width}x{height} needs {want} pixels, got {n} values and {} mask entries",
                mask.map_or(want, |m| m.len())
            ),
        });
    }
    Ok(())
}

/// Write linear RGB as an 8-bit sRGB PNG, scaled by `exposure` (a linear factor, 1 = as is)
/// before encoding. With a mask, the PNG is RGBA and pixels outside it are transparent.
pub fn write_png(
    path: &Path,
    width: u32,
    height: u32,
    rgb_linear: &[[f32; 3]],
    mask: Option<&[bool]>,
    exposure: f32,
) -> Result<()> {
    check_size(path, width, height, rgb_linear.len(), mask)?;
    let enc = |v: f32| (srgb_encode(v * exposure) * 255.0 + 0.5) as u8;
    let err = |e: image::ImageError| Error::Image {
        path: path.to_path_buf(),
        message: e.to_string(),
    };
    match mask {
        Some(m) => {
            let buf: Vec<u8> = rgb_linear
                .iter()
                .zip(m)
                .flat_map(|(p, &inside)| {
                    [
                        enc(p[0]),
                        enc(p[1]),
                        enc(p[2]),
                        if inside { 255 } else { 0 },
                    ]
                })
                .collect();
            image::save_buffer(path, &buf, width, height, image::ColorType::Rgba8).map_err(err)
        }
        None => {
            let buf: Vec<u8> = rgb_linear
                .iter()
                .flat_map(|p| [enc(p[0]), enc(p[1]), enc(p[2])])
                .collect();
            image::save_buffer(path, &buf, width, height, image::ColorType::Rgb8).map_err(err)
        }
    }
}

/// Write linear RGB as a 32-bit float EXR; with a mask, an alpha channel (1 object, 0 not).
pub fn write_exr(
    path: &Path,
    width: u32,
    height: u32,
    rgb_linear: &[[f32; 3]],
    mask: Option<&[bool]>,
) -> Result<()> {
    check_size(path, width, height, rgb_linear.len(), mask)?;
    let w = width as usize;
    let err = |e: exr::error::Error| Error::Image {
        path: path.to_path_buf(),
        message: e.to_string(),
    };
    match mask {
        Some(m) => crate::out_dir::exr::write_rgba(path, w, height as usize, |x, y| {
            let p = rgb_linear[y * w + x];
            (p[0], p[1], p[2], if m[y * w + x] { 1.0f32 } else { 0.0 })
        })
        .map_err(err),
        None => crate::out_dir::exr::write_rgb(path, w, height as usize, |x, y| {
            let p = rgb_linear[y * w + x];
            (p[0], p[1], p[2])
        })
        .map_err(err),
    }
}

/// Unit directions from each vertex toward the camera centre of `image` (world frame).
pub fn view_directions(mesh: &Mesh, image: &Image) -> Vec<Vec3> {
    let c = image.center();
    mesh.positions
        .par_iter()
        .map(|p| unit_toward(&c, p))
        .collect()
}

/// The wavelet renderer's image of one view (the hook for comparing with the independent
/// reference renderer): per-vertex radiance [`WaveletRenderer::vertex_radiance`] toward the
/// camera centre, for vertices of visible faces only, interpolated across the triangles.
/// When more vertices are visible than the rotation has frames, the light is rotated once
/// per frame and blended per vertex ([`WaveletRenderer::with_frames`]).
/// Returns the raster (for the mask) and linear RGB.
pub fn render_wavelet<R: LocalRotation>(
    model: &WaveletModel,
    env: &OctEnv,
    rot: &R,
    camera: &Camera,
    image: &Image,
) -> Result<(Raster, Vec<[f32; 3]>)> {
    let raster = rasterize(model.mesh, camera, image);
    let mut rgb = shade_wavelet(model, &raster, image, &[env], rot)?;
    Ok((raster, rgb.pop().unwrap_or_default()))
}

/// What the wavelet renderer draws: the mesh, its normals in the environment frame, the
/// visibility rows, the environment frame, and the reflectance (`B` RGB weights per vertex,
/// vertex-major).
#[derive(Clone, Copy)]
pub struct WaveletModel<'a> {
    /// The mesh.
    pub mesh: &'a Mesh,
    /// Unit vertex normals in the environment frame.
    pub normals_env: &'a [Vec3],
    /// Per-vertex visibility rows at the rotation's local resolution.
    pub vis: &'a Visibility,
    /// Rows `e_x, e_y, e_z` of the environment frame in world coordinates.
    pub env_from_world: &'a Matrix3<f64>,
    /// Basis BRDFs.
    pub basis: &'a [BasisBrdf],
    /// Per-vertex, per-basis RGB weights `β`.
    pub beta: &'a [[f64; 3]],
}

/// Shade `raster` (a view of `image`) under each light of `envs`: one linear RGB image per
/// light, in order. The per-vertex work that does not depend on the light (frame,
/// `V ⊙ Δω`, BRDF slices) is done once for all lights
/// ([`WaveletRenderer::vertex_radiance_all`]); each image equals what
/// [`render_wavelet`] makes for that light alone, bit for bit.
pub fn shade_wavelet<R: LocalRotation>(
    model: &WaveletModel,
    raster: &Raster,
    image: &Image,
    envs: &[&OctEnv],
    rot: &R,
) -> Result<Vec<Vec<[f32; 3]>>> {
    shade_wavelet_given(model, raster, image, envs, rot, None)
}

/// One view for [`shade_views`]: its raster, its image (the camera's pose) and the lights
/// to shade it under.
pub struct ViewToShade<'a> {
    /// The view's raster.
    pub raster: &'a Raster,
    /// The view's image (its camera centre gives the outgoing directions).
    pub image: &'a Image,
    /// The lights, in the order of the returned images.
    pub envs: Vec<&'a OctEnv>,
}

/// Every view's lights in one list, and the range of each view's in it.
struct LightSlots<'a> {
    ranges: Vec<std::ops::Range<usize>>,
    envs: Vec<&'a OctEnv>,
}

impl<'a> LightSlots<'a> {
    fn new(views: &[ViewToShade<'a>]) -> Self {
        let mut ranges = Vec::with_capacity(views.len());
        let mut envs = Vec::new();
        for v in views {
            ranges.push(envs.len()..envs.len() + v.envs.len());
            envs.extend(v.envs.iter().copied());
        }
        LightSlots { ranges, envs }
    }
}

/// [`shade_wavelet`] of several views at once ([`ShadedViews::images`]`(i, …)[l]` is view
/// `i` under its light `l`). Vertex-major: a vertex that several views need is rotated into its frame once for
/// every light of all of them (with a per-normal rotation such as
/// [`crate::sphere::rotation::SplatRotation`], one walk of its footprint instead of one
/// per view), its frame and `V ⊙ Δω` once; the BRDF slices once per view. With a
/// rotation without precomputed frames every image equals [`shade_wavelet`] of that view
/// alone bit for bit; with precomputed frames they are used as soon as more vertex renders
/// than frames are asked for in all (per view in [`shade_wavelet`]), equal up to rounding.
pub fn shade_views<R: LocalRotation>(
    model: &WaveletModel,
    views: &[ViewToShade],
    rot: &R,
) -> Result<ShadedViews> {
    check_model(model)?;
    let needed: Vec<Vec<bool>> = views
        .iter()
        .map(|v| needed_vertices(model.mesh, v.raster))
        .collect();
    let slots = LightSlots::new(views);
    if slots.envs.is_empty() {
        return Ok(ShadedViews {
            radiance: Vec::new(),
            ranges: slots.ranges,
            n_lights: 0,
        });
    }
    let renders: usize = needed
        .iter()
        .map(|n| n.iter().filter(|&&b| b).count())
        .sum();
    let mut renderer = WaveletRenderer::new_many(rot, model.basis, &slots.envs)?;
    if renders > rot.n_frames() {
        renderer = renderer.with_frames();
    }
    let views_needed = ViewsNeeded {
        centres: views.iter().map(|v| v.image.center()).collect(),
        needed,
        slots: &slots,
    };
    let radiance = vertex_major_radiance(model, &renderer, &views_needed);
    Ok(ShadedViews {
        radiance,
        n_lights: slots.envs.len(),
        ranges: slots.ranges,
    })
}

/// Which vertices each view needs, where its camera is, and its lights' slots.
struct ViewsNeeded<'a> {
    centres: Vec<Vec3>,
    needed: Vec<Vec<bool>>,
    slots: &'a LightSlots<'a>,
}

/// The radiance of every vertex toward every view that needs it, under each of that view's
/// lights: one slot per light of all views, for each vertex ([`ShadedViews`]'s layout), 0
/// where no view needs it. Vertex-major, one scratch per thread.
fn vertex_major_radiance<R: LocalRotation>(
    model: &WaveletModel,
    renderer: &WaveletRenderer<R>,
    v: &ViewsNeeded,
) -> Vec<[f32; 3]> {
    let nl = v.slots.envs.len();
    let (mesh, beta) = (model.mesh, model.beta);
    let (nv, nb) = (mesh.positions.len(), model.basis.len());
    let mut radiance = vec![[0.0f32; 3]; nv * nl];
    radiance.par_chunks_mut(nl).enumerate().for_each_init(
        || {
            let scratch = RadianceScratch::default();
            (scratch, Vec::<VertexView>::new(), vec![[0.0f64; 3]; nl])
        },
        |(scratch, seen, out), (x, rad)| {
            seen.clear();
            for (i, c) in v.centres.iter().enumerate() {
                if v.needed[i][x] {
                    seen.push(VertexView {
                        wo_env: model.env_from_world * unit_toward(c, &mesh.positions[x]),
                        lights: v.slots.ranges[i].clone(),
                    });
                }
            }
            if seen.is_empty() {
                return;
            }
            let n: usize = seen.iter().map(|v| v.lights.len()).sum();
            let beta_x = &beta[x * nb..(x + 1) * nb];
            renderer.vertex_radiance_views(
                scratch,
                &model.normals_env[x],
                model.vis.vertex(x),
                beta_x,
                seen,
                &mut out[..n],
            );
            let slots = seen.iter().flat_map(|v| v.lights.clone());
            for (l, o) in slots.zip(out.iter()) {
                rad[l] = [o[0] as f32, o[1] as f32, o[2] as f32];
            }
        },
    );
    radiance
}

/// The per-vertex radiance [`shade_views`] computed: images on demand, so that a caller
/// holds one view's images at a time.
pub struct ShadedViews {
    /// Vertex-major: `n_lights` radiances per vertex (zero where no view needs it).
    radiance: Vec<[f32; 3]>,
    /// Per view, its lights' slots among the `n_lights`.
    ranges: Vec<std::ops::Range<usize>>,
    n_lights: usize,
}

impl ShadedViews {
    /// View `i`'s images, one per light in its order: the radiance interpolated across
    /// `raster` (the view's raster given to [`shade_views`]).
    pub fn images(&self, i: usize, raster: &Raster, mesh: &Mesh) -> Vec<Vec<[f32; 3]>> {
        let nl = self.n_lights;
        self.ranges[i]
            .clone()
            .map(|l| {
                let per_light: Vec<[f32; 3]> =
                    self.radiance.iter().skip(l).step_by(nl).copied().collect();
                shade_vertices(raster, mesh, &per_light)
            })
            .collect()
    }
}

/// The unit direction from `p` toward `c` (zero when they coincide), as
/// [`view_directions`] computes it.
fn unit_toward(c: &Vec3, p: &Vec3) -> Vec3 {
    let d = c - p;
    let n = d.norm();
    if n > 0.0 {
        d / n
    } else {
        Vec3::zeros()
    }
}

/// The vertices of the faces `raster` shows.
fn needed_vertices(mesh: &Mesh, raster: &Raster) -> Vec<bool> {
    let mut needed = vec![false; mesh.positions.len()];
    for &f in raster.face.iter().filter(|&&f| f != u32::MAX) {
        for &k in &mesh.faces[f as usize] {
            needed[k as usize] = true;
        }
    }
    needed
}

/// The model's arrays agree in their vertex and basis counts.
fn check_model(model: &WaveletModel) -> Result<()> {
    let nv = model.mesh.positions.len();
    let nb = model.basis.len();
    if model.normals_env.len() != nv || model.beta.len() != nv * nb || model.vis.open.len() != nv {
        return Err(Error::Internal(format!(
            "render: {nv} vertices but {} normals, {} visibility rows and {} β entries \
             ({nb} per vertex expected)",
            model.normals_env.len(),
            model.vis.open.len(),
            model.beta.len()
        )));
    }
    Ok(())
}

/// [`shade_wavelet`] under one light with the radiance of some vertices given:
/// `given[x] = Some(rgb)` is used as vertex `x`'s radiance, and only the other vertices the
/// raster needs are rendered. A run's training renders pass the estimator's own predictions
/// at the photo's observations (the model as fitted, through its kept transport rows), so
/// the renderer only fills in the visible vertices that were not observed (grazing, on a
/// depth discontinuity). `given` has one entry per vertex.
pub fn shade_wavelet_known<R: LocalRotation>(
    model: &WaveletModel,
    raster: &Raster,
    image: &Image,
    env: &OctEnv,
    rot: &R,
    given: &[Option<[f32; 3]>],
) -> Result<Vec<[f32; 3]>> {
    let mut rgb = shade_wavelet_given(model, raster, image, &[env], rot, Some(given))?;
    Ok(rgb.pop().unwrap_or_default())
}

/// [`shade_wavelet`], with `given` radiance (one light only) as [`shade_wavelet_known`].
fn shade_wavelet_given<R: LocalRotation>(
    model: &WaveletModel,
    raster: &Raster,
    image: &Image,
    envs: &[&OctEnv],
    rot: &R,
    given: Option<&[Option<[f32; 3]>]>,
) -> Result<Vec<Vec<[f32; 3]>>> {
    let WaveletModel {
        mesh,
        normals_env,
        vis,
        env_from_world,
        basis,
        beta,
    } = *model;
    check_model(model)?;
    let nv = mesh.positions.len();
    let nb = basis.len();
    let needed = needed_vertices(mesh, raster);
    if let Some(given) = given {
        if given.len() != nv || envs.len() != 1 {
            return Err(Error::Internal(format!(
                "render: {} given radiances for {nv} vertices under {} lights (one light)",
                given.len(),
                envs.len()
            )));
        }
    }
    let is_given = |x: usize| given.is_some_and(|g| g[x].is_some());
    // Rotating the light once per precomputed frame costs about as much as rotating it for
    // one vertex per frame: worth it as soon as more vertices than frames are rendered.
    let n_needed = (0..nv).filter(|&x| needed[x] && !is_given(x)).count();
    let mut renderer = WaveletRenderer::new_many(rot, basis, envs)?;
    if n_needed > rot.n_frames() {
        renderer = renderer.with_frames();
    }
    let nl = envs.len();
    let dirs = view_directions(mesh, image);
    // Vertex-major: `nl` radiances per vertex; one scratch per thread.
    let mut radiance = vec![[0.0f32; 3]; nv * nl];
    radiance.par_chunks_mut(nl).enumerate().for_each_init(
        || (RadianceScratch::default(), vec![[0.0f64; 3]; nl]),
        |(scratch, out), (x, rad)| {
            if !needed[x] {
                return;
            }
            if let Some(rgb) = given.and_then(|g| g[x]) {
                rad[0] = rgb;
                return;
            }
            let wo = env_from_world * dirs[x];
            renderer.vertex_radiance_all(
                scratch,
                &normals_env[x],
                vis.vertex(x),
                &wo,
                &beta[x * nb..(x + 1) * nb],
                out,
            );
            for (r, o) in rad.iter_mut().zip(out.iter()) {
                *r = [o[0] as f32, o[1] as f32, o[2] as f32];
            }
        },
    );
    Ok((0..nl)
        .map(|l| {
            let per_light: Vec<[f32; 3]> = (0..nv).map(|x| radiance[x * nl + l]).collect();
            shade_vertices(raster, mesh, &per_light)
        })
        .collect())
}
