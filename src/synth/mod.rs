//! Known-truth synthetic COLMAP workspaces (`relight-cpc synth SCENE OUT_DIR`).
//!
//! A scene is a mesh (icosphere, sphere on a ground plane, or the real "Spot" mesh, alone or
//! on a ground plane), a reflectance in the paper's model (Eq. 11: per-vertex non-negative
//! blend `w_k(x)` of materials, each a per-channel mix `λ_kbc` of basis lobes `ρ_b`) and one
//! real HDR map per photo (static, rotated, or a different map per photo). In
//! `spot-textured` the blend `w_1 = 1 − w_0` follows a procedural noise pattern
//! ([`geometry::pattern`], blobs ~3-6% of the object's size, on a ~24K-vertex mesh), so the
//! photos carry texture that SIFT matches (for real SfM runs, `scripts/colmap_fixture_synth.sh`)
//! while the per-vertex model still represents the reflectance exactly. Each photo is rendered by the
//! independent reference renderer ([`crate::transport::reference`], Eq. 1 by MIS Monte Carlo with
//! shadow rays), then exposed and encoded like a camera would:
//!
//! `pixel_c = sRGB8( clamp( e_I · wb_Ic · L_c + n, 0, 1 ) )`, `n ~ N(0, σ²)`,
//!
//! with the exposure `e_I` chosen so that ~1% of the object's pixels clip (the 99th
//! percentile of `max_c wb_Ic L_c` maps to 1). The workspace holds what COLMAP would give:
//! `sparse/{cameras,images,points3D}.txt` (PINHOLE camera; points sampled on the surface
//! by area and observed in every photo that sees them unoccluded and front-facing, with
//! their exact projections), `images/*.png`, `dense/meshed-poisson.ply`; and `truth/`:
//! `env/<photo>.exr` (the map each photo was rendered with, lat-long in the docs/conventions.md
//! convention, environment frame from the scene's up vector), `materials.json` (lobes, λ,
//! per-photo exposure and white balance), `weights.ply` (the mesh with per-vertex weights
//! `w0 … w{K-1}`), `masks/<photo>.png` (object coverage) and `manifest.json` (scene, up,
//! env frame, per-photo map and rotation, held-out photos, seed, options).
//!
//! Everything is seeded: the same scene, options and seed give the same bytes.

pub mod data;
pub mod geometry;

use crate::import::colmap::{
    Camera, CameraId, Image, ImageId, Point2D, Point3D, Point3DId, Reconstruction, TrackElement,
};
use crate::import::mesh::Mesh;
use crate::observe::trace::SceneBvh;
use crate::sphere::envmap::LatLong;
use crate::transport::reference::{
    Environment, Lobe, PinholeCamera, ReferenceScene, Reflectance, Samples,
};
use crate::{Error, Result, Vec3};
use rand::Rng;
use rand_pcg::Pcg32;
use std::f64::consts::PI;
use std::path::Path;

/// Options of [`build`].
#[derive(Debug, Clone, PartialEq)]
pub struct SynthOptions {
    /// Photo width in pixels.
    pub width: u32,
    /// Photo height in pixels.
    pub height: u32,
    /// Number of photos; `None` takes the scene's default.
    pub photos: Option<usize>,
    /// Seed of every random choice (camera jitter, map rotations, points, noise, MC).
    pub seed: u64,
    /// Minimum number of mesh vertices (the mesh is subdivided until it has at least this
    /// many); `None` takes the scene's default (about 10K).
    pub vertices: Option<usize>,
    /// Make the mesh exactly `vertices` vertices (whole subdivision steps, then a partial
    /// one: [`geometry::refine_to`]) instead of the first subdivision level with at least
    /// that many. Spot scenes only (`spot-varying`, `spot-ggx`, `spot-static`).
    pub exact_vertices: bool,
    /// Standard deviation of Gaussian noise on the linear `[0, 1]` photo scale.
    pub noise: f64,
    /// Random per-photo white balance (channel gains in `[0.85, 1.15]`, green fixed at 1).
    pub white_balance: bool,
    /// Reference-renderer effort.
    pub samples: Samples,
    /// Surface points sampled for `points3D.txt`.
    pub points: usize,
}

impl Default for SynthOptions {
    fn default() -> Self {
        SynthOptions {
            width: 256,
            height: 256,
            photos: None,
            seed: 1,
            vertices: None,
            exact_vertices: false,
            noise: 0.0,
            white_balance: false,
            samples: Samples {
                per_pixel: 4,
                light: 64,
                seed: 1,
            },
            points: 3000,
        }
    }
}

/// What [`build`] wrote.
#[derive(Debug, Clone, PartialEq)]
pub struct SynthSummary {
    /// Scene name.
    pub scene: String,
    /// Photo file names, in image-id order.
    pub photos: Vec<String>,
    /// The held-out photos' names.
    pub held_out: Vec<String>,
    /// Mesh vertices.
    pub vertices: usize,
    /// Mesh faces.
    pub faces: usize,
    /// 3D points written.
    pub points3d: usize,
    /// Their 2D observations.
    pub observations: usize,
    /// Wall time spent in the reference renderer, seconds.
    pub render_seconds: f64,
}

/// Geometry of a scene.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Shape {
    /// Unit icosphere.
    Sphere,
    /// Unit icosphere above a square ground plane (cast shadows).
    SpherePlane,
    /// The Spot mesh, two materials split by a tilted plane with a blended band.
    Spot,
    /// The Spot mesh standing on a square ground plane; on both, the two materials' weights
    /// follow a procedural noise pattern ([`geometry::pattern`]) that SIFT can match.
    SpotTextured,
}

/// How the illumination changes from photo to photo.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Lighting {
    /// One map, unrotated, for every photo.
    Static(&'static str),
    /// One map, a different random azimuthal rotation per photo.
    Rotating(&'static str),
    /// A different map per photo (cycling through the list), each randomly rotated.
    Varying(&'static [&'static str]),
}

struct SceneDef {
    name: &'static str,
    description: &'static str,
    shape: Shape,
    lobes: Vec<Lobe>,
    /// Per material: name and λ per lobe.
    materials: Vec<(&'static str, Vec<[f64; 3]>)>,
    lighting: Lighting,
    photos: usize,
}

const ALL_MAPS: &[&str] = &data::MAP_NAMES;

fn scene_defs() -> Vec<SceneDef> {
    let phong = |e: f64| Lobe::Phong { exponent: e };
    vec![
        SceneDef {
            name: "sphere-diffuse",
            description: "Lambertian sphere, one real map (known reflectance, unknown light: paper Sec. 6.1)",
            shape: Shape::Sphere,
            lobes: vec![Lobe::Lambert],
            materials: vec![("clay", vec![[0.7, 0.5, 0.3]])],
            lighting: Lighting::Static("courtyard"),
            photos: 8,
        },
        SceneDef {
            name: "sphere-glossy",
            description: "Lambert + Phong 50 sphere, one real map (paper Sec. 6.1)",
            shape: Shape::Sphere,
            lobes: vec![Lobe::Lambert, phong(50.0)],
            materials: vec![("glossy", vec![[0.5, 0.35, 0.2], [0.35, 0.35, 0.35]])],
            lighting: Lighting::Static("courtyard"),
            photos: 8,
        },
        SceneDef {
            name: "sphere-specular",
            description: "Lambert + Phong 500 sphere, one real map (paper Sec. 6.1)",
            shape: Shape::Sphere,
            lobes: vec![Lobe::Lambert, phong(500.0)],
            materials: vec![("specular", vec![[0.5, 0.35, 0.2], [0.35, 0.35, 0.35]])],
            lighting: Lighting::Static("courtyard"),
            photos: 8,
        },
        SceneDef {
            name: "sphere-plane",
            description: "glossy sphere casting shadows on a diffuse plane, the sunny city map rotated per photo",
            shape: Shape::SpherePlane,
            lobes: vec![Lobe::Lambert, phong(50.0)],
            materials: vec![
                ("glossy-sphere", vec![[0.6, 0.3, 0.2], [0.3, 0.3, 0.3]]),
                ("diffuse-plane", vec![[0.5, 0.5, 0.5], [0.0, 0.0, 0.0]]),
            ],
            lighting: Lighting::Rotating("city"),
            photos: 12,
        },
        SceneDef {
            name: "spot-varying",
            description: "Spot, two blended materials, a different real map and rotation per photo, held-out photos",
            shape: Shape::Spot,
            lobes: vec![Lobe::Lambert, phong(50.0), Lobe::Ggx { alpha: 0.3 }],
            materials: vec![
                ("orange-ggx", vec![[0.8, 0.45, 0.2], [0.0, 0.0, 0.0], [0.25, 0.25, 0.25]]),
                ("blue-phong", vec![[0.2, 0.3, 0.6], [0.3, 0.3, 0.3], [0.0, 0.0, 0.0]]),
            ],
            lighting: Lighting::Varying(ALL_MAPS),
            photos: 16,
        },
        SceneDef {
            name: "spot-ggx",
            description: "Spot, two blended materials with lobes the transport resolves (Lambert + GGX 0.3, Lambert), a different real map and rotation per photo, held-out photos",
            shape: Shape::Spot,
            lobes: vec![Lobe::Lambert, Lobe::Ggx { alpha: 0.3 }],
            materials: vec![
                ("orange-ggx", vec![[0.8, 0.45, 0.2], [0.25, 0.25, 0.25]]),
                ("blue-lambert", vec![[0.2, 0.3, 0.6], [0.0, 0.0, 0.0]]),
            ],
            lighting: Lighting::Varying(ALL_MAPS),
            photos: 16,
        },
        SceneDef {
            name: "spot-static",
            description: "Spot, two blended materials, one real map for every photo (static illumination)",
            shape: Shape::Spot,
            lobes: vec![Lobe::Lambert, phong(50.0), Lobe::Ggx { alpha: 0.3 }],
            materials: vec![
                ("orange-ggx", vec![[0.8, 0.45, 0.2], [0.0, 0.0, 0.0], [0.25, 0.25, 0.25]]),
                ("blue-phong", vec![[0.2, 0.3, 0.6], [0.3, 0.3, 0.3], [0.0, 0.0, 0.0]]),
            ],
            lighting: Lighting::Static("forest"),
            photos: 12,
        },
        SceneDef {
            name: "spot-textured",
            description: "Spot on a ground plane, two materials in a high-frequency noise pattern (texture for SfM), one real map for every photo, held-out photos",
            shape: Shape::SpotTextured,
            lobes: vec![Lobe::Lambert, phong(50.0), Lobe::Ggx { alpha: 0.3 }],
            materials: vec![
                ("cream-ggx", vec![[0.85, 0.75, 0.55], [0.0, 0.0, 0.0], [0.15, 0.15, 0.15]]),
                ("dark-phong", vec![[0.06, 0.05, 0.05], [0.15, 0.15, 0.15], [0.0, 0.0, 0.0]]),
            ],
            lighting: Lighting::Static("courtyard"),
            photos: 24,
        },
    ]
}

/// The scene names `synth` knows, in a fixed order.
pub fn scene_names() -> Vec<&'static str> {
    scene_defs().iter().map(|d| d.name).collect()
}

/// Embedded map `name`.
fn embedded_map(name: &str) -> Result<LatLong> {
    let bytes: &[u8] = match name {
        "city" => include_bytes!("../../tests/fixtures/synth/hdri/city.exr"),
        "courtyard" => include_bytes!("../../tests/fixtures/synth/hdri/courtyard.exr"),
        "forest" => include_bytes!("../../tests/fixtures/synth/hdri/forest.exr"),
        "interior" => include_bytes!("../../tests/fixtures/synth/hdri/interior.exr"),
        "night" => include_bytes!("../../tests/fixtures/synth/hdri/night.exr"),
        "studio" => include_bytes!("../../tests/fixtures/synth/hdri/studio.exr"),
        "sunrise" => include_bytes!("../../tests/fixtures/synth/hdri/sunrise.exr"),
        "sunset" => include_bytes!("../../tests/fixtures/synth/hdri/sunset.exr"),
        other => return Err(Error::Internal(format!("no embedded map named `{other}`"))),
    };
    LatLong::read_exr_bytes(bytes, &format!("embedded map {name}")).map(|(map, _)| map)
}

const SPOT_PLY: &[u8] = include_bytes!("../../tests/fixtures/synth/spot.ply");

/// The Spot mesh, read by the project's PLY reader from a temporary copy.
fn spot_mesh(out: &Path) -> Result<(Vec<Vec3>, Vec<[u32; 3]>)> {
    let tmp = out.join(".spot-source.ply");
    std::fs::write(&tmp, SPOT_PLY).map_err(|e| Error::io(&tmp, e))?;
    let read = Mesh::read_ply(&tmp);
    std::fs::remove_file(&tmp).map_err(|e| Error::io(&tmp, e))?;
    let (mesh, _) = read?;
    Ok((mesh.positions, mesh.faces))
}

/// Geometry for `shape` with at least `min_vertices` vertices (where the shape allows;
/// exactly that many with `exact`, spot only), and the camera target `(centre, radius)`.
fn make_geometry(shape: Shape, min_vertices: usize, exact: bool, out: &Path) -> Result<Geometry> {
    if exact && shape != Shape::Spot {
        return Err(Error::Config(
            "an exact vertex count needs a spot scene (spot-varying, spot-ggx, spot-static): the other shapes are built from parts".into(),
        ));
    }
    let sphere_level = |target: usize| -> u32 {
        (0..12)
            .find(|&s| 10 * 4usize.pow(s) + 2 >= target)
            .unwrap_or(11)
    };
    match shape {
        Shape::Sphere => {
            let (p, f) = geometry::icosphere(sphere_level(min_vertices));
            Ok((p, f, Vec3::zeros(), 1.0))
        }
        Shape::SpherePlane => {
            // Sphere ~80% of the vertices, plane the rest.
            let (p, f) = geometry::icosphere(sphere_level(min_vertices * 4 / 5));
            let cells = ((min_vertices as f64 / 5.0).sqrt().ceil() as u32).max(8);
            let (pp, pf) =
                geometry::plane(&Vec3::new(0.0, -PLANE_DROP, 0.0), &Vec3::y(), 6.0, cells);
            let (mut pos, mut faces) = (p, f);
            geometry::append(&mut pos, &mut faces, &pp, &pf);
            Ok((pos, faces, Vec3::new(0.0, -0.4, 0.0), 1.9))
        }
        Shape::Spot => {
            let (mut p, mut f) = spot_mesh(out)?;
            if exact {
                if p.len() > min_vertices {
                    return Err(Error::Config(format!(
                        "an exact vertex count of {min_vertices} is below the spot mesh's own {} vertices",
                        p.len()
                    )));
                }
                (p, f) = geometry::refine_to(&p, &f, min_vertices);
            }
            while p.len() < min_vertices {
                let (q, g) = geometry::subdivide(&p, &f);
                p = q;
                f = g;
            }
            let (lo, hi) = crate::import::mesh::bounding_box(&p);
            let c = (lo + hi) * 0.5;
            let r = p.iter().map(|q| (q - c).norm()).fold(0.0, f64::max);
            Ok((p, f, c, r))
        }
        Shape::SpotTextured => {
            // Spot as above (at least 2/5 of the vertices), on a plane touching its lowest
            // point, 2.5× its largest horizontal extent on a side, the rest of the vertices.
            let (mut p, mut f) = spot_mesh(out)?;
            while p.len() < min_vertices * 2 / 5 {
                let (q, g) = geometry::subdivide(&p, &f);
                p = q;
                f = g;
            }
            let (lo, hi) = crate::import::mesh::bounding_box(&p);
            let c = (lo + hi) * 0.5;
            let r = p.iter().map(|q| (q - c).norm()).fold(0.0, f64::max);
            let side = 2.5 * (hi.x - lo.x).max(hi.z - lo.z);
            let cells = ((min_vertices.saturating_sub(p.len()) as f64).sqrt().ceil() as u32).max(8);
            let (pp, pf) = geometry::plane(&Vec3::new(c.x, lo.y, c.z), &Vec3::y(), side, cells);
            geometry::append(&mut p, &mut f, &pp, &pf);
            Ok((p, f, c, r))
        }
    }
}

/// Positions, faces, camera target centre and radius.
type Geometry = (Vec<Vec3>, Vec<[u32; 3]>, Vec3, f64);

/// Height of the ground plane below the unit sphere's centre (a small gap under it).
const PLANE_DROP: f64 = 1.02;

/// Per-vertex material weights (row-major `n × K`).
fn make_weights(shape: Shape, positions: &[Vec3], k: usize) -> Vec<f64> {
    let mut w = vec![0.0; positions.len() * k];
    match shape {
        Shape::Sphere => w.iter_mut().for_each(|x| *x = 1.0),
        Shape::SpherePlane => {
            for (i, p) in positions.iter().enumerate() {
                let m = if p.y < -(1.0 + PLANE_DROP) / 2.0 {
                    1
                } else {
                    0
                };
                w[i * k + m] = 1.0;
            }
        }
        Shape::Spot => {
            // Split by a tilted plane through the box centre; linear blend over a band of
            // 8% of the diagonal.
            let (lo, hi) = crate::import::mesh::bounding_box(positions);
            let c = (lo + hi) * 0.5;
            let band = 0.08 * (hi - lo).norm();
            let dir = Vec3::new(1.0, 0.6, 0.3).normalize();
            for (i, p) in positions.iter().enumerate() {
                let s = ((p - c).dot(&dir) / band + 0.5).clamp(0.0, 1.0);
                w[i * k] = 1.0 - s;
                w[i * k + 1] = s;
            }
        }
        Shape::SpotTextured => {
            // Noise lattice 6% of the object's size (the bounding box of everything above
            // the ground, which is the lowest vertex's height): blobs 3-6 mesh edges across
            // on Spot, 2-4 grid cells on the plane.
            let floor = positions.iter().map(|p| p.y).fold(f64::INFINITY, f64::min);
            let above: Vec<Vec3> = positions
                .iter()
                .filter(|p| p.y > floor + 1e-9)
                .copied()
                .collect();
            let (lo, hi) = crate::import::mesh::bounding_box(&above);
            let scale = 0.06 * (hi - lo).norm();
            for (i, p) in positions.iter().enumerate() {
                let s = geometry::pattern(&(p / scale));
                w[i * k] = 1.0 - s;
                w[i * k + 1] = s;
            }
        }
    }
    w
}

/// A pinhole camera at `eye` looking at `target`, image −y along `up`:
/// `z = (target − eye)/|…|`, `x = z × up / |…|` (right), `y = z × x` (down).
pub fn look_at(
    eye: &Vec3,
    target: &Vec3,
    up: &Vec3,
    width: u32,
    height: u32,
    fov_deg: f64,
) -> PinholeCamera {
    let z = (target - eye).normalize();
    let x = z.cross(up).normalize();
    let y = z.cross(&x);
    let r = nalgebra::Matrix3::from_rows(&[x.transpose(), y.transpose(), z.transpose()]);
    let f = width.min(height) as f64 / 2.0 / (fov_deg.to_radians() / 2.0).tan();
    PinholeCamera {
        width,
        height,
        fx: f,
        fy: f,
        cx: width as f64 / 2.0,
        cy: height as f64 / 2.0,
        rotation: r,
        translation: -(r * eye),
    }
}

/// `map` turned about `e_z` by `shift` whole texels: what was at azimuth `φ` is now at
/// `φ + 2π shift / W` (exact: no resampling).
pub fn rotate_texels(map: &LatLong, shift: usize) -> LatLong {
    let w = map.width;
    let mut out = map.clone();
    for v in 0..map.height {
        for u in 0..w {
            out.rgb[v * w + (u + shift) % w] = map.rgb[v * w + u];
        }
    }
    out
}

#[derive(serde::Serialize)]
struct PhotoTruth {
    name: String,
    env: String,
    map: String,
    rotation_texels: usize,
    rotation_radians: f64,
    held_out: bool,
    exposure: f64,
    white_balance: [f64; 3],
}

#[derive(serde::Serialize)]
struct Manifest<'a> {
    scene: &'a str,
    description: &'a str,
    seed: u64,
    up: [f64; 3],
    env_frame: [[f64; 3]; 3],
    env_convention: &'a str,
    static_illumination: bool,
    held_out: Vec<String>,
    photos: &'a [PhotoTruth],
    image_size: [u32; 2],
    samples_per_pixel: u32,
    light_sample_pairs: u32,
    noise_sigma: f64,
    vertices: usize,
    faces: usize,
    mesh: &'a str,
    weights: &'a str,
    materials: &'a str,
    credits: &'a str,
}

#[derive(serde::Serialize)]
struct MaterialsTruth<'a> {
    lobes: &'a [Lobe],
    formulas: [&'a str; 4],
    materials: Vec<MaterialTruth<'a>>,
    photo_model: &'a str,
    photos: Vec<PhotoScale<'a>>,
}

#[derive(serde::Serialize)]
struct MaterialTruth<'a> {
    name: &'a str,
    /// `lambda[b] = [r, g, b]` weight of lobe b.
    lambda: &'a [[f64; 3]],
}

#[derive(serde::Serialize)]
struct PhotoScale<'a> {
    name: &'a str,
    exposure: f64,
    white_balance: [f64; 3],
}

fn write_json(path: &Path, value: &impl serde::Serialize) -> Result<()> {
    let text = serde_json::to_string_pretty(value)
        .map_err(|e| Error::Internal(format!("cannot serialise {}: {e}", path.display())))?;
    std::fs::write(path, text + "\n").map_err(|e| Error::io(path, e))
}

fn create_dir(path: &Path) -> Result<()> {
    std::fs::create_dir_all(path).map_err(|e| Error::io(path, e))
}

fn save_png(path: &Path, width: u32, height: u32, bytes: Vec<u8>, channels: u8) -> Result<()> {
    let err = |m: String| Error::Image {
        path: path.to_path_buf(),
        message: m,
    };
    let color = if channels == 3 {
        image::ExtendedColorType::Rgb8
    } else {
        image::ExtendedColorType::L8
    };
    image::save_buffer_with_format(path, &bytes, width, height, color, image::ImageFormat::Png)
        .map_err(|e| err(e.to_string()))
}

/// Standard normal deviate (Box–Muller).
fn gaussian(rng: &mut Pcg32) -> f64 {
    let u1: f64 = 1.0 - rng.random::<f64>();
    let u2: f64 = rng.random();
    (-2.0 * u1.ln()).sqrt() * (2.0 * PI * u2).cos()
}

/// Writes the workspace of scene `name` into `out` (created if missing).
pub fn build(name: &str, out: &Path, opts: &SynthOptions) -> Result<SynthSummary> {
    let def = scene_defs()
        .into_iter()
        .find(|d| d.name == name)
        .ok_or_else(|| {
            Error::Config(format!(
                "unknown scene `{name}`; known scenes: {}",
                scene_names().join(", ")
            ))
        })?;
    if opts.width == 0 || opts.height == 0 {
        return Err(Error::Config("synth image size must be positive".into()));
    }
    if !(opts.noise.is_finite() && opts.noise >= 0.0) {
        return Err(Error::Config(format!("noise σ {} must be ≥ 0", opts.noise)));
    }
    let n_photos = opts.photos.unwrap_or(def.photos);
    if n_photos == 0 {
        return Err(Error::Config("synth needs at least one photo".into()));
    }
    for dir in ["sparse", "images", "dense", "truth/env", "truth/masks"] {
        create_dir(&out.join(dir))?;
    }
    let up = Vec3::y();
    let frame = crate::sphere::env_frame(&up).ok_or_else(|| Error::Numeric {
        stage: "synth".into(),
        message: "no environment frame for the up vector".into(),
    })?;

    // Geometry, cleaned by the project's mesh code (the mesh written is the mesh rendered).
    let (positions, faces, target, radius) = make_geometry(
        def.shape,
        opts.vertices
            .unwrap_or(if def.shape == Shape::SpotTextured {
                24_000
            } else {
                10_000
            }),
        opts.exact_vertices,
        out,
    )?;
    let (mesh, _) = Mesh::from_parts(positions, faces);
    let k = def.materials.len();
    let refl = Reflectance {
        lobes: def.lobes.clone(),
        lambda: def.materials.iter().map(|m| m.1.clone()).collect(),
        weights: make_weights(def.shape, &mesh.positions, k),
    };
    refl.validate(mesh.positions.len())?;
    let bvh = SceneBvh::new(&mesh);

    // Cameras around and above the target, evenly spread in azimuth with jitter.
    let mut rng = Pcg32::new(opts.seed, 0x5eed);
    let fov: f64 = 40.0;
    let dist = radius / (fov.to_radians() / 2.0 * 0.85).sin();
    let min_elev = if matches!(def.shape, Shape::SpherePlane | Shape::SpotTextured) {
        20.0
    } else {
        5.0
    };
    let cams: Vec<PinholeCamera> = (0..n_photos)
        .map(|i| {
            let az = 2.0 * PI * (i as f64 + 0.6 * (rng.random::<f64>() - 0.5)) / n_photos as f64;
            let el = (min_elev + 35.0 * rng.random::<f64>()).to_radians();
            let eye = target + Vec3::new(el.cos() * az.cos(), el.sin(), el.cos() * az.sin()) * dist;
            look_at(&eye, &target, &up, opts.width, opts.height, fov)
        })
        .collect();

    // Lighting plan.
    let mut maps: Vec<(String, LatLong)> = Vec::new();
    let mut plan: Vec<(usize, usize)> = Vec::with_capacity(n_photos);
    for i in 0..n_photos {
        let (m, rotate) = match def.lighting {
            Lighting::Static(m) => (m, false),
            Lighting::Rotating(m) => (m, true),
            Lighting::Varying(list) => (list[i % list.len()], true),
        };
        let idx = match maps.iter().position(|x| x.0 == m) {
            Some(j) => j,
            None => {
                maps.push((m.to_string(), embedded_map(m)?));
                maps.len() - 1
            }
        };
        let shift = if rotate {
            rng.random_range(0..maps[idx].1.width)
        } else {
            0
        };
        plan.push((idx, shift));
    }

    // Render, expose, encode.
    let names: Vec<String> = (0..n_photos).map(|i| format!("photo_{i:03}.png")).collect();
    let held: Vec<bool> = (0..n_photos).map(|i| n_photos >= 4 && i % 4 == 3).collect();
    let mut truths = Vec::with_capacity(n_photos);
    let mut photos8: Vec<Vec<u8>> = Vec::with_capacity(n_photos);
    let mut render_seconds = 0.0;
    for (i, cam) in cams.iter().enumerate() {
        let (mi, shift) = plan[i];
        let env_map = rotate_texels(&maps[mi].1, shift);
        let stem = names[i].trim_end_matches(".png");
        let env_rel = format!("env/{stem}.exr");
        data::write_exr(&env_map, &out.join("truth").join(&env_rel), false)?;
        let env = Environment::new(env_map.width, env_map.height, &env_map.rgb, frame)?;
        let scene = ReferenceScene {
            positions: &mesh.positions,
            normals: &mesh.normals,
            faces: &mesh.faces,
            reflectance: &refl,
            env: &env,
            caster: &bvh,
            offset: bvh.ray_offset(),
        };
        let samples = Samples {
            seed: opts.samples.seed
                ^ opts.seed.wrapping_mul(0x9e37_79b9_7f4a_7c15)
                ^ (i as u64) << 40,
            ..opts.samples
        };
        let t0 = std::time::Instant::now();
        let img = scene.render(cam, &samples);
        render_seconds += t0.elapsed().as_secs_f64();

        let wb = if opts.white_balance {
            [
                0.85 + 0.3 * rng.random::<f64>(),
                1.0,
                0.85 + 0.3 * rng.random::<f64>(),
            ]
        } else {
            [1.0; 3]
        };
        // Exposure: the 99th percentile of the object's brightest channel maps to 1.
        let mut bright: Vec<f64> = img
            .rgb
            .iter()
            .zip(&img.coverage)
            .filter(|(_, &c)| c > 0.0)
            .map(|(p, _)| (0..3).map(|c| p[c] as f64 * wb[c]).fold(0.0, f64::max))
            .collect();
        bright.sort_by(|a, b| a.total_cmp(b));
        let p99 = bright
            .get((bright.len() as f64 * 0.99) as usize)
            .or(bright.last())
            .copied()
            .unwrap_or(0.0);
        let exposure = if p99 > 0.0 { 1.0 / p99 } else { 1.0 };
        let mut noise_rng = Pcg32::new(opts.seed ^ 0x006e_6f69_7365, i as u64);
        let mut bytes = Vec::with_capacity(img.rgb.len() * 3);
        for p in &img.rgb {
            for c in 0..3 {
                let mut x = exposure * wb[c] * p[c] as f64;
                if opts.noise > 0.0 {
                    x += opts.noise * gaussian(&mut noise_rng);
                }
                let e = crate::import::photo::linear_to_srgb(x as f32);
                bytes.push((e * 255.0).round().clamp(0.0, 255.0) as u8);
            }
        }
        save_png(
            &out.join("images").join(&names[i]),
            opts.width,
            opts.height,
            bytes.clone(),
            3,
        )?;
        let mask: Vec<u8> = img
            .coverage
            .iter()
            .map(|&c| (c * 255.0).round() as u8)
            .collect();
        save_png(
            &out.join("truth/masks").join(&names[i]),
            opts.width,
            opts.height,
            mask,
            1,
        )?;
        photos8.push(bytes);
        truths.push(PhotoTruth {
            name: names[i].clone(),
            env: env_rel,
            map: maps[mi].0.clone(),
            rotation_texels: shift,
            rotation_radians: 2.0 * PI * shift as f64 / env_map.width as f64,
            held_out: held[i],
            exposure,
            white_balance: wb,
        });
    }

    // Sparse model: surface points by area, observed where visible and front-facing.
    let areas: Vec<f64> = (0..mesh.faces.len())
        .map(|f| {
            let [a, b, c] = mesh.faces[f].map(|v| mesh.positions[v as usize]);
            (b - a).cross(&(c - a)).norm() / 2.0
        })
        .collect();
    let mut cdf = Vec::with_capacity(areas.len());
    let mut acc = 0.0;
    for a in &areas {
        acc += a;
        cdf.push(acc);
    }
    let mut rec = Reconstruction::default();
    rec.cameras.insert(
        CameraId(1),
        Camera::pinhole(
            CameraId(1),
            opts.width,
            opts.height,
            cams[0].fx,
            cams[0].fy,
            cams[0].cx,
            cams[0].cy,
        ),
    );
    for (i, cam) in cams.iter().enumerate() {
        let rot = nalgebra::Rotation3::from_matrix(&cam.rotation);
        let im = Image::from_pose(
            ImageId(i as u32 + 1),
            names[i].clone(),
            CameraId(1),
            &rot,
            &cam.translation,
        );
        rec.images.insert(im.id, im);
    }
    let centers: Vec<Vec3> = cams.iter().map(|c| c.center()).collect();
    let mut pts_rng = Pcg32::new(opts.seed ^ 0x706f_696e_7473_0000, 1);
    let mut observations = 0;
    let mut next_id = 1u64;
    if acc > 0.0 {
        for _ in 0..opts.points {
            let r = pts_rng.random::<f64>() * acc;
            let f = cdf.partition_point(|&c| c <= r).min(cdf.len() - 1);
            let (mut s, mut t) = (pts_rng.random::<f64>(), pts_rng.random::<f64>());
            if s + t > 1.0 {
                s = 1.0 - s;
                t = 1.0 - t;
            }
            let [a, b, c] = mesh.faces[f].map(|v| mesh.positions[v as usize]);
            let x = a + (b - a) * s + (c - a) * t;
            let ng = (b - a).cross(&(c - a));
            if ng.norm() == 0.0 {
                continue;
            }
            let ng = ng.normalize();
            let mut obs = Vec::new();
            for (i, cam) in cams.iter().enumerate() {
                let to_c = centers[i] - x;
                let dist_c = to_c.norm();
                let dir = to_c / dist_c;
                if ng.dot(&dir) <= 0.05 {
                    continue;
                }
                let Some((u, v)) = cam.project(&x) else {
                    continue;
                };
                if !(u >= 0.0 && v >= 0.0 && u < opts.width as f64 && v < opts.height as f64) {
                    continue;
                }
                let off = bvh.ray_offset();
                if bvh.occluded(&(x + ng * off), &dir, 0.0, dist_c - 2.0 * off) {
                    continue;
                }
                obs.push((i, [u, v]));
            }
            if obs.len() < 2 {
                continue;
            }
            let id = Point3DId(next_id);
            next_id += 1;
            let (i0, [u0, v0]) = obs[0];
            let pix = (v0 as usize) * opts.width as usize + u0 as usize;
            let rgb = [
                photos8[i0][3 * pix],
                photos8[i0][3 * pix + 1],
                photos8[i0][3 * pix + 2],
            ];
            let mut track = Vec::with_capacity(obs.len());
            for (i, xy) in obs {
                let im =
                    rec.images
                        .get_mut(&ImageId(i as u32 + 1))
                        .ok_or_else(|| Error::Numeric {
                            stage: "synth".into(),
                            message: format!("image {i} missing"),
                        })?;
                track.push(TrackElement {
                    image_id: im.id,
                    point2d_idx: im.points2d.len() as u32,
                });
                im.points2d.push(Point2D {
                    xy,
                    point3d_id: Some(id),
                });
            }
            observations += track.len();
            rec.points3d.insert(
                id,
                Point3D {
                    id,
                    xyz: x,
                    rgb,
                    error: 0.0,
                    track,
                },
            );
        }
    }
    rec.write_text(&out.join("sparse"))?;
    mesh.write_ply(&out.join("dense/meshed-poisson.ply"), &[])?;
    let wcols: Vec<Vec<f32>> = (0..k)
        .map(|j| {
            (0..mesh.positions.len())
                .map(|v| refl.weights[v * k + j] as f32)
                .collect()
        })
        .collect();
    let wnames: Vec<String> = (0..k).map(|j| format!("w{j}")).collect();
    let extra: Vec<(&str, &[f32])> = wnames
        .iter()
        .zip(&wcols)
        .map(|(n, c)| (n.as_str(), c.as_slice()))
        .collect();
    mesh.write_ply(&out.join("truth/weights.ply"), &extra)?;

    let mat_truth = MaterialsTruth {
        lobes: &refl.lobes,
        formulas: [
            "all lobes include cos θ_i = max(0, n·ω_i) and are colourless; ρ_c(x) = Σ_k w_k(x) Σ_b λ_kbc ρ_b",
            "lambert: ρ = cos θ_i / π",
            "phong: ρ = (N+2)/(2π) · max(0, r·ω_i)^N · cos θ_i, r = 2(n·ω_o)n − ω_o",
            "ggx: ρ = D(h) G1(ω_i) G1(ω_o) / (4 cos θ_o), h = normalize(ω_i+ω_o), D = α²/(π((n·h)²(α²−1)+1)²), G1(v) = 2(n·v)/((n·v)+sqrt(α²+(1−α²)(n·v)²))",
        ],
        materials: def
            .materials
            .iter()
            .map(|(n, l)| MaterialTruth { name: n, lambda: l })
            .collect(),
        photo_model: "photo_linear_c = exposure · white_balance_c · radiance_c (+ Gaussian noise), clipped to [0, 1], sRGB-encoded to 8 bits",
        photos: truths
            .iter()
            .map(|t| PhotoScale {
                name: &t.name,
                exposure: t.exposure,
                white_balance: t.white_balance,
            })
            .collect(),
    };
    write_json(&out.join("truth/materials.json"), &mat_truth)?;
    let held_out: Vec<String> = truths
        .iter()
        .filter(|t| t.held_out)
        .map(|t| t.name.clone())
        .collect();
    let manifest = Manifest {
        scene: def.name,
        description: def.description,
        seed: opts.seed,
        up: [up.x, up.y, up.z],
        env_frame: frame.map(|e| [e.x, e.y, e.z]),
        env_convention: "lat-long 2H×H, v = 0 the top row; θ = π(v+0.5)/H from e_z (up), φ = 2π(u+0.5)/(2H) from e_x toward e_y; texels are radiance averages over their solid angle, rendered as piecewise constant",
        static_illumination: matches!(def.lighting, Lighting::Static(_)),
        held_out: held_out.clone(),
        photos: &truths,
        image_size: [opts.width, opts.height],
        samples_per_pixel: opts.samples.per_pixel,
        light_sample_pairs: opts.samples.light,
        noise_sigma: opts.noise,
        vertices: mesh.positions.len(),
        faces: mesh.faces.len(),
        mesh: "dense/meshed-poisson.ply",
        weights: "truth/weights.ply",
        materials: "truth/materials.json",
        credits: "HDR maps: Greg Zaal (HDRI Haven), CC0, via Debian blender-data; Spot: Keenan Crane",
    };
    write_json(&out.join("truth/manifest.json"), &manifest)?;

    Ok(SynthSummary {
        scene: def.name.to_string(),
        photos: names,
        held_out,
        vertices: mesh.positions.len(),
        faces: mesh.faces.len(),
        points3d: rec.points3d.len(),
        observations,
        render_seconds,
    })
}
