//! Environment maps in Blender's lat-long convention, as EXR and Radiance `.hdr`.
//!
//! The run's lat-long maps ([`crate::envmap::LatLong`]) put azimuth `φ = 0` (`e_x`) at the
//! left edge and let `φ` grow to the right toward `e_y`. Blender's world texture (Cycles'
//! `direction_to_equirectangular`) samples direction `d` at
//! `u = ½ − atan2(d_y, d_x) / 2π`, `v = 1 − acos(d_z) / π` (`v` up from the bottom row): `+X`
//! at the image centre, azimuth growing to the LEFT, up at the top row. Both layouts use the
//! same rows, and column `u_b` of a `W`-wide Blender image (centre `φ = π − 2π (u_b + ½)/W`)
//! is exactly column `(W/2 − 1 − u_b) mod W` of ours: the conversion is a pixel permutation
//! (no resampling). With the object exported by [`crate::export::gltf`] (environment frame =
//! Blender's world axes), a World node tree "Environment Texture → Background" with this
//! image and no rotation lights the object as the run's map did; a world rotation of `θ`
//! about Z in Blender equals `render --rotate θ`.

use crate::envmap::LatLong;
use crate::{Error, Result};
use std::path::Path;

/// Our column of Blender column `u_b` in a map `width` pixels wide.
pub fn source_column(u_b: usize, width: usize) -> usize {
    (width / 2 + width - 1 - u_b) % width
}

/// The map re-laid in Blender's convention (module docs).
pub fn to_blender(ll: &LatLong) -> LatLong {
    let mut out = ll.clone();
    for v in 0..ll.height {
        for u_b in 0..ll.width {
            out.rgb[v * ll.width + u_b] = ll.rgb[v * ll.width + source_column(u_b, ll.width)];
        }
    }
    out
}

/// The inverse of [`to_blender`]: a Blender-convention world image in the run's layout.
pub fn from_blender(ll: &LatLong) -> LatLong {
    let mut out = ll.clone();
    for v in 0..ll.height {
        for u_b in 0..ll.width {
            out.rgb[v * ll.width + source_column(u_b, ll.width)] = ll.rgb[v * ll.width + u_b];
        }
    }
    out
}

/// Write `ll` as Radiance RGBE (`.hdr`) with the `image` crate's encoder.
pub fn write_hdr(path: &Path, ll: &LatLong) -> Result<()> {
    let px: Vec<image::Rgb<f32>> = ll
        .rgb
        .iter()
        .map(|p| image::Rgb(p.map(|v| if v.is_finite() { v.max(0.0) } else { 0.0 })))
        .collect();
    let mut bytes = Vec::new();
    image::codecs::hdr::HdrEncoder::new(&mut bytes)
        .encode(&px, ll.width, ll.height)
        .map_err(|e| Error::Image {
            path: path.to_path_buf(),
            message: format!("cannot encode Radiance HDR: {e}"),
        })?;
    crate::export::write_atomic(path, &bytes)
}

/// Export one of the run's lat-long maps as `DIR/STEM.exr` and `DIR/STEM.hdr` in Blender's
/// convention; returns the two paths.
pub fn export_blender(ll: &LatLong, dir: &Path, stem: &str) -> Result<[std::path::PathBuf; 2]> {
    let b = to_blender(ll);
    let exr = dir.join(format!("{stem}.exr"));
    let hdr = dir.join(format!("{stem}.hdr"));
    b.write_exr(&exr)?;
    write_hdr(&hdr, &b)?;
    Ok([exr, hdr])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Vec3;

    /// Cycles' own formula (module docs), written out independently of `source_column`: a
    /// one-pixel light in direction d of our map lands in the Blender image at the pixel
    /// whose centre Cycles maps d to, for directions all round the horizon and off it.
    #[test]
    fn bright_pixel_lands_where_cycles_looks() {
        let h = 16;
        for k in 0..32 {
            let phi = 2.0 * std::f64::consts::PI * (k as f64 + 0.5) / 32.0;
            let theta = 0.3 + 0.07 * k as f64;
            let d = Vec3::new(
                theta.sin() * phi.cos(),
                theta.sin() * phi.sin(),
                theta.cos(),
            );
            let mut ll = LatLong::black(h);
            let (u, v) = ll.pixel_of(&d);
            ll.rgb[v * ll.width + u] = [1.0; 3];
            let b = to_blender(&ll);
            // Cycles: u_b = 0.5 − atan2(y, x)/2π (wrapped), row from the top = acos(z)/π.
            let ub = (0.5 - d.y.atan2(d.x) / (2.0 * std::f64::consts::PI)).rem_euclid(1.0);
            let col = (ub * b.width as f64) as usize;
            let row = (d.z.acos() / std::f64::consts::PI * h as f64) as usize;
            assert_eq!(b.rgb[row * b.width + col], [1.0; 3], "k={k}");
            assert_eq!(from_blender(&b), ll);
        }
    }

    /// The `.hdr` reads back through the `image` crate's decoder within RGBE's precision
    /// (8-bit mantissa with a shared exponent: relative error < 2^-7).
    #[test]
    fn hdr_round_trip() {
        let mut ll = LatLong::black(8);
        for (i, p) in ll.rgb.iter_mut().enumerate() {
            *p = [0.01 * i as f32 + 0.001, 5.0, 300.0 / (1.0 + i as f32)];
        }
        let dir = std::env::temp_dir().join(format!("relight-hdr-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("m.hdr");
        write_hdr(&path, &ll).unwrap();
        let back = LatLong::read_hdr(&path).unwrap().0;
        for (a, b) in ll.rgb.iter().zip(&back.rgb) {
            let m = a.iter().fold(0.0f32, |m, v| m.max(*v));
            for c in 0..3 {
                assert!((a[c] - b[c]).abs() <= m / 128.0, "{a:?} vs {b:?}");
            }
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}
