//! Cost and error of the light-transport precomputation (issue 4):
//! `cargo bench --bench transport` writes `bench-results/transport.json` and `.md`.
//!
//! - Slices (32² local map): time per on-demand adaptive slice and per lookup in a 32² table
//!   over `ω_o` (bilinear), and the table's error against the on-demand slice (relative L2
//!   over the texels, and of the albedo) at random `ω_o` — the measurement behind
//!   `transport`'s choice of tabulating broad lobes and computing sharp ones on demand.
//! - Transport build (64² global, 32² local, 32² normals, factored rotation, default
//!   basis): time per observation, bytes per observation, and the response error against
//!   the untruncated rows under the real city map (sun kept) for several `keep`.

use nalgebra::Matrix3;
use rand::SeedableRng;
use rand_pcg::Pcg64;
use relight_cpc::sphere::envmap::{LatLong, OctEnv};
use relight_cpc::sphere::rotation::{Rotation, RotationForm};
use relight_cpc::transport::brdf::{default_basis, BasisBrdf, SliceGrid, SliceTable};
use relight_cpc::transport::visibility::Visibility;
use relight_cpc::transport::{build_rows, light_haar, TransportOptions};
use relight_cpc::Vec3;
use serde_json::{json, Value};
use std::path::Path;
use std::time::Instant;

#[path = "../tests/support/random.rs"]
mod random;
use random::random_unit;

fn random_wo(rng: &mut Pcg64) -> Vec3 {
    loop {
        let d = random_unit(rng);
        if d.z > 0.1 {
            return d;
        }
    }
}

fn slices(md: &mut String) -> Value {
    let grid = SliceGrid::new(32).expect("grid");
    let mut rng = Pcg64::seed_from_u64(1);
    let wos: Vec<Vec3> = (0..200).map(|_| random_wo(&mut rng)).collect();
    let mut out = vec![0.0; 1024];
    let mut tab = vec![0.0; 1024];
    let mut rows = Vec::new();
    md.push_str("## Slices (32² local map)\n\n| lobe | on-demand µs | table build s | table MB | lookup µs | table rel. L2 err (median / max) | albedo err (max) |\n|---|---|---|---|---|---|---|\n");
    for b in default_basis()
        .into_iter()
        .chain([BasisBrdf::Ggx { alpha: 0.05 }])
    {
        let t0 = Instant::now();
        for wo in &wos {
            b.slice_with(&grid, wo, &mut out);
        }
        let direct_us = t0.elapsed().as_secs_f64() * 1e6 / wos.len() as f64;
        let t0 = Instant::now();
        let table = SliceTable::new(&b, &grid, 32).expect("table");
        let build_s = t0.elapsed().as_secs_f64();
        let t0 = Instant::now();
        for wo in &wos {
            table.lookup(wo, &mut tab);
        }
        let lookup_us = t0.elapsed().as_secs_f64() * 1e6 / wos.len() as f64;
        let mut errs = Vec::new();
        let mut alb_err: f64 = 0.0;
        for wo in &wos {
            b.slice_with(&grid, wo, &mut out);
            table.lookup(wo, &mut tab);
            let num: f64 = out.iter().zip(&tab).map(|(a, b)| (a - b).powi(2)).sum();
            let den: f64 = out.iter().map(|a| a * a).sum();
            errs.push((num / den.max(1e-300)).sqrt());
            let a1: f64 = out.iter().zip(&grid.solid_angle).map(|(v, w)| v * w).sum();
            let a2: f64 = tab.iter().zip(&grid.solid_angle).map(|(v, w)| v * w).sum();
            alb_err = alb_err.max((a1 - a2).abs() / a1.max(1e-12));
        }
        errs.sort_by(f64::total_cmp);
        let med = errs[errs.len() / 2];
        let max = errs[errs.len() - 1];
        md.push_str(&format!(
            "| {} | {:.1} | {:.2} | {:.1} | {:.1} | {:.3} / {:.3} | {:.4} |\n",
            b.label(),
            direct_us,
            build_s,
            table.memory_bytes() as f64 / 1e6,
            lookup_us,
            med,
            max,
            alb_err
        ));
        rows.push(
            json!({"lobe": b.label(), "on_demand_us": direct_us, "table_build_s": build_s,
            "table_bytes": table.memory_bytes(), "lookup_us": lookup_us,
            "table_rel_l2_median": med, "table_rel_l2_max": max, "table_albedo_err_max": alb_err}),
        );
    }
    md.push('\n');
    Value::Array(rows)
}

fn build(md: &mut String) -> Value {
    let (ng, nl) = (64, 32);
    let t0 = Instant::now();
    let rot = Rotation::new(ng, nl, 32, RotationForm::Factored);
    let rot_s = t0.elapsed().as_secs_f64();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let (ll, _) =
        LatLong::read_exr(&root.join("tests/fixtures/hdri/city_64x32.exr")).expect("city");
    let env = OctEnv::from_latlong(&ll, ng);
    let light = light_haar(&env);
    let mut rng = Pcg64::seed_from_u64(2);
    let nv = 400;
    // Normals in the upper half (|n_z| > 0.2: away from the local-frame flip, see
    // tests/suite/transport_blended.rs), three views per vertex.
    let normals: Vec<Vec3> = (0..nv)
        .map(|_| loop {
            let n = random_unit(&mut rng);
            if n.z.abs() > 0.2 {
                break n;
            }
        })
        .collect();
    let obs_vertex: Vec<u32> = (0..3 * nv).map(|p| (p % nv) as u32).collect();
    let dirs: Vec<Vec3> = obs_vertex
        .iter()
        .map(|&v| loop {
            let d = random_unit(&mut rng);
            if d.dot(&normals[v as usize]) > 0.3 {
                break d;
            }
        })
        .collect();
    let vis = Visibility {
        n_local: nl,
        rays_per_texel: 1,
        frac: vec![255; nv * nl * nl],
        open: vec![true; nv],
        degenerate: 0,
        rays_traced: 0,
        rays_known_open: 0,
    };
    let basis = default_basis();
    let mut rows = Vec::new();
    let mut reference: Option<Vec<f64>> = None;
    md.push_str(&format!(
        "## Transport build\n\n64² global, 32² local, 32² normals (factored rotation, built in {rot_s:.1} s), basis {}, {} observations of {} vertices, city map (sun kept). Threads: {}.\n\n| keep | build s | µs / observation | bytes / observation | response rel. err (median / 99% / max) |\n|---|---|---|---|---|\n",
        basis.iter().map(|b| b.label()).collect::<Vec<_>>().join(", "),
        obs_vertex.len(),
        nv,
        rayon::current_num_threads()
    ));
    for keep in [0usize, 512, 256, 128, 64, 32] {
        let opts = TransportOptions {
            n_global: ng,
            n_local: nl,
            keep,
        };
        let t0 = Instant::now();
        let t = build_rows(&normals, &obs_vertex, &dirs, &vis, &basis, &rot, &opts).expect("build");
        let secs = t0.elapsed().as_secs_f64();
        let resp: Vec<f64> = (0..t.n_obs)
            .flat_map(|p| (0..basis.len()).map(move |b| (p, b)))
            .map(|(p, b)| t.response(p, b, &light[1]))
            .collect();
        let (med, p99, max) = match &reference {
            None => {
                reference = Some(resp.clone());
                (0.0, 0.0, 0.0)
            }
            Some(r) => {
                let mut e: Vec<f64> = r
                    .iter()
                    .zip(&resp)
                    .map(|(a, b)| (a - b).abs() / a.abs().max(1e-12))
                    .collect();
                e.sort_by(f64::total_cmp);
                (e[e.len() / 2], e[e.len() * 99 / 100], e[e.len() - 1])
            }
        };
        let per_obs_us = secs * 1e6 / t.n_obs as f64;
        let bytes = t.memory_bytes() as f64 / t.n_obs as f64;
        md.push_str(&format!(
            "| {} | {:.2} | {:.0} | {:.0} | {:.4} / {:.4} / {:.4} |\n",
            if keep == 0 {
                "all".to_string()
            } else {
                keep.to_string()
            },
            secs,
            per_obs_us,
            bytes,
            med,
            p99,
            max
        ));
        rows.push(
            json!({"keep": keep, "build_s": secs, "us_per_observation": per_obs_us,
            "bytes_per_observation": bytes, "response_rel_err_median": med,
            "response_rel_err_p99": p99, "response_rel_err_max": max}),
        );
    }
    md.push('\n');
    let _ = Matrix3::<f64>::identity();
    json!({"rotation_build_s": rot_s, "rows": rows})
}

fn main() {
    let mut md = String::from("# Transport benchmark (`cargo bench --bench transport`)\n\n");
    let s = slices(&mut md);
    let b = build(&mut md);
    let out = Path::new(env!("CARGO_MANIFEST_DIR")).join("bench-results");
    std::fs::create_dir_all(&out).expect("bench-results");
    let j = json!({"slices": s, "build": b});
    std::fs::write(
        out.join("transport.json"),
        serde_json::to_string_pretty(&j).expect("json"),
    )
    .expect("write json");
    std::fs::write(out.join("transport.md"), &md).expect("write md");
    print!("{md}");
}
