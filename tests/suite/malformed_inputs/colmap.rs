//! COLMAP models, text and binary: missing ids, unknown models, words for numbers,
//! truncation.

use super::*;
use relight_cpc::import::colmap::Reconstruction;

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
