//! The real data the synthetic scenes are built from, embedded in the binary so that
//! `relight-cpc synth` runs anywhere: eight captured HDR environment maps (lat-long, area
//! downsampled from 1024×512 to 256×128, half float, ZIP) and Keenan Crane's "Spot" mesh.
//! Credits and the derivation are in `tests/fixtures/synth/SOURCE.md`.
//!
//! Downsampling averages `f × f` blocks weighted by solid angle (`Δφ (cos θ₀ − cos θ₁)`, so
//! each output texel is the average radiance over its own solid angle); the map's integral
//! `∫ L dω` is preserved exactly (up to rounding).

use crate::envmap::LatLong;
use crate::{Error, Result};
use std::path::Path;

/// Height (texels) of a lat-long map, `theta` edges at `π v / H`: the solid angle of a
/// texel in row `v` of a `2H × H` map.
fn row_solid_angle(width: usize, height: usize, v: usize) -> f64 {
    use std::f64::consts::PI;
    let t0 = PI * v as f64 / height as f64;
    let t1 = PI * (v + 1) as f64 / height as f64;
    2.0 * PI / width as f64 * (t0.cos() - t1.cos())
}

/// Area-weighted downsampling by an integer `factor` (which must divide the height).
pub fn downsample(map: &LatLong, factor: usize) -> Result<LatLong> {
    if factor == 0 || !map.height.is_multiple_of(factor) || map.width != 2 * map.height {
        return Err(Error::Config(format!(
            "cannot downsample a {}×{} lat-long map by {factor}",
            map.width, map.height
        )));
    }
    let (w, h) = (map.width / factor, map.height / factor);
    let mut rgb = vec![[0.0f32; 3]; w * h];
    for v in 0..h {
        for u in 0..w {
            let mut acc = [0.0f64; 3];
            let mut area = 0.0;
            for dv in 0..factor {
                let sv = v * factor + dv;
                let om = row_solid_angle(map.width, map.height, sv);
                for du in 0..factor {
                    let p = map.rgb[sv * map.width + u * factor + du];
                    for c in 0..3 {
                        acc[c] += p[c] as f64 * om;
                    }
                    area += om;
                }
            }
            for c in 0..3 {
                rgb[v * w + u][c] = (acc[c] / area) as f32;
            }
        }
    }
    Ok(LatLong {
        width: w,
        height: h,
        rgb,
    })
}

/// Writes a lat-long map as half-float RGB EXR with ZIP compression (compact fixtures).
pub fn write_half_exr(map: &LatLong, path: &Path) -> Result<()> {
    write_exr(map, path, true)
}

/// Writes a lat-long map as RGB EXR (f32, or f16 when `half`), ZIP-compressed, scan lines
/// in increasing order and written sequentially, so the same map gives the same bytes.
pub fn write_exr(map: &LatLong, path: &Path, half: bool) -> Result<()> {
    use crate::Error;
    use exr::prelude::*;
    let w = map.width;
    let encoding = Encoding {
        compression: Compression::ZIP16,
        blocks: Blocks::ScanLines,
        line_order: LineOrder::Increasing,
    };
    let to_err = |e: exr::error::Error| match e {
        exr::error::Error::Io(e) => Error::io(path, e),
        other => Error::Image {
            path: path.to_path_buf(),
            message: other.to_string(),
        },
    };
    if half {
        let channels = SpecificChannels::rgb(|pos: Vec2<usize>| {
            let p = map.rgb[pos.y() * w + pos.x()];
            (
                f16::from_f32(p[0]),
                f16::from_f32(p[1]),
                f16::from_f32(p[2]),
            )
        });
        let layer = Layer::new(
            (map.width, map.height),
            LayerAttributes::named("rgb"),
            encoding,
            channels,
        );
        Image::from_layer(layer)
            .write()
            .non_parallel()
            .to_file(path)
            .map_err(to_err)
    } else {
        let channels = SpecificChannels::rgb(|pos: Vec2<usize>| {
            let p = map.rgb[pos.y() * w + pos.x()];
            (p[0], p[1], p[2])
        });
        let layer = Layer::new(
            (map.width, map.height),
            LayerAttributes::named("rgb"),
            encoding,
            channels,
        );
        Image::from_layer(layer)
            .write()
            .non_parallel()
            .to_file(path)
            .map_err(to_err)
    }
}

/// Decodes an in-memory lat-long EXR (`name` labels errors).
pub fn read_exr_bytes(bytes: &[u8], name: &str) -> Result<LatLong> {
    use crate::Error;
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
        .from_buffered(std::io::Cursor::new(bytes))
        .map_err(|e| Error::Image {
            path: name.into(),
            message: e.to_string(),
        })?;
    let (width, height, mut rgb) = image.layer_data.channel_data.pixels;
    if height == 0 || width != 2 * height {
        return Err(Error::Image {
            path: name.into(),
            message: format!("embedded map is {width}×{height}, not 2H × H"),
        });
    }
    for p in rgb.iter_mut().flatten() {
        if !p.is_finite() || *p < 0.0 {
            *p = 0.0;
        }
    }
    Ok(LatLong { width, height, rgb })
}

/// Names of the embedded environment maps.
pub const MAP_NAMES: [&str; 8] = [
    "city",
    "courtyard",
    "forest",
    "interior",
    "night",
    "studio",
    "sunrise",
    "sunset",
];
