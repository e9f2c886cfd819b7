//! Bad COLMAP models get a clear error that names the file and the line (text) or the
//! record and byte (binary); none panics. Each test starts from a small valid model written
//! by our writers (checked to read back), and breaks one thing.

use std::path::Path;

use crate::colmap_model::model;
use relight_cpc::import::colmap::Reconstruction;
use relight_cpc::Error;

/// A fresh folder holding the model in both formats, removed when dropped.
fn setup(tag: &str) -> crate::scratch::Scratch {
    let dir = crate::scratch::scratch("colmap-errors", tag);
    let rec = model();
    rec.write_text(&dir).unwrap();
    rec.write_binary(&dir).unwrap();
    assert_eq!(Reconstruction::read_text(&dir).unwrap(), rec);
    assert_eq!(Reconstruction::read_binary(&dir).unwrap(), rec);
    dir
}

/// Replace `from` by `to` in the text file `name` (which must contain it).
fn edit(dir: &Path, name: &str, from: &str, to: &str) {
    let p = dir.join(name);
    let s = std::fs::read_to_string(&p).unwrap();
    assert!(s.contains(from), "{name} lacks {from:?}:\n{s}");
    std::fs::write(&p, s.replacen(from, to, 1)).unwrap();
}

/// The error is a Format error for `file` whose location and message contain the words.
fn expect_format(r: Result<Reconstruction, Error>, file: &str, location: &str, message: &str) {
    match r {
        Err(Error::Format {
            path,
            location: loc,
            message: msg,
        }) => {
            assert!(
                path.ends_with(file),
                "path {} is not {file}",
                path.display()
            );
            assert!(
                loc.contains(location),
                "location {loc:?} lacks {location:?} ({msg})"
            );
            assert!(msg.contains(message), "message {msg:?} lacks {message:?}");
        }
        other => panic!("expected a Format error for {file}, got {other:?}"),
    }
}

fn text(dir: &Path) -> Result<Reconstruction, Error> {
    Reconstruction::read_text(dir)
}
fn bin(dir: &Path) -> Result<Reconstruction, Error> {
    Reconstruction::read_binary(dir)
}

// ---- text ----

#[test]
fn text_comments_and_blank_lines_anywhere_are_skipped() {
    let dir = setup("comments");
    edit(
        &dir,
        "cameras.txt",
        "3 SIMPLE_RADIAL",
        "\n# a comment\n   \n  # indented\n3 SIMPLE_RADIAL",
    );
    edit(&dir, "points3D.txt", "11 ", "# between points\n\n11 ");
    assert_eq!(text(&dir).unwrap(), model());
}

#[test]
fn text_unknown_camera_model() {
    let dir = setup("t-model");
    edit(&dir, "cameras.txt", "SIMPLE_RADIAL", "SIMPLE_RADIALX");
    // Line 4: three header lines, then the first camera.
    expect_format(
        text(&dir),
        "cameras.txt",
        "line 4",
        "unknown camera model \"SIMPLE_RADIALX\"",
    );
}

#[test]
fn text_wrong_number_of_params() {
    let dir = setup("t-params");
    edit(&dir, "cameras.txt", " -0.05", "");
    expect_format(text(&dir), "cameras.txt", "line 4", "needs 4 parameters");
    let dir = setup("t-params2");
    edit(&dir, "cameras.txt", " -0.05", " -0.05 1.0");
    expect_format(text(&dir), "cameras.txt", "line 4", "got 5");
}

#[test]
fn text_nan_and_inf() {
    let dir = setup("t-nan-cam");
    edit(&dir, "cameras.txt", " -0.05", " NaN");
    expect_format(text(&dir), "cameras.txt", "line 4", "not finite");
    let dir = setup("t-inf-point");
    edit(&dir, "points3D.txt", "\n10 0.0", "\n10 inf");
    expect_format(text(&dir), "points3D.txt", "line 4", "not finite");
    let dir = setup("t-nan-kp");
    edit(&dir, "images.txt", "100.0 200.5", "nan 200.5");
    expect_format(text(&dir), "images.txt", "line 6", "(X) is not finite");
}

#[test]
fn text_missing_and_malformed_fields() {
    let dir = setup("t-width");
    edit(&dir, "cameras.txt", "640 480", "640.5 480");
    expect_format(text(&dir), "cameras.txt", "line 4", "WIDTH");
    let dir = setup("t-short-image");
    edit(&dir, "images.txt", " 3 img2.jpg", "");
    expect_format(text(&dir), "images.txt", "line 5", "CAMERA_ID");
    let dir = setup("t-kp3");
    edit(&dir, "images.txt", "5.0 6.0 -1", "5.0 6.0");
    expect_format(text(&dir), "images.txt", "line 6", "not a multiple of 3");
    let dir = setup("t-kpneg");
    edit(&dir, "images.txt", "5.0 6.0 -1", "5.0 6.0 -7");
    expect_format(text(&dir), "images.txt", "line 6", "POINT3D_ID");
    let dir = setup("t-track");
    edit(&dir, "points3D.txt", "2 0 9 0", "2 0 9");
    expect_format(text(&dir), "points3D.txt", "line 4", "pairs");
    let dir = setup("t-rgb");
    edit(&dir, "points3D.txt", " 10 20 30 ", " 10 256 30 ");
    expect_format(text(&dir), "points3D.txt", "line 4", "(G)");
}

#[test]
fn text_truncated_images_file() {
    // The file ends right after an image line: its keypoint line is missing.
    let dir = setup("t-trunc");
    let p = dir.join("images.txt");
    let s = std::fs::read_to_string(&p).unwrap();
    let last_image = s.rfind("\n9 ").unwrap();
    let end = s[last_image + 1..].find('\n').unwrap() + last_image + 1;
    std::fs::write(&p, &s[..end]).unwrap();
    expect_format(text(&dir), "images.txt", "line 8", "ends after image id 9");
}

#[test]
fn text_duplicate_ids_and_dangling_references() {
    let dir = setup("t-dup");
    edit(&dir, "cameras.txt", "7 OPENCV", "3 OPENCV");
    expect_format(text(&dir), "cameras.txt", "line 5", "appears twice");
    let dir = setup("t-cam-ref");
    edit(&dir, "cameras.txt", "7 OPENCV", "8 OPENCV");
    expect_format(text(&dir), "images.txt", "image id 9", "camera id 7");
    let dir = setup("t-track-ref");
    edit(&dir, "points3D.txt", "2 0 9 0", "2 0 5 0");
    expect_format(text(&dir), "points3D.txt", "point3D id 10", "image id 5");
    let dir = setup("t-track-idx");
    edit(&dir, "points3D.txt", "2 0 9 0", "2 0 9 17");
    expect_format(text(&dir), "points3D.txt", "point3D id 10", "point2D 17");
}

#[test]
fn text_not_utf8() {
    let dir = setup("t-utf8");
    let p = dir.join("cameras.txt");
    let mut bytes = std::fs::read(&p).unwrap();
    bytes.extend_from_slice(b"9 PINHOLE 1 1 1 1 0 0 \xff\n");
    std::fs::write(&p, bytes).unwrap();
    expect_format(text(&dir), "cameras.txt", "line 6", "UTF-8");
}

#[test]
fn missing_file_is_an_io_error_naming_it() {
    let dir = setup("t-missing");
    std::fs::remove_file(dir.join("points3D.txt")).unwrap();
    match text(&dir) {
        Err(Error::Io { path, .. }) => assert!(path.ends_with("points3D.txt")),
        other => panic!("{other:?}"),
    }
}

// ---- binary ----

/// Byte offsets in our `cameras.bin`: count (8), then camera 3 (SIMPLE_RADIAL: 4 + 4 + 8 +
/// 8 + 4·8 = 56 bytes), then camera 7 (OPENCV: 24 + 8·8 = 88 bytes).
const CAM0: usize = 8;
const CAM1: usize = 8 + 56;

fn patch(dir: &Path, name: &str, f: impl FnOnce(&mut Vec<u8>)) {
    let p = dir.join(name);
    let mut b = std::fs::read(&p).unwrap();
    f(&mut b);
    std::fs::write(&p, b).unwrap();
}

#[test]
fn binary_truncated() {
    let dir = setup("b-trunc");
    // Cut inside camera 7's parameters (the header check passes: 2 cameras need at least
    // 96 bytes and 139 follow).
    patch(&dir, "cameras.bin", |b| {
        let n = b.len();
        b.truncate(n - 5)
    });
    expect_format(
        bin(&dir),
        "cameras.bin",
        "record 1 (camera id 7",
        "truncated",
    );
    let dir = setup("b-trunc-img");
    patch(&dir, "images.bin", |b| {
        let n = b.len();
        b.truncate(n - 5)
    });
    expect_format(bin(&dir), "images.bin", "record 1 (image id 9", "truncated");
}

#[test]
fn binary_count_disagrees_with_file_size() {
    let dir = setup("b-count");
    patch(&dir, "points3D.bin", |b| {
        b[..8].copy_from_slice(&1000u64.to_le_bytes())
    });
    expect_format(bin(&dir), "points3D.bin", "header", "count says 1000");
    let dir = setup("b-count-small");
    patch(&dir, "cameras.bin", |b| {
        b[..8].copy_from_slice(&1u64.to_le_bytes())
    });
    expect_format(bin(&dir), "cameras.bin", "byte 64", "88 bytes remain");
    let dir = setup("b-count-huge");
    patch(&dir, "images.bin", |b| {
        b[..8].copy_from_slice(&u64::MAX.to_le_bytes())
    });
    expect_format(bin(&dir), "images.bin", "header", "count says");
}

#[test]
fn binary_unknown_model_id() {
    let dir = setup("b-model");
    patch(&dir, "cameras.bin", |b| {
        b[CAM0 + 4..CAM0 + 8].copy_from_slice(&42i32.to_le_bytes())
    });
    expect_format(
        bin(&dir),
        "cameras.bin",
        "record 0 (camera id 3",
        "unknown camera model id 42",
    );
    let dir = setup("b-model-neg");
    patch(&dir, "cameras.bin", |b| {
        b[CAM0 + 4..CAM0 + 8].copy_from_slice(&(-1i32).to_le_bytes())
    });
    expect_format(
        bin(&dir),
        "cameras.bin",
        "record 0",
        "unknown camera model id -1",
    );
}

#[test]
fn binary_wrong_number_of_params_shows_as_size_mismatch() {
    // The binary format has no parameter count: a model id with fewer parameters than were
    // written leaves bytes over, which the next record or the end check reports.
    let dir = setup("b-params");
    patch(&dir, "cameras.bin", |b| {
        // Camera 7 OPENCV (8 params) relabelled PINHOLE (4 params).
        b[CAM1 + 4..CAM1 + 8].copy_from_slice(&1i32.to_le_bytes())
    });
    expect_format(bin(&dir), "cameras.bin", "byte 120", "32 bytes remain");
}

#[test]
fn binary_nan_and_inf() {
    let dir = setup("b-nan");
    // Camera 3's k (last param).
    patch(&dir, "cameras.bin", |b| {
        b[CAM1 - 8..CAM1].copy_from_slice(&f64::NAN.to_le_bytes())
    });
    expect_format(
        bin(&dir),
        "cameras.bin",
        "record 0 (camera id 3",
        "not finite",
    );
    let dir = setup("b-inf-q");
    // Image 2's qw, right after count (8) and id (4).
    patch(&dir, "images.bin", |b| {
        b[12..20].copy_from_slice(&f64::INFINITY.to_le_bytes())
    });
    expect_format(
        bin(&dir),
        "images.bin",
        "record 0 (image id 2",
        "not finite",
    );
    let dir = setup("b-nan-xyz");
    patch(&dir, "points3D.bin", |b| {
        b[16..24].copy_from_slice(&f64::NAN.to_le_bytes())
    });
    expect_format(
        bin(&dir),
        "points3D.bin",
        "record 0 (point3D id 10",
        "not finite",
    );
}

#[test]
fn binary_name_without_nul_and_bad_utf8() {
    let dir = setup("b-name");
    // Cut images.bin inside the second image's name: no NUL before the end. Record 0 is
    // id, pose, camera (64 bytes), "img2.jpg\0" (9), the count (8), 4 keypoints (96).
    let name1 = 8 + (64 + 9 + 8 + 96) + 64;
    patch(&dir, "images.bin", |b| b.truncate(name1 + 3));
    expect_format(
        bin(&dir),
        "images.bin",
        "record 1 (image id 9",
        "no terminating NUL",
    );
    let dir = setup("b-utf8");
    patch(&dir, "images.bin", |b| b[8 + 4 + 56 + 4] = 0xff);
    expect_format(bin(&dir), "images.bin", "record 0 (image id 2", "UTF-8");
}

#[test]
fn binary_huge_inner_counts_do_not_allocate() {
    // A keypoint count and a track length far beyond the file size are reported, not
    // allocated.
    let dir = setup("b-kp");
    let kp_count_at = 8 + 4 + 56 + 4 + "img2.jpg".len() + 1;
    patch(&dir, "images.bin", |b| {
        b[kp_count_at..kp_count_at + 8].copy_from_slice(&(u64::MAX / 2).to_le_bytes())
    });
    expect_format(
        bin(&dir),
        "images.bin",
        "record 0 (image id 2",
        "2D points need",
    );
    let dir = setup("b-track");
    let track_at = 8 + 8 + 24 + 3 + 8;
    patch(&dir, "points3D.bin", |b| {
        b[track_at..track_at + 8].copy_from_slice(&(1u64 << 60).to_le_bytes())
    });
    expect_format(
        bin(&dir),
        "points3D.bin",
        "record 0 (point3D id 10",
        "track of",
    );
}

/// Parse the three files of one format from memory with the stream readers (what the
/// path readers do, without the file system), ignoring the result.
fn parse_all(dir: &Path, files: &[(&str, Vec<u8>)], binary: bool) -> bool {
    use relight_cpc::import::colmap::{binary as b, text as t};
    let mut ok = true;
    for (name, bytes) in files {
        let p = dir.join(name);
        let r = match (binary, *name) {
            (true, "cameras.bin") => b::read_cameras(&bytes[..], &p).map(|_| ()),
            (true, "images.bin") => b::read_images(&bytes[..], &p).map(|_| ()),
            (true, _) => b::read_points3d(&bytes[..], &p).map(|_| ()),
            (false, "cameras.txt") => t::read_cameras(&bytes[..], &p).map(|_| ()),
            (false, "images.txt") => t::read_images(&bytes[..], &p).map(|_| ()),
            (false, _) => t::read_points3d(&bytes[..], &p).map(|_| ()),
        };
        ok &= r.is_ok();
    }
    ok
}

/// Every prefix of every binary file is an error, never a panic; every single-byte change
/// is an error or a model, never a panic.
#[test]
fn binary_prefixes_and_byte_flips_never_panic() {
    let dir = setup("b-fuzz");
    for name in ["cameras.bin", "images.bin", "points3D.bin"] {
        let orig = std::fs::read(dir.join(name)).unwrap();
        for len in 0..orig.len() {
            let cut = vec![(name, orig[..len].to_vec())];
            assert!(
                !parse_all(&dir, &cut, true),
                "{name} cut to {len} bytes read without error"
            );
        }
        for i in 0..orig.len() {
            let mut b = orig.clone();
            b[i] ^= 0xa5;
            parse_all(&dir, &[(name, b)], true);
        }
        assert!(parse_all(&dir, &[(name, orig)], true));
    }
}

/// The same for text: every prefix and every character replaced by one of a few others.
#[test]
fn text_edits_never_panic() {
    let dir = setup("t-fuzz");
    for name in ["cameras.txt", "images.txt", "points3D.txt"] {
        let orig = std::fs::read(dir.join(name)).unwrap();
        for len in 0..orig.len() {
            parse_all(&dir, &[(name, orig[..len].to_vec())], false);
        }
        for i in 0..orig.len() {
            for c in [b'x', b'-', b' ', b'\n', b'9', 0xff] {
                let mut b = orig.clone();
                b[i] = c;
                parse_all(&dir, &[(name, b)], false);
            }
        }
        assert!(parse_all(&dir, &[(name, orig)], false));
    }
}
