//! `relight-cpc export`: a finished run in formats other tools open.
//!
//! - [`gltf`]: the mesh as binary glTF with per-vertex base colour and a metallic-roughness
//!   approximation of the fitted BRDF mixture;
//! - [`envmap`]: the recovered environment maps as lat-long EXR and Radiance `.hdr` in
//!   Blender's world-texture convention.

pub mod envmap;
pub mod gltf;

use crate::out_dir::OutFiles;
use crate::{Error, Result};
use std::path::{Path, PathBuf};

/// What to export.
#[derive(Debug, Clone, Default)]
pub struct ExportOptions {
    /// Write the mesh here as `.glb`.
    pub gltf: Option<PathBuf>,
    /// Write every recovered environment map into this folder (Blender convention).
    pub envmaps: Option<PathBuf>,
    /// Replace a previous export (never anything else; the output-folder contract).
    pub force: bool,
}

/// What [`export_result`] wrote.
#[derive(Debug, Clone, Default)]
pub struct ExportSummary {
    /// The `.glb` and its figures.
    pub gltf: Option<(PathBuf, gltf::GltfSummary)>,
    /// The environment maps written (EXR and HDR per map).
    pub envmaps: Vec<PathBuf>,
}

pub use crate::out_dir::write_atomic;

/// Whether `path` is a GLB this tool wrote (magic `glTF` and our generator string).
fn is_our_glb(path: &Path) -> bool {
    use std::io::Read;
    // The header and the start of the JSON chunk are enough: the generator string sits
    // in the first 4 KiB, so a large GLB is not read whole.
    let mut head = Vec::with_capacity(4096 + 10);
    std::fs::File::open(path)
        .and_then(|f| f.take(4096 + 10).read_to_end(&mut head))
        .is_ok()
        && head.starts_with(b"glTF")
        && head.windows(11).any(|w| w == b"relight-cpc")
}

/// Export the result in `result_dir` as `opts` asks.
pub fn export_result(result_dir: &Path, opts: &ExportOptions) -> Result<ExportSummary> {
    if opts.gltf.is_none() && opts.envmaps.is_none() {
        return Err(Error::Config(
            "export: nothing to do; give --gltf FILE.glb and/or --envmaps DIR".into(),
        ));
    }
    let mut summary = ExportSummary::default();
    if let Some(path) = &opts.gltf {
        summary.gltf = Some(export_gltf(result_dir, path, opts.force)?);
    }
    if let Some(dir) = &opts.envmaps {
        summary.envmaps = export_envmaps(result_dir, dir, opts.force)?;
    }
    Ok(summary)
}

/// `--gltf FILE.glb`: the fitted mesh with its diffuse albedo as a binary glTF, in the
/// folder of `path`; an earlier export is replaced only with `force`.
fn export_gltf(
    result_dir: &Path,
    path: &Path,
    force: bool,
) -> Result<(PathBuf, gltf::GltfSummary)> {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .ok_or_else(|| Error::Config(format!("--gltf {}: needs a file name", path.display())))?;
    let folder = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    // One named file in a shared folder, usually beside the result it came from: an
    // earlier export is replaced only with --force, any other file never.
    let files = OutFiles::claim(folder, &[&name], force, &[result_dir], is_our_glb)?;
    let m = crate::render::relight::load_result(result_dir)?;
    let mesh = gltf::gltf_mesh(
        &m.mesh.positions,
        &m.normals_env,
        &m.mesh.faces,
        &m.env_from_world,
        &m.basis,
        &m.beta,
    )?;
    let label = result_dir
        .canonicalize()
        .ok()
        .and_then(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
        .unwrap_or_else(|| "relight-cpc".into());
    let (bytes, s) = gltf::glb_bytes(&mesh, &label)?;
    files.write(&name, &bytes)?;
    Ok((path.to_path_buf(), s))
}

/// `--envmaps DIR`: every recovered map of the result (`envmaps/NAME.latlong.exr`) as the
/// files Blender's world shader reads (EXR and HDR per map), into `dir` claimed as a
/// whole; the files written.
fn export_envmaps(result_dir: &Path, dir: &Path, force: bool) -> Result<Vec<PathBuf>> {
    let src = result_dir.join("envmaps");
    let mut maps: Vec<PathBuf> = std::fs::read_dir(&src)
        .map_err(|e| Error::io(&src, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.to_string_lossy().ends_with(".latlong.exr"))
        .collect();
    maps.sort();
    if maps.is_empty() {
        return Err(Error::Workspace {
            path: src,
            message: "no NAME.latlong.exr map in the result".into(),
        });
    }
    let claim = crate::out_dir::OutDir::claim(dir, force, &[result_dir], "export")?;
    let mut exported = Vec::new();
    for p in maps {
        let file = p.file_name().map(|n| n.to_string_lossy().into_owned());
        let stem = file
            .as_deref()
            .and_then(|n| n.strip_suffix(".latlong.exr"))
            .unwrap_or("map")
            .to_string();
        let ll = crate::sphere::envmap::LatLong::read_exr(&p)?.0;
        for written in envmap::export_blender(&ll, claim.path(), &stem)? {
            exported.push(dir.join(written.file_name().unwrap_or_default()));
        }
    }
    claim.commit()?;
    Ok(exported)
}
