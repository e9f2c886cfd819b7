//! `relight-cpc bench` fits every run in a child process (`relight-cpc run` with the
//! bench's options, read back from its `report.json`). The check is independent of that
//! path: the same benchmark run in-process by the library ([`bench::bench`] with no
//! executable) must give the same figures, so the child's command line reproduces the
//! options the bench meant.

use relight_cpc::bench::{self, BenchOptions, BenchReport};
use std::path::Path;
use std::process::Command;

fn small(out: &Path) -> BenchOptions {
    let mut o = BenchOptions::quick(out.to_path_buf());
    o.sizes = vec![600];
    o.photos = vec![5];
    o.base_photos = 4;
    o.base_vertices = 600;
    o.no_sweep = true;
    o
}

#[test]
fn child_runs_reproduce_the_in_process_bench() {
    let dir = std::env::temp_dir().join(format!("relight-bench-isolated-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let (cli_out, lib_out) = (dir.join("cli"), dir.join("lib"));

    let status = Command::new(env!("CARGO_BIN_EXE_relight-cpc"))
        .args(["bench", "--quick", "--sizes", "600", "--photos", "5"])
        .args([
            "--base-photos",
            "4",
            "--base-vertices",
            "600",
            "--no-sweep",
            "--out",
        ])
        .arg(&cli_out)
        .status()
        .expect("run relight-cpc bench");
    assert!(status.success(), "bench exited with {status}");
    let text = std::fs::read_to_string(cli_out.join("pipeline.json")).unwrap();
    let cli: serde_json::Value = serde_json::from_str(&text).unwrap();

    let lib: BenchReport = bench::bench(&small(&lib_out)).unwrap();
    assert!(!lib.isolated);
    assert_eq!(cli["isolated"], true);
    assert_eq!(cli["complete"], true);

    let runs = |v: &serde_json::Value| -> Vec<serde_json::Value> {
        let mut r = v["vertex_runs"].as_array().unwrap().clone();
        r.extend(v["photo_runs"].as_array().unwrap().iter().cloned());
        r
    };
    let cli_runs = runs(&cli);
    let lib_runs: Vec<_> = lib.vertex_runs.iter().chain(&lib.photo_runs).collect();
    assert_eq!(cli_runs.len(), 2);
    assert_eq!(cli_runs.len(), lib_runs.len());
    for (c, l) in cli_runs.iter().zip(lib_runs) {
        assert!(c["command"]
            .as_str()
            .unwrap()
            .starts_with("relight-cpc run "));
        assert!(l.command.is_none());
        assert_eq!(c["vertices"].as_u64().unwrap() as usize, l.vertices);
        assert_eq!(c["photos"].as_u64().unwrap() as usize, l.photos);
        assert_eq!(c["observations"].as_u64().unwrap() as usize, l.observations);
        // The fit is deterministic (bitwise across runs and thread counts, see
        // tests/suite/estimate_synth.rs); the JSON round trip of an f64 is exact, so the only
        // allowance is for the printing of the shortest representation: 1e-12 relative.
        for (key, b) in [
            ("train_rmse", l.train_rmse),
            ("holdout_rmse", l.holdout_rmse),
        ] {
            let a = c[key].as_f64().unwrap();
            assert!(
                a.is_finite() && (a - b).abs() <= 1e-12 * b.abs(),
                "{key}: child {a} vs in-process {b}"
            );
        }
        assert!(c["peak_memory_bytes"].as_u64().unwrap() > 0);
    }
    let _ = std::fs::remove_dir_all(&dir);
}
