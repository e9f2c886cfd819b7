//! Photo decoding: 8- and 16-bit PNG, grayscale, JPEG and EXR, against the sRGB standard's
//! formula written out here, the overexposure rule, and unreadable or missing files.

use image::{ImageBuffer, Luma, Rgb};
use relight_cpc::import::photo::{Photo, DEFAULT_CLIP};
use relight_cpc::Error;

/// `name` in a scratch folder of its own, removed when the returned value is dropped.
fn scratch(name: &str) -> crate::scratch::ScratchFile {
    crate::scratch::scratch_file("photo", name)
}

/// IEC 61966-2-1 decoding, written independently of the crate (in f64).
fn srgb(c: f64) -> f64 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

#[test]
fn png8_decodes_with_the_exact_curve_and_marks_clipping() {
    // Every code 0..=255 appears: pixel (i, j) of a 16×16 image has R = 16j + i,
    // G = 255 − R, B = 0 (row-major, top row first).
    let img = ImageBuffer::from_fn(16, 16, |i, j| {
        let r = (16 * j + i) as u8;
        Rgb([r, 255 - r, 0u8])
    });
    let path = scratch("codes.png");
    img.save(&path).unwrap();
    let p = Photo::load(&path, DEFAULT_CLIP).unwrap();
    assert_eq!((p.width, p.height), (16, 16));
    for code in 0..256usize {
        let px = p.rgb[code];
        // f32 result vs f64 formula: 1e-6 absolute.
        assert!(
            (px[0] as f64 - srgb(code as f64 / 255.0)).abs() < 1e-6,
            "{code}"
        );
        assert!((px[1] as f64 - srgb((255 - code) as f64 / 255.0)).abs() < 1e-6);
        assert_eq!(px[2], 0.0);
        // Default threshold 250/255: codes ≥ 250 in any channel (R ≥ 250 or G ≥ 250 ⇔ R ≤ 5).
        assert_eq!(p.overexposed[code], !(6..250).contains(&code), "{code}");
    }
    // A threshold of 1.0 clips only code 255.
    let p = Photo::load(&path, 1.0).unwrap();
    assert_eq!(p.overexposed.iter().filter(|&&o| o).count(), 2);
}

#[test]
fn png16_and_grayscale() {
    let codes = [0u16, 1000, 32768, 64249, 64250, 65535];
    let img = ImageBuffer::from_fn(codes.len() as u32, 1, |i, _| {
        let c = codes[i as usize];
        Rgb([c, c / 2, 0u16])
    });
    let path = scratch("deep.png");
    img.save(&path).unwrap();
    let p = Photo::load(&path, DEFAULT_CLIP).unwrap();
    for (i, &c) in codes.iter().enumerate() {
        assert!((p.rgb[i][0] as f64 - srgb(c as f64 / 65535.0)).abs() < 1e-6);
        assert!((p.rgb[i][1] as f64 - srgb((c / 2) as f64 / 65535.0)).abs() < 1e-6);
        // 250/255 of 65535 is 64250 exactly.
        assert_eq!(p.overexposed[i], c >= 64250, "{c}");
    }
    let gray = ImageBuffer::from_fn(3, 2, |i, j| Luma([(40 * (i + 3 * j)) as u8]));
    let path = scratch("gray.png");
    gray.save(&path).unwrap();
    let p = Photo::load(&path, DEFAULT_CLIP).unwrap();
    for k in 0..6 {
        let v = srgb((40 * k) as f64 / 255.0);
        assert!(p.rgb[k].iter().all(|&c| (c as f64 - v).abs() < 1e-6));
    }
}

#[test]
fn jpeg_decodes_close_to_its_source() {
    // A flat JPEG decodes to within a couple of codes of its source value.
    let img = ImageBuffer::from_pixel(32, 24, Rgb([128u8, 64, 200]));
    let path = scratch("flat.jpg");
    img.save(&path).unwrap();
    let p = Photo::load(&path, DEFAULT_CLIP).unwrap();
    assert_eq!((p.width, p.height), (32, 24));
    let tol = |c: f64| srgb((c + 2.0) / 255.0) - srgb(c / 255.0);
    for px in &p.rgb {
        for (v, c) in px.iter().zip([128.0, 64.0, 200.0]) {
            assert!((*v as f64 - srgb(c / 255.0)).abs() <= tol(c), "{px:?}");
        }
    }
    assert!(p.overexposed.iter().all(|&o| !o));
}

#[test]
fn exr_is_linear_and_only_non_finite_is_masked() {
    let path = scratch("hdr.exr");
    let values = [0.0f32, 0.25, 1.0, 5.0, 30000.0, f32::NAN];
    exr::prelude::write_rgb_file(&path, values.len(), 1, |x, _| {
        (values[x], values[x] * 0.5, 1.0f32)
    })
    .unwrap();
    let p = Photo::load(&path, DEFAULT_CLIP).unwrap();
    for (i, &v) in values.iter().enumerate() {
        if v.is_finite() {
            assert_eq!(p.rgb[i], [v, v * 0.5, 1.0]);
            assert!(!p.overexposed[i]);
        } else {
            assert!(p.overexposed[i]);
            assert_eq!(p.rgb[i], [0.0; 3]);
        }
    }
}

#[test]
fn unreadable_and_missing_photos_are_errors_naming_the_file() {
    let path = scratch("broken.png");
    std::fs::write(&path, b"\x89PNG\r\n\x1a\n but then nothing sensible").unwrap();
    match Photo::load(&path, DEFAULT_CLIP).unwrap_err() {
        Error::Image { path: p, message } => {
            assert_eq!(p, *path);
            assert!(message.contains("decode"), "{message}");
        }
        other => panic!("{other}"),
    }
    let path = scratch("text.jpg");
    std::fs::write(&path, "hello").unwrap();
    assert!(matches!(
        Photo::load(&path, DEFAULT_CLIP).unwrap_err(),
        Error::Image { .. }
    ));
    let path = scratch("broken.exr");
    std::fs::write(&path, b"v/1\x01 not an exr").unwrap();
    let err = Photo::load(&path, DEFAULT_CLIP).unwrap_err();
    assert!(err.to_string().contains("broken.exr"), "{err}");
    let path = scratch("absent.png");
    match Photo::load(&path, DEFAULT_CLIP).unwrap_err() {
        Error::Io { path: p, .. } => assert_eq!(p, *path),
        other => panic!("{other}"),
    }
}
