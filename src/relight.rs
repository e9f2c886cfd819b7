//! Relighting a finished run (`relight-cpc render`): the recovered object under any
//! environment map, from any COLMAP camera.
//!
//! The exit radiance toward a camera at vertex `x` is paper Eq. 5 with the recovered
//! reflectance of Eq. 11, `ρ(x) = Σ_b β_b(x) ρ_b`, `β_b(x) = Σ_k w_k(x) λ[k][b]`:
//!
//! `B_c(x, ω_o) = Σ_b β_{b,c}(x) ∫_Ω ρ_b(ω, ω_o) V_x(ω) L_c(R_x ω) dω`,
//!
//! evaluated untruncated by [`WaveletRenderer::vertex_radiance`](crate::transport::WaveletRenderer::vertex_radiance) (the light rotated into the
//! vertex's own local frame by [`SplatRotation`], `R_n = W_l S_n W_gᵀ` for the exact normal
//! instead of the Eq. 6 blend of precomputed frames, then the local triple product of
//! Eq. 7–8 as a texel sum at the run's render local resolution), and interpolated across
//! the rasterised triangles. The light is a lat-long map (DESIGN §3) in the run's environment frame
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

use crate::brdf::BasisBrdf;
use crate::colmap::{text, Camera, CameraId, Image, ImageId};
use crate::envmap::{LatLong, OctEnv};
use crate::mesh::Mesh;
use crate::render::views::{self, Background};
use crate::render::{self, Raster};
use crate::rotation::SplatRotation;
use crate::transport::LocalRotation;
use crate::visibility::Visibility;
use crate::{Error, Result, Vec3};
use nalgebra::Matrix3;
use std::collections::BTreeMap;
use std::io::{BufReader, BufWriter, Write};
use std::path::{Path, PathBuf};

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

/// Everything a result folder holds for rendering.
pub struct ResultModel {
    /// The cleaned mesh the run used (positions, world normals, faces).
    pub mesh: Mesh,
    /// Unit vertex normals in the environment frame.
    pub normals_env: Vec<Vec3>,
    /// Per-vertex visibility at the render local resolution (as the run computed it).
    pub vis: Visibility,
    /// The basis BRDFs.
    pub basis: Vec<BasisBrdf>,
    /// `β`: `B` RGB weights per vertex, vertex-major.
    pub beta: Vec<[f64; 3]>,
    /// Rows `e_x, e_y, e_z` in world coordinates.
    pub env_from_world: Matrix3<f64>,
    /// Global (light) octahedral side.
    pub n_global: usize,
    /// The estimator's local (hemisphere) side.
    pub n_local: usize,
    /// The renderer's local side: that of the stored visibility rows.
    pub n_render_local: usize,
    /// Normal grid side of the rotation.
    pub normal_grid: usize,
    /// The registered cameras.
    pub cameras: BTreeMap<CameraId, Camera>,
    /// The registered images.
    pub images: BTreeMap<ImageId, Image>,
}

// ---------------------------------------------------------------------------------------
// Writing (called by `run`).

fn put_f64s(w: &mut impl Write, v: impl Iterator<Item = f64>) -> std::io::Result<()> {
    for x in v {
        w.write_all(&x.to_le_bytes())?;
    }
    Ok(())
}

/// Write `model/`, `relight.json` and `relight.bin` for the fitted run (see module docs).
pub(crate) fn write_render_state(f: &crate::run::Fitted, dir: &Path) -> Result<()> {
    let model = dir.join("model");
    std::fs::create_dir_all(&model).map_err(|e| Error::io(&model, e))?;
    let mut cameras = BTreeMap::new();
    let mut images = BTreeMap::new();
    for v in &f.scene.views {
        cameras.insert(v.camera.id, v.camera.clone());
        let mut im = v.image.clone();
        im.points2d.clear();
        images.insert(im.id, im);
    }
    write_with(&model.join("cameras.txt"), |w| {
        text::write_cameras(w, &cameras)
    })?;
    write_with(&model.join("images.txt"), |w| {
        text::write_images(w, &images)
    })?;

    let m = f.env_from_world;
    let meta = serde_json::json!({
        "format": "relight.bin: magic RCPCREL1, u64 nv nf nb texels, f64 positions[nv][3], f64 normals_env[nv][3], u32 faces[nf][3], f64 beta[nv][nb][3], u8 vis[nv][texels], u8 open[nv] (little-endian)",
        "basis": f.basis.iter().map(|b| b.label()).collect::<Vec<_>>(),
        "global_resolution": f.opts.global_resolution,
        "local_resolution": f.opts.local_resolution,
        "render_local_resolution": f.render_vis.n_local,
        "normal_grid": f.opts.normal_grid,
        "rays_per_texel": f.render_vis.rays_per_texel,
        "seed": f.opts.seed,
        "env_from_world": [[m[(0,0)], m[(0,1)], m[(0,2)]], [m[(1,0)], m[(1,1)], m[(1,2)]], [m[(2,0)], m[(2,1)], m[(2,2)]]],
    });
    let text = serde_json::to_string_pretty(&meta).map_err(|e| Error::Config(e.to_string()))?;
    let jp = dir.join("relight.json");
    std::fs::write(&jp, text).map_err(|e| Error::io(&jp, e))?;

    let mesh = &f.scene.mesh;
    let nv = mesh.positions.len();
    let vis = &f.render_vis;
    let t = vis.texels();
    write_with(&dir.join("relight.bin"), |w| {
        w.write_all(MAGIC)?;
        for n in [nv, mesh.faces.len(), f.basis.len(), t] {
            w.write_all(&(n as u64).to_le_bytes())?;
        }
        put_f64s(w, mesh.positions.iter().flat_map(|p| [p.x, p.y, p.z]))?;
        put_f64s(w, f.normals_env.iter().flat_map(|p| [p.x, p.y, p.z]))?;
        for face in &mesh.faces {
            for i in face {
                w.write_all(&i.to_le_bytes())?;
            }
        }
        put_f64s(w, f.beta.iter().flat_map(|b| *b))?;
        w.write_all(&vis.frac)?;
        let open: Vec<u8> = vis.open.iter().map(|&o| o as u8).collect();
        w.write_all(&open)
    })
}

fn write_with(
    path: &Path,
    body: impl FnOnce(&mut BufWriter<std::fs::File>) -> std::io::Result<()>,
) -> Result<()> {
    let file = std::fs::File::create(path).map_err(|e| Error::io(path, e))?;
    let mut w = BufWriter::new(file);
    body(&mut w)
        .and_then(|_| w.flush())
        .map_err(|e| Error::io(path, e))
}

// ---------------------------------------------------------------------------------------
// Loading.

fn missing(dir: &Path, what: &str) -> Error {
    Error::Workspace {
        path: dir.to_path_buf(),
        message: format!("not a relight-cpc result folder: {what} (written by `relight-cpc run`)"),
    }
}

fn json_usize(path: &Path, v: &serde_json::Value, key: &str) -> Result<usize> {
    v.get(key)
        .and_then(|x| x.as_u64())
        .map(|x| x as usize)
        .ok_or_else(|| Error::format(path, key, "missing or not a non-negative integer"))
}

struct Cursor<'a> {
    path: &'a Path,
    data: &'a [u8],
    at: usize,
}

impl Cursor<'_> {
    fn take(&mut self, n: usize, what: &str) -> Result<&[u8]> {
        let end = self.at.checked_add(n).filter(|&e| e <= self.data.len());
        let Some(end) = end else {
            return Err(Error::format(
                self.path,
                what,
                format!(
                    "file ends at byte {} but {n} more bytes were expected",
                    self.data.len()
                ),
            ));
        };
        let s = &self.data[self.at..end];
        self.at = end;
        Ok(s)
    }
    fn u64(&mut self, what: &str) -> Result<u64> {
        let b = self.take(8, what)?;
        let mut a = [0u8; 8];
        a.copy_from_slice(b);
        Ok(u64::from_le_bytes(a))
    }
    fn f64s(&mut self, n: usize, what: &str) -> Result<Vec<f64>> {
        let bytes = n
            .checked_mul(8)
            .ok_or_else(|| Error::format(self.path, what, "count overflows"))?;
        let b = self.take(bytes, what)?;
        let v: Vec<f64> = b
            .chunks_exact(8)
            .map(|c| {
                let mut a = [0u8; 8];
                a.copy_from_slice(c);
                f64::from_le_bytes(a)
            })
            .collect();
        if let Some(i) = v.iter().position(|x| !x.is_finite()) {
            return Err(Error::format(
                self.path,
                format!("{what}[{i}]"),
                "not a finite number",
            ));
        }
        Ok(v)
    }
}

/// Load what [`render_result`] needs from a result folder `dir` (see the module docs), and
/// build the rotation matrices (`R_ν` for the run's normal grid).
///
/// Errors: [`Error::Workspace`] when `dir` or one of its files is missing, [`Error::Format`]
/// (naming the file and the part) when a file is malformed.
pub fn load_result(dir: &Path) -> Result<ResultModel> {
    if !dir.is_dir() {
        return Err(Error::Workspace {
            path: dir.to_path_buf(),
            message: "no such result folder".into(),
        });
    }
    let jp = dir.join("relight.json");
    let bp = dir.join("relight.bin");
    let model = dir.join("model");
    for (p, w) in [
        (&jp, "relight.json is missing"),
        (&bp, "relight.bin is missing"),
        (&model.join("cameras.txt"), "model/cameras.txt is missing"),
        (&model.join("images.txt"), "model/images.txt is missing"),
    ] {
        if !p.is_file() {
            return Err(missing(dir, w));
        }
    }
    let text = std::fs::read_to_string(&jp).map_err(|e| Error::io(&jp, e))?;
    let meta: serde_json::Value = serde_json::from_str(&text)
        .map_err(|e| Error::format(&jp, format!("line {}", e.line()), e.to_string()))?;
    let basis = meta
        .get("basis")
        .and_then(|b| b.as_array())
        .ok_or_else(|| Error::format(&jp, "basis", "missing or not a list"))?
        .iter()
        .map(|b| {
            b.as_str()
                .ok_or_else(|| Error::format(&jp, "basis", "entry is not a string"))
                .and_then(BasisBrdf::parse)
        })
        .collect::<Result<Vec<_>>>()?;
    let n_global = json_usize(&jp, &meta, "global_resolution")?;
    let n_local = json_usize(&jp, &meta, "local_resolution")?;
    let normal_grid = json_usize(&jp, &meta, "normal_grid")?;
    let rays_per_texel = json_usize(&jp, &meta, "rays_per_texel")?;
    let n_render_local = match meta.get("render_local_resolution") {
        Some(_) => json_usize(&jp, &meta, "render_local_resolution")?,
        None => n_local,
    };
    for (k, n) in [
        ("global_resolution", n_global),
        ("local_resolution", n_local),
        ("render_local_resolution", n_render_local),
        ("normal_grid", normal_grid),
    ] {
        if !(n.is_power_of_two() && (2..=1024).contains(&n)) {
            return Err(Error::format(&jp, k, "not a power of two in [2, 1024]"));
        }
    }
    let rows = meta
        .get("env_from_world")
        .and_then(|r| r.as_array())
        .filter(|r| r.len() == 3)
        .ok_or_else(|| Error::format(&jp, "env_from_world", "expected 3 rows"))?;
    let mut env_from_world = Matrix3::zeros();
    for (i, row) in rows.iter().enumerate() {
        let row = row
            .as_array()
            .filter(|r| r.len() == 3)
            .ok_or_else(|| Error::format(&jp, "env_from_world", "expected 3 numbers per row"))?;
        for (j, x) in row.iter().enumerate() {
            env_from_world[(i, j)] = x
                .as_f64()
                .filter(|x| x.is_finite())
                .ok_or_else(|| Error::format(&jp, "env_from_world", "not a finite number"))?;
        }
    }
    if (env_from_world * env_from_world.transpose() - Matrix3::identity())
        .abs()
        .max()
        > 1e-6
    {
        return Err(Error::format(&jp, "env_from_world", "not a rotation"));
    }

    let data = std::fs::read(&bp).map_err(|e| Error::io(&bp, e))?;
    let mut c = Cursor {
        path: &bp,
        data: &data,
        at: 0,
    };
    if c.take(8, "magic")? != MAGIC {
        return Err(Error::format(&bp, "magic", "not a relight.bin file"));
    }
    let nv = c.u64("header")? as usize;
    let nf = c.u64("header")? as usize;
    let nb = c.u64("header")? as usize;
    let t = c.u64("header")? as usize;
    if nb != basis.len() || t != n_render_local * n_render_local {
        return Err(Error::format(
            &bp,
            "header",
            format!(
                "{nb} basis BRDFs and {t} texels, but relight.json says {} and {}²",
                basis.len(),
                n_render_local
            ),
        ));
    }
    let to_vec = |v: Vec<f64>| -> Vec<Vec3> {
        v.chunks_exact(3)
            .map(|c| Vec3::new(c[0], c[1], c[2]))
            .collect()
    };
    let positions = to_vec(c.f64s(nv.saturating_mul(3), "positions")?);
    let normals_env = to_vec(c.f64s(nv.saturating_mul(3), "normals")?);
    let fb = c.take(nf.saturating_mul(12), "faces")?;
    let mut faces = Vec::with_capacity(nf);
    for (k, ch) in fb.chunks_exact(12).enumerate() {
        let mut f = [0u32; 3];
        for (i, x) in f.iter_mut().enumerate() {
            let mut a = [0u8; 4];
            a.copy_from_slice(&ch[4 * i..4 * i + 4]);
            *x = u32::from_le_bytes(a);
            if *x as usize >= nv {
                return Err(Error::format(
                    &bp,
                    format!("face {k}"),
                    format!("vertex index {x} out of range ({nv} vertices)"),
                ));
            }
        }
        faces.push(f);
    }
    let beta: Vec<[f64; 3]> = c
        .f64s(nv.saturating_mul(nb).saturating_mul(3), "beta")?
        .chunks_exact(3)
        .map(|c| [c[0], c[1], c[2]])
        .collect();
    let frac = c.take(nv.saturating_mul(t), "visibility")?.to_vec();
    let open: Vec<bool> = c.take(nv, "open")?.iter().map(|&o| o != 0).collect();
    if c.at != data.len() {
        return Err(Error::format(&bp, "end", "trailing bytes after the data"));
    }
    let world_from_env = env_from_world.transpose();
    let normals = normals_env.iter().map(|n| world_from_env * n).collect();
    let mesh = Mesh {
        positions,
        normals,
        faces,
        colors: None,
    };
    let vis = Visibility {
        n_local: n_render_local,
        rays_per_texel,
        frac,
        open,
        degenerate: 0,
        rays_traced: 0,
    };

    let read = |name: &str| -> Result<BufReader<std::fs::File>> {
        let p = model.join(name);
        std::fs::File::open(&p)
            .map(BufReader::new)
            .map_err(|e| Error::io(&p, e))
    };
    let cameras = text::read_cameras(read("cameras.txt")?, &model.join("cameras.txt"))?;
    let images = text::read_images(read("images.txt")?, &model.join("images.txt"))?;
    Ok(ResultModel {
        mesh,
        normals_env,
        vis,
        basis,
        beta,
        env_from_world,
        n_global,
        n_local,
        n_render_local,
        normal_grid,
        cameras,
        images,
    })
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

/// A file-name-safe stem of an image name (`dir/a.jpg` → `dir_a`).
pub fn file_stem(name: &str) -> String {
    let base = match name.rfind('.') {
        Some(i) if i > 0 => &name[..i],
        _ => name,
    };
    base.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

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
    let mut out = Vec::with_capacity(views.len());
    let mut animations = Vec::new();
    for (camera, image) in &views {
        let camera = match opts.resolution {
            Some(w) => {
                let h =
                    ((w as f64 * camera.height as f64 / camera.width as f64).round() as u32).max(1);
                camera.rescaled(w, h)
            }
            None => camera.clone(),
        };
        let frames: Vec<(Option<usize>, Image)> = match opts.turntable {
            Some(n) => (0..n)
                .map(|i| Ok((Some(i), views::orbit(image, &up, &centre, i, n)?)))
                .collect::<Result<_>>()?,
            None => vec![(None, image.clone())],
        };
        let mut pngs = Vec::new();
        for (frame, pose) in &frames {
            let stem = views::output_stem(&light_name, &image.name, *frame);
            let view = ViewLight {
                model: &model,
                rot: &rot,
                light: &light,
                light_ll: &light_ll,
            };
            let (file, png) = render_one(&view, opts, dir, &camera, pose, &stem)?;
            pngs.extend(png);
            out.push(file);
        }
        if opts.turntable.is_some() {
            let prefix = views::output_stem(&light_name, &image.name, None);
            let gif = format!("{prefix}_turntable.gif");
            views::write_gif(&dir.join(&gif), &pngs, 12)?;
            animations.push(opts.out.join(gif));
            let mp4 = format!("{prefix}_turntable.mp4");
            if views::write_video(dir, &prefix, &dir.join(&mp4), 12)? {
                animations.push(opts.out.join(mp4));
            }
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
mod tests {
    use super::*;

    /// The sun's energy `R · 2π(1 − cos 1°)` is exact on fine and coarse lat-long grids
    /// (integral of the map, a sum of pixel radiance × solid angle; f32 storage → 1e-5).
    #[test]
    fn sun_energy_exact() {
        for h in [16, 64, 512] {
            let mut ll = LatLong::black(h);
            let sun = Sun {
                dir: Vec3::new(0.3, 0.5, 0.8),
                radiance: [1000.0, 500.0, 10.0],
            };
            add_sun(&mut ll, &sun).unwrap();
            let omega = 2.0 * std::f64::consts::PI * (1.0 - SUN_RADIUS_DEG.to_radians().cos());
            let e = ll.integral();
            for (c, (&got, &r)) in e.iter().zip(&sun.radiance).enumerate() {
                let want = r * omega;
                assert!(
                    ((got - want) / want).abs() < 1e-5,
                    "h={h} c={c}: {got} vs {want}"
                );
            }
        }
    }
}
