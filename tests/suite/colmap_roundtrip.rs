//! Readers and writers by round trip (proptest): a random model — every camera model,
//! non-contiguous ids, keypoints with and without 3D points, empty keypoint lists, extreme
//! but finite values — written as text and as binary reads back equal, and the text and
//! binary copies read identically. Text is written in shortest round-trip form, so equality
//! is exact, not within a tolerance.

use std::collections::BTreeMap;

use proptest::prelude::*;
use relight_cpc::import::colmap::{
    Camera, CameraId, CameraModel, Image, ImageId, Point2D, Point3D, Point3DId, Reconstruction,
    TrackElement,
};
use relight_cpc::Vec3;

/// A finite f64 drawn from a wide range, including tiny and huge magnitudes.
fn num() -> impl Strategy<Value = f64> {
    prop_oneof![
        -1e3..1e3f64,
        (-300i32..300, -1.0..1.0f64).prop_map(|(e, m)| m * 10f64.powi(e)),
        Just(0.0),
        Just(-0.0),
    ]
}

fn camera(id: u32) -> impl Strategy<Value = Camera> {
    proptest::sample::select(CameraModel::ALL.to_vec()).prop_flat_map(move |model| {
        (
            1u32..100_000,
            1u32..100_000,
            1.0..5000.0f64,
            proptest::collection::vec(num(), model.num_params() - 1),
        )
            .prop_map(move |(w, h, f, rest)| {
                let mut params = [vec![f], rest].concat();
                if !model.has_single_focal() && params[1] == 0.0 {
                    // fy must be non-zero too.
                    params[1] = f;
                }
                Camera::new(CameraId(id), model, w, h, params).expect("valid camera")
            })
    })
}

fn model() -> impl Strategy<Value = Reconstruction> {
    let cam_ids = proptest::collection::btree_set(0u32..u32::MAX, 1..4);
    let img_ids = proptest::collection::btree_set(0u32..u32::MAX, 1..5);
    let pt_ids = proptest::collection::btree_set(0u64..u64::MAX - 1, 0..6);
    (cam_ids, img_ids, pt_ids).prop_flat_map(|(cam_ids, img_ids, pt_ids)| {
        let cam_ids: Vec<u32> = cam_ids.into_iter().collect();
        let img_ids: Vec<u32> = img_ids.into_iter().collect();
        let pt_ids: Vec<u64> = pt_ids.into_iter().collect();
        let cameras: Vec<_> = cam_ids.iter().map(|&id| camera(id)).collect();
        let n_img = img_ids.len();
        let n_pt = pt_ids.len();
        let images = proptest::collection::vec(
            (
                0..cam_ids.len(),
                proptest::array::uniform4(-1.0..1.0f64),
                proptest::array::uniform3(num()),
                "[a-zA-Z0-9_/.-]{1,20}",
                proptest::collection::vec(
                    (num(), num(), proptest::option::of(0..n_pt.max(1))),
                    0..6,
                ),
            ),
            n_img,
        );
        let points = proptest::collection::vec(
            (
                proptest::array::uniform3(num()),
                proptest::array::uniform3(any::<u8>()),
                0.0..10.0f64,
                proptest::collection::vec((0..n_img, any::<u32>()), 0..5),
            ),
            n_pt,
        );
        (cameras, images, points).prop_filter_map(
            "non-zero quaternion",
            move |(cameras, images, points)| {
                let mut rec = Reconstruction::default();
                for c in cameras {
                    rec.cameras.insert(c.id, c);
                }
                for (k, (ci, q, t, name, kps)) in images.into_iter().enumerate() {
                    let n = q.iter().map(|x| x * x).sum::<f64>().sqrt();
                    if n < 1e-3 {
                        return None;
                    }
                    let im = Image {
                        id: ImageId(img_ids[k]),
                        name,
                        camera_id: CameraId(cam_ids[ci]),
                        // Unit quaternions, as the readers normalise.
                        qvec: q.map(|x| x / n),
                        tvec: t,
                        points2d: kps
                            .into_iter()
                            .map(|(x, y, p)| Point2D {
                                xy: [x, y],
                                point3d_id: p.filter(|_| n_pt > 0).map(|i| Point3DId(pt_ids[i])),
                            })
                            .collect(),
                    };
                    rec.images.insert(im.id, im);
                }
                let images: Vec<(ImageId, usize)> = rec
                    .images
                    .values()
                    .map(|im| (im.id, im.points2d.len()))
                    .collect();
                for (k, (xyz, rgb, error, track)) in points.into_iter().enumerate() {
                    let p = Point3D {
                        id: Point3DId(pt_ids[k]),
                        xyz: Vec3::from(xyz),
                        rgb,
                        error,
                        track: track
                            .into_iter()
                            .filter(|(i, _)| images[*i].1 > 0)
                            .map(|(i, idx)| TrackElement {
                                image_id: images[i].0,
                                point2d_idx: idx % images[i].1 as u32,
                            })
                            .collect(),
                    };
                    rec.points3d.insert(p.id, p);
                }
                // Normalising a unit quaternion again may move its last bit; keep models
                // whose quaternions are fixed points of the readers' normalisation.
                let stable = rec.images.values().all(|im| {
                    let n = im.qvec.iter().map(|x| x * x).sum::<f64>().sqrt();
                    im.qvec.map(|x| x / n) == im.qvec
                });
                stable.then_some(rec)
            },
        )
    })
}

fn scratch(tag: &str) -> std::path::PathBuf {
    std::env::temp_dir().join(format!("relight-colmap-rt-{}-{tag}", std::process::id()))
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 200, rng_seed: proptest::test_runner::RngSeed::Fixed(11), ..ProptestConfig::default() })]

    #[test]
    fn text_and_binary_round_trip(rec in model()) {
        let dir = scratch("prop");
        rec.write_text(&dir).unwrap();
        rec.write_binary(&dir).unwrap();
        let t = Reconstruction::read_text(&dir).unwrap();
        let b = Reconstruction::read_binary(&dir).unwrap();
        std::fs::remove_dir_all(&dir).ok();
        prop_assert_eq!(&t, &rec);
        prop_assert_eq!(&b, &rec);
        // -0.0 == 0.0 for PartialEq; the bits must survive too.
        let bits = |r: &Reconstruction| -> BTreeMap<u32, Vec<u64>> {
            r.images.values().map(|im| (im.id.0, im.tvec.iter().map(|x| x.to_bits()).collect())).collect()
        };
        prop_assert_eq!(bits(&t), bits(&rec));
        prop_assert_eq!(bits(&b), bits(&rec));
    }
}
