//! The catalogue of malformed inputs and unsafe output folders (issue 23): one test each.
//! Every error must name the file, say where (element / record / line) and what was
//! expected and found, in words: no panic, no library `Debug` text (`Error { kind: .. }`,
//! `Custom { .. }`, ply-rs's tab-indented `Error:` lines). The CLI cases run the built
//! binary and check its exit status and stderr; the output-folder cases check that every
//! file is intact afterwards (same bytes).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use crate::scratch::{scratch, Scratch};
use relight_cpc::import::colmap::Reconstruction;
use relight_cpc::import::mesh::Mesh;
use relight_cpc::import::photo::Photo;
use relight_cpc::out_dir::{OutDir, STAMP};
use relight_cpc::sphere::envmap::LatLong;

/// Library `Debug` formatting that must never reach a user.
const DEBUG_MARKS: [&str; 7] = [
    "Error {", "kind:", "Custom {", "Os {", "Some(", "\tError", "\tString",
];

/// `msg` names `file` and has no Debug text; returns it for further checks.
fn plain(msg: String, file: &Path) -> String {
    assert!(
        msg.contains(&*file.to_string_lossy()),
        "does not name {}: {msg}",
        file.display()
    );
    for m in DEBUG_MARKS {
        assert!(!msg.contains(m), "Debug text {m:?} in: {msg}");
    }
    msg
}

/// `err` is an error naming `file`, and its message contains every word of `words`.
fn expect<T: std::fmt::Debug>(r: relight_cpc::Result<T>, file: &Path, words: &[&str]) {
    let msg = plain(
        r.expect_err("malformed input was accepted").to_string(),
        file,
    );
    for w in words {
        assert!(msg.contains(w), "{w:?} missing from: {msg}");
    }
}

fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

/// A scratch folder holding `name` with `bytes`.
fn file(tag: &str, name: &str, bytes: &[u8]) -> (Scratch, PathBuf) {
    let dir = scratch("malformed", tag);
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    (dir, p)
}

const ASCII_HEAD: &str = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n\
property float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\n\
end_header\n";

// ---------------------------------------------------------------- PLY meshes

#[test]
fn ply_truncated_binary_mesh() {
    // The example's real mesh (binary), cut in the middle of its face list.
    let bytes = std::fs::read(repo("examples/spot/dense/meshed-poisson.ply")).unwrap();
    let (_d, p) = file("ply-trunc-bin", "mesh.ply", &bytes[..bytes.len() * 3 / 4]);
    expect(
        Mesh::read_ply(&p),
        &p,
        &["`face` element", "ends early", "expected"],
    );
}

#[test]
fn ply_truncated_ascii_mesh() {
    let text = format!("{ASCII_HEAD}0 0 0\n1 0 0\n");
    let (_d, p) = file("ply-trunc-ascii", "mesh.ply", text.as_bytes());
    expect(
        Mesh::read_ply(&p),
        &p,
        &["`vertex` element", "expected 3", "found 2"],
    );
}

#[test]
fn ply_more_vertices_announced_than_written() {
    // Header says 5 vertices; the face line is read as vertex 3, then the file ends.
    let text = ASCII_HEAD.replace("vertex 3", "vertex 5") + "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    let (_d, p) = file("ply-count-more", "mesh.ply", text.as_bytes());
    expect(Mesh::read_ply(&p), &p, &["expected 5", "found 4"]);
}

#[test]
fn ply_fewer_vertices_announced_than_used() {
    // Header says 2 vertices: the face `3 0 1 2` then uses index 2 of 2 vertices.
    let text = ASCII_HEAD.replace("vertex 3", "vertex 2") + "0 0 0\n1 0 0\n3 0 1 2\n";
    let (_d, p) = file("ply-count-fewer", "mesh.ply", text.as_bytes());
    expect(
        Mesh::read_ply(&p),
        &p,
        &["face 0", "expected vertex indices 0 to 1"],
    );
}

#[test]
fn ply_face_index_out_of_range() {
    let text = format!("{ASCII_HEAD}0 0 0\n1 0 0\n0 1 0\n3 0 1 9\n");
    let (_d, p) = file("ply-index", "mesh.ply", text.as_bytes());
    expect(Mesh::read_ply(&p), &p, &["face 0", "0 to 2", "found 9"]);
}

#[test]
fn ply_negative_face_index() {
    let text = format!("{ASCII_HEAD}0 0 0\n1 0 0\n0 1 0\n3 0 -4 1\n");
    let (_d, p) = file("ply-negative", "mesh.ply", text.as_bytes());
    expect(Mesh::read_ply(&p), &p, &["face 0", "found -4"]);
}

#[test]
fn ply_triangle_strips_are_refused_in_words() {
    let text = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
property float z\nelement tristrips 1\nproperty list int int vertex_indices\nend_header\n\
0 0 0\n1 0 0\n0 1 0\n1 1 0\n4 0 1 2 3\n";
    let (_d, p) = file("ply-strips", "mesh.ply", text.as_bytes());
    expect(
        Mesh::read_ply(&p),
        &p,
        &["header", "triangle strips", "`face`"],
    );
}

#[test]
fn ply_polygons_are_accepted_as_triangle_fans() {
    // A quad and a pentagon: fans of 2 and 3 triangles (5 in all), nothing refused.
    let text = "ply\nformat ascii 1.0\nelement vertex 6\nproperty float x\nproperty float y\n\
property float z\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n\
0 0 0\n1 0 0\n1 1 0\n0 1 0\n2 0.5 0\n1.5 -1 0\n4 0 1 2 3\n5 1 5 4 2 0\n";
    let (_d, p) = file("ply-polygons", "mesh.ply", text.as_bytes());
    let (mesh, cleanup) = Mesh::read_ply(&p).unwrap();
    assert_eq!(cleanup.polygons_triangulated, 2);
    assert_eq!(mesh.faces.len() + cleanup.degenerate_faces, 5);
}

#[test]
fn ply_nan_coordinate_binary() {
    let mut bytes = ASCII_HEAD
        .replace("ascii", "binary_little_endian")
        .into_bytes();
    for v in [[0.0f32, 0.0, 0.0], [1.0, f32::NAN, 0.0], [0.0, 1.0, 0.0]] {
        for c in v {
            bytes.extend(c.to_le_bytes());
        }
    }
    bytes.push(3);
    for k in [0i32, 1, 2] {
        bytes.extend(k.to_le_bytes());
    }
    let (_d, p) = file("ply-nan-bin", "mesh.ply", &bytes);
    expect(Mesh::read_ply(&p), &p, &["vertex 1", "finite", "NaN"]);
}

#[test]
fn ply_nan_coordinate_ascii() {
    let text = format!("{ASCII_HEAD}0 0 0\nnan 0 0\n0 1 0\n3 0 1 2\n");
    let (_d, p) = file("ply-nan-ascii", "mesh.ply", text.as_bytes());
    expect(
        Mesh::read_ply(&p),
        &p,
        &["line 11", "`vertex` record 1", "nan 0 0"],
    );
}

#[test]
fn ply_word_where_a_number_belongs() {
    let text = format!("{ASCII_HEAD}0 0 0\n1 0 0\n0 one 0\n3 0 1 2\n");
    let (_d, p) = file("ply-word", "mesh.ply", text.as_bytes());
    expect(Mesh::read_ply(&p), &p, &["line 12", "x y z", "0 one 0"]);
}

#[test]
fn ply_that_is_a_png() {
    let (_d, p) = file("ply-png", "mesh.ply", b"\x89PNG\r\n\x1a\n....");
    expect(Mesh::read_ply(&p), &p, &["line 1", "not a PLY file"]);
}

#[test]
fn ply_empty_file() {
    let (_d, p) = file("ply-empty", "mesh.ply", b"");
    expect(Mesh::read_ply(&p), &p, &["not a PLY file"]);
}

#[test]
fn ply_unknown_format_line() {
    let text = ASCII_HEAD.replace("format ascii 1.0", "format utf16 1.0");
    let (_d, p) = file("ply-format", "mesh.ply", text.as_bytes());
    expect(Mesh::read_ply(&p), &p, &["line 2", "format utf16 1.0"]);
}

#[test]
fn ply_header_without_end() {
    let (_d, p) = file(
        "ply-noend",
        "mesh.ply",
        b"ply\nformat ascii 1.0\nelement vertex 3\n",
    );
    expect(Mesh::read_ply(&p), &p, &["header", "end_header"]);
}

#[test]
fn ply_without_z() {
    let text = ASCII_HEAD.replace("property float z\n", "");
    let (_d, p) = file("ply-noz", "mesh.ply", text.as_bytes());
    expect(Mesh::read_ply(&p), &p, &["header", "x, y, z"]);
}

#[test]
fn ply_huge_vertex_count_in_a_small_file() {
    // 4 294 967 295 vertices announced, 3 given: an error, not an allocation abort.
    let text =
        ASCII_HEAD.replace("vertex 3", "vertex 4294967295") + "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    let (_d, p) = file("ply-huge", "mesh.ply", text.as_bytes());
    expect(Mesh::read_ply(&p), &p, &["expected 4294967295", "found 4"]);
}

// ---------------------------------------------------------------- environment maps

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

// ---------------------------------------------------------------- photos

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

// ---------------------------------------------------------------- COLMAP models

/// A copy of the example's sparse model (text) in a scratch folder.
fn sparse_copy(tag: &str) -> Scratch {
    let d = scratch("malformed", tag);
    for f in ["cameras.txt", "images.txt", "points3D.txt"] {
        std::fs::copy(repo("examples/spot/sparse").join(f), d.join(f)).unwrap();
    }
    d
}

/// The first data line (not a comment) of `file` in `dir`, and its 1-based number.
fn first_data_line(dir: &Path, file: &str) -> (usize, String) {
    let text = std::fs::read_to_string(dir.join(file)).unwrap();
    text.lines()
        .enumerate()
        .find(|(_, l)| !l.starts_with('#') && !l.trim().is_empty())
        .map(|(i, l)| (i + 1, l.to_string()))
        .unwrap()
}

fn replace_line(dir: &Path, file: &str, line: usize, with: &str) {
    let p = dir.join(file);
    let text = std::fs::read_to_string(&p).unwrap();
    let mut lines: Vec<&str> = text.lines().collect();
    lines[line - 1] = with;
    std::fs::write(&p, lines.join("\n") + "\n").unwrap();
}

#[test]
fn colmap_camera_id_missing_from_cameras_names_images_txt() {
    let d = sparse_copy("colmap-camref");
    let (n, line) = first_data_line(&d, "images.txt");
    // IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME: point CAMERA_ID at 999.
    let mut f: Vec<&str> = line.split_whitespace().collect();
    f[8] = "999";
    replace_line(&d, "images.txt", n, &f.join(" "));
    let p = d.join("images.txt");
    expect(
        Reconstruction::read_text(&d),
        &p,
        &["found camera id 999", "cameras.txt"],
    );
}

#[test]
fn colmap_unknown_camera_model_names_the_line() {
    let d = sparse_copy("colmap-model");
    let (n, line) = first_data_line(&d, "cameras.txt");
    let mut f: Vec<&str> = line.split_whitespace().collect();
    f[1] = "FISHEYE_WHATEVER";
    replace_line(&d, "cameras.txt", n, &f.join(" "));
    let p = d.join("cameras.txt");
    expect(
        Reconstruction::read_text(&d),
        &p,
        &[&format!("line {n}"), "FISHEYE_WHATEVER"],
    );
}

#[test]
fn colmap_point_with_a_word_for_a_coordinate() {
    let d = sparse_copy("colmap-point");
    let (n, line) = first_data_line(&d, "points3D.txt");
    let mut f: Vec<&str> = line.split_whitespace().collect();
    f[2] = "north";
    replace_line(&d, "points3D.txt", n, &f.join(" "));
    let p = d.join("points3D.txt");
    expect(Reconstruction::read_text(&d), &p, &[&format!("line {n}")]);
}

#[test]
fn colmap_binary_cameras_truncated() {
    let d = sparse_copy("colmap-bin");
    let rec = Reconstruction::read_text(&d).unwrap();
    rec.write_binary(&d).unwrap();
    let p = d.join("cameras.bin");
    let bytes = std::fs::read(&p).unwrap();
    std::fs::write(&p, &bytes[..bytes.len() - 5]).unwrap();
    expect(Reconstruction::read_binary(&d), &p, &["record"]);
}

#[test]
fn colmap_binary_camera_id_missing_names_images_bin() {
    let d = sparse_copy("colmap-bin-ref");
    let mut rec = Reconstruction::read_text(&d).unwrap();
    let first = *rec.images.keys().next().unwrap();
    rec.images.get_mut(&first).unwrap().camera_id.0 = 999;
    rec.write_binary(&d).unwrap();
    let p = d.join("images.bin");
    expect(
        Reconstruction::read_binary(&d),
        &p,
        &["found camera id 999", "cameras.bin"],
    );
}

// ---------------------------------------------------------------- files the tool writes

#[test]
fn disk_full_while_writing_a_mesh_is_a_clear_error() {
    // /dev/full accepts the open and fails every write with ENOSPC.
    let dev = Path::new("/dev/full");
    if !dev.exists() {
        eprintln!("skipped: no /dev/full on this system");
        return;
    }
    let (mesh, _) = Mesh::from_parts(
        vec![
            relight_cpc::Vec3::zeros(),
            relight_cpc::Vec3::x(),
            relight_cpc::Vec3::y(),
        ],
        vec![[0, 1, 2]],
    );
    let msg = plain(mesh.write_ply(dev, &[]).unwrap_err().to_string(), dev);
    assert!(msg.contains("No space left"), "{msg}");
}

#[test]
fn disk_full_while_writing_a_map_is_a_clear_error() {
    let dev = Path::new("/dev/full");
    if !dev.exists() {
        eprintln!("skipped: no /dev/full on this system");
        return;
    }
    let msg = plain(
        LatLong::black(4).write_exr(dev).unwrap_err().to_string(),
        dev,
    );
    assert!(msg.contains("No space left"), "{msg}");
}

// ---------------------------------------------------------------- output folders (library)

/// Every file under `dir` with its bytes, sorted: to compare before and after.
fn snapshot(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.push((p.clone(), std::fs::read(&p).unwrap()));
            }
        }
    }
    out.sort();
    out
}

#[test]
fn out_folder_under_a_file_is_refused_before_any_work() {
    // The folder cannot exist: its parent is a file (works as root, unlike chmod).
    let (_d, f) = file("out-under-file", "notes.txt", b"mine");
    let out = f.join("result");
    let msg = OutDir::claim(&out, true, &[], "test")
        .unwrap_err()
        .to_string();
    assert!(msg.contains("is a file"), "{msg}");
    assert_eq!(std::fs::read(&f).unwrap(), b"mine");
}

#[test]
fn out_folder_on_a_read_only_file_system_is_refused() {
    // sysfs refuses new folders even to root (EPERM), like a read-only mount.
    let sys = Path::new("/sys");
    if !sys.is_dir() {
        eprintln!("skipped: no /sys on this system");
        return;
    }
    let out = sys.join("relight-cpc-result");
    let msg = OutDir::claim(&out, false, &[], "test")
        .unwrap_err()
        .to_string();
    assert!(
        msg.contains("cannot write in /sys") && msg.contains("permission denied"),
        "{msg}"
    );
}

#[test]
fn out_folder_error_leaves_the_previous_result_untouched() {
    // A command that fails after the claim (its staging folder dropped) leaves the old
    // result as it was and no staging folder beside it.
    let d = scratch("malformed", "out-fail");
    let out = d.join("res");
    let c = OutDir::claim(&out, false, &[], "test").unwrap();
    std::fs::write(c.path().join("a.txt"), "old").unwrap();
    c.commit().unwrap();
    let before = snapshot(&d);
    {
        let c = OutDir::claim(&out, true, &[], "test").unwrap();
        std::fs::write(c.path().join("a.txt"), "half-written").unwrap();
        // dropped without commit: the command failed
    }
    assert_eq!(snapshot(&d), before);
}

// ---------------------------------------------------------------- the CLI

/// A copy of the built-in example in a scratch folder (so no test can harm the repo's).
fn example_copy(tag: &str) -> (Scratch, PathBuf) {
    let d = scratch("malformed", tag);
    let ws = d.join("spot");
    let mut stack = vec![repo("examples/spot")];
    let root = repo("examples/spot");
    while let Some(s) = stack.pop() {
        let rel = s.strip_prefix(&root).unwrap();
        std::fs::create_dir_all(ws.join(rel)).unwrap();
        for e in std::fs::read_dir(&s).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                std::fs::copy(&p, ws.join(rel).join(p.file_name().unwrap())).unwrap();
            }
        }
    }
    (d, ws)
}

fn cli(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_relight-cpc"))
        .args(args)
        .output()
        .unwrap()
}

/// The CLI failed with exit status 1, no panic, and a plain message containing `words`.
fn cli_refused(o: &Output, words: &[&str]) -> String {
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(o.status.code(), Some(1), "stderr: {err}");
    assert!(!err.contains("panicked"), "{err}");
    for m in DEBUG_MARKS {
        assert!(!err.contains(m), "Debug text {m:?} in: {err}");
    }
    for w in words {
        assert!(err.contains(w), "{w:?} missing from: {err}");
    }
    err
}

#[test]
fn cli_truncated_mesh_is_a_plain_error_naming_the_file() {
    let (d, ws) = example_copy("cli-mesh");
    let mesh = ws.join("dense/meshed-poisson.ply");
    let bytes = std::fs::read(&mesh).unwrap();
    std::fs::write(&mesh, &bytes[..bytes.len() / 2]).unwrap();
    let out = d.join("out");
    let o = cli(&[
        "run",
        ws.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    cli_refused(&o, &[mesh.to_str().unwrap(), "ends early"]);
    assert!(!out.exists(), "no result folder for a failed run");
}

#[test]
fn cli_rerun_without_force_is_refused_naming_force() {
    let (d, ws) = example_copy("cli-rerun");
    let out = d.join("out");
    std::fs::create_dir(&out).unwrap();
    std::fs::write(out.join(STAMP), "{}").unwrap();
    std::fs::write(out.join("report.json"), "{}").unwrap();
    let before = snapshot(&d);
    let o = cli(&["run", ws.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    cli_refused(&o, &["--force", "previous result"]);
    assert_eq!(snapshot(&d), before);
}

#[test]
fn cli_force_on_a_foreign_folder_is_refused_naming_its_files() {
    let (d, ws) = example_copy("cli-foreign");
    let out = d.join("mine");
    std::fs::create_dir_all(out.join("photos")).unwrap();
    std::fs::write(out.join("notes.txt"), "my notes").unwrap();
    let before = snapshot(&d);
    let o = cli(&[
        "run",
        ws.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--force",
    ]);
    cli_refused(&o, &["not a relight-cpc result", "notes.txt", "photos"]);
    assert_eq!(snapshot(&d), before);
}

#[test]
fn cli_force_on_the_workspace_itself_is_refused() {
    let (d, ws) = example_copy("cli-ws");
    let before = snapshot(&d);
    let o = cli(&[
        "run",
        ws.to_str().unwrap(),
        "--out",
        ws.to_str().unwrap(),
        "--force",
    ]);
    cli_refused(&o, &["is the input folder"]);
    assert_eq!(snapshot(&d), before);
}

#[test]
fn cli_force_on_a_folder_holding_the_workspace_is_refused() {
    let (d, ws) = example_copy("cli-parent");
    let before = snapshot(&d);
    let o = cli(&[
        "run",
        ws.to_str().unwrap(),
        "--out",
        d.to_str().unwrap(),
        "--force",
    ]);
    cli_refused(&o, &["contains the input"]);
    assert_eq!(snapshot(&d), before);
}

#[test]
fn cli_force_on_the_mesh_folder_is_refused() {
    let (d, ws) = example_copy("cli-meshdir");
    let dense = ws.join("dense");
    let before = snapshot(&d);
    let o = cli(&[
        "run",
        ws.to_str().unwrap(),
        "--mesh",
        dense.join("meshed-poisson.ply").to_str().unwrap(),
        "--out",
        dense.to_str().unwrap(),
        "--force",
    ]);
    cli_refused(&o, &["folder of the input file"]);
    assert_eq!(snapshot(&d), before);
}

#[test]
fn cli_root_folder_is_refused() {
    let (_d, ws) = example_copy("cli-root");
    let o = cli(&["run", ws.to_str().unwrap(), "--out", "/", "--force"]);
    cli_refused(&o, &["root folder"]);
}

#[test]
fn cli_home_folder_is_refused() {
    let (d, ws) = example_copy("cli-home");
    let home = d.join("home");
    std::fs::create_dir(&home).unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_relight-cpc"))
        .args(["run", ws.to_str().unwrap(), "--out", home.to_str().unwrap()])
        .env("HOME", &home)
        .output()
        .unwrap();
    cli_refused(&o, &["home folder"]);
}

#[test]
fn cli_synth_onto_a_foreign_folder_is_refused() {
    let d = scratch("malformed", "cli-synth");
    std::fs::write(d.join("keep.txt"), "mine").unwrap();
    let before = snapshot(&d);
    let o = cli(&["synth", "sphere-diffuse", d.to_str().unwrap(), "--force"]);
    cli_refused(&o, &["keep.txt"]);
    assert_eq!(snapshot(&d), before);
}

#[test]
fn cli_bench_onto_a_foreign_report_is_refused() {
    let d = scratch("malformed", "cli-bench");
    std::fs::write(d.join("pipeline.json"), "[1, 2, 3]").unwrap();
    let before = snapshot(&d);
    let o = cli(&["bench", "--quick", "--out", d.to_str().unwrap(), "--force"]);
    cli_refused(&o, &["pipeline.json", "not a relight-cpc result"]);
    assert_eq!(snapshot(&d), before);
}

/// SIGTERM during a run: the staging folder is removed, the previous result is as it was,
/// and nothing that looks like a finished result appears.
#[cfg(unix)]
#[test]
fn cli_interrupted_run_leaves_the_previous_result_untouched() {
    let (d, ws) = example_copy("cli-kill");
    let out = d.join("out");
    std::fs::create_dir(&out).unwrap();
    std::fs::write(out.join(STAMP), "{}").unwrap();
    std::fs::write(out.join("report.json"), "previous").unwrap();
    let before = snapshot(&d);
    let mut child = Command::new(env!("CARGO_BIN_EXE_relight-cpc"))
        .args(["run", ws.to_str().unwrap(), "--out", out.to_str().unwrap()])
        .args(["--force", "--quiet"])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Wait (up to 60 s) for the staging folder, i.e. for work to have started.
    let staging = || {
        std::fs::read_dir(&d)
            .unwrap()
            .filter_map(|e| e.ok())
            .any(|e| {
                e.file_name()
                    .to_string_lossy()
                    .contains("relight-cpc-staging")
            })
    };
    let t0 = std::time::Instant::now();
    while !staging() && t0.elapsed().as_secs() < 60 {
        if child.try_wait().unwrap().is_some() {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    assert!(staging(), "the run never created its staging folder");
    Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(128 + 15), "exit status after SIGTERM");
    assert!(!staging(), "staging folder left behind");
    assert_eq!(snapshot(&d), before, "previous result changed");
}
