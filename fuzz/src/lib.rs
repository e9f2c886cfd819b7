//! The checks both fuzz drivers run: the input goes into a reader; an `Err` must name the
//! file it was read from, an `Ok` must be a consistent model. A panic (or an abort from
//! an absurd allocation) is the failure the drivers look for.

use relight_cpc::import::colmap::{binary, text};
use relight_cpc::import::mesh::Mesh;
use std::path::{Path, PathBuf};

fn check_err(r: relight_cpc::Result<()>, path: &Path) {
    if let Err(e) = r {
        let msg = e.to_string();
        assert!(
            msg.contains(&*path.to_string_lossy()),
            "error does not name the file: {msg}"
        );
        assert!(!has_debug_text(&msg), "error shows Debug text: {msg}");
    }
}

/// Whether `msg` carries a library's `Debug` formatting (`Error { kind: .. }`,
/// `Custom { .. }`, `Some(..)`, ply-rs's tab-indented `Error:` lines) instead of words.
pub fn has_debug_text(msg: &str) -> bool {
    ["Error {", "kind:", "Custom {", "Os {", "Some(", "\tError", "\tString"]
        .iter()
        .any(|p| msg.contains(p))
}

/// The first input byte picks cameras / images / points3D; the rest is the file.
fn split(data: &[u8]) -> (u8, &[u8]) {
    match data.split_first() {
        Some((k, rest)) => (k % 3, rest),
        None => (0, data),
    }
}

/// COLMAP text readers.
pub fn colmap_text(data: &[u8]) {
    let (k, bytes) = split(data);
    let path = PathBuf::from("/fuzz/model.txt");
    let r = match k {
        0 => text::read_cameras(bytes, &path).map(|_| ()),
        1 => text::read_images(bytes, &path).map(|_| ()),
        _ => text::read_points3d(bytes, &path).map(|_| ()),
    };
    check_err(r, &path);
}

/// COLMAP binary readers.
pub fn colmap_binary(data: &[u8]) {
    let (k, bytes) = split(data);
    let path = PathBuf::from("/fuzz/model.bin");
    let r = match k {
        0 => binary::read_cameras(bytes, &path).map(|_| ()),
        1 => binary::read_images(bytes, &path).map(|_| ()),
        _ => binary::read_points3d(bytes, &path).map(|_| ()),
    };
    check_err(r, &path);
}

/// The PLY mesh reader (through a temporary file: `Mesh::read_ply` takes a path).
pub fn ply(data: &[u8]) {
    let path = std::env::temp_dir().join(format!("relight-fuzz-{}.ply", std::process::id()));
    if std::fs::write(&path, data).is_err() {
        return;
    }
    match Mesh::read_ply(&path) {
        Ok((mesh, _)) => {
            let n = mesh.positions.len();
            assert!(mesh.faces.iter().flatten().all(|&i| (i as usize) < n));
            assert_eq!(mesh.normals.len(), n);
            assert!(mesh
                .positions
                .iter()
                .all(|p| p.iter().all(|c| c.is_finite())));
        }
        Err(e) => check_err(Err(e), &path),
    }
}

/// The lat-long EXR reader (environment maps; `render --env`).
pub fn envmap(data: &[u8]) {
    let name = "/fuzz/map.exr";
    match relight_cpc::sphere::envmap::LatLong::read_exr_bytes(data, name) {
        Ok((map, _)) => {
            assert_eq!(map.width, 2 * map.height);
            assert!(map.rgb.iter().flatten().all(|c| c.is_finite() && *c >= 0.0));
        }
        Err(e) => check_err(Err(e), Path::new(name)),
    }
}

/// Names of the targets, for the stable driver.
pub const TARGETS: [&str; 4] = ["colmap_text", "colmap_binary", "ply", "envmap"];

/// Runs target `name` on `data`.
pub fn run_target(name: &str, data: &[u8]) {
    match name {
        "colmap_text" => colmap_text(data),
        "colmap_binary" => colmap_binary(data),
        "envmap" => envmap(data),
        _ => ply(data),
    }
}
