//! The two renderers agree (issue 4): `cargo bench --bench agreement` writes
//! `bench-results/agreement.json` and `.md`.
//!
//! Scene: unit icosphere (642 vertices) above a 6 × 6 ground plane (17² vertices), the
//! `sphere-plane` synth geometry (cast shadows), seen by 6 cameras; every (vertex, camera)
//! pair where the camera sees the vertex is one observation. Under each of the 8 embedded
//! real maps (256 × 128), for a diffuse and two glossy materials, two wavelet paths are
//! compared with the independent reference (`reference::quadrature_point`: Eq. 1 by
//! stratified quadrature over the lat-long texels, 3 × 3 jittered shadow rays per texel) at
//! the vertices; see `tests/agreement_support/mod.rs` for the error measure. The reference
//! is computed with two seeds: their difference measures its own error.
//!
//! 1. The wavelet RENDERER (`WaveletRenderer::vertex_radiance`, used by `render_wavelet`
//!    for held-out views and relighting): the light rotated into each vertex's local frame
//!    and the untruncated triple product with visibility and BRDF slice (Eq. 5–8). Per map ×
//!    material at the run's render defaults (64² global, 64² render local map, visibility
//!    64² × 1 ray, `SplatRotation` for the exact normal with 4 × 4 sub-texels), split by
//!    vertex class, and against resolution, visibility rays, sub-texels and the rotation
//!    (the estimator's blended factored rotation with 32² normals, as the renderer used
//!    before).
//! 2. The ESTIMATOR's system (`transport::build_rows`, rows truncated to `keep`
//!    coefficients, then `Transport::response`): error against resolution and kept
//!    coefficients, with the visibility the run gives it (64² × 1 ray averaged down to
//!    32², 4 rays per texel). Truncation concerns only the estimator, not the renderer.
//!
//! `AGREEMENT_QUICK=1` runs a smaller scene (for trying things out).

#[path = "../tests/agreement_support/mod.rs"]
mod support;

use relight_cpc::solve::adapt::downsample_visibility;
use relight_cpc::sphere::rotation::{Rotation, RotationForm, SplatRotation};
use relight_cpc::transport::visibility::{self, Visibility};
use relight_cpc::transport::TransportOptions;
use relight_cpc::Vec3;
use serde_json::{json, Value};
use std::path::Path;
use std::time::Instant;
use support::*;

/// The embedded maps (`tests/fixtures/synth/hdri/`), in their canonical order.
const MAPS: [&str; 8] = relight_cpc::synth::data::MAP_NAMES;

/// A vertex class: name and membership by position.
type Class = (&'static str, fn(&Vec3) -> bool);

/// Errors of every (map, material) for one wavelet result.
fn errors(w: &[Vec<[f64; 3]>], r: &[Vec<[f64; 3]>]) -> Vec<[f64; 3]> {
    w.iter()
        .zip(r)
        .map(|(w, r)| MATERIALS.map(|(_, beta)| rel_rmse(&blend(w, &beta), &blend(r, &beta))))
        .collect()
}

fn mean_max(e: &[[f64; 3]], m: usize) -> (f64, f64) {
    let v: Vec<f64> = e.iter().map(|x| x[m]).collect();
    (
        v.iter().sum::<f64>() / v.len() as f64,
        v.iter().cloned().fold(0.0, f64::max),
    )
}

fn main() {
    let quick = std::env::var("AGREEMENT_QUICK").is_ok();
    let (subdiv, cells, cams) = if quick { (2, 16, 6) } else { (3, 16, 6) };
    let setup = sphere_plane(subdiv, cells, cams);
    let nv = setup.mesh.positions.len();
    let n_obs = setup.obs_vertex.len();
    eprintln!("agreement: {nv} vertices, {n_obs} observations");
    let maps: Vec<_> = MAPS.iter().map(|m| load_map(m, 1)).collect();
    let sub = if quick { 2 } else { 3 };
    let threads = rayon::current_num_threads();

    let t0 = Instant::now();
    let r1 = reference(&setup, &maps, sub, 1);
    let ref_s = t0.elapsed().as_secs_f64();
    eprintln!("reference (seed 1): {ref_s:.1} s");
    let r2 = reference(&setup, &maps, sub, 2);
    // Noise of one reference: the two seeds' difference / √2.
    let ref_noise: Vec<[f64; 3]> = errors(&r2, &r1)
        .iter()
        .map(|e| e.map(|x| x / 2f64.sqrt()))
        .collect();

    // The renderer at the run's render defaults: 64² global, visibility traced at 64² with
    // 1 ray per texel, SplatRotation 64² → 64² with 4 × 4 sub-texels.
    let t0 = Instant::now();
    let vis64 = visibility::compute(&setup.mesh, &setup.bvh, &setup.env_from_world, 64, 1, 1);
    let vis64_s = t0.elapsed().as_secs_f64();
    let t0 = Instant::now();
    let splat = SplatRotation::with_default_supersample(64, 64);
    let ss = splat.supersample();
    let rot_s = t0.elapsed().as_secs_f64();
    let t0 = Instant::now();
    let w_def = renderer(&setup, &maps, &vis64, &splat);
    let ren_s = t0.elapsed().as_secs_f64();
    eprintln!("renderer defaults: {ren_s:.1} s");
    let e_def = errors(&w_def, &r1);
    // The estimator's visibility: the same trace averaged down to 32² (4 rays per texel).
    let vis32 = downsample_visibility(&vis64, 32);

    // Vertex classes: where the diffuse error lives.
    let classes: [Class; 4] = [
        ("sphere, upper half (y > 0: unshadowed)", |x: &Vec3| {
            x.y > 0.0
        }),
        (
            "sphere, lower half (facing the plane; contact below y < −0.8)",
            |x: &Vec3| x.y > -PLANE_DROP + 1e-6 && x.y <= 0.0,
        ),
        (
            "plane under the sphere (r < 1.5: shadow and contact)",
            |x: &Vec3| x.y <= -PLANE_DROP + 1e-6 && (x.x * x.x + x.z * x.z).sqrt() < 1.5,
        ),
        ("plane, r ≥ 1.5 (open or penumbra)", |x: &Vec3| {
            x.y <= -PLANE_DROP + 1e-6 && (x.x * x.x + x.z * x.z).sqrt() >= 1.5
        }),
    ];
    let masks: Vec<Vec<bool>> = classes
        .iter()
        .map(|(_, f)| {
            setup
                .obs_vertex
                .iter()
                .map(|&v| f(&setup.mesh.positions[v as usize]))
                .collect()
        })
        .collect();
    let part = |a: &[[f64; 3]], m: &[bool]| -> Vec<[f64; 3]> {
        a.iter()
            .zip(m)
            .filter(|(_, &k)| k)
            .map(|(x, _)| *x)
            .collect()
    };
    // Per map and class: (renderer, reference noise) diffuse error, each normalised by the
    // class's own mean reference radiance.
    let by_class: Vec<Vec<(f64, f64)>> = (0..MAPS.len())
        .map(|i| {
            let beta = MATERIALS[0].1;
            let w = blend(&w_def[i], &beta);
            let r = blend(&r1[i], &beta);
            let r2b = blend(&r2[i], &beta);
            masks
                .iter()
                .map(|m| {
                    (
                        rel_rmse(&part(&w, m), &part(&r, m)),
                        rel_rmse(&part(&r2b, m), &part(&r, m)) / 2f64.sqrt(),
                    )
                })
                .collect()
        })
        .collect();

    let mut md = String::from(
        "# Wavelet renderer against the reference (`cargo bench --bench agreement`)\n\n",
    );
    md.push_str(&format!(
        "Unit sphere above a ground plane (cast shadows), {nv} vertices, {n_obs} observations \
         ((vertex, camera) pairs with the vertex seen, {cams} cameras), compared at the vertices. \
         Error = RMSE / mean reference radiance over observations and RGB channels, linear \
         radiance, no clipping. Reference: Eq. 1 by stratified quadrature over the 256×128 \
         lat-long texels ({sub}×{sub} jittered shadow rays per texel), {ref_s:.1} s for 8 maps; \
         its own error (two seeds' difference / √2) is the `ref.` column. Threads: {threads}.\n\n\
         The wavelet RENDERER is `WaveletRenderer::vertex_radiance` (what `render_wavelet` \
         draws for held-out views and relighting): the light rotated into the vertex's local \
         frame, then the untruncated triple product with the visibility row and the BRDF slice \
         at the local resolution (Eq. 5–8). It does not truncate: `keep` is only the \
         estimator's transport-row budget (last table). Defaults (`run`'s renderer): \
         visibility 64², 1 ray/texel \
         ({vis64_s:.1} s), SplatRotation 64²→64², {ss}×{ss} sub-texels per global texel \
         ({rot_s:.2} s to set up), renderer {ren_s:.1} s for 8 maps × 3 lobes × {n_obs} \
         observations (one vertex_radiance call per observation and lobe).\n\n"
    ));
    md.push_str(
        "## The renderer per map, run defaults (64² global, 64² render local, SplatRotation)\n\n",
    );
    md.push_str("| map | material | rel. RMSE | ref. own error |\n|---|---|---|---|\n");
    let mut per_map = Vec::new();
    for (i, name) in MAPS.iter().enumerate() {
        for (m, (mname, _)) in MATERIALS.iter().enumerate() {
            md.push_str(&format!(
                "| {name} | {mname} | {:.2}% | {:.2}% |\n",
                100.0 * e_def[i][m],
                100.0 * ref_noise[i][m]
            ));
            per_map.push(
                json!({"map": name, "material": mname, "rel_rmse": e_def[i][m],
                "reference_error": ref_noise[i][m]}),
            );
        }
    }
    md.push('\n');
    md.push_str(
        "## Diffuse renderer error by vertex class (defaults)\n\nEach class normalised by its \
         own mean reference radiance (so a dark shadowed class shows a larger relative error \
         for the same absolute one); in brackets the reference's own error there.\n\n| map |",
    );
    for (c, m) in classes.iter().zip(&masks) {
        md.push_str(&format!(
            " {} ({} obs.) |",
            c.0,
            m.iter().filter(|&&k| k).count()
        ));
    }
    md.push_str("\n|---|---|---|---|---|\n");
    for (name, p) in MAPS.iter().zip(&by_class) {
        md.push_str(&format!("| {name} |"));
        for (e, n) in p {
            md.push_str(&format!(" {:.2}% ({:.2}%) |", 100.0 * e, 100.0 * n));
        }
        md.push('\n');
    }
    md.push('\n');

    // The renderer against resolution.
    md.push_str(
        "## The renderer against resolution\n\nMean / max over the 8 maps. `vis` = the local \
         grid visibility is traced at × rays per texel (averaged down when finer than the \
         local map); rotation `splat s` = `SplatRotation` (exact normal, s × s sub-texels per \
         global texel), `blended` = the estimator's factored rotation (Eq. 6 blend of 32² \
         precomputed frames, bilinear footprints; the renderer before). Times: visibility, \
         rotation build, renderer for 8 maps. First row: the renderer as it was (64² / 32², \
         blended); **bold**: the run's default.\n\n",
    );
    md.push_str("| global | local | vis | rotation | diffuse mean / max | glossy Phong mean / max | glossy GGX mean / max | vis s | rot s | render s |\n|---|---|---|---|---|---|---|---|---|---|\n");
    let mut rsweep = Vec::new();
    // (global, local, vis side, rays, splat sub-texels or 0 = blended factored).
    let rsettings: Vec<(usize, usize, usize, usize, usize)> = vec![
        (64, 32, 32, 2, 0),
        (64, 64, 64, 1, 0),
        (64, 32, 64, 1, 2),
        (64, 64, 64, 1, 2),
        (64, 64, 64, 1, ss),
        (64, 64, 64, 2, ss),
        (32, 64, 64, 1, SplatRotation::default_supersample(32, 64)),
    ];
    let mut traced: Vec<((usize, usize), Visibility, f64)> =
        vec![((64, 1), vis64.clone(), vis64_s)];
    for (ng, nl, nv_side, rays, sub) in rsettings {
        let ti = match traced.iter().position(|t| t.0 == (nv_side, rays)) {
            Some(i) => i,
            None => {
                let t0 = Instant::now();
                let v = visibility::compute(
                    &setup.mesh,
                    &setup.bvh,
                    &setup.env_from_world,
                    nv_side,
                    rays,
                    1,
                );
                traced.push(((nv_side, rays), v, t0.elapsed().as_secs_f64()));
                traced.len() - 1
            }
        };
        let vis_s = traced[ti].2;
        let vis = downsample_visibility(&traced[ti].1, nl);
        let is_default = (ng, nl, nv_side, rays, sub) == (64, 64, 64, 1, ss);
        let (w, rot_s_i, tr_s) = if is_default {
            (w_def.clone(), rot_s, ren_s)
        } else if sub > 0 {
            let t0 = Instant::now();
            let r = SplatRotation::new(ng, nl, sub);
            let rs = t0.elapsed().as_secs_f64();
            let t1 = Instant::now();
            let w = renderer(&setup, &maps, &vis, &r);
            (w, rs, t1.elapsed().as_secs_f64())
        } else {
            let t0 = Instant::now();
            let r = Rotation::new(ng, nl, 32, RotationForm::Factored);
            let rs = t0.elapsed().as_secs_f64();
            let t1 = Instant::now();
            let w = renderer(&setup, &maps, &vis, &r);
            (w, rs, t1.elapsed().as_secs_f64())
        };
        let e = errors(&w, &r1);
        let mm: Vec<(f64, f64)> = (0..3).map(|m| mean_max(&e, m)).collect();
        let rname = if sub > 0 {
            format!("splat {sub}")
        } else {
            "blended".to_string()
        };
        let b = if is_default { "**" } else { "" };
        md.push_str(&format!(
            "| {b}{ng}²{b} | {b}{nl}²{b} | {b}{nv_side}² × {rays}{b} | {b}{rname}{b} | {b}{:.2}% / {:.2}%{b} | {:.2}% / {:.2}% | {:.2}% / {:.2}% | {vis_s:.1} | {rot_s_i:.2} | {tr_s:.1} |\n",
            100.0 * mm[0].0, 100.0 * mm[0].1, 100.0 * mm[1].0, 100.0 * mm[1].1,
            100.0 * mm[2].0, 100.0 * mm[2].1,
        ));
        eprintln!(
            "renderer {ng} {nl} vis {nv_side}x{rays} {rname}: diffuse {:.4} / {:.4}",
            mm[0].0, mm[0].1
        );
        rsweep.push(json!({"n_global": ng, "n_local": nl, "visibility_side": nv_side,
            "rays_per_texel": rays, "rotation": rname, "default": is_default,
            "diffuse_per_map": MAPS.iter().zip(&e).map(|(m, x)| json!({"map": m, "diffuse": x[0]})).collect::<Vec<_>>(),
            "diffuse_mean": mm[0].0, "diffuse_max": mm[0].1,
            "phong_mean": mm[1].0, "phong_max": mm[1].1,
            "ggx_mean": mm[2].0, "ggx_max": mm[2].1,
            "visibility_s": vis_s, "rotation_s": rot_s_i, "render_s": tr_s}));
    }
    md.push('\n');

    // The estimator's truncated system.
    md.push_str(
        "## The estimator's transport rows against resolution and kept coefficients\n\n\
         `transport::build_rows` truncated to `keep` coefficients per row, then \
         `Transport::response`: the system the estimator solves, not what the renderer draws. \
         Mean / max over the 8 maps. Visibility as the run gives it: traced at 64² × 1 ray, \
         averaged down to the local grid (4 rays per 32² texel). Times: visibility, rotation \
         build, transport build + responses for 8 maps.\n\n",
    );
    md.push_str("| global | local | keep | diffuse mean / max | glossy Phong mean / max | glossy GGX mean / max | vis s | rot s | transport s |\n|---|---|---|---|---|---|---|---|---|\n");
    let mut sweep = Vec::new();
    let mut settings: Vec<(usize, usize, usize)> = vec![(32, 32, 128), (64, 16, 128)];
    for &k in &[32usize, 64, 128, 256, 0] {
        settings.push((64, 32, k));
    }
    let vis16 = downsample_visibility(&vis64, 16);
    let mut rots: Vec<((usize, usize), Rotation, f64)> = Vec::new();
    for (ng, nl, keep) in settings {
        let (vis, vis_s) = if nl == 16 {
            (&vis16, vis64_s)
        } else {
            (&vis32, vis64_s)
        };
        let ri = match rots.iter().position(|r| r.0 == (ng, nl)) {
            Some(i) => i,
            None => {
                let t0 = Instant::now();
                let r = Rotation::new(ng, nl, 32, RotationForm::Factored);
                rots.push(((ng, nl), r, t0.elapsed().as_secs_f64()));
                rots.len() - 1
            }
        };
        let opts = TransportOptions {
            n_global: ng,
            n_local: nl,
            keep,
        };
        let t0 = Instant::now();
        let w = wavelet(&setup, &maps, vis, &rots[ri].1, &opts);
        let tr_s = t0.elapsed().as_secs_f64();
        let e = errors(&w, &r1);
        let mm: Vec<(f64, f64)> = (0..3).map(|m| mean_max(&e, m)).collect();
        let keep_s = if keep == 0 {
            "all".to_string()
        } else {
            keep.to_string()
        };
        md.push_str(&format!(
            "| {ng}² | {nl}² | {keep_s} | {:.2}% / {:.2}% | {:.2}% / {:.2}% | {:.2}% / {:.2}% | {vis_s:.1} | {:.1} | {tr_s:.1} |\n",
            100.0 * mm[0].0,
            100.0 * mm[0].1,
            100.0 * mm[1].0,
            100.0 * mm[1].1,
            100.0 * mm[2].0,
            100.0 * mm[2].1,
            rots[ri].2
        ));
        eprintln!(
            "rows {ng} {nl} {keep_s}: diffuse {:.4} / {:.4}",
            mm[0].0, mm[0].1
        );
        sweep.push(json!({"n_global": ng, "n_local": nl, "keep": keep,
            "diffuse_mean": mm[0].0, "diffuse_max": mm[0].1,
            "phong_mean": mm[1].0, "phong_max": mm[1].1,
            "ggx_mean": mm[2].0, "ggx_max": mm[2].1,
            "visibility_s": vis_s, "rotation_s": rots[ri].2, "transport_s": tr_s}));
    }
    md.push('\n');

    let out = Path::new(env!("CARGO_MANIFEST_DIR")).join("bench-results");
    std::fs::create_dir_all(&out).expect("bench-results");
    let suffix = if quick { "-quick" } else { "" };
    let json: Value = json!({
        "vertices": nv, "observations": n_obs, "cameras": cams,
        "reference": {"strata_per_texel": sub * sub, "seconds": ref_s},
        "renderer_default": {"n_global": 64, "n_local": 64, "visibility_side": 64,
            "rays_per_texel": 1, "supersample": ss,
            "visibility_s": vis64_s, "rotation_s": rot_s, "render_s": ren_s,
            "per_map": per_map},
        "renderer_diffuse_by_class": MAPS.iter().zip(&by_class).map(|(m, p)| json!({"map": m,
            "classes": classes.iter().zip(p).map(|(c, (e, n))| json!({"class": c.0,
                "rel_rmse": e, "reference_error": n})).collect::<Vec<_>>()})).collect::<Vec<_>>(),
        "renderer_sweep": rsweep,
        "estimator_rows_sweep": sweep,
        "threads": threads,
    });
    std::fs::write(
        out.join(format!("agreement{suffix}.json")),
        serde_json::to_string_pretty(&json).expect("json") + "\n",
    )
    .expect("write json");
    std::fs::write(out.join(format!("agreement{suffix}.md")), &md).expect("write md");
    print!("{md}");
}
