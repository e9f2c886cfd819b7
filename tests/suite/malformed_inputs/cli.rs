//! Through the built binary: exit status 1, no panic, no Debug text; unsafe output folders
//! refused with every file intact; a real SIGTERM.

use super::*;
use relight_cpc::out_dir::STAMP;
use std::process::{Command, Output};

/// A copy of the built-in example in a scratch folder (so no test can harm the repo's).
fn example_copy(tag: &str) -> (Scratch, PathBuf) {
    let d = scratch("malformed", tag);
    let ws = d.join("spot");
    let mut stack = vec![repo("examples/spot")];
    let root = repo("examples/spot");
    while let Some(s) = stack.pop() {
        let rel = s.strip_prefix(&root).unwrap();
        std::fs::create_dir_all(ws.join(rel)).unwrap();
        for e in std::fs::read_dir(&s).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                std::fs::copy(&p, ws.join(rel).join(p.file_name().unwrap())).unwrap();
            }
        }
    }
    (d, ws)
}

fn cli(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_relight-cpc"))
        .args(args)
        .output()
        .unwrap()
}

/// The CLI failed with exit status 1, no panic, and a plain message containing `words`.
fn cli_refused(o: &Output, words: &[&str]) -> String {
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(o.status.code(), Some(1), "stderr: {err}");
    assert!(!err.contains("panicked"), "{err}");
    for m in DEBUG_MARKS {
        assert!(!err.contains(m), "Debug text {m:?} in: {err}");
    }
    for w in words {
        assert!(err.contains(w), "{w:?} missing from: {err}");
    }
    err
}

#[test]
fn cli_truncated_mesh_is_a_plain_error_naming_the_file() {
    let (d, ws) = example_copy("cli-mesh");
    let mesh = ws.join("dense/meshed-poisson.ply");
    let bytes = std::fs::read(&mesh).unwrap();
    std::fs::write(&mesh, &bytes[..bytes.len() / 2]).unwrap();
    let out = d.join("out");
    let o = cli(&[
        "run",
        ws.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    cli_refused(&o, &[mesh.to_str().unwrap(), "ends early"]);
    assert!(!out.exists(), "no result folder for a failed run");
}

#[test]
fn cli_rerun_without_force_is_refused_naming_force() {
    let (d, ws) = example_copy("cli-rerun");
    let out = d.join("out");
    std::fs::create_dir(&out).unwrap();
    std::fs::write(out.join(STAMP), "{}").unwrap();
    std::fs::write(out.join("report.json"), "{}").unwrap();
    let before = snapshot(&d);
    let o = cli(&["run", ws.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    cli_refused(&o, &["--force", "previous result"]);
    assert_eq!(snapshot(&d), before);
}

#[test]
fn cli_force_on_a_foreign_folder_is_refused_naming_its_files() {
    let (d, ws) = example_copy("cli-foreign");
    let out = d.join("mine");
    std::fs::create_dir_all(out.join("photos")).unwrap();
    std::fs::write(out.join("notes.txt"), "my notes").unwrap();
    let before = snapshot(&d);
    let o = cli(&[
        "run",
        ws.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--force",
    ]);
    cli_refused(&o, &["not a relight-cpc result", "notes.txt", "photos"]);
    assert_eq!(snapshot(&d), before);
}

#[test]
fn cli_force_on_the_workspace_itself_is_refused() {
    let (d, ws) = example_copy("cli-ws");
    let before = snapshot(&d);
    let o = cli(&[
        "run",
        ws.to_str().unwrap(),
        "--out",
        ws.to_str().unwrap(),
        "--force",
    ]);
    cli_refused(&o, &["is the input folder"]);
    assert_eq!(snapshot(&d), before);
}

#[test]
fn cli_force_on_a_folder_holding_the_workspace_is_refused() {
    let (d, ws) = example_copy("cli-parent");
    let before = snapshot(&d);
    let o = cli(&[
        "run",
        ws.to_str().unwrap(),
        "--out",
        d.to_str().unwrap(),
        "--force",
    ]);
    cli_refused(&o, &["contains the input"]);
    assert_eq!(snapshot(&d), before);
}

#[test]
fn cli_force_on_the_mesh_folder_is_refused() {
    let (d, ws) = example_copy("cli-meshdir");
    let dense = ws.join("dense");
    let before = snapshot(&d);
    let o = cli(&[
        "run",
        ws.to_str().unwrap(),
        "--mesh",
        dense.join("meshed-poisson.ply").to_str().unwrap(),
        "--out",
        dense.to_str().unwrap(),
        "--force",
    ]);
    cli_refused(&o, &["folder of the input file"]);
    assert_eq!(snapshot(&d), before);
}

#[test]
fn cli_root_folder_is_refused() {
    let (_d, ws) = example_copy("cli-root");
    let o = cli(&["run", ws.to_str().unwrap(), "--out", "/", "--force"]);
    cli_refused(&o, &["root folder"]);
}

#[test]
fn cli_home_folder_is_refused() {
    let (d, ws) = example_copy("cli-home");
    let home = d.join("home");
    std::fs::create_dir(&home).unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_relight-cpc"))
        .args(["run", ws.to_str().unwrap(), "--out", home.to_str().unwrap()])
        .env("HOME", &home)
        .output()
        .unwrap();
    cli_refused(&o, &["home folder"]);
}

#[test]
fn cli_synth_onto_a_foreign_folder_is_refused() {
    let d = scratch("malformed", "cli-synth");
    std::fs::write(d.join("keep.txt"), "mine").unwrap();
    let before = snapshot(&d);
    let o = cli(&["synth", "sphere-diffuse", d.to_str().unwrap(), "--force"]);
    cli_refused(&o, &["keep.txt"]);
    assert_eq!(snapshot(&d), before);
}

#[test]
fn cli_bench_onto_a_foreign_report_is_refused() {
    let d = scratch("malformed", "cli-bench");
    std::fs::write(d.join("pipeline.json"), "[1, 2, 3]").unwrap();
    let before = snapshot(&d);
    let o = cli(&["bench", "--quick", "--out", d.to_str().unwrap(), "--force"]);
    cli_refused(&o, &["pipeline.json", "not a relight-cpc result"]);
    assert_eq!(snapshot(&d), before);
}

/// SIGTERM during a run: the staging folder is removed, the previous result is as it was,
/// and nothing that looks like a finished result appears.
#[cfg(unix)]
#[test]
fn cli_interrupted_run_leaves_the_previous_result_untouched() {
    let (d, ws) = example_copy("cli-kill");
    let out = d.join("out");
    std::fs::create_dir(&out).unwrap();
    std::fs::write(out.join(STAMP), "{}").unwrap();
    std::fs::write(out.join("report.json"), "previous").unwrap();
    let before = snapshot(&d);
    let mut child = Command::new(env!("CARGO_BIN_EXE_relight-cpc"))
        .args(["run", ws.to_str().unwrap(), "--out", out.to_str().unwrap()])
        .args(["--force", "--quiet"])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Wait (up to 60 s) for the staging folder, i.e. for work to have started.
    let staging = || {
        std::fs::read_dir(&d)
            .unwrap()
            .filter_map(|e| e.ok())
            .any(|e| {
                e.file_name()
                    .to_string_lossy()
                    .contains("relight-cpc-staging")
            })
    };
    let t0 = std::time::Instant::now();
    while !staging() && t0.elapsed().as_secs() < 60 {
        if child.try_wait().unwrap().is_some() {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    assert!(staging(), "the run never created its staging folder");
    Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(128 + 15), "exit status after SIGTERM");
    assert!(!staging(), "staging folder left behind");
    assert_eq!(snapshot(&d), before, "previous result changed");
}
