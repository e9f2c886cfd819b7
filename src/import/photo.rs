//! Photos as linear RGB with an overexposure mask: the observations `y_p` of the paper's
//! objective (Eq. 9) are samples of these, and overexposed pixels get confidence `α_p = 0`.
//!
//! Decoding (docs/conventions.md):
//! - 8- and 16-bit PNG and JPEG (the `image` crate) are sRGB-encoded. Each channel value
//!   `c ∈ [0, 1]` (code / 255 or code / 65535) is decoded with the exact piecewise curve of
//!   IEC 61966-2-1: `c / 12.92` for `c ≤ 0.04045`, else `((c + 0.055) / 1.055)^2.4`.
//! - A pixel is *overexposed* when any channel's encoded value is `≥ clip_threshold`
//!   (default 250/255), i.e. the sensor or the JPEG encoder may have clipped it.
//! - EXR (the `exr` crate) is already linear and may exceed 1: there is no encoded scale to
//!   clip on, so only non-finite or negative-infinite samples are marked overexposed (and
//!   stored as 0). A user who knows an EXR's clip level can mask it before import.
//!
//! The capture time ([`capture_time`]) is the EXIF `DateTimeOriginal` of JPEG, PNG,
//! TIFF, HEIF and WebP files (the `kamadak-exif` crate), read on the camera's clock with no
//! time zone: it only groups photos taken close together (shared light,
//! [`crate::solve::light::shared`]).
//!
//! Pixel coordinates follow COLMAP: the top-left pixel's centre is `(0.5, 0.5)`, x right,
//! y down. [`Photo::sample`] interpolates bilinearly between pixel centres.

use std::path::Path;

use crate::{Error, Result};

/// The default overexposure threshold on the encoded `[0, 1]` scale.
pub const DEFAULT_CLIP: f32 = 250.0 / 255.0;

/// A decoded photo.
#[derive(Debug, Clone, Default)]
pub struct Photo {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Linear RGB, row-major, `width · height` entries (row 0 at the top).
    pub rgb: Vec<[f32; 3]>,
    /// Per pixel: any channel at or above the clip threshold.
    pub overexposed: Vec<bool>,
    /// The clip threshold in linear units: a channel at or above it may have been clipped,
    /// so its true value is at least this ([`Sample::clipped`]); `f32::INFINITY` when the
    /// format has none (EXR, [`Photo::from_linear`]).
    pub clip_level: f32,
}

/// A bilinear sample of a photo ([`Photo::sample_bounds`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// Linear RGB.
    pub rgb: [f32; 3],
    /// Whether any pixel contributing with non-zero weight is overexposed.
    pub overexposed: bool,
    /// Bit `c` set when a contributing pixel's channel `c` is at or above
    /// [`Photo::clip_level`]: the sample's channel `c` is then a lower bound of the
    /// radiance (the other pixels are exact, the clipped one at least its value).
    pub clipped: u8,
}

/// sRGB decoding, exact piecewise curve (IEC 61966-2-1): encoded `[0, 1]` → linear.
pub fn srgb_to_linear(v: f32) -> f32 {
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// sRGB encoding, the inverse of [`srgb_to_linear`]: linear → encoded `[0, 1]` scale
/// (values outside `[0, 1]` are clamped first).
pub fn linear_to_srgb(v: f32) -> f32 {
    let v = v.clamp(0.0, 1.0);
    if v <= 0.0031308 {
        v * 12.92
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

fn image_error(path: &Path, message: impl Into<String>) -> Error {
    Error::Image {
        path: path.to_path_buf(),
        message: message.into(),
    }
}

impl Photo {
    /// A photo from linear RGB values (row-major), nothing overexposed.
    /// `rgb.len()` must be `width · height`; a shorter or longer vector is cut or padded
    /// with black so the struct stays consistent.
    pub fn from_linear(width: u32, height: u32, rgb: Vec<[f32; 3]>) -> Photo {
        let n = width as usize * height as usize;
        let mut rgb = rgb;
        rgb.resize(n, [0.0; 3]);
        Photo {
            width,
            height,
            rgb,
            overexposed: vec![false; n],
            clip_level: f32::INFINITY,
        }
    }

    /// Loads a PNG, JPEG or EXR file (by its content for PNG/JPEG, by the `.exr` extension
    /// for EXR) into linear RGB and the overexposure mask (module docs).
    /// `clip_threshold` is on the encoded `[0, 1]` scale ([`DEFAULT_CLIP`]).
    pub fn load(path: &Path, clip_threshold: f32) -> Result<Photo> {
        if !path.exists() {
            return Err(Error::io(
                path,
                std::io::Error::new(std::io::ErrorKind::NotFound, "photo not found"),
            ));
        }
        let is_exr = path
            .extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| e.eq_ignore_ascii_case("exr"));
        if is_exr {
            return load_exr(path);
        }
        let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
        // The JPEG decoder fills a truncated file's missing rows without an error.
        crate::import::jpeg_end::check_complete(&bytes)
            .map_err(|truncated| image_error(path, truncated.to_string()))?;
        let reader = image::ImageReader::new(std::io::Cursor::new(bytes))
            .with_guessed_format()
            .map_err(|e| Error::io(path, e))?;
        let img = reader
            .decode()
            .map_err(|e| image_error(path, format!("cannot decode image: {e}")))?;
        let (width, height) = (img.width(), img.height());
        let n = width as usize * height as usize;
        let mut rgb = Vec::with_capacity(n);
        let mut overexposed = Vec::with_capacity(n);
        let clip_level;
        match img {
            image::DynamicImage::ImageLuma8(_)
            | image::DynamicImage::ImageLumaA8(_)
            | image::DynamicImage::ImageRgb8(_)
            | image::DynamicImage::ImageRgba8(_) => {
                // 8 bit: one table lookup per channel.
                let lut: Vec<f32> = (0..256).map(|c| srgb_to_linear(c as f32 / 255.0)).collect();
                let clip = clip_code(clip_threshold, 255.0);
                clip_level = level_of_code(clip, 255.0);
                for px in img.into_rgb8().pixels() {
                    let [r, g, b] = px.0;
                    rgb.push([lut[r as usize], lut[g as usize], lut[b as usize]]);
                    overexposed.push(r as f64 >= clip || g as f64 >= clip || b as f64 >= clip);
                }
            }
            other => {
                let clip = clip_code(clip_threshold, 65535.0);
                clip_level = level_of_code(clip, 65535.0);
                for px in other.into_rgb16().pixels() {
                    let [r, g, b] = px.0;
                    rgb.push([r, g, b].map(|c| srgb_to_linear(c as f32 / 65535.0)));
                    overexposed.push(r as f64 >= clip || g as f64 >= clip || b as f64 >= clip);
                }
            }
        }
        Ok(Photo {
            width,
            height,
            rgb,
            overexposed,
            clip_level,
        })
    }

    /// Fraction of pixels marked overexposed.
    pub fn overexposed_fraction(&self) -> f64 {
        if self.overexposed.is_empty() {
            return 0.0;
        }
        self.overexposed.iter().filter(|&&o| o).count() as f64 / self.overexposed.len() as f64
    }

    /// Linear RGB at `pixel = [x, y]` (COLMAP pixel coordinates, centres at `+0.5`),
    /// bilinear between the four nearest pixel centres, clamped to the edge within the
    /// image's half-pixel border. `None` outside `[0, width] × [0, height]`. The flag is true
    /// when any pixel contributing with non-zero weight is overexposed.
    pub fn sample(&self, pixel: [f64; 2]) -> Option<([f32; 3], bool)> {
        self.sample_bounds(pixel).map(|s| (s.rgb, s.overexposed))
    }

    /// [`Photo::sample`] with the channels that are lower bounds ([`Sample::clipped`]).
    pub fn sample_bounds(&self, pixel: [f64; 2]) -> Option<Sample> {
        let (w, h) = (self.width as f64, self.height as f64);
        let [x, y] = pixel;
        if !(x >= 0.0 && x <= w && y >= 0.0 && y <= h) || self.rgb.is_empty() {
            return None;
        }
        // Continuous index with pixel centres at integers, clamped to the centre range.
        let fx = (x - 0.5).clamp(0.0, w - 1.0);
        let fy = (y - 0.5).clamp(0.0, h - 1.0);
        let (x0, y0) = (fx.floor() as usize, fy.floor() as usize);
        let (x1, y1) = (
            (x0 + 1).min(self.width as usize - 1),
            (y0 + 1).min(self.height as usize - 1),
        );
        let (tx, ty) = ((fx - x0 as f64) as f32, (fy - y0 as f64) as f32);
        let stride = self.width as usize;
        let taps = [
            (y0 * stride + x0, (1.0 - tx) * (1.0 - ty)),
            (y0 * stride + x1, tx * (1.0 - ty)),
            (y1 * stride + x0, (1.0 - tx) * ty),
            (y1 * stride + x1, tx * ty),
        ];
        let mut out = Sample {
            rgb: [0.0; 3],
            overexposed: false,
            clipped: 0,
        };
        for (i, wgt) in taps.into_iter().filter(|t| t.1 > 0.0) {
            out.overexposed |= self.overexposed[i];
            for (c, v) in self.rgb[i].into_iter().enumerate() {
                out.rgb[c] += wgt * v;
                if v >= self.clip_level {
                    out.clipped |= 1 << c;
                }
            }
        }
        Some(out)
    }
}

/// The linear value of integer code `code` on a `max_code` scale (the clip level of
/// [`Photo::clip_level`]); infinite above the scale, where nothing can clip.
fn level_of_code(code: f64, max_code: f64) -> f32 {
    if code > max_code {
        f32::INFINITY
    } else {
        // The decoding tables' own arithmetic (f32 division), so a clipped code's value
        // compares equal.
        srgb_to_linear(code as f32 / max_code as f32)
    }
}

/// The smallest integer code counted as clipped for a threshold on the `[0, 1]` scale.
/// Rounded to the nearest code so 250/255 in f32 means code 250 exactly.
fn clip_code(threshold: f32, max_code: f64) -> f64 {
    (threshold as f64 * max_code).round()
}

fn load_exr(path: &Path) -> Result<Photo> {
    use exr::prelude::*;
    struct Buf {
        width: usize,
        rgb: Vec<[f32; 3]>,
        over: Vec<bool>,
    }
    let image = read_first_rgba_layer_from_file(
        path,
        |resolution: Vec2<usize>, _| Buf {
            width: resolution.width(),
            rgb: vec![[0.0; 3]; resolution.width() * resolution.height()],
            over: vec![false; resolution.width() * resolution.height()],
        },
        |buf: &mut Buf, pos: Vec2<usize>, (r, g, b, _a): (f32, f32, f32, f32)| {
            let i = pos.y() * buf.width + pos.x();
            if r.is_finite() && g.is_finite() && b.is_finite() {
                buf.rgb[i] = [r, g, b];
            } else {
                buf.over[i] = true;
            }
        },
    )
    .map_err(|e| image_error(path, format!("cannot read EXR: {e}")))?;
    let size = image.layer_data.size;
    let buf = image.layer_data.channel_data.pixels;
    Ok(Photo {
        width: size.width() as u32,
        height: size.height() as u32,
        rgb: buf.rgb,
        overexposed: buf.over,
        clip_level: f32::INFINITY,
    })
}

/// The EXIF `DateTimeOriginal` of the image at `path` as seconds on the camera's clock
/// (days from 1970-01-01 in the proleptic Gregorian calendar × 86,400 + time of day; no
/// time zone); `None` when the file has no EXIF block, no such field, or an unreadable
/// one: a missing time only means the photo is not grouped by time.
pub fn capture_time(path: &Path) -> Option<i64> {
    let file = std::fs::File::open(path).ok()?;
    let exif = exif::Reader::new()
        .read_from_container(&mut std::io::BufReader::new(file))
        .ok()?;
    let field = exif.get_field(exif::Tag::DateTimeOriginal, exif::In::PRIMARY)?;
    let exif::Value::Ascii(ref parts) = field.value else {
        return None;
    };
    let t = exif::DateTime::from_ascii(parts.first()?).ok()?;
    let valid = (1..=12).contains(&t.month)
        && (1..=31).contains(&t.day)
        && t.hour < 24
        && t.minute < 60
        && t.second < 61;
    valid.then(|| {
        let days = crate::import::calendar::days_from_civil(
            i64::from(t.year),
            i64::from(t.month),
            i64::from(t.day),
        );
        days * 86_400 + i64::from(t.hour) * 3600 + i64::from(t.minute) * 60 + i64::from(t.second)
    })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    #[test]
    fn srgb_curve_is_continuous_and_inverts() {
        // The two pieces meet at 0.04045 within f32 rounding (the standard's constants are
        // rounded: the gap is ~1e-7 relative), and encode ∘ decode is the identity to 1e-6.
        let a = 0.04045f32 / 12.92;
        let b = ((0.04045f32 + 0.055) / 1.055).powf(2.4);
        assert!((a - b).abs() < 1e-6 * a.max(1e-3));
        for i in 0..=1000 {
            let v = i as f32 / 1000.0;
            assert!((linear_to_srgb(srgb_to_linear(v)) - v).abs() < 2e-6, "{v}");
        }
        // Known points: 0 → 0, 1 → 1, code 128 → 0.2158605 (published sRGB tables).
        assert_eq!(srgb_to_linear(0.0), 0.0);
        assert!((srgb_to_linear(1.0) - 1.0).abs() < 1e-6);
        assert!((srgb_to_linear(128.0 / 255.0) - 0.215_860_5).abs() < 1e-6);
    }

    #[test]
    fn bilinear_sample_reproduces_an_affine_image() {
        // Bilinear interpolation is exact for an affine function of the pixel centre, so
        // sampling f(x, y) = 0.1 + 0.01 x + 0.02 y anywhere between centres returns f
        // (f32 arithmetic: 1e-5).
        let (w, h) = (7u32, 5u32);
        let f = |x: f64, y: f64| (0.1 + 0.01 * x + 0.02 * y) as f32;
        let rgb = (0..h)
            .flat_map(|j| (0..w).map(move |i| (i, j)))
            .map(|(i, j)| {
                let v = f(i as f64 + 0.5, j as f64 + 0.5);
                [v, 2.0 * v, 3.0 * v]
            })
            .collect();
        let photo = Photo::from_linear(w, h, rgb);
        for &(x, y) in &[(0.5, 0.5), (1.3, 2.7), (6.5, 4.5), (3.0, 3.0), (5.9, 0.6)] {
            let (s, over) = photo.sample([x, y]).unwrap();
            assert!(!over);
            assert!((s[0] - f(x, y)).abs() < 1e-5, "{x},{y}: {s:?}");
            assert!((s[2] - 3.0 * f(x, y)).abs() < 3e-5);
        }
        assert!(photo.sample([-0.1, 1.0]).is_none());
        assert!(photo.sample([1.0, 5.01]).is_none());
        assert!(photo.sample([f64::NAN, 1.0]).is_none());
    }

    #[test]
    fn clipped_channels_are_flagged_per_channel_on_the_encoded_scale() {
        // A 2×1 PNG: (255, 10, 249) then (100, 250, 100). With the clip at 250/255, the
        // first pixel's red and the second's green are at or above it (249 is not); a
        // sample flags a channel when a pixel contributing to it with non-zero weight does.
        let dir = std::env::temp_dir().join(format!("relight-clip-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("c.png");
        let mut img = image::RgbImage::new(2, 1);
        img.put_pixel(0, 0, image::Rgb([255, 10, 249]));
        img.put_pixel(1, 0, image::Rgb([100, 250, 100]));
        img.save(&path).unwrap();
        let photo = Photo::load(&path, DEFAULT_CLIP).unwrap();
        assert_eq!(photo.clip_level, srgb_to_linear(250.0 / 255.0));
        let at = |x: f64| photo.sample_bounds([x, 0.5]).unwrap();
        assert_eq!((at(0.5).clipped, at(0.5).overexposed), (0b001, true));
        assert_eq!((at(1.5).clipped, at(1.5).overexposed), (0b010, true));
        assert_eq!(at(1.0).clipped, 0b011);
        // Without an encoded scale nothing is a bound.
        let linear = Photo::from_linear(1, 1, vec![[5.0; 3]]);
        assert_eq!(linear.sample_bounds([0.5, 0.5]).unwrap().clipped, 0);
        std::fs::remove_dir_all(&dir).ok();
    }

    /// A 4×4 grey JPEG whose EXIF block (an APP1 segment after the start-of-image marker,
    /// as cameras write it) holds `DateTimeOriginal = stamp`.
    pub(crate) fn jpeg_with_capture_time(stamp: &str) -> Vec<u8> {
        let mut jpeg = Vec::new();
        image::RgbImage::from_pixel(4, 4, image::Rgb([128, 128, 128]))
            .write_to(
                &mut std::io::Cursor::new(&mut jpeg),
                image::ImageFormat::Jpeg,
            )
            .unwrap();
        let field = exif::Field {
            tag: exif::Tag::DateTimeOriginal,
            ifd_num: exif::In::PRIMARY,
            value: exif::Value::Ascii(vec![stamp.as_bytes().to_vec()]),
        };
        let mut writer = exif::experimental::Writer::new();
        writer.push_field(&field);
        let mut tiff = std::io::Cursor::new(Vec::new());
        writer.write(&mut tiff, false).unwrap();
        let tiff = tiff.into_inner();
        let mut app1 = vec![0xFF, 0xE1];
        app1.extend(((tiff.len() + 8) as u16).to_be_bytes());
        app1.extend(b"Exif\0\0");
        app1.extend(tiff);
        let mut out = jpeg[..2].to_vec();
        out.extend(app1);
        out.extend(&jpeg[2..]);
        out
    }

    #[test]
    fn capture_time_reads_date_time_original() {
        let dir = std::env::temp_dir().join(format!("relight-exif-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let a = dir.join("a.jpg");
        let b = dir.join("b.jpg");
        std::fs::write(&a, jpeg_with_capture_time("2024:02:29 23:59:30")).unwrap();
        std::fs::write(&b, jpeg_with_capture_time("2024:03:01 00:04:30")).unwrap();
        // The image still decodes with the EXIF block in it.
        assert!(Photo::load(&a, 1.0).is_ok());
        let (ta, tb) = (capture_time(&a).unwrap(), capture_time(&b).unwrap());
        // 2024-02-29 is day 19782 after 1970-01-01 (see civil_days_match_known_dates).
        assert_eq!(ta, 19782 * 86_400 + 23 * 3600 + 59 * 60 + 30);
        // Across midnight and a leap day: 5 minutes later.
        assert_eq!(tb - ta, 300);
        // No EXIF block: no time, no error.
        let plain = dir.join("plain.png");
        image::RgbImage::new(2, 2).save(&plain).unwrap();
        assert_eq!(capture_time(&plain), None);
        assert_eq!(capture_time(&dir.join("missing.jpg")), None);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
