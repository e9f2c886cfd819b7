//! COLMAP camera models: project/unproject round trips for every model (proptest), values
//! from COLMAP 3.8's formulas written out by hand, and closed forms (equidistant fisheye,
//! FOV) that do not go through our distortion code.

use proptest::prelude::*;
use proptest::strategy::ValueTree;
use relight_cpc::import::colmap::{Camera, CameraId, CameraModel};
use relight_cpc::Vec3;

/// Parameters for `model`: focal lengths in [300, 1500] px, principal point in [100, 900] px,
/// and distortion small enough that the mapping is monotonic on |u|, |v| <= 0.6 (so the
/// inverse is unique): radial |k| <= 0.1, tangential |p| <= 0.01, fisheye |k| <= 0.05,
/// rational denominators |k4..k6| <= 0.05, thin prism |s| <= 0.01, FOV omega in [0.1, 1.2].
fn params_strategy(model: CameraModel) -> impl Strategy<Value = Vec<f64>> {
    let f = 300.0..1500.0f64;
    let c = 100.0..900.0f64;
    let k = -0.1..0.1f64;
    let p = -0.01..0.01f64;
    let kf = -0.05..0.05f64;
    match model {
        CameraModel::SimplePinhole => (f, c.clone(), c)
            .prop_map(|(f, cx, cy)| vec![f, cx, cy])
            .boxed(),
        CameraModel::Pinhole => (f.clone(), f, c.clone(), c)
            .prop_map(|(fx, fy, cx, cy)| vec![fx, fy, cx, cy])
            .boxed(),
        CameraModel::SimpleRadial => (f, c.clone(), c, k)
            .prop_map(|(f, cx, cy, k)| vec![f, cx, cy, k])
            .boxed(),
        CameraModel::Radial => (f, c.clone(), c, k.clone(), k)
            .prop_map(|(f, cx, cy, k1, k2)| vec![f, cx, cy, k1, k2])
            .boxed(),
        CameraModel::OpenCv => (f.clone(), f, c.clone(), c, k.clone(), k, p.clone(), p)
            .prop_map(|(fx, fy, cx, cy, k1, k2, p1, p2)| vec![fx, fy, cx, cy, k1, k2, p1, p2])
            .boxed(),
        CameraModel::OpenCvFisheye => {
            (f.clone(), f, c.clone(), c, proptest::collection::vec(kf, 4))
                .prop_map(|(fx, fy, cx, cy, ks)| [vec![fx, fy, cx, cy], ks].concat())
                .boxed()
        }
        CameraModel::FullOpenCv => (
            f.clone(),
            f,
            c.clone(),
            c,
            proptest::collection::vec(k, 2),
            proptest::collection::vec(p, 2),
            proptest::collection::vec(kf, 4),
        )
            .prop_map(|(fx, fy, cx, cy, k12, p12, k3456)| {
                [vec![fx, fy, cx, cy], k12, p12, k3456].concat()
            })
            .boxed(),
        CameraModel::Fov => (f.clone(), f, c.clone(), c, 0.1..1.2f64)
            .prop_map(|(fx, fy, cx, cy, w)| vec![fx, fy, cx, cy, w])
            .boxed(),
        CameraModel::SimpleRadialFisheye => (f, c.clone(), c, kf)
            .prop_map(|(f, cx, cy, k)| vec![f, cx, cy, k])
            .boxed(),
        CameraModel::RadialFisheye => (f, c.clone(), c, kf.clone(), kf)
            .prop_map(|(f, cx, cy, k1, k2)| vec![f, cx, cy, k1, k2])
            .boxed(),
        CameraModel::ThinPrismFisheye => (
            f.clone(),
            f,
            c.clone(),
            c,
            proptest::collection::vec(kf.clone(), 2),
            proptest::collection::vec(p.clone(), 2),
            proptest::collection::vec(kf, 2),
            proptest::collection::vec(p, 2),
        )
            .prop_map(|(fx, fy, cx, cy, k12, p12, k34, s)| {
                [vec![fx, fy, cx, cy], k12, p12, k34, s].concat()
            })
            .boxed(),
    }
}

fn camera_strategy() -> impl Strategy<Value = Camera> {
    proptest::sample::select(CameraModel::ALL.to_vec()).prop_flat_map(|model| {
        params_strategy(model).prop_map(move |params| {
            Camera::new(CameraId(1), model, 1000, 1000, params).expect("generated params are valid")
        })
    })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, rng_seed: proptest::test_runner::RngSeed::Fixed(7), ..ProptestConfig::default() })]

    /// project then unproject returns the point's normalized coordinates. Tolerance 1e-8
    /// in normalized units (1e-5 px at f = 1000): COLMAP's Newton iteration stops once a
    /// step is below 1e-5, and with quadratic convergence the remaining error is of the
    /// order of the square of that step.
    #[test]
    fn project_then_unproject_round_trips(
        cam in camera_strategy(),
        u in -0.6..0.6f64,
        v in -0.6..0.6f64,
        z in 0.1..100.0f64,
    ) {
        let p = Vec3::new(u * z, v * z, z);
        let px = cam.project(&p).unwrap();
        let ray = cam.unproject(px).unwrap();
        prop_assert!((ray.z - 1.0).abs() == 0.0);
        prop_assert!((ray.x - u).abs() < 1e-8 && (ray.y - v).abs() < 1e-8,
            "{:?} {:?}: ({u}, {v}) -> {px:?} -> ({}, {})", cam.model, cam.params, ray.x, ray.y);
        // And the pixel back: 1e-5 px (the same bound times the focal length).
        let again = cam.project(&ray).unwrap();
        prop_assert!((again[0] - px[0]).abs() < 1e-5 && (again[1] - px[1]).abs() < 1e-5);
    }
}

/// The principal point is the image of the optical axis for every model.
#[test]
fn optical_axis_maps_to_principal_point() {
    let mut runner = proptest::test_runner::TestRunner::deterministic();
    for _ in 0..200 {
        let cam = camera_strategy().new_tree(&mut runner).unwrap().current();
        let px = cam.project(&Vec3::new(0.0, 0.0, 3.0)).unwrap();
        let (cx, cy) = cam.principal_point();
        // Exact up to rounding of f * 0 + c.
        assert!(
            (px[0] - cx).abs() < 1e-12 && (px[1] - cy).abs() < 1e-12,
            "{:?}",
            cam.model
        );
    }
}

fn close(a: [f64; 2], b: [f64; 2], tol: f64) -> bool {
    (a[0] - b[0]).abs() < tol && (a[1] - b[1]).abs() < tol
}

/// Each model on one point, with COLMAP 3.8's formulas written out here (independently of
/// `src/colmap/camera.rs`). Tolerance 1e-9 px: the same arithmetic in a different order.
#[test]
fn models_match_colmap_formulas_by_hand() {
    let p = Vec3::new(0.3, -0.2, 1.5);
    let (u, v): (f64, f64) = (0.3 / 1.5, -0.2 / 1.5);
    let r2 = u * u + v * v;
    let r = r2.sqrt();
    let theta = r.atan();

    let cam = |m: CameraModel, params: &[f64]| {
        Camera::new(CameraId(3), m, 640, 480, params.to_vec()).unwrap()
    };

    // SIMPLE_RADIAL: f, cx, cy, k.
    let c = cam(CameraModel::SimpleRadial, &[500.0, 320.0, 240.0, -0.2]);
    let d = 1.0 + -0.2 * r2;
    assert!(close(
        c.project(&p).unwrap(),
        [500.0 * u * d + 320.0, 500.0 * v * d + 240.0],
        1e-9
    ));

    // RADIAL: f, cx, cy, k1, k2.
    let c = cam(CameraModel::Radial, &[500.0, 320.0, 240.0, -0.2, 0.05]);
    let d = 1.0 - 0.2 * r2 + 0.05 * r2 * r2;
    assert!(close(
        c.project(&p).unwrap(),
        [500.0 * u * d + 320.0, 500.0 * v * d + 240.0],
        1e-9
    ));

    // OPENCV: fx, fy, cx, cy, k1, k2, p1, p2.
    let (k1, k2, p1, p2) = (-0.2, 0.05, 0.001, -0.002);
    let c = cam(
        CameraModel::OpenCv,
        &[500.0, 520.0, 320.0, 240.0, k1, k2, p1, p2],
    );
    let radial = k1 * r2 + k2 * r2 * r2;
    let ud = u + u * radial + 2.0 * p1 * u * v + p2 * (r2 + 2.0 * u * u);
    let vd = v + v * radial + 2.0 * p2 * u * v + p1 * (r2 + 2.0 * v * v);
    assert!(close(
        c.project(&p).unwrap(),
        [500.0 * ud + 320.0, 520.0 * vd + 240.0],
        1e-9
    ));

    // FULL_OPENCV: fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, k5, k6.
    let (k3, k4, k5, k6) = (0.01, 0.02, -0.01, 0.003);
    let c = cam(
        CameraModel::FullOpenCv,
        &[500.0, 520.0, 320.0, 240.0, k1, k2, p1, p2, k3, k4, k5, k6],
    );
    let rad = (1.0 + k1 * r2 + k2 * r2.powi(2) + k3 * r2.powi(3))
        / (1.0 + k4 * r2 + k5 * r2.powi(2) + k6 * r2.powi(3));
    let ud = u * rad + 2.0 * p1 * u * v + p2 * (r2 + 2.0 * u * u);
    let vd = v * rad + 2.0 * p2 * u * v + p1 * (r2 + 2.0 * v * v);
    assert!(close(
        c.project(&p).unwrap(),
        [500.0 * ud + 320.0, 520.0 * vd + 240.0],
        1e-9
    ));

    // OPENCV_FISHEYE: fx, fy, cx, cy, k1..k4; theta_d = theta (1 + k1 t^2 + ... + k4 t^8).
    let ks = [0.01, -0.02, 0.003, -0.001];
    let c = cam(
        CameraModel::OpenCvFisheye,
        &[500.0, 520.0, 320.0, 240.0, ks[0], ks[1], ks[2], ks[3]],
    );
    let td = theta
        * (1.0
            + ks[0] * theta.powi(2)
            + ks[1] * theta.powi(4)
            + ks[2] * theta.powi(6)
            + ks[3] * theta.powi(8));
    assert!(close(
        c.project(&p).unwrap(),
        [500.0 * u * td / r + 320.0, 520.0 * v * td / r + 240.0],
        1e-9
    ));

    // SIMPLE_RADIAL_FISHEYE and RADIAL_FISHEYE: f, cx, cy, k (k1, k2).
    let c = cam(
        CameraModel::SimpleRadialFisheye,
        &[500.0, 320.0, 240.0, 0.02],
    );
    let td = theta * (1.0 + 0.02 * theta * theta);
    assert!(close(
        c.project(&p).unwrap(),
        [500.0 * u * td / r + 320.0, 500.0 * v * td / r + 240.0],
        1e-9
    ));
    let c = cam(
        CameraModel::RadialFisheye,
        &[500.0, 320.0, 240.0, 0.02, -0.01],
    );
    let td = theta * (1.0 + 0.02 * theta.powi(2) - 0.01 * theta.powi(4));
    assert!(close(
        c.project(&p).unwrap(),
        [500.0 * u * td / r + 320.0, 500.0 * v * td / r + 240.0],
        1e-9
    ));

    // FOV: fx, fy, cx, cy, omega; r_d = atan(2 r tan(omega / 2)) / omega.
    let w = 0.8;
    let c = cam(CameraModel::Fov, &[500.0, 520.0, 320.0, 240.0, w]);
    let s = (2.0 * r * (w / 2.0).tan()).atan() / (w * r);
    assert!(close(
        c.project(&p).unwrap(),
        [500.0 * u * s + 320.0, 520.0 * v * s + 240.0],
        1e-9
    ));

    // THIN_PRISM_FISHEYE: (u, v) -> theta (u, v) / r, then radial to r^8, tangential and
    // thin prism on that point.
    let e = [0.01, -0.02, 0.001, -0.002, 0.003, -0.001, 0.004, -0.003];
    let c = cam(
        CameraModel::ThinPrismFisheye,
        &[
            500.0, 520.0, 320.0, 240.0, e[0], e[1], e[2], e[3], e[4], e[5], e[6], e[7],
        ],
    );
    let (uu, vv) = (theta * u / r, theta * v / r);
    let q2 = uu * uu + vv * vv;
    let rad = e[0] * q2 + e[1] * q2.powi(2) + e[4] * q2.powi(3) + e[5] * q2.powi(4);
    let ud = uu + uu * rad + 2.0 * e[2] * uu * vv + e[3] * (q2 + 2.0 * uu * uu) + e[6] * q2;
    let vd = vv + vv * rad + 2.0 * e[3] * uu * vv + e[2] * (q2 + 2.0 * vv * vv) + e[7] * q2;
    assert!(close(
        c.project(&p).unwrap(),
        [500.0 * ud + 320.0, 520.0 * vd + 240.0],
        1e-9
    ));
}

/// Closed forms that need no distortion code: with zero distortion the fisheye models are
/// equidistant (pixel radius f·θ, θ the angle off the axis), and the pinhole models give
/// f·tan θ. A point 60° off the axis; tolerance 1e-9 px.
#[test]
fn equidistant_and_pinhole_closed_forms() {
    let angle = 60f64.to_radians();
    let p = Vec3::new(angle.sin() * 2.0, 0.0, angle.cos() * 2.0);
    let f = 400.0;
    for (m, params) in [
        (
            CameraModel::OpenCvFisheye,
            vec![f, f, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        ),
        (CameraModel::SimpleRadialFisheye, vec![f, 0.0, 0.0, 0.0]),
        (CameraModel::RadialFisheye, vec![f, 0.0, 0.0, 0.0, 0.0]),
        (
            CameraModel::ThinPrismFisheye,
            [vec![f, f, 0.0, 0.0], vec![0.0; 8]].concat(),
        ),
    ] {
        let c = Camera::new(CameraId(1), m, 100, 100, params).unwrap();
        let px = c.project(&p).unwrap();
        assert!(
            (px[0] - f * angle).abs() < 1e-9 && px[1].abs() < 1e-9,
            "{m:?}: {px:?}"
        );
        // And back to the direction.
        let ray = c.unproject(px).unwrap().normalize();
        assert!((ray - p.normalize()).norm() < 1e-8, "{m:?}");
    }
    for (m, params) in [
        (CameraModel::SimplePinhole, vec![f, 0.0, 0.0]),
        (CameraModel::Pinhole, vec![f, f, 0.0, 0.0]),
        (CameraModel::SimpleRadial, vec![f, 0.0, 0.0, 0.0]),
        (
            CameraModel::OpenCv,
            vec![f, f, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        ),
    ] {
        let c = Camera::new(CameraId(1), m, 100, 100, params).unwrap();
        let px = c.project(&p).unwrap();
        assert!(
            (px[0] - f * angle.tan()).abs() < 1e-9 && px[1].abs() < 1e-9,
            "{m:?}"
        );
    }
    // FOV with omega: a ray at angle θ off the axis lands at radius f·atan(2 tan θ tan(ω/2))/ω
    // (Devernay & Faugeras); with ω = 90° that is f·atan(2 tan θ)/ω.
    let w = std::f64::consts::FRAC_PI_2;
    let c = Camera::new(
        CameraId(1),
        CameraModel::Fov,
        100,
        100,
        vec![f, f, 0.0, 0.0, w],
    )
    .unwrap();
    let px = c.project(&p).unwrap();
    let expect = f * (2.0 * angle.tan() * (w / 2.0).tan()).atan() / w;
    assert!((px[0] - expect).abs() < 1e-9, "{px:?} vs {expect}");
}

/// COLMAP's small-omega FOV branch (omega² < 1e-4) uses the series 1 + ω²r²/3 − ω²/12 in
/// both directions; we keep it, so a camera COLMAP refined with it projects the same.
#[test]
fn fov_small_omega_uses_colmaps_series() {
    let w: f64 = 0.005;
    let c = Camera::new(
        CameraId(1),
        CameraModel::Fov,
        100,
        100,
        vec![300.0, 300.0, 50.0, 50.0, w],
    )
    .unwrap();
    let (u, v) = (0.4, -0.3);
    let r2: f64 = u * u + v * v;
    let s = w * w * r2 / 3.0 - w * w / 12.0 + 1.0;
    let px = c.project(&Vec3::new(u, v, 1.0)).unwrap();
    assert!(close(
        px,
        [300.0 * u * s + 50.0, 300.0 * v * s + 50.0],
        1e-9
    ));
}

/// Points behind the camera and non-finite input do not project.
#[test]
fn behind_and_non_finite() {
    for m in CameraModel::ALL {
        let params = match m.num_params() {
            n if m.has_single_focal() => [vec![300.0, 50.0, 50.0], vec![0.01; n - 3]].concat(),
            n => [vec![300.0, 300.0, 50.0, 50.0], vec![0.01; n - 4]].concat(),
        };
        let c = Camera::new(CameraId(1), m, 100, 100, params).unwrap();
        assert!(c.project(&Vec3::new(0.1, 0.1, -1.0)).is_none());
        assert!(c.project(&Vec3::new(0.1, 0.1, 0.0)).is_none());
        assert!(c.project(&Vec3::new(f64::INFINITY, 0.1, 1.0)).is_none());
        assert!(c.unproject([f64::NAN, 3.0]).is_none());
    }
}

/// Rescaling a camera by (s_x, s_y) scales every projected pixel by the same factors
/// (COLMAP's Camera::Rescale); for single-focal models s_x = s_y keeps that exact.
/// Tolerance 1e-9 px: one multiplication more on either side.
#[test]
fn rescaled_camera_scales_pixels() {
    let mut runner = proptest::test_runner::TestRunner::deterministic();
    for _ in 0..200 {
        let cam = camera_strategy().new_tree(&mut runner).unwrap().current();
        let (w, h) = if cam.model.has_single_focal() {
            (500, 500)
        } else {
            (250, 700)
        };
        let small = cam.rescaled(w, h);
        let (sx, sy) = (w as f64 / 1000.0, h as f64 / 1000.0);
        let p = Vec3::new(0.2, -0.3, 1.7);
        let a = cam.project(&p).unwrap();
        let b = small.project(&p).unwrap();
        assert!(
            close(b, [a[0] * sx, a[1] * sy], 1e-9),
            "{:?}: {a:?} -> {b:?}",
            cam.model
        );
        assert_eq!((small.width, small.height), (w, h));
    }
}
