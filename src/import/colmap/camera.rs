//! COLMAP's camera models, exactly as COLMAP 3.8 defines them (`src/base/camera_models.h`).
//!
//! A point in camera coordinates `X = (x, y, z)` (x right, y down, z forward) is first put on
//! the normalized plane, `(u, v) = (x / z, y / z)`; the model's distortion maps it to
//! `(u', v')`; the intrinsics map that to pixels, `px = f_x u' + c_x`, `py = f_y v' + c_y`,
//! with the top-left pixel's centre at `(0.5, 0.5)`. Distortion (COLMAP adds `(du, dv)` to
//! `(u, v)`; `r² = u² + v²`):
//!
//! | model | params | distortion |
//! |---|---|---|
//! | SIMPLE_PINHOLE | f, cx, cy | none |
//! | PINHOLE | fx, fy, cx, cy | none |
//! | SIMPLE_RADIAL | f, cx, cy, k | `u·k r²` |
//! | RADIAL | f, cx, cy, k1, k2 | `u·(k1 r² + k2 r⁴)` |
//! | OPENCV | fx, fy, cx, cy, k1, k2, p1, p2 | `u·(k1 r² + k2 r⁴) + 2 p1 uv + p2 (r² + 2u²)` |
//! | OPENCV_FISHEYE | fx, fy, cx, cy, k1..k4 | `θ = atan r`, `θ_d = θ(1 + k1θ² + k2θ⁴ + k3θ⁶ + k4θ⁸)`, `u' = u θ_d / r` |
//! | FULL_OPENCV | fx, fy, cx, cy, k1, k2, p1, p2, k3..k6 | `u·(1+k1r²+k2r⁴+k3r⁶)/(1+k4r²+k5r⁴+k6r⁶) + tangential` |
//! | FOV | fx, fy, cx, cy, ω | `u' = u · atan(2 r tan(ω/2)) / (r ω)` (Devernay & Faugeras 2001) |
//! | SIMPLE_RADIAL_FISHEYE | f, cx, cy, k | as OPENCV_FISHEYE with `θ_d = θ(1 + kθ²)` |
//! | RADIAL_FISHEYE | f, cx, cy, k1, k2 | as OPENCV_FISHEYE with `θ_d = θ(1 + k1θ² + k2θ⁴)` |
//! | THIN_PRISM_FISHEYE | fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, sx1, sy1 | `(u,v) ← θ(u,v)/r`, then OPENCV-like radial to r⁸ and tangential, plus `sx1 r²`, `sy1 r²` |
//!
//! Unprojection inverts the distortion as COLMAP does: Newton's method with a Jacobian from
//! central differences (relative step 1e-6, at most 100 iterations, stop when the step's
//! squared norm is below 1e-10) — except FOV, which has a closed-form inverse
//! `u = u' tan(r' ω) / (2 r' tan(ω/2))`, and THIN_PRISM_FISHEYE, which maps the undistorted
//! `θ`-plane point back with `tan θ / θ` after the iteration.
//!
//! COLMAP quirk kept on purpose: for `ω² < 1e-4` both FOV directions use the same
//! second-order series `1 + ω² r² / 3 − ω² / 12`, which is the series of the *inverse*
//! mapping only; a model COLMAP refined with that formula is reproduced by using it too.

use crate::{Error, Result, Vec3};

/// A camera's id in a COLMAP model (not necessarily contiguous).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct CameraId(pub u32);

/// The camera models COLMAP 3.8 knows; the discriminant is COLMAP's model id.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum CameraModel {
    /// `f, cx, cy`
    SimplePinhole = 0,
    /// `fx, fy, cx, cy`
    Pinhole = 1,
    /// `f, cx, cy, k`
    SimpleRadial = 2,
    /// `f, cx, cy, k1, k2`
    Radial = 3,
    /// `fx, fy, cx, cy, k1, k2, p1, p2`
    OpenCv = 4,
    /// `fx, fy, cx, cy, k1, k2, k3, k4`
    OpenCvFisheye = 5,
    /// `fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, k5, k6`
    FullOpenCv = 6,
    /// `fx, fy, cx, cy, omega`
    Fov = 7,
    /// `f, cx, cy, k`
    SimpleRadialFisheye = 8,
    /// `f, cx, cy, k1, k2`
    RadialFisheye = 9,
    /// `fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, sx1, sy1`
    ThinPrismFisheye = 10,
}

impl CameraModel {
    /// Every model, in id order.
    pub const ALL: [CameraModel; 11] = [
        CameraModel::SimplePinhole,
        CameraModel::Pinhole,
        CameraModel::SimpleRadial,
        CameraModel::Radial,
        CameraModel::OpenCv,
        CameraModel::OpenCvFisheye,
        CameraModel::FullOpenCv,
        CameraModel::Fov,
        CameraModel::SimpleRadialFisheye,
        CameraModel::RadialFisheye,
        CameraModel::ThinPrismFisheye,
    ];

    /// COLMAP's numeric model id (as stored in `cameras.bin`).
    pub fn id(self) -> u32 {
        self as u32
    }

    /// The model with COLMAP id `id`, if there is one.
    pub fn from_id(id: u32) -> Option<Self> {
        Self::ALL.get(id as usize).copied()
    }

    /// COLMAP's model name (as written in `cameras.txt`).
    pub fn name(self) -> &'static str {
        match self {
            CameraModel::SimplePinhole => "SIMPLE_PINHOLE",
            CameraModel::Pinhole => "PINHOLE",
            CameraModel::SimpleRadial => "SIMPLE_RADIAL",
            CameraModel::Radial => "RADIAL",
            CameraModel::OpenCv => "OPENCV",
            CameraModel::OpenCvFisheye => "OPENCV_FISHEYE",
            CameraModel::FullOpenCv => "FULL_OPENCV",
            CameraModel::Fov => "FOV",
            CameraModel::SimpleRadialFisheye => "SIMPLE_RADIAL_FISHEYE",
            CameraModel::RadialFisheye => "RADIAL_FISHEYE",
            CameraModel::ThinPrismFisheye => "THIN_PRISM_FISHEYE",
        }
    }

    /// The model called `name` (COLMAP spelling, e.g. `SIMPLE_RADIAL`).
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.iter().copied().find(|m| m.name() == name)
    }

    /// Number of parameters (focal lengths, principal point, distortion).
    pub fn num_params(self) -> usize {
        match self {
            CameraModel::SimplePinhole => 3,
            CameraModel::Pinhole => 4,
            CameraModel::SimpleRadial => 4,
            CameraModel::Radial => 5,
            CameraModel::OpenCv => 8,
            CameraModel::OpenCvFisheye => 8,
            CameraModel::FullOpenCv => 12,
            CameraModel::Fov => 5,
            CameraModel::SimpleRadialFisheye => 4,
            CameraModel::RadialFisheye => 5,
            CameraModel::ThinPrismFisheye => 12,
        }
    }

    /// COLMAP's parameter order, e.g. `"f, cx, cy, k"`.
    pub fn params_info(self) -> &'static str {
        match self {
            CameraModel::SimplePinhole => "f, cx, cy",
            CameraModel::Pinhole => "fx, fy, cx, cy",
            CameraModel::SimpleRadial | CameraModel::SimpleRadialFisheye => "f, cx, cy, k",
            CameraModel::Radial | CameraModel::RadialFisheye => "f, cx, cy, k1, k2",
            CameraModel::OpenCv => "fx, fy, cx, cy, k1, k2, p1, p2",
            CameraModel::OpenCvFisheye => "fx, fy, cx, cy, k1, k2, k3, k4",
            CameraModel::FullOpenCv => "fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, k5, k6",
            CameraModel::Fov => "fx, fy, cx, cy, omega",
            CameraModel::ThinPrismFisheye => "fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, sx1, sy1",
        }
    }

    /// True for the models with a single focal length `f` (params start `f, cx, cy`).
    pub fn has_single_focal(self) -> bool {
        matches!(
            self,
            CameraModel::SimplePinhole
                | CameraModel::SimpleRadial
                | CameraModel::Radial
                | CameraModel::SimpleRadialFisheye
                | CameraModel::RadialFisheye
        )
    }

    /// Index of the first distortion parameter.
    fn extra_start(self) -> usize {
        if self.has_single_focal() {
            3
        } else {
            4
        }
    }
}

/// One COLMAP camera: model, image size in pixels and parameters in COLMAP's order.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    /// Id in the model.
    pub id: CameraId,
    /// Camera model.
    pub model: CameraModel,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Parameters in the model's order ([`CameraModel::params_info`]).
    pub params: Vec<f64>,
}

impl Camera {
    /// A checked camera: `params.len()` must equal `model.num_params()`, every parameter must
    /// be finite, the size positive and the focal lengths non-zero.
    pub fn new(
        id: CameraId,
        model: CameraModel,
        width: u32,
        height: u32,
        params: Vec<f64>,
    ) -> Result<Camera> {
        Camera::checked(id, model, width, height, params).map_err(Error::Config)
    }

    /// The camera if [`Camera::check`] accepts it, else the reason, prefixed `camera ID: `
    /// (the readers add the file and line or record).
    pub(crate) fn checked(
        id: CameraId,
        model: CameraModel,
        width: u32,
        height: u32,
        params: Vec<f64>,
    ) -> std::result::Result<Camera, String> {
        let camera = Camera {
            id,
            model,
            width,
            height,
            params,
        };
        camera
            .check()
            .map_err(|m| format!("camera {}: {m}", id.0))?;
        Ok(camera)
    }

    /// A PINHOLE camera (no distortion).
    pub fn pinhole(
        id: CameraId,
        width: u32,
        height: u32,
        fx: f64,
        fy: f64,
        cx: f64,
        cy: f64,
    ) -> Camera {
        Camera {
            id,
            model: CameraModel::Pinhole,
            width,
            height,
            params: vec![fx, fy, cx, cy],
        }
    }

    /// What is wrong with this camera, if anything (used by [`Camera::new`] and the readers).
    pub fn check(&self) -> std::result::Result<(), String> {
        let n = self.model.num_params();
        if self.params.len() != n {
            return Err(format!(
                "model {} needs {n} parameters ({}), got {}",
                self.model.name(),
                self.model.params_info(),
                self.params.len()
            ));
        }
        if let Some(i) = self.params.iter().position(|p| !p.is_finite()) {
            return Err(format!(
                "parameter {i} ({}) is not finite: {}",
                self.model.params_info().split(", ").nth(i).unwrap_or("?"),
                self.params[i]
            ));
        }
        if self.width == 0 || self.height == 0 {
            return Err(format!(
                "image size {}x{} is empty",
                self.width, self.height
            ));
        }
        let (fx, fy) = self.focal();
        if fx == 0.0 || fy == 0.0 {
            return Err("focal length is zero".to_string());
        }
        Ok(())
    }

    /// The same camera for the photo resized to `width` x `height`, as COLMAP's
    /// `Camera::Rescale`: focal lengths and principal point scale with the size
    /// (`f_x, c_x` by `width / self.width`, `f_y, c_y` by `height / self.height`; the
    /// single-focal models by the mean of the two), distortion is unchanged, so every pixel
    /// position scales: `project'(X) = (s_x, s_y) ⊙ project(X)`.
    pub fn rescaled(&self, width: u32, height: u32) -> Camera {
        let sx = width as f64 / self.width as f64;
        let sy = height as f64 / self.height as f64;
        let mut params = self.params.clone();
        if params.len() == self.model.num_params() {
            if self.model.has_single_focal() {
                params[0] *= 0.5 * (sx + sy);
                params[1] *= sx;
                params[2] *= sy;
            } else {
                params[0] *= sx;
                params[1] *= sy;
                params[2] *= sx;
                params[3] *= sy;
            }
        }
        Camera {
            id: self.id,
            model: self.model,
            width,
            height,
            params,
        }
    }

    /// Focal lengths `(f_x, f_y)` in pixels.
    pub fn focal(&self) -> (f64, f64) {
        if self.model.has_single_focal() {
            (self.params[0], self.params[0])
        } else {
            (self.params[0], self.params[1])
        }
    }

    /// Principal point `(c_x, c_y)` in pixels.
    pub fn principal_point(&self) -> (f64, f64) {
        if self.model.has_single_focal() {
            (self.params[1], self.params[2])
        } else {
            (self.params[2], self.params[3])
        }
    }

    /// Camera coordinates (x right, y down, z forward) → pixel (COLMAP: top-left pixel
    /// centre at (0.5, 0.5)); `None` if `z <= 0` or the result is not finite.
    pub fn project(&self, p_cam: &Vec3) -> Option<[f64; 2]> {
        if !p_cam.z.is_finite() || p_cam.z <= 0.0 || !p_cam.x.is_finite() || !p_cam.y.is_finite() {
            return None;
        }
        if self.params.len() != self.model.num_params() {
            return None;
        }
        let px = self.img_from_cam([p_cam.x / p_cam.z, p_cam.y / p_cam.z]);
        (px[0].is_finite() && px[1].is_finite()).then_some(px)
    }

    /// Like [`Camera::project`], but `None` also when the pixel is not the unique image of
    /// the ray: polynomial distortion folds back beyond some radius (SIMPLE_RADIAL with
    /// `k < 0` past `r² = −1/(3k)`), so a point far outside the view can land inside the
    /// image. COLMAP does not check this; use this for anything that must not see such
    /// points (e.g. which mesh vertices a photo observes). The check unprojects the pixel
    /// and requires the ray back to within `1e-6 (1 + |(u, v)|)` in normalized units.
    pub fn project_checked(&self, p_cam: &Vec3) -> Option<[f64; 2]> {
        let px = self.project(p_cam)?;
        if matches!(
            self.model,
            CameraModel::SimplePinhole | CameraModel::Pinhole
        ) {
            return Some(px);
        }
        let (u, v) = (p_cam.x / p_cam.z, p_cam.y / p_cam.z);
        let [ub, vb] = self.cam_from_img(px);
        let tol = 1e-6 * (1.0 + (u * u + v * v).sqrt());
        ((ub - u).abs() <= tol && (vb - v).abs() <= tol).then_some(px)
    }

    /// Pixel → ray direction in camera coordinates with `z = 1` (distortion removed by
    /// COLMAP's scheme); `None` if the inversion does not give a finite answer.
    pub fn unproject(&self, pixel: [f64; 2]) -> Option<Vec3> {
        if self.params.len() != self.model.num_params() {
            return None;
        }
        let [u, v] = self.cam_from_img(pixel);
        (u.is_finite() && v.is_finite()).then(|| Vec3::new(u, v, 1.0))
    }

    /// COLMAP's `ImgFromCam` (`WorldToImage` in older releases): normalized-plane point `(u, v)` → pixel. The camera must
    /// have `model.num_params()` parameters (as [`Camera::new`] and the readers ensure).
    pub fn img_from_cam(&self, uv: [f64; 2]) -> [f64; 2] {
        let (fx, fy) = self.focal();
        let (cx, cy) = self.principal_point();
        let extra = &self.params[self.model.extra_start()..];
        let [u, v] = uv;
        let [xd, yd] = match self.model {
            CameraModel::SimplePinhole | CameraModel::Pinhole => [u, v],
            CameraModel::Fov => fov_distort(extra[0], u, v),
            CameraModel::ThinPrismFisheye => {
                let [uu, vv] = fisheye_theta_plane(u, v);
                let [du, dv] = distortion(self.model, extra, uu, vv);
                [uu + du, vv + dv]
            }
            _ => {
                let [du, dv] = distortion(self.model, extra, u, v);
                [u + du, v + dv]
            }
        };
        [fx * xd + cx, fy * yd + cy]
    }

    /// COLMAP's `CamFromImg` (`ImageToWorld` in older releases): pixel → normalized-plane point `(u, v)`. The camera must
    /// have `model.num_params()` parameters (as [`Camera::new`] and the readers ensure).
    pub fn cam_from_img(&self, pixel: [f64; 2]) -> [f64; 2] {
        let (fx, fy) = self.focal();
        let (cx, cy) = self.principal_point();
        let extra = &self.params[self.model.extra_start()..];
        let u = (pixel[0] - cx) / fx;
        let v = (pixel[1] - cy) / fy;
        match self.model {
            CameraModel::SimplePinhole | CameraModel::Pinhole => [u, v],
            CameraModel::Fov => fov_undistort(extra[0], u, v),
            CameraModel::ThinPrismFisheye => {
                let [u, v] = iterative_undistortion(self.model, extra, [u, v]);
                // Back from the θ-plane: scale by tan θ / θ.
                let theta = (u * u + v * v).sqrt();
                let theta_cos_theta = theta * theta.cos();
                if theta_cos_theta > f64::EPSILON {
                    let scale = theta.sin() / theta_cos_theta;
                    [u * scale, v * scale]
                } else {
                    [u, v]
                }
            }
            _ => iterative_undistortion(self.model, extra, [u, v]),
        }
    }
}

/// THIN_PRISM_FISHEYE's first step: `(u, v) ← θ (u, v) / r` with `θ = atan r`.
fn fisheye_theta_plane(u: f64, v: f64) -> [f64; 2] {
    let r = (u * u + v * v).sqrt();
    if r > f64::EPSILON {
        let theta = r.atan();
        [theta * u / r, theta * v / r]
    } else {
        [u, v]
    }
}

/// COLMAP's `Distortion(extra_params, u, v) -> (du, dv)` for the models that add `(du, dv)`
/// to `(u, v)` (all but the pinholes and FOV, which return zero here).
pub fn distortion(model: CameraModel, extra: &[f64], u: f64, v: f64) -> [f64; 2] {
    match model {
        CameraModel::SimplePinhole | CameraModel::Pinhole | CameraModel::Fov => [0.0, 0.0],
        CameraModel::SimpleRadial => {
            let radial = extra[0] * (u * u + v * v);
            [u * radial, v * radial]
        }
        CameraModel::Radial => {
            let r2 = u * u + v * v;
            let radial = extra[0] * r2 + extra[1] * r2 * r2;
            [u * radial, v * radial]
        }
        CameraModel::OpenCv => {
            let (k1, k2, p1, p2) = (extra[0], extra[1], extra[2], extra[3]);
            let (u2, uv, v2) = (u * u, u * v, v * v);
            let r2 = u2 + v2;
            let radial = k1 * r2 + k2 * r2 * r2;
            [
                u * radial + 2.0 * p1 * uv + p2 * (r2 + 2.0 * u2),
                v * radial + 2.0 * p2 * uv + p1 * (r2 + 2.0 * v2),
            ]
        }
        CameraModel::OpenCvFisheye => fisheye(u, v, |t2| {
            1.0 + t2 * (extra[0] + t2 * (extra[1] + t2 * (extra[2] + t2 * extra[3])))
        }),
        CameraModel::SimpleRadialFisheye => fisheye(u, v, |t2| 1.0 + extra[0] * t2),
        CameraModel::RadialFisheye => fisheye(u, v, |t2| 1.0 + extra[0] * t2 + extra[1] * t2 * t2),
        CameraModel::FullOpenCv => {
            let (k1, k2, p1, p2) = (extra[0], extra[1], extra[2], extra[3]);
            let (k3, k4, k5, k6) = (extra[4], extra[5], extra[6], extra[7]);
            let (u2, uv, v2) = (u * u, u * v, v * v);
            let r2 = u2 + v2;
            let r4 = r2 * r2;
            let r6 = r4 * r2;
            let radial = (1.0 + k1 * r2 + k2 * r4 + k3 * r6) / (1.0 + k4 * r2 + k5 * r4 + k6 * r6);
            [
                u * radial + 2.0 * p1 * uv + p2 * (r2 + 2.0 * u2) - u,
                v * radial + 2.0 * p2 * uv + p1 * (r2 + 2.0 * v2) - v,
            ]
        }
        CameraModel::ThinPrismFisheye => {
            let (k1, k2, p1, p2) = (extra[0], extra[1], extra[2], extra[3]);
            let (k3, k4, sx1, sy1) = (extra[4], extra[5], extra[6], extra[7]);
            let (u2, uv, v2) = (u * u, u * v, v * v);
            let r2 = u2 + v2;
            let r4 = r2 * r2;
            let r6 = r4 * r2;
            let r8 = r6 * r2;
            let radial = k1 * r2 + k2 * r4 + k3 * r6 + k4 * r8;
            [
                u * radial + 2.0 * p1 * uv + p2 * (r2 + 2.0 * u2) + sx1 * r2,
                v * radial + 2.0 * p2 * uv + p1 * (r2 + 2.0 * v2) + sy1 * r2,
            ]
        }
    }
}

/// The equidistant fisheye distortion: `θ = atan r`, `θ_d = θ · poly(θ²)`, `du = u θ_d / r − u`.
fn fisheye(u: f64, v: f64, poly: impl Fn(f64) -> f64) -> [f64; 2] {
    let r = (u * u + v * v).sqrt();
    if r > f64::EPSILON {
        let theta = r.atan();
        let thetad = theta * poly(theta * theta);
        [u * thetad / r - u, v * thetad / r - v]
    } else {
        [0.0, 0.0]
    }
}

/// FOV model, forward: `(u, v) · atan(2 r tan(ω/2)) / (r ω)` with COLMAP's series branches.
pub fn fov_distort(omega: f64, u: f64, v: f64) -> [f64; 2] {
    const EPS: f64 = 1e-4;
    let radius2 = u * u + v * v;
    let omega2 = omega * omega;
    let factor = if omega2 < EPS {
        (omega2 * radius2) / 3.0 - omega2 / 12.0 + 1.0
    } else if radius2 < EPS {
        let t = (omega / 2.0).tan();
        (-2.0 * t * (4.0 * radius2 * t * t - 3.0)) / (3.0 * omega)
    } else {
        let radius = radius2.sqrt();
        (radius * 2.0 * (omega / 2.0).tan()).atan() / (radius * omega)
    };
    [u * factor, v * factor]
}

/// FOV model, inverse: `(u, v) · tan(r ω) / (2 r tan(ω/2))` with COLMAP's series branches.
pub fn fov_undistort(omega: f64, u: f64, v: f64) -> [f64; 2] {
    const EPS: f64 = 1e-4;
    let radius2 = u * u + v * v;
    let omega2 = omega * omega;
    let factor = if omega2 < EPS {
        (omega2 * radius2) / 3.0 - omega2 / 12.0 + 1.0
    } else if radius2 < EPS {
        (omega * (omega * omega * radius2 + 3.0)) / (6.0 * (omega / 2.0).tan())
    } else {
        let radius = radius2.sqrt();
        (radius * omega).tan() / (radius * 2.0 * (omega / 2.0).tan())
    };
    [u * factor, v * factor]
}

/// COLMAP's `IterativeUndistortion`: solve `x + distortion(x) = x0` by Newton's method with a
/// central-difference Jacobian.
pub fn iterative_undistortion(model: CameraModel, extra: &[f64], x0: [f64; 2]) -> [f64; 2] {
    const NUM_ITERATIONS: usize = 100;
    const MAX_STEP_NORM: f64 = 1e-10;
    const REL_STEP_SIZE: f64 = 1e-6;
    let mut x = x0;
    for _ in 0..NUM_ITERATIONS {
        let step0 = f64::EPSILON.max((REL_STEP_SIZE * x[0]).abs());
        let step1 = f64::EPSILON.max((REL_STEP_SIZE * x[1]).abs());
        let dx = distortion(model, extra, x[0], x[1]);
        let dx_0b = distortion(model, extra, x[0] - step0, x[1]);
        let dx_0f = distortion(model, extra, x[0] + step0, x[1]);
        let dx_1b = distortion(model, extra, x[0], x[1] - step1);
        let dx_1f = distortion(model, extra, x[0], x[1] + step1);
        let j00 = 1.0 + (dx_0f[0] - dx_0b[0]) / (2.0 * step0);
        let j01 = (dx_1f[0] - dx_1b[0]) / (2.0 * step1);
        let j10 = (dx_0f[1] - dx_0b[1]) / (2.0 * step0);
        let j11 = 1.0 + (dx_1f[1] - dx_1b[1]) / (2.0 * step1);
        // Residual and the 2x2 inverse applied to it.
        let r0 = x[0] + dx[0] - x0[0];
        let r1 = x[1] + dx[1] - x0[1];
        let det = j00 * j11 - j01 * j10;
        let s0 = (j11 * r0 - j01 * r1) / det;
        let s1 = (-j10 * r0 + j00 * r1) / det;
        x = [x[0] - s0, x[1] - s1];
        let step_norm = s0 * s0 + s1 * s1;
        if step_norm.is_nan() || step_norm < MAX_STEP_NORM {
            // Converged (or the step is NaN, which the caller sees in `x`).
            break;
        }
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_names_and_param_counts_round_trip() {
        for (i, m) in CameraModel::ALL.iter().enumerate() {
            assert_eq!(m.id(), i as u32);
            assert_eq!(CameraModel::from_id(m.id()), Some(*m));
            assert_eq!(CameraModel::from_name(m.name()), Some(*m));
            assert_eq!(m.params_info().split(", ").count(), m.num_params());
        }
        assert_eq!(CameraModel::from_id(11), None);
        assert_eq!(CameraModel::from_name("pinhole"), None);
    }

    #[test]
    fn pinhole_projects_by_hand() {
        // Exact arithmetic on small binary fractions: tolerance 1e-12.
        let c = Camera::pinhole(CameraId(1), 640, 480, 500.0, 400.0, 320.5, 240.25);
        let p = c.project(&Vec3::new(0.5, -0.25, 2.0)).unwrap();
        assert!((p[0] - (500.0 * 0.25 + 320.5)).abs() < 1e-12);
        assert!((p[1] - (400.0 * -0.125 + 240.25)).abs() < 1e-12);
        assert!(c.project(&Vec3::new(0.0, 0.0, 0.0)).is_none());
        assert!(c.project(&Vec3::new(0.0, 0.0, -1.0)).is_none());
        assert!(c.project(&Vec3::new(f64::NAN, 0.0, 1.0)).is_none());
    }

    #[test]
    fn new_rejects_bad_params() {
        let m = CameraModel::SimpleRadial;
        assert!(Camera::new(CameraId(1), m, 10, 10, vec![1.0, 2.0, 3.0, 0.1]).is_ok());
        assert!(Camera::new(CameraId(1), m, 10, 10, vec![1.0, 2.0, 3.0]).is_err());
        assert!(Camera::new(CameraId(1), m, 10, 10, vec![1.0, 2.0, f64::NAN, 0.1]).is_err());
        assert!(Camera::new(CameraId(1), m, 0, 10, vec![1.0, 2.0, 3.0, 0.1]).is_err());
        assert!(Camera::new(CameraId(1), m, 10, 10, vec![0.0, 2.0, 3.0, 0.1]).is_err());
    }
}
