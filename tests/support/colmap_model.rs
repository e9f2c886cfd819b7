//! Shared by the COLMAP reader tests (`tests/suite/colmap_errors.rs`, `tests/suite/proptest_parsers.rs`):
//! one small valid model that our writers turn into the files the tests break.

#![allow(dead_code)]

use relight_cpc::import::colmap::{
    Camera, CameraId, CameraModel, Image, ImageId, Point2D, Point3D, Point3DId, Reconstruction,
    TrackElement,
};
use relight_cpc::Vec3;

/// Two cameras (non-contiguous ids), two images, three points with tracks.
pub fn model() -> Reconstruction {
    let mut rec = Reconstruction::default();
    for (id, model, params) in [
        (
            3,
            CameraModel::SimpleRadial,
            vec![500.0, 320.0, 240.0, -0.05],
        ),
        (
            7,
            CameraModel::OpenCv,
            vec![510.0, 505.0, 321.0, 239.0, 0.01, -0.02, 0.001, 0.0],
        ),
    ] {
        let c = Camera::new(CameraId(id), model, 640, 480, params).unwrap();
        rec.cameras.insert(c.id, c);
    }
    let r = nalgebra::Rotation3::from_euler_angles(0.1, -0.2, 0.3);
    for (id, cam) in [(2u32, 3u32), (9, 7)] {
        let mut im = Image::from_pose(
            ImageId(id),
            format!("img{id}.jpg"),
            CameraId(cam),
            &r,
            &Vec3::new(0.1, 0.0, 4.0),
        );
        im.points2d = (0..3)
            .map(|k| Point2D {
                xy: [100.0 + k as f64, 200.5],
                point3d_id: Some(Point3DId(10 + k as u64)),
            })
            .chain(std::iter::once(Point2D {
                xy: [5.0, 6.0],
                point3d_id: None,
            }))
            .collect();
        rec.images.insert(im.id, im);
    }
    for k in 0..3u64 {
        let p = Point3D {
            id: Point3DId(10 + k),
            xyz: Vec3::new(k as f64, 0.5, -1.0),
            rgb: [10, 20, 30],
            error: 0.5,
            track: vec![
                TrackElement {
                    image_id: ImageId(2),
                    point2d_idx: k as u32,
                },
                TrackElement {
                    image_id: ImageId(9),
                    point2d_idx: k as u32,
                },
            ],
        };
        rec.points3d.insert(p.id, p);
    }
    rec
}
