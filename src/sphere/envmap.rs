//! Environment maps in and out: lat-long EXR files and the solver's octahedral maps.
//!
//! Radiance `L̃(ω)` arriving from direction `ω`, in environment-frame coordinates
//! (docs/conventions.md, [`crate::sphere::env_frame`]). Two forms:
//!
//! - [`LatLong`]: width `2H`, height `H`, pixel `(u, v)` (`v = 0` the top row) centred at
//!   polar angle `θ = π (v + ½) / H` from `e_z` (up) and azimuth `φ = 2π (u + ½) / 2H` from
//!   `e_x` toward `e_y`: `ω = sinθ cosφ e_x + sinθ sinφ e_y + cosθ e_z`. Pixel solid angle
//!   `ΔΩ_v = (2π / 2H) (cos θ_v − cos θ_{v+1})` with `θ_v = π v / H` (exact).
//! - [`OctEnv`]: texel averages `L̄_t = (1/Ω_t) ∫_{texel t} L̃ dω` on the full octahedral
//!   map [`SphereGrid::full`] (the global map of the paper's Sec. 4.2).
//!
//! Lat-long → octahedral ([`OctEnv::from_latlong`]) treats the lat-long map as piecewise
//! constant over its pixels and scatters each pixel's energy `L_p ΔΩ_p` to the octahedral
//! texels through `s × s` sub-pixels with their exact solid angles, then divides by the exact
//! texel solid angle: the integral `∫ L̃ dω` is conserved exactly (a one-pixel sun keeps all
//! of its energy); a constant map comes out constant up to the sub-pixel sampling error,
//! measured in the tests.

use crate::sphere::SphereGrid;
use crate::{Error, Result, Vec3};
use std::f64::consts::PI;
use std::path::Path;

/// A lat-long (equirectangular) environment map, layout in the module docs.
#[derive(Debug, Clone, PartialEq)]
pub struct LatLong {
    /// `2 × height`.
    pub width: usize,
    /// Rows from straight up (`v = 0`) to straight down.
    pub height: usize,
    /// Linear RGB radiance, row-major: pixel `(u, v)` at `v * width + u`.
    pub rgb: Vec<[f32; 3]>,
}

/// What reading a map had to repair.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ReadStats {
    /// Negative samples (lossy compression undershoot) set to 0.
    pub negative_clamped: usize,
    /// NaN or infinite samples set to 0.
    pub non_finite: usize,
}

/// Decode the first RGB(A) layer of an EXR stream as `(width, height, rgb)`.
fn decode_exr_rgb(
    source: impl std::io::Read + std::io::Seek,
) -> std::result::Result<(usize, usize, Vec<[f32; 3]>), exr::error::Error> {
    use exr::prelude::*;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .rgba_channels(
            |res: Vec2<usize>, _: &RgbaChannels| {
                (
                    res.width(),
                    res.height(),
                    vec![[0f32; 3]; res.width() * res.height()],
                )
            },
            |px: &mut (usize, usize, Vec<[f32; 3]>),
             pos: Vec2<usize>,
             (r, g, b, _a): (f32, f32, f32, f32)| {
                let w = px.0;
                px.2[pos.y() * w + pos.x()] = [r, g, b];
            },
        )
        .first_valid_layer()
        .all_attributes()
        .from_buffered(source)?;
    Ok(image.layer_data.channel_data.pixels)
}

/// Largest map decoded, in pixels (16384 × 8192): a header claiming more is refused
/// before any allocation.
const MAX_PIXELS: usize = 1 << 27;

/// Largest ratio of decoded pixels to file bytes accepted: lossless EXR compression of a
/// real map stays far below it, while a damaged header can claim any size.
const MAX_PIXELS_PER_BYTE: usize = 4096;

/// Decode the first RGB(A) layer of EXR bytes as `(width, height, rgb)`; errors in plain
/// words naming `path`: not an EXR file (and what it looks like), a size the file cannot
/// hold, an unsupported compression, damaged data.
fn decode_exr_checked(bytes: &[u8], path: &Path) -> Result<(usize, usize, Vec<[f32; 3]>)> {
    let err = |message: String| Error::Image {
        path: path.to_path_buf(),
        message,
    };
    if !bytes.starts_with(&[0x76, 0x2f, 0x31, 0x01]) {
        let looks = if bytes.starts_with(b"\x89PNG") {
            "a PNG image"
        } else if bytes.starts_with(&[0xff, 0xd8]) {
            "a JPEG image"
        } else if bytes.starts_with(b"#?RADIANCE") || bytes.starts_with(b"#?RGBE") {
            "a Radiance HDR image"
        } else if bytes.is_empty() {
            "an empty file"
        } else {
            "something else"
        };
        return Err(err(format!(
            "expected an OpenEXR file (lat-long, linear RGB), found {looks}; convert it, e.g. `oiiotool IN -o OUT.exr`"
        )));
    }
    let meta = exr::meta::MetaData::read_from_buffered(std::io::Cursor::new(bytes), false)
        .map_err(|e| err(format!("damaged EXR header: {}", exr_words(&e))))?;
    for h in &meta.headers {
        let (w, hh) = (h.layer_size.width(), h.layer_size.height());
        let pixels = w.saturating_mul(hh);
        if pixels > MAX_PIXELS || pixels / MAX_PIXELS_PER_BYTE > bytes.len() {
            return Err(err(format!(
                "the header announces {w} × {hh} pixels, which a {}-byte file cannot hold (or is over the {MAX_PIXELS}-pixel limit)",
                bytes.len()
            )));
        }
    }
    decode_exr_rgb(std::io::Cursor::new(bytes)).map_err(|e| {
        let compression = meta
            .headers
            .first()
            .map(|h| h.compression.to_string())
            .unwrap_or_else(|| "unknown compression".into());
        match e {
            exr::error::Error::NotSupported(what) => err(format!(
                "this EXR reader does not support it ({what}; the file uses {compression}); re-save it with zip or piz compression, e.g. `oiiotool IN --compression zip -o OUT.exr`"
            )),
            other => err(format!(
                "cannot decode the EXR data ({compression}): {}",
                exr_words(&other)
            )),
        }
    })
}

/// An `exr` error in words (its `Display`, which carries no Debug text).
fn exr_words(e: &exr::error::Error) -> String {
    match e {
        exr::error::Error::Io(io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
            "the file ends early (truncated?)".into()
        }
        other => other.to_string(),
    }
}

/// Read the first RGB(A) layer of an EXR file as `(width, height, rgb)`, naming the file.
fn read_exr_rgb(path: &Path) -> Result<(usize, usize, Vec<[f32; 3]>)> {
    let bytes = std::fs::read(path).map_err(|e| crate::Error::io(path, e))?;
    decode_exr_checked(&bytes, path)
}

/// Write `width × height` RGB as 32-bit float EXR.
fn write_exr_rgb(path: &Path, width: usize, height: usize, rgb: &[[f32; 3]]) -> Result<()> {
    crate::out_dir::exr::write_rgb(path, width, height, |x, y| {
        let p = rgb[y * width + x];
        (p[0], p[1], p[2])
    })
    .map_err(|e| match e {
        exr::error::Error::Io(io) => Error::io(path, io),
        other => Error::Image {
            path: path.to_path_buf(),
            message: format!("cannot write EXR: {other}"),
        },
    })
}

/// Clamp negatives and non-finite samples to 0, counting them.
fn sanitize(rgb: &mut [[f32; 3]]) -> ReadStats {
    let mut stats = ReadStats::default();
    for p in rgb.iter_mut() {
        for c in p.iter_mut() {
            if !c.is_finite() {
                *c = 0.0;
                stats.non_finite += 1;
            } else if *c < 0.0 {
                *c = 0.0;
                stats.negative_clamped += 1;
            }
        }
    }
    stats
}

impl LatLong {
    /// A black map of height `height` (width `2 height`).
    pub fn black(height: usize) -> LatLong {
        LatLong {
            width: 2 * height,
            height,
            rgb: vec![[0.0; 3]; 2 * height * height],
        }
    }

    /// Read a lat-long EXR (width must be twice the height). Negative and non-finite samples
    /// are set to 0 and counted in [`ReadStats`].
    pub fn read_exr(path: &Path) -> Result<(LatLong, ReadStats)> {
        let (width, height, rgb) = read_exr_rgb(path)?;
        Self::checked(path, width, height, rgb)
    }

    /// Read a lat-long Radiance RGBE (`.hdr`) file with the `image` crate's decoder (same
    /// layout and checks as [`read_exr`](LatLong::read_exr)).
    pub fn read_hdr(path: &Path) -> Result<(LatLong, ReadStats)> {
        let err = |message: String| Error::Image {
            path: path.to_path_buf(),
            message,
        };
        let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
        let decoder = image::codecs::hdr::HdrDecoder::new(std::io::BufReader::new(file))
            .map_err(|e| err(format!("cannot decode Radiance HDR: {e}")))?;
        let header = decoder.metadata();
        let img = image::DynamicImage::from_decoder(decoder)
            .map_err(|e| match e {
                image::ImageError::IoError(io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
                    err(format!(
                        "the Radiance HDR pixel data ends before the {} × {} pixels its header announces: the file is truncated",
                        header.width, header.height
                    ))
                }
                e => err(format!("cannot decode Radiance HDR: {e}")),
            })?
            .into_rgb32f();
        let (w, h) = (img.width() as usize, img.height() as usize);
        let rgb = img.pixels().map(|p| p.0).collect();
        Self::checked(path, w, h, rgb)
    }

    /// Read a lat-long map by extension: `.exr` or `.hdr` (case-insensitive).
    pub fn read_any(path: &Path) -> Result<(LatLong, ReadStats)> {
        let ext = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase());
        match ext.as_deref() {
            Some("exr") => Self::read_exr(path),
            Some("hdr") => Self::read_hdr(path),
            _ => Err(Error::Image {
                path: path.to_path_buf(),
                message: "an environment map must be a lat-long .exr or Radiance .hdr file".into(),
            }),
        }
    }

    /// Decode a lat-long EXR held in memory (`name` labels errors), like [`read_exr`].
    ///
    /// [`read_exr`]: LatLong::read_exr
    pub fn read_exr_bytes(bytes: &[u8], name: &str) -> Result<(LatLong, ReadStats)> {
        let (width, height, rgb) = decode_exr_checked(bytes, Path::new(name))?;
        Self::checked(Path::new(name), width, height, rgb)
    }

    /// The map from decoded pixels: 2H × H checked, negatives and non-finite values cleared.
    fn checked(
        path: &Path,
        width: usize,
        height: usize,
        mut rgb: Vec<[f32; 3]>,
    ) -> Result<(LatLong, ReadStats)> {
        if height == 0 || width != 2 * height {
            return Err(Error::Image {
                path: path.to_path_buf(),
                message: format!(
                    "a lat-long map must be 2H × H pixels, this one is {width} × {height}"
                ),
            });
        }
        let stats = sanitize(&mut rgb);
        Ok((LatLong { width, height, rgb }, stats))
    }

    /// Write as a 32-bit float EXR.
    pub fn write_exr(&self, path: &Path) -> Result<()> {
        write_exr_rgb(path, self.width, self.height, &self.rgb)
    }

    /// Polar angle of the top edge of row `v` (`v` may be `height`).
    fn theta_edge(&self, v: f64) -> f64 {
        PI * v / self.height as f64
    }

    /// Azimuth `φ` at continuous pixel column `x`.
    fn phi_at(&self, x: f64) -> f64 {
        2.0 * PI * x / self.width as f64
    }

    /// Direction at continuous pixel coordinates `(x, y)` (pixel `(u, v)` spans
    /// `[u, u+1) × [v, v+1)`).
    fn dir_at(&self, x: f64, y: f64) -> Vec3 {
        let theta = self.theta_edge(y);
        let phi = self.phi_at(x);
        Vec3::new(
            theta.sin() * phi.cos(),
            theta.sin() * phi.sin(),
            theta.cos(),
        )
    }

    /// Direction of the centre of pixel `(u, v)`.
    pub fn dir(&self, u: usize, v: usize) -> Vec3 {
        self.dir_at(u as f64 + 0.5, v as f64 + 0.5)
    }

    /// Continuous pixel coordinates `(x, y)` of direction `d` (`d` need not be unit).
    fn coords(&self, d: &Vec3) -> (f64, f64) {
        let r = d.norm();
        let theta = (d.z / r).clamp(-1.0, 1.0).acos();
        let phi = d.y.atan2(d.x).rem_euclid(2.0 * PI);
        (
            phi / (2.0 * PI) * self.width as f64,
            theta / PI * self.height as f64,
        )
    }

    /// The pixel containing direction `d`.
    pub fn pixel_of(&self, d: &Vec3) -> (usize, usize) {
        let (x, y) = self.coords(d);
        (
            (x as usize).min(self.width - 1),
            (y as usize).min(self.height - 1),
        )
    }

    /// Bilinear lookup between pixel centres (periodic in azimuth, clamped at the poles).
    pub fn lookup(&self, d: &Vec3) -> [f32; 3] {
        let (x, y) = self.coords(d);
        let (x, y) = (x - 0.5, (y - 0.5).clamp(0.0, (self.height - 1) as f64));
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = ((x - x0) as f32, (y - y0) as f32);
        let w = self.width as isize;
        let u0 = (x0 as isize).rem_euclid(w) as usize;
        let u1 = (x0 as isize + 1).rem_euclid(w) as usize;
        let v0 = y0 as usize;
        let v1 = (v0 + 1).min(self.height - 1);
        let at = |u: usize, v: usize| self.rgb[v * self.width + u];
        let mut out = [0f32; 3];
        for (c, o) in out.iter_mut().enumerate() {
            *o = (1.0 - fx) * (1.0 - fy) * at(u0, v0)[c]
                + fx * (1.0 - fy) * at(u1, v0)[c]
                + (1.0 - fx) * fy * at(u0, v1)[c]
                + fx * fy * at(u1, v1)[c];
        }
        out
    }

    /// Exact solid angle of a pixel in row `v`.
    pub fn solid_angle(&self, v: usize) -> f64 {
        let dphi = 2.0 * PI / self.width as f64;
        dphi * (self.theta_edge(v as f64).cos() - self.theta_edge(v as f64 + 1.0).cos())
    }

    /// `∫ L̃ dω` per channel.
    pub fn integral(&self) -> [f64; 3] {
        let mut out = [0.0; 3];
        for v in 0..self.height {
            let sa = self.solid_angle(v);
            for u in 0..self.width {
                let p = self.rgb[v * self.width + u];
                for c in 0..3 {
                    out[c] += p[c] as f64 * sa;
                }
            }
        }
        out
    }

    /// Box-filter down by an integer `factor` (which must divide the height), weighting
    /// pixels by their solid angle: each new pixel is the exact average radiance over its
    /// area, so `∫ L̃ dω` is conserved (a sun keeps its energy).
    pub fn downsample(&self, factor: usize) -> Result<LatLong> {
        if factor == 0 || !self.height.is_multiple_of(factor) {
            return Err(Error::Internal(format!(
                "cannot downsample a lat-long map of height {} by {factor}",
                self.height
            )));
        }
        let mut out = LatLong::black(self.height / factor);
        for v in 0..out.height {
            for u in 0..out.width {
                let mut acc = [0.0f64; 3];
                let mut wsum = 0.0;
                for vv in v * factor..(v + 1) * factor {
                    let w = self.solid_angle(vv);
                    for uu in u * factor..(u + 1) * factor {
                        let p = self.rgb[vv * self.width + uu];
                        for c in 0..3 {
                            acc[c] += w * p[c] as f64;
                        }
                        wsum += w;
                    }
                }
                out.rgb[v * out.width + u] = [
                    (acc[0] / wsum) as f32,
                    (acc[1] / wsum) as f32,
                    (acc[2] / wsum) as f32,
                ];
            }
        }
        Ok(out)
    }

    /// The environment turned by `radians` about `e_z`: what was at azimuth `φ` is now at
    /// `φ + radians`. Shifts by whole pixels are exact; fractions interpolate linearly along
    /// each row (which conserves each row's integral).
    pub fn rotated_about_up(&self, radians: f64) -> LatLong {
        let shift = radians / (2.0 * PI) * self.width as f64;
        let whole = shift.floor();
        let frac = (shift - whole) as f32;
        let w = self.width as isize;
        let mut out = self.clone();
        for v in 0..self.height {
            for u in 0..self.width {
                // Source position u − shift, between pixels u − whole − 1 and u − whole.
                let a = (u as isize - whole as isize).rem_euclid(w) as usize;
                let b = (u as isize - whole as isize - 1).rem_euclid(w) as usize;
                let (pa, pb) = (self.rgb[v * self.width + a], self.rgb[v * self.width + b]);
                for c in 0..3 {
                    out.rgb[v * self.width + u][c] = (1.0 - frac) * pa[c] + frac * pb[c];
                }
            }
        }
        out
    }
}

/// An environment map as texel averages on the full octahedral map (environment frame).
#[derive(Debug, Clone, PartialEq)]
pub struct OctEnv {
    /// Texels per side (power of two ≥ 2).
    pub n: usize,
    /// Linear RGB texel averages, texel `t = j n + i` ([`crate::sphere`] layout).
    pub rgb: Vec<[f32; 3]>,
}

impl OctEnv {
    /// Resample a lat-long map to an `n × n` octahedral map, conserving `∫ L̃ dω` exactly
    /// (module docs). Sub-pixels per side are chosen so that every octahedral texel receives
    /// at least ~1000 samples.
    pub fn from_latlong(ll: &LatLong, n: usize) -> OctEnv {
        let grid = SphereGrid::full(n);
        let omega = grid.solid_angles();
        // Sub-pixels per side: total samples ≥ 1024 per texel.
        let pixels = (ll.width * ll.height) as f64;
        let s = ((1024.0 * (n * n) as f64 / pixels).sqrt().ceil() as usize).clamp(1, 64);
        let mut energy = vec![[0.0f64; 3]; n * n];
        let sf = s as f64;
        // The sub-pixel columns' `(cos φ, sin φ)`, the same for every row: the directions
        // are `dir_at`'s bit for bit without its two `sincos` per sample.
        let columns: Vec<(f64, f64)> = (0..ll.width)
            .flat_map(|u| (0..s).map(move |a| u as f64 + (a as f64 + 0.5) / sf))
            .map(|x| {
                let (sin, cos) = ll.phi_at(x).sin_cos();
                (cos, sin)
            })
            .collect();
        for v in 0..ll.height {
            for b in 0..s {
                let y0 = v as f64 + b as f64 / sf;
                let y1 = y0 + 1.0 / sf;
                let sub_sa = 2.0 * PI / (ll.width as f64 * sf)
                    * (ll.theta_edge(y0).cos() - ll.theta_edge(y1).cos());
                let yc = 0.5 * (y0 + y1);
                let (sin_t, cos_t) = ll.theta_edge(yc).sin_cos();
                for u in 0..ll.width {
                    let p = ll.rgb[v * ll.width + u];
                    if p == [0.0; 3] {
                        continue;
                    }
                    for &(cos_p, sin_p) in &columns[u * s..(u + 1) * s] {
                        let d = Vec3::new(sin_t * cos_p, sin_t * sin_p, cos_t);
                        let t = grid.texel_of(&d);
                        for c in 0..3 {
                            energy[t][c] += p[c] as f64 * sub_sa;
                        }
                    }
                }
            }
        }
        let rgb = energy
            .iter()
            .zip(&omega)
            .map(|(e, &o)| [(e[0] / o) as f32, (e[1] / o) as f32, (e[2] / o) as f32])
            .collect();
        OctEnv { n, rgb }
    }

    /// A lat-long map of height `height`: each pixel the solid-angle-weighted mean of
    /// bilinear lookups at `s × s` sub-pixels (`s` so that sub-pixels are no wider than
    /// half an octahedral texel).
    pub fn to_latlong(&self, height: usize) -> LatLong {
        let grid = SphereGrid::full(self.n);
        let mut ll = LatLong::black(height);
        let s = ((2 * self.n).div_ceil(height)).clamp(1, 16);
        let sf = s as f64;
        for v in 0..height {
            for u in 0..ll.width {
                let mut acc = [0.0f64; 3];
                let mut wsum = 0.0;
                for b in 0..s {
                    let y0 = v as f64 + b as f64 / sf;
                    let w = ll.theta_edge(y0).cos() - ll.theta_edge(y0 + 1.0 / sf).cos();
                    for a in 0..s {
                        let d = ll.dir_at(u as f64 + (a as f64 + 0.5) / sf, y0 + 0.5 / sf);
                        for (t, bw) in grid.bilinear(&d) {
                            for (a, &x) in acc.iter_mut().zip(&self.rgb[t]) {
                                *a += w * bw * x as f64;
                            }
                        }
                        wsum += w;
                    }
                }
                ll.rgb[v * ll.width + u] = [
                    (acc[0] / wsum) as f32,
                    (acc[1] / wsum) as f32,
                    (acc[2] / wsum) as f32,
                ];
            }
        }
        ll
    }

    /// Write as an `n × n` 32-bit float EXR (texel `(i, j)` at pixel `x = i`, `y = j`).
    pub fn write_exr(&self, path: &Path) -> Result<()> {
        write_exr_rgb(path, self.n, self.n, &self.rgb)
    }

    /// Read an octahedral map written by [`OctEnv::write_exr`] (square, power-of-two side).
    /// Negative and non-finite samples are set to 0.
    pub fn read_exr(path: &Path) -> Result<OctEnv> {
        let (w, h, mut rgb) = read_exr_rgb(path)?;
        if w != h || w < 2 || !w.is_power_of_two() {
            return Err(Error::Image {
                path: path.to_path_buf(),
                message: format!("an octahedral map must be n × n with n a power of two ≥ 2, this one is {w} × {h}"),
            });
        }
        sanitize(&mut rgb);
        Ok(OctEnv { n: w, rgb })
    }

    /// Channel `c` (0 = R, 1 = G, 2 = B) as `f64` texel values.
    pub fn channel(&self, c: usize) -> Vec<f64> {
        self.rgb.iter().map(|p| p[c] as f64).collect()
    }

    /// Assemble from three channels of `n²` texel values each.
    pub fn from_channels(n: usize, ch: [&[f64]; 3]) -> OctEnv {
        let rgb = (0..n * n)
            .map(|t| [ch[0][t] as f32, ch[1][t] as f32, ch[2][t] as f32])
            .collect();
        OctEnv { n, rgb }
    }

    /// `∫ L̃ dω = Σ_t Ω_t L̄_t` per channel.
    pub fn integral(&self) -> [f64; 3] {
        let omega = SphereGrid::full(self.n).solid_angles();
        let mut out = [0.0; 3];
        for (p, o) in self.rgb.iter().zip(&omega) {
            for c in 0..3 {
                out[c] += p[c] as f64 * o;
            }
        }
        out
    }
}

#[cfg(test)]
mod tests;
