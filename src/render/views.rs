//! What `relight-cpc render` puts around the object and how it names and moves its views:
//! backgrounds, turntable orbits and output names.
//!
//! - Background `env`: a pixel the object does not cover shows the light arriving along the
//!   camera ray, `L̃(R_env · Rᵀ K⁻¹ (x, y, 1))`, looked up bilinearly in the lat-long map
//!   (environment frame, docs/conventions.md) — the same map, rotation and sun the object is lit by.
//!   `transparent`: alpha 0 outside the object (the default). A colour: that sRGB colour.
//! - Turntable: frame `i` of `N` is the camera orbited by `θ_i = 360° · i / N` about the
//!   environment's up axis `e_z` through the centre of the mesh's bounding box: with `A` the
//!   rotation by `θ_i` about that axis, `X_cam = R Aᵀ (X − c) + R c + t`, i.e.
//!   `R' = R Aᵀ`, `t' = t + R (c − Aᵀ c)`. The light stays fixed in the world, so the object
//!   turns under it as on a turntable seen by a camera that moves with the table.
//! - Names: `MAP__CAMERA` (`MAP` the map's file stem, `+sun` when a sun is added, `_rotDEG`
//!   when rotated; `sun` without a map), `_orbitNNN` per turntable frame, so renders under
//!   different maps, rotations and cameras never overwrite each other.

use crate::import::colmap::{Camera, Image};
use crate::sphere::envmap::LatLong;
use crate::{Error, Result, Vec3};
use nalgebra::{Matrix3, Rotation3, Unit};
use std::path::Path;

/// What fills the pixels the object does not cover.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Background {
    /// The environment map seen along each camera ray.
    Env,
    /// Alpha 0.
    Transparent,
    /// One colour, linear RGB.
    Colour([f32; 3]),
}

impl std::str::FromStr for Background {
    type Err = String;

    /// `env`, `transparent`, `black`, `white`, `grey`, or an sRGB colour `#RRGGBB`.
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        let srgb = |v: [u8; 3]| {
            Background::Colour(v.map(|c| crate::import::photo::srgb_to_linear(c as f32 / 255.0)))
        };
        match s.to_ascii_lowercase().as_str() {
            "env" => Ok(Background::Env),
            "transparent" => Ok(Background::Transparent),
            "black" => Ok(srgb([0, 0, 0])),
            "white" => Ok(srgb([255, 255, 255])),
            "grey" | "gray" => Ok(srgb([128, 128, 128])),
            hex if hex.len() == 7 && hex.starts_with('#') => {
                let byte = |i: usize| u8::from_str_radix(&hex[i..i + 2], 16);
                match (byte(1), byte(3), byte(5)) {
                    (Ok(r), Ok(g), Ok(b)) => Ok(srgb([r, g, b])),
                    _ => Err(format!("`{s}`: not a #RRGGBB colour")),
                }
            }
            _ => Err(format!(
                "`{s}`: expected env, transparent, black, white, grey or #RRGGBB"
            )),
        }
    }
}

/// Fill the pixels outside `mask` of a `camera`/`image` view: `Env` looks each pixel's ray
/// up in `light` (lat-long, environment frame `env_from_world`), `Colour` paints it,
/// `Transparent` leaves it. Returns whether the image keeps an alpha channel.
pub fn fill_background(
    rgb: &mut [[f32; 3]],
    mask: &[bool],
    background: Background,
    view: (&Camera, &Image),
    light: &LatLong,
    env_from_world: &Matrix3<f64>,
) -> bool {
    let (camera, image) = view;
    let world_from_cam = image.cam_from_world_rotation().transpose();
    let w = camera.width as usize;
    for (i, (p, &inside)) in rgb.iter_mut().zip(mask).enumerate() {
        if inside {
            continue;
        }
        *p = match background {
            Background::Transparent => return true,
            Background::Colour(c) => c,
            Background::Env => {
                let pixel = [(i % w) as f64 + 0.5, (i / w) as f64 + 0.5];
                match camera.unproject(pixel) {
                    Some(ray) => light.lookup(&(env_from_world * (world_from_cam * ray))),
                    None => [0.0; 3],
                }
            }
        };
    }
    false
}

/// The pose of turntable frame `i` of `n` (module docs): `image` orbited about the unit
/// axis `up` (world) through `centre`.
pub fn orbit(image: &Image, up: &Vec3, centre: &Vec3, i: usize, n: usize) -> Result<Image> {
    if n == 0 {
        return Err(Error::Config("--turntable: at least 1 frame".into()));
    }
    let axis = Unit::try_new(*up, 1e-12)
        .ok_or_else(|| Error::Config("turntable: the up axis is zero".into()))?;
    let a = Rotation3::from_axis_angle(&axis, 2.0 * std::f64::consts::PI * i as f64 / n as f64);
    let r = image.cam_from_world_rotation();
    let t = Vec3::from(image.tvec);
    let r_new = r * a.transpose();
    let t_new = t + r * (centre - a.transpose() * centre);
    let mut out = Image::from_pose(
        image.id,
        image.name.clone(),
        image.camera_id,
        &r_new,
        &t_new,
    );
    out.points2d.clear();
    Ok(out)
}

/// The light's part of output names (module docs): the map's file stem, `+sun`, `_rotDEG`.
pub fn light_name(env: Option<&Path>, sun: bool, rotate_deg: f64) -> String {
    let mut s = match env {
        Some(p) => file_stem(
            &p.file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_else(|| "map".into()),
        ),
        None => String::new(),
    };
    if sun {
        s.push_str(if s.is_empty() { "sun" } else { "+sun" });
    }
    if rotate_deg != 0.0 {
        let deg = format!("{rotate_deg}").replace('.', "p").replace('-', "m");
        s.push_str(&format!("_rot{deg}"));
    }
    s
}

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

/// The output stem of one view: `LIGHT__CAMERA`, `_orbitNNN` for turntable frame `frame`.
pub fn output_stem(light: &str, camera_name: &str, frame: Option<usize>) -> String {
    let cam = file_stem(camera_name);
    match frame {
        Some(i) => format!("{light}__{cam}_orbit{i:03}"),
        None => format!("{light}__{cam}"),
    }
}

/// Write the frames (sRGB, equal sizes) as an endlessly looping animated GIF at `fps`, with
/// the `image` crate's GIF encoder (256-colour palette per frame).
pub fn write_gif(path: &Path, frames: &[image::RgbaImage], fps: u32) -> Result<()> {
    use image::codecs::gif::{GifEncoder, Repeat};
    let err = |e: image::ImageError| Error::Image {
        path: path.to_path_buf(),
        message: format!("cannot write GIF: {e}"),
    };
    let mut bytes = Vec::new();
    {
        let mut enc = GifEncoder::new_with_speed(&mut bytes, 10);
        enc.set_repeat(Repeat::Infinite).map_err(err)?;
        let delay = image::Delay::from_numer_denom_ms(1000, fps.max(1));
        for f in frames {
            enc.encode_frame(image::Frame::from_parts(f.clone(), 0, 0, delay))
                .map_err(err)?;
        }
    }
    crate::out_dir::write_atomic(path, &bytes)
}

/// Encode numbered PNG frames `DIR/STEM_orbit%03d.png` into `OUT` (MP4, H.264) with ffmpeg
/// when it is on the PATH; `Ok(false)` when it is not.
pub fn write_video(dir: &Path, stem_prefix: &str, out: &Path, fps: u32) -> Result<bool> {
    let probe = std::process::Command::new("ffmpeg")
        .arg("-version")
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .status();
    if !probe.is_ok_and(|s| s.success()) {
        return Ok(false);
    }
    let pattern = dir.join(format!("{stem_prefix}_orbit%03d.png"));
    let status = std::process::Command::new("ffmpeg")
        .args([
            "-y",
            "-loglevel",
            "error",
            "-framerate",
            &fps.to_string(),
            "-i",
        ])
        .arg(&pattern)
        .args([
            "-vf",
            "pad=ceil(iw/2)*2:ceil(ih/2)*2",
            "-pix_fmt",
            "yuv420p",
            "-c:v",
            "libx264",
        ])
        .arg(out)
        .status()
        .map_err(|e| Error::io(out, e))?;
    if !status.success() {
        return Err(Error::Image {
            path: out.to_path_buf(),
            message: format!("ffmpeg failed ({status}) encoding {}", pattern.display()),
        });
    }
    Ok(true)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::import::colmap::{CameraId, ImageId};

    /// Orbiting by θ about an axis through c moves the camera centre by exactly that
    /// rotation (checked against nalgebra's rotation of the centre, 1e-12), keeps the
    /// distance to c, and the frame-0 pose is the original.
    #[test]
    fn orbit_rotates_the_camera_centre_about_the_axis() {
        let r = Rotation3::from_euler_angles(0.3, -0.2, 1.1);
        let im = Image::from_pose(
            ImageId(1),
            "a.png",
            CameraId(1),
            &r,
            &Vec3::new(0.1, 0.2, 3.0),
        );
        let (up, c) = (Vec3::new(0.0, 0.0, 1.0), Vec3::new(0.5, -0.5, 0.2));
        let same = orbit(&im, &up, &c, 0, 4).unwrap();
        assert!((same.center() - im.center()).norm() < 1e-12);
        let q = orbit(&im, &up, &c, 1, 4).unwrap();
        let a = Rotation3::from_axis_angle(&Vec3::z_axis(), std::f64::consts::FRAC_PI_2);
        let want = a * (im.center() - c) + c;
        assert!(
            (q.center() - want).norm() < 1e-12,
            "{} vs {want}",
            q.center()
        );
        // The point the camera looked at (c) stays where it was in the image.
        let before = im.cam_from_world_point(&c);
        let after = q.cam_from_world_point(&c);
        assert!((before - after).norm() < 1e-12);
    }

    #[test]
    fn names_carry_map_rotation_and_camera() {
        let l = light_name(Some(Path::new("maps/sunset.hdr")), false, 90.0);
        assert_eq!(l, "sunset_rot90");
        assert_eq!(
            output_stem(&l, "dir/photo_001.png", None),
            "sunset_rot90__dir_photo_001"
        );
        assert_eq!(light_name(None, true, -12.5), "sun_rotm12p5");
        assert_eq!(output_stem("a", "b.jpg", Some(7)), "a__b_orbit007");
    }

    #[test]
    fn background_parses() {
        assert_eq!("env".parse::<Background>().unwrap(), Background::Env);
        assert_eq!(
            "#ffffff".parse::<Background>().unwrap(),
            Background::Colour([1.0; 3])
        );
        assert!("#ggg000".parse::<Background>().is_err());
        assert!("purple".parse::<Background>().is_err());
    }
}
