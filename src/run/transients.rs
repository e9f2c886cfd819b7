//! Transient occluders in the training photos (issue 28): a short pilot fit, the
//! spatially coherent outlier mask of its residuals ([`crate::observe::outliers`]), and
//! the masked observations given `α = 0` before the estimate proper.
//!
//! The pilot is the estimate itself (same light model, materials start and options, but
//! Tukey's redescending weights in its lighting steps, so that an occluder does not tint
//! its photo's map) stopped after [`PILOT_ITERATIONS`] outer iterations: the mask needs
//! residuals against light and reflectance, not against the photos' consensus (the
//! per-vertex median across photos would call every shadow and highlight an outlier).
//! [`PILOT_ROUNDS`] rounds: each fits the observations the previous round left unmasked
//! and scores all of them again, so a map the occluder bent in the first round no longer
//! marks its photo's clean pixels.
//!
//! Each training photo's mask is written as an 8-bit PNG in the photo's pixel frame,
//! `outliers/STEM.png`: 255 where the rasterised mesh's interpolated mask is `≥ 1/2`
//! (the visible triangle's vertices masked in that photo, by barycentric weight), 0
//! elsewhere.

use std::path::Path;

use crate::import::mesh::Mesh;
use crate::import::scene::Scene;
use crate::observe::outliers::{
    coherent_mask, excess_over_vertex_median, scores, Adjacency, OutlierOptions,
};
use crate::observe::raster::Raster;
use crate::observe::Observations;
use crate::solve::{self, EstimateOptions, Materials0, Problem};
use crate::transport::Transport;
use crate::{Error, Result};

/// Outer iterations of the pilot fit. Its lights and materials only need to explain the
/// photos well enough that an occluder stands out: measured in
/// `bench-results/realphoto.md`.
pub const PILOT_ITERATIONS: usize = 2;

/// Rounds of pilot fit and mask (module docs).
pub const PILOT_ROUNDS: usize = 2;

/// What the transient pass masked.
#[derive(Debug, Clone, Default)]
pub(crate) struct Transients {
    /// Per training photo (training order), the vertices whose observation was masked.
    pub masked: Vec<Vec<u32>>,
    /// Observations with `α > 0` before the mask.
    pub used_before: usize,
}

impl Transients {
    /// Masked observations in all.
    pub(crate) fn count(&self) -> usize {
        self.masked.iter().map(Vec::len).sum()
    }
}

/// Runs the pilot, masks `obs` in place (`α = 0`) and says what it masked.
pub(crate) fn mask_transients(
    obs: &mut Observations,
    transport: &Transport,
    mesh: &Mesh,
    init: &Materials0,
    opts: &EstimateOptions,
) -> Result<Transients> {
    let nv = mesh.positions.len();
    let adj = Adjacency::from_faces(&mesh.faces, nv);
    let o = OutlierOptions::with_floor(opts.robust_floor);
    let pilot = EstimateOptions {
        max_outer: PILOT_ITERATIONS,
        validation_fraction: 0.0,
        robust: solve::Robust::Tukey { c: 4.685 },
        ..opts.clone()
    };
    let raw = obs.weight.clone();
    let mut mask = vec![false; obs.len()];
    for _ in 0..PILOT_ROUNDS {
        for ((w, &r), &m) in obs.weight.iter_mut().zip(&raw).zip(&mask) {
            *w = if m { 0.0 } else { r };
        }
        let pred = {
            let problem = Problem {
                obs,
                transport,
                n_vertices: nv,
                n_photos: obs.photo_ranges.len(),
            };
            let est = solve::estimate(&problem, init.clone(), &pilot, &mut |_, _| {})?;
            solve::predict(&problem, &est)
        };
        obs.weight.copy_from_slice(&raw);
        let s = scores(obs, &pred, o.floor);
        let e = excess_over_vertex_median(obs, &s, nv);
        mask = coherent_mask(obs, &e, &adj, &o);
    }
    let used_before = obs.weight.iter().filter(|&&w| w > 0.0).count();
    let mut masked = vec![Vec::new(); obs.photo_ranges.len()];
    for (k, r) in obs.photo_ranges.iter().enumerate() {
        for p in r.clone() {
            if mask[p] {
                obs.weight[p] = 0.0;
                if let Some(b) = obs.bound_weight.get_mut(p) {
                    *b = 0.0;
                }
                masked[k].push(obs.vertex[p]);
            }
        }
    }
    Ok(Transients {
        masked,
        used_before,
    })
}

/// Pixels whose interpolated vertex mask is `≥ 1/2` (module docs).
pub fn pixel_mask(raster: &Raster, faces: &[[u32; 3]], vertex_masked: &[bool]) -> Vec<bool> {
    raster
        .face
        .iter()
        .zip(&raster.bary)
        .map(|(&f, b)| {
            let Some(tri) = faces.get(f as usize) else {
                return false;
            };
            let m: f32 = (0..3)
                .map(|k| {
                    if vertex_masked.get(tri[k] as usize) == Some(&true) {
                        b[k]
                    } else {
                        0.0
                    }
                })
                .sum();
            m >= 0.5
        })
        .collect()
}

/// Writes `outliers/STEM.png` for every training photo (module docs); the folder's path
/// relative to `dir`.
pub(crate) fn write_masks(
    t: &Transients,
    scene: &Scene,
    train: &[usize],
    dir: &Path,
) -> Result<&'static str> {
    let folder = "outliers";
    let out = dir.join(folder);
    std::fs::create_dir_all(&out).map_err(|e| Error::io(&out, e))?;
    let nv = scene.mesh.positions.len();
    for (k, &v) in train.iter().enumerate() {
        let view = &scene.views[v];
        let mut flagged = vec![false; nv];
        for &x in t.masked.get(k).map_or(&[][..], Vec::as_slice) {
            flagged[x as usize] = true;
        }
        let raster = crate::observe::raster::rasterize(&scene.mesh, &view.camera, &view.image);
        let pix = pixel_mask(&raster, &scene.mesh.faces, &flagged);
        let bytes: Vec<u8> = pix.iter().map(|&m| if m { 255 } else { 0 }).collect();
        let img = image::GrayImage::from_raw(raster.width, raster.height, bytes)
            .ok_or_else(|| Error::Internal("outlier mask: raster size mismatch".into()))?;
        let mut png = Vec::new();
        img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
            .map_err(|e| Error::Internal(format!("outlier mask PNG: {e}")))?;
        let stem = crate::render::views::file_stem(&view.image.name);
        crate::out_dir::write_atomic(&out.join(format!("{stem}.png")), &png)?;
    }
    Ok(folder)
}
