//! Workspace discovery: the layouts COLMAP writes, the preference order (undistorted model
//! with undistorted photos, binary before text), the mesh search and its errors, and the
//! real-COLMAP fixture.

use std::path::Path;

use relight_cpc::import::colmap::{
    Camera, CameraId, Image, ImageId, ModelFormat, Point3D, Point3DId, Reconstruction,
};
use relight_cpc::import::workspace::Workspace;
use relight_cpc::{Error, Vec3};

/// An empty scratch folder, removed when the returned value is dropped.
fn tmp(tag: &str) -> crate::scratch::Scratch {
    crate::scratch::scratch("ws", tag)
}

/// A one-camera, two-image model; `tag` goes into the image names so tests can tell which
/// model was read.
fn model(tag: &str) -> Reconstruction {
    let mut rec = Reconstruction::default();
    let c = Camera::pinhole(CameraId(1), 64, 48, 50.0, 50.0, 32.0, 24.0);
    rec.cameras.insert(c.id, c);
    for id in [1u32, 5] {
        let im = Image::from_pose(
            ImageId(id),
            format!("{tag}{id}.png"),
            CameraId(1),
            &nalgebra::Rotation3::identity(),
            &Vec3::new(0.0, 0.0, 3.0),
        );
        rec.images.insert(im.id, im);
    }
    let p = Point3D {
        id: Point3DId(1),
        xyz: Vec3::zeros(),
        rgb: [1, 2, 3],
        error: 0.1,
        track: vec![],
    };
    rec.points3d.insert(p.id, p);
    rec
}

fn touch(p: &Path) {
    std::fs::create_dir_all(p.parent().unwrap()).unwrap();
    std::fs::write(p, b"ply\n").unwrap();
}

fn image_tag(ws: &Workspace) -> String {
    let rec = ws.read_model().unwrap();
    rec.images
        .values()
        .next()
        .unwrap()
        .name
        .trim_end_matches("1.png")
        .to_string()
}

#[test]
fn undistorted_pair_is_preferred_and_binary_before_text() {
    let root = tmp("pref");
    model("dist").write_binary(&root.join("sparse/0")).unwrap();
    std::fs::create_dir_all(root.join("images")).unwrap();
    model("und")
        .write_binary(&root.join("dense/sparse"))
        .unwrap();
    model("undtxt")
        .write_text(&root.join("dense/sparse"))
        .unwrap();
    std::fs::create_dir_all(root.join("dense/images")).unwrap();
    touch(&root.join("dense/meshed-poisson.ply"));
    touch(&root.join("dense/meshed-delaunay.ply"));
    touch(&root.join("dense/fused.ply"));

    let ws = Workspace::discover(&root, None).unwrap();
    assert_eq!(ws.sparse_dir, root.join("dense/sparse"));
    assert_eq!(ws.sparse_format, ModelFormat::Binary);
    assert_eq!(image_tag(&ws), "und");
    assert_eq!(ws.images_dir, root.join("dense/images"));
    assert_eq!(ws.mesh_path, root.join("dense/meshed-poisson.ply"));
    assert_eq!(ws.fused_path, Some(root.join("dense/fused.ply")));
    assert_eq!(ws.truth_dir, None);
    // The notes say what was picked and what was passed over.
    let notes = ws.notes.join("\n");
    assert!(notes.contains("dense/sparse (binary format, binary read before the text copy"));
    assert!(
        notes.contains("also found a binary model in sparse/0"),
        "{notes}"
    );
}

#[test]
fn undistorted_model_without_its_photos_falls_back() {
    let root = tmp("fallback");
    model("und")
        .write_binary(&root.join("dense/sparse"))
        .unwrap();
    model("dist").write_text(&root.join("sparse")).unwrap();
    std::fs::create_dir_all(root.join("images")).unwrap();
    touch(&root.join("dense/meshed-delaunay.ply"));
    std::fs::create_dir_all(root.join("truth")).unwrap();
    let ws = Workspace::discover(&root, None).unwrap();
    assert_eq!(ws.sparse_dir, root.join("sparse"));
    assert_eq!(ws.sparse_format, ModelFormat::Text);
    assert_eq!(image_tag(&ws), "dist");
    assert_eq!(ws.images_dir, root.join("images"));
    assert_eq!(ws.mesh_path, root.join("dense/meshed-delaunay.ply"));
    assert_eq!(ws.truth_dir, Some(root.join("truth")));
    assert!(ws.notes.join("\n").contains("dense/images is missing"));
}

#[test]
fn numbered_models_lowest_first_and_root_level_mesh() {
    // image_undistorter's own layout at the root (images/, sparse/) plus mapper-style
    // numbered models: sparse/ holds no model itself, sparse/0 and sparse/1 do.
    let root = tmp("numbered");
    model("one").write_text(&root.join("sparse/1")).unwrap();
    model("zero").write_text(&root.join("sparse/0")).unwrap();
    model("ten").write_binary(&root.join("sparse/10")).unwrap();
    std::fs::create_dir_all(root.join("images")).unwrap();
    touch(&root.join("meshed-poisson.ply"));
    let ws = Workspace::discover(&root, None).unwrap();
    assert_eq!(ws.sparse_dir, root.join("sparse/0"));
    assert_eq!(image_tag(&ws), "zero");
    assert_eq!(ws.mesh_path, root.join("meshed-poisson.ply"));
    let notes = ws.notes.join("\n");
    assert!(
        notes.contains("sparse/1") && notes.contains("sparse/10"),
        "{notes}"
    );
}

#[test]
fn mesh_override_and_missing_mesh() {
    let root = tmp("mesh");
    model("m").write_binary(&root.join("sparse")).unwrap();
    std::fs::create_dir_all(root.join("images")).unwrap();
    // No mesh anywhere: a Workspace error listing where it looked.
    match Workspace::discover(&root, None) {
        Err(Error::Workspace { path, message }) => {
            assert_eq!(path, *root);
            assert!(message.contains("no mesh"), "{message}");
            assert!(message.contains("dense/meshed-poisson.ply"), "{message}");
            assert!(message.contains("--mesh"), "{message}");
        }
        other => panic!("{other:?}"),
    }
    // A mesh named by the user.
    let mesh = root.join("elsewhere/my.ply");
    touch(&mesh);
    touch(&root.join("dense/meshed-poisson.ply"));
    let ws = Workspace::discover(&root, Some(&mesh)).unwrap();
    assert_eq!(ws.mesh_path, mesh);
    // A named mesh that does not exist is an error, not a fallback.
    let missing = root.join("nope.ply");
    match Workspace::discover(&root, Some(&missing)) {
        Err(Error::Workspace { path, message }) => {
            assert_eq!(path, missing);
            assert!(message.contains("--mesh"));
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn missing_or_incomplete_model() {
    let root = tmp("nomodel");
    std::fs::create_dir_all(root.join("images")).unwrap();
    match Workspace::discover(&root, None) {
        Err(Error::Workspace { message, .. }) => {
            assert!(message.contains("no COLMAP sparse model"), "{message}")
        }
        other => panic!("{other:?}"),
    }
    // Two of three binary files.
    model("x").write_binary(&root.join("sparse")).unwrap();
    std::fs::remove_file(root.join("sparse/points3D.bin")).unwrap();
    match Workspace::discover(&root, None) {
        Err(Error::Workspace { message, .. }) => {
            assert!(message.contains("incomplete model"), "{message}");
            assert!(message.contains("cameras.bin, images.bin"), "{message}");
        }
        other => panic!("{other:?}"),
    }
    // Not a folder at all.
    assert!(matches!(
        Workspace::discover(&root.join("absent"), None),
        Err(Error::Workspace { .. })
    ));
}

#[test]
fn photos_missing_and_unregistered_are_reported() {
    let root = tmp("photos");
    model("p").write_binary(&root.join("sparse")).unwrap();
    touch(&root.join("images/p1.png"));
    touch(&root.join("images/extra.JPG"));
    touch(&root.join("images/sub/more.jpg"));
    touch(&root.join("images/notes.txt"));
    touch(&root.join("mesh.ply"));
    let ws = Workspace::discover(&root, Some(&root.join("mesh.ply"))).unwrap();
    let rec = ws.read_model().unwrap();
    let m = ws.match_photos(&rec);
    assert_eq!(m.found, vec![(ImageId(1), root.join("images/p1.png"))]);
    assert_eq!(m.missing, vec![(ImageId(5), "p5.png".to_string())]);
    assert_eq!(
        m.unregistered,
        vec!["extra.JPG".to_string(), "sub/more.jpg".to_string()]
    );
}

#[test]
fn real_colmap_fixture() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/colmap-buddha");
    // The fixture has no mesh (Debian's COLMAP cannot make one without CUDA), so discovery
    // without --mesh must say so.
    assert!(matches!(
        Workspace::discover(&root, None),
        Err(Error::Workspace { .. })
    ));
    let dir = tmp("fixture-mesh");
    let mesh = dir.join("m.ply");
    touch(&mesh);
    let ws = Workspace::discover(&root, Some(&mesh)).unwrap();
    assert_eq!(ws.sparse_dir, root.join("dense/sparse"));
    assert_eq!(ws.sparse_format, ModelFormat::Binary);
    assert_eq!(ws.images_dir, root.join("dense/images"));
    let rec = ws.read_model().unwrap();
    let m = ws.match_photos(&rec);
    assert_eq!(m.found.len(), rec.images.len());
    assert!(m.missing.is_empty() && m.unregistered.is_empty());
}
