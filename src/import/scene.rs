//! The imported scene: a COLMAP workspace's model, cleaned mesh, registered photos that
//! exist on disk, and the fused point cloud carried to the mesh — everything the paper's
//! pipeline (Sec. 3–5) starts from — plus `inspect`, the report of what import found.
//!
//! Import is [`load_scene`] (model, mesh, view list; cheap) then [`load_photos`] (decodes
//! every photo in parallel and checks its size against its camera). `inspect`
//! ([`crate::observe::inspect`]) reports what import found.

use std::path::{Path, PathBuf};

use rayon::prelude::*;

use crate::import::colmap::{Camera, Image, Reconstruction};
use crate::import::mesh::{Mesh, MeshCleanup};
use crate::import::photo::Photo;
use crate::import::points::{transfer, FusedTransfer};
use crate::import::workspace::Workspace;
use crate::{Error, Result};

/// One registered image whose photo is on disk, with its camera.
#[derive(Debug, Clone)]
pub struct View {
    /// The registered image (pose, name, 2D points).
    pub image: Image,
    /// Its camera (intrinsics and distortion).
    pub camera: Camera,
    /// The photo file.
    pub photo_path: PathBuf,
}

/// A loaded workspace.
#[derive(Debug, Clone)]
pub struct Scene {
    /// Where everything was found.
    pub workspace: Workspace,
    /// The sparse model.
    pub recon: Reconstruction,
    /// The cleaned mesh.
    pub mesh: Mesh,
    /// What cleaning changed.
    pub cleanup: MeshCleanup,
    /// Registered images whose photo exists, sorted by name.
    pub views: Vec<View>,
    /// Photos left out, each `"name: reason"` (missing on disk, or not registered).
    pub skipped: Vec<String>,
    /// The fused point cloud carried to the mesh vertices, when `fused.ply` exists.
    pub fused: Option<FusedTransfer>,
}

impl Scene {
    /// The photo files of the views `views` (indices into [`Scene::views`]), in that order.
    pub fn photo_paths(&self, views: &[usize]) -> Vec<&Path> {
        views
            .iter()
            .map(|&v| self.views[v].photo_path.as_path())
            .collect()
    }
}

/// Reads the model, the mesh and (when present) the fused points of a discovered
/// workspace, and lists the views. Registered images missing on disk and unregistered
/// photos are skipped and listed in [`Scene::skipped`]; no photo found at all is an error.
pub fn load_scene(ws: Workspace) -> Result<Scene> {
    let recon = ws.read_model()?;
    let (mesh, cleanup) = Mesh::read_ply(&ws.mesh_path)?;
    let matched = ws.match_photos(&recon);
    let mut views = Vec::with_capacity(matched.found.len());
    for (id, path) in &matched.found {
        let Some(image) = recon.images.get(id) else {
            continue;
        };
        let camera = recon.camera_of(image).ok_or_else(|| {
            Error::format(
                &ws.sparse_dir,
                format!("image {} ({})", id.0, image.name),
                format!(
                    "refers to camera {} that the model lacks",
                    image.camera_id.0
                ),
            )
        })?;
        views.push(View {
            image: image.clone(),
            camera: camera.clone(),
            photo_path: path.clone(),
        });
    }
    views.sort_by(|a, b| a.image.name.cmp(&b.image.name));
    let mut skipped: Vec<String> = matched
        .missing
        .iter()
        .map(|(_, name)| {
            format!(
                "{name}: registered in the model but not found in {}",
                ws.images_dir.display()
            )
        })
        .collect();
    skipped.extend(
        matched
            .unregistered
            .iter()
            .map(|name| format!("{name}: in the photo folder but not registered by the model")),
    );
    if views.is_empty() {
        return Err(Error::Workspace {
            path: ws.images_dir.clone(),
            message: format!(
                "none of the {} registered photos was found here",
                recon.images.len()
            ),
        });
    }
    let fused = match &ws.fused_path {
        Some(p) => Some(transfer(p, &mesh)?),
        None => None,
    };
    Ok(Scene {
        workspace: ws,
        recon,
        mesh,
        cleanup,
        views,
        skipped,
        fused,
    })
}

/// Decodes the photo of every view (in parallel), in view order. `clip` is the
/// overexposure threshold on the encoded scale ([`crate::import::photo::DEFAULT_CLIP`]).
pub fn load_photos(scene: &Scene, clip: f32) -> Result<Vec<Photo>> {
    load_view_photos(&scene.views, clip)
}

/// [`load_photos`] for any list of views. A photo whose size differs from its camera's is
/// an [`Error::Image`] naming the photo; when several photos fail, the first in view order
/// is reported.
pub fn load_view_photos(views: &[View], clip: f32) -> Result<Vec<Photo>> {
    let loaded: Vec<Result<Photo>> = views
        .par_iter()
        .map(|v| {
            let photo = Photo::load(&v.photo_path, clip)?;
            if photo.width != v.camera.width || photo.height != v.camera.height {
                return Err(Error::Image {
                    path: v.photo_path.clone(),
                    message: format!(
                        "photo is {}x{} but its camera {} is {}x{}",
                        photo.width, photo.height, v.camera.id.0, v.camera.width, v.camera.height
                    ),
                });
            }
            Ok(photo)
        })
        .collect();
    loaded.into_iter().collect()
}
