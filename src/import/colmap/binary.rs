//! COLMAP's binary model format (`cameras.bin`, `images.bin`, `points3D.bin`), little-endian,
//! as COLMAP 3.8 writes it (`src/base/reconstruction.cc`):
//!
//! - `cameras.bin`: `u64 count`, then per camera `u32 id, i32 model_id, u64 width,
//!   u64 height, f64 params[num_params(model)]`.
//! - `images.bin`: `u64 count`, then per image `u32 id, f64 qw qx qy qz, f64 tx ty tz,
//!   u32 camera_id, name as bytes up to a NUL, u64 num_points2D`, then per keypoint
//!   `f64 x, f64 y, u64 point3D_id` (`u64::MAX` = no 3D point).
//! - `points3D.bin`: `u64 count`, then per point `u64 id, f64 x y z, u8 r g b, f64 error,
//!   u64 track_length`, then per element `u32 image_id, u32 point2D_idx`.
//!
//! The reader holds the file in memory and bounds-checks every field; errors name the file,
//! the record (counted from 0, with its id once known) and the byte offset. A header count
//! that the file size cannot hold, or bytes left over after the last record, are errors.

use std::collections::BTreeMap;
use std::io::{Read, Write};
use std::path::Path;

use byteorder::{LittleEndian, WriteBytesExt};

use super::{
    normalize_qvec, Camera, CameraId, CameraModel, Image, ImageId, Point2D, Point3D, Point3DId,
    TrackElement,
};
use crate::{Error, Result, Vec3};

/// COLMAP's `kInvalidPoint3DId`.
const INVALID_POINT3D_ID: u64 = u64::MAX;

/// A bounds-checked little-endian reader over the whole file.
struct Cursor<'a> {
    data: &'a [u8],
    pos: usize,
}

impl<'a> Cursor<'a> {
    fn take(&mut self, n: usize, what: &str) -> std::result::Result<&'a [u8], String> {
        let remaining = self.data.len() - self.pos;
        if n > remaining {
            return Err(format!(
                "truncated: {what} needs {n} bytes at byte {} but the file ends at byte {}",
                self.pos,
                self.data.len()
            ));
        }
        let s = &self.data[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }

    fn array<const N: usize>(&mut self, what: &str) -> std::result::Result<[u8; N], String> {
        let s = self.take(N, what)?;
        let mut a = [0u8; N];
        a.copy_from_slice(s);
        Ok(a)
    }

    fn u8(&mut self, what: &str) -> std::result::Result<u8, String> {
        Ok(self.array::<1>(what)?[0])
    }
    fn u32(&mut self, what: &str) -> std::result::Result<u32, String> {
        Ok(u32::from_le_bytes(self.array(what)?))
    }
    fn i32(&mut self, what: &str) -> std::result::Result<i32, String> {
        Ok(i32::from_le_bytes(self.array(what)?))
    }
    fn u64(&mut self, what: &str) -> std::result::Result<u64, String> {
        Ok(u64::from_le_bytes(self.array(what)?))
    }
    fn f64(&mut self, what: &str) -> std::result::Result<f64, String> {
        let at = self.pos;
        let x = f64::from_le_bytes(self.array(what)?);
        if x.is_finite() {
            Ok(x)
        } else {
            Err(format!("{what} at byte {at} is not finite: {x}"))
        }
    }

    /// Bytes up to a NUL (consumed), as UTF-8.
    fn cstring(&mut self, what: &str) -> std::result::Result<String, String> {
        let start = self.pos;
        let rest = &self.data[start..];
        let len = rest.iter().position(|&b| b == 0).ok_or_else(|| {
            format!("truncated: {what} starting at byte {start} has no terminating NUL before the end of the file")
        })?;
        self.pos += len + 1;
        String::from_utf8(rest[..len].to_vec())
            .map_err(|_| format!("{what} at byte {start} is not valid UTF-8"))
    }

    fn remaining(&self) -> usize {
        self.data.len() - self.pos
    }
}

/// Read a whole stream into memory; `path` names it in errors.
fn slurp(mut reader: impl Read, path: &Path) -> Result<Vec<u8>> {
    let mut data = Vec::new();
    reader
        .read_to_end(&mut data)
        .map_err(|e| Error::io(path, e))?;
    Ok(data)
}

/// Read the `u64` record count and check that `count` records of at least `min_record`
/// bytes fit in the file.
fn read_count(cur: &mut Cursor, path: &Path, min_record: usize, what: &str) -> Result<usize> {
    let count = cur
        .u64("the record count")
        .map_err(|m| Error::format(path, "header", m))?;
    let available = cur.remaining() as u64;
    if count.saturating_mul(min_record as u64) > available {
        return Err(Error::format(
            path,
            "header",
            format!(
                "the count says {count} {what}, which need at least {} bytes, but only {available} bytes follow the header",
                count.saturating_mul(min_record as u64)
            ),
        ));
    }
    Ok(count as usize)
}

/// After the last record: no bytes may be left over.
fn check_end(cur: &Cursor, path: &Path, count: usize, what: &str) -> Result<()> {
    if cur.remaining() != 0 {
        return Err(Error::format(
            path,
            format!("byte {}", cur.pos),
            format!(
                "the count says {count} {what} but {} bytes remain after the last one",
                cur.remaining()
            ),
        ));
    }
    Ok(())
}

fn record_loc(record: usize, id: Option<String>, start: usize) -> String {
    match id {
        Some(id) => format!("record {record} ({id}, starting at byte {start})"),
        None => format!("record {record} (starting at byte {start})"),
    }
}

/// Parse `cameras.bin` from `reader`; `path` names the file in errors.
pub fn read_cameras(reader: impl Read, path: &Path) -> Result<BTreeMap<CameraId, Camera>> {
    let data = slurp(reader, path)?;
    let mut cur = Cursor {
        data: &data,
        pos: 0,
    };
    // id, model, width, height and at least three params.
    let count = read_count(&mut cur, path, 4 + 4 + 8 + 8 + 3 * 8, "cameras")?;
    let mut cameras = BTreeMap::new();
    for record in 0..count {
        let start = cur.pos;
        let mut id_seen = None;
        let parsed = (|| {
            let id = CameraId(cur.u32("camera id")?);
            id_seen = Some(format!("camera id {}", id.0));
            let model_id = cur.i32("model id")?;
            let model = u32::try_from(model_id)
                .ok()
                .and_then(CameraModel::from_id)
                .ok_or_else(|| {
                    format!("unknown camera model id {model_id} (COLMAP 3.8 has 0..=10)")
                })?;
            let width = cur.u64("width")?;
            let height = cur.u64("height")?;
            let width = u32::try_from(width).map_err(|_| format!("width {width} is too large"))?;
            let height =
                u32::try_from(height).map_err(|_| format!("height {height} is too large"))?;
            let params = (0..model.num_params())
                .map(|_| cur.f64("a camera parameter"))
                .collect::<std::result::Result<Vec<_>, _>>()?;
            let camera = Camera::checked(id, model, width, height, params)?;
            if cameras.contains_key(&id) {
                return Err(format!("camera id {} appears twice", id.0));
            }
            Ok::<_, String>(camera)
        })();
        let camera =
            parsed.map_err(|m| Error::format(path, record_loc(record, id_seen, start), m))?;
        cameras.insert(camera.id, camera);
    }
    check_end(&cur, path, count, "cameras")?;
    Ok(cameras)
}

/// Parse `images.bin` from `reader`; `path` names the file in errors.
pub fn read_images(reader: impl Read, path: &Path) -> Result<BTreeMap<ImageId, Image>> {
    let data = slurp(reader, path)?;
    let mut cur = Cursor {
        data: &data,
        pos: 0,
    };
    // id, qvec, tvec, camera id, an empty name's NUL, the keypoint count.
    let count = read_count(&mut cur, path, 4 + 32 + 24 + 4 + 1 + 8, "images")?;
    let mut images = BTreeMap::new();
    for record in 0..count {
        let start = cur.pos;
        let mut id_seen = None;
        let parsed = (|| {
            let id = ImageId(cur.u32("image id")?);
            id_seen = Some(format!("image id {}", id.0));
            let mut q = [0.0; 4];
            for x in &mut q {
                *x = cur.f64("a quaternion component")?;
            }
            let qvec = normalize_qvec(q).ok_or("the quaternion is zero")?;
            let mut tvec = [0.0; 3];
            for x in &mut tvec {
                *x = cur.f64("a translation component")?;
            }
            let camera_id = CameraId(cur.u32("camera id")?);
            let name = cur.cstring("the image name")?;
            let n = cur.u64("the number of 2D points")?;
            if n.saturating_mul(24) > cur.remaining() as u64 {
                return Err(format!(
                    "truncated: {n} 2D points need {} bytes at byte {} but the file ends at byte {}",
                    n.saturating_mul(24),
                    cur.pos,
                    cur.data.len()
                ));
            }
            let mut points2d = Vec::with_capacity(n as usize);
            for _ in 0..n {
                let x = cur.f64("a 2D point's x")?;
                let y = cur.f64("a 2D point's y")?;
                let pid = cur.u64("a 2D point's 3D point id")?;
                points2d.push(Point2D {
                    xy: [x, y],
                    point3d_id: (pid != INVALID_POINT3D_ID).then_some(Point3DId(pid)),
                });
            }
            if images.contains_key(&id) {
                return Err(format!("image id {} appears twice", id.0));
            }
            Ok::<_, String>(Image {
                id,
                name,
                camera_id,
                qvec,
                tvec,
                points2d,
            })
        })();
        let image =
            parsed.map_err(|m| Error::format(path, record_loc(record, id_seen, start), m))?;
        images.insert(image.id, image);
    }
    check_end(&cur, path, count, "images")?;
    Ok(images)
}

/// Parse `points3D.bin` from `reader`; `path` names the file in errors.
pub fn read_points3d(reader: impl Read, path: &Path) -> Result<BTreeMap<Point3DId, Point3D>> {
    let data = slurp(reader, path)?;
    let mut cur = Cursor {
        data: &data,
        pos: 0,
    };
    // id, xyz, rgb, error, track length.
    let count = read_count(&mut cur, path, 8 + 24 + 3 + 8 + 8, "3D points")?;
    let mut points = BTreeMap::new();
    for record in 0..count {
        let start = cur.pos;
        let mut id_seen = None;
        let parsed = (|| {
            let id = Point3DId(cur.u64("3D point id")?);
            id_seen = Some(format!("point3D id {}", id.0));
            let xyz = Vec3::new(cur.f64("x")?, cur.f64("y")?, cur.f64("z")?);
            let rgb = [cur.u8("red")?, cur.u8("green")?, cur.u8("blue")?];
            let error = cur.f64("the error")?;
            let n = cur.u64("the track length")?;
            if n.saturating_mul(8) > cur.remaining() as u64 {
                return Err(format!(
                    "truncated: a track of {n} elements needs {} bytes at byte {} but the file ends at byte {}",
                    n.saturating_mul(8),
                    cur.pos,
                    cur.data.len()
                ));
            }
            let mut track = Vec::with_capacity(n as usize);
            for _ in 0..n {
                track.push(TrackElement {
                    image_id: ImageId(cur.u32("a track element's image id")?),
                    point2d_idx: cur.u32("a track element's 2D point index")?,
                });
            }
            if points.contains_key(&id) {
                return Err(format!("3D point id {} appears twice", id.0));
            }
            Ok::<_, String>(Point3D {
                id,
                xyz,
                rgb,
                error,
                track,
            })
        })();
        let point =
            parsed.map_err(|m| Error::format(path, record_loc(record, id_seen, start), m))?;
        points.insert(point.id, point);
    }
    check_end(&cur, path, count, "3D points")?;
    Ok(points)
}

/// Write `cameras.bin`.
pub fn write_cameras(
    w: &mut impl Write,
    cameras: &BTreeMap<CameraId, Camera>,
) -> std::io::Result<()> {
    w.write_u64::<LittleEndian>(cameras.len() as u64)?;
    for c in cameras.values() {
        w.write_u32::<LittleEndian>(c.id.0)?;
        w.write_i32::<LittleEndian>(c.model.id() as i32)?;
        w.write_u64::<LittleEndian>(c.width as u64)?;
        w.write_u64::<LittleEndian>(c.height as u64)?;
        for p in &c.params {
            w.write_f64::<LittleEndian>(*p)?;
        }
    }
    Ok(())
}

/// Write `images.bin`.
pub fn write_images(w: &mut impl Write, images: &BTreeMap<ImageId, Image>) -> std::io::Result<()> {
    w.write_u64::<LittleEndian>(images.len() as u64)?;
    for im in images.values() {
        w.write_u32::<LittleEndian>(im.id.0)?;
        for q in im.qvec {
            w.write_f64::<LittleEndian>(q)?;
        }
        for t in im.tvec {
            w.write_f64::<LittleEndian>(t)?;
        }
        w.write_u32::<LittleEndian>(im.camera_id.0)?;
        w.write_all(im.name.as_bytes())?;
        w.write_u8(0)?;
        w.write_u64::<LittleEndian>(im.points2d.len() as u64)?;
        for p in &im.points2d {
            w.write_f64::<LittleEndian>(p.xy[0])?;
            w.write_f64::<LittleEndian>(p.xy[1])?;
            w.write_u64::<LittleEndian>(p.point3d_id.map_or(INVALID_POINT3D_ID, |id| id.0))?;
        }
    }
    Ok(())
}

/// Write `points3D.bin`.
pub fn write_points3d(
    w: &mut impl Write,
    points: &BTreeMap<Point3DId, Point3D>,
) -> std::io::Result<()> {
    w.write_u64::<LittleEndian>(points.len() as u64)?;
    for p in points.values() {
        w.write_u64::<LittleEndian>(p.id.0)?;
        for x in [p.xyz.x, p.xyz.y, p.xyz.z] {
            w.write_f64::<LittleEndian>(x)?;
        }
        w.write_all(&p.rgb)?;
        w.write_f64::<LittleEndian>(p.error)?;
        w.write_u64::<LittleEndian>(p.track.len() as u64)?;
        for te in &p.track {
            w.write_u32::<LittleEndian>(te.image_id.0)?;
            w.write_u32::<LittleEndian>(te.point2d_idx)?;
        }
    }
    Ok(())
}
