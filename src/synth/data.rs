//! The real data the synthetic scenes are built from, embedded in the binary so that
//! `relight-cpc synth` runs anywhere: eight captured HDR environment maps (lat-long, area
//! downsampled from 1024×512 to 256×128, half float, ZIP) and Keenan Crane's "Spot" mesh.
//! Credits and the derivation are in `tests/fixtures/synth/SOURCE.md`.
//!
//! The maps were area-downsampled with [`LatLong::downsample`] (solid-angle-weighted block
//! averages, the integral `∫ L dω` preserved) and are decoded with
//! [`LatLong::read_exr_bytes`].

use crate::sphere::envmap::LatLong;
use crate::Result;
use std::path::Path;

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
