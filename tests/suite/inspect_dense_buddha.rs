//! `inspect` on a complete workspace made by real COLMAP with a dense point cloud and a
//! Poisson mesh (tests/fixtures/colmap-dense-buddha, scripts/colmap_workspace.sh): counts
//! against COLMAP's model_analyzer log and the fixture's README, the fused-point transfer
//! against a brute-force nearest-neighbour search over the file read by ply-rs directly.

use std::path::{Path, PathBuf};

use relight_cpc::import::scene::load_scene;
use relight_cpc::import::workspace::Workspace;
use relight_cpc::observe::inspect::inspect;
use relight_cpc::Vec3;

fn fixture() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/colmap-dense-buddha")
}

#[test]
fn dense_workspace_inspects_to_the_figures_its_tools_wrote() {
    let r = inspect(&fixture(), None).unwrap();
    // Discovery: the undistorted pair, the Poisson mesh and the fused cloud.
    assert!(r.sparse_dir.ends_with("dense/sparse"), "{}", r.sparse_dir);
    assert!(r.mesh_path.ends_with("dense/meshed-poisson.ply"));
    // The figures COLMAP's model_analyzer wrote to logs/26-model_analyzer.log when the
    // fixture was made (read here rather than copied, so a regenerated fixture is checked
    // against its own log).
    let log = std::fs::read_to_string(fixture().join("logs/26-model_analyzer.log")).unwrap();
    let field = |key: &str| -> f64 {
        log.lines()
            .find_map(|l| {
                l.split_once(key)
                    .map(|(_, v)| v.trim().trim_end_matches("px"))
            })
            .and_then(|v| v.trim().parse().ok())
            .unwrap_or_else(|| panic!("model_analyzer log lacks {key}"))
    };
    assert_eq!(r.cameras, field("Cameras:") as usize);
    assert_eq!(r.images_registered, field("Registered images:") as usize);
    assert_eq!(r.points3d, field("Points:") as usize);
    assert_eq!(r.views_used, r.images_registered);
    let obs: usize = r
        .per_image
        .iter()
        .map(|i| i.reprojection_observations + i.reprojection_outliers)
        .sum();
    assert_eq!(obs, field("Observations:") as usize);
    // model_analyzer prints the per-point errors COLMAP stored, which image_undistorter
    // copies unchanged from the mapper's model: they are in the pixels of the mapper's
    // 1024-px-wide photos (calibration.txt), while the undistorted photos are smaller, so
    // our recomputed figure is that one times width / 1024. It also averages per point, we
    // per observation: 0.05 px (see inspect_buddha).
    let colmap_error = field("Mean reprojection error:");
    let scale = r.per_image[0].width as f64 / 1024.0;
    assert!(scale < 0.6, "undistorted photos are downscaled ({scale})");
    let e = r.mean_reprojection_error_px.unwrap();
    assert!(
        (e - colmap_error * scale).abs() < 0.05,
        "{e} vs {}",
        colmap_error * scale
    );
    // The mesh and the fused cloud: counts from their PLY headers (written by the fixture
    // script); the mesh is clean, so nothing may be dropped.
    let header_count = |file: &str, element: &str| -> usize {
        let bytes = std::fs::read(fixture().join(file)).unwrap();
        let text = String::from_utf8_lossy(&bytes[..bytes.len().min(4096)]).to_string();
        text.lines()
            .find_map(|l| l.strip_prefix(&format!("element {element} ")))
            .and_then(|v| v.trim().parse().ok())
            .unwrap_or_else(|| panic!("{file} has no element {element}"))
    };
    assert_eq!(
        r.mesh_vertices,
        header_count("dense/meshed-poisson.ply", "vertex")
    );
    assert_eq!(
        r.mesh_faces,
        header_count("dense/meshed-poisson.ply", "face")
    );
    assert_eq!(r.dropped_faces + r.mesh_cleanup.unreferenced_vertices, 0);
    let f = r.fused.as_ref().unwrap();
    assert_eq!(f.points, header_count("dense/fused.ply", "vertex"));
    assert!(f.colors && f.normals);
    assert!(f.distance.mean <= f.distance.median * 3.0 && f.distance.p95 <= f.distance.max);
    // Every registered photo sees part of the mesh; confidences in (0, 1].
    for im in &r.per_image {
        assert!(im.observed_vertices > 0, "{}", im.name);
        assert!(im.mean_confidence > 0.0 && im.mean_confidence <= 1.0);
        assert!(im.candidates.observed == im.observed_vertices);
    }
    assert!(
        r.vertices_observed * 2 > r.mesh_vertices,
        "{}",
        r.vertices_observed
    );
}

#[test]
fn fused_transfer_matches_brute_force_nearest_points() {
    use ply_rs::parser::Parser;
    use ply_rs::ply::{DefaultElement, Property};
    let scene = load_scene(Workspace::discover(&fixture(), None).unwrap()).unwrap();
    let fused = scene.fused.as_ref().unwrap();
    // The cloud, read without this crate.
    let mut file = std::fs::File::open(fixture().join("dense/fused.ply")).unwrap();
    let ply = Parser::<DefaultElement>::new().read_ply(&mut file).unwrap();
    let coord = |e: &DefaultElement, k: &str| match e[k] {
        Property::Float(v) => v as f64,
        Property::Double(v) => v,
        ref p => panic!("{p:?}"),
    };
    let pts: Vec<Vec3> = ply.payload["vertex"]
        .iter()
        .map(|e| Vec3::new(coord(e, "x"), coord(e, "y"), coord(e, "z")))
        .collect();
    // Every 7th vertex (915 of them) against all 15,000 points. Distances are stored in
    // f32: 1e-6 relative.
    for v in (0..scene.mesh.positions.len()).step_by(7) {
        let x = scene.mesh.positions[v];
        let best = pts
            .iter()
            .map(|p| (p - x).norm())
            .fold(f64::INFINITY, f64::min);
        let got = fused.distance[v] as f64;
        assert!(
            (got - best).abs() <= 1e-6 * best.max(1e-3),
            "vertex {v}: {got} vs {best}"
        );
    }
}
