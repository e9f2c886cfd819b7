//! `inspect` on the workspace real COLMAP wrote (tests/fixtures/colmap-buddha, see its
//! README). COLMAP made no dense mesh there (no CUDA), so the tests pass a proxy mesh with
//! `--mesh`: a UV sphere around the sparse points. The counts are checked against COLMAP's
//! own `model_analyzer` log, not against this crate's readers.

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::scratch::scratch;
use crate::uv_sphere::{direction, uv_sphere};
use relight_cpc::import::colmap::Reconstruction;
use relight_cpc::import::mesh::Mesh;
use relight_cpc::observe::inspect::inspect;
use relight_cpc::Vec3;

fn fixture() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/colmap-buddha")
}

/// A UV sphere (`rings` × `segments`) of radius `r` around `c`, written as PLY.
fn sphere_ply(path: &Path, c: Vec3, r: f64, rings: usize, segments: usize) {
    let (pos, faces) = uv_sphere(rings, segments, |th, ph| c + r * direction(th, ph));
    let (mesh, _) = Mesh::from_parts(pos, faces);
    mesh.write_ply(path, &[]).unwrap();
}

/// The proxy mesh: centred on the sparse points, radius half the nearest camera distance,
/// so every camera is outside it and sees its near side.
fn proxy_mesh(dir: &Path) -> PathBuf {
    let (rec, _) = Reconstruction::read(&fixture().join("dense/sparse")).unwrap();
    let n = rec.points3d.len() as f64;
    let c = rec.points3d.values().map(|p| p.xyz).sum::<Vec3>() / n;
    let near = rec
        .images
        .values()
        .map(|im| (im.center() - c).norm())
        .fold(f64::INFINITY, f64::min);
    let path = dir.join("proxy.ply");
    sphere_ply(&path, c, 0.5 * near, 60, 120);
    path
}

#[test]
fn inspect_reports_what_colmap_wrote() {
    let dir = scratch("inspect", "lib");
    let mesh = proxy_mesh(&dir);
    let r = inspect(&fixture(), Some(&mesh)).unwrap();
    // logs/7-model_analyzer.log: 1 camera (single_camera), 8 registered images, 434 points.
    assert_eq!(r.cameras, 1);
    assert_eq!(r.images_registered, 8);
    assert_eq!(r.points3d, 434);
    assert_eq!(r.views_used, 8);
    assert!(r.skipped.is_empty(), "{:?}", r.skipped);
    // The undistorted pair is picked (dense/images are 519x288, the PINHOLE model's size).
    assert!(r.sparse_dir.ends_with("dense/sparse"), "{}", r.sparse_dir);
    assert!(r
        .per_image
        .iter()
        .all(|im| im.width == 519 && im.height == 288));
    // Sphere: 60 rings × 120 segments → 59·120 + 2 vertices, 2·120·59 faces, none dropped.
    assert_eq!(r.mesh_vertices, 59 * 120 + 2);
    assert_eq!(r.mesh_faces, 2 * 120 * 59);
    assert_eq!(r.dropped_faces, 0);
    // Per image: names in order; every camera sees part of the sphere.
    let names: Vec<&str> = r.per_image.iter().map(|i| i.name.as_str()).collect();
    let mut sorted = names.clone();
    sorted.sort();
    assert_eq!(names, sorted);
    assert_eq!(
        r.observations,
        r.per_image
            .iter()
            .map(|i| i.observed_vertices)
            .sum::<usize>()
    );
    for im in &r.per_image {
        assert!(
            im.observed_vertices > 100,
            "{}: {}",
            im.name,
            im.observed_vertices
        );
        assert!((0.0..=1.0).contains(&im.overexposed_fraction));
        assert!(im.mean_confidence > 0.0 && im.mean_confidence <= 1.0);
        // COLMAP's bundle adjustment leaves sub-pixel errors: each image's mean < 1 px.
        let e = im.reprojection_error_px.unwrap();
        assert!(e > 0.0 && e < 1.0, "{}: {e}", im.name);
    }
    // Observation-weighted mean of the per-image means = the overall per-observation mean,
    // which COLMAP reports as 0.364914 px averaged per point instead of per observation:
    // the two weightings differ by track length, a few hundredths of a pixel here (0.05).
    let total: usize = r
        .per_image
        .iter()
        .map(|i| i.reprojection_observations)
        .sum();
    let outliers: usize = r.per_image.iter().map(|i| i.reprojection_outliers).sum();
    // 1581 observations in COLMAP's log; the folded ones (see scene docs) are under 2%.
    assert_eq!(total + outliers, 1581);
    assert!(outliers * 50 < total + outliers, "{outliers} outliers");
    let weighted: f64 = r
        .per_image
        .iter()
        .map(|i| i.reprojection_error_px.unwrap() * i.reprojection_observations as f64)
        .sum::<f64>()
        / total as f64;
    let overall = r.mean_reprojection_error_px.unwrap();
    assert!((weighted - overall).abs() < 1e-9);
    assert!((overall - 0.364914).abs() < 0.05, "{overall}");
    // Human-readable form names every photo.
    let text = r.to_string();
    assert!(names.iter().all(|n| text.contains(n)));
}

#[test]
fn cli_json_has_the_issue_keys_and_errors_exit_nonzero() {
    let dir = scratch("inspect", "cli");
    let mesh = proxy_mesh(&dir);
    let exe = env!("CARGO_BIN_EXE_relight-cpc");
    let out = Command::new(exe)
        .args(["inspect", "--json", "--mesh"])
        .arg(&mesh)
        .arg(fixture())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    for key in [
        "cameras",
        "images_registered",
        "points3d",
        "mesh_vertices",
        "mesh_faces",
        "observations",
        "per_image",
    ] {
        assert!(v.get(key).is_some(), "missing key {key}");
    }
    let first = &v["per_image"][0];
    for key in [
        "name",
        "observed_vertices",
        "overexposed_fraction",
        "reprojection_error_px",
    ] {
        assert!(first.get(key).is_some(), "per_image lacks {key}");
    }
    assert_eq!(v["images_registered"], 8);

    // A workspace that does not exist: exit 1, the path named on stderr.
    let missing = dir.join("no-such-workspace");
    let out = Command::new(exe)
        .arg("inspect")
        .arg(&missing)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("no-such-workspace"), "{err}");
}
