//! Whole-workspace import on small workspaces written here: photos missing or unregistered
//! (skipped and reported), no photo at all, a photo of the wrong size and an unreadable
//! photo (errors naming the photo, and `inspect` exiting 1), and the fused point cloud
//! carried to the mesh with known distances.

use std::collections::BTreeMap;
use std::path::Path;
use std::process::Command;

use crate::scratch::scratch;
use image::{ImageBuffer, Rgb};
use nalgebra::{Matrix3, Rotation3};
use relight_cpc::import::colmap::{Camera, CameraId, Image, ImageId, Reconstruction};
use relight_cpc::import::mesh::Mesh;
use relight_cpc::import::photo::DEFAULT_CLIP;
use relight_cpc::import::scene::{load_photos, load_scene};
use relight_cpc::import::workspace::Workspace;
use relight_cpc::{Error, Vec3};

const W: u32 = 64;
const H: u32 = 48;

/// Cube [-1, 1]³ as 8 vertices and 12 outward triangles.
fn cube() -> Mesh {
    let p: Vec<Vec3> = (0..8)
        .map(|i| {
            Vec3::new(
                if i & 1 == 1 { 1.0 } else { -1.0 },
                if i & 2 == 2 { 1.0 } else { -1.0 },
                if i & 4 == 4 { 1.0 } else { -1.0 },
            )
        })
        .collect();
    let f = vec![
        [0, 2, 1],
        [1, 2, 3],
        [4, 5, 6],
        [5, 7, 6],
        [0, 1, 4],
        [1, 5, 4],
        [2, 6, 3],
        [3, 6, 7],
        [0, 4, 2],
        [2, 4, 6],
        [1, 3, 5],
        [3, 7, 5],
    ];
    Mesh::from_parts(p, f).0
}

/// A workspace with `sparse/` (text), `images/` and `dense/meshed-poisson.ply`: three
/// registered images a.png, b.png, c.png looking at the cube from +z, +x, −z.
fn workspace(root: &Path) {
    let cam = Camera::pinhole(CameraId(3), W, H, 60.0, 60.0, 32.0, 24.0);
    let poses = [
        (
            "a.png",
            [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]],
            Vec3::new(0.0, 0.0, 6.0),
        ),
        (
            "b.png",
            [[0.0, 0.0, -1.0], [0.0, -1.0, 0.0], [-1.0, 0.0, 0.0]],
            Vec3::new(6.0, 0.0, 0.0),
        ),
        (
            "c.png",
            [[-1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0]],
            Vec3::new(0.0, 0.0, -6.0),
        ),
    ];
    let mut images = BTreeMap::new();
    for (k, (name, rows, c)) in poses.iter().enumerate() {
        let r = Rotation3::from_matrix_unchecked(Matrix3::from_row_slice(&rows.concat()));
        let id = ImageId(10 + 5 * k as u32); // not contiguous
        images.insert(id, Image::from_pose(id, *name, cam.id, &r, &-(r * c)));
    }
    let rec = Reconstruction {
        cameras: [(cam.id, cam)].into_iter().collect(),
        images,
        points3d: BTreeMap::new(),
    };
    rec.write_text(&root.join("sparse")).unwrap();
    std::fs::create_dir_all(root.join("images")).unwrap();
    for name in ["a.png", "b.png", "c.png"] {
        write_photo(&root.join("images").join(name), W, H);
    }
    std::fs::create_dir_all(root.join("dense")).unwrap();
    cube()
        .write_ply(&root.join("dense/meshed-poisson.ply"), &[])
        .unwrap();
}

fn write_photo(path: &Path, w: u32, h: u32) {
    ImageBuffer::from_fn(w, h, |i, j| Rgb([(i * 3) as u8, (j * 5) as u8, 100u8]))
        .save(path)
        .unwrap();
}

#[test]
fn complete_workspace_imports_every_view_in_name_order() {
    let root = scratch("scene", "complete");
    workspace(&root);
    let scene = load_scene(Workspace::discover(&root, None).unwrap()).unwrap();
    let names: Vec<&str> = scene.views.iter().map(|v| v.image.name.as_str()).collect();
    assert_eq!(names, ["a.png", "b.png", "c.png"]);
    assert!(scene.skipped.is_empty());
    assert_eq!(scene.mesh.positions.len(), 8);
    assert!(scene.fused.is_none());
    let photos = load_photos(&scene, DEFAULT_CLIP).unwrap();
    assert_eq!(photos.len(), 3);
    assert!(photos.iter().all(|p| (p.width, p.height) == (W, H)));
}

#[test]
fn missing_and_unregistered_photos_are_skipped_with_reasons() {
    let root = scratch("scene", "skips");
    workspace(&root);
    std::fs::remove_file(root.join("images/b.png")).unwrap();
    write_photo(&root.join("images/stray.png"), W, H);
    let scene = load_scene(Workspace::discover(&root, None).unwrap()).unwrap();
    let names: Vec<&str> = scene.views.iter().map(|v| v.image.name.as_str()).collect();
    assert_eq!(names, ["a.png", "c.png"]);
    assert_eq!(scene.skipped.len(), 2, "{:?}", scene.skipped);
    assert!(scene.skipped[0].starts_with("b.png: registered"));
    assert!(scene.skipped[1].starts_with("stray.png: in the photo folder but not registered"));
}

#[test]
fn no_photo_at_all_is_an_error() {
    let root = scratch("scene", "none");
    workspace(&root);
    for n in ["a.png", "b.png", "c.png"] {
        std::fs::remove_file(root.join("images").join(n)).unwrap();
    }
    match load_scene(Workspace::discover(&root, None).unwrap()).unwrap_err() {
        Error::Workspace { path, message } => {
            assert_eq!(path, root.join("images"));
            assert!(message.contains("none of the 3"), "{message}");
        }
        other => panic!("{other}"),
    }
}

#[test]
fn wrong_size_and_unreadable_photos_are_errors_naming_the_photo() {
    let root = scratch("scene", "wrongsize");
    workspace(&root);
    write_photo(&root.join("images/b.png"), W + 1, H);
    let scene = load_scene(Workspace::discover(&root, None).unwrap()).unwrap();
    match load_photos(&scene, DEFAULT_CLIP).unwrap_err() {
        Error::Image { path, message } => {
            assert_eq!(path, root.join("images/b.png"));
            assert!(
                message.contains("65x48") && message.contains("64x48"),
                "{message}"
            );
        }
        other => panic!("{other}"),
    }
    // The CLI reports it and exits 1.
    let out = Command::new(env!("CARGO_BIN_EXE_relight-cpc"))
        .arg("inspect")
        .arg(&*root)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("b.png") && err.contains("65x48"), "{err}");

    // Two bad photos: the first in name order is reported, every run.
    std::fs::write(root.join("images/a.png"), b"not a png").unwrap();
    for _ in 0..3 {
        match load_photos(&scene, DEFAULT_CLIP).unwrap_err() {
            Error::Image { path, .. } => assert_eq!(path, root.join("images/a.png")),
            other => panic!("{other}"),
        }
    }
}

#[test]
fn fused_points_transfer_with_known_distances() {
    // Fused points at every cube vertex pushed 0.01 out along its normal and one far
    // outlier: each vertex's nearest point is its own (the others are ≥ 2 away), so every
    // distance is 0.01 and colours/normals come from that point.
    let root = scratch("scene", "fused");
    workspace(&root);
    let mesh = cube();
    let mut pts = Vec::new();
    for (p, n) in mesh.positions.iter().zip(&mesh.normals) {
        pts.push(p + 0.01 * n);
    }
    pts.push(Vec3::new(50.0, 0.0, 0.0));
    let mut ply = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\n\
         property float z\nproperty float nx\nproperty float ny\nproperty float nz\n\
         property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n",
        pts.len()
    );
    for (k, p) in pts.iter().enumerate() {
        ply += &format!("{} {} {} 0 0 1 {} 0 0\n", p.x, p.y, p.z, 10 * k);
    }
    std::fs::write(root.join("dense/fused.ply"), ply).unwrap();
    let scene = load_scene(Workspace::discover(&root, None).unwrap()).unwrap();
    let fused = scene.fused.as_ref().unwrap();
    assert_eq!(fused.n_points, 9);
    // Ascii floats with ~7 significant digits: 1e-6.
    for d in &fused.distance {
        assert!((*d as f64 - 0.01).abs() < 1e-6, "{d}");
    }
    assert!((fused.stats.max - 0.01).abs() < 1e-6 && (fused.stats.mean - 0.01).abs() < 1e-6);
    let colors = fused.colors.as_ref().unwrap();
    for (k, c) in colors.iter().enumerate() {
        assert_eq!(c[0], (10 * k) as f32 / 255.0);
    }
    assert!(fused
        .normals
        .as_ref()
        .unwrap()
        .iter()
        .all(|n| *n == Vec3::z()));
}
