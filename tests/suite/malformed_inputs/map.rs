//! Environment maps: not EXR, wrong aspect, truncated, oversized headers, DWAB.

use super::*;
use relight_cpc::sphere::envmap::LatLong;

#[test]
fn env_map_that_is_a_png() {
    let (_d, p) = file("env-png", "sky.exr", b"\x89PNG\r\n\x1a\n....");
    expect(
        LatLong::read_exr(&p),
        &p,
        &["expected an OpenEXR file", "PNG"],
    );
}

#[test]
fn env_map_that_is_radiance_hdr() {
    let (_d, p) = file(
        "env-hdr",
        "sky.exr",
        b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n",
    );
    expect(
        LatLong::read_exr(&p),
        &p,
        &["expected an OpenEXR file", "Radiance HDR"],
    );
}

#[test]
fn env_map_empty_file() {
    let (_d, p) = file("env-empty", "sky.exr", b"");
    expect(LatLong::read_exr(&p), &p, &["an empty file"]);
}

#[test]
fn env_map_wrong_aspect() {
    // A valid 10 × 10 EXR written by the exr crate: square, so not a lat-long map.
    let d = scratch("malformed", "env-aspect");
    let p = d.join("square.exr");
    exr::prelude::write_rgb_file(&p, 10, 10, |_, _| (1.0f32, 1.0f32, 1.0f32)).unwrap();
    expect(LatLong::read_exr(&p), &p, &["2H × H", "10 × 10"]);
}

#[test]
fn env_map_truncated() {
    let bytes = std::fs::read(repo("tests/fixtures/synth/hdri/studio.exr")).unwrap();
    let (_d, p) = file("env-trunc", "studio.exr", &bytes[..bytes.len() / 3]);
    expect(LatLong::read_exr(&p), &p, &["EXR"]);
}

#[test]
fn env_map_truncated_radiance_hdr() {
    // A 32 × 16 Radiance map written by the `image` crate's encoder, cut at half: the
    // error says the pixels run out, with the size the header announced.
    let d = scratch("malformed", "env-hdr-trunc");
    let whole = d.join("whole.hdr");
    let pixels: Vec<image::Rgb<f32>> = (0..32 * 16)
        .map(|i| image::Rgb([1.0 + i as f32 * 0.01, 0.5, 0.25]))
        .collect();
    let out = std::io::BufWriter::new(std::fs::File::create(&whole).unwrap());
    image::codecs::hdr::HdrEncoder::new(out)
        .encode(&pixels, 32, 16)
        .unwrap();
    assert!(LatLong::read_hdr(&whole).is_ok(), "the whole map must read");
    let bytes = std::fs::read(&whole).unwrap();
    let (_d2, p) = file("env-hdr-half", "sky.hdr", &bytes[..bytes.len() / 2]);
    expect(LatLong::read_hdr(&p), &p, &["truncated", "32 × 16"]);
}

#[test]
fn env_map_header_claiming_more_pixels_than_the_file_holds() {
    // The data window of the 64 × 32 fixture grown to 50000 × 50000 in the header: refused
    // before any allocation (found by the envmap fuzz target: it aborted the process).
    let mut bytes = std::fs::read(repo("tests/fixtures/hdri/city_64x32.exr")).unwrap();
    let key = b"dataWindow\0box2i\0";
    let at = bytes
        .windows(key.len())
        .position(|w| w == key)
        .expect("dataWindow attribute")
        + key.len()
        + 4; // attribute size
             // box2i = xMin, yMin, xMax, yMax (i32 LE).
    bytes[at + 8..at + 12].copy_from_slice(&49_999i32.to_le_bytes());
    bytes[at + 12..at + 16].copy_from_slice(&49_999i32.to_le_bytes());
    let (_d, p) = file("env-huge", "city.exr", &bytes);
    expect(LatLong::read_exr(&p), &p, &["pixels", "cannot hold"]);
}

#[test]
fn env_map_dwab_compression_is_read() {
    // DWAB (lossy) as Blender ships it: the exr crate decodes it; the map is 2:1 and the
    // small negative undershoot of the lossy codec is clamped and counted.
    let p = repo("tests/fixtures/hdri/studio_dwab.exr");
    let (map, stats) = LatLong::read_exr(&p).unwrap();
    assert_eq!((map.width, map.height), (1024, 512));
    assert!(map.rgb.iter().flatten().all(|c| c.is_finite() && *c >= 0.0));
    eprintln!("DWAB: {} negative samples clamped", stats.negative_clamped);
}
