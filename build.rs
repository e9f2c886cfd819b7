//! Embeds the built-in example workspace (examples/spot) into the binary: writes
//! `$OUT_DIR/builtin_example.rs`, a list of `(relative path, include_bytes!(...))` pairs, so
//! the installed binary carries the example instead of a path into the source tree.

use std::path::{Path, PathBuf};

fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    let mut paths: Vec<PathBuf> = entries.filter_map(|e| e.ok().map(|e| e.path())).collect();
    paths.sort();
    for p in paths {
        if p.is_dir() {
            walk(&p, out);
        } else if p.is_file() {
            out.push(p);
        }
    }
}

fn main() {
    let root = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").expect("cargo sets it"));
    let example = root.join("examples").join("spot");
    println!("cargo:rerun-if-changed=examples/spot");
    let mut files = Vec::new();
    walk(&example, &mut files);
    let mut code = String::from("&[\n");
    for f in &files {
        let rel = f.strip_prefix(&example).expect("walked below the example");
        let rel = rel
            .components()
            .map(|c| c.as_os_str().to_string_lossy().into_owned())
            .collect::<Vec<_>>()
            .join("/");
        code.push_str(&format!(
            "    ({rel:?}, include_bytes!({:?})),\n",
            f.display().to_string()
        ));
        println!("cargo:rerun-if-changed={}", f.display());
    }
    code.push_str("]\n");
    let out = PathBuf::from(std::env::var("OUT_DIR").expect("cargo sets it"));
    std::fs::write(out.join("builtin_example.rs"), code).expect("OUT_DIR is writable");
}
