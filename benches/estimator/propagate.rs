//! Part 7: the cost of the propagation of materials to the vertices no training photo sees
//! ([`propagate_unseen`]) on the large Spot meshes. The unseen set stands in for a real
//! one: a contiguous underside (the 15% of vertices lowest in `y`, a patch whose diameter
//! sets the conjugate-gradient iterations) and every 10th other vertex (isolated gaps).
//! `PROPAGATE_MESHES` (comma list of PLY paths) replaces the default meshes.

use relight_cpc::import::mesh::Mesh;
use relight_cpc::solve::materials::propagate::{knn_graph, propagate_unseen, NEIGHBOURS};
use relight_cpc::stages::Stopwatch;
use serde_json::{json, Value};

const MESHES: [&str; 2] = [
    "/work/scratch/speed100k/bw/spot-varying-v100000-p13-1024x1024/dense/meshed-poisson.ply",
    "/work/scratch/speed100k/bw/spot-varying-v400000-p13-1024x1024/dense/meshed-poisson.ply",
];

/// Materials in the propagated weights (the pipeline benchmark's K).
const K: usize = 6;

pub fn propagate(md: &mut String) -> Value {
    let paths: Vec<String> = std::env::var("PROPAGATE_MESHES")
        .map(|v| v.split(',').map(str::to_string).collect())
        .unwrap_or_else(|_| MESHES.iter().map(|s| s.to_string()).collect());
    md.push_str(&format!("{}\n\n", stamp()));
    md.push_str(&format!(
        "## 7. Propagating materials to unseen vertices\n\n{K} materials; unseen = the 15% lowest vertices + every 10th other. CPU = user + system of the process over the call.\n\n\
         | mesh | vertices | unseen filled | CG iterations | wall s | CPU s | of which the graph (CPU s, timed apart) |\n|---|---|---|---|---|---|---|\n"
    ));
    let mut rows = Vec::new();
    for path in paths {
        let Ok((mesh, _)) = Mesh::read_ply(std::path::Path::new(&path)) else {
            eprintln!("{path}: not readable, skipped");
            continue;
        };
        let n = mesh.positions.len();
        let mut ys: Vec<f64> = mesh.positions.iter().map(|p| p.y).collect();
        ys.sort_by(f64::total_cmp);
        let cut = ys[n * 15 / 100];
        let seen: Vec<bool> = (0..n)
            .map(|x| mesh.positions[x].y > cut && x % 10 != 0)
            .collect();
        let mut w: Vec<f64> = (0..n * K).map(|i| ((i % K) as f64 + 1.0) / 21.0).collect();
        let watch = Stopwatch::start();
        knn_graph(&mesh.positions, NEIGHBOURS).expect("graph");
        let (_, knn_cpu) = watch.elapsed();
        let watch = Stopwatch::start();
        let p = propagate_unseen(&mesh.positions, &seen, &mut w, K).expect("propagation");
        let (wall, cpu) = watch.elapsed();
        md.push_str(&format!(
            "| `{path}` | {n} | {} | {} | {wall:.2} | {cpu:.2} | {knn_cpu:.2} |\n",
            p.filled, p.iterations
        ));
        rows.push(json!({"mesh": path, "vertices": n, "filled": p.filled, "isolated": p.isolated, "iterations": p.iterations, "wall_s": wall, "cpu_s": cpu, "graph_cpu_s": knn_cpu}));
    }
    md.push('\n');
    Value::Array(rows)
}

/// The date (UTC) and the load average when the bench ran.
pub fn stamp() -> String {
    let date = std::process::Command::new("date")
        .arg("-u")
        .output()
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
        .unwrap_or_default();
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    let load: Vec<&str> = load.split_whitespace().take(3).collect();
    format!("Measured {date}, load average {}.", load.join(" "))
}
