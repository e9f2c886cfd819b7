//! The two renderers agree (issue 4): `cargo bench --bench agreement` writes
//! `bench-results/agreement.json` and `.md`.
//!
//! Scene: unit icosphere (642 vertices) above a 6 × 6 ground plane (33² vertices), the
//! `sphere-plane` synth geometry (cast shadows), seen by 8 cameras; every (vertex, camera)
//! pair where the camera sees the vertex is one observation. Under each of the 8 embedded
//! real maps (256 × 128), for a diffuse and two glossy materials, the wavelet path
//! (visibility → transport rows truncated to `keep` → response, Eq. 5–8) is compared with
//! the independent reference (`reference::quadrature_point`: Eq. 1 by stratified quadrature
//! over the lat-long texels, 3 × 3 jittered shadow rays per texel) at the vertices; see
//! `tests/agreement_support/mod.rs` for the error measure. The reference is computed with
//! two seeds: their difference measures its own error.
//!
//! Tables: per map × material at the default resolutions (64² global, 32² local, keep 128,
//! 32² rotation normals, 2 visibility rays per texel), and the error against the global /
//! local resolution and the number of kept coefficients, with timings.
//! `AGREEMENT_QUICK=1` runs a smaller scene and fewer settings (for trying things out).

#[path = "../tests/agreement_support/mod.rs"]
mod support;

use relight_cpc::rotation::{Rotation, RotationForm};
use relight_cpc::transport::TransportOptions;
use relight_cpc::visibility;
use serde_json::{json, Value};
use std::path::Path;
use std::time::Instant;
use support::*;

const MAPS: [&str; 8] = [
    "city",
    "courtyard",
    "forest",
    "interior",
    "night",
    "studio",
    "sunrise",
    "sunset",
];

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
    let (subdiv, cells, cams) = if quick { (2, 16, 6) } else { (3, 32, 8) };
    let setup = sphere_plane(subdiv, cells, cams);
    let nv = setup.mesh.positions.len();
    let n_obs = setup.obs_vertex.len();
    eprintln!("agreement: {nv} vertices, {n_obs} observations");
    let maps: Vec<_> = MAPS.iter().map(|m| load_map(m, 1)).collect();
    let sub = if quick { 2 } else { 3 };

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

    // Default resolution.
    let defaults = TransportOptions::default();
    let t0 = Instant::now();
    let vis32 = visibility::compute(&setup.mesh, &setup.bvh, &setup.env_from_world, 32, 2, 1);
    let vis32_s = t0.elapsed().as_secs_f64();
    let t0 = Instant::now();
    let rot = Rotation::new(64, 32, 32, RotationForm::Factored);
    let rot_s = t0.elapsed().as_secs_f64();
    let t0 = Instant::now();
    let w_def = wavelet(&setup, &maps, &vis32, &rot, &defaults);
    let wav_s = t0.elapsed().as_secs_f64();
    let w_all = wavelet(
        &setup,
        &maps,
        &vis32,
        &rot,
        &TransportOptions {
            keep: 0,
            ..defaults
        },
    );
    let e_def = errors(&w_def, &r1);
    // Where the untruncated diffuse error is: sphere vs plane vertices, provably open vs
    // traced (occluded) ones.
    let on_sphere: Vec<bool> = setup
        .obs_vertex
        .iter()
        .map(|&v| setup.mesh.positions[v as usize].y > -PLANE_DROP + 1e-6)
        .collect();
    let open: Vec<bool> = setup
        .obs_vertex
        .iter()
        .map(|&v| vis32.open[v as usize])
        .collect();
    let part = |a: &[[f64; 3]], m: &[bool], want: bool| -> Vec<[f64; 3]> {
        a.iter()
            .zip(m)
            .filter(|(_, &k)| k == want)
            .map(|(x, _)| *x)
            .collect()
    };
    let parts: Vec<[f64; 4]> = (0..MAPS.len())
        .map(|i| {
            let beta = MATERIALS[0].1;
            let w = blend(&w_all[i], &beta);
            let r = blend(&r1[i], &beta);
            [
                rel_rmse(&part(&w, &on_sphere, true), &part(&r, &on_sphere, true)),
                rel_rmse(&part(&w, &on_sphere, false), &part(&r, &on_sphere, false)),
                rel_rmse(&part(&w, &open, true), &part(&r, &open, true)),
                rel_rmse(&part(&w, &open, false), &part(&r, &open, false)),
            ]
        })
        .collect();
    let e_all = errors(&w_all, &r1);

    let mut md = String::from(
        "# Wavelet renderer against the reference (`cargo bench --bench agreement`)\n\n",
    );
    md.push_str(&format!(
        "Unit sphere above a ground plane (cast shadows), {nv} vertices, {n_obs} observations \
         ((vertex, camera) pairs with the vertex seen, {cams} cameras), compared at the vertices. \
         Error = RMSE / mean reference radiance over observations and RGB channels, linear \
         radiance, no clipping. Reference: Eq. 1 by stratified quadrature over the 256×128 \
         lat-long texels ({sub}×{sub} jittered shadow rays per texel), {ref_s:.1} s for 8 maps; \
         its own error (two seeds' difference / √2) is the `ref.` column. Wavelet: visibility \
         32², 2 rays/texel ({vis32_s:.1} s), rotation 64²→32² with 32² normals ({rot_s:.1} s), \
         transport rows for 3 lobes and response for 8 maps {wav_s:.1} s. Threads: {}.\n\n",
        rayon::current_num_threads()
    ));
    md.push_str("## Per map, default resolutions (64² global, 32² local, keep 128)\n\n");
    md.push_str("| map | material | rel. RMSE keep 128 | rel. RMSE keep all | ref. own error |\n|---|---|---|---|---|\n");
    let mut per_map = Vec::new();
    for (i, name) in MAPS.iter().enumerate() {
        for (m, (mname, _)) in MATERIALS.iter().enumerate() {
            md.push_str(&format!(
                "| {name} | {mname} | {:.2}% | {:.2}% | {:.2}% |\n",
                100.0 * e_def[i][m],
                100.0 * e_all[i][m],
                100.0 * ref_noise[i][m]
            ));
            per_map.push(
                json!({"map": name, "material": mname, "rel_rmse_keep128": e_def[i][m],
                "rel_rmse_keep_all": e_all[i][m], "reference_error": ref_noise[i][m]}),
            );
        }
    }
    md.push('\n');
    md.push_str(&format!(
        "## Diffuse, keep all: where the error is\n\n{} of {n_obs} observations are on the sphere, \
         {} on provably open vertices (the upper cap: no rays traced).\n\n\
         | map | sphere | plane | open | traced |\n|---|---|---|---|---|\n",
        on_sphere.iter().filter(|&&x| x).count(),
        open.iter().filter(|&&x| x).count()
    ));
    for (name, p) in MAPS.iter().zip(&parts) {
        md.push_str(&format!(
            "| {name} | {:.2}% | {:.2}% | {:.2}% | {:.2}% |\n",
            100.0 * p[0],
            100.0 * p[1],
            100.0 * p[2],
            100.0 * p[3]
        ));
    }
    md.push('\n');

    // Resolution and truncation.
    md.push_str("## Against resolution and kept coefficients\n\nMean / max over the 8 maps. Times: visibility (per local resolution), rotation build, transport build + responses for 8 maps.\n\n");
    md.push_str("| global | local | keep | diffuse mean / max | glossy Phong mean / max | glossy GGX mean / max | vis s | rot s | transport s |\n|---|---|---|---|---|---|---|---|---|\n");
    let mut sweep = Vec::new();
    let mut settings: Vec<(usize, usize, usize)> = Vec::new();
    let globals: &[usize] = if quick { &[32, 64] } else { &[16, 32, 64] };
    for &nl in &[16usize, 32] {
        for &ng in globals {
            settings.push((ng, nl, 128));
        }
    }
    for &k in &[32usize, 64, 256, 0] {
        settings.push((64, 32, k));
    }
    let t0 = Instant::now();
    let vis16 = visibility::compute(&setup.mesh, &setup.bvh, &setup.env_from_world, 16, 2, 1);
    let vis16_s = t0.elapsed().as_secs_f64();
    let mut rots: Vec<((usize, usize), Rotation, f64)> = Vec::new();
    for (ng, nl, keep) in settings {
        let (vis, vis_s) = if nl == 16 {
            (&vis16, vis16_s)
        } else {
            (&vis32, vis32_s)
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
            "{ng} {nl} {keep_s}: diffuse {:.4} / {:.4}",
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
        "default": {"visibility_s": vis32_s, "rotation_s": rot_s, "wavelet_s": wav_s},
        "per_map": per_map, "sweep": sweep,
        "diffuse_keep_all_by_part": MAPS.iter().zip(&parts).map(|(m, p)| json!({"map": m,
            "sphere": p[0], "plane": p[1], "open": p[2], "traced": p[3]})).collect::<Vec<_>>(),
        "threads": rayon::current_num_threads(),
    });
    std::fs::write(
        out.join(format!("agreement{suffix}.json")),
        serde_json::to_string_pretty(&json).expect("json") + "\n",
    )
    .expect("write json");
    std::fs::write(out.join(format!("agreement{suffix}.md")), &md).expect("write md");
    print!("{md}");
}
