//! Finding the parts of a COLMAP workspace where COLMAP's own tools put them.
//!
//! The sparse model and the photos go together: a model's cameras describe the photos it
//! was made from. `image_undistorter` writes undistorted photos and a PINHOLE model side by
//! side (`dense/images` + `dense/sparse`, or `images` + `sparse` when its output folder is
//! the workspace root), and the dense mesh is made from those, so the undistorted pair is
//! preferred when it is complete. The candidates, in order:
//!
//! 1. `dense/sparse` with `dense/images` (undistorted model and photos);
//! 2. `sparse` holding a model directly, with `images`;
//! 3. `sparse/N` (the lowest N holding a model, as `mapper` numbers its models from 0),
//!    with `images`.
//!
//! Within a model folder, binary (`*.bin`) is read before text (`*.txt`), as COLMAP does.
//! The mesh: the path given by the user (`--mesh`), else `meshed-poisson.ply`, then
//! `meshed-delaunay.ply`, next to the chosen model's dense folder (`dense/`, or the root).
//! `fused.ply` is picked up the same way when present; `truth/` marks a synthetic scene.
//! Every choice, and every candidate passed over, is recorded in [`Workspace::notes`].

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use crate::import::colmap::{ImageId, ModelFormat, Reconstruction};
use crate::{Error, Result};

/// The parts of a COLMAP workspace the job needs.
#[derive(Clone, Debug, PartialEq)]
pub struct Workspace {
    /// The folder the user named.
    pub root: PathBuf,
    /// The folder holding the chosen sparse model.
    pub sparse_dir: PathBuf,
    /// The format the model is read in (binary when both are present).
    pub sparse_format: ModelFormat,
    /// The folder holding the photos that go with the model.
    pub images_dir: PathBuf,
    /// The triangle mesh (PLY).
    pub mesh_path: PathBuf,
    /// COLMAP's fused point cloud, when present.
    pub fused_path: Option<PathBuf>,
    /// `root/truth` if present (synthetic scenes carry their ground truth there).
    pub truth_dir: Option<PathBuf>,
    /// What was picked and why, and what was passed over.
    pub notes: Vec<String>,
}

/// Which photos of a model were found on disk.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PhotoMatch {
    /// Registered images whose photo exists, with its path.
    pub found: Vec<(ImageId, PathBuf)>,
    /// Registered images whose photo is missing (id, name in the model).
    pub missing: Vec<(ImageId, String)>,
    /// Photo files in the folder that the model did not register (relative names).
    pub unregistered: Vec<String>,
}

/// The model format in `dir`, or why there is none.
fn model_format(dir: &Path) -> std::result::Result<ModelFormat, String> {
    if ModelFormat::Binary.present_in(dir) {
        return Ok(ModelFormat::Binary);
    }
    if ModelFormat::Text.present_in(dir) {
        return Ok(ModelFormat::Text);
    }
    let partial: Vec<&str> = ModelFormat::Binary
        .file_names()
        .into_iter()
        .chain(ModelFormat::Text.file_names())
        .filter(|f| dir.join(f).is_file())
        .collect();
    if partial.is_empty() {
        Err("no model files".to_string())
    } else {
        Err(format!(
            "incomplete model: has only {} (needs cameras, images and points3D in one format)",
            partial.join(", ")
        ))
    }
}

/// Numbered model folders `sparse/N`, in increasing N.
fn numbered_models(sparse: &Path) -> Vec<PathBuf> {
    let Ok(entries) = std::fs::read_dir(sparse) else {
        return Vec::new();
    };
    let mut numbered: Vec<(u64, PathBuf)> = entries
        .filter_map(|e| e.ok())
        .filter(|e| e.path().is_dir())
        .filter_map(|e| {
            let n = e.file_name().to_str()?.parse::<u64>().ok()?;
            Some((n, e.path()))
        })
        .collect();
    numbered.sort();
    numbered.into_iter().map(|(_, p)| p).collect()
}

fn rel(root: &Path, p: &Path) -> String {
    let r = p.strip_prefix(root).unwrap_or(p);
    if r.as_os_str().is_empty() {
        ".".to_string()
    } else {
        r.display().to_string()
    }
}

/// A place a COLMAP model may be: its model folder, its photo folder, the folder its mesh
/// would sit in, and why it is a candidate.
struct ModelPlace {
    model_dir: PathBuf,
    images_dir: PathBuf,
    dense_dir: PathBuf,
    why: &'static str,
}

/// The place taken and its model's format.
struct ChosenModel {
    place: ModelPlace,
    format: ModelFormat,
}

/// The places a model is looked for, in order of preference (module docs).
fn model_places(root: &Path) -> Vec<ModelPlace> {
    let mut places = vec![
        ModelPlace {
            model_dir: root.join("dense/sparse"),
            images_dir: root.join("dense/images"),
            dense_dir: root.join("dense"),
            why: "the undistorted model with the undistorted photos (image_undistorter output)",
        },
        ModelPlace {
            model_dir: root.join("sparse"),
            images_dir: root.join("images"),
            dense_dir: root.to_path_buf(),
            why: "the model in sparse/",
        },
    ];
    for dir in numbered_models(&root.join("sparse")) {
        places.push(ModelPlace {
            model_dir: dir,
            images_dir: root.join("images"),
            dense_dir: root.to_path_buf(),
            why: "a numbered mapper model",
        });
    }
    places
}

/// The first place with a readable model and its photo folder; what was passed over and
/// why goes to `notes`, and into the error when no place has both.
fn choose_model(root: &Path, notes: &mut Vec<String>) -> Result<ChosenModel> {
    let mut chosen: Option<ChosenModel> = None;
    let mut looked = Vec::new();
    for place in model_places(root) {
        let format = match model_format(&place.model_dir) {
            Ok(format) => format,
            Err(why_not) => {
                looked.push(format!("{}: {why_not}", rel(root, &place.model_dir)));
                continue;
            }
        };
        if !place.images_dir.is_dir() {
            let msg = format!(
                "{}: has a {} model but its photo folder {} is missing",
                rel(root, &place.model_dir),
                format.name(),
                rel(root, &place.images_dir)
            );
            looked.push(msg.clone());
            notes.push(format!("passed over {msg}"));
            continue;
        }
        if let Some(c) = &chosen {
            notes.push(format!(
                "also found a {} model in {}; not used (took {})",
                format.name(),
                rel(root, &place.model_dir),
                rel(root, &c.place.model_dir)
            ));
            continue;
        }
        let other = match format {
            ModelFormat::Binary if ModelFormat::Text.present_in(&place.model_dir) => {
                ", binary read before the text copy beside it"
            }
            _ => "",
        };
        notes.push(format!(
            "model: {} ({} format{other}): {}",
            rel(root, &place.model_dir),
            format.name(),
            place.why
        ));
        notes.push(format!("photos: {}", rel(root, &place.images_dir)));
        chosen = Some(ChosenModel { place, format });
    }
    chosen.ok_or_else(|| Error::Workspace {
        path: root.to_path_buf(),
        message: format!(
            "no COLMAP sparse model with its photos; looked in {}",
            looked.join("; ")
        ),
    })
}

/// Where the mesh and the fused points are looked for: next to the chosen model, then
/// the other dense folder.
fn mesh_dirs(root: &Path, dense_dir: &Path) -> Vec<PathBuf> {
    let mut dirs = vec![dense_dir.to_path_buf()];
    for d in [root.join("dense"), root.to_path_buf()] {
        if !dirs.contains(&d) {
            dirs.push(d);
        }
    }
    dirs
}

/// The mesh: the user's (`--mesh`), else the first Poisson or Delaunay mesh in `dirs`.
fn find_mesh(
    root: &Path,
    dirs: &[PathBuf],
    mesh_override: Option<&Path>,
    notes: &mut Vec<String>,
) -> Result<PathBuf> {
    if let Some(m) = mesh_override {
        if !m.is_file() {
            return Err(Error::Workspace {
                path: m.to_path_buf(),
                message: "the mesh given with --mesh does not exist or is not a file".to_string(),
            });
        }
        notes.push(format!("mesh: {} (given with --mesh)", m.display()));
        return Ok(m.to_path_buf());
    }
    let tried: Vec<PathBuf> = dirs
        .iter()
        .flat_map(|d| [d.join("meshed-poisson.ply"), d.join("meshed-delaunay.ply")])
        .collect();
    let Some(found) = tried.iter().find(|p| p.is_file()) else {
        return Err(Error::Workspace {
            path: root.to_path_buf(),
            message: format!(
                "no mesh: looked for {}; make one with COLMAP's poisson_mesher or name one with --mesh",
                tried.iter().map(|p| rel(root, p)).collect::<Vec<_>>().join(", ")
            ),
        });
    };
    notes.push(format!("mesh: {}", rel(root, found)));
    Ok(found.clone())
}

impl Workspace {
    /// Find model, photos, mesh, fused points and truth under `root` (rules in the module
    /// docs). `mesh_override` replaces the mesh search. A missing model, photo folder or
    /// mesh is an [`Error::Workspace`] saying where it looked.
    pub fn discover(root: &Path, mesh_override: Option<&Path>) -> Result<Workspace> {
        if !root.is_dir() {
            return Err(Error::Workspace {
                path: root.to_path_buf(),
                message: "is not a folder".to_string(),
            });
        }
        let mut notes = Vec::new();
        let chosen = choose_model(root, &mut notes)?;
        let dirs = mesh_dirs(root, &chosen.place.dense_dir);
        let mesh_path = find_mesh(root, &dirs, mesh_override, &mut notes)?;
        let fused_path = dirs
            .iter()
            .map(|d| d.join("fused.ply"))
            .find(|p| p.is_file());
        if let Some(f) = &fused_path {
            notes.push(format!("fused points: {}", rel(root, f)));
        }
        let truth = root.join("truth");
        let truth_dir = truth.is_dir().then_some(truth);
        if truth_dir.is_some() {
            notes.push("truth: truth/ (synthetic scene with known answers)".to_string());
        }
        Ok(Workspace {
            root: root.to_path_buf(),
            sparse_dir: chosen.place.model_dir,
            sparse_format: chosen.format,
            images_dir: chosen.place.images_dir,
            mesh_path,
            fused_path,
            truth_dir,
            notes,
        })
    }

    /// Read the chosen sparse model in the chosen format.
    pub fn read_model(&self) -> Result<Reconstruction> {
        match self.sparse_format {
            ModelFormat::Binary => Reconstruction::read_binary(&self.sparse_dir),
            ModelFormat::Text => Reconstruction::read_text(&self.sparse_dir),
        }
    }

    /// Match the model's registered images with the photo files: found, missing on disk,
    /// and on disk but not registered (photo files: `.jpg`, `.jpeg`, `.png`, `.exr`, `.tif`,
    /// `.tiff`, any case, searched recursively since COLMAP names may contain folders).
    pub fn match_photos(&self, rec: &Reconstruction) -> PhotoMatch {
        let mut m = PhotoMatch::default();
        let mut registered = BTreeSet::new();
        for im in rec.images.values() {
            let path = self.images_dir.join(&im.name);
            registered.insert(im.name.clone());
            if path.is_file() {
                m.found.push((im.id, path));
            } else {
                m.missing.push((im.id, im.name.clone()));
            }
        }
        let mut on_disk = Vec::new();
        list_photos(&self.images_dir, &self.images_dir, &mut on_disk);
        on_disk.sort();
        m.unregistered = on_disk
            .into_iter()
            .filter(|n| !registered.contains(n))
            .collect();
        m
    }
}

/// Photo files under `dir`, as names relative to `base` with `/` separators.
fn list_photos(base: &Path, dir: &Path, out: &mut Vec<String>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.filter_map(|e| e.ok()) {
        let p = e.path();
        if p.is_dir() {
            list_photos(base, &p, out);
            continue;
        }
        let ext = p
            .extension()
            .and_then(|x| x.to_str())
            .map(|x| x.to_ascii_lowercase())
            .unwrap_or_default();
        if ["jpg", "jpeg", "png", "exr", "tif", "tiff"].contains(&ext.as_str()) {
            if let Ok(r) = p.strip_prefix(base) {
                let name: Vec<String> = r
                    .components()
                    .map(|c| c.as_os_str().to_string_lossy().into_owned())
                    .collect();
                out.push(name.join("/"));
            }
        }
    }
}
