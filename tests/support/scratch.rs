//! Shared by the tests that write files: a scratch folder (or a file in its own scratch
//! folder) removed on drop, so a test run leaves nothing under the temporary folder, a
//! small `synth` workspace in it, and small options for `run` (on the built-in example, with
//! the check that its report's timeline follows its starts).

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

/// Options for `run` on `workspace` at small sizes (16² / 8² maps, 8² normal grid, 32
/// coefficients, at most 3 outer iterations, 1 ray per texel, no progress, no training
/// renders), writing into `out`.
pub fn small_options(workspace: PathBuf, out: PathBuf) -> relight_cpc::run::RunOptions {
    let mut o = relight_cpc::run::RunOptions::new(workspace, out);
    (
        o.global_resolution,
        o.local_resolution,
        o.normal_grid,
        o.keep,
    ) = (16, 8, 8, 32);
    (o.max_iterations, o.rays_per_texel, o.edge_rays) = (3, 1, 0);
    (o.progress, o.render_training) = (false, false);
    o
}

/// [`small_options`] on the built-in example with 2 materials, writing into `dir/out`: for
/// tests of what the report records of the fit.
pub fn small_example_options(dir: &Path) -> relight_cpc::run::RunOptions {
    use relight_cpc::run::{builtin_example, MaterialCount};
    let mut o = small_options(builtin_example().unwrap(), dir.join("out"));
    o.materials = MaterialCount::Fixed(2);
    o
}

/// The report's timeline follows the starts' records, start by start: as many points per
/// start as that start's fit had iterations, on one clock that never goes back.
pub fn assert_timeline_follows_starts(
    timeline: &[relight_cpc::report::TimelinePoint],
    starts: &relight_cpc::solve::starts::MultiStart,
) {
    for (i, s) in starts.starts.iter().enumerate() {
        let points = timeline.iter().filter(|p| p.start == i).count();
        assert_eq!(points, s.iterations, "start {i}: {s:?}");
    }
    assert!(timeline.windows(2).all(|w| w[0].start <= w[1].start));
    assert!(timeline.windows(2).all(|w| w[0].seconds <= w[1].seconds));
}
