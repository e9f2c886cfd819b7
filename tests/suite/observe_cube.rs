//! Observation extraction on a scene with known answers: a cube [-1, 1]³ whose faces are
//! 20×20 grids, an occluding plate in front of it, and two pinhole cameras. Which vertices
//! are observed, their samples, directions and confidences are all computed here in closed
//! form from the geometry, independently of `observe`.

use crate::uv_sphere::{direction, uv_sphere};
use nalgebra::{Matrix3, Rotation3};
use relight_cpc::import::colmap::{Camera, CameraId, Image, ImageId};
use relight_cpc::import::mesh::Mesh;
use relight_cpc::import::photo::Photo;
use relight_cpc::import::scene::View;
use relight_cpc::observe::trace::SceneBvh;
use relight_cpc::observe::{extract_with_stats, ObserveOptions};
use relight_cpc::Vec3;

const N: usize = 20; // grid cells per cube face: vertex spacing 0.1
const W: u32 = 200;
const F: f64 = 200.0;

/// Unwelded cube: each face its own (N+1)² grid, so every vertex normal is its face normal
/// exactly. Returns the mesh and, per vertex, its face's outward normal.
fn scene() -> (Mesh, usize) {
    let mut pos = Vec::new();
    let mut faces = Vec::new();
    // (normal, u axis, v axis) with u × v = normal so triangles face outward.
    let axes = [
        (Vec3::z(), Vec3::x(), Vec3::y()),
        (-Vec3::z(), Vec3::y(), Vec3::x()),
        (Vec3::x(), Vec3::y(), Vec3::z()),
        (-Vec3::x(), Vec3::z(), Vec3::y()),
        (Vec3::y(), Vec3::z(), Vec3::x()),
        (-Vec3::y(), Vec3::x(), Vec3::z()),
    ];
    for (n, u, v) in axes {
        let base = pos.len() as u32;
        for j in 0..=N {
            for i in 0..=N {
                let a = -1.0 + 2.0 * i as f64 / N as f64;
                let b = -1.0 + 2.0 * j as f64 / N as f64;
                pos.push(n + u * a + v * b);
            }
        }
        let id = |i: usize, j: usize| base + (j * (N + 1) + i) as u32;
        for j in 0..N {
            for i in 0..N {
                faces.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
                faces.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
    }
    let n_cube = pos.len();
    // Occluding plate at z = 3 over x, y ∈ [-0.225, 0.325] (its shadow on z = 1 seen from
    // (0, 0, 5) is x, y ∈ [-0.45, 0.65]: between grid lines, so no vertex is borderline).
    let base = pos.len() as u32;
    for (x, y) in [
        (-0.225, -0.225),
        (0.325, -0.225),
        (0.325, 0.325),
        (-0.225, 0.325),
    ] {
        pos.push(Vec3::new(x, y, 3.0));
    }
    faces.push([base, base + 1, base + 2]);
    faces.push([base, base + 2, base + 3]);
    let (mesh, cleanup) = Mesh::from_parts(pos, faces);
    assert_eq!(cleanup.degenerate_faces + cleanup.unreferenced_vertices, 0);
    (mesh, n_cube)
}

fn view(id: u32, rows: [[f64; 3]; 3], center: Vec3) -> View {
    let m = Matrix3::new(
        rows[0][0], rows[0][1], rows[0][2], rows[1][0], rows[1][1], rows[1][2], rows[2][0],
        rows[2][1], rows[2][2],
    );
    let r = Rotation3::from_matrix_unchecked(m);
    let t = -(r * center);
    View {
        image: Image::from_pose(ImageId(id), format!("v{id}.png"), CameraId(1), &r, &t),
        camera: Camera::pinhole(CameraId(1), W, W, F, F, 100.0, 100.0),
        photo_path: format!("v{id}.png").into(),
    }
}

/// Photo 0: RGB affine in the pixel position, top-left 90×90 pixels overexposed.
fn photo0() -> Photo {
    let mut rgb = Vec::new();
    let mut over = Vec::new();
    for j in 0..W {
        for i in 0..W {
            let (u, v) = (i as f32 + 0.5, j as f32 + 0.5);
            rgb.push([0.001 * u, 0.002 * v, 0.5]);
            over.push(i < 90 && j < 90);
        }
    }
    let mut p = Photo::from_linear(W, W, rgb);
    p.overexposed = over;
    p
}

#[test]
fn cube_with_occluder_observations_match_geometry() {
    let (mesh, n_cube) = scene();
    let bvh = SceneBvh::new(&mesh);
    // View 0 at (0, 0, 5) looking down −z (camera y = −world y); view 1 at (5, 0, 0)
    // looking down −x.
    let views = vec![
        view(
            1,
            [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]],
            Vec3::new(0.0, 0.0, 5.0),
        ),
        view(
            2,
            [[0.0, 0.0, -1.0], [0.0, -1.0, 0.0], [-1.0, 0.0, 0.0]],
            Vec3::new(5.0, 0.0, 0.0),
        ),
    ];
    let photos = vec![
        photo0(),
        Photo::from_linear(W, W, vec![[0.25, 0.5, 0.75]; (W * W) as usize]),
    ];
    // The weights below are the grazing ramp alone: no edge margin (tested in
    // realphoto_effects and the margins module).
    let opts = ObserveOptions {
        edge_margin: None,
        ..ObserveOptions::default()
    };
    let (obs, stats) = extract_with_stats(&mesh, &bvh, &views, &photos, &opts);

    // Expected set, view 0: front face (z = 1) vertices, not on the silhouette ring
    // (|x| = 1 or |y| = 1: probes fall off the cube), not in the plate's shadow.
    // View 1: face x = 1, minus its ring. Tolerances: positions are multiples of 0.1 in f64,
    // so |·| = 1 tests use 1e-9.
    let on_ring = |a: f64, b: f64| (a.abs() - 1.0).abs() < 1e-9 || (b.abs() - 1.0).abs() < 1e-9;
    let shadowed = |x: f64, y: f64| (-0.45..=0.65).contains(&x) && (-0.45..=0.65).contains(&y);
    let mut expect: Vec<Vec<u32>> = vec![Vec::new(), Vec::new()];
    for v in 0..n_cube {
        let p = mesh.positions[v];
        let n = mesh.normals[v];
        if (n - Vec3::z()).norm() < 1e-12 && !on_ring(p.x, p.y) && !shadowed(p.x, p.y) {
            expect[0].push(v as u32);
        }
        if (n - Vec3::x()).norm() < 1e-12 && !on_ring(p.y, p.z) {
            expect[1].push(v as u32);
        }
    }
    for (i, e) in expect.iter().enumerate() {
        let got = &obs.vertex[obs.photo_ranges[i].clone()];
        assert_eq!(got, e.as_slice(), "view {i}: observed vertex set");
        assert!(obs.photo[obs.photo_ranges[i].clone()]
            .iter()
            .all(|&p| p == i as u32));
    }
    // The 11×11 grid vertices in the shadow are counted as occluded, the plate's own 4
    // corners (on its silhouette) as discontinuities together with the two rings.
    assert_eq!(stats[0].occluded, 11 * 11);
    assert_eq!(stats[0].observed, expect[0].len());
    assert_eq!(stats[1].occluded, 0);
    // Rings: 80 per face seen, plus the plate's 4 corners in view 0.
    assert_eq!(stats[0].discontinuity, 80 + 4);
    assert_eq!(stats[1].discontinuity, 80);

    // Samples, directions, confidences in closed form.
    let cams = [Vec3::new(0.0, 0.0, 5.0), Vec3::new(5.0, 0.0, 0.0)];
    for k in 0..obs.len() {
        let i = obs.photo[k] as usize;
        let p = mesh.positions[obs.vertex[k] as usize];
        let to_c = cams[i] - p;
        let wo = to_c.normalize();
        let d = obs.dir[k];
        // dir is stored in f32: 1e-6.
        assert!((Vec3::new(d[0] as f64, d[1] as f64, d[2] as f64) - wo).norm() < 1e-6);
        // Depth is 4 for both faces seen: pixel = 100 + 50 · (camera x, y).
        let (u, v) = if i == 0 {
            (100.0 + 50.0 * p.x, 100.0 - 50.0 * p.y)
        } else {
            (100.0 - 50.0 * p.z, 100.0 - 50.0 * p.y)
        };
        let cos = 4.0 / to_c.norm();
        let alpha = (cos - 0.1) / 0.9;
        if i == 0 {
            // Bilinear is exact on an affine image (f32: 1e-5).
            assert!(
                (obs.rgb[k][0] as f64 - 0.001 * u).abs() < 1e-5,
                "{u} {:?}",
                obs.rgb[k]
            );
            assert!((obs.rgb[k][1] as f64 - 0.002 * v).abs() < 1e-5);
            // Overexposed when a bilinear tap (floor(u − 0.5) and the next) is in the mask.
            let over = (u - 0.5).floor() < 90.0 && (v - 0.5).floor() < 90.0;
            let w = if over { 0.0 } else { alpha };
            assert!(
                (obs.weight[k] as f64 - w).abs() < 1e-6,
                "{u},{v}: {} vs {w}",
                obs.weight[k]
            );
        } else {
            assert_eq!(obs.rgb[k], [0.25, 0.5, 0.75]);
            assert!((obs.weight[k] as f64 - alpha).abs() < 1e-6);
        }
    }
    assert!(stats[0].overexposed > 0 && stats[0].overexposed < stats[0].observed);
}

#[test]
fn output_is_identical_with_one_thread() {
    // Determinism: the same arrays from a one-thread pool as from the global pool.
    let (mesh, _) = scene();
    let bvh = SceneBvh::new(&mesh);
    let views = vec![view(
        1,
        [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]],
        Vec3::new(0.3, 0.2, 5.0),
    )];
    let photos = vec![photo0()];
    // The weights below are the grazing ramp alone: no edge margin (tested in
    // realphoto_effects and the margins module).
    let opts = ObserveOptions {
        edge_margin: None,
        ..ObserveOptions::default()
    };
    let (a, _) = extract_with_stats(&mesh, &bvh, &views, &photos, &opts);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let (b, _) = pool.install(|| extract_with_stats(&mesh, &bvh, &views, &photos, &opts));
    assert!(!a.is_empty());
    assert_eq!(a.vertex, b.vertex);
    assert_eq!(a.rgb, b.rgb);
    assert_eq!(a.weight, b.weight);
    assert_eq!(a.dir, b.dir);
}

#[test]
fn smooth_convex_surface_has_no_false_discontinuities() {
    // A unit UV sphere seen from (0, 0, 5): convex, so nothing is occluded, and the
    // tangent-plane depth prediction of the probes holds away from the silhouette. Every
    // vertex with cos θ > 0.5 lies ≥ 5 px inside the silhouette (image radius ≈ 41 px,
    // 41·(1 − sin 60°) ≈ 5.5 px) and must be observed; every vertex with cos θ ≤ min_cos
    // must not be. Curvature bends the surface off its tangent plane by ~s²/2 over the
    // probe footprint s ≈ 0.03, far below τ = 2% of the depth.
    let (rings, segs) = (60usize, 120usize);
    let (pos, faces) = uv_sphere(rings, segs, direction);
    let (mesh, _) = Mesh::from_parts(pos, faces);
    let bvh = SceneBvh::new(&mesh);
    let c = Vec3::new(0.0, 0.0, 5.0);
    let views = vec![view(
        1,
        [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]],
        c,
    )];
    let photos = vec![Photo::from_linear(W, W, vec![[0.5; 3]; (W * W) as usize])];
    // The weights below are the grazing ramp alone: no edge margin (tested in
    // realphoto_effects and the margins module).
    let opts = ObserveOptions {
        edge_margin: None,
        ..ObserveOptions::default()
    };
    let (obs, stats) = extract_with_stats(&mesh, &bvh, &views, &photos, &opts);
    assert_eq!(stats[0].occluded, 0);
    let seen: std::collections::HashSet<u32> = obs.vertex.iter().copied().collect();
    let mut strict = 0;
    for (v, (p, n)) in mesh.positions.iter().zip(&mesh.normals).enumerate() {
        let cos = n.dot(&(c - p).normalize());
        if cos > 0.5 {
            strict += 1;
            assert!(
                seen.contains(&(v as u32)),
                "vertex {v} (cos {cos:.3}) not observed"
            );
        }
        if cos <= opts.min_cos {
            assert!(!seen.contains(&(v as u32)));
        }
    }
    assert!(strict > 500);
    // The flagged ones are all near the silhouette.
    assert!(
        stats[0].discontinuity < stats[0].facing / 5,
        "{:?}",
        stats[0]
    );
}
