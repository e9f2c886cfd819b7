//! Shared by `tests/suite/transport_agreement.rs` and `benches/agreement.rs`: the wavelet path
//! (visibility → transport rows → response, paper Eq. 5–8) against the independent
//! reference (`reference::quadrature_point`, Eq. 1 by stratified quadrature over the
//! lat-long texels with shadow rays) on a unit sphere above a ground plane (the
//! `sphere-plane` synth geometry: cast shadows) under real maps.
//!
//! Both are compared AT THE VERTICES, for every (vertex, camera) pair where the camera sees
//! the vertex (front-facing with `n·ω_o > 0.2`, unoccluded): the wavelet path computes
//! per-vertex radiance and an image only interpolates it, so comparing vertices measures
//! the method, not the mesh's tessellation of the shading. Radiance is linear, unclipped,
//! in the map's units, so no exposure enters.
//!
//! Error measure: relative RMSE = `sqrt(mean_{p,c} (w − r)²) / mean_{p,c} r` over the
//! observations `p` and colour channels `c` (normalised by the MEAN reference radiance,
//! which is stricter than normalising by its RMS).

#![allow(dead_code)]

use nalgebra::Matrix3;
use rand_pcg::Pcg32;
use rayon::prelude::*;
use relight_cpc::import::mesh::Mesh;
use relight_cpc::observe::trace::SceneBvh;
use relight_cpc::render::wavelet::WaveletRenderer;
use relight_cpc::sphere::envmap::{LatLong, OctEnv};
use relight_cpc::sphere::rotation::LocalRotation;
use relight_cpc::synth::geometry;
use relight_cpc::transport::brdf::BasisBrdf;
use relight_cpc::transport::reference::{quadrature_point, Environment, Lobe};
use relight_cpc::transport::visibility::Visibility;
use relight_cpc::transport::{build_rows, light_haar, TransportOptions};
use relight_cpc::Vec3;
use std::path::Path;

/// Height of the ground plane below the sphere's centre (as in the `sphere-plane` scene).
pub const PLANE_DROP: f64 = 1.02;

/// The lobes, in the same order for both renderers.
pub fn lobes() -> (Vec<BasisBrdf>, Vec<Lobe>) {
    (
        vec![
            BasisBrdf::Lambert,
            BasisBrdf::Phong { exponent: 50.0 },
            BasisBrdf::Ggx { alpha: 0.3 },
        ],
        vec![
            Lobe::Lambert,
            Lobe::Phong { exponent: 50.0 },
            Lobe::Ggx { alpha: 0.3 },
        ],
    )
}

/// Materials as colourless weights of the lobes above: name and β per lobe.
pub const MATERIALS: [(&str, [f64; 3]); 3] = [
    ("diffuse (Lambert)", [1.0, 0.0, 0.0]),
    ("glossy (½ Lambert + ½ Phong 50)", [0.5, 0.5, 0.0]),
    ("glossy (½ Lambert + ½ GGX 0.3)", [0.5, 0.0, 0.5]),
];

/// The scene: mesh, BVH, environment frame (up = +y) and the observations.
pub struct Setup {
    pub mesh: Mesh,
    pub bvh: SceneBvh,
    pub env_from_world: Matrix3<f64>,
    pub frame: [Vec3; 3],
    pub normals_env: Vec<Vec3>,
    /// Observation `p`: vertex and unit world direction vertex → camera.
    pub obs_vertex: Vec<u32>,
    pub obs_dir: Vec<Vec3>,
}

/// Unit icosphere (`subdiv` midpoint splits) above a 6 × 6 plane of `cells²` quads, seen by
/// `n_cams` cameras 6.5 units from (0, −0.4, 0), evenly spread in azimuth, alternating
/// between 25° and 50° elevation.
pub fn sphere_plane(subdiv: u32, cells: u32, n_cams: usize) -> Setup {
    let (mut pos, mut faces) = geometry::icosphere(subdiv);
    let (pp, pf) = geometry::plane(&Vec3::new(0.0, -PLANE_DROP, 0.0), &Vec3::y(), 6.0, cells);
    geometry::append(&mut pos, &mut faces, &pp, &pf);
    let (mesh, _) = Mesh::from_parts(pos, faces);
    let bvh = SceneBvh::new(&mesh);
    let frame = relight_cpc::sphere::env_frame(&Vec3::y()).expect("frame");
    let env_from_world = Matrix3::from_rows(&[
        frame[0].transpose(),
        frame[1].transpose(),
        frame[2].transpose(),
    ]);
    let normals_env = mesh.normals.iter().map(|n| env_from_world * n).collect();
    let target = Vec3::new(0.0, -0.4, 0.0);
    let cams: Vec<Vec3> = (0..n_cams)
        .map(|i| {
            let az = 2.0 * std::f64::consts::PI * (i as f64 + 0.25) / n_cams as f64;
            let el: f64 = if i % 2 == 0 { 25.0 } else { 50.0 };
            let el = el.to_radians();
            target + Vec3::new(el.cos() * az.cos(), el.sin(), el.cos() * az.sin()) * 6.5
        })
        .collect();
    let eps = bvh.ray_offset();
    let mut obs_vertex = Vec::new();
    let mut obs_dir = Vec::new();
    for (v, (x, n)) in mesh.positions.iter().zip(&mesh.normals).enumerate() {
        for c in &cams {
            let d = c - x;
            let dist = d.norm();
            let d = d / dist;
            if n.dot(&d) > 0.2 && !bvh.occluded(&(x + n * eps), &d, eps, dist) {
                obs_vertex.push(v as u32);
                obs_dir.push(d);
            }
        }
    }
    Setup {
        mesh,
        bvh,
        env_from_world,
        frame,
        normals_env,
        obs_vertex,
        obs_dir,
    }
}

/// One of the embedded synth maps (`tests/fixtures/synth/hdri/NAME.exr`, 256 × 128),
/// area-downsampled by `factor` (1 = as stored).
pub fn load_map(name: &str, factor: usize) -> LatLong {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let (ll, _) = LatLong::read_exr(&root.join(format!("tests/fixtures/synth/hdri/{name}.exr")))
        .expect("embedded map");
    if factor > 1 {
        ll.downsample(factor).expect("downsample")
    } else {
        ll
    }
}

/// Per map, per observation, per lobe: the reference radiance (RGB), by
/// [`quadrature_point`] with `sub²` strata per lat-long texel; vertex `v` uses random stream
/// `(seed, v)`.
pub fn reference(setup: &Setup, maps: &[LatLong], sub: usize, seed: u64) -> Vec<Vec<[f64; 3]>> {
    let (_, lobes) = lobes();
    let nb = lobes.len();
    let envs: Vec<Environment> = maps
        .iter()
        .map(|m| Environment::new(m.width, m.height, &m.rgb, setup.frame).expect("env"))
        .collect();
    let env_refs: Vec<&Environment> = envs.iter().collect();
    // Observations grouped by vertex (they are pushed vertex by vertex).
    let mut groups: Vec<(u32, std::ops::Range<usize>)> = Vec::new();
    for (p, &v) in setup.obs_vertex.iter().enumerate() {
        match groups.last_mut() {
            Some((g, r)) if *g == v => r.end = p + 1,
            _ => groups.push((v, p..p + 1)),
        }
    }
    let offset = setup.bvh.ray_offset();
    let per_group: Vec<Vec<[f64; 3]>> = groups
        .par_iter()
        .map(|(v, r)| {
            let v = *v as usize;
            let n = setup.mesh.normals[v];
            let mut rng = Pcg32::new(seed, v as u64);
            quadrature_point(
                &setup.mesh.positions[v],
                &n,
                &n,
                offset,
                &setup.bvh,
                &setup.obs_dir[r.clone()],
                &lobes,
                &env_refs,
                sub,
                &mut rng,
            )
            .expect("quadrature")
        })
        .collect();
    let n_obs = setup.obs_vertex.len();
    let mut out = vec![vec![[0.0; 3]; n_obs * nb]; maps.len()];
    for ((_, r), vals) in groups.iter().zip(&per_group) {
        let nw = r.len();
        for (e, dst) in out.iter_mut().enumerate() {
            for (o, p) in r.clone().enumerate() {
                for b in 0..nb {
                    dst[p * nb + b] = vals[(e * nw + o) * nb + b];
                }
            }
        }
    }
    out
}

/// Per map, per observation, per lobe: the wavelet path's radiance (RGB), the response of
/// the transport rows (truncated to `opts.keep`) to each channel's Haar light.
pub fn wavelet<R: LocalRotation>(
    setup: &Setup,
    maps: &[LatLong],
    vis: &Visibility,
    rot: &R,
    opts: &TransportOptions,
) -> Vec<Vec<[f64; 3]>> {
    let (basis, _) = lobes();
    let nb = basis.len();
    let dirs: Vec<Vec3> = setup
        .obs_dir
        .iter()
        .map(|d| setup.env_from_world * d)
        .collect();
    let t = build_rows(
        &setup.normals_env,
        &setup.obs_vertex,
        &dirs,
        vis,
        &basis,
        rot,
        opts,
    )
    .expect("transport");
    maps.iter()
        .map(|m| {
            let light = light_haar(&OctEnv::from_latlong(m, opts.n_global));
            (0..t.n_obs * nb)
                .into_par_iter()
                .map(|i| {
                    let (p, b) = (i / nb, i % nb);
                    [0, 1, 2].map(|c| t.response(p, b, &light[c]))
                })
                .collect()
        })
        .collect()
}

/// Per map, per observation, per lobe: the wavelet RENDERER's radiance (RGB),
/// [`WaveletRenderer::vertex_radiance`] (the light rotated into the local frame, triple
/// product with the visibility row and the BRDF slice at the local resolution, untruncated;
/// what `render_wavelet` shows for held-out views and relighting), one lobe at a time.
pub fn renderer<R: LocalRotation + Sync>(
    setup: &Setup,
    maps: &[LatLong],
    vis: &Visibility,
    rot: &R,
) -> Vec<Vec<[f64; 3]>> {
    let (basis, _) = lobes();
    let nb = basis.len();
    maps.iter()
        .map(|m| {
            let env = OctEnv::from_latlong(m, rot.n_global());
            let r = WaveletRenderer::new(rot, &basis, &env).expect("renderer");
            let per_obs: Vec<Vec<[f64; 3]>> = (0..setup.obs_vertex.len())
                .into_par_iter()
                .map(|p| {
                    let v = setup.obs_vertex[p] as usize;
                    let wo = setup.env_from_world * setup.obs_dir[p];
                    (0..nb)
                        .map(|b| {
                            let beta: Vec<[f64; 3]> = (0..nb)
                                .map(|k| if k == b { [1.0; 3] } else { [0.0; 3] })
                                .collect();
                            r.vertex_radiance(&setup.normals_env[v], vis.vertex(v), &wo, &beta)
                        })
                        .collect()
                })
                .collect();
            per_obs.into_iter().flatten().collect()
        })
        .collect()
}

/// Blend per-lobe values (`n_obs × n_lobes`) with colourless weights `beta`.
pub fn blend(per_lobe: &[[f64; 3]], beta: &[f64; 3]) -> Vec<[f64; 3]> {
    per_lobe
        .chunks(beta.len())
        .map(|l| {
            let mut o = [0.0; 3];
            for (x, w) in l.iter().zip(beta) {
                for c in 0..3 {
                    o[c] += w * x[c];
                }
            }
            o
        })
        .collect()
}

/// `sqrt(mean (a − b)²) / mean b` over entries and channels.
pub fn rel_rmse(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    let n = (a.len() * 3) as f64;
    let se: f64 = a
        .iter()
        .zip(b)
        .flat_map(|(x, y)| (0..3).map(move |c| (x[c] - y[c]).powi(2)))
        .sum();
    let mean: f64 = b.iter().flatten().sum::<f64>() / n;
    (se / n).sqrt() / mean
}
