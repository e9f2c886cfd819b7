//! COLMAP's text model format (`cameras.txt`, `images.txt`, `points3D.txt`), as COLMAP 3.8
//! reads and writes it.
//!
//! - `cameras.txt`: one line per camera, `CAMERA_ID MODEL WIDTH HEIGHT PARAMS[]`.
//! - `images.txt`: two lines per image, `IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME` and
//!   `X Y POINT3D_ID ...` (`POINT3D_ID` −1 for a keypoint without a 3D point; the second
//!   line may be empty).
//! - `points3D.txt`: one line per point, `POINT3D_ID X Y Z R G B ERROR (IMAGE_ID POINT2D_IDX)...`.
//!
//! Every line starting with `#` and every blank line is skipped (except the keypoint line
//! that follows an image line, which is read as it is, empty or not). Every field is
//! bounds-checked and parsed; errors name the file and the line (counted from 1).
//! Floating-point values are written in Rust's shortest round-trip form, so a model
//! written and read back is bit-identical.

use std::collections::BTreeMap;
use std::io::{BufRead, Write};
use std::path::Path;
use std::str::FromStr;

use super::{
    normalize_qvec, Camera, CameraId, CameraModel, Image, ImageId, Point2D, Point3D, Point3DId,
    TrackElement,
};
use crate::{Error, Result, Vec3};

/// Lines of a text file with their numbers (from 1); a read or UTF-8 failure is an error
/// naming the line.
struct Lines<'a, R> {
    reader: R,
    path: &'a Path,
    line_no: usize,
    buf: String,
}

impl<'a, R: BufRead> Lines<'a, R> {
    fn new(reader: R, path: &'a Path) -> Self {
        Lines {
            reader,
            path,
            line_no: 0,
            buf: String::new(),
        }
    }

    /// The next raw line (without its line ending), or `None` at the end of the file.
    fn next_raw(&mut self) -> Result<Option<&str>> {
        self.buf.clear();
        self.line_no += 1;
        let n = self.reader.read_line(&mut self.buf).map_err(|e| {
            if e.kind() == std::io::ErrorKind::InvalidData {
                self.err("the line is not valid UTF-8 text")
            } else {
                Error::io(self.path, e)
            }
        })?;
        if n == 0 {
            return Ok(None);
        }
        Ok(Some(self.buf.trim_end_matches(['\n', '\r'])))
    }

    /// The next line that is neither blank nor a `#` comment.
    fn next_data(&mut self) -> Result<Option<String>> {
        loop {
            match self.next_raw()? {
                None => return Ok(None),
                Some(line) => {
                    let t = line.trim();
                    if !t.is_empty() && !t.starts_with('#') {
                        return Ok(Some(t.to_string()));
                    }
                }
            }
        }
    }

    fn err(&self, message: impl Into<String>) -> Error {
        Error::format(self.path, format!("line {}", self.line_no), message)
    }
}

/// Field `idx` of `tokens`, parsed as `T`; `what` names it in the error.
fn field<T: FromStr>(tokens: &[&str], idx: usize, what: &str) -> std::result::Result<T, String> {
    let tok = tokens.get(idx).ok_or_else(|| {
        format!(
            "missing field {} ({what}): the line has only {} fields",
            idx + 1,
            tokens.len()
        )
    })?;
    tok.parse::<T>().map_err(|_| {
        format!(
            "field {} ({what}) is not a valid {}: {tok:?}",
            idx + 1,
            short_type::<T>()
        )
    })
}

/// Field `idx` as a finite f64.
fn finite(tokens: &[&str], idx: usize, what: &str) -> std::result::Result<f64, String> {
    let x: f64 = field(tokens, idx, what)?;
    if x.is_finite() {
        Ok(x)
    } else {
        Err(format!("field {} ({what}) is not finite: {x}", idx + 1))
    }
}

fn short_type<T>() -> &'static str {
    let name = std::any::type_name::<T>();
    match name {
        "f64" => "number",
        "u8" => "integer 0..=255",
        "u32" => "non-negative 32-bit integer",
        "u64" => "non-negative 64-bit integer",
        "i64" => "integer",
        _ => name,
    }
}

/// Parse `cameras.txt` from `reader`; `path` names the file in errors.
pub fn read_cameras(reader: impl BufRead, path: &Path) -> Result<BTreeMap<CameraId, Camera>> {
    let mut lines = Lines::new(reader, path);
    let mut cameras = BTreeMap::new();
    while let Some(line) = lines.next_data()? {
        let tokens: Vec<&str> = line.split_whitespace().collect();
        let parsed = (|| {
            let id = CameraId(field(&tokens, 0, "CAMERA_ID")?);
            let name: String = field(&tokens, 1, "MODEL")?;
            let model = CameraModel::from_name(&name).ok_or_else(|| {
                format!("unknown camera model {name:?} (COLMAP 3.8 knows SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV, OPENCV_FISHEYE, FULL_OPENCV, FOV, SIMPLE_RADIAL_FISHEYE, RADIAL_FISHEYE, THIN_PRISM_FISHEYE)")
            })?;
            let width: u32 = field(&tokens, 2, "WIDTH")?;
            let height: u32 = field(&tokens, 3, "HEIGHT")?;
            let params = (4..tokens.len())
                .map(|i| finite(&tokens, i, "PARAMS[]"))
                .collect::<std::result::Result<Vec<_>, _>>()?;
            Camera::checked(id, model, width, height, params)
        })();
        let camera = parsed.map_err(|m| lines.err(m))?;
        if cameras.contains_key(&camera.id) {
            return Err(lines.err(format!("camera id {} appears twice", camera.id.0)));
        }
        cameras.insert(camera.id, camera);
    }
    Ok(cameras)
}

/// Parse `images.txt` from `reader`; `path` names the file in errors.
pub fn read_images(reader: impl BufRead, path: &Path) -> Result<BTreeMap<ImageId, Image>> {
    let mut lines = Lines::new(reader, path);
    let mut images = BTreeMap::new();
    while let Some(line) = lines.next_data()? {
        // First line: pose, camera and name.
        let tokens: Vec<&str> = line.split_whitespace().collect();
        let mut image = parse_image_line(&tokens).map_err(|m| lines.err(m))?;
        if images.contains_key(&image.id) {
            return Err(lines.err(format!("image id {} appears twice", image.id.0)));
        }
        // Second line: keypoints, possibly none (an empty line).
        let Some(points_line) = lines.next_raw()?.map(str::to_string) else {
            return Err(lines.err(format!(
                "the file ends after image id {}: expected its line of 2D points (X Y POINT3D_ID ...)",
                image.id.0
            )));
        };
        let tokens: Vec<&str> = points_line.split_whitespace().collect();
        image.points2d = parse_points2d(&tokens, image.id).map_err(|m| lines.err(m))?;
        images.insert(image.id, image);
    }
    Ok(images)
}

/// An image's first line, `IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME` (the name may hold
/// spaces), as an [`Image`] without its 2D points; the quaternion normalised.
fn parse_image_line(tokens: &[&str]) -> std::result::Result<Image, String> {
    let id = ImageId(field(tokens, 0, "IMAGE_ID")?);
    let mut q = [0.0; 4];
    for (k, name) in ["QW", "QX", "QY", "QZ"].iter().enumerate() {
        q[k] = finite(tokens, 1 + k, name)?;
    }
    let qvec = normalize_qvec(q).ok_or("the quaternion QW QX QY QZ is zero")?;
    let mut tvec = [0.0; 3];
    for (k, name) in ["TX", "TY", "TZ"].iter().enumerate() {
        tvec[k] = finite(tokens, 5 + k, name)?;
    }
    let camera_id = CameraId(field(tokens, 8, "CAMERA_ID")?);
    if tokens.len() < 10 {
        return Err("missing field 10 (NAME)".to_string());
    }
    Ok(Image {
        id,
        name: tokens[9..].join(" "),
        camera_id,
        qvec,
        tvec,
        points2d: Vec::new(),
    })
}

/// An image's second line, `X Y POINT3D_ID` triples (none on an empty line). `-1` (and
/// `u64::MAX`, COLMAP's invalid id in binary) mean "no 3D point".
fn parse_points2d(tokens: &[&str], image: ImageId) -> std::result::Result<Vec<Point2D>, String> {
    if !tokens.len().is_multiple_of(3) {
        return Err(format!(
            "2D points of image id {}: {} fields is not a multiple of 3 (X Y POINT3D_ID)",
            image.0,
            tokens.len()
        ));
    }
    let mut points = Vec::with_capacity(tokens.len() / 3);
    for k in (0..tokens.len()).step_by(3) {
        let x = finite(tokens, k, "X")?;
        let y = finite(tokens, k + 1, "Y")?;
        let point3d_id = match tokens[k + 2] {
            "-1" => None,
            _ => match field::<u64>(tokens, k + 2, "POINT3D_ID") {
                Ok(u64::MAX) => None,
                Ok(p) => Some(Point3DId(p)),
                Err(_) => {
                    return Err(format!(
                        "field {} (POINT3D_ID) is {:?}; only -1 or ids >= 0 are valid",
                        k + 3,
                        tokens[k + 2]
                    ))
                }
            },
        };
        points.push(Point2D {
            xy: [x, y],
            point3d_id,
        });
    }
    Ok(points)
}

/// Parse `points3D.txt` from `reader`; `path` names the file in errors.
pub fn read_points3d(reader: impl BufRead, path: &Path) -> Result<BTreeMap<Point3DId, Point3D>> {
    let mut lines = Lines::new(reader, path);
    let mut points = BTreeMap::new();
    while let Some(line) = lines.next_data()? {
        let tokens: Vec<&str> = line.split_whitespace().collect();
        let parsed = (|| {
            let id = Point3DId(field(&tokens, 0, "POINT3D_ID")?);
            let xyz = Vec3::new(
                finite(&tokens, 1, "X")?,
                finite(&tokens, 2, "Y")?,
                finite(&tokens, 3, "Z")?,
            );
            let rgb = [
                field::<u8>(&tokens, 4, "R")?,
                field::<u8>(&tokens, 5, "G")?,
                field::<u8>(&tokens, 6, "B")?,
            ];
            let error = finite(&tokens, 7, "ERROR")?;
            let rest = tokens.len().saturating_sub(8);
            if !rest.is_multiple_of(2) {
                return Err(format!(
                    "the track has {rest} fields, not a whole number of (IMAGE_ID, POINT2D_IDX) pairs"
                ));
            }
            let mut track = Vec::with_capacity(rest / 2);
            for k in (8..tokens.len()).step_by(2) {
                track.push(TrackElement {
                    image_id: ImageId(field(&tokens, k, "IMAGE_ID")?),
                    point2d_idx: field(&tokens, k + 1, "POINT2D_IDX")?,
                });
            }
            Ok::<_, String>(Point3D {
                id,
                xyz,
                rgb,
                error,
                track,
            })
        })();
        let point = parsed.map_err(|m| lines.err(m))?;
        if points.contains_key(&point.id) {
            return Err(lines.err(format!("3D point id {} appears twice", point.id.0)));
        }
        points.insert(point.id, point);
    }
    Ok(points)
}

/// Write `cameras.txt` with COLMAP's header.
pub fn write_cameras(
    w: &mut impl Write,
    cameras: &BTreeMap<CameraId, Camera>,
) -> std::io::Result<()> {
    writeln!(w, "# Camera list with one line of data per camera:")?;
    writeln!(w, "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]")?;
    writeln!(w, "# Number of cameras: {}", cameras.len())?;
    for c in cameras.values() {
        write!(w, "{} {} {} {}", c.id.0, c.model.name(), c.width, c.height)?;
        for p in &c.params {
            write!(w, " {p:?}")?;
        }
        writeln!(w)?;
    }
    Ok(())
}

/// Write `images.txt` with COLMAP's header.
pub fn write_images(w: &mut impl Write, images: &BTreeMap<ImageId, Image>) -> std::io::Result<()> {
    let num_obs: usize = images
        .values()
        .map(|im| {
            im.points2d
                .iter()
                .filter(|p| p.point3d_id.is_some())
                .count()
        })
        .sum();
    let mean_obs = if images.is_empty() {
        0.0
    } else {
        num_obs as f64 / images.len() as f64
    };
    writeln!(w, "# Image list with two lines of data per image:")?;
    writeln!(
        w,
        "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME"
    )?;
    writeln!(w, "#   POINTS2D[] as (X, Y, POINT3D_ID)")?;
    writeln!(
        w,
        "# Number of images: {}, mean observations per image: {mean_obs}",
        images.len()
    )?;
    for im in images.values() {
        let [qw, qx, qy, qz] = im.qvec;
        let [tx, ty, tz] = im.tvec;
        writeln!(
            w,
            "{} {qw:?} {qx:?} {qy:?} {qz:?} {tx:?} {ty:?} {tz:?} {} {}",
            im.id.0, im.camera_id.0, im.name
        )?;
        let mut first = true;
        for p in &im.points2d {
            if !first {
                write!(w, " ")?;
            }
            first = false;
            let pid = p.point3d_id.map_or(-1, |id| id.0 as i128);
            write!(w, "{:?} {:?} {pid}", p.xy[0], p.xy[1])?;
        }
        writeln!(w)?;
    }
    Ok(())
}

/// Write `points3D.txt` with COLMAP's header.
pub fn write_points3d(
    w: &mut impl Write,
    points: &BTreeMap<Point3DId, Point3D>,
) -> std::io::Result<()> {
    let track_sum: usize = points.values().map(|p| p.track.len()).sum();
    let mean_track = if points.is_empty() {
        0.0
    } else {
        track_sum as f64 / points.len() as f64
    };
    writeln!(w, "# 3D point list with one line of data per point:")?;
    writeln!(
        w,
        "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)"
    )?;
    writeln!(
        w,
        "# Number of points: {}, mean track length: {mean_track}",
        points.len()
    )?;
    for p in points.values() {
        write!(
            w,
            "{} {:?} {:?} {:?} {} {} {} {:?}",
            p.id.0, p.xyz.x, p.xyz.y, p.xyz.z, p.rgb[0], p.rgb[1], p.rgb[2], p.error
        )?;
        for te in &p.track {
            write!(w, " {} {}", te.image_id.0, te.point2d_idx)?;
        }
        writeln!(w)?;
    }
    Ok(())
}
