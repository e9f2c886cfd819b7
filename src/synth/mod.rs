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
use crate::import::geotag::GeoTag;
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

mod photos;
mod scenes;
mod sparse;
mod truth;

use photos::Rendered;
use scenes::SceneDef;
use scenes::{embedded_map, make_geometry, make_weights, scene_defs, Lighting, Shape};
pub use scenes::{look_at, rotate_texels, scene_names};
use truth::{
    create_dir, gaussian, save_png, save_png_exif, write_json, Manifest, MaterialTruth,
    MaterialsTruth, PhotoScale, PhotoTruth,
};

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
    /// that many. Scenes on Spot alone only (every `spot-` scene but `spot-textured`,
    /// `scenes::spot_scene_names`).
    pub exact_vertices: bool,
    /// Standard deviation of Gaussian noise on the linear `[0, 1]` photo scale.
    pub noise: f64,
    /// Random per-photo white balance (channel gains in `[0.85, 1.15]`, green fixed at 1).
    pub white_balance: bool,
    /// The linear value the 99th percentile of the object's brightest channel is exposed
    /// to: 1 clips about 1% of the object's pixels (more where the sun's highlight is
    /// large), below about 0.7 nearly none.
    pub exposure_peak: f64,
    /// Photos lit by the same map see it at the same rotation, so they share one sky (as
    /// photos taken in one session do): with a scene's 16 photos cycling 8 maps, photos `i`
    /// and `i + 8` stand on opposite sides under one sky. For the scenes whose map turns
    /// from photo to photo; the others are unchanged.
    pub shared_skies: bool,
    /// Suns from a day's clock (sun-and-sky scenes only): photo `i` of `n` is taken at
    /// [`GEOTAG_PLACE`] on [`GEOTAG_DAY`] at `GEOTAG_HOURS.0 + (i + u_i / 2) / n` of the span
    /// to `GEOTAG_HOURS.1` UTC (`u_i` uniform), its sun where the solar position puts it
    /// with north at a random azimuth of the environment frame
    /// ([`crate::solve::light::sky::clock`]; the manifest's `north_radians`), and its PNG
    /// carries the place and time as an EXIF geotag ([`crate::import::geotag`]).
    pub geotag: bool,
    /// The pixels the object does not cover show the light along their ray (the map the
    /// photo is lit by, at the pixel's centre, under the photo's exposure and white
    /// balance; a pixel the object covers partly is blended by its coverage). Off: black.
    pub sky_background: bool,
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
            exposure_peak: 1.0,
            shared_skies: false,
            geotag: false,
            sky_background: false,
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

/// Height of a `spot-sky` map (lat-long, twice as wide).
pub const SKY_MAP_HEIGHT: usize = 128;
/// Sun-and-sky map weights of [`sky_map`]: powers (integrals over the sphere) of the sky,
/// the sun lobe and the ground per channel, and the sun lobe's `κ` (a lobe ~4° wide).
pub const SKY_MAP_POWER: [[f64; 3]; 3] = [[0.8, 1.0, 1.3], [3.0, 2.7, 2.2], [0.35, 0.3, 0.25]];
/// Turbidity and sun-lobe sharpness of [`sky_map`].
pub const SKY_MAP_TURBIDITY: f64 = 3.0;
pub const SKY_MAP_KAPPA: f64 = 300.0;

/// A clear-sky lat-long map of `height` rows from the sun-and-sky model
/// ([`crate::solve::light::sky`]) with sun `sun` (environment frame, `e_z` up): the
/// Hosek–Wilkie sky scaled to power `SKY_MAP_POWER[0]`, the sun lobe and the ground to the
/// next two (the lobe and ground bases integrate to 1; the sky by its own quadrature here).
pub fn sky_map(sun: &Vec3, height: usize) -> Result<LatLong> {
    use crate::solve::light::sky::{ground, sky_radiance, sky_state, sun_lobe, SunSky};
    let p = SunSky {
        sun: sun.normalize(),
        turbidity: SKY_MAP_TURBIDITY,
        kappa: SKY_MAP_KAPPA,
    };
    let state = sky_state(&p)?;
    let mut ll = LatLong::black(height);
    let mut sky = vec![[0.0_f64; 3]; ll.rgb.len()];
    let mut total = [0.0_f64; 3];
    for v in 0..ll.height {
        let sa = ll.solid_angle(v);
        for u in 0..ll.width {
            let s = sky_radiance(&state, &ll.dir(u, v), &p.sun);
            for c in 0..3 {
                total[c] += s[c] * sa;
            }
            sky[v * ll.width + u] = s;
        }
    }
    for v in 0..ll.height {
        for u in 0..ll.width {
            let d = ll.dir(u, v);
            let (lobe, g) = (sun_lobe(p.kappa, d.dot(&p.sun)), ground(&d));
            let s = sky[v * ll.width + u];
            ll.rgb[v * ll.width + u] = std::array::from_fn(|c| {
                let w = &SKY_MAP_POWER;
                (w[0][c] * s[c] / total[c].max(f64::MIN_POSITIVE) + w[1][c] * lobe + w[2][c] * g)
                    as f32
            });
        }
    }
    Ok(ll)
}

/// Writes the workspace of scene `name` into `out` (created if missing).
pub fn build(name: &str, out: &Path, opts: &SynthOptions) -> Result<SynthSummary> {
    let def = find_scene(name)?;
    let n_photos = check_options(&def, opts)?;
    for dir in ["sparse", "images", "dense", "truth/env", "truth/masks"] {
        create_dir(&out.join(dir))?;
    }
    let up = Vec3::y();
    let frame = crate::sphere::env_frame(&up).ok_or_else(|| Error::Numeric {
        stage: "synth".into(),
        message: "no environment frame for the up vector".into(),
    })?;
    let object = make_object(&def, opts, out)?;
    // One random stream, drawn in a fixed order: cameras, lighting plan, white balance.
    let mut rng = Pcg32::new(opts.seed, 0x5eed);
    let cams = place_cameras(&mut rng, &def, opts, &object, &up, n_photos);
    let lighting = plan_lighting(&mut rng, &def, n_photos, opts)?;
    let shoot = photos::Shoot {
        object: &object,
        cams: &cams,
        lighting: &lighting,
        frame,
        opts,
        out,
    };
    let photos = photos::render_all(&mut rng, &shoot)?;
    let sparse = sparse::sparse_model(&object, &cams, &photos, opts)?;
    sparse.rec.write_text(&out.join("sparse"))?;
    object
        .mesh
        .write_ply(&out.join("dense/meshed-poisson.ply"), &[])?;
    write_weights(&object, &out.join("truth/weights.ply"))?;
    write_materials(&def, &object, &photos, &out.join("truth/materials.json"))?;
    let held_out = write_manifest(&def, opts, &object, &photos, &lighting, frame, out)?;
    Ok(SynthSummary {
        scene: def.name.to_string(),
        photos: photos.names,
        held_out,
        vertices: object.mesh.positions.len(),
        faces: object.mesh.faces.len(),
        points3d: sparse.rec.points3d.len(),
        observations: sparse.observations,
        render_seconds: photos.render_seconds,
    })
}

/// The scene called `name`.
fn find_scene(name: &str) -> Result<SceneDef> {
    scene_defs()
        .into_iter()
        .find(|d| d.name == name)
        .ok_or_else(|| {
            Error::Config(format!(
                "unknown scene `{name}`; known scenes: {}",
                scene_names().join(", ")
            ))
        })
}

/// Refuses options no workspace can be made with; returns the number of photos.
fn check_options(def: &SceneDef, opts: &SynthOptions) -> Result<usize> {
    if opts.width == 0 || opts.height == 0 {
        return Err(Error::Config("synth image size must be positive".into()));
    }
    if !(opts.noise.is_finite() && opts.noise >= 0.0) {
        return Err(Error::Config(format!("noise σ {} must be ≥ 0", opts.noise)));
    }
    if !(opts.exposure_peak.is_finite() && opts.exposure_peak > 0.0) {
        return Err(Error::Config(format!(
            "exposure peak {} must be a positive number",
            opts.exposure_peak
        )));
    }
    let n_photos = opts.photos.unwrap_or(def.photos);
    if n_photos == 0 {
        return Err(Error::Config("synth needs at least one photo".into()));
    }
    if opts.geotag && def.lighting != Lighting::Sky {
        return Err(Error::Config(format!(
            "--geotag needs a sun-and-sky scene (spot-sky); `{}` is lit by HDR maps",
            def.name
        )));
    }
    Ok(n_photos)
}

/// The scene's object as rendered and written: the cleaned mesh, its reflectance, its BVH,
/// and where the cameras look (`target`, with the object within `radius`).
pub(crate) struct Object {
    mesh: Mesh,
    refl: Reflectance,
    bvh: SceneBvh,
    target: Vec3,
    radius: f64,
}

/// The mesh (cleaned by the project's mesh code: the mesh written is the mesh rendered) and
/// its reflectance.
fn make_object(def: &SceneDef, opts: &SynthOptions, out: &Path) -> Result<Object> {
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
    Ok(Object {
        mesh,
        refl,
        bvh,
        target,
        radius,
    })
}

/// Cameras around and above the object, evenly spread in azimuth with jitter.
fn place_cameras(
    rng: &mut Pcg32,
    def: &SceneDef,
    opts: &SynthOptions,
    object: &Object,
    up: &Vec3,
    n_photos: usize,
) -> Vec<PinholeCamera> {
    let (target, radius) = (object.target, object.radius);
    let fov: f64 = 40.0;
    let dist = radius / (fov.to_radians() / 2.0 * 0.85).sin();
    let min_elev = if matches!(def.shape, Shape::SpherePlane | Shape::SpotTextured) {
        20.0
    } else {
        5.0
    };
    (0..n_photos)
        .map(|i| {
            let az = 2.0 * PI * (i as f64 + 0.6 * (rng.random::<f64>() - 0.5)) / n_photos as f64;
            let el = (min_elev + 35.0 * rng.random::<f64>()).to_radians();
            let eye = target + Vec3::new(el.cos() * az.cos(), el.sin(), el.cos() * az.sin()) * dist;
            look_at(&eye, &target, up, opts.width, opts.height, fov)
        })
        .collect()
}

/// The maps the photos are lit by, and per photo the map (index into `maps`), its
/// rotation in texels and, for a sun-and-sky map, its sun direction.
pub(crate) struct LightingPlan {
    maps: Vec<(String, LatLong)>,
    plan: Vec<(usize, usize, Option<Vec3>)>,
    /// Per photo its geotag ([`SynthOptions::geotag`]).
    geotags: Vec<Option<GeoTag>>,
    /// The frame azimuth of north under [`SynthOptions::geotag`].
    north: Option<f64>,
}

/// Latitude and longitude (degrees) of [`SynthOptions::geotag`]'s photos.
pub const GEOTAG_PLACE: (f64, f64) = (45.0, 7.0);
/// Their day: 2024-06-21, days after 1970-01-01.
pub const GEOTAG_DAY: i64 = 19_895;
/// Their span of UTC hours (about 06:30 to 17:30 local solar time there: the sun 16° to
/// 68° high).
pub const GEOTAG_HOURS: (f64, f64) = (6.0, 17.0);

/// A geotagged photo's tag and the sun it gives (environment frame).
struct TaggedSun {
    tag: GeoTag,
    sun: Vec3,
}

/// Photo `i` of `n`'s geotag and sun under [`SynthOptions::geotag`], north at frame
/// azimuth `north`.
fn clock_sun(rng: &mut Pcg32, i: usize, n: usize, north: f64) -> Result<TaggedSun> {
    use crate::solve::light::sky::clock::ClockSun;
    use crate::solve::light::sky::SunSky;
    let (h0, h1) = GEOTAG_HOURS;
    let hours = h0 + (h1 - h0) * (i as f64 + 0.5 * rng.random::<f64>()) / n as f64;
    let tag = GeoTag {
        latitude: GEOTAG_PLACE.0,
        longitude: GEOTAG_PLACE.1,
        utc_seconds: GEOTAG_DAY * 86_400 + (hours * 3600.0).round() as i64,
    };
    let sun = ClockSun::at(&tag)
        .ok_or_else(|| Error::Internal(format!("synth --geotag: no sun at {hours:.2} h UTC")))?;
    let theta = SunSky::from_angles(sun.frame_azimuth(north), sun.elevation, 3.0, 1.0);
    Ok(TaggedSun {
        tag,
        sun: theta.sun,
    })
}

/// Per photo a map and its rotation, as the scene's lighting says; with `shared_skies` a
/// map keeps the rotation drawn for the first photo it lights.
fn plan_lighting(
    rng: &mut Pcg32,
    def: &SceneDef,
    n_photos: usize,
    opts: &SynthOptions,
) -> Result<LightingPlan> {
    let mut maps: Vec<(String, LatLong)> = Vec::new();
    let mut plan: Vec<(usize, usize, Option<Vec3>)> = Vec::with_capacity(n_photos);
    let north = opts.geotag.then(|| 2.0 * PI * rng.random::<f64>());
    let mut geotags = vec![None; n_photos];
    for i in 0..n_photos {
        let (m, rotate) = match def.lighting {
            Lighting::Static(m) => (m, false),
            Lighting::Rotating(m) => (m, true),
            Lighting::Varying(list) => (list[i % list.len()], true),
            Lighting::Sky => {
                let sun = if let Some(north) = north {
                    let TaggedSun { tag, sun } = clock_sun(rng, i, n_photos, north)?;
                    geotags[i] = Some(tag);
                    sun
                } else {
                    let az = 2.0 * PI * (i as f64 + 0.5 * rng.random::<f64>()) / n_photos as f64;
                    let el = (20.0 + 40.0 * rng.random::<f64>()).to_radians();
                    Vec3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin())
                };
                maps.push(("sky".into(), sky_map(&sun, SKY_MAP_HEIGHT)?));
                plan.push((maps.len() - 1, 0, Some(sun)));
                continue;
            }
            Lighting::Grouped(list) => (list[i % list.len()], false),
        };
        let idx = match maps.iter().position(|x| x.0 == m) {
            Some(j) => j,
            None => {
                maps.push((m.to_string(), embedded_map(m)?));
                maps.len() - 1
            }
        };
        let earlier = plan.iter().find(|p| p.0 == idx).map(|p| p.1);
        let shift = match (rotate, earlier) {
            (true, Some(shift)) if opts.shared_skies => shift,
            (true, _) => rng.random_range(0..maps[idx].1.width),
            (false, _) => 0,
        };
        plan.push((idx, shift, None));
    }
    Ok(LightingPlan {
        maps,
        plan,
        geotags,
        north,
    })
}

/// `truth/weights.ply`: the mesh with per-vertex material weights `w0 … w{K-1}`.
fn write_weights(object: &Object, path: &Path) -> Result<()> {
    let (mesh, refl) = (&object.mesh, &object.refl);
    let k = refl.lambda.len();
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
    mesh.write_ply(path, &extra)
}

/// `truth/materials.json`: lobes, formulas, λ per material, and the photo model.
fn write_materials(def: &SceneDef, object: &Object, photos: &Rendered, path: &Path) -> Result<()> {
    let refl = &object.refl;
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
        photos: photos
            .truths
            .iter()
            .map(|t| PhotoScale {
                name: &t.name,
                exposure: t.exposure,
                white_balance: t.white_balance,
            })
            .collect(),
    };
    write_json(path, &mat_truth)
}

/// `truth/manifest.json`; returns the held-out photos' names.
fn write_manifest(
    def: &SceneDef,
    opts: &SynthOptions,
    object: &Object,
    photos: &Rendered,
    lighting: &LightingPlan,
    frame: [Vec3; 3],
    out: &Path,
) -> Result<Vec<String>> {
    let up = frame[2];
    let held_out: Vec<String> = photos
        .truths
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
        north_radians: lighting.north,
        held_out: held_out.clone(),
        photos: &photos.truths,
        image_size: [opts.width, opts.height],
        samples_per_pixel: opts.samples.per_pixel,
        light_sample_pairs: opts.samples.light,
        noise_sigma: opts.noise,
        vertices: object.mesh.positions.len(),
        faces: object.mesh.faces.len(),
        mesh: "dense/meshed-poisson.ply",
        weights: "truth/weights.ply",
        materials: "truth/materials.json",
        credits: "HDR maps: Greg Zaal (HDRI Haven), CC0, via Debian blender-data; Spot: Keenan Crane",
    };
    write_json(&out.join("truth/manifest.json"), &manifest)?;
    Ok(held_out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `(map, rotation)` of every photo of `scene`'s lighting plan.
    fn skies(scene: &str, shared_skies: bool) -> Vec<(usize, usize)> {
        let def = find_scene(scene).unwrap();
        let mut rng = Pcg32::new(3, 0x5eed);
        let opts = SynthOptions {
            shared_skies,
            ..SynthOptions::default()
        };
        let plan = plan_lighting(&mut rng, &def, 16, &opts).unwrap();
        plan.plan.iter().map(|p| (p.0, p.1)).collect()
    }

    #[test]
    fn shared_skies_give_photos_under_one_map_one_rotation() {
        // 16 photos cycling 8 maps: photo i and i + 8 see the same map. With shared skies
        // they see it at the same rotation; without, each draws its own from the map's
        // width in texels (the embedded maps are 64 texels wide or more, so at most a few
        // of the 8 pairs can agree by chance; all 8 agreeing would be the option ignored).
        let shared = skies("spot-diffuse", true);
        let own = skies("spot-diffuse", false);
        for i in 0..8 {
            assert_eq!(shared[i].0, shared[i + 8].0);
            assert_eq!(shared[i], shared[i + 8], "photo {i} and {}", i + 8);
            assert_eq!(own[i].0, own[i + 8].0);
        }
        let agreeing = (0..8).filter(|&i| own[i] == own[i + 8]).count();
        assert!(agreeing < 8, "own rotations agree on every pair");
        // Scenes whose map does not turn are unchanged by the option.
        assert_eq!(skies("spot-groups", true), skies("spot-groups", false));
    }

    #[test]
    fn geotagged_suns_follow_the_summer_day() {
        // 16 photos from 06:00 to 17:00 UTC at 45° N on the June solstice. Astronomy, not
        // the solar position code: the noon sun stands at 90° − 45° + 23.44° = 68.44°, so
        // no photo's sun is higher (0.05°: the algorithm's and the declination's rounding)
        // and the photo nearest noon (at most half a 41-minute slot away, where the sun
        // sinks by less than 3°) is within 3° of it; seen from above the sun turns
        // clockwise (east, south, west), so its frame azimuth falls from photo to photo.
        let def = find_scene("spot-sky").unwrap();
        let mut rng = Pcg32::new(3, 0x5eed);
        let opts = SynthOptions {
            geotag: true,
            ..SynthOptions::default()
        };
        let plan = plan_lighting(&mut rng, &def, 16, &opts).unwrap();
        assert!(plan.north.is_some() && plan.geotags.iter().all(Option::is_some));
        let suns: Vec<Vec3> = plan.plan.iter().map(|p| p.2.unwrap()).collect();
        let elev: Vec<f64> = suns.iter().map(|s| s.z.asin().to_degrees()).collect();
        let top = elev.iter().copied().fold(f64::MIN, f64::max);
        assert!((68.44 - 3.0..=68.44 + 0.05).contains(&top), "{elev:.2?}");
        for w in suns.windows(2) {
            // z-component of s_i × s_{i+1}: negative when the azimuth falls.
            assert!(w[0].x * w[1].y - w[0].y * w[1].x < 0.0, "{suns:?}");
        }
        // A scene lit by HDR maps refuses the option.
        let err = check_options(&find_scene("spot-diffuse").unwrap(), &opts).unwrap_err();
        assert!(err.to_string().contains("spot-sky"), "{err}");
    }
}
