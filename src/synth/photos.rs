//! `synth`'s photos: each rendered by the reference renderer under its planned map, then
//! exposed and encoded like a camera (module docs of [`super`]):
//! `pixel_c = sRGB8( clamp( e_I · wb_Ic · L_c + n, 0, 1 ) )`, with `e_I` putting the 99th
//! percentile of the object's `max_c wb_Ic L_c` at 1.

use super::*;
use crate::transport::reference::ReferenceImage;

/// What rendering needs from the earlier steps of [`super::build`].
pub(super) struct Shoot<'a> {
    pub(super) object: &'a Object,
    pub(super) cams: &'a [PinholeCamera],
    pub(super) lighting: &'a LightingPlan,
    pub(super) frame: [Vec3; 3],
    pub(super) opts: &'a SynthOptions,
    pub(super) out: &'a Path,
}

/// The photos written, with their truth.
pub(super) struct Rendered {
    /// File names, in image-id order.
    pub(super) names: Vec<String>,
    pub(super) truths: Vec<PhotoTruth>,
    /// Each photo's 8-bit sRGB bytes (the sparse points take their colour from them).
    pub(super) photos8: Vec<Vec<u8>>,
    pub(super) render_seconds: f64,
}

/// Renders, exposes and writes every photo with its mask and truth map. `rng` gives the
/// white balance (the stream's last use in [`super::build`]).
pub(super) fn render_all(rng: &mut Pcg32, shoot: &Shoot) -> Result<Rendered> {
    let (opts, out) = (shoot.opts, shoot.out);
    let n_photos = shoot.cams.len();
    let names: Vec<String> = (0..n_photos).map(|i| format!("photo_{i:03}.png")).collect();
    let held: Vec<bool> = (0..n_photos).map(|i| n_photos >= 4 && i % 4 == 3).collect();
    let mut truths = Vec::with_capacity(n_photos);
    let mut photos8: Vec<Vec<u8>> = Vec::with_capacity(n_photos);
    let mut render_seconds = 0.0;
    for (i, cam) in shoot.cams.iter().enumerate() {
        let (mi, shift, sun) = shoot.lighting.plan[i];
        let maps = &shoot.lighting.maps;
        let env_map = rotate_texels(&maps[mi].1, shift);
        let stem = names[i].trim_end_matches(".png");
        let env_rel = format!("env/{stem}.exr");
        data::write_exr(&env_map, &out.join("truth").join(&env_rel), false)?;
        let env = Environment::new(env_map.width, env_map.height, &env_map.rgb, shoot.frame)?;
        let t0 = std::time::Instant::now();
        let img = render_photo(shoot.object, &env, cam, opts, i);
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
        let exposure = opts.exposure_peak * exposure(&img, &wb);
        let img = if opts.sky_background {
            with_sky(img, &env, cam)
        } else {
            img
        };
        let bytes = encode(&img, exposure, &wb, opts, i);
        let size = (opts.width, opts.height);
        let exif = match &shoot.lighting.geotags[i] {
            Some(tag) => Some(crate::import::geotag::exif_block(tag)?),
            None => None,
        };
        save_png_exif(
            &out.join("images").join(&names[i]),
            size.0,
            size.1,
            bytes.clone(),
            3,
            exif,
        )?;
        save_png(
            &out.join("truth/masks").join(&names[i]),
            size.0,
            size.1,
            mask(&img),
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
    Ok(Rendered {
        names,
        truths,
        photos8,
        render_seconds,
    })
}

/// Photo `i` of `object` under `env` by the reference renderer, with its own sample seed.
fn render_photo(
    object: &Object,
    env: &Environment,
    cam: &PinholeCamera,
    opts: &SynthOptions,
    i: usize,
) -> ReferenceImage {
    let scene = ReferenceScene {
        positions: &object.mesh.positions,
        normals: &object.mesh.normals,
        faces: &object.mesh.faces,
        reflectance: &object.refl,
        env,
        caster: &object.bvh,
        offset: object.bvh.ray_offset(),
    };
    let samples = Samples {
        seed: opts.samples.seed ^ opts.seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ (i as u64) << 40,
        ..opts.samples
    };
    scene.render(cam, &samples)
}

/// `img` with each pixel's uncovered share showing the light along the ray through its
/// centre: `rgb += (1 − coverage) L̃(d)` ([`SynthOptions::sky_background`]).
fn with_sky(mut img: ReferenceImage, env: &Environment, cam: &PinholeCamera) -> ReferenceImage {
    let w = img.width;
    for (i, (p, &cov)) in img.rgb.iter_mut().zip(&img.coverage).enumerate() {
        if cov >= 1.0 {
            continue;
        }
        let d = cam.ray_dir((i % w) as f64 + 0.5, (i / w) as f64 + 0.5);
        let l = env.radiance(&d);
        for c in 0..3 {
            p[c] += ((1.0 - f64::from(cov)) * l[c]) as f32;
        }
    }
    img
}

/// Exposure: the 99th percentile of the object's brightest channel (after white balance
/// `wb`) maps to 1.
fn exposure(img: &ReferenceImage, wb: &[f64; 3]) -> f64 {
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
    if p99 > 0.0 {
        1.0 / p99
    } else {
        1.0
    }
}

/// The photo's 8-bit sRGB bytes: exposed, white-balanced, with photo `i`'s seeded noise.
fn encode(
    img: &ReferenceImage,
    exposure: f64,
    wb: &[f64; 3],
    opts: &SynthOptions,
    i: usize,
) -> Vec<u8> {
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
    bytes
}

/// The object's coverage as an 8-bit mask.
fn mask(img: &ReferenceImage) -> Vec<u8> {
    img.coverage
        .iter()
        .map(|&c| (c * 255.0).round() as u8)
        .collect()
}
