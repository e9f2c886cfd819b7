//! The catalogue of malformed inputs and unsafe output folders (issue 23): one test each.
//! Every error must name the file, say where (element / record / line) and what was
//! expected and found, in words: no panic, no library `Debug` text (`Error { kind: .. }`,
//! `Custom { .. }`, ply-rs's tab-indented `Error:` lines). The CLI cases run the built
//! binary and check its exit status and stderr; the output-folder cases check that every
//! file is intact afterwards (same bytes).

//!
//! One module per kind of input: [`ply`], [`map`], [`photo`], [`colmap`], [`output`]
//! (files and folders the tool writes) and [`cli`] (the built binary).

mod cli;
mod colmap;
mod map;
mod output;
mod photo;
mod ply;

use std::path::{Path, PathBuf};

use crate::scratch::{scratch, snapshot, Scratch};

/// Library `Debug` formatting that must never reach a user.
const DEBUG_MARKS: [&str; 7] = [
    "Error {", "kind:", "Custom {", "Os {", "Some(", "\tError", "\tString",
];

/// `msg` names `file` and has no Debug text; returns it for further checks.
fn plain(msg: String, file: &Path) -> String {
    assert!(
        msg.contains(&*file.to_string_lossy()),
        "does not name {}: {msg}",
        file.display()
    );
    for m in DEBUG_MARKS {
        assert!(!msg.contains(m), "Debug text {m:?} in: {msg}");
    }
    msg
}

/// `err` is an error naming `file`, and its message contains every word of `words`.
fn expect<T: std::fmt::Debug>(r: relight_cpc::Result<T>, file: &Path, words: &[&str]) {
    let msg = plain(
        r.expect_err("malformed input was accepted").to_string(),
        file,
    );
    for w in words {
        assert!(msg.contains(w), "{w:?} missing from: {msg}");
    }
}

fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

/// A scratch folder holding `name` with `bytes`.
fn file(tag: &str, name: &str, bytes: &[u8]) -> (Scratch, PathBuf) {
    let dir = scratch("malformed", tag);
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    (dir, p)
}

const ASCII_HEAD: &str = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n\
property float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\n\
end_header\n";
