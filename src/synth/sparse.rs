//! `synth`'s sparse model, what COLMAP would give: one PINHOLE camera, the photos' poses,
//! and points sampled on the surface by area, each observed (with its exact projection) in
//! every photo that sees it unoccluded and front-facing, kept when seen at least twice.

use super::*;

/// The model and its number of 2D observations.
pub(super) struct Sparse {
    pub(super) rec: Reconstruction,
    pub(super) observations: usize,
}

/// The sparse model of `object` seen by `cams` (photos `photos`, whose bytes colour the
/// points).
pub(super) fn sparse_model(
    object: &Object,
    cams: &[PinholeCamera],
    photos: &Rendered,
    opts: &SynthOptions,
) -> Result<Sparse> {
    let mesh = &object.mesh;
    let cdf = area_cdf(mesh);
    let acc = cdf.last().copied().unwrap_or(0.0);
    let mut rec = posed_cameras(cams, &photos.names, opts);
    let centers: Vec<Vec3> = cams.iter().map(|c| c.center()).collect();
    let mut pts_rng = Pcg32::new(opts.seed ^ 0x706f_696e_7473_0000, 1);
    let mut observations = 0;
    let mut next_id = 1u64;
    if acc > 0.0 {
        for _ in 0..opts.points {
            let Some((x, ng)) = surface_point(&mut pts_rng, mesh, &cdf, acc) else {
                continue;
            };
            let obs = observers(&x, &ng, cams, &centers, &object.bvh, opts);
            if obs.len() < 2 {
                continue;
            }
            let id = Point3DId(next_id);
            next_id += 1;
            observations += obs.len();
            add_point(&mut rec, id, x, &obs, &photos.photos8, opts.width)?;
        }
    }
    Ok(Sparse { rec, observations })
}

/// The running sum of the faces' areas (the last entry is the total).
fn area_cdf(mesh: &Mesh) -> Vec<f64> {
    let areas: Vec<f64> = (0..mesh.faces.len())
        .map(|f| {
            let [a, b, c] = mesh.faces[f].map(|v| mesh.positions[v as usize]);
            (b - a).cross(&(c - a)).norm() / 2.0
        })
        .collect();
    let mut cdf = Vec::with_capacity(areas.len());
    let mut acc = 0.0;
    for a in &areas {
        acc += a;
        cdf.push(acc);
    }
    cdf
}

/// The model with its one camera and every photo's pose, no points yet.
fn posed_cameras(cams: &[PinholeCamera], names: &[String], opts: &SynthOptions) -> Reconstruction {
    let mut rec = Reconstruction::default();
    rec.cameras.insert(
        CameraId(1),
        Camera::pinhole(
            CameraId(1),
            opts.width,
            opts.height,
            cams[0].fx,
            cams[0].fy,
            cams[0].cx,
            cams[0].cy,
        ),
    );
    for (i, cam) in cams.iter().enumerate() {
        let rot = nalgebra::Rotation3::from_matrix(&cam.rotation);
        let im = Image::from_pose(
            ImageId(i as u32 + 1),
            names[i].clone(),
            CameraId(1),
            &rot,
            &cam.translation,
        );
        rec.images.insert(im.id, im);
    }
    rec
}

/// A point uniform over the surface (face by area from `cdf` of total `acc`, then uniform
/// in the face) and its face's unit normal; `None` on a degenerate face.
fn surface_point(rng: &mut Pcg32, mesh: &Mesh, cdf: &[f64], acc: f64) -> Option<(Vec3, Vec3)> {
    let r = rng.random::<f64>() * acc;
    let f = cdf.partition_point(|&c| c <= r).min(cdf.len() - 1);
    let (mut s, mut t) = (rng.random::<f64>(), rng.random::<f64>());
    if s + t > 1.0 {
        s = 1.0 - s;
        t = 1.0 - t;
    }
    let [a, b, c] = mesh.faces[f].map(|v| mesh.positions[v as usize]);
    let x = a + (b - a) * s + (c - a) * t;
    let ng = (b - a).cross(&(c - a));
    if ng.norm() == 0.0 {
        return None;
    }
    Some((x, ng.normalize()))
}

/// The photos that see `x` (normal `ng`) front-facing, inside the image and unoccluded,
/// with its pixel position in each.
fn observers(
    x: &Vec3,
    ng: &Vec3,
    cams: &[PinholeCamera],
    centers: &[Vec3],
    bvh: &SceneBvh,
    opts: &SynthOptions,
) -> Vec<(usize, [f64; 2])> {
    let mut obs = Vec::new();
    for (i, cam) in cams.iter().enumerate() {
        let to_c = centers[i] - x;
        let dist_c = to_c.norm();
        let dir = to_c / dist_c;
        if ng.dot(&dir) <= 0.05 {
            continue;
        }
        let Some((u, v)) = cam.project(x) else {
            continue;
        };
        if !(u >= 0.0 && v >= 0.0 && u < opts.width as f64 && v < opts.height as f64) {
            continue;
        }
        let off = bvh.ray_offset();
        if bvh.occluded(&(x + ng * off), &dir, 0.0, dist_c - 2.0 * off) {
            continue;
        }
        obs.push((i, [u, v]));
    }
    obs
}

/// Adds point `id` at `x` with its track (`obs`), coloured by the first photo that sees it.
fn add_point(
    rec: &mut Reconstruction,
    id: Point3DId,
    x: Vec3,
    obs: &[(usize, [f64; 2])],
    photos8: &[Vec<u8>],
    width: u32,
) -> Result<()> {
    let (i0, [u0, v0]) = obs[0];
    let pix = (v0 as usize) * width as usize + u0 as usize;
    let rgb = [
        photos8[i0][3 * pix],
        photos8[i0][3 * pix + 1],
        photos8[i0][3 * pix + 2],
    ];
    let mut track = Vec::with_capacity(obs.len());
    for &(i, xy) in obs {
        let im = rec
            .images
            .get_mut(&ImageId(i as u32 + 1))
            .ok_or_else(|| Error::Numeric {
                stage: "synth".into(),
                message: format!("image {i} missing"),
            })?;
        track.push(TrackElement {
            image_id: im.id,
            point2d_idx: im.points2d.len() as u32,
        });
        im.points2d.push(Point2D {
            xy,
            point3d_id: Some(id),
        });
    }
    rec.points3d.insert(
        id,
        Point3D {
            id,
            xyz: x,
            rgb,
            error: 0.0,
            track,
        },
    );
    Ok(())
}
