//! Photos: unreadable, truncated (PNG and JPEG), missing; CMYK, 16-bit and grey are read.

use super::*;
use relight_cpc::import::photo::Photo;

#[test]
fn photo_unreadable_bytes() {
    let (_d, p) = file("photo-garbage", "photo.png", b"not an image at all");
    let r = Photo::load(&p, 250.0 / 255.0);
    expect(r, &p, &[]);
}

#[test]
fn photo_truncated_png() {
    let bytes = std::fs::read(repo("examples/spot/images/photo_000.png")).unwrap();
    let (_d, p) = file("photo-trunc", "photo_000.png", &bytes[..bytes.len() / 2]);
    expect(Photo::load(&p, 250.0 / 255.0), &p, &[]);
}

#[test]
fn photo_truncated_jpeg() {
    // A real camera JPEG of the Buddha collection cut at three quarters: the decoder
    // would fill the missing rows, the end-of-image check refuses the file.
    let bytes = std::fs::read(repo(
        "tests/fixtures/colmap-dense-buddha/dense/images/00006.jpg",
    ))
    .unwrap();
    let (_d, p) = file(
        "photo-trunc-jpeg",
        "00006.jpg",
        &bytes[..bytes.len() * 3 / 4],
    );
    expect(
        Photo::load(&p, 250.0 / 255.0),
        &p,
        &["truncated", "end-of-image"],
    );
}

#[test]
fn photo_missing() {
    let d = scratch("malformed", "photo-missing");
    let p = d.join("photo.png");
    expect(Photo::load(&p, 250.0 / 255.0), &p, &[]);
}

#[test]
fn photo_cmyk_jpeg_is_read() {
    // tests/fixtures/photos/SOURCE.md: one flat colour, sRGB (200, 100, 50) before
    // ImageMagick's conversion to CMYK. Read back as RGB it keeps the hue order r > g > b
    // (JPEG and the CMYK round trip move each channel by a few codes, not the order).
    let p = repo("tests/fixtures/photos/cmyk-8x6.jpg");
    let photo = Photo::load(&p, 250.0 / 255.0).unwrap();
    assert_eq!((photo.width, photo.height), (8, 6));
    let [r, g, b] = photo.rgb[20];
    assert!(r > g && g > b, "CMYK read as ({r}, {g}, {b})");
}

#[test]
fn photo_sixteen_bit_png_is_read_at_full_depth() {
    // One 16-bit code per pixel: the linear value must be the sRGB curve at code/65535,
    // which an 8-bit read could not give to better than 1/255.
    let d = scratch("malformed", "photo-16");
    let p = d.join("deep.png");
    let codes: Vec<u16> = (0..4 * 3 * 3).map(|i| (i * 1500 + 7) as u16).collect();
    let bytes: Vec<u8> = codes.iter().flat_map(|c| c.to_ne_bytes()).collect();
    image::save_buffer(&p, &bytes, 4, 3, image::ExtendedColorType::Rgb16).unwrap();
    let photo = Photo::load(&p, 1.0).unwrap();
    for (i, px) in photo.rgb.iter().enumerate() {
        for c in 0..3 {
            let want =
                relight_cpc::import::photo::srgb_to_linear(codes[3 * i + c] as f32 / 65535.0);
            // f32 arithmetic on values in [0, 1]: 1e-6 is a few ulps.
            assert!((px[c] - want).abs() < 1e-6, "pixel {i} channel {c}");
        }
    }
}

#[test]
fn photo_grey_png_is_read_as_equal_channels() {
    let d = scratch("malformed", "photo-grey");
    let p = d.join("grey.png");
    let codes: Vec<u8> = (0..12).map(|i| (i * 20) as u8).collect();
    image::save_buffer(&p, &codes, 4, 3, image::ExtendedColorType::L8).unwrap();
    let photo = Photo::load(&p, 1.0).unwrap();
    for (i, px) in photo.rgb.iter().enumerate() {
        let want = relight_cpc::import::photo::srgb_to_linear(codes[i] as f32 / 255.0);
        // The 8-bit table holds the same f32 values as the function: exact up to ulps.
        assert!(px.iter().all(|v| (v - want).abs() < 1e-6), "pixel {i}");
    }
}
