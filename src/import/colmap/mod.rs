//! COLMAP sparse models: cameras, registered images with their 2D points, and 3D points with
//! their tracks, read from and written to COLMAP's text and binary formats.
//!
//! Geometry (docs/conventions.md): an image stores the world-to-camera pose as a unit quaternion
//! `q = (w, x, y, z)` and a translation `t`, so `X_cam = R(q) X_world + t` and the camera
//! centre is `C = −Rᵀ t`. The camera looks down +z with x right and y down; [`Camera`]
//! maps camera coordinates to pixels with the model's distortion ([`camera`]), pixel
//! centres at +0.5. The reprojection error of an observation is `|π(R X + t) − x_obs|` in
//! pixels, where π is [`Camera::project`]; COLMAP's own per-point `error` is the mean of
//! that over the point's track, and `model_analyzer` reports the mean of those per-point
//! errors ([`Reconstruction::mean_point_error`]).
//!
//! One file per format, as in COLMAP: [`text`] (`cameras.txt`, `images.txt`,
//! `points3D.txt`) and [`binary`] (`cameras.bin`, `images.bin`, `points3D.bin`). Parsers
//! read from a stream and name the file with the line (text) or record and byte offset
//! (binary) in every error. Ids are typed and need not be contiguous.

pub mod binary;
pub mod camera;
pub mod text;

use std::collections::BTreeMap;
use std::path::Path;

use nalgebra::{Isometry3, Quaternion, Rotation3, Translation3, UnitQuaternion};

pub use camera::{Camera, CameraId, CameraModel};

use crate::{Error, Result, Vec3};

/// An image's id in a COLMAP model.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct ImageId(pub u32);

/// A 3D point's id in a COLMAP model.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Point3DId(pub u64);

/// Which of COLMAP's two model formats a model was read from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ModelFormat {
    /// `cameras.txt`, `images.txt`, `points3D.txt`.
    Text,
    /// `cameras.bin`, `images.bin`, `points3D.bin`.
    Binary,
}

impl ModelFormat {
    /// The three file names of a model in this format.
    pub fn file_names(self) -> [&'static str; 3] {
        match self {
            ModelFormat::Text => ["cameras.txt", "images.txt", "points3D.txt"],
            ModelFormat::Binary => ["cameras.bin", "images.bin", "points3D.bin"],
        }
    }

    /// `"text"` or `"binary"`.
    pub fn name(self) -> &'static str {
        match self {
            ModelFormat::Text => "text",
            ModelFormat::Binary => "binary",
        }
    }

    /// True when all three files of this format exist in `dir`.
    pub fn present_in(self, dir: &Path) -> bool {
        self.file_names().iter().all(|f| dir.join(f).is_file())
    }
}

/// A keypoint of an image, possibly the observation of a 3D point.
#[derive(Clone, Debug, PartialEq)]
pub struct Point2D {
    /// Pixel position (COLMAP convention: top-left pixel centre at (0.5, 0.5)).
    pub xy: [f64; 2],
    /// The 3D point it observes, if any.
    pub point3d_id: Option<Point3DId>,
}

/// A registered image: its pose (world to camera), camera and keypoints.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Id in the model.
    pub id: ImageId,
    /// File name relative to the image folder.
    pub name: String,
    /// The camera (intrinsics) it was taken with.
    pub camera_id: CameraId,
    /// World-to-camera rotation as a unit quaternion `(w, x, y, z)`.
    pub qvec: [f64; 4],
    /// World-to-camera translation.
    pub tvec: [f64; 3],
    /// Keypoints; tracks refer to them by index.
    pub points2d: Vec<Point2D>,
}

impl Image {
    /// The rotation `R` of [`Image::cam_from_world`].
    pub fn cam_from_world_rotation(&self) -> Rotation3<f64> {
        let [w, x, y, z] = self.qvec;
        UnitQuaternion::from_quaternion(Quaternion::new(w, x, y, z)).to_rotation_matrix()
    }

    /// The rigid transform `X_cam = R X_world + t`.
    pub fn cam_from_world(&self) -> Isometry3<f64> {
        let [w, x, y, z] = self.qvec;
        Isometry3::from_parts(
            Translation3::new(self.tvec[0], self.tvec[1], self.tvec[2]),
            UnitQuaternion::from_quaternion(Quaternion::new(w, x, y, z)),
        )
    }

    /// `R p + t`: a world point in this image's camera coordinates.
    pub fn cam_from_world_point(&self, p: &Vec3) -> Vec3 {
        self.cam_from_world_rotation() * p + Vec3::from(self.tvec)
    }

    /// The camera centre in world coordinates, `C = −Rᵀ t`.
    pub fn center(&self) -> Vec3 {
        -(self.cam_from_world_rotation().transpose() * Vec3::from(self.tvec))
    }

    /// The camera's viewing direction (+z of the camera) in world coordinates, `Rᵀ e_z`.
    pub fn view_direction(&self) -> Vec3 {
        self.cam_from_world_rotation().transpose() * Vec3::z()
    }

    /// An image with pose `X_cam = rotation · X_world + t` and no keypoints.
    pub fn from_pose(
        id: ImageId,
        name: impl Into<String>,
        camera_id: CameraId,
        rotation: &Rotation3<f64>,
        t: &Vec3,
    ) -> Image {
        let q = UnitQuaternion::from_rotation_matrix(rotation);
        Image {
            id,
            name: name.into(),
            camera_id,
            qvec: [q.w, q.i, q.j, q.k],
            tvec: [t.x, t.y, t.z],
            points2d: Vec::new(),
        }
    }
}

/// One observation of a 3D point: image and keypoint index.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TrackElement {
    /// The observing image.
    pub image_id: ImageId,
    /// Index into that image's `points2d`.
    pub point2d_idx: u32,
}

/// A triangulated point with its colour, COLMAP's error and its track.
#[derive(Clone, Debug, PartialEq)]
pub struct Point3D {
    /// Id in the model.
    pub id: Point3DId,
    /// World position.
    pub xyz: Vec3,
    /// Colour (8-bit sRGB).
    pub rgb: [u8; 3],
    /// COLMAP's mean reprojection error of the track, in pixels.
    pub error: f64,
    /// The images and keypoints that observe it.
    pub track: Vec<TrackElement>,
}

/// A COLMAP sparse model.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Reconstruction {
    /// Cameras by id.
    pub cameras: BTreeMap<CameraId, Camera>,
    /// Registered images by id.
    pub images: BTreeMap<ImageId, Image>,
    /// 3D points by id.
    pub points3d: BTreeMap<Point3DId, Point3D>,
}

impl Reconstruction {
    /// Read `cameras.txt`, `images.txt` and `points3D.txt` from `dir`.
    pub fn read_text(dir: &Path) -> Result<Self> {
        let [c, i, p] = ModelFormat::Text.file_names().map(|f| dir.join(f));
        let rec = Reconstruction {
            cameras: text::read_cameras(open(&c)?, &c)?,
            images: text::read_images(open(&i)?, &i)?,
            points3d: text::read_points3d(open(&p)?, &p)?,
        };
        rec.check_references(&[&c, &i, &p])?;
        Ok(rec)
    }

    /// Read `cameras.bin`, `images.bin` and `points3D.bin` from `dir`.
    pub fn read_binary(dir: &Path) -> Result<Self> {
        let [c, i, p] = ModelFormat::Binary.file_names().map(|f| dir.join(f));
        let rec = Reconstruction {
            cameras: binary::read_cameras(open(&c)?, &c)?,
            images: binary::read_images(open(&i)?, &i)?,
            points3d: binary::read_points3d(open(&p)?, &p)?,
        };
        rec.check_references(&[&c, &i, &p])?;
        Ok(rec)
    }

    /// Read the model in `dir`, binary when all three `.bin` files exist (as COLMAP does),
    /// else text.
    pub fn read(dir: &Path) -> Result<(Self, ModelFormat)> {
        if ModelFormat::Binary.present_in(dir) {
            Ok((Self::read_binary(dir)?, ModelFormat::Binary))
        } else if ModelFormat::Text.present_in(dir) {
            Ok((Self::read_text(dir)?, ModelFormat::Text))
        } else {
            Err(Error::Workspace {
                path: dir.to_path_buf(),
                message:
                    "no COLMAP model here: expected cameras, images and points3D as .bin or .txt"
                        .to_string(),
            })
        }
    }

    /// Write the model as text into `dir` (created if missing).
    pub fn write_text(&self, dir: &Path) -> Result<()> {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        let [c, i, p] = ModelFormat::Text.file_names().map(|f| dir.join(f));
        write_file(&c, |w| text::write_cameras(w, &self.cameras))?;
        write_file(&i, |w| text::write_images(w, &self.images))?;
        write_file(&p, |w| text::write_points3d(w, &self.points3d))
    }

    /// Write the model in binary into `dir` (created if missing).
    pub fn write_binary(&self, dir: &Path) -> Result<()> {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        let [c, i, p] = ModelFormat::Binary.file_names().map(|f| dir.join(f));
        write_file(&c, |w| binary::write_cameras(w, &self.cameras))?;
        write_file(&i, |w| binary::write_images(w, &self.images))?;
        write_file(&p, |w| binary::write_points3d(w, &self.points3d))
    }

    /// The camera of `image`, if the model has it.
    pub fn camera_of(&self, image: &Image) -> Option<&Camera> {
        self.cameras.get(&image.camera_id)
    }

    /// Pixel position of world point `x` in image `image_id`; `None` when the image or its
    /// camera is unknown or the point is behind the camera.
    pub fn project(&self, image_id: ImageId, x: &Vec3) -> Option<[f64; 2]> {
        let image = self.images.get(&image_id)?;
        self.camera_of(image)?
            .project(&image.cam_from_world_point(x))
    }

    /// Reprojection error in pixels of every observation (track element) of every 3D point,
    /// in point-id order. Observations that cannot be projected (behind the camera) are
    /// left out.
    pub fn reprojection_errors(&self) -> Vec<(Point3DId, ImageId, f64)> {
        let mut out = Vec::new();
        for p in self.points3d.values() {
            for te in &p.track {
                if let Some(e) = self.observation_error(p, te) {
                    out.push((p.id, te.image_id, e));
                }
            }
        }
        out
    }

    fn observation_error(&self, p: &Point3D, te: &TrackElement) -> Option<f64> {
        let image = self.images.get(&te.image_id)?;
        let obs = image.points2d.get(te.point2d_idx as usize)?;
        let px = self
            .camera_of(image)?
            .project(&image.cam_from_world_point(&p.xyz))?;
        Some(((px[0] - obs.xy[0]).powi(2) + (px[1] - obs.xy[1]).powi(2)).sqrt())
    }

    /// Mean over all observations of `|project(X) − xy|` in pixels; `None` without any.
    pub fn mean_reprojection_error(&self) -> Option<f64> {
        let errors = self.reprojection_errors();
        (!errors.is_empty()).then(|| errors.iter().map(|e| e.2).sum::<f64>() / errors.len() as f64)
    }

    /// Mean reprojection error of the track of point `id`, recomputed (COLMAP stores the
    /// same figure in [`Point3D::error`]).
    pub fn point_error(&self, id: Point3DId) -> Option<f64> {
        let p = self.points3d.get(&id)?;
        let errors: Vec<f64> = p
            .track
            .iter()
            .filter_map(|te| self.observation_error(p, te))
            .collect();
        (!errors.is_empty()).then(|| errors.iter().sum::<f64>() / errors.len() as f64)
    }

    /// COLMAP's "mean reprojection error" as `model_analyzer` prints it: the mean of the
    /// stored per-point errors [`Point3D::error`] (points with a negative error, COLMAP's
    /// "unknown", are left out).
    pub fn mean_point_error(&self) -> Option<f64> {
        let errors: Vec<f64> = self
            .points3d
            .values()
            .map(|p| p.error)
            .filter(|e| *e >= 0.0)
            .collect();
        (!errors.is_empty()).then(|| errors.iter().sum::<f64>() / errors.len() as f64)
    }

    /// Mean reprojection error in pixels of the 2D points of image `id` that observe a 3D
    /// point; `None` when it has none.
    pub fn image_reprojection_error(&self, id: ImageId) -> Option<f64> {
        let image = self.images.get(&id)?;
        let camera = self.camera_of(image)?;
        let (mut sum, mut n) = (0.0, 0usize);
        for p2 in &image.points2d {
            let Some(p3) = p2.point3d_id.and_then(|pid| self.points3d.get(&pid)) else {
                continue;
            };
            if let Some(px) = camera.project(&image.cam_from_world_point(&p3.xyz)) {
                sum += ((px[0] - p2.xy[0]).powi(2) + (px[1] - p2.xy[1]).powi(2)).sqrt();
                n += 1;
            }
        }
        (n > 0).then(|| sum / n as f64)
    }

    /// Number of 2D points of image `id` that observe a 3D point.
    pub fn num_observations(&self, id: ImageId) -> usize {
        self.images.get(&id).map_or(0, |im| {
            im.points2d
                .iter()
                .filter(|p| p.point3d_id.is_some())
                .count()
        })
    }

    /// The image called `name`, if registered.
    pub fn image_by_name(&self, name: &str) -> Option<&Image> {
        self.images.values().find(|im| im.name == name)
    }

    /// Check that every reference points at something that exists: images at cameras,
    /// keypoints at 3D points, tracks at images and keypoints. `files` are the cameras,
    /// images and points3D files the model was read from, named in errors.
    pub fn check_references(&self, files: &[&Path; 3]) -> Result<()> {
        let [cameras_file, images_file, points_file] = *files;
        for im in self.images.values() {
            if !self.cameras.contains_key(&im.camera_id) {
                return Err(Error::format(
                    images_file,
                    format!("image id {}", im.id.0),
                    format!(
                        "expected a camera id of {} ({}), found camera id {}",
                        cameras_file.display(),
                        id_list(self.cameras.keys().map(|c| c.0 as u64)),
                        im.camera_id.0
                    ),
                ));
            }
            for (k, p2) in im.points2d.iter().enumerate() {
                if let Some(pid) = p2.point3d_id {
                    if !self.points3d.contains_key(&pid) {
                        return Err(Error::format(
                            images_file,
                            format!("image id {}, point2D {k}", im.id.0),
                            format!("3D point id {} is not in the points3D file", pid.0),
                        ));
                    }
                }
            }
        }
        for p in self.points3d.values() {
            for te in &p.track {
                let Some(im) = self.images.get(&te.image_id) else {
                    return Err(Error::format(
                        points_file,
                        format!("point3D id {}", p.id.0),
                        format!(
                            "track names image id {}, which is not in the images file",
                            te.image_id.0
                        ),
                    ));
                };
                if te.point2d_idx as usize >= im.points2d.len() {
                    return Err(Error::format(
                        points_file,
                        format!("point3D id {}", p.id.0),
                        format!(
                            "track names point2D {} of image id {}, which has only {}",
                            te.point2d_idx,
                            te.image_id.0,
                            im.points2d.len()
                        ),
                    ));
                }
            }
        }
        Ok(())
    }
}

/// Up to ten ids, comma-separated, for an error message.
fn id_list(ids: impl Iterator<Item = u64>) -> String {
    let all: Vec<u64> = ids.collect();
    let mut s: Vec<String> = all.iter().take(10).map(|i| i.to_string()).collect();
    if all.len() > 10 {
        s.push(format!("… {} in all", all.len()));
    }
    if s.is_empty() {
        "it has none".into()
    } else {
        format!("ids {}", s.join(", "))
    }
}

/// Open `path` for buffered reading.
fn open(path: &Path) -> Result<std::io::BufReader<std::fs::File>> {
    std::fs::File::open(path)
        .map(std::io::BufReader::new)
        .map_err(|e| Error::io(path, e))
}

/// Create `path` and fill it with `f`.
fn write_file(
    path: &Path,
    f: impl FnOnce(&mut std::io::BufWriter<std::fs::File>) -> std::io::Result<()>,
) -> Result<()> {
    use std::io::Write;
    let file = std::fs::File::create(path).map_err(|e| Error::io(path, e))?;
    let mut w = std::io::BufWriter::new(file);
    f(&mut w)
        .and_then(|_| w.flush())
        .map_err(|e| Error::io(path, e))
}

/// Unit-normalise a quaternion read from a file; `None` when its norm is zero or not finite.
pub(crate) fn normalize_qvec(q: [f64; 4]) -> Option<[f64; 4]> {
    let n = q.iter().map(|x| x * x).sum::<f64>().sqrt();
    (n.is_finite() && n > 0.0).then(|| q.map(|x| x / n))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pose_conventions() {
        // A camera at C = (1, 2, 3) looking down world -z (R = diag(1, -1, -1)).
        // Tolerance 1e-12: a few f64 operations on O(1) numbers.
        let r = Rotation3::from_matrix_unchecked(nalgebra::Matrix3::new(
            1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, -1.0,
        ));
        let c = Vec3::new(1.0, 2.0, 3.0);
        let t = -(r * c);
        let im = Image::from_pose(ImageId(4), "a.jpg", CameraId(1), &r, &t);
        assert!((im.center() - c).norm() < 1e-12);
        assert!(im.cam_from_world_point(&c).norm() < 1e-12);
        // A point 5 units below the camera is 5 units in front of it.
        let p = im.cam_from_world_point(&Vec3::new(1.0, 2.0, -2.0));
        assert!((p - Vec3::new(0.0, 0.0, 5.0)).norm() < 1e-12);
        assert!((im.view_direction() - Vec3::new(0.0, 0.0, -1.0)).norm() < 1e-12);
        let iso = im.cam_from_world();
        let q = Vec3::new(0.3, -0.2, 0.9);
        assert!(
            (iso.transform_point(&q.into()).coords - im.cam_from_world_point(&q)).norm() < 1e-12
        );
    }
}
