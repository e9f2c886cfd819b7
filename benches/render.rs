//! The wavelet renderer's two ways of getting the light into a vertex's local frame, on
//! the same data in one process: rotated per vertex (the blended resampling of Eq. 6 for
//! every vertex, the path before `WaveletRenderer::with_frames`) and rotated once per
//! precomputed frame then blended per vertex. Run defaults (64² global, 32² local, 32²
//! normal grid, factored; basis lambert, phong:50, phong:500). `cargo bench --bench render`
//! writes `bench-results/render.json` and `bench-results/render.md`.
//! `RENDER_BENCH_VERTICES` (default 6400, the Buddha fixture's size) sets the vertex count;
//! the per-vertex path is timed on a tenth of them and scaled.

use std::time::Instant;

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use rayon::prelude::*;
use relight_cpc::render::wavelet::WaveletRenderer;
use relight_cpc::sphere::envmap::OctEnv;
use relight_cpc::sphere::rotation::{Rotation, RotationForm};
use relight_cpc::transport::brdf::BasisBrdf;
use serde_json::json;

use relight_cpc::stages::cpu_seconds_fine as cpu_seconds;

#[path = "../tests/support/random.rs"]
mod random;
use random::random_vertices;

fn main() {
    let (ng, nl, nn) = (64, 32, 32);
    let nv: usize = std::env::var("RENDER_BENCH_VERTICES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(6400);
    let mut rng = Pcg64::seed_from_u64(5);
    let (normals, dirs, vis) = random_vertices(&mut rng, nv, nl, 2, 128);
    let basis = [
        BasisBrdf::Lambert,
        BasisBrdf::Phong { exponent: 50.0 },
        BasisBrdf::Phong { exponent: 500.0 },
    ];
    let beta: Vec<[f64; 3]> = (0..nv * 3)
        .map(|_| [0, 1, 2].map(|_| rng.random_range(0.0..1.0)))
        .collect();
    let rgb: Vec<[f32; 3]> = (0..ng * ng)
        .map(|_| [0, 1, 2].map(|_| rng.random_range(0.0..2.0f32)))
        .collect();
    let env = OctEnv { n: ng, rgb };
    let t = Instant::now();
    let rot = Rotation::new(ng, nl, nn, RotationForm::Factored);
    let rot_build = t.elapsed().as_secs_f64();
    let threads = rayon::current_num_threads();

    let radiance = |r: &WaveletRenderer<Rotation>, n: usize| -> Vec<[f64; 3]> {
        (0..n)
            .into_par_iter()
            .map(|p| {
                r.vertex_radiance(
                    &normals[p],
                    vis.vertex(p),
                    &dirs[p],
                    &beta[p * 3..p * 3 + 3],
                )
            })
            .collect()
    };
    // Per vertex, on a tenth of the vertices.
    let n_pv = (nv / 10).max(1);
    let (w0, c0) = (Instant::now(), cpu_seconds());
    let per_vertex = WaveletRenderer::new(&rot, &basis, &env).expect("renderer");
    let a = radiance(&per_vertex, n_pv);
    let pv_wall = w0.elapsed().as_secs_f64() / n_pv as f64;
    let pv_cpu = (cpu_seconds() - c0) / n_pv as f64;
    // Frames: the rotation into all frames (once per light) plus the per-vertex blend.
    let (w1, c1) = (Instant::now(), cpu_seconds());
    let framed = WaveletRenderer::new(&rot, &basis, &env)
        .expect("renderer")
        .with_frames();
    let table_wall = w1.elapsed().as_secs_f64();
    let table_cpu = cpu_seconds() - c1;
    let (w2, c2) = (Instant::now(), cpu_seconds());
    let b = radiance(&framed, nv);
    let fr_wall = w2.elapsed().as_secs_f64() / nv as f64;
    let fr_cpu = (cpu_seconds() - c2) / nv as f64;
    let mut max_rel = 0.0f64;
    for (x, y) in a.iter().zip(&b) {
        for c in 0..3 {
            max_rel = max_rel.max((x[c] - y[c]).abs() / x[c].abs().max(1e-300));
        }
    }
    let before_cpu = pv_cpu * nv as f64;
    let after_cpu = table_cpu + fr_cpu * nv as f64;
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    let j = json!({
        "n_global": ng, "n_local": nl, "normal_grid": nn, "vertices": nv, "threads": threads,
        "rotation_build_seconds": rot_build,
        "per_vertex": {"vertices_timed": n_pv, "wall_us_per_vertex": pv_wall * 1e6, "cpu_us_per_vertex": pv_cpu * 1e6},
        "frames": {"table_wall_s": table_wall, "table_cpu_s": table_cpu, "table_bytes": 3 * rot.len() * nl * nl * 8,
                   "wall_us_per_vertex": fr_wall * 1e6, "cpu_us_per_vertex": fr_cpu * 1e6},
        "cpu_seconds_per_light_and_view": {"per_vertex": before_cpu, "frames": after_cpu},
        "speedup_cpu": before_cpu / after_cpu,
        "max_relative_difference": max_rel,
        "load_average_at_end": load.trim(),
    });
    let out = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("bench-results");
    std::fs::create_dir_all(&out).expect("bench-results");
    std::fs::write(
        out.join("render.json"),
        serde_json::to_string_pretty(&j).expect("json"),
    )
    .expect("write render.json");
    let md = format!(
        "# Wavelet renderer: per-vertex rotation vs rotate-once-per-frame\n\n\
         `cargo bench --bench render` ({threads} threads, load average at end {}). \
         {nv} vertices with random normals, views, visibility and β; light {ng}², local {nl}², \
         normal grid {nn}² ({} frames), factored rotation, basis lambert, phong:50, phong:500.\n\n\
         | path | CPU µs / vertex | wall µs / vertex | once per light (CPU s) | CPU s for {nv} vertices |\n\
         |---|---|---|---|---|\n\
         | per vertex (timed on {n_pv}) | {:.1} | {:.1} | 0 | {:.2} |\n\
         | frames + blend | {:.1} | {:.1} | {:.3} ({:.1} MB) | {:.2} |\n\n\
         CPU speed-up ×{:.1}; largest relative difference between the two paths {:.1e} \
         (factored form: bitwise equal, tests/suite/render_frames.rs).\n",
        load.trim(),
        rot.len(),
        pv_cpu * 1e6,
        pv_wall * 1e6,
        before_cpu,
        fr_cpu * 1e6,
        fr_wall * 1e6,
        table_cpu,
        (3 * rot.len() * nl * nl * 8) as f64 / 1e6,
        after_cpu,
        before_cpu / after_cpu,
        max_rel
    );
    std::fs::write(out.join("render.md"), &md).expect("write render.md");
    print!("{md}");
}
