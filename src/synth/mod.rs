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

mod scenes;
mod truth;

use scenes::{embedded_map, make_geometry, make_weights, scene_defs, Lighting, Shape};
pub use scenes::{look_at, rotate_texels, scene_names};
use truth::{
    create_dir, gaussian, save_png, write_json, Manifest, MaterialTruth, MaterialsTruth,
    PhotoScale, PhotoTruth,
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
    /// that many. Spot scenes only (`spot-varying`, `spot-ggx`, `spot-sky`, `spot-static`).
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

    // Lighting plan: per photo a map (index into `maps`), its rotation and its sun.
    let mut maps: Vec<(String, LatLong)> = Vec::new();
    let mut plan: Vec<(usize, usize, Option<Vec3>)> = Vec::with_capacity(n_photos);
    for i in 0..n_photos {
        let (m, rotate) = match def.lighting {
            Lighting::Static(m) => (m, false),
            Lighting::Rotating(m) => (m, true),
            Lighting::Varying(list) => (list[i % list.len()], true),
            Lighting::Sky => {
                let az = 2.0 * PI * (i as f64 + 0.5 * rng.random::<f64>()) / n_photos as f64;
                let el = (20.0 + 40.0 * rng.random::<f64>()).to_radians();
                let sun = Vec3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin());
                maps.push(("sky".into(), sky_map(&sun, SKY_MAP_HEIGHT)?));
                plan.push((maps.len() - 1, 0, Some(sun)));
                continue;
            }
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
        plan.push((idx, shift, None));
    }

    // Render, expose, encode.
    let names: Vec<String> = (0..n_photos).map(|i| format!("photo_{i:03}.png")).collect();
    let held: Vec<bool> = (0..n_photos).map(|i| n_photos >= 4 && i % 4 == 3).collect();
    let mut truths = Vec::with_capacity(n_photos);
    let mut photos8: Vec<Vec<u8>> = Vec::with_capacity(n_photos);
    let mut render_seconds = 0.0;
    for (i, cam) in cams.iter().enumerate() {
        let (mi, shift, sun) = plan[i];
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
            sun: sun.map(|v| [v.x, v.y, v.z]),
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
