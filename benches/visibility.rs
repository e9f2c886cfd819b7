//! Cost and accuracy of the visibility sampling (issue 26):
//! `cargo bench --bench visibility [-- MESH.ply] [--reference RAYS]` (default: the built-in
//! example's mesh, 64 reference rays)
//! writes `bench-results/visibility-sampling.json` and `.md`.
//!
//! Each sampling is run on every vertex of the mesh in one worker thread (CPU seconds of
//! the thread, `/proc/self/task/*/schedstat`), the runs interleaved over `REPS` rounds so
//! that a noisy machine slows them alike. Accuracy: against `REFERENCE_RAYS` stratified rays
//! per texel, the root-mean-square error of the texel fractions over the traced vertices'
//! texels, and the mean absolute error of each vertex's visible solid angle `Σ_t V_t Δω_t`.

use nalgebra::Matrix3;
use relight_cpc::import::mesh::Mesh;
use relight_cpc::observe::trace::SceneBvh;
use relight_cpc::sphere::SphereGrid;
use relight_cpc::stages::cpu_seconds_fine;
use relight_cpc::transport::visibility::{compute_sampled, Sampling, Visibility};
use serde_json::json;
use std::path::{Path, PathBuf};

#[path = "support/today.rs"]
mod today;
use today::today;

const N_LOCAL: usize = 32;
const REPS: usize = 3;
const REFERENCE_RAYS: usize = 64;

fn errors(v: &Visibility, reference: &Visibility, solid_angle: &[f64]) -> (f64, f64) {
    let (mut se, mut n, mut sa_err, mut traced) = (0.0, 0usize, 0.0, 0usize);
    for vi in 0..v.open.len() {
        if reference.open[vi] {
            continue;
        }
        let (a, b) = (v.vertex(vi), reference.vertex(vi));
        let mut d_sa = 0.0;
        for t in 0..a.len() {
            let d = (f64::from(a[t]) - f64::from(b[t])) / 255.0;
            se += d * d;
            d_sa += d * solid_angle[t];
        }
        n += a.len();
        sa_err += d_sa.abs();
        traced += 1;
    }
    ((se / n.max(1) as f64).sqrt(), sa_err / traced.max(1) as f64)
}

fn main() {
    let mesh_path: PathBuf = std::env::args()
        .skip(1)
        .find(|a| a.ends_with(".ply"))
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new("examples/spot/dense/meshed-poisson.ply").to_path_buf());
    let (mesh, _) = Mesh::read_ply(&mesh_path).expect("mesh");
    let bvh = SceneBvh::new(&mesh);
    let m = Matrix3::identity();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("pool");
    let run = |s: Sampling| {
        pool.install(|| {
            let c0 = cpu_seconds_fine();
            let v = compute_sampled(&mesh, &bvh, &m, N_LOCAL, s, 1, true);
            (v, cpu_seconds_fine() - c0)
        })
    };
    let args: Vec<String> = std::env::args().collect();
    let reference_rays = args
        .iter()
        .position(|a| a == "--reference")
        .and_then(|i| args.get(i + 1)?.parse().ok())
        .unwrap_or(REFERENCE_RAYS);
    let (reference, ref_cpu) = run(Sampling::Uniform {
        rays: reference_rays,
    });
    let solid_angle = SphereGrid::hemi(N_LOCAL).solid_angles();
    let samplings = [
        Sampling::Uniform { rays: 1 },
        Sampling::Uniform { rays: 2 },
        Sampling::Uniform { rays: 4 },
        Sampling::Adaptive {
            edge_rays: 3,
            lattice: 1,
        },
        Sampling::Adaptive {
            edge_rays: 4,
            lattice: 1,
        },
        Sampling::Adaptive {
            edge_rays: 4,
            lattice: 2,
        },
        Sampling::Adaptive {
            edge_rays: 3,
            lattice: 2,
        },
        Sampling::Adaptive {
            edge_rays: 8,
            lattice: 2,
        },
    ];
    let mut cpu = vec![Vec::new(); samplings.len()];
    let mut results = Vec::new();
    for rep in 0..REPS {
        for (i, &s) in samplings.iter().enumerate() {
            let (v, c) = run(s);
            cpu[i].push(c);
            if rep == 0 {
                results.push(v);
            }
        }
    }
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    let mut md = format!(
        "# Visibility sampling: cost and accuracy\n\nMeasured {} with `cargo bench --bench visibility -- {}`. Mesh `{}` ({} vertices, {} traced), {N_LOCAL}² texels, one worker thread, \
         {REPS} interleaved rounds; reference {reference_rays} stratified rays per texel ({ref_cpu:.1} CPU s). \
         Load average at the end: {}\n\n| sampling | rays traced | CPU s (median) | CPU s (all rounds) | texel RMS error | mean \\|visible solid-angle error\\| (sr) |\n|---|---:|---:|---|---:|---:|\n",
        today(),
        std::env::args().skip(1).collect::<Vec<_>>().join(" "),
        mesh_path.display(),
        mesh.positions.len(),
        mesh.positions.len() - reference.open_count(),
        load.trim()
    );
    let mut rows = Vec::new();
    for ((s, v), c) in samplings.iter().zip(&results).zip(&cpu) {
        let mut sorted = c.clone();
        sorted.sort_by(f64::total_cmp);
        let (rms, sa) = errors(v, &reference, &solid_angle);
        md.push_str(&format!(
            "| {s:?} | {} | {:.2} | {} | {rms:.4} | {sa:.4} |\n",
            v.rays_traced,
            sorted[REPS / 2],
            c.iter()
                .map(|x| format!("{x:.2}"))
                .collect::<Vec<_>>()
                .join(" / ")
        ));
        rows.push(
            json!({"sampling": format!("{s:?}"), "rays_traced": v.rays_traced,
            "cpu_seconds": c, "texel_rms_error": rms, "solid_angle_mean_abs_error": sa}),
        );
    }
    print!("{md}");
    let out = Path::new("bench-results");
    std::fs::write(out.join("visibility-sampling.md"), &md).expect("write md");
    let j = json!({"mesh": mesh_path.display().to_string(), "load": load.trim(), "rows": rows});
    std::fs::write(
        out.join("visibility-sampling.json"),
        serde_json::to_string_pretty(&j).expect("json"),
    )
    .expect("write json");
}
