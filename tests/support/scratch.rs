//! Shared by the tests that write files: a scratch folder (or a file in its own scratch
//! folder) removed on drop, so a test run leaves nothing under the temporary folder, and a
//! small `synth` workspace in it.

#![allow(dead_code)]

use std::path::{Path, PathBuf};

use relight_cpc::synth::{self, SynthOptions};
use relight_cpc::transport::reference::Samples;

/// A scratch folder removed on drop.
pub struct Scratch(pub PathBuf);

impl std::ops::Deref for Scratch {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<Path> for Scratch {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// A fresh, empty `relight-{prefix}-{pid}-{tag}` under the system's temporary folder.
pub fn scratch(prefix: &str, tag: &str) -> Scratch {
    let p = std::env::temp_dir().join(format!("relight-{prefix}-{}-{tag}", std::process::id()));
    let _ = std::fs::remove_dir_all(&p);
    std::fs::create_dir_all(&p).unwrap();
    Scratch(p)
}

/// A file path `name` in a folder of its own, the folder removed when this is dropped.
pub struct ScratchFile {
    _dir: Scratch,
    path: PathBuf,
}

impl std::ops::Deref for ScratchFile {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.path
    }
}

impl AsRef<Path> for ScratchFile {
    fn as_ref(&self) -> &Path {
        &self.path
    }
}

/// `relight-{prefix}-{pid}-{name}/{name}` under the system's temporary folder (the file is
/// not created).
pub fn scratch_file(prefix: &str, name: &str) -> ScratchFile {
    let dir = scratch(prefix, name);
    let path = dir.join(name);
    ScratchFile { _dir: dir, path }
}

/// A 64×64 synth workspace `dir/ws` of `scene` with `photos` photos, about `vertices`
/// vertices, `per_pixel` samples per pixel and `light` light samples each, 300 points.
pub fn workspace(
    dir: &Path,
    scene: &str,
    photos: usize,
    vertices: usize,
    per_pixel: u32,
    light: u32,
) -> PathBuf {
    let ws = dir.join("ws");
    let opts = SynthOptions {
        width: 64,
        height: 64,
        photos: Some(photos),
        vertices: Some(vertices),
        exact_vertices: false,
        samples: Samples {
            per_pixel,
            light,
            seed: 3,
        },
        points: 300,
        ..SynthOptions::default()
    };
    synth::build(scene, &ws, &opts).unwrap();
    ws
}

/// Every file under `dir` with its bytes, sorted by path: to compare before and after, or
/// two results.
pub fn snapshot(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.push((p.clone(), std::fs::read(&p).unwrap()));
            }
        }
    }
    out.sort();
    out
}
