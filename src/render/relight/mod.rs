//! Relighting a finished run (`relight-cpc render`): the recovered object under any
//! environment map, from any COLMAP camera.
//!
//! The exit radiance toward a camera at vertex `x` is paper Eq. 5 with the recovered
//! reflectance of Eq. 11, `ρ(x) = Σ_b β_b(x) ρ_b`, `β_b(x) = Σ_k w_k(x) λ[k][b]`:
//!
//! `B_c(x, ω_o) = Σ_b β_{b,c}(x) ∫_Ω ρ_b(ω, ω_o) V_x(ω) L_c(R_x ω) dω`,
//!
//! evaluated untruncated by [`WaveletRenderer::vertex_radiance`](crate::render::wavelet::WaveletRenderer::vertex_radiance) (the light rotated into the
//! vertex's own local frame by [`SplatRotation`], `R_n = W_l S_n W_gᵀ` for the exact normal
//! instead of the Eq. 6 blend of precomputed frames, then the local triple product of
//! Eq. 7–8 as a texel sum at the run's render local resolution), and interpolated across
//! the rasterised triangles. The light is a lat-long map (docs/conventions.md) in the run's environment frame
//! (`materials.json` → `env_frame`), optionally plus a sun: a disc of radius 1° and given
//! radiance whose solid angle `2π(1 − cos 1°)` is preserved exactly on the lat-long grid.
//!
//! `run` leaves in its result folder what this needs (written by `write_render_state`):
//! `model/cameras.txt` + `model/images.txt` (the registered views, COLMAP text, no 2D
//! points), `relight.json` (basis labels, resolutions, frame, visibility parameters) and
//! `relight.bin` (little-endian: positions, environment-frame normals, faces, `β`, and the
//! per-vertex visibility rows at the render local resolution, `render_local_resolution` in
//! `relight.json`, stored rather than re-traced: one byte per texel). Results written
//! before that key existed hold their rows at `local_resolution`.

use crate::import::colmap::{text, Camera, CameraId, Image, ImageId};
use crate::import::mesh::Mesh;
use crate::import::scene::View;
use crate::render::views::{self, Background};
use crate::render::{self, Raster};
use crate::sphere::envmap::{LatLong, OctEnv};
use crate::sphere::rotation::LocalRotation;
use crate::sphere::rotation::SplatRotation;
use crate::transport::brdf::BasisBrdf;
use crate::transport::visibility::Visibility;
use crate::{Error, Result, Vec3};
use nalgebra::Matrix3;
use std::collections::BTreeMap;
use std::io::{BufReader, BufWriter, Write};
use std::path::{Path, PathBuf};

mod load;

pub use load::{load_result, ResultModel};

mod write;

pub use write::{write_render_state, RenderState};

/// Magic bytes opening `relight.bin`.
const MAGIC: &[u8; 8] = b"RCPCREL1";

/// The sun's angular radius (degrees).
pub const SUN_RADIUS_DEG: f64 = 1.0;

/// A directional light added to the map: a disc of `radiance` (RGB, linear) around unit
/// direction `dir` (environment frame), radius [`SUN_RADIUS_DEG`].
#[derive(Debug, Clone, Copy)]
pub struct Sun {
    /// Direction toward the sun, environment frame (normalised on use).
    pub dir: Vec3,
    /// Radiance inside the disc.
    pub radiance: [f64; 3],
}

/// Which cameras to render.
#[derive(Debug, Clone)]
pub enum CameraSelection {
    /// Every registered camera of the run.
    AllRegistered,
    /// One registered camera, by image name.
    Named(String),
    /// Every image of a folder holding COLMAP text `cameras.txt` and `images.txt`.
    Folder(PathBuf),
}

/// Options of [`render_result`].
#[derive(Debug, Clone)]
pub struct RenderOptions {
    /// Lat-long EXR environment map (environment frame of the run); `None`: black (then a
    /// sun is required).
    pub env: Option<PathBuf>,
    /// Optional sun.
    pub sun: Option<Sun>,
    /// The cameras.
    pub cameras: CameraSelection,
    /// Output folder, claimed under [`crate::out_dir`]'s contract.
    pub out: PathBuf,
    /// Replace a previous result in `out`.
    pub force: bool,
    /// Linear factor applied before sRGB encoding of the PNG (the EXR stays unscaled).
    pub exposure: f64,
    /// Output width in pixels (height keeps the aspect); `None`: the camera's size.
    pub resolution: Option<u32>,
    /// Turn the map by this many degrees about the environment's up axis `e_z` (what was at
    /// azimuth `φ` moves to `φ + DEG`; a sun stays where given).
    pub rotate_deg: f64,
    /// Render this many turntable frames per camera ([`crate::render::views`]).
    pub turntable: Option<usize>,
    /// What fills the pixels the object does not cover.
    pub background: Background,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            env: None,
            sun: None,
            cameras: CameraSelection::AllRegistered,
            out: PathBuf::from("renders"),
            exposure: 1.0,
            resolution: None,
            rotate_deg: 0.0,
            turntable: None,
            background: Background::Transparent,
            force: false,
        }
    }
}

/// One rendered view.
#[derive(Debug, Clone)]
pub struct RenderedFile {
    /// The image name (from images.txt).
    pub name: String,
    /// Linear RGBA EXR (alpha = object mask).
    pub exr: PathBuf,
    /// sRGB RGBA PNG.
    pub png: PathBuf,
    /// The object mask as an 8-bit grey PNG.
    pub mask: PathBuf,
    /// Object pixels.
    pub covered: usize,
}

/// What [`render_result`] wrote.
#[derive(Debug, Clone)]
pub struct RenderSummary {
    /// The views, in images.txt order (by id).
    pub views: Vec<RenderedFile>,
    /// Wall-clock seconds for loading the result (incl. the rotation matrices).
    pub load_seconds: f64,
    /// Wall-clock seconds for rendering all views.
    pub render_seconds: f64,
    /// Turntable animations written (GIF always, MP4 when ffmpeg is present).
    pub animations: Vec<PathBuf>,
}

// ---------------------------------------------------------------------------------------
// Light.

/// Add a sun disc to a lat-long map: pixels whose centre lies within [`SUN_RADIUS_DEG`] of
/// `sun.dir` get `radiance · Ω_disc / Σ Ω_pixels` so the disc's energy `radiance · Ω_disc`,
/// `Ω_disc = 2π(1 − cos r)`, is exact on any grid; when no pixel centre falls inside (coarse
/// maps), the pixel holding the direction takes all of it.
pub fn add_sun(ll: &mut LatLong, sun: &Sun) -> Result<()> {
    let n = sun.dir.norm();
    if !(n.is_finite() && n > 0.0) || sun.radiance.iter().any(|r| !r.is_finite() || *r < 0.0) {
        return Err(Error::Config(
            "sun: the direction must be non-zero and the radiance finite and ≥ 0".into(),
        ));
    }
    let d = sun.dir / n;
    let cos_r = SUN_RADIUS_DEG.to_radians().cos();
    let omega = 2.0 * std::f64::consts::PI * (1.0 - cos_r);
    let mut inside = Vec::new();
    let mut area = 0.0;
    for v in 0..ll.height {
        for u in 0..ll.width {
            if ll.dir(u, v).dot(&d) >= cos_r {
                inside.push(v * ll.width + u);
                area += ll.solid_angle(v);
            }
        }
    }
    if inside.is_empty() {
        let (u, v) = ll.pixel_of(&d);
        inside.push(v * ll.width + u);
        area = ll.solid_angle(v);
    }
    let s = omega / area;
    for i in inside {
        for c in 0..3 {
            ll.rgb[i][c] += (sun.radiance[c] * s) as f32;
        }
    }
    Ok(())
}

/// The light of `opts` on the run's `n_global² ` octahedral grid.
pub fn load_light(opts: &RenderOptions, n_global: usize) -> Result<OctEnv> {
    Ok(OctEnv::from_latlong(&load_light_latlong(opts)?, n_global))
}

/// The light of `opts` as a lat-long map: the map (`.exr` or `.hdr`) turned by
/// `opts.rotate_deg`, plus the sun.
pub fn load_light_latlong(opts: &RenderOptions) -> Result<LatLong> {
    if !opts.rotate_deg.is_finite() {
        return Err(Error::Config(
            "render: --rotate must be a finite angle".into(),
        ));
    }
    let mut ll = match &opts.env {
        Some(p) => LatLong::read_any(p)?
            .0
            .rotated_about_up(opts.rotate_deg.to_radians()),
        None if opts.sun.is_some() => LatLong::black(512),
        None => {
            return Err(Error::Config(
                "render: give an environment map (--env) or a sun (--sun)".into(),
            ))
        }
    };
    if let Some(sun) = &opts.sun {
        add_sun(&mut ll, sun)?;
    }
    Ok(ll)
}

// ---------------------------------------------------------------------------------------
// Rendering.

/// The renderer's rotation for `model` ([`SplatRotation`] at its global side and the
/// stored visibility's local side, default sub-texels).
pub fn render_rotation(model: &ResultModel) -> SplatRotation {
    SplatRotation::with_default_supersample(model.n_global, model.vis.n_local)
}

/// Render the model under `light` from one camera: rasterise, evaluate the per-vertex exit
/// radiance toward the camera centre for vertices of visible faces, interpolate. `rot`
/// must rotate from the light's side to the stored visibility's ([`render_rotation`]).
pub fn render_view<R: LocalRotation>(
    model: &ResultModel,
    rot: &R,
    light: &OctEnv,
    camera: &Camera,
    image: &Image,
) -> Result<(Raster, Vec<[f32; 3]>)> {
    let wm = render::WaveletModel {
        mesh: &model.mesh,
        normals_env: &model.normals_env,
        vis: &model.vis,
        env_from_world: &model.env_from_world,
        basis: &model.basis,
        beta: &model.beta,
    };
    render::render_wavelet(&wm, light, rot, camera, image)
}

/// The (camera, image) pairs `sel` names.
fn select_cameras(model: &ResultModel, sel: &CameraSelection) -> Result<Vec<(Camera, Image)>> {
    let pairs = |cams: &BTreeMap<CameraId, Camera>,
                 ims: &BTreeMap<ImageId, Image>,
                 path: &Path|
     -> Result<Vec<(Camera, Image)>> {
        ims.values()
            .map(|im| {
                cams.get(&im.camera_id)
                    .map(|c| (c.clone(), im.clone()))
                    .ok_or_else(|| {
                        Error::format(
                            path,
                            format!("image {}", im.name),
                            format!("camera {} is not in cameras.txt", im.camera_id.0),
                        )
                    })
            })
            .collect()
    };
    match sel {
        CameraSelection::AllRegistered => {
            pairs(&model.cameras, &model.images, Path::new("model/images.txt"))
        }
        CameraSelection::Named(name) => {
            let all = pairs(&model.cameras, &model.images, Path::new("model/images.txt"))?;
            let known: Vec<&str> = all.iter().map(|(_, i)| i.name.as_str()).collect();
            let hit = all.iter().find(|(_, i)| &i.name == name).cloned();
            hit.map(|p| vec![p]).ok_or_else(|| {
                Error::Config(format!(
                    "render: no registered camera named `{name}`; the run has: {}",
                    known.join(", ")
                ))
            })
        }
        CameraSelection::Folder(dir) => {
            let cp = dir.join("cameras.txt");
            let ip = dir.join("images.txt");
            let open = |p: &Path| -> Result<BufReader<std::fs::File>> {
                std::fs::File::open(p)
                    .map(BufReader::new)
                    .map_err(|e| Error::io(p, e))
            };
            let cams = text::read_cameras(open(&cp)?, &cp)?;
            let ims = text::read_images(open(&ip)?, &ip)?;
            if ims.is_empty() {
                return Err(Error::format(&ip, "images", "no image in the file"));
            }
            pairs(&cams, &ims, &ip)
        }
    }
}

/// Relight the result in `result_dir` as `opts` asks: per camera (and turntable frame)
/// `STEM.exr` (linear RGBA, alpha = mask), `STEM.png` (sRGB at `opts.exposure`, RGBA when
/// the background is transparent) and `STEM.mask.png`; `STEM` names the light and the
/// camera ([`views::output_stem`]). Turntables also get `LIGHT__CAMERA_turntable.gif`
/// and, with ffmpeg, `.mp4`.
pub fn render_result(result_dir: &Path, opts: &RenderOptions) -> Result<RenderSummary> {
    check_options(opts)?;
    let mut inputs = vec![result_dir];
    inputs.extend(opts.env.as_deref());
    if let CameraSelection::Folder(d) = &opts.cameras {
        inputs.push(d);
    }
    let claim = crate::out_dir::OutDir::claim(&opts.out, opts.force, &inputs, "render")?;
    let t0 = std::time::Instant::now();
    let model = load_result(result_dir)?;
    let views = select_cameras(&model, &opts.cameras)?;
    let light_ll = load_light_latlong(opts)?;
    let light = OctEnv::from_latlong(&light_ll, model.n_global);
    let rot = render_rotation(&model);
    let load_seconds = t0.elapsed().as_secs_f64();
    let t1 = std::time::Instant::now();
    let dir = claim.path();
    let light_name = views::light_name(opts.env.as_deref(), opts.sun.is_some(), opts.rotate_deg);
    let up = model.env_from_world.row(2).transpose();
    let centre = mesh_centre(&model.mesh);
    let view = ViewLight {
        model: &model,
        rot: &rot,
        light: &light,
        light_ll: &light_ll,
    };
    let mut out = Vec::with_capacity(views.len());
    let mut animations = Vec::new();
    for (camera, image) in &views {
        let camera = at_resolution(camera, opts.resolution);
        let frames: Vec<(Option<usize>, Image)> = match opts.turntable {
            Some(n) => (0..n)
                .map(|i| Ok((Some(i), views::orbit(image, &up, &centre, i, n)?)))
                .collect::<Result<_>>()?,
            None => vec![(None, image.clone())],
        };
        let mut pngs = Vec::new();
        for (frame, pose) in &frames {
            let stem = views::output_stem(&light_name, &image.name, *frame);
            let (file, png) = render_one(&view, opts, dir, &camera, pose, &stem)?;
            pngs.extend(png);
            out.push(file);
        }
        if opts.turntable.is_some() {
            let prefix = views::output_stem(&light_name, &image.name, None);
            animations.extend(write_turntable(dir, &opts.out, &prefix, &pngs)?);
        }
    }
    claim.commit()?;
    Ok(RenderSummary {
        views: out,
        load_seconds,
        render_seconds: t1.elapsed().as_secs_f64(),
        animations,
    })
}

/// The options' checks that need no file: a positive exposure, resolution and frame count.
fn check_options(opts: &RenderOptions) -> Result<()> {
    if !(opts.exposure.is_finite() && opts.exposure > 0.0) {
        return Err(Error::Config("render: --exposure must be > 0".into()));
    }
    if opts.resolution == Some(0) {
        return Err(Error::Config("render: --resolution must be > 0".into()));
    }
    if opts.turntable == Some(0) {
        return Err(Error::Config(
            "render: --turntable must be at least 1 frame".into(),
        ));
    }
    Ok(())
}

/// `camera` rescaled to `width` pixels across (its aspect kept, at least 1 pixel high), or
/// as it is without a width.
fn at_resolution(camera: &Camera, width: Option<u32>) -> Camera {
    match width {
        Some(w) => {
            let h = ((w as f64 * camera.height as f64 / camera.width as f64).round() as u32).max(1);
            camera.rescaled(w, h)
        }
        None => camera.clone(),
    }
}

/// A turntable's frames as `PREFIX_turntable.gif` in `dir`, and `.mp4` when ffmpeg
/// is there; the files' paths under `out` (the folder the user named).
fn write_turntable(
    dir: &Path,
    out: &Path,
    prefix: &str,
    frames: &[image::RgbaImage],
) -> Result<Vec<PathBuf>> {
    let mut written = Vec::new();
    let gif = format!("{prefix}_turntable.gif");
    views::write_gif(&dir.join(&gif), frames, 12)?;
    written.push(out.join(gif));
    let mp4 = format!("{prefix}_turntable.mp4");
    if views::write_video(dir, prefix, &dir.join(&mp4), 12)? {
        written.push(out.join(mp4));
    }
    Ok(written)
}

/// The centre of the mesh's bounding box (the turntable's pivot).
fn mesh_centre(mesh: &Mesh) -> Vec3 {
    let mut lo = Vec3::repeat(f64::INFINITY);
    let mut hi = Vec3::repeat(f64::NEG_INFINITY);
    for p in &mesh.positions {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    if lo.x.is_finite() {
        (lo + hi) / 2.0
    } else {
        Vec3::zeros()
    }
}

/// The model and the light one view is rendered with.
struct ViewLight<'a> {
    model: &'a ResultModel,
    rot: &'a SplatRotation,
    light: &'a OctEnv,
    light_ll: &'a LatLong,
}

/// Render and write one view as `STEM.{exr,png,mask.png}`; returns the file record and the
/// PNG's pixels when a turntable animation needs them.
fn render_one(
    view: &ViewLight,
    opts: &RenderOptions,
    dir: &Path,
    camera: &Camera,
    image: &Image,
    stem: &str,
) -> Result<(RenderedFile, Option<image::RgbaImage>)> {
    let (raster, mut rgb) = render_view(view.model, view.rot, view.light, camera, image)?;
    let mask = raster.mask();
    let (w, h) = (camera.width, camera.height);
    let exr = dir.join(format!("{stem}.exr"));
    let png = dir.join(format!("{stem}.png"));
    let mp = dir.join(format!("{stem}.mask.png"));
    let alpha = views::fill_background(
        &mut rgb,
        &mask,
        opts.background,
        (camera, image),
        view.light_ll,
        &view.model.env_from_world,
    );
    render::write_exr(&exr, w, h, &rgb, Some(&mask))?;
    let png_mask = alpha.then_some(mask.as_slice());
    render::write_png(&png, w, h, &rgb, png_mask, opts.exposure as f32)?;
    let grey: Vec<u8> = mask.iter().map(|&m| if m { 255 } else { 0 }).collect();
    image::save_buffer(&mp, &grey, w, h, image::ColorType::L8).map_err(|e| Error::Image {
        path: mp.clone(),
        message: e.to_string(),
    })?;
    let pixels = match opts.turntable {
        Some(_) => Some(
            image::open(&png)
                .map_err(|e| Error::Image {
                    path: png.clone(),
                    message: e.to_string(),
                })?
                .into_rgba8(),
        ),
        None => None,
    };
    Ok((
        // Where the files will be once the output folder is committed.
        RenderedFile {
            name: image.name.clone(),
            exr: opts.out.join(exr.file_name().unwrap_or_default()),
            png: opts.out.join(png.file_name().unwrap_or_default()),
            mask: opts.out.join(mp.file_name().unwrap_or_default()),
            covered: raster.covered(),
        },
        pixels,
    ))
}

#[cfg(test)]
mod tests;
